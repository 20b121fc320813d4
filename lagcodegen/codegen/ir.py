"""The language-neutral operation tree every backend prints (C: :mod:`.c`, Fortran: :mod:`.fortran`).

The tree is built once from symengine by :mod:`.lowering`, in the evaluation order of the
generated code; every backend prints the same tree, so every language evaluates the same
operations in the same order (the same doubles).

Nodes (frozen dataclasses; a backend's printer has one ``_print_<Node>`` method per kind):
:class:`Number` (a double), :class:`Integer`, :class:`Ratio` (p/q of two literals), :class:`Name`
(a scalar variable), :class:`Element` (an array element, 0-based indices), :class:`Neg`,
:class:`BinOp` (+, -, *, /), :class:`Power`, :class:`Call` (a math function by its neutral name,
:data:`FUNCTIONS`), :class:`Compare`, :class:`Logic` (and/or), :class:`Not`, :class:`Select`
(first case whose condition holds), :class:`Sign`; the statement :class:`Assign`.
"""

from __future__ import annotations

import contextlib
import re
import sys
from dataclasses import dataclass
from typing import Callable, Union


# ----------------------------------------------------------------------------- expression nodes
@dataclass(frozen=True)
class Number:
    """A floating-point constant (printed exactly: the shortest text that reads back the same double)."""

    value: float


@dataclass(frozen=True)
class Integer:
    """An integer constant small enough for a C int literal."""

    value: int


@dataclass(frozen=True)
class Ratio:
    """The rational constant ``num/den``, evaluated as the division of two double literals."""

    num: int
    den: int


@dataclass(frozen=True)
class Name:
    """A scalar variable: the time ``t``, a temporary, a local tangent."""

    name: str


@dataclass(frozen=True)
class Element:
    """An element of an array (0-based ``index``; a tuple for the matrices of kernel targets)."""

    array: str
    index: int | tuple


@dataclass(frozen=True)
class Neg:
    """Unary minus."""

    arg: "Node"


@dataclass(frozen=True)
class BinOp:
    """``left op right``, op one of + - * /."""

    op: str
    left: "Node"
    right: "Node"


@dataclass(frozen=True)
class Power:
    """``base`` to the power ``exp`` (the C library's pow)."""

    base: "Node"
    exp: "Node"


@dataclass(frozen=True)
class Call:
    """A math function by its neutral name (:data:`FUNCTIONS`)."""

    func: str
    args: tuple


@dataclass(frozen=True)
class Compare:
    """``left op right`` as a truth value, op one of == != < <=."""

    op: str
    left: "Node"
    right: "Node"


@dataclass(frozen=True)
class Logic:
    """The conjunction (op "and") or disjunction ("or") of truth values."""

    op: str
    args: tuple


@dataclass(frozen=True)
class Not:
    """Logical negation."""

    arg: "Node"


@dataclass(frozen=True)
class Select:
    """The value of the first (condition, value) of ``cases`` whose condition holds, else ``default``."""

    cases: tuple
    default: "Node"


@dataclass(frozen=True)
class Sign:
    """-1, 0 or 1 by the sign of ``arg``."""

    arg: "Node"


Node = Union[Number, Integer, Ratio, Name, Element, Neg, BinOp, Power, Call, Compare, Logic, Not, Select, Sign]


# ----------------------------------------------------------------------------- statements
@dataclass(frozen=True)
class Assign:
    """``targets[0] (= targets[1] ...) = value``; ``local``: the target is a temporary of the
    function (a Name declared where it is assigned); ``accumulate``: the value is added to the
    target."""

    targets: tuple
    value: Node
    local: bool = False
    accumulate: bool = False


#: The math functions of the tree by neutral name (symengine's function classes that have one).
FUNCTIONS = frozenset((
    "sin", "cos", "tan", "asin", "acos", "atan", "atan2", "sinh", "cosh", "tanh", "asinh", "acosh", "atanh",
    "exp", "log", "sqrt", "cbrt", "erf", "erfc", "gamma", "loggamma", "abs", "max", "min", "floor",
    "ceiling", "truncate"))
