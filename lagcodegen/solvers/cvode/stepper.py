"""The CVODE family's steppers: the C state of an integrator object
(:class:`lagcodegen.simulation.integrator.Integrator`) on CVODE, the runtime's
``lcg_cvode_stepper`` (the ODE of a scene; lagcodegen/runtime/lcg_cvode_stepper.c) and
``lcg_cvc_stepper`` (the index-1 form of a constrained system; lcg_cvc_stepper.c): CVODE memory
made once, the run drivers' own callbacks.

Each stepper runs in a module of its own (:func:`stepper_runtime`, built once per installation
and SUNDIALS version): one translation unit with its run driver (``lcg_cvode.c``,
``lcg_cvc.c``), whose callbacks it shares."""

from __future__ import annotations

import functools
import os

import numpy as np

from ...build import DEFAULT_CFLAGS, driver_runtime, find_sundials, runtime_sources
from ...codegen.signatures import CVC_OPTIONS, CVODE_OPTIONS
from ...codegen.cffi_decl import DAE_TABLE_CDEF, MODEL_TABLE_CDEF, POLL_CDEF, driver_cdef, header_cdef
from ...errors import LagcodegenError
from ...runtime import sources as runtime_files
from ..base import NativeEvents
from ..control import POLL_EVERY, install
from ..request import Index1Form, Recording, StepControl, option_fields
from ..stepper import NativeStepper, tolerance_option

#: The stepper's files of lagcodegen/runtime/ (lcg_cvode_stepper.c includes lcg_cvode.c).
STEPPER_FILES = ("lcg_cvode_stepper.c", "lcg_cvode_stepper.h", "lcg_stepper.h")

#: The stepper's functions: lcg_cvode_stepper.h as it is.
STEPPER_CDEF = header_cdef("lcg_cvode_stepper.h")


def stepper_cdef() -> str:
    """The stepper module's interface: the model table, the CVODE driver's structs, the events
    record, the stepper's functions (lcg_cvode_stepper.h) and the poll callback."""
    return "\n".join([MODEL_TABLE_CDEF, driver_cdef("inputs"), driver_cdef("cvode"), driver_cdef("dae"), STEPPER_CDEF,
                      POLL_CDEF])


#: The index-1 stepper's files (lcg_cvc_stepper.c includes lcg_cvc.c).
CVC_STEPPER_FILES = ("lcg_cvc_stepper.c", "lcg_cvc_stepper.h", "lcg_stepper.h")

#: The index-1 stepper's functions: lcg_cvc_stepper.h as it is.
CVC_STEPPER_CDEF = header_cdef("lcg_cvc_stepper.h")


def cvc_stepper_cdef() -> str:
    """The index-1 stepper module's interface: the constrained model table and events record, the
    index-1 driver's structs, the stepper's functions (lcg_cvc_stepper.h) and the poll callback."""
    return "\n".join([MODEL_TABLE_CDEF, DAE_TABLE_CDEF, driver_cdef("cvc"), CVC_STEPPER_CDEF, POLL_CDEF])


#: kind -> (files, cdef, header, units) of the steppers' modules (units: the C files compiled; the
#: stepper's own includes its run driver; lcg_cvode.c reads input tables, lcg_inputs.c)
_KINDS = {"cvode": (STEPPER_FILES, stepper_cdef, "lcg_cvode_stepper.h", ("lcg_cvode_stepper.c", "lcg_inputs.c")),
          "cvc": (CVC_STEPPER_FILES, cvc_stepper_cdef, "lcg_cvc_stepper.h", ("lcg_cvc_stepper.c",))}


@functools.lru_cache(maxsize=8)
def _stepper_runtime(kind: str, cc: str, cflags: tuple[str, ...]):
    files, cdef, header, units = _KINDS[kind]
    sundials = find_sundials()
    link = sundials.link_args(("cvode", "core"))

    def render() -> dict[str, str]:
        return {**runtime_sources(sundials), **runtime_files(files)}

    texts = [f"{name}\0{text}" for name, text in sorted(render().items())]
    return driver_runtime(f"{kind}_stepper", [sundials.version, sundials.sunindextype, *texts], render, cdef(),
                          header, [*link, "-lm", "-pthread"], cc, cflags, units=units)


