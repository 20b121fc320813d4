"""The Taylor jet of a constrained system with contacts (``simulate(method="taylor")`` of a system
whose :class:`~lagcodegen.theory.constraints.Inequality` constraints have a restitution): the
index-1 system of the rows held

    [M R^T; R 0] [q''; -lambda] = [F; gamma - stab]

(the equality rows always, each contact and its no-slip tangential rows while the contact is in
persistent contact; stab = 2 alpha s + beta^2 h for holonomic rows and contacts, alpha s for the
others, as the generated ``<prefix>_imp_crhs``) differentiated order by order, for every active
set at once: the rows held are run-time values of the jet's workspace (set by the table's
``hold``), and a row not held reads lambda_[k] = 0. Per order k the same recurrence as the mass
matrix's,

    K_[0] (q''_[k], -lambda_[k]) = (F_[k], (gamma - stab)_[k]) - sum_{j=1..k} K_[j] (q''_[k-j], -lambda_[k-j]),

with K_[0] = [M_[0] R_[0]^T; R_[0] 0] over the rows held factored once per jet by LU with partial
pivoting (a small regularization -eps of the multipliers' block when the rows held are dependent,
as ``solve_active`` of ``<prefix>_impact.c``). M, F and the rows' entries R, s, h, gamma (from
:func:`lagcodegen.formulation.constrained.impact_blocks`, the expressions of the contact code) are
decomposed into elementary operations by :mod:`.decompose`; the contacts' gaps g_k = h_(J+k) and
the multipliers are rows of the jet, whose polynomials the runtime's contact driver
(lagcodegen/runtime/lcg_taylor_imp.c) searches for impacts and releases.

The system's events (its compiled root functions) are rows of the jet too, their polynomials
searched by the driver, except those whose expression uses a multiplier (row -1: the driver
refuses a run that locates them). The file ``<prefix>_taylor_contact.c`` defines the jet's table
``lcg_taylor_model`` (no outputs, no events of its own: the constrained table's outputs and the
contact table's events are the driver's) and the contact table ``lcg_taylor_contact``
(lagcodegen/runtime/lcg_taylor_contact.h). With Coulomb friction it also exports
``<prefix>_taylor_contact_slip`` (tl_slip: after hold, the tangential rows of slipping contacts not
held, lambda_t = wc lambda_n with wc = -sigma mu, the normal's force column G + wc T; 3-D, slip 2:
lambda_t = -mu d lambda_n with d = u/|u| computed in the jet order by order from the tangential
rows' velocities); the stick/slip modes are the friction core's (lcg_imp_fric.c), driven by
lcg_taylor_imp.c.
"""

from __future__ import annotations

import dataclasses

import symengine as se

# --- the rest of lagcodegen: the one place to repoint when modules move -------------------
from ... import progress
from ...errors import ModelError
from ...formulation.constrained import impact_blocks
from ...formulation.kernels import symbol_map
from ...formulation.scene import Scene
from ...runtime import source as runtime_file
from ...version import __version__
from ..record import GeneratedCode, new_code
# ------------------------------------------------------------------------------------------
from .decompose import Decomposition, _assemble, _Decomposer, _where, fuse_products, group_by_atoms, \
    linearize_trig, scene_expressions
from .emit import CHUNK, P_MAX, _jinja, taylor_context


@dataclasses.dataclass
class ContactRows:
    """The rows of a constrained system with contacts in a jet: ``R[r][i]``, ``s[r]``, ``h[r]``,
    ``gam[r]`` (a row of the jet, a run constant or a number, as the entries of
    :class:`~.decompose.Decomposition`), ``nj`` equality rows (``njh`` holonomic), ``nk``
    contacts, the tangential rows after them (``tangent_of``: the contact of each)."""

    R: list
    s: list
    h: list
    gam: list
    nj: int
    njh: int
    nk: int
    tangent_of: list
    friction: bool = False  # a contact has Coulomb friction: the jet takes its slipping modes (tl_slip)
    events: list = dataclasses.field(default_factory=list)  # per event: its row, or -1 (uses a multiplier)

    @property
    def nr(self) -> int:
        return len(self.s)

    def holonomic(self, r: int) -> bool:
        """Whether row r is stabilized as a position (2 alpha s + beta^2 h) rather than a velocity."""
        return r < self.njh or self.nj <= r < self.nj + self.nk

    def contact_of(self, r: int) -> int:
        """The contact (0..nk-1) whose mode holds row r, or -1 (an equality row, always held)."""
        if r < self.nj:
            return -1
        if r < self.nj + self.nk:
            return r - self.nj
        return self.tangent_of[r - self.nj - self.nk]


