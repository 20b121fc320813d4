"""Typed values of a model file, read with located errors.

One job: :class:`_Reader`, the base of the loader, turns the parsed TOML values into what
the model needs (tables, strings, expressions, vectors, 3x3 matrices, constants) and refuses
anything else with a :class:`~.locate.ModelFileError` at the value's line.
"""

from __future__ import annotations

import difflib
import math
from contextlib import contextmanager
from typing import Iterator, Mapping, Sequence

import sympy as sp

from ..errors import ModelError
from ..util import excerpt
from .expressions import ExpressionError, parse_expression
from .locate import ModelFileError, _format_key, _Key, _Locator


def _type_name(value: object) -> str:
    if isinstance(value, bool):
        return "a boolean"
    return {int: "an integer", float: "a float", str: "a string", list: "an array",
            dict: "a table"}.get(type(value), f"a {type(value).__name__}")


class _Reader:
    """Reads typed values; ``symbols`` are the names expressions may use, ``velocities`` the
    velocity names (allowed only where ``velocities=True``) mapped to why not elsewhere."""

    def __init__(self, text: str, filename: str):
        self.text = text
        self.filename = filename
        self.locate = _Locator(text, filename)
        self.symbols: dict[str, sp.Basic] = {}
        self.velocities: dict[str, str] = {}

    # ------------------------------------------------------------------ errors
    def error(self, path: Sequence[_Key], message: str, token: str | None = None,
              needle: str | None = None) -> ModelFileError:
        return self.locate.error(path, message, needle=needle, token=token)

    @contextmanager
    def at(self, path: Sequence[_Key], needle: str | None = None) -> Iterator[None]:
        """Locate ModelErrors raised by the Model API at ``path``."""
        try:
            yield
        except ModelFileError:
            raise
        except ModelError as exc:
            raise self.error(path, str(exc), needle=needle) from None

    # ------------------------------------------------------------------ structure
    def fields(self, path: Sequence[_Key], table: dict, required: Sequence[str] = (),
               optional: Sequence[str] = ()) -> None:
        """Refuse unknown keys (typos) and report missing required keys."""
        allowed = list(required) + list(optional)
        for key in table:
            if key not in allowed:
                close = difflib.get_close_matches(key, allowed, n=1)
                hint = f"; did you mean {close[0]!r}?" if close else ""
                raise self.error([*path, key], f"unknown key {excerpt(key)}{hint} (allowed: {', '.join(allowed)})",
                                 token=key)
        for key in required:
            if key not in table:
                raise self.error(path, f"missing required key {key!r}", token=key, needle="")

    def table(self, path: Sequence[_Key], value: object) -> dict:
        if not isinstance(value, dict):
            raise self.error(path, f"must be a table, got {_type_name(value)}", token=_format_key(path))
        return value

    def tables(self, path: Sequence[_Key], value: object) -> list[dict]:
        if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
            raise self.error(path, f"must be an array of tables ([[{_format_key(path)}]])",
                             token=_format_key(path))
        return value

    def string(self, path: Sequence[_Key], value: object) -> str:
        if not isinstance(value, str):
            raise self.error(path, f"must be a string, got {_type_name(value)}", token=repr(value))
        return value

    def strings(self, path: Sequence[_Key], value: object) -> list[str]:
        if not isinstance(value, list):
            raise self.error(path, f"must be an array of strings, got {_type_name(value)}", token=repr(value))
        return [self.string([*path, i], v) for i, v in enumerate(value)]

    # ------------------------------------------------------------------ values
    def expr(self, path: Sequence[_Key], value: object, velocities: bool = False,
             extra: Mapping[str, sp.Basic] | None = None) -> sp.Expr:
        """An expression: a TOML number or a string parsed by :func:`parse_expression`
        (``extra``: more names allowed here, e.g. the multipliers in events)."""
        if isinstance(value, bool) or not isinstance(value, (int, float, str)):
            raise self.error(path, f"must be a number or an expression string, got {_type_name(value)}",
                             token=repr(value))
        if isinstance(value, int):
            return sp.Integer(value)
        if isinstance(value, float):
            if not math.isfinite(value):
                raise self.error(path, f"must be finite, got {value}", token=str(value))
            return sp.Float(value)
        symbols = self.symbols if velocities else {
            name: sym for name, sym in self.symbols.items() if name not in self.velocities}
        if extra:
            symbols = {**symbols, **extra}
        try:
            return parse_expression(value, symbols, None if velocities else self.velocities)
        except ExpressionError as exc:
            raise self.error(path, str(exc), token=exc.token, needle=value) from None

    def vector(self, path: Sequence[_Key], value: object, velocities: bool = False,
               sizes: Sequence[int] = (2, 3)) -> list[sp.Expr]:
        if not isinstance(value, list) or len(value) not in sizes:
            got = f"{len(value)} components" if isinstance(value, list) else _type_name(value)
            want = " or ".join(map(str, sizes))
            raise self.error(path, f"must be an array of {want} expressions, got {got}", token=repr(value))
        return [self.expr([*path, i], v, velocities) for i, v in enumerate(value)]

    def matrix3(self, path: Sequence[_Key], value: object) -> sp.Matrix:
        if not isinstance(value, list) or len(value) != 3:
            raise self.error(path, "must be a 3x3 array of expressions", token=repr(value))
        return sp.Matrix([self.vector([*path, i], row, sizes=(3,)) for i, row in enumerate(value)])

    def constant(self, path: Sequence[_Key], value: object) -> float:
        """A finite real number: a TOML number or a constant expression such as ``"pi/2"``."""
        if isinstance(value, bool) or not isinstance(value, (int, float, str)):
            raise self.error(path, f"must be a number, got {_type_name(value)}", token=repr(value))
        if isinstance(value, str):
            try:
                expr = parse_expression(value, {"pi": sp.pi})
            except ExpressionError as exc:
                raise self.error(path, f"{exc} (a constant is expected here)", token=exc.token,
                                 needle=value) from None
            number = float(expr.evalf())
            if not math.isfinite(number):
                raise self.error(path, f"must be a finite number, {excerpt(value)} is {number}", token=value)
            return number
        if not math.isfinite(value):
            raise self.error(path, f"must be a finite number, got {value}", token=str(value))
        return float(value)

    def integer(self, path: Sequence[_Key], value: object, low: int, high: int) -> int:
        """A TOML integer from ``low`` to ``high``."""
        if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
            what = f"an integer >= {low}" if isinstance(value, bool) or not isinstance(value, int) or value < low \
                else f"an integer <= {high}"
            raise self.error(path, f"must be {what}, got {excerpt(value)}", token=repr(value))
        return value

    def array(self, path: Sequence[_Key], value: object) -> list:
        if not isinstance(value, list):
            raise self.error(path, f"must be an array of expressions, got {_type_name(value)}", token=repr(value))
        return value
