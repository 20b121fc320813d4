"""The result of one simulation, the same for every backend: its columns by name, files (CSV,
NPZ), plots, animations (:mod:`lagcodegen.animation`) and its notebook view."""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import LagcodegenError
from .util import atomic_binary


#: Values of a CSV file formatted at a time (:func:`write_csv`): a chunk takes some tens of
#: milliseconds, and Ctrl-C (KeyboardInterrupt, raised between chunks) stops a long write that soon.
CSV_CHUNK_VALUES = 1 << 18

#: The format of a value in a CSV file: 17 significant digits, which read back as the same double.
CSV_FORMAT = "%.17g"


def write_csv(path: str | os.PathLike, columns: dict[str, np.ndarray]) -> Path:
    """Write ``columns`` (name -> 1-D array of one length, as :meth:`Result.columns`) to ``path``
    as CSV: a header line of the names, then a row per index, each value in :data:`CSV_FORMAT`
    (every double reads back exactly; nan, inf and -inf as such).

    The rows are formatted :data:`CSV_CHUNK_VALUES` values at a time into a temporary file beside
    ``path`` that replaces it at the end (:func:`lagcodegen.util.atomic_binary`): Ctrl-C between
    chunks, or any error, leaves ``path`` as it was and no temporary file. LagcodegenError if the
    columns are not 1-D arrays of real numbers of one length."""
    path = Path(path)
    names = list(columns)
    if not names:
        raise LagcodegenError(f"{path}: no columns to write")
    arrays = []
    for name in names:
        try:
            arr = np.asarray(columns[name], dtype=float)
        except (TypeError, ValueError):
            raise LagcodegenError(f"{path}: column {name!r} is not an array of real numbers") from None
        if arr.ndim != 1:
            raise LagcodegenError(f"{path}: column {name!r} has shape {arr.shape}, expected one value per row")
        arrays.append(arr)
    nrows = len(arrays[0])
    if any(len(a) != nrows for a in arrays):
        raise LagcodegenError(f"{path}: the columns differ in length ("
                              + ", ".join(f"{k} {len(a)}" for k, a in zip(names, arrays)) + ")")
    step = max(1, CSV_CHUNK_VALUES // len(names))
    row = ",".join([CSV_FORMAT] * len(names)) + "\n"
    with atomic_binary(path) as fh:  # the temporary file is removed on any exception (Ctrl-C, SIGTERM)
        fh.write((",".join(names) + "\n").encode("utf-8"))
        for start in range(0, nrows, step):  # KeyboardInterrupt comes between chunks
            block = np.column_stack([a[start:start + step] for a in arrays])
            fh.write(((row * len(block)) % tuple(block.ravel().tolist())).encode("ascii"))
    return path


def sensitivity_index(names: list, values: list, value: str, direction: str, what: str) -> tuple[int, int]:
    """(j, k): ``direction`` among the sensitivity directions ``names`` and ``value`` among the
    states and outputs ``values`` of a ``what`` ("run", "ensemble"), else LagcodegenError
    listing them."""
    if direction not in names:
        raise LagcodegenError(f"{direction!r} is not a sensitivity direction of this {what} ({', '.join(names)})")
    if value not in values:
        raise LagcodegenError(f"{value!r} is neither a state nor an output of this {what} ({', '.join(values)})")
    return names.index(direction), values.index(value)


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
    n_speeds: int | None = None  # generalized speeds: y = (q_1..q_n, v_1..v_nv, z...); None: nv = n
    events: list = field(default_factory=list)  # events found by root finding (lagcodegen.model.events.EventRecord)
    formulation: str = ""  # constrained systems: "index1", "ggl" or "minimal"
    model_name: str = ""  # the model's name (plot titles), set by the compiled model
    # constrained systems with contacts: their impacts, switches and releases
    # (lagcodegen.simulation.constrained_impacts.ContactLog), else None
    impacts: object = None
    # how the model is drawn (lagcodegen.animation.Drawing, or a callable making one on first use)
    drawing: object = field(default=None, repr=False, compare=False)
    #: forward sensitivities (nt, ns, nvalues): d(value)/d(direction) at every output time, with
    #: sensitivity_names the directions and sensitivity_values the states then the outputs
    #: (:meth:`sensitivity`); None without ``simulate(..., sensitivities=[...])``
    sensitivities: np.ndarray | None = field(default=None, repr=False, compare=False)
    sensitivity_names: list = field(default_factory=list, compare=False)
    sensitivity_values: list = field(default_factory=list, compare=False)

    def set_sensitivities(self, names: list, values: list, array: np.ndarray) -> None:
        """Attach the forward sensitivities ``array`` (nt, len(names), len(values))."""
        self.sensitivities = array
        self.sensitivity_names = list(names)
        self.sensitivity_values = list(values)

    def sensitivity(self, value: str, direction: str) -> np.ndarray:
        """d value / d direction at every output time: ``value`` a state or output name,
        ``direction`` one of the run's sensitivity directions (a run-time parameter, or an
        initial value "<q>(0)", "<q>_dot(0)")."""
        if self.sensitivities is None:
            raise LagcodegenError("this result has no sensitivities: run simulate(..., sensitivities=[...])")
        j, k = sensitivity_index(self.sensitivity_names, self.sensitivity_values, value, direction, "run")
        return self.sensitivities[:, j, k]

    @property
    def success(self) -> bool:
        return self.status >= 0

    @property
    def n(self) -> int:
        return self.n_coordinates if self.n_coordinates is not None else len(self.state_names) // 2

    @property
    def nv(self) -> int:
        """The number of speeds (= :attr:`n` unless the model has generalized speeds)."""
        return self.n if self.n_speeds is None else self.n_speeds

    @property
    def q(self) -> dict[str, np.ndarray]:
        """Coordinates by name (including quadrature states such as reconstructed ignorable coordinates)."""
        idx = list(range(self.n)) + list(range(self.n + self.nv, len(self.state_names)))
        return {self.state_names[i]: self.y[:, i] for i in idx}

    @property
    def v(self) -> dict[str, np.ndarray]:
        """Velocities by coordinate name; generalized speeds by their own names."""
        if self.n_speeds is not None:
            return {name: self.y[:, self.n + i] for i, name in enumerate(self.state_names[self.n:self.n + self.nv])}
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
        """Write CSV (``.csv``, :func:`write_csv`: the columns t, states, outputs, each double
        exactly) or NPZ (``.npz``), atomically: an interrupted or failed write leaves ``path`` as
        it was and no temporary file."""

        path = Path(path)
        cols = self.columns()
        if path.suffix == ".npz":
            with atomic_binary(path) as fh:  # the temporary file is removed on any exception (SIGTERM in the CLI)
                np.savez(fh, **cols, stats=np.array(repr(self.stats)), message=np.array(self.message))
            return path
        if path.suffix != ".csv":
            raise ValueError(f"{path}: results are written as .csv or .npz")
        write_csv(path, cols)
        return path

    # ------------------------------------------------------------------ pictures
    def title(self) -> str:
        """The model's name (else the backend and method), the title of plots."""
        return self.model_name or f"{self.backend} {self.method}".strip()

    def panels(self) -> list[list[str]]:
        """The default panels of :meth:`plot`: each coordinate, then the outputs that tell what
        the run is about, a panel per kind: energies (T + V, T, V, D), the Jacobi integral h,
        its rate, the multipliers lambda_j, the constraint residuals, integrals of motion C_i."""
        panels = [[name] for name in self.state_names[: self.n]]
        kinds = [lambda k: k in ("energy", "kinetic_energy", "potential_energy", "dissipation"),
                 lambda k: k == "jacobi_h", lambda k: k == "dh_dt", lambda k: k.startswith("lambda_"),
                 lambda k: k.startswith(("g_", "gdot_")), lambda k: k.startswith("C_")]
        for kind in kinds:
            names = [k for k in self.outputs if kind(k)]
            if names:
                panels.append(names)
        return panels

    def plot(self, path: str | os.PathLike | None = None, what: list | None = None, *, xy: bool | str | None = None,
             phase: bool = False, title: str | None = None):
        """Plot the run against time: a panel per coordinate and per requested kind of output
        (:meth:`panels`), or per item of ``what`` (a name, or a list of names sharing a panel);
        titled with the model's name.

        ``xy``: instead, the x-y path of planar points (an orbit, not r(t)): True every 2-D
        point, or a point's name (positions from the outputs, or computed from the states by
        the model's drawing). ``phase``: instead, phase portraits q' against q.

        With ``path``, the figure is saved as PNG (atomically) and the path returned; without,
        the matplotlib figure is returned: a notebook draws it (its ``_repr_png_``, as it was
        made without pyplot: :func:`lagcodegen.notebook.shown`).
        """
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure

        from .notebook import shown

        if xy:
            fig = self._xy_figure(xy)
        elif phase:
            if self.n_speeds is not None:
                raise LagcodegenError("phase portraits plot q' against q: this run's speeds are generalized speeds, "
                                      "not the coordinates' rates")
            names = self.state_names[: self.n]
            fig = Figure(figsize=(4 * min(len(names), 3), 4 * ((len(names) + 2) // 3)))
            for i, name in enumerate(names):
                ax = fig.add_subplot((len(names) + 2) // 3, min(len(names), 3), i + 1)
                ax.plot(self.y[:, i], self.y[:, self.n + i], lw=0.8)
                ax.set_xlabel(name)
                ax.set_ylabel(f"{name}'")
                ax.grid(alpha=0.3)
        else:
            panels = [[w] if isinstance(w, str) else list(w) for w in what] if what else self.panels()
            fig = Figure(figsize=(8, 1.8 * len(panels) + 1))
            axes = fig.subplots(len(panels), 1, sharex=True, squeeze=False)[:, 0]
            for ax, names in zip(axes, panels):
                for name in names:
                    ax.plot(self.t, self[name], lw=1, label=name)
                ax.set_ylabel(names[0] if len(names) == 1 else ", ".join(names) if len(names) <= 3
                              else f"{names[0]}, ...")
                if len(names) > 1:
                    ax.legend(fontsize="small", loc="best")
                ax.grid(alpha=0.3)
            axes[-1].set_xlabel("t")
        fig.suptitle(title if title is not None else self.title())
        fig.tight_layout()
        if path is None:
            return shown(fig)
        FigureCanvasAgg(fig)
        path = Path(path)
        with atomic_binary(path) as fh:  # a unique temporary file, never a predictable name
            fig.savefig(fh, dpi=100, format="png")
        return path

    def _xy_figure(self, which):
        from matplotlib.figure import Figure

        drawing = self.drawn()
        planar = [p for p, d in drawing.points.items() if d == 2]
        if which is not True:
            if which not in drawing.points:
                raise LagcodegenError(f"xy={which!r}: not a point of the model (points: "
                                      f"{', '.join(drawing.points) or 'none'})")
            planar = [which]
        if not planar:
            raise LagcodegenError("xy: the model has no planar (2-D) point")
        tracks = self.tracks()
        fig = Figure(figsize=(6, 6))
        ax = fig.add_subplot()
        for p in planar:
            ax.plot(tracks[p][:, 0], tracks[p][:, 1], lw=0.8, label=p)
        for name, pos in drawing.pivots.items():
            ax.plot([pos[0]], [pos[1]], "ks")
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel("x")
        ax.set_ylabel("y")
        ax.grid(alpha=0.3)
        if len(planar) > 1:
            ax.legend(fontsize="small")
        return fig

    def drawn(self):
        """How this run's model is drawn (:class:`lagcodegen.animation.Drawing`): the compiled
        model's, else the points among the outputs; LagcodegenError if there is neither."""
        from .animation import drawing_from_columns, resolve
        drawing = resolve(self.drawing) or drawing_from_columns(list(self.outputs), self.model_name)
        if drawing is None or not drawing.points:
            raise LagcodegenError("nothing to draw: this result has no point positions and no model to compute them "
                                  "(simulate with outputs=['positions'] a model with points or bodies)")
        return drawing

    def tracks(self) -> dict[str, np.ndarray]:
        """Positions {point: (N, dim)} of the model's points over the run: the ``positions``
        outputs if they were requested, else computed from the states."""
        from .animation import tracks
        return tracks(self.drawn(), self.outputs, lambda: (self.t, self.y, self.parameters))

    def animate(self, path: str | os.PathLike, *, fps: float = 25, duration: float | None = None,
                frames: int | None = None, trail: bool | float = False, size: tuple[float, float] = (5.0, 5.0),
                dpi: float = 80, title: str | None = None) -> Path:
        """Draw the mechanism moving: its points, the links between them and to fixed pivots
        (2-D or 3-D as the model is), into ``path``: ``.gif``, ``.mp4`` (needs ffmpeg) or
        ``.html`` (a player), written atomically.

        ``frames`` evenly spaced over the run (default ``fps * duration``; ``duration`` in
        seconds of playback, default the run's length up to 10 s); ``trail``: True the whole
        path behind each point, a number the last that much model time. The positions are the
        ``positions`` outputs if requested, else computed from the states by the model.
        """
        from .animation import animate
        drawing = self.drawn()
        return animate(path, drawing, self.t, self.tracks(), fps=fps, duration=duration, frames=frames, trail=trail,
                       title=self.title() if title is None else title, size=size, dpi=dpi)

    # ------------------------------------------------------------------ notebooks
    def to_pandas(self):
        """The columns (t, states, outputs) as a pandas DataFrame indexed by nothing but row
        number; pandas is optional (LagcodegenError if it is missing)."""
        try:
            import pandas
        except ImportError:
            raise LagcodegenError("Result.to_pandas needs pandas, which is not installed (pip install pandas); "
                                  "Result.columns() gives the same columns as a dict of arrays") from None
        return pandas.DataFrame(self.columns())

    def _repr_html_(self) -> str:
        from .notebook import result_html
        return result_html(self)
