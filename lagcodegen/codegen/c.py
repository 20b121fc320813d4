"""C code generation: a :class:`~lagcodegen.formulation.scene.Scene` rendered through the jinja2 templates.

Expressions are reduced by common-subexpression elimination (symengine's ``cse``, which
matches sympy's) and printed by symengine's C printer (sympy's C99 printer gives the same
text but costs 90% of the generation time of a 20-link pendulum), with every floating-point
constant printed to 17 significant digits. The symbols of the model are renamed
to array elements before elimination: q_i -> y[i], q_i' -> y[n+i], run-time parameter k ->
p[k]; folded parameters become numbers (printed with 17 significant digits, exact doubles).
"""

from __future__ import annotations

import dataclasses
from itertools import accumulate

import symengine as se

from ..formulation.kernels import Block, cse, model_blocks, sparse_jacobian
from ..formulation.scene import Scene
from ..formulation.tangent import TangentProgram, build_program, tangent_program
from ..version import __version__
from . import ir
from .record import GeneratedCode, header_context, new_code
from .templates import environment

_INDENT = "    "


_ATOM, _UNARY, _MUL, _ADD, _REL = 4, 3, 2, 1, 0


def _print_double(value: float) -> str:
    """A double as symengine's C printer writes the numerators and denominators of rationals
    (15 significant digits; ".0" appended to an integral text)."""
    text = f"{value:.15g}"
    if "." not in text and "e" not in text:
        text += "." if len(text) == 15 else ".0"
    return text


class CPrinter(ir.Printer):
    """C99 text of :mod:`lagcodegen.codegen.ir` trees (one ``_print_<Node>`` per node kind).

    The text is the one symengine's C printer writes for the same expression: operands in the
    tree's order, parentheses where C's precedence needs them, and around rationals in products
    and negative literals; every floating-point constant by Python's repr (the shortest text
    that reads back the same double). ``layout``: array name -> function of a target's index
    tuple giving the C subscripts (default ``[i][j]...``).
    """

    #: The tree's function names that C's math library spells differently.
    FUNCTIONS = {"abs": "fabs", "max": "fmax", "min": "fmin", "gamma": "tgamma", "loggamma": "lgamma",
                 "ceiling": "ceil", "truncate": "trunc"}
    #: C99 keywords (no array or variable of the generated code may be named so).
    RESERVED = frozenset((
        "auto", "break", "case", "char", "const", "continue", "default", "do", "double", "else", "enum", "extern",
        "float", "for", "goto", "if", "inline", "int", "long", "register", "restrict", "return", "short", "signed",
        "sizeof", "static", "struct", "switch", "typedef", "union", "unsigned", "void", "volatile", "while",
        "_Bool", "_Complex", "_Imaginary"))

    def __init__(self, layout: dict | None = None):
        self.layout = layout or {}

    # -- precedence of a node's text
    def _prec(self, node) -> int:
        if isinstance(node, ir.BinOp):
            return _ADD if node.op in "+-" else _MUL
        if isinstance(node, ir.Ratio):
            return _ADD
        if isinstance(node, ir.Neg) or (isinstance(node, ir.Integer) and node.value < 0):
            return _UNARY
        if isinstance(node, ir.Compare):
            return _REL
        return _ATOM

    def _paren(self, node, below: int) -> str:
        text = self.doprint(node)
        return f"({text})" if self._prec(node) < below else text

    # -- leaves
    def _print_Number(self, node: ir.Number) -> str:
        text = repr(node.value)
        if not any(ch in text for ch in ".e"):
            text += ".0"
        return f"({text})" if node.value < 0 else text

    def _print_Integer(self, node: ir.Integer) -> str:
        return str(node.value)

    def _print_Ratio(self, node: ir.Ratio) -> str:
        return f"{_print_double(node.num)}/{_print_double(node.den)}"

    def _print_Name(self, node: ir.Name) -> str:
        return node.name

    def _print_Element(self, node: ir.Element) -> str:
        index = node.index if isinstance(node.index, tuple) else (node.index,)
        place = self.layout.get(node.array)
        if place is not None:
            return node.array + place(index)
        return node.array + "".join(f"[{k}]" for k in index)

    # -- operations
    def _print_Neg(self, node: ir.Neg) -> str:
        return "-" + self._paren(node.arg, _UNARY)

    def _print_BinOp(self, node: ir.BinOp) -> str:
        level = _ADD if node.op in "+-" else _MUL
        left = self._paren(node.left, level)
        if level == _ADD and isinstance(node.right, ir.Ratio):  # a quotient: no parentheses after + or -
            right = self.doprint(node.right)
        else:
            right = self._paren(node.right, level + 1)
        return f"{left} {node.op} {right}" if level == _ADD else f"{left}{node.op}{right}"

    def _print_Power(self, node: ir.Power) -> str:
        return f"pow({self.doprint(node.base)}, {self.doprint(node.exp)})"

    def _print_Call(self, node: ir.Call) -> str:
        return f"{self.FUNCTIONS.get(node.func, node.func)}({', '.join(self.doprint(a) for a in node.args)})"

    def _print_Compare(self, node: ir.Compare) -> str:
        return f"{self.doprint(node.left)} {node.op} {self.doprint(node.right)}"

    def _print_Logic(self, node: ir.Logic) -> str:
        word = " && " if node.op == "and" else " || "
        return "(" + word.join(f"({self.doprint(a)})" for a in node.args) + ")"

    def _print_Not(self, node: ir.Not) -> str:
        return f"!({self.doprint(node.arg)})"

    def _print_Select(self, node: ir.Select) -> str:
        text = "".join(f"(({self.doprint(c)}) ? (\n   {self.doprint(v)}\n)\n: " for c, v in node.cases)
        return text + f"(\n   {self.doprint(node.default)}\n" + ")" * (len(node.cases) + 1)

    def _print_Sign(self, node: ir.Sign) -> str:
        x = self.doprint(node.arg)
        return f"(({x} == 0.0) ? (0.0) : (({x} < 0.0) ? (-1.0) : (1.0)))"


