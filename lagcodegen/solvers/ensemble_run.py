"""One ensemble call into the generated C: the per-member inputs as arrays (states, run-time
parameters) and :func:`run_native`, which fills an :class:`~.ensemble_result.EnsembleResult` from a
driver's ``<prefix>_<driver>_solve_many`` (lagcodegen/runtime/lcg_pool.h)."""

from __future__ import annotations

import os
from typing import Mapping

import numpy as np

from ..codes import Flag
from ..errors import LagcodegenError
from .base import message
from .control import CANCELLED, NOT_RUN, POLL_EVERY, Progress, take_pending
from .ensemble_result import COUNT_NAMES, FLAG_TEXT, MAX_MESSAGES, EnsembleInterrupted, EnsembleResult


def _members(*arrays) -> int:
    """N from the leading dimension of the per-member inputs (2-D states, 1-D parameters)."""
    sizes = {a.shape[0] for a, per_member_ndim in arrays if a is not None and a.ndim == per_member_ndim}
    if len(sizes) > 1:
        raise LagcodegenError(f"the ensemble inputs disagree on the number of members: {sorted(sizes)}")
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
        parts = [_matrix(q0, n_mem, n, "q0", names[:n]),
                 np.zeros((n_mem, n)) if v0 is None else _matrix(v0, n_mem, n, "v0", names[:n])]
        nz = cm.ny - 2 * n
        if nz:
            parts.append(np.zeros((n_mem, nz)) if z0 is None else _matrix(z0, n_mem, nz, "z0", names[2 * n:]))
        Y = np.ascontiguousarray(np.hstack(parts))
    P = parameter_matrix(cm._defaults, list(cm.param_names), params, n_mem)
    return n_mem, Y, P


# ---------------------------------------------------------------------- the C call
def _columns(save, state_cols: list, output_names: list, extra: dict) -> tuple[list, list]:
    """(names, indices into the row (state | outputs)) of the trajectory columns ``save`` keeps."""
    nrow = len(state_cols)
    if save is None or save == "final":
        return [], []
    if save == "trajectory":
        names = [n for n in state_cols if not n.startswith("_")] + list(output_names)
    elif isinstance(save, str):
        names = [save]
    else:
        names = list(save)
    index = {n: i for i, n in enumerate(state_cols)}
    index.update({n: nrow + i for i, n in enumerate(output_names)})
    index.update(extra)
    bad = [n for n in names if n not in index]
    if bad:
        raise LagcodegenError(f"save: unknown names {', '.join(map(repr, bad))} (states and outputs: "
                              f"{', '.join([n for n in index if not n.startswith('_')])}; or 'final', 'trajectory')")
    return names, [index[n] for n in names]


