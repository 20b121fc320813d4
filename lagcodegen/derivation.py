"""Lagrange's equations M(q, q', t) q'' = F(q, q', t) from a :class:`~lagcodegen.model.Model`.

One job: a model's elements into one M and F (:class:`EquationsOfMotion`): Lagrange's closed-form
terms, their projection onto generalized speeds, a rigid-body tree's terms
(:mod:`lagcodegen.model.treedynamics` computes them) and equations given directly
(:meth:`Model.equations_of_motion`, Kane's) are added here, with the energies and momenta beside.

The derivation runs on symengine (fast), and every result is offered as sympy objects:

* T from the bodies (eq. 2.2) plus any T given directly, V (eq. 2.7), L = T - V (sec. 3.2),
* generalized momenta p_i = dL/dq_i' (eq. 2.3),
* generalized forces Q_i from Cartesian forces (eq. 2.6) and Q* (eq. 3.16),
* Rayleigh dissipation D (eq. 3.15) entering as -dD/dq_i' (eq. 3.14),
* the equations (3.16) written as M q'' = F with
      M_ij = d^2 L / dq_i' dq_j'
      F_i  = dL/dq_i - sum_j (d^2 L / dq_i' dq_j) q_j' - d^2 L / dq_i' dt - dD/dq_i' + Q_i.

M is never inverted symbolically: generated code solves M q'' = F numerically.

Links of rigid-body trees (:meth:`Model.link`) are not differentiated: their M, their share of F
(the bias C q' + g, with a minus sign), of T, V and the momenta come from the tree's recursions
(:mod:`lagcodegen.model.treedynamics`) as symengine expressions that keep the tree (DAGs: each
body's kinematics once, shared), added to the closed-form terms of the model's other elements.
Their sympy views (:attr:`EquationsOfMotion.M`, ...) expand the DAG into a tree, so above
:data:`SYMPY_VIEW_MAX_OPS` operations they are refused with a message; the generated code never
needs them.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from functools import cached_property

import symengine as se
import sympy as sp

from . import progress
from .errors import DerivationError, ModelError
from .util import excerpt
from .model.mechanics import as_model
from .model.model import Model, Particle, PlanarBody, RigidBody, require_model
from .model.treedynamics import TreeDynamics, tree_nodes

#: The sympy views of an EquationsOfMotion whose expressions count more nodes than this
#: when written out as trees ( a rigid-body tree's expressions are DAGs
#: whose written-out size grows exponentially with depth) are refused with a ModelError.
SYMPY_VIEW_MAX_OPS = 200_000


def require_lagrange(model, what: str) -> None:
    """ModelError naming ``what`` if ``model`` (a Model or equations of one) has generalized
    speeds (q' = k(q, v, t), v != q'): the places that take only Lagrange's form q' = v."""
    model = getattr(model, "model", model)
    if getattr(model, "general", False):
        raise ModelError(f"{what}: model {model.name!r} has generalized speeds (nq = {model.nq}, nv = {model.nv}; "
                         "quaternion joints or Model.generalized_speeds), which it does not take yet; it takes models "
                         "whose speeds are their coordinates' rates (Euler-angle joints: rotation='ZYX')")


def to_se(expr, what: str = "expression"):
    """sympy -> symengine, with a clear error for constructs symengine lacks."""
    try:
        return se.sympify(expr)
    except Exception as exc:  # symengine raises several types here
        raise ModelError(f"{what} cannot be handled by the derivation engine: {excerpt(expr)} "
                         f"({excerpt(str(exc), quote=False)})") from None


def to_sp(expr):
    """symengine -> sympy."""
    return sp.sympify(expr)


def _sp_matrix(rows) -> sp.Matrix:
    return sp.Matrix([[to_sp(e) for e in row] for row in rows])


def _viewable(eom, what: str, *exprs) -> None:
    """Refuse a sympy view of a rigid-body tree's DAG expressions that would be too large."""
    if eom.tree is None:
        return
    flat = [e for x in exprs for e in (x if isinstance(x, list) else [x])]
    flat = [e for x in flat for e in (x if isinstance(x, list) else [x])]
    ops = tree_nodes(flat, SYMPY_VIEW_MAX_OPS)
    if ops > SYMPY_VIEW_MAX_OPS:
        raise ModelError(f"{what} of model {eom.model.name!r} is kept as a program along its rigid-body tree; "
                         f"written out for sympy it would count more than {ops} nodes (more than "
                         f"SYMPY_VIEW_MAX_OPS = {SYMPY_VIEW_MAX_OPS}): use the symengine fields (M_se, F_se, ...) "
                         "or the generated code")


