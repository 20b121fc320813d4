"""C99 text of the procedures of the tree (:mod:`.procedure`): a ``static`` function, the locals
the tree scopes declared at their first assignment, compound assignments (``-=``, ``/=``), braces
only around bodies of more than one statement, flat row-major storage of the matrices the tree
lets a language store so (``K[i * dim + j]``). Needs <float.h> and <math.h>."""

from __future__ import annotations

from . import ir
from . import procedure as pr

_TYPES = {"int": "int", "real": "double"}
_FUNCTIONS = {"abs": "fabs"}


class CProcedurePrinter(pr.Printer):
    """Prints a :class:`~.procedure.Procedure` as a static C99 function."""

    def text(self, proc: pr.Procedure) -> str:
        """The function, without a final newline."""
        self.proc = proc
        self.kinds = {**{a.name: a.kind for a in proc.args}, **{v.name: v.kind for v in proc.locals}}
        self.counts = frozenset(a.name for a in proc.args if not a.shape and a.kind == "int")
        self.flat: dict = {}
        args = ", ".join(self._arg(a) for a in proc.args)
        head = f"static {'int' if proc.returns else 'void'} {proc.name}({args})"
        lines = [head, "{"]
        for kind in ("real", "int"):
            top = [v for v in proc.locals if v.kind == kind and not v.scoped]
            if top:
                lines.append(self.pad(1) + _TYPES[kind] + " " + ", ".join(
                    v.name + ("" if v.init is None else f" = {self.literal(v.init)}") for v in top) + ";")
        lines.append("")
        lines += self.body(proc.body, 1)
        return "\n".join(lines + ["}"])

    def _arg(self, a: pr.Arg) -> str:
        if not a.shape:
            return f"{_TYPES[a.kind]} {a.name}"
        return f"{'const ' if a.intent == 'in' else ''}{_TYPES[a.kind]} *{a.name}"

    # ------------------------------------------------------------------ statements
    def _block(self, head: str, stmts, level: int) -> list[str]:
        inner = self.body(stmts, level + 1)
        if len(stmts) == 1:
            return [self.pad(level) + head] + inner
        return [self.pad(level) + head + " {"] + inner + [self.pad(level) + "}"]

    def _stmt_Set(self, st: pr.Set, level: int) -> list[str]:
        target = self.expr(st.target)
        if st.declare:
            return [f"{self.pad(level)}{_TYPES[self.kinds[st.target.name]]} {target} = {self.expr(st.value)};"]
        v = st.value
        if isinstance(v, ir.BinOp) and v.op in "-/" and v.left == st.target:
            return [f"{self.pad(level)}{target} {v.op}= {self.expr(v.right)};"]
        return [f"{self.pad(level)}{target} = {self.expr(v)};"]

    def _stmt_For(self, st: pr.For, level: int) -> list[str]:
        v = st.var
        if st.down:
            top = pr.Index(st.hi.terms, st.hi.const - 1)
            head = f"for ({v} = {self.expr(top)}; {v} >= {self.expr(st.lo)}; --{v})"
        else:
            head = f"for ({v} = {self.expr(st.lo)}; {v} < {self.expr(st.hi)}; ++{v})"
        return self._block(head, st.body, level)

    def _stmt_EachElement(self, st: pr.EachElement, level: int) -> list[str]:
        """One loop over the flat storage (the first variable runs over all size * size elements)."""
        i = st.vars[0]
        self.flat[st.array] = i
        try:
            return self._block(f"for ({i} = 0; {i} < {st.size} * {st.size}; ++{i})", st.body, level)
        finally:
            del self.flat[st.array]

    def _stmt_If(self, st: pr.If, level: int) -> list[str]:
        return self._block(f"if ({self.expr(st.cond)})", st.body, level)

    def _stmt_Return(self, st: pr.Return, level: int) -> list[str]:
        if st.value is None:
            return [self.pad(level) + "return;"]
        return [f"{self.pad(level)}return {int(st.value)};"]

    # ------------------------------------------------------------------ expressions
    def index_value(self, e: pr.Index) -> str:
        return self.index(e, self.counts)

    def literal(self, value: float) -> str:
        text = repr(value)
        return text if "e" in text or "." in text else text + ".0"

    def call(self, func: str, args: list) -> str:
        if func == "epsilon":
            return "DBL_EPSILON"
        if func == "real":  # C converts by itself
            return args[0]
        return f"{_FUNCTIONS.get(func, func)}({', '.join(args)})"

    def element(self, e: ir.Element) -> str:
        if e.array in self.flat:  # inside EachElement: the flat index
            return f"{e.array}[{self.flat[e.array]}]"
        if len(e.index) == 1:
            return f"{e.array}[{self.expr(e.index[0])}]"
        row, col = e.index
        return f"{e.array}[{self.expr(row)} * {self.proc.layouts[e.array]} + {self.expr(col)}]"
