"""Impact runs of constrained systems with contacts: inequality constraints g_k(q, t) >= 0
(notes, eq. 4.3) given as :class:`~lagcodegen.theory.constraints.Inequality` with a coefficient
of restitution e_k, integrated by the runtime's impact driver in one call (index-1:
lagcodegen/runtime/lcg_imp.c on CVODE; GGL: lagcodegen/runtime/lcg_imp_ida.c on IDA, below).

**Impact law.** When a free contact reaches g_k = 0 with a closing normal velocity
w_k = G_k q' + G0_k < 0 (G_k = dg_k/dq, G0_k = dg_k/dt), the run stops at the located root and
the velocities jump by the impulses of the constraint forces lambda A (sec. 4.3; eq. 4.5
integrated over an impact of zero duration, where the bounded forces F contribute nothing):

    M (q'+ - q'-) = R^T P,   w_k+ = -e_k w_k-  (Newton's law, every contact that takes part),
    A q'+ + A0 = 0 (equality rows), w_j+ = 0 (contacts already in persistent contact),

solved together in the generated code (``<prefix>_impact.c``, or with Fortran model code
``<prefix>_impact.f90`` and its C tables ``<prefix>_impact_table.c``: the augmented matrix
[M R^T; R 0] factored numerically by LU; M is never inverted symbolically). With the notes'
Lambda = -P this is q'+ = q'- - M^-1 A^T Lambda. P_k >= 0 is the impulse of contact k in the sign
of its multiplier (positive: the contact pushes). Contacts take part when they touch
(g_k <= ``gap_tol``) and close (w_k < 0). Simultaneous contacts are solved jointly; a contact
whose impulse comes out negative is dropped and the system solved again without it (the active
set of the linear complementarity problem of the impact, found by elimination; at most
n_contacts + 1 solves). Limits: Newton's law on the joint system is the simultaneous-impact
law, which is not the sequence of pairwise impacts: for chains in contact at the same instant
(a cradle whose balls touch) it does not reproduce the pairwise result (let small gaps separate
the impacts, as the cradle example does); after the joint solve a dropped contact may still
close (it is then hit again at once, as the next impact); without friction (below) impulses act
along G_k only.

**Persistent contact.** A contact whose rebound speed e_k |w_k-| is at most ``contact_speed``,
or that is hit again within ``min_flight`` of its previous impact (accumulating impacts, Zeno),
takes a plastic impact (e_k = 0) and then holds g_k = 0 as a holonomic constraint with its
multiplier (the index-1 formulation, eq. 4.5, Baumgarte stabilized as the equality rows);
it is released where the multiplier turns negative (root finding on lambda_k, as the particle
leaving the sphere). A contact that touches at rest at the start (|w_k| <= ``contact_speed``)
starts in persistent contact if its multiplier is positive there.

**Result.** ``Result.impacts`` (:class:`ContactLog`) lists every impact, switch to persistent
contact and release with its time, contact, kind, impulse and normal velocities before and
after, the final modes, and the accumulation (Zeno) time extrapolated from the impacts
(:meth:`ContactLog.accumulation_time`); ``Result.outputs["lambda_ineq_<k>"]`` is the multiplier
of contact k at the output times (0 while free).

**No slip.** An :class:`~lagcodegen.theory.constraints.Inequality` with a ``tangent`` is a
rough contact: its tangential row d tangent/dq is held with it (in impacts: tangential velocity
to zero; in persistent contact: a multiplier of either sign, unbounded friction), e.g. the corners
of Housner's rocking block. Active rows that are dependent (a block resting flat on two no-slip
corners) are solved with a small regularization of the multiplier block (see the generated
``solve_active``).

**Coulomb friction** (index-1 and GGL). An :class:`~lagcodegen.theory.constraints.Inequality`
with a ``tangent`` and ``friction=mu`` (a position expression whose time derivative is the slip
velocity u = T q' + T0) obeys Coulomb's law, not an ideal constraint's (sec. 4.3): in persistent
contact it sticks (row T held, lambda_t free) while |lambda_t| <= mu lambda_n, and slips
otherwise with lambda_t = -mu lambda_n sign(u) set by the law (the normal row's force direction
G - sign(u) mu T: the system is no longer symmetric). Transitions are roots located by CVODE: stick -> slip where
mu lambda_n -+ lambda_t reaches 0, slip -> stick or reversal where u reaches 0 (then the
sticking force decides: admissible, it grips; else it slips the other way), release where
lambda_n reaches 0. At each switch and impact the modes of all contacts in persistent contact
are chosen together by enumerating stick / slip+ / slip- / release per contact (slip from rest
only when |u| <= ``contact_speed``; at most 4096 combinations), the mode whose root fired
excluded, and checking each combination's forces and accelerations. Exactly one consistent
motion is taken (consistent modes with the same accelerations, e.g. at the limit of friction,
count as one; the most constrained is kept); none (inconsistency) or several with different
accelerations (indeterminacy) is Painleve's paradox and raises :class:`PainleveError` naming it,
as does the contact problem of a slipping contact turning singular during a run (a root of its
determinant). Impacts take Newton's law on the normal and, per contact, a tangential impulse that
sticks (T dv = -u) when |P_t| <= mu P_n, else slides with P_t = -sigma mu P_n (sigma u+ >= 0), the
modes again enumerated jointly (a "tangential_impulse" record each); a contact that begins to stick
has its slip velocity projected to 0. ``Result.impacts`` records the transitions ("slip",
"grip", "reverse"; :meth:`ContactLog.transitions`, ``stats["stick_slip"]``) and the final modes
(``ContactLog.friction_modes``); ``outputs["lambda_t_ineq_<k>"]`` is the tangential multiplier.
A contact with two tangents (3-D) has the exact circular cone: it sticks while |lambda_t| <=
mu lambda_n, slips with the force -mu lambda_n u/|u| against its slip velocity (mode "slip", the
outputs ``lambda_t0_ineq_<k>``, ``lambda_t1_ineq_<k>``); a slip from rest and a sliding impulse
take the direction that makes the force oppose the resulting slip (fixed-point iteration, and
Newton's method on all such directions together where contacts are coupled). Models
with generalized speeds take friction alike (the rows act on v, q' = k(q, v, t)).

*Where it lives*: the friction core lagcodegen/runtime/lcg_imp_fric.c (the contact problem of a
mode, the enumeration of the modes, frictional impacts, slip directions, the roots, the Painleve
messages), called by the drivers lcg_imp.c (index-1) and lcg_imp_ida.c (GGL) and shipped with C
bundles, whose RK4 example drives it (:mod:`lagcodegen.codegen.bundle_contacts`); it solves the
modes from the model's numbers (M, F, rows, gamma) that the generated ``<prefix>_impact.c`` (or
``.f90``) gives through the table ``lcg_imp_friction`` (lcg_imp_model.h; generated only for
systems with friction or the GGL formulation): no Python in the loop, Ctrl-C polled. So that a
friction limit is not crossed and recrossed within one CVODE step while a contact sticks under
forcing that depends on time alone, CVODE's state carries the integrals of the contact forces,
whose error control keeps the steps to the forces' time scale. Impacts with friction and
Newton's law can gain energy in some configurations (a known property of that impact law); the
law is applied as stated. Other solvers than the native CVODE and IDA are refused by name.

**GGL on IDA** (:meth:`ImpactRunner.run_ggl`, lagcodegen/runtime/lcg_imp_ida.c): the equality rows
and the contacts in persistent contact (with their no-slip tangential rows) are rows of the GGL
residual [q' - v - R_h^T mu; M v' - F - R^T lambda; h_r; R_r v + R0_r], the free contacts' rows
lambda_r = 0, mu_r = 0; an impact, a switch into persistent contact or a release (the multiplier,
an unknown of the DAE, reaching 0) stops IDA at the located root, the same impact law applies
(lagcodegen/runtime/lcg_imp_law.c, shared with the index-1 driver) and IDA restarts from
consistent values (lambda and v' from the index-1 system of the rows held, mu = 0). With Coulomb
friction a sticking contact holds its tangential row(s) as GGL rows (velocity level, as no-slip
tangents); a slipping contact holds its normal row only and its tangential rows are
lambda_t + sigma mu lambda_n = 0 (3-D: lambda_t = -mu lambda_n d, d the slip direction at the
state), so that the residual's force is W^T lambda with W = G - sigma mu T for that contact; the
roots (stick -> slip, slip -> stick, release, the contact problem turning singular) are the
friction core's, evaluated with the contact forces of the index-1 problem at IDA's state (the
unknowns lambda of index-2 rows carry the velocity constraints' error divided by the step); at
each root and impact the modes of all contacts are chosen by the friction core exactly as on the
index-1 driver and IDA restarts from consistent values. A contact problem turning singular stops
a GGL run where its determinant has fallen to 1e-4 of its value where the modes began (IDA cannot
step up to the zero, where lambda is infinite). Models with generalized speeds (q' = k(q, v, t):
quaternion bases) run there too, the positions corrected along the speeds' images,
q' - k(q, v + R_h^T mu, t) (k is affine in v; mu = 0 on the solution). **Minimal coordinates**:
:class:`~.minimal.MinimalSimulation` runs the reduced model with the contacts in the remaining
coordinates on the index-1 driver.

**Taylor** (``method="taylor"``, :mod:`.taylor_impacts`): the same law and Coulomb friction, planar and
3-D (the core's modes); impacts and releases are roots of the Taylor polynomials
of the gaps and multipliers. Ensembles run each member as one call of the
system's driver (index-1, GGL or Taylor), every member's events and contact log kept
(:mod:`.impact_ensemble`); the integrator object makes one call per propagate call
(:mod:`.impact_stepper`). Fortran model code (``lang="fortran"``) runs on the same drivers: its
contact functions are bound to the C names, with the same tables, and its runs are the C code's
(bit for bit where neither compiler fuses multiply-adds). Not supported with contacts: the
scikit-sundae backend, projection.
"""