@dataclass
class EquationsOfMotion:
    """Derived equations of a model. Symbolic fields come as sympy objects (converted lazily).

    ``M`` is the mass matrix and ``F`` the generalized force vector of M q'' = F (eq. 3.16).
    """

    model: Model
    T_se: object
    V_se: object
    D_se: object
    Q_se: list  # generalized forces (Cartesian mapped + Q*), not including -dD/dq'
    p_se: list  # momenta dL/dq'
    M_se: list  # n x n (list of rows)
    F_se: list  # n
    h_se: object = None  # Jacobi energy function (eq. 3.5)
    Uv_se: object = 0  # velocity-dependent part of the generalized potentials (eq. 3.4)
    dhdt_se: object = None  # dh/dt along solutions (eq. 3.6 with non-potential forces)
    quadratures: list = field(default_factory=list)  # (state name, symengine rate): extra states z' = rate
    derivation_seconds: float = 0.0
    tree: object = None  # treedynamics.TreeDynamics of the model's links (None: no links)
    #: False if M need not be symmetric (equations given directly, e.g. Kane's with dependent speeds):
    #: the generated code writes every entry and factors M by LU.
    symmetric: bool = True
    #: The quantities the equations do not determine (equations given directly without their
    #: energies, Model.equations_of_motion): name ("T", "V", "momenta", "D", "Q", "L", "h", "dhdt")
    #: -> why; their views and outputs are refused with it.
    unknown: dict = field(default_factory=dict)
    _cache: dict = field(default_factory=dict, repr=False)

    # ------------------------------------------------------------ symbols
    @property
    def q(self) -> list[sp.Symbol]:
        return list(self.model.coords)

    @property
    def qd(self) -> list[sp.Symbol]:
        return list(self.model.speeds)

    @property
    def t(self) -> sp.Symbol:
        return self.model.t

    @property
    def n(self) -> int:
        return self.model.n

    @property
    def general(self) -> bool:
        """True if the speeds are not the coordinates' rates: q' = G(q, t) v + g(q, t) (nq >= nv),
        M(q, t) v' = F(q, v, t) with M nv x nv (quaternion joints, Kane's form)."""
        return self.model.general

    @property
    def v(self) -> list[sp.Symbol]:
        """The generalized speeds (the q' symbols :attr:`qd` unless :attr:`general`)."""
        return list(self.model.v)

    @property
    def nq(self) -> int:
        return self.model.nq

    @property
    def nv(self) -> int:
        return self.model.nv

    @property
    def qdot_se(self) -> list:
        """q' in (q, v, t) per coordinate (symengine): the speeds themselves unless :attr:`general`."""
        cache = self._cache.get("qdot")
        if cache is None:
            cache = self._cache["qdot"] = [to_se(e, f"kinematic equation of {q.name!r}")
                                           for e, q in zip(self.model.qdot, self.model.coords)]
        return cache

    @property
    def parameters(self) -> dict:
        """Parameter symbols and their default values."""
        return dict(self.model.params)

    # ------------------------------------------------------------ sympy views
    def _known(self, name: str) -> None:
        """ModelError if the equations do not determine ``name`` (:attr:`unknown`)."""
        if name in self.unknown:
            raise ModelError(self.unknown[name])

    @cached_property
    def T(self) -> sp.Expr:
        """Kinetic energy T(q, q', t) (eq. 2.2)."""
        self._known('T')
        _viewable(self, 'T', self.T_se)
        return to_sp(self.T_se)

    @cached_property
    def V(self) -> sp.Expr:
        """Potential energy V(q, t) (eq. 2.7), including the velocity-free part of generalized potentials."""
        self._known('V')
        _viewable(self, 'V', self.V_se)
        return to_sp(self.V_se)

    @cached_property
    def U_velocity(self) -> sp.Expr:
        """Velocity-dependent part of the generalized potentials (eq. 3.4), e.g. -e v . A."""
        self._known('L')
        return to_sp(self.Uv_se)

    @cached_property
    def L(self) -> sp.Expr:
        """Lagrangian L = T - V - U_velocity (secs. 3.2, 3.3)."""
        self._known('L')
        return self.T - self.V - self.U_velocity

    @cached_property
    def D(self) -> sp.Expr:
        """Rayleigh dissipation function (eq. 3.15)."""
        self._known('D')
        _viewable(self, 'D', self.D_se)
        return to_sp(self.D_se)

    @cached_property
    def Q(self) -> sp.Matrix:
        """Generalized forces from Cartesian forces (eq. 2.6) and Q* (eq. 3.16)."""
        self._known('Q')
        return sp.Matrix([to_sp(e) for e in self.Q_se])

    @cached_property
    def momenta(self) -> sp.Matrix:
        """Generalized (canonical) momenta p_i = dL/dq_i'; equal to dT/dq_i' (eq. 2.3) unless a
        generalized potential depends on the velocities (then e.g. m v + e A)."""
        self._known('momenta')
        _viewable(self, 'momenta', self.p_se)
        return sp.Matrix([to_sp(e) for e in self.p_se])

    @cached_property
    def M(self) -> sp.Matrix:
        """Mass matrix (symmetric), M_ij = d^2 L / dq_i' dq_j'."""
        _viewable(self, 'M', self.M_se)
        return _sp_matrix(self.M_se)

    @cached_property
    def F(self) -> sp.Matrix:
        """Right side of M q'' = F (eq. 3.16)."""
        _viewable(self, 'F', self.F_se)
        return sp.Matrix([to_sp(e) for e in self.F_se])

    @cached_property
    def h(self) -> sp.Expr:
        """Jacobi energy function h = sum_i q_i' dL/dq_i' - L (eq. 3.5)."""
        self._known('h')
        _viewable(self, 'h', self.h_se)
        return to_sp(self.h_se)

    @cached_property
    def dhdt(self) -> sp.Expr:
        """dh/dt along solutions: -dL/dt + sum_i q_i' (Q_i - dD/dq_i') (eq. 3.6 plus eq. 3.16's forces).

        For D homogeneous quadratic in the velocities, sum_i q_i' dD/dq_i' = 2 D.
        """
        self._known('dhdt')
        _viewable(self, 'dhdt', self.dhdt_se)
        return to_sp(self.dhdt_se)

    @property
    def energy(self) -> sp.Expr:
        """Mechanical energy T + V."""
        return self.T + self.V

    def position(self, point: str) -> list:
        """The position x(q, t) of the model's point named ``point`` as symengine expressions
        (converted from sympy once; :func:`derive` converts those of the bodies)."""
        cache = self._cache.setdefault("positions", {})
        if point not in cache:
            cache[point] = [to_se(c, f"position of {point!r}") for c in self.model.points[point].position]
        return cache[point]

    def accelerations(self) -> sp.Matrix:
        """Symbols q_i'' used by :meth:`equations`."""
        return sp.Matrix([sp.Symbol(f"{q.name}_ddot") for q in self.q])

    def equations(self) -> sp.Matrix:
        """Lagrange's equations as residuals M q'' - F (each = 0)."""
        return self.M * self.accelerations() - self.F

    def _repr_latex_(self) -> str:
        """Lagrange's equations M q'' = F with dotted velocities; a few rows, each of bounded
        length, then how many more (a 20-link chain's stays a few kB)."""
        from .notebook import eom_latex
        return eom_latex(self)

    def _repr_html_(self) -> str:
        from .notebook import eom_html
        return eom_html(self)


