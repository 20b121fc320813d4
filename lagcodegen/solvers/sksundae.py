"""The scikit-sundae family: scikit-sundae's Python API (CVODE, IDA) on the same compiled
functions as the native drivers (one Python callback per right-hand-side evaluation, about 5 us
each): the second method that checks them. ODE runs, index-1 and GGL constrained runs.

``max_steps`` means what it means on the native drivers, a budget of internal steps for the
whole run (scikit-sundae's ``max_num_steps`` counts the steps of one output interval):
:func:`_budgeted_solve` takes the steps one by one and interpolates at the output times."""

from __future__ import annotations

import time
from types import SimpleNamespace

import numpy as np

from ..codes import NONFINITE_CAUSES
from ..errors import LagcodegenError
from ..model.events import EventRecord
from ..result import Result
from .base import ERR_NONFINITE, ERR_SINGULAR, SINGULAR_AUGMENTED, message
from .ida.native import ALGEBRAIC_ATOL
from .request import Index1Form, StepControl


def solve_sksundae(cm, t, y0, p, control: StepControl, events=None) -> Result:
    """An ODE run of ``cm`` on scikit-sundae's CVODE with the step control ``control``; ``events``
    (:class:`~lagcodegen.solvers.cvode.events.CompiledEvents`): its ``eventsfn`` on the same
    compiled event functions as the native driver's root finding."""
    from sksundae.cvode import CVODE

    method, rtol, atol, jacobian = control.method, control.rtol, control.atol, control.jacobian
    max_steps, first_step, max_step = control.max_steps, control.first_step, control.max_step
    min_step, max_order = control.min_step, control.max_order
    ffi, ny = cm.ffi, cm.ny
    crhs, cjac = cm.c_rhs, cm.c_jac
    pp = ffi.from_buffer("double[]", p) if p.size else ffi.NULL
    state = {"model_error": 0, "t": float(t[0])}
    jbuf = np.empty((ny, ny), order="F")

    def rhsfn(tt, y, yp):
        rc = crhs(tt, ffi.from_buffer("double[]", y), pp, ffi.from_buffer("double[]", yp, require_writable=True))
        state["nonfinite"] = rc == ERR_NONFINITE  # as the native driver: named if the run fails right after
        if rc == ERR_SINGULAR:
            state["model_error"], state["t"] = ERR_SINGULAR, tt
            yp[:] = np.nan
        elif rc:
            state["t_nonfinite"] = tt
            yp[:] = np.nan

    def jacfn(tt, y, yp, JJ):
        rc = cjac(tt, ffi.from_buffer("double[]", y), ffi.from_buffer("double[]", yp), pp,
                  ffi.from_buffer("double[]", jbuf.T))
        if rc:
            jbuf[:] = np.nan
        JJ[:, :] = jbuf

    options = dict(method="Adams" if method == "adams" else "BDF", rtol=rtol,
                   atol=atol if type(atol) is float or (atol != atol[0]).any() else float(atol[0]),
                   max_num_steps=max_steps, first_step=first_step, max_step=max_step, min_step=min_step)
    if max_order:
        options["max_order"] = max_order
    if jacobian:
        options["jacfn"] = jacfn
    if events is not None:
        options.update(_ode_events(events, p))
    soln = _budgeted_solve(CVODE(rhsfn, **options), t, (y0,), max_steps, options.get("eventsfn"))
    done = len(soln.t)
    y = np.asarray(soln.y, dtype=float).reshape(done, ny)
    outs = np.full((done, cm.code.nout), np.nan)
    if cm.code.nout and done:
        tt = np.ascontiguousarray(soln.t, dtype=float)
        yy = np.ascontiguousarray(y)
        batch = cm.c_outputs_batch
        if batch is not None:  # one C call for all rows
            batch(done, ffi.from_buffer("double[]", tt), ffi.from_buffer("double[]", yy), pp,
                  ffi.from_buffer("double[]", outs))
        else:
            for k in range(done):
                try:
                    outs[k] = cm.outputs(tt[k], yy[k], p)
                except LagcodegenError:
                    break
    status = int(getattr(soln, "status", 0))
    if state.get("nonfinite") and not state["model_error"] and status in NONFINITE_CAUSES["CVODE"]:
        state["model_error"], state["t"] = ERR_NONFINITE, state["t_nonfinite"]
    # nfev omits difference-quotient Jacobian calls.
    stats = dict(steps=soln.steps, rhs_evals=int(getattr(soln, "nfev", -1)),
                 jac_evals=int(getattr(soln, "njev", -1)), t_reached=float(soln.t[-1]) if done else float(t[0]),
                 model_error=state["model_error"])
    text = str(getattr(soln, "message", ""))
    if status < 0 or not getattr(soln, "success", True):
        status = status if status < 0 else -3
        text = message(status, state["model_error"], text, t=state["t"] if state["model_error"] else None)
        stats["t_reached"] = state["t"] if state["model_error"] else soln.t_reached
    res = Result(t=np.asarray(soln.t, dtype=float), y=y, state_names=list(cm.state_names),
                 outputs={k: outs[:, i] for i, k in enumerate(cm.output_names)}, stats=stats,
                 status=status if status < 0 else 0, message=text if status < 0 else "success",
                 backend="sksundae", method=method)
    if events is not None:
        res.events = _event_records(soln, events.events, ny, cm.state_names, float(t[0]), float(t[-1]))
        res.stats["events"] = len(res.events)
    return res


