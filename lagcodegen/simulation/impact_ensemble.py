"""Ensembles of constrained systems with contacts (inequalities with a restitution, sec. 4.3):
each member one call of the system's impact driver (index-1: lagcodegen/runtime/lcg_imp.c on
CVODE; GGL: lagcodegen/runtime/lcg_imp_ida.c on IDA; Coulomb friction included), through
:meth:`ConstrainedSimulation.run_contacts <lagcodegen.simulation.constrained.ConstrainedSimulation>`,
as ``simulate`` makes it, the members spread over a pool of threads (the driver releases the
GIL; every call has its own SUNDIALS context), so each member is bit-identical to its single run.

As in the other ensembles, every member keeps its records: its events
(``EnsembleResult.member(i).events``, at most ``max_events`` as its single run keeps them: 10000
by default; stats ``events`` counts every event found, ``events_dropped`` those beyond) and its contact log (``.impacts``: every impact, switch to
persistent contact and release, :class:`~.constrained_impacts.ContactLog`). ``executor=`` splits
the members into chunks as the other ensembles do (:func:`lagcodegen.solvers.ensemble.run_chunks`;
a Dask client among them), their records carried back with their results. Ctrl-C stops the
running members (flag -80) and raises :class:`~lagcodegen.solvers.ensemble_result.EnsembleInterrupted`
with what finished.
"""

from __future__ import annotations

import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from ..errors import LagcodegenError, ModelError, SolverError
from ..solvers.control import CANCELLED, NOT_RUN, Progress
from ..solvers.ensemble import run_chunks
from ..solvers.ensemble_result import COUNT_NAMES, FLAG_TEXT, REJECTED, EnsembleInterrupted, EnsembleResult
from ..solvers.ensemble_run import default_threads, saved_columns
from ..solvers.family import Problem, Request
from ..solvers.registry import resolve
from ..solvers.request import Recording
from ..util import output_times
from .constrained_impacts import ContactOptions
from .ensemble import _param_row, _qv, parameter_matrix, run_keywords

#: The per-member counters of :data:`COUNT_NAMES` read from a member's ``Result.stats``.
_STAT_OF = {"steps": "steps", "rhs_evals": "rhs_evals", "jac_evals": "jac_evals",
            "err_test_fails": "err_test_fails", "nonlin_conv_fails": "nonlin_conv_fails", "model_error": "model_error"}


def ensemble_contacts(sim, t, q0=None, v0=None, *, params=None, recording: Recording, executor=None,
                      chunk_size=None, initial="check", ic_tol=1e-8, options: dict) -> EnsembleResult:
    """:meth:`ConstrainedSimulation.ensemble <lagcodegen.simulation.constrained.ConstrainedSimulation.ensemble>`
    of a system with contacts: ``options`` are simulate's (``contacts=`` a
    :class:`~.constrained_impacts.ContactOptions` among them); a member whose initial state is
    rejected (not on the constraints, a contact violated) gets flag -84 and the reason; a member
    stopped by Painleve's paradox keeps its run up to there, its flag and message."""
    threads, save = recording.threads, recording.save  # recording.progress: a progress line as members finish
    options = dict(options)
    contacts = options.pop("contacts", None)
    if contacts is not None and not isinstance(contacts, ContactOptions):
        raise LagcodegenError(f"contacts must be a ContactOptions, got {type(contacts).__name__}")
    solver, rtol, atol, events, options = run_keywords(options)
    family = resolve(sim.formulation, solver, options)
    roots = sim._roots(events)
    contacts = ContactOptions() if contacts is None else contacts
    family.check(sim.formulation, Request(roots=roots, contacts=contacts))  # each member's run, refused here
    t = output_times(t)
    n_mem, Q, V, _ = _qv(sim, q0, v0, params)
    P = parameter_matrix(sim.compiled._defaults, list(sim.param_names), params, n_mem)
    if executor is not None:
        more = {} if contacts is None else {"contacts": contacts}
        return run_chunks(sim, executor, chunk_size, n_mem, t, dict(q0=Q, v0=V), P, threads, save,
                          dict(solver=family, rtol=rtol, atol=atol, events=events, initial=initial, ic_tol=ic_tol,
                               **more))
    cancel = np.zeros(1, dtype=np.intc)  # set on Ctrl-C: the running members stop with -80
    t0 = float(t[0])

    def member(i: int):
        if cancel[0]:
            return None
        p = np.ascontiguousarray(_param_row(P, i), dtype=float)
        try:
            y0 = sim._initial_values(t0, Q[i], V[i], p, initial, ic_tol, sim._ggl)[0]  # as simulate
        except LagcodegenError as exc:
            return f"{FLAG_TEXT[REJECTED]}: {exc}"
        start = time.perf_counter()
        try:
            res = family.run(sim.formulation, Problem(sim, rtol, atol, t, y0, p),
                             Request(roots=roots, contacts=contacts, cancel=cancel))
        except KeyboardInterrupt:
            cancel[0] = 1
            raise
        except SolverError as exc:  # Painleve's paradox: the run up to there is the member's
            if exc.result is None:
                raise
            res = exc.result
        except ModelError as exc:  # a contact violated at the start (other errors: the run's options, raised)
            return f"{FLAG_TEXT[REJECTED]}: {exc}"
        res.stats["wall"] = time.perf_counter() - start
        return res

    n_threads = default_threads(n_mem) if threads is None else max(1, int(threads))
    results: list = [None] * n_mem
    interrupted = False
    bar = Progress(n_mem, show=recording.progress)
    with ThreadPoolExecutor(max_workers=n_threads) as pool:
        futures = [pool.submit(member, i) for i in range(n_mem)]
        try:
            for i, fut in enumerate(futures):
                results[i] = fut.result()
                bar.update(i + 1, n_mem)
        except LagcodegenError:
            cancel[0] = 1
            raise
        except KeyboardInterrupt:
            cancel[0] = 1
            interrupted = True
            for fut in futures:
                fut.cancel()
            for i, fut in enumerate(futures):
                if not fut.cancelled():
                    try:
                        results[i] = fut.result()
                    except KeyboardInterrupt:
                        results[i] = None
    bar.close(sum(r is not None for r in results))
    out = _assemble(sim, t, results, P, save)
    if interrupted:
        raise EnsembleInterrupted(out) from None
    return out


