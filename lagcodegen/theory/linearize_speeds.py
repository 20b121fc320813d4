"""Linearization of equations with generalized speeds about a state, at rest or moving.

The equations are q' = k(q, v, t) = G(q, t) v + g(q, t), M(q, t) v' = F(q, v, t) (nq >= nv;
quaternion joints, Kane's form). About a reference motion (q0(t), v0(t)) through the state
(q0, v0) with accelerations a0 = M^-1 F there, a perturbation is written in tangent coordinates
theta (nv of them) that move with the reference:

    q = q0(t) + G(q0(t), t) theta,      v = v0(t) + dv,

so a quaternion is perturbed by rotations and never in its norm (a rotation exp(theta/2) to first
order, as Pinocchio's ``integrate``). To first order (eq. 3.16 differentiated, and the kinematics
differentiated along the reference motion)

    M dv' + C dv + K theta = 0,     theta' = H theta + dv,
    K = -(dF/dq - d(M a0)/dq) G,   C = -dF/dv,
    G H = (dk/dq) G - sum_l (dG/dq_l) k0_l - dG/dt       (k0 = k(q0, v0, t)),

the last line the kinematics' own variation along the motion (a Lie bracket of the speeds'
fields; for a body-frame angular velocity w0 it is H theta = theta x w0). H is solved by least
squares and refused when G H does not reach the right-hand side (tangent coordinates that do not
close). At rest with g = 0, H = 0 and the result is the classical M theta'' + C theta' + K theta = 0.

The coefficients are those at (q0, v0, t), frozen. About a moving state that is exact only where
they do not change along the motion (a free body spinning about a principal axis, a top
spinning about the vertical): the first-order matrix is compared at the states the motion
reaches a short time before and after (one classical Runge-Kutta step each way), and a motion
along which it changes (e.g. the steady precession of a symmetric top in body-frame speeds,
whose speeds turn with the spin) is refused by name.
"""

from __future__ import annotations

import math
from typing import Mapping

import numpy as np
import symengine as se

from ..errors import ModelError
from ..util import check_finite
from .linearization import Linearization, exact_number, values_by_name

__all__ = ["linearize_speeds"]

#: The time step of the steadiness check, in units of 1 / max |entry of the first-order matrix|.
STEADY_STEP = 1e-3


