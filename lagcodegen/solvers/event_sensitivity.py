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

from typing import Callable

import cffi
import numpy as np

from ..libraries import events_gradient_library
from ..model.events import EventRecord


class EventGradients:
    """The compiled ``<prefix>_events_grad`` of the checked ``events`` of ``scene`` (``cm`` its
    compiled model), called through cffi (a few microseconds where ctypes' pointer arguments take
    tens)."""

    def __init__(self, cm, scene, events: list):
        self.ne = len(events)
        self.ny, self.np = cm.ny, cm.code.np
        built = events_gradient_library(cm.code, scene, list(events))  # asked of the build stage
        self.library, self.path = built.handle, built.path
        self._ffi = ffi = cffi.FFI()
        self._fn = ffi.cast("int (*)(double, const double *, const double *, double *, double *, double *)",
                            built.address("gradient"))

    def __call__(self, t: float, y: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(gt (ne,), gy (ne, ny), gp (ne, np)) at (t, y, p); NaN where not finite."""
        gt = np.empty(self.ne)
        gy = np.empty((self.ne, self.ny))
        gp = np.empty((self.ne, max(self.np, 1)))
        self.into(t, np.ascontiguousarray(y, dtype=float), np.ascontiguousarray(p, dtype=float), gt, gy, gp)
        return gt, gy, gp[:, :self.np]

    def into(self, t: float, y: np.ndarray, p: np.ndarray, gt: np.ndarray, gy: np.ndarray, gp: np.ndarray) -> None:
        """:meth:`__call__` into the caller's contiguous float64 arrays gt (ne), gy (ne, ny) and gp
        (ne, max(np, 1)), from contiguous ``y`` and ``p``."""
        fb = self._ffi.from_buffer
        self._fn(float(t), fb("double[]", y), fb("double[]", p) if p.size else self._ffi.NULL, fb("double[]", gt),
                 fb("double[]", gy), fb("double[]", gp))


def event_gradients(cm, scene, events) -> EventGradients:
    """The event derivatives of the checked ``events`` of ``scene`` (a tuple of
    :class:`~lagcodegen.model.events.Event`), built on first use and kept with the compiled model
    ``cm``."""
    events = tuple(events)
    return cm.artifacts.get(EventGradients, events, lambda: EventGradients(cm, scene, list(events)))


def event_records(grad: EventGradients, events, state_names, names, which, p: np.ndarray, times, rows, kinds,
                  directions, ydot: Callable[[float, np.ndarray], np.ndarray]) -> list[EventRecord]:
    """The records of the events a driver found, each with its time's and state's sensitivities
    (module docstring): event ``kinds[e]`` (index into ``events``) at ``times[e]``, crossing in
    ``directions[e]``, the augmented state ``rows[e]`` = (y, s_1 .. s_ns) there; ``names`` the
    directions, ``which[j]`` the run-time parameter of direction j (-1: an initial value);
    ``ydot(t, row)`` the states' right-hand side y' at the event's augmented state ``row``."""
    ny, ns = grad.ny, len(names)
    count = len(times)
    if not count:
        return []
    rows = np.asarray(rows, dtype=float)
    y = rows[:, :ny].copy()
    s = rows[:, ny:ny * (1 + ns)].reshape(count, ns, ny)
    kinds = np.asarray(kinds, dtype=int)
    yd = np.array([ydot(float(t), row) for t, row in zip(times, rows)]).reshape(count, ny)
    p = np.ascontiguousarray(p, dtype=float)
    GT, GY, GP = np.empty((count, grad.ne)), np.empty((count, grad.ne, ny)), np.empty((count, grad.ne, max(grad.np, 1)))
    for e in range(count):  # the event functions' derivatives at each event
        grad.into(float(times[e]), y[e], p, GT[e], GY[e], GP[e])
    at = np.arange(count)
    gt, gy = GT[at, kinds], GY[at, kinds]  # those of the event function that fired
    which = np.asarray(which, dtype=int)
    moved = np.flatnonzero(which >= 0)  # the directions that are parameters: dg/dtheta = dg/dp
    gp = np.zeros((count, ns))
    gp[:, moved] = GP[at, kinds][:, which[moved]]
    rate = gt + np.einsum("ei,ei->e", gy, yd)
    with np.errstate(divide="ignore", invalid="ignore"):
        dt = -(np.einsum("ei,eji->ej", gy, s) + gp) / rate[:, None]
    dt[rate == 0.0] = np.nan
    ys = s + yd[:, None, :] * dt[:, :, None]
    out = []
    for e, (k, dte) in enumerate(zip(kinds.tolist(), dt.tolist())):
        ev = events[k]
        rec = EventRecord(ev.name, k, float(times[e]), y[e], int(directions[e]), ev.terminal, list(state_names))
        rec.t_sensitivity = dict(zip(names, dte))
        rec.y_sensitivity = dict(zip(names, ys[e]))
        out.append(rec)
    return out
