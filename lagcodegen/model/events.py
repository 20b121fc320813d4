"""Events: root functions from inequality constraints and user expressions; hybrid (switched) runs.

An :class:`Event` is a scalar expression e(q, q', t, p, lambda) whose zero crossings the
solvers locate (CVODE's CVodeRootInit/CVodeGetRootInfo in the constrained CVODE driver,
IDARootInit in the IDA driver, the ``eventsfn`` of scikit-sundae on that backend). Every
inequality constraint g_k(q, t) >= 0 of a :class:`~lagcodegen.theory.constraints.ConstrainedSystem`
(eq. 4.3) becomes the event ``ineq_<k>`` (direction -1, terminal): the moment the
inequality would start to be violated; those with a coefficient of restitution
(:class:`~lagcodegen.theory.constraints.Inequality`) are contacts with impacts instead. Event expressions may use the Lagrange multipliers
``lambda_<j>`` (eq. 4.5), e.g. a normal force that drops to zero.

Occurrences are reported in ``Result.events`` (a list of :class:`EventRecord`); a terminal
event stops the run and its state is appended as the last row of the result.

Switched runs (a first system until a terminal event, then a second one) are
:func:`lagcodegen.simulation.hybrid.simulate_with_switch`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Iterable, Mapping

import numpy as np
import sympy as sp

from ..errors import ModelError
from ..util import excerpt

#: Crossing directions: -1 decreasing (from + to -), +1 increasing, 0 both.
DIRECTIONS = (-1, 0, 1)


@dataclass(frozen=True)
class Event:
    """A root function: ``expr`` crossing zero in ``direction`` (-1, 0, +1); ``terminal`` stops the run."""

    name: str
    expr: object
    direction: int = 0
    terminal: bool = True

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name.isidentifier():
            raise ModelError(f"event name {self.name!r} must be an identifier")
        if self.direction not in DIRECTIONS:
            raise ModelError(f"event {self.name!r}: direction must be -1, 0 or +1, got {self.direction!r}")


@dataclass
class EventRecord:
    """One occurrence of an event: which one, when, the state there and the crossing direction."""

    name: str
    index: int
    t: float
    y: np.ndarray  # (q, q') at the event
    direction: int
    terminal: bool
    state_names: list = field(default_factory=list)
    #: runs with sensitivities (CVODE, Taylor): d t_event / d direction, and the sensitivity of the state at
    #: the event, d y(t_event) / d direction = s + y' d t_event / d direction (ny values), by the
    #: run's directions; None otherwise
    t_sensitivity: dict | None = field(default=None, compare=False)
    y_sensitivity: dict | None = field(default=None, compare=False, repr=False)

    @property
    def q(self) -> dict:
        n = len(self.y) // 2
        return dict(zip(self.state_names[:n], self.y[:n]))

    @property
    def v(self) -> dict:
        n = len(self.y) // 2
        return dict(zip(self.state_names[:n], self.y[n:2 * n]))


def _as_event(item, k: int) -> Event:
    if isinstance(item, Event):
        return item
    if isinstance(item, Mapping):
        return Event(**item)
    if isinstance(item, (tuple, list)) and 2 <= len(item) <= 4:
        return Event(*item)
    raise ModelError(f"event {k}: give an Event, a dict or a tuple (name, expr[, direction[, terminal]]), "
                     f"got {excerpt(item)}")


def event_list(system, events: Iterable = ()) -> list[Event]:
    """Every event of a constrained system: its inequality constraints, then ``events``.

    Expressions are checked: they may use the model's coordinates, velocities, parameters, t
    and the multipliers ``lambda_<j>`` of ``system`` (if any), nothing else.
    """
    model = system.model
    restitution = getattr(system, "restitution", None) or [None] * len(getattr(system, "inequalities", []))
    out = [Event(f"ineq_{k}", g, -1, True) for k, g in enumerate(getattr(system, "inequalities", []))
           if restitution[k] is None]  # contacts (a restitution) are impacts, not events
    names = {e.name for e in out}
    allowed = model.known_symbols() | set(getattr(system, "multipliers", []))
    for k, item in enumerate(events):
        ev = _as_event(item, k)
        if ev.name in names:
            raise ModelError(f"event name {ev.name!r} is used twice")
        names.add(ev.name)
        try:
            expr = sp.sympify(ev.expr, strict=True)
        except (sp.SympifyError, TypeError) as exc:
            raise ModelError(f"event {ev.name!r}: not a symbolic expression: {ev.expr!r}") from exc
        bad = expr.free_symbols - allowed
        if bad:
            lam = ", ".join(s.name for s in getattr(system, "multipliers", [])) or "none"
            raise ModelError(f"event {ev.name!r} uses unknown symbol(s): {', '.join(sorted(s.name for s in bad))} "
                             f"(multipliers: {lam})")
        out.append(Event(ev.name, expr, ev.direction, bool(ev.terminal)))
    return out


def records(events: list[Event], t, y, which, direction, state_names, ny: int) -> list[EventRecord]:
    """EventRecords from the arrays a driver fills (the first ny values of each row of ``y``; the
    records of one call share one copy of ``state_names``)."""
    rows = np.asarray(y, dtype=float)[:, :ny]  # (events, width) -> the state columns
    names = list(state_names)
    # the arrays read as Python numbers at once (the same values as element by element)
    return [EventRecord(events[i].name, i, tk, rows[k].copy(), dk, events[i].terminal, names)
            for k, (i, tk, dk) in enumerate(zip(np.asarray(which).tolist(), np.asarray(t, dtype=float).tolist(),
                                                np.asarray(direction).tolist()))]


