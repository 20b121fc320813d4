"""Run the Taylor integrator of a scene: :func:`build_taylor` asks the build stage for it
(:mod:`lagcodegen.libraries`, which generates it through :mod:`lagcodegen.codegen.taylor`) ->
:class:`TaylorModule`, whose :meth:`~TaylorModule.simulate` calls the C driver once for all
output times and returns a :class:`Result`.

By default (``runtime=True``) the model compiles only its jet (``<prefix>_taylor_jet.c``: the
recurrences, outputs, event rows and their table ``lcg_taylor_model``) into a plain shared library
without Python.h, and the model-independent driver ``lcg_taylor_solve`` of the Taylor runtime
(:func:`taylor_runtime`, compiled once per installation) integrates it. ``runtime=False`` compiles
the standalone integrator ``<prefix>_taylor.c`` (the same driver text with the sizes as constants;
what C bundles ship) into a cffi module of its own.

The per-call Python is kept lean (the options and statistics structs are allocated once per
module, an events struct is reused from run to run, arrays are handed to C without copies,
nothing is validated twice): callers such as
``simulate(method="taylor")`` check the user's input once.
"""

from __future__ import annotations

import ctypes
import functools
import operator
import os

import numpy as np

# --- the rest of lagcodegen: the one place to repoint when modules move -------------------
from ...build import DEFAULT_CFLAGS, driver_runtime
from ...codegen.cffi_decl import taylor_runtime_cdef
from ...codegen.record import GeneratedCode
from ...codegen.taylor.decompose import Decomposition
from ...codegen.taylor.emit import P_MAX, runtime_key_texts, runtime_sources
from ...codes import model_error_flag
from ...errors import LagcodegenError
from ...formulation.scene import Scene
from ...libraries import taylor_integrator, taylor_jet_library
from ...model.events import records
from ...result import Result
from ...util import c_vector
from ..base import message as base_message
from ..control import CANCELLED, POLL_EVERY, install, raise_pending
# ------------------------------------------------------------------------------------------

#: The statistics struct's fields a run reads, in one call.
_STATS = operator.attrgetter("nsteps", "njet", "order", "nroot", "t_reached", "h_last", "h_min", "h_max",
                             "model_error", "nt_done")


def run_stats(st) -> dict:
    """Result.stats of a Taylor run from its statistics struct ``st``."""
    nsteps, njet, order_used, nroot, t_reached, h_last, h_min, h_max, model_error, _ = _STATS(st)
    return {"steps": nsteps, "rhs_evals": njet, "jet_evals": njet, "order": order_used, "root_searches": nroot,
            "t_reached": t_reached, "h_last": h_last, "h_min": h_min, "h_max": h_max, "model_error": model_error}


def events_struct(ffi, ctype: str, max_events: int, width: int):
    """A new events struct of the Taylor driver (``ctype``: ``lcg_taylor_events *`` or a
    standalone driver's) for ``max_events`` events of rows of ``width`` values, and the arrays
    it points into (times, rows, event indices, directions), to keep while it is used."""
    keep = (np.empty(max_events), np.empty((max_events, width)), np.zeros(max_events, dtype=np.intc),
            np.zeros(max_events, dtype=np.intc))
    buf = ffi.from_buffer
    ev = ffi.new(ctype)
    ev.max_events = max_events
    ev.t = buf("double[]", keep[0])
    ev.y = buf("double[]", keep[1])
    ev.which = buf("int[]", keep[2])
    ev.direction = buf("int[]", keep[3])
    return ev, keep


def message(flag: int, model_error: int, detail: str) -> str:
    """The text of a driver flag (:data:`lagcodegen.solvers.base.FLAG_TEXT` ["Taylor"])."""
    return base_message(flag, model_error, detail, "Taylor")


@functools.lru_cache(maxsize=4)
def _taylor_runtime(cc: str, cflags: tuple[str, ...]):
    return driver_runtime("taylor", [f"P_MAX {P_MAX}", *runtime_key_texts()], runtime_sources, taylor_runtime_cdef(),
                          "lcg_taylor.h", ["-lm", "-pthread"], cc, cflags)


def taylor_runtime(cc: str | None = None, cflags: tuple[str, ...] = DEFAULT_CFLAGS):
    """The Taylor runtime: a cffi module with the model-independent Taylor driver
    (lagcodegen/runtime/lcg_taylor.c, ``lcg_taylor_solve``, ``lcg_taylor_jet``, ensembles), built
    into the cache once per lagcodegen version, compiler, flags and Python (no SUNDIALS)."""
    return _taylor_runtime(cc or os.environ.get("CC") or "cc", tuple(cflags))


