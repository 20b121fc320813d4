"""The Jacobian in tangent form: forward-mode differentiation of the right-hand side's program.

The expanded Jacobian (:func:`lagcodegen.formulation.kernels.model_blocks`, key ``jac``)
differentiates r = M a - F symbolically: n x 2n expressions, each as long as a row of M and F,
so its code grows like n^3 (and gcc's time and memory faster still). Here the right-hand side
kernel (M's upper triangle, F, the quadrature rates) is first reduced to a straight-line program
by common-subexpression elimination,

    v_k = f_k(v_0 .. v_{k-1}, y, p, t),    M_ij, F_i, z'_k = g(v, y, p, t),

and differentiated in forward mode along a seed direction e_j (dy = e_j):

    dv_k = sum over the direct operands u of f_k of (d f_k / d u) * du,

the partial derivatives d f_k / d u being expressions of the program's own values, computed
once per call. The generated code runs the tangent program once per column j of dr/dy
(a loop, so the code holds it once per group of columns): its size is that of the right-hand
side plus one term per (statement, operand) pair, which grows like the right-hand side, n^2
for a chain. The columns are grouped (positions q, velocities q'): a group's tangent program
holds only the statements that depend on one of its columns (M(q, t) has no velocity in it,
so the velocity columns skip dM and every statement of M).

Column j of the Jacobian is then, as in the expanded form, -M^-1 (dM a - dF) (a = q'') for
the accelerations and dz'/dy_j for the quadrature rates. Everything here is language-neutral:
:class:`TangentProgram` holds symengine expressions in the kernels' array symbols (``y[i]``,
``p[k]``, ``t``) and in the program's own symbols (``v<k>`` values, ``e<m>`` partial
derivatives, ``dv<k>`` tangents, ``s[i]`` the seed); :mod:`lagcodegen.codegen.c` prints it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import symengine as se

from .kernels import Block

#: Choices of Scene.jacobian_form: "expanded" (kernels.model_blocks: symbolic dr/dy),
#: "tangent" (this module).
JACOBIAN_FORMS = ("expanded", "tangent")


@dataclass
class TangentGroup:
    """The tangent program of the columns ``start <= j < stop`` of dr/dy.

    ``statements``: (name, expr) for the values with a nonzero tangent in this group, in
    order (``dv<k>`` = a linear combination of earlier tangents and the seed ``s[i]``);
    ``targets``: (target, expr) for the structurally nonzero derivatives of the kernel's
    targets: ("dM", i, j) (upper triangle), ("dF", i), ("dZ", k); the others are zero.
    """

    start: int
    stop: int
    statements: list = field(default_factory=list)
    targets: list = field(default_factory=list)
    cases: dict = field(default_factory=dict)
    stored: list = field(default_factory=list)
    resets: dict = field(default_factory=dict)

    @property
    def mass(self) -> bool:
        """True if some entry of M depends on a column of this group."""
        return any(t[0] == "dM" for t, _ in self.targets) or any(
            isinstance(t, tuple) and t[0] == "dM" for case in self.cases.values() for t, _ in case)

    @property
    def force(self) -> bool:
        """True if some entry of F depends on a column of this group."""
        return any(t[0] == "dF" for t, _ in self.targets) or any(
            isinstance(t, tuple) and t[0] == "dF" for case in self.cases.values() for t, _ in case)


@dataclass
class TangentProgram:
    """Forward-mode program of the right-hand side kernel (see the module docstring).

    ``primal``: (v<k>, expr) statements, in order (only those the Jacobian reads);
    ``values``: (target, expr) computing M's upper triangle ("M", i, j) from them; ``partials``: a Block
    of targets ("e", m) (the nontrivial partial derivatives, printed as constants after
    common-subexpression elimination); ``groups``: the tangent programs of the column groups
    (positions, velocities) with a structurally nonzero derivative (the others' columns of
    dr/dy are zero).
    """

    n: int
    nz: int
    primal: list
    values: list
    partials: Block
    groups: list

    def size(self) -> int:
        """Number of operand terms of the tangent statements (a measure of the code's size)."""
        return sum(len(se.Add.make_args(e)) for g in self.groups
                   for _, e in g.statements + g.targets + [x for case in g.cases.values() for x in case])


def _seed(i: int):
    return se.Symbol(f"s[{i}]")


#: Statements and targets depending on at most this many columns of their group are "narrow":
#: computed only for those columns (one copy each, selected by the column), not in every column.
NARROW = 2


def tangent_program(rhs: Block, n: int, nz: int = 0, narrow: int = NARROW) -> TangentProgram:
    """The forward-mode program of the right-hand side kernel ``rhs`` (model_blocks(scene)["rhs"]:
    targets ("M", i, j), ("F", i), ("ydot", 2n + k)), for the derivatives by y[0] .. y[2n-1]
    (the quadrature states z do not enter the rates, as in the expanded form). Statements and
    targets depending on at most ``narrow`` columns of a group are specialized per column
    (:func:`_split`; 0: none)."""
    repl, reduced = se.cse(list(rhs.exprs))
    # Rename the elimination's symbols (x<k>) to v<k>: the printer eliminates again, with x<k>.
    rename = {sym: se.Symbol(f"v{k}") for k, (sym, _) in enumerate(repl)}
    primal = [(rename[sym], expr.xreplace(rename)) for sym, expr in repl]
    values = [(tgt, expr.xreplace(rename)) for tgt, expr in zip(rhs.targets, reduced)]
    state = {se.Symbol(f"y[{i}]"): i for i in range(2 * n)}
    index = {v: k for k, (v, _) in enumerate(primal)}

    partials = Block()
    known: dict = {}

    def coefficient(expr, u):
        """d expr / d u: numbers and single symbols inline, anything else an e<m> constant."""
        d = se.diff(expr, u)
        if d == 0:
            return None
        if d.is_Number or d.is_Symbol:
            return d
        if d not in known:
            known[d] = se.Symbol(f"e{len(partials.exprs)}")
            partials.add(("e", len(partials.exprs)), d)
        return known[d]

    def operands(expr):
        return sorted((u for u in expr.free_symbols if u in index or u in state),
                      key=lambda u: (u in state, index.get(u, state.get(u))))

    # Partial derivatives: one list of (coefficient, operand) per statement and per target.
    links = [[(c, u) for u in operands(f) if (c := coefficient(f, u)) is not None] for _, f in primal]
    target_links = [[(c, u) for u in operands(g) if (c := coefficient(g, u)) is not None] for _, g in values]

    def kind(target):
        name, *idx = target
        if name == "M":
            return ("dM", *idx)
        if name == "F":
            return ("dF", *idx)
        return ("dZ", idx[0] - 2 * n)

    groups = []
    for start, stop in ((0, n), (n, 2 * n)):
        active: dict = {}  # operand -> its tangent symbol in this group

        def tangent(terms):
            parts = [c * active[u] for c, u in terms if u in active]
            return se.Add(*parts) if parts else None

        for i in range(start, stop):
            active[se.Symbol(f"y[{i}]")] = _seed(i)
        group = TangentGroup(start, stop)
        for (v, _), terms in zip(primal, links):
            d = tangent(terms)
            if d is not None:
                active[v] = se.Symbol(f"d{v}")
                group.statements.append((f"d{v}", d))
        for (tgt, _), terms in zip(values, target_links):
            d = tangent(terms)
            if d is not None:
                group.targets.append((kind(tgt), d))
        group.statements = _live(group.statements, [e for _, e in group.targets])
        if group.targets:
            groups.append(_split(group, narrow))
    # Only what the Jacobian reads: M, the partial derivatives the tangents use, their values.
    used = set()
    for g in groups:
        for _, e in g.statements + g.targets + [item for case in g.cases.values() for item in case]:
            used |= e.free_symbols
    kept = Block()
    for (tgt, e) in zip(partials.targets, partials.exprs):
        if se.Symbol(f"e{tgt[1]}") in used:
            kept.add(tgt, e)
    mass = [(t, e) for t, e in values if t[0] == "M"]
    primal = _live(primal, [e for _, e in mass] + kept.exprs)
    return TangentProgram(n, nz, primal, mass, kept, groups)


def _split(group: TangentGroup, narrow: int) -> TangentGroup:
    """Move the group's narrow statements and targets (depending on at most ``narrow`` of its
    columns) into per-column ``cases``: in column c only those depending on c are computed, with
    the seed s[c] = 1 folded in, and the others are zero. A narrow tangent that a wide statement
    or target reads is ``stored`` (a variable, zero outside the columns it depends on: ``resets``
    lists per column what to zero again after it, narrow entries of dM and dF included); the
    wide statements and targets stay in ``statements`` and ``targets``, run in every column."""
    if narrow <= 0:
        return group
    seeds = {f"s[{i}]": i for i in range(group.start, group.stop)}
    deps: dict = {}

    def tangents(expr):
        return [str(u) for u in expr.free_symbols if str(u) in seeds or str(u) in deps]

    def columns(expr):
        out = set()
        for u in tangents(expr):
            out |= {seeds[u]} if u in seeds else deps[u]
        return out

    for name, e in group.statements:
        deps[name] = columns(e)
    is_narrow = {name: len(d) <= narrow for name, d in deps.items()}
    wide = [(name, e) for name, e in group.statements if not is_narrow[name]]
    wide_targets = [(t, e) for t, e in group.targets if len(columns(e)) > narrow]
    stored = set()
    for _, e in wide + wide_targets:
        stored |= {u for u in tangents(e) if u in deps and is_narrow[u]}
    narrow_items = [(name, e) for name, e in group.statements if is_narrow[name]]
    narrow_targets = [(t, e) for t, e in group.targets if len(columns(e)) <= narrow]
    cases, resets = {}, {}
    for c in range(group.start, group.stop):
        case = []
        for item, e in narrow_items + narrow_targets:
            if c not in (deps[item] if isinstance(item, str) else columns(e)):
                continue
            terms = []
            for term in se.Add.make_args(e):
                (u,) = tangents(term)
                if u == f"s[{c}]":
                    terms.append(term.xreplace({se.Symbol(u): se.Integer(1)}))
                elif u in deps and c in deps[u]:
                    terms.append(term)
            case.append((item, se.Add(*terms)))
        live = set(stored) | {str(u) for t, e in case if not isinstance(t, str) for u in e.free_symbols}
        kept = []
        for item, e in reversed(case):
            if not isinstance(item, str) or item in live:
                live |= {str(u) for u in e.free_symbols}
                kept.append((item, e))
        cases[c] = kept[::-1]
        resets[c] = [item for item, _ in cases[c] if item in stored or (not isinstance(item, str) and item[0] != "dZ")]
    group.statements, group.targets = wide, wide_targets
    group.cases = {c: case for c, case in cases.items() if case}
    group.resets = {c: r for c, r in resets.items() if r}
    group.stored = [name for name, _ in narrow_items if name in stored]
    return group


def _live(statements: list, roots: list) -> list:
    """The statements (name, expr) that ``roots`` (expressions) read, directly or through others."""
    live = set()
    for e in roots:
        live |= {str(s) for s in e.free_symbols}
    kept = []
    for name, e in reversed(statements):
        if str(name) in live:
            live |= {str(s) for s in e.free_symbols}
            kept.append((name, e))
    return kept[::-1]
