"""The CVODE family's ensemble runners: the options struct of the runtime's ``lcg_cvode_solve_many``
(the ODE of a scene) or ``lcg_cvc_solve_many`` (index-1 constrained systems) built exactly as the
single-run drivers get it (members bit-identical to single runs), and one call over all members
(:func:`~lagcodegen.solvers.ensemble_run.run_native`)."""

from __future__ import annotations

import numpy as np

from ..base import METHODS, native_options, tolerances
from ..inputs import fill_inputs
from ..ensemble_run import event_arrays, run_native


def ensemble_ode(cm, t, Y, P, rtol, atol, opts: dict, *, max_wall: float, threads, save, progress, events=None,
                 max_events: int = 64, inputs=None):
    """The members (rows of Y, P) of the ODE of ``cm``; ``opts`` the resolved driver options
    (:meth:`CVODE._ode_options <lagcodegen.solvers.cvode.CVODE>`); ``events``
    (:class:`~.events.CompiledEvents`) located in every member (its stats ``events`` and
    ``terminated``; a terminal event's time and state are the member's ``t_reached`` and final
    state); ``inputs``: one :class:`~lagcodegen.solvers.inputs.InputSet` per member, or None."""
    rtol, atol_arr = tolerances(rtol, atol, cm.ny)
    band = opts.get("band")
    keep: list = []
    opt = native_options(cm.ffi, cm.options_type, atol_arr, keep, method=METHODS[opts["method"]],
                         jacobian=int(opts["jacobian"]), rtol=rtol, max_steps=opts["max_steps"],
                         first_step=opts["first_step"], max_step=opts["max_step"], min_step=opts["min_step"],
                         max_order=opts["max_order"],
                         linear_solver=1 if band else 2 if opts.get("fixedpoint") else 0,
                         mupper=band[0] if band else 0, mlower=band[1] if band else 0)
    opt.max_wall = max_wall
    setup = None
    if inputs is not None:
        P = np.ascontiguousarray(np.broadcast_to(P, (Y.shape[0], cm.code.np)))  # each member its row (and tables)

        def setup(e, keep):
            e.inputs = fill_inputs(cm.ffi, inputs, keep)
    return run_native(cm.ffi, cm.native_solve_many, cm.ensemble_type, opt, t=t, Y0=Y, P=P, setup=setup,
                      nrow=cm.ny, nout=cm.code.nout, state_names=cm.state_names, output_names=cm.output_names,
                      row_names=cm.state_names, save=save, threads=threads, progress=progress, poll=cm.poll,
                      method=opts["method"], n_coordinates=cm.n, param_names=cm.param_names,
                      events=None if events is None else (events.directions, events.terminal),
                      max_events=max_events, roots=None if events is None else events.table)


def ensemble_index1(sim, t, Y, P, rtol, atol, family, method: str, projection: bool, alpha: float, beta: float,
                    roots: bool, max_events: int, *, threads, save, progress):
    """The members (consistent states, rows of Y) of an index-1 constrained system ``sim``."""
    n = sim.n
    rtol, atol_arr = tolerances(rtol, atol, 2 * n)
    keep: list = []
    opt = native_options(sim.ffi, sim.cvc_options_type, atol_arr, keep, method=METHODS[method], rtol=rtol,
                         alpha=alpha, beta=beta, projection=int(projection), proj_tol=family.proj_tol,
                         proj_maxit=family.proj_maxit, proj_err=1, max_steps=int(family.max_steps),
                         first_step=family.first_step, max_step=family.max_step, min_step=family.min_step,
                         max_order=family.max_order, roots=int(roots), max_wall=float(family.max_wall))
    return run_native(sim.ffi, sim.cvc_solve_many, sim.cvc_ensemble_type, opt, t=t, Y0=Y, P=P, nrow=2 * n,
                      nout=len(sim.info.output_names), state_names=sim.state_names, output_names=sim.output_names,
                      row_names=list(sim.state_names), save=save, threads=threads, progress=progress,
                      poll=sim.compiled.poll, events=event_arrays(sim.info.events), max_events=max_events,
                      method=method, formulation=sim.formulation, n_coordinates=n, param_names=sim.param_names)
