"""The C state of an integrator object with forward sensitivities on CVODE: the runtime's
``lcg_cvsens_stepper`` (lagcodegen/runtime/lcg_cvsens_stepper.c, one translation unit with the
sensitivity driver lcg_cvsens.c, whose callbacks and block Newton solver it shares), in a module
of its own built once per installation and SUNDIALS version.

The stepper works on the integrator's (t, y, p) array and on an array of its own, the
sensitivities s (ns, ny) (s[j, i] = dy_i/dtheta_j), which the integrator shows transposed as
``sensitivities`` (ny, ns); a write of either restarts CVODE at the next call."""

from __future__ import annotations

import functools
import os

import numpy as np

from ...build import DEFAULT_CFLAGS, driver_runtime, find_sundials
from ...codegen.cffi_decl import header_cdef
from ...runtime import sources as runtime_files
from ..control import install
from ..request import Recording, StepControl
from ..stepper import NativeStepper
from .sensitivity import CDEF, LINKED_UNITS, _sources, directions, functions, sens_options, sens_stats
from .sensitivity_events import SensEvents

#: The stepper's files of lagcodegen/runtime/ (lcg_cvsens_stepper.c includes lcg_cvsens.c).
STEPPER_FILES = ("lcg_cvsens_stepper.c", "lcg_cvsens_stepper.h", "lcg_stepper.h")

#: The stepper module's interface: the driver's (lcg_cvsens.h), then lcg_cvsens_stepper.h as it is.
STEPPER_CDEF = header_cdef("lcg_cvsens_stepper.h")


@functools.lru_cache(maxsize=4)
def _runtime(cc: str, cflags: tuple[str, ...]):
    sundials = find_sundials()

    def render() -> dict[str, str]:
        return {**_sources(), **runtime_files(STEPPER_FILES)}

    texts = [f"{k}\0{v}" for k, v in sorted(render().items())]
    return driver_runtime("cvsens_stepper", [sundials.version, *texts], render, CDEF + "\n" + STEPPER_CDEF,
                          "lcg_cvsens_stepper.h", [*sundials.link_args(("cvode", "core")), "-lm"], cc, cflags,
                          units=("lcg_cvsens_stepper.c", *LINKED_UNITS))


def stepper_runtime(cc: str | None = None, cflags: tuple[str, ...] = DEFAULT_CFLAGS):
    """The sensitivity stepper's cffi module, built once per installation."""
    return _runtime(cc or os.environ.get("CC") or "cc", tuple(cflags))


class CVSensStepper(NativeStepper):
    """The C stepper of a compiled scene's ODE with the sensitivities ``recording.sensitivities``
    on CVODE (the step control ``control``), on ``mem`` = (t, y, p), a float64 array the caller
    keeps; its sensitivities start as a run's (unit vectors for initial values, zeros for
    parameters). ``recording.events`` (:class:`~.events.CompiledEvents` or None) located as in a
    run, each record with its
    time's sensitivities (the rows of :meth:`event_arrays`: the state, then the sensitivities)."""

    family = "cvode"
    kind = "cvsens"
    calls = ("until", "step")
    with_sensitivities = True  # the integrator object shows them (SensitivityIntegrator)

    def __init__(self, cm, mem: np.ndarray, control: StepControl, recording: Recording):
        names, which, s0 = directions(cm, recording.sensitivities)
        events = recording.events
        fns = functions(cm)
        rt = stepper_runtime()
        ffi, lib = rt.ffi, rt.lib
        self.ffi, self.lib, self.rt = ffi, lib, rt
        self.cm, self.fns = cm, fns  # keep the libraries open
        self.names, self.which = names, which
        ny, ns = cm.ny, len(names)
        self.sens = np.ascontiguousarray(s0)  # (ns, ny): the memory the C stepper works on
        self.sout = None  # (nt, ns, ny): where propagate_grid's sensitivities go (set per call)
        table = ffi.cast("const lcg_model *", int(cm.ffi.cast("uintptr_t", cm.table)))
        rhs = ffi.cast("lcg_sens_rhs_fn", int(fns.rt.ffi.cast("uintptr_t", fns.rhs)))
        opt, atol_all = sens_options(ffi, install(rt), control, ny, ns)
        self.compiled = events
        self.events = list(events.events) if events is not None else []
        self._native = SensEvents(ffi, events, ny, ns, recording.max_events) if self.events else None
        msg = ffi.new("char[]", 512)
        handle = lib.lcg_cvsens_stepper_new(table, rhs, ns, ffi.from_buffer("int[]", which), opt,
                                            ffi.from_buffer("double[]", mem), ffi.from_buffer("double[]", self.sens),
                                            self._native.struct if self._native else ffi.NULL, msg, 512)
        self._bind(handle, msg, "CVODE integrator with sensitivities")
        self.mem = mem
        self._grid = lib.lcg_cvsens_stepper_grid
        self._sout_ptr = ffi.from_buffer

    def grid(self, nt, tout, yout) -> int:
        """The grid call (the integrator's): the sensitivities into ``self.sout`` (nt, ns, ny)."""
        sout = self.sout
        if sout is None or sout.shape[0] != nt:
            sout = self.sout = np.empty((max(nt, 0), len(self.names), self.cm.ny))
        return self._grid(self.handle, nt, tout, yout, self._sout_ptr("double[]", sout))

    def stats_dict(self) -> dict:
        return sens_stats(self.stats)

    def event_records(self, state_names) -> list:
        """The last call's events with their times' sensitivities (:class:`SensEvents`)."""
        p = np.array(self.mem[1 + self.cm.ny:])
        return self._native.records(self.cm, self.fns, self.names, self.which, p)
