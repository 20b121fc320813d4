"""Ensembles: N runs of one compiled simulation that differ in initial state and run-time
parameters, in ONE call into a native driver's ``*_solve_many`` (the runtime's ``lcg_cvode_solve_many``,
``lcg_cvc_solve_many``, ``lcg_ida_solve_many``, or a module's own, e.g. Taylor; lagcodegen/runtime/lcg_pool.h).

The members are spread over a pthread pool and taken in turn from a shared counter (their run
times differ); each member is a run of the single-run driver with its own SUNDIALS context, so its
numbers are bit-identical to the same run alone. A member that fails (step budget, singular mass
matrix, non-finite value, wall-clock limit) is data: its flag in ``status``, its message in
``messages``. Python sees arrays by member (:class:`EnsembleResult`); per member it pays no Python.

``executor=`` (any object with ``submit(fn, *args) -> future``: a ``concurrent.futures`` executor,
a ``dask.distributed.Client``) splits the members into chunks, runs each chunk as one ensemble call
on a worker (the compiled simulation is pickled by its generated sources and rebuilt there from
the worker's cache) and puts the results back by offset; a chunk that fails is retried once, then
its members are marked (flag -83) with the traceback as their message.
"""

from __future__ import annotations

import math
import traceback
from typing import Mapping

import numpy as np

from ..errors import LagcodegenError
from ..util import check_finite, output_times
from .base import LINEAR_SOLVERS, METHODS, native_options, tolerances
from .control import CHUNK_FAILED
from .cvode import band_widths
from .ensemble_result import FLAG_TEXT, REJECTED, EnsembleInterrupted, EnsembleResult  # noqa: F401 - public names
from .ida import ALGEBRAIC_ATOL
from .ensemble_run import _members, _matrix, _param_row, ode_states, parameter_matrix, run_native
from .ode import choose_method
from .taylor.ensemble import run_taylor_ensemble

#: Ensemble runners of the families other than CVODE, by method name (as :data:`.ode.FAMILIES`).
ENSEMBLE_FAMILIES = {"taylor": run_taylor_ensemble}


# ---------------------------------------------------------------------- the ODE of a compiled scene
def cvode_options(cm, y_probe, p_probe, *, method="adams", rtol=1e-8, atol=1e-10, jacobian=None,
                  max_steps=1_000_000, first_step=0.0, max_step=0.0, min_step=0.0, max_order=0,
                  linear_solver="dense", bandwidths=None, max_wall=0.0, keep=None):
    """The options struct of ``<prefix>_cvode_solve`` exactly as :func:`~lagcodegen.solvers.simulate`
    builds it for the same keywords (so that members are bit-identical to single runs)."""
    if method not in METHODS:
        raise LagcodegenError(f"method must be one of {', '.join([*METHODS, 'taylor', 'auto'])}, got {method!r}")
    if linear_solver not in LINEAR_SOLVERS:
        raise LagcodegenError(f"linear_solver must be one of {', '.join(LINEAR_SOLVERS)}, got {linear_solver!r}")
    rtol, atol_arr = tolerances(rtol, atol, cm.ny)
    if linear_solver == "fixedpoint":
        jacobian = False
    has_jac = cm.code.jacobian or bool(getattr(cm.code, "sparse_jacobian", False))
    if jacobian is None:
        jacobian = has_jac
    if jacobian and not has_jac:
        raise LagcodegenError("jacobian=True but the scene emits no Jacobian (Scene(jacobian=False))")
    band = band_widths(cm, bandwidths, y_probe, p_probe) if linear_solver == "band" else None
    keep = [] if keep is None else keep
    opt = native_options(cm.ffi, cm.options_type, atol_arr, keep, method=METHODS[method],
                         jacobian=int(bool(jacobian)), rtol=rtol, max_steps=int(max_steps), first_step=first_step,
                         max_step=max_step, min_step=min_step, max_order=max_order,
                         linear_solver=1 if band else 2 if linear_solver == "fixedpoint" else 0,
                         mupper=band[0] if band else 0, mlower=band[1] if band else 0)
    opt.max_wall = float(max_wall)
    return opt, keep


ODE_OPTIONS = ("method", "rtol", "atol", "jacobian", "max_steps", "first_step", "max_step", "min_step", "max_order",
               "linear_solver", "bandwidths", "order", "solver", "backend", "raise_on_error")


