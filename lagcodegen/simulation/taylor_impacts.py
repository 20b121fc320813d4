"""Runs of constrained systems with contacts on the Taylor method (``simulate(method="taylor")``):
the Taylor contact driver (lagcodegen/runtime/lcg_taylor_imp.c) integrates the system's contact
jet (:mod:`lagcodegen.codegen.taylor.contacts`: the index-1 system of the equality rows and the
contacts in persistent contact, the rows held set at run time), locates impacts and releases as
roots of the gaps' and multipliers' Taylor polynomials, and applies the impact law of the other
impact drivers (lagcodegen/runtime/lcg_imp_law.c, through the model's contact table): one call,
no Python in the loop. The result is that of the index-1 driver (:mod:`.constrained_impacts`):
``res.impacts`` (:class:`~.constrained_impacts.ContactLog`), ``outputs["lambda_ineq_<k>"]``.

The jet is the index-1 system of the rows held for every active set at once (the rows held are
run-time values of the jet's workspace, a row not held reads lambda_k = 0; per order the
recurrence of the mass matrix's with the augmented matrix [M R^T; R 0], factored once per step).
Every root of a step's polynomials is isolated, so no flight is skipped at any tolerance. Where
switches follow one another without flight at one time (impacts accumulating below the resolution
of t, as the frictionless rocking block's alternating corners), the contacts that touch at rest
are held from there on ("stick" records without impulse).

Frictionless and no-slip contacts, equality rows, generalized speeds, minimal coordinates,
ensembles, the integrator object; the system's compiled events located on the steps' polynomials
(those whose expression uses a multiplier refused by name).

Coulomb friction (planar: one tangent row; 3-D: two, the circular cone): the modes are the friction core's
(lagcodegen/runtime/lcg_imp_fric.c, as on CVODE and IDA: lcg_fr_start at the start, lcg_fr_impact
and lcg_fr_modes at every switch with the core's ``ending``, Painleve's paradox raising
:class:`~.constrained_impacts.PainleveError`). While the modes are fixed a sticking contact holds
its tangential row, a slipping one only its normal row with the force direction G - sigma mu T
(the jet's tl_slip: lambda_t = -sigma mu lambda_n at every order, K_[0] no longer symmetric). The
transitions (lcg_fr_roots: mu lambda_n -+ lambda_t, the slip velocity, the determinant) are
evaluated on the step's polynomial (the state there, its multipliers by lcg_fr_crhs) at 8 points
of each step, a sign change bisected to the resolution of t (a root pair within one eighth of a
step is not seen). 3-D: the force direction G - mu (d1 T1 + d2 T2) with d = u/|u| in the jet (the
Taylor series of |u| and of u/|u| order by order, lambda_t = -mu d lambda_n as their product),
so d turns along the motion within a step; while |u| is at most 100 contact_speed (a slip from
rest, or one about to stop: u/|u| has no useful series there) d is the core's, fixed within the
step and renewed at each step's start, the steps then at most 1e-9, doubling. Refused by name:
sensitivities.
"""

from __future__ import annotations

import ctypes
import functools
import os
import time

import numpy as np

from ..build import DEFAULT_CFLAGS, driver_runtime, types_headers
from ..codegen.cffi_decl import POLL_CDEF, TAYLOR_TABLE_CDEF, driver_cdef, header_cdef
from ..codegen.record import scene_of_code
from ..codegen.taylor.emit import P_MAX, runtime_key_texts, runtime_sources
from ..errors import LagcodegenError
from ..libraries import taylor_contact_library
from ..result import Result
from ..runtime import sources as runtime_files
from ..solvers.base import NativeEvents
from ..solvers.control import POLL_EVERY, install
from ..solvers.request import Index1Form, Recording, StepControl
from ..solvers.taylor.runner import run_stats
from .constrained_impacts import ContactOptions, ImpactRunner

#: The files of lagcodegen/runtime/ the Taylor contact driver is compiled from (besides the Taylor
#: runtime's sources, whose lcg_taylor_driver.h it includes).
RUNTIME_FILES = ("lcg_taylor_imp.c", "lcg_taylor_imp.h", "lcg_taylor_contact.h", "lcg_imp_law.c", "lcg_imp_law.h",
                 "lcg_imp_fric.c", "lcg_imp_fric.h", "lcg_imp_model.h", "lcg_dae_model.h", "lcg_model.h")

