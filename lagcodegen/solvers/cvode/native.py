"""The native CVODE family: the runtime's model-independent C drivers call CVODE with no Python in
the solver loop, one call over all output times: ``lcg_cvode_solve`` for the ODE of a scene (plain,
Routhian, minimal coordinates; dense, band or fixed-point iteration) and ``lcg_cvc_solve`` for the
index-1 form of a constrained system (Baumgarte, projection, events), each taking the model's
function table."""

from __future__ import annotations

import time

import numpy as np

from ...codegen.signatures import CVC_OPTIONS as CVC_STRUCT
from ...codegen.signatures import CVODE_OPTIONS as CVODE_STRUCT
from ...codegen.signatures import pack_format
from ...codes import TOO_MUCH_WORK
from ...errors import LagcodegenError
from ...formulation.scene import band_order
from ...formulation.scene import bandwidths as widths
from ...result import Result
from ..base import (SINGULAR_AUGMENTED, NativeEvents, PreparedOptions, message, native_stats,
                   pooled_stats, reached_rows)
from ..control import CANCELLED, POLL_EVERY, raise_pending
from ..request import Index1Form, Recording, StepControl, option_values


def band_widths(cm, bandwidths=None, y=None, p=None) -> tuple[int, int]:
    """(upper, lower) bandwidths of the band solver for ``cm``: ``bandwidths`` if given, else
    from the scene's Jacobian pattern in the interleaved order (:func:`scene.band_order`); a
    module without a recorded pattern (e.g. Fortran) is probed numerically at ``y``. A model with
    generalized speeds is refused by name: the band order pairs q_i with q_i' (y[i], y[n + i])."""
    code = getattr(cm, "code", None)
    if getattr(code, "nv", None) is not None:
        raise LagcodegenError(f"model {code.model_name!r} has generalized speeds (nq = {code.n}, nv = {code.nv}): "
                              "the band linear solver (its order interleaves each coordinate with its rate) cannot "
                              "take it; use the dense linear solver")
    if bandwidths is not None:
        mu, ml = (int(b) for b in bandwidths)
        if not (0 <= mu < cm.ny and 0 <= ml < cm.ny):
            raise LagcodegenError(f"bandwidths must lie in [0, {cm.ny - 1}], got {bandwidths!r}")
        return mu, ml
    pattern = getattr(cm.code, "jac_pattern", None)
    if pattern is None:
        pattern = _probe_pattern(cm, y, p)
    return widths(pattern, band_order(cm.n, cm.code.nz))


def _probe_pattern(cm, y, p) -> np.ndarray:
    """Nonzero pattern of df/dy from forward differences at y and at two perturbed states."""
    rng = np.random.default_rng(12345)
    y = np.zeros(cm.ny) if y is None else np.asarray(y, dtype=float)
    pattern = np.zeros((cm.ny, cm.ny), dtype=bool)
    for yy in (y, y + 0.1 * rng.standard_normal(cm.ny), y + 0.1 * rng.standard_normal(cm.ny)):
        try:
            f0 = cm.rhs(0.0, yy, p)
        except LagcodegenError:
            continue
        for j in range(cm.ny):
            y1 = yy.copy()
            y1[j] += 1e-6 * max(1.0, abs(yy[j]))
            try:
                pattern[:, j] |= cm.rhs(0.0, y1, p) != f0
            except LagcodegenError:
                pattern[:, j] = True
    return pattern


#: The fields of the CVODE driver's options that vary between ODE runs and their pack format
#: (PreparedOptions; the format from the struct's declaration, lagcodegen.codegen.signatures).
_CVODE_VARYING = ("method", "jacobian", "rtol", "max_steps", "first_step", "max_step", "min_step", "max_order",
                  "linear_solver", "mupper", "mlower", "max_wall")
CVODE_RUN_OPTIONS = (_CVODE_VARYING, pack_format(CVODE_STRUCT, _CVODE_VARYING))


