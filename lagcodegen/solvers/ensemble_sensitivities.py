"""Ensembles with forward sensitivities, for every family that has them: each member one run of
the family's sensitivity driver (its own C state), so each member's states and sensitivities are
bit-identical to the same run alone; the members are spread over ``threads`` Python threads (the
drivers run without the GIL) and gathered into one
:class:`~lagcodegen.solvers.ensemble_result.EnsembleResult` whose ``sensitivities`` (N, ns,
nvalues) hold each member's at its last output time (``sensitivity_trajectories`` (N, nt, ns,
nvalues) with ``save`` other than "final"). Ctrl-C raises
:class:`~lagcodegen.solvers.ensemble_result.EnsembleInterrupted` holding the members that
finished (the others NOT_RUN). Used by :mod:`lagcodegen.solvers.cvode.sensitivity_ensemble` and
:mod:`lagcodegen.solvers.taylor.ensemble`."""

from __future__ import annotations

import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from .control import NOT_RUN, Progress
from .ensemble_result import COUNT_NAMES, EnsembleInterrupted, EnsembleResult
from .ensemble_run import default_threads, saved_columns


def ensemble_of_runs(cm, t: np.ndarray, Y: np.ndarray, P: np.ndarray, names: list, member_run, *,
                     threads, save, progress, method: str) -> EnsembleResult:
    """The members (rows of Y, P) of the ODE of ``cm`` with the sensitivities ``names`` (parsed;
    None: runs without sensitivities, such as Taylor's with events):
    ``member_run(i, y0, p)`` member i's run, a :class:`~lagcodegen.result.Result` with its
    sensitivities (reentrant: called from several threads; ``i`` the member's index, for runs
    that differ by member beyond y0 and p, such as their input tables), whose stats give the ensemble's
    per-member counts (COUNT_NAMES; those a run does not count: 0). Events
    located in a member are its ``member_events`` (the run's records, as many as the run keeps),
    counted in its stats ``events``, ``events_dropped`` (found beyond those kept) and
    ``terminated``; a terminal
    event's time, state and sensitivities are the member's ``t_reached``, final row and final
    sensitivities, its trajectory the output times before it. A member that fails keeps its rows
    up to the last output time it reached: its ``final`` row and sensitivities are that time's
    (``t_reached`` the solver's time)."""
    n_mem, nt, ny, nout = Y.shape[0], t.shape[0], cm.ny, cm.code.nout
    values = list(cm.state_names) + list(cm.output_names)
    cols_names, cols = saved_columns(save, list(cm.state_names), list(cm.output_names), {})
    sensitive = names is not None
    ns, nv = len(names or ()), ny + nout
    final = np.full((n_mem, ny + nout), np.nan)
    traj = np.full((n_mem, nt, len(cols)), np.nan) if cols else None
    sens = np.full((n_mem, ns, nv), np.nan) if sensitive else None
    sens_traj = np.full((n_mem, nt, ns, nv), np.nan) if cols and sensitive else None
    status = np.full(n_mem, NOT_RUN, dtype=np.intc)
    nt_done = np.zeros(n_mem, dtype=np.intc)
    t_reached = np.full(n_mem, np.nan)
    count = {k: np.zeros(n_mem, dtype=np.dtype("l")) for k in COUNT_NAMES}
    wall = np.zeros(n_mem)
    events: list = [[] for _ in range(n_mem)]
    dropped = np.zeros(n_mem, dtype=np.dtype("l"))
    messages: dict = {}
    bar = Progress(n_mem, show=progress)

    def member(i: int) -> None:
        p = P if P.ndim == 1 else P[i]
        start = time.perf_counter()
        y0, p = np.ascontiguousarray(Y[i]), np.ascontiguousarray(p)
        res = member_run(i, y0, p)
        wall[i] = time.perf_counter() - start
        rows = res.t.size
        grid = min(rows, t.size)  # the rows at output times (a terminal event's row follows them)
        while grid and res.t[grid - 1] != t[grid - 1]:
            grid -= 1
        status[i] = res.status
        nt_done[i] = grid
        t_reached[i] = res.stats["t_reached"] if res.status < 0 else res.t[-1]
        for k in COUNT_NAMES:
            count[k][i] = res.stats.get(k, 0)
        events[i] = list(res.events)
        dropped[i] = max(0, int(res.stats.get("events", 0)) - len(res.events))
        if res.status < 0:
            messages[i] = res.message
        if rows:
            row = np.concatenate([res.y[-1], [res.outputs[k][-1] for k in cm.output_names]])
            final[i] = row
            if sensitive:
                sens[i] = res.sensitivities[-1]
            if traj is not None:
                full = np.column_stack([res.y, *(res.outputs[k] for k in cm.output_names)])
                traj[i, :grid] = full[:grid, cols]
                if sensitive:
                    sens_traj[i, :grid] = res.sensitivities[:grid]

    def result() -> EnsembleResult:
        stats = dict(count)
        stats["wall"] = wall
        stats["events_dropped"] = dropped
        res = EnsembleResult(t=t, state_names=list(cm.state_names), output_names=list(cm.output_names),
                             status=status, t_reached=t_reached, nt_done=nt_done, final=final, nrow=ny, stats=stats,
                             messages=messages, columns=cols_names, traj=traj, params=P,
                             param_names=list(cm.param_names), method=method, n_coordinates=cm.n,
                             member_events=events)
        if sensitive:
            res.set_sensitivities(names, values, sens, sens_traj)
        return res

    n_threads = default_threads(n_mem) if threads is None else max(1, int(threads))
    pool = ThreadPoolExecutor(max_workers=n_threads) if n_threads > 1 else None
    futures = []
    try:
        if pool is None:
            for i in range(n_mem):
                member(i)
                bar.update(i + 1, n_mem)
        else:
            futures = [pool.submit(member, i) for i in range(n_mem)]
            for done, fut in enumerate(futures, 1):
                fut.result()
                bar.update(done, n_mem)
    except KeyboardInterrupt:  # Ctrl-C: the members not started stay NOT_RUN; those running finish
        for fut in futures:
            fut.cancel()
        if pool is not None:
            pool.shutdown(wait=True)
        raise EnsembleInterrupted(result()) from None
    finally:
        if pool is not None:
            pool.shutdown(wait=True)
        bar.close(int(np.count_nonzero(status != NOT_RUN)))
    return result()
