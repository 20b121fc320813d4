"""The CVODE family's ensemble runners: the options struct of the runtime's ``lcg_cvode_solve_many``
(the ODE of a scene) or ``lcg_cvc_solve_many`` (index-1 constrained systems) built exactly as the
single-run drivers get it (members bit-identical to single runs), and one call over all members
(:func:`~lagcodegen.solvers.ensemble_run.run_native`)."""

from __future__ import annotations

import numpy as np

from ...codegen.signatures import CVC_OPTIONS, CVODE_OPTIONS
from ..base import native_options, tolerances
from ..inputs import fill_inputs
from ..ensemble_run import run_native
from ..request import Index1Form, Layout, Recording, RunArrays, StepControl, option_fields


def ensemble_ode(cm, t, Y, P, control: StepControl, recording: Recording, inputs=None):
    """The members (rows of Y, P) of the ODE of ``cm`` with the step control ``control`` (as
    :meth:`CVODE.ode_control <lagcodegen.solvers.cvode.CVODE>` resolves it); ``recording.events``
    (:class:`~.events.CompiledEvents`) located in every member (its stats ``events`` and
    ``terminated``; a terminal event's time and state are the member's ``t_reached`` and final
    state); ``inputs``: one :class:`~lagcodegen.solvers.inputs.InputSet` per member, or None."""
    c = control.with_tolerances(*tolerances(control.rtol, control.atol, cm.ny))
    keep: list = []
    opt = native_options(cm.ffi, cm.options_type, c.atol, keep, **option_fields(CVODE_OPTIONS, c))
    setup = None
    if inputs is not None:
        P = np.ascontiguousarray(np.broadcast_to(P, (Y.shape[0], cm.code.np)))  # each member its row (and tables)

        def setup(e, keep):
            e.inputs = fill_inputs(cm.ffi, inputs, keep)
    events = recording.events
    layout = Layout(nrow=cm.ny, nout=cm.code.nout, state_names=cm.state_names, output_names=cm.output_names,
                    row_names=cm.state_names, param_names=cm.param_names, method=c.method, n_coordinates=cm.n)
    recording = recording.replace(events=None if events is None else events.events,
                                  roots=None if events is None else events.table)
    return run_native(cm.ffi, cm.native_solve_many, cm.ensemble_type, opt, RunArrays(t, Y, P), layout, recording,
                      poll=cm.poll, setup=setup)


def ensemble_index1(sim, t, Y, P, control: StepControl, form: Index1Form, recording: Recording):
    """The members (consistent states, rows of Y) of an index-1 constrained system ``sim`` in the
    index-1 form ``form``; ``recording.roots``: locate the compiled events in each member."""
    n = sim.n
    c = control.with_tolerances(*tolerances(control.rtol, control.atol, sim.ny))
    keep: list = []
    opt = native_options(sim.ffi, sim.cvc_options_type, c.atol, keep, proj_err=1,
                         **option_fields(CVC_OPTIONS, c, form, recording))
    layout = Layout(nrow=sim.ny, nout=len(sim.info.output_names), state_names=sim.state_names,
                    output_names=sim.output_names, row_names=list(sim.state_names), param_names=sim.param_names,
                    method=c.method, formulation=sim.formulation, n_coordinates=n)
    return run_native(sim.ffi, sim.cvc_solve_many, sim.cvc_ensemble_type, opt, RunArrays(t, Y, P), layout,
                      recording.replace(events=member_events(sim, recording), roots=None), poll=sim.compiled.poll)


def member_events(sim, recording: Recording):
    """The events an ensemble of the constrained system ``sim`` records per member: its compiled
    events when it locates them (``recording.roots``), else None."""
    return list(sim.info.events) if recording.roots and sim.info.events else None
