"""Fortran 2008 text of the procedures of the tree (:mod:`.procedure`), as module procedures
(indented for the ``contains`` part): 1-based indices (every index value of the tree plus one),
every local declared at the top, a truth value as a ``logical`` result set false at entry, a
one-line ``if`` around a single simple statement, matrices as 2-D arrays. A local takes its
other name (``Local.alt``) where its own is a Fortran intrinsic's or equals another name of the
procedure but for case (Fortran ignores case). Needs ``c_double`` and ``ieee_is_finite``.

Idioms of its own: a fallback sets the result as a flag, leaves the first way's loop with ``exit``
and returns after it unless the flag changed; a permutation the tree keeps as the identity is set
so at entry (an ``intent(out)`` array is undefined until written); a loop up a tree is a
``do while`` over the array of parents, whose values are 1-based like every index value (0 at a root);
consecutive arguments of one type and intent share a declaration. The printer's options: ``sizes``
names the tree's sizes (the module's parameters, e.g. ``{"N": "nq"}``; by default a size's name in
lower case), ``zero`` the sizes that are zero at compile time (their :class:`~.procedure.Sized`
work and the locals it needs are left out, the arguments that leaves unused named in an empty
``associate``), and ``spaced`` a blank line after the declarations."""

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

    def __init__(self, sizes: dict | None = None, zero=(), spaced: bool = True):
        self.sizes = sizes or {}
        self.zero = frozenset(zero)
        self.spaced = spaced

    def text(self, proc: pr.Procedure) -> str:
        """The procedure, without a final newline."""
        self.proc = proc
        self.counts = frozenset(a.name for a in proc.args if not a.shape and a.kind == "int") | set(proc.sizes)
        names = [a.name for a in proc.args] + [v.name for v in proc.locals]
        self.names = {size: self.sizes.get(size, size.lower()) for size in proc.sizes}
        for v in proc.args + proc.locals:
            clash = any(o != v.name and o.lower() == v.name.lower() for o in names)
            self.names[v.name] = v.alt if v.alt and (clash or v.name.lower() in INTRINSICS) else v.name
        self.fallback, self.loops, self._outer = None, 0, None
        arglist = ", ".join(self.name(a.name) for a in proc.args)
        result = {"truth": "logical", "kind": "integer"}.get(proc.returns)
        kind, head = (("function", f"recursive {result} function {proc.name}({arglist}) result({proc.result})")
                      if proc.returns else ("subroutine", f"recursive subroutine {proc.name}({arglist})"))
        lines = [self.pad(1) + head]
        for a in proc.args:
            decl = f"{self.pad(2)}{_TYPES[a.kind]}, intent({a.intent}) :: "
            if lines[-1].startswith(decl):  # the previous argument's type and intent
                lines[-1] += ", " + self.name(a.name) + self._shape(a.shape)
            else:
                lines.append(decl + self.name(a.name) + self._shape(a.shape))
        # the locals of Sized work after the others (the declaration without them is the same text)
        guarded = proc.guarded()
        ordered = ([v for v in proc.locals if not v.sizes() & guarded]
                   + [v for v in proc.locals if v.sizes() & guarded and not v.sizes() & self.zero])
        for kind_ in ("real", "int"):
            local = [self.name(v.name) + self._shape(v.shape) for v in ordered if v.kind == kind_]
            if local:
                lines.append(f"{self.pad(2)}{_TYPES[kind_]} :: {', '.join(local)}")
        if self.spaced:
            lines.append("")
        used = set().union({a for a, _ in proc.identity}, *(pr.names(st) for st in pr.walk(proc.body, self.zero)))
        unused = [self.name(a.name) for a in proc.args if a.name not in used]
        if unused:
            none = next((st.none for st in pr.walk(proc.body) if isinstance(st, pr.Sized) and st.none), None)
            lines += ["", *([f"{self.pad(2)}! {none}"] if none else []),
                      f"{self.pad(2)}associate ({', '.join(f'unused_{n} => {n}' for n in unused)})",
                      f"{self.pad(2)}end associate"]
        if proc.returns == "truth":
            lines.append(f"{self.pad(2)}{proc.result} = .false.")
        for array, size in proc.identity:
            lines += self.body((pr.For("i", pr.ix(), pr.ix(size), (
                pr.Set(ir.Element(array, (pr.ix("i"),)), pr.ix("i")),)),), 2)
        lines += [f"{self.pad(2)}{self.name(v.name)} = {self.literal(v.init)}"
                  for v in proc.locals if v.init is not None]
        lines += self.body(proc.body, 2)
        return "\n".join(lines + [f"{self.pad(1)}end {kind} {proc.name}"])

    def _shape(self, shape) -> str:
        return f"({', '.join(map(self.name, shape))})" if shape else ""

    def name(self, name: str) -> str:
        return self.names.get(name, name)

    # ------------------------------------------------------------------ statements
    def _stmt_Set(self, st: pr.Set, level: int) -> list[str]:
        return [f"{self.pad(level)}{self.expr(st.target)} = {self.expr(st.value)}"]

    def _stmt_For(self, st: pr.For, level: int) -> list[str]:
        lo = self.index(st.lo, self.counts, 1)
        hi = self.index(pr.Index(st.hi.terms, st.hi.const - 1), self.counts, 1)
        head = f"do {self.name(st.var)} = {hi}, {lo}, -1" if st.down else f"do {self.name(st.var)} = {lo}, {hi}"
        self.loops += 1
        try:
            inner = self.body(st.body, level + 1)
        finally:
            self.loops -= 1
        return [self.pad(level) + head + (f" ! {st.note}" if st.note else "")] + inner + [self.pad(level) + "end do"]

    def _stmt_Ancestors(self, st: pr.Ancestors, level: int) -> list[str]:
        """``i = P(k)``, then ``do while (i >= 1)`` with ``i = P(i)`` closing the body (the parents
        in 1-based values, 0 at a root; inclusive: from ``i = k``)."""
        v = ir.Name(st.var)
        up = lambda at: pr.Set(v, ir.Element(st.parents, (at,)))  # noqa: E731
        start = pr.Set(v, st.of) if st.inclusive else up(st.of)
        self.loops += 1
        try:
            inner = self.body(st.body + (up(pr.ix(st.var)),), level + 1)
        finally:
            self.loops -= 1
        cond = self.expr(ir.Compare(">=", pr.ix(st.var), pr.ix()))  # at or after the first index
        return (self._stmt_Set(start, level) + [f"{self.pad(level)}do while ({cond})"] + inner
                + [self.pad(level) + "end do"])

    def _stmt_EachElement(self, st: pr.EachElement, level: int) -> list[str]:
        """Nested loops over rows, then columns."""
        i, j = (self.name(v) for v in st.vars)
        size = self.name(st.size)
        return ([f"{self.pad(level)}do {i} = 1, {size}", f"{self.pad(level + 1)}do {j} = 1, {size}"]
                + self.body(st.body, level + 2) + [self.pad(level + 1) + "end do", self.pad(level) + "end do"])

    def _stmt_If(self, st: pr.If, level: int) -> list[str]:
        cond = self.expr(st.cond)
        if len(st.body) == 1 and isinstance(st.body[0], (pr.Set, pr.Return)) and not st.note:
            inner = self.body(st.body, 0)
            if len(inner) == 1:
                return [f"{self.pad(level)}if ({cond}) {inner[0]}"]
        note = f" ! {st.note}" if st.note else ""
        return ([f"{self.pad(level)}if ({cond}) then{note}"] + self.body(st.body, level + 1)
                + [self.pad(level) + "end if"])

    def _stmt_Exchange(self, st: pr.Exchange, level: int) -> list[str]:
        at, other = ir.Element(st.array, (st.at,)), ir.Element(st.array, (st.other,))
        swap = (pr.Set(ir.Name(st.temp), at), pr.Set(at, other), pr.Set(other, ir.Name(st.temp)))
        return self._stmt_If(pr.If(ir.Compare("!=", st.other, st.at), swap), level)

    def _stmt_Return(self, st: pr.Return, level: int) -> list[str]:
        """A truth value false: ``return`` (the result is false from the entry on); true, or a
        kind: the result set, and ``return`` unless it is the procedure's last statement."""
        if self.proc.returns == "kind":
            lines = [f"{self.pad(level)}{self.proc.result} = {int(st.value)}"]
        else:
            lines = [f"{self.pad(level)}{self.proc.result} = .true."] if st.value else []
        if not st.value or st is not self.proc.last():
            lines.append(self.pad(level) + "return")
        return lines

    def _stmt_Fallback(self, st: pr.Fallback, level: int) -> list[str]:
        """The result as the flag: the first way's kind, changed by a Fail, which leaves the loop."""
        self.fallback = st
        try:
            first = self.body(st.first, level)
        finally:
            self.fallback = None
        return ([f"{self.pad(level)}{self.proc.result} = {st.kinds[0]}"] + first
                + [f"{self.pad(level)}if ({self.proc.result} == {st.kinds[0]}) return", ""]
                + ([f"{self.pad(level)}! {st.note}"] if st.note else []) + self.body(st.second, level))

    def _stmt_Fail(self, st: pr.Fail, level: int) -> list[str]:
        if self.fallback is None or self.loops != 1 or self.fallback.first[-1] is not self._outer:
            raise NotImplementedError("Fortran leaves the first way of a fallback only from its closing outer loop")
        return [f"{self.pad(level)}{self.proc.result} = {self.fallback.kinds[1]}", self.pad(level) + "exit"]

    def body(self, stmts, level: int) -> list[str]:
        lines: list[str] = []
        for st in stmts:
            if isinstance(st, pr.For) and self.loops == 0:
                self._outer = st
            lines += getattr(self, "_stmt_" + type(st).__name__)(st, level)
        return lines

    def _stmt_Identity(self, st: pr.Identity, level: int) -> list[str]:
        """Set at entry (Procedure.identity)."""
        if not any(array == st.array for array, _ in self.proc.identity):
            raise ValueError(f"{st.array} is not among the procedure's identity permutations")
        return []

    def _stmt_Sized(self, st: pr.Sized, level: int) -> list[str]:
        return [] if st.size in self.zero else self.body(st.body, level)

    def _stmt_Comment(self, st: pr.Comment, level: int) -> list[str]:
        return [f"{self.pad(level)}! {line}" for line in st.text.split("\n")]

    def _stmt_Blank(self, st: pr.Blank, level: int) -> list[str]:
        return [""]

    # ------------------------------------------------------------------ expressions
    NOT, OR, COMPARE = ".not. ", " .or. ", {"!=": "/="}

    def index_value(self, e: pr.Index) -> str:
        return self.index(e, self.counts, 1)

    def literal(self, value: float) -> str:
        text = repr(value)
        if "e" in text:  # 1e-08: 1.0e-8
            mantissa, exponent = text.split("e")
            text = f"{mantissa if '.' in mantissa else mantissa + '.0'}e{int(exponent)}"
        return f"{text}_c_double"

    def call(self, func: str, args: list) -> str:
        if func == "epsilon":
            return "epsilon(1.0_c_double)"
        if func == "real":
            return f"real({args[0]}, c_double)"
        return f"{_FUNCTIONS.get(func, func)}({', '.join(args)})"

    def element(self, e: ir.Element) -> str:
        return f"{e.array}({', '.join(self.expr(i) for i in e.index)})"