_ELEMENT = re.compile(r"([A-Za-z_]\w*)\[(\d+)\]\Z")


def symbol_node(name: str) -> Node:
    """The node of a kernel symbol: ``y[3]`` -> Element("y", 3) (the array symbols of
    :mod:`lagcodegen.formulation.kernels`), any other name a scalar :class:`Name`."""
    m = _ELEMENT.match(name)
    return Element(m.group(1), int(m.group(2))) if m else Name(name)


def target_nodes(target: tuple) -> tuple:
    """The nodes assigned for a kernel target (:class:`lagcodegen.formulation.kernels.Block`):
    ("M", i, j) off the diagonal fills both triangles, ("Mx", i, j) the entry M[i][j] alone (a mass
    matrix that is not symmetric); ("y", 3) is the element y[3]."""
    kind, *idx = target
    if kind == "M" and idx[0] != idx[1]:
        return Element("M", (idx[0], idx[1])), Element("M", (idx[1], idx[0]))
    if kind == "Mx":
        return (Element("M", (idx[0], idx[1])),)
    return (Element(kind, tuple(idx)),)


def substitute(node: Node, leaf: Callable[[Node], Node | None]) -> Node:
    """``node`` with each leaf (Name, Element) replaced by ``leaf(it)`` where that is not None."""
    if isinstance(node, (Name, Element)):
        new = leaf(node)
        return node if new is None else new
    if isinstance(node, (Number, Integer, Ratio)):
        return node
    if isinstance(node, (Neg, Not, Sign)):
        return type(node)(substitute(node.arg, leaf))
    if isinstance(node, (BinOp, Compare)):
        return type(node)(node.op, substitute(node.left, leaf), substitute(node.right, leaf))
    if isinstance(node, Power):
        return Power(substitute(node.base, leaf), substitute(node.exp, leaf))
    if isinstance(node, Call):
        return Call(node.func, tuple(substitute(a, leaf) for a in node.args))
    if isinstance(node, Logic):
        return Logic(node.op, tuple(substitute(a, leaf) for a in node.args))
    return Select(tuple((substitute(c, leaf), substitute(v, leaf)) for c, v in node.cases),
                  substitute(node.default, leaf))


def elements(node: Node, array: str) -> set:
    """The indices of the elements of ``array`` that ``node`` reads."""
    return {n.index for n in walk(node) if isinstance(n, Element) and n.array == array}


def walk(node: Node):
    """Every node of a tree, parents before children."""
    yield node
    if isinstance(node, (Neg, Not, Sign)):
        yield from walk(node.arg)
    elif isinstance(node, (BinOp, Compare)):
        yield from walk(node.left)
        yield from walk(node.right)
    elif isinstance(node, Power):
        yield from walk(node.base)
        yield from walk(node.exp)
    elif isinstance(node, (Call, Logic)):
        for a in node.args:
            yield from walk(a)
    elif isinstance(node, Select):
        for c, v in node.cases:
            yield from walk(c)
            yield from walk(v)
        yield from walk(node.default)


#: The recursion limit while a backend prints: the tree functions here and the printers recurse
#: along a sum's or product's chain, one level per term (a closed-form term of a rigid-body tree's
#: point mass, a large model's long sums), which Python's default limit of 1000 does not allow.
DEEP_RECURSION = 100_000


@contextlib.contextmanager
def deep_recursion(limit: int = DEEP_RECURSION):
    """Raise the interpreter's recursion limit to at least ``limit`` for the block."""
    old = sys.getrecursionlimit()
    sys.setrecursionlimit(max(old, limit))
    try:
        yield
    finally:
        sys.setrecursionlimit(old)


class Printer:
    """Base of the backends' printers: ``doprint(node)`` calls ``_print_<Node>`` of the node's kind."""

    def doprint(self, node: Node) -> str:
        return getattr(self, "_print_" + type(node).__name__)(node)