def c_expr(expr, resolve=None) -> str:
    """C99 text of a symengine expression (:func:`lagcodegen.codegen.ir.expression` printed by
    :class:`CPrinter`): symengine's C text, with every constant exact."""
    return CPrinter().doprint(ir.expression(expr, resolve))


def c_statement(printer: CPrinter, st: ir.Assign, pad: str = _INDENT) -> str:
    """One C statement: ``const double x = e;`` (a local), ``t += e;`` (accumulate) or ``t1 = t2 = e;``."""
    value = printer.doprint(st.value)
    if st.local:
        return f"{pad}const double {printer.doprint(st.targets[0])} = {value};"
    if st.accumulate:
        return f"{pad}{printer.doprint(st.targets[0])} += {value};"
    return pad + " = ".join(printer.doprint(t) for t in st.targets) + f" = {value};"


def _layout(ng: int = 0) -> dict:
    """C storage of the kernel targets: ("G", i, j) by columns (G[j] is the column d r / d y_j,
    solved in place), ("jac", row, col) the column-major ng x ng matrix ``jac``."""
    return {"G": lambda idx: f"[{idx[1]}][{idx[0]}]", "jac": lambda idx: f"[{idx[1] * ng + idx[0]}]"}


def print_block(block: Block, ng: int = 0) -> str:
    """The C statements of a kernel :class:`Block` (after common-subexpression elimination)."""
    printer = CPrinter(_layout(ng))
    return "\n".join(c_statement(printer, st) for st in ir.block_statements(block, cse))


#: The program form's pieces: at most this many statements or characters per C function, so that
#: the compiler's time grows like the code's size (gcc's register allocation and dead-store
#: elimination grow much faster on one long function).
CHUNK_STATEMENTS = 120
CHUNK_CHARS = 8000

