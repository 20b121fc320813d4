"""The inverse-dynamics regressor of a rigid-body tree: tau = Y(q, q', q'') pi, linear in the
bodies' dynamic parameters pi (Atkeson, An and Hollerbach 1986; Pinocchio's
``computeJointTorqueRegressor``).

The bodies are the tree's moving links: the link carried by each joint (links on fixed joints
are merged into it, as the derivation merges them and Pinocchio's URDF reader does), in the
model's order of links (:attr:`Model.links`); a spherical or free joint's massless intermediate
frames carry none. Each body brings 10 columns, Pinocchio's order
(:data:`lagcodegen.model.bodies.DYNAMIC_PARAMETERS`): m, m c_x, m c_y, m c_z, then the inertia
about the body frame's origin I_xx, I_xy, I_yy, I_xz, I_yz, I_zz.

By recursive Newton-Euler: the velocities and accelerations (gravity as the base's acceleration)
forward, then per body and per parameter the force of a unit inertia f = I a + v x* I v (linear
in the inertia) carried from the body to each ancestor joint and projected on its axis. The
tree's share of tau is Y pi; the model's other elements (joint damping, springs, particles) are
not in Y.
"""

from __future__ import annotations

import symengine as se

from . import treedynamics as td
from .treedynamics import ONE, ZERO, TreeDynamics, cross, dot, vadd


def _unit_inertias() -> list:
    """The 10 inertias (m, h, I_o) with one dynamic parameter 1, the others 0."""
    out = []
    for k in range(10):
        m, h, Io = ZERO, [ZERO] * 3, [[ZERO] * 3 for _ in range(3)]
        if k == 0:
            m = ONE
        elif k < 4:
            h[k - 1] = ONE
        else:
            i, j = [(0, 0), (0, 1), (1, 1), (0, 2), (1, 2), (2, 2)][k - 4]
            Io[i][j] = Io[j][i] = ONE
        out.append((m, h, Io))
    return out


def body_nodes(model) -> list[tuple[int, str]]:
    """(node index, link name) of the tree's bodies: each link on a moving joint, at the last
    node of its joint (the nodes of :class:`TreeDynamics`, appended link by link)."""
    out, count = [], 0
    for link in model.links:
        steps = len(link.speeds) if link.joint.quaternion else len(list(link.joint.steps(link.coordinates)))
        count += steps
        if steps:
            out.append((count - 1, link.name))
    return out


def accelerations(tree: TreeDynamics, qdd: list) -> list:
    """(alpha_i, a_i) of every node in its coordinates: the spatial accelerations with gravity
    as the base's acceleration (the forward pass of :meth:`TreeDynamics.rnea`)."""
    vel = tree.velocities()
    a0 = tree.gravity_acceleration()
    acc = []
    for k, nd in enumerate(tree.nodes):
        w, v = vel[k]
        if nd.parent < 0:
            al, a = [ZERO] * 3, nd.down(a0)
        else:
            alp, ap = acc[nd.parent]
            al, a = nd.down(alp), nd.down(vadd(ap, cross(alp, tree.origin(k))))
        Sq = [td.mul(tree.qd[nd.speed], x) for x in nd.axis]
        Sa = [td.mul(qdd[nd.speed], x) for x in nd.axis]
        if nd.group is not None:  # a quaternion joint's nodes: v_in x S v_J (TreeDynamics.rnea)
            w, v = tree._incoming[nd.group]
        if nd.kind == "R":
            al, a = vadd(al, cross(w, Sq), Sa), vadd(a, cross(v, Sq))
        else:
            a = vadd(a, cross(w, Sq), Sa)
        acc.append((al, a))
    return acc


def regressor(tree: TreeDynamics, qdd: list) -> tuple[list, list]:
    """(Y as n rows of 10 nb entries, the bodies' link names) of ``tree`` at accelerations ``qdd``."""
    bodies = body_nodes(tree.model)
    if tree.mimics:  # the mimic joints' pseudo-speeds: gain times their leader's
        qdd = list(qdd) + [td.mul(se.Float(g), qdd[s]) for _, s, g, _ in tree.mimics]
    vel, acc = tree.velocities(), accelerations(tree, qdd)
    units = _unit_inertias()
    Y = [[ZERO] * (10 * len(bodies)) for _ in range(tree.n)]
    for b, (k, _) in enumerate(bodies):
        w, v = vel[k]
        al, a = acc[k]
        for c, unit in enumerate(units):
            n, f = tree.apply_inertia(unit, al, a)
            nm, lm = tree.apply_inertia(unit, w, v)
            n, f = vadd(n, cross(w, nm), cross(v, lm)), vadd(f, cross(w, lm))
            j = k
            while True:
                nd = tree.nodes[j]
                Y[nd.speed][10 * b + c] = dot(nd.axis, n if nd.kind == "R" else f)
                if nd.parent < 0:
                    break
                f2 = nd.up(f)
                n, f = vadd(nd.up(n), cross(tree.origin(j), f2)), f2
                j = nd.parent
    if tree.mimics:  # rows folded into the leaders' (G^T Y)
        cols = [tree._fold([Y[i][c] for i in range(tree.n)]) for c in range(10 * len(bodies))]
        Y = [[cols[c][i] for c in range(len(cols))] for i in range(tree.n_speeds)]
    return Y, [name for _, name in bodies]


def body_parameters(tree: TreeDynamics) -> list:
    """pi: the 10 dynamic parameters of each body (:func:`body_nodes`) in its frame, as the tree
    holds them (expressions in the model's parameters; zeros for a massless body)."""
    out = []
    for k, _ in body_nodes(tree.model):
        inertia = tree.nodes[k].inertia
        if inertia is None:
            out += [ZERO] * 10
            continue
        m, h, Io = inertia
        out += [m, *h, Io[0][0], Io[0][1], Io[1][1], Io[0][2], Io[1][2], Io[2][2]]
    return [se.sympify(e) for e in out]


def recorded_regressor(model, q: list, qd: list, qdd: list) -> tuple[list, list, list, list]:
    """Y(q, q', q'') as a straight-line program (:func:`lagcodegen.model.treedynamics.recorded`):
    (definitions, Y rows, pi, body names); pi in the model's parameters, outside the program."""
    pi = body_parameters(TreeDynamics(model, q, qd))
    td._RECORD = []
    try:
        Y, names = regressor(TreeDynamics(model, q, qd), qdd)
        return td._live(td._RECORD, [e for row in Y for e in row]), Y, pi, names
    finally:
        td._RECORD = None
