"""The IDA family's stepper: the C state of an integrator object
(:class:`lagcodegen.simulation.integrator.Integrator`) on the GGL form of a constrained system,
the runtime's ``lcg_ida_stepper`` (lagcodegen/runtime/lcg_ida_stepper.c: IDA memory made once, the
run driver's own residual, Jacobian and root functions, its IDACalcIC start).

The stepper runs in a module of its own (:func:`stepper_runtime`, built once per installation
and SUNDIALS version): one translation unit with the run driver ``lcg_ida.c``, plus ``lcg_cvc.c``
(the table check and consistent initial state the driver calls)."""

from __future__ import annotations

import functools
import os

import numpy as np

from ...build import DEFAULT_CFLAGS, driver_runtime, find_sundials, runtime_sources
from ...codegen.signatures import IDA_OPTIONS
from ...codegen.cffi_decl import DAE_TABLE_CDEF, MODEL_TABLE_CDEF, POLL_CDEF, driver_cdef, header_cdef
from ...runtime import sources as runtime_files
from ..base import NativeEvents
from ..control import POLL_EVERY, install
from ..request import GGLForm, Recording, StepControl, option_fields
from ..stepper import NativeStepper
from .native import ALGEBRAIC_ATOL

#: The stepper's files of lagcodegen/runtime/ (lcg_ida_stepper.c includes lcg_ida.c).
STEPPER_FILES = ("lcg_ida_stepper.c", "lcg_ida_stepper.h", "lcg_stepper.h")

#: The stepper's functions: lcg_ida_stepper.h as it is.
STEPPER_CDEF = header_cdef("lcg_ida_stepper.h")


def stepper_cdef() -> str:
    """The stepper module's interface: the model tables and events record, the IDA driver's
    structs, the stepper's functions (lcg_ida_stepper.h) and the poll callback."""
    return "\n".join([MODEL_TABLE_CDEF, DAE_TABLE_CDEF, driver_cdef("ida"), STEPPER_CDEF, POLL_CDEF])


@functools.lru_cache(maxsize=4)
def _stepper_runtime(cc: str, cflags: tuple[str, ...]):
    sundials = find_sundials()
    link = sundials.link_args(("ida", "core"))

    def render() -> dict[str, str]:
        return {**runtime_sources(sundials), **runtime_files(STEPPER_FILES)}

    texts = [f"{name}\0{text}" for name, text in sorted(render().items())]
    return driver_runtime("ida_stepper", [sundials.version, sundials.sunindextype, *texts], render, stepper_cdef(),
                          "lcg_ida_stepper.h", [*sundials.link_args(("cvode", "ida", "core")), "-lm", "-pthread"],
                          cc, cflags, units=("lcg_cvc.c", "lcg_ida_stepper.c"))


def stepper_runtime(cc: str | None = None, cflags: tuple[str, ...] = DEFAULT_CFLAGS):
    """The IDA stepper's module (cffi; lcg_ida_stepper.c with the driver it includes, and
    lcg_cvc.c), built into the cache once per lagcodegen version, compiler, flags, Python and
    SUNDIALS."""
    return _stepper_runtime(cc or os.environ.get("CC") or "cc", tuple(cflags))


class IDAStepper(NativeStepper):
    """The C stepper of a constrained system's GGL form on IDA (``lcg_ida_stepper``), on ``mem`` =
    (t, y, p) with y = (q, v), a float64 array the caller keeps, from the initial values (yy0,
    yp0) of the unknowns (q, v, lambda, mu), with the step control ``control`` in the GGL form
    ``form``; ``recording.roots``: locate the compiled events (at most ``recording.max_events``
    kept per call)."""

    family = "ida"
    kind = "ida"

    def __init__(self, sim, mem: np.ndarray, yy0: np.ndarray, yp0: np.ndarray, control: StepControl, form: GGLForm,
                 recording: Recording):
        rt = stepper_runtime()
        ffi, lib = rt.ffi, rt.lib
        self.ffi, self.lib, self.rt = ffi, lib, rt
        self.sim = sim  # keeps the model's library open
        ng = sim.info.ng
        table = ffi.cast("const lcg_dae_model *", int(sim.ffi.cast("uintptr_t", sim.table)))
        c, roots = control, recording.roots
        atol_keep = np.ascontiguousarray(np.broadcast_to(np.asarray(c.atol, dtype=float), (ng,)))
        opt = ffi.new("lcg_ida_options *")
        for name, value in option_fields(IDA_OPTIONS, c, form, recording).items():
            setattr(opt, name, value)
        opt.atol, opt.atol_vec = float(atol_keep.min()), ffi.from_buffer("double[]", atol_keep)
        opt.calc_ic, opt.ic_alg_atol = 1, ALGEBRAIC_ATOL
        opt.poll = install(rt)
        opt.poll_every = POLL_EVERY
        self.events = list(sim.info.events) if roots else []
        self._native = NativeEvents(ffi, "lcg_events", self.events, ng, recording.max_events) if self.events \
            else None
        msg = ffi.new("char[]", 512)
        yy0 = np.ascontiguousarray(yy0, dtype=float)
        yp0 = np.ascontiguousarray(yp0, dtype=float)
        handle = lib.lcg_ida_stepper_new(table, opt, ffi.from_buffer("double[]", mem), ffi.from_buffer("double[]", yy0),
                                         ffi.from_buffer("double[]", yp0),
                                         self._native.struct if self._native else ffi.NULL, msg, 512)
        del atol_keep  # copied by the stepper
        self._bind(handle, msg, "IDA integrator")
        self._unknowns = np.frombuffer(ffi.buffer(lib.lcg_ida_stepper_unknowns(handle), 8 * ng), dtype=float)
        self.n_state = sim.ny

    def _release(self) -> None:
        self._unknowns = None  # a view of the C stepper's memory

    def multipliers(self) -> np.ndarray:
        """lambda (and mu) of the current unknowns, a copy."""
        return self._unknowns[self.n_state:].copy()

