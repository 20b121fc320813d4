"""The IDA family's ensemble runner: the options struct of the runtime's ``lcg_ida_solve_many``
built as the single-run driver gets it, and one call over all members."""

from __future__ import annotations

import numpy as np

from ...codegen.signatures import IDA_OPTIONS
from ..base import native_options
from ..cvode.ensemble import member_events
from ..ensemble_run import run_native
from ..request import GGLForm, Layout, Recording, RunArrays, StepControl, option_fields
from .native import ALGEBRAIC_ATOL


def ensemble_ggl(sim, t, Y, P, control: StepControl, form: GGLForm, recording: Recording):
    """The members of the GGL form of ``sim``: rows of Y are (yy0, yp0), ``control.atol`` one value
    per unknown; ``recording.roots``: locate the compiled events in each member."""
    n, ng, J, JH = sim.n, sim.info.ng, sim.info.J, sim.info.JH
    keep: list = []
    opt = native_options(sim.ffi, sim.ida_options_type, control.atol, keep, calc_ic=1, ic_alg_atol=ALGEBRAIC_ATOL,
                         **option_fields(IDA_OPTIONS, control, form, recording))
    row_names = list(sim.state_names) + [f"_lambda_{j}" for j in range(J)] + [f"mu_{k}" for k in range(JH)]
    layout = Layout(nrow=ng, nout=len(sim.info.output_names), state_names=sim.state_names,
                    output_names=sim.output_names, row_names=row_names, param_names=sim.param_names,
                    extra_outputs={f"mu_{k}": sim.ny + J + k for k in range(JH)}, method="bdf",
                    formulation=sim.formulation, n_coordinates=n)
    arrays = RunArrays(t, np.ascontiguousarray(Y[:, :ng]), P, np.ascontiguousarray(Y[:, ng:]))
    return run_native(sim.ffi, sim.ida_solve_many, sim.ida_ensemble_type, opt, arrays, layout,
                      recording.replace(events=member_events(sim, recording), roots=None), poll=sim.compiled.poll)
