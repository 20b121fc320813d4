"""The Taylor family's options object (:class:`Taylor`): its values checked once, resolved into
what the Taylor runtime's driver takes (:mod:`.run`, :mod:`.ensemble`)."""

from __future__ import annotations

from dataclasses import dataclass

from ...errors import LagcodegenError
from ...util import check_baumgarte
from ...result import Result
from ..family import Family, combinations, ode_ensemble, ode_run, ode_stepper, take_sensitivities
from ..request import Recording, StepControl
from .ensemble import run_taylor_ensemble, run_taylor_events_ensemble, run_taylor_sensitivity_ensemble
from .run import run_taylor, taylor_module
from .prepared import PreparedTaylorRun
from .stepper import TaylorSensitivityStepper, TaylorStepper


#: Why Taylor refuses a constrained system without contacts.
_NO_CONSTRAINED = ("the Taylor method integrates constrained systems with contacts (Inequality with a restitution) "
                   "only, on its contact driver; constrained systems without contacts run on CVODE (method='adams' "
                   "or 'bdf') or IDA (formulation 'ggl')")

#: The fields a prepared run honours (max_events: the events kept by a prepared run with events).
_PREPARED = frozenset(("max_steps", "max_step", "max_wall", "order", "max_events"))


@dataclass(frozen=True, kw_only=True)
class Taylor(Family):
    """The generated Taylor-series integrator of a scene (libm only, no SUNDIALS; the model's jet
    built on first use): ``order`` of the series (None: from the tolerance, about
    -ln(rtol)/2 + 3); ``max_events``: events kept in a run. It needs no Jacobian, so
    ``jacobian=`` beside ``method="taylor"`` has no effect. Forward sensitivities of a run:
    ``sensitivities`` names of run-time parameters and initial values (``"<q>(0)"``,
    ``"<q>_dot(0)"``), propagated by jet transport of the variational equations
    (:mod:`.variational`, :mod:`.sensitivity`: built on first use per set of names and events),
    in runs, ensembles and the integrator object, with events too (their times' sensitivities
    in the records, as on CVODE); ``sensitivity_errcon`` the
    sensitivities in the step-size rule (default True, as CVODE's).

    Constrained systems with contacts (index-1 form; :mod:`lagcodegen.simulation.taylor_impacts`):
    runs and ensembles on the Taylor contact driver, impacts and releases located on the
    polynomials of the gaps and multipliers, ``baumgarte`` the stabilization of the rows held
    (None: the system's compiled default); the integrator object of such systems (each propagate
    call one run of the driver); their compiled events located on the steps' polynomials (those
    using a multiplier refused). Refused by name: constrained systems without contacts, the
    sensitivities of systems with contacts, Coulomb friction."""

    name = "Taylor"
    methods = ("taylor",)
    faces = ("ode", "index1")
    only = {"baumgarte": ("index1",)}
    ignores = ("jacobian",)

    order: int | None = None
    max_events: int = 10_000
    sensitivities: tuple[str, ...] | None = None
    sensitivity_errcon: bool = True
    #: index-1 systems with contacts: Baumgarte's (alpha, beta) or "auto" (None: the compiled default)
    baumgarte: tuple[float, float] | str | None = None

    def __post_init__(self):
        super().__post_init__()
        take_sensitivities(self)
        if self.baumgarte is not None:
            object.__setattr__(self, "baumgarte", check_baumgarte(self.baumgarte))
        if self.order is not None and not (isinstance(self.order, int) and 2 <= self.order):
            raise LagcodegenError(f"Taylor order must be an integer >= 2, got {self.order!r}")

    def run_ode(self, cm, t, y, p, rtol: float, atol, events=()) -> Result:
        """A run of the ODE of ``cm`` (inputs checked by the face); ``events`` located on each
        step's polynomial."""
        if self.sensitivities is not None:
            return self._run_sensitivities(cm, t, y, p, rtol, atol, events)
        return run_taylor(cm, t, y, p, rtol=rtol, atol=atol, max_step=self.max_step, max_steps=int(self.max_steps),
                          order=self.order, events=events, max_events=self.max_events, max_wall=float(self.max_wall))

    def _run_sensitivities(self, cm, t, y, p, rtol: float, atol, events=()) -> Result:
        """A run of the states and their sensitivities (:mod:`.sensitivity`); ``events`` located
        on the state part of each step's polynomial, each with its time's sensitivities."""
        from .run import scene_of
        from .sensitivity import variational_module
        module = variational_module(cm, scene_of(cm), self.sensitivities, events)
        return module.simulate(t, y, p, rtol=rtol, atol=atol, errcon=bool(self.sensitivity_errcon),
                               max_step=float(self.max_step), max_steps=int(self.max_steps), order=self.order,
                               max_wall=float(self.max_wall), max_events=self.max_events)

    def _no_sensitivities(self, what: str) -> None:
        if self.sensitivities is not None:
            raise LagcodegenError(f"{what} do not compute sensitivities: use simulate(..., sensitivities=[...])")

    def stepper_ode(self, cm, mem, rtol: float, atol, events=()) -> TaylorStepper:
        """The C state of an integrator object on the ODE of ``cm`` (``mem`` = (t, y, p), checked by
        the face): the jet's storage and workspace made once (:mod:`.stepper`); ``events`` located
        on each step's polynomial; ``max_steps`` is the budget of one call."""
        if self.sensitivities is not None:
            return TaylorSensitivityStepper(cm, mem, self.sensitivities, rtol=rtol, atol=atol,
                                            errcon=bool(self.sensitivity_errcon), max_step=float(self.max_step),
                                            max_steps=int(self.max_steps), order=self.order,
                                            max_wall=float(self.max_wall), events=tuple(events),
                                            max_events=self.max_events)
        return TaylorStepper(cm, mem, rtol=rtol, atol=atol, max_step=float(self.max_step),
                             max_steps=int(self.max_steps), order=self.order, events=tuple(events),
                             max_events=self.max_events, max_wall=float(self.max_wall))

    def prepared_ode(self, cm, rtol: float, atol, fixed: dict):
        """The runs of :meth:`run_ode` (no events) with these tolerances prepared once
        (:class:`.prepared.PreparedTaylorRun`): what ``simulate()``'s fast path calls; ``fixed``
        the members every result shares. None when a field it does not know is set (a field
        added later takes the full path until the prepared run honours it)."""
        if self.sensitivities is not None:
            return self._prepared_sensitivities(cm, rtol, atol, fixed)
        if not self.defaults_beside(_PREPARED):
            return None
        return PreparedTaylorRun(taylor_module(cm), rtol=rtol, atol=atol, max_step=float(self.max_step),
                                 max_steps=int(self.max_steps), order=self.order, max_wall=float(self.max_wall),
                                 fixed=fixed)

    def prepared_ode_events(self, cm, rtol: float, atol, fixed: dict, events: tuple):
        """The runs of :meth:`run_ode` with ``events`` (located on each step's polynomial, at most
        ``max_events`` kept) prepared once (:class:`.prepared.PreparedTaylorRun`); None with
        sensitivities or a field it does not know."""
        if self.sensitivities is not None or not self.defaults_beside(_PREPARED):
            return None
        return PreparedTaylorRun(taylor_module(cm, events), rtol=rtol, atol=atol, max_step=float(self.max_step),
                                 max_steps=int(self.max_steps), order=self.order, max_wall=float(self.max_wall),
                                 fixed=fixed, max_events=self.max_events)

    def _prepared_sensitivities(self, cm, rtol: float, atol, fixed: dict):
        """The runs of :meth:`run_ode` with sensitivities (no events) prepared once
        (:class:`.prepared_sensitivity.PreparedTaylorSensitivityRun`), or None when a field it does
        not know is set."""
        if not self.defaults_beside(_PREPARED | {"sensitivities", "sensitivity_errcon"}):
            return None
        from .prepared_sensitivity import PreparedTaylorSensitivityRun
        from .run import scene_of
        from .sensitivity import variational_module
        module = variational_module(cm, scene_of(cm), self.sensitivities)
        return PreparedTaylorSensitivityRun(module, rtol=rtol, atol=atol, errcon=bool(self.sensitivity_errcon),
                                            max_step=float(self.max_step), max_steps=int(self.max_steps),
                                            order=self.order, max_wall=float(self.max_wall), fixed=fixed,
                                            model_ffi=cm.ffi, param_names=cm.param_names)

    def run_ode_inputs(self, cm, t, y, p, rtol: float, atol, inputs) -> Result:
        """A run of the ODE of ``cm`` driven by the input tables ``inputs``: each input a cubic of t
        in the jet, the run split at the tables' breakpoints (:mod:`.inputs`); with sensitivities,
        the variational jet of those cubics, the states and sensitivities carried across the
        breakpoints (:mod:`.sensitivity_inputs`)."""
        if self.sensitivities is not None:
            from .sensitivity_inputs import run_taylor_sensitivity_inputs
            return run_taylor_sensitivity_inputs(cm, t, y, p, inputs, self.sensitivities, self.control(rtol, atol))
        from .inputs import run_taylor_inputs
        return run_taylor_inputs(cm, t, y, p, inputs, rtol=rtol, atol=atol, max_step=self.max_step,
                                 max_steps=int(self.max_steps), order=self.order, max_wall=float(self.max_wall))

    def ensemble_ode_inputs(self, cm, t, Y, P, rtol, atol, inputs, *, threads, save, progress):
        """Members (rows of Y, P) of the ODE of ``cm``, member i driven by the input tables
        ``inputs[i]``, with sensitivities: each member the run :meth:`run_ode_inputs` makes of it
        alone (:func:`.sensitivity_inputs.run_taylor_sensitivity_inputs`), bit-identical to it.
        Without sensitivities refused (those members run on CVODE)."""
        if self.sensitivities is None:
            raise LagcodegenError("input tables are interpolated by the native CVODE driver; Taylor ensembles do "
                                  "not take them without sensitivities (use method='adams' or 'bdf')")
        from .sensitivity_inputs import run_taylor_sensitivity_inputs_ensemble
        recording = Recording(sensitivities=self.sensitivities, save=save, threads=threads, progress=progress)
        return run_taylor_sensitivity_inputs_ensemble(cm, t, Y, P, inputs, self.control(rtol, atol), recording)

    def ensemble_ode(self, cm, t, Y, P, rtol, atol, *, threads, save, progress, events=()):
        """Members (rows of Y, P) of the ODE of ``cm`` in one call of ``lcg_taylor_solve_many``; with
        sensitivities, each member a run of the variational jet (:mod:`.ensemble`), ``events``
        located in each; with events and no sensitivities, each member a run of the jet with
        them (:func:`.ensemble.run_taylor_events_ensemble`), its events recorded."""
        recording = Recording(events=events, max_events=self.max_events, sensitivities=self.sensitivities, save=save,
                              threads=threads, progress=progress)
        if self.sensitivities is not None:
            return run_taylor_sensitivity_ensemble(cm, t, Y, P, self.control(rtol, atol), recording)
        if events:
            return run_taylor_events_ensemble(cm, t, Y, P, self.control(rtol, atol), recording)
        return run_taylor_ensemble(cm, t, Y, P, self.control(rtol, atol), recording)

    # ------------------------------------------------------------------ the one entry (Family.run)
    def _ode_prepared(self, pr, rq):
        if rq.events:
            return self.prepared_ode_events(pr.sim, pr.rtol, pr.atol, rq.fixed, tuple(rq.events))
        return self.prepared_ode(pr.sim, pr.rtol, pr.atol, rq.fixed)

    def run_index1(self, sim, t, y0, p, rtol, atol, *, roots: bool = False, contacts=None, cancel=None) -> Result:
        """A run of the constrained system ``sim`` with contacts (``contacts``: the run's
        :class:`~lagcodegen.simulation.constrained_impacts.ContactOptions`) on the Taylor contact
        driver (:meth:`ConstrainedSimulation.run_contacts_taylor
        <lagcodegen.simulation.constrained.ConstrainedSimulation>`); ``cancel``: an ensemble's flag
        that stops the run once set. A system without contacts is refused by name."""
        if contacts is None:
            raise LagcodegenError(_NO_CONSTRAINED)
        return sim.run_contacts_taylor(self, t, y0, p, rtol, atol, roots=roots, contacts=contacts, cancel=cancel)

    def ensemble_index1(self, sim, t, Y, P, rtol, atol, roots: bool, *, threads, save, progress):
        """Refused by name: ensembles of constrained systems without contacts (those with contacts
        run each member through :meth:`run_index1`, :mod:`lagcodegen.simulation.impact_ensemble`)."""
        raise LagcodegenError(_NO_CONSTRAINED)

    def stepper_index1(self, sim, mem, rtol, atol, *, roots: bool = False, contacts=None):
        """The stepper of an integrator object of the constrained system ``sim`` with contacts on
        the memory ``mem`` = (t, y, p): each propagate call one run of the Taylor contact driver
        (:meth:`ConstrainedSimulation.contact_stepper_taylor
        <lagcodegen.simulation.constrained.ConstrainedSimulation>`). A system without contacts is
        refused by name."""
        if contacts is None:
            raise LagcodegenError(_NO_CONSTRAINED)
        return sim.contact_stepper_taylor(self, mem, rtol, atol, roots=roots, contacts=contacts)

    def _index1_stepper(self, pr, rq):
        return self.stepper_index1(pr.sim, pr.y, pr.rtol, pr.atol, roots=rq.roots, contacts=rq.contacts)

    def _index1_run(self, pr, rq):
        return self.run_index1(pr.sim, pr.t, pr.y, pr.p, pr.rtol, pr.atol, roots=rq.roots, contacts=rq.contacts,
                               cancel=rq.cancel)

    #: What Taylor runs (Family.run), declared once: every other combination is refused by name
    #: (events with input tables; ensembles with input tables need sensitivities: those members
    #: run on CVODE; of constrained systems, the runs of systems with contacts only, each member of
    #: their ensembles one such run).
    runs = {
        ("ode", "run"): (ode_run, combinations("", "events", "inputs", "sensitivities", "events+sensitivities",
                                                "inputs+sensitivities")),
        ("ode", "stepper"): (ode_stepper, combinations("", "events", "sensitivities", "events+sensitivities")),
        ("ode", "ensemble"): (ode_ensemble, combinations("", "events", "sensitivities", "events+sensitivities",
                                                          "inputs+sensitivities")),
        ("ode", "prepared"): (_ode_prepared, combinations("", "events", "sensitivities")),
        # constrained systems with contacts (plain: a system without contacts, refused by run_index1 by name)
        ("index1", "run"): (_index1_run, combinations("", "impacts", "events+impacts")),
        ("index1", "stepper"): (_index1_stepper, combinations("", "impacts", "events+impacts")),
    }
    refusals = {
        ("ode", "ensemble", frozenset({"inputs"})):
            "input tables are interpolated by the native CVODE driver; Taylor ensembles do not take them without "
            "sensitivities (use method='adams' or 'bdf')",
        ("index1", "run", frozenset({"events"})): _NO_CONSTRAINED,
        ("index1", "run", frozenset({"sensitivities"})): _NO_CONSTRAINED,
        ("index1", "run", frozenset({"events", "sensitivities"})): _NO_CONSTRAINED,
        ("index1", "stepper", frozenset({"events"})): _NO_CONSTRAINED,
        ("index1", "stepper", frozenset({"sensitivities", "impacts"})):
            "the integrator object does not compute sensitivities",
        ("index1", "run", frozenset({"sensitivities", "impacts"})):
            "sensitivities of systems with contacts (impacts) are not computed",
        ("index1", "run", frozenset({"events", "sensitivities", "impacts"})):
            "sensitivities of systems with contacts (impacts) are not computed",
    }

    def control(self, rtol, atol) -> StepControl:
        """The step control of a run with these tolerances (``max_step``, ``max_steps``, ``order``,
        ``max_wall``, the sensitivities' ``errcon``)."""
        return StepControl.of(self, rtol, atol, method="taylor")
