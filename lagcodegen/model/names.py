"""The names a model's symbols may take, and what a user states as sympy expressions: one
place for the checks :class:`~lagcodegen.model.model.Model` and its speeds
(:mod:`lagcodegen.model.speeds`) apply."""

from __future__ import annotations

import keyword
import unicodedata

import sympy as sp

from ..errors import ModelError
from ..util import excerpt, lookalike

#: Names a coordinate or parameter may not take (they name other things).
RESERVED_NAMES = frozenset({"t", "pi", "E", "I", "oo", "nan", "zoo"})
#: No model name starts with this: the symbols lagcodegen invents while it derives and
#: generates (e.g. the accelerations ``__acc<i>`` of the analytic Jacobian) use it, so that
#: they can never be a user's coordinate or parameter.
RESERVED_PREFIX = "__"
#: Suffixes of the symbols every coordinate q brings along: its velocity ``<q>_dot`` and its
#: acceleration ``<q>_ddot`` (:meth:`EquationsOfMotion.accelerations`).
DERIVED_SUFFIXES = ("_dot", "_ddot")


def check_name(name: str, what: str) -> str:
    """``name`` if a coordinate, parameter, link or speed may take it, else a ModelError naming
    ``what`` and the reason (not an identifier, a look-alike character, reserved)."""
    if not isinstance(name, str) or not name.isidentifier() or keyword.iskeyword(name):
        raise ModelError(f"{what} name {excerpt(name)} is not a valid identifier")
    changed = lookalike(name)
    if changed:
        raise ModelError(f"{what} name {excerpt(name)} has the look-alike character {changed} in expressions "
                         f"(Python normalizes names, NFKC): it could not be told from "
                         f"{excerpt(unicodedata.normalize('NFKC', name))}; write the name in plain characters")
    if name in RESERVED_NAMES:
        raise ModelError(f"{what} name {name!r} is reserved")
    if name.startswith(RESERVED_PREFIX):
        raise ModelError(f"{what} name {name!r} starts with {RESERVED_PREFIX!r}, which is reserved for the "
                         "symbols lagcodegen generates")
    return name


def as_expr(value, what: str) -> sp.Expr:
    """``value`` as a sympy expression, else a ModelError naming ``what``."""
    try:
        expr = sp.sympify(value, strict=True)
    except (sp.SympifyError, TypeError) as exc:
        raise ModelError(f"{what} is not a symbolic expression: {excerpt(value)}") from exc
    return expr
