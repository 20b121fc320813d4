"""Procedures of the language-neutral tree: loops over arrays, conditions and local variables, for
the dense linear algebra the generated code carries (:mod:`.linalg` writes it once, every backend
prints it: C with :mod:`.c_procedure`, Fortran with :mod:`.fortran_procedure`).

Indices are 0-based in the tree: an index variable, an array of indices (``piv``) and the bounds
of a loop. A backend with 1-based arrays prints every index value plus one (the same values in
its own counting), so a tree means the same operations in every language.

Expressions are those of :mod:`.ir` (``Name``, ``Element`` with a tuple of index expressions,
``Number``, ``Integer``, ``BinOp``, ``Compare``, ``Not``, ``Logic`` "or", ``Call`` of :data:`FUNCTIONS`) and
:class:`Index`, an affine sum of index variables and sizes. Statements: :class:`Set` (an
assignment; ``declare``: the first of a local variable, declared there where the language allows
it), :class:`For`, :class:`EachElement` (every element of a matrix, in the order the language
keeps it), :class:`If`, :class:`Exchange` (of two elements), :class:`Return`. A :class:`Procedure`
has its arguments (:class:`Arg`), its locals (:class:`Local`) and a body.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from . import ir

#: The functions of a procedure's expressions: of a real, "abs", "sqrt", "isfinite" (a truth value);
#: "real" (a size as a real), "epsilon" (no argument: the machine epsilon of double precision).
FUNCTIONS = frozenset(("abs", "sqrt", "isfinite", "real", "epsilon"))
_PREC = {"+": 1, "-": 1, "*": 2, "/": 2}


@dataclass(frozen=True)
class Index:
    """An index value: sum of coefficient * name over ``terms`` (index variables, and sizes such
    as ``dim``, which are counts and not indices) plus ``const``."""

    terms: tuple  # ((name, coefficient), ...)
    const: int = 0


# ----------------------------------------------------------------------------- statements
@dataclass(frozen=True)
class Set:
    """``target = value`` (target an ir.Name or ir.Element); ``declare``: the first assignment of a local
    the tree declares in the innermost block (C declares it here; others at the top)."""

    target: object
    value: object
    declare: bool = False


@dataclass(frozen=True)
class For:
    """``var`` from ``lo`` up to ``hi`` - 1 (Index values), or with ``down`` from ``hi`` - 1
    down to ``lo``."""

    var: str
    lo: Index
    hi: Index
    body: tuple
    down: bool = False


@dataclass(frozen=True)
class EachElement:
    """``body`` for every element (``vars`` = (row, column)) of the square matrix ``array`` of
    ``size`` rows: for order-independent work (a maximum), in the language's storage order."""

    array: str
    size: str
    vars: tuple
    body: tuple


@dataclass(frozen=True)
class If:
    """``body`` when ``cond`` holds; no other branch (the solves need none). A language with a
    one-line ``if`` prints a body of one simple statement so."""

    cond: object
    body: tuple


@dataclass(frozen=True)
class Return:
    """Leave the procedure; ``value``: the truth value of a procedure that returns one (its last
    statement, or an early exit)."""

    value: bool | None = None


@dataclass(frozen=True)
class Exchange:
    """Exchange the elements ``at`` and ``other`` (an index value, at least ``at``) of ``array``
    where they differ, through the scoped real local ``temp``. C bounds ``other`` (as the local
    ``bound``) in an array of a constant size, which lets compilers see the access in range."""

    array: str
    at: Index
    other: object
    temp: str = "tmp"
    bound: str = "r"


# ----------------------------------------------------------------------------- declarations
@dataclass(frozen=True)
class Arg:
    """An argument: ``kind`` "int" or "real"; ``shape``: () for a scalar (passed by value), else
    the sizes of its dimensions (names of size arguments); ``intent``: "in", "out" or "inout"."""

    name: str
    kind: str
    shape: tuple = ()
    intent: str = "in"
    alt: str | None = None  # as Local.alt


