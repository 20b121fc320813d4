"""Forward sensitivities on the Taylor integrator: the C code of the variational jet
(:mod:`.variational`) built on first use per set of directions, and its runs by the Taylor
runtime's driver.

The generated code (``<prefix>_taylor_var.c``, template taylor/jet_var.c.j2) is specific to the
set of directions and is built only when sensitivities are asked for: a scene's Taylor code
without them is unchanged. It presents the augmented system to the model-independent Taylor
driver through the same table (``lcg_taylor_model``: ny (1 + ns) states, nout (1 + ns)
outputs: the outputs, then d out / d theta_j = (d out/dy) s_j + d out/dp), so a run is one
call of ``lcg_taylor_solve``.

Directions: a run-time parameter by its name, ``"<q>(0)"``, ``"<q>_dot(0)"`` (parsed as on
CVODE). A model with generalized speeds (y = (q, v, z), q' = k(q, v, t): quaternion joints, Kane's
speeds) takes CVODE's directions too: any state's initial value by its name and the rotations
``"<joint>_rx(0)"`` .. of a quaternion joint, whose s0 (the quaternion's rates of the unit speed
about the axis) is formed at each run's initial state as CVODE forms it; its variational jet
carries the tangent of the kinematics, s_q' = dk (:mod:`.variational`).

Events: the jet of a set of events carries the event functions' rows of the states' jet in its
table, so the driver locates them on the state part of the augmented run as on a plain
run (the same rows, one order more of the operations), stores the augmented state at each
event, and a terminal one ends the run; each record then gets its time's sensitivities from the
event functions' derivatives (:mod:`lagcodegen.solvers.event_sensitivity`, as on CVODE), and a
terminal event's state and its sensitivities s(t_e) are the run's last row.

Error control (``errcon``, CVODES's errconS; default on): the sensitivities take part
in the step-size rule with the states' tolerances (w_i = atol_i + rtol |s_i|); off, their
weights are infinite, the steps are those of the states alone and the sensitivities are only
as accurate as those steps make them.
"""

from __future__ import annotations

import ctypes
from dataclasses import dataclass
import time

import numpy as np
import symengine as se

# --- the rest of lagcodegen: the one place to repoint when modules move -------------------
from ...build import plain_library
from ...codegen.c import c_expr, print_block
from ...codegen.record import header_context, new_code
from ...errors import LagcodegenError, ModelError
from ...formulation.kernels import Block, substituter
from ...formulation.scene import Scene
from ...result import Result
from ...version import __version__
from ..control import CANCELLED, POLL_EVERY, install, raise_pending
from ..event_sensitivity import event_gradients, event_records
# ------------------------------------------------------------------------------------------
from .decompose import Decomposition, decompose
from .emit import CHUNK, P_MAX, _EventInfo, _jinja, check_events
from .runner import events_struct, message, run_stats, taylor_runtime
from .schedule import GROUP, item_count, schedule
from .variational import VariationalDecomposition, _is_row, variational


@dataclass(frozen=True)
class _Direction:
    name: str
    base: int        # first row of its sensitivity of y
    sacc: int        # first row of its s''
    R: list
    dz: list
    dkin: list | None = None  # generalized speeds: the tangents of the coordinates' rates


def _outputs_block(scene: Scene, directions: list[tuple[str, int]], ny: int) -> tuple[Block, int]:
    """The outputs and their sensitivities d out/d theta_j = (d out/dy) s_j + d out/dp (theta_j a
    parameter): ``out[k]``, then ``out[nout (1 + j) + k]``."""
    c = substituter(scene)
    outs = [c(se.sympify(o.expr)) for o in scene.output_list()]
    nout = len(outs)
    ys = [se.Symbol(f"y[{i}]") for i in range(ny)]
    targets, exprs = [("out", k) for k in range(nout)], list(outs)
    for j, (kind, index) in enumerate(directions):
        s = [se.Symbol(f"y[{ny * (1 + j) + i}]") for i in range(ny)]
        for k, o in enumerate(outs):
            e = sum((se.diff(o, ys[i]) * s[i] for i in range(ny) if o.has(ys[i])), se.Integer(0))
            if kind == "param":
                e = e + se.diff(o, se.Symbol(f"p[{index}]"))
            if e.atoms(se.Derivative, se.Subs):
                raise ModelError(f"sensitivities of output {scene.output_list()[k].name!r} need derivatives "
                                 "symengine cannot take in closed form")
            targets.append(("out", nout * (1 + j) + k))
            exprs.append(e)
    return Block(targets, exprs), nout * (1 + len(directions))


