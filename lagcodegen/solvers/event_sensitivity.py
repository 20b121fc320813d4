"""The sensitivities of event times in runs with forward sensitivities, for every solver family:
the derivatives of the event functions (``<prefix>_events_grad.c``,
:func:`lagcodegen.codegen.events.events_gradient_source`) compiled once per compiled model and
set of events, and the event records made from the states and sensitivities a driver stored at
each event (CVODE: :mod:`.cvode.sensitivity_events`; Taylor: :mod:`.taylor.sensitivity`).

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
from typing import Callable

import numpy as np

from ..build import plain_library
from ..codegen.events import events_gradient_function, events_gradient_source
from ..model.events import EventRecord


class EventGradients:
    """The compiled ``<prefix>_events_grad`` of the checked ``events`` of ``scene`` (``cm`` its
    compiled model)."""

    def __init__(self, cm, scene, events: list):
        self.ne = len(events)
        self.ny, self.np = cm.ny, cm.code.np
        self.library, self.path, _ = plain_library(f"the event derivatives of model {cm.code.model_name!r}",
                                                   f"{cm.code.prefix}_events_grad",
                                                   events_gradient_source(scene, list(events)))
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


def event_gradients(cm, scene, events) -> EventGradients:
    """The event derivatives of the checked ``events`` of ``scene`` (a tuple of
    :class:`~lagcodegen.model.events.Event`), built on first use and kept with the compiled model
    ``cm``."""
    events = tuple(events)
    key = ("event-gradients", events)
    found = cm.solver_state.get(key)
    if found is None:
        found = cm.solver_state[key] = EventGradients(cm, scene, list(events))
    return found


def event_records(grad: EventGradients, events, state_names, names, which, p: np.ndarray, times, rows, kinds,
                  directions, ydot: Callable[[float, np.ndarray], np.ndarray]) -> list[EventRecord]:
    """The records of the events a driver found, each with its time's and state's sensitivities
    (module docstring): event ``kinds[e]`` (index into ``events``) at ``times[e]``, crossing in
    ``directions[e]``, the augmented state ``rows[e]`` = (y, s_1 .. s_ns) there; ``names`` the
    directions, ``which[j]`` the run-time parameter of direction j (-1: an initial value);
    ``ydot(t, row)`` the states' right-hand side y' at the event's augmented state ``row``."""
    ny, ns = grad.ny, len(names)
    out = []
    for e in range(len(times)):
        t, row, k = float(times[e]), rows[e], int(kinds[e])
        y, s = np.array(row[:ny], dtype=float), np.asarray(row[ny:ny * (1 + ns)], dtype=float).reshape(ns, ny)
        yd = ydot(t, row)
        gt, gy, gp = grad(t, y, p)
        rate = gt[k] + gy[k] @ yd
        dt = np.array([-(gy[k] @ s[j] + (gp[k, which[j]] if which[j] >= 0 else 0.0)) for j in range(ns)])
        with np.errstate(divide="ignore", invalid="ignore"):
            dt = dt / rate if rate != 0.0 else np.full(ns, np.nan)
        ev = events[k]
        rec = EventRecord(ev.name, k, t, y, int(directions[e]), ev.terminal, list(state_names))
        rec.t_sensitivity = dict(zip(names, dt.tolist()))
        rec.y_sensitivity = {name: s[j] + yd * dt[j] for j, name in enumerate(names)}
        out.append(rec)
    return out
