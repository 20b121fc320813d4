"""Independent speeds: a constrained system's velocity constraints eliminated (Maggi's, Voronets'
and Kane's form), the formulation "minimal" of systems with nonholonomic constraints.

Every equality constraint at velocity level, A(q, t) q' + A0(q, t) = 0 (eq. 4.3; holonomic rows
from eq. 4.2), J rows over n coordinates. With n - J *independent speeds* u (the rates of n - J
of the coordinates) the dependent rates follow by solving the constraint,

    q'_dep = -A_dep^-1 (A_ind u + A0),  i.e.  q' = B(q, t) u + b(q, t),  A B = 0,

and Lagrange's equations projected onto the speeds, B^T (M q'' - F) = 0 with q'' = B u' + B' u
+ b', are M_r u' = F_r with M_r = B^T M B (the design brief's generalized speeds; the
derivation's :func:`~lagcodegen.derivation._project` computes them from the model with the
kinematic equations q' = B u + b). The multipliers drop out (they can be recovered from the full
equations). The state is (q in R^n, u in R^(n-J)); a holonomic constraint then holds through its
rate only and drifts at the integration's tolerance (its residual g_j is an output).

Which speeds are independent: given, or chosen by column-pivoted QR of A at a random state
(the pivot columns are dependent). The choice is singular where A_dep is: the generated code
then divides by zero there (a run stops with a non-finite value).
"""

from __future__ import annotations

import copy
from typing import Sequence

import numpy as np
import scipy.linalg
import sympy as sp

from ..errors import ModelError
from ..model.model import Model
from .constraints import ConstrainedSystem


def random_state(system: ConstrainedSystem, seed: int = 0) -> dict:
    """A random state (symbols -> numbers): coordinates in [-1, 1], parameters at their defaults,
    t = 0.3."""
    model = system.model
    at = {q: float(x) for q, x in zip(model.coords, np.random.default_rng(seed).uniform(-1.0, 1.0, model.n))}
    at.update({s: float(v) for s, v in model.params.items()})
    at[model.t] = 0.3
    return at


def numeric_A(system: ConstrainedSystem, at: dict) -> np.ndarray:
    """The constraint matrix A at the point ``at`` (symbols -> numbers)."""
    try:
        return np.array(system.A.subs(at).evalf(), dtype=float)
    except (TypeError, ValueError):
        raise ModelError("independent speeds: the constraint matrix A does not evaluate to numbers at the state "
                         "(a symbol that is no coordinate or parameter?)") from None


def choose_independent(system: ConstrainedSystem, independent: Sequence[str] | None = None,
                       A: np.ndarray | None = None) -> tuple[list[int], list[int]]:
    """(independent coordinate indices, dependent ones): ``independent`` (coordinate names whose
    rates are the speeds), checked, or chosen by column-pivoted QR of ``A`` (the constraint matrix
    at a state, numbers; None: at :func:`random_state`): its pivot columns are the dependent rates."""
    model = system.model
    n, J = model.n, system.J
    if A is None:
        A = numeric_A(system, random_state(system))
    if independent is not None:
        if isinstance(independent, str):
            independent = independent.replace(",", " ").split()
        ind = sorted({model.index(name) for name in independent})
        if len(ind) != n - J:
            raise ModelError(f"independent speeds: {len(ind)} given, but {n} coordinates and {J} constraints leave "
                             f"{n - J}")
        dep = [i for i in range(n) if i not in ind]
        if J and np.linalg.matrix_rank(A[:, dep]) < J:
            raise ModelError(f"independent speeds {', '.join(model.coords[i].name for i in ind)}: the constraints "
                             f"cannot be solved for the rates of {', '.join(model.coords[i].name for i in dep)} "
                             "(A_dep is singular at the state); choose other independent speeds")
        return ind, dep
    if J == 0:
        return list(range(n)), []
    _, R, piv = scipy.linalg.qr(A, pivoting=True)
    rank = int(np.sum(np.abs(np.diag(R)) > 1e-10 * max(1.0, np.abs(R).max())))
    if rank < J:
        raise ModelError(f"independent speeds: the {J} constraints have rank {rank} at the state (dependent rows, "
                         "or a configuration where no choice of speeds is regular)")
    dep = sorted(int(i) for i in piv[:J])
    return [i for i in range(n) if i not in dep], dep


def pivoted_solve(A: sp.Matrix, b: sp.Matrix, at: dict) -> tuple[sp.Matrix, tuple]:
    """x with A x = b by Gaussian elimination, symbolically, each pivot the entry of largest
    magnitude at the numeric point ``at`` (symbols -> numbers; sympy's structural LU may divide by
    an expression that vanishes at the state, e.g. sin(phi) upright). Returns (x, the pivot rows
    in order): a solution regular wherever those pivots do not vanish."""
    m = A.shape[0]
    A, b = A.copy(), b.copy()
    rows = list(range(m))
    order = []
    for k in range(m):
        values = [abs(complex(A[r, k].evalf(subs=at))) for r in rows[k:]]
        best = k + int(np.argmax(values))
        if values[best - k] < 1e-12:
            raise ModelError("independent speeds: the constraints cannot be solved for the dependent rates at the "
                             "initial state (A_dep is singular there)")
        rows[k], rows[best] = rows[best], rows[k]
        order.append(rows[k])
        pivot = A[rows[k], k]
        for r in rows[k + 1:]:
            factor = A[r, k] / pivot
            if factor != 0:
                A[r, :] = A[r, :] - factor * A[rows[k], :]
                b[r] = b[r] - factor * b[rows[k]]
    x = [sp.Integer(0)] * m
    for k in reversed(range(m)):
        r = rows[k]
        x[k] = (b[r] - sum((A[r, j] * x[j] for j in range(k + 1, m)), sp.Integer(0))) / A[r, k]
    return sp.Matrix(x), tuple(order)


def independent_speeds_model(system: ConstrainedSystem, *, independent: Sequence[str] | None = None,
                             name: str | None = None, at: dict | None = None) -> Model:
    """The model of ``system`` in independent speeds (module docstring): a copy of its model
    with the generalized speeds u (the independent coordinates' rates, named ``<q>_dot`` as
    before) and the kinematic equations q' = B u + b of every coordinate; the holonomic
    constraints' residuals as outputs ``g_<j>``. Inequality constraints are refused. ``at``
    (symbols -> numbers, e.g. the initial state and parameters; default :func:`random_state`): the
    dependent rates are solved with the pivots largest there (:func:`pivoted_solve`)."""
    if not isinstance(system, ConstrainedSystem):
        raise ModelError(f"independent speeds need a ConstrainedSystem, got {type(system).__name__}")
    if system.inequalities:
        raise ModelError("independent speeds: inequality constraints are not taken (use formulation 'index1', "
                         "whose impact driver does)")
    model = system.model
    at = random_state(system) if at is None else at
    ind, dep = choose_independent(system, independent, numeric_A(system, at))
    A, A0 = system.A, system.A0
    qd = sp.Matrix(model.speeds)
    rates: list = list(model.speeds)
    if dep:
        A_dep = A[:, dep]
        rhs = -(A[:, ind] * sp.Matrix([qd[i] for i in ind]) + A0)
        solved, _ = pivoted_solve(A_dep, rhs, at)
        for k, i in enumerate(dep):
            rates[i] = solved[k]
    reduced = copy.deepcopy(model)
    reduced.name = name or f"{model.name}_speeds"
    reduced.generalized_speeds([model.speeds[i].name for i in ind], rates)
    for j, f in enumerate(system.holonomic):
        reduced.output(f"g_{j}", f)
    return reduced