def _ode_events(events, p) -> dict:
    """scikit-sundae's ``eventsfn`` on the compiled event functions of an ODE run (``events``:
    :class:`~lagcodegen.solvers.cvode.events.CompiledEvents`); a value that is not finite is NaN."""
    p = np.ascontiguousarray(p, dtype=float)

    def eventsfn(tt, y, out):
        try:
            out[:] = events.values(tt, y, p)
        except LagcodegenError:
            out[:] = np.nan

    eventsfn.terminal = [bool(e.terminal) for e in events.events]
    eventsfn.direction = [int(e.direction) for e in events.events]
    return {"eventsfn": eventsfn, "num_events": len(events.events)}


def _event_records(soln, evs, ny: int, state_names, t0: float, t_end: float) -> list[EventRecord]:
    """The EventRecords of a scikit-sundae solution; roots within rounding of the start ``t0`` (a
    run restarted from an event's state) are left out, as the native driver does, and so are the
    repeats of a root that the interpolating calls at output times report again."""
    recs = []
    if getattr(soln, "t_events", None) is None:
        return recs
    eps = np.finfo(float).eps
    last: dict = {}
    for k, te in enumerate(np.atleast_1d(soln.t_events)):
        te = float(te)
        if te - t0 <= 100 * eps * (abs(t0) + abs(t_end - t0)):
            continue
        info = np.atleast_2d(soln.i_events)[k]
        yk = np.atleast_2d(soln.y_events)[k]
        for i in np.flatnonzero(info):
            if i in last and abs(te - last[i]) <= 1000 * eps * (abs(te) + abs(t_end - t0)):
                continue  # the same root, located again (CVODE's root tolerance is 100 eps (|t| + |h|))
            last[i] = te
            ev = evs[i]
            recs.append(EventRecord(ev.name, int(i), float(te), np.array(yk[:ny], dtype=float),
                                    int(np.sign(info[i])), ev.terminal, list(state_names)))
    return recs


def _budgeted_solve(solver, t, initial: tuple, max_steps: int, eventsfn=None) -> SimpleNamespace:
    """What ``solver.solve(t, *initial)`` returns (t, y, status, message, success, nfev, njev,
    the events), plus ``steps``, with ``max_steps`` a budget of internal steps for the whole run
    as on the native drivers: one internal step per call (stopping at t[-1]), each output time
    interpolated by a call that takes no step once a step has passed it; a terminal event ends
    the run with its own row; a run that would need more steps stops with status -1."""
    first = solver.init_step(float(t[0]), *initial)
    rows_t, rows_y = [float(t[0])], [np.array(first.y, dtype=float)]
    last, steps, status, text = first, 0, 0, ""
    t_end, tn, k, nt = float(t[-1]), float(t[0]), 1, len(t)
    while k < nt:
        if tn < t[k]:
            if steps >= max_steps:
                status = -1
                text = f"the step budget max_steps = {max_steps} is used up before t = {float(t[k]):.17g}"
                break
            r = solver.step(float(t[k]), "onestep", t_end)
            last, steps = r, steps + 1
            if r.status < 0:
                status, text, tn = int(r.status), str(r.message), float(r.t)
                break
            tn = float(r.t)
            if r.status == 2 and eventsfn is not None and np.any(eventsfn._i_cnt >= eventsfn._max_events):
                rows_t.append(tn)
                rows_y.append(np.array(r.y, dtype=float))
                break
            continue
        r = solver.step(float(t[k]), "normal", None)  # t[k] lies within the last step: no new step
        last = r
        if r.status < 0:
            status, text = int(r.status), str(r.message)
            break
        rows_t.append(float(r.t))
        rows_y.append(np.array(r.y, dtype=float))
        k += 1
    return SimpleNamespace(t=np.array(rows_t), y=np.array(rows_y), status=status, success=status >= 0,
                           message=text or "success", nfev=last.nfev, njev=last.njev, steps=steps,
                           t_reached=tn, i_events=last.i_events, t_events=last.t_events,
                           y_events=last.y_events)