# ---------------------------------------------------------------------- helpers
class _Engine:
    """symengine views of the model's symbols plus time differentiation."""

    def __init__(self, model: Model):
        self.model = model
        self.q = [se.Symbol(s.name) for s in model.coords]
        self.qd = [se.Symbol(s.name) for s in model.speeds]
        self.v = [se.Symbol(s.name) for s in model.velocities] if model.general else self.qd
        self.t = se.Symbol(model.t.name)
        self.memo: dict = {}

    def ddt(self, e):
        """Total time derivative of an expression in (q, t)."""
        grad = gradient(e, self.q)
        return se.Add(se.diff(e, self.t), *(grad[q] * v for q, v in zip(self.q, self.qd) if q in grad))

    def vec(self, m, what):
        return [self.convert(c, what) for c in m]

    def convert(self, e, what):
        """:func:`to_se` remembering every sum and product converted: a chain's positions share
        their terms (the position of link k is that of link k - 1 plus two terms), converted once."""
        hit = self.memo.get(e)
        if hit is None:
            if isinstance(e, (sp.Add, sp.Mul)):
                op = se.Add if isinstance(e, sp.Add) else se.Mul
                hit = op(*(self.convert(a, what) for a in e.args))
            else:
                hit = to_se(e, what)
            self.memo[e] = hit
        return hit


