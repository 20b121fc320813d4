"""Prepared runs made explicit: :meth:`CompiledModel.prepare <lagcodegen.simulation.ode.CompiledModel.prepare>`
fixes the output times, the solver family and its options and the tolerances of a run once, and
returns a :class:`PreparedRun` to call with initial states and parameters alone.

A prepared run is the run ``simulate()``'s fast path calls (:mod:`.fastpath`): where the family
prepares the run (CVODE's native driver, also with forward sensitivities; the Taylor family, also
with events) its options struct, directions and arrays are made once; elsewhere (input tables,
array tolerances, scikit-sundae) each call runs ``simulate()``'s full path with the options
fixed here. Either way a call returns what ``simulate(t, ..., **options)`` returns, bit for bit,
with the same checks and errors for what it brings anew (initial state, parameters)."""

from __future__ import annotations

import numpy as np

from ..result import Result
from ..solvers.base import tolerances
from ..solvers.registry import resolve
from ..util import output_times
from .fastpath import FastRun, family_run, preparable


class PreparedRun:
    """``simulate(t, solver=..., rtol=..., atol=..., events=..., **options)`` of one compiled
    scene with everything but the initial state and the parameters fixed.

    ``t`` is the output times (checked once, kept read-only); ``prepared`` says whether the
    family prepared the run (else each call takes ``simulate()``'s full path with these options).
    Call it with ``q0``, ``v0`` (or ``y0``), ``z0``, ``params`` and ``raise_on_error`` as
    :meth:`~lagcodegen.simulation.ode.CompiledModel.simulate` takes them."""

    __slots__ = ("_cm", "t", "_fast", "_solver", "_rtol", "_atol", "_events", "_options")

    def __init__(self, cm, t, *, solver, rtol, atol, events, options: dict):
        times = np.array(output_times(t), dtype=np.float64)
        times.flags.writeable = False
        self._cm, self.t = cm, times
        self._solver, self._rtol, self._atol, self._events = solver, rtol, atol, tuple(events)
        self._options = dict(options)
        # every option checked now: a bad keyword or value raises here, not at the first call
        rtol_f, _ = tolerances(rtol, atol, cm.ny, scalar=True)
        resolve("ode", solver, {k: v for k, v in options.items() if k != "inputs"}, cm.method_size, rtol_f,
                costs=cm.method_costs)
        run = family_run(cm, solver, rtol, atol, options, self._events) if preparable(rtol, atol, options) else None
        self._fast = None if run is None else FastRun(cm, run, rtol, atol, options)

    @property
    def prepared(self) -> bool:
        """True where the family prepared the run (its options struct and arrays made once)."""
        return self._fast is not None

    def __call__(self, *, q0=None, v0=None, y0=None, z0=None, params: dict | None = None,
                 raise_on_error: bool = True) -> Result:
        """The run from this initial state with these parameters (defaults from the model):
        ``simulate()``'s result for the prepared times and options, bit for bit."""
        if self._fast is not None:
            return self._fast(self._cm, self.t, q0, v0, y0, z0, params, raise_on_error)
        return self._cm.simulate(self.t, q0, v0, y0=y0, z0=z0, params=params, solver=self._solver, rtol=self._rtol,
                                 atol=self._atol, events=self._events, raise_on_error=raise_on_error,
                                 **self._options)

    def __repr__(self) -> str:
        kind = "prepared" if self.prepared else "full path"
        return (f"PreparedRun({self._cm.code.model_name or 'model'}, {self.t.size} output times "
                f"{self.t[0]:g}..{self.t[-1]:g}, {kind})")
