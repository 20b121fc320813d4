"""One ensemble call into the generated C: :func:`run_native` fills an
:class:`~.ensemble_result.EnsembleResult` from a driver's ``*_solve_many`` (lagcodegen/runtime/lcg_pool.h),
whichever family's driver it is."""

from __future__ import annotations

import os

import numpy as np

from ..codes import Flag
from ..errors import LagcodegenError
from .base import message
from .control import CANCELLED, NOT_RUN, POLL_EVERY, Progress, take_pending
from .request import Layout, Recording, RunArrays
from .ensemble_result import COUNT_NAMES, FLAG_TEXT, MAX_MESSAGES, EnsembleInterrupted, EnsembleResult, MemberEventList


# ---------------------------------------------------------------------- the C call
def saved_columns(save, state_cols: list, output_names: list, extra: dict) -> tuple[list, list]:
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


def run_native(ffi, fn, ens_type: str, opt, arrays: RunArrays, layout: Layout, recording: Recording, *, poll,
               setup=None) -> EnsembleResult:
    """One call of a driver's solve-many function ``fn`` (with its options struct ``opt``) over the
    members ``arrays`` (initial states ``y`` (N, *), IDA's ``yp`` or None, parameters ``p``, output
    times ``t``), their rows laid out as ``layout`` says; ``recording``: what each member keeps
    (``save``), the ``threads`` and ``progress`` bar, the events (``events``: their directions and
    terminal flags and each member's first ``max_events`` recorded: :class:`MemberEvents`) and of an ODE ensemble the
    event functions (``roots``: an ``lcg_ode_roots *``, or None); ``poll`` the Ctrl-C callback;
    ``setup(e, keep)``: sets further fields of the ensemble struct ``e`` (arrays kept in ``keep``)."""
    t, Y0, P, YP0 = arrays.t, arrays.y, arrays.p, arrays.yp
    nrow, nout, extra_outputs = layout.nrow, layout.nout, layout.extra_outputs
    save, threads, progress = recording.save, recording.threads, recording.progress
    events, roots = recording.events, recording.roots
    n_mem, nt = Y0.shape[0], t.shape[0]
    extra_outputs = extra_outputs or {}
    names, cols = saved_columns(save, layout.row_names, layout.output_names, extra_outputs)
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
    if setup is not None:
        setup(e, keep)
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
    found = None
    if events is not None:
        found = MemberEvents(events, n_mem, recording.max_events, nrow)
        found.attach(e, buf, keep)
    if roots is not None and roots is not False:  # the event functions' table of an ODE ensemble
        e.roots = roots
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
    member_events = None
    if found is not None:
        member_events = found.records(counts[:, COUNT_NAMES.index("events")], layout.state_names)
        stats["events_dropped"] = found.dropped(counts[:, COUNT_NAMES.index("events")])
    res = EnsembleResult(t=t, state_names=list(layout.state_names), output_names=list(layout.output_names),
                         status=status, t_reached=t_reached, nt_done=nt_done, final=final, nrow=nrow, stats=stats,
                         messages=messages, columns=names, traj=traj, params=P, param_names=list(layout.param_names),
                         extra_outputs=dict(extra_outputs), method=layout.method, formulation=layout.formulation,
                         n_coordinates=layout.n_coordinates, member_events=member_events)
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


class MemberEvents:
    """The arrays an ensemble driver fills with each member's first events (``ev_t``, ``ev_y``,
    ``ev_which``, ``ev_direction`` of its struct: at most ``max_events`` per member, 0: the pool's
    64) for the events ``events`` (:class:`~lagcodegen.model.events.Event` s), and the
    :class:`~lagcodegen.model.events.EventRecord` s made from them, as a single run makes its own."""

    def __init__(self, events: list, n_mem: int, max_events: int, nrow: int):
        self.events = list(events)
        self.max_events = int(max_events) if max_events and max_events > 0 else 64
        if self.max_events > 2**31 - 1:
            raise LagcodegenError(f"max_events: {max_events} does not fit the driver's int")
        m = self.max_events
        # filled by the driver up to each member's count (only those slots are read): not cleared
        size = n_mem * m * (nrow + 2) * 8
        problem = f"ensemble events: {n_mem} members x max_events={m} x {nrow + 2} values ({size / 2**30:.3g} GiB) " \
                  "do not fit in memory: give a smaller max_events (the solver's max_events=) or fewer members " \
                  "per call (executor=, chunk_size=)"
        if size > physical_memory():
            raise LagcodegenError(problem)
        try:
            self.t = np.empty((n_mem, m))
            self.y = np.empty((n_mem, m, nrow))
            self.which = np.empty((n_mem, m), dtype=np.intc)
            self.direction = np.empty((n_mem, m), dtype=np.intc)
        except MemoryError as exc:
            raise LagcodegenError(problem) from exc
        self.rootdir, self.terminal = event_arrays(self.events)

    def attach(self, e, buf, keep: list) -> None:
        """Point the ensemble struct ``e`` at the arrays (kept alive in ``keep``)."""
        keep += [self.rootdir, self.terminal, self.t, self.y, self.which, self.direction]
        e.max_events = self.max_events
        e.rootdir = buf("int[]", self.rootdir)
        e.terminal = buf("int[]", self.terminal)
        e.ev_t = buf("double[]", self.t)
        e.ev_y = buf("double[]", self.y)
        e.ev_which = buf("int[]", self.which)
        e.ev_direction = buf("int[]", self.direction)

    def kept(self, found: np.ndarray) -> np.ndarray:
        return np.minimum(np.asarray(found), self.max_events)

    def dropped(self, found: np.ndarray) -> np.ndarray:
        """(N,) events found beyond ``max_events`` in each member (found and not kept)."""
        return np.asarray(found) - self.kept(found)

    def records(self, found: np.ndarray, state_names: list) -> "MemberEventList":
        """Each member's EventRecords (the first ``len(state_names)`` values of each row; ``found``
        the events each member found, from its counts), made when a member's are asked for."""
        return MemberEventList([e.name for e in self.events], self.terminal[:len(self.events)].astype(bool).tolist(),
                               (self.t, self.y, self.which, self.direction), self.kept(found), list(state_names))


def physical_memory() -> float:
    """The machine's memory in bytes (inf where it cannot be asked)."""
    try:
        return float(os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
    except (AttributeError, OSError, ValueError):
        return float("inf")


def event_arrays(events) -> tuple:
    """(directions, terminal flags) of ``events`` as the int arrays of an ensemble struct."""
    return (np.array([e.direction for e in events] or [0], dtype=np.intc),
            np.array([1 if e.terminal else 0 for e in events] or [0], dtype=np.intc))
