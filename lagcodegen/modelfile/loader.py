"""Declarative model files: a mechanical model and its simulation settings in TOML.

A build step can describe a model without writing Python::

    [model]
    name = "double_pendulum"              # optional; default: the file's stem (or "model")
    coordinates = ["theta1", "theta2"]

    [parameters]                          # name = default value (finite number)
    l1 = 1.0
    g = 9.81

    [[points]]                            # optional named points (anchors, attachment points)
    name = "anchor"
    position = [0, 0]

    [[particles]]                         # name, mass, position (2 or 3 components)
    name = "bob1"
    mass = "m1"
    position = ["l1*sin(theta1)", "-l1*cos(theta1)"]

    [[planar_bodies]]                     # name, mass, inertia, position (2), angle
    [[rigid_bodies]]                      # name, mass, inertia, position (3), orientation
                                          # inertia: 3 principal moments or a 3x3 array;
                                          # orientation: 3x3 array (body -> world rotation)
    [gravity]                             # g; up optional (default: last axis)
    g = "g"
    up = [0, 1]

    [[springs]]                           # a, b: point names or positions; k; rest_length, label optional
    a = "bob1"
    b = "anchor"
    k = "k"

    [[dampers]]                           # point, c; b (second point), label optional
    [[forces]]                            # point, vector; label optional
    [[generalized_forces]]                # coordinate, expr; label optional
    [energy]                              # kinetic, potential, dissipation (each optional)
    [outputs]                             # name = "expression" (user outputs)

    [constraints]                         # optional (notes, sec. 4); every key optional
    holonomic = ["x**2 + y**2 - l**2"]    # f(q, t) = 0 (eq. 4.1)
    nonholonomic = [                      # A . q' + A0 = 0 (eq. 4.3); A0 optional (default 0)
        { A = ["sin(th)", "-cos(th)", 0], A0 = 0 },      # one coefficient per coordinate, or
        { coefficients = { x = 1, phi = "-R" } },        # by coordinate name (missing ones 0)
    ]
    inequalities = ["y + 2*l"]            # g(q, t) >= 0: monitored (terminal event ineq_<k>)
    integrable = "error"                  # or "allow" (keep an integrable Pfaffian row)

    [[events]]                            # constrained files: root functions
    name = "leave"
    expr = "lambda_0"                     # q, <coord>_dot, t, parameters, multipliers lambda_<j>
    direction = -1                        # -1 decreasing, 0 both, 1 increasing (default 0)
    terminal = true                       # default true

    [simulation]                          # every key optional
    t_start = 0.0
    t_end = 20.0
    n_out = 1001
    method = "adams"                      # or "bdf"
    rtol = 1e-8
    atol = 1e-10
    initial = { theta1 = 1.0, theta2 = 0.5, theta1_dot = 0.0 }
    outputs = ["energy", "positions"]     # scene outputs (see lagcodegen.scene.Scene)
    runtime_parameters = ["g"]            # default: every parameter stays adjustable
    parameters = { g = 1.62 }             # overrides of the parameter defaults
    jacobian = true
    formulation = "index1"                # constrained files: "index1" (default), "ggl", "minimal"
    baumgarte = [5.0, 5.0]                # index1: (alpha, beta); default none
    projection = false                    # index1: project after each step (needs method "bdf")

Each table maps onto one :class:`~lagcodegen.model.Model` call (``particle``, ``point``,
``planar_body``, ``rigid_body``, ``gravity``, ``spring``, ``damper``, ``force``,
``generalized_force``, ``kinetic_energy``, ``potential_energy``, ``dissipation``,
``output``). Where a point is expected (``a``, ``b``, ``point``), a string names a point
(``[[points]]`` or a body) and an array gives a position.

Expressions are TOML numbers or strings such as ``"-l1*cos(theta1)"``. A string is parsed
by :func:`ast.parse` and converted by walking a whitelist of node types: numbers, names,
``+ - * / **``, unary ``-``/``+`` and calls of ``sin cos tan asin acos atan atan2 sinh
cosh tanh exp log sqrt abs sign``. Names are the coordinates, their velocities
``<coord>_dot`` (only in forces, kinetic energy, dissipation, outputs and events), the parameters,
``t`` and ``pi``. Nothing is ever evaluated: no ``eval``, no ``sympify`` of raw text.
Parameter values, ``initial`` values and ``t_start``/``t_end``/``rtol``/``atol`` may be
constant expressions too (``"pi/2"``).

With a ``[constraints]`` table, :attr:`ModelFile.constrained` is the
:class:`~lagcodegen.constraints.ConstrainedSystem` (constraint j, holonomic ones first, has the
multiplier ``lambda_<j>``, counted from 0), :attr:`ModelFile.events` the ``[[events]]`` as
:class:`~lagcodegen.events.Event` items, and :meth:`ModelFile.compile`/:meth:`ModelFile.simulate`
go through :func:`lagcodegen.dae.compile_constrained`. Constrained runs output the requested
outputs (default: energy) plus ``lambda`` (not in minimal coordinates), ``residuals`` and, with
inequality constraints, ``inequalities``.

Every problem raises :class:`ModelFileError` (a :class:`~lagcodegen.errors.ModelError`)
naming the file, the line when it can be found, the key path (``particles[1].position[0]``)
and the offending token.
"""

from __future__ import annotations

import ast
import difflib
import json
import math
import re
import sys
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Iterator, Mapping, Sequence, Union

import numpy as np
import sympy as sp

from .. import hooks
from ..derivation import derive
from ..errors import ModelError
from ..model.events import DIRECTIONS, Event
from ..model.model import Model
from ..model.outputs import CONSTRAINT_OUTPUT_GROUPS, OUTPUT_GROUPS
from ..theory.constraints import FORMULATIONS, ConstrainedSystem

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

if TYPE_CHECKING:  # pragma: no cover
    from ..derivation import EquationsOfMotion
    from ..result import Result

