"""The Taylor method driven by input tables: each input u of the tables becomes, in a jet of its
own, the cubic u(t) = c0 + c1 s + c2 s^2 + c3 s^3, s = t - tc, with c0..c3 and tc extra run-time
parameters after the scene's (:class:`InputSeriesScene`), so that the jet carries u's Taylor
coefficients on every step; the run goes segment by segment between the tables' breakpoints
(:func:`run_taylor_inputs`), each segment a call of the Taylor driver with the coefficients of
the pieces that hold there. A step never straddles a breakpoint, and inside a segment the input
is exactly the table's polynomial piece (no interpolation error of the method)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import symengine as se

from ...errors import LagcodegenError
from ...formulation.scene import Scene
from ...result import Result
from .run import scene_of
from .runner import TaylorModule, build_taylor

#: Extra run-time parameters per input: c0, c1, c2, c3, tc.
PER_INPUT = 5


@dataclass
class InputSeriesScene(Scene):
    """A scene whose inputs ``series_inputs`` are cubics of t with run-time coefficients: input a
    is p[np + 5a + j] (j = 0..3) times (t - p[np + 5a + 4])^j summed, np the scene's run-time
    parameters (the table's piece on the current segment)."""

    series_inputs: tuple = ()

    def substitutions(self) -> dict:
        sub = super().substitutions()
        t = se.Symbol(self.eom.model.t.name)
        base = len(self.runtime_parameters)
        for a, name in enumerate(self.series_inputs):
            k = base + PER_INPUT * a
            c = [se.Symbol(f"p[{k + j}]") for j in range(4)]
            s = t - se.Symbol(f"p[{k + 4}]")
            sub[se.Symbol(name)] = c[0] + s * (c[1] + s * (c[2] + s * c[3]))
        return sub


def series_module(cm, names: tuple):
    """The compiled Taylor integrator of ``cm``'s scene with the inputs ``names`` as cubics of t
    (built once per set of inputs, then reused)."""
    def make():
        scene = scene_of(cm)
        series = InputSeriesScene(eom=scene.eom, jacobian=False, outputs=list(scene.outputs),
                                  runtime_parameters=list(scene.runtime_parameters), values=dict(scene.values),
                                  prefix=f"{scene.prefix}_useries", series_inputs=names)
        return build_taylor(series)
    return cm.artifacts.get(TaylorModule, ("inputs", names), make)


def segment_parameters(p: np.ndarray, tables, a: float) -> np.ndarray:
    """``p`` extended by the coefficients and origin of each table's piece that holds at ``a``."""
    extra = []
    for tab in tables.tables:
        k = int(tab.piece(a))
        origin = tab.times[min(max(k - 1, 0), tab.times.size - 1)]
        extra.extend([*tab.coefficients[k], origin])
    return np.ascontiguousarray(np.concatenate([p, extra]))


def run_taylor_inputs(cm, t: np.ndarray, y: np.ndarray, p: np.ndarray, tables, *, rtol: float, atol, max_step: float,
                      max_steps: int, order: int | None, max_wall: float = 0.0) -> Result:
    """Integrate ``cm`` with the Taylor method, the inputs from ``tables``
    (:class:`~lagcodegen.solvers.inputs.InputSet`), segment by segment between their breakpoints."""
    module = series_module(cm, tuple(tables.names))

    def segment(seg, start, pseg, budget):
        res = module.simulate(seg, start, pseg, rtol=rtol, atol=atol, max_step=max_step, max_steps=budget,
                              order=order, max_wall=max_wall)
        return res, (np.ascontiguousarray(res.y[-1]) if res.t.size else start)

    return run_segments(cm, t, p, tables, np.ascontiguousarray(y, dtype=float), segment,
                        max_steps=max_steps, output_names=module.output_names)


#: The statistics of a segment's run summed over the segments (those a run reports).
_SUMMED = ("steps", "rhs_evals", "jet_evals", "root_searches", "wall_time")


def run_segments(cm, t: np.ndarray, p: np.ndarray, tables, start, segment, *, max_steps: int,
                 output_names: list) -> Result:
    """The run of ``cm`` from t[0] to t[-1] split at the breakpoints of ``tables`` inside it:
    ``segment(times, start, parameters, budget)`` runs one segment from ``start`` at times[0]
    (its output times inside, then its end) with the parameters :func:`segment_parameters`
    makes and at most ``budget`` steps, and returns (its Result, the start of the next segment).
    The rows at the output times ``t``, their sensitivities when the segments' Results have
    them; statistics summed (steps, evaluations, wall time; h_min, h_max the extremes),
    ``restarts`` the breakpoints inside."""
    breaks = np.unique(np.concatenate([tab.times for tab in tables.tables]))
    breaks = breaks[(breaks > t[0]) & (breaks < t[-1])]
    edges = np.concatenate([[t[0]], breaks, [t[-1]]])
    rows_t, rows_y, rows_out, rows_s = [], [], [], []
    stats = {"steps": 0, "rhs_evals": 0, "jet_evals": 0, "root_searches": 0}
    status, message, last = 0, "success", None
    for i in range(edges.size - 1):
        a, b = float(edges[i]), float(edges[i + 1])
        final = i == edges.size - 2
        inner = t[(t > a) & (t < b)]
        seg = np.ascontiguousarray(np.concatenate([[a], inner, [b]]))
        budget = max_steps - stats["steps"]
        if budget < 1:
            status, message = -1, f"the step budget max_steps = {max_steps} is used up before t = {b!r}"
            break
        last, start = segment(seg, start, segment_parameters(p, tables, a), budget)
        for k in _SUMMED:
            if k in last.stats:
                stats[k] = stats.get(k, 0) + last.stats[k]
        for k, pick in (("h_min", min), ("h_max", max)):
            if k in last.stats:
                stats[k] = pick(stats.get(k, last.stats[k]), last.stats[k])
        keep = np.ones(last.t.size, dtype=bool)  # the outputs of [a, b) (and b at the end)
        if keep.size:
            keep[0] = bool(np.any(t == a))
        if not final and last.t.size == seg.size:
            keep[-1] = False  # b: the next segment's first row
        rows_t.append(last.t[keep])
        rows_y.append(last.y[keep])
        rows_out.append(np.column_stack([last.outputs[n][keep] for n in output_names])
                        if output_names else np.empty((int(keep.sum()), 0)))
        if last.sensitivities is not None:
            rows_s.append(last.sensitivities[keep])
        if last.status != 0:
            status, message = last.status, last.message
            break
    if last is None:
        raise LagcodegenError("Taylor with input tables: no segment was run")
    tt = np.concatenate(rows_t)
    yy = np.concatenate(rows_y)
    oo = np.concatenate(rows_out)
    stats.update(order=last.stats["order"], t_reached=last.stats["t_reached"], h_last=last.stats["h_last"],
                 model_error=last.stats["model_error"], restarts=int(edges.size - 2))
    res = Result(t=tt, y=yy, state_names=list(cm.state_names),
                 outputs={n: oo[:, j] for j, n in enumerate(output_names)}, stats=stats, status=status,
                 message=message, backend="native", method="taylor", n_coordinates=cm.n)
    if rows_s:
        res.set_sensitivities(last.sensitivity_names, last.sensitivity_values, np.concatenate(rows_s))
    return res
