"""The CVODE family's options object (:class:`CVODE`): its values checked once, resolved into
what the native drivers (:mod:`.native`, :mod:`.ensemble`) or scikit-sundae
(:mod:`lagcodegen.solvers.sksundae`) take, for the ODE of a compiled scene and the index-1 form
of a constrained system."""

from __future__ import annotations

import math
import weakref
from dataclasses import dataclass

from ...errors import LagcodegenError
from ...result import Result
from ...util import check_baumgarte
from ..base import LINEAR_SOLVERS, METHODS, check_initial_mass_matrix, tolerances
from ..family import Family, choice, combinations, ode_ensemble, ode_run, ode_stepper, take_sensitivities
from . import ensemble, native
from .prepared import PreparedCVODERun
from .stepper import CVCStepper, CVODEStepper
from .events import compiled_events
from ..request import Index1Form, Recording, StepControl, remembered

BACKENDS = ("native", "sksundae")
#: The fields a prepared ODE run honours (the index-1 ones are refused on the ODE by check_face;
#: max_events: a prepared run has no events; sensitivities: their own prepared run).
_PREPARED = frozenset(("max_steps", "max_step", "max_wall", "method", "backend", "max_order", "first_step",
                       "min_step", "linear_solver", "bandwidths", "jacobian", "max_events", "sensitivities",
                       "sensitivity_errcon", "sensitivity_corrector", "baumgarte", "projection", "proj_tol",
                       "proj_maxit"))