__all__ = ["FORMULATIONS", "FUNCTIONS", "ExpressionError", "ModelFile", "ModelFileError", "SimulationSettings",
           "constrained_method", "constrained_outputs", "load_model", "loads_model", "parse_expression"]

#: Functions an expression may call: name -> (sympy function, number of arguments).
FUNCTIONS: dict[str, tuple[Callable[..., sp.Expr], int]] = {
    "sin": (sp.sin, 1), "cos": (sp.cos, 1), "tan": (sp.tan, 1),
    "asin": (sp.asin, 1), "acos": (sp.acos, 1), "atan": (sp.atan, 1), "atan2": (sp.atan2, 2),
    "sinh": (sp.sinh, 1), "cosh": (sp.cosh, 1), "tanh": (sp.tanh, 1),
    "exp": (sp.exp, 1), "log": (sp.log, 1), "sqrt": (sp.sqrt, 1),
    "abs": (sp.Abs, 1), "sign": (sp.sign, 1),
}

METHODS = ("adams", "bdf")
#: What [constraints] integrable = ... may say (see ConstrainedSystem).
_INTEGRABLE = ("error", "allow")

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
_NON_FINITE = (sp.zoo, sp.oo, -sp.oo, sp.nan)


# ============================================================================ results
@dataclass
class SimulationSettings:
    """The ``[simulation]`` table: how a build step should run the model."""

    t_start: float = 0.0
    t_end: float = 10.0
    n_out: int = 1001
    method: str = "adams"
    rtol: float = 1e-8
    atol: float = 1e-10
    initial: dict[str, float] = field(default_factory=dict)
    outputs: list[str] = field(default_factory=list)
    runtime_parameters: list[str] | None = None
    parameters: dict[str, float] = field(default_factory=dict)
    jacobian: bool = True
    formulation: str | None = None  # constrained files: "index1" (default), "ggl" or "minimal"
    baumgarte: tuple[float, float] = (0.0, 0.0)  # index1: (alpha, beta); (0, 0) is none
    projection: bool = False  # index1: project onto the constraints after each step (BDF)


@dataclass
class ModelFile:
    """A loaded model file: the model, its simulation settings and where it came from."""

    model: Model
    simulation: SimulationSettings
    path: Path
    source: str = field(default="", repr=False, compare=False)  # the TOML text, for error lines
    #: The model with the file's [constraints] (a ConstrainedSystem), or None without constraints.
    constrained: ConstrainedSystem | None = field(default=None, repr=False, compare=False)
    #: The file's [[events]] (Event items; the inequality constraints' events ineq_<k> come on top).
    events: list[Event] = field(default_factory=list, compare=False)

    def initial_state(self) -> tuple[list[float], list[float]]:
        """Initial coordinates and velocities from ``simulation.initial`` (missing entries 0.0)."""
        init = self.simulation.initial
        q0 = [float(init.get(q.name, 0.0)) for q in self.model.coords]
        v0 = [float(init.get(v.name, 0.0)) for v in self.model.speeds]
        return q0, v0

    def times(self) -> np.ndarray:
        """Output times: ``n_out`` points evenly spaced from ``t_start`` to ``t_end``."""
        s = self.simulation
        return np.linspace(s.t_start, s.t_end, s.n_out)

    def derive(self) -> EquationsOfMotion:
        """:func:`lagcodegen.derive` of the model, with model errors located in this file."""
        try:
            return derive(self.model)
        except ModelFileError:
            raise
        except ModelError as exc:
            raise _Locator(self.source, str(self.path)).error(("model", "coordinates"), str(exc)) from None

    def compile(self, **options: Any) -> Any:
        """:func:`lagcodegen.compile_model` with this file's scene settings (``options`` override).

        With constraints: :func:`lagcodegen.dae.compile_constrained` with the file's formulation,
        Baumgarte parameters, projection, events and outputs (see :func:`constrained_outputs`);
        ``options`` (``formulation=...``, ``lang=...``, ``outputs=...``) override.
        """
        return hooks.call("compile_file", self, **options)

    def simulate(self, compiled: Any = None, **options: Any) -> Result:
        """Run the simulation the file describes (compiling first unless ``compiled`` is given).

        A given ``compiled`` model should come from :meth:`compile`: parameter overrides are
        passed for its run-time parameters only. Constrained files integrate with BDF where the
        formulation needs it (``ggl``, index-1 with projection), else with ``method``; the
        result has the events found in ``Result.events``.
        """
        cm = compiled if compiled is not None else self.compile()
        s = self.simulation
        q0, v0 = self.initial_state()
        method = s.method
        if self.constrained is not None:
            method = constrained_method(getattr(cm, "formulation", s.formulation), getattr(cm, "projection", False),
                                        s.method)
        kwargs: dict[str, Any] = dict(
            q0=q0, v0=v0, method=method, rtol=s.rtol, atol=s.atol,
            params={k: v for k, v in s.parameters.items() if k in cm.param_names})
        kwargs.update(options)
        return cm.simulate(self.times(), **kwargs)


def constrained_outputs(system: ConstrainedSystem, requested: Sequence[str], formulation: str | None) -> list[str]:
    """Outputs of a constrained run: ``requested`` (default: energy) plus the multipliers
    (``lambda``, except in minimal coordinates, which have none), the constraint residuals
    (``residuals``) and, when there are inequality constraints, their values (``inequalities``)."""
    out = list(requested) if requested else ["energy"]
    extra = ["lambda"] if formulation != "minimal" and system.J else []
    extra.append("residuals")
    if system.inequalities:
        extra.append("inequalities")
    return out + [name for name in extra if name not in out]


def constrained_method(formulation: str | None, projection: bool, method: str) -> str:
    """The integration method of a constrained run: GGL (IDA) and index-1 with projection
    (CVODE projects with BDF only) use ``"bdf"``; otherwise ``method``."""
    if formulation == "ggl" or (formulation in (None, "index1") and projection):
        return "bdf"
    return method


