"""Expressions of a model file, converted to sympy without evaluating any code.

One job: the whitelist. A string is parsed by :func:`ast.parse` and :class:`_Converter` walks
the allowed node types only (numbers, names, ``+ - * / **``, unary ``-``/``+``, calls of
:data:`FUNCTIONS`), refusing everything else, numbers too large to build exactly and integer
powers of expressions above :data:`MAX_POWER`, with an :class:`ExpressionError` that names the
offending token.
"""

from __future__ import annotations

import ast
import difflib
import math
import sys
from typing import Callable, Mapping

import sympy as sp

from ..errors import ModelError
from ..util import excerpt, lookalike

#: Functions an expression may call: name -> (sympy function, number of arguments).
FUNCTIONS: dict[str, tuple[Callable[..., sp.Expr], int]] = {
    "sin": (sp.sin, 1), "cos": (sp.cos, 1), "tan": (sp.tan, 1),
    "asin": (sp.asin, 1), "acos": (sp.acos, 1), "atan": (sp.atan, 1), "atan2": (sp.atan2, 2),
    "sinh": (sp.sinh, 1), "cosh": (sp.cosh, 1), "tanh": (sp.tanh, 1),
    "exp": (sp.exp, 1), "log": (sp.log, 1), "sqrt": (sp.sqrt, 1),
    "abs": (sp.Abs, 1), "sign": (sp.sign, 1),
}

_BINARY_OPS: dict[type, Callable[[sp.Expr, sp.Expr], sp.Expr]] = {
    ast.Add: lambda a, b: a + b,
    ast.Sub: lambda a, b: a - b,
    ast.Mult: lambda a, b: a * b,
    ast.Div: lambda a, b: a / b,
    ast.Pow: lambda a, b: a ** b,
}
_OPERATOR_TEXT = {ast.FloorDiv: "//", ast.Mod: "%", ast.MatMult: "@", ast.LShift: "<<",
                  ast.RShift: ">>", ast.BitOr: "|", ast.BitXor: "^", ast.BitAnd: "&",
                  ast.Invert: "~", ast.Not: "not"}
_CONSTRUCT_TEXT = {
    ast.Attribute: "attribute access", ast.Subscript: "subscript", ast.Lambda: "lambda",
    ast.ListComp: "comprehension", ast.SetComp: "comprehension", ast.DictComp: "comprehension",
    ast.GeneratorExp: "generator expression", ast.Compare: "comparison",
    ast.BoolOp: "boolean operator", ast.IfExp: "conditional expression",
    ast.NamedExpr: "assignment expression", ast.Starred: "starred argument",
    ast.List: "list", ast.Tuple: "tuple", ast.Set: "set", ast.Dict: "dict",
    ast.JoinedStr: "f-string", ast.Await: "await", ast.Yield: "yield", ast.YieldFrom: "yield",
    ast.Slice: "slice",
}
#: Largest integer/rational size (bits) and power size an expression may build exactly.
_MAX_BITS = 4096
_MAX_TEXT = 20_000
#: Largest integer exponent of a power of an expression in the coordinates (``(theta + 1)**100``).
#: The derivation differentiates and expands such powers: its time grows like the square of the
#: exponent (0.2 s at 200, 2.5 s at 1000, unbounded at 100000) and from about 500 on the expanded
#: coefficients (binomials times the exponent) exceed double precision (the C would hold ``inf``).
MAX_POWER = 100
_NON_FINITE = (sp.zoo, sp.oo, -sp.oo, sp.nan)


class ExpressionError(ModelError):
    """An expression string is not allowed; ``token`` is the offending name or construct."""

    def __init__(self, message: str, token: str):
        self.token = token
        super().__init__(message)


def parse_expression(text: str, symbols: Mapping[str, sp.Basic],
                     forbidden: Mapping[str, str] | None = None) -> sp.Expr:
    """Convert an expression string to sympy without evaluating any code.

    ``symbols`` maps the allowed names to sympy objects; ``forbidden`` maps names that exist
    but are not allowed here (e.g. velocities in a position) to the reason. Raises
    :class:`ExpressionError` naming the offending token.
    """
    if len(text) > _MAX_TEXT:
        raise ExpressionError(f"expression is too long ({len(text)} characters)", token=text[:40] + "...")
    try:
        tree = ast.parse(text.strip(), mode="eval")
    except SyntaxError as exc:
        if "integer string conversion" in str(exc.msg):  # a literal beyond Python's digit limit
            raise ExpressionError(f"number too large: an integer of more than {sys.get_int_max_str_digits()} digits "
                                  f"in {excerpt(text)}", token=text) from None
        raise ExpressionError(f"invalid expression syntax ({exc.msg}) in {excerpt(text)}", token=text) from None
    except (ValueError, RecursionError, MemoryError):
        raise ExpressionError(f"expression cannot be parsed: {excerpt(text)}", token=text) from None
    try:
        expr = _Converter(text.strip(), symbols, forbidden or {}).convert(tree)
    except RecursionError:
        raise ExpressionError(f"expression is nested too deeply: {excerpt(text)}", token=text) from None
    if not isinstance(expr, sp.Expr):  # pragma: no cover - every converted node is an Expr
        raise ExpressionError(f"not an expression: {excerpt(text)}", token=text)
    if expr.has(*_NON_FINITE):
        raise ExpressionError(f"expression {excerpt(text)} is not finite", token=text)
    if expr.has(sp.I):
        raise ExpressionError(f"expression {excerpt(text)} has a complex value", token=text)
    return expr


