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
it), :class:`For`, :class:`Ancestors` (a loop up a tree along an array of parents),
:class:`EachElement` (every element of a matrix, in the order the language keeps it), :class:`If`,
:class:`Exchange` (of two elements), :class:`Return`, :class:`Fallback` with :class:`Fail` (a
first way that may give up for a second one), :class:`Identity` (of a permutation),
:class:`Sized` (work that only a nonzero size asks for), :class:`Comment` and :class:`Blank`. A
:class:`Procedure` has its arguments (:class:`Arg`), its locals (:class:`Local`) and a body.

What the tree says is what is computed; how it reads is the printer's: a fallback is a ``goto``
in C and a flag with ``exit`` in Fortran, an identity permutation is set where C's code needs it
and at entry in Fortran (whose ``intent(out)`` arrays are otherwise undefined), sizes are named
per language (the printer's table of sizes), and a printer that knows a size to be zero at
compile time leaves out the work and the locals that need it.
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
    note: str | None = None  # what the loop computes, printed as a comment on its head


@dataclass(frozen=True)
class EachElement:
    """``body`` for every element (``vars`` = (row, column)) of the square matrix ``array`` of
    ``size`` rows: for order-independent work (a maximum), in the language's storage order."""

    array: str
    size: str
    vars: tuple
    body: tuple


@dataclass(frozen=True)
class Ancestors:
    """``body`` for ``var`` over the ancestors of ``of`` (an Index value) in a tree, from its parent
    to the root (with ``inclusive``: from ``of`` itself). ``parents`` is an array of index values
    (as ``piv``), each node's parent, the value before the first index (-1) at a root: a
    language with 1-based arrays holds them plus one (0 at a root), like every index value."""

    var: str
    of: Index
    parents: str
    body: tuple
    inclusive: bool = False


@dataclass(frozen=True)
class If:
    """``body`` when ``cond`` holds; no other branch (the solves need none). A language with a
    one-line ``if`` prints a body of one simple statement so. ``note``: what the body does,
    printed as a comment opening it."""

    cond: object
    body: tuple
    note: str | None = None


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


@dataclass(frozen=True)
class Fail:
    """Give up the first way of the procedure's :class:`Fallback` and take its second. Inside the
    first way's outer loop (Fortran leaves that loop), or before the Fallback (C: a ``goto``)."""


@dataclass(frozen=True)
class Fallback:
    """``first``, then the procedure returns ``kinds[0]``; where a :class:`Fail` in it gives up,
    ``second`` (which returns ``kinds[1]`` itself). ``label``: the name of the second way where
    the language jumps to it; ``note``: its description where the language prints one."""

    first: tuple
    second: tuple
    kinds: tuple = (1, 2)
    label: str = "fallback"
    note: str | None = None


@dataclass(frozen=True)
class Identity:
    """Element ``at`` of the permutation ``array`` is ``at`` (on this path the permutation is the
    identity): printed here, or left out by a printer that sets the whole permutation at entry
    (``Procedure.identity``)."""

    array: str
    at: Index


@dataclass(frozen=True)
class Sized:
    """Statements that only do work where ``size`` is nonzero; a printer that knows ``size`` to be
    zero at compile time leaves them out (with the locals that need it, :attr:`Local.needs`), and
    ``none`` describes that case where the language says why arguments go unused."""

    size: str
    body: tuple
    none: str | None = None


@dataclass(frozen=True)
class Comment:
    """A comment: one line, or several (``text`` with newlines)."""

    text: str


@dataclass(frozen=True)
class Blank:
    """An empty line."""


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
    shape: tuple = ()  # a local array: the sizes of its dimensions
    needs: str | None = None  # a size whose work (Sized) alone uses the local

    def sizes(self) -> set:
        """The sizes whose being zero makes the local needless."""
        return set(self.shape) | ({self.needs} if self.needs else set())


@dataclass(frozen=True)
class Procedure:
    """A procedure: ``returns`` "truth" (a truth value, named ``result`` where the language names
    it), "kind" (a small integer, likewise) or None; ``layouts``: {array: size} of the matrices a
    language may store flat, by rows; ``identity``: ((array, size), ...), permutations that are
    the identity where the body does not write them (the body says where it needs that with
    :class:`Identity`)."""

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
    identity: tuple = ()

    def guarded(self) -> set:
        """The sizes of the :class:`Sized` parts of the body."""
        return {st.size for st in walk(self.body) if isinstance(st, Sized)}

    def last(self):
        """The statement the procedure ends with (inside a closing :class:`Fallback`)."""
        st = self.body[-1]
        while isinstance(st, Fallback):
            st = st.second[-1]
        return st


def walk(stmts, skip=frozenset()):
    """Every statement of ``stmts`` and of the bodies inside, outer first; ``skip``: sizes whose
    :class:`Sized` parts are left out."""
    for st in stmts:
        if isinstance(st, Sized) and st.size in skip:
            continue
        yield st
        for inner in ("body", "first", "second"):
            if isinstance(getattr(st, inner, None), tuple):
                yield from walk(getattr(st, inner), skip)


def names(node) -> set:
    """The names (variables, arrays, sizes) an expression or a statement's own fields use."""
    found: set = set()
    if isinstance(node, (tuple, list)):
        for x in node:
            found |= names(x)
    elif isinstance(node, ir.Name):
        found.add(node.name)
    elif isinstance(node, Index):
        found |= {name for name, _ in node.terms}
    elif hasattr(node, "__dataclass_fields__"):
        for f in node.__dataclass_fields__:
            value = getattr(node, f)
            if f in ("array", "var", "size", "parents") and isinstance(value, str):
                found.add(value)
            elif f not in ("body", "first", "second"):
                found |= names(value)
    return found


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
        if isinstance(e, ir.Neg):
            text = "-" + self.expr(e.arg, 3)
            return f"({text})" if prec > 1 else text
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