class ModelFileError(ModelError):
    """A problem in a model file. ``filename``, ``line`` (or None), ``key`` and ``token`` say where."""

    def __init__(self, message: str, filename: str, line: int | None, key: str, token: str | None):
        self.filename = filename
        self.line = line
        self.key = key
        self.token = token
        where = f"{filename}:{line}" if line else filename
        super().__init__(message, location=f"{where}: {key}" if key else where)


class ExpressionError(ModelError):
    """An expression string is not allowed; ``token`` is the offending name or construct."""

    def __init__(self, message: str, token: str):
        self.token = token
        super().__init__(message)


# ============================================================================ expressions
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
        raise ExpressionError(f"invalid expression syntax ({exc.msg}) in {text!r}", token=text) from None
    except (ValueError, RecursionError, MemoryError):
        raise ExpressionError(f"expression cannot be parsed: {text!r}", token=text) from None
    try:
        expr = _Converter(text.strip(), symbols, forbidden or {}).convert(tree)
    except RecursionError:
        raise ExpressionError(f"expression is nested too deeply: {text!r}", token=text) from None
    if not isinstance(expr, sp.Expr):  # pragma: no cover - every converted node is an Expr
        raise ExpressionError(f"not an expression: {text!r}", token=text)
    if expr.has(*_NON_FINITE):
        raise ExpressionError(f"expression {text!r} is not finite", token=text)
    if expr.has(sp.I):
        raise ExpressionError(f"expression {text!r} has a complex value", token=text)
    return expr


class _Converter:
    """Walks a whitelist of ast nodes and builds the sympy expression directly."""

    def __init__(self, text: str, symbols: Mapping[str, sp.Basic], forbidden: Mapping[str, str]):
        self.text = text
        self.symbols = symbols
        self.forbidden = forbidden

    def source(self, node: ast.AST) -> str:
        return ast.get_source_segment(self.text, node) or type(node).__name__

    def reject(self, node: ast.AST, what: str) -> ExpressionError:
        token = self.source(node)
        return ExpressionError(f"{what} {token!r} is not allowed in {self.text!r}", token=token)

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
            raise ExpressionError(f"attribute access {self.source(node)!r} (attribute {node.attr!r}) is not "
                                  f"allowed in {self.text!r}", token=self.source(node))
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

    def name(self, node: ast.Name) -> sp.Expr:
        name = node.id
        if name in self.symbols:
            return self.symbols[name]
        if name in self.forbidden:
            raise ExpressionError(f"{name!r} is not allowed here ({self.forbidden[name]}) in {self.text!r}",
                                  token=name)
        if name in FUNCTIONS:
            raise ExpressionError(f"function {name!r} must be called, as {name}(...), in {self.text!r}",
                                  token=name)
        close = difflib.get_close_matches(name, list(self.symbols), n=1)
        hint = f"; did you mean {close[0]!r}?" if close else ""
        known = ", ".join(self.symbols) or "none"
        raise ExpressionError(f"unknown name {name!r} in {self.text!r}{hint} (known names: {known})", token=name)

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
            raise ExpressionError(f"operator {sym!r} is not allowed in {self.text!r}{hint}", token=sym)
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
        raise ExpressionError(f"operator {sym!r} is not allowed in {self.text!r}", token=sym)

    def call(self, node: ast.Call) -> sp.Expr:
        if not isinstance(node.func, ast.Name):
            token = self.source(node.func)
            raise ExpressionError(f"call of {token!r} is not allowed in {self.text!r}; only the functions "
                                  f"{', '.join(FUNCTIONS)} may be called", token=token)
        name = node.func.id
        if name not in FUNCTIONS:
            raise ExpressionError(f"function {name!r} is not allowed in {self.text!r}; allowed functions: "
                                  f"{', '.join(FUNCTIONS)}", token=name)
        if node.keywords:
            kw = node.keywords[0]
            token = f"{kw.arg}=" if kw.arg else "**"
            raise ExpressionError(f"keyword argument {token!r} in call of {name!r} is not allowed in "
                                  f"{self.text!r}", token=token)
        for arg in node.args:
            if isinstance(arg, ast.Starred):
                raise self.reject(arg, "starred argument")
        func, arity = FUNCTIONS[name]
        if len(node.args) != arity:
            plural = "s" if arity != 1 else ""
            raise ExpressionError(f"function {name!r} takes {arity} argument{plural}, got {len(node.args)} in "
                                  f"{self.text!r}", token=name)
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
        if value.is_Number:
            if value.is_Rational and max(abs(int(value.p)).bit_length(), int(value.q).bit_length()) > _MAX_BITS:
                raise self.reject(node, "number too large:")
            try:
                finite = math.isfinite(float(value))
            except OverflowError:
                finite = False
            if not finite:
                raise self.reject(node, "number outside double precision range:")
        return value


# ============================================================================ locating errors
_Key = Union[str, int]
_HEADER = re.compile(r"^\s*(\[\[?)\s*([A-Za-z_][\w.\s-]*?)\s*\]\]?\s*(#.*)?$")
_ASSIGNMENT = re.compile(r"^\s*[\w\"'.-]+\s*=")


def _format_key(path: Sequence[_Key]) -> str:
    out = ""
    for part in path:
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            text = part if re.fullmatch(r"[A-Za-z0-9_-]+", part) else json.dumps(part)
            out += f".{text}" if out else text
    return out


