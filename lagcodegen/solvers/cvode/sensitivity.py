"""Forward sensitivities on CVODE: the model's sensitivity functions (``<prefix>_sens.c``,
:mod:`lagcodegen.codegen.sensitivity`) compiled on first use per compiled model, and one call of
the runtime's sensitivity driver (``lagcodegen/runtime/lcg_cvsens.c``: the augmented ODE with
the states' Newton matrix reused for every sensitivity block; CVODES's staggered corrector by
default, its simultaneous one on request: ``corrector``, :data:`CORRECTORS`).

Directions: a run-time parameter by its name, a coordinate's initial value ``"<q>(0)"``, its
initial velocity ``"<q>_dot(0)"`` (also ``"<state>(0)"`` for any state name). Error control on
the sensitivities (``errcon``, CVODES's errconS) is on by default: the sensitivities enter
CVODE's error test and Newton convergence test with the states' tolerances; off, they are left
out of the error test (weights ~1e-300) and are then only as accurate as the steps chosen for the
states (the staggered corrector still iterates them to its convergence test with the states'
tolerances; the simultaneous one leaves them out of that test too).
"""

from __future__ import annotations

import functools
import os
import time

import numpy as np

from ...build import DEFAULT_CFLAGS, driver_runtime, find_sundials
from ...codegen.cffi_decl import MODEL_TABLE_CDEF, POLL_CDEF, driver_cdef, header_cdef
from ...codegen.sensitivity import SENS_OUTPUTS, SENS_RHS
from ...errors import LagcodegenError
from ...libraries import sensitivity_library
from ...result import Result
from ...runtime import sources as runtime_files
from ..base import METHODS, message
from ..control import CANCELLED, POLL_EVERY, install, raise_pending
from ..direction import parse_all
from ..request import Recording, StepControl
from .sensitivity_events import SensEvents

#: The runtime files of the sensitivity driver.
FILES = ("lcg_cvsens.c", "lcg_cvsens.h", "lcg_model.h", "lcg_control.h", "lcg_sundials.h", "sundials_api.h",
         "lcg_inputs.h", "lcg_inputs.c")
#: The C files a unit that includes lcg_cvsens.c (the stepper, lcg_cvsens_stepper.c) compiles beside it.
LINKED_UNITS = ("lcg_inputs.c",)

#: The driver module's interface: the model table and the input tables' structs, then lcg_cvsens.h
#: as it is (the sensitivity functions' types, the options, statistics and events structs, the
#: solve functions), the poll callback.
CDEF = "\n".join([MODEL_TABLE_CDEF, driver_cdef("inputs"), header_cdef("lcg_cvsens.h"), POLL_CDEF])

#: The statistics of a sensitivity run: keys of Result.stats (those of the plain runs where they
#: count the same) -> fields of lcg_cvsens_stats.
STATS = {"steps": "nsteps", "rhs_evals": "nrhs", "lin_setups": "nlinsetups", "err_test_fails": "netfails",
         "nonlin_iters": "nniters", "nonlin_conv_fails": "nncfails", "jac_evals": "njac", "factorizations": "nfactor",
         "block_solves": "nblock_solves", "rhs_evals_states": "nrhs_states", "sens_iters": "nsens_iters",
         "h_last": "h_last", "t_reached": "t_reached", "model_error": "model_error"}


def sens_stats(st) -> dict:
    """Result.stats of a sensitivity run from its statistics struct ``st`` (:data:`STATS`)."""
    return {key: getattr(st, field) for key, field in STATS.items()}


def _sources() -> dict[str, str]:
    from ...build import config_header, generated_headers, types_headers
    return {**runtime_files(FILES), "lcg_config.h": config_header(find_sundials()), **generated_headers(),
            **types_headers(("inputs",))}


@functools.lru_cache(maxsize=4)
def _runtime(cc: str, cflags: tuple[str, ...]):
    sundials = find_sundials()
    texts = [f"{k}\0{v}" for k, v in sorted(_sources().items())]
    return driver_runtime("cvsens", texts, _sources, CDEF, "lcg_cvsens.h",
                          [*sundials.link_args(("cvode", "core")), "-lm"], cc, cflags)


def sens_runtime(cc: str | None = None, cflags: tuple[str, ...] = DEFAULT_CFLAGS):
    """The sensitivity driver's cffi module (``lcg_cvsens_solve``), built once per installation."""
    return _runtime(cc or os.environ.get("CC") or "cc", tuple(cflags))


