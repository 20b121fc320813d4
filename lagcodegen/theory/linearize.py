"""Linearization of M(q, q', t) q'' = F(q, q', t) about a state (small oscillations).

About a reference state (q0, q0', t) with accelerations a0 (M a0 = F; a0 = 0 at
equilibria and at the steady motions of a Routhian-reduced system, eq. 3.13), a
perturbation dq obeys, to first order,

    M dq'' + C dq' + K dq = 0,
    M = M(q0),  K = -(dF/dq - d(M a0)/dq),  C = -(dF/dq' - d(M a0)/dq'),

(eq. 3.16 differentiated; the d(M a0) terms vanish where a0 = 0), i.e. y' = A y with

    A = [[0, I], [-M^-1 K, -M^-1 C]].

M is never inverted symbolically: the numeric A uses ``numpy.linalg.solve``. For C = 0 and
symmetric K the natural frequencies are the square roots of the generalized eigenvalues of
(K, M), and the state is linearly stable iff they are all real (every w^2 > 0). The same
function serves the full equations and a Routhian-reduced system (pass the integrals C_i in
``params``), and a :class:`~lagcodegen.theory.constraints.ConstrainedSystem`, linearized about
a steady motion and reduced to independent coordinates and speeds
(:mod:`lagcodegen.theory.linearize_constrained`).
"""

from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np
import symengine as se
import sympy as sp

from ..derivation import EquationsOfMotion, derive
from ..errors import ModelError
from ..model.model import Model
from ..util import check_finite
from .constraints import ConstrainedSystem
from .linearize_constrained import linearize_constrained
from .linearize_speeds import linearize_speeds
from .linearization import Linearization, exact_number, values_by_name

__all__ = ["Linearization", "exact_number", "linearize"]


# ---------------------------------------------------------------------- helpers
def _parametervalues_by_name(eom: EquationsOfMotion, params: Mapping[str, float] | None, numeric: bool) -> dict:
    names = {s.name: v for s, v in eom.model.params.items()}
    for k in params or {}:
        if k not in names:
            raise ModelError(f"{k!r} is not a parameter of model {eom.model.name!r} "
                             f"(parameters: {', '.join(names) or 'none'})")
    if not numeric:
        return dict(params or {})
    out = {k: float(v) for k, v in names.items()}
    out.update({k: check_finite(v, f"parameter {k!r}") for k, v in (params or {}).items()})
    return out


def _jacobians(qs, vs, M, F, acc: list):
    """Symbolic K = -(dF/dq - d(M a)/dq) and C = -(dF/dq' - d(M a)/dq') with accelerations ``acc``."""
    n = len(qs)
    q = [se.Symbol(s.name) for s in qs]
    v = [se.Symbol(s.name) for s in vs]
    r = [F[i] - sum((M[i][k] * acc[k] for k in range(n)), se.Integer(0)) for i in range(n)]
    K = [[-se.diff(r[i], q[j]) for j in range(n)] for i in range(n)]
    C = [[-se.diff(r[i], v[j]) for j in range(n)] for i in range(n)]
    return K, C


def _linearize_speeds(eom: EquationsOfMotion, q0, v0, t, params, symbolic: bool, tol: float) -> Linearization:
    """Equations with generalized speeds, in tangent coordinates (:mod:`.linearize_speeds`)."""
    if symbolic:
        raise ModelError("linearize: symbolic=True takes models whose speeds are their coordinates' rates; this one "
                         "has generalized speeds (linearized numerically, in tangent coordinates)")
    return linearize_speeds(eom, q0=q0, v0=v0, t=t, values=_parametervalues_by_name(eom, params, numeric=True),
                            tol=tol)