#: The right-hand side of a scene without the tangent Jacobian is printed in program form
#: (:func:`lagcodegen.formulation.tangent.build_program`, pieces of at most CHUNK_STATEMENTS)
#: from this many operations (symengine's count_ops) on; smaller ones as one function, as before.
PROGRAM_MIN_OPS = 6000


def _chunks(items: list, size=len) -> list[list]:
    """``items`` in pieces of at most CHUNK_STATEMENTS items or CHUNK_CHARS of ``size``."""
    out, cur, total = [], [], 0
    for item in items:
        n = size(item)
        if cur and (len(cur) >= CHUNK_STATEMENTS or total + n > CHUNK_CHARS):
            out.append(cur)
            cur, total = [], 0
        cur.append(item)
        total += n
    if cur:
        out.append(cur)
    return out


@dataclasses.dataclass
class CFunction:
    """A static C function of the program form: ``void name(params)`` whose body casts the
    unused-looking parameters to void and runs ``lines``."""

    name: str
    params: list  # (declaration, name)
    lines: list

    def head(self, storage: str = "static") -> str:
        return f"{storage} NOINLINE void {self.name}({', '.join(d for d, _ in self.params)})"

    def text(self, storage: str = "static") -> str:
        casts = " ".join(f"(void){n};" for _, n in self.params)
        return f"{self.head(storage)}\n{{\n{_INDENT}{casts}\n" + "\n".join(self.lines) + "\n}"


def _params(*decls: str) -> list:
    """C parameter declarations with their names: "double M[][N]" -> ("double M[][N]", "M")."""
    out = []
    for d in decls:
        name = d.split("[", 1)[0].replace("*", " ").split()[-1]
        out.append((d, name))
    return out


def _functions(name: str, params: list, pieces: list[list[str]]) -> list[CFunction]:
    """Functions ``name<k>(params)``, one per piece of statements."""
    return [CFunction(f"{name}{k}", params, chunk) for k, chunk in enumerate(pieces)]


def _value_pieces(prog, ranges: list[tuple[int, int]], outside: set) -> list[list[list[str]]]:
    """The statements computing the program's values, per range of ``ranges`` in pieces (lists of
    lines). A value read by one statement only (and not in ``outside``: the values the targets
    and the tangent code read) is written into that statement; a value read only within its
    piece is a local ``u<k>``; the others are stored in ``v``."""
    nv = len(prog)
    consumers: list[list[int]] = [[] for _ in range(nv)]
    for j in range(nv):
        for u in prog.exprs[j].free_symbols:
            k = prog.index(u)
            if k is not None:
                consumers[k].append(j)
    inline = [len(consumers[k]) == 1 and k not in outside for k in range(nv)]
    full: list = [None] * nv
    for k in range(nv):
        e = prog.exprs[k]
        sub = {u: full[i] for u in e.free_symbols if (i := prog.index(u)) is not None and inline[i]}
        full[k] = e.xreplace(sub) if sub else e
    printer = CPrinter()
    trees = {k: ir.expression(full[k]) for k in range(nv) if not inline[k]}
    # Pieces by the size of the statement's text with the values in v (as "k: text").
    sizes = {k: len(str(k)) + 1 + len(printer.doprint(trees[k])) for k in trees}
    piece: dict[int, int] = {}
    out, count = [], 0
    for start, stop in ranges:
        chunks = _chunks([k for k in range(start, stop) if not inline[k]], sizes.__getitem__)
        for chunk in chunks:
            for k in chunk:
                piece[k] = count
            count += 1
        out.append(chunks)

    def where(j):  # the statement that computes value j (j itself, or the one it is written into)
        while inline[j]:
            j = consumers[j][0]
        return j
    local = {k for k in piece if k not in outside and all(piece[where(j)] == piece[k] for j in consumers[k])}

    def ref(node):
        if isinstance(node, ir.Element) and node.array == "v" and node.index in local:
            return ir.Name(f"u{node.index}")
        return None
    result = []
    for chunks in out:
        pieces = []
        for chunk in chunks:
            lines = []
            for k in chunk:
                value = ir.substitute(trees[k], ref)
                target = ir.Name(f"u{k}") if k in local else ir.Element("v", k)
                lines.append(c_statement(printer, ir.Assign((target,), value, local=k in local)))
            pieces.append(lines)
        result.append(pieces)
    return result