def contact_decompose(system, scene: Scene, events=(), *,
                      form: str | None = None) -> tuple[Decomposition, ContactRows]:
    """The elementary operations of M, F and of the rows of ``system`` (compiled from ``scene``)
    and of its ``events`` (the constrained system's events, :func:`lagcodegen.model.events.event_list`;
    an event whose expression uses a multiplier gets no row: its value needs the solve of the same
    order): the cheaper of the derived and trig-linearized forms (``form`` to force one), products
    fused (:func:`~.decompose.fuse_products`)."""
    eom = scene.eom
    model = eom.model
    if eom.quadratures:
        raise ModelError("constrained systems with quadrature states are not supported")
    n = model.nv
    nq = model.nq if eom.general else None
    multipliers = {sp_symbol.name for sp_symbol in getattr(system, "multipliers", ())}
    jet_events = [ev for ev in events if not {str(x) for x in getattr(ev.expr, "free_symbols", ())} & multipliers]
    exprs, time_symbol, state = scene_expressions(scene, jet_events)
    blocks = impact_blocks(system, scene, mass_force=False)
    rows = blocks["rows"]
    for target, e in zip(rows.targets, rows.exprs):
        exprs[target] = se.sympify(e)
    nr = sum(1 for t in rows.targets if t[0] == "s")
    names = {v: se.Symbol(str(k)) for k, v in symbol_map(scene).items() if isinstance(v, se.Symbol)}
    nj = len(system.rows())
    njh = len(system.holonomic)
    nk = len(system.contacts)

    def where(loc):
        if loc[0] in ("R", "s", "h", "gam"):
            what = (f"equality row {loc[1]}" if loc[1] < nj else f"contact {system.contacts[loc[1] - nj]}"
                    if loc[1] < nj + nk else f"tangential row {loc[1] - nj - nk}")
            return f"the {dict(R='row', s='velocity', h='position', gam='acceleration term')[loc[0]]} of {what}"
        return _where(scene, loc, jet_events)

    best = None
    for f in ((form,) if form else ("derived", "trig-linearized")):
        d = _Decomposer(state, time_symbol, n, 0, nq)
        d.names = names
        entries = {}
        with progress.stage("taylor", total=len(exprs), unit=f"expressions, {f} form") as stage:
            for loc, e in exprs.items():
                d.where = where(loc)
                if f == "trig-linearized" and not d.is_const(e):
                    e = group_by_atoms(linearize_trig(e), d.varsyms)
                # the gaps and the events: rows of the jet, searched for roots
                rooted = (loc[0] == "h" and nj <= loc[1] < nj + nk) or loc[0] == "event"
                entries[loc] = d.row(e) if rooted else d.node(e)
                stage.advance()
        dec = _assemble(d, entries, n, 0, len(jet_events), nq, f)
        rows_of = iter(dec.events)
        crow = ContactRows(R=[[entries[("R", r, i)] for i in range(n)] for r in range(nr)],
                           s=[entries[("s", r)] for r in range(nr)], h=[entries[("h", r)] for r in range(nr)],
                           gam=[entries[("gam", r)] for r in range(nr)], nj=nj, njh=njh, nk=nk,
                           tangent_of=list(blocks["tangent_of"]), friction=bool(system.has_friction),
                           events=[next(rows_of) if ev in jet_events else -1 for ev in events])
        dec.cost += sum(1.0 for row in crow.R for e in row if isinstance(e, int))
        if best is None or dec.cost < best[0].cost:
            best = (dec, crow)
    dec, crow = best
    used = [e for row in crow.R for e in row] + crow.s + crow.h + crow.gam
    fused = _fuse_keeping(dec, used)
    return fused, crow


