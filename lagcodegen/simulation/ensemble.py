"""Ensembles of the faces: the per-member inputs as arrays (states, run-time parameters), each
member's initial state checked as the face's ``simulate`` checks it (constrained systems:
projected, rejected members kept as data; minimal coordinates: grouped by solution branch), and
the call of the family's ensemble runner (the family resolved once, as ``simulate`` resolves it,
by :func:`lagcodegen.solvers.registry.resolve`).

The members are spread over a pthread pool in C (:mod:`lagcodegen.solvers.ensemble_run`), each a
run of the single-run driver with its own SUNDIALS context, so its numbers are bit-identical to
the same run alone; ``executor=`` splits them into chunks (:func:`lagcodegen.solvers.ensemble.run_chunks`).
"""

from __future__ import annotations

from typing import Mapping

import numpy as np

from ..errors import LagcodegenError
from ..solvers.ensemble import run_chunks
from ..solvers.ensemble_result import FLAG_TEXT, REJECTED, EnsembleResult
from ..solvers.family import Members, Problem, Request
from ..solvers.inputs import member_sets
from ..solvers.registry import resolve
from ..solvers.request import Recording
from ..util import output_times


def run_keywords(options: dict) -> tuple:
    """(solver, rtol, atol, events, the family's options) of an ensemble's keywords: those that
    simulate() takes by name, the rest for the family object."""
    options = dict(options)
    options.pop("raise_on_error", None)  # an ensemble's failures are data
    return (options.pop("solver", None), options.pop("rtol", 1e-8), options.pop("atol", 1e-10),
            options.pop("events", None), options)


def _members(*arrays) -> int:
    """N from the leading dimension of the per-member inputs (2-D states, 1-D parameters)."""
    sizes = {a.shape[0] for a, per_member_ndim in arrays if a is not None and a.ndim == per_member_ndim}
    if len(sizes) > 1:
        raise LagcodegenError(f"the ensemble inputs disagree on the number of members: {sorted(sizes)}")
    if 0 in sizes:
        raise LagcodegenError("the ensemble has no members: its per-member inputs (q0, v0, y0, params) have 0 rows; "
                              "give at least one member")
    return sizes.pop() if sizes else 1


def _matrix(x, n: int, width: int, what: str, names) -> np.ndarray:
    """(n, width) float array of per-member values: ``x`` (n, width), (width,) shared, or a mapping
    name -> (n,) / scalar."""
    if isinstance(x, Mapping):
        unknown = [k for k in x if k not in names]
        if unknown:
            raise LagcodegenError(f"{what}: unknown names {', '.join(map(repr, unknown))} "
                                  f"(expected {', '.join(names)})")
        missing = [k for k in names if k not in x]
        if missing:
            raise LagcodegenError(f"{what}: missing {', '.join(missing)}")
        x = np.column_stack([np.broadcast_to(np.asarray(x[k], dtype=float), (n,)) for k in names]) if names \
            else np.zeros((n, 0))
    try:
        arr = np.asarray(x, dtype=float)
    except (TypeError, ValueError):
        raise LagcodegenError(f"{what} must be an array of numbers") from None
    if arr.ndim == 1 and arr.size == width:
        arr = np.broadcast_to(arr, (n, width))
    if arr.shape != (n, width):
        raise LagcodegenError(f"{what} has shape {arr.shape}, expected ({n}, {width}) or ({width},): "
                              f"{', '.join(names)}")
    if not np.isfinite(arr).all():
        bad = np.argwhere(~np.isfinite(arr))[0]
        raise LagcodegenError(f"{what}: non-finite value for member {bad[0]} ({names[bad[1]]})")
    return np.ascontiguousarray(arr)


