"""A link's inertia as its dynamic parameters (m, h = m c, I_o about the link frame's origin:
:data:`lagcodegen.model.bodies.DYNAMIC_PARAMETERS`) moved into the frame of the tree node that
carries it, linearly: the equations of motion stay linear in the parameters (what identification
by least squares needs; :mod:`lagcodegen.model.regressor`).

A rigid displacement r' = p + R r of the link frame into the node frame gives

    m' = m,  h' = m p + R h,
    I_o' = R I_o R^T + m (|p|^2 1 - p p^T) + 2 (p . R h) 1 - p (R h)^T - (R h) p^T

(the sum of m_i (|r'|^2 1 - r' r'^T) over the body's mass points).
"""

from __future__ import annotations

import symengine as se

from ..errors import ModelError
from ..util import excerpt


def _se(e, what: str):
    try:
        return se.sympify(e)
    except Exception as exc:  # symengine raises several types
        raise ModelError(f"{what} cannot be handled by the derivation engine: {excerpt(e)} "
                         f"({excerpt(str(exc), quote=False)})") from None


def placed_inertia(origin_inertia: tuple, place) -> tuple:
    """(m, h, I_o) (symengine; h a list, I_o a list of rows) of a link's ``origin_inertia``
    (:attr:`lagcodegen.model.bodies.Link.origin_inertia`) in the node frame where the link frame
    sits at ``place`` (a :class:`~lagcodegen.model.bodies.Placement`; None: the node frame)."""
    m0, h0, I0 = origin_inertia
    m = _se(m0, "mass")
    h = [_se(x, "first moment") for x in h0]
    Io = [[_se(I0[i, j], "inertia") for j in range(3)] for i in range(3)]
    if place is None:
        return m, h, Io
    R = se.DenseMatrix(3, 3, [_se(c, "placement") for c in place.rotation])
    p = [_se(c, "placement") for c in place.translation]
    Rh = list(R * se.DenseMatrix(3, 1, h))
    RIR = R * se.DenseMatrix(3, 3, [x for row in Io for x in row]) * R.T
    pp = se.Add(*(x * x for x in p))
    pRh = se.Add(*(a * b for a, b in zip(p, Rh)))
    out = [[se.expand(RIR[i, j] - m * p[i] * p[j] - p[i] * Rh[j] - Rh[i] * p[j]
                      + ((m * pp + 2 * pRh) if i == j else 0)) for j in range(3)] for i in range(3)]
    return m, [se.expand(m * p[i] + Rh[i]) for i in range(3)], out
