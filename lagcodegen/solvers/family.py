"""What a solver family is: a frozen options object that checks its values once, when made, and
runs the faces of a compiled simulation it integrates (:class:`Family`), and the one translation
of ``simulate``'s option keywords into such an object (:meth:`Family.from_options`,
:meth:`Family.updated`).

A family object is what ``simulate(..., solver=...)`` and ``ensemble(..., solver=...)`` take
(``CVODE(method="bdf")``); the keyword spellings (``method="bdf"``, ``linear_solver="band"``,
``baumgarte=(5, 5)``) are turned into the same object by the same code, so both spellings run the
same code after it. The faces (:mod:`lagcodegen.simulation`) it runs:

* ``"ode"``: the ODE y' = f(t, y) of a compiled scene (``run_ode``, ``ensemble_ode``);
* ``"index1"``: a constrained system at the acceleration level (``run_index1``, ``ensemble_index1``);
* ``"ggl"``: a constrained system in the stabilized index-2 GGL form (``run_ggl``, ``ensemble_ggl``).

Each face's runs are a declared interface (:class:`OdeRuns`, :class:`OdeInputRuns`,
:class:`Index1Runs`, :class:`GGLRuns`; prepared runs :class:`PreparedOdeRuns`,
:class:`PreparedOdeEventRuns`): a family lists the faces it integrates in ``faces``
(checked by :meth:`Family.check_face` when resolved) and has that face's methods; the
simulations call them by name, never through a name built at run time.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import ClassVar, Protocol, runtime_checkable

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
    (``only``: field -> faces) and keywords they accept without effect (``ignores``).
    """

    name: ClassVar[str] = ""
    methods: ClassVar[tuple[str, ...]] = ()
    faces: ClassVar[tuple[str, ...]] = ()
    only: ClassVar[dict] = {}
    ignores: ClassVar[tuple[str, ...]] = ()

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
        """Raise unless this family implements the interface of ``runs`` ("run", "stepper",
        "ensemble") on ``face`` (:data:`INTERFACES`), naming what is missing."""
        interface = INTERFACES.get((face, runs))
        if interface is None or not isinstance(self, interface):
            raise LagcodegenError(f"{self.name} has no {RUN_KINDS.get(runs, runs)} runner for {FACES.get(face, face)}")

    def defaults_beside(self, names: frozenset[str]) -> bool:
        """Whether every field not in ``names`` has its default value (a caller that honours only
        ``names`` may then stand in for the family's own runner)."""
        return all(_same(getattr(self, name), f.default) for name, f in self.fields().items() if name not in names)

@runtime_checkable
class OdeRuns(Protocol):
    """A run of the ODE face of a compiled scene to output times (CVODE, Taylor)."""

    def run_ode(self, cm, t, y, p, rtol: float, atol, events=()): ...


@runtime_checkable
class OdeSteppers(Protocol):
    """An integrator object's C stepper of the ODE face on the memory ``mem`` = (t, y, p)."""

    def stepper_ode(self, cm, mem, rtol: float, atol, events=()): ...


@runtime_checkable
class OdeEnsembles(Protocol):
    """An ensemble of runs of the ODE face."""

    def ensemble_ode(self, cm, t, Y, P, rtol, atol, *, threads, save, progress, events=()): ...


@runtime_checkable
class OdeInputRuns(Protocol):
    """The runs of the ODE face driven by input tables (native CVODE, Taylor)."""

    def run_ode_inputs(self, cm, t, y, p, rtol: float, atol, inputs): ...

    def ensemble_ode_inputs(self, cm, t, Y, P, rtol, atol, inputs, *, threads, save, progress): ...


@runtime_checkable
class PreparedOdeRuns(Protocol):
    """The ODE runs a family prepares once for given tolerances (``simulate()``'s fast path,
    :meth:`CompiledModel.prepare <lagcodegen.simulation.ode.CompiledModel.prepare>`): None where
    a run needs more than its driver's call."""

    def prepared_ode(self, cm, rtol: float, atol, fixed: dict): ...


@runtime_checkable
class PreparedOdeEventRuns(Protocol):
    """The ODE runs with events a family prepares once (Taylor)."""

    def prepared_ode_events(self, cm, rtol: float, atol, fixed: dict, events: tuple): ...


@runtime_checkable
class Index1Runs(Protocol):
    """A run of a constrained system in the index-1 form (CVODE)."""

    def run_index1(self, sim, t, y0, p, rtol, atol, roots: bool): ...


@runtime_checkable
class Index1Steppers(Protocol):
    def stepper_index1(self, sim, mem, rtol: float, atol, roots: bool): ...


@runtime_checkable
class Index1Ensembles(Protocol):
    def ensemble_index1(self, sim, t, Y, P, rtol, atol, roots: bool, *, threads, save, progress): ...


@runtime_checkable
class GGLRuns(Protocol):
    """A run of a constrained system in the GGL form (IDA)."""

    def run_ggl(self, sim, t, yy0, yp0, p, rtol, atol, roots: bool): ...


@runtime_checkable
class GGLSteppers(Protocol):
    def stepper_ggl(self, sim, mem, yy0, yp0, rtol, atol, roots: bool): ...


@runtime_checkable
class GGLEnsembles(Protocol):
    def ensemble_ggl(self, sim, t, Y, P, rtol, atol, roots: bool, *, threads, save, progress): ...


#: The interface a family implements for each (face, kind of run): the one table of what can be
#: asked of a family, checked by :func:`~.registry.resolve` (``runs=``) before anything runs.
INTERFACES = {
    ("ode", "run"): OdeRuns, ("ode", "stepper"): OdeSteppers, ("ode", "ensemble"): OdeEnsembles,
    ("index1", "run"): Index1Runs, ("index1", "stepper"): Index1Steppers, ("index1", "ensemble"): Index1Ensembles,
    ("ggl", "run"): GGLRuns, ("ggl", "stepper"): GGLSteppers, ("ggl", "ensemble"): GGLEnsembles,
}
#: How each kind of run is named in messages.
RUN_KINDS = {"run": "run", "stepper": "integrator object (stepper)", "ensemble": "ensemble"}


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
