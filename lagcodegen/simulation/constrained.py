"""The face of a compiled constrained system (:class:`ConstrainedSimulation`): its runs and
ensembles (index-1 on CVODE, GGL on IDA), its drivers' reusable structs, its pickling.

:func:`~lagcodegen.api.compile_constrained` turns a :class:`~lagcodegen.theory.constraints.ConstrainedSystem` into
compiled code with one of three formulations of the equations with multipliers (eq. 4.5)

    M q'' = F + A^T lambda,   A q' + A0 = 0   (eqs. 4.2, 4.3; f(q, t) = 0, eq. 4.1, for holonomic rows)

* ``"index1"``: differentiate every constraint to the acceleration level, A q'' = gamma, and
  solve the augmented (n+J) x (n+J) system [M A^T; A 0][q''; -lambda] = [F; gamma - stab]
  numerically in C (Schur complement of M by Cholesky, else dense LU with partial pivoting) at
  every right-hand-side call; integrate y = (q, q') with CVODE (difference-quotient Jacobian).
  Drift of f(q) and A q' + A0 is controlled by Baumgarte stabilization (f'' + 2 alpha f' +
  beta^2 f = 0 for holonomic rows, s' + alpha s = 0 for nonholonomic rows s = A q' + A0; by
  default alpha = beta = the natural rate of each run's initial state) and/or by projection onto the
  constraint manifold after each step through CVODE's own projection interface
  (CVodeSetProjFn: Gauss-Newton q <- q - A^T (A A^T)^{-1} f, then q' onto A q' + A0 = 0;
  CVODE only allows it with BDF).
* ``"ggl"``: the stabilized index-2 DAE of Gear, Gupta and Leimkuhler for IDA, unknowns
  (q, v, lambda, mu) and residual [q' - v - A_h^T mu; M v' - F - A^T lambda; f(q, t); A v + A0]
  (nonholonomic rows: only the velocity row, no mu). lambda, mu are algebraic (IDASetId) and
  left out of the error test (IDASetSuppressAlg) on the native driver; the residual Jacobian
  dF/dy + cj dF/dy' is generated symbolically. Consistent initial values: q0, v0 are checked
  (or projected), lambda and y' are computed from the augmented system and polished by
  IDACalcIC(IDA_YA_YDP_INIT).
* ``"minimal"``: holonomic constraints solved symbolically (sympy) for some coordinates,
  substituted into the model to give an unconstrained model in the remaining coordinates.

All return a :class:`~lagcodegen.result.Result` with y = (q, q') (minimal: the remaining
coordinates; the eliminated ones are outputs), outputs ``lambda_<j>``, ``g_<j>`` (f_j(q, t),
holonomic j), ``gdot_<j>`` (A_j q' + A0_j), ``energy`` (T + V), and on request the
constraint forces ``R_<j>_<coordinate>`` = lambda_j A_j (sec. 4.3), and ``events``.

``lang="fortran"`` (index1, ggl) generates the model functions as Fortran 2008 modules bound
to the C names (:mod:`lagcodegen.codegen.fortran`); the native drivers stay C and call them through
the same function table, so results and solver statistics are the C version's.

The native drivers are model-independent and compiled once, into the runtime
(:func:`lagcodegen.build.runtime`): a model compiles only its own functions (model, ``<prefix>_dae.c``
and its table ``<prefix>_dae_table.c``, lcg_dae_model.h) into a library without Python.h, and
every function of it is called through that table, from the drivers and from Python alike.

The compiled functions and the consistent initial state are :mod:`.constrained_functions`'; the
runners are the solver families' (:mod:`lagcodegen.solvers`); minimal coordinates are
:mod:`.minimal`.
"""

from __future__ import annotations

import functools
import math
from typing import Mapping

import numpy as np

from ..errors import LagcodegenError, ModelError, SingularMassMatrixError, SolverError
from ..formulation.constrained import ConstrainedCodeInfo
from ..formulation.drawing import attaches_run_drawing
from ..result import Result
from ..solvers.base import ERR_SINGULAR, NativeEvents, PreparedOptions, file_initial, tolerances
from ..solvers.control import POLL_EVERY
from ..solvers.family import Problem, Request
from ..solvers.cvode.native import CVC_OPTIONS
from ..solvers.ida.native import ALGEBRAIC_ATOL, IDA_OPTIONS
from ..solvers.registry import resolve
from ..solvers.request import Index1Form, Recording, StepControl
from ..theory.constraints import ConstrainedSystem
from ..util import check_finite, output_times
from .constrained_functions import ConstrainedFunctions
from .constrained_impacts import ContactOptions, ContactRun, ImpactRunner
from .ensemble import ensemble_constrained
from .impact_ensemble import ensemble_contacts
from .impact_stepper import ImpactStepper
from .integrator import Integrator
from .ode import CompiledModel