class _Numbers:
    """M, F, dF/dq, dF/dv, dM/dq, k, dk/dq, G = dk/dv, dG/dq, dG/dt of ``eom`` with the parameters
    substituted exactly, compiled once (``symengine.Lambdify``) in (q, v, t); a state whose
    double-precision evaluation is not finite is evaluated again entry by entry, exactly."""

    def __init__(self, eom, psub: dict):
        model = eom.model
        q = [se.Symbol(s.name) for s in model.coords]
        v = [se.Symbol(s.name) for s in model.v]
        t = se.Symbol(eom.t.name)
        nq, nv = len(q), len(v)
        M = [se.sympify(e).xreplace(psub) for row in eom.M_se for e in row]
        F = [se.sympify(e).xreplace(psub) for e in eom.F_se]
        k = [se.sympify(e).xreplace(psub) for e in eom.qdot_se]
        G = [se.diff(e, w) for e in k for w in v]
        parts = {"M": M, "F": F, "k": k, "G": G,
                 "dFdq": [se.diff(e, x) for e in F for x in q], "dFdv": [se.diff(e, w) for e in F for w in v],
                 "dMdq": [se.diff(e, x) for e in M for x in q], "dkdq": [se.diff(e, x) for e in k for x in q],
                 "dGdq": [se.diff(e, x) for e in G for x in q], "dGdt": [se.diff(e, t) for e in G]}
        self.shapes = {"M": (nv, nv), "F": (nv,), "k": (nq,), "G": (nq, nv), "dFdq": (nv, nq), "dFdv": (nv, nv),
                       "dMdq": (nv, nv, nq), "dkdq": (nq, nq), "dGdq": (nq, nv, nq), "dGdt": (nq, nv)}
        self.slices, self.exprs = {}, []
        for key, items in parts.items():
            self.slices[key] = slice(len(self.exprs), len(self.exprs) + len(items))
            self.exprs += items
        self.args = q + v + [t]
        stray = set().union(*(e.free_symbols for e in self.exprs)) - set(self.args)
        if stray:
            raise ModelError(f"linearize: the equations depend on {', '.join(sorted(map(str, stray)))}, which has no "
                             "value (not a coordinate, speed, time or parameter)")
        self.fn = se.Lambdify(self.args, self.exprs, real=True, cse=True)
        motion = self.exprs[self.slices["M"]] + self.exprs[self.slices["F"]] + self.exprs[self.slices["k"]]
        self.motion_fn = se.Lambdify(self.args, motion, real=True, cse=True)
        self.nq, self.nv = nq, nv

    def __call__(self, q: np.ndarray, v: np.ndarray, t: float) -> dict:
        x = np.concatenate([q, v, [t]])
        with np.errstate(all="ignore"):
            out = np.asarray(self.fn(x), dtype=float).ravel()
        if not np.all(np.isfinite(out)):
            state = {s: se.RealDouble(float(y)) for s, y in zip(self.args, x)}
            out = np.array([_exact(e, state) for e in self.exprs])
        vals = {key: out[sl].reshape(self.shapes[key]) for key, sl in self.slices.items()}
        bad = [key for key, y in vals.items() if not np.all(np.isfinite(y))]
        if bad:
            raise ModelError(f"linearize: {', '.join(bad)} not finite and real at the state")
        return vals

    def rates(self, q: np.ndarray, v: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray]:
        """(q', v') of the equations of motion at a state."""
        nq, nv = self.nq, self.nv
        with np.errstate(all="ignore"):
            out = np.asarray(self.motion_fn(np.concatenate([q, v, [t]])), dtype=float).ravel()
        M, F, k = out[:nv * nv].reshape(nv, nv), out[nv * nv:nv * nv + nv], out[nv * nv + nv:]
        return k, _solve(M, F)


def _exact(e, state: dict) -> float:
    try:
        x = complex(e.xreplace(state).evalf())
    except (TypeError, ValueError, RuntimeError):
        return math.nan
    return x.real if abs(x.imag) <= 1e-12 * max(1.0, abs(x.real)) else math.nan


def _solve(M: np.ndarray, F: np.ndarray) -> np.ndarray:
    try:
        return np.linalg.solve(M, F)
    except np.linalg.LinAlgError:
        raise ModelError("linearize: the mass matrix is singular at this state") from None


def _coefficients(num: _Numbers, q: np.ndarray, v: np.ndarray, t: float) -> tuple:
    """(M, C, K, H, a0, bracket residual) at a state (see the module docstring)."""
    x = num(q, v, t)
    M, G, k0 = x["M"], x["G"], x["k"]
    a0 = _solve(M, x["F"])
    Kq = -(x["dFdq"] - np.einsum("ikl,k->il", x["dMdq"], a0))
    C = -x["dFdv"]
    rhs = x["dkdq"] @ G - np.einsum("ijl,l->ij", x["dGdq"], k0) - x["dGdt"]
    H = np.linalg.lstsq(G, rhs, rcond=None)[0]
    miss = float(np.max(np.abs(G @ H - rhs), initial=0.0)) / max(1.0, float(np.max(np.abs(rhs), initial=0.0)))
    return M, C, Kq @ G, H, a0, miss


def _first_order(M, C, K, H) -> np.ndarray:
    nv = M.shape[0]
    return np.block([[H, np.eye(nv)], [-_solve(M, K), -_solve(M, C)]])


def _rk4(num: _Numbers, q, v, t: float, h: float) -> tuple:
    """One classical Runge-Kutta step of the equations of motion (h < 0: backwards)."""
    def f(y, s):
        dq, dv = num.rates(y[:num.nq], y[num.nq:], s)
        return np.concatenate([dq, dv])
    y = np.concatenate([q, v])
    k1 = f(y, t)
    k2 = f(y + h / 2 * k1, t + h / 2)
    k3 = f(y + h / 2 * k2, t + h / 2)
    k4 = f(y + h * k3, t + h)
    y = y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return y[:num.nq], y[num.nq:], t + h