class _Converter:
    """Walks a whitelist of ast nodes and builds the sympy expression directly."""

    def __init__(self, text: str, symbols: Mapping[str, sp.Basic], forbidden: Mapping[str, str]):
        self.text = text
        self.symbols = symbols
        self.forbidden = forbidden

    def source(self, node: ast.AST) -> str:
        return ast.get_source_segment(self.text, node) or type(node).__name__

    def within(self, token: str | None = None) -> str:
        """The expression for a message: all of it, or an excerpt about ``token`` if it is long."""
        return excerpt(self.text, around=token)

    def reject(self, node: ast.AST, what: str) -> ExpressionError:
        token = self.source(node)
        return ExpressionError(f"{what} {excerpt(token)} is not allowed in {self.within(token)}", token=token)

    def convert(self, node: ast.AST) -> sp.Expr:
        if isinstance(node, ast.Expression):
            return self.convert(node.body)
        if isinstance(node, ast.Constant):
            return self.constant(node)
        if isinstance(node, ast.Name):
            return self.name(node)
        if isinstance(node, ast.BinOp):
            return self.binary(node)
        if isinstance(node, ast.UnaryOp):
            return self.unary(node)
        if isinstance(node, ast.Call):
            return self.call(node)
        what = _CONSTRUCT_TEXT.get(type(node), f"Python construct {type(node).__name__}")
        if isinstance(node, ast.Attribute):
            raise ExpressionError(f"attribute access {excerpt(self.source(node))} (attribute {excerpt(node.attr)}) "
                                  f"is not allowed in {self.within(self.source(node))}", token=self.source(node))
        raise self.reject(node, what)

    def constant(self, node: ast.Constant) -> sp.Expr:
        value = node.value
        if type(value) is int:
            if value.bit_length() > _MAX_BITS:
                raise self.reject(node, "number too large:")
            return sp.Integer(value)
        if type(value) is float:
            if not math.isfinite(value):
                raise self.reject(node, "non-finite number")
            return sp.Float(value)
        kind = {str: "string literal", bytes: "bytes literal", bool: "boolean", complex: "complex number",
                type(None): "None", type(...): "Ellipsis"}.get(type(value), "constant")
        raise self.reject(node, kind)

    def written(self, node: ast.Name) -> str:
        """The name as written: Python has NFKC-normalized ``node.id`` (the full-width ``\uff4b`` to
        ``k``), so a look-alike would silently be another name; it is refused, naming the character."""
        text = self.source(node)
        changed = lookalike(text)
        if changed and text != node.id:
            raise ExpressionError(f"name {excerpt(text)} has the look-alike character {changed} (Python normalizes "
                                  f"names, NFKC) in {self.within(text)}; write names in plain characters",
                                  token=text)
        return node.id

    def name(self, node: ast.Name) -> sp.Expr:
        name = self.written(node)
        if name in self.symbols:
            return self.symbols[name]
        if name in self.forbidden:
            raise ExpressionError(f"{name!r} is not allowed here ({self.forbidden[name]}) in {self.within(name)}",
                                  token=name)
        if name in FUNCTIONS:
            raise ExpressionError(f"function {name!r} must be called, as {name}(...), in {self.within(name)}",
                                  token=name)
        close = difflib.get_close_matches(name, list(self.symbols), n=1)
        hint = f"; did you mean {close[0]!r}?" if close else ""
        known = ", ".join(self.symbols) or "none"
        raise ExpressionError(f"unknown name {excerpt(name)} in {self.within(name)}{hint} (known names: {known})",
                              token=name)

    def binary(self, node: ast.BinOp) -> sp.Expr:
        # Long sums and products nest to the left: walk that spine without recursion.
        chain = [node]
        while isinstance(chain[-1].left, ast.BinOp):
            chain.append(chain[-1].left)
        value = self.convert(chain[-1].left)
        for link in reversed(chain):
            value = self.apply(link, value, self.convert(link.right))
        return value

    def apply(self, node: ast.BinOp, left: sp.Expr, right: sp.Expr) -> sp.Expr:
        op = _BINARY_OPS.get(type(node.op))
        if op is None:
            sym = _OPERATOR_TEXT.get(type(node.op), type(node.op).__name__)
            hint = " (use ** for powers)" if isinstance(node.op, ast.BitXor) else ""
            raise ExpressionError(f"operator {sym!r} is not allowed in {self.within(sym)}{hint}", token=sym)
        if isinstance(node.op, ast.Div) and right == 0:
            raise self.reject(node, "division by zero:")
        if isinstance(node.op, ast.Pow) and left.is_Number and right.is_Number:
            self.check_power(node, left, right)
        return self.checked(node, op(left, right))

    def unary(self, node: ast.UnaryOp) -> sp.Expr:
        if isinstance(node.op, ast.USub):
            return -self.convert(node.operand)
        if isinstance(node.op, ast.UAdd):
            return self.convert(node.operand)
        sym = _OPERATOR_TEXT.get(type(node.op), type(node.op).__name__)
        raise ExpressionError(f"operator {sym!r} is not allowed in {self.within(sym)}", token=sym)

    def call(self, node: ast.Call) -> sp.Expr:
        if not isinstance(node.func, ast.Name):
            token = self.source(node.func)
            raise ExpressionError(f"call of {excerpt(token)} is not allowed in {self.within(token)}; only the "
                                  f"functions {', '.join(FUNCTIONS)} may be called", token=token)
        name = self.written(node.func)
        if name not in FUNCTIONS:
            raise ExpressionError(f"function {excerpt(name)} is not allowed in {self.within(name)}; allowed functions: "
                                  f"{', '.join(FUNCTIONS)}", token=name)
        if node.keywords:
            kw = node.keywords[0]
            token = f"{kw.arg}=" if kw.arg else "**"
            raise ExpressionError(f"keyword argument {excerpt(token)} in call of {name!r} is not allowed in "
                                  f"{self.within(token)}", token=token)
        for arg in node.args:
            if isinstance(arg, ast.Starred):
                raise self.reject(arg, "starred argument")
        func, arity = FUNCTIONS[name]
        if len(node.args) != arity:
            plural = "s" if arity != 1 else ""
            raise ExpressionError(f"function {name!r} takes {arity} argument{plural}, got {len(node.args)} in "
                                  f"{self.within(name)}", token=name)
        return self.checked(node, func(*(self.convert(a) for a in node.args)))

    def check_power(self, node: ast.BinOp, base: sp.Expr, exponent: sp.Expr) -> None:
        """Refuse numeric powers whose exact value would be huge (e.g. ``9**9**9``)."""
        if base.is_Rational:
            size = max(abs(int(base.p)).bit_length(), int(base.q).bit_length())
        else:
            magnitude = abs(float(base))
            size = abs(math.log2(magnitude)) + 1 if magnitude else 0
        if abs(float(exponent)) * size > _MAX_BITS:
            raise self.reject(node, "numeric power too large:")

    def checked(self, node: ast.AST, value: sp.Expr) -> sp.Expr:
        """Refuse non-finite or oversized numeric results (``0**-1``, ``log(0)``, ``10.0**400``)."""
        if value in _NON_FINITE:
            raise self.reject(node, "non-finite value:")
        for term in (value, *(value.args if value.is_Mul or value.is_Add else ())):
            if term.is_Number and term is not value and not _in_double_range(term):
                token = self.source(node)
                raise ExpressionError(f"{excerpt(token)} makes the number {term.evalf(3)}, "
                                      f"outside double precision range, in {self.within(token)}", token=token)
            if term.is_Pow and term.exp.is_Integer and abs(int(term.exp)) > MAX_POWER and not term.base.is_Number:
                token = self.source(node)
                raise ExpressionError(f"power {excerpt(str(term))} in {self.within(token)} has the exponent "
                                      f"{term.exp}: integer powers of expressions are limited to "
                                      f"{MAX_POWER} (the derivation expands them; write the model with a "
                                      f"lower power or a new coordinate)", token=token)
        if value.is_Number:
            if value.is_Rational and max(abs(int(value.p)).bit_length(), int(value.q).bit_length()) > _MAX_BITS:
                raise self.reject(node, "number too large:")
            if not _in_double_range(value):
                raise self.reject(node, "number outside double precision range:")
        return value


def _in_double_range(value: sp.Expr) -> bool:
    """True if the number ``value`` converts to a finite double."""
    try:
        return math.isfinite(float(value))
    except OverflowError:
        return False
