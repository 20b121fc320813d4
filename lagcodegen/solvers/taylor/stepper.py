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
from ...codegen.cffi_decl import POLL_CDEF, TAYLOR_TABLE_CDEF, driver_cdef, header_cdef
from ...codegen.taylor.emit import P_MAX, runtime_key_texts, runtime_sources
from ...errors import LagcodegenError
from ...runtime import sources as runtime_files
from ..control import POLL_EVERY, install
# ------------------------------------------------------------------------------------------
from .run import taylor_module
from .runner import events_struct, run_stats

#: The stepper's files of lagcodegen/runtime/ (lcg_taylor_stepper.c includes lcg_taylor.c).
STEPPER_FILES = ("lcg_taylor_stepper.c", "lcg_taylor_stepper.h", "lcg_stepper.h")

#: The stepper's functions: lcg_taylor_stepper.h as it is.
STEPPER_CDEF = header_cdef("lcg_taylor_stepper.h")


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
        self.events = module.events
        self.state_names = module.state_names
        self._open(module, mem, ny=module.ny, rtol=rtol, atol=atol, max_step=max_step, max_steps=max_steps,
                   order=order, max_events=max_events, max_wall=max_wall)

    def _open(self, module, mem: np.ndarray, *, ny: int, rtol: float, atol, max_step: float, max_steps: int,
              order: int | None, max_events: int, max_wall: float, rel_block: int = 0) -> None:
        """The C stepper of ``module`` (a compiled jet: its ``table``, a cdata of the Taylor
        runtime, with ``ny`` states) on ``mem`` = (t, y (ny values), p); ``atol`` a float or ny
        values; ``rel_block`` the options' (lcg_taylor_options: the sensitivities' blocks)."""
        rt = stepper_runtime()
        ffi, lib = rt.ffi, rt.lib
        self.module, self.ffi, self.lib, self.rt = module, ffi, lib, rt
        table = ffi.cast("const lcg_taylor_model *", int(ffi.cast("uintptr_t", module.table)))
        opt = ffi.new("lcg_taylor_options *")
        opt.rtol = rtol
        if isinstance(atol, float):
            opt.atol, opt.atol_vec = atol, ffi.NULL
            atol_keep = None
        else:
            atol_keep = np.ascontiguousarray(np.broadcast_to(np.asarray(atol, dtype=float), (ny,)))
            opt.atol = float(atol_keep.min())
            opt.atol_vec = ffi.from_buffer("double[]", atol_keep)
        opt.max_steps = max_steps
        opt.max_step = max_step
        opt.order = order or 0
        opt.rel_block = rel_block
        opt.poll = install(rt)
        opt.poll_every = POLL_EVERY
        opt.max_wall = max_wall
        self.ev = ffi.NULL
        self._keep = None
        if self.events:
            self.ev, self._keep = events_struct(ffi, "lcg_taylor_events *", max_events, ny)
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
        return run_stats(self.stats)

    def event_arrays(self):
        """(count, terminated, (t, y, which, direction)) of the last call's events."""
        ev = self.ev
        return int(ev.n_events), bool(ev.terminated), self._keep


class TaylorSensitivityStepper(TaylorStepper):
    """The C stepper of a compiled scene's variational jet along the directions ``names``
    (:mod:`.sensitivity`): the same runtime stepper on the augmented system, whose memory ``mem``
    = (t, y, s, p) is its own (s (ns, ny), ``sens``: unit vectors for initial values, zeros for
    parameters, a rotation of a quaternion joint's at the initial state, as a run starts), made
    from the integrator's (t, y, p) ``face_mem``; the integrator
    object's views are made on ``mem`` (``params_at``: where p starts). ``grid`` writes the states
    into the caller's rows and the sensitivities into ``sout`` (nt, ns, ny). ``events``: the
    variational jet's (located on the states' part), each record with its time's sensitivities."""

    with_sensitivities = True  # the integrator object shows them (SensitivityIntegrator)

    def __init__(self, cm, face_mem: np.ndarray, names, *, rtol: float, atol, errcon: bool, max_step: float,
                 max_steps: int, order: int | None, max_wall: float = 0.0, events=(), max_events: int = 10_000):
        from .run import scene_of
        from .sensitivity import variational_module
        module = variational_module(cm, scene_of(cm), names, events)
        ny, ns = cm.ny, module.ns
        self.events = module.events
        self.state_names = module.state_names
        self.names = list(module.names)
        self.cm = cm
        mem = np.empty(face_mem.size + ns * ny)
        mem[:1 + ny] = face_mem[:1 + ny]
        # a rotation of a quaternion joint (generalized speeds): its s0 at the integrator's initial state
        mem[1 + ny:1 + ny * (1 + ns)] = module.initial_sensitivities(face_mem[1:1 + ny], face_mem[0],
                                                                      face_mem[1 + ny:]).ravel()
        mem[1 + ny * (1 + ns):] = face_mem[1 + ny:]
        self.mem = mem
        self.sens = mem[1 + ny:1 + ny * (1 + ns)].reshape(ns, ny)  # (ns, ny): a view of the C memory
        self.params_at = 1 + ny * (1 + ns)
        self.sout = None  # (nt, ns, ny): where propagate_grid's sensitivities go (set per call)
        self._open(module, mem, ny=ny * (1 + ns), rtol=rtol, atol=module.tolerances(atol, errcon), max_step=max_step,
                   max_steps=max_steps, order=order, max_events=max_events, max_wall=max_wall, rel_block=ny)
        self._grid_rows = self.grid
        self.grid = self._grid_split

    def event_records(self, state_names) -> list:
        """The last call's events with their times' sensitivities (rows: the state, then the
        sensitivities, as the stepper stored them)."""
        count, _, (tt, yy, which, direction) = self.event_arrays()
        count = min(count, tt.shape[0])
        p = np.array(self.mem[self.params_at:])
        return self.module.records(p, tt[:count], yy[:count], which[:count], direction[:count])

    def _grid_split(self, nt, tout, yout) -> int:
        """The grid call (the integrator's): the augmented rows computed apart, the states copied
        into ``yout`` (the cdata of nt rows of ny) and the sensitivities into ``sout``."""
        ny, ns = self.cm.ny, len(self.names)
        rows = np.empty((max(nt, 0), ny * (1 + ns)))
        flag = self._grid_rows(nt, tout, self.ffi.from_buffer("double[]", rows))
        if nt > 0:
            states = np.frombuffer(self.ffi.buffer(yout, nt * ny * 8), dtype=np.float64).reshape(nt, ny)
            states[...] = rows[:, :ny]
            sout = self.sout
            if sout is None or sout.shape != (nt, ns, ny):
                sout = self.sout = np.empty((nt, ns, ny))
            sout[...] = rows[:, ny:].reshape(nt, ns, ny)
        return flag
