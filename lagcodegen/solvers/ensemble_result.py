"""The result of an ensemble (:class:`EnsembleResult`: arrays by member) and the flags of members
that did not run to the end."""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..codes import FLAG_TEXT as CODE_TEXT
from ..codes import Flag
from ..errors import LagcodegenError
from ..model.events import EventRecord
from ..result import Result, sensitivity_index
from .control import FLAG_TEXT as CONTROL_TEXT
from .control import NOT_RUN

#: Columns of the per-member counts the drivers fill.
COUNT_NAMES = ("steps", "rhs_evals", "jac_evals", "err_test_fails", "nonlin_conv_fails", "model_error", "events",
               "terminated")
#: Messages kept verbatim (the first failures); later failed members get the text of their flag.
MAX_MESSAGES = 1000
#: A member whose initial state the Python checks reject (constrained systems): never run.
REJECTED = int(Flag.REJECTED)
FLAG_TEXT = {**CONTROL_TEXT, REJECTED: CODE_TEXT[REJECTED]}




class MemberEventList(Sequence):
    """Every member's events as the ensemble drivers record them (arrays by member: times ``t``
    (N, m), state rows ``y`` (N, m, width), event functions ``which`` and ``direction`` (N, m); the
    first ``kept[i]`` of member i filled), item i the member's list of
    :class:`~lagcodegen.model.events.EventRecord`, made when asked for exactly as a single run makes
    its own (:func:`lagcodegen.model.events.records`); ``names``, ``terminal``: the events'."""

    def __init__(self, names: list, terminal: list, arrays: tuple, kept: np.ndarray, state_names: list):
        self.names, self.terminal = list(names), list(terminal)
        self.t, self.y, self.which, self.direction = arrays
        self.kept = np.asarray(kept)
        self.state_names = list(state_names)

    def __len__(self) -> int:
        return int(self.kept.shape[0])

    def __getitem__(self, i):
        if isinstance(i, slice):
            return [self[j] for j in range(*i.indices(len(self)))]
        i = range(len(self))[i]
        k, width = int(self.kept[i]), len(self.state_names)
        rows = np.asarray(self.y[i, :k], dtype=float)[:, :width]
        names = list(self.state_names)
        return [EventRecord(self.names[w], w, tk, rows[j].copy(), dk, self.terminal[w], names)
                for j, (w, tk, dk) in enumerate(zip(self.which[i, :k].tolist(), self.t[i, :k].tolist(),
                                                    self.direction[i, :k].tolist()))]


class EnsembleInterrupted(KeyboardInterrupt):
    """Ctrl-C during an ensemble: ``.result`` holds what finished (the others have status -80 or -82)."""

    def __init__(self, result: "EnsembleResult"):
        super().__init__("ensemble interrupted")
        self.result = result


