"""Linearization of a constrained system about a steady motion (eqs. 4.5 and 3.16 to first order).

For M q'' = F + A^T lambda with A q' + A0 = 0 (holonomic rows A = df/dq, eq. 4.2) at a steady
motion (q0, v0, a0) on the constraints: the multipliers lambda0 by least squares
(A^T lambda0 = M a0 - F, refused when the residual says the state is not steady), the
first-order terms K = -(dF/dq - d(M a0)/dq + d(A^T lambda0)/dq), C = -dF/dq' and
S = d(A v0 + A0)/dq, then independent speeds u and coordinates q_I (pivoting on A, or named)
with dv = B0 du + D dq, dq = P dq_I:

    M_r du' + C_r du + K_r dq_I = 0,   dq_I' = H dq_I + G du,
    M_r = B0^T M B0,  C_r = B0^T (M D B0 + C B0),  K_r = B0^T (M D D + C D + K) P.

The derivation is in :func:`lagcodegen.theory.linearize.linearize` (the entry point).
"""

from __future__ import annotations

import math
from typing import Mapping, Sequence

import numpy as np
import symengine as se

from ..derivation import to_se
from ..errors import ModelError
from ..util import check_finite, excerpt
from .constraints import ConstrainedSystem, dependent_rows
from .linearization import Linearization, exact_number, values_by_name

__all__ = ["linearize_constrained"]


def _state_numbers(model, q0, v0, t, params: Mapping[str, float] | None):
    """(names, q, v, t, parameter values by name) of a state, checked."""
    names = [s.name for s in model.coords]
    speeds = [s.name for s in model.v] if model.general else names
    n = len(names)
    if q0 is None:
        raise ModelError("linearize: the state q0 is required")
    qv = np.array([check_finite(x, f"q0[{k}]") for k, x in zip(names, values_by_name(q0, names, "q0", [0.0] * n))])
    vv = np.array([check_finite(x, f"v0[{k}]")
                   for k, x in zip(speeds, values_by_name(v0, speeds, "v0", [0.0] * len(speeds)))])
    tv = 0.0 if t is None else check_finite(t, "t")
    known = {s.name: float(v) for s, v in model.params.items()}
    for k in params or {}:
        if k not in known:
            raise ModelError(f"{k!r} is not a parameter of model {model.name!r} "
                             f"(parameters: {', '.join(known) or 'none'})")
    values = dict(known)
    values.update({k: check_finite(v, f"parameter {k!r}") for k, v in (params or {}).items()})
    return names, qv, vv, tv, values


