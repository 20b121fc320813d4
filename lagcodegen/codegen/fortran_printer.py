"""Fortran 2008 text of the operation tree (:mod:`.ir`): :class:`FortranPrinter`, its literals and
names, and the statements of a block (:func:`fortran_block`) split and wrapped for free form.

The printer keeps the tree's evaluation order (the C backend's, so that the two agree to the last
bit); the block adds what Fortran needs around the statements: declarations of the temporaries,
mirrored mass-matrix entries after the statements, the dummy arguments a block does not read
(for a no-op ``associate``), long sums cut into running partial results, continuation lines.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..errors import ModelError
from . import ir

INDENT = "  "
#: Fortran 2008 allows 255 continuation lines per statement; longer sums are split before that.
MAX_CONTINUATIONS = 200
#: Code lines are wrapped at this column (free form allows 132).
LINE = 100

#: The tree's math functions with a Fortran 2008 intrinsic of the same meaning (neutral name -> Fortran).
_INTRINSICS = {name: name for name in ("sin", "cos", "tan", "asin", "acos", "atan", "atan2", "sinh", "cosh",
                                       "tanh", "asinh", "acosh", "atanh", "exp", "log", "sqrt", "erf", "erfc",
                                       "abs", "max", "min", "gamma")}
_INTRINSICS.update(loggamma="log_gamma")
#: The tree's functions without a Fortran intrinsic: called from the C math library through a
#: bind(C) interface (neutral name -> (C name, number of arguments)).
_LIBM = {"cbrt": ("cbrt", 1), "floor": ("floor", 1), "ceiling": ("ceil", 1), "truncate": ("trunc", 1)}
#: Arities of the C math library functions the module may bind (C name -> number of arguments).
LIBM_ARITY = dict(_LIBM.values())


def fortran_real(value: float) -> str:
    """A double-precision Fortran literal of ``value`` with 17 significant digits."""
    text = f"{float(value):.17g}"
    if not math.isfinite(float(value)):
        raise ModelError(f"non-finite constant {value} in generated code")
    mantissa, _, exponent = text.partition("e")
    if "." not in mantissa:
        mantissa += ".0"
    return f"{mantissa}d{exponent or '0'}"


def fortran_name(name: str, renames: dict[str, tuple[str, int]] | None = None) -> str:
    """The Fortran spelling of a kernel symbol: ``y[3]`` -> ``y(4)``; with ``renames``
    ``{"a": ("ydot", 2)}``, ``a[0]`` -> ``ydot(3)``. Other names are unchanged."""
    node = ir.symbol_node(name)
    if isinstance(node, ir.Name):
        return name
    return FortranPrinter(renames).doprint(node)


_ATOM, _POW, _MUL, _NEG, _ADD, _REL, _NOT, _AND, _OR = 9, 8, 7, 6, 5, 4, 3, 2, 1


class FortranPrinter(ir.Printer):
    """Fortran 2008 text of :mod:`lagcodegen.codegen.ir` trees, with the tree's evaluation order
    (one ``_print_<Node>`` per node kind, returning (text, precedence)).

    Every number is a double-precision literal with 17 significant digits (integers too, so no
    integer division can arise); ``pow`` is ``**`` (gfortran calls the same ``pow``, and turns
    ``x**2.0d0`` into ``x*x`` as gcc does with ``pow(x, 2)``); a negated left operand of ``*``
    or ``/`` is hoisted (``-a*b`` is ``-(a*b)`` in Fortran: the same double, rounding is
    symmetric); truth values in arithmetic and conditionals are ``merge``; ``==``/``!=`` on
    reals are ``<=``/``>=`` tests (the same result, NaN included; gfortran -Wcompare-reals).
    Elements are 1-based, arrays renamed by ``renames`` ({array: (name, offset)}); calls of C
    math functions without an intrinsic are recorded in ``libm``.
    """

    #: Fortran 2008 keywords and names of the generated module that no variable of the code may take.
    RESERVED = frozenset(("program", "module", "function", "subroutine", "end", "if", "then", "else", "do", "call",
                          "real", "integer", "logical", "implicit", "none", "intent", "in", "out", "inout", "value",
                          "bind", "use", "contains", "return", "result", "merge", "associate", "interface", "factor",
                          "solve", "n", "nz", "ny", "nv", "nw", "ns", "nout", "nnz"))

    def __init__(self, renames: dict | None = None):
        self.renames = dict(renames or {})
        self.libm: set[str] = set()

    def doprint(self, node) -> str:
        return self.number(node)[0]

    def number(self, node) -> tuple[str, int]:
        return getattr(self, "_print_" + type(node).__name__)(node)

    def _truth(self, node) -> tuple[str, int]:
        """A truth value in arithmetic: 1 or 0 (C's value of a comparison)."""
        return f"merge(1.0d0, 0.0d0, {self.logical(node)[0]})", _ATOM

    _print_Compare = _print_Logic = _print_Not = _truth

    @staticmethod
    def paren(text_prec, minimum):
        text, prec = text_prec
        return text if prec >= minimum else f"({text})"

    def _negated(self, text: str) -> tuple[str, int]:
        return "-" + text, _NEG

    def _print_Number(self, node: ir.Number):
        if math.copysign(1.0, node.value) < 0:
            return self._negated(fortran_real(-node.value))
        return fortran_real(node.value), _ATOM

    def _print_Integer(self, node: ir.Integer):
        if node.value < 0:
            return self._negated(fortran_real(-node.value))
        return fortran_real(node.value), _ATOM

    def _print_Ratio(self, node: ir.Ratio):
        num = ir.Integer(node.num)
        return self._print_BinOp(ir.BinOp("/", num, ir.Integer(node.den)))

    def _print_Name(self, node: ir.Name):
        if node.name.lower() in self.RESERVED:
            raise ModelError(f"the symbol {node.name!r} is a Fortran keyword or a name of the module; rename it")
        return node.name, _ATOM

    def _print_Element(self, node: ir.Element):
        index = node.index if isinstance(node.index, tuple) else (node.index,)
        array, offset = self.renames.get(node.array, (node.array, 0))
        if len(index) == 1:
            return f"{array}({index[0] + offset + 1})", _ATOM
        return f"{array}({', '.join(str(k + 1) for k in index)})", _ATOM

    def _print_Neg(self, node: ir.Neg):
        return "-" + self.paren(self.number(node.arg), _MUL), _NEG

    def _print_BinOp(self, node: ir.BinOp):
        op, left, right = node.op, node.left, node.right
        if op in "+-":
            return f"{self.paren(self.number(left), _ADD)} {op} {self.paren(self.number(right), _MUL)}", _ADD
        ltext, lprec = self.number(left)
        rtext = self.paren(self.number(right), _POW)
        if lprec == _NEG:
            return f"{ltext}{op}{rtext}", _NEG
        return f"{self.paren((ltext, lprec), _MUL)}{op}{rtext}", _MUL

    def _print_Power(self, node: ir.Power):
        base = self.paren(self.number(node.base), _ATOM)
        return f"{base}**{self.paren(self.number(node.exp), _ATOM)}", _POW

    def _print_Call(self, node: ir.Call):
        texts = [self.number(a)[0] for a in node.args]
        if node.func in _INTRINSICS:
            return f"{_INTRINSICS[node.func]}({', '.join(texts)})", _ATOM
        if node.func in _LIBM and len(node.args) == _LIBM[node.func][1]:
            name = _LIBM[node.func][0]
            self.libm.add(name)
            return f"libm_{name}({', '.join(texts)})", _ATOM
        raise ModelError(f"the function {node.func!r} has no Fortran translation")

    def _print_Select(self, node: ir.Select):
        text = self.number(node.default)[0]
        for cond, value in reversed(node.cases):
            text = f"merge({self.number(value)[0]}, {text}, {self.logical(cond)[0]})"
        return text, _ATOM

    def _print_Sign(self, node: ir.Sign):
        x, zero = node.arg, ir.Number(0.0)
        return self.number(ir.Select(((ir.Compare("==", x, zero), zero),),
                                     ir.Select(((ir.Compare("<", x, zero), ir.Neg(ir.Number(1.0))),),
                                               ir.Number(1.0))))

    def logical(self, node) -> tuple[str, int]:
        """The Fortran logical expression of a truth value (C's truth of a number: x != 0, NaN true)."""
        if isinstance(node, ir.Not):
            return f".not. {self.paren(self.logical(node.arg), _ATOM)}", _NOT
        if isinstance(node, ir.Logic):
            prec = _AND if node.op == "and" else _OR
            word = ".and." if node.op == "and" else ".or."
            text = self.paren(self.logical(node.args[0]), prec)
            for arg in node.args[1:]:
                text = f"{text} {word} {self.paren(self.logical(arg), prec + 1)}"
            return text, prec
        if not isinstance(node, ir.Compare):
            x = self.number(node)[0]
            return f"(.not. ({x} <= 0.0d0 .and. {x} >= 0.0d0))", _ATOM
        a = self.paren(self.number(node.left), _ADD)
        b = self.paren(self.number(node.right), _ADD)
        if node.op == "==":  # no equality test on reals (gfortran -Wcompare-reals); NaN compares false
            return f"({a} <= {b} .and. {a} >= {b})", _ATOM
        if node.op == "!=":
            return f"(.not. ({a} <= {b} .and. {a} >= {b}))", _ATOM
        return f"{a} {node.op} {b}", _REL


def _chain(node, ops):
    """Operands of the left-associative chain ``((a op b) op c) ...`` rooted at ``node``,
    as [(None, a), (op, b), (op, c), ...]."""
    items = []
    while isinstance(node, ir.BinOp) and node.op in ops:
        items.append((node.op, node.right))
        node = node.left
    items.append((None, node))
    return items[::-1]


def statement_lines(writer: FortranPrinter, target: str, node) -> list[str]:
    """``target = <node>``; a sum (or product) too long for one statement becomes running
    partial results in the same order, ``target = a + b``, ``target = target + c``, ... (the
    same additions as the single C statement)."""
    text = writer.number(node)[0]
    if len(text) < MAX_CONTINUATIONS * (LINE - 20):
        return [f"{target} = {text}"]
    for ops in (("+", "-"), ("*", "/")):
        items = _chain(node, ops)
        if len(items) > 1:
            break
    else:
        raise ModelError(f"an expression for {target} is too long for one Fortran statement")
    lines, acc, size = [], None, 0
    for op, operand in items:
        part = writer.number(operand)
        if acc is not None and size + len(part[0]) > (MAX_CONTINUATIONS // 2) * (LINE - 20):
            lines.append(f"{target} = {acc}")
            acc, size = target, len(target)
        if acc is None:
            acc = part[0] if ops[0] == "+" else writer.paren(part, _MUL)
        else:
            acc = f"{acc} {op} {writer.paren(part, _MUL)}" if ops[0] == "+" else f"{acc}{op}{writer.paren(part, _POW)}"
        size += len(part[0]) + 3
    lines.append(f"{target} = {acc}")
    return lines


def wrap(line: str, pad: str) -> list[str]:
    """Free-form continuation lines (``&``) of at most LINE columns, split between tokens."""
    out, first = [], True
    while True:
        lead = pad if first else pad + "    "
        room = LINE - len(lead) - 2
        if len(line) <= room + 2:
            out.append(lead + line)
            return out
        cut = -1
        # Split after a space (between terms) if one is near the end, else after a comma,
        # a lone * or /, or "(".
        for allowed in (" ", " ,*/("):
            for k in range(room, room // 2 if allowed == " " else 0, -1):
                c, nxt, prev = line[k - 1], line[k], line[k - 2] if k >= 2 else ""
                if c in allowed and (c not in "*/" or (nxt not in "*=/" and prev not in "*/")):
                    cut = k
                    break
            if cut > 0:
                break
        if cut <= 0:
            raise ModelError(f"cannot wrap Fortran line: {line[:80]}...")
        out.append(lead + line[:cut].rstrip() + " &")
        line = line[cut:].lstrip()
        first = False


@dataclass
class FortranBlock:
    """Declarations, statements, the dummy arguments the statements do not reference, and the
    libm functions they call."""

    decls: str
    code: str
    unused: str  # associate list, e.g. "unused_t => t, unused_p => p(1:0)"; "" if all are used
    libm: tuple[str, ...] = ()


def fortran_block(statements: list, dummies: tuple[str, ...] = (), optional: tuple[str, ...] = (),
                  renames: dict[str, tuple[str, int]] | None = None, indent: int = 2, what: str = "expression",
                  scalars: tuple[str, ...] = ("t",)) -> FortranBlock:
    """The Fortran statements of the assignments ``statements`` (:class:`lagcodegen.codegen.ir.Assign`).

    Local temporaries are declared ``real(c_double)``; an assignment to two targets (the mirrored
    entries of the mass matrix) assigns the first, and the second after every statement.
    ``dummies``: the dummy arguments the statements may reference (any other symbol is an
    error); those of ``optional`` they do not reference are listed in ``unused`` for a no-op
    ``associate`` (gfortran -Wunused-dummy-argument). ``scalars``: the dummies that are scalars
    (referenced by name, e.g. ``t``, ``cj``) rather than arrays.
    """
    pad = INDENT * indent
    used: set[str] = set()
    lines: list[str] = []
    after: list[str] = []
    writer = FortranPrinter(renames)
    temps = [st.targets[0].name for st in statements if st.local]
    local = set(temps)
    for st in statements:
        for leaf in ir.walk(st.value):
            if isinstance(leaf, ir.Name) and leaf.name not in local:
                owner, name = leaf.name, leaf.name
            elif isinstance(leaf, ir.Element):
                owner, name = writer.renames.get(leaf.array, (leaf.array, 0))[0], f"{leaf.array}[{leaf.index}]"
            else:
                continue
            if owner not in dummies:
                raise ModelError(f"{what}: symbol {name!r} is neither a coordinate, a velocity, a "
                                 "parameter nor the time t; it cannot be emitted")
            used.add(owner)
        target = writer.doprint(st.targets[0])
        try:
            for statement in statement_lines(writer, target, st.value):
                lines += wrap(statement, pad)
        except ModelError as exc:
            raise ModelError(f"{what}: {exc}") from None
        after += [f"{writer.doprint(t)} = {target}" for t in st.targets[1:]]
    lines += [pad + line for line in after]
    decls = [f"{pad}real(c_double) :: {', '.join(temps[k:k + 10])}" for k in range(0, len(temps), 10)]
    unused = ", ".join(f"unused_{d} => {d}" if d in scalars else f"unused_{d} => {d}(1:0)"
                       for d in optional if d not in used)
    return FortranBlock("\n".join(decls), "\n".join(lines), unused, tuple(sorted(writer.libm)))
