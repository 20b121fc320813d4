"""The integrator object with forward sensitivities (:class:`SensitivityIntegrator`, made by
``sim.integrator(..., sensitivities=[...])``): an :class:`~.integrator.Integrator` whose C
stepper carries the sensitivities s = dy/dtheta of the directions ``sensitivity_names`` along
with the state: on CVODE ``lcg_cvsens_stepper`` (:mod:`lagcodegen.solvers.cvode.sensitivity_stepper`),
on the Taylor method the Taylor stepper on the variational jet
(:class:`lagcodegen.solvers.taylor.stepper.TaylorSensitivityStepper`, whose memory (t, y, s, p)
the views are made on).

``sensitivities`` is a writable (ny, ns) view of the stepper's memory (entry [i, j] = d y_i / d
theta_j): set it (e.g. to zero, or to unit columns) and the next call restarts from it, as the
state and parameters do. ``propagate_grid`` returns ``(states, sensitivities)``: the states
(len(times), ny) as the plain integrator's, and the sensitivities (len(times), ny, ns) at the
same times. Events carry their times' sensitivities (``t_sensitivity``, ``y_sensitivity``).
"""

from __future__ import annotations

import numpy as np

from ..errors import LagcodegenError
from ..model.events import EventRecord
from .integrator import Integrator


class SensitivityIntegrator(Integrator):
    """An :class:`~.integrator.Integrator` with forward sensitivities (module docstring)."""

    def __init__(self, stepper, mem: np.ndarray, *, state_names, param_names, family: str):
        super().__init__(stepper, mem, state_names=state_names, param_names=param_names, family=family)
        params_at = getattr(stepper, "params_at", None)
        if params_at is not None:  # the stepper's memory holds the sensitivities between y and p
            self._params = mem[params_at:]
        self.sensitivity_names = list(stepper.names)
        self._sens = stepper.sens  # (ns, ny), the C memory

    @property
    def sensitivities(self) -> np.ndarray:
        """d y_i / d theta_j at :attr:`time`, shape (ny, ns): a writable view (no copy) of the C
        memory; a write takes effect at the next call (CVODE restarts there)."""
        return self._sens.T

    @sensitivities.setter
    def sensitivities(self, value) -> None:
        try:
            arr = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            raise LagcodegenError(f"sensitivities must be an array of numbers, got {value!r:.60}") from None
        shape = (self._ny, len(self.sensitivity_names))
        if arr.shape != shape:
            raise LagcodegenError(f"sensitivities has shape {arr.shape}, expected {shape} (states "
                                  f"{', '.join(self.state_names)} by directions {', '.join(self.sensitivity_names)})")
        if not np.all(np.isfinite(arr)):
            raise LagcodegenError("sensitivities has non-finite values")
        self._sens.T[...] = arr

    def sensitivity(self, state: str, direction: str) -> float:
        """d state / d direction at :attr:`time`."""
        if state not in self.state_names:
            raise LagcodegenError(f"{state!r} is not a state ({', '.join(self.state_names)})")
        if direction not in self.sensitivity_names:
            raise LagcodegenError(f"{direction!r} is not a sensitivity direction of this integrator "
                                  f"({', '.join(self.sensitivity_names)})")
        return float(self._sens[self.sensitivity_names.index(direction), self.state_names.index(state)])

    def propagate_grid(self, times, *, out: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """As :meth:`Integrator.propagate_grid <lagcodegen.simulation.integrator.Integrator.propagate_grid>`,
        returning ``(states (nt, ny), sensitivities (nt, ny, ns))`` (the rows reached)."""
        times = self._times(times)
        self._stepper.sout = np.empty((times.shape[0], len(self.sensitivity_names), self._ny))
        y = super().propagate_grid(times, out=out)
        return y, self._stepper.sout[:y.shape[0]].transpose(0, 2, 1)

    def _collect(self) -> EventRecord | None:
        count, terminated, _ = self._stepper.event_arrays()
        recs = self._stepper.event_records(self.state_names)
        self.events = recs
        self.stopped_by = recs[-1] if terminated and recs else None
        return self.stopped_by

    def __repr__(self) -> str:
        state = "closed" if self.closed else f"t = {self.time:.6g}"
        return f"<Integrator {self.family}, {self._ny} states, {len(self.sensitivity_names)} sensitivities, {state}>"