class _ConstrainedNumbers:
    """The numbers the constrained linearization needs at a state (q, v, t) and parameter values:
    M, F, A, A0, f, gamma = -d/dt (A q' + A0) at q'' = 0, dF/dq, dF/dq', dM/dq, dA/dq, dA0/dq.

    Differentiated symbolically once per system (symengine) and compiled, with the parameters
    as arguments, into one function (``symengine.Lambdify``, common subexpressions shared): later
    states and parameter values cost one call. Where that double-precision evaluation is not
    finite (a parameter that is exactly zero multiplying a pole, e.g. C^2 cos/sin^3 at C = 0),
    the expressions are evaluated again with the parameters substituted exactly first, as the
    unconstrained :func:`linearize` does.
    """

    def __init__(self, system: ConstrainedSystem):
        model, eom = system.model, system.derived()
        n, J = system.n, system.J
        q = [se.Symbol(s.name) for s in model.coords]
        v = [se.Symbol(s.name) for s in model.speeds]
        t = se.Symbol(model.t.name)
        self.params = [se.Symbol(s.name) for s in model.params]
        rows = system.rows()
        M = [se.sympify(e) for row in eom.M_se for e in row]
        F = [se.sympify(e) for e in eom.F_se]
        A = [to_se(a, f"constraint {r.index}") for r in rows for a in r.A]
        A0 = [to_se(r.A0, f"constraint {r.index}") for r in rows]
        s = [se.Add(*(a * w for a, w in zip(A[j * n:(j + 1) * n], v)), A0[j]) for j in range(J)]
        parts = {
            "M": M, "F": F, "A": A, "A0": A0,
            "f": [to_se(e, f"holonomic constraint {j}") for j, e in enumerate(system.holonomic)],
            "gamma": [-se.Add(se.diff(sj, t), *(se.diff(sj, qk) * w for qk, w in zip(q, v))) for sj in s],
            "dFdq": [se.diff(e, qk) for e in F for qk in q], "dFdv": [se.diff(e, w) for e in F for w in v],
            "dMdq": [se.diff(e, qk) for e in M for qk in q], "dAdq": [se.diff(e, qk) for e in A for qk in q],
            "dA0dq": [se.diff(e, qk) for e in A0 for qk in q]}
        self.shapes = {"M": (n, n), "F": (n,), "A": (J, n), "A0": (J,), "f": (len(parts["f"]),), "gamma": (J,),
                       "dFdq": (n, n), "dFdv": (n, n), "dMdq": (n, n, n), "dAdq": (J, n, n), "dA0dq": (J, n)}
        self.slices, self.exprs = {}, []
        for key, items in parts.items():
            self.slices[key] = slice(len(self.exprs), len(self.exprs) + len(items))
            self.exprs += items
        self.args = q + v + [t] + self.params
        stray = set().union(*(e.free_symbols for e in self.exprs)) - set(self.args)
        if stray:
            raise ModelError(f"linearize: the equations depend on {', '.join(sorted(map(str, stray)))}, which has no "
                             "value (not a coordinate, velocity, time or parameter)")
        self.fn = se.Lambdify(self.args, self.exprs, real=True, cse=True)

    def __call__(self, q: np.ndarray, v: np.ndarray, t: float, values: Mapping[str, float], where: str) -> dict:
        p = [values[s.name] for s in self.params]
        with np.errstate(all="ignore"):
            out = np.asarray(self.fn(np.concatenate([q, v, [t], p])), dtype=float).ravel()
        if not np.all(np.isfinite(out)):  # evaluate exactly: parameters first, then the state
            psub = {s: exact_number(x) for s, x in zip(self.params, p)}
            psub[self.args[2 * len(q)]] = exact_number(t)
            state = {s: se.RealDouble(float(x)) for s, x in zip(self.args, np.concatenate([q, v]))}
            out = np.array([self._exact(e, psub, state) for e in self.exprs])
        vals = {k: out[sl].reshape(self.shapes[k]) for k, sl in self.slices.items()}
        bad = [k for k, x in vals.items() if not np.all(np.isfinite(x))]
        if bad:
            raise ModelError(f"linearize: {', '.join(bad)} not finite and real at the state ({where})")
        return vals

    @staticmethod
    def _exact(e, psub: dict, state: dict) -> float:
        try:
            x = complex(e.xreplace(psub).xreplace(state).evalf())
        except (TypeError, ValueError, RuntimeError):
            return math.nan
        return x.real if abs(x.imag) <= 1e-12 * max(1.0, abs(x.real)) else math.nan


def _constrained_numbers(system: ConstrainedSystem) -> _ConstrainedNumbers:
    """The compiled functions of ``system``, made on the first call and kept on the system."""
    kept = system.__dict__.get("_linearize_compiled")
    if kept is None:
        kept = system.__dict__["_linearize_compiled"] = _ConstrainedNumbers(system)
    return kept