def parameter_matrix(defaults: np.ndarray, names: list, params, n: int) -> np.ndarray:
    """Run-time parameters by member: (np,) when every member has the defaults or the same values,
    else (n, np). ``params``: None, a mapping name -> scalar or (n,) array, or an (n, np) array."""
    if params is None:
        return defaults.copy()
    if not isinstance(params, Mapping):
        return _matrix(params, n, len(names), "params", names)
    unknown = [k for k in params if k not in names]
    if unknown:
        raise LagcodegenError(f"{', '.join(map(repr, unknown))} is not a run-time parameter "
                              f"(run-time parameters: {', '.join(names) or 'none'})")
    if all(np.ndim(v) == 0 for v in params.values()):
        p = defaults.copy()
        for k, v in params.items():
            p[names.index(k)] = float(v)
        if not np.isfinite(p).all():
            raise LagcodegenError("params: non-finite value")
        return p
    P = np.array(np.broadcast_to(defaults, (n, len(names))))
    for k, v in params.items():
        v = np.asarray(v, dtype=float)
        if v.ndim > 1 or (v.ndim == 1 and v.shape[0] != n):
            raise LagcodegenError(f"parameter {k!r}: expected a scalar or {n} values, got shape {v.shape}")
        P[:, names.index(k)] = v
    if not np.isfinite(P).all():
        bad = np.argwhere(~np.isfinite(P))[0]
        raise LagcodegenError(f"params: non-finite value for member {bad[0]} ({names[bad[1]]})")
    return P


def _param_row(P: np.ndarray, i: int) -> np.ndarray:
    return P if P.ndim == 1 else P[i]


def ode_states(cm, q0, v0, y0, z0, params) -> tuple[int, np.ndarray, np.ndarray]:
    """(N, Y0 (N, ny), P) of an ensemble of the ODE of ``cm``."""
    arrs = [(None if x is None or isinstance(x, Mapping) else np.asarray(x, dtype=float), 2)
            for x in (q0, v0, y0, z0)]
    pn = None
    if isinstance(params, Mapping):
        lens = {np.shape(v)[0] for v in params.values() if np.ndim(v) == 1}
        pn = (np.zeros(lens.pop()), 1) if len(lens) == 1 else None
    elif params is not None:
        pn = (np.asarray(params, dtype=float), 2)
    for x in (q0, v0, z0):
        if isinstance(x, Mapping):
            lens = {np.shape(v)[0] for v in x.values() if np.ndim(v) == 1}
            if lens:
                arrs.append((np.zeros(lens.pop()), 1))
    n_mem = _members(*arrs, *([pn] if pn else []))
    n, names = cm.n, cm.state_names
    if y0 is not None:
        if q0 is not None or v0 is not None or z0 is not None:
            raise LagcodegenError("give either y0 or q0/v0, not both")
        Y = _matrix(y0, n_mem, cm.ny, "y0", names)
    else:
        if q0 is None:
            raise LagcodegenError("q0 (or y0) is required")
        nv = getattr(cm, "nv", n)  # generalized speeds: v0 by their names
        parts = [_matrix(q0, n_mem, n, "q0", names[:n]),
                 np.zeros((n_mem, nv)) if v0 is None else _matrix(v0, n_mem, nv, "v0",
                                                                  names[:n] if cm.code.nv is None else names[n:n + nv])]
        nz = cm.ny - n - nv
        if nz:
            parts.append(np.zeros((n_mem, nz)) if z0 is None else _matrix(z0, n_mem, nz, "z0", names[n + nv:]))
        Y = np.ascontiguousarray(np.hstack(parts))
    P = parameter_matrix(cm._defaults, list(cm.param_names), params, n_mem)
    return n_mem, Y, P



