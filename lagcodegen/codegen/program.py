"""The program form laid out as functions of operation-tree statements, for every backend.

A large right-hand side is printed as a straight-line program (:func:`lagcodegen.formulation.tangent.build_program`)
and, with the tangent Jacobian, its forward-mode derivative (:func:`lagcodegen.formulation.tangent.tangent_program`).
Here those programs become :class:`Piece` s of :class:`lagcodegen.codegen.ir.Assign` statements
(functions of their own, at most ``chunk`` statements or characters each, so that a compiler's
time grows like the code's size), and the tables that say which pieces each column of the
Jacobian runs and which accumulators it zeroes: :class:`ProgramForm`. The decisions (which
values are written into their single reader, which live in a piece's locals, which cross pieces
in the arrays ``v``, ``w``, ``s``) are the same for every language; a backend prints the
statements and the tables (:func:`lagcodegen.codegen.c.print_program`,
:func:`lagcodegen.codegen.fortran.generate_fortran`). Sizes are measured by the backend's own
text (``measure``), so that pieces stay as large as the backend's compiler handles well.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import symengine as se

from ..formulation.kernels import count_ops
from . import ir, lowering

#: The program form's pieces: at most this many statements or characters per function, so that
#: the compiler's time grows like the code's size (gcc's register allocation and dead-store
#: elimination grow much faster on one long function).
CHUNK_STATEMENTS = 120
CHUNK_CHARS = 8000

#: The right-hand side of a scene without the tangent Jacobian is printed in program form
#: (:func:`lagcodegen.formulation.tangent.build_program`, pieces of at most CHUNK_STATEMENTS)
#: from this many operations (symengine's count_ops) on; smaller ones as one function.
PROGRAM_MIN_OPS = 6000

#: A block in pieces (:func:`block_pieces`: the expanded Jacobian of a large model) with more
#: operations than this is hash-consed (:func:`lagcodegen.formulation.tangent.build_program`)
#: rather than eliminated.
BLOCK_CSE_MAX_OPS = 400_000


def tangent_jacobian(scene) -> bool:
    """True if the scene's Jacobian is printed in tangent form (:mod:`lagcodegen.formulation.tangent`)."""
    return bool(scene.jacobian) and scene.resolved_jacobian_form() == "tangent"


def use_program(scene, rhs, min_ops: int | None = None) -> bool:
    """True if the right-hand side ``rhs`` is printed in program form: with the tangent Jacobian
    (they share its values), or from ``min_ops`` (default :data:`PROGRAM_MIN_OPS`) operations on."""
    if tangent_jacobian(scene) or rhs.defs:  # a block with temporaries is a program already (a rigid-body tree)
        return True
    return bool(rhs.exprs) and count_ops(rhs.exprs) >= (PROGRAM_MIN_OPS if min_ops is None else min_ops)


@dataclass
class Measure:
    """The sizes the pieces are cut by: ``statement(st)`` the length of a statement's text,
    ``value(k, tree)`` that of the statement computing value k; at most ``statements``
    statements or ``chars`` characters per piece."""

    statement: Callable
    value: Callable
    statements: int
    chars: int

    def chunks(self, items: list, size) -> list[list]:
        """``items`` in pieces of at most ``statements`` items or ``chars`` of ``size``."""
        out, cur, total = [], [], 0
        for item in items:
            n = size(item)
            if cur and (len(cur) >= self.statements or total + n > self.chars):
                out.append(cur)
                cur, total = [], 0
            cur.append(item)
            total += n
        if cur:
            out.append(cur)
        return out


@dataclass
class Piece:
    """A function ``name`` running ``statements`` (kind: "values", "tangent", "mass" or "block":
    its parameters are the backend's for that kind)."""

    name: str
    kind: str
    statements: list


@dataclass
class ProgramForm:
    """The program form of a right-hand side (and its tangent Jacobian).

    ``values``/``partials``: the pieces computing the right-hand side's values and the extra
    values of the partial derivatives; ``tangent``: the pieces of the Jacobian's columns and
    wide statements; ``mass``: the pieces storing M; ``targets``: the statements of F and the
    quadrature rates; ``calls[j]``: the indices into ``tangent`` that column j runs, in order,
    ``resets[j]``: the accumulator ranges [start, stop) it zeroes after them (flattened);
    sizes ``nv`` (values), ``nw`` (accumulators per half of w), ``ns`` (scratch)."""

    values: list
    partials: list
    mass: list
    targets: list
    nv: int
    tangent: list = field(default_factory=list)
    calls: list = field(default_factory=list)
    resets: list = field(default_factory=list)
    nw: int = 1
    ns: int = 1

    @property
    def pieces(self) -> list:
        """Every piece function, in the order they are defined."""
        return self.values + self.partials + self.tangent + self.mass


