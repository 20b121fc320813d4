"""The Taylor family's stepper: the C state of an integrator object
(:class:`lagcodegen.simulation.integrator.Integrator`) on the generated Taylor integrator, the
runtime's ``lcg_taylor_stepper`` (lagcodegen/runtime/lcg_taylor_stepper.c: the driver's own step,
on memory that lives between calls).

The stepper runs in a module of its own (:func:`stepper_runtime`, built once per installation):
one translation unit with the Taylor driver ``lcg_taylor.c``, whose static step functions it
shares."""

from __future__ import annotations

import functools
import os

import numpy as np

# --- the rest of lagcodegen: the one place to repoint when modules move -------------------
from ...build import DEFAULT_CFLAGS, driver_runtime
from ...codegen.cffi_decl import POLL_CDEF, TAYLOR_TABLE_CDEF, driver_cdef
from ...errors import LagcodegenError
from ...runtime import sources as runtime_files
from ..control import POLL_EVERY, install
# ------------------------------------------------------------------------------------------
from .emit import P_MAX, runtime_key_texts, runtime_sources
from .run import taylor_module

#: The stepper's files of lagcodegen/runtime/ (lcg_taylor_stepper.c includes lcg_taylor.c).
STEPPER_FILES = ("lcg_taylor_stepper.c", "lcg_taylor_stepper.h")

STEPPER_CDEF = """
typedef struct lcg_taylor_stepper lcg_taylor_stepper;
lcg_taylor_stepper *lcg_taylor_stepper_new(const lcg_taylor_model *m, const lcg_taylor_options *opt, double *mem,
                                           lcg_taylor_events *ev, char *message, size_t size);
void lcg_taylor_stepper_free(lcg_taylor_stepper *s);
lcg_taylor_stats *lcg_taylor_stepper_stats(lcg_taylor_stepper *s);
int lcg_taylor_stepper_advance(lcg_taylor_stepper *s, double t_end, int nt, const double *tout, double *yout,
                               int one_step);
int lcg_taylor_stepper_until(lcg_taylor_stepper *s, double t_end);
int lcg_taylor_stepper_grid(lcg_taylor_stepper *s, int nt, const double *tout, double *yout);
int lcg_taylor_stepper_step(lcg_taylor_stepper *s, double t_limit);
"""


def stepper_cdef() -> str:
    """The stepper module's interface: the jet table, the Taylor driver's structs, the stepper's
    functions (lcg_taylor_stepper.h) and the poll callback."""
    return "\n".join([TAYLOR_TABLE_CDEF, driver_cdef("taylor"), STEPPER_CDEF, POLL_CDEF])


def _sources() -> dict[str, str]:
    return {**runtime_sources(), **runtime_files(STEPPER_FILES)}


@functools.lru_cache(maxsize=4)
def _stepper_runtime(cc: str, cflags: tuple[str, ...]):
    texts = [f"{name}\0{text}" for name, text in sorted(runtime_files(STEPPER_FILES).items())]
    return driver_runtime("taylor_stepper", [f"P_MAX {P_MAX}", *texts, *runtime_key_texts()], _sources,
                          stepper_cdef(), "lcg_taylor_stepper.h", ["-lm", "-pthread"], cc, cflags,
                          units=("lcg_taylor_stepper.c",))


def stepper_runtime(cc: str | None = None, cflags: tuple[str, ...] = DEFAULT_CFLAGS):
    """The Taylor stepper's module (cffi; lcg_taylor_stepper.c with the driver it includes), built
    into the cache once per lagcodegen version, compiler, flags and Python."""
    return _stepper_runtime(cc or os.environ.get("CC") or "cc", tuple(cflags))


class TaylorStepper:
    """The C stepper of a compiled scene's Taylor integrator on ``mem`` = (t, y, p), a float64
    array the caller keeps (the integrator object's views). ``events``: compiled into the jet and
    recorded per call (at most ``max_events``)."""

    family = "taylor"

    def __init__(self, cm, mem: np.ndarray, *, rtol: float, atol, max_step: float, max_steps: int,
                 order: int | None, events=(), max_events: int = 10_000, max_wall: float = 0.0):
        module = taylor_module(cm, tuple(events))  # the jet (built on first use, kept with cm)
        rt = stepper_runtime()
        ffi, lib = rt.ffi, rt.lib
        self.module, self.ffi, self.lib, self.rt = module, ffi, lib, rt
        self.events = module.events
        self.state_names = module.state_names
        table = ffi.cast("const lcg_taylor_model *", int(module.ffi.cast("uintptr_t", module.table)))
        opt = ffi.new("lcg_taylor_options *")
        opt.rtol = rtol
        if isinstance(atol, float):
            opt.atol, opt.atol_vec = atol, ffi.NULL
            atol_keep = None
        else:
            atol_keep = np.ascontiguousarray(np.broadcast_to(np.asarray(atol, dtype=float), (module.ny,)))
            opt.atol = float(atol_keep.min())
            opt.atol_vec = ffi.from_buffer("double[]", atol_keep)
        opt.max_steps = max_steps
        opt.max_step = max_step
        opt.order = order or 0
        opt.poll = install(rt)
        opt.poll_every = POLL_EVERY
        opt.max_wall = max_wall
        self.ev = ffi.NULL
        self._keep = None
        if self.events:
            self._keep = (np.empty(max_events), np.empty((max_events, module.ny)), np.empty(max_events, dtype=np.intc),
                          np.empty(max_events, dtype=np.intc))
            ev = self.ev = ffi.new("lcg_taylor_events *")
            ev.max_events = max_events
            ev.t = ffi.from_buffer("double[]", self._keep[0])
            ev.y = ffi.from_buffer("double[]", self._keep[1])
            ev.which = ffi.from_buffer("int[]", self._keep[2])
            ev.direction = ffi.from_buffer("int[]", self._keep[3])
        msg = ffi.new("char[]", 512)
        self._mem = mem
        handle = lib.lcg_taylor_stepper_new(table, opt, ffi.from_buffer("double[]", mem), self.ev, msg, 512)
        del atol_keep  # copied by the stepper
        if handle == ffi.NULL:
            raise LagcodegenError(f"Taylor integrator: {ffi.string(msg).decode(errors='replace')}")
        self.handle = handle
        self.stats = lib.lcg_taylor_stepper_stats(handle)
        self.until = functools.partial(lib.lcg_taylor_stepper_until, handle)
        self.advance = functools.partial(lib.lcg_taylor_stepper_advance, handle)
        self.grid = functools.partial(lib.lcg_taylor_stepper_grid, handle)
        self.step = functools.partial(lib.lcg_taylor_stepper_step, handle)
        self.order = int(self.stats.order)

    def free(self) -> None:
        """Free the C stepper (once)."""
        handle, self.handle = self.handle, None
        if handle is not None:
            self.lib.lcg_taylor_stepper_free(handle)

    def stats_dict(self) -> dict:
        st = self.stats
        return {"steps": st.nsteps, "jet_evals": st.njet, "rhs_evals": st.njet, "order": st.order,
                "root_searches": st.nroot, "h_last": st.h_last, "h_min": st.h_min, "h_max": st.h_max,
                "t_reached": st.t_reached, "model_error": st.model_error}

    def event_arrays(self):
        """(count, terminated, (t, y, which, direction)) of the last call's events."""
        ev = self.ev
        return int(ev.n_events), bool(ev.terminated), self._keep
