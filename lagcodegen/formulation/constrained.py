"""Generated code for constrained systems (eq. 4.5): the augmented index-1 system, the GGL residual.

:func:`generate_constrained_c` renders templates/c/dae.c.j2 (accelerations and multipliers from
[M A^T; A 0][q''; -lambda] = [F; gamma], constraint residuals, projection, outputs, events) and,
for the GGL formulation, the DAE residual F(t, y, y') and its Jacobian dF/dy + cj dF/dy' for
IDA; with ``lang="fortran"`` the same functions come from templates/fortran/dae.f90.j2 (bound
to the same C names, evaluating the same operations: :func:`constrained_blocks` builds the
expression blocks once for both languages). The native drivers are model-independent C
(lagcodegen/runtime/lcg_cvc.c, lcg_ida.c), compiled once into the runtime, and reach a model's
functions through its table (lcg_dae_model.h); :func:`lagcodegen.compile_constrained` compiles and runs them.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Iterable, Sequence

import symengine as se

from ..derivation import to_se
from ..errors import ModelError
from ..model.events import event_list
from ..model.model import RESERVED_PREFIX
from ..model.outputs import CONSTRAINT_OUTPUT_GROUPS
from ..model.outputs import DEFAULT_CONSTRAINED_OUTPUTS as DEFAULT_OUTPUTS
from ..theory.constraints import ConstrainedSystem
from ..model.treedynamics import substitute_shared
from .kernels import Block, symbol_map, tree_rhs
from .scene import Scene


# ---------------------------------------------------------------------- symbolic pieces
class ConstrainedSymbols:
    """symengine pieces of a constrained system: M, F, A, A0, s = A q' + A0, gamma, f."""

    def __init__(self, system: ConstrainedSystem, eom):
        model = system.model
        self.system = system
        self.eom = eom
        self.n = model.n
        self.q = [se.Symbol(s.name) for s in model.coords]
        self.v = [se.Symbol(s.name) for s in model.speeds]
        self.t = se.Symbol(model.t.name)
        rows = system.rows()
        self.A = [[to_se(a, f"constraint {r.index}") for a in r.A] for r in rows]
        self.A0 = [to_se(r.A0, f"constraint {r.index}") for r in rows]
        self.f = [to_se(f, f"holonomic constraint {j}") for j, f in enumerate(system.holonomic)]
        self.s = [sum((a * v for a, v in zip(row, self.v)), se.Integer(0)) + a0 for row, a0 in zip(self.A, self.A0)]
        self.gamma = []
        for s in self.s:  # gamma = -d/dt (A q' + A0) with q'' excluded
            d = se.diff(s, self.t)
            for q, v in zip(self.q, self.v):
                d = d + se.diff(s, q) * v
            self.gamma.append(-d)
        self.lam = [se.Symbol(m.name) for m in system.multipliers]
        self.J = len(rows)
        self.JH = len(self.f)
        self.M = eom.M_se
        self.F = eom.F_se
        self.nq = self.nv = self.n
        self.general = model.general
        if model.general:
            self._speeds(model, eom)

    def _speeds(self, model, eom) -> None:
        """Generalized speeds v (q' = k(q, v, t), linear in v): the rows in v, A_v = dk/dv-weighted
        A (A_v = A G), s = A k + A0 (= A_v v + A0_v), gamma = -(ds/dt + ds/dq k) (v' excluded); the
        holonomic rows in q kept as ``Aq`` (the positions' projection) and k as ``kin``."""
        self.nv = model.nv
        self.qd = [se.Symbol(s.name) for s in model.speeds]
        self.v = [se.Symbol(s.name) for s in model.v]
        inv = {qd: k for qd, k in zip(self.qd, eom.qdot_se) if qd not in set(self.v)}
        self.kin = [se.sympify(k) for k in eom.qdot_se]
        self.Aq = [list(self.A[j]) for j in range(self.JH)]
        self.s = [se.sympify(s).xreplace(inv) for s in self.s]
        self.A = [[se.diff(s, v) for v in self.v] for s in self.s]
        self.gamma = [-self.rate(s) for s in self.s]
        self.n = self.nv

    def rate(self, w):
        """d/dt w(q, v, t) with v' excluded: dw/dt + dw/dq q' (q' = k for generalized speeds)."""
        d = se.diff(w, self.t)
        for q, k in zip(self.q, self.kin if self.general else self.v):
            d = d + se.diff(w, q) * k
        return d



def block_substituter(sym, sub: dict):
    """f(exprs) -> ``exprs`` with the substitution ``sub`` into array symbols: each expression's
    xreplace, or for a rigid-body tree (whose M, F, energy, ... are DAGs) one shared substitution
    over the whole list (:func:`~lagcodegen.model.treedynamics.substitute_shared`): copies of a
    DAG made by separate xreplace calls share nothing, and the common-subexpression elimination of
    a block then compares them node by node, in time exponential in the tree's depth (minutes for
    a 20-joint robot)."""
    if getattr(sym.eom, "tree", None) is not None:
        return lambda exprs: substitute_shared(sub, exprs)
    return lambda exprs: [se.sympify(e).xreplace(sub) for e in exprs]