def linearize_speeds(eom, *, q0, v0, t: float | None, values: Mapping[str, float], tol: float) -> Linearization:
    """The linearization of equations with generalized speeds about (q0, v0, t) in tangent
    coordinates (module docstring; eq. 3.16 to first order). ``values``: every parameter's value
    by name. ``tol``: the relative change of the first-order matrix along a moving state over a
    time ``STEADY_STEP`` / max|A| above which the state is refused as not steady.

    The result's ``coordinates`` and ``speeds`` are the speeds' names (the tangent directions);
    ``G`` = I and ``H`` are set when H != 0 (a moving state), so that ``A`` = [[H, I], [-M^-1 K,
    -M^-1 C]]."""
    model = eom.model
    qnames, vnames = [s.name for s in model.coords], [s.name for s in model.v]
    if q0 is None:
        raise ModelError("linearize: the state q0 is required")
    qv = np.array([check_finite(x, f"q0[{k}]") for k, x in zip(qnames, values_by_name(q0, qnames, "q0",
                                                                                       model.neutral()))])
    vv = np.array([check_finite(x, f"v0[{k}]") for k, x in zip(vnames, values_by_name(v0, vnames, "v0",
                                                                                       [0.0] * len(vnames)))])
    tv = 0.0 if t is None else check_finite(t, "t")
    psub = {se.Symbol(k): exact_number(x) for k, x in values.items()}
    num = _Numbers(eom, psub)
    M, C, K, H, a0, miss = _coefficients(num, qv, vv, tv)
    if miss > 1e-9:
        raise ModelError(f"linearize: the kinematics' variation along the motion is not a combination of the speeds' "
                         f"directions (G H = (dk/dq) G - (dG/dq) k0 - dG/dt misses by {miss:.2g} relative): tangent "
                         "coordinates theta with dq = G theta do not close at this state")
    if np.any(vv != 0):
        _check_steady(num, (qv, vv, tv), _first_order(M, C, K, H), tol)
    moving = bool(np.any(H != 0))
    nv = len(vnames)
    return Linearization(coordinates=list(vnames), M=M, C=C, K=K, q0=qv, v0=vv, a0=a0, t=tv, params=dict(values),
                         symbolic=False, speeds=list(vnames) if moving else None,
                         G=np.eye(nv) if moving else None, H=H if moving else None)


def _check_steady(num: _Numbers, state: tuple, A: np.ndarray, tol: float) -> None:
    """ModelError unless the first-order matrix stays A (to ``tol`` relative) along the motion."""
    def first_order_at(step: float) -> np.ndarray:
        q, v, t = _rk4(num, *state, step)
        M, C, K, H, _, _ = _coefficients(num, q, v, t)
        return _first_order(M, C, K, H)

    check_steady(A, first_order_at, tol, "first-order matrix",
                 " (its speeds or the forces in their frame turn as it moves, e.g. a top precessing in body-frame "
                 "speeds)", ". Linearize it on coordinates in which it is steady (e.g. rotation='ZYX' away from "
                 "pitch = +-pi/2, where the precession and spin angles are ignorable)")


def check_steady(A: np.ndarray, first_order_at, tol: float, what: str, why: str = "", advice: str = "") -> None:
    """ModelError unless ``first_order_at(step)`` (the first-order matrix at the state the motion
    reaches after a time ``step``) stays ``A`` to ``tol`` relative over -+h, h = STEADY_STEP /
    max|A| (a central difference); ``what`` names the matrix, ``why`` and ``advice`` complete the
    message."""
    scale = float(np.max(np.abs(A), initial=0.0))
    if scale == 0.0:
        return
    h = STEADY_STEP / scale
    seen = [first_order_at(step) for step in (h, -h)]
    change = float(np.max(np.abs(seen[0] - seen[1]))) / scale
    if change > tol:
        raise ModelError(f"linearize: the linearized equations change along this motion (their {what} by "
                         f"{change:.2g} relative over a time {2 * h:.3g}, tol {tol:g}): the state is not a steady "
                         f"motion in these speeds{why}, and coefficients frozen at one instant would not give its "
                         f"stability{advice}")
