"""The event functions of a scene's ODE as one kernel: the events (:class:`~lagcodegen.model.events.Event`)
checked against the scene's symbols, with the names of the scene's outputs usable in their
expressions, and the :class:`~lagcodegen.formulation.kernels.Block` ``gout[k] = g_k(t, y, p)``
that the CVODE driver of a plain, Routhian-reduced or minimal-coordinate model locates
(CVodeRootInit) and the scikit-sundae backend evaluates. Kept apart from the model's kernels:
a model's code is the same with or without events."""

from __future__ import annotations

from typing import Iterable

import symengine as se
import sympy as sp

from ..derivation import to_se
from ..errors import ModelError
from ..model.events import Event, event_list
from .kernels import Block, substituter
from .scene import Scene


def scene_events(scene: Scene, events: Iterable = ()) -> list[Event]:
    """``events`` as checked :class:`Event` s of ``scene``: expressions in the coordinates,
    velocities, quadrature states, parameters and t, where a name of an output the scene can
    compute (:meth:`Scene.available_outputs`: ``energy``, ``p_theta``, ``bob_y``, a user output,
    ...) stands for its expression; any other name raises ModelError naming it."""
    model = scene.eom.model
    known = {s.name for s in model.known_symbols()}
    known |= {name for name, _ in scene.eom.quadratures}
    outputs = None
    resolved = []
    for k, item in enumerate(events):
        ev = _event(item, k)
        expr = ev.expr
        if isinstance(expr, str) or isinstance(expr, sp.Basic):
            try:
                expr = sp.sympify(expr, strict=not isinstance(expr, str))
            except (sp.SympifyError, TypeError, SyntaxError) as exc:
                raise ModelError(f"event {ev.name!r}: not a symbolic expression: {ev.expr!r}") from exc
            names = {s.name: s for s in expr.free_symbols if s.name not in known}
            if names:
                outputs = scene.available_outputs() if outputs is None else outputs
                sub = {s: sp.sympify(outputs[name]) for name, s in names.items() if name in outputs}
                if sub:
                    expr = expr.xreplace(sub)
            # numbers of the text in double precision, as everywhere in the generated code
            floats = {f: sp.Float(float(f)) for f in expr.atoms(sp.Float) if f._prec > 53}
            if floats:
                expr = expr.xreplace(floats)
        resolved.append(Event(ev.name, expr, ev.direction, ev.terminal))
    return event_list(_Quadratures(scene.eom), resolved)


def _event(item, k: int) -> Event:
    if isinstance(item, Event):
        return item
    if isinstance(item, dict):
        return Event(**item)
    if isinstance(item, (tuple, list)) and 2 <= len(item) <= 4:
        return Event(*item)
    raise ModelError(f"event {k}: give an Event, a dict or a tuple (name, expr[, direction[, terminal]]), "
                     f"got {item!r}")


class _Quadratures:
    """The equations of motion as :func:`event_list` reads a system: the model, whose known
    symbols the quadrature states (e.g. a Routhian's ignorable coordinates) join."""

    def __init__(self, eom):
        self.model = _Model(eom)


class _Model:
    def __init__(self, eom):
        self._model = eom.model
        self._extra = {sp.Symbol(name) for name, _ in eom.quadratures}

    def known_symbols(self):
        return self._model.known_symbols() | self._extra


def events_block(scene: Scene, events: list[Event]) -> Block:
    """``gout[k]`` = the expression of event k (checked by :func:`scene_events`), in the scene's
    array names (y[i], p[k]; folded parameters as numbers)."""
    c = substituter(scene)
    return Block([("gout", k) for k in range(len(events))],
                 [c(to_se(ev.expr, f"event {ev.name!r}")) for ev in events])


def events_gradient_block(scene: Scene, events: list[Event]) -> Block:
    """The derivatives of the event functions (checked by :func:`scene_events`) for the event
    times' sensitivities (eq. of :mod:`lagcodegen.solvers.event_sensitivity`):
    ``gt[k]`` = dg_k/dt, ``gy[k*ny + i]`` = dg_k/dy_i (y = (q, q', z)), ``gp[k*np + m]`` =
    dg_k/dp_m over the run-time parameters; the entries that vanish are left out (the generated
    function zeroes its arrays first). A derivative symengine cannot take in closed form raises
    ModelError."""
    eom = scene.eom
    model = eom.model
    c = substituter(scene)
    states = [se.Symbol(s.name) for s in model.coords] + [se.Symbol(s.name) for s in model.speeds]
    states += [se.Symbol(name) for name, _ in eom.quadratures]
    params = [se.Symbol(name) for name in scene.runtime_parameters]
    general = eom.general  # y = (q, v, z): g in the array symbols first (q' inside: the kinematics)
    if general:
        states = [se.Symbol(f"y[{i}]") for i in range(model.nq + model.nv + len(eom.quadratures))]
        params = [se.Symbol(f"p[{m}]") for m in range(len(params))]
    time = se.Symbol(model.t.name)
    ny, npar = len(states), len(params)
    block = Block()
    for k, ev in enumerate(events):
        g = to_se(ev.expr, f"event {ev.name!r}")
        g = c(g) if general else g
        for key, var in [(("gt", k), time)] + [(("gy", k * ny + i), v) for i, v in enumerate(states)] \
                + [(("gp", k * npar + m), v) for m, v in enumerate(params)]:
            e = se.diff(g, var) if general else c(se.diff(g, var))
            if e.atoms(se.Derivative, se.Subs):
                raise ModelError(f"event {ev.name!r}: its derivative {e} cannot be taken in closed form")
            if e != 0:
                block.add(key, e)
    return block
