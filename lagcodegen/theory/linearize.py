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
``params``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np
import symengine as se
import sympy as sp

from ..derivation import EquationsOfMotion, derive, to_se
from ..errors import ModelError
from ..model.model import Model
from ..util import check_finite, excerpt
from .constraints import ConstrainedSystem, dependent_rows

__all__ = ["Linearization", "linearize"]


@dataclass
class Linearization:
    """M dq'' + C dq' + K dq = 0 about a state.

    Numeric (default): ``M``, ``C``, ``K`` are numpy arrays and ``q0``, ``v0``, ``a0`` (the
    accelerations at the state) arrays. Symbolic (``linearize(..., symbolic=True)``): sympy
    matrices in the state symbols, with ``a0`` the acceleration symbols ``<q>_ddot`` (to be
    replaced by the solution of M a = F; zero at equilibria); the numeric properties below
    then raise.
    """

    coordinates: list[str]
    M: object
    C: object
    K: object
    q0: object
    v0: object
    a0: object
    t: object
    params: dict
    symbolic: bool = False
    #: Constrained systems (:func:`linearize` of a ConstrainedSystem): the independent speeds
    #: u (``speeds``, named by their coordinates) and the kinematics dq' = H dq + G du of the
    #: independent ``coordinates``; None for unconstrained equations (u = q', G = I, H = 0).
    speeds: list | None = None
    G: object = None
    H: object = None
    #: Constrained systems: the multipliers lambda0 at the state (A^T lambda0 = M a0 - F, least
    #: squares), the residual of that fit and of A a0 = gamma (max abs), and the dependent speeds
    #: and coordinates (names) the reduction eliminated.
    multipliers: object = None
    residual: float = 0.0
    dependent_speeds: list | None = None
    dependent_coordinates: list | None = None

    def _numeric(self, what: str) -> None:
        if self.symbolic:
            raise ModelError(f"{what} needs a numeric linearization (symbolic=False)")

    @property
    def n(self) -> int:
        return len(self.coordinates)

    @property
    def reduced(self) -> bool:
        """Whether this is the reduced linearization of a constrained system (speeds u != q')."""
        return self.G is not None

    @property
    def A(self) -> np.ndarray:
        """First-order system matrix [[0, I], [-M^-1 K, -M^-1 C]] (2n x 2n).

        Of a constrained system: [[H, G], [-M^-1 K, -M^-1 C]] in the state (dq, du) of the
        independent coordinates and speeds (n + n_u square).
        """
        self._numeric("A")
        n = self.n
        try:
            MK = np.linalg.solve(self.M, self.K)
            MC = np.linalg.solve(self.M, self.C)
        except np.linalg.LinAlgError:
            raise ModelError("the mass matrix is singular at the linearization state") from None
        if self.reduced:
            return np.block([[self.H, self.G], [-MK, -MC]])
        return np.block([[np.zeros((n, n)), np.eye(n)], [-MK, -MC]])

    @property
    def eigenvalues(self) -> np.ndarray:
        """Eigenvalues of A (complex), sorted by imaginary then real part."""
        ev = np.linalg.eigvals(self.A)
        return ev[np.lexsort((ev.real, ev.imag))]

    @property
    def conservative(self) -> bool:
        """C = 0, and K and M symmetric (to rounding): the (K, M) eigenproblem applies."""
        self._numeric("conservative")
        if self.reduced and (self.K.shape[0] != self.K.shape[1] or np.any(self.H != 0)
                             or not np.array_equal(self.G, np.eye(self.n))):
            return False
        scale = max(np.max(np.abs(self.K)), np.max(np.abs(self.M)), 1e-300)
        tol = 1e-12 * scale
        return (np.max(np.abs(self.C), initial=0.0) <= tol and np.max(np.abs(self.K - self.K.T), initial=0.0) <= tol
                and np.max(np.abs(self.M - self.M.T), initial=0.0) <= tol)

    @property
    def omega_squared(self) -> np.ndarray:
        """Generalized eigenvalues w^2 of K v = w^2 M v, ascending (C is ignored).

        ``scipy.linalg.eigh`` when K, M are symmetric and M positive definite; otherwise the
        real parts of the eigenvalues of M^-1 K.
        """
        self._numeric("omega_squared")
        if self.K.shape[0] != self.K.shape[1]:
            raise ModelError(f"omega_squared needs as many speeds as coordinates; this reduced linearization has "
                             f"{self.K.shape[0]} speeds ({', '.join(self.speeds or [])}) and {self.n} coordinates: "
                             "use eigenvalues")
        import scipy.linalg  # scipy: only for this generalized symmetric eigenproblem
        K, M = self.K, self.M
        if np.allclose(K, K.T, rtol=1e-12, atol=0) and np.allclose(M, M.T, rtol=1e-12, atol=0):
            try:
                return scipy.linalg.eigh(0.5 * (K + K.T), 0.5 * (M + M.T), eigvals_only=True)
            except np.linalg.LinAlgError:
                pass
        return np.sort(np.linalg.eigvals(np.linalg.solve(M, K)).real)

    @property
    def frequencies(self) -> np.ndarray:
        """Angular frequencies of the oscillating modes, ascending.

        Conservative case (C = 0, symmetric K): sqrt(w^2) of every positive generalized
        eigenvalue of (K, M) (unstable or neutral modes have none). Otherwise the positive
        imaginary parts of the eigenvalues of A (damped or gyroscopic frequencies).
        """
        if self.conservative:
            w2 = self.omega_squared
            scale = max(1.0, float(np.max(np.abs(w2), initial=0.0)))
            return np.sqrt(w2[w2 > 1e-12 * scale])
        ev = self.eigenvalues
        scale = max(1.0, float(np.max(np.abs(ev), initial=0.0)))
        return np.sort(ev.imag[ev.imag > 1e-12 * scale])

    def stable(self, tol: float | None = None) -> bool:
        """Linear stability: every eigenvalue of A has real part <= ``tol``.

        Default ``tol`` = 1e-9 max(1, max |eigenvalue|), so the purely imaginary eigenvalues
        of a conservative system (computed with rounding-level real parts) count as stable
        (stable in the linear sense; zero eigenvalues, neutral directions, count too).
        """
        ev = self.eigenvalues
        if tol is None:
            tol = 1e-9 * max(1.0, float(np.max(np.abs(ev), initial=0.0)))
        return bool(np.all(ev.real <= tol))