def _rhs_target(target: tuple) -> tuple:
    kind, *idx = target
    if kind == "ydot":
        return (ir.Element("ydot", idx[0]),)
    return ir.target_nodes(target)


def _op_statement(op: tuple, value: ir.Node) -> ir.Assign:
    """The statement of a tangent operation (kind, k, e) with the tree ``value`` of e: the local
    tangent d<k> =, w[k] +=, g[k] +=, jz[k] =."""
    kind, k, _ = op
    if kind == "d":
        return ir.Assign((ir.Name(f"d{k}"),), value, local=True)
    if kind in ("w", "g"):
        return ir.Assign((ir.Element(kind, k),), value, accumulate=True)
    return ir.Assign((ir.Element("jz", k),), value)


def _column_lines(ops: list, printer: CPrinter) -> tuple[list[str], set, bool]:
    """The statements of a column's narrow operations; when they fill more than one piece, the
    local tangents d<k> live in the scratch array s (they cross the pieces). Also returns the
    values v[k] they read, and whether s is used."""
    trees = [ir.expression(op[2]) for op in ops]
    statements = [_op_statement(op, t) for op, t in zip(ops, trees)]
    reads = set().union(*(ir.elements(t, "v") for t in trees)) if trees else set()
    lines = [c_statement(printer, st) for st in statements]
    crossing = len(_chunks(lines)) > 1
    if crossing:
        slot = {f"d{k}": ir.Element("s", i) for i, k in enumerate(k for kind, k, _ in ops if kind == "d")}

        def scratch(node):
            return slot.get(node.name) if isinstance(node, ir.Name) else None
        lines = []
        for st in statements:
            target = st.targets[0]
            if st.local:
                target = slot[target.name]
            lines.append(c_statement(printer, ir.Assign((target,), ir.substitute(st.value, scratch),
                                                        accumulate=st.accumulate)))
    return lines, reads, crossing


def _w_index(symbol) -> int | None:
    node = ir.symbol_node(symbol.name)
    return node.index if isinstance(node, ir.Element) and node.array == "w" else None


def _wide_pieces(ops: list, acc: set, shared: set, nw: int, printer: CPrinter) -> tuple[list[list[str]], set]:
    """The wide operations of a block in pieces. The column code has added the narrow parts of
    the tangents in ``acc`` to w[i]; the tangent of wide value i is assigned to w[nw + i] (or to
    a local ``wl<i>`` if only its own piece reads it, and it is not ``shared`` with other blocks):
    tangent = w[i] (if in acc) + the wide terms. Also returns the values v[k] they read."""
    trees = [ir.expression(op[2]) for op in ops]
    sizes = [len(c_statement(printer, _op_statement(op, t))) for op, t in zip(ops, trees)]
    chunks = _chunks(list(range(len(ops))), sizes.__getitem__)
    piece = {j: c for c, chunk in enumerate(chunks) for j in chunk}
    define = {op[1]: j for j, op in enumerate(ops) if op[0] == "w"}
    readers: dict[int, set] = {}
    for j, op in enumerate(ops):
        for u in op[2].free_symbols:
            if (i := _w_index(u)) is not None:
                readers.setdefault(i, set()).add(piece[j])
    local = {i for i, j in define.items() if i not in shared and readers.get(i, set()) <= {piece[j]}}

    def value(i):
        return ir.Name(f"wl{i}") if i in local else ir.Element("w", nw + i)

    def ref(node):
        return value(node.index) if isinstance(node, ir.Element) and node.array == "w" else None
    out = []
    reads = set()
    for chunk in chunks:
        lines = []
        for j in chunk:
            kind, i, _ = ops[j]
            reads |= ir.elements(trees[j], "v")
            tree = ir.substitute(trees[j], ref)
            if kind == "w":
                if i in acc:
                    tree = ir.plus(ir.Element("w", i), tree)
                st = ir.Assign((value(i),), tree, local=i in local)
            else:
                st = _op_statement(ops[j], tree)
            lines.append(c_statement(printer, st))
        out.append(lines)
    return out, reads


