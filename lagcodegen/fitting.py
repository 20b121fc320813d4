"""Fitting run-time parameters (and initial values) of a compiled model to measured trajectories:
nonlinear least squares (``scipy.optimize.least_squares``, trust-region reflective) with the exact
Jacobian of the residuals from the forward sensitivities
(:mod:`lagcodegen.solvers.cvode.sensitivity`), one run with sensitivities per experiment and
iterate.

Residuals r = (model(t_i; theta) - data_i) / sigma_i stacked over the observed names and the
experiments; at the optimum the covariance is s^2 (J^T J)^-1 with s^2 = SSR / (m - n_theta) and
the standard errors its diagonal's square roots. A near-singular J^T J (parameters the data do not
identify) shows in ``FitResult.condition``.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Mapping, Sequence

import numpy as np

from .errors import LagcodegenError, SolverError


@dataclass
class FitResult:
    """The estimates (``params``, by name), their standard errors (``stderr``) and covariance
    (``cov``, in the order of ``names``), the residuals at the optimum (stacked: experiments, then
    observed names, then times), ``iterations`` (Jacobian evaluations of the trust-region method),
    ``cost_history`` (0.5 SSR at every evaluation of the residuals), ``condition`` (of J^T J), the
    optimizer's ``status``/``message``, ``nfev``, the wall time, and ``stationarity`` (the largest
    cosine between the residuals and a column of the Jacobian at the estimates: 0 at a minimum).
    :attr:`converged` says whether the estimates are a minimum of the least squares."""

    names: list
    params: dict
    stderr: dict
    cov: np.ndarray
    residuals: np.ndarray
    iterations: int
    nfev: int
    cost: float
    cost_history: list
    condition: float
    status: int
    message: str
    success: bool
    wall_time: float = 0.0
    residual_variance: float = 0.0
    stationarity: float = 0.0
    experiments: list = field(default_factory=list, repr=False)

    @property
    def converged(self) -> bool:
        """Whether the optimizer stopped on one of its tolerances (not on ``max_nfev``) at a
        stationary point: ``stationarity`` at most :data:`STATIONARITY`. A fit whose model cannot
        follow the data (a cost that no step lowers by a relative ``ftol`` while the gradient is
        far from zero) is not converged."""
        return self.success and math.isfinite(self.cost) and self.stationarity <= STATIONARITY

    def __str__(self) -> str:
        rows = [f"{name} = {self.params[name]:.10g} +- {self.stderr[name]:.3g}" for name in self.names]
        status = "" if self.converged else "not converged: "
        return "\n".join(rows + [f"iterations {self.iterations}, cost {self.cost:.6g}, cond(J^T J) "
                                 f"{self.condition:.3g}: {status}{self.message}"])


#: The largest cosine between the residuals and a column of the Jacobian (``FitResult.stationarity``)
#: of a converged fit: where least_squares stops near a minimum on ftol = 1e-8 it is about
#: sqrt(ftol) = 1e-4; a model that cannot follow the data leaves it at several percent.
STATIONARITY = 1e-2


@dataclass
class _Experiment:
    t: np.ndarray
    data: np.ndarray
    sigma: np.ndarray
    start: dict


def _experiment(sim, observe, t, data, sigma, start) -> _Experiment:
    t = np.ascontiguousarray(np.asarray(t, dtype=float))
    if t.ndim != 1 or t.size < 2 or not np.all(np.diff(t) > 0) or not np.all(np.isfinite(t)):
        raise LagcodegenError("fit: t must be increasing finite times (at least two)")
    data = np.asarray(data, dtype=float)
    if data.ndim == 1 and len(observe) == 1:
        data = data[:, None]
    if data.shape != (t.size, len(observe)):
        raise LagcodegenError(f"fit: data must have shape (len(t), len(observe)) = {(t.size, len(observe))}, "
                              f"got {data.shape}")
    if not np.all(np.isfinite(data)):
        raise LagcodegenError("fit: data has non-finite values")
    sigma = np.broadcast_to(np.asarray(1.0 if sigma is None else sigma, dtype=float), data.shape).copy()
    if not np.all(sigma > 0):
        raise LagcodegenError("fit: sigma must be positive")
    return _Experiment(t, data, sigma, start)


#: least_squares' options by default: its stopping tolerances at 1e-8, the relative noise of the
#: residuals at simulate's default rtol (tighter ones only chase the integration error), and at
#: most 100 evaluations of the residuals.
LEAST_SQUARES = {"xtol": 1e-8, "ftol": 1e-8, "gtol": 1e-8, "max_nfev": 100}


def fit(sim, t=None, data=None, *, params: Mapping[str, float], observe: Sequence[str],
        sigma=None, bounds: Mapping[str, tuple] | None = None, experiments: Sequence[Mapping] | None = None,
        fixed: Mapping[str, float] | None = None, solver_options: Mapping | None = None,
        **options) -> FitResult:
    """Fit ``params`` (name -> starting value: run-time parameters of ``sim``, or initial values
    ``"<q>(0)"``/``"<q>_dot(0)"``) so that the ``observe``d states or outputs of ``sim`` match
    ``data`` (shape (len(t), len(observe))) at the times ``t`` (``t[0]`` the initial time of the
    run), weighted by 1/``sigma`` (a scalar, one per observed name, or data's shape).

    ``options``: those of ``sim.simulate``: the initial state (``q0``, ``v0`` or ``y0``), ``rtol``
    (1e-8), ``atol`` (1e-10), ``method``, ``max_steps``, ...

    ``sim`` may be a compiled constrained system (index-1 formulation or minimal coordinates):
    its initial state is ``q0``, ``v0`` of every coordinate, projected onto the constraints of
    each trial's parameters (``initial="project"`` unless given), and the sensitivities are those
    of that projected start (:mod:`lagcodegen.solvers.cvode.sensitivity_constrained`).

    ``experiments``: several runs fitted together, each a mapping with ``t``, ``data`` and any of
    ``q0``, ``v0``, ``y0`` (its initial state), ``sigma``, ``params`` (its own values of run-time
    parameters not fitted); then ``t``, ``data`` and the initial state are not given here.
    ``fixed``: values of other run-time parameters. ``bounds``: name -> (lower, upper).
    ``solver_options``: least_squares' options over :data:`LEAST_SQUARES` (``xtol``, ``ftol``,
    ``gtol``, ``max_nfev``, ...). Returns :class:`FitResult`.
    """
    from scipy.optimize import least_squares

    q0, v0, y0 = options.pop("q0", None), options.pop("v0", None), options.pop("y0", None)
    rtol, atol = options.pop("rtol", 1e-8), options.pop("atol", 1e-10)
    for key in ("params", "sensitivities", "raise_on_error"):
        if key in options:
            raise LagcodegenError(f"fit: {key!r} is set by the fit itself")
    ls_options = {**LEAST_SQUARES, **dict(solver_options or {})}
    names = list(params)
    if not names:
        raise LagcodegenError("fit: give at least one parameter to fit")
    observe = [observe] if isinstance(observe, str) else list(observe)
    if not observe:
        raise LagcodegenError("fit: observe at least one state or output")
    twice = sorted({o for o in observe if observe.count(o) > 1})
    if twice:  # the same values counted twice would shrink the standard errors by sqrt(2)
        raise LagcodegenError(f"fit: {', '.join(map(repr, twice))} observed more than once; observe each name once "
                              "(a repeated column counts the same measurements twice)")
    outputs = getattr(sim, "output_names", None)
    if outputs is None and hasattr(sim, "compiled_branch"):  # minimal coordinates: a branch's (all the same)
        outputs = sim.compiled_branch(0).output_names
    known = list(sim.state_names) + list(outputs or [])
    for name in observe:
        if name not in known:
            raise LagcodegenError(f"fit: {name!r} is neither a state nor an output of the model "
                                  f"({', '.join(known)})")
    if experiments is None:
        if t is None or data is None:
            raise LagcodegenError("fit: give t and data (or experiments)")
        exps = [_experiment(sim, observe, t, data, sigma, dict(q0=q0, v0=v0, y0=y0, params={}))]
    else:
        if t is not None or data is not None or q0 is not None or v0 is not None or y0 is not None:
            raise LagcodegenError("fit: with experiments, give t, data and initial states in each experiment")
        exps = []
        for k, e in enumerate(experiments):
            unknown = set(e) - {"t", "data", "q0", "v0", "y0", "sigma", "params"}
            if unknown or "t" not in e or "data" not in e:
                raise LagcodegenError(f"fit: experiment {k} needs 't' and 'data' (and may have q0, v0, y0, sigma, "
                                      f"params){'; unknown: ' + ', '.join(sorted(unknown)) if unknown else ''}")
            exps.append(_experiment(sim, observe, e["t"], e["data"], e.get("sigma", sigma),
                                    dict(q0=e.get("q0"), v0=e.get("v0"), y0=e.get("y0"),
                                         params=dict(e.get("params", {})))))
    if _constrained(sim):  # every trial's initial state projected onto its constraints
        options.setdefault("initial", "project")
    fixed = dict(fixed or {})
    run_params = [n for n in names if n in sim.param_names]
    for n in fixed:
        if n not in sim.param_names:
            raise LagcodegenError(f"fit: fixed {n!r} is not a run-time parameter ({', '.join(sim.param_names)})")
        if n in names:
            raise LagcodegenError(f"fit: {n!r} is both fitted and fixed")
    x0 = np.array([float(params[n]) for n in names])
    if not np.all(np.isfinite(x0)):
        raise LagcodegenError("fit: starting values must be finite")
    lo, hi = np.full(x0.size, -np.inf), np.full(x0.size, np.inf)
    for n, (a, b) in (bounds or {}).items():
        if n not in names:
            raise LagcodegenError(f"fit: bounds given for {n!r}, which is not fitted ({', '.join(names)})")
        i = names.index(n)
        lo[i], hi[i] = (-np.inf if a is None else float(a)), (np.inf if b is None else float(b))
        if not lo[i] < hi[i] or not lo[i] <= x0[i] <= hi[i]:
            raise LagcodegenError(f"fit: bounds of {n!r} must satisfy lower < upper and hold the start "
                                  f"{x0[i]:g}, got ({a}, {b})")
    history: list = []
    cache: dict = {}
    prepared = _prepared_runs(sim, exps, names, rtol, atol, options)

    def simulated(k, e, initial, p, values):
        """(model values (nt, observe), their sensitivities (nt, names, observe)) of experiment k
        from the initial-state keywords ``initial`` (:func:`_start`)."""
        try:
            if prepared is not None:
                res = prepared[k](**initial, params=p)
            else:
                res = sim.simulate(e.t, **initial, params=p, rtol=rtol, atol=atol, sensitivities=names, **options)
        except SolverError as exc:
            raise LagcodegenError(f"fit: the run of experiment {k} failed at parameters "
                                  f"{values}: {exc}") from None
        columns = [res.sensitivity_values.index(o) for o in observe]
        return np.column_stack([res[o] for o in observe]), res.sensitivities[:, :, columns]

    def evaluate(x):
        key = x.tobytes()
        if key in cache:
            return cache[key]
        values = dict(zip(names, x))
        rs, js = [], []
        for k, e in enumerate(exps):
            p = {**e.start["params"], **fixed, **{n: values[n] for n in run_params}}
            q0_, v0_, y0_ = e.start["q0"], e.start["v0"], e.start["y0"]
            initial = _start(sim, q0_, v0_, y0_, values, names)
            model, sens = simulated(k, e, initial, p, values)
            rs.append(((model - e.data) / e.sigma).T.ravel())
            J = np.stack([sens[:, :, i] / e.sigma[:, [i]] for i in range(len(observe))])  # (observe, nt, names)
            js.append(J.reshape(-1, len(names)))
        r, J = np.concatenate(rs), np.vstack(js)
        history.append(0.5 * float(r @ r))
        if len(cache) >= 16:  # the optimizer asks for its best point again at the end: keep a few
            cache.pop(next(iter(cache)))
        cache[key] = (r, J)
        return r, J

    start = time.perf_counter()
    out = least_squares(lambda x: evaluate(x)[0], x0, jac=lambda x: evaluate(x)[1], bounds=(lo, hi),
                        **{"method": "trf", "x_scale": "jac", **ls_options})
    wall = time.perf_counter() - start
    r, J = evaluate(out.x)
    m, n = r.size, len(names)
    ssr = float(r @ r)
    s2 = ssr / (m - n) if m > n else math.nan
    JtJ = J.T @ J
    cond = float(np.linalg.cond(JtJ))
    try:
        cov = s2 * np.linalg.inv(JtJ)
    except np.linalg.LinAlgError:
        cov = np.full((n, n), np.inf)
    err = np.sqrt(np.clip(np.diag(cov), 0, None))
    stationarity = _stationarity(r, J, out.x, lo, hi)
    return FitResult(names=names, params=dict(zip(names, out.x.tolist())), stderr=dict(zip(names, err.tolist())),
                     cov=cov, residuals=r, iterations=int(out.njev or 0), nfev=int(out.nfev), cost=0.5 * ssr,
                     cost_history=history, condition=cond, status=int(out.status), message=str(out.message),
                     success=bool(out.success), wall_time=wall, residual_variance=s2, stationarity=stationarity,
                     experiments=exps)


def _constrained(sim) -> bool:
    """Whether ``sim`` is a compiled constrained system (index-1, GGL or minimal coordinates)."""
    return getattr(sim, "formulation", None) in ("index1", "ggl", "minimal") and hasattr(sim, "system")


def _start(sim, q0, v0, y0, values: dict, names: list) -> dict:
    """The initial-state keywords of an experiment's run with the fitted initial values of
    ``values`` put in: ``y0`` for the ODE of a scene; ``q0``, ``v0`` of every coordinate for a
    constrained system (projected onto the constraints by the run, ``initial="project"``)."""
    if not _constrained(sim):
        return {"y0": _initial(sim, q0, v0, y0, values, names)}
    from .util import state_values
    if y0 is not None:
        raise LagcodegenError("fit: give the initial state of a constrained system as q0 and v0 (every coordinate)")
    coords = [q.name for q in sim.system.model.coords]
    q = np.array(state_values(q0, coords, "q0"), dtype=float)
    v = np.array(state_values(v0, coords, "v0"), dtype=float)
    for d in _directions(names, list(sim.param_names), coords):
        if d.kind == "position":
            q[coords.index(d.target)] = values[d.name]
        elif d.kind == "velocity":
            v[coords.index(d.target)] = values[d.name]
    return {"q0": q, "v0": v}


def _directions(names: list, params: list, coords: list, states: list | None = None) -> list:
    """The fitted names as :class:`~lagcodegen.solvers.direction.Direction` values (parsed once
    here), with the fit's messages."""
    from .solvers.direction import Direction
    return [Direction.parse(name, params=params, coords=coords, states=states or (), what="fit") for name in names]


