"""Events in runs with forward sensitivities on CVODE: the events record of the sensitivity
driver (``lcg_cvsens_events`` of lcg_cvsens.h, ``lcg_cvsens_solve_events``: root finding on the
state part of the augmented ODE), and
the sensitivities of each event's time from the derivatives of its event function
(``<prefix>_events_grad.c``, :func:`lagcodegen.codegen.events.events_gradient_source`).

At an event g(t_e, y(t_e; theta), theta) = 0; differentiating in a direction theta (implicit
function theorem) with s = dy/dtheta at fixed time:

    dt_e/dtheta = -(dg/dy s + dg/dtheta) / (dg/dt + dg/dy y'(t_e)),

(dg/dtheta = dg/dp_k for a run-time parameter, 0 for an initial value) and the state at the
event moves by dy(t_e)/dtheta = s(t_e) + y'(t_e) dt_e/dtheta. The events reset nothing (impacts
are another driver): s is continuous through a non-terminal event; a terminal event ends the run
with its state as the last row, whose sensitivities are s(t_e) (at the fixed time t_e, as every
row's). A crossing where the event function does not move (dg/dt + dg/dy y' = 0) gives an
infinite time sensitivity: NaN there.
"""

from __future__ import annotations

import ctypes

import numpy as np

from ...build import plain_library
from ...codegen.events import events_gradient_function, events_gradient_source
from ...model.events import EventRecord
from .events import scene_of


class EventGradients:
    """The compiled ``<prefix>_events_grad`` of one set of compiled events of ``cm``."""

    def __init__(self, cm, compiled):
        scene = scene_of(cm)
        self.ne = len(compiled.events)
        self.ny, self.np = cm.ny, cm.code.np
        self.library, self.path, _ = plain_library(f"the event derivatives of model {cm.code.model_name!r}",
                                                   f"{cm.code.prefix}_events_grad",
                                                   events_gradient_source(scene, compiled.events))
        fn = getattr(self.library, events_gradient_function(cm.code.prefix))
        dp = ctypes.POINTER(ctypes.c_double)
        fn.restype, fn.argtypes = ctypes.c_int, [ctypes.c_double, dp, dp, dp, dp, dp]
        self._fn, self._dp = fn, dp

    def __call__(self, t: float, y: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(gt (ne,), gy (ne, ny), gp (ne, np)) at (t, y, p); NaN where not finite."""
        gt = np.empty(self.ne)
        gy = np.empty((self.ne, self.ny))
        gp = np.empty((self.ne, max(self.np, 1)))
        dp = self._dp
        y = np.ascontiguousarray(y, dtype=float)
        p = np.ascontiguousarray(p, dtype=float)
        self._fn(float(t), y.ctypes.data_as(dp), p.ctypes.data_as(dp) if p.size else None, gt.ctypes.data_as(dp),
                 gy.ctypes.data_as(dp), gp.ctypes.data_as(dp))
        return gt, gy, gp[:, :self.np]


def gradients(cm, compiled) -> EventGradients:
    """The event derivatives of ``compiled`` (a :class:`~.events.CompiledEvents` of ``cm``), built
    on first use and kept with the compiled model."""
    key = ("cvsens-event-gradients", tuple(compiled.events))
    found = cm.solver_state.get(key)
    if found is None:
        found = cm.solver_state[key] = EventGradients(cm, compiled)
    return found


class SensEvents:
    """The ``lcg_cvsens_events`` struct of one run (``ffi`` the sensitivity driver's), its buffers,
    and the records made from it."""

    def __init__(self, ffi, compiled, ny: int, ns: int, max_events: int):
        self.compiled = compiled
        self.ny, self.ns = ny, ns
        self.t = np.full(max_events, np.nan)
        self.y = np.full((max_events, ny * (1 + ns)), np.nan)
        self.which = np.zeros(max_events, dtype=np.intc)
        self.direction = np.zeros(max_events, dtype=np.intc)
        self.rootdir = compiled.directions
        self.terminal = compiled.terminal
        fb = ffi.from_buffer
        ev = self.struct = ffi.new("lcg_cvsens_events *")
        ev.nroot = len(compiled.events)
        ev.roots = ffi.cast("int (*)(double, const double *, const double *, double *)",
                            ctypes.cast(compiled._fn, ctypes.c_void_p).value)
        ev.rootdir = fb("int[]", self.rootdir)
        ev.terminal = fb("int[]", self.terminal)
        ev.max_events = max_events
        ev.t = fb("double[]", self.t)
        ev.y = fb("double[]", self.y)
        ev.which = fb("int[]", self.which)
        ev.direction = fb("int[]", self.direction)

    @property
    def terminated(self) -> bool:
        return bool(self.struct.terminated)

    def records(self, cm, fns, names: list, which: np.ndarray, p: np.ndarray) -> list[EventRecord]:
        """The events found, each with its time's and state's sensitivities (module docstring)."""
        count = min(int(self.struct.n_events), self.t.size)
        if not count:
            return []
        grad = gradients(cm, self.compiled)
        ny, ns = self.ny, self.ns
        ffi = fns.rt.ffi
        fb = ffi.from_buffer
        ydot = np.empty(ny)
        out = []
        for e in range(count):
            t, row, k = float(self.t[e]), self.y[e], int(self.which[e])
            y, s = row[:ny].copy(), row[ny:].reshape(ns, ny)
            fns.rhs(t, fb("double[]", y), fb("double[]", p) if p.size else ffi.NULL, 0, ffi.NULL, ffi.NULL,
                    fb("double[]", ydot), ffi.NULL)
            gt, gy, gp = grad(t, y, p)
            rate = gt[k] + gy[k] @ ydot
            dt = np.array([-(gy[k] @ s[j] + (gp[k, which[j]] if which[j] >= 0 else 0.0)) for j in range(ns)])
            with np.errstate(divide="ignore", invalid="ignore"):
                dt = dt / rate if rate != 0.0 else np.full(ns, np.nan)
            ev = self.compiled.events[k]
            rec = EventRecord(ev.name, k, t, y, int(self.direction[e]), ev.terminal, list(cm.state_names))
            rec.t_sensitivity = dict(zip(names, dt.tolist()))
            rec.y_sensitivity = {name: s[j] + ydot * dt[j] for j, name in enumerate(names)}
            out.append(rec)
        return out

    def event_row(self, fns, p: np.ndarray, which: np.ndarray, nout: int) -> tuple[np.ndarray, np.ndarray]:
        """(s (ns, ny), d outputs (ns, nout)) at the last event recorded (the terminal one)."""
        ny, ns = self.ny, self.ns
        e = min(int(self.struct.n_events), self.t.size) - 1
        row = self.y[e]
        s = np.ascontiguousarray(row[ny:].reshape(ns, ny))
        dout = np.full((ns, max(nout, 1)), np.nan)
        if nout:
            ffi = fns.rt.ffi
            fb = ffi.from_buffer
            fns.out(float(self.t[e]), fb("double[]", np.ascontiguousarray(row[:ny])),
                    fb("double[]", p) if p.size else ffi.NULL, ns, fb("int[]", which), fb("double[]", s),
                    fb("double[]", dout))
        return s, dout[:, :nout]