class _SpeedsConstrainedNumbers:
    """The numbers of a constrained system whose model has generalized speeds (q' = k(q, v, t) =
    G v + g), in tangent coordinates theta (dq = G theta, one per speed): the rows in v,
    s = A k + A0 = A_v v + A0_v, and every q-derivative multiplied by G, under the keys of
    :class:`_ConstrainedNumbers` (n = nv), plus ``H``, the kinematics' variation along the motion
    (:mod:`.linearize_speeds`). Compiled per parameter values (they are substituted exactly)."""

    def __init__(self, system: ConstrainedSystem, values: Mapping[str, float]):
        from .linearize_speeds import _Numbers
        model, eom = system.model, system.derived()
        psub = {se.Symbol(k): exact_number(x) for k, x in values.items()}
        self.num = _Numbers(eom, psub)
        q = [se.Symbol(x.name) for x in model.coords]
        v = [se.Symbol(x.name) for x in model.v]
        t = se.Symbol(model.t.name)
        k = [se.sympify(e).xreplace(psub) for e in eom.qdot_se]
        rows = system.rows()
        s = [se.Add(*(to_se(a, f"constraint {r.index}").xreplace(psub) * ki for a, ki in zip(r.A, k)),
                    to_se(r.A0, f"constraint {r.index}").xreplace(psub)) for r in rows]
        Av = [se.diff(e, w) for e in s for w in v]
        parts = {"s": s, "Av": Av, "dsdq": [se.diff(e, x) for e in s for x in q],
                 "dAvdq": [se.diff(e, x) for e in Av for x in q],
                 "f": [to_se(e, f"holonomic constraint {j}").xreplace(psub) for j, e in enumerate(system.holonomic)],
                 "gamma": [-se.Add(se.diff(e, t), *(se.diff(e, x) * ki for x, ki in zip(q, k))) for e in s]}
        J, nq, nv = len(rows), len(q), len(v)
        self.shapes = {"s": (J,), "Av": (J, nv), "dsdq": (J, nq), "dAvdq": (J, nv, nq), "f": (len(parts["f"]),),
                       "gamma": (J,)}
        self.slices, exprs = {}, []
        for key, items in parts.items():
            self.slices[key] = slice(len(exprs), len(exprs) + len(items))
            exprs += items
        stray = set().union(*(e.free_symbols for e in exprs)) - set(q + v + [t])
        if stray:
            raise ModelError(f"linearize: the constraints depend on {', '.join(sorted(map(str, stray)))}, which has "
                             "no value (not a coordinate, speed, time or parameter)")
        self.fn = se.Lambdify(q + v + [t], exprs, real=True, cse=True)

    def __call__(self, q: np.ndarray, v: np.ndarray, t: float, where: str) -> dict:
        from .linearize_speeds import _coefficients
        with np.errstate(all="ignore"):
            out = np.asarray(self.fn(np.concatenate([q, v, [t]])), dtype=float).ravel()
        c = {key: out[sl].reshape(self.shapes[key]) for key, sl in self.slices.items()}
        x = self.num(q, v, t)
        bad = [key for key, y in {**c, **x}.items() if not np.all(np.isfinite(y))]
        if bad:
            raise ModelError(f"linearize: {', '.join(bad)} not finite and real at the state ({where})")
        G = x["G"]
        H, miss = _coefficients(self.num, q, v, t)[3::2]
        if miss > 1e-9:
            raise ModelError(f"linearize: the kinematics' variation along the motion is not a combination of the "
                             f"speeds' directions (misses by {miss:.2g} relative) at this state")
        A = c["Av"]
        return {"M": x["M"], "F": x["F"], "A": A, "A0": c["s"] - A @ v, "f": c["f"], "gamma": c["gamma"],
                "dFdq": x["dFdq"] @ G, "dFdv": x["dFdv"], "dMdq": np.einsum("ijl,lk->ijk", x["dMdq"], G),
                "dAdq": np.einsum("jil,lk->jik", c["dAvdq"], G), "S": c["dsdq"] @ G, "H": H, "k": x["k"]}


def _nonsingular(B: np.ndarray, scale: float) -> bool:
    if B.size == 0:
        return True
    s = np.linalg.svd(B, compute_uv=False)
    return bool(s[-1] > 1e-9 * max(scale, 1e-300))


