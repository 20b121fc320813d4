"""Language-neutral kernels: the expressions of each generated function as :class:`Block` s.

Symbols are renamed to array elements (q_i -> y[i], q_i' -> y[n+i], z_k -> y[2n+k], run-time
parameter k -> p[k]) and folded parameters replaced by numbers. Targets are tuples (array
name, 0-based indices...). Every formulation (ODE, Routhian, minimal coordinates, index-1,
GGL) produces Blocks; every language backend (:mod:`lagcodegen.codegen.c`,
:mod:`lagcodegen.codegen.fortran`) prints the same Blocks after the same common-subexpression
elimination, so C and Fortran evaluate the same operations.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import symengine as se

from .. import progress
from ..errors import ModelError
from ..model.model import RESERVED_PREFIX
from ..model.treedynamics import recorded, substitute_shared, tree_nodes
from .scene import Scene

#: A common-subexpression elimination of at least this many operations (symengine's count_ops,
#: plus 10 per expression: many small expressions cost too) runs in a child process
#: (:func:`lagcodegen.progress.isolated`), so that Ctrl-C stops it at once; a smaller one runs
#: here (a fork costs some 15 ms). Measured (symengine 0.15, 20/30-link pendulums): the
#: right-hand side, 230 expressions and 61 000 operations, takes 0.2 s, 495 and 185 000 1.1 s;
#: the tangent Jacobian's 4126 partial derivatives of 21 000 operations 0.4 s.
ISOLATE_CSE_OPS = 50_000


#: :func:`count_ops` asks symengine only below this many nodes of the expressions written out
#: as trees.
TREE_NODES_LIMIT = 5_000_000


def count_ops(exprs) -> int:
    """symengine's count_ops of ``exprs``, safe on DAGs: the expressions of a rigid-body tree
    (:mod:`lagcodegen.model.treedynamics`) share their subexpressions, and count_ops walks them
    as trees (exponential in the tree's depth). Above TREE_NODES_LIMIT tree nodes the tree node
    count stands for it (an over-estimate: every threshold compared with it is passed)."""
    exprs = list(exprs)
    if not exprs:
        return 0
    nodes = tree_nodes(exprs, TREE_NODES_LIMIT)
    return se.count_ops(*exprs) if nodes <= TREE_NODES_LIMIT else nodes


def cse_cost(exprs) -> int:
    """The measure of :data:`ISOLATE_CSE_OPS`: operations plus 10 per expression."""
    return count_ops(exprs) + 10 * len(exprs) if exprs else 0


def cse(exprs) -> tuple[list, list]:
    """symengine's ``cse(exprs)`` (replacements, reduced expressions), reported as the stage
    "cse" (:mod:`lagcodegen.progress`) and stoppable by Ctrl-C: it is one C call holding the
    GIL, seconds long for a 50-link chain, so large ones (:data:`ISOLATE_CSE_OPS`) run in a
    child process. The result is the same either way."""
    exprs = list(exprs)
    with progress.stage("cse", unit=f"of {len(exprs)} expressions"):
        if exprs and progress.can_isolate() and cse_cost(exprs) >= ISOLATE_CSE_OPS:
            return progress.isolated(se.cse, exprs)
        return se.cse(exprs)


@dataclass
class Block:
    """One common-subexpression-eliminated block of generated code: ``targets`` (tuples such as
    ("M", i, j), ("F", i), ("out", k)) and ``exprs`` (symengine, in the array symbols ``y[i]``,
    ``p[k]``, ``lam[j]``, ``yp[i]``, ``a[i]``, ``t``, ``cj``)."""

    targets: list = field(default_factory=list)
    exprs: list = field(default_factory=list)
    #: Temporaries (symbol, expression) computed in order before the targets (a rigid-body tree's
    #: program, :func:`lagcodegen.model.treedynamics.recorded`): the exprs may use them.
    defs: list = field(default_factory=list)

    def __bool__(self) -> bool:
        return bool(self.exprs)

    def add(self, target: tuple, expr) -> None:
        self.targets.append(target)
        self.exprs.append(expr)

    def __add__(self, other: "Block") -> "Block":
        return Block(self.targets + other.targets, self.exprs + other.exprs, self.defs + other.defs)

    def add_partials(self, expr, variables, c, target) -> None:
        """Add ``c(d expr / d variables[j])`` under ``target(j)`` for each j where it is not zero
        (``c``: the substitution into array symbols, :func:`substituter`)."""
        expr = se.sympify(expr)
        for j, var in enumerate(variables):
            e = c(se.diff(expr, var))
            if e != 0:
                self.add(target(j), e)


def symbol_map(scene: Scene) -> dict:
    """symengine substitution: model symbols -> array elements, folded parameters -> numbers."""
    eom = scene.eom
    model = eom.model
    n = model.n
    sub = {}
    zero = 2 * n  # the first quadrature state
    for i, q in enumerate(model.coords):
        sub[se.Symbol(q.name)] = se.Symbol(f"y[{i}]")
    if model.general:  # y = (q, v, z); a coordinate's rate q' is its kinematic equation k(q, v, t)
        for i, v in enumerate(model.velocities):
            sub[se.Symbol(v.name)] = se.Symbol(f"y[{n + i}]")
        rates = substitute_all(dict(sub), eom.qdot_se)
        for qd, k in zip(model.speeds, rates):
            if qd not in model.velocities:
                sub[se.Symbol(qd.name)] = k
        zero = n + model.nv
    else:
        for i, v in enumerate(model.speeds):
            sub[se.Symbol(v.name)] = se.Symbol(f"y[{n + i}]")
    for k, (name, _) in enumerate(eom.quadratures):
        sub[se.Symbol(name)] = se.Symbol(f"y[{zero + k}]")
    for k, name in enumerate(scene.runtime_parameters):
        sub[se.Symbol(name)] = se.Symbol(f"p[{k}]")
    sub.update(scene.substitutions())
    return sub


def require_symmetric(eom, what: str) -> None:
    """ModelError if the mass matrix of ``eom`` need not be symmetric (equations given directly,
    Kane's with dependent speeds): only the C right-hand side (LU) handles that; ``what`` names the
    feature refused."""
    if not getattr(eom, "symmetric", True):
        raise ModelError(f"model {eom.model.name!r}: its mass matrix is not symmetric (equations given directly, "
                         f"e.g. Kane's with dependent speeds): {what} is not available for it (the C backend's "
                         "right-hand side is: compile_model(..., lang='c'))")


def mass_matrix_is_diagonal(eom) -> bool:
    """True if every off-diagonal entry of M is structurally zero (the generated solve divides)."""
    n = len(eom.M_se)
    return n > 1 and all(eom.M_se[i][j] == 0 for i in range(n) for j in range(n) if i != j)


def substituter(scene: Scene):
    """f(expr) renaming the model's symbols to array elements (q_i -> y[i], ...) and folding constants."""
    sub = symbol_map(scene)

    def c(e):
        return se.sympify(e).xreplace(sub) if sub else se.sympify(e)
    return c


def substitute_all(sub: dict, exprs) -> list:
    """``exprs`` with the substitution ``sub`` (:func:`symbol_map`) applied, as one matrix: the
    same expressions as ``e.xreplace(sub)`` each, the dictionary converted once rather than per
    expression (1325 entries of a 50-link chain: 0.17 -> 0.05 s)."""
    exprs = [se.sympify(e) for e in exprs]
    if not sub or not exprs:
        return exprs
    return list(se.DenseMatrix(len(exprs), 1, exprs).xreplace(sub))


def residual_derivatives(eom):
    """d r_i / d y_j for r = M a - F (eq. 3.16 as a residual), y = (q, q'), with the
    accelerations a as the symbols ``a[i]``: a function (i, j) -> symengine expression in the
    model's symbols. The dense and the sparse Jacobian are both built from it."""
    model = eom.model
    n = model.n
    a = [se.Symbol(f"a[{i}]") for i in range(n)]
    # "__" opens no model name (model.RESERVED_PREFIX), so "__acc<i>" is no user symbol; the
    # name is kept (rather than "a[i]" directly) because symengine orders terms by name hashes
    # and the generated C stays byte for byte what it was.
    acc = [se.Symbol(f"{RESERVED_PREFIX}acc{i}") for i in range(n)]
    y = [se.Symbol(s.name) for s in model.coords] + [se.Symbol(s.name) for s in model.speeds]
    r = [sum((eom.M_se[i][j] * acc[j] for j in range(n)), se.Integer(0)) - eom.F_se[i] for i in range(n)]
    asub = dict(zip(acc, a))

    def d(i: int, j: int):
        return se.diff(r[i], y[j]).xreplace(asub)
    return d


def model_blocks(scene: Scene) -> dict[str, Block]:
    """The kernels of the ODE M(q, t) q'' = F(q, q', t) (eq. 3.16) with quadratures z' = rate.

    Keys ``rhs``, ``jac`` (if the scene asks for it) and ``out``; targets ("M", i, j) for the
    upper triangle of M (the code mirrors it), ("F", i), ("ydot", k) (quadrature rates),
    ("G", i, j) = d r_i / d y_j for r = M a - F with a = q'' (the symbols ``a[i]``),
    ("Z", k, j) = d z'_k / d y_j and ("out", k). Reports the stage "formulate"
    (:mod:`lagcodegen.progress`): the rows of M, then the Jacobian's columns.
    """
    n = scene.eom.model.n
    if scene.eom.general:
        with progress.stage("formulate", total=scene.eom.nv, unit="rows") as stage:
            return _general_blocks(scene, stage)
    with progress.stage("formulate", total=n + (2 * n if scene.jacobian else 0), unit="rows and columns") as stage:
        return _model_blocks(scene, stage)


def _general_blocks(scene: Scene, stage) -> dict[str, Block]:
    """The kernels of q' = k(q, v, t), M(q, t) v' = F(q, v, t) (generalized speeds): ``rhs``
    with ("ydot", i) = k_i for the coordinates' rates, ("M", a, b) (upper triangle; ("Mx", a, b) every
    entry when M is not symmetric, :attr:`EquationsOfMotion.symmetric`) and
    ("F", a) of the speeds' equations, ("ydot", nq + nv + k) the quadratures; ``out``; and
    with ``scene.jacobian`` (the expanded form) ``jac``: M, ("G", a, j) = d r_a / d y_j for
    r = M a - F (a = v', the symbols ``a[i]``) and ("Z", r, j) = d ydot_r / d y_j for the rows
    given in closed form: the kinematic rates (r < nq) and the quadratures (r = nq + k), j over
    the state's (q, v)."""
    eom = scene.eom
    model = eom.model
    nq, nv = model.nq, model.nv
    if eom.tree is not None and scene.jacobian:
        raise ModelError(f"model {model.name!r}: the expanded Jacobian of a rigid-body tree is not generated (its "
                         "entries would be derivatives of the tree's DAGs): use the tangent form "
                         "(jacobian_form 'auto' or 'tangent') or jacobian=False")
    sub = symbol_map(scene)
    subst = substitute_shared if eom.tree is not None else substitute_all
    if eom.tree is not None:
        rhs = tree_rhs(eom, sub)
    else:
        rhs = Block()
        for a in range(nv):
            if not eom.symmetric:  # M not symmetric (Kane's equations with dependent speeds): every entry
                for b, e in enumerate(subst(sub, eom.M_se[a])):
                    rhs.add(("Mx", a, b), e)
                continue
            for b, e in enumerate(subst(sub, eom.M_se[a][a:]), start=a):
                rhs.add(("M", a, b), e)
        rhs = rhs + Block([("F", a) for a in range(nv)], subst(sub, eom.F_se))
    for i, e in enumerate(substitute_all(sub, eom.qdot_se)):
        rhs.add(("ydot", i), e)
    for _ in range(nv):
        stage.advance()
    for k, (_, rate) in enumerate(eom.quadratures):
        rhs.add(("ydot", nq + nv + k), se.sympify(rate).xreplace(sub))
    blocks = {"rhs": rhs}
    if scene.jacobian:
        blocks["jac"] = _general_jacobian(scene, rhs)
    outputs = scene.output_list()
    blocks["out"] = Block([("out", k) for k in range(len(outputs))], subst(sub, [o.expr for o in outputs]))
    return blocks


def _general_jacobian(scene: Scene, rhs: Block) -> Block:
    """The expanded Jacobian's kernel of a model with generalized speeds (:func:`_general_blocks`):
    the right-hand side's entries (in the array symbols) differentiated by the state's symbols
    y[0] .. y[nq + nv - 1] (the coordinates' rates q' inside F are the kinematics already)."""
    model = scene.eom.model
    nq, nv = model.nq, model.nv
    y = [se.Symbol(f"y[{j}]") for j in range(nq + nv)]
    a = [se.Symbol(f"a[{i}]") for i in range(nv)]
    M = [[se.Integer(0)] * nv for _ in range(nv)]
    F = [se.Integer(0)] * nv
    rows = {}  # row of ydot in closed form -> its expression
    jac = Block()
    for target, e in zip(rhs.targets, rhs.exprs):
        kind, *idx = target
        if kind == "M":
            M[idx[0]][idx[1]] = M[idx[1]][idx[0]] = e
            jac.add(target, e)
        elif kind == "F":
            F[idx[0]] = e
        else:  # ("ydot", r): a kinematic rate (r < nq) or a quadrature (r >= nq + nv)
            rows[idx[0]] = e
    for j, var in enumerate(y):
        dM = [[se.diff(M[i][k], var) if M[i][k] != 0 else M[i][k] for k in range(nv)] for i in range(nv)]
        for i in range(nv):
            jac.add(("G", i, j), sum((dM[i][k] * a[k] for k in range(nv)), se.Integer(0)) - se.diff(F[i], var))
    for r, e in sorted(rows.items()):
        row = r if r < nq else r - nv  # Z's rows: the nq kinematic rates, then the quadratures
        for j, var in enumerate(y):
            jac.add(("Z", row, j), se.diff(e, var))
    return jac


def _model_blocks(scene: Scene, stage) -> dict[str, Block]:
    eom = scene.eom
    model = eom.model
    n = model.n
    c = substituter(scene)
    sub = symbol_map(scene)
    # A rigid-body tree's DAGs: one substitution sharing subexpressions across the kernels.
    subst = substitute_shared if eom.tree is not None else substitute_all
    if eom.tree is not None and scene.jacobian:
        raise ModelError(f"model {model.name!r}: the expanded Jacobian of a rigid-body tree is not generated (its "
                         "entries would be derivatives of the tree's DAGs): use the C backend's tangent form "
                         "(jacobian_form 'auto' or 'tangent') or jacobian=False")
    if eom.tree is not None:
        rhs = tree_rhs(eom, sub)
        for _ in range(n):
            stage.advance()
    else:
        mass = Block()
        for i in range(n):  # row by row: a loop point for progress
            if not eom.symmetric:  # M not symmetric (equations given directly): every entry
                for j, e in enumerate(subst(sub, eom.M_se[i])):
                    mass.add(("Mx", i, j), e)
            else:
                for j, e in enumerate(subst(sub, eom.M_se[i][i:]), start=i):
                    mass.add(("M", i, j), e)
            stage.advance()
        rhs = mass + Block([("F", i) for i in range(n)], subst(sub, eom.F_se))
    for k, (_, rate) in enumerate(eom.quadratures):
        rhs.add(("ydot", 2 * n + k), c(rate))
    blocks = {"rhs": rhs}
    if scene.jacobian:
        y = [se.Symbol(s.name) for s in model.coords] + [se.Symbol(s.name) for s in model.speeds]
        dr = residual_derivatives(eom)
        jac = mass + Block()
        for j in range(2 * n):
            for i in range(n):
                jac.add(("G", i, j), c(dr(i, j)))
            stage.advance()
        for k, (_, rate) in enumerate(eom.quadratures):
            for j, var in enumerate(y):
                jac.add(("Z", k, j), c(se.diff(rate, var)))
        blocks["jac"] = jac
    outputs = scene.output_list()
    blocks["out"] = Block([("out", k) for k in range(len(outputs))], subst(sub, [o.expr for o in outputs]))
    return blocks


def tree_rhs(eom, sub: dict) -> Block:
    """The right-hand side kernel of a model with a rigid-body tree: the tree's program
    (:func:`lagcodegen.model.treedynamics.recorded`: composite rigid bodies for M, recursive
    Newton-Euler for the bias) as the block's temporaries, plus the closed-form terms of the
    model's other elements; targets as :func:`model_blocks`' ("M", i, j), ("F", i)."""
    model = eom.model
    n = model.nv
    q = [se.Symbol(s.name) for s in model.coords]
    qd = [se.Symbol(s.name) for s in model.v]
    defs, Mt, bias = recorded(model, q, qd)
    M_rest, F_rest = eom.tree.rest
    block = Block(defs=list(zip([sym for sym, _ in defs], substitute_all(sub, [e for _, e in defs]))))

    def c(e):
        return se.sympify(e).xreplace(sub)
    for i in range(n):
        for j in range(i, n):
            block.add(("M", i, j), c(M_rest[i][j] + Mt[i][j]))
    for i in range(n):
        block.add(("F", i), c(F_rest[i] - bias[i]))
    return block


@dataclass
class SparseJacobian:
    """Kernel of the sparse Jacobian: the structurally nonzero entries of df/dy (``pattern``)
    in compressed-column order. ``block`` computes M (``Md`` when diagonal) and either the
    entries ``vals`` directly or the columns ``G`` of dr/dy to be solved with M; ``copies``
    lists (k, j, i): vals[k] = -G[j][i] after the solve; ``solve_cols`` the columns solved."""

    block: Block
    diagonal: bool
    entries: list
    colptr: list
    copies: list
    solve_cols: list


def sparse_jacobian(scene: Scene, pattern) -> SparseJacobian:
    """The sparse Jacobian's kernel. With M structurally diagonal each entry is one expression,
    -(dr_i/dy_j)/M_ii with r = M a - F; otherwise M is factored once and only the columns of
    dr/dy with a nonzero entry are solved for."""
    eom = scene.eom
    require_symmetric(eom, "the sparse Jacobian")
    model = eom.model
    n = model.n
    ny = pattern.shape[0]
    c = substituter(scene)
    y = [se.Symbol(s.name) for s in model.coords] + [se.Symbol(s.name) for s in model.speeds]
    dr = residual_derivatives(eom)
    M = [[c(eom.M_se[i][j]) for j in range(n)] for i in range(n)]
    diagonal = all(M[i][j] == 0 for i in range(n) for j in range(n) if i != j)
    entries = [(i, j) for j in range(ny) for i in range(ny) if pattern[i, j]]
    colptr = [0]
    for j in range(ny):
        colptr.append(colptr[-1] + int(pattern[:, j].sum()))
    block = Block()
    if diagonal:
        for i in range(n):
            block.add(("Md", i), M[i][i])
    else:
        for i in range(n):
            for j in range(i, n):
                block.add(("M", i, j), M[i][j])
    copies, solve_cols = [], []
    for k, (i, j) in enumerate(entries):
        if i < n:  # dq'_i/dq'_i
            block.add(("vals", k), se.Integer(1))
        elif i < 2 * n:
            ii = i - n
            d = c(dr(ii, j)) if j < 2 * n else se.Integer(0)
            if diagonal:
                block.add(("vals", k), -d / M[ii][ii])
            else:
                if d != 0:
                    block.add(("G", ii, j), d)
                if j not in solve_cols:
                    solve_cols.append(j)
                copies.append((k, j, ii))
        else:  # quadrature rates
            rate = eom.quadratures[i - 2 * n][1]
            block.add(("vals", k), c(se.diff(rate, y[j])) if j < 2 * n else se.Integer(0))
    return SparseJacobian(block, diagonal, entries, colptr, copies, solve_cols)