@dataclass(frozen=True)
class Local:
    """A local scalar: ``kind`` "int" (an index) or "real"; ``init``: a real value set at entry;
    ``scoped``: declared at its first assignment (Set with ``declare``) where the language allows
    it; ``alt``: its name where ``name`` cannot be used (a language's intrinsic, or a name equal
    to another but for case in a language that ignores case)."""

    name: str
    kind: str
    init: float | None = None
    scoped: bool = False
    alt: str | None = None


@dataclass(frozen=True)
class Procedure:
    """A procedure: ``returns`` "truth" (a truth value, named ``result`` where the language names
    it) or None; ``layouts``: {array: size} of the matrices a language may store flat, by rows."""

    name: str
    args: tuple
    locals: tuple
    body: tuple
    returns: str | None = None
    result: str = "ok"
    layouts: dict = field(default_factory=dict)
    #: Sizes that are constants of the generated source (C: a macro such as N; Fortran: a module
    #: parameter, lower case): arrays of these sizes have them in their declarations.
    sizes: tuple = ()


def ix(*terms, const: int = 0) -> Index:
    """An Index: ``ix("i")`` is i, ``ix("k", const=1)`` is k + 1, ``ix()`` is 0; a term is a name
    (coefficient 1) or (name, coefficient)."""
    return Index(tuple((t, 1) if isinstance(t, str) else t for t in terms), const)


class Printer:
    """Base of the backends' procedure printers: the statements of a body, each printed by the
    ``_stmt_<Statement>`` method of the backend, with ``level`` the indentation depth."""

    indent = "    "

    def body(self, stmts, level: int) -> list[str]:
        """The lines of the statements ``stmts`` at depth ``level``."""
        lines: list[str] = []
        for st in stmts:
            lines += getattr(self, "_stmt_" + type(st).__name__)(st, level)
        return lines

    def pad(self, level: int) -> str:
        return self.indent * level

    def index(self, e, counts: frozenset, shift: int = 0) -> str:
        """An Index as text: its terms in order, then its constant plus ``shift`` for each term
        that is an index variable (not in ``counts``) and once (a 1-based language: shift = 1)."""
        const = e.const + (shift - shift * sum(c for name, c in e.terms if name not in counts) if shift else 0)
        text = ""
        for name, coef in e.terms:
            word = self.name(name) if coef in (1, -1) else f"{abs(coef)} * {self.name(name)}"
            text += (word if coef > 0 else "-" + word) if not text else (f" + {word}" if coef > 0 else f" - {word}")
        if not text:
            return str(const)
        return text + (f" + {const}" if const > 0 else f" - {-const}" if const < 0 else "")

    def name(self, name: str) -> str:
        return name

    #: The language's texts of negation, disjunction and comparison operators other than the tree's.
    NOT, OR, COMPARE = "!", " || ", {}

    def expr(self, e, prec: int = 0) -> str:
        """The text of the expression ``e`` (``prec``: the precedence its place asks for)."""
        if isinstance(e, ir.Name):
            return self.name(e.name)
        if isinstance(e, Index):
            return self.index_value(e)
        if isinstance(e, ir.Element):
            return self.element(e)
        if isinstance(e, ir.Number):
            return self.literal(float(e.value))
        if isinstance(e, ir.Integer):
            return str(e.value)
        if isinstance(e, ir.BinOp):
            p = _PREC[e.op]
            text = f"{self.expr(e.left, p)} {e.op} {self.expr(e.right, p + 1)}"
            return f"({text})" if p < prec else text
        if isinstance(e, ir.Call):
            if e.func not in FUNCTIONS:
                raise TypeError(f"no function {e.func!r} in a procedure (functions: {', '.join(sorted(FUNCTIONS))})")
            return self.call(e.func, [self.expr(a) for a in e.args])
        if isinstance(e, ir.Compare):
            return f"{self.expr(e.left)} {self.COMPARE.get(e.op, e.op)} {self.expr(e.right)}"
        if isinstance(e, ir.Not):
            inner = self.expr(e.arg)
            return self.NOT + (inner if isinstance(e.arg, ir.Call) else f"({inner})")
        if isinstance(e, ir.Logic) and e.op == "or":
            return self.OR.join(self.expr(a) for a in e.args)
        raise TypeError(f"no text for {type(e).__name__} in a procedure")