from __future__ import annotations

import ctypes
import functools
import os
import time
from dataclasses import dataclass, field

import numpy as np

from ..build import DEFAULT_CFLAGS, config_header, driver_runtime, find_sundials, generated_headers, types_headers
from ..codegen.cffi_decl import DAE_TABLE_CDEF, MODEL_TABLE_CDEF, POLL_CDEF, driver_cdef, header_cdef
from ..codegen.signatures import IMP_FRICTION_TABLE, IMP_TABLE, cffi_struct
from ..codes import Flag
from ..errors import LagcodegenError, SolverError
from ..result import Result
from ..runtime import sources as runtime_files
from ..solvers.control import CANCELLED, POLL_EVERY, install, raise_pending
from ..solvers.base import METHODS, SINGULAR_AUGMENTED, NativeEvents, message, native_stats
from ..solvers.request import GGLForm, Index1Form, Recording, StepControl

#: The kinds of :class:`ImpactRecord` (lcg_imp.h: LCG_IMP_BOUNCE, ...). With Coulomb friction:
#: "slip" (a sticking contact begins to slip), "grip" (a slipping one begins to stick), "reverse"
#: (a slipping one slips the other way from rest), "tangential_impulse" (the tangential impulse of
#: a contact in an impact).
KINDS = ("bounce", "stick", "release", "contact_impulse", "slip", "grip", "reverse", "tangential_impulse")