def _with_nonholonomic(A: np.ndarray, Ah: np.ndarray, dep_h: list, rest: list, scale: float) -> list:
    """The dependent speeds: ``dep_h`` (solved from the holonomic rows Ah) and, among ``rest``, the
    columns pivoted on the nonholonomic rows with the holonomic ones eliminated (their Schur
    complement); ModelError if A is singular on them."""
    J, n = A.shape
    JH = Ah.shape[0]
    schur = A[JH:, rest]
    if JH:
        schur = schur - A[JH:, dep_h] @ np.linalg.solve(Ah[:, dep_h], Ah[:, rest])
    dep = sorted(dep_h + [rest[i] for i in _pivot_columns(schur, list(range(len(rest))), J - JH)])
    if not _nonsingular(A[:, dep], scale):
        raise ModelError(f"linearize: the constraint Jacobian A ({J}x{n}) has rank < {J} at this state "
                         f"({dependent_rows(A)}): redundant constraints or a singular configuration")
    return dep


def _pivot_columns(A: np.ndarray, columns: list[int], k: int) -> list[int]:
    """k of ``columns`` on which A (k rows) is best conditioned: QR with column pivoting."""
    import scipy.linalg  # scipy: column pivoting
    if k == 0:
        return []
    _, _, perm = scipy.linalg.qr(A[:, columns], pivoting=True, mode="economic")
    return sorted(columns[i] for i in perm[:k])


def _dependent(A: np.ndarray, JH: int, names: list[str], independent) -> tuple[list[int], list[int]]:
    """(dependent speeds, dependent coordinates) as column indices, holonomic rows the first JH of A.

    The dependent coordinates (JH) are a subset of the dependent speeds (J), chosen so that
    A_h restricted to them is regular; the dependent speeds make A_dep (J x J) regular.
    """
    J, n = A.shape
    scale = float(np.linalg.svd(A, compute_uv=False)[0]) if J else 1.0
    Ah = A[:JH]
    everything = list(range(n))
    if independent is None:
        dep_h = _pivot_columns(Ah, everything, JH)
        if not _nonsingular(Ah[:, dep_h], scale):
            raise ModelError(f"linearize: the holonomic constraints' Jacobian has rank < {JH} at this state "
                             f"({dependent_rows(Ah)})")
        return _with_nonholonomic(A, Ah, dep_h, [i for i in everything if i not in dep_h], scale), dep_h
    if isinstance(independent, str):
        chosen = [independent]
    elif isinstance(independent, (list, tuple)) and all(isinstance(k, str) for k in independent):
        chosen = list(independent)
    else:
        raise ModelError(f"linearize: independent must be a list of coordinate names, got {excerpt(repr(independent))}")
    unknown = [k for k in chosen if k not in names]
    if unknown or len(set(chosen)) != len(chosen):
        what = f"unknown coordinate(s) {', '.join(map(str, unknown))}" if unknown else "a name repeated"
        raise ModelError(f"linearize: independent: {what} (coordinates: {', '.join(names)})")
    ind = [names.index(k) for k in chosen]
    shown = ", ".join(chosen) or "none"
    if len(ind) == n - J:
        dep = [i for i in everything if i not in ind]
        if not _nonsingular(A[:, dep], scale):
            what = "coordinates and speeds" if J == JH else "speeds"
            raise ModelError(f"linearize: independent {what} ({shown}) cannot be chosen at this state: the "
                             f"constraints cannot be solved for the other {what} "
                             f"({', '.join(names[i] for i in dep)}), A restricted to them is singular; "
                             f"choose other independent {what} (or leave independent=None to pivot on A)")
        return dep, [dep[i] for i in _pivot_columns(Ah[:, dep], list(range(len(dep))), JH)]
    if JH and len(ind) == n - JH:
        dep_h = [i for i in everything if i not in ind]
        if not _nonsingular(Ah[:, dep_h], scale):
            raise ModelError(f"linearize: independent coordinates ({shown}) cannot be chosen at this state: the "
                             f"holonomic constraints cannot be solved for {', '.join(names[i] for i in dep_h)} "
                             "(their Jacobian is singular there); choose other independent coordinates")
        return _with_nonholonomic(A, Ah, dep_h, ind, scale), dep_h
    counts = f"the {n - J} independent speeds"
    if JH:
        counts += f" or the {n - JH} independent coordinates"
    raise ModelError(f"linearize: independent names {len(ind)} coordinate(s) ({shown}); give {counts} "
                     f"({n} coordinates, {JH} holonomic and {J - JH} nonholonomic constraints)")