def mass_force_block(sym, sub: dict) -> Block:
    """The kernel ``mf`` of the constrained forms: the upper triangle of M and F, through the
    substitution ``sub`` into array symbols (:func:`block_substituter`)."""
    targets, exprs = [], []
    for i in range(sym.n):
        for j in range(i, sym.n):
            targets.append(("M", i, j))
            exprs.append(sym.M[i][j])
    for i in range(sym.n):
        targets.append(("F", i))
        exprs.append(sym.F[i])
    return Block(targets, block_substituter(sym, sub)(exprs))


def mass_force_program(sym, sub: dict) -> Block:
    """For a rigid-body tree, M and F (the targets of :func:`mass_force_block`) as the tree's
    recorded program (:func:`~lagcodegen.formulation.kernels.tree_rhs`: the block's temporaries),
    which the C backend prints in pieces as it does the unconstrained right-hand side; an empty
    block for other models. The expression block ``mf`` stays for the backends that print it."""
    if getattr(sym.eom, "tree", None) is None:
        return Block()
    return tree_rhs(sym.eom, sub)

def kinematics_block(sym, c) -> Block:
    """The coordinates' rates ydot[i] = k_i(q, v, t) of a system with generalized speeds."""
    return Block([("ydot", i) for i in range(sym.nq)], [c(k) for k in sym.kin])


def _constrained_outputs(system: ConstrainedSystem, sym: ConstrainedSymbols, scene: Scene,
                         names: Sequence[str]) -> list[tuple[str, object]]:
    """(name, symengine expression) of the requested outputs, groups expanded."""
    model = system.model
    avail = dict(scene.available_outputs())
    coord_names = [q.name for q in model.coords]
    speed_names = [v.name for v in model.v] if model.general else coord_names
    lam_names, force_names, resid_names, ineq_names = [], [], [], []
    for j in range(sym.J):
        avail[f"lambda_{j}"] = sym.lam[j]
        lam_names.append(f"lambda_{j}")
        for i, c in enumerate(speed_names):
            avail[f"R_{j}_{c}"] = sym.lam[j] * sym.A[j][i]
            force_names.append(f"R_{j}_{c}")
    for j in range(sym.JH):
        avail[f"g_{j}"] = sym.f[j]
        resid_names.append(f"g_{j}")
    for j in range(sym.J):
        avail[f"gdot_{j}"] = sym.s[j]
        resid_names.append(f"gdot_{j}")
    for k, g in enumerate(system.inequalities):
        avail[f"ineq_{k}"] = to_se(g, f"inequality constraint {k}")
        ineq_names.append(f"ineq_{k}")
    groups = {"lambda": lam_names, "constraint_forces": force_names, "residuals": resid_names,
              "inequalities": ineq_names,
              "momenta": [f"p_{c}" for c in coord_names],
              "positions": [f"{pt.name}_{a}" for pt in model.points.values() for a in "xyz"[:pt.dim]]}
    out: list[str] = []
    for item in names:
        if item in groups:
            out += groups[item]
        elif item in avail:
            out.append(item)
        else:
            raise ModelError(f"unknown output {item!r} (groups: {', '.join(CONSTRAINT_OUTPUT_GROUPS)}, "
                             f"energy, momenta, positions, ...; single outputs: "
                             f"{', '.join(k for k in avail if k not in ('momenta', 'positions'))})")
    seen: list[str] = []
    for nme in out:
        if nme not in seen:
            seen.append(nme)
    return [(nme, avail[nme]) for nme in seen]


def _uses(exprs, symbols) -> bool:
    symbols = set(symbols)
    return any(se.sympify(e).free_symbols & symbols for e in exprs)


# ---------------------------------------------------------------------- code generation
@dataclass
class ConstrainedCodeInfo:
    """Layout of the generated constrained code."""

    prefix: str
    n: int
    J: int
    JH: int
    ng: int
    output_names: list
    events: list
    ggl: bool
    ggl_jac: bool
    folded: dict = field(default_factory=dict)  # parameters folded into the code, with their values
    lang: str = "c"  # language of the model functions ("c" or "fortran"); the drivers are C
    contacts: tuple = ()  # indices of the inequalities with a restitution (<prefix>_impact.c)


