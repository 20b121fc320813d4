"""Ensembles with forward sensitivities on CVODE: every member one call of the sensitivity driver
(:func:`lagcodegen.solvers.cvode.sensitivity.solve_sensitivities`, its own SUNDIALS context),
spread over threads and gathered by :func:`lagcodegen.solvers.ensemble_sensitivities.ensemble_of_runs`
(each member bit-identical to its run alone; Ctrl-C keeps the members that finished)."""

from __future__ import annotations

import numpy as np

from ..ensemble_result import EnsembleResult
from ..ensemble_sensitivities import ensemble_of_runs
from .sensitivity import directions, functions, solve_sensitivities
from .sensitivity_events import gradients

#: The sensitivity driver's statistics behind the ensemble's per-member counts (COUNT_NAMES).
def ensemble_sensitivities(cm, t: np.ndarray, Y: np.ndarray, P: np.ndarray, rtol: float, atol, names, *,
                           threads, save, progress, **driver) -> EnsembleResult:
    """The members (rows of Y, P) of the ODE of ``cm`` with the sensitivities ``names`` (checked
    once); ``driver``: the keywords of :func:`solve_sensitivities` (method, errcon, jacobian,
    budgets, events: located in every member, as :func:`ensemble_of_runs` says)."""
    names = directions(cm, names)[0]
    functions(cm)  # built once, before the threads start
    if driver.get("events") is not None:
        gradients(cm, driver["events"])  # the event functions' derivatives too

    def member_run(i, y0, p):
        return solve_sensitivities(cm, t, y0, p, names, rtol=rtol, atol=atol, **driver)

    return ensemble_of_runs(cm, t, Y, P, names, member_run, threads=threads, save=save,
                            progress=progress, method=driver.get("method", ""))


def ensemble_sensitivities_inputs(family, cm, t: np.ndarray, Y: np.ndarray, P: np.ndarray, rtol: float, atol,
                                  names, inputs: list, *, threads, save, progress, method: str) -> EnsembleResult:
    """The members (rows of Y, P) of the ODE of ``cm``, member i driven by the input tables
    ``inputs[i]`` (:class:`~lagcodegen.solvers.inputs.InputSet`), with the sensitivities
    ``names``: each member the run :func:`.sensitivity.run` makes of it alone (the options of the
    resolved solver ``family``), so its states and sensitivities are bit-identical to that run's.
    A direction along an input of any member's tables is refused before anything runs."""
    from ..base import tolerances
    from .sensitivity import check_inputs, run
    names, which, _ = directions(cm, names)
    for tables in inputs:
        check_inputs(names, which, tables)
    rtol, atol = tolerances(rtol, atol, cm.ny, scalar=True)  # as simulate() resolves them
    functions(cm)  # built once, before the threads start

    def member_run(i, y0, p):
        return run(family, cm, t, y0, p, rtol, atol, names, errcon=bool(family.sensitivity_errcon),
                   inputs=inputs[i])

    return ensemble_of_runs(cm, t, Y, P, names, member_run, threads=threads, save=save, progress=progress,
                            method=method)