def linearize_constrained(system: ConstrainedSystem, *, q0, v0=None, t: float | None = None,
                          params: Mapping[str, float] | None = None, independent: Sequence[str] | None = None,
                          a0=None, tol: float = 1e-8, moving: str = "check") -> Linearization:
    """Linearize a constrained system about a steady motion, reduced to independent coordinates and
    speeds: the "Constrained systems" part of :func:`lagcodegen.theory.linearize.linearize`, which
    is the entry point (it checks the arguments and handles J = 0); see there for the formulas.

    With generalized speeds (a model whose speeds are not its coordinates' rates) the coordinates
    are tangent ones, theta' = H theta + dv (:mod:`.linearize_speeds`); H = 0 otherwise. About a
    moving state the basis B0 and D change along the motion (e.g. dependent speeds in a frame the
    independent ones turn against), and dv' = B0 du' + B0' du + D dq' + D' dq, so

        C_r = B0^T (M (D B0 + B0') + C B0),  K_r = B0^T (M (D (H + D) + D') + C D + K) P,

    B0', D' by central differences along the motion (q0 -+ h k0, v0 -+ h a0, the same independent
    speeds and coordinates); the independent coordinates move by ((H + D) P)_I. ``moving``:
    "check" (those terms, and, unless ``a0`` is given for an instantaneous linearization, a state
    along which the reduced first-order matrix changes by more than ``tol`` relative refused as no
    steady motion in these coordinates, :func:`_check_steady`), "terms" (the terms only), "frozen"
    (neither: the coefficients at the state)."""
    model = system.model
    names, qv, vv, tv, values = _state_numbers(model, q0, v0, t, params)
    n, J, JH = system.n, system.J, system.n_holonomic
    where = ", ".join(f"{k}={x:g}" for k, x in zip(names, qv))
    if model.general:  # tangent coordinates, one per speed; theta' = H theta + dv (.linearize_speeds)
        names, n = [s.name for s in model.v], model.nv
        key = tuple(sorted(values.items()))
        kept = system.__dict__.get("_linearize_speeds_compiled")
        if kept is None or kept[0] != key:  # compiled per parameter values (substituted exactly)
            kept = system.__dict__["_linearize_speeds_compiled"] = (key, _SpeedsConstrainedNumbers(system, values))
        x = kept[1](qv, vv, tv, where)
    else:
        x = _constrained_numbers(system)(qv, vv, tv, values, where)
    M, F, A = x["M"], x["F"], x["A"]

    # the state must satisfy the constraints (eqs. 4.1-4.3)
    bad = []
    for j, val in enumerate(x["f"]):
        if abs(val) > tol * max(1.0, float(np.max(np.abs(A[j]))) * float(np.max(np.abs(qv), initial=0.0))):
            bad.append(f"holonomic constraint {j} ({excerpt(str(system.holonomic[j]))} = 0) has residual {val:.3g}")
    s0 = A @ vv + x["A0"]
    for j in range(J):
        if abs(s0[j]) > tol * max(1.0, float(np.max(np.abs(A[j]))) * float(np.max(np.abs(vv), initial=0.0))):
            bad.append(f"velocity constraint {j} (A_{j} q' + A0_{j}) has residual {s0[j]:.3g}")
    if bad:
        raise ModelError("linearize: the state violates the constraints: " + "; ".join(bad))

    # accelerations and multipliers: A^T lambda0 = M a0 - F (least squares), A a0 = gamma
    acc = np.zeros(n) if a0 is None else np.array(
        [check_finite(a_, f"a0[{k}]") for k, a_ in zip(names, values_by_name(a0, names, "a0", [0.0] * n))])
    gamma = x["gamma"]
    target = M @ acc - F
    lam0 = np.linalg.lstsq(A.T, target, rcond=None)[0]
    res_dyn = float(np.max(np.abs(A.T @ lam0 - target), initial=0.0))
    res_acc = float(np.max(np.abs(A @ acc - gamma), initial=0.0))
    scale_dyn = max(1.0, float(np.max(np.abs(F))), float(np.max(np.abs(M @ acc))))
    scale_acc = max(1.0, float(np.max(np.abs(gamma))), float(np.max(np.abs(A @ acc))))
    if res_dyn > tol * scale_dyn or res_acc > tol * scale_acc:
        true_acc = _constrained_accelerations(M, F, A, gamma)
        raise ModelError(
            "linearize: the state is not a steady motion consistent with the constraints: "
            f"A^T lambda = M a0 - F has the least-squares residual {res_dyn:.3g} (relative {res_dyn / scale_dyn:.2g}) "
            f"and A a0 = gamma the residual {res_acc:.3g} (relative {res_acc / scale_acc:.2g}), tolerance {tol:g}; "
            "the accelerations the constraints allow there are "
            + ", ".join(f"{k}''={a_:.6g}" for k, a_ in zip(names, true_acc))
            + " (give them as a0 for an instantaneous linearization, or choose a state where they vanish)")

    # first-order terms: K = -(dF/dq - d(M a0)/dq + d(A^T lambda0)/dq), C = -dF/dq', S = d(A v0 + A0)/dq
    K = -(x["dFdq"] - np.einsum("ikj,k->ij", x["dMdq"], acc) + np.einsum("lij,l->ij", x["dAdq"], lam0))
    C = -x["dFdv"]
    S = x["S"] if model.general else np.einsum("jik,i->jk", x["dAdq"], vv) + x["dA0dq"]
    Hk = x["H"] if model.general else np.zeros((n, n))  # dq' = H dq + dv (0 unless generalized speeds)

    # independent speeds u and coordinates; dv = B0 du + D dq, dq = P dq_I
    dep, dep_h = _dependent(A, JH, names, independent)
    ind = [i for i in range(n) if i not in dep]
    indq = [i for i in range(n) if i not in dep_h]
    B0 = np.zeros((n, len(ind)))
    B0[ind, :] = np.eye(len(ind))
    B0[dep, :] = -np.linalg.solve(A[:, dep], A[:, ind])
    D = np.zeros((n, n))
    D[dep, :] = -np.linalg.solve(A[:, dep], S)
    P = np.zeros((n, len(indq)))
    P[indq, :] = np.eye(len(indq))
    if JH:
        P[dep_h, :] = -np.linalg.solve(A[:JH][:, dep_h], A[:JH][:, indq])
    k0 = x["k"] if model.general else vv  # q' along the motion
    dB0, dD = np.zeros_like(B0), np.zeros_like(D)
    if moving != "frozen" and (np.any(k0 != 0) or np.any(acc != 0)):
        dB0, dD = _basis_rates(system, (qv, vv, tv, acc, k0), values, [names[i] for i in ind],
                               _time_step(M, C, K, B0, P, Hk, D))
    Mr = B0.T @ M @ B0
    Cr = B0.T @ (M @ (D @ B0 + dB0) + C @ B0)
    Kr = B0.T @ (M @ (D @ (Hk + D) + dD) + C @ D + K) @ P
    lin = Linearization(coordinates=[names[i] for i in indq], M=Mr, C=Cr, K=Kr, q0=qv, v0=vv, a0=acc, t=tv,
                         params=values, symbolic=False, speeds=[names[i] for i in ind], G=B0[indq, :],
                         H=((Hk + D) @ P)[indq, :], multipliers=lam0, residual=max(res_dyn, res_acc),
                         dependent_speeds=[names[i] for i in dep], dependent_coordinates=[names[i] for i in dep_h])
    lin._basis = (B0, D)  # for the basis' rates of a linearization at a neighbouring state (_basis_rates)
    if moving == "check" and a0 is None and np.any(k0 != 0):  # a steady motion (a0 = 0) is claimed
        _check_steady(system, lin, k0, tol)
    return lin