@dataclass
class ConstrainedBlocks:
    """Everything the constrained templates need besides the sizes: the expression blocks
    (mf: M, F; con: A, s, g; gam; out; roots; ggl_res; ggl_jac) and the output and event lists."""

    scene: Scene
    n: int
    J: int
    JH: int
    ng: int
    blocks: dict
    outputs: list  # (name, symengine expression)
    events: list
    outputs_use_lam: bool
    roots_use_lam: bool
    #: Texts a backend printed from the blocks, by name, for the other files of the same code to
    #: reuse (the C backend's program of a tree's M and F: ``<prefix>_dae.c`` and ``_impact.c``).
    printed: dict = field(default_factory=dict)


def constrained_blocks(system: ConstrainedSystem, scene: Scene, *, ggl: bool = False, ggl_jacobian: bool = True,
                       outputs: Sequence[str] = DEFAULT_OUTPUTS, events: Iterable = ()) -> ConstrainedBlocks:
    """The expression blocks of the constrained code of ``system`` (symbols renamed as in ``scene``)."""
    sym = ConstrainedSymbols(system, scene.eom)
    n, J, JH = sym.n, sym.J, sym.JH
    ng = sym.nq + n + J + JH
    base = symbol_map(scene)

    def c(e, sub=base):
        return se.sympify(e).xreplace(sub)

    subst = block_substituter(sym, base)
    blocks = {}
    blocks["mf"] = mass_force_block(sym, base)
    blocks["mf_program"] = mass_force_program(sym, base)
    # A, s, g
    targets, exprs = [], []
    for r in range(J):
        for i in range(n):
            targets.append(("A", r, i))
            exprs.append(sym.A[r][i])
        targets.append(("s", r))
        exprs.append(sym.s[r])
    for k in range(JH):
        targets.append(("g", k))
        exprs.append(sym.f[k])
    blocks["con"] = Block(targets, subst(exprs))
    blocks["gam"] = Block([("gam", r) for r in range(J)], subst(sym.gamma))
    if sym.general:  # the holonomic rows in q (positions' projection) and q' = k(q, v, t)
        blocks["conq"] = Block([("Aq", r, i) for r in range(JH) for i in range(sym.nq)],
                               [c(sym.Aq[r][i]) for r in range(JH) for i in range(sym.nq)])
        blocks["kin"] = kinematics_block(sym, c)

    # outputs and roots: the multipliers are the array lam[]
    out_sub = dict(base)
    out_sub.update({lam: se.Symbol(f"lam[{j}]") for j, lam in enumerate(sym.lam)})
    outs = _constrained_outputs(system, sym, scene, list(outputs))
    out_subst = block_substituter(sym, out_sub)
    blocks["out"] = Block([("out", k) for k in range(len(outs))], out_subst([e for _, e in outs]))
    evs = event_list(system, events)
    root_exprs = [to_se(ev.expr, f"event {ev.name!r}") for ev in evs]
    blocks["roots"] = Block([("gout", k) for k in range(len(evs))], out_subst(root_exprs))

    # GGL residual and Jacobian
    blocks["ggl_res"] = blocks["ggl_jac"] = Block([], [])
    if ggl:
        # with generalized speeds: nq coordinate rows q' - k(q, v, t) - Aq^T mu (Aq = df/dq), nv speed rows
        nq, rate, Ah = (sym.nq, sym.kin, sym.Aq) if sym.general else (n, sym.v, sym.A)
        ny = nq + n
        qp = [se.Symbol(f"__qp{i}") for i in range(nq)]
        vp = [se.Symbol(f"__vp{i}") for i in range(n)]
        mu = [se.Symbol(f"__mu{k}") for k in range(JH)]
        # IDA's coefficient: the C argument cj, a reserved symbol until printed (a coordinate or
        # parameter named "cj" is y[i] or p[k] in the code, never this symbol)
        cj = se.Symbol(f"{RESERVED_PREFIX}cj")
        res = []
        for i in range(nq):
            res.append(qp[i] - rate[i] - sum((Ah[k][i] * mu[k] for k in range(JH)), se.Integer(0)))
        for i in range(n):
            res.append(sum((sym.M[i][j] * vp[j] for j in range(n)), se.Integer(0)) - sym.F[i]
                       - sum((sym.A[r][i] * sym.lam[r] for r in range(J)), se.Integer(0)))
        res += list(sym.f)
        res += list(sym.s)
        gsub = dict(base)
        gsub.update({lam: se.Symbol(f"y[{ny + j}]") for j, lam in enumerate(sym.lam)})
        gsub.update({m: se.Symbol(f"y[{ny + J + k}]") for k, m in enumerate(mu)})
        gsub.update({x: se.Symbol(f"yp[{i}]") for i, x in enumerate(qp)})
        gsub.update({x: se.Symbol(f"yp[{nq + i}]") for i, x in enumerate(vp)})
        gsub[cj] = se.Symbol("cj")
        blocks["ggl_res"] = Block([("rr", i) for i in range(ng)], block_substituter(sym, gsub)(res))
        if ggl_jacobian:
            yvars = sym.q + sym.v + sym.lam + mu
            ypvars = qp + vp
            targets, exprs = [], []
            for col, var in enumerate(yvars):
                for row, r in enumerate(res):
                    d = se.diff(r, var)
                    if col < ny:
                        d = d + cj * se.diff(r, ypvars[col])
                    if d != 0:
                        targets.append(("jac", row, col))
                        exprs.append(c(d, gsub))
            blocks["ggl_jac"] = Block(targets, exprs)
    return ConstrainedBlocks(scene, n, J, JH, ng, blocks, outs, evs, _uses([e for _, e in outs], sym.lam),
                             _uses(root_exprs, sym.lam))


