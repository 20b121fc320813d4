"""The integrator object of a constrained system with contacts (inequalities with a restitution,
sec. 4.3): the stepper that :class:`~.integrator.Integrator` drives, each of its calls one run of
the system's impact driver (index-1: lagcodegen/runtime/lcg_imp.c on CVODE; GGL:
lagcodegen/runtime/lcg_imp_ida.c on IDA; impacts located inside the steps and their jumps applied,
persistent contact and release, Coulomb friction) from the integrator's memory ``(t, y, p)``, the
modes of the contacts carried from one call to the next (with friction the driver chooses the
stick/slip modes of those in contact again at the start of a call, from the slip velocities, as at
the start of any run); on the Taylor method each call is one run of the Taylor contact driver
(:mod:`.taylor_impacts`, lagcodegen/runtime/lcg_taylor_imp.c).

A call of ``propagate_grid`` over the times of a ``simulate`` run is that run: the same driver
call, bit-identical. Between calls the integrator starts afresh from the state reached (its step
history is not kept; GGL: the multipliers computed again from the state), as after a written
state; the contacts in persistent contact stay so. What a call
recorded is the integrator's ``events`` and ``impacts`` (a
:class:`~.constrained_impacts.ContactLog`). The impact driver advances to given times only:
``Integrator.step`` (one internal step) is refused by name.
"""

from __future__ import annotations

import numpy as np

from ..errors import LagcodegenError, SingularMassMatrixError, SolverError
from ..solvers.base import ERR_SINGULAR
from ..solvers.request import GGLForm
from .constrained_impacts import ContactLog


class ImpactStepper:
    """The stepper of an :class:`~.integrator.Integrator` over a system with contacts: ``run`` a
    :class:`~.constrained_impacts.ContactRun`, ``mem`` the integrator's array (t, y, p)."""

    def __init__(self, sim, run, mem: np.ndarray):
        self.sim = sim
        self.run = run
        # the driver's family: the Taylor contact driver's "taylor", else IDA (GGL) or CVODE (index-1)
        self.family = getattr(run.runner, "family", None) or ("ida" if isinstance(run.form, GGLForm) else "cvode")
        self.mem = mem
        self.ffi = run.runner.ffi
        self.events = list(sim.info.events) if run.recording.roots else []
        self.ny = sim.ny
        self.handle = True  # None once freed
        self.active = np.zeros(len(run.runner.contacts), dtype=np.intc)  # the contacts' modes between calls
        self.impacts = None  # the ContactLog of the last call
        self._last = None  # the Result of the last call
        self.stats = _Counts()

    def free(self) -> None:
        self.handle = None

    def _advance(self, times: np.ndarray) -> np.ndarray:
        """One driver call from the memory's (t, y) through ``times`` (increasing, after t); the
        memory set to where it ended; the rows at the times reached."""
        if self.handle is None:
            raise LagcodegenError("the integrator is closed")
        mem, ny = self.mem, self.ny
        t0 = float(mem[0])
        tout = np.concatenate([[t0], times])
        p = np.ascontiguousarray(mem[1 + ny:])
        y0 = np.array(mem[1:1 + ny])
        res = self.run.execute(tout, y0, p, active=self.active)
        self._last, self.impacts = res, res.impacts
        if res.t.size:
            mem[0] = res.t[-1]
            mem[1:1 + ny] = res.y[-1]
        if not res.success:
            cls = SingularMassMatrixError if res.stats.get("model_error") == ERR_SINGULAR else SolverError
            raise cls(res.message, t=float(res.stats.get("t_reached", mem[0])), flag=res.status, result=res)
        done = res.t.size if not (res.events and res.events[-1].terminal and res.t[-1] != tout[res.t.size - 1]) \
            else res.t.size - 1
        self.stats.nt_done = max(done - 1, 0)
        return res.y[1:done]

    def until(self, t) -> int:
        t = float(t)
        if not t >= self.mem[0]:
            raise LagcodegenError(f"t = {t!r} is before the integrator's time {self.mem[0]!r}")
        if t > self.mem[0]:
            self._advance(np.array([t]))
        else:
            self._none()
        return 0

    def grid(self, nt: int, times_ptr, out_ptr) -> int:
        if nt == 0:
            raise LagcodegenError("propagate_grid needs at least one time")
        times = np.frombuffer(self.ffi.buffer(times_ptr, nt * 8), dtype=float)
        out = np.frombuffer(self.ffi.buffer(out_ptr, nt * self.ny * 8), dtype=float).reshape(nt, self.ny)
        t0 = float(self.mem[0])
        if not (times[0] >= t0 and np.all(np.diff(times) > 0)):
            raise LagcodegenError("propagate_grid: the times must increase from the integrator's time on")
        first = 1 if times[0] == t0 else 0
        if first:
            out[0] = self.mem[1:1 + self.ny]
        if nt > first:
            rows = self._advance(np.array(times[first:]))
            out[first:first + rows.shape[0]] = rows
            self.stats.nt_done = first + rows.shape[0]
        else:
            self._none()
            self.stats.nt_done = nt
        return 0

    def multipliers(self) -> np.ndarray:
        """Refused by name: each call is a run of its own (GGL: IDA restarted at the call and at
        every switch), whose multipliers are in its outputs, not kept as the integrator's unknowns."""
        raise LagcodegenError("Integrator.multipliers is not available for systems with contacts: each "
                              "propagate call is one run of the impact driver; the contact forces are in "
                              "simulate()'s outputs (res['lambda_ineq_<k>']) and the impulses in integ.impacts")

    def step(self, t_limit) -> int:
        raise LagcodegenError("Integrator.step (one internal step) is not available for systems with contacts: "
                              "the impact driver advances to given times (propagate_for, propagate_until, "
                              "propagate_grid)")

    def _none(self) -> None:
        """A call that does not advance: no events, an empty contact log with the current modes."""
        self._last = None
        contacts = self.run.runner.contacts
        self.impacts = ContactLog([], {k: "contact" if a else "free" for k, a in zip(contacts, self.active)})

    def event_arrays(self):
        """(count, terminated, (t, y, which, direction)) of the last call's events."""
        recs = [] if self._last is None else self._last.events
        ny = self.ny
        tt = np.array([r.t for r in recs], dtype=float)
        yy = np.array([r.y for r in recs], dtype=float).reshape(len(recs), ny)
        which = np.array([r.index for r in recs], dtype=np.intc)
        direction = np.array([r.direction for r in recs], dtype=np.intc)
        terminated = bool(recs) and recs[-1].terminal
        return len(recs), terminated, (tt, yy, which, direction)

    def stats_dict(self) -> dict:
        return {} if self._last is None else dict(self._last.stats)


class _Counts:
    """What the integrator reads of a stepper's statistics struct: the output times done."""

    def __init__(self):
        self.nt_done = 0