def _chunks(items: list) -> list[list]:
    """``items`` (operations, :class:`.schedule.Fused` groups) split into runs of at most CHUNK
    operations, each printed as a function of its own."""
    out: list[list] = []
    size = CHUNK
    for item in items:
        if size + item_count(item) > CHUNK:
            out.append([])
            size = 0
        out[-1].append(item)
        size += item_count(item)
    return out


def _sconv_groups(conv_rows: list, ns: int) -> list[list]:
    """The sums sum_{j=1..k} M_[j] s''_[k-j] of every direction and row as loops of up to GROUP
    products: groups of units (direction, row i, its terms [(M row, column)], first
    accumulator)."""
    groups: list[list] = []
    size = GROUP
    for jd in range(ns):
        for i, terms in conv_rows:
            if size + len(terms) > GROUP and size:
                groups.append([])
                size = 0
            groups[-1].append((jd, i, terms, size))
            size += len(terms)
    return groups


def variational_sources(scene: Scene, directions: list[tuple[str, int]], names: list[str],
                        decomposition: Decomposition | None = None,
                        events=()) -> tuple[dict[str, str], VariationalDecomposition]:
    """``{"<prefix>_taylor_var.c": ..., "lcg_taylor_model.h": ...}``: the jet of the states and
    of their sensitivities along ``directions`` (named ``names``) with its table
    ``<prefix>_taylor_var_model``; and the :class:`VariationalDecomposition` it prints. With the
    checked ``events``, the table has their rows (without: the same text as before events
    existed here)."""
    d = decomposition or decompose(scene, events)
    v = variational(d, directions)
    n, ny0, ns = d.n, d.ny, v.ns
    M = v.M
    conv = [(i, M[i][j], j) for i in range(n) for j in range(n) if _is_row(M[i][j])]
    conv_rows = [(i, [(mm, j) for i2, mm, j in conv if i2 == i]) for i in range(n) if any(cc[0] == i for cc in conv)]
    block, nout = _outputs_block(scene, directions, ny0)
    tangent = frozenset(range(ny0, ny0 * (1 + ns))) | frozenset(r for rows in v.sacc for r in rows)
    ops = v.ops_a + v.ops_b
    kinds = {op.kind for op in ops}
    ctx = header_context(scene, new_code(scene))
    # the table's nq counts the speeds and nz the states beyond 2 nv (lcg_taylor_model.h): with
    # generalized speeds the coordinates beyond the speeds count there (as the plain jet's table)
    ctx.update(
        n=n, ny0=ny0, ny=ny0 * (1 + ns), ns=ns, nq=n * (1 + ns), nz=(ny0 - 2 * n) * (1 + ns), nout=nout,
        nrows=v.nrows, kin=v.kin,
        p_max=P_MAX, acc=v.acc, np=len(scene.runtime_parameters), nbase=len(d.ops),
        outputs_block=print_block(block) if nout else "",
        ops_a=v.ops_a, ops_b=v.ops_b,
        chunks=_chunks(v.ops_a[:len(d.ops)]) + _chunks(schedule(v.ops_a[len(d.ops):], tangent)),
        chunks_b=_chunks(schedule(v.ops_b, tangent)),
        sconv_groups=_sconv_groups(conv_rows, ns),
        helpers_inline=-(-len(v.ops_a) // CHUNK) - (-len(v.ops_b) // CHUNK) <= 2,
        kinds=kinds, labels=v.labels, consts=v.consts,
        const_lines=[f"c[{k}] = {c_expr(e)};" for k, e in enumerate(v.consts)],
        M=M, F=v.F, rates=v.rates, conv=conv, conv_rows=conv_rows, time_row=v.time_row,
        mass_constant=d.constant_mass, mass_diagonal=d.diagonal_mass, direction_names=names,
        dirs=[_Direction(names[j], ny0 * (1 + j), v.sacc[j][0], v.R[j], v.dz[j], v.dkin[j] if v.kin is not None
                         else None) for j in range(ns)],
        events=[_EventInfo(ev.name, row, int(ev.direction), int(bool(ev.terminal)))
                for row, ev in zip(v.events, events)])
    env = _jinja()
    header = env.get_template("taylor/lcg_taylor_model.h.j2").render(version=__version__, p_max=P_MAX)
    files = {"lcg_taylor_model.h": header,
             f"{scene.prefix}_taylor_var.c": env.get_template("taylor/jet_var.c.j2").render(**ctx)}
    return files, v


# ------------------------------------------------------------------ build and run


class VariationalModule:
    """The compiled jet of a scene's states and sensitivities along a set of directions (and with
    a set of checked events: their rows in its table), run by the Taylor runtime's driver. Not
    reentrant (its options struct is reused)."""

    def __init__(self, cm, scene: Scene, names: list[str], directions: list[tuple[str, int]], s0: np.ndarray,
                 cc: str | None = None, verbose: bool = False, events=()):
        code = cm.code
        self.names, self.directions, self.s0 = list(names), list(directions), s0
        from ..cvode.sensitivity import rotation_directions
        self.cm = cm  # a rotation's s0 is formed from its rhs at each run's initial state
        self.rotations = rotation_directions(cm, self.names)
        self.events = list(events)
        self.which = np.array([index if kind == "param" else -1 for kind, index in self.directions], dtype=int)
        self.state_names, self.output_names = list(code.state_names), list(code.output_names)
        self.n, self.ny, self.nout, self.ns = code.n, code.ny, code.nout, len(names)
        files, self.decomposition = variational_sources(scene, directions, self.names, events=self.events)
        # the event functions' derivatives for the event times' sensitivities, built with the jet
        self.gradients = event_gradients(cm, scene, self.events) if self.events else None
        rt = self.rt = taylor_runtime(cc)
        self.library, self.path, _ = plain_library(f"the Taylor sensitivities of model {code.model_name!r}",
                                                   f"{scene.prefix}_taylor_var", files, cc, verbose=verbose)
        getter = getattr(self.library, f"{scene.prefix}_taylor_var_table")
        getter.restype = ctypes.c_void_p
        self.table = rt.ffi.cast("const lcg_taylor_model *", getter())
        nyv = self.ny * (1 + self.ns)
        if (self.table.ny, self.table.nout, self.table.ne, self.table.nrows) != (
                nyv, self.nout * (1 + self.ns), len(self.events), self.decomposition.nrows):
            raise LagcodegenError(f"the Taylor sensitivity library of model {code.model_name!r} ({self.path}) has "
                                  "another layout than its code")
        self.opt = rt.ffi.new("lcg_taylor_options *")
        self.opt.poll = install(rt)
        self.opt.poll_every = POLL_EVERY

    def initial_sensitivities(self, y0, t0: float, p) -> np.ndarray:
        """s(t0), (ns, ny), of a run from ``y0`` at ``t0`` with the parameters ``p``: the
        directions' s0 (unit vectors for initial values, zeros for parameters), and for a rotation
        of a quaternion joint (generalized speeds) the quaternion's rates of the unit speed about its
        axis at ``y0``, formed as CVODE forms them
        (:func:`lagcodegen.solvers.cvode.sensitivity.general_directions`)."""
        if not self.rotations:
            return self.s0
        from ..cvode.sensitivity import directions
        return directions(self.cm, self.names, np.asarray(y0, dtype=float), float(t0),
                          np.asarray(p, dtype=float))[2]

    def tolerances(self, atol, errcon: bool) -> np.ndarray:
        """The absolute tolerances of the augmented system: the states' ``atol`` (scalar or ny
        values), then for each direction the same (``errcon``) or infinite (the sensitivities out
        of the step-size rule)."""
        ny = self.ny
        atol = np.broadcast_to(np.asarray(atol, dtype=float), (ny,))
        return np.ascontiguousarray(np.concatenate([atol] + [atol if errcon else np.full(ny, np.inf)] * self.ns))

    def simulate(self, t: np.ndarray, y0: np.ndarray, p: np.ndarray, *, rtol: float, atol, errcon: bool = True,
                 max_step: float = 0.0, max_steps: int = 1_000_000, order: int | None = None,
                 max_wall: float = 0.0, max_events: int = 10_000) -> Result:
        """The trajectory and its sensitivities at ``t`` from y(t[0]) = ``y0``: a Result whose
        ``sensitivities`` (nt, ns, ny + nout) hold d(state or output)/d(direction); with events,
        ``events`` (at most ``max_events`` kept) with their times' sensitivities, a terminal one
        the last row (module docstring)."""
        ny = self.ny
        atol_all = self.tolerances(atol, errcon)
        atol = atol_all[:ny]
        opt, fb = self.opt, self.rt.ffi.from_buffer
        opt.rtol = rtol
        opt.atol = float(atol.min())
        opt.atol_vec = fb("double[]", atol_all)
        opt.max_steps = int(max_steps)
        opt.max_step = float(max_step)
        opt.order = int(order or 0)
        opt.rel_block = ny  # each direction's sensitivities: one block of the step-size rule
        opt.max_wall = float(max_wall)
        return self.solve(opt, t, y0, p, max_events=max_events)

    def new_options(self, *, rtol: float, atol, errcon: bool, max_step: float, max_steps: int,
                    order: int | None, max_wall: float):
        """A new options struct for :meth:`solve` with the values :meth:`simulate` sets, and the
        array its atol_vec points into (keep both alive while it is used)."""
        atol_all = self.tolerances(atol, errcon)
        opt = self.rt.ffi.new("lcg_taylor_options *")
        opt.poll = self.opt.poll
        opt.poll_every = POLL_EVERY
        opt.rtol = rtol
        opt.atol = float(atol_all[:self.ny].min())
        opt.atol_vec = self.rt.ffi.from_buffer("double[]", atol_all)
        opt.max_steps = int(max_steps)
        opt.max_step = float(max_step)
        opt.order = int(order or 0)
        opt.rel_block = self.ny  # each direction's sensitivities: one block of the step-size rule
        opt.max_wall = float(max_wall)
        return opt, atol_all

    def solve(self, opt, t: np.ndarray, y0: np.ndarray, p: np.ndarray, *, max_events: int = 10_000,
              s0: np.ndarray | None = None) -> Result:
        """:meth:`simulate` with the options struct ``opt`` made by the caller (kept alive with the
        array its atol_vec points into): reentrant (its own statistics and events structs), for
        the members of an ensemble. ``s0``: the sensitivities at t[0], (ns, ny) (default: those of
        the directions at the start of a run)."""
        ffi, lib = self.rt.ffi, self.rt.lib
        ny, ns, nout = self.ny, self.ns, self.nout
        nyv = ny * (1 + ns)
        s_start = self.initial_sensitivities(y0, t[0], p) if s0 is None else s0
        y0v = np.ascontiguousarray(np.concatenate([np.asarray(y0, dtype=float),
                                                   np.asarray(s_start, dtype=float).ravel()]))
        nt = t.shape[0]
        yout = np.empty((nt, nyv))
        out = np.empty((nt, max(nout * (1 + ns), 1)))
        st, fb = ffi.new("lcg_taylor_stats *"), ffi.from_buffer
        p = np.ascontiguousarray(p, dtype=float)
        ev, keep = self._events_struct(max_events) if self.events else (ffi.NULL, None)
        start = time.perf_counter()
        flag = lib.lcg_taylor_solve(self.table, fb("double[]", p) if p.size else ffi.NULL, fb("double[]", y0v), nt,
                                    fb("double[]", np.ascontiguousarray(t)), fb("double[]", yout),
                                    fb("double[]", out), opt, st, ev)
        wall = time.perf_counter() - start
        if flag == CANCELLED:
            raise_pending()
        stats = sens_stats(st, wall)
        done = min(int(st.nt_done), nt)
        sl = slice(0, done)
        res = Result(t=t[sl].copy(), y=yout[sl, :ny].copy(), state_names=self.state_names,
                     outputs={name: out[sl, i].copy() for i, name in enumerate(self.output_names)}, stats=stats,
                     status=flag, message="success" if flag == 0 else message(
                         flag, st.model_error, ffi.string(st.message).decode(errors="replace")),
                     backend="native", method="taylor", n_coordinates=self.n)
        s = yout[sl, ny:].reshape(done, ns, ny)
        ds = out[sl, nout:nout * (1 + ns)].reshape(done, ns, nout)
        res.set_sensitivities(self.names, self.state_names + self.output_names, np.concatenate([s, ds], axis=2))
        if keep is not None:
            self._events_into(res, ev, keep, p)
        return res

    def _events_struct(self, max_events: int):
        """A new ``lcg_taylor_events`` for ``max_events`` events of the augmented state, and the
        arrays it points into (times, rows (y, s), event indices, directions)."""
        return events_struct(self.rt.ffi, "lcg_taylor_events *", max_events, self.ny * (1 + self.ns))

    def _ydot(self, t: float, row: np.ndarray, p: np.ndarray) -> np.ndarray:
        """y'(t) of the states from the first-order coefficients of the jet at the augmented state
        ``row``."""
        ffi = self.rt.ffi
        fb = ffi.from_buffer
        nyv = self.ny * (1 + self.ns)
        jet = np.empty((nyv, 2))
        rc = self.rt.lib.lcg_taylor_jet(self.table, float(t), fb("double[]", np.ascontiguousarray(row)),
                                        fb("double[]", p) if p.size else ffi.NULL, 1, fb("double[]", jet))
        if rc:
            return np.full(self.ny, np.nan)
        return jet[:self.ny, 1].copy()

    def records(self, p: np.ndarray, times, rows, kinds, directions) -> list:
        """The records of the events the driver stored (event ``kinds[e]`` at ``times[e]``, crossing
        in ``directions[e]``, the augmented state ``rows[e]``), each with its time's and state's
        sensitivities (:func:`lagcodegen.solvers.event_sensitivity.event_records`)."""
        return event_records(self.gradients, self.events, self.state_names, self.names, self.which, p, times, rows,
                             kinds, directions, lambda t, row: self._ydot(t, row, p))

    def _events_into(self, res: Result, ev, keep, p: np.ndarray) -> None:
        """The events of a run into ``res`` (``events`` with their times' sensitivities,
        ``stats["events"]``, ``stats["terminated"]``); a terminal event's state, outputs and their
        sensitivities appended as the last row."""
        count = min(int(ev.n_events), keep[0].shape[0])
        times, rows = keep[0][:count], keep[1][:count]
        res.events = self.records(p, times, rows, keep[2][:count], keep[3][:count])
        res.stats["events"] = int(ev.n_events)
        res.stats["terminated"] = int(ev.terminated)
        if not (ev.terminated and res.events and (res.t.size == 0 or res.events[-1].t > res.t[-1])):
            return
        ny, ns, nout = self.ny, self.ns, self.nout
        te, row = float(times[-1]), np.ascontiguousarray(rows[-1])
        out = np.full(max(nout * (1 + ns), 1), np.nan)
        if nout:
            ffi = self.rt.ffi
            fb = ffi.from_buffer
            self.table.outputs(te, fb("double[]", row), fb("double[]", p) if p.size else ffi.NULL,
                               fb("double[]", out))
        res.t = np.append(res.t, te)
        res.y = np.vstack([res.y, row[None, :ny]])
        res.outputs = {name: np.append(v, out[i]) for i, (name, v) in enumerate(res.outputs.items())}
        last = np.concatenate([row[ny:].reshape(ns, ny), out[nout:nout * (1 + ns)].reshape(ns, nout)], axis=1)
        res.sensitivities = np.concatenate([res.sensitivities, last[None]])


def sens_stats(st, wall: float) -> dict:
    """Result.stats of a Taylor sensitivity run from its statistics struct ``st`` and its wall
    time: those of a plain run (:func:`.runner.run_stats`)."""
    return {**run_stats(st), "wall_time": wall}


def directions_of(cm, names) -> tuple[list[str], list[tuple[str, int]], np.ndarray]:
    """(names, directions, s0) of the sensitivity directions ``names`` (run-time parameters,
    ``"<q>(0)"``, ``"<q>_dot(0)"``; parsed as on CVODE, the same names and errors). Every Taylor
    sensitivity run passes here. A model with generalized speeds takes CVODE's directions
    (:func:`lagcodegen.solvers.cvode.sensitivity.general_directions`: any state's initial value by
    its name, and the rotations ``"<joint>_rx(0)"`` .. of a quaternion joint, ("state", -1) here):
    a rotation's s0 depends on the initial state, so it is left zero here and formed per run
    (:meth:`VariationalModule.initial_sensitivities`, as CVODE forms it)."""
    from ..cvode.sensitivity import directions
    names, which, s0 = directions(cm, names, defer=True)
    dirs = [("param", int(k)) if k >= 0 else ("state", int(np.argmax(s0[j])) if s0[j].any() else -1)
            for j, k in enumerate(which)]
    return names, dirs, s0


def _checked_events(cm, scene: Scene, events) -> tuple:
    """``events`` checked (:func:`.emit.check_events`), once per compiled model and events as
    given (checking takes sympy milliseconds, a run with events tens of microseconds)."""
    try:
        given = ("taylor-sensitivity events given", tuple(events))
        found = cm.artifacts.find(tuple, given)
    except TypeError:  # unhashable items (dicts, lists): checked every time
        given, found = None, None
    if found is None:
        found = tuple(check_events(scene, events))
        if given is not None:
            cm.artifacts.keep(tuple, given, found)
    return found


def variational_module(cm, scene: Scene, names, events=()) -> VariationalModule:
    """The compiled variational jet of ``cm`` along ``names`` with ``events`` (checked here:
    ModelError naming a bad one; built once per set of directions and events, then kept with the
    compiled model)."""
    names, dirs, s0 = directions_of(cm, names)
    events = _checked_events(cm, scene, events) if events else ()
    key = (tuple(names),) + ((events,) if events else ())
    return cm.artifacts.get(VariationalModule, key, lambda: VariationalModule(cm, scene, names, dirs, s0,
                                                                              events=events))
