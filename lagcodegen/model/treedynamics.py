"""The recursions of a rigid-body tree (Featherstone, Rigid Body Dynamics Algorithms, 2008) as
symengine expressions that keep the tree: each body's rotation, velocity, acceleration and force
is built once, from its parent's (or children's), and shared by every expression that needs it
(a DAG: never expanded; sin and cos of each joint angle built once). Constants fold while the
expressions are built: zero and unit entries of placements, axis-aligned joint axes.

* forward kinematics, base to tips: omega_i = E^T omega_p + S_i q'_i, v_i likewise;
* recursive Newton-Euler (:meth:`TreeDynamics.rnea`): accelerations with gravity as the base's
  acceleration g up, f_i = I_i a_i + v_i x* I_i v_i, tau_i = S_i^T f_i tips to base; with
  q'' = 0 it is the bias C(q, q') q' + g(q), so that F = Q - bias in M q'' = F (eq. 3.16);
* composite rigid bodies (:meth:`TreeDynamics.mass_matrix`): M_ij = S_i^T I^c_i X S_j;
* T = 1/2 sum v_i . I_i v_i (= 1/2 q'^T M q', eq. 2.2), V = g sum m_i (up . x_G,i) (eq. 2.7).

Spatial vectors are pairs of 3-vectors in body coordinates at the body frame's origin: motion
(omega, v), force (n, f); a spatial inertia is (m, h = m c, I_o = I_G + m (|c|^2 1 - c c^T)).
Fixed joints are merged into their parent (their inertia moved into the parent's frame);
spherical and free joints with Euler angles are chains of elementary rotations and translations
through massless frames (:meth:`lagcodegen.model.bodies.Joint.steps`). A quaternion joint
(generalized speeds, Featherstone ch. 4: motion subspace the identity in the child frame) is a
group of nodes at one frame: the first carries the joint's rotation R(q) (and a free joint's
translation), each node one column of the motion subspace and one speed (``Node.speed``, an index
into v, where the 1-dof nodes' speed is their coordinate's rate); the velocity-product term of the
group is v_in x S v_J with v_in the velocity carried from the parent (``Node.group``).

One job: the tree's recursions; :mod:`lagcodegen.derivation` adds them to the closed-form terms
of the model's other elements.
"""

from __future__ import annotations

from dataclasses import dataclass

import symengine as se
import sympy as sp

from ..errors import ModelError
from .bodies import Placement
from .inertial import _se, placed_inertia

ZERO = se.Integer(0)
ONE = se.Integer(1)

#: Trees of at least this many moving frames take their mass matrix in world coordinates
#: (:meth:`TreeDynamics.mass_matrix_world`: 6 products per pair of joints, against a spatial
#: transform per pair in body coordinates, which folds better on small robots with axis-aligned
#: placements).
WORLD_CRBA_MIN_NODES = 10


def tree_nodes(exprs, limit: int) -> int:
    """The number of nodes of ``exprs`` written out as trees (each shared subexpression counted
    once per use), computed over the distinct nodes (linear in a DAG's size); stops counting
    above ``limit``. The measure of what a tree's DAG expressions would cost as closed forms."""
    memo: dict = {}
    total = 0
    for e in exprs:
        stack = [(e, False)]
        while stack:
            x, done = stack.pop()
            if done:
                memo[x] = 1 + sum(memo[a] for a in x.args)
            elif x not in memo:
                stack.append((x, True))
                stack.extend((a, False) for a in x.args if a not in memo)
        total += memo[e]
        if total > limit:
            break
    return total


def substitute_shared(sub: dict, exprs) -> list:
    """``exprs`` with the substitution ``sub`` applied, every distinct subexpression once across
    all of them: the result shares its subexpressions as the input does (the DAGs built here;
    symengine's xreplace shares within one
    expression only, and copies compared later cost time exponential in the tree's depth)."""
    memo: dict = dict(sub)
    out = []
    for e in exprs:
        e = se.sympify(e)
        stack = [(e, False)]
        while stack:
            x, done = stack.pop()
            if done:
                args = x.args
                new = [memo[a] for a in args]
                memo[x] = x if all(a is b for a, b in zip(new, args)) else x.func(*new)
            elif x not in memo:
                if not x.args:
                    memo[x] = x
                else:
                    stack.append((x, True))
                    stack.extend((a, False) for a in x.args if a not in memo)
        out.append(memo[e])
    return out