#: Program-form sources whose pieces hold more than this many characters are cut into groups of
#: about GROUP_CHARS, each between ``#if`` lines, so that the build compiles the file as several
#: objects at once (``-DLCG_PARTS=K -DLCG_PART=k``: group g in object g % K, the rest of the file in
#: object 0; ``lagcodegen.build``). Without those macros the file is one translation unit as before.
SPLIT_MIN_CHARS = 100_000
GROUP_CHARS = 20_000


def _group_pieces(functions: list[CFunction]) -> tuple[str, str, int]:
    """The piece functions (static) as the source's text, in groups between ``#if`` lines
    when they exceed SPLIT_MIN_CHARS (then declared ``PIECE``: static in one translation unit,
    hidden across the objects of a split build): (text, prototypes of a split build, number of
    groups)."""
    defs = [f.text() for f in functions]
    total = sum(map(len, defs))
    if total <= SPLIT_MIN_CHARS:
        return "\n\n".join(defs), "", 1
    defs = [f.text("PIECE") for f in functions]
    groups: list[list[str]] = [[]]
    size = 0
    for d in defs:
        if groups[-1] and size + len(d) > GROUP_CHARS:
            groups.append([])
            size = 0
        groups[-1].append(d)
        size += len(d)
    text = "\n\n".join(f"#if !defined(LCG_PART) || {g} % LCG_PARTS == LCG_PART\n" + "\n\n".join(ds) + "\n#endif"
                        for g, ds in enumerate(groups))
    protos = "\n".join(f.head("PIECE") + ";" for f in functions)
    return text, protos, len(groups)


def _ranges(indices: list[int]) -> list[int]:
    """Sorted ``indices`` as [start, stop) pairs, flattened."""
    out: list[int] = []
    for i in sorted(set(indices)):
        if out and out[-1] == i:
            out[-1] = i + 1
        else:
            out += [i, i + 1]
    return out


_VALUE_PARAMS = _params("double t", "const double *y", "const double *p", "double *v")
_TANGENT_PARAMS = _params("double t", "const double *y", "const double *p", "const double *v", "const double *a",
                          "double *w", "double *g", "double *jz", "double *s")


