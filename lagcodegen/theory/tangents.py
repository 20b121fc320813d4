"""The tangents of rough contacts (:class:`~lagcodegen.theory.constraints.Inequality`'s
``tangent``; notes, sec. 4.3): one expression (planar friction, one tangential direction) or a pair (3-D friction,
the circular cone over both), each a position expression in (q, t) whose rate is the slip
velocity, or the slip velocity itself, linear in the speeds."""

from __future__ import annotations

import sympy as sp

from ..errors import ModelError
from ..model.model import Model
from ..util import excerpt


def scalar_expression(value, what: str) -> sp.Expr:
    """``value`` as a scalar sympy expression; ModelError naming ``what`` (and an excerpt of the
    value) when it is none."""
    try:
        expr = sp.sympify(value, strict=True)
    except (sp.SympifyError, TypeError) as exc:
        raise ModelError(f"{what} is not a symbolic expression: {excerpt(value)}") from exc
    if not isinstance(expr, sp.Expr):
        raise ModelError(f"{what} is not a scalar expression: {excerpt(value)}")
    return expr


def check_tangent(model: Model, tangent, what: str):
    """The tangent of a rough contact checked (``what`` names the contact in messages): an
    expression, or a tuple of two for 3-D friction."""
    items = tuple(tangent) if isinstance(tangent, (tuple, list)) else (tangent,)
    if len(items) not in (1, 2):
        raise ModelError(f"{what}: tangent must be one expression or two (3-D friction: two tangential "
                         f"directions), got {len(items)}")
    speeds = set(model.speeds) | set(model.velocities)
    out = []
    for d, item in enumerate(items):
        where = f"{what}, tangent" + ("" if len(items) == 1 else f" {d}")
        e = scalar_expression(item, where)
        model.check_symbols(e, where, allow_speeds=True)
        used = e.free_symbols & speeds
        if used and any(sp.diff(e, a, b) != 0 for a in used for b in used):  # a slip velocity: linear in them
            raise ModelError(f"{where} ({excerpt(e)}) uses speeds ({', '.join(sorted(x.name for x in used))}) "
                             "but is not linear in them: a tangent is a position expression or the slip "
                             "velocity, linear in the speeds")
        out.append(e)
    return out[0] if len(out) == 1 else tuple(out)