class SensitivityFunctions:
    """The compiled ``<prefix>_sens_rhs`` and ``<prefix>_sens_outputs`` of a compiled model, as
    function pointers of the driver's module (``rt``); ``library`` keeps the library open."""

    def __init__(self, cm):
        code = cm.code
        if cm.table is None:
            raise LagcodegenError("sensitivities need a compiled model of a scene on the native runtime "
                                  "(compile_model(...), native build)")
        prefix = code.prefix
        built = sensitivity_library(code)  # asked of the build stage
        self.library, self.path = built.handle, built.path
        self.rt = sens_runtime()
        self.poll = install(self.rt)  # Ctrl-C during a run
        ffi = self.rt.ffi
        self.rhs = ffi.cast("lcg_sens_rhs_fn", built.address("rhs"))
        self.out = ffi.cast("lcg_sens_out_fn", built.address("outputs"))
        table_address = int(cm.ffi.cast("uintptr_t", cm.table))
        self.table = ffi.cast("const lcg_model *", table_address)
        self.prototypes = (SENS_RHS.format(prefix=prefix), SENS_OUTPUTS.format(prefix=prefix))


def functions(cm) -> SensitivityFunctions:
    """The sensitivity functions of ``cm``, built on first use (kept in ``cm.artifacts``)."""
    return cm.artifacts.get(SensitivityFunctions, "ode", lambda: SensitivityFunctions(cm))


def directions(cm, names, y0=None, t0: float = 0.0, p=None, defer: bool = False
               ) -> tuple[list[str], np.ndarray, np.ndarray]:
    """(names, which, s0) of the directions ``names``: which[j] the run-time parameter index
    (-1 for an initial value), s0 (ns, ny) the initial sensitivities (unit vectors for initial
    values, zero for parameters). Unknown or repeated names raise LagcodegenError. A model with
    generalized speeds: :func:`general_directions` (a rotation direction needs the initial state
    ``y0`` at ``t0`` with the parameters ``p``, unless ``defer``: the caller fills it in per run,
    or uses only the names and which)."""
    if getattr(cm.code, "nv", None) is not None:
        return general_directions(cm, names, y0, t0, p, defer)
    return parse_directions(names, params=list(cm.param_names), states=list(cm.state_names), n=cm.n, ny=cm.ny,
                            folded=getattr(cm.code, "folded", {}) or {}, listed_in="the scene's runtime_parameters")


def rotation_directions(cm, names) -> bool:
    """True if ``names`` (parsed) hold a rotation of a quaternion (:func:`general_directions`),
    whose s0 depends on the initial state."""
    if getattr(cm.code, "nv", None) is None:
        return False
    states = list(cm.state_names)
    return any(nm.endswith("(0)") and nm[-6:-3] in ("_rx", "_ry", "_rz") and nm[:-3] not in states
               for nm in names)


def _quaternion_joint(base: str, states: list) -> str | None:
    """The joint whose unit quaternion (Pinocchio's layout: <joint>_qx .. _qw, speeds <joint>_wx ..)
    ``base`` is one component of, or None."""
    joint, _, comp = base.rpartition("_")
    if comp in ("qx", "qy", "qz", "qw") and f"{joint}_qw" in states and f"{joint}_wx" in states:
        return joint
    return None


