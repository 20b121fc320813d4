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

from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np
import symengine as se
import sympy as sp

from ..derivation import EquationsOfMotion, require_lagrange
from ..errors import ModelError
from ..util import check_finite

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

    def _numeric(self, what: str) -> None:
        if self.symbolic:
            raise ModelError(f"{what} needs a numeric linearization (symbolic=False)")

    @property
    def n(self) -> int:
        return len(self.coordinates)

    @property
    def A(self) -> np.ndarray:
        """First-order system matrix [[0, I], [-M^-1 K, -M^-1 C]] (2n x 2n)."""
        self._numeric("A")
        n = self.n
        try:
            MK = np.linalg.solve(self.M, self.K)
            MC = np.linalg.solve(self.M, self.C)
        except np.linalg.LinAlgError:
            raise ModelError("the mass matrix is singular at the linearization state") from None
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


def linearize(eom: EquationsOfMotion, q0=None, v0=None, t: float | None = None,
              params: Mapping[str, float] | None = None, symbolic: bool = False) -> Linearization:
    """Linearize the equations of ``eom`` about (q0, v0, t) (see the module docstring).

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

    Models with generalized speeds (quaternion joints) are refused by name.
    """
    require_lagrange(eom, "linearize")
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