def gradient(e, symbols) -> dict:
    """The nonzero derivatives of ``e`` by ``symbols``, {symbol: derivative}: a sum is differentiated
    term by term, each term by the symbols it holds only (a chain's positions, sums of n terms of
    one coordinate each, cost O(n) rather than n derivatives of the whole sum). The same
    expressions as se.diff(e, symbol)."""
    wanted = set(symbols)
    parts: dict = {}
    for term in (e.args if isinstance(e, se.Add) else (e,)):
        for s in term.free_symbols & wanted:
            parts.setdefault(s, []).append(se.diff(term, s))
    out = {s: se.Add(*ds) for s, ds in parts.items()}
    return {s: d for s, d in out.items() if d != 0}


PYTHAGORAS_MAX_COORDS = 3


def pythagoras(expr):
    """Expand and replace sin(a)^2 by 1 - cos(a)^2 so that sin^2 + cos^2 terms cancel.

    Keeps T free of identities like l^2 (sin^2 q + cos^2 q) q'^2 that would otherwise hide
    that a coordinate is ignorable and cost flops in the generated code.
    """
    expr = se.expand(expr)
    sines = [a for a in expr.atoms(se.sin)]
    if not sines:
        return expr
    return se.expand(expr.xreplace({s**2: 1 - se.cos(s.args[0]) ** 2 for s in sines}))


#: Translational kinetic energies m/2 |x'|^2 of bodies moved by more coordinates than
#: PYTHAGORAS_MAX_COORDS (and of a mass free of q and t) enter Lagrange's equations through their
#: velocity Jacobians J = dx/dq (:func:`_point_masses`), not by differentiating L: the same
#: equations, without the terms of dT/dq and d/dt dT/dq' that cancel only after expansion (the
#: operation counts of a 50-link chain in README.md, "Notes on the solvers").
SPLIT_POINT_MASSES = True


def _kinetic_energy(model: Model, eng: _Engine, split: bool = False):
    """T, and (with ``split``) the part of T differentiated symbolically plus the point masses
    (mass, position, velocity) kept out of it (see SPLIT_POINT_MASSES): (T, T_rest, masses)."""
    T = se.Integer(0)
    rest = se.Integer(0)
    masses = []
    params = {se.Symbol(s.name) for s in model.params}
    for body in model.bodies:
        m = to_se(body.mass, f"mass of {body.name!r}")
        x = eng.vec(body.point.position, f"position of {body.name!r}")
        v = [eng.ddt(c) for c in x]
        vv = sum((c * c for c in v), se.Integer(0))
        # Expanding pays for bodies moved by few coordinates; for long chains it would square
        # the number of terms (the n-link pendulum's last bob depends on all n angles).
        few = len(set(eng.q) & set().union(*(c.free_symbols for c in x))) <= PYTHAGORAS_MAX_COORDS
        term = m / 2 * (pythagoras(vv) if few else vv)
        T = T + term
        if split and not few and m.free_symbols <= params:
            masses.append((m, x, v))
        else:
            rest = rest + term
        if isinstance(body, PlanarBody):
            w = eng.ddt(to_se(body.angle, f"angle of {body.name!r}"))
            term = to_se(body.inertia, f"inertia of {body.name!r}") / 2 * w * w
            T, rest = T + term, rest + term
        elif isinstance(body, RigidBody):
            R = se.Matrix(3, 3, [to_se(c, f"orientation of {body.name!r}") for c in body.orientation])
            Rdot = R.applyfunc(eng.ddt)
            W = R.T * Rdot  # [w]x in body axes
            w = se.Matrix([W[2, 1], W[0, 2], W[1, 0]])
            I = se.Matrix(3, 3, [to_se(c, f"inertia of {body.name!r}") for c in body.inertia])
            term = (w.T * I * w)[0, 0] / 2
            T, rest = T + term, rest + term
        elif not isinstance(body, Particle):  # pragma: no cover - guarded by Model
            raise ModelError(f"unknown body type {type(body).__name__}")
    for label, Tk in model.kinetic_terms:
        term = to_se(Tk, f"kinetic energy {label!r}")
        T, rest = T + term, rest + term
    return T, rest, masses