def general_directions(cm, names, y0=None, t0: float = 0.0, p=None, defer: bool = False
                       ) -> tuple[list[str], np.ndarray, np.ndarray]:
    """The directions of a model with generalized speeds, y = (q, v, z): a run-time parameter;
    the initial value ``"<state>(0)"`` of any state by its name (a coordinate, a speed such as
    ``"ball_wx(0)"`` or ``"elbow_dot(0)"``, a quadrature); and for a joint with a unit quaternion
    (``<joint>_qx`` .. ``_qw``) the rotations ``"<joint>_rx(0)"``, ``_ry``, ``_rz``: the
    quaternion turned by d(theta) about the axis of its speed ``<joint>_w<axis>`` (s0 = dq/d(theta)
    = the kinematic rates k(q0, e) of the unit speed e, Pinocchio's q x exp(e theta / 2) for its
    joints, whose angular speeds are in the body's frame). A single quaternion component is
    refused by name: its perturbation leaves the unit sphere that the kinematics keep. Without
    ``y0`` a rotation's s0 is left zero with ``defer`` (to be filled in once the initial state is
    known), else refused."""
    states = list(cm.state_names)
    params = list(cm.param_names)
    folded = getattr(cm.code, "folded", {}) or {}
    nq, nv = cm.code.n, cm.code.nv
    if isinstance(names, str):
        names = [names]
    names = list(names)
    if not names:
        raise LagcodegenError("sensitivities: give at least one parameter or initial value")
    which, s0 = [], np.zeros((len(names), cm.ny))
    for j, name in enumerate(names):
        if not isinstance(name, str):
            raise LagcodegenError(f"sensitivities: {name!r:.80} is not a name")
        if names.index(name) != j:
            raise LagcodegenError(f"sensitivities: {name!r:.80} is given twice")
        if name in params:
            which.append(params.index(name))
            continue
        if name in folded:
            raise LagcodegenError(f"sensitivities: parameter {name!r:.80} is folded into the code as a constant; "
                                  "list it in the scene's runtime_parameters")
        base = name[:-3] if name.endswith("(0)") else None
        joint = _quaternion_joint(base, states) if base else None
        if joint is not None:
            raise LagcodegenError(
                f"sensitivities: {name!r} perturbs one component of the unit quaternion of joint {joint!r}, which "
                f"leaves the unit sphere the kinematics keep; give a rotation of the joint instead: "
                f"'{joint}_rx(0)', '{joint}_ry(0)', '{joint}_rz(0)' (about the axes of its speeds {joint}_wx ..)")
        which.append(-1)
        if base in states:
            s0[j, states.index(base)] = 1.0
            continue
        joint, _, axis = (base or "").rpartition("_")
        if axis in ("rx", "ry", "rz") and f"{joint}_qw" in states and f"{joint}_w{axis[1]}" in states:
            if y0 is None:
                if defer:  # filled in per run (PreparedSensitivities) or not needed (names only)
                    continue
                raise LagcodegenError(f"sensitivities: the rotation direction {name!r} depends on the initial "
                                      "state, which this kind of run does not give it: use simulate(...)")
            y = np.array(y0, dtype=float)
            y[nq:nq + nv] = 0.0
            base_rates = cm.rhs(t0, y, p)[:nq]
            y[states.index(f"{joint}_w{axis[1]}")] = 1.0
            s0[j, :nq] = cm.rhs(t0, y, p)[:nq] - base_rates  # k(q0, e) - k(q0, 0): linear in the speeds
            continue
        quaternions = sorted({b for s in states if (b := _quaternion_joint(s, states))})
        rotations = "; rotations: " + ", ".join(f"'{b}_rx(0)'" for b in quaternions) + " .." if quaternions else ""
        raise LagcodegenError(f"sensitivities: {name!r:.80} is neither a run-time parameter ({', '.join(params) or 'none'}) "
                              f"nor an initial value '<state>(0)' (states: {', '.join(states)}{rotations})")
    return names, np.array(which, dtype=np.intc), s0


def parse_directions(names, *, params: list, states: list, n: int, ny: int, folded, listed_in: str
                     ) -> tuple[list[str], np.ndarray, np.ndarray]:
    """(names, which, s0) of the directions ``names`` among the run-time parameters ``params``
    and the initial values of ``states`` (the first n the coordinates, whose velocities follow
    them in y; s0 has ny columns); a name in ``folded`` is refused as a constant of the code, to
    be listed in ``listed_in``. Shared by the ODE and the constrained formulations."""
    coords = states[:n]
    dirs = parse_all(names, params=params, coords=coords, states=states, folded=folded, listed_in=listed_in)
    which, s0 = [], np.zeros((len(dirs), ny))
    for j, d in enumerate(dirs):
        if d.kind == "parameter":
            which.append(params.index(d.target))
        else:
            which.append(-1)
            s0[j, d.state_index(coords, states)] = 1.0
    names = [d.name for d in dirs]
    return names, np.array(which, dtype=np.intc), s0


#: The driver's correctors (lcg_cvsens.h: LCG_CVSENS_STAGGERED, LCG_CVSENS_SIMULTANEOUS).
CORRECTORS = {"staggered": 0, "simultaneous": 1}


