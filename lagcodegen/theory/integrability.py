"""The Frobenius test of Pfaffian constraints (notes, eq. 4.3): is A . dq + A0 dt = 0 integrable?

A single 1-form w = sum_i A_i dq_i + A0 dt has an integrating factor, so that the constraint is
holonomic (eq. 4.1), exactly when w ^ dw = 0. :func:`integrability` decides every component of
w ^ dw by evaluation at random points and, for the components that vanish there, symbolically
(within a budget); :class:`~lagcodegen.theory.constraints.ConstrainedSystem` runs it on its
nonholonomic constraints.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import Sequence

import numpy as np
import symengine as se
import sympy as sp

from ..derivation import pythagoras, to_se

__all__ = ["FROBENIUS_SAMPLES", "FROBENIUS_SIMPLIFY_OPS", "IntegrabilityReport", "frobenius_terms", "integrability"]


@dataclass(frozen=True)
class IntegrabilityReport:
    """Result of the Frobenius test w ^ dw = 0 for one Pfaffian form w = A . dq + A0 dt."""

    integrable: bool
    obstruction: dict  # (var_i, var_j, var_k) names -> sympy expression not identically zero
    proven: bool  # True: decided symbolically; False: decided from numerical samples

    def __bool__(self) -> bool:
        return self.integrable


def frobenius_terms(A: Sequence, A0, coords: Sequence[sp.Symbol], t: sp.Symbol) -> dict:
    """The components of w ^ dw for w = sum_i A_i dq_i + A0 dt, one per triple of variables.

    With the variables x = (q_1..q_n, t) and coefficients a = (A_1..A_n, A0), the component
    on dx_i ^ dx_j ^ dx_k (i < j < k) is

        a_i (d_j a_k - d_k a_j) + a_j (d_k a_i - d_i a_k) + a_k (d_i a_j - d_j a_i).

    A single 1-form is integrable (has an integrating factor, so that the constraint is
    holonomic, eq. 4.1) exactly when all of them vanish (Frobenius).
    """
    xs = list(coords) + [t]
    a = [sp.sympify(c) for c in A] + [sp.sympify(A0)]
    out = {}
    for i, j, k in itertools.combinations(range(len(xs)), 3):
        xi, xj, xk = xs[i], xs[j], xs[k]
        term = (a[i] * (sp.diff(a[k], xj) - sp.diff(a[j], xk))
                + a[j] * (sp.diff(a[i], xk) - sp.diff(a[k], xi))
                + a[k] * (sp.diff(a[j], xi) - sp.diff(a[i], xj)))
        out[(xi.name, xj.name, xk.name)] = term
    return out


def _frobenius_terms_se(A: Sequence, A0, coords: Sequence[sp.Symbol], t: sp.Symbol) -> dict:
    """:func:`frobenius_terms` in symengine (each coefficient differentiated once per variable)."""
    xs = [se.Symbol(x.name) for x in list(coords) + [t]]
    a = [to_se(c, "constraint coefficient") for c in list(A) + [A0]]
    d = [[se.diff(ai, x) for x in xs] for ai in a]  # d[k][j] = d a_k / d x_j
    out = {}
    for i, j, k in itertools.combinations(range(len(xs)), 3):
        term = (a[i] * (d[k][j] - d[j][k]) + a[j] * (d[i][k] - d[k][i]) + a[k] * (d[j][i] - d[i][j]))
        out[(xs[i].name, xs[j].name, xs[k].name)] = term
    return out


#: Random points at which every component of w ^ dw is evaluated (each symbol, parameters too, in [0.3, 1.7]).
FROBENIUS_SAMPLES = 12
#: The Frobenius test's budget: a component of w ^ dw that vanishes at every sample and is not zero
#: once expanded with sin^2 = 1 - cos^2 goes to ``sympy.simplify`` only up to this many operations
#: (simplify grows fast with the size); a larger one is decided by the samples (``proven`` False).
FROBENIUS_SIMPLIFY_OPS = 400


def integrability(A: Sequence, A0, coords: Sequence[sp.Symbol], t: sp.Symbol, seed: int = 0) -> IntegrabilityReport:
    """Frobenius test (w ^ dw = 0, time included) for the Pfaffian form A . dq + A0 dt (eq. 4.3).

    Each component of w ^ dw (:func:`frobenius_terms`) is decided by evaluation at random points
    (every symbol, parameters included, gets a random value in [0.3, 1.7]: integrability must hold
    for generic parameters; a clearly nonzero value proves non-integrability) and, when those
    vanish, by symbolic simplification (``proven`` is False if it could not be reduced to 0, or was
    over the budget FROBENIUS_SIMPLIFY_OPS, and the decision rests on the samples). The components
    are built and evaluated with symengine (one compiled function for all of them): a
    nonintegrable constraint costs no simplification.
    """
    terms = _frobenius_terms_se(A, A0, coords, t)
    keys = [k for k, e in terms.items() if e != 0]
    rng = np.random.default_rng(seed)
    obstruction = {}
    proven = True
    if not keys:
        return IntegrabilityReport(integrable=True, obstruction={}, proven=True)
    symbols = sorted(set().union(*(terms[k].free_symbols for k in keys)), key=lambda s: s.name)
    if symbols:
        fn = se.Lambdify(symbols, [terms[k] for k in keys], real=True)
        with np.errstate(all="ignore"):
            samples = np.array([np.asarray(fn(rng.uniform(0.3, 1.7, len(symbols))), dtype=float).ravel()
                                for _ in range(FROBENIUS_SAMPLES)])
    else:
        samples = np.array([[float(terms[k]) for k in keys]])
    for col, key in enumerate(keys):
        vals = samples[:, col]
        vals = vals[np.isfinite(vals)]
        if np.any(np.abs(vals) > 1e-9):  # certainly not zero
            obstruction[key] = sp.sympify(terms[key])
            continue
        if pythagoras(terms[key]) == 0:  # expanded, sin^2 = 1 - cos^2: proven zero, cheaply
            continue
        expr = sp.sympify(terms[key])
        simplified = expr
        if sp.count_ops(expr) <= FROBENIUS_SIMPLIFY_OPS:  # the budget: larger ones rest on the samples
            try:
                simplified = sp.simplify(expr)
            except Exception:  # pragma: no cover - simplify failures are sympy's
                pass
        if simplified == 0:
            continue
        proven = False
        if vals.size == 0:  # no finite sample and no simplification: not shown to vanish
            obstruction[key] = expr
    return IntegrabilityReport(integrable=not obstruction, obstruction=obstruction, proven=proven)