#: The friction transitions among :data:`KINDS`.
FRICTION_TRANSITIONS = ("slip", "grip", "reverse")

#: The files of lagcodegen/runtime/ the impact driver is compiled from.
RUNTIME_FILES = ("lcg_imp.c", "lcg_imp.h", "lcg_imp_law.c", "lcg_imp_law.h", "lcg_imp_fric.c", "lcg_imp_fric.h",
                 "lcg_imp_ida.c", "lcg_imp_ida.h", "lcg_imp_model.h", "lcg_dae_model.h", "lcg_model.h",
                 "lcg_control.h", "lcg_sundials.h", "sundials_api.h")

_CDEF = "\n".join([MODEL_TABLE_CDEF, DAE_TABLE_CDEF, driver_cdef("cvc"), driver_cdef("ida"), cffi_struct(IMP_TABLE),
                   cffi_struct(IMP_FRICTION_TABLE), header_cdef("lcg_imp.h"), header_cdef("lcg_imp_ida.h"),
                   POLL_CDEF])


class PainleveError(SolverError):
    """Contacts with Coulomb friction that have no consistent stick/slip/release mode
    (inconsistency), several with different motions (indeterminacy), or whose contact problem
    became singular while slipping: Painleve's paradox, reported instead of integrating a branch.
    ``t``: where; ``result``: the run up to there."""


