"""The Taylor family's ensemble runner (``method="taylor"``): the Taylor runtime's
``lcg_taylor_solve_many`` (lagcodegen/runtime/lcg_taylor.c) over the jet of the scene, the same
module :func:`~.run.taylor_module` builds for ``simulate`` (no events). Ctrl-C stops running
members too; ``max_wall`` limits each member. With sensitivities
(:func:`run_taylor_sensitivity_ensemble`), each member is a run of the variational jet
(:mod:`.prepared_sensitivity`; with events, :meth:`.sensitivity.VariationalModule.solve`),
bit-identical to the same run alone."""

from __future__ import annotations

import numpy as np

from .. import control
from ..base import tolerances
from ..ensemble_run import run_native
from .run import taylor_module


def run_taylor_ensemble(cm, t, Y, P, *, threads, save, progress, rtol=1e-8, atol=1e-10, max_step=0.0,
                        max_steps=1_000_000, order=None, max_wall=0.0):
    tm = taylor_module(cm)  # the jet of simulate(method="taylor") without events, built once
    ffi, table = tm.ffi, tm.table
    rtol, atol_arr = tolerances(rtol, atol, cm.ny)
    opt = ffi.new("lcg_taylor_options *")
    opt.rtol = rtol
    keep = []
    if np.all(atol_arr == atol_arr[0]):
        opt.atol = float(atol_arr[0])
        opt.atol_vec = ffi.NULL
    else:
        keep.append(atol_arr)
        opt.atol = float(atol_arr.min())
        opt.atol_vec = ffi.from_buffer("double[]", atol_arr)
    opt.max_steps = int(max_steps)
    opt.max_step = float(max_step)
    opt.order = int(order or 0)
    opt.max_wall = float(max_wall)
    solve_many = tm.lib.lcg_taylor_solve_many

    def solve(e, o):
        e.model = table
        return solve_many(e, o)

    return run_native(ffi, solve, "lcg_taylor_ensemble", opt, t=t, Y0=Y, P=P,
                      nrow=cm.ny, nout=cm.code.nout, state_names=cm.state_names, output_names=cm.output_names,
                      row_names=cm.state_names, save=save, threads=threads, progress=progress,
                      poll=control.install(tm.module), method="taylor", n_coordinates=cm.n,
                      param_names=cm.param_names)


def run_taylor_sensitivity_ensemble(cm, t, Y, P, names, *, threads, save, progress, rtol=1e-8, atol=1e-10,
                                    errcon=True, max_step=0.0, max_steps=1_000_000, order=None, max_wall=0.0,
                                    events=(), max_events=10_000):
    """The members (rows of Y, P) with the sensitivities ``names``: each one run of the variational
    jet (built once, before the threads start) on its own statistics and arrays, gathered by
    :func:`lagcodegen.solvers.ensemble_sensitivities.ensemble_of_runs`; ``events`` located in
    every member (at most ``max_events`` kept per member), each with its time's sensitivities."""
    from ..ensemble_sensitivities import ensemble_of_runs
    from .prepared_sensitivity import PreparedTaylorSensitivityRun
    from .run import scene_of
    from .sensitivity import variational_module
    module = variational_module(cm, scene_of(cm), names, events)
    rtol, atol_arr = tolerances(rtol, atol, cm.ny)
    run = PreparedTaylorSensitivityRun(module, rtol=rtol, atol=atol_arr, errcon=errcon, max_step=float(max_step),
                                       max_steps=int(max_steps), order=order, max_wall=float(max_wall), fixed={},
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

    return ensemble_of_runs(cm, t, Y, P, module.names, member_run, threads=threads, save=save,
                            progress=progress, method="taylor")
