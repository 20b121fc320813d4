"""Hybrid (switched) runs: :func:`simulate_with_switch` runs a first compiled system until a
terminal event and continues with a second one from the event state (e.g. a particle on a
sphere, then in free flight)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Mapping

import numpy as np

from ..errors import LagcodegenError
from ..model.events import EventRecord
from ..util import output_times


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

    ``first``: a compiled constrained system (:func:`lagcodegen.api.compile_constrained`) or a
    compiled model; ``second``: either as well (e.g. the free particle after it leaves a
    surface). ``event`` names the switching event (default: the first terminal event).
    ``transfer(record) -> (q0, v0)`` maps the event state to the second system's initial
    state (default: same coordinate names). ``params`` go to both phases (each keeps the
    names it knows); ``kwargs`` (rtol, atol, ...) go to both, ``first_kwargs``/``second_kwargs``
    to one. Output times: the ``t`` before the event for the first phase, then the event
    time and the ``t`` after it for the second.
    """
    t = output_times(t)
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