@dataclass(frozen=True, kw_only=True)
class ContactOptions:
    """How contacts switch between impacts and persistent contact (see the module docstring).

    ``contact_speed``: a rebound at most this fast (in the units of w = G q' + G0) is a plastic
    impact into persistent contact; ``min_flight``: an impact within this time of the contact's
    previous one is one too (accumulation); ``gap_tol``: contacts with g <= gap_tol take part in
    an impact; ``max_records``: records kept at most."""

    contact_speed: float = 1e-6
    min_flight: float = 1e-9
    gap_tol: float = 1e-9
    max_records: int = 100_000

    def __post_init__(self):
        for name in ("contact_speed", "min_flight", "gap_tol"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not (0 <= v < float("inf")):
                raise LagcodegenError(f"ContactOptions: {name} must be a finite number >= 0, got {v!r}")
        if isinstance(self.max_records, bool) or not isinstance(self.max_records, int) or self.max_records < 1:
            raise LagcodegenError(f"ContactOptions: max_records must be a positive integer, got {self.max_records!r}")


@dataclass(frozen=True)
class ImpactRecord:
    """One contact record: ``t``, ``contact`` (index k of the inequality g_k >= 0), ``kind`` (one
    of :data:`KINDS`), ``impulse`` P_k (>= 0: the contact pushes; the notes' Lambda = -P), and the
    normal velocity w_k = G_k q' + G0_k before and after. Friction records ("slip", "grip",
    "reverse", "tangential_impulse") carry the tangential multiplier lambda_t (transitions) or
    the tangential impulse P_t, and the slip velocity u = T q' + T0 before and after in place of w."""

    t: float
    contact: int
    kind: str
    impulse: float
    w_before: float
    w_after: float


@dataclass
class ContactLog:
    """The contact records of a run, in time order (``records``), with column views."""

    records: list = field(default_factory=list)
    final_modes: dict = field(default_factory=dict)  # contact k -> "free" or "contact" at the end
    truncated: bool = False  # more records than ContactOptions.max_records
    #: contacts with Coulomb friction: k -> "free", "stick", "slip+" or "slip-" at the end ("slip"
    #: for a 3-D contact, two tangents)
    friction_modes: dict = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.records)

    def __iter__(self):
        return iter(self.records)

    def __getitem__(self, i):
        return self.records[i]

    def select(self, kind: str | None = None, contact: int | None = None) -> list:
        """The records of one kind and/or contact."""
        return [r for r in self.records if (kind is None or r.kind == kind) and (contact is None or r.contact == contact)]

    @property
    def times(self) -> np.ndarray:
        """Times of the impacts (bounces and switches into persistent contact)."""
        return np.array([r.t for r in self.records if r.kind in ("bounce", "stick")])

    def accumulation_time(self, contact: int, *, resolved: float = 1e-4) -> float | None:
        """Where the impacts of ``contact`` accumulate (Zeno), extrapolated from three consecutive
        impacts as a geometric sequence of flight times: t_inf = t_n + d_n r / (1 - r) with
        d_n = t_n - t_(n-1), r = d_n / d_(n-1) (exact for a ball on a flat floor, where r = e).
        The last three impacts whose flights are at least ``resolved`` times the first flight
        are used: the last impacts, slower than the tolerances resolve, locate their roots only
        to about atol / speed. None with fewer than three such impacts or flights that do not
        shrink."""
        times = [r.t for r in self.records if r.contact == contact and r.kind in ("bounce", "stick")]
        if len(times) < 3:
            return None
        first = times[1] - times[0]
        n = len(times) - 1
        while n >= 2 and not (times[n] - times[n - 1] >= resolved * first):
            n -= 1
        if n < 2:
            return None
        d1, d2 = times[n - 1] - times[n - 2], times[n] - times[n - 1]
        if not (0 < d2 < d1):
            return None
        ratio = d2 / d1
        return times[n] + d2 * ratio / (1 - ratio)

    def transitions(self, contact: int | None = None) -> list:
        """The friction transitions (records of kind "slip", "grip", "reverse"), of one contact or all."""
        return [r for r in self.records if r.kind in FRICTION_TRANSITIONS
                and (contact is None or r.contact == contact)]

    @property
    def impulses(self) -> np.ndarray:
        return np.array([r.impulse for r in self.records if r.kind in ("bounce", "stick")])


@functools.lru_cache(maxsize=4)
def _runtime(cc: str, cflags: tuple[str, ...]):
    sundials = find_sundials()

    def render() -> dict[str, str]:
        return {**runtime_files(RUNTIME_FILES), "lcg_config.h": config_header(sundials), **generated_headers(),
                **types_headers(("dae", "cvc", "ida"))}

    texts = [f"{k}\0{v}" for k, v in sorted(render().items())]
    return driver_runtime("impacts", texts, render, _CDEF, "lcg_imp_ida.h",
                          [*sundials.link_args(("cvode", "ida", "core")), "-lm"], cc, cflags)


def impact_runtime(cc: str | None = None, cflags: tuple[str, ...] = DEFAULT_CFLAGS):
    """The impact driver (lagcodegen/runtime/lcg_imp.c) as a cffi module of its own, built into
    the cache once per lagcodegen version, compiler, flags and Python."""
    return _runtime(cc or os.environ.get("CC") or "cc", tuple(cflags))


