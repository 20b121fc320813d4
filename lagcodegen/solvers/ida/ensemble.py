"""The IDA family's ensemble runner: the options struct of the runtime's ``lcg_ida_solve_many``
built as the single-run driver gets it, and one call over all members."""

from __future__ import annotations

import numpy as np

from ..base import native_options
from ..ensemble_run import event_arrays, run_native
from .native import ALGEBRAIC_ATOL


def ensemble_ggl(sim, t, Y, P, rtol: float, atol_arr: np.ndarray, family, jacobian: bool, roots: bool,
                 max_events: int, *, threads, save, progress):
    """The members of the GGL form of ``sim``: rows of Y are (yy0, yp0), ``atol_arr`` one value
    per unknown."""
    n, ng, J, JH = sim.n, sim.info.ng, sim.info.J, sim.info.JH
    keep: list = []
    opt = native_options(sim.ffi, sim.ida_options_type, atol_arr, keep, rtol=rtol,
                         suppress_alg=int(bool(family.suppress_alg)), jacobian=int(jacobian), calc_ic=1,
                         ic_alg_atol=ALGEBRAIC_ATOL, stop_at_outputs=int(bool(family.stop_at_outputs)),
                         max_steps=int(family.max_steps), first_step=family.first_step, max_step=family.max_step,
                         min_step=family.min_step, max_order=family.max_order, roots=int(roots),
                         max_wall=float(family.max_wall))
    row_names = list(sim.state_names) + [f"_lambda_{j}" for j in range(J)] + [f"mu_{k}" for k in range(JH)]
    return run_native(sim.ffi, sim.ida_solve_many, sim.ida_ensemble_type, opt, t=t,
                      Y0=np.ascontiguousarray(Y[:, :ng]), P=P, nrow=ng, nout=len(sim.info.output_names),
                      state_names=sim.state_names, output_names=sim.output_names, row_names=row_names, save=save,
                      threads=threads, progress=progress, poll=sim.compiled.poll,
                      YP0=np.ascontiguousarray(Y[:, ng:]), events=event_arrays(sim.info.events),
                      max_events=max_events, extra_outputs={f"mu_{k}": 2 * n + J + k for k in range(JH)},
                      method="bdf", formulation=sim.formulation, n_coordinates=n, param_names=sim.param_names)