def ensemble_ode(cm, t, q0=None, v0=None, *, y0=None, z0=None, params=None, threads=None, save="final",
                 executor=None, progress=None, max_wall: float = 0.0, chunk_size=None, **options) -> EnsembleResult:
    """:meth:`CompiledModel.ensemble`: see :func:`ensemble` for the arguments."""
    unknown = [k for k in options if k not in ODE_OPTIONS]
    if unknown:
        raise LagcodegenError(f"ensemble: unknown options {', '.join(unknown)}")
    solver = options.pop("solver", None)
    if solver is not None:
        options = {**solver.keywords(), **options}
    if options.pop("backend", "native") != "native":
        raise LagcodegenError("ensembles run on the native drivers (backend='native')")
    options.pop("raise_on_error", None)
    t = output_times(t)
    n_mem, Y, P = ode_states(cm, q0, v0, y0, z0, params)
    if executor is not None:
        return run_chunks(cm, executor, chunk_size, n_mem, t, dict(y0=Y), P, threads, save, max_wall, options)
    method = options.get("method", "adams")
    if method == "auto":
        method = options["method"] = choose_method(cm.n, float(options.get("rtol", 1e-8)))
    family = ENSEMBLE_FAMILIES.get(method)
    if family is not None:
        return family(cm, t, Y, P, threads=threads, save=save, progress=progress, max_wall=max_wall, **options)
    options.pop("order", None)
    if not cm.native or cm.native_solve_many is None:
        raise LagcodegenError("this module was built without the native driver (build(native=False))")
    opt, keep = cvode_options(cm, Y[0], _param_row(P, 0), max_wall=max_wall, **options)
    return run_native(cm.ffi, cm.native_solve_many, cm.ensemble_type, opt, t=t, Y0=Y, P=P,
                      nrow=cm.ny, nout=cm.code.nout, state_names=cm.state_names, output_names=cm.output_names,
                      row_names=cm.state_names, save=save, threads=threads, progress=progress, poll=cm.poll,
                      method=options.get("method", "adams"), n_coordinates=cm.n, param_names=cm.param_names)


# ---------------------------------------------------------------------- executors (Dask, process pools)
def _run_chunk(sim, t, inputs: dict, P, threads, save, max_wall, options):
    """One chunk on a worker: an ensemble call of ``sim`` (rebuilt from its sources there)."""
    return sim.ensemble(t, params=P, threads=threads, save=save, max_wall=max_wall, progress=False, **inputs,
                        **options)


def run_chunks(sim, executor, chunk_size, n_mem: int, t, inputs: dict, P, threads, save, max_wall, options,
               retries: int = 1) -> EnsembleResult:
    """The members split into chunks, each an ensemble call submitted to ``executor``; the results
    put back by offset. A chunk that raises is resubmitted ``retries`` times, then its members get
    flag -83 and the traceback as message."""
    if chunk_size is None:
        chunk_size = max(1, min(10_000, math.ceil(n_mem / 8)))
    chunk_size = int(chunk_size)
    threads = 1 if threads is None else threads  # executors run one worker per core
    starts = list(range(0, n_mem, chunk_size))
    payload = sim
    if len(starts) > 1 and callable(getattr(executor, "scatter", None)):
        # a dask.distributed Client: the simulation goes to each worker once (its generated
        # sources, sometimes its sympy scene), not once per chunk
        payload = executor.scatter(sim, broadcast=True)

    def args(s):
        sl = slice(s, min(s + chunk_size, n_mem))
        chunk_inputs = {k: np.ascontiguousarray(v[sl]) if isinstance(v, np.ndarray) else v
                        for k, v in inputs.items()}
        Pc = P if P.ndim == 1 else np.ascontiguousarray(P[sl])
        return (payload, t, chunk_inputs, Pc, threads, save, max_wall, options)

    futures = {s: executor.submit(_run_chunk, *args(s)) for s in starts}
    parts, failures = [], {}
    for s in starts:
        fut, tries = futures[s], 0
        while True:
            try:
                part = fut.result()
                break
            except KeyboardInterrupt:
                for f in futures.values():
                    try:
                        f.cancel()
                    except Exception:  # noqa: BLE001 - best effort
                        pass
                raise
            except Exception:  # noqa: BLE001 - a failed chunk is data, retried first
                if tries < retries:
                    tries += 1
                    fut = executor.submit(_run_chunk, *args(s))
                    continue
                failures[s] = traceback.format_exc()
                part = None
                break
        if part is not None:
            parts.append((np.arange(s, s + len(part)), part))
    if not parts:
        raise LagcodegenError("every chunk of the ensemble failed:\n" + next(iter(failures.values())))
    out = EnsembleResult.assemble(n_mem, parts, parts[0][1], params=P)
    for s, tb in failures.items():
        idx = np.arange(s, min(s + chunk_size, n_mem))
        out.status[idx] = CHUNK_FAILED
        for i in idx.tolist():
            out.messages[i] = f"{FLAG_TEXT[CHUNK_FAILED]}:\n{tb}"
    out.chunk_size = chunk_size
    return out