@dataclass(frozen=True)
class ContactRun:
    """What an impact driver takes for runs of one system (besides the times, state and
    parameters): the runner, the step control, the form (:class:`Index1Form`: Baumgarte on the
    index-1 driver; :class:`GGLForm`: the GGL driver on IDA, with ``alg_atol`` the absolute
    tolerance of its multipliers), what is recorded, the contact settings (made by
    ``ConstrainedSimulation.contact_run``: the runs of simulate, ensembles and the integrator
    object; ``taylor_contact_run``: those of the Taylor contact driver, :mod:`.taylor_impacts`,
    whose runner takes the index-1 driver's arguments)."""

    runner: "ImpactRunner"  # or a TaylorImpactRunner (the index-1 driver's run signature)
    control: StepControl
    form: Index1Form | GGLForm
    recording: Recording
    contacts: ContactOptions
    alg_atol: float | None = None

    def execute(self, t, y0, p, *, cancel=None, active=None) -> Result:
        """One run of the driver of this form over the output times ``t`` from y0 (``cancel``,
        ``active``: as :meth:`ImpactRunner.run`)."""
        if isinstance(self.form, GGLForm):
            return self.runner.run_ggl(t, y0, p, self.control, self.form, self.recording, self.contacts,
                                       self.alg_atol, cancel=cancel, active=active)
        return self.runner.run(t, y0, p, self.control, self.form, self.recording, self.contacts, cancel=cancel,
                               active=active)