def dag_dependencies(index: dict):
    """deps(e): the indices (``index``: symbol -> index) of the symbols in ``e``, memoized over
    the distinct subexpressions of every expression asked about (a rigid-body tree's DAGs, whose
    ``free_symbols`` walks every path: exponential in the tree's depth)."""
    memo: dict = {}
    empty: frozenset = frozenset()

    def deps(e) -> set[int]:
        stack = [(e, False)]
        while stack:
            x, done = stack.pop()
            if done:
                out = empty
                for a in x.args:
                    d = memo[a]
                    if d and not d <= out:
                        out = out | d
                memo[x] = out
            elif x not in memo:
                if not x.args:
                    memo[x] = frozenset((index[x],)) if x in index else empty
                else:
                    stack.append((x, True))
                    stack.extend((a, False) for a in x.args if a not in memo)
        return set(memo[e])
    return deps




def _is0(x) -> bool:
    return x.is_Number and x == 0


#: While a list, every expression built here is named by a temporary symbol ``__mb<k>`` and
#: recorded as (symbol, expression) in order (:func:`recorded`): the tree as a straight-line
#: program of small statements rather than as a DAG.
_RECORD: list | None = None


def _named(e):
    if _RECORD is None or not e.args:
        return e
    sym = se.Symbol(f"__mb{len(_RECORD)}")
    _RECORD.append((sym, e))
    return sym


def mul(a, b):
    """a b with 0 and 1 folded."""
    if _is0(a) or _is0(b):
        return ZERO
    if a.is_Number and a == 1:
        return b
    if b.is_Number and b == 1:
        return a
    return _named(a * b)


def add(*terms):
    """The sum of ``terms`` with zeros dropped (one Add node)."""
    kept = [t for t in terms if not _is0(t)]
    if not kept:
        return ZERO
    return kept[0] if len(kept) == 1 else _named(se.Add(*kept))


def neg(a):
    return ZERO if _is0(a) else _named(-a)


def dot(a, b):
    return add(*(mul(x, y) for x, y in zip(a, b)))


def cross(a, b):
    return [add(mul(a[1], b[2]), neg(mul(a[2], b[1]))),
            add(mul(a[2], b[0]), neg(mul(a[0], b[2]))),
            add(mul(a[0], b[1]), neg(mul(a[1], b[0])))]


def vadd(*vs):
    return [add(*(v[k] for v in vs)) for k in range(3)]


def scale(s, v):
    return [mul(s, x) for x in v]


def matvec(R, x, transpose: bool = False):
    """R x (or R^T x) for a 3x3 matrix of constants given as rows."""
    out = []
    for i in range(3):
        terms = []
        for k in range(3):
            r = R[k][i] if transpose else R[i][k]
            if _is0(r) or _is0(x[k]):
                continue
            terms.append(x[k] if r == 1 else neg(x[k]) if r == -1 else mul(r, x[k]))
        out.append(add(*terms))
    return out


@dataclass
class Node:
    """A moving frame of the tree: ``parent`` (index, -1: the world), the fixed placement of its
    joint frame in the parent frame (``R_T`` rows, ``p_T``), the elementary joint (``kind`` "R"
    or "P", unit ``axis`` in the joint frame, coordinate index ``coord``), and its inertia
    (m, h, I_o) in its own frame (zeros: massless)."""

    parent: int
    R_T: list
    p_T: list
    kind: str
    axis: list
    coord: int
    inertia: tuple | None = None
    speed: int | None = None   # index into v (None: the coordinate's rate, index ``coord``)
    rot: list | None = None    # a quaternion joint's rotation R_J (rows); "still": no motion of the frame
    shift: list | None = None  # a free joint's translation (x, y, z) in the joint frame
    group: int | None = None   # the first node of a quaternion joint's group

    # --- the joint's rotation R_J applied to vectors (axis-aligned axes: a plane rotation)
    def setup(self, q, c, s):
        self.q, self.c, self.s = q, c, s
        if self.speed is None:
            self.speed = self.coord
        self.aligned = None
        nz = [k for k in range(3) if not _is0(self.axis[k])]
        if len(nz) == 1 and self.axis[nz[0]] in (ONE, -ONE):
            k = nz[0]
            self.aligned = (k, self.axis[k] == ONE)
        self.identity_T = all((self.R_T[i][j] == (ONE if i == j else ZERO)) for i in range(3) for j in range(3))

    def joint_rot(self, x, transpose: bool):
        """R_J x (R_J^T x with ``transpose``) for a revolute node; x itself for a prismatic one."""
        if self.rot is not None:
            return list(x) if self.rot == "still" else matvec(self.rot, x, transpose)
        if self.kind == "P":
            return list(x)
        c, s = self.c, self.s
        if self.aligned is not None:
            k, positive = self.aligned
            if positive == transpose:
                s = neg(s)
            i, j = (k + 1) % 3, (k + 2) % 3
            out = list(x)
            out[i] = add(mul(c, x[i]), neg(mul(s, x[j])))
            out[j] = add(mul(s, x[i]), mul(c, x[j]))
            return out
        # Rodrigues: R x = c x + s (a x x) + (1 - c)(a . x) a
        a = self.axis
        axx = cross(a, x)
        if transpose:
            axx = [neg(t) for t in axx]
        ax = mul(add(ONE, neg(c)), dot(a, x))
        return [add(mul(c, x[k]), mul(s, axx[k]), mul(ax, a[k])) for k in range(3)]

    def down(self, x):
        """R^T x: a parent-frame vector in this frame's coordinates (R = R_T R_J)."""
        y = list(x) if self.identity_T else matvec(self.R_T, x, transpose=True)
        return self.joint_rot(y, transpose=True)

    def up(self, x):
        """R x: this frame's vector in parent-frame coordinates."""
        y = self.joint_rot(x, transpose=False)
        return y if self.identity_T else matvec(self.R_T, y)