class _Locator:
    """Finds the line of a key path (and a value in it) in the raw TOML text, best effort."""

    def __init__(self, text: str, filename: str):
        self.filename = filename
        self.lines = text.splitlines()
        self.headers: list[tuple[int, bool, str]] = []  # (line index, array of tables?, name)
        for i, line in enumerate(self.lines):
            m = _HEADER.match(line)
            if m:
                self.headers.append((i, m.group(1) == "[[", re.sub(r"\s+", "", m.group(2))))

    def error(self, path: Sequence[_Key], message: str, needle: str | None = None,
              token: str | None = None) -> ModelFileError:
        """A located error: ``needle`` is text to look for (default ``token``)."""
        line = self.line(path, needle if needle is not None else token)
        return ModelFileError(message, self.filename, line, _format_key(path), token)

    def _section(self, path: Sequence[_Key]) -> tuple[int, int, list[str]] | None:
        """(first line, end line, keys left) of the table that holds ``path``."""
        if not path:
            return None
        # An array of tables ([[particles]], [[constraints.nonholonomic]]): its k-th header.
        k = next((i for i, part in enumerate(path) if not isinstance(part, str)), len(path))
        arrays = [i for i, is_array, name in self.headers if is_array and name == ".".join(map(str, path[:k]))]
        if 0 < k < len(path) and arrays:
            if path[k] >= len(arrays):
                return None
            start, rest = arrays[path[k]], path[k + 1:]
        else:
            names = []
            for part in path:
                if not isinstance(part, str):
                    break
                names.append(part)
            start = None
            for k in range(len(names), 0, -1):
                dotted = ".".join(names[:k])
                found = [i for i, is_array, name in self.headers if not is_array and name == dotted]
                if found:
                    start, rest = found[0], path[k:]
                    break
            if start is None:
                return None
        end = next((i for i, _, _ in self.headers if i > start), len(self.lines))
        return start, end, list(rest)

    def line(self, path: Sequence[_Key], needle: str | None = None) -> int | None:
        """1-based line number of ``path`` (and of ``needle`` within its value), or None."""
        section = self._section(path)
        if section is None:
            return self._find(needle, 0, len(self.lines)) if needle else None
        start, end, keys = section
        pos = start
        k = 0
        while k < len(keys):
            key = keys[k]
            if isinstance(key, int):
                # Element `key` of an inline array of tables: the (key+1)-th line with the next key.
                if k + 1 >= len(keys) or not isinstance(keys[k + 1], str):
                    break
                pattern = self._key_pattern(keys[k + 1])
                hits = [i for i in range(pos, end) if pattern.search(self.lines[i])]
                if key >= len(hits):
                    break
                pos = hits[key]
                k += 2
                continue
            pattern = self._key_pattern(key)
            hit = next((i for i in range(pos, end) if pattern.search(self.lines[i])), None)
            if hit is None:
                break
            pos = hit
            k += 1
        if needle:
            stop = next((i for i in range(pos + 1, end) if _ASSIGNMENT.match(self.lines[i])), end)
            hit = self._find(needle, pos, stop)
            if hit is not None:
                return hit
        return pos + 1

    @staticmethod
    def _key_pattern(key: str) -> re.Pattern:
        return re.compile(r"(?:^|[\s{,.])[\"']?" + re.escape(key) + r"[\"']?\s*=")

    def _find(self, needle: str, start: int, stop: int) -> int | None:
        for candidate in (f'"{needle}"', f"'{needle}'", needle):
            for i in range(start, stop):
                if candidate in self.lines[i]:
                    return i + 1
        return None


# ============================================================================ loading
_TOP_LEVEL = ("model", "parameters", "points", "particles", "planar_bodies", "rigid_bodies", "gravity",
              "springs", "dampers", "forces", "generalized_forces", "energy", "outputs", "constraints", "events",
              "simulation")
_SIMULATION_KEYS = ("t_start", "t_end", "n_out", "method", "rtol", "atol", "initial", "outputs",
                    "runtime_parameters", "parameters", "jacobian", "formulation", "baumgarte", "projection")
_CONSTRAINT_KEYS = ("holonomic", "nonholonomic", "inequalities", "integrable")
_CONSTRAINT_PATH = re.compile(r"\b(nonholonomic|holonomic|inequality) constraint (\d+)")
_POSITION_ONLY = "velocities are allowed only in forces, kinetic energy, dissipation, outputs and events"


