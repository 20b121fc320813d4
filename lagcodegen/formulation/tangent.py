"""Straight-line programs of the right-hand side, and the Jacobian in tangent form.

The expanded Jacobian (:func:`lagcodegen.formulation.kernels.model_blocks`, key ``jac``)
differentiates r = M a - F symbolically: n x 2n expressions, each as long as a row of M and F,
so that its code grows like n^3 for a dense system, and gcc's time and memory grow faster still
on the one huge function it makes. Here the right-hand side kernel (M's upper triangle, F, the
quadrature rates) is first turned into a straight-line :class:`Program` of small statements,

    v[k] = f_k(operands),    operands: earlier values v[i], the state y[i], p[k], t, numbers,

by hash-consing (every distinct subexpression once; sums with their numeric coefficients,
products of two factors, one function or power each: :meth:`Program.atom`), optionally after
symengine's common-subexpression elimination (which finds shared partial sums, at a cost that
grows fast with the size). Every partial derivative d f_k / d u of a statement by an operand u is
then a number times one value (``cos(y[0])`` is the value computed for the right-hand side, the
product of the other factor, ...): the derivative values that the right-hand side does not
compute are appended to the program (:attr:`Program.n_rhs` separates them).

The Jacobian is forward-mode differentiation of that program along each column j of dr/dy
(seed dy = e_j), grouped by positions and velocities (M(q, t) has no velocity in it: the
velocity columns skip every statement of M). In a group, a statement is *narrow* if it depends
on at most ``narrow`` of the group's columns, *wide* otherwise:

* column c runs only the narrow statements that depend on c (their tangents, with the seed
  folded in), and adds their contributions to the wide statements that read them (scatter into
  the accumulators ``w``) and to the result g = dr/dy_c (dM a - dF: the entries of M add
  dM_ik a_k to g_i, those of F subtract);
* then the wide statements run in every column, in one piece of code shared by the columns:
  dv = (accumulated narrow part) + sum of (partial) x (tangent of a wide operand).

The code therefore holds each narrow statement once per column it depends on (at most
``narrow`` times) and each wide one once: its size grows like the right-hand side's, n^2 for a
chain; its run time is the sparse cost (like the expanded form) for the narrow part and a dense
forward sweep for the wide part. Column j of the Jacobian is then -M^-1 g for the accelerations
and dz'/dy_j for the quadrature rates. Everything here is language-neutral (symengine expressions
in the array symbols ``y[i]``, ``p[k]``, ``t``, ``v[k]``, ``a[i]``, ``w[i]`` and the local
tangents ``d<k>``); :mod:`lagcodegen.codegen.program` lays it out as pieces for every backend.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import symengine as se

from ..errors import ModelError
from .kernels import Block, count_ops, cse as eliminate

#: Choices of Scene.jacobian_form: "expanded" (kernels.model_blocks: symbolic dr/dy),
#: "tangent" (this module).
JACOBIAN_FORMS = ("expanded", "tangent")

#: Statements depending on at most this many columns of a group are "narrow": computed only in
#: those columns (one specialized copy each), not in every column.
NARROW = 2

#: Programs built from at most this many operations (symengine's count_ops) start from
#: symengine's common-subexpression elimination (shared partial sums: a smaller program); larger
#: ones from hash-consing alone (its time grows like the size; the elimination's much faster).
#: Measured on n-link chains' right-hand sides (elimination vs hash-consing: seconds, C bytes of
#: the pieces): 32 000 operations (40 links) 0.5 vs 0.3 s, 101 vs 122 kB; 72 000 (60 links) 2.0
#: vs 0.8 s, 217 vs 268 kB; 111 000 (75 links) 3.6 vs 1.0 s, 332 vs 416 kB; 197 000 (100 links)
#: 9 vs 3 s. Above some 60 000 operations the elimination costs more than the compiler saves
#: on the smaller code (about 1 s of gcc per 100 kB).
CSE_MAX_OPS = 60_000


def _is_atom(e) -> bool:
    return not e.args


class Program:
    """A straight-line program: values ``v[k] = exprs[k]`` (each over atoms: numbers, the
    symbols ``y[i]``, ``p[k]``, ``t`` and earlier ``v[i]``), built by :meth:`atom`.

    ``deps[k]``: the columns (indices i < 2n of y) that value k depends on; the other symbols
    (parameters, t, the quadrature states) are constants of the differentiation."""

    def __init__(self, n: int, nparams: int = 0, nv: int | None = None):
        self.n = n
        #: The velocity columns: y[n] .. y[n + nv - 1] (nv = n unless the model has generalized speeds).
        self.nv = n if nv is None else nv
        self.exprs: list = []
        self.deps: list[frozenset] = []
        self.symbols: list = []
        self._memo: dict = {}    # statement (over atoms) -> its value symbol
        self._seen: dict = {}    # any expression flattened before -> its atom
        self._index: dict = {}   # value symbol -> k
        ncol = n + self.nv
        self._state = {se.Symbol(f"y[{i}]"): i for i in range(ncol)}
        # With ``nparams``, the run-time parameters p[m] are differentiation columns too (2n + m):
        # the per-direction tangent of the sensitivities (lagcodegen.formulation.sensitivity).
        self._state.update({se.Symbol(f"p[{m}]"): ncol + m for m in range(nparams)})
        self.n_rhs = 0
        self.partials: list = []
        #: Built from a recorded program (a rigid-body tree's, :attr:`Block.defs`): its values are
        #: small statements meant to be evaluated one by one (the backends lower each value once
        #: and write a value read once into its reader as an operation tree, never re-expanded).
        self.recorded = False

    def __len__(self) -> int:
        return len(self.exprs)

    def deps_of(self, atom) -> frozenset:
        """The columns an atom (number, symbol, value) depends on."""
        if atom in self._index:
            return self.deps[self._index[atom]]
        if atom in self._state:
            return frozenset((self._state[atom],))
        return frozenset()

    def index(self, atom):
        """k if ``atom`` is the value v[k], else None."""
        return self._index.get(atom)

    def _value(self, expr):
        """The value computing ``expr`` (a statement over atoms), created if new."""
        if _is_atom(expr):
            return expr
        sym = self._memo.get(expr)
        if sym is None:
            k = len(self.exprs)
            sym = se.Symbol(f"v[{k}]")
            deps = frozenset()
            for u in expr.free_symbols:
                d = self.deps_of(u)
                if d:
                    deps = deps | d
            self.exprs.append(expr)
            self.deps.append(deps)
            self.symbols.append(sym)
            self._memo[expr] = sym
            self._index[sym] = k
        return sym

    def _key(self, atom):
        """Order of the factors of a product: constants first, then by creation."""
        if atom.is_Number:
            return (0, 0, "")
        deps = self.deps_of(atom)
        k = self._index.get(atom)
        return (1 if not deps else 2, -1 if k is None else k, str(atom))

    def atom(self, e, known: dict | None = None):
        """An atom (number, symbol or value) equal to the expression ``e``, adding the values
        it needs. ``known`` maps symbols standing for earlier expressions (a common-subexpression
        elimination's) to their atoms."""
        if _is_atom(e):
            if known and e in known:
                return known[e]
            return e
        hit = self._seen.get(e)
        if hit is not None:
            return hit
        if isinstance(e, se.Add):
            const, terms = se.Integer(0), []
            for arg in e.args:
                coef, rest = se.Integer(1), arg
                if isinstance(arg, se.Mul) and arg.args[0].is_Number:
                    coef, rest = arg.args[0], se.Mul(*arg.args[1:])
                a = self.atom(rest, known)
                if a.is_Number:
                    const += coef * a
                else:
                    terms.append(coef * a)
            out = self._value(se.Add(const, *terms))
        elif isinstance(e, se.Mul):
            coef, factors = se.Integer(1), []
            for arg in e.args:
                a = self.atom(arg, known)
                if a.is_Number:
                    coef *= a
                else:
                    factors.append(a)
            factors.sort(key=self._key)
            consts = [f for f in factors if not self.deps_of(f)]
            rest = [f for f in factors if self.deps_of(f)]
            if len(consts) > 1:
                rest.insert(0, self._value(se.Mul(*consts)))
            elif consts:
                rest.insert(0, consts[0])
            prod = rest[0] if rest else se.Integer(1)
            for f in rest[1:-1]:
                prod = self._value(prod * f)
            if len(rest) > 1:
                prod = self._value(coef * prod * rest[-1])
            elif coef != 1 or not rest:
                prod = self._value(coef * prod)
            out = prod
        elif isinstance(e, se.Pow):
            base, exp = (self.atom(a, known) for a in e.args)
            out = self._value(se.Pow(base, exp))
        else:
            args = [self.atom(a, known) for a in e.args]
            out = self._value(type(e)(*args))
        self._seen[e] = out
        return out

    def partial(self, k: int, u):
        """d v[k] / d u as (number, atom or None): a number times one value (appended to the
        program if new)."""
        d = se.diff(self.exprs[k], u)
        if d.atoms(se.Derivative, se.Subs):
            raise ModelError(f"tangent Jacobian: cannot differentiate {self.exprs[k]} (use jacobian_form='expanded')")
        if d.is_Number:
            return d, None
        coef, rest = se.Integer(1), d
        if isinstance(d, se.Mul) and d.args[0].is_Number:
            coef, rest = d.args[0], se.Mul(*d.args[1:])
        return coef, self.atom(rest)

    def finish_rhs(self) -> None:
        """Mark the values so far as the right-hand side's and compute every statement's partial
        derivatives by its operands (``partials[k]``: list of (operand, coefficient, atom))."""
        self.n_rhs = len(self.exprs)
        k = 0
        while k < len(self.exprs):  # partial values appended here have partials too (unused)
            if k < self.n_rhs:
                ops = sorted((u for u in self.exprs[k].free_symbols if self.deps_of(u)), key=self._key)
                self.partials.append([(u, *self.partial(k, u)) for u in ops])
            else:
                self.partials.append([])
            k += 1


def build_program(rhs: Block, n: int, cse: bool | None = None, nparams: int = 0,
                  nv: int | None = None) -> tuple[Program, list]:
    """The :class:`Program` of the right-hand side kernel ``rhs`` and its targets as (target,
    atom). ``cse``: start from symengine's common-subexpression elimination (None: when the
    block has at most :data:`CSE_MAX_OPS` operations). ``nparams``: the run-time parameters
    p[0] .. p[nparams-1] count as columns of the dependencies (``Program.deps``) too. ``nv``:
    the number of speeds of a model with generalized speeds (state columns y[0] .. y[n + nv - 1])."""
    prog = Program(n, nparams, nv)
    exprs = list(rhs.exprs)
    known: dict = {}
    for sym, e in rhs.defs:  # a program already (a rigid-body tree's): no elimination
        known[sym] = prog.atom(e, known)
        cse = False
        prog.recorded = True
    if cse is None:
        cse = count_ops(exprs) <= CSE_MAX_OPS if exprs else False
    if cse and exprs:
        repl, exprs = eliminate(exprs)
        for sym, e in repl:
            known[sym] = prog.atom(e, known)
    targets = [(t, prog.atom(e, known)) for t, e in zip(rhs.targets, exprs)]
    return prog, targets


@dataclass
class TangentGroup:
    """The tangent code of the columns ``start <= j < stop`` of dr/dy.

    ``columns[c]``: the operations of column c alone (its narrow statements); ``blocks``: the wide
    statements as (columns, lo, hi, operations), one block per set of columns they depend on,
    run in column c if c is in that set, after the column's own operations, in the order of the
    list; the block's accumulators are ``w[lo:hi]``. Operations are (kind, index, expr):
    ("d", k, e) the local tangent ``d<k>`` = e of value k; ("w", i, e) ``w[i] += e``;
    ("g", i, e) ``g[i] += e`` (g = dM a - dF); ("z", k, e) d z'_k / d y_j = e.
    """

    start: int
    stop: int
    columns: dict = field(default_factory=dict)
    blocks: list = field(default_factory=list)
    nw: int = 0

    @property
    def wide(self) -> list:
        """Every wide operation, in order."""
        return [op for _, _, _, ops in self.blocks for op in ops]


@dataclass
class TangentProgram:
    """The right-hand side as a :class:`Program` and its Jacobian in tangent form (module docstring).

    ``targets``: (target, atom) of the right-hand side kernel (("M", i, k) upper triangle,
    ("F", i), ("ydot", 2n + k)); ``groups``: the tangent code per column group with a
    structurally nonzero derivative (positions, velocities). With generalized speeds (``nv``
    not None) the columns are y[0] .. y[n + nv - 1] and the "z" operations index the rows of
    ydot themselves (the kinematic rates ("ydot", i < n) and the quadratures ("ydot", n + nv + k)).
    """

    n: int
    nz: int
    program: Program
    targets: list
    groups: list
    nv: int | None = None

    @property
    def ncol(self) -> int:
        """The columns of dr/dy differentiated: 2n, or n + nv with generalized speeds."""
        return 2 * self.n if self.nv is None else self.n + self.nv

    def size(self) -> int:
        """Number of operand terms of the program and the tangent code (a measure of the code's size)."""
        ops = [e for g in self.groups for col in list(g.columns.values()) + [g.wide] for _, _, e in col]
        return sum(len(se.Add.make_args(e)) for e in ops) + len(self.program)


def _mass_terms(target, tangent):
    """The contributions of d(target) = ``tangent`` to g = dM a - dF."""
    kind, *idx = target
    if kind == "M":
        i, k = idx
        out = [("g", i, tangent * se.Symbol(f"a[{k}]"))]
        if i != k:
            out.append(("g", k, tangent * se.Symbol(f"a[{i}]")))
        return out
    if kind == "F":
        return [("g", idx[0], -tangent)]
    return [("z", idx[0], tangent)]


def tangent_program(rhs: Block, n: int, nz: int = 0, narrow: int | None = None, cse: bool | None = None,
                    program: tuple | None = None, nv: int | None = None) -> TangentProgram:
    """The forward-mode Jacobian of the right-hand side kernel ``rhs`` (model_blocks(scene)["rhs"]:
    targets ("M", i, j), ("F", i), ("ydot", 2n + k)) by y[0] .. y[2n-1] (the quadrature states z
    do not enter the rates, as in the expanded form). ``program``: (Program, targets) of
    :func:`build_program` if already built (its partials are computed here). ``nv``: the speeds
    of a model with generalized speeds: columns y[0] .. y[n + nv - 1], targets ("ydot", i) also
    for the kinematic rates i < n, and the "z" operations index ydot's rows (TangentProgram)."""
    prog, targets = program if program is not None else build_program(rhs, n, cse, nv=nv)
    narrow = NARROW if narrow is None else narrow
    zero = 2 * n if nv is None else 0  # the row of ydot of the "z" operations' index 0
    targets = [((("ydot", t[1] - zero) if t[0] == "ydot" else t), a) for t, a in targets]
    prog.finish_rhs()
    groups = []
    for start, stop in ((0, n), (n, n + (n if nv is None else nv))):
        group = _group(prog, targets, start, stop, narrow)
        if group.columns or group.blocks:
            groups.append(group)
    targets = [((("ydot", zero + t[1]) if t[0] == "ydot" else t), a) for t, a in targets]
    return TangentProgram(n, nz, prog, targets, groups, nv)


def _group(prog: Program, targets: list, start: int, stop: int, narrow: int) -> TangentGroup:
    cols = frozenset(range(start, stop))
    nv = prog.n_rhs
    dg = [d & cols for d in prog.deps[:nv]]
    is_wide = [len(d) > narrow for d in dg]
    # Wide values by the set of columns they depend on (operands depend on subsets: smaller sets
    # first is an order of evaluation), accumulators contiguous per set.
    # Values read by a wide value of another set first in their set (their tangents are zeroed after
    # each column that computes them, as one range).
    shared = {u for k in range(nv) if is_wide[k] for u, _, _ in prog.partials[k]
              if (j := prog.index(u)) is not None and is_wide[j] and dg[j] != dg[k]}
    order = sorted((k for k in range(nv) if is_wide[k]), key=lambda k: (len(dg[k]), sorted(dg[k]), k))
    slots = sorted(order, key=lambda k: (len(dg[k]), sorted(dg[k]), prog.symbols[k] not in shared, k))
    widx = {k: i for i, k in enumerate(slots)}
    state = {se.Symbol(f"y[{i}]"): i for i in cols}
    group = TangentGroup(start, stop, nw=len(widx))

    def dsym(k):
        return se.Symbol(f"d{k}")

    def wsym(k):
        return se.Symbol(f"w[{widx[k]}]")

    def scaled(coef, atom, t):
        e = coef if atom is None else coef * atom
        return e * t

    # The operands of each value with their index (None: not a value), once.
    links = [[(u, coef, atom, prog.index(u)) for u, coef, atom in prog.partials[k]] for k in range(nv)]
    by_column: dict[int, list[int]] = {c: [] for c in cols}
    for k in range(nv):
        for c in dg[k]:
            by_column[c].append(k)
    # Column c: the narrow values depending on c, their contributions to wide values and targets.
    for c in sorted(cols):
        ops = []
        for k in by_column[c]:
            terms = []
            for u, coef, atom, j in links[k]:
                if j is None:
                    if state.get(u) == c:
                        terms.append(coef if atom is None else coef * atom)
                elif c in dg[j] and not is_wide[j]:
                    terms.append(scaled(coef, atom, dsym(j)))
            if not terms:
                continue
            if is_wide[k]:
                ops.append(("w", widx[k], se.Add(*terms)))
            else:
                ops.append(("d", k, se.Add(*terms)))
        for tgt, a in targets:
            j = prog.index(a)
            if j is None:
                if state.get(a) == c:
                    ops += _mass_terms(tgt, se.Integer(1))
            elif c in dg[j] and not is_wide[j]:
                ops += _mass_terms(tgt, dsym(j))
        ops = _live_ops(ops)
        if ops:
            group.columns[c] = ops
    # The wide values (narrow parts accumulated above), then their targets, by blocks.
    by_target: dict = {}
    for tgt, a in targets:
        j = prog.index(a)
        if j is not None and is_wide[j]:
            by_target.setdefault(j, []).append(tgt)
    block = None
    for k in order:
        if block is None or block[0] != dg[k]:
            block = [dg[k], widx[k], widx[k] + 1, []]
            group.blocks.append(block)
        block[1], block[2] = min(block[1], widx[k]), max(block[2], widx[k] + 1)
        terms = [scaled(coef, atom, wsym(j)) for u, coef, atom, j in links[k] if j is not None and is_wide[j]]
        if terms:
            block[3].append(("w", widx[k], se.Add(*terms)))
        for tgt in by_target.get(k, ()):
            block[3] += _mass_terms(tgt, wsym(k))
    group.blocks = [tuple(b) for b in group.blocks]
    return group


def _live_ops(ops: list) -> list:
    """The operations whose result is read (accumulations and results always are)."""
    live: set = set()
    kept = []
    for op in reversed(ops):
        kind, k, e = op
        if kind == "d" and f"d{k}" not in live:
            continue
        live |= {str(s) for s in e.free_symbols}
        kept.append(op)
    return kept[::-1]