def _point_masses(masses: list, eng: _Engine):
    """The contributions of point masses (mass m, position x(q, t), velocity v = x') to the
    momenta, M and F (eq. 3.16), from the velocity Jacobian J = dx/dq alone: with
    v = J q' + dx/dt, d/dt dT/dq' - dT/dq = m J^T (J q'' + a), a = v' at q'' = 0, so
    p += m J^T v, M += m J^T J, F -= m J^T a. Returns (p, M, F): lists of terms per coordinate
    (p, F) and per entry (i, j) of M (the terms of dp_i/dq_j', j >= i). Terms m J_ci of equal
    value are gathered (m J_ci (a_1 + a_2 + ...)), which on a chain sums the accelerations of
    every outer link into one Add."""
    n = len(eng.q)
    index = {q: i for i, q in enumerate(eng.q)}
    speed = {v: i for i, v in enumerate(eng.qd)}
    pg = [dict() for _ in range(n)]
    fg = [dict() for _ in range(n)]
    for m, x, v in masses:
        for xc, vc in zip(x, v):
            J = sorted((index[q], d) for q, d in gradient(xc, eng.q).items())
            if not J:
                continue
            dv = gradient(vc, eng.q)
            a = se.Add(se.diff(vc, eng.t), *(dv[q] * eng.qd[index[q]] for q in sorted(dv, key=index.get)))
            for i, Ji in J:
                coef = m * Ji
                pg[i].setdefault(coef, []).append(vc)
                fg[i].setdefault(coef, []).append(a)
    p, M = [], {}
    for i, g in enumerate(pg):
        p.append([])
        for c, vs in g.items():
            total = se.Add(*vs)
            p[-1].append(c * total)
            for qd, d in gradient(total, eng.qd).items():  # d p_i / d q_j' = c d total / d q_j'
                if speed[qd] >= i:
                    M.setdefault((i, speed[qd]), []).append(c * d)
    F = [[-c * se.Add(*acc) for c, acc in g.items()] for g in fg]
    return p, M, F


def _potential_energy(model: Model, eng: _Engine):
    V = se.Integer(0)
    for label, Vk in model.potential_terms:
        V = V + to_se(Vk, f"potential {label!r}")
    if model.gravity_spec is not None:
        g, up = model.gravity_spec
        g = to_se(g, "gravity")
        for body in model.bodies:
            x = eng.vec(body.point.position, f"position of {body.name!r}")
            if up is None:
                height = x[-1]
            else:
                if len(up) != len(x):
                    raise ModelError(f"gravity 'up' has {len(up)} components, {body.name!r} has {len(x)}")
                u = eng.vec(up, "gravity up")
                height = sum((a * b for a, b in zip(x, u)), se.Integer(0))
            V = V + to_se(body.mass, f"mass of {body.name!r}") * g * height
    return V


def _generalized_forces(model: Model, eng: _Engine):
    Q = [se.Integer(0)] * model.n
    for label, pt, F in model.cartesian_forces:
        x = eng.vec(pt.position, f"position of {pt.name!r}")
        f = eng.vec(F, label)
        for i, q in enumerate(eng.q):  # eq. 2.6
            Q[i] = Q[i] + sum((fk * se.diff(xk, q) for fk, xk in zip(f, x)), se.Integer(0))
    for label, i, Qs in model.generalized_forces:
        Q[i] = Q[i] + to_se(Qs, label)
    return Q


def derive(model: Model, check: bool = True) -> EquationsOfMotion:
    """Derive Lagrange's equations (eq. 3.16) of ``model`` as M q'' = F.

    ``check=False`` skips the test for an identically singular mass matrix (for callers that
    only want the energies and momenta, e.g. to explain why a reduction is impossible).

    Reports the stage "derive" (:mod:`lagcodegen.progress`), one step per coordinate.

    A ``sympy.physics.mechanics.System`` or ``KanesMethod`` is taken through
    :func:`lagcodegen.model.mechanics.as_model`.
    """
    model = require_model(as_model(model, unset=1.0), "derive")
    with progress.stage("derive", total=max(model.n, model.nv), unit="coordinates") as stage:
        return _derive(model, check, stage)


def _lagrangian_terms(model: Model) -> bool:
    """True if the model has elements Lagrange's equations are formed from (not only equations
    given directly, :meth:`Model.equations_of_motion`)."""
    return bool(model.bodies or model.kinetic_terms or model.potential_terms or model.generalized_potential_terms
                or model.dissipation_terms or model.cartesian_forces or model.generalized_forces or model.links)