def solve_index1(sim, t, y0, p, control: StepControl, form: Index1Form, roots: bool) -> Result:
    """An index-1 constrained run on scikit-sundae's CVODE with the step control ``control`` and
    the Baumgarte parameters of ``form`` (no projection: scikit-sundae does not expose
    CVodeSetProjFn); ``roots``: locate the compiled events."""
    from sksundae.cvode import CVODE

    method, rtol, atol, jacobian = control.method, control.rtol, control.atol, control.jacobian
    max_steps, first_step, max_step = control.max_steps, control.first_step, control.max_step
    min_step, max_order = control.min_step, control.max_order
    alpha, beta = form.alpha, form.beta

    ffi, ny = sim.ffi, sim.ny
    pp = sim.c_params(p)
    crhs = sim.c_crhs
    state = {"model_error": 0, "t": float(t[0])}

    def rhsfn(tt, y, yp):
        rc = crhs(tt, ffi.from_buffer("double[]", y), pp, alpha, beta,
                  ffi.from_buffer("double[]", yp, require_writable=True))
        if rc:
            if rc == ERR_SINGULAR:
                state["model_error"], state["t"] = rc, tt
            yp[:] = np.nan

    options = dict(method="Adams" if method == "adams" else "BDF", rtol=rtol,
                   atol=atol if np.any(atol != atol[0]) else float(atol[0]), max_num_steps=max_steps,
                   first_step=first_step, max_step=max_step, min_step=min_step)
    if max_order:
        options["max_order"] = max_order
    if roots:
        options.update(_events(sim, lambda tt, y: (y, None), p))
    start = time.perf_counter()
    soln = _budgeted_solve(CVODE(rhsfn, **options), t, (y0,), max_steps, options.get("eventsfn"))
    wall = time.perf_counter() - start
    return _constrained_result(sim, soln, t, ny, p, state, wall, method, "scikit-sundae")


def solve_ggl(sim, t, yy0, yp0, p, control: StepControl, roots: bool) -> Result:
    """A GGL constrained run on scikit-sundae's IDA with the step control ``control`` (a huge
    atol keeps lambda, mu out of the error test: scikit-sundae never calls IDASetSuppressAlg);
    ``roots``: locate the compiled events."""
    from sksundae.ida import IDA

    method, rtol, atol, jacobian = control.method, control.rtol, control.atol, control.jacobian
    max_steps, first_step, max_step = control.max_steps, control.first_step, control.max_step
    min_step, max_order = control.min_step, control.max_order

    ffi, ny, ng, J = sim.ffi, sim.ny, sim.info.ng, sim.info.J
    pp = sim.c_params(p)
    cres, cjac = sim.c_ggl_res, sim.c_ggl_jac
    state = {"model_error": 0, "t": float(t[0])}
    jbuf = np.empty((ng, ng), order="F")

    def resfn(tt, y, yp, res):
        rc = cres(tt, ffi.from_buffer("double[]", y), ffi.from_buffer("double[]", yp), pp,
                  ffi.from_buffer("double[]", res, require_writable=True))
        if rc:
            res[:] = np.nan

    def jacfn(tt, y, yp, res, cj, JJ):
        rc = cjac(tt, cj, ffi.from_buffer("double[]", y), ffi.from_buffer("double[]", yp), pp,
                  ffi.from_buffer("double[]", jbuf.T))
        if rc:
            jbuf[:] = np.nan
        JJ[:, :] = jbuf

    atol = atol.copy()
    atol[ny:] = np.maximum(atol[ny:], ALGEBRAIC_ATOL)
    options = dict(rtol=rtol, atol=atol, algebraic_idx=list(range(ny, ng)), calc_initcond="yp0",
                   calc_init_dt=float(t[1] - t[0]), max_num_steps=max_steps, first_step=first_step,
                   max_step=max_step, min_step=min_step)
    if max_order:
        options["max_order"] = max_order
    if jacobian:
        options["jacfn"] = jacfn
    if roots:
        options.update(_events(sim, lambda tt, y: (np.ascontiguousarray(y[: ny]),
                                                   np.ascontiguousarray(y[ny: ny + J])), p, dae=True))
    start = time.perf_counter()
    soln = _budgeted_solve(IDA(resfn, **options), t, (yy0, yp0), max_steps, options.get("eventsfn"))
    wall = time.perf_counter() - start
    res = _constrained_result(sim, soln, t, ny, p, state, wall, "bdf", "IDA", lam_slice=slice(ny, ny + J))
    yfull = np.asarray(soln.y, dtype=float).reshape(len(soln.t), -1)
    res.outputs.update(sim.ggl_multiplier_outputs(yfull))
    res.stats["algebraic_atol"] = ALGEBRAIC_ATOL
    return res