def _time_step(M, C, K, B0, P, H, D) -> float:
    """A time step of the central differences along the motion: STEADY_STEP over the largest rate
    of the frozen reduced equations."""
    from .linearize_speeds import STEADY_STEP
    Mr = B0.T @ M @ B0
    try:
        rates = [np.linalg.solve(Mr, B0.T @ (C @ B0)), np.linalg.solve(Mr, B0.T @ (C @ D + K) @ P)]
    except np.linalg.LinAlgError:
        raise ModelError("linearize: the reduced mass matrix B0^T M B0 is singular at this state") from None
    scale = max([float(np.max(np.abs(r), initial=0.0)) for r in rates] + [float(np.max(np.abs(H), initial=0.0)),
                                                                           float(np.max(np.abs(D), initial=0.0)), 1e-300])
    return STEADY_STEP / scale


def _basis_rates(system: ConstrainedSystem, state: tuple, values: dict, speeds: list, h: float) -> tuple:
    """(B0', D') along the motion through ``state`` = (q0, v0, t, a0, k0) by central differences
    over +-h, with the independent speeds ``speeds`` kept."""
    q, v, t, acc, k0 = state
    seen = []
    for step in (h, -h):
        other = linearize_constrained(system, q0=q + step * k0, v0=v + step * acc, t=t + step, params=values,
                                      independent=speeds, a0=acc, tol=math.inf, moving="frozen")
        seen.append(other._basis)
    return (seen[0][0] - seen[1][0]) / (2 * h), (seen[0][1] - seen[1][1]) / (2 * h)