def _prepared_runs(sim, exps: list, names: list, rtol, atol, options: dict) -> list | None:
    """Per experiment, the run of the fit made explicit: ``sim.prepare(e.t, rtol=..., atol=...,
    sensitivities=names, **options)`` (:class:`~lagcodegen.simulation.prepared.PreparedRun`: the
    solver resolved and every option checked once; where the family prepares the run, its options
    struct, directions and arrays made once), each evaluation calling it with the trial's initial
    state and parameters, bit-identical to ``simulate``. None for a simulation without prepared
    runs (constrained systems): every evaluation then calls ``simulate``."""
    if _constrained(sim) or not hasattr(sim, "prepare"):
        return None
    return [sim.prepare(e.t, rtol=rtol, atol=atol, sensitivities=list(names), **options) for e in exps]


def _initial(sim, q0, v0, y0, values: dict, names: list) -> np.ndarray:
    """The initial state of an experiment with the fitted initial values of ``values`` put in."""
    from .solvers.base import initial_state
    y = np.array(initial_state(sim, q0, v0, y0, None), dtype=float)
    states = list(sim.state_names)
    coords = states[:sim.n]
    for d in _directions(names, list(sim.param_names), coords, states):
        if d.kind != "parameter":
            y[d.state_index(coords, states)] = values[d.name]
    return y


def _stationarity(r: np.ndarray, J: np.ndarray, x: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> float:
    """The largest cosine between the residuals and a column of the Jacobian: 0 at a minimum of
    the least squares (the residuals orthogonal to every direction the parameters can move the
    model in), about sqrt(ftol) where the optimizer stops near one, near 1 where the model
    cannot follow the data at all. 0 for zero residuals. A parameter at one of its bounds
    (``lo``, ``hi``; within 1e-6 (1 + |bound|)) whose descent direction leaves the range does
    not count: the minimum is on the bound."""
    rn = float(np.linalg.norm(r))
    if rn == 0.0:
        return 0.0
    g = J.T @ r  # the gradient of the cost; the cost falls along -g
    with np.errstate(invalid="ignore"):
        at_lo = np.isfinite(lo) & (x - lo <= 1e-6 * (1 + np.abs(lo))) & (g > 0)
        at_hi = np.isfinite(hi) & (hi - x <= 1e-6 * (1 + np.abs(hi))) & (g < 0)
    cols = np.linalg.norm(J, axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):
        cos = np.abs(g) / (cols * rn)
    cos = np.where((cols > 0) & ~at_lo & ~at_hi, cos, 0.0)
    return float(np.max(cos)) if cos.size else 0.0
