"""Fortran 2008 text of the procedures of the tree (:mod:`.procedure`), as module procedures
(indented for the ``contains`` part): 1-based indices (every index value of the tree plus one),
every local declared at the top, a truth value as a ``logical`` result set false at entry, a
one-line ``if`` around a single simple statement, matrices as 2-D arrays. A local takes its
other name (``Local.alt``) where its own is a Fortran intrinsic's or equals another name of the
procedure but for case (Fortran ignores case). Needs ``c_double`` and ``ieee_is_finite``."""

from __future__ import annotations

from . import ir
from . import procedure as pr

_TYPES = {"int": "integer", "real": "real(c_double)"}
_FUNCTIONS = {"isfinite": "ieee_is_finite"}
#: Names of Fortran intrinsic procedures that the tree's locals and arguments use (legal to shadow,
#: but unclear): each such one takes its other name.
INTRINSICS = frozenset(("scale", "kind"))


class FortranProcedurePrinter(pr.Printer):
    """Prints a :class:`~.procedure.Procedure` as a recursive module procedure."""

    indent = "  "

    def text(self, proc: pr.Procedure) -> str:
        """The procedure, without a final newline."""
        self.proc = proc
        self.counts = frozenset(a.name for a in proc.args if not a.shape and a.kind == "int") | set(proc.sizes)
        names = [a.name for a in proc.args] + [v.name for v in proc.locals]
        self.names = {size: size.lower() for size in proc.sizes}
        for v in proc.args + proc.locals:
            clash = any(o != v.name and o.lower() == v.name.lower() for o in names)
            self.names[v.name] = v.alt if v.alt and (clash or v.name.lower() in INTRINSICS) else v.name
        arglist = ", ".join(self.name(a.name) for a in proc.args)
        kind, head = (("function", f"recursive logical function {proc.name}({arglist}) result({proc.result})")
                      if proc.returns else ("subroutine", f"recursive subroutine {proc.name}({arglist})"))
        lines = [self.pad(1) + head]
        for a in proc.args:
            shape = f"({', '.join(map(self.name, a.shape))})" if a.shape else ""
            lines.append(f"{self.pad(2)}{_TYPES[a.kind]}, intent({a.intent}) :: {self.name(a.name)}{shape}")
        for kind_ in ("real", "int"):
            local = [self.name(v.name) for v in proc.locals if v.kind == kind_]
            if local:
                lines.append(f"{self.pad(2)}{_TYPES[kind_]} :: {', '.join(local)}")
        lines.append("")
        if proc.returns:
            lines.append(f"{self.pad(2)}{proc.result} = .false.")
        lines += [f"{self.pad(2)}{self.name(v.name)} = {self.literal(v.init)}"
                  for v in proc.locals if v.init is not None]
        lines += self.body(proc.body, 2)
        return "\n".join(lines + [f"{self.pad(1)}end {kind} {proc.name}"])

    def name(self, name: str) -> str:
        return self.names.get(name, name)

    # ------------------------------------------------------------------ statements
    def _stmt_Set(self, st: pr.Set, level: int) -> list[str]:
        return [f"{self.pad(level)}{self.expr(st.target)} = {self.expr(st.value)}"]

    def _stmt_For(self, st: pr.For, level: int) -> list[str]:
        lo = self.index(st.lo, self.counts, 1)
        hi = self.index(pr.Index(st.hi.terms, st.hi.const - 1), self.counts, 1)
        head = f"do {self.name(st.var)} = {hi}, {lo}, -1" if st.down else f"do {self.name(st.var)} = {lo}, {hi}"
        return [self.pad(level) + head] + self.body(st.body, level + 1) + [self.pad(level) + "end do"]

    def _stmt_EachElement(self, st: pr.EachElement, level: int) -> list[str]:
        """Nested loops over rows, then columns."""
        i, j = (self.name(v) for v in st.vars)
        size = self.name(st.size)
        return ([f"{self.pad(level)}do {i} = 1, {size}", f"{self.pad(level + 1)}do {j} = 1, {size}"]
                + self.body(st.body, level + 2) + [self.pad(level + 1) + "end do", self.pad(level) + "end do"])

    def _stmt_If(self, st: pr.If, level: int) -> list[str]:
        cond = self.expr(st.cond)
        if len(st.body) == 1 and isinstance(st.body[0], (pr.Set, pr.Return)):
            inner = self.body(st.body, 0)
            if len(inner) == 1:
                return [f"{self.pad(level)}if ({cond}) {inner[0]}"]
        return ([f"{self.pad(level)}if ({cond}) then"] + self.body(st.body, level + 1)
                + [self.pad(level) + "end if"])

    def _stmt_Exchange(self, st: pr.Exchange, level: int) -> list[str]:
        at, other = ir.Element(st.array, (st.at,)), ir.Element(st.array, (st.other,))
        swap = (pr.Set(ir.Name(st.temp), at), pr.Set(at, other), pr.Set(other, ir.Name(st.temp)))
        return self._stmt_If(pr.If(ir.Compare("!=", st.other, st.at), swap), level)

    def _stmt_Return(self, st: pr.Return, level: int) -> list[str]:
        """False: ``return`` (the result is false from the entry on); true: the result set, and
        ``return`` unless it is the procedure's last statement."""
        lines = [f"{self.pad(level)}{self.proc.result} = .true."] if st.value else []
        if not st.value or st is not self.proc.body[-1]:
            lines.append(self.pad(level) + "return")
        return lines

    # ------------------------------------------------------------------ expressions
    NOT, OR, COMPARE = ".not. ", " .or. ", {"!=": "/="}

    def index_value(self, e: pr.Index) -> str:
        return self.index(e, self.counts, 1)

    def literal(self, value: float) -> str:
        return f"{value!r}_c_double"

    def call(self, func: str, args: list) -> str:
        if func == "epsilon":
            return "epsilon(1.0_c_double)"
        if func == "real":
            return f"real({args[0]}, c_double)"
        return f"{_FUNCTIONS.get(func, func)}({', '.join(args)})"

    def element(self, e: ir.Element) -> str:
        return f"{e.array}({', '.join(self.expr(i) for i in e.index)})"