def _value_pieces(prog, ranges: list[tuple[int, int]], outside: set, measure: Measure) -> list[list[list]]:
    """The statements computing the program's values, per range of ``ranges`` in pieces. A value
    read by one statement only (and not in ``outside``: the values the targets and the tangent
    code read) is written into that statement; a value read only within its piece is a local
    ``u<k>``; the others are stored in ``v``."""
    nv = len(prog)
    consumers: list[list[int]] = [[] for _ in range(nv)]
    for j in range(nv):
        for u in prog.exprs[j].free_symbols:
            k = prog.index(u)
            if k is not None:
                consumers[k].append(j)
    inline = [len(consumers[k]) == 1 and k not in outside for k in range(nv)]
    if getattr(prog, "recorded", False):
        trees = _recorded_trees(prog, inline)
    else:
        full: list = [None] * nv
        for k in range(nv):
            e = prog.exprs[k]
            sub = {u: full[i] for u in e.free_symbols if (i := prog.index(u)) is not None and inline[i]}
            full[k] = e.xreplace(sub) if sub else e
        trees = {k: lowering.expression(full[k]) for k in range(nv) if not inline[k]}
    piece: dict[int, int] = {}
    out, count = [], 0
    for start, stop in ranges:
        chunks = measure.chunks([k for k in range(start, stop) if not inline[k]], lambda k: measure.value(k, trees[k]))
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
            pieces.append([ir.Assign((ir.Name(f"u{k}") if k in local else ir.Element("v", k),),
                                     ir.substitute(trees[k], ref), local=k in local) for k in chunk])
        result.append(pieces)
    return result


def _recorded_trees(prog, inline: list) -> dict:
    """The operation trees of a recorded program's values (``Program.recorded``,
    :class:`lagcodegen.formulation.tangent.Program`) that are not written into their reader:
    each value's statement lowered once (:func:`lagcodegen.codegen.lowering.statement`), a value
    read once (``inline``) written into its reader as its tree (no symengine expression is built
    for the combination, and its operations stay grouped as the program computed them)."""
    done: dict = {}

    def resolve(name: str):
        if name.startswith("v["):
            return done.get(int(name[2:-1]))
        return None
    trees = {}
    for k, e in enumerate(prog.exprs):
        tree = lowering.statement(e, resolve)
        if inline[k]:
            done[k] = tree
        else:
            trees[k] = tree
    return trees


def op_statement(op: tuple, value: ir.Node) -> ir.Assign:
    """The statement of a tangent operation (kind, k, e) with the tree ``value`` of e: the local
    tangent d<k> =, w[k] +=, g[k] +=, jz[k] =."""
    kind, k, _ = op
    if kind == "d":
        return ir.Assign((ir.Name(f"d{k}"),), value, local=True)
    if kind in ("w", "g"):
        return ir.Assign((ir.Element(kind, k),), value, accumulate=True)
    return ir.Assign((ir.Element("jz", k),), value)


def _column(ops: list, measure: Measure) -> tuple[list[list], set, int]:
    """The pieces of a column's narrow operations; when they fill more than one piece, the local
    tangents d<k> live in the scratch array s (they cross the pieces). Also returns the values
    v[k] they read and the scratch size (0 without)."""
    trees = [lowering.expression(op[2]) for op in ops]
    statements = [op_statement(op, t) for op, t in zip(ops, trees)]
    reads = set().union(*(ir.elements(t, "v") for t in trees)) if trees else set()
    if len(measure.chunks(statements, measure.statement)) == 1:
        return [statements], reads, 0
    slot = {f"d{k}": ir.Element("s", i) for i, k in enumerate(k for kind, k, _ in ops if kind == "d")}

    def scratch(node):
        return slot.get(node.name) if isinstance(node, ir.Name) else None
    moved = [ir.Assign((slot[st.targets[0].name] if st.local else st.targets[0],), ir.substitute(st.value, scratch),
                       accumulate=st.accumulate) for st in statements]
    return measure.chunks(moved, measure.statement), reads, len(slot)


def _w_index(symbol) -> int | None:
    node = ir.symbol_node(symbol.name)
    return node.index if isinstance(node, ir.Element) and node.array == "w" else None


def _wide(ops: list, acc: set, shared: set, nw: int, measure: Measure) -> tuple[list[list], set]:
    """The wide operations of a block in pieces. The column code has added the narrow parts of
    the tangents in ``acc`` to w[i]; the tangent of wide value i is assigned to w[nw + i] (or to
    a local ``wl<i>`` if only its own piece reads it, and it is not ``shared`` with other blocks):
    tangent = w[i] (if in acc) + the wide terms. Also returns the values v[k] they read."""
    trees = [lowering.expression(op[2]) for op in ops]
    sizes = [measure.statement(op_statement(op, t)) for op, t in zip(ops, trees)]
    chunks = measure.chunks(list(range(len(ops))), sizes.__getitem__)
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
        statements = []
        for j in chunk:
            kind, i, _ = ops[j]
            reads |= ir.elements(trees[j], "v")
            tree = ir.substitute(trees[j], ref)
            if kind == "w":
                if i in acc:
                    tree = lowering.plus(ir.Element("w", i), tree)
                statements.append(ir.Assign((value(i),), tree, local=i in local))
            else:
                statements.append(op_statement(ops[j], tree))
        out.append(statements)
    return out, reads