# ---------------------------------------------------------------------- helpers
def _values(val, names: Sequence[str], what: str, default) -> list:
    if val is None:
        return list(default)
    if isinstance(val, Mapping):
        unknown = set(val) - set(names)
        if unknown:
            raise ModelError(f"{what}: unknown coordinate(s) {', '.join(sorted(unknown))}")
        return [val.get(k, d) for k, d in zip(names, default)]
    vals = list(np.ravel(np.asarray(val, dtype=object)))
    if len(vals) != len(names):
        raise ModelError(f"{what} has {len(vals)} values, expected {len(names)} ({', '.join(names)})")
    return vals


def _parameter_values(eom: EquationsOfMotion, params: Mapping[str, float] | None, numeric: bool) -> dict:
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


def exact_number(v: float):
    """A float as symengine number: integral values exactly (0 * x must vanish)."""
    return se.Integer(int(v)) if float(v).is_integer() and abs(v) < 2**53 else se.RealDouble(v)


def _jacobians(qs, vs, M, F, acc: list):
    """Symbolic K = -(dF/dq - d(M a)/dq) and C = -(dF/dq' - d(M a)/dq') with accelerations ``acc``."""
    n = len(qs)
    q = [se.Symbol(s.name) for s in qs]
    v = [se.Symbol(s.name) for s in vs]
    r = [F[i] - sum((M[i][k] * acc[k] for k in range(n)), se.Integer(0)) for i in range(n)]
    K = [[-se.diff(r[i], q[j]) for j in range(n)] for i in range(n)]
    C = [[-se.diff(r[i], v[j]) for j in range(n)] for i in range(n)]
    return K, C


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
        constraints and is a steady motion.

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
    -M_r^-1 C_r]]. The coefficients are frozen at (q0, v0): exact where they do not depend on
    the coordinates that move along the steady motion (ignorable ones, eq. 3.8).
    """
    if isinstance(eom, ConstrainedSystem):
        if symbolic:
            raise ModelError("linearize: symbolic=True is for unconstrained equations; a ConstrainedSystem is "
                             "linearized numerically about a steady motion")
        if not isinstance(tol, (int, float)) or isinstance(tol, bool) or not 0 < tol < 1:
            raise ModelError(f"linearize: tol must be a number in (0, 1), got {tol!r}")
        return _linearize_constrained(eom, q0, v0, t, params, independent, a0, float(tol))
    if isinstance(eom, Model):
        eom = derive(eom)
    if not isinstance(eom, EquationsOfMotion):
        raise ModelError("linearize needs EquationsOfMotion (lagcodegen.derive), a Model or a ConstrainedSystem, "
                         f"got {type(eom).__name__}")
    if independent is not None or a0 is not None:
        raise ModelError("linearize: independent and a0 are for constrained systems (a ConstrainedSystem)")
    names = [s.name for s in eom.q]
    n = eom.n
    if symbolic:
        acc = [se.Symbol(f"{s}_ddot") for s in names]
        K, C = _jacobians(eom.q, eom.qd, eom.M_se, eom.F_se, acc)
        sub = {}
        if q0 is not None:
            sub.update(dict(zip(eom.q, [sp.sympify(x) for x in _values(q0, names, "q0", eom.q)])))
        if v0 is not None:
            sub.update(dict(zip(eom.qd, [sp.sympify(x) for x in _values(v0, names, "v0", eom.qd)])))
        if t is not None:
            sub[eom.t] = sp.sympify(t)
        for k, val in _parameter_values(eom, params, numeric=False).items():
            sub[sp.Symbol(k)] = sp.sympify(val)

        def mat(rows):
            return sp.Matrix([[sp.simplify(sp.sympify(e).xreplace(sub)) for e in row] for row in rows])

        return Linearization(coordinates=names, M=mat(eom.M_se), C=mat(C), K=mat(K),
                             q0=[sub.get(s, s) for s in eom.q], v0=[sub.get(s, s) for s in eom.qd],
                             a0=[sp.Symbol(f"{s}_ddot") for s in names], t=sub.get(eom.t, eom.t),
                             params=dict(params or {}), symbolic=True)

    if q0 is None:
        raise ModelError("linearize: the state q0 is required (or pass symbolic=True)")
    qv = np.array([check_finite(x, f"q0[{k}]") for k, x in zip(names, _values(q0, names, "q0", [0.0] * n))])
    vv = np.array([check_finite(x, f"v0[{k}]") for k, x in zip(names, _values(v0, names, "v0", [0.0] * n))])
    tv = 0.0 if t is None else check_finite(t, "t")
    values = _parameter_values(eom, params, numeric=True)
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


# ---------------------------------------------------------------------- constrained systems
def _state_numbers(model, q0, v0, t, params: Mapping[str, float] | None):
    """(names, q, v, t, parameter values by name) of a state, checked."""
    names = [s.name for s in model.coords]
    n = len(names)
    if q0 is None:
        raise ModelError("linearize: the state q0 is required")
    qv = np.array([check_finite(x, f"q0[{k}]") for k, x in zip(names, _values(q0, names, "q0", [0.0] * n))])
    vv = np.array([check_finite(x, f"v0[{k}]") for k, x in zip(names, _values(v0, names, "v0", [0.0] * n))])
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


def _nonsingular(B: np.ndarray, scale: float) -> bool:
    if B.size == 0:
        return True
    s = np.linalg.svd(B, compute_uv=False)
    return bool(s[-1] > 1e-9 * max(scale, 1e-300))


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
        rest = [i for i in everything if i not in dep_h]
        schur = A[JH:, rest]
        if JH:
            schur = schur - A[JH:, dep_h] @ np.linalg.solve(Ah[:, dep_h], Ah[:, rest])
        dep_n = [rest[i] for i in _pivot_columns(schur, list(range(len(rest))), J - JH)]
        dep = sorted(dep_h + dep_n)
        if not _nonsingular(A[:, dep], scale):
            raise ModelError(f"linearize: the constraint Jacobian A ({J}x{n}) has rank < {J} at this state "
                             f"({dependent_rows(A)}): redundant constraints or a singular configuration")
        return dep, dep_h
    chosen = [independent] if isinstance(independent, str) else list(independent)
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
        schur = A[JH:, ind] - A[JH:, dep_h] @ np.linalg.solve(Ah[:, dep_h], Ah[:, ind])
        dep_n = [ind[i] for i in _pivot_columns(schur, list(range(len(ind))), J - JH)]
        dep = sorted(dep_h + dep_n)
        if not _nonsingular(A[:, dep], scale):
            raise ModelError(f"linearize: the constraint Jacobian A ({J}x{n}) has rank < {J} at this state "
                             f"({dependent_rows(A)})")
        return dep, dep_h
    counts = f"the {n - J} independent speeds"
    if JH:
        counts += f" or the {n - JH} independent coordinates"
    raise ModelError(f"linearize: independent names {len(ind)} coordinate(s) ({shown}); give {counts} "
                     f"({n} coordinates, {JH} holonomic and {J - JH} nonholonomic constraints)")


def _linearize_constrained(system: ConstrainedSystem, q0, v0, t, params, independent, a0, tol: float) -> Linearization:
    """:func:`linearize` of a constrained system about a steady motion (see there)."""
    model = system.model
    if system.J == 0:  # inequalities only: nothing to eliminate
        return linearize(system.derived(), q0, v0, t, params)
    names, qv, vv, tv, values = _state_numbers(model, q0, v0, t, params)
    n, J, JH = system.n, system.J, system.n_holonomic
    where = ", ".join(f"{k}={x:g}" for k, x in zip(names, qv))
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
        [check_finite(a_, f"a0[{k}]") for k, a_ in zip(names, _values(a0, names, "a0", [0.0] * n))])
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
    S = np.einsum("jik,i->jk", x["dAdq"], vv) + x["dA0dq"]

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
    Mr = B0.T @ M @ B0
    Cr = B0.T @ (M @ D @ B0 + C @ B0)
    Kr = B0.T @ (M @ D @ D + C @ D + K) @ P
    return Linearization(coordinates=[names[i] for i in indq], M=Mr, C=Cr, K=Kr, q0=qv, v0=vv, a0=acc, t=tv,
                         params=values, symbolic=False, speeds=[names[i] for i in ind], G=B0[indq, :],
                         H=(D @ P)[indq, :], multipliers=lam0, residual=max(res_dyn, res_acc),
                         dependent_speeds=[names[i] for i in dep], dependent_coordinates=[names[i] for i in dep_h])


def _constrained_accelerations(M: np.ndarray, F: np.ndarray, A: np.ndarray, gamma: np.ndarray) -> np.ndarray:
    """q'' of [M A^T; A 0][q''; -lambda] = [F; gamma] (eq. 4.5), least squares if singular."""
    n, J = M.shape[0], A.shape[0]
    K = np.block([[M, A.T], [A, np.zeros((J, J))]])
    return np.linalg.lstsq(K, np.concatenate([F, gamma]), rcond=None)[0][:n]