# ---------------------------------------------------------------------- the ODE of a compiled scene
def ensemble_ode(cm, t, q0=None, v0=None, *, y0=None, z0=None, params=None, recording: Recording,
                 executor=None, chunk_size=None, options: dict) -> EnsembleResult:
    """:meth:`CompiledModel.ensemble <lagcodegen.simulation.ode.CompiledModel.ensemble>`
    (``recording``: its ``save``, ``threads`` and ``progress``; ``options`` the run's keywords,
    ``inputs`` among them)."""
    threads, save, progress = recording.threads, recording.save, recording.progress
    options = dict(options)
    inputs = options.pop("inputs", None)
    solver, rtol, atol, events, options = run_keywords(options)
    t = output_times(t)
    n_mem, Y, P = ode_states(cm, q0, v0, y0, z0, params)
    family = resolve("ode", solver, options, cm.method_size, float(rtol), runs="ensemble",
                     costs=cm.method_costs)
    sets = member_sets(cm.code.input_names, cm.param_names, inputs, n_mem, cm.code.model_name,
                       params=params)
    request = Request(events=tuple(events or ()), inputs=sets, members=Members(threads, save, progress))
    if sets is not None and executor is not None:
        raise LagcodegenError("ensembles with input tables run in this process (executor= is not supported)")
    family.check("ode", request)  # refused here, before any chunk is sent
    if executor is not None:
        more = {"events": list(events)} if events else {}
        return run_chunks(cm, executor, chunk_size, n_mem, t, dict(y0=Y), P, threads, save,
                          dict(solver=family, rtol=rtol, atol=atol, **more))
    return family.run("ode", Problem(cm, rtol, atol, t, Y, P), request)


# ---------------------------------------------------------------------- constrained systems
def _qv(sim, q0, v0, params) -> tuple[int, np.ndarray, np.ndarray, np.ndarray]:
    model = sim.system.model
    names = [q.name for q in model.coords]
    speeds = [v.name for v in model.v] if model.general else names  # generalized speeds: v0 by their names
    n = len(names)
    arrs = [(None if x is None or isinstance(x, Mapping) else np.asarray(x, dtype=float), 2) for x in (q0, v0)]
    if isinstance(params, Mapping):
        lens = {np.shape(v)[0] for v in params.values() if np.ndim(v) == 1}
        if len(lens) == 1:
            arrs.append((np.zeros(lens.pop()), 1))
    elif params is not None:
        arrs.append((np.asarray(params, dtype=float), 2))
    n_mem = _members(*arrs)
    if q0 is None:
        raise LagcodegenError("q0 is required")
    Q = _matrix(q0, n_mem, n, "q0", names)
    V = np.zeros((n_mem, len(speeds))) if v0 is None else _matrix(v0, n_mem, len(speeds), "v0", speeds)
    return n_mem, Q, V, names


def ensemble_constrained(sim, t, q0=None, v0=None, *, params=None, recording: Recording, executor=None,
                         chunk_size=None, initial="check", ic_tol=1e-8, options: dict) -> EnsembleResult:
    """:meth:`ConstrainedSimulation.ensemble <lagcodegen.simulation.constrained.ConstrainedSimulation.ensemble>`
    (index-1 on CVODE, GGL on IDA; ``recording``: its ``save``, ``threads`` and ``progress``):
    every member's initial state is checked (or projected) as ``simulate`` does; a member whose
    initial state is rejected gets flag -84 and the reason as its message, and is not run."""
    threads, save, progress = recording.threads, recording.save, recording.progress
    solver, rtol, atol, events, options = run_keywords(options)
    family = resolve(sim.formulation, solver, options, runs="ensemble")
    roots = sim._roots(events)
    t = output_times(t)
    n_mem, Q, V, names = _qv(sim, q0, v0, params)
    P = parameter_matrix(sim.compiled._defaults, list(sim.param_names), params, n_mem)
    if executor is not None:
        return run_chunks(sim, executor, chunk_size, n_mem, t, dict(q0=Q, v0=V), P, threads, save,
                          dict(solver=family, rtol=rtol, atol=atol, events=events, initial=initial, ic_tol=ic_tol))
    ggl = sim.formulation == "ggl"
    t0 = float(t[0])
    rows, rejected = [], {}
    for i in range(n_mem):
        p_i = _param_row(P, i)
        try:
            y0 = sim.consistent_initial_state(t0, Q[i], V[i], p_i, initial=initial, ic_tol=ic_tol)
            if ggl:
                yy0, yp0 = sim._ggl_initial(t0, y0, p_i)
                rows.append(np.concatenate([yy0, yp0]))
            else:
                sim.kkt(t0, y0, p_i)
                rows.append(y0)
        except LagcodegenError as exc:
            rejected[i] = f"{FLAG_TEXT[REJECTED]}: {exc}"
    valid = np.array([i for i in range(n_mem) if i not in rejected], dtype=np.int64)
    width = 2 * sim.info.ng if ggl else sim.ny
    Y = np.ascontiguousarray(np.array(rows).reshape(len(valid), width))
    Pv = P if P.ndim == 1 else np.ascontiguousarray(P[valid])
    part = family.run(sim.formulation, Problem(sim, rtol, atol, t, Y, Pv),
                      Request(roots=roots, members=Members(threads, save, progress)))
    if not rejected:
        return part
    out = EnsembleResult.assemble(n_mem, [(valid, part)], part, params=P)
    for i, text in rejected.items():
        out.status[i] = REJECTED
        out.messages[i] = text
    return out