def sens_options(ffi, poll, control: StepControl, ny: int, ns: int):
    """(the driver's ``lcg_cvsens_options`` struct made by ``ffi`` with the Ctrl-C ``poll``
    function, the tolerance array it points to: keep it alive with the struct) of the step
    control ``control``: the states' absolute tolerances ``control.atol`` (scalar or ny values)
    repeated for each of the ns directions, or effectively none for them without
    ``control.errcon``; ``control.corrector`` one of :data:`CORRECTORS`."""
    corrector, errcon = control.corrector, control.errcon
    if corrector not in CORRECTORS:
        raise LagcodegenError(f"sensitivity_corrector must be one of {', '.join(map(repr, CORRECTORS))}, "
                              f"not {corrector!r}")
    atol = np.broadcast_to(np.asarray(control.atol, dtype=float), (ny,))
    if errcon and ns and not np.all(atol > 0.0):
        raise LagcodegenError(
            "sensitivities with error control need atol > 0 in every state component (atol is "
            f"{np.array2string(atol, separator=', ')}): a direction's error weights are 1/(rtol max|s| + atol), and "
            "the direction of a parameter starts at s = 0; give atol > 0 (it is also the sensitivities' atol) or "
            "sensitivity_errcon=False")
    atol_all = np.concatenate([atol] + [atol if errcon else np.full(ny, 1e300)] * ns)
    opt = ffi.new("lcg_cvsens_options *")
    c = control
    opt.method = METHODS[c.method]
    opt.rtol = c.rtol
    opt.atol = ffi.from_buffer("double[]", atol_all)
    opt.max_steps = int(c.max_steps)
    opt.jacobian = int(bool(c.jacobian))
    opt.max_order = int(c.max_order)
    opt.first_step, opt.max_step, opt.min_step = c.first_step, c.max_step, c.min_step
    opt.poll, opt.poll_every, opt.max_wall = poll, POLL_EVERY, float(c.max_wall)
    opt.corrector = CORRECTORS[corrector]
    return opt, atol_all


def solve_sensitivities(cm, t: np.ndarray, y0: np.ndarray, p: np.ndarray, control: StepControl,
                        recording: Recording, inputs=None) -> Result:
    """One run of the sensitivity driver with the step control ``control`` (``method``,
    ``errcon``, ``corrector``, budgets) along the directions ``recording.sensitivities``: a
    :class:`~lagcodegen.result.Result` whose ``sensitivities`` (nt, ns, ny + nout) hold
    d(state or output)/d(direction) at every output time, named by ``sensitivity_names``
    (directions) and ``state_names`` + output names. ``recording.events``
    (:class:`~.events.CompiledEvents`, at most ``recording.max_events`` kept): located as in a
    plain run, each record with its time's sensitivities (:mod:`.sensitivity_events`); a terminal
    one ends the run with its state as the last row. ``inputs``
    (:class:`~lagcodegen.solvers.inputs.InputSet`): the run driven by these tables
    (``lcg_cvsens_solve_inputs``), restarted where they jump or kink; no direction may be an
    input (:func:`check_inputs`)."""
    method, events = control.method, recording.events
    if method not in ("adams", "bdf"):
        raise LagcodegenError(f"sensitivities run on CVODE with method 'adams' or 'bdf', not {method!r}")
    names, which, s0 = directions(cm, recording.sensitivities, y0, float(t[0]), p)
    if inputs and events is not None:
        raise LagcodegenError("events with input tables: not supported")
    if inputs:
        check_inputs(names, which, inputs)
    fns = functions(cm)
    ffi, lib = fns.rt.ffi, fns.rt.lib
    ns, ny, nt = len(names), cm.ny, t.size
    nout = cm.code.nout
    yout = np.empty((nt, ny))
    sout = np.empty((nt, ns, ny))
    out = np.empty((nt, max(nout, 1)))
    dout = np.empty((nt, ns, max(nout, 1)))
    opt, atol_all = sens_options(fns.rt.ffi, fns.poll, control, ny, ns)
    st = ffi.new("lcg_cvsens_stats *")
    fb = ffi.from_buffer
    p_ptr = fb("double[]", p) if p.size else ffi.NULL
    start = time.perf_counter()
    args = (fns.table, fns.rhs, fns.out, p_ptr, ns, fb("int[]", which), fb("double[]", y0),
            fb("double[]", np.ascontiguousarray(s0)), nt, fb("double[]", t), fb("double[]", yout), fb("double[]", sout),
            fb("double[]", out), fb("double[]", dout), opt, st)
    found = None if events is None else SensEvents(ffi, events, ny, ns, recording.max_events)
    if inputs:
        keep: list = []
        flag = lib.lcg_cvsens_solve_inputs(*args[:4], inputs.struct(ffi, keep), *args[4:])
    elif found is None:
        flag = lib.lcg_cvsens_solve(*args)
    else:
        flag = lib.lcg_cvsens_solve_events(*args, found.struct)
    wall = time.perf_counter() - start
    if flag == CANCELLED:
        raise_pending()  # Ctrl-C during the run: KeyboardInterrupt
    res = driver_result(cm, ffi, st, flag, wall, method, names, t, yout, sout, out, dout)
    if found is not None:
        add_events(cm, fns, res, found, names, which, p)
    return res


