"""How a scene's model is drawn: its points, which of them are linked, and a function computing
their positions from the states, as a :class:`lagcodegen.animation.Drawing` record.

Links are read from the model's geometry: two points (or a point and the origin, the suspension
of a pendulum) are joined when their distance is the same in every configuration, a rod or a
rigid body between them. The test is numerical: the distance at a few random states (q in
[-2, 2], t in [0, 1], the scene's parameter values) constant to 1e-9 relative. Points that no
coordinate or time moves are drawn as fixed pivots. Springs are drawn between their ends (an
end given as a position, not a named point, becomes a point of its own). The links of rigid-body trees are drawn
from the tree: each joint joined to its children's joints and to its own centre of mass.
Bodies carry short axes (a rigid body its three body axes, the columns of R; a planar body the
direction of its angle; a tree link its frame's axes), their length
:data:`AXIS_FRACTION` of the model's size, so that a rotation shows.

:func:`attaches_drawing` decorates a compiled model's ``simulate``: every result gets a deferred
drawing (made on first use, once per compiled model) and the model's name, so that
``res.animate("x.gif")`` and ``res.plot()`` need nothing else.
"""

from __future__ import annotations

import dataclasses
import functools
from typing import Callable

import numpy as np
import symengine as se
import sympy as sp

from ..animation import Drawing, resolve
from ..derivation import to_se
from ..model.model import PlanarBody, RigidBody
from .scene import Scene

#: Random states of the rigid-link test, and its relative tolerance.
LINK_SAMPLES = 5
LINK_RTOL = 1e-9
#: Relative tolerance of a distance kept over a constrained run (its constraint residuals are
#: about the tolerances of the integration, far above the unconstrained model's LINK_RTOL).
RUN_LINK_RTOL = 1e-4
#: Name of the origin when it is drawn as a pivot.
ORIGIN = "origin"
#: Length of the axes drawn on bodies, as a fraction of the largest distance of a point from the
#: origin over the link test's samples (1 where every point sits at the origin).
AXIS_FRACTION = 0.3


def drawing_of(scene: Scene) -> Drawing:
    """The drawing of ``scene``'s model (see the module's docstring)."""
    eom = scene.eom
    model = eom.model
    names = list(model.points)
    dims = {p: model.points[p].dim for p in names}
    located = {p: eom.position(p) for p in names}
    tree_points, tree_links = link_points(model)  # the joints and centres of mass of tree links
    for p, position in tree_points.items():
        dims[p] = 3
        located[p] = [to_se(c, f"position of {p!r}") for c in position]
    names += list(tree_points)
    springs: list[tuple[str, str]] = []
    for i, (_, pa, pb) in enumerate(model.springs):  # ends at unnamed positions become points of their own
        ends = []
        for end, pt in (("a", pa), ("b", pb)):
            name = pt.name if model.points.get(pt.name) is pt else f"spring{i}.{end}"
            if name not in dims:
                names.append(name)
                dims[name] = pt.dim
                located[name] = [to_se(c, f"position of {name!r}") for c in pt.position]
            ends.append(name)
        springs.append((ends[0], ends[1]))
    sub = scene.substitutions()
    coords = [se.Symbol(q.name) for q in model.coords]
    params = [se.Symbol(name) for name in scene.runtime_parameters]
    t = se.Symbol(model.t.name)
    directions = body_directions(model)  # (tip name, body point, axis letter, direction expressions)
    exprs = [c for p in names for c in located[p]] + [to_se(c, f"axis of {body!r}")
                                                     for _, body, _, d in directions for c in d]
    exprs = [c.xreplace(sub) if sub else c for c in exprs]
    if not exprs:
        return Drawing(model.name, {})
    f = se.Lambdify([t, *coords, *params], exprs, backend="lambda")
    n = len(coords)
    pvals = scene.default_parameters()
    sizes = [dims[p] for p in names] + [len(d) for _, _, _, d in directions]

    def positions(t_arr, q_rows, p_vals) -> list[np.ndarray]:
        """Positions of the points, then the axes' unit directions, each (N, dim)."""
        rows = np.array([f([ti, *q, *p_vals]) for ti, q in zip(t_arr, q_rows)], dtype=float).reshape(len(t_arr), -1)
        out, k = [], 0
        for size in sizes:
            out.append(rows[:, k:k + size])
            k += size
        return out

    rng = np.random.default_rng(12345)
    samples = positions(rng.uniform(0, 1, LINK_SAMPLES), rng.uniform(-2, 2, (LINK_SAMPLES, n)), pvals)
    at = dict(zip(names, samples))
    reach = max((float(np.linalg.norm(x, axis=1).max()) for x in at.values()), default=0.0)
    axis_length = AXIS_FRACTION * (reach if reach > 0 else 1.0)
    fixed = tuple(p for p in names if np.ptp(at[p], axis=0).max() <= LINK_RTOL * (1 + np.abs(at[p]).max()))
    links: list[tuple[str, str]] = []

    def rigid(a: np.ndarray, b: np.ndarray) -> bool:
        d = np.linalg.norm(a - b, axis=1)
        return bool(d.min() > 0 and np.ptp(d) <= LINK_RTOL * (1 + d.max()))

    loose = [p for p in names if p not in tree_points]  # the tree's links come from the tree
    for i, a in enumerate(loose):
        for b in loose[i + 1:]:
            if dims[a] == dims[b] and not (a in fixed and b in fixed) and rigid(at[a], at[b]):
                links.append((a, b))
    links += tree_links
    pivots: dict[str, tuple[float, ...]] = {}
    fixed_at_origin = [p for p in fixed if np.abs(at[p][0]).max() <= LINK_RTOL]
    for p in loose:
        if p in fixed:
            continue
        origin = np.zeros_like(at[p])
        if rigid(at[p], origin):
            if fixed_at_origin:  # a declared anchor there: the pair test has linked them
                continue
            pivots[ORIGIN] = (0.0,) * dims[p]
            links.append((ORIGIN, p))
    param_names = list(scene.runtime_parameters)

    def evaluate(t_arr, y, parameters) -> dict[str, np.ndarray]:
        y = np.asarray(y, dtype=float)
        pv = [float(parameters.get(name, d)) for name, d in zip(param_names, pvals)] if parameters else pvals
        values = positions(np.asarray(t_arr, dtype=float), y[:, :n], pv)
        out = dict(zip(names, values))
        for (tip, body, _, _), direction in zip(directions, values[len(names):]):
            out[tip] = out[body] + axis_length * direction
        return out

    return Drawing(model.name, dims, links, pivots, fixed, evaluate,
                   {tip: (body, axis) for tip, body, axis, _ in directions}, springs)


