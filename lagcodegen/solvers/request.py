"""The few typed records a run hands to the C boundary (the drivers', steppers' and ensembles'
arguments), the same for every family:

* :class:`StepControl`: how the solver steps (method, tolerances, budgets, Jacobian, linear
  solver, order), made from a family object and the run's tolerances by :meth:`StepControl.of`;
* :class:`Index1Form`, :class:`GGLForm`: the settings of a constrained system's form
  (Baumgarte and projection of the index-1 form; IDA's algebraic unknowns of the GGL form);
* :class:`Recording`: what a run records beside its trajectory (events or root finding and how
  many are kept, the sensitivities' directions) and, for ensembles, what each member keeps,
  the threads and the progress bar;
* :class:`RunArrays`: the output times, initial state(s) and parameters of a call;
* :class:`Layout`: the layout of the rows of an ensemble's result (states, outputs,
  parameters, by name).

A driver's options struct is filled from them through its declaration in
:mod:`lagcodegen.codegen.signatures`: :func:`option_fields` gives the value of every field of
the struct that the records carry, by the field's name (the same values, converted the same way,
whichever driver, stepper or ensemble writes them)."""

from __future__ import annotations

import dataclasses
import functools
import operator
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..codegen.signatures import Struct
from .base import METHODS

@dataclass(frozen=True)
class StepControl:
    """How a run steps: ``method`` ("adams", "bdf", "taylor"; "" where the driver has one),
    ``rtol`` and ``atol`` (a float or one value per state, as the driver takes them), the budgets
    ``max_steps`` (internal steps of the run), ``max_wall`` (seconds, 0: none), the step sizes
    ``first_step``, ``max_step``, ``min_step`` (0: the solver's), ``max_order`` (0: the solver's),
    Taylor's series ``order`` (None: from the tolerance), ``jacobian`` (the generated one, else
    difference quotients), CVODE's linear solver (``band`` = (upper, lower) bandwidths, or
    ``fixedpoint``: functional iteration), and of sensitivity runs ``errcon`` (the
    sensitivities in the error test) and ``corrector`` ("staggered" or "simultaneous")."""

    rtol: float
    atol: Any
    method: str = ""
    max_steps: int = 1_000_000
    first_step: float = 0.0
    max_step: float = 0.0
    min_step: float = 0.0
    max_order: int = 0
    order: int | None = None
    jacobian: bool = False
    band: tuple[int, int] | None = None
    fixedpoint: bool = False
    max_wall: float = 0.0
    errcon: bool = True
    corrector: str = "staggered"

    @classmethod
    def of(cls, family, rtol, atol, method: str = "", jacobian: bool = False, band=None,
           fixedpoint: bool = False) -> "StepControl":
        """The step control of a run of ``family`` (a :class:`~lagcodegen.solvers.family.Family`)
        with these tolerances: its budgets (``max_steps`` as an int, ``max_step``, ``max_wall``
        as floats), the fields it has of ``first_step``, ``min_step``, ``max_order``, ``order``,
        its sensitivities' ``errcon`` and ``corrector``, and the values the family resolved for
        this run: ``method``, ``jacobian``, CVODE's ``band`` or ``fixedpoint``."""
        get = getattr
        return cls(rtol, atol, method, int(family.max_steps), get(family, "first_step", 0.0),
                   float(family.max_step), get(family, "min_step", 0.0), get(family, "max_order", 0),
                   get(family, "order", None), jacobian, band, fixedpoint, float(family.max_wall),
                   bool(get(family, "sensitivity_errcon", True)), get(family, "sensitivity_corrector", "staggered"))

    def with_tolerances(self, rtol, atol) -> "StepControl":
        """This control with other (e.g. resolved) tolerances."""
        return dataclasses.replace(self, rtol=rtol, atol=atol)

    def replace(self, **values) -> "StepControl":
        return dataclasses.replace(self, **values)

    @property
    def linear_solver(self) -> int:
        """The CVODE driver's ``linear_solver`` field: 0 dense, 1 band, 2 fixed-point iteration."""
        return 1 if self.band else 2 if self.fixedpoint else 0

    @property
    def bandwidths(self) -> tuple[int, int]:
        """The CVODE driver's ``mupper``, ``mlower`` fields (0, 0 without the band solver)."""
        return (self.band[0], self.band[1]) if self.band else (0, 0)


@dataclass(frozen=True)
class Index1Form:
    """The index-1 form of a constrained system (eq. 4.5): the Baumgarte parameters ``alpha``,
    ``beta``, ``projection`` onto the constraints after each step (CVODE's projection, BDF only)
    with its tolerance ``proj_tol`` and iteration limit ``proj_maxit``."""

    alpha: float
    beta: float
    projection: bool = False
    proj_tol: float = 1e-12
    proj_maxit: int = 10


@dataclass(frozen=True)
class GGLForm:
    """The GGL form of a constrained system on IDA: ``suppress_alg`` (lambda, mu out of the
    error test), ``stop_at_outputs`` (step exactly to every output time)."""

    suppress_alg: bool = True
    stop_at_outputs: bool = False