def ensemble_minimal(sim, t, q0=None, v0=None, *, params=None, recording: Recording, executor=None,
                     chunk_size=None, initial="check", ic_tol=1e-8, options: dict) -> EnsembleResult:
    """:meth:`MinimalSimulation.ensemble <lagcodegen.simulation.minimal.MinimalSimulation.ensemble>`
    (``recording``: its ``save``, ``threads`` and ``progress``): members grouped by the solution
    branch of the constraints their initial state lies on (one ensemble call per branch); the
    outputs ``residuals``/``g_*``/``gdot_*`` computed in Python by ``simulate`` are not part of
    ensembles."""
    threads, save, progress = recording.threads, recording.save, recording.progress
    roots = sim.check_events(options.get("events"))
    t = output_times(t)
    n_mem, Q, V, names = _qv(sim, q0, v0, params)
    model = sim.system.model
    pnames = list(sim.param_names)
    defaults = {s.name: v_ for s, v_ in model.params.items()}
    base = np.array([float({**defaults, **sim._values}[k]) for k in pnames])
    P = parameter_matrix(base, pnames, params, n_mem)
    if executor is not None:
        return run_chunks(sim, executor, chunk_size, n_mem, t, dict(q0=Q, v0=V), P, threads, save,
                          dict(options, initial=initial, ic_tol=ic_tol))
    branch = np.full(n_mem, -1)
    rejected = {}
    for i in range(n_mem):
        p_i = _param_row(P, i)
        vals = {**defaults, **sim._values, **dict(zip(pnames, (float(x) for x in p_i)))}
        try:
            if initial == "check":
                sim.system.check_initial(Q[i], V[i], vals, t0=float(t[0]), tol=ic_tol)
            branch[i] = sim._branch_for(Q[i], float(t[0]), vals, ic_tol if initial == "check" else np.inf)
        except LagcodegenError as exc:
            rejected[i] = f"{FLAG_TEXT[REJECTED]}: {exc}"
    parts, like = [], None
    ode_options = {k: v for k, v in options.items() if k != "events"}
    if roots:
        ode_options["events"] = sim.events
    for b in sorted(set(branch.tolist()) - {-1}):
        idx = np.flatnonzero(branch == b)
        cm = sim.compiled_branch(b)
        keep_idx = [model.index(qr) for qr in sim.remaining]
        Pb = P if P.ndim == 1 else P[idx]
        Pcm = np.ascontiguousarray(Pb[..., [pnames.index(k) for k in cm.param_names]])
        part = cm.ensemble(t, q0=Q[idx][:, keep_idx], v0=V[idx][:, keep_idx], params=Pcm, threads=threads, save=save,
                           progress=progress, **ode_options)
        part.formulation = "minimal"
        parts.append((idx, part))
        like = like or part
    if like is None:
        raise LagcodegenError("no member of the ensemble has a usable initial state:\n" + next(iter(rejected.values())))
    out = EnsembleResult.assemble(n_mem, parts, like, params=P)
    out.param_names = pnames
    for i, text in rejected.items():
        out.status[i] = REJECTED
        out.messages[i] = text
    return out