# ---------------------------------------------------------------------- constrained systems
CONSTRAINED_OPTIONS = ("rtol", "atol", "method", "baumgarte", "projection", "initial", "ic_tol", "max_steps",
                       "first_step", "max_step", "min_step", "max_order", "events", "max_events", "suppress_alg",
                       "alg_atol", "jacobian", "stop_at_outputs", "proj_tol", "proj_maxit", "backend",
                       "raise_on_error")


def _qv(sim, q0, v0, params) -> tuple[int, np.ndarray, np.ndarray, np.ndarray]:
    names = [q.name for q in sim.system.model.coords]
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
    V = np.zeros((n_mem, n)) if v0 is None else _matrix(v0, n_mem, n, "v0", names)
    return n_mem, Q, V, names


def ensemble_constrained(sim, t, q0=None, v0=None, *, params=None, threads=None, save="final", executor=None,
                         progress=None, max_wall: float = 0.0, chunk_size=None, **options) -> EnsembleResult:
    """:meth:`ConstrainedSimulation.ensemble` (index-1 on CVODE, GGL on IDA): every member's initial
    state is checked (or projected) as :meth:`~ConstrainedSimulation.simulate` does; a member whose
    initial state is rejected gets flag -84 and the reason as its message, and is not run."""
    unknown = [k for k in options if k not in CONSTRAINED_OPTIONS]
    if unknown:
        raise LagcodegenError(f"ensemble: unknown options {', '.join(unknown)}")
    if options.pop("backend", "native") != "native":
        raise LagcodegenError("ensembles run on the native drivers (backend='native')")
    options.pop("raise_on_error", None)
    t = output_times(t)
    n_mem, Q, V, names = _qv(sim, q0, v0, params)
    P = parameter_matrix(sim.compiled._defaults, list(sim.param_names), params, n_mem)
    if executor is not None:
        return run_chunks(sim, executor, chunk_size, n_mem, t, dict(q0=Q, v0=V), P, threads, save, max_wall,
                          options)
    o = dict(rtol=1e-8, atol=1e-10, method=None, baumgarte=None, projection=None, initial="check", ic_tol=1e-8,
             max_steps=1_000_000, first_step=0.0, max_step=0.0, min_step=0.0, max_order=0, events=True,
             max_events=64, suppress_alg=True, alg_atol=None, jacobian=None, stop_at_outputs=False,
             proj_tol=1e-12, proj_maxit=10)
    o.update(options)
    ggl = sim.formulation == "ggl"
    n, t0 = sim.n, float(t[0])
    rows, rejected = [], {}
    for i in range(n_mem):
        p_i = _param_row(P, i)
        try:
            y0 = sim.consistent_initial_state(t0, Q[i], V[i], p_i, initial=o["initial"], ic_tol=o["ic_tol"])
            if ggl:
                yy0, yp0 = sim._ggl_initial(t0, y0, p_i)
                rows.append(np.concatenate([yy0, yp0]))
            else:
                sim.kkt(t0, y0, p_i)
                rows.append(y0)
        except LagcodegenError as exc:
            rejected[i] = f"{FLAG_TEXT[REJECTED]}: {exc}"
    valid = np.array([i for i in range(n_mem) if i not in rejected], dtype=np.int64)
    width = 2 * sim.info.ng if ggl else 2 * n
    Y = np.ascontiguousarray(np.array(rows).reshape(len(valid), width))
    Pv = P if P.ndim == 1 else np.ascontiguousarray(P[valid])
    roots = bool(o["events"]) and len(sim.info.events) > 0
    evs = sim.info.events
    events = (np.array([e.direction for e in evs] or [0], dtype=np.intc),
              np.array([1 if e.terminal else 0 for e in evs] or [0], dtype=np.intc))
    ffi, keep = sim.ffi, []
    poll = sim.compiled.poll
    common = dict(max_steps=int(o["max_steps"]), first_step=o["first_step"], max_step=o["max_step"],
                  min_step=o["min_step"], max_order=o["max_order"], roots=int(roots), max_wall=float(max_wall))
    if not ggl:
        projection = sim.projection if o["projection"] is None else bool(o["projection"])
        alpha, beta = sim._stabilization(o["baumgarte"], projection, t0, None, None)  # "auto": per member, in C
        method = o["method"] or ("bdf" if projection else "adams")
        if method not in METHODS:
            raise LagcodegenError(f"method must be one of {', '.join(METHODS)}, got {method!r}")
        if projection and method != "bdf":
            raise LagcodegenError("projection onto the constraints (CVodeSetProjFn) needs method='bdf'")
        rtol, atol_arr = tolerances(o["rtol"], o["atol"], 2 * n)
        opt = native_options(ffi, sim.cvc_options_type, atol_arr, keep, method=METHODS[method], rtol=rtol,
                             alpha=float(alpha), beta=float(beta), projection=int(projection),
                             proj_tol=o["proj_tol"], proj_maxit=o["proj_maxit"], proj_err=1, **common)
        fn, ens_type, nrow = sim.cvc_solve_many, sim.cvc_ensemble_type, 2 * n
        Y0, YP0, extra, row_names = Y, None, {}, list(sim.state_names)
    else:
        if o["method"] not in (None, "bdf"):
            raise LagcodegenError("IDA integrates with BDF only (method='bdf')")
        method = "bdf"
        jacobian = sim.info.ggl_jac if o["jacobian"] is None else bool(o["jacobian"])
        if jacobian and not sim.info.ggl_jac:
            raise LagcodegenError("jacobian=True but the residual Jacobian was not generated")
        ng = sim.info.ng
        rtol, atol_arr = tolerances(o["rtol"], o["atol"], ng, 2 * n)
        if np.asarray(o["atol"]).size != ng:
            atol_arr[2 * n:] = ALGEBRAIC_ATOL if o["alg_atol"] is None else check_finite(o["alg_atol"], "alg_atol")
        opt = native_options(ffi, sim.ida_options_type, atol_arr, keep, rtol=rtol,
                             suppress_alg=int(bool(o["suppress_alg"])), jacobian=int(jacobian), calc_ic=1,
                             ic_alg_atol=ALGEBRAIC_ATOL, stop_at_outputs=int(bool(o["stop_at_outputs"])), **common)
        fn, ens_type, nrow = sim.ida_solve_many, sim.ida_ensemble_type, ng
        Y0, YP0 = np.ascontiguousarray(Y[:, :ng]), np.ascontiguousarray(Y[:, ng:])
        J, JH = sim.info.J, sim.info.JH
        row_names = list(sim.state_names) + [f"_lambda_{j}" for j in range(J)] + [f"mu_{k}" for k in range(JH)]
        extra = {f"mu_{k}": 2 * n + J + k for k in range(JH)}
    part = run_native(ffi, fn, ens_type, opt, t=t, Y0=Y0, P=Pv, nrow=nrow, nout=len(sim.info.output_names),
                      state_names=sim.state_names, output_names=sim.output_names, row_names=row_names, save=save,
                      threads=threads, progress=progress, poll=poll, YP0=YP0, events=events,
                      max_events=int(o["max_events"]), extra_outputs=extra, method=method,
                      formulation=sim.formulation, n_coordinates=n, param_names=sim.param_names)
    if not rejected:
        return part
    out = EnsembleResult.assemble(n_mem, [(valid, part)], part, params=P)
    for i, text in rejected.items():
        out.status[i] = REJECTED
        out.messages[i] = text
    return out


