"""Forward sensitivities of Taylor runs driven by input tables: the variational jet
(:mod:`.variational`, :mod:`.sensitivity`) of the :class:`.inputs.InputSeriesScene` (each input
a cubic of t whose coefficients are run-time parameters after the scene's: never directions, so
du/dtheta = 0 along every direction), run segment by segment between the tables' breakpoints as
:mod:`.inputs` runs the plain jet (:func:`.inputs.run_segments`), the augmented state (y, s)
carried from one segment to the next: the breakpoints are fixed times, independent of the
directions, so s is continuous across them even where an input jumps.

A direction along an input the tables drive is refused by name, as on CVODE
(:func:`lagcodegen.solvers.cvode.sensitivity.check_inputs`). The module of a set of directions
and inputs is built once and kept with the compiled model; a run makes its own options struct
(:meth:`.sensitivity.VariationalModule.new_options`), so runs are reentrant (the members of an
ensemble)."""

from __future__ import annotations

import numpy as np

# --- the rest of lagcodegen: the one place to repoint when modules move -------------------
from ...result import Result
from ..request import Recording, StepControl
# ------------------------------------------------------------------------------------------
from .inputs import InputSeriesScene, run_segments
from .run import scene_of
from .sensitivity import VariationalModule, directions_of


def series_variational_module(cm, names, inputs: tuple) -> VariationalModule:
    """The variational jet of ``cm`` along the directions ``names`` with the inputs ``inputs``
    (names) as cubics of t (built once per set of directions and inputs, then reused)."""
    names, dirs, s0 = directions_of(cm, names)
    def make():
        scene = scene_of(cm)
        series = InputSeriesScene(eom=scene.eom, jacobian=False, outputs=list(scene.outputs),
                                  runtime_parameters=list(scene.runtime_parameters), values=dict(scene.values),
                                  prefix=f"{scene.prefix}_useries", series_inputs=tuple(inputs))
        return VariationalModule(cm, series, names, dirs, s0)
    return cm.artifacts.get(VariationalModule, ("inputs", tuple(names), tuple(inputs)), make)


def run_taylor_sensitivity_inputs(cm, t: np.ndarray, y: np.ndarray, p: np.ndarray, tables, names,
                                  control: StepControl) -> Result:
    """The trajectory of ``cm`` driven by ``tables`` (:class:`~lagcodegen.solvers.inputs.InputSet`)
    and its sensitivities along ``names`` with the step control ``control`` (as a Taylor
    sensitivity run without tables reports them; statistics summed over the segments)."""
    c = control
    max_steps = c.max_steps
    from ..cvode.sensitivity import check_inputs, directions
    check_inputs(*directions(cm, names, defer=True)[:2], tables)  # before anything is built
    module = series_variational_module(cm, names, tuple(tables.names))
    opt, keep = module.new_options(rtol=c.rtol, atol=c.atol, errcon=c.errcon, max_step=c.max_step,
                                   max_steps=max_steps, order=c.order, max_wall=c.max_wall)
    ny, ns = module.ny, module.ns

    def segment(seg, start, pseg, budget):
        y0, s0 = start
        opt.max_steps = int(budget)
        res = module.solve(opt, seg, y0, pseg, s0=s0)
        if not res.t.size:
            return res, start
        return res, (np.ascontiguousarray(res.y[-1]), np.ascontiguousarray(res.sensitivities[-1, :, :ny]))

    y = np.ascontiguousarray(y, dtype=float)  # a rotation's s0 (generalized speeds): at this initial state
    start = (y, np.ascontiguousarray(module.initial_sensitivities(y, t[0], p).reshape(ns, ny)))
    res = run_segments(cm, np.ascontiguousarray(t, dtype=float), p, tables, start, segment,
                       max_steps=int(max_steps), output_names=module.output_names)
    del keep  # the tolerances opt pointed into: alive until here
    return res


def run_taylor_sensitivity_inputs_ensemble(cm, t: np.ndarray, Y: np.ndarray, P: np.ndarray, inputs: list,
                                           control: StepControl, recording: Recording):
    """The members (rows of Y, P), member i driven by the input tables ``inputs[i]``, with the
    sensitivities ``recording.sensitivities`` and the step control ``control``: each member
    :func:`run_taylor_sensitivity_inputs` (its own options struct; the module of every set of inputs
    built before the threads start), gathered by
    :func:`lagcodegen.solvers.ensemble_sensitivities.ensemble_of_runs`."""
    from ..base import tolerances
    from ..cvode.sensitivity import check_inputs, directions
    from ..ensemble_sensitivities import ensemble_of_runs
    names = recording.sensitivities
    parsed, which, _ = directions(cm, names, defer=True)
    for tables in inputs:
        check_inputs(parsed, which, tables)
        series_variational_module(cm, names, tuple(tables.names))
    control = control.with_tolerances(*tolerances(control.rtol, control.atol, cm.ny, scalar=True))  # as simulate()
    t = np.ascontiguousarray(t, dtype=float)

    def member_run(i, y0, p):
        return run_taylor_sensitivity_inputs(cm, t, y0, p, inputs[i], names, control)

    return ensemble_of_runs(cm, t, Y, P, parsed, member_run, threads=recording.threads, save=recording.save,
                            progress=recording.progress, method="taylor")
