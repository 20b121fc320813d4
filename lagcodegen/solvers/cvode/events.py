"""Events on the ODE of a compiled scene for the CVODE family: the scene's event functions
generated (:func:`lagcodegen.codegen.events.events_source`) and compiled into a small library of
their own, once per compiled model and set of events (the model's own code and library stay as
they are), handed to the runtime's ``lcg_cvode_solve_events`` as an ``lcg_ode_roots`` table
(CVodeRootInit) or called from Python (scikit-sundae's ``eventsfn``)."""

from __future__ import annotations

import ctypes

import numpy as np

from ...codegen.record import scene_of_code
from ...errors import LagcodegenError
from ...formulation.events import scene_events
from ...libraries import events_library
from ...model.events import EventRecord
from ..base import ERR_NONFINITE

#: The C type of a generated event function (lcg_ode_roots.roots).
ROOTS_TYPE = "int (*)(double, const double *, const double *, double *)"


class CompiledEvents:
    """The event functions of one set of events of a compiled scene: the checked events, the
    ctypes function, and (for the native driver) the ``lcg_ode_roots`` table pointing at it."""

    def __init__(self, cm, events: list, built):
        self.events = list(events)
        self.path = built.path
        self._library = built  # keeps the library open
        fn = getattr(built.handle, built.functions["events"])
        dp = ctypes.POINTER(ctypes.c_double)
        fn.restype, fn.argtypes = ctypes.c_int, [ctypes.c_double, dp, dp, dp]
        self._fn = fn
        self._dp = dp
        self.table = None
        self._ffi = cm.ffi
        if cm.table is not None:  # the runtime's driver takes the table
            ffi = cm.ffi
            self.table = ffi.new("lcg_ode_roots *")
            self.table.nroot = len(self.events)
            self.table.roots = ffi.cast(ROOTS_TYPE, ctypes.cast(fn, ctypes.c_void_p).value)

    @property
    def directions(self) -> np.ndarray:
        return np.array([e.direction for e in self.events], dtype=np.intc)

    @property
    def terminal(self) -> np.ndarray:
        return np.array([1 if e.terminal else 0 for e in self.events], dtype=np.intc)

    def values(self, t: float, y: np.ndarray, p: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """g(t, y, p) of every event (``out``: where to write them); a value that is not finite
        raises LagcodegenError naming the event."""
        out = np.empty(len(self.events)) if out is None else out
        y = np.ascontiguousarray(y, dtype=float)
        if self.table is not None:  # through cffi: a few us where ctypes takes tens
            fb = self._ffi.from_buffer
            rc = self.table.roots(float(t), fb("double[]", y), fb("double[]", p) if p.size else self._ffi.NULL,
                                  fb("double[]", out))
        else:
            dp = self._dp
            rc = self._fn(float(t), y.ctypes.data_as(dp), p.ctypes.data_as(dp) if p.size else None,
                          out.ctypes.data_as(dp))
        if rc == ERR_NONFINITE:
            bad = [e.name for e, v in zip(self.events, out) if not np.isfinite(v)]
            raise LagcodegenError(f"event function{'s' if len(bad) > 1 else ''} {', '.join(bad)} not finite at "
                                  f"t = {t:.17g}")
        return out

    def records(self, t, y, which, direction, state_names) -> list[EventRecord]:
        return [EventRecord(self.events[int(i)].name, int(i), float(tt), np.array(yy, dtype=float), int(d),
                            self.events[int(i)].terminal, list(state_names))
                for tt, yy, i, d in zip(t, y, which, direction)]


def scene_of(cm):
    """The scene ``cm`` was generated from (its events are generated from it); LagcodegenError if
    ``cm`` has none (unpickled, or assembled by hand)."""
    return scene_of_code(cm.code, "events on CVODE")


def compiled_events(cm, events) -> CompiledEvents | None:
    """The compiled event functions of ``events`` on ``cm``'s scene (None without events): checked
    (:func:`lagcodegen.formulation.events.scene_events`; ModelError naming a bad one), generated
    and compiled on first use, then kept with the compiled model."""
    events = list(events or ())
    if not events:
        return None
    try:  # the events as given (checking them takes sympy milliseconds; a run with events, tens of us)
        given = ("given", tuple(events))
        found = cm.artifacts.find(CompiledEvents, given)
    except TypeError:  # unhashable items (dicts, lists): checked every time
        given, found = None, None
    if found is not None:
        return found
    scene = scene_of(cm)
    checked = scene_events(scene, events)
    def make():
        built = events_library(cm.code, scene, checked)  # asked of the build stage
        return CompiledEvents(cm, checked, built)
    found = cm.artifacts.get(CompiledEvents, ("checked", tuple(checked)), make)
    return found if given is None else cm.artifacts.keep(CompiledEvents, given, found)