def run_native(ffi, fn, ens_type: str, opt, *, t: np.ndarray, Y0: np.ndarray, P: np.ndarray, nrow: int,
               nout: int, state_names: list, output_names: list, row_names: list, save, threads,
               progress, poll, YP0=None, events=None, max_events: int = 64, extra_outputs=None,
               method: str = "", formulation: str = "", n_coordinates=None, param_names=()) -> EnsembleResult:
    """One call of a driver's solve-many function ``fn`` over the members Y0 (N, *), P."""
    n_mem, nt = Y0.shape[0], t.shape[0]
    extra_outputs = extra_outputs or {}
    names, cols = _columns(save, row_names, output_names, extra_outputs)
    keep = []
    buf = ffi.from_buffer
    e = ffi.new(f"{ens_type} *")
    e.nmem = n_mem
    e.nthreads = default_threads(n_mem) if threads is None else max(1, int(threads))
    if P.size:
        P = np.ascontiguousarray(P)
        e.p = buf("double[]", P)
        e.p_stride = 0 if P.ndim == 1 else P.shape[1]
    e.y0 = buf("double[]", Y0)
    e.y0_stride = Y0.shape[1]
    if YP0 is not None:
        e.yp0 = buf("double[]", YP0)
        e.yp0_stride = YP0.shape[1]
    t = np.ascontiguousarray(t, dtype=float)
    e.nt = nt
    e.tout = buf("double[]", t)
    final = np.empty((n_mem, nrow + nout))
    e.final = buf("double[]", final)
    traj = None
    if cols:
        traj = np.empty((n_mem, nt, len(cols)))
        colarr = np.array(cols, dtype=np.intc)
        keep.append(colarr)
        e.traj = buf("double[]", traj)
        e.ncol = len(cols)
        e.col = buf("int[]", colarr)
    status = np.full(n_mem, NOT_RUN, dtype=np.intc)
    nt_done = np.zeros(n_mem, dtype=np.intc)
    t_reached = np.full(n_mem, np.nan)
    wall = np.zeros(n_mem)
    counts = np.zeros((n_mem, len(COUNT_NAMES)), dtype=np.dtype("l"))
    msgs = np.zeros((MAX_MESSAGES, 256), dtype=np.uint8)
    msg_member = np.zeros(MAX_MESSAGES, dtype=np.dtype("l"))
    e.flag = buf("int[]", status)
    e.nt_done = buf("int[]", nt_done)
    e.t_reached = buf("double[]", t_reached)
    e.wall = buf("double[]", wall)
    e.counts = buf("long[]", counts)
    e.messages = buf("char[]", msgs)
    e.max_messages = MAX_MESSAGES
    e.message_member = buf("long[]", msg_member)
    if events is not None:
        rootdir, terminal = events
        keep += [rootdir, terminal]
        e.max_events = max_events
        e.rootdir = buf("int[]", rootdir)
        e.terminal = buf("int[]", terminal)
    bar = Progress(n_mem, show=progress)
    handle = ffi.new_handle(bar)
    if poll != ffi.NULL:
        e.poll = poll
        e.poll_data = handle
        e.poll_every = POLL_EVERY
    rc = fn(e, opt)
    bar.close(int(e.done))
    err = take_pending() if rc == CANCELLED else None
    if rc == Flag.NOMEM:
        raise LagcodegenError("ensemble: out of memory (threads or per-thread buffers)")
    not_run = status == NOT_RUN
    if not_run.any():
        final[not_run] = np.nan
        if traj is not None:
            traj[not_run] = np.nan
    messages = {}
    failed = np.flatnonzero(status < 0)
    if failed.size:
        texts = {}
        for m in range(min(int(e.n_messages), MAX_MESSAGES)):
            texts[int(msg_member[m])] = bytes(msgs[m]).split(b"\0", 1)[0].decode(errors="replace")
        solver = "IDA" if "ida" in ens_type else "CVODE"
        for i in failed.tolist():
            flag = int(status[i])
            if flag in FLAG_TEXT:
                text = FLAG_TEXT[flag] if flag != Flag.TIMED_OUT else texts.get(i, FLAG_TEXT[flag])
            else:
                text = message(flag, int(counts[i, 5]), texts.get(i, ""), solver)
            messages[i] = text
    stats = {name: counts[:, k] for k, name in enumerate(COUNT_NAMES)}
    stats["wall"] = wall
    res = EnsembleResult(t=t, state_names=list(state_names), output_names=list(output_names), status=status,
                         t_reached=t_reached, nt_done=nt_done, final=final, nrow=nrow, stats=stats,
                         messages=messages, columns=names, traj=traj, params=P, param_names=list(param_names),
                         extra_outputs=dict(extra_outputs), method=method, formulation=formulation,
                         n_coordinates=n_coordinates)
    if err is not None:
        if isinstance(err, KeyboardInterrupt):
            raise EnsembleInterrupted(res) from None
        raise err
    return res


def default_threads(n_mem: int) -> int:
    try:
        cores = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        cores = os.cpu_count() or 1
    return max(1, min(cores, n_mem))