def ode_options(cm) -> PreparedOptions:
    """The options structs of ``cm``'s CVODE driver kept for reuse across its ODE runs (one per
    distinct set of values; made on first use)."""
    return cm.artifacts.get(PreparedOptions, "cvode", lambda: PreparedOptions(
        cm.ffi, cm.options_type, *CVODE_RUN_OPTIONS, poll=cm.poll, poll_every=POLL_EVERY))


def ode_struct(cm, control: StepControl):
    """The options struct of an ODE run of ``cm`` on the native driver with the step control
    ``control`` (from :func:`ode_options`: shared, never written)."""
    return ode_options(cm).get(control.atol, *option_values(CVODE_STRUCT, _CVODE_VARYING, control))


def run_message(ffi, flag: int, st) -> str:
    """The message of an ODE run of the native driver that ended with ``flag`` (statistics ``st``)."""
    detail = ffi.string(st.message).decode(errors="replace") if flag < 0 else ""
    text = message(flag, st.model_error, detail, t=st.t_reached)
    if flag == TOO_MUCH_WORK and st.t_reached + st.h_last == st.t_reached:  # steps that no longer advance t
        text = (f"the step size fell below the resolution of t at t = {st.t_reached:.17g} (is the solution "
                f"singular there?); {text}")
    return text


def solve_native(cm, t, y0, p, control: StepControl, recording: Recording = Recording(), inputs=None) -> Result:
    """An ODE run of a compiled scene with the step control ``control``: one call of the native
    driver (``lcg_cvode_solve``) over all output times; with ``recording.events``
    (:class:`~.events.CompiledEvents`, at most ``recording.max_events`` kept),
    ``lcg_cvode_solve_events`` locates them (CVODE's root finding; a terminal event's state is the
    run's last row); with
    ``inputs`` (:class:`~lagcodegen.solvers.inputs.InputSet`), ``lcg_cvode_solve_inputs`` sets the
    inputs' parameters from their tables in C."""
    ffi = cm.ffi
    nt = t.size
    yout = np.empty((nt, cm.ny))  # rows past st.nt_done are cut off below
    out = np.empty((nt, max(cm.code.nout, 1)))
    keep: list = []
    opt = ode_struct(cm, control)
    events, method = recording.events, control.method
    st = ffi.new(cm.stats_type)
    found = None
    args = (ffi.from_buffer("double[]", y0), nt, ffi.from_buffer("double[]", t), ffi.from_buffer("double[]", yout),
            ffi.from_buffer("double[]", out), opt, st)
    if events is not None and inputs:
        raise LagcodegenError("events with input tables: not supported")
    if events is not None:
        found = NativeEvents(ffi, "lcg_events", events.events, cm.ny, recording.max_events)
        flag = cm.lib.lcg_cvode_solve_events(cm.table, events.table, cm.c_params(p), *args, found.struct)
    elif inputs:
        flag = cm.lib.lcg_cvode_solve_inputs(cm.table, cm.c_params(p), inputs.struct(ffi, keep), *args)
    else:
        flag = cm.native_solve(cm.c_params(p), *args)
    if flag == CANCELLED:
        raise_pending()  # Ctrl-C during the run: KeyboardInterrupt
    done = st.nt_done
    if done < nt:
        t, yout, out = t[:done].copy(), yout[:done].copy(), out[:done].copy()
    text = run_message(ffi, flag, st)
    res = Result(t=t, y=yout, state_names=list(cm.state_names),
                 outputs={k: out[:, i] for i, k in enumerate(cm.output_names)},
                 stats=native_stats(ffi, st), status=int(flag), message=text,
                 backend="native", method=method)
    if found is not None:
        res.events = found.records(cm.state_names, cm.ny)
        res.stats["events"] = int(found.struct.n_events)
        if found.terminated and res.events:
            add_event_row(cm, res, res.events[-1], p)
    return res