#: The tables are opaque to Python (their addresses come from the model's libraries).
_OPAQUE = "typedef ... lcg_taylor_contact;\ntypedef ... lcg_imp_model;\ntypedef ... lcg_imp_friction;\n"


def _cdef() -> str:
    header = header_cdef("lcg_taylor_imp.h")
    return "\n".join([TAYLOR_TABLE_CDEF, driver_cdef("taylor"), driver_cdef("dae"), _OPAQUE, header, POLL_CDEF])


@functools.lru_cache(maxsize=4)
def _runtime(cc: str, cflags: tuple[str, ...]):
    def render() -> dict[str, str]:
        return {**runtime_sources(), **runtime_files(RUNTIME_FILES), **types_headers(("dae",))}

    own = sorted(runtime_files(RUNTIME_FILES).items())
    texts = [f"P_MAX {P_MAX}", *runtime_key_texts(), *(f"{k}\0{v}" for k, v in own)]
    return driver_runtime("taylor_impacts", texts, render, _cdef(), "lcg_taylor_imp.h", ["-lm", "-pthread"], cc,
                          cflags, units=("lcg_taylor_imp.c", "lcg_imp_law.c", "lcg_imp_fric.c"))


def taylor_impact_runtime(cc: str | None = None, cflags: tuple[str, ...] = DEFAULT_CFLAGS):
    """The Taylor contact driver (lagcodegen/runtime/lcg_taylor_imp.c) as a cffi module of its own,
    built into the cache once per lagcodegen version, compiler, flags and Python (no SUNDIALS)."""
    return _runtime(cc or os.environ.get("CC") or "cc", tuple(cflags))


