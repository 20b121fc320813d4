"""Events in runs with forward sensitivities on CVODE: the events record of the sensitivity
driver (``lcg_cvsens_events`` of lcg_cvsens.h, ``lcg_cvsens_solve_events``: root finding on the
state part of the augmented ODE), and
the records made from what it stored at each event, with their times' sensitivities
(:mod:`lagcodegen.solvers.event_sensitivity`: the derivatives of the event functions and the
implicit-function formula, shared with the Taylor family). The events reset nothing: s is
continuous through a non-terminal event; a terminal one ends the run with its state as the last
row, whose sensitivities are s(t_e).
"""

from __future__ import annotations

import ctypes

import numpy as np

from ...model.events import EventRecord
from ..event_sensitivity import EventGradients, event_gradients, event_records
from .events import scene_of


def gradients(cm, compiled) -> EventGradients:
    """The event derivatives of ``compiled`` (a :class:`~.events.CompiledEvents` of ``cm``), built
    on first use and kept with the compiled model."""
    return event_gradients(cm, scene_of(cm), compiled.events)


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
        ffi = fns.rt.ffi
        fb = ffi.from_buffer
        ny = self.ny

        def ydot(t, row):
            out = np.empty(ny)
            fns.rhs(t, fb("double[]", np.ascontiguousarray(row[:ny])), fb("double[]", p) if p.size else ffi.NULL, 0,
                    ffi.NULL, ffi.NULL, fb("double[]", out), ffi.NULL)
            return out

        return event_records(gradients(cm, self.compiled), self.compiled.events, cm.state_names, names, which, p,
                             self.t[:count], self.y[:count], self.which[:count], self.direction[:count], ydot)

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