def check_inputs(names, which, inputs) -> None:
    """Refuse a direction along a run-time parameter that an input table of ``inputs``
    (:class:`~lagcodegen.solvers.inputs.InputSet`) sets: the input is a given signal u(t), not a
    constant of the run (the other directions see du/dtheta = 0)."""
    for name, slot in zip(names, which.tolist()):
        if slot >= 0 and slot in inputs.slots:
            raise LagcodegenError(f"sensitivities: {name!r} is an input driven by a table in this run (a given "
                                  "signal u(t), not a parameter of the run); choose other directions or fit the "
                                  "table's values outside the run")


def driver_result(model, ffi, st, flag: int, wall: float, method: str, names, t, yout, sout, out, dout) -> Result:
    """The :class:`~lagcodegen.result.Result` of one call of the sensitivity driver (ODE or
    index-1 ``model``, its ``state_names`` and ``output_names``): the rows it reached of its
    arrays, copied, its statistics struct ``st`` (:data:`STATS` and ``wall_time``) and the text
    of its ``flag``."""
    nout = len(model.output_names)
    stats = sens_stats(st)
    stats["wall_time"] = wall
    detail = ffi.string(st.message).decode(errors="replace") if flag < 0 else ""
    text = "success" if flag >= 0 else message(flag, st.model_error, detail, t=st.t_reached)
    sl = slice(0, st.nt_done)
    res = Result(t=t[sl].copy(), y=yout[sl].copy(), state_names=list(model.state_names),
                 outputs={k: out[sl, i].copy() for i, k in enumerate(model.output_names)}, stats=stats,
                 status=int(flag), message=text, backend="native", method=method)
    res.set_sensitivities(names, list(model.state_names) + list(model.output_names),
                          np.concatenate([sout[sl], dout[sl, :, :nout]], axis=2))
    return res


def add_events(cm, fns, res: Result, found: SensEvents, names, which, p) -> None:
    """The events of a run into ``res`` (``events``, ``stats["events"]``), the state of a terminal
    one appended as its last row with its sensitivities."""
    from .native import add_event_row
    res.events = found.records(cm, fns, names, which, p)
    res.stats["events"] = int(found.struct.n_events)
    res.stats["terminated"] = int(found.terminated)
    if found.terminated and res.events:
        rows = res.t.size
        add_event_row(cm, res, res.events[-1], p)
        if res.t.size > rows:
            s, dout = found.event_row(fns, p, which, cm.code.nout)
            res.sensitivities = np.concatenate([res.sensitivities, np.concatenate([s, dout], axis=1)[None]])


def run(family, cm, t: np.ndarray, y: np.ndarray, p: np.ndarray, rtol: float, atol, names, *, events=None,
        inputs=None) -> Result:
    """A sensitivity run of ``cm`` along the directions ``names`` with the resolved solver ``family`` (a
    :class:`~lagcodegen.solvers.cvode.CVODE` on the native backend with the dense Newton solver:
    the block solver of the sensitivity driver replaces it), with its options; ``inputs`` its
    input tables, if any."""
    check_family(family)
    control = family.ode_control(cm, rtol, atol, y, p if not inputs else inputs.apply(p, t[0]), True)
    recording = family.recording(10_000, events=events, sensitivities=names)
    return solve_sensitivities(cm, t, y, p, control, recording, inputs=inputs)