def _fuse_keeping(d: Decomposition, used: list) -> Decomposition:
    """:func:`~.decompose.fuse_products` with the rows' entries ``used`` counted as uses (a
    product that a row reads is not folded away)."""
    keep = list(d.events)
    d.events = keep + [e for e in used if isinstance(e, int) and not isinstance(e, bool)]
    out = fuse_products(d)
    out.events = keep
    return out


def contact_context(scene: Scene, d: Decomposition, rows: ContactRows) -> dict:
    """The template context of ``taylor/jet_contact.c.j2``."""
    ctx = taylor_context(scene, d, ())
    n = d.n
    mconv = [(i, d.M[i][j], j) for i in range(n) for j in range(n) if isinstance(d.M[i][j], int)]
    rconv = [(r, i, rows.R[r][i]) for r in range(rows.nr) for i in range(n) if isinstance(rows.R[r][i], int)]
    ctx.update(unrolled=None, table=True, nout=0, ne=0, event_rows=rows.events, nr=rows.nr, nj=rows.nj,
               njh=rows.njh, nk=rows.nk,
               R=rows.R, s=rows.s, h=rows.h, gam=rows.gam, holonomic=[rows.holonomic(r) for r in range(rows.nr)],
               contact_of=[rows.contact_of(r) for r in range(rows.nr)], mconv=mconv, rconv=rconv,
               gap_rows=[rows.h[rows.nj + k] for k in range(rows.nk)], lam_row=d.nrows, chunk_size=CHUNK,
               p_max=P_MAX, friction=rows.friction,
               normal_of=[rows.nj + rows.contact_of(r) if r >= rows.nj + rows.nk else -1 for r in range(rows.nr)])
    tangents: dict = {}
    for r in range(rows.nj + rows.nk, rows.nr):
        tangents.setdefault(rows.contact_of(r), []).append(r)
    # 3-D Coulomb friction (two tangential rows): d = u/|u| in the jet while the contact slips
    ctx["cones"] = [dict(t1=t[0], t2=t[1], nn=rows.nj + c, s1=rows.s[t[0]], s2=rows.s[t[1]], R1=rows.R[t[0]],
                         R2=rows.R[t[1]]) for c, t in sorted(tangents.items()) if rows.friction and len(t) == 2]
    return ctx


def contact_jet_sources(system, scene: Scene, *, decomposition: tuple | None = None,
                        events=()) -> dict[str, str]:
    """``<prefix>_taylor_contact.c`` (the jet of ``system``'s index-1 system of the rows held and its
    tables, libm only), ``lcg_taylor_model.h`` and ``lcg_taylor_contact.h``; ``decomposition``: the
    (:class:`~.decompose.Decomposition`, :class:`ContactRows`) pair of :func:`contact_decompose`
    (made here when None, with the system's ``events``)."""
    d, rows = decomposition or contact_decompose(system, scene, events)
    ctx = contact_context(scene, d, rows)
    env = _jinja()
    return {"lcg_taylor_model.h": env.get_template("taylor/lcg_taylor_model.h.j2").render(version=__version__,
                                                                                         p_max=P_MAX),
            "lcg_taylor_contact.h": runtime_file("lcg_taylor_contact.h"),
            f"{scene.prefix}_taylor_contact.c": env.get_template("taylor/jet_contact.c.j2").render(**ctx)}


def contact_jet_code(system, scene: Scene, events=()) -> tuple[GeneratedCode, Decomposition, ContactRows]:
    """The contact jet of ``system`` (compiled from ``scene``) with its ``events`` as a
    :class:`GeneratedCode` whose files are those of :func:`contact_jet_sources`, with its
    decomposition and rows."""
    d, rows = contact_decompose(system, scene, events)
    code = new_code(dataclasses.replace(scene, jacobian=False, sparse_jacobian=False))
    code.scene = scene
    code.files.update(contact_jet_sources(system, scene, decomposition=(d, rows)))
    return code, d, rows
