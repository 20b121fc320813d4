"""The result of a linearization (eq. 3.16 to first order): M dq'' + C dq' + K dq = 0 about a state.

:class:`Linearization` holds M, C, K and the state, and gives the first-order matrix A, its
eigenvalues, frequencies and linear stability; :func:`~lagcodegen.theory.linearize.linearize`
makes one for unconstrained equations, and for a constrained system reduced to independent
coordinates and speeds (:mod:`lagcodegen.theory.linearize_constrained`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np
import symengine as se

from ..errors import ModelError

__all__ = ["Linearization", "exact_number", "values_by_name"]


@dataclass
class Linearization:
    """M dq'' + C dq' + K dq = 0 about a state.

    Numeric (default): ``M``, ``C``, ``K`` are numpy arrays and ``q0``, ``v0``, ``a0`` (the
    accelerations at the state) arrays. Symbolic (``linearize(..., symbolic=True)``): sympy
    matrices in the state symbols, with ``a0`` the acceleration symbols ``<q>_ddot`` (to be
    replaced by the solution of M a = F; zero at equilibria); the numeric properties below
    then raise.

    Of a constrained system (eq. 4.5, :mod:`lagcodegen.theory.linearize_constrained`): the
    reduced M_r du' + C_r du + K_r dq = 0 with dq' = H dq + G du, where ``coordinates`` are the
    independent coordinates and ``speeds`` the independent speeds; ``q0``, ``v0``, ``a0`` stay
    the full state (all n coordinates).
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


def values_by_name(val, names: Sequence[str], what: str, default) -> list:
    """``val`` (None: ``default``; a dict by name; or a sequence in ``names`` order) as a list in ``names`` order."""
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


def exact_number(v: float):
    """A float as symengine number: integral values exactly (0 * x must vanish)."""
    return se.Integer(int(v)) if float(v).is_integer() and abs(v) < 2**53 else se.RealDouble(v)