@dataclass(frozen=True, kw_only=True)
class CVODE(Family):
    """CVODE (variable-order multistep methods).

    ``method`` "adams" (nonstiff) or "bdf" (stiff); None: Adams, but BDF for an index-1 run with
    projection. ``backend`` "native" (the runtime's C driver, no Python in the solver loop) or
    "sksundae" (scikit-sundae calling the same compiled functions). ``max_order`` (0: CVODE's),
    ``first_step``, ``min_step`` (0: CVODE's). The ODE of a scene: ``linear_solver`` "dense",
    "band" (native: the bandwidths of the scene's Jacobian pattern in the interleaved order, or
    ``bandwidths`` = (upper, lower)) or "fixedpoint" (native: no linear solver, no Jacobian);
    ``jacobian`` the generated one (None: when compiled) or difference quotients (False).
    Index-1 constrained systems (eq. 4.5): ``baumgarte`` ("auto" or (alpha, beta); None: the
    compiled default), ``projection`` onto the constraints after each step (None: the compiled
    default; BDF only), ``proj_tol``, ``proj_maxit``, ``max_events`` (events kept; None: 10000 in
    a run, 64 per ensemble member). Forward sensitivities of the ODE of a scene and of index-1
    constrained systems (native; index-1: :mod:`.sensitivity_constrained`):
    ``sensitivities`` names of run-time parameters and initial values (``"<q>(0)"``,
    ``"<q>_dot(0)"``; :mod:`.sensitivity`), ``sensitivity_errcon`` the sensitivities in the error
    test (default True, CVODES's errconS), ``sensitivity_corrector`` "staggered" (CVODES's
    CV_STAGGERED: the Newton iteration converges on the states alone, then the sensitivities are
    corrected with the same matrix; the default, cheaper) or "simultaneous" (every direction in
    every Newton iteration); in runs with events (:mod:`.sensitivity_events`),
    ensembles (:mod:`.sensitivity_ensemble`) and the integrator object (:mod:`.sensitivity_stepper`).
    """

    name = "CVODE"
    methods = ("adams", "bdf")
    faces = ("ode", "index1")
    only = {"linear_solver": ("ode",), "bandwidths": ("ode",), "jacobian": ("ode",), "baumgarte": ("index1",),
            "projection": ("index1",), "proj_tol": ("index1",), "proj_maxit": ("index1",),
            "max_events": ("index1", "ode"), "sensitivities": ("ode", "index1"),
            "sensitivity_errcon": ("ode", "index1"), "sensitivity_corrector": ("ode", "index1")}

    method: str | None = None
    backend: str = "native"
    max_order: int = 0
    first_step: float = 0.0
    min_step: float = 0.0
    linear_solver: str = "dense"
    bandwidths: tuple[int, int] | None = None
    jacobian: bool | None = None
    baumgarte: tuple[float, float] | str | None = None
    projection: bool | None = None
    proj_tol: float = 1e-12
    proj_maxit: int = 10
    max_events: int | None = None
    sensitivities: tuple[str, ...] | None = None
    sensitivity_errcon: bool = True
    sensitivity_corrector: str = "staggered"

    def __post_init__(self):
        super().__post_init__()
        take_sensitivities(self)
        if self.method is not None:
            choice("method", self.method, tuple(METHODS))
        choice("backend", self.backend, BACKENDS)
        choice("sensitivity_corrector", self.sensitivity_corrector, ("staggered", "simultaneous"))
        choice("linear_solver", self.linear_solver, LINEAR_SOLVERS)
        if self.linear_solver != "dense" and self.backend != "native":
            raise LagcodegenError(f"linear_solver={self.linear_solver!r} needs backend='native'")
        if self.baumgarte is not None:
            object.__setattr__(self, "baumgarte", check_baumgarte(self.baumgarte))
        if self.projection and self.method == "adams":
            raise LagcodegenError("projection onto the constraints (CVodeSetProjFn) needs method='bdf': "
                                  "CVODE supports projection with BDF only")
        if self.projection and self.backend != "native":
            raise LagcodegenError("the sksundae backend has no projection (scikit-sundae does not expose "
                                  "CVodeSetProjFn): use backend='native'")
        if self.max_wall and self.backend != "native":
            raise LagcodegenError("max_wall needs backend='native'")

    # ------------------------------------------------------------------ the ODE of a scene
    def ode_control(self, cm, rtol, atol, y, p, native_backend: bool) -> StepControl:
        """The step control of a run of the ODE of ``cm`` with these tolerances (the Jacobian and
        linear solver resolved; ``y``, ``p``: where a band solver's widths are probed)."""
        jacobian = False if self.linear_solver == "fixedpoint" else self.jacobian  # functional iteration
        has_jac = cm.code.jacobian or (bool(getattr(cm.code, "sparse_jacobian", False)) and native_backend)
        if jacobian is None:
            jacobian = has_jac
        if jacobian and not has_jac:
            raise LagcodegenError("jacobian=True but the scene emits no Jacobian (Scene(jacobian=False))")
        band = native.band_widths(cm, self.bandwidths, y, p) if self.linear_solver == "band" else None
        return StepControl.of(self, rtol, atol, method=self.method or "adams", jacobian=bool(jacobian), band=band,
                              fixedpoint=self.linear_solver == "fixedpoint")

    def recording(self, default_max_events: int, **values) -> Recording:
        """What a run records: ``values`` (events, sensitivities, ...) and at most ``max_events``
        events (None: ``default_max_events``)."""
        return Recording(max_events=default_max_events if self.max_events is None else self.max_events, **values)

    def run_ode(self, cm, t, y, p, rtol: float, atol, events=()) -> Result:
        """A run of the ODE of ``cm`` (inputs checked by the face; ``atol`` a float or ny values);
        ``events`` located by CVODE's root finding on their compiled functions
        (:func:`.events.compiled_events`)."""
        compiled = compiled_events(cm, events)
        if compiled is not None:  # a value that is not finite at the start: named here
            compiled.values(float(t[0]), y, p)
        if self.sensitivities is not None:  # events: their times' sensitivities too (.sensitivity_events)
            from .sensitivity import run
            return run(self, cm, t, y, p, rtol, atol, self.sensitivities, events=compiled)
        if self.backend != "native":  # the native driver reports this itself, from its first RHS call
            check_initial_mass_matrix(cm, t[0], y, p)
        native_backend = self.backend == "native"
        # the records made once while the values stay the same (the model by a weak reference, the
        # compiled events: one object per set, kept with the model); a band solver's widths may be
        # probed at y, p: made every time
        key = (weakref.ref(cm), rtol, atol, compiled, native_backend) \
            if self.linear_solver != "band" and type(atol) is float else None
        control, recording = remembered(self, key, lambda: (
            self.ode_control(cm, rtol, atol, y, p, native_backend), self.recording(10_000, events=compiled)))
        if native_backend:
            if not cm.native:
                raise LagcodegenError("this module was built without the native driver (build(native=False))")
            if compiled is not None and compiled.table is None:
                raise LagcodegenError("events on the native CVODE driver need a model built for the runtime "
                                      "(build(code, native=True) of plain C code)")
            return native.solve_native(cm, t, y, p, control, recording)
        from ..sksundae import solve_sksundae
        res = solve_sksundae(cm, t, y, p, control, events=compiled)
        # its outputs are evaluated after the run, where nothing fails: check the first row
        if res.t.size and not all(math.isfinite(v[0]) for v in res.outputs.values()):
            cm.check_initial_outputs(t[0], y, p)
        return res

    def prepared_ode(self, cm, rtol: float, atol, fixed: dict):
        """The runs of :meth:`run_ode` (no events) with these tolerances prepared once
        (:class:`.prepared.PreparedCVODERun`; with sensitivities
        :class:`.prepared_sensitivity.PreparedSensitivityRun`): what ``simulate()``'s fast path
        calls; ``fixed`` the members every result shares. None where a run needs more than the
        native driver's call (scikit-sundae, bandwidths probed at the initial state, a field it does
        not know set: a field added later takes the full path until the prepared run honours it)."""
        if self.sensitivities is not None:
            return self._prepared_sensitivities(cm, rtol, atol, fixed)
        if self.backend != "native" or not cm.native or cm.native_solve is None \
                or not self.defaults_beside(_PREPARED):
            return None
        if self.linear_solver == "band" and self.bandwidths is None and getattr(cm.code, "jac_pattern", None) is None:
            return None
        return PreparedCVODERun(cm, self.ode_control(cm, rtol, atol, None, None, True), fixed)

    def _prepared_sensitivities(self, cm, rtol: float, atol, fixed: dict):
        """The runs of :meth:`run_ode` with sensitivities (no events) prepared once
        (:class:`.prepared_sensitivity.PreparedSensitivityRun`), where the run is the sensitivity
        driver's call alone (the fields :func:`.sensitivity.check_family` accepts, the dense
        Newton solver's options); else None."""
        if self.backend != "native" or self.linear_solver != "dense" or not self.defaults_beside(_PREPARED):
            return None
        from .prepared_sensitivity import PreparedSensitivityRun
        control = self.ode_control(cm, rtol, atol, None, None, True)
        if control.method not in ("adams", "bdf"):
            return None
        return PreparedSensitivityRun(cm, self.sensitivities, control, fixed)

    def stepper_ode(self, cm, mem, rtol: float, atol, events=()) -> CVODEStepper:
        """The C state of an integrator object on the ODE of ``cm`` (``mem`` = (t, y, p), checked by
        the face): CVODE memory made once (:mod:`.stepper`); ``max_steps`` is the budget of one call;
        ``events`` located by CVODE's root finding on their compiled functions, as in :meth:`run_ode`."""
        if self.backend != "native":
            raise LagcodegenError("the integrator object runs on the native driver (backend='native')")
        y, p = mem[1:1 + cm.ny], mem[1 + cm.ny:]
        compiled = compiled_events(cm, events)
        if compiled is not None:
            if compiled.table is None:
                raise LagcodegenError("events on the CVODE integrator object need a model built for the runtime "
                                      "(build(code, native=True) of plain C code)")
            compiled.values(float(mem[0]), y, p)  # a value that is not finite at the start: named here
        control = self.ode_control(cm, rtol, atol, y, p, True)
        recording = self.recording(10_000, events=compiled, sensitivities=self.sensitivities)
        if self.sensitivities is not None:  # the sensitivity driver's stepper (.sensitivity_stepper)
            from .sensitivity import check_family
            from .sensitivity_stepper import CVSensStepper
            check_family(self)
            return CVSensStepper(cm, mem, control, recording)
        return CVODEStepper(cm, mem, control, recording)

    def run_ode_inputs(self, cm, t, y, p, rtol: float, atol, inputs) -> Result:
        """A run of the ODE of ``cm`` driven by the input tables ``inputs``
        (:class:`~lagcodegen.solvers.inputs.InputSet`), interpolated in C by the native driver."""
        if self.backend != "native":
            raise LagcodegenError("input tables need backend='native' (the tables are interpolated in the native "
                                  "CVODE driver)")
        if not cm.native or cm.table is None:
            raise LagcodegenError("input tables need the native driver (build(native=True), the default)")
        if self.sensitivities is not None:  # the sensitivity driver with the tables (.sensitivity)
            from .sensitivity import run
            return run(self, cm, t, y, p, rtol, atol, self.sensitivities, inputs=inputs)
        control = self.ode_control(cm, rtol, atol, y, inputs.apply(p, t[0]), True)
        return native.solve_native(cm, t, y, p, control, inputs=inputs)

    def ensemble_ode(self, cm, t, Y, P, rtol, atol, *, threads, save, progress, events=()):
        """Members (rows of Y, P) of the ODE of ``cm`` in one call of the native driver; ``events``
        located in each member (:func:`.events.compiled_events`)."""
        self._native_only()
        if not cm.native or cm.native_solve_many is None:
            raise LagcodegenError("this module was built without the native driver (build(native=False))")
        compiled = compiled_events(cm, events)
        if self.sensitivities is not None:
            from .sensitivity import check_family
            check_family(self)
        control = self.ode_control(cm, rtol, atol, Y[0], P if P.ndim == 1 else P[0], True)
        recording = self.recording(64, events=compiled, sensitivities=self.sensitivities, save=save,
                                   threads=threads, progress=progress)
        if self.sensitivities is not None:  # each member a run of the sensitivity driver (.sensitivity_ensemble)
            from .sensitivity_ensemble import ensemble_sensitivities
            return ensemble_sensitivities(cm, t, Y, P, control, recording)
        return ensemble.ensemble_ode(cm, t, Y, P, control, recording)

    def ensemble_ode_inputs(self, cm, t, Y, P, rtol, atol, inputs, *, threads, save, progress):
        """Members (rows of Y, P) of the ODE of ``cm``, member i driven by the input tables
        ``inputs[i]``, in one call of the native driver; with sensitivities, each member the
        sensitivity driver's run with its tables (:mod:`.sensitivity_ensemble`)."""
        self._native_only()
        if not cm.native or cm.native_solve_many is None:
            raise LagcodegenError("this module was built without the native driver (build(native=False))")
        if self.sensitivities is not None:
            from .sensitivity import check_family
            check_family(self)
        control = self.ode_control(cm, rtol, atol, Y[0], inputs[0].apply(P if P.ndim == 1 else P[0], t[0]), True)
        recording = Recording(sensitivities=self.sensitivities, save=save, threads=threads, progress=progress)
        if self.sensitivities is not None:
            from .sensitivity_ensemble import ensemble_sensitivities_inputs
            return ensemble_sensitivities_inputs(self, cm, t, Y, P, control, inputs, recording)
        return ensemble.ensemble_ode(cm, t, Y, P, control, recording, inputs=inputs)

    # ------------------------------------------------------------------ index-1 constrained systems
    def index1_settings(self, sim, t0: float, y0, p, native_backend: bool = True):
        """(method, projection, alpha, beta) of an index-1 run of ``sim`` (its compiled defaults
        where this object says None; ``y0`` None: "auto" Baumgarte left to the native driver)."""
        projection = sim.projection if self.projection is None else bool(self.projection)
        alpha, beta = sim.stabilization(self.baumgarte, projection, t0, y0, p, native_backend)
        method = self.method or ("bdf" if projection else "adams")
        if projection and method != "bdf":
            raise LagcodegenError("projection onto the constraints (CVodeSetProjFn) needs method='bdf': "
                                  "CVODE supports projection with BDF only")
        if projection and not native_backend:
            raise LagcodegenError("the sksundae backend has no projection (scikit-sundae does not expose "
                                  "CVodeSetProjFn): use backend='native'")
        return method, projection, float(alpha), float(beta)

    def run_index1(self, sim, t, y0, p, rtol, atol, roots: bool) -> Result:
        """An index-1 run of ``sim`` from the consistent state ``y0`` (eq. 4.5, Baumgarte and/or
        projection); ``roots``: locate the compiled events."""
        native_backend = self.backend == "native"
        method, projection, alpha, beta = self.index1_settings(sim, float(t[0]), y0, p, native_backend)
        if type(rtol) is float and type(atol) is float and 0 < rtol < math.inf and 0 <= atol < math.inf \
                and native_backend:
            atol_arr = atol  # what tolerances() returns for these
        else:
            rtol, atol_arr = tolerances(rtol, atol, sim.ny, scalar=native_backend)
        # the records made once while the values stay the same (repeated runs of a fit or a sweep)
        key = (rtol, atol_arr, method, projection, alpha, beta, bool(roots)) if type(atol_arr) is float else None
        control, form, recording = remembered(self, key, lambda: (
            StepControl.of(self, rtol, atol_arr, method=method), self.index1_form(projection, alpha, beta),
            self.recording(10_000, roots=bool(roots))))
        if native_backend:
            res = native.solve_index1(sim, t, y0, p, control, form, recording)
        else:
            from .. import sksundae
            res = sksundae.solve_index1(sim, t, y0, p, control, form, roots)
            res.stats.update(alpha=alpha, beta=beta)
        res.stats["projection"] = projection
        return res

    def stepper_index1(self, sim, mem, rtol: float, atol, roots: bool) -> CVCStepper:
        """The C state of an integrator object on the index-1 form of ``sim`` (``mem`` = (t, y, p),
        y a consistent state; checked by the face): CVODE memory made once with this object's
        stabilization, projection and root finding (:mod:`.stepper`); ``max_steps`` is the budget of
        one call."""
        if self.backend != "native":
            raise LagcodegenError("the integrator object runs on the native driver (backend='native')")
        if self.sensitivities is not None:
            raise LagcodegenError("the integrator object does not compute sensitivities: use simulate(..., "
                                  "sensitivities=[...])")
        ny = sim.ny
        method, projection, alpha, beta = self.index1_settings(sim, float(mem[0]), mem[1:1 + ny], mem[1 + ny:])
        return CVCStepper(sim, mem, StepControl.of(self, rtol, atol, method=method),
                          self.index1_form(projection, alpha, beta), self.recording(10_000, roots=roots))

    def ensemble_index1(self, sim, t, Y, P, rtol, atol, roots: bool, *, threads, save, progress):
        """Members (consistent initial states, rows of Y) of an index-1 system in one native call."""
        self._native_only()
        if self.sensitivities is not None:
            raise LagcodegenError("ensembles do not compute sensitivities: run simulate(..., sensitivities=[...]) "
                                  "per member")
        method, projection, alpha, beta = self.index1_settings(sim, float(t[0]), None, None)
        recording = self.recording(64, roots=roots, save=save, threads=threads, progress=progress)
        return ensemble.ensemble_index1(sim, t, Y, P, StepControl.of(self, rtol, atol, method=method),
                                        self.index1_form(projection, alpha, beta), recording)

    def index1_form(self, projection: bool, alpha: float, beta: float) -> Index1Form:
        """The index-1 form of a run: these resolved settings with this object's projection
        tolerance and iteration limit."""
        return Index1Form(alpha=alpha, beta=beta, projection=projection, proj_tol=self.proj_tol,
                          proj_maxit=self.proj_maxit)

    # ------------------------------------------------------------------ the one entry (Family.run)
    def _ode_prepared(self, pr, rq):
        return self.prepared_ode(pr.sim, pr.rtol, pr.atol, rq.fixed)

    def _index1_run(self, pr, rq) -> Result:
        if rq.contacts is not None:  # the simulation's index-1 impact driver (.constrained_impacts)
            return pr.sim.run_contacts(self, pr.t, pr.y, pr.p, pr.rtol, pr.atol, rq.roots, rq.contacts,
                                       cancel=rq.cancel)
        if self.sensitivities is not None:  # the constrained sensitivity driver (.sensitivity_constrained)
            from .sensitivity_constrained import run_index1
            return run_index1(self, pr.sim, pr.t, pr.y, pr.p, pr.rtol, pr.atol, roots=rq.roots, initial=rq.initial)
        return self.run_index1(pr.sim, pr.t, pr.y, pr.p, pr.rtol, pr.atol, rq.roots)

    def _index1_stepper(self, pr, rq):
        if rq.contacts is not None:  # each propagate call one run of the impact driver (.impact_stepper)
            return pr.sim.contact_stepper(self, pr.y, pr.rtol, pr.atol, rq.roots, rq.contacts)
        return self.stepper_index1(pr.sim, pr.y, pr.rtol, pr.atol, rq.roots)

    def _index1_ensemble(self, pr, rq):
        m = rq.members
        return self.ensemble_index1(pr.sim, pr.t, pr.y, pr.p, pr.rtol, pr.atol, rq.roots, threads=m.threads,
                                    save=m.save, progress=m.progress)

    #: What CVODE runs (Family.run), declared once: every other combination is refused by name.
    runs = {
        ("ode", "run"): (ode_run, combinations("", "events", "inputs", "sensitivities", "events+sensitivities",
                                                "inputs+sensitivities")),
        ("ode", "stepper"): (ode_stepper, combinations("", "events", "sensitivities", "events+sensitivities")),
        ("ode", "ensemble"): (ode_ensemble, combinations("", "events", "inputs", "sensitivities",
                                                          "events+sensitivities", "inputs+sensitivities")),
        ("ode", "prepared"): (_ode_prepared, combinations("", "sensitivities")),
        ("index1", "run"): (_index1_run, combinations("", "events", "sensitivities", "impacts", "events+impacts")),
        ("index1", "stepper"): (_index1_stepper, combinations("", "events", "impacts", "events+impacts")),
        # the ensembles of a system with contacts are its members' runs, each through ("index1", "run")
        ("index1", "ensemble"): (_index1_ensemble, combinations("", "events")),
    }
    refusals = {
        ("index1", "ensemble", frozenset({"sensitivities"})):
            "ensembles do not compute sensitivities: run simulate(..., sensitivities=[...]) per member",
        ("index1", "ensemble", frozenset({"events", "sensitivities"})):
            "ensembles do not compute sensitivities: run simulate(..., sensitivities=[...]) per member",
        ("index1", "stepper", frozenset({"sensitivities"})):
            "the integrator object does not compute sensitivities: use simulate(..., sensitivities=[...])",
        ("index1", "stepper", frozenset({"events", "sensitivities"})):
            "the integrator object does not compute sensitivities: use simulate(..., sensitivities=[...])",
        ("index1", "run", frozenset({"sensitivities", "impacts"})):
            "sensitivities of systems with contacts (impacts) are not computed",
        ("index1", "run", frozenset({"events", "sensitivities", "impacts"})):
            "sensitivities of systems with contacts (impacts) are not computed",
        ("index1", "run", frozenset({"events", "sensitivities"})):
            "sensitivities with events: not supported (run the sensitivities with events=False, or locate the "
            "events in a run of their own)",
    }

    def _native_only(self) -> None:
        if self.backend != "native":
            raise LagcodegenError("ensembles run on the native drivers (backend='native')")