def print_program(prog, targets: list, tangent: TangentProgram | None = None) -> dict:
    """The C pieces of the program form (templates/c/model.c.j2): the right-hand side's values
    ``v[k]`` computed by static functions of at most CHUNK_STATEMENTS statements each (shared by
    rhs and jac), and with ``tangent`` the Jacobian's: the values only its partial derivatives
    need, one function per column of dr/dy with its narrow statements, and the wide statements
    of each group (:mod:`lagcodegen.formulation.tangent`)."""
    pad = _INDENT
    printer = CPrinter()
    n_rhs = prog.n_rhs or len(prog)
    ctx = dict(nv=max(1, len(prog)), nw=1, ns=1, groups=[], jac_calls=[])
    outside = {prog.index(a) for _, a in targets} - {None}
    functions: list[CFunction] = []
    if tangent is not None:
        nscratch = 1
        pieces: list[str] = []
        ncol = 2 * tangent.n
        calls: list[list[int]] = [[] for _ in range(ncol)]
        resets: list[list[int]] = [[] for _ in range(ncol)]

        def add(more, columns):
            functions.extend(more)
            for f in more:
                for c in columns:
                    calls[c].append(len(pieces))
                pieces.append(f.name)
        for gi, g in enumerate(tangent.groups):
            for c, ops in g.columns.items():
                lines, reads, crossing = _column_lines(ops, printer)
                outside |= reads
                if crossing:
                    nscratch = max(nscratch, sum(op[0] == "d" for op in ops))
                add(_functions(f"column{c}_", _TANGENT_PARAMS, _chunks(lines)), [c])
            acc = {k for ops in g.columns.values() for kind, k, _ in ops if kind == "w"}
            owner: dict[int, int] = {}
            for bi, (_, lo, hi, _) in enumerate(g.blocks):
                owner.update((k, bi) for k in range(lo, hi))
            shared = set()
            for bi, (_, _, _, ops) in enumerate(g.blocks):  # read by another block: kept in w
                shared |= {i for op in ops for u in op[2].free_symbols
                           if (i := _w_index(u)) is not None and owner.get(i) != bi}
            for bi, (cols, lo, hi, ops) in enumerate(g.blocks):
                # Wide values with only narrow operands have no operation: their tangent is w[i].
                ops = [("w", i, se.Integer(0)) for i in range(lo, hi)
                       if i in acc and all(op[1] != i for op in ops if op[0] == "w")] + ops
                wide, reads = _wide_pieces(ops, acc, shared, g.nw, printer)
                outside |= reads
                add(_functions(f"wide{gi}_{bi}_", _TANGENT_PARAMS, wide), sorted(cols))
                for c in cols:
                    resets[c] += [g.nw + i for i in range(lo, hi) if i in shared]
            for c, ops in g.columns.items():
                resets[c] += sorted({k for kind, k, _ in ops if kind == "w"})
            ctx["nw"] = max(ctx["nw"], g.nw)
        ctx["pieces"] = _int_rows([]) if not pieces else ",\n".join(f"{pad}{f}" for f in pieces)
        ctx["call_start"] = _int_rows([0] + list(accumulate(len(c) for c in calls)))
        ctx["calls"] = _int_rows([k for c in calls for k in c] or [0])
        ranges = [_ranges(r) for r in resets]
        ctx["reset_start"] = _int_rows([0] + list(accumulate(len(r) for r in ranges)))
        ctx["resets"] = _int_rows([x for r in ranges for x in r] or [0])
        ctx["npieces"] = len(pieces)
        ctx["ns"] = nscratch
        rhs_pieces, extra_pieces = _value_pieces(prog, [(0, n_rhs), (n_rhs, len(prog))], outside)
    else:
        rhs_pieces, extra_pieces = _value_pieces(prog, [(0, n_rhs)], outside)[0], []
    values = _functions("values", _VALUE_PARAMS, rhs_pieces)
    partials = _functions("partials", _VALUE_PARAMS, extra_pieces)
    rhs_calls = [f.name for f in values]
    empty = f"{pad}v[0] = 0.0; /* no values: v is read initialized */"
    ctx["rhs_values"] = "\n".join(f"{pad}{f}(t, y, p, v);" for f in rhs_calls) or empty
    ctx["jac_values"] = "\n".join(f"{pad}{f}(t, y, p, v);" for f in rhs_calls + [f.name for f in partials]) or empty
    # M in pieces of its own too: hundreds of stores into the caller's M cost gcc seconds there.
    mass_lines = [c_statement(printer, ir.Assign(ir.target_nodes(t), ir.expression(a)))
                  for t, a in targets if t[0] == "M"]
    mass = _functions("mass", _params("const double *y", "const double *p", "const double *v", "double M[][N]"),
                      _chunks(mass_lines))
    ctx["mass"] = "\n".join(f"{pad}{f.name}(y, p, v, M);" for f in mass)
    ctx["rhs_targets"] = "\n".join([ctx["mass"]] + [c_statement(printer, ir.Assign(_rhs_target(t), ir.expression(a)))
                                                     for t, a in targets if t[0] != "M"])
    ctx["functions"] = values + partials + functions + mass
    return ctx