def add_event_row(cm, res: Result, rec, p) -> None:
    """The state of the terminal event ``rec`` that ended an ODE run appended to ``res`` as its last
    row, with its outputs (NaN where they are not finite), as the Taylor driver's runs have it."""
    if res.t.size and rec.t <= res.t[-1]:
        return
    try:
        o = cm.outputs(rec.t, rec.y, p)
    except LagcodegenError:
        o = np.full(len(res.outputs), np.nan)
    res.t = np.append(res.t, rec.t)
    res.y = np.vstack([res.y, np.asarray(rec.y, dtype=float)[None, :]])
    res.outputs = {name: np.append(v, o[i]) for i, (name, v) in enumerate(res.outputs.items())}


#: The fields of the index-1 driver's options that vary between runs and their pack format
#: (PreparedOptions; the format from the struct's declaration, lagcodegen.codegen.signatures).
_CVC_VARYING = ("method", "rtol", "max_steps", "first_step", "max_step", "min_step", "max_order", "alpha", "beta",
                "projection", "proj_tol", "proj_maxit", "roots", "max_wall")
CVC_OPTIONS = (_CVC_VARYING, pack_format(CVC_STRUCT, _CVC_VARYING))


def solve_index1(sim, t, y0, p, control: StepControl, form: Index1Form, recording: Recording) -> Result:
    """An index-1 run of a constrained system (eq. 4.5 at the acceleration level, Baumgarte
    and/or CVODE's projection: ``form``): one call of the runtime's ``lcg_cvc_solve`` on the
    model's table (``sim.c_cvc_solve``); ``recording.roots``: locate the compiled events (at most
    ``recording.max_events`` kept). ``control.atol`` a float (every state) or an array; ``t``
    and ``y0`` contiguous float64 arrays (the caller's checks)."""
    c, roots, method = control, recording.roots, control.method
    ffi = sim.ffi
    ny, nt = sim.ny, t.size
    yout = np.empty((nt, ny))  # rows past st.nt_done are cut off below
    out = np.empty((nt, sim.n_out_columns))
    opt = sim.cvc_options.get(c.atol, *option_values(CVC_STRUCT, _CVC_VARYING, c, form, recording))
    pool = sim.cvc_stats_pool
    st = pooled_stats(ffi, pool, sim.cvc_stats_type)
    events = sim.native_events(recording.max_events) if roots else None
    fb, darr = ffi.from_buffer, sim._double_array
    try:
        start = time.perf_counter()
        flag = sim.c_cvc_solve(sim.c_params(p), fb(darr, y0), nt, fb(darr, t), fb(darr, yout),
                               fb(darr, out), opt, st, events.struct if events else ffi.NULL)
        wall = time.perf_counter() - start
        if flag == CANCELLED:
            raise_pending()
        recs = events.records(sim.state_names, ny) if events else []
        tt, yy, oo = reached_rows(t, yout, out, st.nt_done)
        if events and events.terminated and recs:
            tt, yy, oo = append_event_row(sim, tt, yy, oo, recs[-1].t, recs[-1].y, p)
    finally:
        if events:
            sim.release_events(events)
    stats = native_stats(ffi, st)
    stats["wall_time"] = wall
    text = "success" if flag >= 0 else message(flag, st.model_error, ffi.string(st.message).decode(errors="replace"),
                                               "CVODE", SINGULAR_AUGMENTED)
    pool.append(st)
    return Result(t=tt, y=yy, state_names=sim.state_names,
                  outputs=dict(zip(sim.info.output_names, oo.T)), stats=stats,
                  status=int(flag), message=text, backend="native", method=method, events=recs)


def append_event_row(sim, tt, yy, oo, t_event: float, y_event, p, lam=None):
    """The arrays of a run that a terminal event ended, with the event's own row appended (its
    outputs from the compiled functions; NaN where they fail)."""
    if tt.size and t_event <= tt[-1]:
        return tt, yy, oo
    try:
        o = sim.outputs(t_event, y_event[: sim.ny], p, lam=lam)
    except LagcodegenError:
        o = np.full(oo.shape[1], np.nan)
    return (np.append(tt, t_event), np.vstack([yy, np.asarray(y_event)[None, :]]),
            np.vstack([oo, np.resize(o, (1, oo.shape[1]))]))
