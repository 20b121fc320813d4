"""Ensembles on executors (run control above one C call): the members split into chunks, each
chunk one ensemble call of the compiled simulation on a worker (``executor=``: any object with
``submit(fn, *args) -> future``: a ``concurrent.futures`` executor, a ``dask.distributed.Client``;
the simulation is pickled by its generated sources and rebuilt there from the worker's cache, with
its symbolic scene only when the runs need it: :func:`needs_scene`),
the results put back by offset; a chunk that fails is retried once, then its members are marked
(flag -83) with the traceback as their message.

One call into a driver's ``*_solve_many`` is :mod:`.ensemble_run`; its result
:class:`~.ensemble_result.EnsembleResult` (arrays by member; a member that fails is data: its flag in
``status``, its message in ``messages``); the faces' ensembles are :mod:`lagcodegen.simulation.ensemble`.
"""

from __future__ import annotations

import math
import traceback

import numpy as np

from ..errors import LagcodegenError
from .control import CHUNK_FAILED
from .payload import WithScene, with_scene
from .ensemble_result import FLAG_TEXT, REJECTED, EnsembleInterrupted, EnsembleResult  # noqa: F401 - public names


# ---------------------------------------------------------------------- executors (Dask, process pools)
def _run_chunk(sim, t, inputs: dict, P, threads, save, options):
    """One chunk on a worker: an ensemble call of ``sim`` (rebuilt from its sources there)."""
    if isinstance(sim, WithScene):  # an executor that did not pickle it (threads)
        sim = sim.sim
    return sim.ensemble(t, params=P, threads=threads, save=save, progress=False, **inputs, **options)


def needs_scene(sim, options: dict) -> bool:
    """Whether the chunks of ``sim``'s ensemble with ``options`` need the symbolic scene of its
    compiled model on the worker, which its pickle leaves out: sensitivities, and for the ODE of a
    compiled scene the Taylor method or events (generated from the scene where they run)."""
    solver = options.get("solver")
    if getattr(solver, "sensitivities", None) is not None:
        return True
    from ..codegen.record import GeneratedCode
    if not isinstance(getattr(sim, "code", None), GeneratedCode):  # constrained: events compiled in
        return False
    return bool(options.get("events")) or getattr(solver, "name", "CVODE") != "CVODE"


def run_chunks(sim, executor, chunk_size, n_mem: int, t, inputs: dict, P, threads, save, options,
               retries: int = 1) -> EnsembleResult:
    """The members of ``sim.ensemble`` split into chunks, each an ensemble call submitted to
    ``executor`` with the per-member ``inputs`` of its members and ``options`` (the resolved
    ``solver`` object among them); the results put back by offset. A chunk that raises is
    resubmitted ``retries`` times, then its members get flag -83 and the traceback as message."""
    if chunk_size is None:
        chunk_size = max(1, min(10_000, math.ceil(n_mem / 8)))
    chunk_size = int(chunk_size)
    threads = 1 if threads is None else threads  # executors run one worker per core
    starts = list(range(0, n_mem, chunk_size))
    payload = sim
    if needs_scene(sim, options):  # pickled with its scene, once (else its generated sources only)
        payload = with_scene(sim)
    if len(starts) > 1 and callable(getattr(executor, "scatter", None)):
        # a dask.distributed Client: the simulation goes to each worker once, not once per chunk
        # hash=False: a key of its own per call (a hashed key is shared with an earlier call of the same
        # simulation, whose release would drop the data under this one: "lost dependencies")
        payload = executor.scatter(payload, broadcast=True, hash=False)

    def args(s):
        sl = slice(s, min(s + chunk_size, n_mem))
        chunk_inputs = {k: np.ascontiguousarray(v[sl]) if isinstance(v, np.ndarray) else v
                        for k, v in inputs.items()}
        Pc = P if P.ndim == 1 else np.ascontiguousarray(P[sl])
        return (payload, t, chunk_inputs, Pc, threads, save, options)

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
