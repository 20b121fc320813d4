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
        self.counts = frozenset(a.name for a in proc.args if not a.shape and a.kind == "int") | set(proc.sizes)
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
        const = "const " if a.intent == "in" else ""
        if self._fixed(a.name):
            return f"{const}{_TYPES[a.kind]} {a.name}{''.join(f'[{n}]' for n in a.shape)}"
        return f"{const}{_TYPES[a.kind]} *{a.name}"

    def _fixed(self, array: str) -> bool:
        """Whether the argument ``array`` has a constant size (an array type, not a pointer)."""
        return any(a.name == array and a.shape and set(a.shape) <= set(self.proc.sizes) for a in self.proc.args)

    # ------------------------------------------------------------------ statements
    def _block(self, head: str, stmts, level: int) -> list[str]:
        inner = self.body(stmts, level + 1)
        if len(stmts) == 1 and not (isinstance(stmts[0], pr.Exchange) and self._fixed(stmts[0].array)):
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
        if len(e.index) == 1 or e.array not in self.proc.layouts:
            return e.array + "".join(f"[{self.expr(i)}]" for i in e.index)
        row, col = e.index
        return f"{e.array}[{self.expr(row)} * {self.proc.layouts[e.array]} + {self.expr(col)}]"