def _events(sim, split, p, dae: bool = False) -> dict:
    """scikit-sundae's ``eventsfn`` on the compiled root functions of ``sim``."""
    roots_c, ffi = sim.c_roots, sim.ffi
    pp = sim.c_params(p)
    evs = sim.info.events

    def fill(tt, y, ev_out):
        yv, lam = split(tt, y)
        lp = ffi.NULL if lam is None else ffi.from_buffer("double[]", lam)
        rc = roots_c(tt, ffi.from_buffer("double[]", yv), lp, pp,
                     ffi.from_buffer("double[]", ev_out, require_writable=True))
        if rc:
            ev_out[:] = np.nan

    if dae:
        def eventsfn(tt, y, yp, events):
            fill(tt, y, events)
    else:
        def eventsfn(tt, y, events):
            fill(tt, y, events)

    eventsfn.terminal = [bool(e.terminal) for e in evs]
    eventsfn.direction = [int(e.direction) for e in evs]
    return {"eventsfn": eventsfn, "num_events": len(evs)}


def _constrained_result(sim, soln, t, ny, p, state, wall, method, solver, lam_slice=None) -> Result:
    done = len(soln.t)
    y = np.asarray(soln.y, dtype=float).reshape(done, -1)
    nout = len(sim.info.output_names)
    outs = np.full((done, nout), np.nan)
    for k in range(done):
        lam = None if lam_slice is None else y[k, lam_slice]
        try:
            outs[k] = sim.outputs(soln.t[k], y[k, :ny], p, lam=lam)
        except LagcodegenError:
            break
    recs = []
    if getattr(soln, "t_events", None) is not None:
        for k, te in enumerate(np.atleast_1d(soln.t_events)):
            info = np.atleast_2d(soln.i_events)[k]
            yk = np.atleast_2d(soln.y_events)[k]
            for i in np.flatnonzero(info):
                ev = sim.info.events[i]
                recs.append(EventRecord(ev.name, int(i), float(te), np.array(yk[:ny], dtype=float),
                                        int(np.sign(info[i])), ev.terminal, list(sim.state_names)))
    status = int(getattr(soln, "status", 0))
    stats = dict(steps=soln.steps, rhs_evals=int(getattr(soln, "nfev", -1)), jac_evals=int(getattr(soln, "njev", -1)),
                 t_reached=float(soln.t[-1]) if done else float(t[0]), model_error=state["model_error"],
                 wall_time=wall)
    text = str(getattr(soln, "message", ""))
    if status < 0 or not getattr(soln, "success", True):
        status = status if status < 0 else -3
        text = message(status, state["model_error"], text, solver, SINGULAR_AUGMENTED)
        stats["t_reached"] = state["t"] if state["model_error"] else soln.t_reached
    res = Result(t=np.asarray(soln.t, dtype=float), y=y[:, :ny].copy(), state_names=list(sim.state_names),
                 outputs={k: outs[:, i] for i, k in enumerate(sim.info.output_names)}, stats=stats,
                 status=status if status < 0 else 0, message=text if status < 0 else "success",
                 backend="sksundae", method=method)
    res.events = recs
    return res