@dataclass
class EnsembleResult:
    """The members of an ensemble, as arrays by member.

    ``status`` (N,) the flag of each member (0 success; negative: the solver's flag, -80 cancelled,
    -81 wall-clock limit, -82 never started, -83 its chunk failed, -84 initial state rejected,
    -100 - e a model error e); ``t_reached`` (N,); ``y`` (N, ny) the state at the last time reached
    (NaN for members never run); ``outputs`` name -> (N,) outputs there; ``trajectories`` name ->
    (N, nt) for the columns kept with ``save=`` ("trajectory": every state and output; a list: those
    names); ``stats`` name -> (N,) counters and ``wall`` seconds; ``messages`` {member: text} for
    the failed members only. ``member(i)`` is member i as a :class:`Result`.
    """

    t: np.ndarray
    state_names: list
    output_names: list
    status: np.ndarray
    t_reached: np.ndarray
    nt_done: np.ndarray
    final: np.ndarray            # (N, nrow + nout): state row (solver layout) and outputs
    nrow: int                    # state row size of the driver (GGL: q, v, lambda, mu)
    stats: dict
    messages: dict
    columns: list = field(default_factory=list)  # names of the trajectory columns
    traj: np.ndarray | None = None               # (N, nt, ncol)
    params: np.ndarray | None = None             # (N, np) or (np,)
    param_names: list = field(default_factory=list)
    extra_outputs: dict = field(default_factory=dict)  # name -> column of the state row (GGL mu_k)
    method: str = ""
    formulation: str = ""
    n_coordinates: int | None = None
    #: forward sensitivities (ensembles run with ``sensitivities=[...]``): (N, ns, nvalues) at each
    #: member's last output time; (N, nt, ns, nvalues) at every output time with ``save`` other
    #: than "final"; directions ``sensitivity_names``, values ``sensitivity_values`` (states, outputs)
    sensitivities: np.ndarray | None = field(default=None, repr=False)
    sensitivity_trajectories: np.ndarray | None = field(default=None, repr=False)
    sensitivity_names: list = field(default_factory=list)
    sensitivity_values: list = field(default_factory=list)
    #: each member's events (a list of EventRecord, the records a single run of the member gives,
    #: at most the ensemble's max_events: stats "events" counts every event found, "events_dropped"
    #: those beyond max_events) and, of systems with contacts, its contact log (ContactLog, or None
    #: where it did not run); None for ensembles that locate no events
    member_events: list | None = field(default=None, repr=False)
    member_impacts: list | None = field(default=None, repr=False)

    def set_sensitivities(self, names: list, values: list, final: np.ndarray, trajectories=None) -> None:
        """Attach the members' sensitivities: ``final`` (N, ns, nvalues), ``trajectories``
        (N, nt, ns, nvalues) or None."""
        self.sensitivity_names, self.sensitivity_values = list(names), list(values)
        self.sensitivities, self.sensitivity_trajectories = final, trajectories

    def sensitivity(self, value: str, direction: str) -> np.ndarray:
        """d value / d direction by member: (N, nt) at every output time when the trajectories
        were saved, else (N,) at each member's last output time."""
        if self.sensitivities is None:
            raise LagcodegenError("this ensemble has no sensitivities: run ensemble(..., sensitivities=[...])")
        j, k = sensitivity_index(self.sensitivity_names, self.sensitivity_values, value, direction, "ensemble")
        if self.sensitivity_trajectories is not None:
            return self.sensitivity_trajectories[:, :, j, k]
        return self.sensitivities[:, j, k]

    # ------------------------------------------------------------------ arrays
    def __len__(self) -> int:
        return int(self.status.shape[0])

    @property
    def success(self) -> np.ndarray:
        return self.status >= 0

    @property
    def n_failed(self) -> int:
        return int(np.count_nonzero(self.status < 0))

    @property
    def y(self) -> np.ndarray:
        """(N, ny) states at the last time reached."""
        return self.final[:, : len(self.state_names)]

    @property
    def outputs(self) -> dict:
        out = {name: self.final[:, self.nrow + i] for i, name in enumerate(self.output_names)}
        out.update({name: self.final[:, col] for name, col in self.extra_outputs.items()})
        return out

    @property
    def trajectories(self) -> dict:
        if self.traj is None:
            return {}
        return {name: self.traj[:, :, j] for j, name in enumerate(self.columns)}

    def __getitem__(self, name: str) -> np.ndarray:
        """The trajectory (N, nt) of a saved column, else the final value (N,) of a state or output."""
        if self.traj is not None and name in self.columns:
            return self.traj[:, :, self.columns.index(name)]
        if name in self.state_names:
            return self.y[:, self.state_names.index(name)]
        outs = self.outputs
        if name in outs:
            return outs[name]
        raise KeyError(f"{name!r}: not a state ({', '.join(self.state_names)}) nor an output "
                       f"({', '.join(outs) or 'none'})")

    def member(self, i: int) -> Result:
        """Member ``i`` as a :class:`Result`: its trajectory if every state was saved (rows up to the
        last output time reached), else one row at ``t_reached``."""
        i = int(i)
        names = self.state_names
        full = self.traj is not None and all(n in self.columns for n in names)
        if full:
            rows = int(self.nt_done[i])
            idx = [self.columns.index(n) for n in names]
            t = self.t[:rows].copy()
            y = self.traj[i, :rows][:, idx].copy()
            outputs = {n: self.traj[i, :rows, self.columns.index(n)].copy() for n in self.outputs
                       if n in self.columns}
        else:
            t = np.array([self.t_reached[i]])
            y = self.y[i][None, :].copy()
            outputs = {n: np.array([v[i]]) for n, v in self.outputs.items()}
        stats = {k: (v[i].item() if hasattr(v[i], "item") else v[i]) for k, v in self.stats.items()}
        stats["t_reached"] = float(self.t_reached[i])
        status = int(self.status[i])
        res = Result(t=t, y=y, state_names=list(names), outputs=outputs, stats=stats, status=status,
                     message=self.messages.get(i, "success" if status >= 0 else FLAG_TEXT.get(status, "")),
                     backend="native", method=self.method)
        if self.params is not None and self.param_names:
            p = self.params if self.params.ndim == 1 else self.params[i]
            res.parameters = dict(zip(self.param_names, (float(x) for x in p)))
        res.n_coordinates = self.n_coordinates
        res.formulation = self.formulation
        if self.member_events is not None:
            res.events = list(self.member_events[i])
        if self.member_impacts is not None:
            res.impacts = self.member_impacts[i]
        if self.sensitivities is not None:
            sens = self.sensitivity_trajectories[i, :rows] if full and self.sensitivity_trajectories is not None \
                else self.sensitivities[i][None]
            res.set_sensitivities(self.sensitivity_names, self.sensitivity_values, sens.copy())
        return res

    # ------------------------------------------------------------------ files
    def save(self, path: str | os.PathLike) -> Path:
        """Write NPZ (atomically): t, status, t_reached, nt_done, y (final states), final_<output>,
        stats_<name>, params, trajectories (traj, columns), the messages of failed members and
        every member's events (``event_member``, ``event_name``, ``event_index``, ``event_t``,
        ``event_direction``, ``event_terminal``, ``event_y``: one entry per event)."""
        import tempfile
        path = Path(path)
        if path.suffix != ".npz":
            raise LagcodegenError(f"{path}: ensembles are written as .npz")
        data = dict(t=self.t, status=self.status, t_reached=self.t_reached, nt_done=self.nt_done, y=self.y,
                    state_names=np.array(self.state_names), output_names=np.array(list(self.outputs)),
                    param_names=np.array(self.param_names),
                    message_members=np.array(sorted(self.messages), dtype=np.int64),
                    message_texts=np.array([self.messages[k] for k in sorted(self.messages)], dtype=str))
        data.update({f"final_{k}": v for k, v in self.outputs.items()})
        data.update({f"stats_{k}": v for k, v in self.stats.items()})
        if self.params is not None:
            data["params"] = self.params
        if self.traj is not None:
            data["traj"] = self.traj
            data["columns"] = np.array(self.columns)
        if self.member_events is not None:
            data.update(self._event_arrays())
        fd, tmp = tempfile.mkstemp(dir=path.parent if str(path.parent) else ".", suffix=".npz")
        os.close(fd)
        try:
            np.savez(tmp, **data)
            os.replace(tmp, path)
        finally:
            if os.path.exists(tmp):
                os.unlink(tmp)
        return path

    def _event_arrays(self) -> dict:
        """Every member's events as flat arrays (one entry per event, members in order): ``event_member``,
        ``event_name``, ``event_index``, ``event_t``, ``event_direction``, ``event_terminal``, ``event_y``
        (events x states)."""
        recs = [(i, r) for i in range(len(self)) for r in self.member_events[i]]
        width = len(self.state_names)
        return dict(event_member=np.array([i for i, _ in recs], dtype=np.int64),
                    event_name=np.array([r.name for _, r in recs], dtype=str),
                    event_index=np.array([r.index for _, r in recs], dtype=np.int64),
                    event_t=np.array([r.t for _, r in recs], dtype=float),
                    event_direction=np.array([r.direction for _, r in recs], dtype=np.int64),
                    event_terminal=np.array([r.terminal for _, r in recs], dtype=bool),
                    event_y=np.array([r.y for _, r in recs], dtype=float).reshape(len(recs), width))

    # ------------------------------------------------------------------ assembly
    @classmethod
    def assemble(cls, n: int, parts: list, like: "EnsembleResult", params=None) -> "EnsembleResult":
        """One result of ``n`` members from ``parts`` [(member indices, EnsembleResult)], laid out
        like ``like``; members in no part are NOT_RUN."""
        ncolf = like.final.shape[1]
        out = cls(t=like.t, state_names=like.state_names, output_names=like.output_names,
                  status=np.full(n, NOT_RUN, dtype=np.intc), t_reached=np.full(n, np.nan),
                  nt_done=np.zeros(n, dtype=np.intc), final=np.full((n, ncolf), np.nan), nrow=like.nrow,
                  stats={k: np.zeros(n, dtype=v.dtype) for k, v in like.stats.items()}, messages={},
                  columns=like.columns,
                  traj=None if like.traj is None else np.full((n, like.traj.shape[1], like.traj.shape[2]), np.nan),
                  params=params, param_names=like.param_names, extra_outputs=like.extra_outputs,
                  method=like.method, formulation=like.formulation, n_coordinates=like.n_coordinates)
        for idx, part in parts:
            idx = np.asarray(idx)
            out.status[idx] = part.status
            out.t_reached[idx] = part.t_reached
            out.nt_done[idx] = part.nt_done
            out.final[idx] = part.final
            for k in out.stats:
                if k in part.stats:
                    out.stats[k][idx] = part.stats[k]
            if out.traj is not None and part.traj is not None:
                out.traj[idx] = part.traj
            out.messages.update({int(idx[j]): text for j, text in part.messages.items()})
        if like.member_events is not None or like.member_impacts is not None:
            out.member_events, out.member_impacts = [[] for _ in range(n)], [None] * n
            for idx, part in parts:
                for j, i in enumerate(np.asarray(idx).tolist()):
                    if part.member_events is not None:
                        out.member_events[i] = part.member_events[j]
                    if part.member_impacts is not None:
                        out.member_impacts[i] = part.member_impacts[j]
        if like.sensitivities is not None:
            final = np.full((n, *like.sensitivities.shape[1:]), np.nan)
            traj = None if like.sensitivity_trajectories is None else \
                np.full((n, *like.sensitivity_trajectories.shape[1:]), np.nan)
            for idx, part in parts:
                final[np.asarray(idx)] = part.sensitivities
                if traj is not None:
                    traj[np.asarray(idx)] = part.sensitivity_trajectories
            out.set_sensitivities(like.sensitivity_names, like.sensitivity_values, final, traj)
        return out
