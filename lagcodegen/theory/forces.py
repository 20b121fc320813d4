"""Generalized forces as the notes state them, in sympy: eqs. 2.6, 2.7, 3.4 and 3.14.

:mod:`lagcodegen.derivation` computes the same quantities internally (on symengine) while
forming M q'' = F; this module is the public, readable statement of the relations, used to
verify the derivation and to explain it:

* :func:`generalized_force_from_cartesian`: Q_i = sum_j F_j dx_j/dq_i (eq. 2.6);
* :func:`generalized_force_from_potential`: Q_i = -dV/dq_i (eq. 2.7);
* :func:`generalized_force_from_generalized_potential`: Q_i = d/dt(dU/dq_i') - dU/dq_i (eq. 3.4);
* :func:`dissipative_force`: Q_i = -dD/dq_i' (eq. 3.14).

Velocities are plain symbols (``<q>_dot`` in a :class:`~lagcodegen.model.Model`), and
accelerations, where a total time derivative needs them, are the symbols ``<q>_ddot``.
"""

from __future__ import annotations

from typing import Sequence

import sympy as sp

from ..errors import ModelError


def accelerations(q: Sequence[sp.Symbol]) -> list[sp.Symbol]:
    """The symbols q_i'' named ``<q>_ddot`` (as in :meth:`EquationsOfMotion.accelerations`)."""
    return [sp.Symbol(f"{qi.name}_ddot") for qi in q]


def total_time_derivative(expr, q: Sequence[sp.Symbol], qdot: Sequence[sp.Symbol], t: sp.Symbol,
                          qddot: Sequence | None = None) -> sp.Expr:
    """d/dt of expr(q, q', t) along a motion: sum_i (d/dq_i q_i' + d/dq_i' q_i'') + d/dt.

    ``qddot`` defaults to the symbols ``<q>_ddot``; pass expressions (e.g. M^{-1} F) to
    differentiate along the solutions of the equations of motion.
    """
    q, qdot = list(q), list(qdot)
    qddot = accelerations(q) if qddot is None else list(qddot)
    if not len(q) == len(qdot) == len(qddot):
        raise ModelError(f"q, q' and q'' have different lengths ({len(q)}, {len(qdot)}, {len(qddot)})")
    expr = sp.sympify(expr)
    out = sp.diff(expr, t)
    for qi, vi, ai in zip(q, qdot, qddot):
        out += sp.diff(expr, qi) * vi + sp.diff(expr, vi) * ai
    return out


def generalized_force_from_cartesian(F: Sequence, x: Sequence, q: Sequence[sp.Symbol]) -> sp.Matrix:
    """Q_i = sum_j F_j dx_j/dq_i (eq. 2.6).

    ``F`` and ``x`` are matching Cartesian components (stack several points' components to
    add their forces); ``x`` is a function of (q, t).
    """
    F, x = list(F), list(x)
    if len(F) != len(x):
        raise ModelError(f"F has {len(F)} components, x has {len(x)}")
    return sp.Matrix([sum((sp.sympify(Fj) * sp.diff(xj, qi) for Fj, xj in zip(F, x)), sp.Integer(0))
                      for qi in q])


def generalized_force_from_potential(V, q: Sequence[sp.Symbol]) -> sp.Matrix:
    """Q_i = -dV/dq_i (eq. 2.7), V written in the generalized coordinates."""
    return sp.Matrix([-sp.diff(V, qi) for qi in q])


def generalized_force_from_generalized_potential(U, q: Sequence[sp.Symbol], qdot: Sequence[sp.Symbol],
                                                 t: sp.Symbol) -> sp.Matrix:
    """Q_i = d/dt(dU/dq_i') - dU/dq_i (eq. 3.4) for a generalized potential U(q, q', t).

    d/dt is the total derivative along the motion (:func:`total_time_derivative`), so the
    result is in (q, q', q'', t), with q_i'' the symbols ``<q>_ddot``. Example: a charge e in
    fields phi, A has U = e (phi - q' . A), and Q is the Lorentz force e (E + v x B).
    """
    return sp.Matrix([total_time_derivative(sp.diff(U, vi), q, qdot, t) - sp.diff(U, qi)
                      for qi, vi in zip(q, qdot)])


def dissipative_force(D, qdot: Sequence[sp.Symbol]) -> sp.Matrix:
    """Q_i = -dD/dq_i' (eq. 3.14) for a Rayleigh dissipation function D (eq. 3.15)."""
    return sp.Matrix([-sp.diff(D, vi) for vi in qdot])