def stepper_runtime(kind: str = "cvode", cc: str | None = None, cflags: tuple[str, ...] = DEFAULT_CFLAGS):
    """The module of the CVODE stepper ``kind`` ("cvode": the ODE of a scene, "cvc": the index-1
    form of a constrained system; cffi, the stepper's C with the driver it includes), built into
    the cache once per lagcodegen version, compiler, flags, Python and SUNDIALS."""
    return _stepper_runtime(kind, cc or os.environ.get("CC") or "cc", tuple(cflags))


class CVODEStepper(NativeStepper):
    """The C stepper of a compiled scene's ODE on CVODE, on ``mem`` = (t, y, p), a float64 array
    the caller keeps. ``control``: the step control as the family resolves it
    (:meth:`lagcodegen.solvers.cvode.CVODE.ode_control`); ``recording.events``: compiled event
    functions (:class:`~.events.CompiledEvents`, or None) located by CVODE's root finding and
    recorded per call (at most ``recording.max_events``)."""

    family = "cvode"
    kind = "cvode"
    calls = ("until", "advance", "grid", "step")

    def __init__(self, cm, mem: np.ndarray, control: StepControl, recording: Recording):
        if cm.table is None:
            raise LagcodegenError("the integrator object on CVODE needs the model library of a native build "
                                  "(build_code(..., native=True), the default of compile_model)")
        rt = stepper_runtime("cvode")
        ffi, lib = rt.ffi, rt.lib
        self.ffi, self.lib, self.rt = ffi, lib, rt
        self.cm = cm  # keeps the model's library open
        table = ffi.cast("const lcg_model *", int(cm.ffi.cast("uintptr_t", cm.table)))
        c, events = control, recording.events
        opt = ffi.new("lcg_cvode_options *")
        for name, value in option_fields(CVODE_OPTIONS, c).items():
            setattr(opt, name, value)
        atol_keep = tolerance_option(ffi, opt, c.atol, cm.ny)
        opt.poll = install(rt)
        opt.poll_every = POLL_EVERY
        self.compiled = events  # keeps the event functions' library open
        self.events = list(events.events) if events is not None else []
        self._native = NativeEvents(ffi, "lcg_events", self.events, cm.ny, recording.max_events) if self.events \
            else None
        roots = ffi.cast("const lcg_ode_roots *", int(cm.ffi.cast("uintptr_t", events.table))) if self.events \
            else ffi.NULL
        msg = ffi.new("char[]", 512)
        handle = lib.lcg_cvode_stepper_new_events(table, roots, opt, ffi.from_buffer("double[]", mem),
                                                  self._native.struct if self._native else ffi.NULL, msg, 512)
        del atol_keep  # copied by the stepper
        self._bind(handle, msg, "CVODE integrator")


class CVCStepper(NativeStepper):
    """The C stepper of a constrained system's index-1 form on CVODE (``lcg_cvc_stepper``), on
    ``mem`` = (t, y, p) with y = (q, q'), a float64 array the caller keeps, with the step control
    ``control`` in the index-1 form ``form``; ``recording.roots``: locate the compiled events
    (recorded per call, at most ``recording.max_events``)."""

    family = "cvode"
    kind = "cvc"

    def __init__(self, sim, mem: np.ndarray, control: StepControl, form: Index1Form, recording: Recording):
        rt = stepper_runtime("cvc")
        ffi, lib = rt.ffi, rt.lib
        self.ffi, self.lib, self.rt = ffi, lib, rt
        self.sim = sim  # keeps the model's library open
        ny = sim.ny
        table = ffi.cast("const lcg_dae_model *", int(sim.ffi.cast("uintptr_t", sim.table)))
        c, roots = control, recording.roots
        opt = ffi.new("lcg_cvc_options *")
        for name, value in option_fields(CVC_OPTIONS, c, form, recording).items():
            setattr(opt, name, value)
        atol_keep = tolerance_option(ffi, opt, c.atol, ny)
        opt.proj_err = 1
        opt.poll = install(rt)
        opt.poll_every = POLL_EVERY
        self.events = list(sim.info.events) if roots else []
        self._native = NativeEvents(ffi, "lcg_events", self.events, ny, recording.max_events) if self.events \
            else None
        msg = ffi.new("char[]", 512)
        handle = lib.lcg_cvc_stepper_new(table, opt, ffi.from_buffer("double[]", mem),
                                         self._native.struct if self._native else ffi.NULL, msg, 512)
        del atol_keep  # copied by the stepper
        self._bind(handle, msg, "CVODE (index-1) integrator")