def build_taylor(scene: Scene, *, events=(), cc: str | None = None, verbose: bool = False,
                 runtime: bool = True, cflags: tuple[str, ...] = DEFAULT_CFLAGS) -> "TaylorModule":
    """The compiled Taylor integrator of ``scene`` (generated and compiled by
    :mod:`lagcodegen.libraries`, cached like every build): with ``runtime``, only its jet
    (:func:`~lagcodegen.libraries.taylor_jet_library`, its table's layout checked here), for the
    Taylor runtime's driver (compiled once with the default flags); else the standalone
    integrator, driver included (:func:`~lagcodegen.libraries.taylor_integrator`). ``cflags``:
    the C compiler's flags of what is compiled there (e.g. ``-DLCG_TAYLOR_CAP=1.3`` changes a standalone driver's step
    cap, see templates/taylor/_driver.j2; the runtime's driver, lagcodegen/runtime/lcg_taylor_driver.h,
    has the same rule; a large jet compiled for the runtime with the default flags takes
    :data:`lagcodegen.libraries.LARGE_JET_CFLAGS`)."""
    cflags = tuple(cflags)
    if runtime and any(flag.startswith("-DLCG_TAYLOR_CAP") for flag in cflags):
        raise LagcodegenError("LCG_TAYLOR_CAP sets the step cap of a driver, and the Taylor runtime's driver is "
                              "compiled once with the default flags: build the standalone integrator "
                              "(build_taylor(..., runtime=False)) to compile it with another cap")
    if not runtime:
        built, d, events = taylor_integrator(scene, events, cc=cc, cflags=cflags, verbose=verbose)
        return TaylorModule(built.code, built.module, d, events, built.path)
    jet = taylor_jet_library(scene, events, cc=cc, cflags=cflags, verbose=verbose)
    code, d, events = jet.extra
    rt = taylor_runtime(cc)
    library, path = jet.handle, jet.path
    getter = getattr(library, jet.functions["table"])
    getter.restype = ctypes.c_void_p
    table = rt.ffi.cast("const lcg_taylor_model *", getter())
    got = (table.abi, table.nq, table.nz, table.ny, table.np, table.nout, table.ne, table.nrows, table.order_max)
    # generalized speeds: the table counts the speeds, and the states beyond 2 nv (lcg_taylor_model.h)
    nq, nz = (code.n, code.nz) if d.kin is None else (d.n, code.ny - 2 * d.n)
    expected = (rt.lib.LCG_TAYLOR_ABI, nq, nz, code.ny, code.np, code.nout, len(events), d.nrows,
                rt.lib.LCG_TAYLOR_ORDER_MAX)
    if got != expected:
        raise LagcodegenError(f"the Taylor library built for model {code.model_name!r} ({path}) has another layout "
                              f"than its code: (abi, nq, nz, ny, np, nout, ne, nrows, order_max) = {got}, expected "
                              f"{expected}")
    return TaylorModule(code, rt, d, events, path, table=table, library=library)