def _derive(model: Model, check: bool, stage) -> EquationsOfMotion:
    start = time.perf_counter()
    model.validate()
    if model.given_equations and not _lagrangian_terms(model):
        return _derive_given(model, check, stage, start)
    eng = _Engine(model)
    T, T_rest, masses = _kinetic_energy(model, eng, split=SPLIT_POINT_MASSES)
    V = _potential_energy(model, eng)
    D = se.Integer(0)
    for label, Dk in model.dissipation_terms:
        D = D + to_se(Dk, f"dissipation {label!r}")
    Q = _generalized_forces(model, eng)
    # Generalized potentials U(q, q', t) (eq. 3.4): the velocity-free part U(q, 0, t) counts as
    # potential energy (e phi for a charge), the rest (-e v . A) only enters L.
    U = se.Integer(0)
    for label, Uk in model.generalized_potential_terms:
        U = U + to_se(Uk, f"generalized potential {label!r}")
    U0 = U.xreplace({v: se.Integer(0) for v in eng.qd}) if U != 0 else U
    V = V + U0
    Uv = U - U0
    L = T - V - Uv
    n = model.n

    used = L.free_symbols | D.free_symbols
    for Qi in Q:
        used |= Qi.free_symbols
    tree = TreeDynamics(model, eng.q, eng.v) if model.links else None
    if tree is not None:
        used |= {eng.q[nd.coord] for nd in tree.nodes if nd.coord < len(eng.q)}
        used |= {eng.q[c] for c, _, _, _ in tree.mimics}
        if model.general:
            used |= {se.Symbol(c.name) for lk in model.links if lk.joint.quaternion for c in lk.coordinates}
    for q, qd in zip(eng.q, eng.qd):
        if q not in used and qd not in used and not model.given_equations:
            raise ModelError(f"coordinate {q.name!r} appears nowhere in T, V, D or the forces")

    # L without the point masses of _point_masses (differentiated symbolically), and their terms.
    L_rest = T_rest - V - Uv if masses else L
    p_mass, M_mass, F_mass = _point_masses(masses, eng)
    # One coordinate at a time (momentum, row of M, entry of F): a loop point for progress.
    p, F = [], []
    M = [[None] * n for _ in range(n)]
    for i in range(n):
        pi = se.diff(L_rest, eng.qd[i])
        free = pi.free_symbols
        Fi = se.diff(L_rest, eng.q[i]) - se.diff(pi, eng.t) - se.diff(D, eng.qd[i]) + Q[i]
        for j in range(n):
            if eng.q[j] in free:
                Fi = Fi - se.diff(pi, eng.q[j]) * eng.qd[j]
        for j in range(i, n):
            d = se.diff(pi, eng.qd[j]) if eng.qd[j] in free else se.Integer(0)
            M[i][j] = M[j][i] = se.Add(d, *M_mass[i, j]) if (i, j) in M_mass else d
        if masses:
            pi = se.Add(pi, *p_mass[i])
            Fi = se.Add(Fi, *F_mass[i])
        p.append(pi)  # eq. 2.3
        F.append(Fi)
        stage.advance()
    check_rows = check and tree is None and not model.given_equations
    if check_rows and all(M[i][j] == 0 for i in range(n) for j in range(n)):
        raise DerivationError("the mass matrix is identically zero: T does not depend on the velocities")
    for i in range(n if check_rows else 0):
        if M[i][i] == 0 and all(M[i][j] == 0 for j in range(n)):
            raise DerivationError(
                f"row {i} of the mass matrix is identically zero: no kinetic energy in velocity "
                f"{model.speeds[i].name!r}")
    h = sum((v * pi for v, pi in zip(eng.qd, p)), se.Integer(0)) - L  # eq. 3.5
    dhdt = -se.diff(L, eng.t) + sum((v * (Qi - se.diff(D, v)) for v, Qi in zip(eng.qd, Q)), se.Integer(0))
    if model.general:
        M, F, p, Q, (T, V, h, D, dhdt, Uv) = _project(model, eng, M, F, p, Q, (T, V, h, D, dhdt, Uv))
        n = model.nv
    symmetric, unknown = True, {}
    if model.given_equations:  # before the tree's terms: the tree's kernels add them as closed-form terms
        T, V, symmetric, unknown = _add_given(model, eng, M, F, p, T, V)
        if tree is not None and not symmetric:
            raise ModelError(f"model {model.name!r}: equations given directly whose mass matrix is not symmetric "
                             "cannot be added to a rigid-body tree's (Model.link)")
    if tree is not None:
        T, V, h = _add_tree(tree, eng, M, F, p, T, V, h)
        for i in range(n if check else 0):
            if M[i][i] == 0 and all(M[i][j] == 0 for j in range(n)):
                raise DerivationError(
                    f"row {i} of the mass matrix is identically zero: no kinetic energy in velocity "
                    f"{model.v[i].name!r} (a joint whose links beyond it have no mass or inertia)")
    eom = EquationsOfMotion(model=model, T_se=T, V_se=V, D_se=D, Q_se=Q, p_se=p, M_se=M, F_se=F,
                            h_se=h, dhdt_se=dhdt, Uv_se=Uv, derivation_seconds=time.perf_counter() - start,
                            tree=tree, symmetric=symmetric, unknown=unknown)
    eom._cache["positions"] = {pt.name: eng.vec(pt.position, f"position of {pt.name!r}")
                               for pt in model.points.values()}
    return eom