def link_points(model) -> tuple[dict[str, list], list[tuple[str, str]]]:
    """The points drawn for the links of rigid-body trees (:meth:`lagcodegen.model.Model.link`),
    as sympy world positions: each link's joint frame origin (named as the link) and, where it
    is elsewhere, its centre of mass (``<link>.com``); and the lines between them: each joint to
    its children's joints and to its own centre of mass."""
    points: dict[str, list] = {}
    lines: list[tuple[str, str]] = []
    for lk in model.links:
        points[lk.name] = list(lk.position())
        if lk.parent is not None:
            lines.append((lk.parent.name, lk.name))
        if any(c != 0 for c in lk.com):
            points[f"{lk.name}.com"] = list(lk.com_position())
            lines.append((lk.name, f"{lk.name}.com"))
    return points, lines


def body_directions(model) -> list[tuple[str, str, str, list]]:
    """The axes drawn on the model's bodies: (tip name ``<body>.<axis>``, the body's point, the
    axis letter, the axis' unit direction as sympy expressions): a rigid body's three body axes
    in world coordinates (the columns of its orientation R), a planar body's (cos, sin) of its
    angle, a tree link's frame axes (the columns of its world rotation) at its centre of mass."""
    out = []
    for lk in model.links:
        if lk.mass != 0:
            at = f"{lk.name}.com" if any(c != 0 for c in lk.com) else lk.name
            R = lk.rotation()
            for k, axis in enumerate("xyz"):
                out.append((f"{lk.name}.{axis}", at, axis, list(R[:, k])))
    for body in model.bodies:
        if isinstance(body, RigidBody):
            for k, axis in enumerate("xyz"):
                out.append((f"{body.name}.{axis}", body.point.name, axis, list(body.orientation[:, k])))
        elif isinstance(body, PlanarBody):
            out.append((f"{body.name}.x", body.point.name, "x", [sp.cos(body.angle), sp.sin(body.angle)]))
    return out


class DeferredDrawing:
    """A drawing made on first call (and kept): what a result holds until it is drawn. Pickled,
    it is made and stored without its position function (see :class:`Drawing`)."""

    def __init__(self, make: Callable[[], Drawing]):
        self._make = make
        self._drawing: Drawing | None = None

    def __call__(self) -> Drawing:
        if self._drawing is None:
            self._drawing = self._make()
        return self._drawing

    def __reduce__(self):
        try:
            drawing = self()
        except Exception:  # noqa: BLE001 - a model the drawing cannot evaluate: pickled without one
            drawing = None
        return (_stored, (drawing,))