def load_model(path: str | Path) -> ModelFile:
    """Load a TOML model file (see the module docstring for the format)."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ModelFileError(f"cannot read model file: {exc}", str(path), None, "", None) from None
    return _Loader(text, str(path), path).load()


def loads_model(text: str, filename: str = "<string>") -> ModelFile:
    """Load a model from TOML text; ``filename`` is used in messages and as ``ModelFile.path``."""
    return _Loader(text, filename, Path(filename)).load()


def _type_name(value: object) -> str:
    if isinstance(value, bool):
        return "a boolean"
    return {int: "an integer", float: "a float", str: "a string", list: "an array",
            dict: "a table"}.get(type(value), f"a {type(value).__name__}")


class _Loader:
    """Reads one TOML document into a Model and SimulationSettings."""

    def __init__(self, text: str, filename: str, path: Path):
        self.text = text
        self.filename = filename
        self.path = path
        self.locate = _Locator(text, filename)
        self.model: Model | None = None
        self.symbols: dict[str, sp.Basic] = {}
        self.velocities: dict[str, str] = {}
        self.system: ConstrainedSystem | None = None
        self.events: list[Event] = []

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
                raise self.error([*path, key], f"unknown key {key!r}{hint} (allowed: {', '.join(allowed)})",
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
                raise self.error(path, f"must be a finite number, {value!r} is {number}", token=value)
            return number
        if not math.isfinite(value):
            raise self.error(path, f"must be a finite number, got {value}", token=str(value))
        return float(value)

    def point_ref(self, path: Sequence[_Key], value: object) -> str | list[sp.Expr]:
        """A point: the name of a declared point, or a position array."""
        assert self.model is not None
        if isinstance(value, str):
            if value not in self.model.points:
                known = ", ".join(self.model.points) or "none"
                raise self.error(path, f"no point named {value!r} (points: {known})", token=value)
            return value
        if isinstance(value, list):
            return self.vector(path, value)
        raise self.error(path, f"must be a point name or a position array, got {_type_name(value)}",
                         token=repr(value))

    # ------------------------------------------------------------------ sections
    def load(self) -> ModelFile:
        try:
            data = tomllib.loads(self.text)
        except tomllib.TOMLDecodeError as exc:
            m = re.search(r"line (\d+)", str(exc))
            line = int(m.group(1)) if m else None
            raise ModelFileError(f"invalid TOML: {exc}", self.filename, line, "", None) from None
        for key in data:
            if key not in _TOP_LEVEL:
                close = difflib.get_close_matches(key, _TOP_LEVEL, n=1)
                hint = f"; did you mean {close[0]!r}?" if close else ""
                raise self.error([key], f"unknown top-level table {key!r}{hint} (allowed: {', '.join(_TOP_LEVEL)})",
                                 token=key, needle=key)
        if "model" not in data:
            raise ModelFileError("missing required table [model]", self.filename, None, "", "model")
        self.load_model_table(self.table(["model"], data["model"]))
        self.load_parameters(self.table(["parameters"], data.get("parameters", {})))
        for section, loader in (("points", self.load_point), ("particles", self.load_particle),
                                ("planar_bodies", self.load_planar_body), ("rigid_bodies", self.load_rigid_body)):
            for i, entry in enumerate(self.tables([section], data.get(section, []))):
                loader([section, i], entry)
        if "gravity" in data:
            self.load_gravity(self.table(["gravity"], data["gravity"]))
        for section, loader in (("springs", self.load_spring), ("dampers", self.load_damper),
                                ("forces", self.load_force), ("generalized_forces", self.load_generalized_force)):
            for i, entry in enumerate(self.tables([section], data.get(section, []))):
                loader([section, i], entry)
        self.load_energy(self.table(["energy"], data.get("energy", {})))
        self.load_outputs(self.table(["outputs"], data.get("outputs", {})))
        assert self.model is not None
        with self.at(["model"]):
            self.model.validate()
        if "constraints" in data:
            self.load_constraints(self.table(["constraints"], data["constraints"]))
        events = self.tables(["events"], data.get("events", []))
        if events and self.system is None:
            raise self.error(["events", 0], "events need a [constraints] table: they are located by the "
                             "constrained solvers (give the constraints, or inequalities = [...] only)",
                             token="events", needle="events")
        for i, entry in enumerate(events):
            self.events.append(self.load_event(["events", i], entry))
        simulation = self.load_simulation(self.table(["simulation"], data.get("simulation", {})))
        return ModelFile(model=self.model, simulation=simulation, path=self.path, source=self.text,
                         constrained=self.system, events=list(self.events))

    def load_model_table(self, table: dict) -> None:
        self.fields(["model"], table, required=["coordinates"], optional=["name"])
        if "name" in table:
            name = self.string(["model", "name"], table["name"])
        else:
            stem = self.path.stem
            name = stem if stem.isidentifier() else "model"
        with self.at(["model", "name"], needle=name):
            self.model = Model(name)
        coords = self.strings(["model", "coordinates"], table["coordinates"])
        if not coords:
            raise self.error(["model", "coordinates"], "at least one coordinate is needed", token="coordinates")
        for i, name in enumerate(coords):
            self.declare_name(["model", "coordinates", i], name)
            with self.at(["model", "coordinates", i], needle=name):
                q = self.model.coordinate(name)
            v = self.model.dot(q)
            self.symbols[q.name] = q
            self.symbols[v.name] = v
            self.velocities[v.name] = _POSITION_ONLY
        self.symbols["t"] = self.model.t
        self.symbols["pi"] = sp.pi

    def declare_name(self, path: Sequence[_Key], name: str) -> None:
        if name in FUNCTIONS:
            raise self.error(path, f"name {name!r} is taken by the function {name}()", token=name, needle=name)

    def load_parameters(self, table: dict) -> None:
        assert self.model is not None
        for name, value in table.items():
            path = ["parameters", name]
            self.declare_name(path, name)
            number = self.constant(path, value)
            with self.at(path, needle=name):
                self.symbols[name] = self.model.parameter(name, number)

    def load_point(self, path: list[_Key], entry: dict) -> None:
        assert self.model is not None
        self.fields(path, entry, required=["name", "position"])
        name = self.string([*path, "name"], entry["name"])
        position = self.vector([*path, "position"], entry["position"])
        with self.at([*path, "name"], needle=name):
            self.model.point(name, position)

    def load_particle(self, path: list[_Key], entry: dict) -> None:
        assert self.model is not None
        self.fields(path, entry, required=["name", "mass", "position"])
        name = self.string([*path, "name"], entry["name"])
        mass = self.expr([*path, "mass"], entry["mass"])
        position = self.vector([*path, "position"], entry["position"])
        with self.at([*path, "name"], needle=name):
            self.model.particle(name, mass, position)

    def load_planar_body(self, path: list[_Key], entry: dict) -> None:
        assert self.model is not None
        self.fields(path, entry, required=["name", "mass", "inertia", "position", "angle"])
        name = self.string([*path, "name"], entry["name"])
        mass = self.expr([*path, "mass"], entry["mass"])
        inertia = self.expr([*path, "inertia"], entry["inertia"])
        position = self.vector([*path, "position"], entry["position"], sizes=(2,))
        angle = self.expr([*path, "angle"], entry["angle"])
        with self.at([*path, "name"], needle=name):
            self.model.planar_body(name, mass, inertia, position, angle)

    def load_rigid_body(self, path: list[_Key], entry: dict) -> None:
        assert self.model is not None
        self.fields(path, entry, required=["name", "mass", "inertia", "position", "orientation"])
        name = self.string([*path, "name"], entry["name"])
        mass = self.expr([*path, "mass"], entry["mass"])
        raw = entry["inertia"]
        if isinstance(raw, list) and raw and all(isinstance(r, list) for r in raw):
            inertia = self.matrix3([*path, "inertia"], raw)
        else:
            inertia = sp.diag(*self.vector([*path, "inertia"], raw, sizes=(3,)))
        position = self.vector([*path, "position"], entry["position"], sizes=(3,))
        orientation = self.matrix3([*path, "orientation"], entry["orientation"])
        with self.at([*path, "name"], needle=name):
            self.model.rigid_body(name, mass, inertia, position, orientation)

    def load_gravity(self, table: dict) -> None:
        assert self.model is not None
        self.fields(["gravity"], table, required=["g"], optional=["up"])
        g = self.expr(["gravity", "g"], table["g"])
        up = self.vector(["gravity", "up"], table["up"]) if "up" in table else None
        with self.at(["gravity"]):
            self.model.gravity(g, up)

    def load_spring(self, path: list[_Key], entry: dict) -> None:
        assert self.model is not None
        self.fields(path, entry, required=["a", "b", "k"], optional=["rest_length", "label"])
        a = self.point_ref([*path, "a"], entry["a"])
        b = self.point_ref([*path, "b"], entry["b"])
        k = self.expr([*path, "k"], entry["k"])
        rest = self.expr([*path, "rest_length"], entry["rest_length"]) if "rest_length" in entry else 0
        label = self.string([*path, "label"], entry["label"]) if "label" in entry else None
        with self.at(path):
            self.model.spring(a, b, k, rest_length=rest, label=label)

    def load_damper(self, path: list[_Key], entry: dict) -> None:
        assert self.model is not None
        self.fields(path, entry, required=["point", "c"], optional=["b", "label"])
        a = self.point_ref([*path, "point"], entry["point"])
        c = self.expr([*path, "c"], entry["c"])
        b = self.point_ref([*path, "b"], entry["b"]) if "b" in entry else None
        label = self.string([*path, "label"], entry["label"]) if "label" in entry else None
        with self.at(path):
            self.model.damper(a, c, b=b, label=label)

    def load_force(self, path: list[_Key], entry: dict) -> None:
        assert self.model is not None
        self.fields(path, entry, required=["point", "vector"], optional=["label"])
        point = self.point_ref([*path, "point"], entry["point"])
        vector = self.vector([*path, "vector"], entry["vector"], velocities=True)
        label = self.string([*path, "label"], entry["label"]) if "label" in entry else None
        with self.at([*path, "vector"]):
            self.model.force(point, vector, label=label)

    def load_generalized_force(self, path: list[_Key], entry: dict) -> None:
        assert self.model is not None
        self.fields(path, entry, required=["coordinate", "expr"], optional=["label"])
        coord = self.string([*path, "coordinate"], entry["coordinate"])
        names = [q.name for q in self.model.coords]
        if coord not in names:
            raise self.error([*path, "coordinate"], f"{coord!r} is not a coordinate (coordinates: "
                             f"{', '.join(names)})", token=coord)
        expr = self.expr([*path, "expr"], entry["expr"], velocities=True)
        label = self.string([*path, "label"], entry["label"]) if "label" in entry else None
        self.model.generalized_force(coord, expr, label=label)

    def load_energy(self, table: dict) -> None:
        assert self.model is not None
        self.fields(["energy"], table, optional=["kinetic", "potential", "dissipation"])
        if "kinetic" in table:
            self.model.kinetic_energy(self.expr(["energy", "kinetic"], table["kinetic"], velocities=True),
                                      label="energy.kinetic")
        if "potential" in table:
            self.model.potential_energy(self.expr(["energy", "potential"], table["potential"]),
                                        label="energy.potential")
        if "dissipation" in table:
            self.model.dissipation(self.expr(["energy", "dissipation"], table["dissipation"], velocities=True),
                                   label="energy.dissipation")

    def builtin_outputs(self) -> list[str]:
        """Output names a scene provides by itself (see :class:`lagcodegen.scene.Scene`)."""
        assert self.model is not None
        names = list(OUTPUT_GROUPS) + [f"p_{q.name}" for q in self.model.coords]
        names += [f"{pt.name}_{axis}" for pt in self.model.points.values() for axis in "xyz"[:pt.dim]]
        return names

    def load_outputs(self, table: dict) -> None:
        assert self.model is not None
        builtin = self.builtin_outputs()
        for name, value in table.items():
            path = ["outputs", name]
            if name in builtin:
                raise self.error(path, f"output name {name!r} is taken by a built-in output", token=name,
                                 needle=name)
            expr = self.expr(path, value, velocities=True)
            with self.at(path, needle=name):
                self.model.output(name, expr)

    def load_constraints(self, table: dict) -> None:
        """[constraints]: holonomic f(q, t) = 0, nonholonomic A . q' + A0 = 0, inequalities g >= 0."""
        assert self.model is not None
        path = ["constraints"]
        self.fields(path, table, optional=_CONSTRAINT_KEYS)
        coords = set(self.model.coords)
        holonomic = []
        for i, value in enumerate(self.array([*path, "holonomic"], table.get("holonomic", []))):
            f = self.expr([*path, "holonomic", i], value)
            if not f.free_symbols & coords:
                raise self.error([*path, "holonomic", i], f"holonomic constraint {f} = 0 involves no coordinate "
                                 f"({', '.join(q.name for q in self.model.coords)})", token=str(value),
                                 needle=str(value))
            holonomic.append(f)
        nonholonomic = [self.load_pfaffian([*path, "nonholonomic", i], entry) for i, entry in
                        enumerate(self.tables([*path, "nonholonomic"], table.get("nonholonomic", [])))]
        inequalities = [self.expr([*path, "inequalities", i], value) for i, value in
                        enumerate(self.array([*path, "inequalities"], table.get("inequalities", [])))]
        integrable = "error"
        if "integrable" in table:
            integrable = self.string([*path, "integrable"], table["integrable"])
            if integrable not in _INTEGRABLE:
                raise self.error([*path, "integrable"], f"must be one of {', '.join(map(repr, _INTEGRABLE))}, got "
                                 f"{integrable!r}", token=integrable)
        if not (holonomic or nonholonomic or inequalities):
            raise self.error(path, "the [constraints] table gives no constraint (holonomic, nonholonomic or "
                             "inequalities)", token="constraints", needle="")
        n, J = self.model.n, len(holonomic) + len(nonholonomic)
        if J > n:
            raise self.error(path, f"{J} equality constraints ({len(holonomic)} holonomic, {len(nonholonomic)} "
                             f"nonholonomic) but only {n} coordinates: at most {n} are possible",
                             token="constraints", needle="")
        params = {p.name for p in self.model.params}
        for j in range(J):
            name = f"lambda_{j}"
            if name in params:
                raise self.error(["parameters", name], f"the name {name!r} is reserved for the Lagrange multiplier "
                                 f"of constraint {j}: rename the parameter", token=name, needle=name)
            if name in self.symbols:
                raise self.error(["model", "coordinates"], f"the name {name!r} is reserved for the Lagrange "
                                 f"multiplier of constraint {j}: rename the coordinate", token=name, needle=name)
        try:
            self.system = ConstrainedSystem(self.model, holonomic, nonholonomic, inequalities, integrable=integrable)
        except ModelError as exc:
            m = _CONSTRAINT_PATH.search(str(exc))
            where: list[_Key] = path
            if m:
                kind = "inequalities" if m.group(1) == "inequality" else m.group(1)
                where = [*path, kind, int(m.group(2))]
            message = str(exc).replace("pass integrable='allow'", 'set integrable = "allow" in [constraints]')
            raise self.error(where, message, token=_format_key(where)) from None

    def load_pfaffian(self, path: list[_Key], entry: dict) -> tuple[tuple, sp.Expr]:
        """A nonholonomic constraint: ``{A = [...], A0 = ...}`` or ``{coefficients = {q = ...}, A0 = ...}``."""
        assert self.model is not None
        self.fields(path, entry, optional=["A", "coefficients", "A0"])
        names = [q.name for q in self.model.coords]
        if ("A" in entry) == ("coefficients" in entry):
            what = "both 'A' and 'coefficients' given" if "A" in entry else "missing key 'A' or 'coefficients'"
            raise self.error(path, f"{what}: give one (A: an array of one coefficient per coordinate, "
                             f"{', '.join(names)}; coefficients: a table by coordinate name, missing ones 0)",
                             token="A" if "A" in entry else "coefficients", needle="")
        if "A" in entry:
            raw = entry["A"]
            if not isinstance(raw, list) or len(raw) != len(names):
                got = f"{len(raw)} coefficients" if isinstance(raw, list) else _type_name(raw)
                raise self.error([*path, "A"], f"must be an array of {len(names)} expressions, one per coordinate "
                                 f"({', '.join(names)}), got {got}", token=repr(raw))
            A = [self.expr([*path, "A", i], v) for i, v in enumerate(raw)]
        else:
            A = [sp.Integer(0)] * len(names)
            for name, value in self.table([*path, "coefficients"], entry["coefficients"]).items():
                if name not in names:
                    close = difflib.get_close_matches(name, names, n=1)
                    hint = f"; did you mean {close[0]!r}?" if close else ""
                    raise self.error([*path, "coefficients", name], f"{name!r} is not a coordinate{hint} "
                                     f"(coordinates: {', '.join(names)})", token=name, needle=name)
                A[names.index(name)] = self.expr([*path, "coefficients", name], value)
        A0 = self.expr([*path, "A0"], entry["A0"]) if "A0" in entry else sp.Integer(0)
        if all(a == 0 for a in A):
            raise self.error(path, "every coefficient is zero: not a constraint on the velocities",
                             token="A" if "A" in entry else "coefficients", needle="")
        return tuple(A), A0

    def array(self, path: Sequence[_Key], value: object) -> list:
        if not isinstance(value, list):
            raise self.error(path, f"must be an array of expressions, got {_type_name(value)}", token=repr(value))
        return value

    def load_event(self, path: list[_Key], entry: dict) -> Event:
        """[[events]]: name, expr (q, q', t, parameters, lambda_<j>), direction, terminal."""
        assert self.system is not None
        self.fields(path, entry, required=["name", "expr"], optional=["direction", "terminal"])
        name = self.string([*path, "name"], entry["name"])
        if not name.isidentifier():
            raise self.error([*path, "name"], f"event name {name!r} must be an identifier", token=name)
        taken = [f"ineq_{k}" for k in range(len(self.system.inequalities))] + [e.name for e in self.events]
        if name in taken:
            what = "is used twice" if name in (e.name for e in self.events) else \
                "is taken by the event of an inequality constraint"
            raise self.error([*path, "name"], f"event name {name!r} {what}", token=name)
        multipliers = {lam.name: lam for lam in self.system.multipliers}
        expr = self.expr([*path, "expr"], entry["expr"], velocities=True, extra=multipliers)
        direction = entry.get("direction", 0)
        if isinstance(direction, bool) or direction not in DIRECTIONS:
            raise self.error([*path, "direction"], f"must be -1 (decreasing), 0 (both) or 1 (increasing), got "
                             f"{direction!r}", token=repr(direction))
        terminal = entry.get("terminal", True)
        if not isinstance(terminal, bool):
            raise self.error([*path, "terminal"], f"must be true or false, got {terminal!r}", token=repr(terminal))
        with self.at(path):
            return Event(name, expr, int(direction), terminal)

    def load_simulation(self, table: dict) -> SimulationSettings:
        assert self.model is not None
        self.fields(["simulation"], table, optional=_SIMULATION_KEYS)
        s = SimulationSettings()
        sim = ["simulation"]
        if "t_start" in table:
            s.t_start = self.constant([*sim, "t_start"], table["t_start"])
        if "t_end" in table:
            s.t_end = self.constant([*sim, "t_end"], table["t_end"])
        if not s.t_end > s.t_start:
            raise self.error([*sim, "t_end"], f"t_end ({s.t_end:g}) must be greater than t_start ({s.t_start:g})",
                             token="t_end")
        if "n_out" in table:
            n_out = table["n_out"]
            if isinstance(n_out, bool) or not isinstance(n_out, int) or n_out < 2:
                raise self.error([*sim, "n_out"], f"must be an integer >= 2, got {n_out!r}", token=repr(n_out))
            s.n_out = n_out
        if "method" in table:
            method = self.string([*sim, "method"], table["method"])
            if method not in METHODS:
                raise self.error([*sim, "method"], f"unknown method {method!r} (use one of: {', '.join(METHODS)})",
                                 token=method)
            s.method = method
        for key in ("rtol", "atol"):
            if key in table:
                value = self.constant([*sim, key], table[key])
                if value < 0:
                    raise self.error([*sim, key], f"must not be negative, got {value:g}", token=key)
                setattr(s, key, value)
        for key in ("jacobian", "projection"):
            if key in table and not isinstance(table[key], bool):
                raise self.error([*sim, key], f"must be true or false, got {table[key]!r}", token=key)
        if "jacobian" in table:
            s.jacobian = table["jacobian"]
        self.load_formulation(table, s)
        s.initial = self.load_initial(self.table([*sim, "initial"], table.get("initial", {})))
        params = [p.name for p in self.model.params]
        if "parameters" in table:
            for name, value in self.table([*sim, "parameters"], table["parameters"]).items():
                if name not in params:
                    raise self.error([*sim, "parameters", name], f"{name!r} is not a parameter (parameters: "
                                     f"{', '.join(params) or 'none'})", token=name)
                s.parameters[name] = self.constant([*sim, "parameters", name], value)
        if "runtime_parameters" in table:
            path = [*sim, "runtime_parameters"]
            runtime = self.strings(path, table["runtime_parameters"])
            for i, name in enumerate(runtime):
                if name not in params:
                    raise self.error([*path, i], f"{name!r} is not a parameter (parameters: "
                                     f"{', '.join(params) or 'none'})", token=name)
                if runtime.index(name) != i:
                    raise self.error([*path, i], f"parameter {name!r} is listed twice", token=name)
            s.runtime_parameters = runtime
        if "outputs" in table:
            path = [*sim, "outputs"]
            known = self.builtin_outputs() + list(self.model.outputs) + self.constraint_outputs()
            for i, name in enumerate(self.strings(path, table["outputs"])):
                if s.formulation == "minimal" and (name in ("lambda", "constraint_forces") or
                                                   name.startswith(("lambda_", "R_"))):
                    raise self.error([*path, i], f"output {name!r}: minimal coordinates have no Lagrange "
                                     "multipliers (use formulation 'index1' or 'ggl')", token=name)
                if name not in known:
                    close = difflib.get_close_matches(name, known, n=1)
                    hint = f"; did you mean {close[0]!r}?" if close else ""
                    raise self.error([*path, i], f"unknown output {name!r}{hint} (known: {', '.join(known)})",
                                     token=name)
                s.outputs.append(name)
        return s

    def constraint_outputs(self) -> list[str]:
        """Output names a constrained system adds (groups and single names), none without constraints."""
        if self.system is None:
            return []
        system = self.system
        names = list(CONSTRAINT_OUTPUT_GROUPS)
        names += [f"lambda_{j}" for j in range(system.J)]
        names += [f"R_{j}_{q.name}" for j in range(system.J) for q in system.model.coords]
        names += [f"g_{j}" for j in range(system.n_holonomic)] + [f"gdot_{j}" for j in range(system.J)]
        names += [f"ineq_{k}" for k in range(len(system.inequalities))]
        return names

    def load_formulation(self, table: dict, s: SimulationSettings) -> None:
        """formulation, baumgarte and projection (constrained files only)."""
        sim = ["simulation"]
        if self.system is None:
            for key in ("formulation", "baumgarte", "projection"):
                if key in table:
                    raise self.error([*sim, key], f"{key!r} applies to constrained models only (this file has no "
                                     "[constraints] table)", token=key)
            return
        s.formulation = "index1"
        if "formulation" in table:
            formulation = self.string([*sim, "formulation"], table["formulation"])
            if formulation not in FORMULATIONS:
                close = difflib.get_close_matches(formulation, FORMULATIONS, n=1)
                hint = f"; did you mean {close[0]!r}?" if close else ""
                raise self.error([*sim, "formulation"], f"unknown formulation {formulation!r}{hint} (use one of: "
                                 f"{', '.join(FORMULATIONS)})", token=formulation)
            s.formulation = formulation
        if "baumgarte" in table:
            path = [*sim, "baumgarte"]
            raw = table["baumgarte"]
            if not isinstance(raw, list) or len(raw) != 2:
                raise self.error(path, f"must be an array [alpha, beta] of two numbers, got {raw!r}",
                                 token=repr(raw))
            values = tuple(self.constant([*path, i], v) for i, v in enumerate(raw))
            for i, value in enumerate(values):
                if value < 0:
                    raise self.error([*path, i], f"must not be negative, got {value:g}", token=repr(raw[i]))
            s.baumgarte = (values[0], values[1])
        if "projection" in table:
            s.projection = table["projection"]
        for key, used in (("baumgarte", s.baumgarte != (0.0, 0.0)), ("projection", s.projection)):
            if used and s.formulation != "index1":
                raise self.error([*sim, key], f"{key!r} applies to formulation 'index1' only (the formulation is "
                                 f"{s.formulation!r})", token=key)
        if "method" in table and s.method != "bdf":
            if s.formulation == "ggl":
                raise self.error([*sim, "method"], f"formulation 'ggl' integrates with IDA, BDF only: method "
                                 f"{s.method!r} is not possible (use \"bdf\" or leave method out)", token=s.method)
            if s.projection:
                raise self.error([*sim, "method"], f"projection onto the constraints needs method \"bdf\" (CVODE "
                                 f"projects with BDF only), got {s.method!r}", token=s.method)
        if s.formulation == "minimal" and (self.events or self.system.inequalities):
            raise self.error([*sim, "formulation"], "formulation 'minimal' has no events or inequality constraints "
                             "(the plain CVODE driver has no root finding): use 'index1' or 'ggl'", token="minimal")

    def load_initial(self, table: dict) -> dict[str, float]:
        assert self.model is not None
        names = [q.name for q in self.model.coords] + [v.name for v in self.model.speeds]
        initial = {}
        for name, value in table.items():
            path = ["simulation", "initial", name]
            if name not in names:
                raise self.error(path, f"{name!r} is not a coordinate or velocity (state: {', '.join(names)})",
                                 token=name)
            initial[name] = self.constant(path, value)
        return initial
