"""The integrator object of a compiled model (:class:`Integrator`, made by
:meth:`lagcodegen.simulation.ode.CompiledModel.integrator`): an integration that lives between
calls, for stepwise and repeated use (closed loops, co-simulation, many short runs).

It holds one float64 array ``(t, y, p)`` that the family's C stepper works on in place
(``lcg_taylor_stepper``, ``lcg_cvode_stepper`` of lagcodegen/runtime/); ``state`` and ``params``
are numpy views of it, so reading and writing them copies nothing, and a write takes effect at the
next call (the Taylor stepper recomputes its run constants of new parameters; CVODE restarts from
the written state, as a new run would). Inputs (:meth:`lagcodegen.model.model.Model.input`) are
run-time parameters: a controller writes ``integ.params[k]`` and calls :meth:`propagate_for`.
Sizes and dtypes are checked once, when the object is made; each call is one C call.
"""

from __future__ import annotations

import math
import weakref

import numpy as np

from ..codes import Flag
from ..errors import LagcodegenError, SingularMassMatrixError, SolverError
from ..model.events import EventRecord, records
from ..solvers import control
from ..solvers.base import message

_BAD_INPUT = int(Flag.BAD_INPUT)
_CANCELLED = int(Flag.CANCELLED)
_INF = math.inf
_F64 = np.dtype(np.float64)
_NDARRAY, _empty = np.ndarray, np.empty


def _closed(*args):
    raise LagcodegenError("the integrator is closed (Integrator.close or the end of its with block): make a new one")