def _stored(drawing: Drawing | None) -> Drawing | None:
    return drawing


def _code(cm):
    """The generated code of a compiled model, or of the model under a constrained one."""
    code = getattr(cm, "code", None)
    return code if code is not None else getattr(getattr(cm, "compiled", None), "code", None)


def deferred_drawing(cm) -> DeferredDrawing | None:
    """The deferred drawing of a compiled model (one per model), None without its scene."""
    cached = cm.__dict__.get("_lcg_drawing")
    if cached is not None:  # made from the model's scene on an earlier call
        return cached
    code = _code(cm)
    scene = code.stored_scene() if hasattr(code, "stored_scene") else getattr(code, "scene", None)
    if not isinstance(scene, Scene):
        if getattr(code, "rederive", None) is None:
            return None
        # code from the cache of a model file: its scene derived again when the drawing is read
        cached = cm.__dict__["_lcg_drawing"] = DeferredDrawing(lambda: drawing_of(_rederived(code)))
        return cached
    cached = cm.__dict__.get("_lcg_drawing")
    if cached is None:
        cached = cm.__dict__["_lcg_drawing"] = DeferredDrawing(functools.partial(drawing_of, scene))
    return cached


def _rederived(code) -> Scene:
    """The scene of ``code`` (a GeneratedCode with ``rederive``), derived again once."""
    if code.scene is None:
        code.scene = code.rederive()
    return code.scene


def attaches_drawing(simulate: Callable) -> Callable:
    """Decorate a compiled model's ``simulate(self, t, **options)``: its result gets the model's
    deferred drawing (``Result.drawing``) and name (``Result.model_name``)."""

    @functools.wraps(simulate)
    def wrapped(self, *args, **kwargs):
        res = simulate(self, *args, **kwargs)
        if getattr(res, "drawing", "absent") is None:
            res.drawing = deferred_drawing(self)
        if hasattr(res, "model_name") and not res.model_name:
            res.model_name = getattr(_code(self), "model_name", "") or ""
        return res

    return wrapped


def with_run_links(drawing: Drawing, t: np.ndarray, y: np.ndarray, parameters: dict) -> Drawing:
    """``drawing`` with the links that a run of a constrained system keeps: two points (or a point
    and the origin) whose distance stays constant over the run (to :data:`RUN_LINK_RTOL`), such
    as a pendulum's rod written as a constraint x^2 + y^2 = l^2, which the unconstrained model's
    geometry (:func:`drawing_of`) cannot show."""
    if drawing.evaluate is None or len(t) < 2:
        return drawing
    at = drawing.evaluate(t, y, parameters)
    names = [p for p in drawing.points if p in at]
    links = list(drawing.links)
    pivots = dict(drawing.pivots)
    linked = set(links) | {(b, a) for a, b in links}

    def kept(a: np.ndarray, b: np.ndarray) -> bool:
        d = np.linalg.norm(a - b, axis=1)
        return bool(d.min() > 0 and np.ptp(d) <= RUN_LINK_RTOL * d.max())

    for i, a in enumerate(names):
        for b in names[i + 1:]:
            if (a, b) not in linked and drawing.points[a] == drawing.points[b] and kept(at[a], at[b]):
                links.append((a, b))
    for p in names:
        if p not in drawing.fixed and (ORIGIN, p) not in linked and kept(at[p], np.zeros_like(at[p])):
            pivots[ORIGIN] = (0.0,) * drawing.points[p]
            links.append((ORIGIN, p))
    return dataclasses.replace(drawing, links=links, pivots=pivots)


def keep_run_links(res) -> None:
    """Make the drawing of the result ``res`` of a constrained run (if it has one) draw the links
    its run keeps (:func:`with_run_links`), once it is drawn."""
    base = res.drawing
    if base is not None:
        res.drawing = DeferredDrawing(lambda: with_run_links(resolve(base), res.t, res.y, res.parameters))


def attaches_run_drawing(simulate: Callable) -> Callable:
    """Decorate a constrained system's ``simulate``: as :func:`attaches_drawing`, the result's
    drawing being the unconstrained model's plus the links the run keeps (:func:`with_run_links`)."""

    @functools.wraps(simulate)
    def wrapped(self, *args, **kwargs):
        res = simulate(self, *args, **kwargs)
        if getattr(res, "drawing", "absent") is None:
            res.drawing = deferred_drawing(self)
            keep_run_links(res)
        if hasattr(res, "model_name") and not res.model_name:
            res.model_name = getattr(_code(self), "model_name", "") or ""
        return res

    return wrapped
