"""Energy bookkeeping of derived equations: the split of T and Jacobi's energy function h.

* :func:`kinetic_split` writes T = T2 + T1 + T0 (eq. 2.2) with its coefficients alpha, beta,
  gamma; :func:`is_natural` applies the remark after eq. 2.2 to a model (no body's position
  or orientation depends explicitly on t).
* :func:`jacobi_h` is h = sum_i q_i' dL/dq_i' - L (eq. 3.5); :func:`check_jacobi` verifies,
  symbolically, dh/dt = -dL/dt along Lagrange's equations (eq. 3.6, with the power of the
  non-potential forces of eq. 3.16 added when there are any) and the forms h = T2 - T0 + V
  (eq. 3.7) and h = T + V (natural systems).

Everything here is sympy and meant for checks and explanations on small systems; the
generated code never needs it (the ``jacobi_h`` and ``dh_dt`` outputs come from
:mod:`lagcodegen.derivation`).
"""

from __future__ import annotations

import cmath
from dataclasses import dataclass
from itertools import combinations_with_replacement
from typing import Sequence

import symengine as se
import sympy as sp

from ..derivation import EquationsOfMotion
from ..errors import DerivationError
from ..model.model import Model, PlanarBody, RigidBody
from .forces import total_time_derivative


def _nonzero_somewhere(expr: sp.Expr) -> bool:
    """True if ``expr`` is clearly nonzero at a fixed sample point (30-digit evaluation).

    A proof of non-vanishing, so :func:`is_zero` can skip the slow simplifications; False
    proves nothing (the point may be a root, or the value not a finite number).
    """
    point = {s: sp.Rational(37 + 13 * k, 61) for k, s in enumerate(sorted(expr.free_symbols, key=str))}
    try:
        value = complex(expr.evalf(30, subs=point))
    except (TypeError, ValueError):
        return False
    return cmath.isfinite(value) and abs(value) > 1e-15


def is_zero(expr) -> bool:
    """True if ``expr`` simplifies to 0: polynomial expansion first (symengine, then sympy),
    then rational normalization, then sympy's simplify; an expression clearly nonzero at a
    sample point is rejected before the slow steps. A matrix is zero when every entry is."""
    if isinstance(expr, sp.MatrixBase):
        return all(is_zero(e) for e in expr)
    expr = sp.sympify(expr)
    if expr == 0:
        return True
    try:
        if se.expand(se.sympify(expr)) == 0:
            return True
    except Exception:  # symengine lacks some sympy constructs: fall through to sympy
        pass
    if _nonzero_somewhere(expr):
        return False
    expanded = sp.expand(expr)
    if expanded == 0 or sp.cancel(sp.together(expanded)) == 0:
        return True
    return sp.simplify(sp.expand_trig(sp.simplify(expanded))) == 0


@dataclass(frozen=True)
class KineticSplit:
    """T = T2 + T1 + T0 (eq. 2.2).

    ``alpha`` (n x n, symmetric) holds alpha_ij = d^2 T / dq_i' dq_j', ``beta`` (n x 1) the
    coefficients beta_i = dT/dq_i' at q' = 0, ``gamma`` = T at q' = 0; all functions of (q, t).
    ``natural`` is True when T1 and T0 vanish identically.
    """

    T2: sp.Expr
    T1: sp.Expr
    T0: sp.Expr
    alpha: sp.Matrix
    beta: sp.Matrix
    gamma: sp.Expr
    natural: bool

    @property
    def T(self) -> sp.Expr:
        """T2 + T1 + T0."""
        return self.T2 + self.T1 + self.T0


def split_quadratic(T, qdot: Sequence[sp.Symbol]) -> KineticSplit:
    """Split an expression at most quadratic in ``qdot`` as in eq. 2.2.

    Raises :class:`DerivationError` if some third derivative d^3 T / dq_i' dq_j' dq_k' does not
    vanish (T is then not of the form of eq. 2.2).
    """
    T = sp.expand(sp.sympify(T))
    qdot = list(qdot)
    at_rest = {v: 0 for v in qdot}
    for i, j, k in combinations_with_replacement(range(len(qdot)), 3):
        d3 = sp.diff(T, qdot[i], qdot[j], qdot[k])
        if d3 != 0 and not is_zero(d3):
            raise DerivationError(
                f"T is not quadratic in the velocities (eq. 2.2): d^3T/d{qdot[i]} d{qdot[j]} d{qdot[k]} = {d3}")
    n = len(qdot)
    alpha = sp.Matrix(n, n, lambda i, j: sp.simplify(sp.diff(T, qdot[i], qdot[j]).subs(at_rest)))
    beta = sp.Matrix([sp.simplify(sp.diff(T, v).subs(at_rest)) for v in qdot])
    gamma = sp.simplify(T.subs(at_rest))
    v = sp.Matrix(qdot)
    T2 = sp.expand((v.T * alpha * v)[0, 0] / 2)
    T1 = sp.expand((beta.T * v)[0, 0])
    natural = all(is_zero(b) for b in beta) and is_zero(gamma)
    return KineticSplit(T2=T2, T1=T1, T0=gamma, alpha=alpha, beta=beta, gamma=gamma, natural=natural)


