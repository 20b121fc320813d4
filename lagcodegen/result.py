"""The result of one simulation, the same for every backend."""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .util import atomic_binary, atomic_write


@dataclass
class Result:
    """Trajectory, outputs and solver statistics of a run.

    ``y`` has one row per output time: (q_1..q_n, q_1'..q_n'). Index by name:
    ``res["theta"]`` (coordinate), ``res["theta_dot"]`` (velocity), ``res["energy"]`` (output).
    ``stats`` holds steps, rhs_evals (including difference-quotient Jacobian calls, where the
    backend reports them), jac_evals, and more.
    """

    t: np.ndarray
    y: np.ndarray
    state_names: list[str]
    outputs: dict[str, np.ndarray]
    stats: dict = field(default_factory=dict)
    status: int = 0
    message: str = ""
    backend: str = "native"
    method: str = ""
    parameters: dict = field(default_factory=dict)
    n_coordinates: int | None = None  # n: y = (q_1..q_n, q_1'..q_n', z...) with z quadrature states
    events: list = field(default_factory=list)  # events found by root finding (lagcodegen.model.events.EventRecord)
    formulation: str = ""  # constrained systems: "index1", "ggl" or "minimal"

    @property
    def success(self) -> bool:
        return self.status >= 0

    @property
    def n(self) -> int:
        return self.n_coordinates if self.n_coordinates is not None else len(self.state_names) // 2

    @property
    def q(self) -> dict[str, np.ndarray]:
        """Coordinates by name (including quadrature states such as reconstructed ignorable coordinates)."""
        idx = list(range(self.n)) + list(range(2 * self.n, len(self.state_names)))
        return {self.state_names[i]: self.y[:, i] for i in idx}

    @property
    def v(self) -> dict[str, np.ndarray]:
        """Velocities by coordinate name."""
        return {name: self.y[:, self.n + i] for i, name in enumerate(self.state_names[: self.n])}

    def __getitem__(self, name: str) -> np.ndarray:
        if name in self.state_names:
            return self.y[:, self.state_names.index(name)]
        if name in self.outputs:
            return self.outputs[name]
        if name == "t":
            return self.t
        raise KeyError(f"{name!r}: not a state ({', '.join(self.state_names)}) nor an output "
                       f"({', '.join(self.outputs) or 'none'})")

    def columns(self) -> dict[str, np.ndarray]:
        cols = {"t": self.t}
        cols.update({name: self.y[:, i] for i, name in enumerate(self.state_names)})
        cols.update(self.outputs)
        return cols

    def drifts(self) -> dict[str, float]:
        """Drift of every invariant among the outputs (energy, Jacobi h, integrals of motion C_*)."""
        keys = [k for k in self.outputs if k in ("energy", "jacobi_h") or k.startswith("C_")]
        return {k: self.drift(k) for k in keys}

    def drift(self, name: str) -> float:
        """max |x(t) - x(t0)| of an output (e.g. energy), relative to max(1, |x(t0)|)."""
        x = self[name]
        return float(np.max(np.abs(x - x[0])) / max(1.0, abs(x[0])))

    # ------------------------------------------------------------------ files
    def save(self, path: str | os.PathLike) -> Path:
        """Write CSV (``.csv``) or NPZ (``.npz``), atomically."""

        path = Path(path)
        cols = self.columns()
        if path.suffix == ".npz":
            with atomic_binary(path) as fh:  # the temporary file is removed on any exception (SIGTERM in the CLI)
                np.savez(fh, **cols, stats=np.array(repr(self.stats)), message=np.array(self.message))
            return path
        if path.suffix != ".csv":
            raise ValueError(f"{path}: results are written as .csv or .npz")
        names = list(cols)
        data = np.column_stack([cols[k] for k in names])
        lines = [",".join(names)]
        lines += [",".join(repr(float(x)) for x in row) for row in data]
        return atomic_write(path, "\n".join(lines) + "\n")

    def plot(self, path: str | os.PathLike, what: list[str] | None = None) -> Path:
        """Save a PNG of the coordinates (or the named columns) against time."""
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        what = what or self.state_names[: self.n]
        fig, axes = plt.subplots(len(what), 1, figsize=(8, 1.8 * len(what) + 1), sharex=True, squeeze=False)
        for ax, name in zip(axes[:, 0], what):
            ax.plot(self.t, self[name], lw=1)
            ax.set_ylabel(name)
            ax.grid(alpha=0.3)
        axes[-1, 0].set_xlabel("t")
        fig.suptitle(f"{self.backend} {self.method}".strip())
        fig.tight_layout()
        path = Path(path)
        try:
            with atomic_binary(path) as fh:  # a unique temporary file, never a predictable name
                fig.savefig(fh, dpi=100, format="png")
        finally:
            plt.close(fig)
        return path