def check_family(family) -> None:
    """Refuse the options of ``family`` (a CVODE object) that the sensitivity driver does not take
    (as :func:`run` does)."""
    if family.backend != "native":
        raise LagcodegenError("sensitivities need backend='native'")
    if family.linear_solver != "dense":
        raise LagcodegenError(f"sensitivities use their own block-structured Newton solver: linear_solver "
                              f"{family.linear_solver!r} does not apply (leave it 'dense')")


class PreparedSensitivities:
    """Repeated sensitivity runs of one model at the same output times, directions and options
    with other initial states and parameters (the evaluations of a fit): the directions, the
    driver's options struct and the output arrays made once, so that a run costs the driver's
    call and nothing per call in Python beyond it (:func:`solve_sensitivities` makes them anew
    and builds a :class:`~lagcodegen.result.Result` each time). ``__call__(y0, p)`` runs and
    returns (flag, message); the arrays ``yout`` (nt, ny), ``sout`` (nt, ns, ny), ``out`` (nt,
    nout) and ``dout`` (nt, ns, nout) hold the run's values (``nt_done`` rows of them)."""

    def __init__(self, cm, t: np.ndarray, names, control: StepControl):
        if control.method not in ("adams", "bdf"):
            raise LagcodegenError(f"sensitivities run on CVODE with method 'adams' or 'bdf', not {control.method!r}")
        self.names, which, s0 = directions(cm, names, defer=True)
        # Rotations of a quaternion (general_directions): their s0 depends on the initial state.
        self._cm, self._t0 = cm, float(np.asarray(t, dtype=float).ravel()[0])
        self._rotations = rotation_directions(cm, self.names)
        fns = functions(cm)
        self.fns = fns
        ffi = fns.rt.ffi
        ns, ny = len(self.names), cm.ny
        self.t = np.ascontiguousarray(t, dtype=float)
        nt = self.t.size
        self.nout = nout = cm.code.nout
        self._which = np.ascontiguousarray(which)
        self._s0 = np.ascontiguousarray(s0)
        self.yout = np.empty((nt, ny))
        self.sout = np.empty((nt, ns, ny))
        self.out = np.empty((nt, max(nout, 1)))
        self.dout = np.empty((nt, ns, max(nout, 1)))
        opt, self._atol = sens_options(fns.rt.ffi, fns.poll, control, ny, ns)
        self._opt = opt
        self._st = ffi.new("lcg_cvsens_stats *")
        fb = ffi.from_buffer
        self._args = (fb("int[]", self._which), fb("double[]", self._s0), nt, fb("double[]", self.t),
                      fb("double[]", self.yout), fb("double[]", self.sout), fb("double[]", self.out),
                      fb("double[]", self.dout), opt, self._st)
        self.nt_done = 0

    def __call__(self, y0: np.ndarray, p: np.ndarray) -> tuple[int, str]:
        fns = self.fns
        ffi, lib = fns.rt.ffi, fns.rt.lib
        y0 = np.ascontiguousarray(y0, dtype=float)
        p = np.ascontiguousarray(p, dtype=float)
        which, s0, nt, t, yout, sout, out, dout, opt, st = self._args
        if self._rotations:  # the rotations' s0 at this initial state
            self._s0[:] = directions(self._cm, self.names, y0, self._t0, p)[2]
        flag = lib.lcg_cvsens_solve(fns.table, fns.rhs, fns.out, ffi.from_buffer("double[]", p) if p.size else ffi.NULL,
                                    len(self.names), which, ffi.from_buffer("double[]", y0), s0, nt, t, yout, sout, out,
                                    dout, opt, st)
        if flag == CANCELLED:
            raise_pending()  # Ctrl-C during the run: KeyboardInterrupt
        self.nt_done = st.nt_done
        if flag >= 0:
            return int(flag), "success"
        detail = ffi.string(st.message).decode(errors="replace")
        return int(flag), message(flag, st.model_error, detail, t=st.t_reached)


def prepare(family, cm, t: np.ndarray, y: np.ndarray, p: np.ndarray, rtol: float, atol, names, *,
            errcon: bool = True) -> PreparedSensitivities:
    """The :class:`PreparedSensitivities` of ``cm`` along ``names`` with the options of the
    resolved solver ``family`` (as :func:`run`; ``y``, ``p`` a representative initial state and
    parameters)."""
    check_family(family)
    return PreparedSensitivities(cm, t, names, family.ode_control(cm, rtol, atol, y, p, True).replace(errcon=errcon))