def _check_steady(system: ConstrainedSystem, lin: Linearization, k0: np.ndarray, tol: float) -> None:
    """ModelError unless the reduced first-order matrix of ``lin`` stays the same (to ``tol``
    relative) at the states the motion reaches a short time h = STEADY_STEP / max|A| before and
    after: (q0 -+ h k0, v0 -+ h a0), the same independent speeds and coordinates, the constraints'
    checks off there (the states leave them at O(h^2), which the central difference cancels)."""
    from .linearize_speeds import check_steady

    def first_order_at(step: float) -> np.ndarray:
        return linearize_constrained(system, q0=lin.q0 + step * k0, v0=lin.v0 + step * lin.a0, t=lin.t + step,
                                     params=lin.params, independent=lin.speeds, a0=lin.a0, tol=math.inf,
                                     moving="terms").A

    check_steady(lin.A, first_order_at, tol, "reduced first-order matrix")


def _constrained_accelerations(M: np.ndarray, F: np.ndarray, A: np.ndarray, gamma: np.ndarray) -> np.ndarray:
    """q'' of [M A^T; A 0][q''; -lambda] = [F; gamma] (eq. 4.5), least squares if singular."""
    n, J = M.shape[0], A.shape[0]
    K = np.block([[M, A.T], [A, np.zeros((J, J))]])
    return np.linalg.lstsq(K, np.concatenate([F, gamma]), rcond=None)[0][:n]