class TaylorModule:
    """A compiled Taylor integrator. Not reentrant: one call at a time per module (the options
    and statistics structs are reused)."""

    def __init__(self, code: GeneratedCode, module, decomposition: Decomposition, events, path=None, table=None,
                 library=None):
        self.code = code
        self.decomposition = decomposition
        self.events = list(events)
        self.path = path
        self.module = module
        self.ffi = ffi = module.ffi
        self.lib = lib = module.lib
        self.table = table        # the jet's table (runtime builds), else None
        self._library = library   # keeps the jet's library open
        pre = code.prefix
        self.n, self.ny, self.nout = code.n, code.ny, code.nout
        self.state_names = list(code.state_names)
        self.output_names = list(code.output_names)
        self.param_names = list(code.param_names)
        if table is not None:
            self._solve = functools.partial(lib.lcg_taylor_solve, table)
            self._jet = functools.partial(lib.lcg_taylor_jet, table)
            self._out = table.outputs if table.outputs != ffi.NULL else None
            self.types = ("lcg_taylor_options *", "lcg_taylor_stats *", "lcg_taylor_events *")
        else:
            self._solve = getattr(lib, f"{pre}_taylor_solve")
            self._jet = getattr(lib, f"{pre}_taylor_jet")
            self._out = getattr(lib, f"{pre}_taylor_outputs")
            self.types = (f"{pre}_taylor_options *", f"{pre}_taylor_stats *", f"{pre}_taylor_events *")
        self._opt = ffi.new(self.types[0])
        self._st = ffi.new(self.types[1])
        if table is not None:  # run control: Ctrl-C stops a long run (the poll callback)
            self._opt.poll = install(module)
            self._opt.poll_every = POLL_EVERY
        self._buf = ffi.from_buffer
        empty = np.zeros(1)  # the outputs of a model without outputs: the driver writes none
        self._no_out = (empty, ffi.from_buffer("double[]", empty))  # shared by its prepared runs too
        self._ptrs = [None, None, None]
        self._ev_pool: list = []  # events structs of finished runs (_events_struct)
        self._opt_key = None
        self._atol = None
        self.p_max = P_MAX

    # ------------------------------------------------------------------ helpers
    def jet(self, t: float, y, p, order: int) -> np.ndarray:
        """Normalized Taylor coefficients (ny x (order+1)) of the state at (t, y); ``order`` in
        1..P_MAX."""
        y = c_vector(y, self.ny, "y", self.state_names)
        p = c_vector(p, len(self.param_names), "p", self.param_names)
        if not 1 <= int(order) <= P_MAX:
            raise LagcodegenError(f"Taylor jet: order must be 1..{P_MAX}, got {order}")
        out = np.empty((self.ny, int(order) + 1))
        rc = self._jet(float(t), self._buf("double[]", y), self._buf("double[]", p) if p.size else self.ffi.NULL,
                       int(order), self._buf("double[]", out))
        if rc:
            raise LagcodegenError(f"Taylor jet failed: {message(model_error_flag(rc) if rc > 0 else rc, rc, '')}")
        return out

    def _outputs_at(self, t: float, y, p) -> np.ndarray:
        out = np.full(max(self.nout, 1), np.nan)
        if self.nout and self._out is not None:
            self._out(float(t), self._buf("double[]", np.ascontiguousarray(y)),
                      self._buf("double[]", p) if p.size else self.ffi.NULL, self._buf("double[]", out))
        return out

    # ------------------------------------------------------------------ run
    def _ptr(self, arr, slot: int):
        """cdata of ``arr``, reused while the same array object comes back (the cdata holds a
        reference, so the object cannot be replaced by another at the same address)."""
        cached = self._ptrs[slot]
        if cached is not None and cached[0] is arr:
            return cached[1]
        ptr = self._buf("double[]", arr) if arr.size else self.ffi.NULL
        self._ptrs[slot] = (arr, ptr)
        return ptr

    def simulate(self, t_out: np.ndarray, y0: np.ndarray, p: np.ndarray, *, rtol: float = 1e-8,
                 atol=1e-10, max_step: float = 0.0, max_steps: int = 1_000_000, order: int | None = None,
                 max_events: int = 10_000, max_wall: float = 0.0) -> Result:
        """Integrate from ``t_out[0]`` with y(t_out[0]) = ``y0`` (float64 arrays, contiguous;
        not checked again) and return the trajectory at ``t_out``.

        Tolerances (per step, per component i): the step keeps the last two terms of the
        Taylor polynomial below w_i = atol_i + rtol |y_i| (Jorba & Zou); the order is
        ceil(-ln(rtol)/2 + 3) unless ``order`` is given. ``atol``: a scalar or ny values.
        """
        ffi = self.ffi
        nt = t_out.shape[0]
        yout = np.empty((nt, self.ny))
        if self.nout:
            out = np.empty((nt, self.nout))
            out_ptr = self._buf("double[]", out)
        else:  # the driver writes no outputs: the same placeholder and its cdata every call
            out, out_ptr = self._no_out
        opt, st = self._opt, self._st
        key = (rtol, atol, max_step, max_steps, order, max_wall)
        # new values written into the struct (kept while they come back; an array atol each time:
        # arrays are not compared)
        if not (isinstance(atol, float) and key == self._opt_key):
            if max_wall and self.table is None:
                raise LagcodegenError("max_wall needs the Taylor runtime's driver (build_taylor(runtime=True))")
            self._set_options(rtol, atol, max_step, max_steps, order)
            if self.table is not None:
                opt.max_wall = max_wall
            self._opt_key = key if isinstance(atol, float) else None
        ev = ffi.NULL
        keep = None
        if self.events:
            ev, keep = self._events_struct(max_events)
        flag = self._solve(self._ptr(p, 0), self._ptr(y0, 1), nt, self._ptr(t_out, 2), self._buf("double[]", yout),
                           out_ptr, opt, st, ev)
        if flag == CANCELLED:
            raise_pending()  # Ctrl-C during the run: KeyboardInterrupt
        stats = run_stats(st)
        done = st.nt_done
        t = t_out
        if done < nt:
            t, yout, out = t_out[:done].copy(), yout[:done], out[:done]
        text = "success" if flag == 0 else message(flag, st.model_error,
                                                   ffi.string(st.message).decode(errors="replace"))
        outputs = {name: out[:, i] for i, name in enumerate(self.output_names)} if self.nout else {}
        # the fields positionally (t, y, state_names, outputs, stats, status, message, backend,
        # method, parameters, n_coordinates): the same Result as by keyword, at half the cost
        res = Result(t, yout, self.state_names, outputs, stats, flag, text, "native", "taylor", {}, self.n)
        if keep is not None:
            self._events_into(res, ev, keep, p)
            self._ev_pool.append((ev, keep))  # read out: the next run may fill it
        return res

    def _set_options(self, rtol, atol, max_step, max_steps, order) -> None:
        atol_vec = self._write_options(self._opt, rtol, atol, max_step, max_steps, order)
        if atol_vec is not None:
            self._atol = atol_vec

    def _write_options(self, opt, rtol, atol, max_step, max_steps, order):
        """Write the run's options into ``opt``; returns the array ``opt.atol_vec`` points into
        (to be kept alive with ``opt``), or None for a scalar ``atol``."""
        opt.rtol = rtol
        atol_vec = None
        if isinstance(atol, float):
            opt.atol = atol
            opt.atol_vec = self.ffi.NULL
        else:
            atol_vec = np.ascontiguousarray(np.broadcast_to(np.asarray(atol, dtype=float), (self.ny,)))
            opt.atol = float(atol_vec.min())
            opt.atol_vec = self._buf("double[]", atol_vec)
        opt.max_steps = max_steps
        opt.max_step = max_step
        opt.order = order or 0
        return atol_vec

    def options_struct(self, *, rtol: float, atol, max_step: float, max_steps: int, order: int | None,
                       max_wall: float):
        """A new options struct of these values, as :meth:`simulate` sets its own (which is left
        alone), for a caller that keeps it across runs; returns (struct, the array its atol_vec
        points into or None), both to be kept together."""
        if max_wall and self.table is None:
            raise LagcodegenError("max_wall needs the Taylor runtime's driver (build_taylor(runtime=True))")
        opt = self.ffi.new(self.types[0])
        atol_vec = self._write_options(opt, rtol, atol, max_step, max_steps, order)
        if self.table is not None:
            opt.poll = self._opt.poll
            opt.poll_every = self._opt.poll_every
            opt.max_wall = max_wall
        return opt, atol_vec

    def _events_struct(self, max_events: int):
        """An events struct for ``max_events`` events and its arrays: a finished run's from the pool
        (the driver clears its count; the records copy what they keep), else a new one."""
        try:
            ev, keep = self._ev_pool.pop()  # atomic: concurrent runs never share one
        except IndexError:
            return events_struct(self.ffi, self.types[2], max_events, self.ny)
        if keep[0].shape[0] != max_events:
            return events_struct(self.ffi, self.types[2], max_events, self.ny)
        return ev, keep

    def _events_into(self, res: Result, ev, keep, p) -> None:
        n_events = int(ev.n_events)
        count = min(n_events, keep[0].shape[0])
        recs = records(self.events, keep[0][:count], keep[1][:count], keep[2][:count], keep[3][:count],
                       self.state_names, self.ny)
        res.events = recs
        res.stats["events"] = n_events
        if ev.terminated and recs and recs[-1].t > res.t[-1]:
            rec = recs[-1]
            res.t = np.append(res.t, rec.t)
            res.y = np.vstack([res.y, rec.y[None, :]])
            o = self._outputs_at(rec.t, rec.y, p)
            res.outputs = {name: np.append(v, o[i]) for i, (name, v) in enumerate(res.outputs.items())}