class ImpactRunner:
    """The impact driver bound to one compiled constrained system with contacts (its contact
    table ``<prefix>_imp_model_table()`` from the model's library)."""

    def __init__(self, sim):
        info = sim.info
        if not info.contacts:
            raise LagcodegenError("this constrained system has no contacts (Inequality with a restitution)")
        self.sim = sim
        self.rt = rt = impact_runtime()
        self.ffi = ffi = rt.ffi
        self.poll = install(rt)  # Ctrl-C (and progress) during a run, as the other drivers
        library = sim.compiled._library  # the model library (ctypes), kept open by the compiled model
        getter = getattr(library, f"{info.prefix}_imp_model_table")
        getter.restype = ctypes.c_void_p
        getter.argtypes = []
        self.table = ffi.cast("const lcg_imp_model *", getter())
        dae_addr = int(sim.ffi.cast("uintptr_t", sim.table))
        self.dae = ffi.cast("const lcg_dae_model *", dae_addr)
        if self.table.nk != len(info.contacts) or self.table.nq != sim.n or self.table.dae != self.dae:
            raise LagcodegenError(f"the contact table of {info.prefix!r} does not match its code")
        self.contacts = list(info.contacts)
        self.restitution = np.array([sim.system.restitution[k] for k in self.contacts], dtype=float)
        system = sim.system
        #: Coulomb coefficients (-1: none), the row of each contact's tangential multiplier
        self.mu = np.array([-1.0 if system.friction[k] is None else system.friction[k] for k in self.contacts])
        self.friction = ffi.NULL
        #: the model's numbers at a state (lcg_imp_friction): friction's modes, the GGL residual
        self.numbers = ffi.NULL
        self.tangent_rows = {}
        if system.has_friction or sim._ggl:
            getter = getattr(library, f"{info.prefix}_imp_friction_table", None)
            if getter is None:
                raise LagcodegenError(f"the code of {info.prefix!r} has no friction table (generated by a "
                                      "lagcodegen without Coulomb friction): generate it again")
            getter.restype = ctypes.c_void_p
            getter.argtypes = []
            self.numbers = ffi.cast("const lcg_imp_friction *", getter())
            if self.numbers.imp != self.table:
                raise LagcodegenError(f"the friction table of {info.prefix!r} does not match its code")
            row = info.J + len(self.contacts)
            for k in self.contacts:  # one tangential row (planar), two (3-D)
                tangent = system.tangents[k]
                if tangent is None:
                    continue
                count = len(tangent) if isinstance(tangent, tuple) else 1
                self.tangent_rows[k] = list(range(row, row + count))
                row += count
            if system.has_friction:
                self.friction = self.numbers

    def gaps(self, t: float, y, p) -> tuple[np.ndarray, np.ndarray]:
        """(g_k, w_k) of the contacts at (t, y)."""
        ffi = self.ffi
        nk = len(self.contacts)
        g, w = np.empty(nk), np.empty(nk)
        y = np.ascontiguousarray(y, dtype=float)
        p = np.ascontiguousarray(p, dtype=float)
        rc = self.table.gaps(float(t), ffi.from_buffer("double[]", y), ffi.from_buffer("double[]", p) if p.size
                             else ffi.NULL, ffi.from_buffer("double[]", g), ffi.from_buffer("double[]", w))
        if rc:
            raise LagcodegenError(f"the contact gaps are not finite at t = {t}")
        return g, w

    def run(self, t, y0, p, control: StepControl, form: Index1Form, recording: Recording,
            contacts: ContactOptions, cancel=None, active=None) -> Result:
        """A run on the impact driver with the step control ``control`` (a scalar atol), the
        Baumgarte parameters of ``form`` (no projection), ``recording.roots``: locate the compiled
        events (at most ``recording.max_events``), and the contact settings ``contacts``;
        ``cancel``: None, or a numpy int array of one value that stops the run (-80) once set
        nonzero (an ensemble's members, from another thread); ``active``: None, or the contacts'
        modes (a numpy intc array of one value per contact, nonzero: in persistent contact) at the
        start, overwritten with those at the end (as the driver returns them: with friction
        1 stick, 2 slip+, 3 slip-)."""
        sim, ffi = self.sim, self.ffi
        method, rtol, atol, roots = control.method, control.rtol, control.atol, recording.roots
        nk, nj = len(self.contacts), sim.info.J
        nr = nj + nk
        if not (type(atol) is float or isinstance(atol, (int, float))):
            raise LagcodegenError("runs with contacts take a scalar atol")
        nlam = int(self.table.nrow) if self.friction != ffi.NULL else nr
        buf = self._buffers(t, max(nlam, 1), contacts, recording)
        self._modes(buf, active)
        opt = ffi.new("lcg_cvc_options *")
        opt.method, opt.rtol, opt.atol, opt.atol_vec = METHODS[method], float(rtol), float(atol), ffi.NULL
        c = control
        opt.max_steps, opt.first_step, opt.max_step, opt.min_step = int(c.max_steps), c.first_step, c.max_step, \
            c.min_step
        opt.max_order, opt.alpha, opt.beta, opt.roots, opt.max_wall = int(c.max_order), form.alpha, form.beta, \
            int(roots), c.max_wall
        opt.poll, opt.poll_every = self.poll, POLL_EVERY
        if cancel is not None:
            opt.cancel = ffi.from_buffer("int[]", cancel)
        st = ffi.new("lcg_cvc_stats *")
        p = np.ascontiguousarray(p, dtype=float)
        start = time.perf_counter()
        flag = self.rt.lib.lcg_imp_solve(self.table, *self._arguments(buf, p, y0, opt, st), self.friction,
                                         ffi.from_buffer("double[]", self.mu))
        return self._result(buf.raw(flag, st, p, time.perf_counter() - start), contacts, method, "CVODE")

    def run_ggl(self, t, y0, p, control: StepControl, form: GGLForm, recording: Recording,
                contacts: ContactOptions, alg_atol: float, *, cancel=None, active=None) -> Result:
        """A run on the GGL impact driver (lagcodegen/runtime/lcg_imp_ida.c: IDA, the rows held as
        GGL rows with their multipliers, the impact law and Coulomb friction of the index-1
        driver) with the step control ``control`` (a scalar atol on q, v; ``control.order``
        unused), ``form`` (``suppress_alg``; ``stop_at_outputs`` is refused: outputs are
        interpolated), the recording of :meth:`run`, the contact settings ``contacts`` and
        ``alg_atol``, the absolute tolerance of the unknowns lambda, mu; ``cancel``, ``active``:
        as :meth:`run`."""
        ffi = self.ffi
        atol = control.atol
        if not isinstance(atol, (int, float)) or isinstance(atol, bool):
            raise LagcodegenError("runs with contacts take a scalar atol")
        if form.stop_at_outputs:
            raise LagcodegenError("runs with contacts on IDA interpolate their outputs: stop_at_outputs=True is "
                                  "not taken (the steps stop at the impacts, not at the output times)")
        buf = self._buffers(t, int(self.table.nrow), contacts, recording)
        self._modes(buf, active)
        opt = ffi.new("lcg_ida_options *")
        c = control
        opt.rtol, opt.atol, opt.atol_vec, opt.max_steps = float(c.rtol), float(atol), ffi.NULL, int(c.max_steps)
        opt.first_step, opt.max_step, opt.min_step, opt.max_order = c.first_step, c.max_step, c.min_step, \
            int(c.max_order)
        opt.suppress_alg, opt.jacobian, opt.calc_ic, opt.ic_alg_atol = int(form.suppress_alg), 0, 0, \
            float(alg_atol)
        opt.roots, opt.stop_at_outputs, opt.max_wall = int(recording.roots), 0, c.max_wall
        opt.poll, opt.poll_every = self.poll, POLL_EVERY
        if cancel is not None:
            opt.cancel = ffi.from_buffer("int[]", cancel)
        st = ffi.new("lcg_ida_stats *")
        extra = np.zeros(2)
        p = np.ascontiguousarray(p, dtype=float)
        start = time.perf_counter()
        mu = ffi.from_buffer("double[]", self.mu) if self.friction != ffi.NULL else ffi.NULL
        flag = self.rt.lib.lcg_imp_ida_solve(self.numbers, *self._arguments(buf, p, y0, opt, st),
                                             ffi.from_buffer("double[]", extra), mu,
                                             int(bool(self.sim.system.model.general)))
        res = self._result(buf.raw(flag, st, p, time.perf_counter() - start), contacts, "bdf", "IDA")
        res.stats["contact_retries"], res.stats["max_penetration"] = int(extra[0]), float(extra[1])
        res.stats["suppress_alg"] = bool(form.suppress_alg)
        return res

    def _modes(self, buf: "_Buffers", active) -> None:
        """The contacts' modes of a run: ``active`` (None: the driver's own start) in place of the
        buffer's, checked."""
        if active is None:
            return
        nk = len(self.contacts)
        if not (isinstance(active, np.ndarray) and active.dtype == np.intc and active.shape == (nk,)):
            raise LagcodegenError(f"active must be an intc array of {nk} values (one per contact)")
        buf.active = active

    def _buffers(self, t, nlam: int, contacts: ContactOptions, recording: Recording) -> "_Buffers":
        """The arrays a driver's call fills for the output times ``t`` (``nlam`` multipliers per
        time) and its events struct (``recording.roots``: the compiled events, at most
        ``recording.max_events``)."""
        sim, nt = self.sim, t.size
        events = NativeEvents(self.ffi, "lcg_events", sim.info.events, sim.ny, recording.max_events) \
            if recording.roots and sim.info.events else None
        return _Buffers(t, np.empty((nt, sim.ny)), np.empty((nt, sim.n_out_columns)), np.zeros((nt, nlam)),
                        np.empty((contacts.max_records, 6)), np.zeros(len(self.contacts), dtype=np.intc),
                        self.ffi.new("int *"), events,
                        np.array([contacts.contact_speed, contacts.min_flight, contacts.gap_tol]), contacts.max_records)

    def _arguments(self, buf: "_Buffers", p: np.ndarray, y0, opt, st) -> list:
        """The arguments the impact drivers (lcg_imp_solve, lcg_imp_ida_solve) share after their
        model table: parameters, initial state, output times and arrays, options, restitution,
        settings, modes, records, statistics, events."""
        ffi, fb = self.ffi, self.ffi.from_buffer
        y0 = np.ascontiguousarray(y0, dtype=float)
        buf.y0 = y0  # kept alive through the call
        return [fb("double[]", p) if p.size else ffi.NULL, fb("double[]", y0), buf.t.size, fb("double[]", buf.t),
                fb("double[]", buf.yout), fb("double[]", buf.out), fb("double[]", buf.lamout), opt,
                fb("double[]", self.restitution), fb("double[]", buf.settings), fb("int[]", buf.active),
                buf.max_records, fb("double[]", buf.rec), buf.n_rec, st,
                buf.events.struct if buf.events else ffi.NULL]

    def _result(self, raw: "_Raw", contacts: ContactOptions, method: str, solver: str, stats_of=None) -> Result:
        """The Result of a driver's call ``raw``: trajectory, outputs with the multipliers, events,
        statistics (``stats_of(st)``; None: a SUNDIALS driver's, :func:`native_stats`) and the
        contact log."""
        sim, ffi = self.sim, self.ffi
        flag, st, events, t, p = raw.flag, raw.st, raw.events, raw.t, raw.p
        nj, ny = sim.info.J, sim.ny
        if flag == CANCELLED:
            raise_pending()  # Ctrl-C during the run: KeyboardInterrupt
        done = st.nt_done
        recs = events.records(sim.state_names, ny) if events else []
        tt, yy, oo, ll = t[:done].copy(), raw.yout[:done].copy(), raw.out[:done].copy(), raw.lamout[:done].copy()
        if events and events.terminated and recs and (not tt.size or recs[-1].t > tt[-1]):
            ev = recs[-1]
            tt = np.append(tt, ev.t)
            yy = np.vstack([yy, ev.y[None, :]])
            try:
                o = sim.outputs(ev.t, ev.y, p)
            except LagcodegenError:
                o = np.full(oo.shape[1], np.nan)
            oo = np.vstack([oo, np.resize(o, (1, oo.shape[1]))])
            ll = np.vstack([ll, np.full((1, ll.shape[1]), np.nan)])
        stats = native_stats(ffi, st) if stats_of is None else stats_of(st)
        stats["wall_time"] = raw.wall
        if events:  # every event found (those beyond max_events not kept)
            stats["events"] = int(events.struct.n_events)
        text = "success" if flag >= 0 else message(flag, st.model_error, ffi.string(st.message).decode(
            errors="replace"), solver, SINGULAR_AUGMENTED)
        outputs = dict(zip(sim.info.output_names, oo.T))
        for j in range(nj):  # the equality multipliers with the contact forces (the constrained table's
            if f"lambda_{j}" in outputs:  # outputs solve without the contact rows)
                outputs[f"lambda_{j}"] = ll[:, j]
        for i, k in enumerate(self.contacts):
            outputs[f"lambda_ineq_{k}"] = ll[:, nj + i]
        for k, rows in self.tangent_rows.items():
            if not all(r < ll.shape[1] for r in rows):  # index-1 without friction: no tangential rows kept
                continue
            if len(rows) == 1:
                outputs[f"lambda_t_ineq_{k}"] = ll[:, rows[0]]
            else:  # 3-D: one per tangent
                for d, r in enumerate(rows):
                    outputs[f"lambda_t{d}_ineq_{k}"] = ll[:, r]
        count, active = raw.n_rec, raw.active
        log = ContactLog([ImpactRecord(float(r[0]), self.contacts[int(r[1])], KINDS[int(r[2])], float(r[3]),
                                       float(r[4]), float(r[5])) for r in raw.rec[: min(count, contacts.max_records)]],
                         {k: "contact" if active[i] else "free" for i, k in enumerate(self.contacts)},
                         count > contacts.max_records)
        stats["impacts"] = len(log.times)
        if self.friction != ffi.NULL:  # the driver returns the final modes as 1 stick, 2 slip+, 3 slip-, 4 slip (3-D)
            log.friction_modes = {k: ("free", "stick", "slip+", "slip-", "slip")[int(active[i])]
                                  for i, k in enumerate(self.contacts) if self.mu[i] >= 0}
            stats["stick_slip"] = len(log.transitions())
        if flag == int(Flag.CONTACT_MODE):
            text = ffi.string(st.message).decode(errors="replace")
        res = Result(t=tt, y=yy, state_names=sim.state_names, outputs=outputs, stats=stats, status=int(flag),
                     message=text, backend="native", method=method, events=recs)
        res.impacts = log
        if flag == int(Flag.CONTACT_MODE):  # Painleve, or more modes than the driver enumerates
            cls = PainleveError if "Painleve" in text else SolverError
            raise cls(text, t=float(st.t_reached), flag=int(flag), result=res)
        return res


@dataclass
class _Buffers:
    """What an impact driver's call fills: trajectory, outputs, multipliers, records, final modes,
    the records' count, the events struct; with the output times, the contact settings and the
    records kept at most."""

    t: np.ndarray
    yout: np.ndarray
    out: np.ndarray
    lamout: np.ndarray
    rec: np.ndarray
    active: np.ndarray
    n_rec: object
    events: object
    settings: np.ndarray
    max_records: int
    y0: object = None

    def raw(self, flag: int, st, p: np.ndarray, wall: float) -> "_Raw":
        """The call's outcome as :class:`_Raw`."""
        return _Raw(flag, st, self.events, self.t, self.yout, self.out, self.lamout, self.rec, int(self.n_rec[0]),
                    self.active, p, wall)


@dataclass(frozen=True)
class _Raw:
    """What a driver's call returned: its flag, statistics and events structs, the output times and
    the arrays it filled, the records' count, the final modes, the parameters and the wall time."""

    flag: int
    st: object
    events: object
    t: np.ndarray
    yout: np.ndarray
    out: np.ndarray
    lamout: np.ndarray
    rec: np.ndarray
    n_rec: int
    active: np.ndarray
    p: np.ndarray
    wall: float