class Integrator:
    """An integration of a compiled model that lives between calls.

    Made once by ``sim.integrator(q0=..., v0=..., method=..., rtol=..., atol=..., params=...,
    events=...)``; then :meth:`propagate_until`, :meth:`propagate_for`, :meth:`propagate_grid`,
    :meth:`step` advance it. ``state`` (y = (q, q', z)) and ``params`` (the run-time parameters,
    inputs among them) are writable numpy views of the memory the C code integrates; ``time`` is
    the current time. Not reentrant: one call at a time. Free its C memory with :meth:`close` (or a
    ``with`` block; the garbage collector does it otherwise).
    """

    def __init__(self, stepper, mem: np.ndarray, *, state_names, param_names, family: str):
        self._stepper = stepper
        self._mem = mem
        ny = len(state_names)
        self.state_names = list(state_names)
        self.param_names = list(param_names)
        self.family = family
        self._state = mem[1:1 + ny]
        self._params = mem[1 + ny:]
        self._ny = ny
        self._until = stepper.until
        self._grid = stepper.grid
        self._step = stepper.step
        self._ffi = stepper.ffi
        self._t = stepper.ffi.from_buffer("double[]", mem)  # mem[0] read and written as a Python float
        self._from_buffer = stepper.ffi.from_buffer
        self._last_arrays = ((None, None), (None, None))  # propagate_grid's times and out, and their cdata
        self._ne = len(stepper.events)
        self.events: list[EventRecord] = []  # the events located by the last call
        self.stopped_by: EventRecord | None = None  # the terminal event that ended the last call, or None
        self._finalizer = weakref.finalize(self, stepper.free)

    # ------------------------------------------------------------------ views
    @property
    def state(self) -> np.ndarray:
        """The state y = (q, q', z) at :attr:`time`: a writable view (no copy) of the C memory."""
        return self._state

    @state.setter
    def state(self, value) -> None:
        self._state[...] = self._values(value, self._ny, "state", self.state_names)

    @property
    def params(self) -> np.ndarray:
        """The run-time parameters (inputs among them), in :attr:`param_names` order: a writable view
        (no copy) of the C memory; a write takes effect at the next call."""
        return self._params

    @params.setter
    def params(self, value) -> None:
        if isinstance(value, dict):
            for name, v in value.items():
                self.set_param(name, v)
            return
        self._params[...] = self._values(value, self._params.size, "params", self.param_names)

    def set_param(self, name: str, value: float) -> None:
        """Set the run-time parameter (or input) ``name``."""
        try:
            k = self.param_names.index(name)
        except ValueError:
            raise LagcodegenError(f"{name!r} is not a run-time parameter of this model (run-time parameters: "
                                  f"{', '.join(self.param_names) or 'none'})") from None
        v = float(value)
        if not math.isfinite(v):
            raise LagcodegenError(f"parameter {name!r} must be finite, got {value!r}")
        self._params[k] = v

    @property
    def time(self) -> float:
        """The current time; setting it restarts the integration there."""
        return self._t[0]

    @time.setter
    def time(self, value: float) -> None:
        try:
            v = float(value)
        except (TypeError, ValueError):
            raise LagcodegenError(f"time must be a number, got {value!r:.60}") from None
        if not math.isfinite(v):
            raise LagcodegenError(f"time must be finite, got {value!r}")
        self._t[0] = v

    @staticmethod
    def _values(value, size: int, what: str, names) -> np.ndarray:
        try:
            arr = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            raise LagcodegenError(f"{what} must be {size} numbers, got {value!r:.60}") from None
        if arr.shape != (size,):
            raise LagcodegenError(f"{what} has shape {arr.shape}, expected ({size},): {', '.join(names)}")
        if not np.all(np.isfinite(arr)):
            raise LagcodegenError(f"{what} has non-finite values")
        return arr

    # ------------------------------------------------------------------ advancing
    def propagate_until(self, t: float) -> EventRecord | None:
        """Advance to time ``t`` (not before :attr:`time`), stopping exactly there. Returns the
        terminal event that stopped it earlier (also :attr:`stopped_by`), else None."""
        try:
            flag = self._until(t)
        except TypeError:
            raise LagcodegenError(f"t must be a number, got {t!r:.60}") from None
        if flag:
            self._failed(flag)
        if self._ne:
            return self._collect()
        return None

    def propagate_for(self, dt: float) -> EventRecord | None:
        """Advance by ``dt`` >= 0 (see :meth:`propagate_until`)."""
        try:
            flag = self._until(self._t[0] + dt)
        except TypeError:
            raise LagcodegenError(f"dt must be a number, got {dt!r:.60}") from None
        if flag:
            self._failed(flag)
        if self._ne:
            return self._collect()
        return None

    def propagate_grid(self, times, *, out: np.ndarray | None = None) -> np.ndarray:
        """Advance to ``times[-1]`` and return the states at ``times`` (increasing, from :attr:`time`
        on; a time equal to :attr:`time` gives the current state), one row each (into ``out``, a
        C-contiguous float64 array of shape (len(times), ny), if given). A terminal event stops it:
        the rows reached (see :attr:`stopped_by`)."""
        if type(times) is not _NDARRAY or times.dtype is not _F64 or times.ndim != 1:
            times = self._times(times)
        nt = times.shape[0]
        if out is not None and (type(out) is not _NDARRAY or out.dtype is not _F64 or out.shape != (nt, self._ny)):
            raise LagcodegenError(f"out must be a float64 array of shape ({nt}, {self._ny})")
        fb = self._from_buffer
        try:
            if out is None:  # new arrays: converted as they come
                out = _empty((nt, self._ny))
                flag = self._grid(nt, fb("double[]", times), fb("double[]", out))
            else:
                # the caller's preallocated arrays: their cdata kept while the same arrays come back
                # (no conversion per call; the cdata holds its array, so no other array can take
                # its place at the same address)
                (last_times, times_ptr), (last_out, out_ptr) = self._last_arrays
                if times is not last_times or out is not last_out:
                    times_ptr = times_ptr if times is last_times else fb("double[]", times)
                    out_ptr = out_ptr if out is last_out else fb("double[]", out)
                    self._last_arrays = ((times, times_ptr), (out, out_ptr))
                flag = self._grid(nt, times_ptr, out_ptr)
        except (ValueError, BufferError):  # not contiguous
            if out is not None and not out.flags.c_contiguous:
                raise LagcodegenError("out must be C-contiguous") from None
            return self.propagate_grid(np.ascontiguousarray(times), out=out)
        if flag:
            if nt == 0:
                raise LagcodegenError("propagate_grid needs at least one time")
            self._failed(flag)
        if self._ne:
            self._collect()
            done = self._stepper.stats.nt_done
            if done < nt:
                return out[:done]
        return out

    @staticmethod
    def _times(times) -> np.ndarray:
        try:
            arr = np.ascontiguousarray(times, dtype=float)
        except (TypeError, ValueError):
            raise LagcodegenError(f"times must be an array of numbers, got {times!r:.60}") from None
        if arr.ndim != 1:
            raise LagcodegenError(f"times must be one-dimensional, got shape {arr.shape}")
        return arr

    def step(self, t_limit: float = _INF) -> float:
        """One step of the integrator (Taylor: one step of its rule; CVODE: one internal step),
        ending at ``t_limit`` at the latest; returns the new :attr:`time`."""
        try:
            flag = self._step(t_limit)
        except TypeError:
            raise LagcodegenError(f"t_limit must be a number, got {t_limit!r:.60}") from None
        if flag:
            self._failed(flag)
        if self._ne:
            self._collect()
        return self._t[0]

    @property
    def impacts(self):
        """Systems with contacts: the contact log of the last call (impacts, switches, releases;
        :class:`~lagcodegen.simulation.constrained_impacts.ContactLog`), else None."""
        return getattr(self._stepper, "impacts", None)

    @property
    def multipliers(self) -> np.ndarray:
        """The GGL form's multipliers (lambda, then mu) at :attr:`time` (a copy); IDA only."""
        if self._stepper.handle is None:
            _closed()
        if not hasattr(self._stepper, "multipliers"):
            raise LagcodegenError("multipliers are unknowns of the GGL form only (compile_constrained(..., 'ggl'))")
        return self._stepper.multipliers()

    # ------------------------------------------------------------------ outcome
    @property
    def stats(self) -> dict:
        """Statistics of the last call (steps, evaluations, step sizes, ...)."""
        if self._stepper.handle is None:
            _closed()
        return self._stepper.stats_dict()

    def _collect(self) -> EventRecord | None:
        count, terminated, (tt, yy, which, direction) = self._stepper.event_arrays()
        k = min(count, tt.shape[0])
        recs = records(self._stepper.events, tt[:k], yy[:k], which[:k], direction[:k], self.state_names, self._ny)
        self.events = recs
        self.stopped_by = recs[-1] if terminated and recs else None
        return self.stopped_by

    def _failed(self, flag: int):
        st = self._stepper.stats
        detail = self._ffi.string(st.message).decode(errors="replace")
        if flag == _CANCELLED:
            control.raise_pending()
        if flag == _BAD_INPUT:
            raise LagcodegenError(detail or "bad arguments")
        name = {"taylor": "Taylor", "ida": "IDA"}.get(self.family, "CVODE")
        text = message(flag, st.model_error, detail, name, t=st.t_reached)
        cls = SingularMassMatrixError if st.model_error == 1 else SolverError
        raise cls(text, t=self._t[0], flag=flag)

    # ------------------------------------------------------------------ lifetime
    def close(self) -> None:
        """Free the C memory now (idempotent); later calls raise LagcodegenError. The views stay
        readable (they belong to this object's array)."""
        self._until = self._grid = self._step = _closed
        self._finalizer()

    @property
    def closed(self) -> bool:
        return not self._finalizer.alive

    def __enter__(self) -> "Integrator":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __reduce__(self):
        raise LagcodegenError("an integrator object holds C memory and does not pickle: pickle the compiled "
                              "model and make the integrator where it is used")

    def __repr__(self) -> str:
        state = "closed" if self.closed else f"t = {self.time:.6g}"
        return f"<Integrator {self.family}, {self._ny} states, {state}>"