def ensemble_minimal(sim, t, q0=None, v0=None, *, params=None, threads=None, save="final", executor=None,
                     progress=None, max_wall: float = 0.0, chunk_size=None, initial: str = "check",
                     ic_tol: float = 1e-8, **options) -> EnsembleResult:
    """:meth:`MinimalSimulation.ensemble`: members grouped by the solution branch of the
    constraints their initial state lies on (one ensemble call per branch); the outputs
    ``residuals``/``g_*``/``gdot_*`` computed in Python by :meth:`MinimalSimulation.simulate` are
    not part of ensembles."""
    for key in ("baumgarte", "projection", "suppress_alg", "events"):
        options.pop(key, None)
    t = output_times(t)
    n_mem, Q, V, names = _qv(sim, q0, v0, params)
    model = sim.system.model
    pnames = list(sim.param_names)
    defaults = {s.name: v_ for s, v_ in model.params.items()}
    base = np.array([float({**defaults, **sim._values}[k]) for k in pnames])
    P = parameter_matrix(base, pnames, params, n_mem)
    if executor is not None:
        return run_chunks(sim, executor, chunk_size, n_mem, t, dict(q0=Q, v0=V, initial=initial, ic_tol=ic_tol), P,
                          threads, save, max_wall, options)
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
    for b in sorted(set(branch.tolist()) - {-1}):
        idx = np.flatnonzero(branch == b)
        cm = sim.compiled_branch(b)
        keep_idx = [model.index(qr) for qr in sim.remaining]
        Pb = P if P.ndim == 1 else P[idx]
        Pcm = np.ascontiguousarray(Pb[..., [pnames.index(k) for k in cm.param_names]])
        part = cm.ensemble(t, q0=Q[idx][:, keep_idx], v0=V[idx][:, keep_idx], params=Pcm, threads=threads, save=save,
                           progress=progress, max_wall=max_wall, **{"method": "adams", **options})
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