class TaylorImpactRunner:
    """The Taylor contact driver bound to one compiled constrained system with contacts: its
    contact jet (built on first use, :func:`~lagcodegen.libraries.taylor_contact_library`) and the
    index-1 impact runner's contact table, buffers and result (:class:`.constrained_impacts.ImpactRunner`)."""

    def __init__(self, sim, impacts: ImpactRunner):
        system = sim.system
        if sim.info.lang != "c":
            raise LagcodegenError("contacts are generated in C only")
        self.sim = sim
        self.impacts = impacts
        self.rt = rt = taylor_impact_runtime()
        self.ffi = ffi = rt.ffi
        self.poll = install(rt)
        scene = scene_of_code(sim.compiled.code, "method='taylor'")
        self.library = lib = taylor_contact_library(system, scene, list(sim.info.events))
        _, self.decomposition, self.rows = lib.extra
        getter = getattr(lib.handle, lib.functions["table"])
        getter.restype = ctypes.c_void_p
        getter.argtypes = []
        self.table = ffi.cast("const lcg_taylor_contact *", getter())
        self.imp = ffi.cast("const lcg_imp_model *", int(impacts.ffi.cast("uintptr_t", impacts.table)))
        if self.rows.nk != len(impacts.contacts) or self.decomposition.ny != sim.ny:
            raise LagcodegenError(f"the Taylor contact jet of {sim.info.prefix!r} does not match its code")
        self.fric = ffi.NULL  # Coulomb friction: the jet's tl_slip, the friction table, mu
        if system.has_friction:
            slip = getattr(lib.handle, f"{sim.info.prefix}_taylor_contact_slip")
            slip.restype = ctypes.c_void_p
            slip.argtypes = []
            self.fric = ffi.new("lcg_taylor_friction *")
            self.fric.slip = ffi.cast("void (*)(void *, const int *, const double *)", slip())
            self.fric.fr = ffi.cast("const lcg_imp_friction *", int(impacts.ffi.cast("uintptr_t", impacts.friction)))
            self.fric.mu = self._mu = ffi.from_buffer("double[]", impacts.mu)

    #: the family of the runs (the integrator object's name for it)
    family = "taylor"

    @property
    def contacts(self) -> list:
        """The system's contacts (the indices k of its inequalities with a restitution)."""
        return self.impacts.contacts

    def run(self, t, y0, p, control: StepControl, form: Index1Form, recording: Recording, contacts: ContactOptions,
            *, cancel=None, active=None) -> Result:
        """A run from ``y0`` at the output times ``t`` with the step control ``control`` (a scalar
        atol; ``order``, budgets), the Baumgarte rates of ``form`` (alpha, beta; negative: the
        natural rate at y0; no projection), ``recording`` (``roots``: locate the compiled events,
        at most ``max_events`` kept; those using a multiplier are refused) and the contact settings
        ``contacts``; ``cancel``: None,
        or a numpy int array of one value that stops the run (-80) once set; ``active``: None, or
        the contacts' modes at the start (a numpy intc array, nonzero: in persistent contact),
        overwritten with those at the end (the arguments of
        :meth:`.constrained_impacts.ImpactRunner.run`, so that the integrator object,
        :mod:`.impact_stepper`, drives either)."""
        ffi, impacts = self.ffi, self.impacts
        atol = control.atol
        if isinstance(atol, bool) or not isinstance(atol, (int, float)):
            raise LagcodegenError("runs with contacts take a scalar atol")
        if form.projection:
            raise LagcodegenError("the Taylor contact driver projects nothing (projection=False)")
        sim = self.sim
        nr = sim.info.J + len(impacts.contacts)
        if self.fric != ffi.NULL:  # with friction: every row's multiplier (as the CVODE driver)
            nr = int(impacts.table.nrow)
        buf = impacts._buffers(t, nr, contacts, Recording(roots=False))
        if recording.roots and sim.info.events:  # the events located on the steps' polynomials
            refused = [ev.name for ev, row in zip(sim.info.events, self.rows.events) if row < 0]
            if refused:
                raise LagcodegenError(f"the Taylor contact driver does not locate the event(s) {', '.join(refused)}: "
                                      "their expressions use a multiplier, which the Taylor jet computes after the "
                                      "events of the same order; run with events=False, or on CVODE "
                                      "(method='adams' or 'bdf')")
            buf.events = NativeEvents(ffi, "lcg_events", sim.info.events, sim.ny, recording.max_events)
        if active is not None:
            nk = len(self.contacts)
            if not (isinstance(active, np.ndarray) and active.dtype == np.intc and active.shape == (nk,)):
                raise LagcodegenError(f"active must be an intc array of {nk} values (one per contact)")
            buf.active = active
        opt = ffi.new("lcg_taylor_options *")
        opt.rtol, opt.atol, opt.atol_vec = float(control.rtol), float(atol), ffi.NULL
        opt.max_steps, opt.max_step = int(control.max_steps), float(control.max_step)
        opt.order, opt.rel_block = int(control.order or 0), 0
        opt.max_wall, opt.poll, opt.poll_every = float(control.max_wall), self.poll, POLL_EVERY
        if cancel is not None:
            opt.cancel = ffi.from_buffer("int[]", cancel)
        st = ffi.new("lcg_taylor_stats *")
        stab = np.array([form.alpha, form.beta], dtype=float)
        p = np.ascontiguousarray(p, dtype=float)
        y0 = np.ascontiguousarray(y0, dtype=float)
        fb = ffi.from_buffer
        start = time.perf_counter()
        flag = self.rt.lib.lcg_taylor_imp_solve(
            self.table, self.imp, fb("double[]", p) if p.size else ffi.NULL, fb("double[]", y0), t.size,
            fb("double[]", buf.t), fb("double[]", buf.yout), fb("double[]", buf.out), fb("double[]", buf.lamout), opt,
            fb("double[]", impacts.restitution), fb("double[]", buf.settings), fb("int[]", buf.active),
            buf.max_records, fb("double[]", buf.rec), buf.n_rec, st, fb("double[]", stab),
            buf.events.struct if buf.events else ffi.NULL, self.fric)
        res = impacts._result(buf.raw(flag, st, p, time.perf_counter() - start), contacts, "taylor", "Taylor",
                              stats_of=run_stats)
        res.stats["alpha"], res.stats["beta"] = float(stab[0]), float(stab[1])
        return res