def _add_given(model: Model, eng: _Engine, M: list, F: list, p: list, T, V):
    """Add the equations given directly (:meth:`Model.equations_of_motion`) in place to M, F and the
    momenta (dT/dv of their kinetic energies); return (T, V with their energies, whether M is
    symmetric, :attr:`EquationsOfMotion.unknown`)."""
    n = model.nv
    symmetric = True
    unknown: dict = {}
    labels = ", ".join(repr(eq.label) for eq in model.given_equations)
    for eq in model.given_equations:
        what = f"equations {eq.label!r}"
        for i in range(n):
            for j in range(n):
                e = to_se(eq.M[i, j], f"mass matrix of {what}")
                if e != 0:
                    M[i][j] = e if M[i][j] == 0 else se.Add(M[i][j], e)
            e = to_se(eq.F[i], f"forces of {what}")
            if e != 0:
                F[i] = e if F[i] == 0 else se.Add(F[i], e)
        symmetric = symmetric and eq.symmetric
        why = dict(eq.missing)
        if eq.kinetic_energy is None:
            unknown.setdefault("T", f"the kinetic energy of model {model.name!r} is not known: "
                                    + (why["T"] if "T" in why else f"its equations {eq.label!r} were given without it "
                                       "(Model.equations_of_motion(..., kinetic_energy=T))"))
        else:
            Tg = to_se(eq.kinetic_energy, f"kinetic energy of {what}")
            T = se.Add(T, Tg)
            for i, v in enumerate(eng.v):
                d = se.diff(Tg, v)
                if d != 0:
                    p[i] = se.Add(p[i], d)
        if eq.potential_energy is None:
            unknown.setdefault("V", f"the potential energy of model {model.name!r} is not known: "
                                    + (why["V"] if "V" in why else f"its equations {eq.label!r} were given without "
                                       "it (Model.equations_of_motion(..., potential_energy=V))"))
        else:
            V = se.Add(V, to_se(eq.potential_energy, f"potential energy of {what}"))
    if "T" in unknown:
        unknown["momenta"] = unknown["T"].replace("kinetic energy", "momenta (dT/dv)", 1)
    for key, what in (("D", "dissipation function"), ("Q", "generalized forces"), ("L", "Lagrangian"),
                      ("h", "Jacobi energy function"), ("dhdt", "rate of the Jacobi energy function")):
        unknown[key] = (f"the {what} of model {model.name!r} is not known: equations given directly ({labels}) "
                        "determine only the motion and, when given, the energies T and V")
    return T, V, symmetric, unknown


def _derive_given(model: Model, check: bool, stage, start: float) -> EquationsOfMotion:
    """The equations of a model that has equations given directly and nothing else."""
    eng = _Engine(model)
    n = model.nv
    zero = se.Integer(0)
    M = [[zero] * n for _ in range(n)]
    F, p = [zero] * n, [zero] * n
    T, V, symmetric, unknown = _add_given(model, eng, M, F, p, zero, zero)
    for i in range(n):
        if check and all(M[i][j] == 0 for j in range(n)):
            raise DerivationError(f"row {i} of the mass matrix is identically zero (the equation of speed "
                                  f"{model.v[i].name!r})")
        stage.advance()
    eom = EquationsOfMotion(model=model, T_se=T, V_se=V, D_se=zero, Q_se=[zero] * n, p_se=p, M_se=M, F_se=F,
                            h_se=zero, dhdt_se=zero, Uv_se=zero, derivation_seconds=time.perf_counter() - start,
                            symmetric=symmetric, unknown=unknown)
    eom._cache["positions"] = {pt.name: eng.vec(pt.position, f"position of {pt.name!r}")
                               for pt in model.points.values()}
    return eom


