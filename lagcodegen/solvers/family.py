"""What a solver family is: a frozen options object that checks its values once, when made, and
runs the faces of a compiled simulation it integrates (:class:`Family`), and the one translation
of ``simulate``'s option keywords into such an object (:meth:`Family.from_options`,
:meth:`Family.updated`).

A family object is what ``simulate(..., solver=...)`` and ``ensemble(..., solver=...)`` take
(``CVODE(method="bdf")``); the keyword spellings (``method="bdf"``, ``linear_solver="band"``,
``baumgarte=(5, 5)``) are turned into the same object by the same code, so both spellings run the
same code after it. The faces (:mod:`lagcodegen.simulation`) it runs: ``"ode"`` (the ODE
y' = f(t, y) of a compiled scene), ``"index1"`` (a constrained system at the acceleration level),
``"ggl"`` (a constrained system in the stabilized index-2 GGL form).

**One entry.** Every simulation asks a family through one call, :meth:`Family.run` (the
:class:`Runs` interface): ``family.run(face, Problem(...), Request(...))``. The
:class:`Problem` is what is integrated (the compiled simulation, tolerances, times, initial
state(s), parameters); the :class:`Request` is the kind of run (to output times, an integrator
object's stepper, a prepared run, an ensemble of :class:`Members`), what it records (events; the
family's sensitivities, asked as a :class:`Sensitivities` value) and what drives it (input
tables; a system's contacts, its impacts recorded). Each family declares once, in its ``runs``
table, the (face, kind) pairs it runs and the combinations of events, inputs, sensitivities and
impacts each takes (:func:`combinations`); anything
else is refused by :meth:`Family.check`, by name, before anything runs. No method name is built
at run time.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, ClassVar, Protocol, runtime_checkable

from ..errors import LagcodegenError

#: The faces a family may integrate, with the words that name them in messages.
FACES = {"ode": "the ODE of a compiled scene", "index1": "a constrained system in the index-1 form",
         "ggl": "a constrained system in the GGL form", "minimal": "a constrained system in minimal coordinates"}

#: Keywords of simulate() that ask for nothing when given with one of these values: accepted
#: (without effect) by a family that has no such option, e.g. ``backend="native"`` on Taylor.
NEUTRAL = {"backend": ("native",), "linear_solver": ("dense",), "bandwidths": (None,), "max_order": (0,),
           "first_step": (0.0,), "min_step": (0.0,), "order": (None,), "jacobian": (None,), "baumgarte": (None,),
           "projection": (None, False), "suppress_alg": (True,), "alg_atol": (None,), "stop_at_outputs": (False,)}


@dataclass(frozen=True, kw_only=True)
class Family:
    """The options every family has (the budgets of a run) and the checks they share.

    ``max_steps``: internal steps over the whole run; ``max_step``: largest step (0: none);
    ``max_wall``: wall-clock limit of a run (of each ensemble member) in seconds (0: none).
    Subclasses name themselves (``name``), the ``method=`` spellings that choose them
    (``methods``), the faces they run (``faces``), the fields that apply to some faces only
    (``only``: field -> faces), keywords they accept without effect (``ignores``), and their
    runs (``runs``: (face, kind of run) -> (function, combinations); ``refusals``: their words
    for a combination they do not take).
    """

    name: ClassVar[str] = ""
    methods: ClassVar[tuple[str, ...]] = ()
    faces: ClassVar[tuple[str, ...]] = ()
    only: ClassVar[dict] = {}
    ignores: ClassVar[tuple[str, ...]] = ()
    #: The runs of the family: (face, kind of run) -> (the function running a problem and a
    #: request, the combinations of what a request asks that it takes: :func:`combinations`).
    runs: ClassVar[dict] = {}
    #: Why a combination is not run, where a family has more to say than that it is not
    #: (:meth:`why_not`).
    refusals: ClassVar[dict] = {}

    max_steps: int = 1_000_000
    max_step: float = 0.0
    max_wall: float = 0.0

    def __post_init__(self):
        if isinstance(self.max_steps, bool) or not isinstance(self.max_steps, int) or self.max_steps < 1:
            raise LagcodegenError(f"max_steps must be a positive integer, got {self.max_steps!r}")
        for name in ("max_step", "max_wall"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 <= value < float("inf"):
                raise LagcodegenError(f"{name} must be a finite number >= 0, got {value!r}")

    # ------------------------------------------------------------------ from keywords
    @classmethod
    def fields(cls) -> dict:
        return {f.name: f for f in dataclasses.fields(cls)}

    @classmethod
    def from_options(cls, face: str, options: dict) -> "Family":
        """The family object of ``options`` (simulate's keywords other than the face's own)."""
        return cls(**cls._own(face, options))

    def updated(self, face: str, options: dict) -> "Family":
        """This object with ``options`` given beside it applied; a keyword that contradicts a
        value set in the object is an error."""
        own = self._own(face, options)
        if not own:
            return self
        fields = self.fields()
        for key, value in own.items():
            mine = getattr(self, key)
            if mine != fields[key].default and mine != value:
                raise LagcodegenError(f"{key}={value!r} contradicts solver={self!r}")
        return dataclasses.replace(self, **own)

    @classmethod
    def _own(cls, face: str, options: dict) -> dict:
        """The keywords of ``options`` that are fields of this family; the others must be neutral
        (:data:`NEUTRAL`) or ignored by the family, else LagcodegenError naming them."""
        fields = cls.fields()
        own, foreign = {}, []
        for key, value in options.items():
            if key in fields:
                own[key] = value
            elif key in cls.ignores or any(_same(value, v) for v in NEUTRAL.get(key, ())):
                continue
            else:
                foreign.append(key)
        if foreign:
            raise LagcodegenError(f"{_names(foreign)} not an option of {cls.name} on {FACES.get(face, face)} "
                                  f"(its options: {', '.join(cls.fields_for(face))})")
        return own

    @classmethod
    def fields_for(cls, face: str) -> list[str]:
        return [name for name in cls.fields() if face in cls.only.get(name, (face,))]

    def check_face(self, face: str) -> None:
        """Raise unless this family runs ``face`` with every option set here."""
        if face not in self.faces:
            runs = " and ".join(FACES[f] for f in self.faces)
            raise LagcodegenError(f"{self.name} integrates {runs}, not {FACES.get(face, face)}")
        fields = self.fields()
        wrong = [name for name, faces in self.only.items()
                 if face not in faces and not _same(getattr(self, name), fields[name].default)]
        if wrong:
            raise LagcodegenError(f"{', '.join(map(repr, wrong))}: option{'s' if len(wrong) > 1 else ''} of {self.name} "
                                  f"that {FACES.get(face, face)} does not take")

    def check_runs(self, face: str, runs: str) -> None:
        """Raise unless this family has a run of the kind ``runs`` ("run", "stepper", "ensemble",
        "prepared") on ``face`` (:attr:`runs`), naming what is missing."""
        if (face, runs) not in self.runs:
            raise LagcodegenError(f"{self.name} has no {RUN_KINDS.get(runs, runs)} runner for {FACES.get(face, face)}")

    def supports(self, face: str, request: "Request") -> bool:
        """Whether this family runs ``request`` on ``face`` (:attr:`runs`)."""
        entry = self.runs.get((face, request.how))
        return entry is not None and request.asks(self) in entry[1]

    def run(self, face: str, problem: "Problem", request: "Request | None" = None):
        """The one entry of a family: the run of ``problem`` on ``face`` ("ode", "index1",
        "ggl") that ``request`` asks for (:class:`Request`: a run to output times, an integrator
        object's stepper, a prepared run or an ensemble; with events, input tables, this
        family's sensitivities). What each family takes is declared once, in its :attr:`runs`
        table; any other combination is refused (:meth:`check`), by name, before anything runs."""
        request = _PLAIN if request is None else request
        return self.check(face, request)(self, problem, request)

    def check(self, face: str, request: "Request"):
        """The function of :attr:`runs` that runs ``request`` on ``face``; LagcodegenError naming
        the kind of run, the face and what was asked together when this family does not take it
        (:meth:`why_not` may say why)."""
        how = request.how
        entry = self.runs.get((face, how))
        if entry is None:
            raise LagcodegenError(f"{self.name} has no {RUN_KINDS.get(how, how)} runner for {FACES.get(face, face)}")
        function, allowed = entry
        asked = request.asks(self)
        if asked not in allowed:
            takes = "; ".join(sorted(" and ".join(sorted(a)) if a else "plain" for a in allowed))
            reason = self.why_not(face, how, asked)
            raise LagcodegenError(reason or f"{self.name}: a {RUN_KINDS.get(how, how)} of {FACES.get(face, face)} "
                                  f"with {' and '.join(sorted(asked))} together is not supported (it takes: {takes})")
        return function

    def why_not(self, face: str, how: str, asked: frozenset[str]) -> str | None:
        """A family's own words for a combination its :attr:`runs` does not take (its
        :attr:`refusals`: (face, kind of run, what is asked) -> the message; None: the generic
        message). Events with input tables are refused on every family."""
        if {"events", "inputs"} <= asked:
            return "events with input tables: not supported"
        return self.refusals.get((face, how, asked))

    def defaults_beside(self, names: frozenset[str]) -> bool:
        """Whether every field not in ``names`` has its default value (a caller that honours only
        ``names`` may then stand in for the family's own runner)."""
        return all(_same(getattr(self, name), f.default) for name, f in self.fields().items() if name not in names)

@dataclass(frozen=True, slots=True)
class Problem:
    """What a run integrates: ``sim`` (a compiled scene on the ODE face, a constrained simulation
    on the index-1 and GGL faces), its tolerances ``rtol`` and ``atol``, the output times ``t``
    (None for a stepper or a prepared run), the initial state ``y`` (rows of it for an ensemble;
    a stepper's memory (t, y, p)), its derivative ``yp`` (the GGL form's consistent (y, y')
    pair: ``y`` and ``yp``) and the parameters ``p`` (rows for an ensemble)."""

    sim: Any
    rtol: Any
    atol: Any
    t: Any = None
    y: Any = None
    p: Any = None
    yp: Any = None


@dataclass(frozen=True, slots=True)
class Members:
    """How an ensemble runs its members: ``threads``, what each keeps (``save``: "final" or
    "all") and the ``progress`` bar."""

    threads: Any = None
    save: str = "final"
    progress: Any = None


@dataclass(frozen=True, slots=True)
class Request:
    """What a simulation asks of a family besides the problem: the ``kind`` of run ("run": to
    output times, "stepper": an integrator object's C state, "prepared": a run made once for
    many calls), what it records (``events``: the ODE face's :class:`~lagcodegen.model.events.Event`
    objects; ``roots``: a constrained system's compiled events located; the sensitivities are
    the family's own ``sensitivities``), what drives it (``inputs``: an input set, one per
    member for an ensemble), how many members (``members``: None for one run, else
    :class:`Members`), ``fixed`` (a prepared run: what every result shares), ``initial``
    (constrained sensitivity runs: how the initial state was made consistent) and ``contacts``
    (a system with contacts: the run's contact settings, its impacts recorded; ``cancel``: an
    ensemble's flag that stops a member's run once set)."""

    kind: str = "run"
    events: tuple = ()
    roots: bool = False
    inputs: Any = None
    members: Members | None = None
    fixed: dict | None = None
    initial: str = "check"
    contacts: Any = None
    cancel: Any = None

    def asks(self, family: "Family") -> frozenset[str]:
        """What this request asks beyond a plain run, in the words of :attr:`Family.runs`:
        "events", "inputs", "sensitivities", "impacts"."""
        asked = set()
        if self.events or self.roots:
            asked.add("events")
        if self.inputs is not None:
            asked.add("inputs")
        if getattr(family, "sensitivities", None) is not None:
            asked.add("sensitivities")
        if self.contacts is not None:
            asked.add("impacts")
        return frozenset(asked)

    @property
    def how(self) -> str:
        """The kind of run: "ensemble" when there are members, else :attr:`kind`."""
        return "ensemble" if self.members is not None else self.kind


@runtime_checkable
class Runs(Protocol):
    """The one entry of a solver family: ``run(face, problem, request)`` (:meth:`Family.run`)."""

    def run(self, face: str, problem: Problem, request: Request = ...): ...


_PLAIN = Request()


@dataclass(frozen=True)
class Sensitivities:
    """Forward sensitivities asked of a run, as one value: ``directions`` (names of run-time
    parameters and initial values, ``"<q>(0)"``, ``"<q>_dot(0)"``:
    :class:`~lagcodegen.solvers.direction.Direction`), ``errcon`` (the sensitivities in the error
    test or step-size rule) and ``corrector`` (CVODE's "staggered" or "simultaneous").
    ``simulate(..., sensitivities=Sensitivities(["k"], errcon=False))`` is
    ``sensitivities=["k"], sensitivity_errcon=False``; the family keeps them in its fields."""

    directions: tuple[str, ...]
    errcon: bool = True
    corrector: str = "staggered"

    def __post_init__(self):
        names = (self.directions,) if isinstance(self.directions, str) else self.directions
        try:
            object.__setattr__(self, "directions", tuple(names))
        except TypeError:
            raise LagcodegenError(f"Sensitivities: directions must be a list of names, got {names!r:.80}") from None
        if not isinstance(self.errcon, bool):
            raise LagcodegenError(f"Sensitivities: errcon must be True or False, got {self.errcon!r:.40}")
        choice("Sensitivities: corrector", self.corrector, ("staggered", "simultaneous"))

    @classmethod
    def of(cls, family: "Family") -> "Sensitivities | None":
        """The sensitivities ``family`` computes (None: none)."""
        directions = getattr(family, "sensitivities", None)
        if directions is None:
            return None
        return cls(directions, bool(getattr(family, "sensitivity_errcon", True)),
                   getattr(family, "sensitivity_corrector", "staggered"))


def take_sensitivities(obj) -> None:
    """Normalize the ``sensitivities`` field of the family object ``obj``: a
    :class:`Sensitivities` value sets the directions and the family's ``sensitivity_errcon``
    and ``sensitivity_corrector`` (a corrector other than "staggered" on a family without one is
    refused); a name or a list of names becomes a tuple (:func:`names_field`)."""
    value = obj.sensitivities
    if not isinstance(value, Sensitivities):
        names_field(obj, "sensitivities")
        return
    object.__setattr__(obj, "sensitivities", value.directions)
    object.__setattr__(obj, "sensitivity_errcon", value.errcon)
    if "sensitivity_corrector" in obj.fields():
        object.__setattr__(obj, "sensitivity_corrector", value.corrector)
    elif value.corrector != "staggered":
        raise LagcodegenError(f"Sensitivities(corrector={value.corrector!r}): {obj.name} has no corrector choice")


def combinations(*allowed: str) -> frozenset[frozenset[str]]:
    """The combinations of what a request asks that a family's run takes, each written as words
    joined by "+" ("" a plain run): ``combinations("", "events", "events+sensitivities")``."""
    return frozenset(frozenset(w for w in words.split("+") if w) for words in allowed)


#: How each kind of run is named in messages.
RUN_KINDS = {"run": "run", "stepper": "integrator object (stepper)", "ensemble": "ensemble",
             "prepared": "prepared run"}


def _same(a, b) -> bool:
    try:
        return bool(a == b) and type(a) is not bool or a is b
    except Exception:  # noqa: BLE001 - arrays and other values without a truth value
        return False


def _names(keys: list) -> str:
    return ", ".join(map(repr, keys)) + (" is" if len(keys) == 1 else " are")


def choice(name: str, value, choices) -> None:
    """Raise LagcodegenError unless ``value`` is one of ``choices``."""
    if value not in choices:
        raise LagcodegenError(f"{name} must be one of {', '.join(map(str, choices))}, got {value!r}")


def names_field(obj, name: str) -> None:
    """Normalize the names field ``name`` of the frozen options object ``obj`` (None kept): one
    name becomes a 1-tuple, any other iterable a tuple; anything else raises LagcodegenError
    naming the field."""
    value = getattr(obj, name)
    if value is None:
        return
    names = (value,) if isinstance(value, str) else value
    try:
        object.__setattr__(obj, name, tuple(names))
    except TypeError:
        raise LagcodegenError(f"{name} must be a list of names, got {names!r}") from None


# ---------------------------------------------------------------------- the ODE face's runs, shared
def ode_run(family, pr: Problem, rq: Request):
    """A run of the ODE face to output times on a family with ``run_ode`` and
    ``run_ode_inputs`` (input tables)."""
    if rq.inputs is not None:
        return family.run_ode_inputs(pr.sim, pr.t, pr.y, pr.p, pr.rtol, pr.atol, rq.inputs)
    return family.run_ode(pr.sim, pr.t, pr.y, pr.p, pr.rtol, pr.atol, rq.events)


def ode_stepper(family, pr: Problem, rq: Request):
    """An integrator object's stepper of the ODE face on the memory ``pr.y`` = (t, y, p)."""
    return family.stepper_ode(pr.sim, pr.y, pr.rtol, pr.atol, rq.events)


def ode_ensemble(family, pr: Problem, rq: Request):
    """An ensemble of the ODE face (rows of ``pr.y``, ``pr.p``), with input tables one set per member."""
    m = rq.members
    if rq.inputs is not None:
        return family.ensemble_ode_inputs(pr.sim, pr.t, pr.y, pr.p, pr.rtol, pr.atol, rq.inputs,
                                          threads=m.threads, save=m.save, progress=m.progress)
    return family.ensemble_ode(pr.sim, pr.t, pr.y, pr.p, pr.rtol, pr.atol, threads=m.threads, save=m.save,
                               progress=m.progress, events=rq.events)