#: A block printed by print_block_pieces (the expanded Jacobian of a large model) with more operations
#: than this is hash-consed (lagcodegen.formulation.tangent.build_program) rather than eliminated.
BLOCK_CSE_MAX_OPS = 400_000


def print_block_pieces(block: Block, name: str, before: list, after: list, scratch: str,
                       error: str) -> tuple[list, str]:
    """A kernel :class:`Block` as static functions ``name<k>(before, double *<scratch>, after)`` of at
    most CHUNK_STATEMENTS statements (after common-subexpression elimination, the temporaries in
    the array ``scratch``): returns (the functions; the statements of the caller: allocation,
    calls ``name<k>(...)``, free; ``return error`` when the allocation fails)."""
    printer = CPrinter(_layout())
    if se.count_ops(*block.exprs) > BLOCK_CSE_MAX_OPS:  # symengine's elimination takes minutes: hash-consing
        prog, targets = build_program(block, 0, cse=False)
        nv = len(prog)
        array = "v"
        pieces = _value_pieces(prog, [(0, nv)], {prog.index(a) for _, a in targets} - {None})[0]
        pieces += _chunks([c_statement(printer, ir.Assign(ir.target_nodes(t), ir.expression(a))) for t, a in targets])
        size = max(nv, 1)
    else:
        array = scratch
        repl, reduced = cse(block.exprs)

        def temp(node):
            return ir.Element(scratch, int(node.name[1:])) if isinstance(node, ir.Name) else None
        lines = [c_statement(printer, ir.Assign((temp(ir.Name(str(sym))),), ir.substitute(ir.expression(e), temp)))
                 for sym, e in repl]
        lines += [c_statement(printer, ir.Assign(ir.target_nodes(t), ir.substitute(ir.expression(e), temp)))
                  for t, e in zip(block.targets, reduced)]
        pieces = _chunks(lines)
        size = max([int(str(sym)[1:]) + 1 for sym, _ in repl] or [1])
    params = _params(*before, f"double *{array}", *after)
    functions = _functions(name, params, pieces)
    args = ", ".join(n for _, n in params)
    calls = [f"{_INDENT}double *{array} = (double *)malloc({size} * sizeof(double));",
             f"{_INDENT}if ({array} == NULL)", f"{_INDENT * 2}return {error};"]
    calls += [f"{_INDENT}{f.name}({args});" for f in functions] + [f"{_INDENT}free({array});"]
    return functions, "\n".join(calls)


def use_program(scene: Scene, rhs: Block) -> bool:
    """True if the right-hand side is printed in program form: with the tangent Jacobian (they
    share its values), or from PROGRAM_MIN_OPS operations on."""
    if scene.jacobian and scene.resolved_jacobian_form() == "tangent":
        return True
    return bool(rhs.exprs) and se.count_ops(*rhs.exprs) >= PROGRAM_MIN_OPS