def kinetic_split(eom: EquationsOfMotion) -> KineticSplit:
    """T = T2 + T1 + T0 of the derived kinetic energy (eq. 2.2); see :func:`split_quadratic`."""
    return split_quadratic(eom.T, eom.qd)


def is_natural(model: Model) -> bool:
    """The remark after eq. 2.2: the map q -> x has no explicit t (dx/dt = 0 at fixed q).

    Checked on what carries kinetic energy: every body's position, and the angle (planar
    bodies) or orientation (rigid bodies); for the links of a rigid-body tree (:meth:`Model.link`)
    their placements and inertial data (the joints move with q alone). Massless points (spring
    anchors, force points) do not enter T and are not looked at. Kinetic energy given directly
    has no map x(q, t): it counts as natural when its own T1 and T0 vanish.
    """
    t = model.t
    for link in model.links:
        data = [link.mass, *link.com, *link.inertia, *link.origin.rotation, *link.origin.translation]
        if any(sp.sympify(e).has(t) for e in data):
            return False
    for body in model.bodies:
        exprs = list(body.point.position)
        if isinstance(body, PlanarBody):
            exprs.append(body.angle)
        elif isinstance(body, RigidBody):
            exprs.extend(body.orientation)
        if any(not is_zero(sp.diff(e, t)) for e in exprs):
            return False
    return all(split_quadratic(T, model.speeds).natural for _, T in model.kinetic_terms)


def jacobi_h(eom: EquationsOfMotion) -> sp.Expr:
    """Jacobi's energy function h = sum_i q_i' dL/dq_i' - L (eq. 3.5), as sympy."""
    return eom.h


@dataclass(frozen=True)
class JacobiCheck:
    """Symbolic facts about Jacobi's h of one system (see :func:`check_jacobi`).

    * ``h``: eq. 3.5;
    * ``dhdt``: dh/dt along Lagrange's equations, q'' = M^{-1} F substituted (unsimplified);
    * ``expected``: -dL/dt + sum_i q_i' (Q_i - dD/dq_i') (eq. 3.6 plus the power of the forces
      of eq. 3.16; just -dL/dt for a Lagrangian system);
    * ``lagrangian``: D = 0 and Q = 0 (only T and a (generalized) potential);
    * ``explicit_time``: L depends explicitly on t;
    * ``holds``: dhdt - expected simplifies to 0 (eq. 3.6);
    * ``matches_derivation``: the derivation's dh/dt (the ``dh_dt`` output) equals ``expected``;
    * ``conserved``: ``expected`` is identically 0 (for a Lagrangian system: L has no explicit t);
    * ``equals_T2_minus_T0_plus_V``: h - (T2 - T0 + V) simplifies to 0 (eq. 3.7);
    * ``equals_T_plus_V``: h - (T + V) simplifies to 0 (natural systems).
    """

    h: sp.Expr
    dhdt: sp.Expr
    expected: sp.Expr
    lagrangian: bool
    explicit_time: bool
    holds: bool
    matches_derivation: bool
    conserved: bool
    equals_T2_minus_T0_plus_V: bool
    equals_T_plus_V: bool


def check_jacobi(eom: EquationsOfMotion) -> JacobiCheck:
    """Verify eqs. 3.5-3.7 symbolically for the derived equations ``eom``.

    dh/dt is formed by the chain rule, sum_i (dh/dq_i q_i' + dh/dq_i' q_i'') + dh/dt, with
    q'' = M^{-1} F = adj(M) F / det(M) (eq. 3.16). Eq. 3.6 is then checked on
    det(M) (dh/dt - expected), a polynomial in the entries of M and F that expands to 0 when
    the identity holds (det M is nonzero wherever the equations of motion are solvable).
    Meant for small systems: the adjugate grows quickly with n.

    V in eq. 3.7 is the derivation's V (generalized potentials included), so the eq. 3.7 form
    holds only for velocity-independent potentials.
    """
    h, L, t = eom.h, eom.L, eom.t
    M, F = eom.M, eom.F
    det = M.det(method="berkowitz")
    adjF = M.adjugate(method="berkowitz") * F
    dh_dqdot = sp.Matrix([sp.diff(h, v) for v in eom.qd])
    explicit_part = total_time_derivative(h, eom.q, eom.qd, t, [0] * eom.n)  # dh/dq . q' + dh/dt
    dhdt = explicit_part + (dh_dqdot.T * adjF)[0, 0] / det
    power = sum((v * (Qi - sp.diff(eom.D, v)) for v, Qi in zip(eom.qd, eom.Q)), sp.Integer(0))
    dLdt = sp.diff(L, t)
    expected = -dLdt + power
    split = kinetic_split(eom)
    return JacobiCheck(
        h=h,
        dhdt=dhdt,
        expected=expected,
        lagrangian=is_zero(eom.D) and all(is_zero(Qi) for Qi in eom.Q),
        explicit_time=not is_zero(dLdt),
        holds=is_zero(det * (explicit_part - expected) + (dh_dqdot.T * adjF)[0, 0]),
        matches_derivation=is_zero(eom.dhdt - expected),
        conserved=is_zero(expected),
        equals_T2_minus_T0_plus_V=is_zero(h - (split.T2 - split.T0 + eom.V)),
        equals_T_plus_V=is_zero(h - (eom.T + eom.V)),
    )
