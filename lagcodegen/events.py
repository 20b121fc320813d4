"""Events: root functions from inequality constraints and user expressions; hybrid (switched) runs.

An :class:`Event` is a scalar expression e(q, q', t, p, lambda) whose zero crossings the
solvers locate (CVODE's CVodeRootInit/CVodeGetRootInfo in the constrained CVODE driver,
IDARootInit in the IDA driver, the ``eventsfn`` of scikit-sundae on that backend). Every
inequality constraint g_k(q, t) >= 0 of a :class:`~lagcodegen.constraints.ConstrainedSystem`
(eq. 4.3) becomes the event ``ineq_<k>`` (direction -1, terminal): the moment the
inequality would start to be violated. Event expressions may use the Lagrange multipliers
``lambda_<j>`` (eq. 4.5), e.g. a normal force that drops to zero.

Occurrences are reported in ``Result.events`` (a list of :class:`EventRecord`); a terminal
event stops the run and its state is appended as the last row of the result.

:func:`simulate_with_switch` runs a first system until a terminal event and continues with a
second one from the event state (e.g. a particle on a sphere, then in free flight).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Iterable, Mapping

import numpy as np
import sympy as sp

from .errors import LagcodegenError, ModelError

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
                     f"got {item!r}")


def event_list(system, events: Iterable = ()) -> list[Event]:
    """Every event of a constrained system: its inequality constraints, then ``events``.

    Expressions are checked: they may use the model's coordinates, velocities, parameters, t
    and the multipliers ``lambda_<j>`` of ``system`` (if any), nothing else.
    """
    model = system.model
    out = [Event(f"ineq_{k}", g, -1, True) for k, g in enumerate(getattr(system, "inequalities", []))]
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
    """EventRecords from the arrays a driver fills."""
    out = []
    for k in range(len(t)):
        i = int(which[k])
        ev = events[i]
        out.append(EventRecord(ev.name, i, float(t[k]), np.array(y[k][:ny], dtype=float), int(direction[k]),
                               ev.terminal, list(state_names)))
    return out


# ---------------------------------------------------------------------- hybrid runs
@dataclass
class HybridResult:
    """Phases of a switched run, the switching event, and the phases joined into one table."""

    phases: list
    switch: EventRecord | None
    t: np.ndarray
    columns: dict

    def __getitem__(self, name: str) -> np.ndarray:
        if name == "t":
            return self.t
        if name not in self.columns:
            raise KeyError(f"{name!r}: not a column common to every phase ({', '.join(self.columns)})")
        return self.columns[name]

    @property
    def switch_time(self) -> float | None:
        return None if self.switch is None else self.switch.t


def _default_transfer(names_from: list[str], names_to_q: list[str]):
    def transfer(rec: EventRecord):
        q, v = rec.q, rec.v
        missing = [k for k in names_to_q if k not in q]
        if missing:
            raise LagcodegenError(f"simulate_with_switch: the second system's coordinate(s) "
                                  f"{', '.join(missing)} are not coordinates of the first; pass transfer=")
        return [q[k] for k in names_to_q], [v[k] for k in names_to_q]
    return transfer


def simulate_with_switch(first, second, t, q0, v0=None, params: Mapping | None = None,
                         event: str | None = None, transfer: Callable | None = None,
                         first_kwargs: Mapping | None = None, second_kwargs: Mapping | None = None,
                         **kwargs) -> HybridResult:
    """Run ``first`` until a terminal event, then ``second`` from the event state.

    ``first``: a compiled constrained system (:func:`lagcodegen.dae.compile_constrained`) or a
    compiled model; ``second``: either as well (e.g. the free particle after it leaves a
    surface). ``event`` names the switching event (default: the first terminal event).
    ``transfer(record) -> (q0, v0)`` maps the event state to the second system's initial
    state (default: same coordinate names). ``params`` go to both phases (each keeps the
    names it knows); ``kwargs`` (rtol, atol, ...) go to both, ``first_kwargs``/``second_kwargs``
    to one. Output times: the ``t`` before the event for the first phase, then the event
    time and the ``t`` after it for the second.
    """
    t = np.asarray(t, dtype=float).ravel()
    if t.size == 2:
        t = np.linspace(t[0], t[1], 1001)
    params = dict(params or {})

    def own(sim, values):
        names = set(getattr(sim, "param_names", []))
        return {k: v for k, v in values.items() if k in names}

    res1 = first.simulate(t, q0=q0, v0=v0, params=own(first, params), **{**kwargs, **(first_kwargs or {})})
    evs = getattr(res1, "events", []) or []
    terminal = [e for e in evs if e.terminal and (event is None or e.name == event)]
    if not terminal:
        return HybridResult([res1], None, res1.t, _columns([res1]))
    rec = terminal[-1]
    names1 = res1.state_names
    names2_q = second.state_names[: second.n]
    transfer = transfer or _default_transfer(names1, names2_q)
    q1, v1 = transfer(rec)
    t2 = np.concatenate([[rec.t], t[t > rec.t]])
    if t2.size < 2:
        return HybridResult([res1], rec, res1.t, _columns([res1]))
    res2 = second.simulate(t2, q0=q1, v0=v1, params=own(second, params), **{**kwargs, **(second_kwargs or {})})
    # The switching instant appears once, from the first phase (its last row).
    tt = np.concatenate([res1.t, res2.t[1:]])
    return HybridResult([res1, res2], rec, tt, _columns([res1, res2], skip_first=True))


def _columns(results: list, skip_first: bool = False) -> dict:
    common = None
    for r in results:
        names = set(r.state_names) | set(r.outputs)
        common = names if common is None else common & names
    cols = {}
    for name in sorted(common or ()):
        parts = [np.asarray(results[0][name])]
        for r in results[1:]:
            x = np.asarray(r[name])
            parts.append(x[1:] if skip_first else x)
        cols[name] = np.concatenate(parts)
    return cols