def _ranges(indices: list[int]) -> list[int]:
    """Sorted ``indices`` as [start, stop) pairs, flattened."""
    out: list[int] = []
    for i in sorted(set(indices)):
        if out and out[-1] == i:
            out[-1] = i + 1
        else:
            out += [i, i + 1]
    return out


def rhs_target(target: tuple) -> tuple:
    """The nodes a right-hand side target is stored in (the quadrature rates in ydot)."""
    kind, *idx = target
    if kind == "ydot":
        return (ir.Element("ydot", idx[0]),)
    return ir.target_nodes(target)


def _named(name: str, kind: str, pieces: list) -> list[Piece]:
    return [Piece(f"{name}{k}", kind, statements) for k, statements in enumerate(pieces)]


def program_form(prog, targets: list, tangent, measure: Measure) -> ProgramForm:
    """The :class:`ProgramForm` of the program ``prog`` (:class:`lagcodegen.formulation.tangent.Program`)
    with its targets (target, atom), and with ``tangent`` (a :class:`~lagcodegen.formulation.tangent.TangentProgram`)
    the Jacobian's: the values only its partial derivatives need, one piece per column of dr/dy
    with its narrow statements, and the wide statements of each group."""
    n_rhs = prog.n_rhs or len(prog)
    outside = {prog.index(a) for _, a in targets} - {None}
    form = ProgramForm([], [], [], [], max(1, len(prog)))
    if tangent is not None:
        ncol = tangent.ncol
        calls: list[list[int]] = [[] for _ in range(ncol)]
        resets: list[list[int]] = [[] for _ in range(ncol)]

        def add(more, columns):
            for p in more:
                for c in columns:
                    calls[c].append(len(form.tangent))
                form.tangent.append(p)
        for gi, g in enumerate(tangent.groups):
            for c, ops in g.columns.items():
                pieces, reads, nscratch = _column(ops, measure)
                outside |= reads
                form.ns = max(form.ns, nscratch)
                add(_named(f"column{c}_", "tangent", pieces), [c])
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
                pieces, reads = _wide(ops, acc, shared, g.nw, measure)
                outside |= reads
                add(_named(f"wide{gi}_{bi}_", "tangent", pieces), sorted(cols))
                for c in cols:
                    resets[c] += [g.nw + i for i in range(lo, hi) if i in shared]
            for c, ops in g.columns.items():
                resets[c] += sorted({k for kind, k, _ in ops if kind == "w"})
            form.nw = max(form.nw, g.nw)
        form.calls = calls
        form.resets = [_ranges(r) for r in resets]
        rhs_pieces, extra = _value_pieces(prog, [(0, n_rhs), (n_rhs, len(prog))], outside, measure)
    else:
        rhs_pieces, extra = _value_pieces(prog, [(0, n_rhs)], outside, measure)[0], []
    form.values = _named("values", "values", rhs_pieces)
    form.partials = _named("partials", "values", extra)
    # M in pieces of its own too: hundreds of stores into the caller's M cost gcc seconds there.
    mass = [ir.Assign(ir.target_nodes(t), lowering.expression(a)) for t, a in targets if t[0] in ("M", "Mx")]
    form.mass = _named("mass", "mass", measure.chunks(mass, measure.statement))
    form.targets = [ir.Assign(rhs_target(t), lowering.expression(a)) for t, a in targets if t[0] not in ("M", "Mx")]
    return form


def block_pieces(block, scratch: str, measure: Measure, eliminate,
                 cse_max_ops: int | None = None) -> tuple[list, str, int]:
    """A kernel block as pieces of statements (after common-subexpression elimination, the
    temporaries in the array ``scratch``; above ``cse_max_ops`` operations hash-consed into a
    program whose values are in the array ``v`` instead; default :data:`BLOCK_CSE_MAX_OPS`):
    (pieces, the array, its size)."""
    from ..formulation.tangent import build_program
    # A program already (temporaries, a rigid-body tree's), or symengine's elimination would take minutes:
    # hash-consing.
    if block.defs or count_ops(block.exprs) > (BLOCK_CSE_MAX_OPS if cse_max_ops is None else cse_max_ops):
        prog, targets = build_program(block, 0, cse=False)
        pieces = _value_pieces(prog, [(0, len(prog))], {prog.index(a) for _, a in targets} - {None}, measure)[0]
        pieces += measure.chunks([ir.Assign(ir.target_nodes(t), lowering.expression(a)) for t, a in targets],
                                 measure.statement)
        return pieces, "v", max(len(prog), 1)
    repl, reduced = eliminate(block.exprs)

    def temp(node):
        return ir.Element(scratch, int(node.name[1:])) if isinstance(node, ir.Name) else None
    statements = [ir.Assign((temp(ir.Name(str(sym))),), ir.substitute(lowering.expression(e), temp)) for sym, e in repl]
    statements += [ir.Assign(ir.target_nodes(t), ir.substitute(lowering.expression(e), temp))
                   for t, e in zip(block.targets, reduced)]
    size = max([int(str(sym)[1:]) + 1 for sym, _ in repl] or [1])
    return measure.chunks(statements, measure.statement), scratch, size