def _assemble(sim, t: np.ndarray, results: list, P: np.ndarray, save) -> EnsembleResult:
    """The members' results (a Result, the message of a rejected member, or None: not run) as an
    :class:`EnsembleResult` with each member's events and contact log."""
    n_mem, nt, ny = len(results), t.size, sim.ny
    output_names = list(sim.info.output_names) + [f"lambda_ineq_{k}" for k in sim.info.contacts]
    output_names += [name for name in _tangential_outputs(results) if name not in output_names]
    names, cols = saved_columns(save, list(sim.state_names), output_names, {})
    final = np.full((n_mem, ny + len(output_names)), np.nan)
    traj = np.full((n_mem, nt, len(cols)), np.nan) if cols else None
    status = np.full(n_mem, NOT_RUN, dtype=np.intc)
    nt_done = np.zeros(n_mem, dtype=np.intc)
    t_reached = np.full(n_mem, np.nan)
    stats = {name: np.zeros(n_mem, dtype=np.dtype("l")) for name in COUNT_NAMES}
    stats["impacts"] = np.zeros(n_mem, dtype=np.dtype("l"))
    stats["events_dropped"] = np.zeros(n_mem, dtype=np.dtype("l"))
    stats["wall"] = np.zeros(n_mem)
    messages: dict = {}
    events: list = [[] for _ in range(n_mem)]
    impacts: list = [None] * n_mem
    for i, res in enumerate(results):
        if res is None:
            continue
        if isinstance(res, str):
            status[i] = REJECTED
            messages[i] = res
            continue
        status[i] = res.status
        if res.status < 0:
            messages[i] = res.message
        rows = res.t.size
        # the rows on the output grid (a terminal event's row follows them)
        done = rows if rows == 0 or (rows <= nt and res.t[rows - 1] == t[rows - 1]) else rows - 1
        nt_done[i] = done
        t_reached[i] = float(res.t[-1]) if rows else t[0]
        if rows:
            row = np.concatenate([res.y[-1], [res.outputs[n][-1] if n in res.outputs else np.nan
                                              for n in output_names]])
            final[i] = row
            if traj is not None:
                table = np.column_stack([res.y, *[res.outputs.get(n, np.full(rows, np.nan)) for n in output_names]])
                traj[i, :done] = table[:done][:, cols]
        for name, key in _STAT_OF.items():
            stats[name][i] = int(res.stats.get(key, 0))
        stats["events"][i] = max(len(res.events), int(res.stats.get("events", 0)))
        stats["events_dropped"][i] = stats["events"][i] - len(res.events)
        stats["terminated"][i] = int(bool(res.events) and res.events[-1].terminal)
        stats["impacts"][i] = int(res.stats.get("impacts", 0))
        stats["wall"][i] = float(res.stats.get("wall", 0.0))
        events[i] = list(res.events)
        impacts[i] = res.impacts
    for i in np.flatnonzero(status == CANCELLED).tolist():
        messages.setdefault(i, FLAG_TEXT[CANCELLED])
    out = EnsembleResult(t=t, state_names=list(sim.state_names), output_names=output_names, status=status,
                         t_reached=t_reached, nt_done=nt_done, final=final, nrow=ny, stats=stats, messages=messages,
                         columns=names, traj=traj, params=P, param_names=list(sim.param_names),
                         method=_method(results), formulation=sim.formulation, n_coordinates=sim.n)
    out.member_events, out.member_impacts = events, impacts
    return out


def _tangential_outputs(results: list) -> list:
    """The tangential multipliers' outputs (contacts with a tangent: lambda_t_ineq_<k>, 3-D
    lambda_t0_ineq_<k> and lambda_t1_ineq_<k>) the members report."""
    for res in results:
        if res is not None and not isinstance(res, str):
            return [n for n in res.outputs if n.startswith("lambda_t") and "_ineq_" in n]
    return []


def _method(results: list) -> str:
    for res in results:
        if res is not None and not isinstance(res, str):
            return res.method
    return ""