def impact_blocks(system: ConstrainedSystem, scene: Scene, mass_force: bool = True) -> dict:
    """The expression blocks of the contact code of ``system`` (templates/c/impact.c.j2): ``mf``
    (M, F; with ``mf_program`` for a rigid-body tree, :func:`mass_force_program`; both empty
    without ``mass_force``: the caller has those of :func:`constrained_blocks`) and ``rows``: for the equality rows r < J the rows A_r, s_r = A_r q' + A0_r, h_r = f_r
    (holonomic) and gamma_r (as :func:`constrained_blocks`), then for each contact k (an
    inequality g_k >= 0 with a restitution, eq. 4.3) the row J + k: G_k = dg_k/dq,
    w_k = G_k q' + dg_k/dt, h = g_k and gamma = -d/dt w_k with q'' excluded; then for each rough
    contact (a ``tangent``) its tangential row (two, consecutive, for a 3-D contact), h = 0: from a
    position tangent as from g, from a tangent given as the slip velocity u (in the speeds) the row
    du/dv, u and -du/dt with v' excluded. Also returns ``tangent_of`` (the contact, 0..NC-1, of
    each tangential row) as ``blocks["tangent_of"]``."""
    sym = ConstrainedSymbols(system, scene.eom)
    n, J, JH = sym.n, sym.J, sym.JH
    base = symbol_map(scene)

    mf = mass_force_block(sym, base) if mass_force else Block()
    rows, vals, heights, gammas = [list(r) for r in sym.A], list(sym.s), [], list(sym.gamma)
    heights = list(sym.f) + [se.Integer(0)] * (J - JH)
    speeds = set(sym.v) | set(getattr(sym, "qd", ()))

    def velocity_row(u):
        """A tangent given as the slip velocity u itself (linear in the speeds; q' of a model with
        generalized speeds taken as k(q, v, t)): the row du/dv, u, -du/dt with v' excluded."""
        if sym.general:
            u = u.xreplace({qd: k for qd, k in zip(sym.qd, sym.kin)})
        return [se.diff(u, v) for v in sym.v], u, -sym.rate(u)

    def row(g):
        if g.free_symbols & speeds:
            return velocity_row(g)
        if sym.general:  # w = dg/dq k + dg/dt in (q, v, t); the row in v: dw/dv
            w = sum((se.diff(g, q) * k for q, k in zip(sym.q, sym.kin)), se.Integer(0)) + se.diff(g, sym.t)
            return [se.diff(w, v) for v in sym.v], w, -sym.rate(w)
        G = [se.diff(g, q) for q in sym.q]
        w = sum((a * v for a, v in zip(G, sym.v)), se.Integer(0)) + se.diff(g, sym.t)
        d = se.diff(w, sym.t)
        for q, v in zip(sym.q, sym.v):
            d = d + se.diff(w, q) * v
        return G, w, -d

    tangent_of = []
    for k in system.contacts:
        g = to_se(system.inequalities[k], f"inequality constraint {k}")
        G, w, gam = row(g)
        rows.append(G)
        vals.append(w)
        heights.append(g)
        gammas.append(gam)
    for i, k in enumerate(system.contacts):
        tangent = system.tangents[k]
        if tangent is None:
            continue
        for d, tg in enumerate(tangent if isinstance(tangent, tuple) else (tangent,)):
            G, w, gam = row(to_se(tg, f"inequality constraint {k}, tangent {d}"))
            rows.append(G)
            vals.append(w)
            heights.append(se.Integer(0))
            gammas.append(gam)
            tangent_of.append(i)
    targets, exprs = [], []
    for r, row in enumerate(rows):
        for i in range(n):
            targets.append(("R", r, i))
            exprs.append(row[i])
        targets += [("s", r), ("h", r), ("gam", r)]
        exprs += [vals[r], heights[r], gammas[r]]
    return {"mf": mf, "mf_program": mass_force_program(sym, base) if mass_force else Block(), "rows": Block(targets, block_substituter(sym, base)(exprs)), "tangent_of": tangent_of}


#: Languages of the generated constrained code (the native drivers are C in both cases).


# ---------------------------------------------------------------------- public API
