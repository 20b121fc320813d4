"""The Taylor family's ensemble runner (``method="taylor"``): the Taylor runtime's
``lcg_taylor_solve_many`` (lagcodegen/runtime/lcg_taylor.c) over the jet of the scene, the same
module :func:`~.run.taylor_module` builds for ``simulate`` (no events). Ctrl-C stops running
members too; ``max_wall`` limits each member. With events (:func:`run_taylor_events_ensemble`),
each member is the prepared run of the jet with them, bit-identical to the same run alone. With sensitivities
(:func:`run_taylor_sensitivity_ensemble`), each member is a run of the variational jet
(:mod:`.prepared_sensitivity`; with events, :meth:`.sensitivity.VariationalModule.solve`),
bit-identical to the same run alone."""

from __future__ import annotations

import numpy as np

from ...codegen.signatures import TAYLOR_OPTIONS
from .. import control as poll_control
from ..base import tolerances
from ..ensemble_run import run_native
from ..request import Layout, Recording, RunArrays, StepControl, option_fields
from .run import taylor_module


def run_taylor_ensemble(cm, t, Y, P, control: StepControl, recording: Recording):
    """The members (rows of Y, P) in one call of ``lcg_taylor_solve_many`` with the step control
    ``control`` (tolerances, ``max_step``, ``max_steps``, ``order``, ``max_wall``); ``recording``:
    what each member keeps (``save``), the ``threads`` and ``progress`` bar (no events)."""
    c = control
    tm = taylor_module(cm)  # the jet of simulate(method="taylor") without events, built once
    ffi, table = tm.ffi, tm.table
    rtol, atol_arr = tolerances(c.rtol, c.atol, cm.ny)
    opt = ffi.new("lcg_taylor_options *")
    for name, value in option_fields(TAYLOR_OPTIONS, c.with_tolerances(rtol, atol_arr)).items():
        setattr(opt, name, value)
    keep = []
    if np.all(atol_arr == atol_arr[0]):
        opt.atol = float(atol_arr[0])
        opt.atol_vec = ffi.NULL
    else:
        keep.append(atol_arr)
        opt.atol = float(atol_arr.min())
        opt.atol_vec = ffi.from_buffer("double[]", atol_arr)
    solve_many = tm.lib.lcg_taylor_solve_many

    def solve(e, o):
        e.model = table
        return solve_many(e, o)

    layout = Layout(nrow=cm.ny, nout=cm.code.nout, state_names=cm.state_names, output_names=cm.output_names,
                    row_names=cm.state_names, param_names=cm.param_names, method="taylor", n_coordinates=cm.n)
    return run_native(ffi, solve, "lcg_taylor_ensemble", opt, RunArrays(t, Y, P), layout,
                      recording.replace(events=None, roots=None), poll=poll_control.install(tm.module))


def run_taylor_events_ensemble(cm, t, Y, P, control: StepControl, recording: Recording):
    """The members (rows of Y, P) with the events ``recording.events`` located in each (at most
    ``recording.max_events`` kept per member) and no sensitivities: each member one run of the
    jet with those events, the run ``simulate(method="taylor", events=...)`` makes of it alone
    (:class:`.prepared.PreparedTaylorRun`: its own statistics, arrays and events struct, the
    module built once before the threads start), gathered by
    :func:`lagcodegen.solvers.ensemble_sensitivities.ensemble_of_runs`; every member's events
    recorded, a terminal event's time and state its ``t_reached`` and final row."""
    from ..ensemble_sensitivities import ensemble_of_runs
    from .prepared import PreparedTaylorRun
    c = control
    module = taylor_module(cm, tuple(recording.events))
    rtol, atol_arr = tolerances(c.rtol, c.atol, cm.ny)
    atol = float(atol_arr[0]) if np.all(atol_arr == atol_arr[0]) else atol_arr
    run = PreparedTaylorRun(module, rtol=rtol, atol=atol, max_step=float(c.max_step), max_steps=int(c.max_steps),
                            order=c.order, max_wall=float(c.max_wall), fixed={}, max_events=recording.max_events)
    t = np.ascontiguousarray(t, dtype=float)
    t_ptr, buffer = module.ffi.from_buffer("double[]", t), module.ffi.from_buffer

    def member_run(i, y0, p):
        return run(t, t_ptr, buffer("double[]", y0), p, buffer("double[]", p) if p.size else module.ffi.NULL)

    return ensemble_of_runs(cm, t, Y, P, None, member_run, threads=recording.threads, save=recording.save,
                            progress=recording.progress, method="taylor")


def run_taylor_sensitivity_ensemble(cm, t, Y, P, control: StepControl, recording: Recording):
    """The members (rows of Y, P) with the sensitivities ``recording.sensitivities`` and the step
    control ``control``: each one run of the variational jet (built once, before the threads
    start) on its own statistics and arrays, gathered by
    :func:`lagcodegen.solvers.ensemble_sensitivities.ensemble_of_runs`; ``recording.events``
    located in every member (at most ``recording.max_events`` kept per member), each with its
    time's sensitivities."""
    c, names, events, max_events = control, recording.sensitivities, recording.events, recording.max_events
    from ..ensemble_sensitivities import ensemble_of_runs
    from .prepared_sensitivity import PreparedTaylorSensitivityRun
    from .run import scene_of
    from .sensitivity import variational_module
    module = variational_module(cm, scene_of(cm), names, events)
    rtol, atol_arr = tolerances(c.rtol, c.atol, cm.ny)
    run = PreparedTaylorSensitivityRun(module, rtol=rtol, atol=atol_arr, errcon=c.errcon, max_step=float(c.max_step),
                                       max_steps=int(c.max_steps), order=c.order, max_wall=float(c.max_wall), fixed={},
                                       model_ffi=cm.ffi, param_names=cm.param_names)
    t = np.ascontiguousarray(t, dtype=float)
    t_ptr = module.rt.ffi.from_buffer("double[]", t)
    model_buffer = cm.ffi.from_buffer

    if module.events:  # the records and a terminal event's row too: the full run with run's options
        def member_run(i, y0, p):
            return module.solve(run.opt, t, y0, p, max_events=max_events)
    else:
        def member_run(i, y0, p):
            return run(t, t_ptr, model_buffer("double[]", y0), p, None)

    return ensemble_of_runs(cm, t, Y, P, module.names, member_run, threads=recording.threads, save=recording.save,
                            progress=recording.progress, method="taylor")