def _project(model: Model, eng: _Engine, M: list, F: list, p: list, Q: list, scalars: tuple):
    """Lagrange's equations in q (M_q q'' = F_q, eq. 3.16) carried to generalized speeds v by
    the kinematic equations q' = k(q, v, t) = G v + g: with q'' = G v' + (dk/dq) k + dk/dt,
    premultiplied by G^T (Maggi's / Kane's form; the design brief's generalized speeds):
    M_v = G^T M_q G, F_v = G^T (F_q - M_q ((dk/dq) k + dk/dt)), p_v = G^T p_q, Q_v = G^T Q,
    every q' replaced by k. Returns (M_v, F_v, p_v, Q_v, scalars with q' replaced)."""
    nq, nv = model.nq, model.nv
    k = [to_se(e, f"kinematic equation of {q.name!r}") for e, q in zip(model.kinematics, model.coords)]
    sub = dict(zip(eng.qd, k))
    G = [[se.diff(k[i], eng.v[a]) for a in range(nv)] for i in range(nq)]
    for i, q in enumerate(model.coords):
        for a in range(nv):
            if any(x in G[i][a].free_symbols for x in eng.v):
                raise ModelError(f"kinematic equation of {q.name!r} is not linear in the generalized speeds: "
                                 f"{excerpt(model.kinematics[i])}")
    Mq = [[se.sympify(M[i][j]).xreplace(sub) for j in range(nq)] for i in range(nq)]
    # The structural nonzeros, each entry compared with 0 once (a tree's closed-form M is mostly
    # zeros: Talos's 51 x 50 products took 0.4 s of comparisons), the sums over them in the same order.
    m_rows = [[j for j in range(nq) if Mq[i][j] != 0] for i in range(nq)]
    g_nz = [[G[i][a] != 0 for a in range(nv)] for i in range(nq)]
    bias = [se.Add(se.diff(k[i], eng.t), *(se.diff(k[i], eng.q[m]) * k[m] for m in range(nq))) for i in range(nq)]
    Fq = [se.sympify(F[i]).xreplace(sub) - se.Add(*(Mq[i][j] * bias[j] for j in m_rows[i])) for i in range(nq)]
    pq = [se.sympify(x).xreplace(sub) for x in p]
    Qq = [se.sympify(x).xreplace(sub) for x in Q]

    def left(vec):  # G^T vec
        return [se.Add(*(G[i][a] * vec[i] for i in range(nq) if g_nz[i][a] and vec[i] != 0)) for a in range(nv)]
    MG = [[se.Add(*(Mq[i][j] * G[j][b] for j in m_rows[i] if g_nz[j][b])) for b in range(nv)] for i in range(nq)]
    mg_nz = [[bool(m_rows[i]) and MG[i][b] != 0 for b in range(nv)] for i in range(nq)]
    Mv = [[se.Add(*(G[i][a] * MG[i][b] for i in range(nq) if g_nz[i][a] and mg_nz[i][b])) for b in range(nv)]
          for a in range(nv)]
    return Mv, left(Fq), left(pq), left(Qq), tuple(se.sympify(x).xreplace(sub) for x in scalars)


def _add_tree(tree: TreeDynamics, eng: _Engine, M: list, F: list, p: list, T, V, h):
    """Add the links' terms (:mod:`lagcodegen.model.treedynamics`) in place to M (composite rigid
    bodies), F (minus the recursive Newton-Euler bias at q'' = 0, gravity included) and the
    momenta p = M q' (eq. 2.3); return T, V and h with the links' T and V (h = T + V for them:
    their T is homogeneous quadratic in q' and nothing of theirs depends on t, eq. 3.5)."""
    n = len(M)
    tree.rest = ([list(row) for row in M], list(F))  # the closed-form terms, for the kernels
    Mt = tree.mass_matrix()
    bias = tree.rnea()
    for i in range(n):
        for j in range(i, n):
            if Mt[i][j] != 0:
                M[i][j] = M[j][i] = Mt[i][j] if M[i][j] == 0 else se.Add(M[i][j], Mt[i][j])
        if bias[i] != 0:
            F[i] = se.Add(F[i], -bias[i])
        terms = [Mt[i][j] * eng.v[j] for j in range(n) if Mt[i][j] != 0]
        if terms:
            p[i] = se.Add(p[i], *terms)
    Tt, Vt = tree.kinetic_energy(), tree.potential_energy()
    return se.Add(T, Tt), se.Add(V, Vt), se.Add(h, Tt, Vt)
