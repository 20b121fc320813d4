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
from ...errors import LagcodegenError
from ...runtime import sources as runtime_files
from ..control import install
from .sensitivity import CDEF, LINKED_UNITS, _sources, directions, functions, sens_options
from .sensitivity_events import SensEvents

#: The stepper's files of lagcodegen/runtime/ (lcg_cvsens_stepper.c includes lcg_cvsens.c).
STEPPER_FILES = ("lcg_cvsens_stepper.c", "lcg_cvsens_stepper.h")

STEPPER_CDEF = """
typedef struct lcg_cvsens_stepper lcg_cvsens_stepper;
lcg_cvsens_stepper *lcg_cvsens_stepper_new(const lcg_model *m, lcg_sens_rhs_fn sens_rhs, int ns, const int *which,
                                           const lcg_cvsens_options *opt, double *mem, double *s,
                                           lcg_cvsens_events *ev, char *message, size_t size);
void lcg_cvsens_stepper_free(lcg_cvsens_stepper *st);
lcg_cvsens_stats *lcg_cvsens_stepper_stats(lcg_cvsens_stepper *st);
int lcg_cvsens_stepper_until(lcg_cvsens_stepper *st, double t_end);
int lcg_cvsens_stepper_grid(lcg_cvsens_stepper *st, int nt, const double *tout, double *yout, double *sout);
int lcg_cvsens_stepper_step(lcg_cvsens_stepper *st, double t_limit);
"""


@functools.lru_cache(maxsize=4)
def _runtime(cc: str, cflags: tuple[str, ...]):
    sundials = find_sundials()

    def render() -> dict[str, str]:
        return {**_sources(), **runtime_files(STEPPER_FILES)}

    texts = [f"{k}\0{v}" for k, v in sorted(render().items())]
    return driver_runtime("cvsens_stepper", [sundials.version, *texts], render, CDEF + STEPPER_CDEF,
                          "lcg_cvsens_stepper.h", [*sundials.link_args(("cvode", "core")), "-lm"], cc, cflags,
                          units=("lcg_cvsens_stepper.c", *LINKED_UNITS))


def stepper_runtime(cc: str | None = None, cflags: tuple[str, ...] = DEFAULT_CFLAGS):
    """The sensitivity stepper's cffi module, built once per installation."""
    return _runtime(cc or os.environ.get("CC") or "cc", tuple(cflags))


class CVSensStepper:
    """The C stepper of a compiled scene's ODE with the sensitivities ``names`` on CVODE, on
    ``mem`` = (t, y, p), a float64 array the caller keeps; ``sens`` (ns, ny) the initial
    sensitivities (None: unit vectors for initial values, zeros for parameters, as a run starts).
    ``events`` (:class:`~.events.CompiledEvents` or None) located as in a run, each record with its
    time's sensitivities."""

    family = "cvode"
    with_sensitivities = True  # the integrator object shows them (SensitivityIntegrator)

    def __init__(self, cm, mem: np.ndarray, names, *, rtol: float, atol, errcon: bool, method: str,
                 jacobian: bool, max_steps: int, first_step: float, max_step: float, min_step: float,
                 max_order: int, max_wall: float = 0.0, events=None, max_events: int = 10_000,
                 corrector: str = "staggered"):
        names, which, s0 = directions(cm, names)
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
        opt, atol_all = sens_options(ffi, install(rt), method=method, rtol=rtol, atol=atol, ny=ny, ns=ns,
                                     errcon=errcon, max_steps=max_steps, jacobian=jacobian, max_order=max_order,
                                     first_step=first_step, max_step=max_step, min_step=min_step, max_wall=max_wall,
                                     corrector=corrector)
        self.compiled = events
        self.events = list(events.events) if events is not None else []
        self._native = SensEvents(ffi, events, ny, ns, max_events) if self.events else None
        msg = ffi.new("char[]", 512)
        handle = lib.lcg_cvsens_stepper_new(table, rhs, ns, ffi.from_buffer("int[]", which), opt,
                                            ffi.from_buffer("double[]", mem), ffi.from_buffer("double[]", self.sens),
                                            self._native.struct if self._native else ffi.NULL, msg, 512)
        if handle == ffi.NULL:
            raise LagcodegenError(f"CVODE integrator with sensitivities: {ffi.string(msg).decode(errors='replace')}")
        self.handle = handle
        self.mem = mem
        self.stats = lib.lcg_cvsens_stepper_stats(handle)
        self.until = functools.partial(lib.lcg_cvsens_stepper_until, handle)
        self.step = functools.partial(lib.lcg_cvsens_stepper_step, handle)
        self._grid = lib.lcg_cvsens_stepper_grid
        self._sout_ptr = ffi.from_buffer

    def grid(self, nt, tout, yout) -> int:
        """The grid call (the integrator's): the sensitivities into ``self.sout`` (nt, ns, ny)."""
        sout = self.sout
        if sout is None or sout.shape[0] != nt:
            sout = self.sout = np.empty((max(nt, 0), len(self.names), self.cm.ny))
        return self._grid(self.handle, nt, tout, yout, self._sout_ptr("double[]", sout))

    def free(self) -> None:
        """Free the C stepper (once)."""
        handle, self.handle = self.handle, None
        if handle is not None:
            self.lib.lcg_cvsens_stepper_free(handle)

    def stats_dict(self) -> dict:
        st = self.stats
        return {"steps": st.nsteps, "rhs_evals": st.nrhs, "error_test_fails": st.netfails,
                "nonlinear_conv_fails": st.nncfails, "jac_evals": st.njac, "factorizations": st.nfactor,
                "block_solves": st.nblock_solves, "h_last": st.h_last, "t_reached": st.t_reached,
                "model_error": st.model_error}

    def event_arrays(self):
        """(count, terminated, (t, y, which, direction)) of the last call's events (rows: the state,
        then the sensitivities)."""
        ev = self._native
        return int(ev.struct.n_events), ev.terminated, (ev.t, ev.y, ev.which, ev.direction)

    def event_records(self, state_names) -> list:
        """The last call's events with their times' sensitivities (:class:`SensEvents`)."""
        p = np.array(self.mem[1 + self.cm.ny:])
        return self._native.records(self.cm, self.fns, self.names, self.which, p)
