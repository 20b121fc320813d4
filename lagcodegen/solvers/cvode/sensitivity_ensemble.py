"""Ensembles with forward sensitivities on CVODE: every member one call of the sensitivity driver
(:func:`lagcodegen.solvers.cvode.sensitivity.solve_sensitivities`, its own SUNDIALS context),
spread over threads and gathered by :func:`lagcodegen.solvers.ensemble_sensitivities.ensemble_of_runs`
(each member bit-identical to its run alone; Ctrl-C keeps the members that finished)."""

from __future__ import annotations

import numpy as np

from ..ensemble_result import EnsembleResult
from ..ensemble_sensitivities import ensemble_of_runs
from ..request import Recording, StepControl
from .sensitivity import directions, functions, solve_sensitivities
from .sensitivity_events import gradients

#: The sensitivity driver's statistics behind the ensemble's per-member counts (COUNT_NAMES).
def ensemble_sensitivities(cm, t: np.ndarray, Y: np.ndarray, P: np.ndarray, control: StepControl,
                           recording: Recording) -> EnsembleResult:
    """The members (rows of Y, P) of the ODE of ``cm`` with the sensitivities
    ``recording.sensitivities`` (checked once), each one run of :func:`solve_sensitivities` with the
    step control ``control`` and ``recording`` (events: located in every member, as
    :func:`ensemble_of_runs` says; ``save``, ``threads``, ``progress``: the ensemble's)."""
    names = directions(cm, recording.sensitivities, defer=True)[0]
    functions(cm)  # built once, before the threads start
    if recording.events is not None:
        gradients(cm, recording.events)  # the event functions' derivatives too
    member = recording.replace(sensitivities=names)

    def member_run(i, y0, p):
        return solve_sensitivities(cm, t, y0, p, control, member)

    return ensemble_of_runs(cm, t, Y, P, names, member_run, threads=recording.threads, save=recording.save,
                            progress=recording.progress, method=control.method)


def ensemble_sensitivities_inputs(family, cm, t: np.ndarray, Y: np.ndarray, P: np.ndarray, control: StepControl,
                                  inputs: list, recording: Recording) -> EnsembleResult:
    """The members (rows of Y, P) of the ODE of ``cm``, member i driven by the input tables
    ``inputs[i]`` (:class:`~lagcodegen.solvers.inputs.InputSet`), with the sensitivities
    ``recording.sensitivities``: each member the run :func:`.sensitivity.run` makes of it alone
    (the options of the resolved solver ``family``, the tolerances of ``control``), so its states
    and sensitivities are bit-identical to that run's. A direction along an input of any member's
    tables is refused before anything runs."""
    from ..base import tolerances
    from .sensitivity import check_inputs, run
    names, which, _ = directions(cm, recording.sensitivities, defer=True)
    for tables in inputs:
        check_inputs(names, which, tables)
    rtol, atol = tolerances(control.rtol, control.atol, cm.ny, scalar=True)  # as simulate() resolves them
    functions(cm)  # built once, before the threads start

    def member_run(i, y0, p):
        return run(family, cm, t, y0, p, rtol, atol, names, inputs=inputs[i])

    return ensemble_of_runs(cm, t, Y, P, names, member_run, threads=recording.threads, save=recording.save,
                            progress=recording.progress, method=control.method)