@dataclass(frozen=True)
class Recording:
    """What a run records beside its trajectory: ``events`` (the driver's events: compiled event
    functions, event objects, or an ensemble's (directions, terminal flags) arrays; None: none),
    ``roots`` (root finding on a constrained system's compiled events; the event functions'
    table of an ODE ensemble), ``max_events`` kept (per run or member), ``sensitivities`` (the
    directions, by name). Of an ensemble: ``save`` (what each member keeps: "final",
    "trajectory" or names), ``threads`` (None: the cores) and ``progress`` (the bar)."""

    events: Any = None
    roots: Any = False
    max_events: int = 10_000
    sensitivities: Any = None
    save: Any = "final"
    threads: int | None = None
    progress: Any = None

    def replace(self, **values) -> "Recording":
        return dataclasses.replace(self, **values)


@dataclass(frozen=True)
class RunArrays:
    """The arrays of a call: output times ``t``, initial state(s) ``y`` (one row per member of an
    ensemble), parameters ``p`` (one row per member, or one shared vector), and IDA's initial
    derivatives ``yp`` (or None)."""

    t: np.ndarray
    y: np.ndarray
    p: np.ndarray
    yp: np.ndarray | None = None


@dataclass(frozen=True)
class Layout:
    """The layout of an ensemble's rows: ``nrow`` state values and ``nout`` outputs per row,
    the names of the states (``state_names``), of the outputs, of the driver's row
    (``row_names``; hidden ones start with "_"), of the parameters, further named columns of the
    row (``extra_outputs``: name -> index), and what the result reports: ``method``,
    ``formulation``, ``n_coordinates``."""

    nrow: int
    nout: int
    state_names: Any
    output_names: Any
    row_names: Any
    param_names: Any = ()
    extra_outputs: dict | None = None
    method: str = ""
    formulation: str = ""
    n_coordinates: int | None = None


def _known(control: StepControl, form, recording: Recording | None) -> dict:
    """Every options field the records carry, by its name in the drivers' structs."""
    c = control
    mupper, mlower = c.bandwidths
    known = {"rtol": c.rtol, "max_steps": int(c.max_steps), "first_step": c.first_step, "max_step": c.max_step,
             "min_step": c.min_step, "max_order": c.max_order, "jacobian": int(bool(c.jacobian)),
             "linear_solver": c.linear_solver, "mupper": mupper, "mlower": mlower, "max_wall": float(c.max_wall),
             "order": int(c.order or 0)}
    if c.method in METHODS:
        known["method"] = METHODS[c.method]
    if isinstance(form, Index1Form):
        known.update(alpha=form.alpha, beta=form.beta, projection=int(bool(form.projection)),
                     proj_tol=form.proj_tol, proj_maxit=form.proj_maxit)
    elif isinstance(form, GGLForm):
        known.update(suppress_alg=int(bool(form.suppress_alg)), stop_at_outputs=int(bool(form.stop_at_outputs)))
    if recording is not None and isinstance(recording.roots, (bool, int, np.bool_)):  # not an ensemble's table
        known["roots"] = int(recording.roots)
    return known


def option_fields(struct: Struct, control: StepControl, form=None, recording: Recording | None = None) -> dict:
    """The fields of a driver's options ``struct`` (its declaration,
    :mod:`lagcodegen.codegen.signatures`) that ``control``, ``form`` (an :class:`Index1Form` or a
    :class:`GGLForm`) and ``recording`` (``roots``) carry: field name -> value, in the struct's
    order (the tolerances' vector, the run-control pointers and fixed fields are the caller's)."""
    known = _known(control, form, recording)
    return {f.name: known[f.name] for f in struct.fields if f.name in known}


def option_values(struct: Struct, names: tuple, control: StepControl, form=None,
                  recording: Recording | None = None) -> tuple:
    """The values of the fields ``names`` of ``struct`` (:func:`option_fields`), in that order:
    what :class:`~lagcodegen.solvers.base.PreparedOptions` takes (those of the last call again
    when it had the same records, by identity: records are never written)."""
    global _last_values
    last = _last_values
    if last is not None and last[0] is control and last[1] is form and last[2] is recording \
            and last[3] is struct and last[4] is names:
        return last[5]
    values = _picker(struct, names)(_known(control, form, recording))
    _last_values = (control, form, recording, struct, names, values)
    return values


_last_values = None  # (control, form, recording, struct, names, values) of the last call


def remembered(owner, key, make):
    """``make()``, or what it made for ``owner`` (e.g. a family object) and an equal ``key``
    the last time: the records of a run made once while its values stay the same. ``key`` None:
    made every time (keys of plain values only: numbers, strings, identities of read-only
    arrays that the records made keep alive)."""
    if key is None:
        return make()
    entry = _REMEMBERED.get(id(owner))
    if entry is not None and entry[0] is owner and entry[1] == key:
        return entry[2]
    value = make()
    if len(_REMEMBERED) >= 256:
        _REMEMBERED.clear()
    _REMEMBERED[id(owner)] = (owner, key, value)
    return value


_REMEMBERED: dict = {}  # id(owner) -> (owner, key, records)


@functools.lru_cache(maxsize=64)
def _picker(struct: Struct, names: tuple):
    """The getter of the fields ``names`` of ``struct`` from :func:`_known`'s values (the names
    checked against the struct's declaration once)."""
    declared = {f.name for f in struct.fields}
    unknown = [name for name in names if name not in declared]
    if unknown:
        raise KeyError(f"{struct.name} has no field {', '.join(map(repr, unknown))}")
    pick = operator.itemgetter(*names)
    return pick if len(names) > 1 else (lambda known: (pick(known),))