def linearize(eom: EquationsOfMotion | ConstrainedSystem, q0=None, v0=None, t: float | None = None,
              params: Mapping[str, float] | None = None, symbolic: bool = False, *,
              independent: Sequence[str] | None = None, a0=None, tol: float = 1e-8) -> Linearization:
    """Linearize the equations of ``eom`` about (q0, v0, t) (see the module docstring).

    ``eom`` may also be a :class:`~lagcodegen.theory.constraints.ConstrainedSystem` (holonomic
    and nonholonomic rows, eq. 4.5): it is linearized about a steady motion and reduced to
    independent coordinates and speeds (see "Constrained systems" below).

    Parameters
    ----------
    q0, v0:
        The state: arrays in coordinate order or dicts by name. Numeric mode needs ``q0``;
        ``v0`` defaults to zero. Symbolic mode keeps every state symbol not given.
    t:
        Time of the state (numeric default 0; symbolic default: the symbol t).
    params:
        Parameter values by name (numeric: defaults from the model). For a Routhian-reduced
        system the integrals ``C_<q>`` are parameters.
    symbolic:
        Return sympy matrices M, C, K as functions of the state symbols, the parameters and
        the accelerations ``<q>_ddot`` at the state (no matrix is inverted).
        Unconstrained equations only.
    independent:
        Constrained systems: the names of the n - J independent speeds (their coordinates), or
        of the n - J_h independent coordinates. Default: chosen by pivoting on A at the state
        (QR with column pivoting, holonomic rows first).
    a0:
        Constrained systems: the accelerations of the steady motion (default 0).
    tol:
        Constrained systems: relative tolerance of the checks that the state satisfies the
        constraints and is a steady motion. Generalized speeds, about a moving state: the
        relative change of the linearized equations along the motion above which the state
        is refused as not steady.

    Generalized speeds
    ------------------
    Equations with q' = G(q, t) v + g(q, t) (quaternion joints, Kane's form) are linearized in
    tangent coordinates theta (dq = G(q0) theta, one per speed, named by the speeds): a
    quaternion is perturbed by rotations. About a moving state (v0 != 0) the tangent
    coordinates move with it and theta' = H theta + dv carries the kinematics' variation
    (H theta = theta x w0 for a body-frame angular velocity w0); the result then has ``H`` and
    ``G`` = I and ``A`` = [[H, I], [-M^-1 K, -M^-1 C]]. The coefficients are frozen at the
    state, so a moving state along which they change is refused by name (see
    :mod:`lagcodegen.theory.linearize_speeds`).

    Constrained systems
    -------------------
    For M q'' = F + A^T lambda, A q' + A0 = 0 (eq. 4.5; holonomic rows A = df/dq, eq. 4.2) at
    a steady motion (q0, v0) with accelerations a0, all on the constraints:

    1. lambda0 from A^T lambda0 = M a0 - F (least squares); its residual, and that of
       A a0 = gamma, must be below ``tol`` (relative to max(1, |F|, |M a0|)), or the state is
       refused (not a steady motion consistent with the constraints; the message gives the
       accelerations the constraints allow there);
    2. K = -(dF/dq - d(M a0)/dq + d(A^T lambda0)/dq), C = -dF/dq', S = d(A v0 + A0)/dq;
    3. dependent speeds (J) with A_dep regular and dependent coordinates (J_h of them) with
       A_h regular on them: dv = B0 du + D dq with B0 = [I; -A_dep^-1 A_ind] (A B0 = 0) and
       D = -A_dep^-1 S on the dependent rows (A dv + S dq = 0), dq = P dq_I with
       P = [I; -A_h,dep^-1 A_h,ind];
    4. multiplying M dv' + C dv + K dq = A^T dlambda (dv' = B0 du' + D dv) by B0^T:

           M_r du' + C_r du + K_r dq_I = 0,     dq_I' = H dq_I + G du,
           M_r = B0^T M B0,  C_r = B0^T (M D B0 + C B0),  K_r = B0^T (M D D + C D + K) P,
           G, H = the independent-coordinate rows of B0 and D P.

    The result's ``coordinates`` are the independent coordinates, ``speeds`` the
    independent speeds, ``M``, ``C``, ``K`` = M_r, C_r, K_r, and ``A`` = [[H, G], [-M_r^-1 K_r,
    -M_r^-1 C_r]]. About a moving state B0 and D may turn along the motion (dependent speeds in a
    frame that turns against the independent ones): their rates B0', D' (central differences
    along the motion) add M B0' to C_r's bracket and M D' to K_r's. The coefficients are then
    taken at (q0, v0); with ``a0`` not given (a steady motion), a state along which the reduced
    first-order matrix changes by more than ``tol`` relative is refused as not steady in these
    coordinates (give ``a0`` for an instantaneous linearization).
    """
    if isinstance(eom, ConstrainedSystem):
        if symbolic:
            raise ModelError("linearize: symbolic=True is for unconstrained equations; a ConstrainedSystem is "
                             "linearized numerically about a steady motion")
        if not isinstance(tol, (int, float)) or isinstance(tol, bool) or not 0 < tol < 1:
            raise ModelError(f"linearize: tol must be a number in (0, 1), got {tol!r}")
        if eom.J == 0:  # inequalities only: nothing to eliminate
            return linearize(eom.derived(), q0, v0, t, params)
        return linearize_constrained(eom, q0=q0, v0=v0, t=t, params=params, independent=independent, a0=a0,
                                     tol=float(tol))
    if isinstance(eom, Model):
        eom = derive(eom)
    if not isinstance(eom, EquationsOfMotion):
        raise ModelError("linearize needs EquationsOfMotion (lagcodegen.derive), a Model or a ConstrainedSystem, "
                         f"got {type(eom).__name__}")
    if eom.general:
        if independent is not None or a0 is not None:
            raise ModelError("linearize: independent and a0 are for constrained systems (a ConstrainedSystem)")
        if not isinstance(tol, (int, float)) or isinstance(tol, bool) or not 0 < tol < 1:
            raise ModelError(f"linearize: tol must be a number in (0, 1), got {tol!r}")
        return _linearize_speeds(eom, q0, v0, t, params, symbolic, float(tol))
    if independent is not None or a0 is not None:
        raise ModelError("linearize: independent and a0 are for constrained systems (a ConstrainedSystem)")
    names = [s.name for s in eom.q]
    n = eom.n
    if symbolic:
        acc = [se.Symbol(f"{s}_ddot") for s in names]
        K, C = _jacobians(eom.q, eom.qd, eom.M_se, eom.F_se, acc)
        sub = {}
        if q0 is not None:
            sub.update(dict(zip(eom.q, [sp.sympify(x) for x in values_by_name(q0, names, "q0", eom.q)])))
        if v0 is not None:
            sub.update(dict(zip(eom.qd, [sp.sympify(x) for x in values_by_name(v0, names, "v0", eom.qd)])))
        if t is not None:
            sub[eom.t] = sp.sympify(t)
        for k, val in _parametervalues_by_name(eom, params, numeric=False).items():
            sub[sp.Symbol(k)] = sp.sympify(val)

        def mat(rows):
            return sp.Matrix([[sp.simplify(sp.sympify(e).xreplace(sub)) for e in row] for row in rows])

        return Linearization(coordinates=names, M=mat(eom.M_se), C=mat(C), K=mat(K),
                             q0=[sub.get(s, s) for s in eom.q], v0=[sub.get(s, s) for s in eom.qd],
                             a0=[sp.Symbol(f"{s}_ddot") for s in names], t=sub.get(eom.t, eom.t),
                             params=dict(params or {}), symbolic=True)

    if q0 is None:
        raise ModelError("linearize: the state q0 is required (or pass symbolic=True)")
    qv = np.array([check_finite(x, f"q0[{k}]") for k, x in zip(names, values_by_name(q0, names, "q0", [0.0] * n))])
    vv = np.array([check_finite(x, f"v0[{k}]") for k, x in zip(names, values_by_name(v0, names, "v0", [0.0] * n))])
    tv = 0.0 if t is None else check_finite(t, "t")
    values = _parametervalues_by_name(eom, params, numeric=True)
    # Parameters first (integral values exactly, so that a zero integral removes its terms,
    # e.g. C^2 cos/sin^3 at theta = 0), then the state.
    psub = {se.Symbol(k): exact_number(v) for k, v in values.items()}
    psub[se.Symbol(eom.t.name)] = exact_number(tv)
    sub = {se.Symbol(s.name): se.RealDouble(x) for s, x in zip(eom.q, qv)}
    sub.update({se.Symbol(s.name): se.RealDouble(x) for s, x in zip(eom.qd, vv)})
    Mp = [[se.sympify(e).xreplace(psub) for e in row] for row in eom.M_se]
    Fp = [se.sympify(e).xreplace(psub) for e in eom.F_se]

    def num(e) -> float:
        try:
            x = complex(se.sympify(e).xreplace(sub).evalf())
        except (TypeError, ValueError, RuntimeError) as exc:
            raise ModelError(f"linearize: cannot evaluate {e} at the state ({exc})") from None
        if not np.isfinite(x.real) or abs(x.imag) > 1e-12 * max(1.0, abs(x.real)):
            raise ModelError(f"linearize: {e} is not finite and real at the state "
                             f"({', '.join(f'{k}={x:g}' for k, x in zip(names, qv))})")
        return x.real

    M = np.array([[num(Mp[i][j]) for j in range(n)] for i in range(n)])
    F = np.array([num(f) for f in Fp])
    try:
        a0 = np.linalg.solve(M, F)
    except np.linalg.LinAlgError:
        raise ModelError("linearize: the mass matrix is singular at this state") from None
    acc = [se.RealDouble(float(x)) for x in a0]
    K, C = _jacobians(eom.q, eom.qd, Mp, Fp, acc)
    return Linearization(coordinates=names, M=M, C=np.array([[num(e) for e in row] for row in C]),
                         K=np.array([[num(e) for e in row] for row in K]), q0=qv, v0=vv, a0=a0, t=tv,
                         params=values, symbolic=False)