def generate_c(scene: Scene) -> GeneratedCode:
    """Render the C header and source of ``scene`` (functions: rhs, jac if asked, outputs if any)."""
    tangent = scene.jacobian and scene.resolved_jacobian_form() == "tangent"
    blocks = model_blocks(dataclasses.replace(scene, jacobian=False) if tangent else scene)
    code = new_code(scene)
    ctx = header_context(scene, code)
    env = environment()
    extra = dict(program=None)
    if use_program(scene, blocks["rhs"]):
        n = scene.eom.model.n
        built = build_program(blocks["rhs"], n)
        tp = tangent_program(blocks["rhs"], n, len(scene.eom.quadratures), program=built) if tangent else None
        extra = dict(program=print_program(built[0], built[1], tp))
    jac = print_block(blocks["jac"]) if "jac" in blocks and not extra["program"] else ""
    if "jac" in blocks and extra["program"]:  # a large expanded Jacobian: in pieces too
        nz = len(scene.eom.quadratures)
        params = ["double t", "const double *y", "const double *p", "const double *a", "double M[][N]",
                  "double G[][N]"] + (["double Z[][2 * N]"] if nz else [])
        defs, jac = print_block_pieces(blocks["jac"], "jacobian", params[:4], params[4:], "x",
                                       f"{code.prefix.upper()}_ERR_MEMORY")
        extra["program"]["functions"] += defs
    if extra["program"]:
        program = extra["program"]
        program["functions"], program["prototypes"], program["groups"] = _group_pieces(program["functions"])
        if program["groups"] > 1:
            code.split[code.source_name] = program["groups"]
    code.files[code.header_name] = env.get_template("c/model.h.j2").render(**ctx, program=extra["program"])
    code.files[code.source_name] = env.get_template("c/model.c.j2").render(
        **ctx, rhs=None if extra["program"] else print_block(blocks["rhs"]),
        jac=jac, out=print_block(blocks["out"]), tangent=tangent, **extra)
    code.jac_pattern = scene.jacobian_pattern()
    if scene.sparse_jacobian:
        _add_sparse_jacobian(scene, code, env)
    return code


def _int_rows(values: list[int], per_line: int = 16) -> str:
    rows = [", ".join(str(v) for v in values[k:k + per_line]) for k in range(0, len(values), per_line)]
    return ",\n".join(_INDENT + r for r in rows)


def _add_sparse_jacobian(scene: Scene, code: GeneratedCode, env) -> None:
    """Files <prefix>_sparse.h/.c: <prefix>_jac_sparse, the structurally nonzero entries of df/dy
    in compressed-column order (:func:`lagcodegen.formulation.kernels.sparse_jacobian`)."""
    sj = sparse_jacobian(scene, code.jac_pattern)
    after = [f"{_INDENT}vals[{k}] = -G[{j}][{i}];" for k, j, i in sj.copies]
    ctx = dict(prefix=code.prefix, PREFIX=code.prefix.upper(), version=__version__, model_name=code.model_name,
               nnz=len(sj.entries), colptr=_int_rows(sj.colptr), rowind=_int_rows([i for i, _ in sj.entries]),
               diagonal=sj.diagonal, block=print_block(sj.block), after="\n".join(after),
               solve_cols=_int_rows(sj.solve_cols), nsolve=len(sj.solve_cols))
    code.files[f"{code.prefix}_sparse.h"] = env.get_template("c/jac_sparse.h.j2").render(**ctx)
    code.files[f"{code.prefix}_sparse.c"] = env.get_template("c/jac_sparse.c.j2").render(**ctx)
    code.cffi_headers.append(f"{code.prefix}_sparse.h")
    code.sparse_jacobian = True


def generate(scene: Scene) -> GeneratedCode:
    """The language interface of :mod:`lagcodegen.codegen`: :func:`generate_c`."""
    return generate_c(scene)


def check_prefix(prefix: str, suffix: str = "") -> None:
    """Every C identifier prefix is usable in C (Fortran limits the length)."""


def constrained_source(cb, ctx: dict) -> dict[str, str]:
    """``<prefix>_dae.c``: the constrained kernels (:func:`lagcodegen.formulation.constrained.constrained_blocks`)."""
    b = cb.blocks
    text = environment().get_template("c/dae.c.j2").render(
        **ctx, mf=print_block(b["mf"]), con=print_block(b["con"]), gam=print_block(b["gam"]),
        out=print_block(b["out"]), root_block=print_block(b["roots"]), ggl_res=print_block(b["ggl_res"]),
        ggl_jac_block=print_block(b["ggl_jac"], cb.ng))
    return {f"{ctx['prefix']}_dae.c": text}
