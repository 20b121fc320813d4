"""C99 text of the procedures of the tree (:mod:`.procedure`): a ``static`` function, the locals
the tree scopes declared at their first assignment, compound assignments (``-=``, ``/=``), braces
only around bodies of more than one statement, flat row-major storage of the matrices the tree
lets a language store so (``K[i * dim + j]``), a fallback as a ``goto`` to its label, a loop up a
tree as ``for (i = P[k]; i >= 0; i = P[i])``. Needs <float.h> and <math.h>.

A backend chooses per procedure how its arguments read (the printer's options): ``dims`` names a
size in declarations (C has no array of size zero: ``{"J": "JD"}``, a size at least 1),
``vector_pointers`` declares the vectors as pointers, and without ``const_matrices`` the matrices
read but not written are declared without ``const`` (C99 converts a ``double (*)[N]`` to a
``const double (*)[N]`` only by a cast, which callers that pass their own arrays do not write)."""

from __future__ import annotations

from . import ir
from . import procedure as pr

_TYPES = {"int": "int", "real": "double"}
_FUNCTIONS = {"abs": "fabs"}


class CProcedurePrinter(pr.Printer):
    """Prints a :class:`~.procedure.Procedure` as a static C99 function."""

    #: Columns of a function's head before its arguments continue on the next line.
    WIDTH = 110

    def __init__(self, dims: dict | None = None, vector_pointers: bool = False, const_matrices: bool = True):
        self.dims = dims or {}
        self.vector_pointers = vector_pointers
        self.const_matrices = const_matrices

    def text(self, proc: pr.Procedure) -> str:
        """The function, without a final newline."""
        self.proc = proc
        self.kinds = {**{a.name: a.kind for a in proc.args}, **{v.name: v.kind for v in proc.locals}}
        self.counts = frozenset(a.name for a in proc.args if not a.shape and a.kind == "int") | set(proc.sizes)
        self.flat: dict = {}
        self.label = next((st.label for st in pr.walk(proc.body) if isinstance(st, pr.Fallback)), None)
        lead = f"static {'int' if proc.returns else 'void'} {proc.name}("
        lines = [lead]
        for i, a in enumerate(proc.args):
            word = self._arg(a) + (")" if i == len(proc.args) - 1 else ",")
            if i and len(lines[-1]) + 1 + len(word) > self.WIDTH:
                lines.append(" " * len(lead) + word)
            else:
                lines[-1] += (" " if i else "") + word
        lines.append("{")
        for kind in ("real", "int"):
            top = [v for v in proc.locals if v.kind == kind and not v.scoped]
            if top:
                lines.append(self.pad(1) + _TYPES[kind] + " " + ", ".join(
                    v.name + self._dims(v.shape) + ("" if v.init is None else f" = {self.literal(v.init)}")
                    for v in top) + ";")
        lines.append("")
        lines += self.body(proc.body, 1)
        return "\n".join(lines + ["}"])

    def _dims(self, shape) -> str:
        return "".join(f"[{self.dims.get(n, n)}]" for n in shape)

    def _arg(self, a: pr.Arg) -> str:
        if not a.shape:
            return f"{_TYPES[a.kind]} {a.name}"
        const = "const " if a.intent == "in" and (len(a.shape) == 1 or self.const_matrices) else ""
        if self._fixed(a.name) and not (self.vector_pointers and len(a.shape) == 1):
            return f"{const}{_TYPES[a.kind]} {a.name}{self._dims(a.shape)}"
        return f"{const}{_TYPES[a.kind]} *{a.name}"

    def _fixed(self, array: str) -> bool:
        """Whether the argument ``array`` has a constant size (an array type, not a pointer)."""
        return any(a.name == array and a.shape and set(a.shape) <= set(self.proc.sizes) for a in self.proc.args)

    # ------------------------------------------------------------------ statements
    def _block(self, head: str, stmts, level: int, note: str | None = None, gap: str = "  ") -> list[str]:
        """``head`` and its body, braced unless one statement; ``note`` a comment after the head
        (``gap`` before it; after the brace of a braced body)."""
        inner = self.body(stmts, level + 1)
        note = f"{gap}/* {note} */" if note else ""
        if len(stmts) == 1 and not (isinstance(stmts[0], pr.Exchange) and self._fixed(stmts[0].array)):
            return [self.pad(level) + head + note] + inner
        return [self.pad(level) + head + " {" + note] + inner + [self.pad(level) + "}"]

    def _stmt_Set(self, st: pr.Set, level: int) -> list[str]:
        target = self.expr(st.target)
        if st.declare:
            return [f"{self.pad(level)}{_TYPES[self.kinds[st.target.name]]} {target} = {self.expr(st.value)};"]
        v = st.value
        if isinstance(v, ir.BinOp) and v.op in "+-/" and v.left == st.target:
            return [f"{self.pad(level)}{target} {v.op}= {self.expr(v.right)};"]
        return [f"{self.pad(level)}{target} = {self.expr(v)};"]

    def _stmt_For(self, st: pr.For, level: int) -> list[str]:
        v = st.var
        if st.down:
            top = pr.Index(st.hi.terms, st.hi.const - 1)
            head = f"for ({v} = {self.expr(top)}; {v} >= {self.expr(st.lo)}; --{v})"
        else:
            below = f"< {self.expr(st.hi)}"
            if st.hi.terms and st.hi.const == 1:  # up to x + 1 exclusive: up to x inclusive
                below = f"<= {self.expr(pr.Index(st.hi.terms))}"
            head = f"for ({v} = {self.expr(st.lo)}; {v} {below}; ++{v})"
        return self._block(head, st.body, level, st.note)

    def _stmt_Ancestors(self, st: pr.Ancestors, level: int) -> list[str]:
        """``for (i = P[k]; i >= 0; i = P[i])`` (inclusive: from ``i = k``)."""
        v = st.var
        start = self.expr(st.of if st.inclusive else ir.Element(st.parents, (st.of,)))
        step = self.expr(ir.Element(st.parents, (pr.ix(v),)))
        return self._block(f"for ({v} = {start}; {v} >= 0; {v} = {step})", st.body, level)

    def _stmt_EachElement(self, st: pr.EachElement, level: int) -> list[str]:
        """One loop over the flat storage (the first variable runs over all size * size elements)."""
        i = st.vars[0]
        self.flat[st.array] = i
        try:
            return self._block(f"for ({i} = 0; {i} < {st.size} * {st.size}; ++{i})", st.body, level)
        finally:
            del self.flat[st.array]

    def _stmt_If(self, st: pr.If, level: int) -> list[str]:
        return self._block(f"if ({self.expr(st.cond)})", st.body, level, st.note, gap=" ")

    def _stmt_Exchange(self, st: pr.Exchange, level: int) -> list[str]:
        at, a = self.expr(st.at), st.array
        size = next(x.shape[0] for x in self.proc.args if x.name == a) if self._fixed(a) else None
        other = st.bound if size else self.expr(st.other)
        swap = (pr.Set(ir.Name(st.temp), ir.Element(a, (st.at,)), declare=True),
                pr.Set(ir.Element(a, (st.at,)), ir.Element(a, (ir.Name(other),))),
                pr.Set(ir.Element(a, (ir.Name(other),)), ir.Name(st.temp)))
        if size is None:
            return self._block(f"if ({other} != {at})", swap, level)
        return ([f"{self.pad(level)}const int {other} = {self.expr(st.other)};  /* in [{at}, {size}) by construction; "
                 "the bound lets compilers see it */"]
                + self._block(f"if ({other} != {at} && {other} > {at} && {other} < {size})", swap, level))

    def _stmt_Return(self, st: pr.Return, level: int) -> list[str]:
        if st.value is None:
            return [self.pad(level) + "return;"]
        return [f"{self.pad(level)}return {int(st.value)};"]

    def _stmt_Fallback(self, st: pr.Fallback, level: int) -> list[str]:
        """The first way, its return, then the second way under its label."""
        return (self.body(st.first, level) + [f"{self.pad(level)}return {st.kinds[0]};", "", f"{st.label}:"]
                + self.body(st.second, level))

    def _stmt_Fail(self, st: pr.Fail, level: int) -> list[str]:
        if self.label is None:
            raise ValueError("a Fail outside a procedure with a Fallback")
        return [f"{self.pad(level)}goto {self.label};"]

    def _stmt_Identity(self, st: pr.Identity, level: int) -> list[str]:
        return self._stmt_Set(pr.Set(ir.Element(st.array, (st.at,)), st.at), level)

    def _stmt_Sized(self, st: pr.Sized, level: int) -> list[str]:
        """The loops run zero times where the size is zero."""
        return self.body(st.body, level)

    def _stmt_Comment(self, st: pr.Comment, level: int) -> list[str]:
        """``/* text */``; text of several lines continued by `` * ``, closed on its last."""
        first, *more = st.text.split("\n")
        lines = [f"{self.pad(level)}/* {first}"] + [f"{self.pad(level)} * {line}" for line in more]
        lines[-1] += " */"
        return lines

    def _stmt_Blank(self, st: pr.Blank, level: int) -> list[str]:
        return [""]

    # ------------------------------------------------------------------ expressions
    def index_value(self, e: pr.Index) -> str:
        return self.index(e, self.counts)

    def literal(self, value: float) -> str:
        text = repr(value)
        if "e" in text:  # 1e-08: 1e-8
            mantissa, exponent = text.split("e")
            return f"{mantissa}e{int(exponent)}"
        return text if "." in text else text + ".0"

    def call(self, func: str, args: list) -> str:
        if func == "epsilon":
            return "DBL_EPSILON"
        if func == "real":  # C converts by itself
            return args[0]
        return f"{_FUNCTIONS.get(func, func)}({', '.join(args)})"

    def element(self, e: ir.Element) -> str:
        if e.array in self.flat:  # inside EachElement: the flat index
            return f"{e.array}[{self.flat[e.array]}]"
        if len(e.index) == 1 or e.array not in self.proc.layouts:
            return e.array + "".join(f"[{self.expr(i)}]" for i in e.index)
        row, col = e.index
        return f"{e.array}[{self.expr(row)} * {self.proc.layouts[e.array]} + {self.expr(col)}]"