class TreeDynamics:
    """The recursions of the model's links (module docstring) over symengine symbols ``q``, ``qd``
    (lists in the model's coordinate order)."""

    def __init__(self, model, q: list, qd: list):
        self.model = model
        self.n = len(qd)
        self.q, self.qd = q, qd
        index = {c.name: i for i, c in enumerate(model.coords)}
        speed_index = {v.name: i for i, v in enumerate(model.v)}
        self.nodes: list[Node] = []
        # mimic joints (Joint.mimicking): (leader coordinate, leader speed, gain, offset) each; their
        # nodes move along pseudo-coordinates len(q) + k, speeds len(qd) + k (_extend_mimics)
        self.mimics: list[tuple] = []
        # link name -> (node index, Placement of the link frame in that node; None: the identity)
        anchors: dict = {}
        masses: dict = {}   # node index -> list of (m, c, I_G) in node coordinates (symengine)
        spatial: dict = {}  # node index -> list of (m, h, I_o) in node coordinates (dynamic parameters)
        for link in model.links:
            if link.parent is None:
                node, place = -1, link.origin
            else:
                node, place = anchors[link.parent.name]
                place = link.origin if place is None else place * link.origin
            if link.joint.quaternion:
                node, place = self._quaternion_group(link, node, place, index, speed_index), None
            for kind, axis, coord in link.joint.steps(link.coordinates):
                if place is None:  # the next elementary motion of a spherical or free joint
                    R, p = [[ONE if i == j else ZERO for j in range(3)] for i in range(3)], [ZERO] * 3
                else:
                    R = [[_se(place.rotation[i, j], f"origin of {link.name!r}") for j in range(3)] for i in range(3)]
                    p = [_se(c, f"origin of {link.name!r}") for c in place.translation]
                if link.joint.mimic:
                    leader, gain, offset = link.joint.mimic
                    self.mimics.append((index[leader], speed_index[model.speeds[index[leader]].name], gain, offset))
                    ci, si = len(q) + len(self.mimics) - 1, len(qd) + len(self.mimics) - 1
                else:
                    ci = index[coord.name]
                    si = speed_index[model.speeds[ci].name]
                self.nodes.append(Node(node, R, p, kind, [se.Integer(int(a)) if sp.sympify(a).is_Integer
                                                          else _se(a, f"axis of {link.joint.name!r}") for a in axis],
                                       ci, speed=si))
                node, place = len(self.nodes) - 1, None
            anchors[link.name] = (node, place)
            if node >= 0 and link.origin_inertia is not None:  # dynamic parameters: kept linear
                spatial.setdefault(node, []).append(placed_inertia(link.origin_inertia, place))
            elif node >= 0 and link.mass != 0:
                com = se.DenseMatrix(3, 1, [_se(c, "centre of mass") for c in link.com])
                IG = se.DenseMatrix(3, 3, [_se(c, "inertia") for c in sp.Matrix(link.inertia)])
                if place is not None:
                    R = se.DenseMatrix(3, 3, [_se(c, "placement") for c in place.rotation])
                    com = se.DenseMatrix(3, 1, [_se(c, "placement") for c in place.translation]) + R * com
                    IG = R * IG * R.T
                masses.setdefault(node, []).append((_se(link.mass, "mass"), com, IG))
        for k, items in masses.items():
            m = se.Add(*(it[0] for it in items))
            h = [se.Add(*(it[0] * it[1][i] for it in items)) for i in range(3)]
            Io = [[se.Add(*(it[2][i, j] + it[0] * ((it[1].T * it[1])[0, 0] * (1 if i == j else 0)
                                                      - it[1][i] * it[1][j]) for it in items))
                   for j in range(3)] for i in range(3)]
            Io = [[se.expand(e) if not e.free_symbols else e for e in row] for row in Io]
            self.nodes[k].inertia = (m, h, Io)
        for k, items in spatial.items():
            if self.nodes[k].inertia is not None:
                items = [self.nodes[k].inertia, *items]
            self.nodes[k].inertia = (se.Add(*(it[0] for it in items)),
                                     [se.Add(*(it[1][i] for it in items)) for i in range(3)],
                                     [[se.Add(*(it[2][i][j] for it in items)) for j in range(3)] for i in range(3)])
        if self.mimics:
            q, qd = self._extend_mimics(q, qd)
        self.coord_node = {}
        for k, nd in enumerate(self.nodes):
            qk = q[nd.coord]
            if nd.rot is not None:
                nd.setup(qk, None, None)
            else:
                nd.setup(qk, _named(se.cos(qk)), _named(se.sin(qk)))
            self.coord_node[nd.coord] = k
        self.children: list[list[int]] = [[] for _ in self.nodes]
        for k, nd in enumerate(self.nodes):
            if nd.parent >= 0:
                self.children[nd.parent].append(k)
        self._velocities = None

    def _extend_mimics(self, q: list, qd: list) -> tuple[list, list]:
        """q and q' with the mimic joints' pseudo-coordinates gain q_leader + offset and rates
        gain q_leader' appended: the recursions run over them as over any joint
        (:attr:`n_full`), :meth:`mass_matrix` and :meth:`rnea` fold them into the leaders'."""
        q = list(q) + [se.Add(mul(se.Float(g), q[c]), se.Float(o)) if o else mul(se.Float(g), q[c])
                       for c, _, g, o in self.mimics]
        qd = list(qd) + [mul(se.Float(g), qd[s]) for _, s, g, _ in self.mimics]
        self.q, self.qd, self.n = q, qd, len(qd)
        return q, qd

    @property
    def n_speeds(self) -> int:
        """The model's speeds (without the mimic joints' pseudo-speeds)."""
        return self.n - len(self.mimics)

    def _fold(self, vec: list) -> list:
        """A vector over the speeds and the mimic pseudo-speeds as one over the speeds: each
        pseudo-speed's entry times its gain added to its leader's (G^T x, q'_mimic = gain q'_leader)."""
        if not self.mimics:
            return vec
        nv = self.n_speeds
        out = list(vec[:nv])
        for k, (_, s, g, _) in enumerate(self.mimics):
            out[s] = add(out[s], mul(se.Float(g), vec[nv + k]))
        return out

    def _fold_matrix(self, M: list) -> list:
        """G^T M G of a matrix over the speeds and pseudo-speeds (:meth:`_fold` on rows and columns)."""
        if not self.mimics:
            return M
        rows = [self._fold(row) for row in M]  # the columns folded: M G
        nv = self.n_speeds
        out = [list(r[:nv]) for r in rows[:nv]]
        for k, (_, s, g, _) in enumerate(self.mimics):
            for b in range(nv):
                out[s][b] = add(out[s][b], mul(se.Float(g), rows[nv + k][b]))
        return out

    def _quaternion_group(self, link, node: int, place, index: dict, speed_index: dict) -> int:
        """Append the nodes of ``link``'s quaternion joint (a free joint: three translations
        along the child's axes, then three rotations; a spherical joint: the rotations) after
        ``node``, placed at ``place``; return the last node."""
        if place is None:
            R, p = [[ONE if i == j else ZERO for j in range(3)] for i in range(3)], [ZERO] * 3
        else:
            R = [[_se(place.rotation[i, j], f"origin of {link.name!r}") for j in range(3)] for i in range(3)]
            p = [_se(c, f"origin of {link.name!r}") for c in place.translation]
        coords = [se.Symbol(c.name) for c in link.coordinates]
        x, y, z, w = coords[-4:]
        n2 = _named(se.Add(mul(x, x), mul(y, y), mul(z, z), mul(w, w)))
        s2 = _named(se.Integer(2) / n2)
        xx, yy, zz = mul(x, x), mul(y, y), mul(z, z)
        xy, xz, yz, xw, yw, zw = mul(x, y), mul(x, z), mul(y, z), mul(x, w), mul(y, w), mul(z, w)
        rot = [[add(ONE, neg(mul(s2, add(yy, zz)))), mul(s2, add(xy, neg(zw))), mul(s2, add(xz, yw))],
               [mul(s2, add(xy, zw)), add(ONE, neg(mul(s2, add(xx, zz)))), mul(s2, add(yz, neg(xw)))],
               [mul(s2, add(xz, neg(yw))), mul(s2, add(yz, xw)), add(ONE, neg(mul(s2, add(xx, yy))))]]
        units = [[ONE, ZERO, ZERO], [ZERO, ONE, ZERO], [ZERO, ZERO, ONE]]
        kinds = (["P"] * 3 if link.joint.kind == "free" else []) + ["R"] * 3
        first = len(self.nodes)
        coord = index[link.coordinates[0].name]
        for j, (kind, speed) in enumerate(zip(kinds, link.speeds)):
            axis = units[j % 3]
            if j == 0:
                nd = Node(node, R, p, kind, axis, coord, speed=speed_index[speed.name], rot=rot, group=first,
                          shift=coords[:3] if link.joint.kind == "free" else None)
            else:
                nd = Node(first + j - 1, [list(r) for r in units], [ZERO] * 3, kind, axis, coord,
                          speed=speed_index[speed.name], rot="still", group=first)
            self.nodes.append(nd)
        return len(self.nodes) - 1

    # ------------------------------------------------------------------ kinematics
    def origin(self, k: int):
        """The node's origin in its parent frame: p_T (+ R_T a q for a prismatic joint; + R_T x
        for a free joint's translation x)."""
        nd = self.nodes[k]
        if nd.shift is not None:
            d = list(nd.shift)
            return vadd(nd.p_T, d if nd.identity_T else matvec(nd.R_T, d))
        if nd.rot is not None:
            return nd.p_T
        if nd.kind == "P":
            d = scale(nd.q, nd.axis)
            return vadd(nd.p_T, d if nd.identity_T else matvec(nd.R_T, d))
        return nd.p_T

    def velocities(self) -> list[tuple[list, list]]:
        """(omega_i, v_i) of every node in its own coordinates."""
        if self._velocities is None:
            out = []
            self._incoming = {}
            for k, nd in enumerate(self.nodes):
                if nd.parent < 0:
                    w, v = [ZERO] * 3, [ZERO] * 3
                else:
                    wp, vp = out[nd.parent]
                    w, v = nd.down(wp), nd.down(vadd(vp, cross(wp, self.origin(k))))
                if nd.group == k:  # the velocity a quaternion joint's group carries from the parent
                    self._incoming[k] = (w, v)
                Sq = scale(self.qd[nd.speed], nd.axis)
                if nd.kind == "R":
                    w = vadd(w, Sq)
                else:
                    v = vadd(v, Sq)
                out.append((w, v))
            self._velocities = out
        return self._velocities

    @staticmethod
    def apply_inertia(inertia, w, v):
        """I (omega, v) = (I_o omega + h x v, m v - h x omega)."""
        m, h, Io = inertia
        return (vadd([dot(row, w) for row in Io], cross(h, v)), vadd(scale(m, v), [neg(x) for x in cross(h, w)]))

    def gravity_acceleration(self):
        """The base's acceleration g up (gravity as a fictitious acceleration), in world axes."""
        spec = self.model.gravity_spec
        if spec is None:
            return [ZERO] * 3
        g, up = spec
        if up is None:
            up = sp.Matrix([0, 0, 1])
        if len(up) != 3:
            raise ModelError(f"gravity 'up' has {len(up)} components; links move in 3-D")
        g = _se(g, "gravity")
        return [mul(g, _se(u, "gravity up")) for u in up]

    # ------------------------------------------------------------------ dynamics
    def rnea(self, qdd: list | None = None, velocities: bool = True, gravity: bool = True) -> list:
        """tau = RNEA(q, q', q'') per coordinate (zero for coordinates outside the tree): the
        generalized forces the joints need for accelerations ``qdd`` (None: zero) under
        gravity (M q'' + C q' + g, Featherstone's algorithm 5.1)."""
        if self.mimics:
            if qdd is not None:
                qdd = list(qdd) + [mul(se.Float(g), qdd[sp_]) for _, sp_, g, _ in self.mimics]
            return self._fold(self._rnea(qdd, velocities, gravity))
        return self._rnea(qdd, velocities, gravity)

    def _rnea(self, qdd: list | None, velocities: bool, gravity: bool) -> list:
        """:meth:`rnea` over the speeds and the mimic joints' pseudo-speeds."""
        vel = self.velocities() if velocities else [([ZERO] * 3, [ZERO] * 3) for _ in self.nodes]
        acc = []
        force = []
        a0 = self.gravity_acceleration() if gravity else [ZERO] * 3
        for k, nd in enumerate(self.nodes):
            w, v = vel[k]
            if nd.parent < 0:
                al, a = [ZERO] * 3, nd.down(a0)
            else:
                alp, ap = acc[nd.parent]
                al, a = nd.down(alp), nd.down(vadd(ap, cross(alp, self.origin(k))))
            if velocities:
                Sq = scale(self.qd[nd.speed], nd.axis)
                wc, vc = (w, v) if nd.group is None else self._incoming[nd.group]
                if nd.kind == "R":  # c_J = v x S q' (a group: v_in x S v_J, Node.group)
                    al, a = vadd(al, cross(wc, Sq)), vadd(a, cross(vc, Sq))
                else:
                    a = vadd(a, cross(wc, Sq))
            if qdd is not None:
                Sa = scale(qdd[nd.speed], nd.axis)
                if nd.kind == "R":
                    al = vadd(al, Sa)
                else:
                    a = vadd(a, Sa)
            acc.append((al, a))
            if nd.inertia is None:
                force.append(([], []))
                continue
            n, f = self.apply_inertia(nd.inertia, al, a)
            terms_n, terms_f = [[x] for x in n], [[x] for x in f]
            if velocities:
                nm, lm = self.apply_inertia(nd.inertia, w, v)
                for t, x in zip(terms_n, vadd(cross(w, nm), cross(v, lm))):
                    t.append(x)
                for t, x in zip(terms_f, cross(w, lm)):
                    t.append(x)
            force.append((terms_n, terms_f))
        tau = [ZERO] * self.n
        for k in reversed(range(len(self.nodes))):
            nd = self.nodes[k]
            tn, tf = force[k]
            if not tn:
                continue
            n, f = [add(*t) for t in tn], [add(*t) for t in tf]
            tau[nd.speed] = dot(nd.axis, n if nd.kind == "R" else f)
            if nd.parent >= 0:
                Rf = nd.up(f)
                Rn = vadd(nd.up(n), cross(self.origin(k), Rf))
                pn, pf = force[nd.parent]
                if not pn:
                    pn, pf = [[] for _ in range(3)], [[] for _ in range(3)]
                    force[nd.parent] = (pn, pf)
                for t, x in zip(pn, Rn):
                    t.append(x)
                for t, x in zip(pf, Rf):
                    t.append(x)
        return tau

    def _inertia_up(self, k: int, inertia):
        """A node's (composite) inertia expressed in its parent's frame, about its origin."""
        nd = self.nodes[k]
        m, h, Io = inertia
        p = self.origin(k)
        hr = nd.up(h)
        cols = [nd.up([Io[0][j], Io[1][j], Io[2][j]]) for j in range(3)]  # R Io (columns)
        rows = [nd.up([cols[j][i] for j in range(3)]) for i in range(3)]  # R (R Io)^T = R Io R^T (columns)
        IoR = [[rows[j][i] for j in range(3)] for i in range(3)]
        pp, hp = dot(p, p), dot(hr, p)
        out = [[None] * 3 for _ in range(3)]
        for i in range(3):
            for j in range(i, 3):
                e = add(IoR[i][j], neg(mul(m, mul(p[i], p[j]))), neg(mul(hr[i], p[j])), neg(mul(p[i], hr[j])))
                if i == j:
                    e = add(e, mul(m, pp), mul(se.Integer(2), hp))
                out[i][j] = out[j][i] = e
        return m, vadd(hr, scale(m, p)), out

    def composite_inertias(self) -> list:
        """I^c_i: the inertia of node i and all its descendants, in node i's frame."""
        comp: list = [nd.inertia for nd in self.nodes]
        for k in reversed(range(len(self.nodes))):
            nd = self.nodes[k]
            if comp[k] is None or nd.parent < 0:
                continue
            m, h, Io = self._inertia_up(k, comp[k])
            if comp[nd.parent] is None:
                comp[nd.parent] = (m, h, Io)
            else:
                pm, ph, pI = comp[nd.parent]
                comp[nd.parent] = (add(pm, m), vadd(ph, h), [[add(pI[i][j], Io[i][j]) for j in range(3)]
                                                             for i in range(3)])
        return comp

    def mass_matrix(self) -> list:
        """M (n x n list of rows) by composite rigid bodies; entries outside the tree's
        coordinates are zero. Up to WORLD_CRBA_MIN_NODES moving frames in body coordinates
        (:meth:`mass_matrix_local`), above in world coordinates (:meth:`mass_matrix_world`)."""
        if len(self.nodes) >= WORLD_CRBA_MIN_NODES:
            return self._fold_matrix(self.mass_matrix_world())
        return self._fold_matrix(self.mass_matrix_local())

    def world_poses(self) -> list:
        """(E, x) of every node: its axes (rows of a 3x3 list) and origin in world coordinates."""
        out = []
        for k, nd in enumerate(self.nodes):
            p = self.origin(k)
            cols = [nd.up([ONE if i == j else ZERO for i in range(3)]) for j in range(3)]  # R columns
            R = [[cols[j][i] for j in range(3)] for i in range(3)]
            if nd.parent < 0:
                out.append((R, p))
                continue
            Ep, xp = out[nd.parent]
            E = [[add(*(mul(Ep[i][m], R[m][j]) for m in range(3))) for j in range(3)] for i in range(3)]
            out.append((E, vadd(xp, matvec(Ep, p))))
        return out

    def mass_matrix_world(self) -> list:
        """M by composite rigid bodies in world coordinates: each body's inertia moved to the world
        frame once, composite inertias summed tips to base (plain sums there), the joints' motion
        subspaces S_j = (u, x x u) (revolute) or (0, u) (prismatic) in world coordinates, and
        M_ij = S_i . (I^c_j S_j) for i an ancestor of j (or i = j): 6 products per pair instead
        of a spatial transform per pair (Featherstone's algorithm 6.2 in one frame)."""
        M = [[ZERO] * self.n for _ in range(self.n)]
        poses = self.world_poses()
        comp: list = [None] * len(self.nodes)
        for k, nd in enumerate(self.nodes):
            if nd.inertia is None:
                continue
            E, x = poses[k]
            m, h, Io = nd.inertia
            hr = matvec(E, h)
            cols = [matvec(E, [Io[0][j], Io[1][j], Io[2][j]]) for j in range(3)]
            rows = [matvec(E, [cols[j][i] for j in range(3)]) for i in range(3)]
            IoR = [[rows[j][i] for j in range(3)] for i in range(3)]
            xx, hx = dot(x, x), dot(hr, x)
            I = [[None] * 3 for _ in range(3)]
            for i in range(3):
                for j in range(i, 3):
                    e = add(IoR[i][j], neg(mul(m, mul(x[i], x[j]))), neg(mul(hr[i], x[j])), neg(mul(x[i], hr[j])))
                    if i == j:
                        e = add(e, mul(m, xx), mul(se.Integer(2), hx))
                    I[i][j] = I[j][i] = e
            comp[k] = [[m], [[t] for t in vadd(hr, scale(m, x))], [[[I[i][j]] for j in range(3)] for i in range(3)]]
        for k in reversed(range(len(self.nodes))):  # composite: plain sums in one frame
            nd = self.nodes[k]
            if comp[k] is None or nd.parent < 0:
                continue
            c = [add(*comp[k][0]), [add(*t) for t in comp[k][1]], [[add(*t) for t in row] for row in comp[k][2]]]
            comp[k] = [[c[0]], [[t] for t in c[1]], [[[t] for t in row] for row in c[2]]]
            if comp[nd.parent] is None:
                comp[nd.parent] = [[c[0]], [[t] for t in c[1]], [[[t] for t in row] for row in c[2]]]
            else:
                pc = comp[nd.parent]
                pc[0].append(c[0])
                for t, v in zip(pc[1], c[1]):
                    t.append(v)
                for prow, row in zip(pc[2], c[2]):
                    for t, v in zip(prow, row):
                        t.append(v)
        S = []
        for k, nd in enumerate(self.nodes):
            E, x = poses[k]
            u = matvec(E, nd.axis)
            S.append((u, cross(x, u)) if nd.kind == "R" else ([ZERO] * 3, u))
        for k, nd in enumerate(self.nodes):
            if comp[k] is None:
                continue
            m = add(*comp[k][0])
            h = [add(*t) for t in comp[k][1]]
            Io = [[add(*t) for t in row] for row in comp[k][2]]
            w, v = S[k]
            n, f = self.apply_inertia((m, h, Io), w, v)
            i = nd.speed
            j = k
            while j >= 0:
                sj = S[j]
                M[self.nodes[j].speed][i] = M[i][self.nodes[j].speed] = add(dot(sj[0], n), dot(sj[1], f))
                j = self.nodes[j].parent
        return M

    def mass_matrix_local(self) -> list:
        """M by composite rigid bodies in body coordinates (Featherstone's algorithm 6.2): the
        composite inertia's force I^c_i S_i carried to every ancestor by spatial transforms."""
        M = [[ZERO] * self.n for _ in range(self.n)]
        comp = self.composite_inertias()
        for k, nd in enumerate(self.nodes):
            if comp[k] is None:
                continue
            m, h, Io = comp[k]
            if nd.kind == "R":
                n, f = [dot(row, nd.axis) for row in Io], cross(nd.axis, h)
            else:
                n, f = cross(h, nd.axis), scale(m, nd.axis)
            i = nd.speed
            M[i][i] = dot(nd.axis, n if nd.kind == "R" else f)
            j = k
            while self.nodes[j].parent >= 0:
                f2 = self.nodes[j].up(f)
                n = vadd(self.nodes[j].up(n), cross(self.origin(j), f2))
                f = f2
                j = self.nodes[j].parent
                pj = self.nodes[j]
                M[pj.speed][i] = M[i][pj.speed] = dot(pj.axis, n if pj.kind == "R" else f)
        return M

    def kinetic_energy(self):
        """T = 1/2 sum omega . n + v . l with (n, l) = I (omega, v) (eq. 2.2)."""
        terms = []
        for nd, (w, v) in zip(self.nodes, self.velocities()):
            if nd.inertia is not None:
                nm, lm = self.apply_inertia(nd.inertia, w, v)
                terms += [dot(w, nm), dot(v, lm)]
        return mul(se.Rational(1, 2), add(*terms))

    def potential_energy(self):
        """V = g sum (m_i height_i + up_i . h_i), heights of the node origins along ``up`` (eq. 2.7)."""
        spec = self.model.gravity_spec
        if spec is None:
            return ZERO
        a0 = self.gravity_acceleration()  # g up
        ups, heights, terms = [], [], []
        for k, nd in enumerate(self.nodes):
            if nd.parent < 0:
                up_p, h_p = a0, ZERO
            else:
                up_p, h_p = ups[nd.parent], heights[nd.parent]
            height = add(h_p, dot(up_p, self.origin(k)))
            up = nd.down(up_p)
            ups.append(up)
            heights.append(height)
            if nd.inertia is not None:
                m, h, _ = nd.inertia
                terms += [mul(m, height), dot(up, h)]
        # links fixed to the world: constant potential, left out
        return add(*terms)