#: Events structs (with their buffers, max_events x NY values) kept for reuse per simulation and
#: value of max_events, at most; and the values of max_events kept at most.
_EVENT_POOL, _EVENT_POOL_KEYS = 2, 8

#: Why contacts refuse the scikit-sundae backend: one implementation of the contact law.
NATIVE_CONTACTS = ("the impact law and the choice of contact modes are the native drivers' C (lagcodegen/runtime/"
                   "lcg_imp_law.c, lcg_imp_fric.c), driven inside their step loop; the scikit-sundae backend steps the "
                   "model from Python and has no impact driver")


def _contact_options(contacts) -> ContactOptions:
    """A run's contact settings: ``contacts`` checked (None: the defaults)."""
    if contacts is None:
        return ContactOptions()
    if not isinstance(contacts, ContactOptions):
        raise LagcodegenError(f"contacts must be a ContactOptions, got {type(contacts).__name__}")
    return contacts


class ConstrainedSimulation(ConstrainedFunctions):
    """A compiled constrained system (formulation ``index1`` or ``ggl``); call :meth:`simulate`.

    ``baumgarte`` and ``projection`` are the compiled defaults of index-1 runs (a run's
    ``solver=CVODE(baumgarte=..., projection=...)`` or keywords override them)."""

    def __init__(self, system: ConstrainedSystem, formulation: str, cm: CompiledModel, info: ConstrainedCodeInfo,
                 baumgarte: tuple[float, float] | str, projection: bool):
        super().__init__(system, cm, info, formulation == "ggl")
        self.formulation = formulation
        self.baumgarte = baumgarte
        self.projection = projection
        lib, table = self.lib, self.table
        # the runtime's model-independent drivers applied to this model and their C types
        self.c_cvc_solve = functools.partial(lib.lcg_cvc_solve, table)
        self.c_ida_solve = functools.partial(lib.lcg_ida_solve, table) if self.c_ggl_res is not None else None
        self.cvc_options_type, self.cvc_stats_type = "lcg_cvc_options", "lcg_cvc_stats *"
        self.ida_options_type, self.ida_stats_type = "lcg_ida_options", "lcg_ida_stats *"
        self.cvc_ensemble_type, self.ida_ensemble_type, self.events_type = ("lcg_cvc_ensemble", "lcg_ida_ensemble",
                                                                            "lcg_events")
        # the drivers' options structs, kept across calls (one per distinct set of option values)
        self.cvc_options = PreparedOptions(self.ffi, self.cvc_options_type, *CVC_OPTIONS, proj_err=1,
                                           poll=cm.poll, poll_every=POLL_EVERY)
        self.ida_options = PreparedOptions(self.ffi, self.ida_options_type, *IDA_OPTIONS, calc_ic=1,
                                           ic_alg_atol=ALGEBRAIC_ATOL, poll=cm.poll, poll_every=POLL_EVERY)
        self._has_events = len(info.events) > 0
        self.n_out_columns = max(len(info.output_names), 1)  # columns of the drivers' output rows
        self._event_pool: dict = {}  # max_events -> NativeEvents structs free for reuse
        self._pair_times = None  # (key, array) of the last t = (t0, t1)
        self.ggl_atol_cache = (None, None)  # (bytes of a scalar atol, GGL tolerances of every unknown), last call
        self.cvc_stats_pool: list = []  # the drivers' statistics structs free for reuse
        self.ida_stats_pool: list = []
        self._default_parameters = dict(zip(self.param_names, self._default_p))  # Result.parameters
        self._impact_runner = None  # the impact driver on this model (systems with contacts), made on first use
        self._taylor_impact_runner = None  # the Taylor contact driver on this model, made on first use

    # ------------------------------------------------------------------ simulate
    @attaches_run_drawing
    def simulate(self, t, q0=None, v0=None, *, params: Mapping | None = None, solver=None, rtol: float = 1e-8,
                 atol=1e-10, events: bool | None = None, initial: str = "check", ic_tol: float = 1e-8,
                 raise_on_error: bool = True, **options) -> Result:
        """Integrate from t[0] and return the trajectory at the times ``t``.

        ``q0``/``v0``: initial coordinates and velocities (arrays or dicts by name), checked or
        projected per ``initial`` (see :meth:`consistent_initial_state`). ``atol`` may be a
        scalar, one value per (q, q') or, for GGL, one per (q, q', lambda, mu). ``events``:
        root finding on the compiled events (None or True: on; False: off).

        ``solver``: :class:`~lagcodegen.solvers.cvode.CVODE` (index-1: ``method``,
        ``baumgarte``, ``projection``, ``backend``, budgets; the values used are in
        ``stats["alpha"]``, ``stats["beta"]``, ``stats["projection"]``) or
        :class:`~lagcodegen.solvers.ida.IDA` (GGL: ``suppress_alg``, ``jacobian``, ``alg_atol``,
        ``stop_at_outputs``, ``backend``, budgets). ``options``: the same fields as keywords
        (``method="bdf"``, ``baumgarte=(5, 5)``, ``projection=True``, ``max_steps=...``, ...),
        made into that object by :func:`lagcodegen.solvers.registry.resolve`; an option the
        formulation's family does not have raises LagcodegenError naming it.

        Systems with contacts (:class:`~lagcodegen.theory.constraints.Inequality` with a
        restitution) run on an impact driver (:mod:`.constrained_impacts`: impacts, persistent
        contact and release in one call, Coulomb friction included; index-1: CVODE, native backend,
        no projection; GGL: IDA, native backend); the keyword
        ``contacts`` (a :class:`~.constrained_impacts.ContactOptions`, taken from ``options``
        before the solver's options are resolved) sets how contacts switch, and ``res.impacts``
        lists what happened.

        Output times are served by the integrator's interpolation (GGL with
        ``stop_at_outputs``: exact steps): ``t = (t0, t1)`` (1001 output times) takes the steps
        that ``[t0, t1]`` takes, up to CVODE's estimate of the first step, which looks at the
        first output interval.

        ``sensitivities`` (index-1, CVODE): forward sensitivities of the states and outputs (the
        multipliers ``lambda_<j>`` included) with respect to run-time parameters and initial values
        (``"<q>(0)"``, ``"<q>_dot(0)"``), in ``res.sensitivity(value, direction)``; without events;
        Baumgarte stabilization and projection differentiated as the run applies them, the
        initial ones through the initial projection onto the constraints
        (:mod:`lagcodegen.solvers.cvode.sensitivity_constrained`).
        """
        if self._ggl and (options.get("sensitivities") is not None
                          or getattr(solver, "sensitivities", None) is not None):
            raise LagcodegenError("sensitivities are computed for the index-1 formulation (CVODE) and minimal "
                                  "coordinates, not for GGL on IDA: compile_constrained(system, 'index1')")
        contacts = options.pop("contacts", None)  # the run's contact settings, not a solver option
        family = resolve(self.formulation, solver, options)
        t = self._times(t)
        q0, v0 = file_initial(self, q0, v0)
        if q0 is None:
            raise LagcodegenError("q0 is required")
        roots = self._roots(events)
        sensitivities = getattr(family, "sensitivities", None) is not None
        p = self._default_p if params is None else self.parameter_vector(params)
        y0, yy0, yp0 = self._initial_values(float(t[0]), q0, v0, p, initial, ic_tol, self._ggl)
        if sensitivities and self.system.model.general:
            raise LagcodegenError(f"sensitivities of constrained systems with generalized speeds (model "
                                  f"{self.system.model.name!r}: nq = {self._n}, nv = {self.nv}) are not computed yet")
        request = Request(roots=roots, initial=initial,
                          contacts=_contact_options(contacts) if self.info.contacts else None)
        if self._ggl and not self.info.contacts:  # the GGL unknowns (the GGL impact driver starts from y0)
            if yy0 is None:
                yy0, yp0 = self._ggl_initial(t[0], y0, p)
            problem = Problem(self, rtol, atol, t, yy0, p, yp0)
        else:
            problem = Problem(self, rtol, atol, t, y0, p)
        res = family.run(self.formulation, problem, request)
        res.parameters = self._default_parameters.copy() if p is self._default_p else dict(zip(self.param_names, p))
        res.n_coordinates = self._n
        if self.system.model.general:
            res.n_speeds = self.nv
        res.formulation = self.formulation
        if raise_on_error and not res.success:
            cls = SingularMassMatrixError if res.stats.get("model_error") == ERR_SINGULAR else SolverError
            t_end = res.stats.get("t_reached", res.t[-1] if res.t.size else t[0])
            raise cls(res.message, t=t_end, flag=res.status, result=res)
        return res

    def integrator(self, *, q0=None, v0=None, t0: float = 0.0, params: Mapping | None = None, solver=None,
                   rtol: float = 1e-8, atol=1e-10, events: bool | None = None, initial: str = "check",
                   ic_tol: float = 1e-8, **options) -> Integrator:
        """An integration that lives between calls (:class:`~lagcodegen.simulation.integrator.Integrator`:
        ``propagate_until``, ``propagate_for``, ``propagate_grid``, ``step``; ``state`` = (q, q')
        and ``params`` writable in place): the index-1 form on CVODE or the GGL form on IDA.

        The initial state is checked or projected as in :meth:`simulate`; ``events`` (None or
        True: the compiled events) are located on the way and a terminal one stops a call; the
        options are simulate's (``max_steps`` per call). A written state: index-1 integrates
        from it (the stabilization, or ``projection``, pulls it back onto the constraints); GGL
        projects it onto the constraints and computes consistent multipliers before the next
        step (``Integrator.multipliers``: the GGL unknowns lambda, mu).
        """
        contacts = options.pop("contacts", None)  # systems with contacts: the run's contact settings
        family = resolve(self.formulation, solver, options, runs="stepper")
        if q0 is None:
            raise LagcodegenError("q0 is required")
        t0 = check_finite(t0, "t0")
        roots = self._roots(events)
        p = self._default_p if params is None else self.parameter_vector(params)
        y0, yy0, yp0 = self._initial_values(t0, q0, v0, p, initial, ic_tol, self._ggl)
        mem = np.concatenate([[t0], y0, p])  # (t, y, p): the memory the C stepper works on
        if self.info.contacts:  # each propagate call one run of the impact driver (.impact_stepper)
            stepper = family.run(self.formulation, Problem(self, rtol, atol, y=mem),
                                 Request(kind="stepper", roots=roots, contacts=_contact_options(contacts)))
        elif self._ggl:
            if yy0 is None:
                yy0, yp0 = self._ggl_initial(t0, y0, p)
            stepper = family.run("ggl", Problem(self, rtol, atol, y=mem, yp=(yy0, yp0)),
                                 Request(kind="stepper", roots=roots))
        else:
            rtol, atol_arr = tolerances(rtol, atol, self._ny, scalar=True)
            stepper = family.run("index1", Problem(self, rtol, atol_arr, y=mem), Request(kind="stepper", roots=roots))
        return Integrator(stepper, mem, state_names=self.state_names, param_names=self.param_names,
                          family=stepper.family)

    def contact_stepper(self, family, mem, rtol, atol, roots: bool, contacts) -> ImpactStepper:
        """The stepper of an integrator object of this system with contacts on the memory ``mem``
        = (t0, y0, p) (:mod:`.impact_stepper`: each call one run of the impact driver, index-1 on
        CVODE or GGL on IDA)."""
        ny = self._ny
        t0, y0, p = float(mem[0]), mem[1:1 + ny], mem[1 + ny:]
        return ImpactStepper(self, self.contact_run(family, t0, y0, p, rtol, atol, roots, contacts), mem)

    def run_contacts(self, family, t, y0, p, rtol, atol, roots: bool, contacts, cancel=None) -> Result:
        """A run of a system with contacts on its impact driver (:mod:`.constrained_impacts`: the
        index-1 driver on CVODE, the GGL driver on IDA); ``cancel``: None, or a numpy int array of
        one value that stops the run (-80) once set."""
        run = self.contact_run(family, float(t[0]), y0, p, rtol, atol, roots, contacts)
        return run.execute(t, y0, p, cancel=cancel)

    def run_contacts_taylor(self, family, t, y0, p, rtol, atol, *, roots: bool, contacts, cancel=None) -> Result:
        """A run of this system with contacts on the Taylor contact driver (:mod:`.taylor_impacts`:
        impacts and releases located on the Taylor polynomials of the gaps and multipliers, the
        impact law of the index-1 driver) with the Taylor family ``family`` (its ``order``, budgets,
        ``baumgarte`` and ``max_events``), ``roots``: locate the compiled events; ``cancel``: None,
        or a numpy int array of one value that stops the run (-80) once set. The GGL formulation
        takes its contacts on IDA only."""
        run = self.taylor_contact_run(family, float(t[0]), y0, p, rtol, atol, roots=roots, contacts=contacts)
        return run.execute(t, y0, p, cancel=cancel)

    def taylor_contact_run(self, family, t0: float, y0, p, rtol, atol, *, roots: bool, contacts) -> ContactRun:
        """What the Taylor contact driver (:mod:`.taylor_impacts`) takes for runs of this system
        from (t0, y0) with the parameters p on the Taylor family ``family`` (``roots``: locate the
        compiled events), as a :class:`~.constrained_impacts.ContactRun` (the contacts checked at y0)."""
        if self._ggl:
            raise LagcodegenError("the Taylor method runs contacts in the index-1 formulation: "
                                  "compile_constrained(system, 'index1')")
        rtol, atol = tolerances(rtol, atol, self._ny, scalar=True)
        if not isinstance(atol, float):
            raise LagcodegenError("runs with contacts take a scalar atol")
        impacts = self._contact_runner(t0, y0, p)
        runner = self._taylor_impact_runner
        if runner is None:
            from .taylor_impacts import TaylorImpactRunner
            runner = self._taylor_impact_runner = TaylorImpactRunner(self, impacts)
        alpha, beta = self.stabilization(family.baumgarte, False, t0, y0, p, True)
        return ContactRun(runner, family.control(rtol, atol), Index1Form(float(alpha), float(beta)),
                          Recording(roots=bool(roots), max_events=family.max_events), _contact_options(contacts))

    def contact_stepper_taylor(self, family, mem, rtol, atol, *, roots: bool, contacts) -> ImpactStepper:
        """The stepper of an integrator object of this system with contacts on the Taylor method
        (:mod:`.impact_stepper`: each call one run of the Taylor contact driver) on ``mem`` =
        (t0, y0, p)."""
        ny = self._ny
        t0, y0, p = float(mem[0]), mem[1:1 + ny], mem[1 + ny:]
        run = self.taylor_contact_run(family, t0, y0, p, rtol, atol, roots=roots, contacts=contacts)
        return ImpactStepper(self, run, mem)

    def contact_run(self, family, t0: float, y0, p, rtol, atol, roots: bool, contacts) -> ContactRun:
        """What the impact driver takes for runs of this system with contacts from (t0, y0) with
        the parameters p on ``family`` (checked: index-1: CVODE, native backend, no projection;
        GGL: IDA, native backend; the contacts not violated at y0), as a
        :class:`~.constrained_impacts.ContactRun` (the runs of simulate, ensembles and the
        integrator object)."""
        contacts = _contact_options(contacts)
        backend = getattr(family, "backend", None)
        if self._ggl:  # the GGL impact driver (IDA)
            if backend != "native":
                raise LagcodegenError("systems with contacts run on the native IDA driver (backend='native'), not "
                                      f"backend={backend!r}: {NATIVE_CONTACTS}")
            runner = self._contact_runner(t0, y0, p)
            alg_atol = ALGEBRAIC_ATOL if family.alg_atol is None else float(family.alg_atol)
            return ContactRun(runner, StepControl.of(family, rtol, atol), family.ggl_form(),
                              family.recording(10_000, roots=roots), contacts, alg_atol)
        if self.system.has_friction and (type(family).__name__ != "CVODE" or backend != "native"):
            raise LagcodegenError(f"Coulomb friction on contacts (Inequality(..., friction=mu)) runs on the native "
                                  f"impact drivers only (index-1: CVODE, GGL: IDA; and method='taylor'); the solver "
                                  f"{type(family).__name__} (backend {backend!r}) cannot take it: "
                                  "solver=CVODE(backend='native')")
        if backend != "native":
            raise LagcodegenError(f"systems with contacts run on the native CVODE driver (backend='native'): "
                                  f"{NATIVE_CONTACTS}")
        method, projection, alpha, beta = family.index1_settings(self, t0, y0, p)
        if projection:
            raise LagcodegenError("systems with contacts run without projection (projection=False; Baumgarte "
                                  "stabilization holds the constraints and the persistent contacts)")
        runner = self._contact_runner(t0, y0, p)
        return ContactRun(runner, StepControl.of(family, rtol, atol, method=method), Index1Form(alpha, beta),
                          family.recording(10_000, roots=roots), contacts)

    def _contact_runner(self, t0: float, y0, p) -> ImpactRunner:
        """The impact driver on this model (made on first use), the initial state checked against
        the contacts (g >= 0)."""
        runner = self._impact_runner
        if runner is None:
            runner = self._impact_runner = ImpactRunner(self)
        g, _ = runner.gaps(t0, y0, p)
        bad = [f"g_{k} = {v:.3g}" for k, v in zip(runner.contacts, g) if not v >= -1e-9]
        if bad:
            raise ModelError(f"inconsistent initial conditions: the contact(s) {', '.join(bad)} are violated "
                             "(inequality constraints g >= 0)")
        return runner

    def _roots(self, events) -> bool:
        """Whether a run locates the compiled events (``events`` of simulate or ensemble)."""
        if events is None or events is True:
            return self._has_events
        if events is False:
            return False
        raise LagcodegenError(f"events={events!r:.60}: the events of a constrained system are compiled in "
                              "(compile_constrained(events=...)); events= of a run is True or False (root "
                              "finding on or off)")

    def _times(self, t) -> np.ndarray:
        """:func:`~lagcodegen.util.output_times`, with the 1001 times of the last pair (t0, t1) of
        Python numbers kept (read-only) for the next call with the same pair."""
        if (type(t) is tuple or type(t) is list) and len(t) == 2:
            a, b = t
            if (type(a) is float or type(a) is int) and (type(b) is float or type(b) is int):
                key = (a, b, a == 0 and math.copysign(1.0, a) < 0, b == 0 and math.copysign(1.0, b) < 0)
                last = self._pair_times
                if last is not None and last[0] == key:
                    return last[1]
                times = output_times(t)
                times.flags.writeable = False
                self._pair_times = (key, times)
                return times
        return output_times(t)

    def ensemble(self, t, q0=None, v0=None, *, params=None, threads=None, save="final", executor=None,
                 progress=None, chunk_size=None, initial: str = "check", ic_tol: float = 1e-8, **options):
        """N runs in one call into the generated C (index-1: CVODE, GGL: IDA) over a thread pool,
        bit-identical to :meth:`simulate` member by member; see
        :meth:`lagcodegen.simulation.ode.CompiledModel.ensemble` for the arguments, and
        :meth:`simulate` for ``options`` (``max_wall``: per member). Members whose initial state is
        rejected get status -84. Systems with contacts: each member one run of the impact driver
        (:mod:`.impact_ensemble`), its events and contact log in ``member(i).events`` and
        ``.impacts``."""
        members = ensemble_constrained  # each member's run in the native pool (index-1: CVODE, GGL: IDA)
        if self.info.contacts:  # each member one run of the impact driver (index-1: CVODE, GGL: IDA)
            members = ensemble_contacts
        recording = Recording(save=save, threads=threads, progress=progress)
        return members(self, t, q0, v0, params=params, recording=recording, executor=executor, chunk_size=chunk_size,
                       initial=initial, ic_tol=ic_tol, options=options)

    def __reduce__(self):
        """Pickled by the system and the generated code (the compiled module is rebuilt from the
        receiving process's cache)."""
        return ConstrainedSimulation, (self.system, self.formulation, self.compiled, self.info, self.baumgarte,
                                       self.projection)

    # ------------------------------------------------------------------ what the native runners take
    def native_events(self, max_events: int) -> NativeEvents:
        """An events struct for a native run (from the pool of this simulation when one is free;
        the drivers reset its counters); hand it back with :meth:`release_events`."""
        pool = self._event_pool.get(max_events)
        if pool:
            try:
                return pool.pop()
            except IndexError:  # taken by another thread meanwhile
                pass
        ny = self.info.ng if self.formulation == "ggl" else self._ny
        return NativeEvents(self.ffi, self.events_type, self.info.events, ny, max_events)

    def release_events(self, events: NativeEvents) -> None:
        """Return an events struct of :meth:`native_events` (its records already made)."""
        pools = self._event_pool
        if events.max_events not in pools and len(pools) >= _EVENT_POOL_KEYS:
            pools.clear()
        pool = pools.setdefault(events.max_events, [])
        if len(pool) < _EVENT_POOL:
            pool.append(events)

    def cvc_solve_many(self, e, opt) -> int:
        """The runtime's index-1 ensemble driver (``lcg_cvc_solve_many``) on this model: ``e`` a
        ``lcg_cvc_ensemble *`` (its model field is set here)."""
        e.model = self.table
        return self.lib.lcg_cvc_solve_many(e, opt)

    def ida_solve_many(self, e, opt) -> int:
        """The runtime's GGL ensemble driver (``lcg_ida_solve_many``) on this model: ``e`` a
        ``lcg_ida_ensemble *`` (its model field is set here)."""
        if self.c_ggl_res is None:
            raise LagcodegenError("the GGL residual is compiled with formulation='ggl' only")
        e.model = self.table
        return self.lib.lcg_ida_solve_many(e, opt)