def _live(defs: list, outputs: list) -> list:
    """The definitions that ``outputs`` read, directly or through other definitions, in order
    (the recursions compute a few quantities no output needs: a composite inertia's entries
    that no joint axis reads, ...); the others would be dead code (unused variables in C)."""
    need = set()
    for e in outputs:
        need |= se.sympify(e).free_symbols
    out = []
    for sym, e in reversed(defs):
        if sym in need:
            need |= e.free_symbols
            out.append((sym, e))
    out.reverse()
    return out


def recorded(model, q: list, qd: list) -> tuple[list, list, list]:
    """The tree's M and bias (:meth:`TreeDynamics.mass_matrix`, :meth:`TreeDynamics.rnea` at
    q'' = 0) as a straight-line program: (definitions [(temporary, expression)] in order, M,
    bias), every expression small (over q, q', parameters, numbers and earlier temporaries).
    The generated code evaluates this program; the DAG form (the same values) serves the
    symbolic consumers."""
    global _RECORD
    _RECORD = []
    try:
        tree = TreeDynamics(model, q, qd)
        M = tree.mass_matrix()
        bias = tree.rnea()
        return _live(_RECORD, [e for row in M for e in row] + bias), M, bias
    finally:
        _RECORD = None


def recorded_inverse_dynamics(model, q: list, qd: list, qdd: list) -> tuple[list, list]:
    """tau = RNEA(q, q', q'') of the tree as a straight-line program: (definitions, tau)."""
    global _RECORD
    _RECORD = []
    try:
        tau = TreeDynamics(model, q, qd).rnea(qdd)
        return _live(_RECORD, tau), tau
    finally:
        _RECORD = None
