"""Pictures that move: a mechanism's points and the links between them, drawn frame by frame
into a GIF (Pillow), an MP4 (ffmpeg, where it is installed) or an HTML player (matplotlib's
``to_jshtml``).

What to draw comes as a :class:`Drawing`, a plain record (point names, links, fixed pivots, and
optionally a function computing the points' positions from the states) that the compiled model
attaches to its results (:mod:`lagcodegen.formulation.drawing` makes it from the model); where a
result has none, the points are found among its outputs (``<point>_x``, ``<point>_y``,
``<point>_z``) and drawn without links. :meth:`lagcodegen.result.Result.animate` is the entry
point; :class:`Animator` is the figure and its per-frame update.

One of the lowest stages (beside :mod:`lagcodegen.notebook`): imports nothing of lagcodegen but
the errors and util; matplotlib is imported when a picture is drawn.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Mapping, Sequence

import numpy as np

from .errors import LagcodegenError
from .util import atomic_write, excerpt, staged_outputs

#: Frames of an animation at most (a longer one is refused: lower fps or duration).
MAX_FRAMES = 5000
#: Default length of an animation in seconds of wall-clock playback (shorter runs play in real time).
DEFAULT_DURATION = 10.0
#: A spring's zigzags, and their half-width as a fraction of half the picture's extent.
SPRING_COILS = 8
SPRING_WIDTH = 0.04
#: Suffixes :func:`animate` writes.
FORMATS = (".gif", ".mp4", ".html")
#: Pixels of a frame's side at most (size * dpi; a larger one is refused before any drawing).
MAX_PIXELS = 8192


@dataclass
class Drawing:
    """How a model is drawn: what the compiled model hands to its results.

    ``points``: the model's points by name with their dimension (2 or 3), in the model's order;
    ``links``: pairs of names joined by a line (points, or names of ``pivots``); ``pivots``:
    fixed positions drawn as squares (a pendulum's suspension); ``fixed``: points that never
    move (drawn as pivots); ``body_axes``: tips of the axes drawn on bodies, tip name -> (the
    body's point, axis letter "x", "y" or "z"), so that a body's rotation shows (a top's spin);
    ``springs``: pairs of names (points or pivots) joined by a spring, drawn as a zigzag;
    ``evaluate(t, y, parameters)``: the positions {name: (N, dim)} of the points and axis tips at
    the states ``y`` (N rows) and times ``t`` (N) with the run-time ``parameters`` (name ->
    value), or None (then the points' positions must be among the result's outputs, and no axes
    are drawn). ``evaluate`` is dropped when the record is pickled.
    """

    name: str
    points: dict[str, int]
    links: list[tuple[str, str]] = field(default_factory=list)
    pivots: dict[str, tuple[float, ...]] = field(default_factory=dict)
    fixed: tuple[str, ...] = ()
    evaluate: Callable | None = field(default=None, repr=False, compare=False)
    body_axes: dict[str, tuple[str, str]] = field(default_factory=dict)
    springs: list[tuple[str, str]] = field(default_factory=list)

    @property
    def dim(self) -> int:
        """3 if any point is 3-D, else 2."""
        return 3 if any(d == 3 for d in self.points.values()) else 2

    def __getstate__(self):
        state = dict(self.__dict__)
        state["evaluate"] = None
        return state


def resolve(drawing) -> Drawing | None:
    """``drawing`` as a :class:`Drawing`: itself, or what a deferred one (a callable) makes."""
    if drawing is None or isinstance(drawing, Drawing):
        return drawing
    return drawing()


def drawing_from_columns(columns: Sequence[str], name: str = "") -> Drawing | None:
    """The points among output names (``<p>_x`` with ``<p>_y``, and ``<p>_z`` if present), no
    links; None if there are none."""
    cols = set(columns)
    points = {}
    for c in columns:
        if c.endswith("_x") and c[:-2] + "_y" in cols:
            p = c[:-2]
            points[p] = 3 if p + "_z" in cols else 2
    return Drawing(name, points) if points else None


def tracks(drawing: Drawing, outputs: Mapping[str, np.ndarray], evaluate_args: Callable[[], tuple] | None = None
           ) -> dict[str, np.ndarray]:
    """Positions {point: (N, dim)} of the drawing's points: from ``outputs`` (``<p>_x`` ...) where
    they are all there, else from ``drawing.evaluate(*evaluate_args())``. Raises LagcodegenError
    saying what to request when neither is possible."""
    axes = "xyz"
    computed = None
    if drawing.evaluate is not None and evaluate_args is not None and drawing.body_axes:
        computed = drawing.evaluate(*evaluate_args())
    if all(f"{p}_{a}" in outputs for p, d in drawing.points.items() for a in axes[:d]):
        out = {p: np.column_stack([np.asarray(outputs[f"{p}_{a}"], dtype=float) for a in axes[:d]])
               for p, d in drawing.points.items()}
        if computed is not None:
            out.update({tip: np.asarray(computed[tip], dtype=float) for tip in drawing.body_axes})
        return out
    if drawing.evaluate is None or evaluate_args is None:
        missing = [f"{p}_{a}" for p, d in drawing.points.items() for a in axes[:d] if f"{p}_{a}" not in outputs]
        raise LagcodegenError(f"cannot draw {drawing.name or 'this result'}: the positions "
                              f"{', '.join(missing[:6])}{' ...' if len(missing) > 6 else ''} are not among the "
                              "outputs and no model is attached to compute them: simulate with "
                              "outputs=['positions'] (compile_model(..., outputs=['positions']))")
    out = computed if computed is not None else drawing.evaluate(*evaluate_args())
    tracks = {p: np.asarray(out[p], dtype=float).reshape(-1, d) for p, d in drawing.points.items()}
    tracks.update({tip: np.asarray(out[tip], dtype=float) for tip in drawing.body_axes if tip in out})
    return tracks


def frame_times(t: np.ndarray, *, fps: float, duration: float | None, frames: int | None) -> np.ndarray:
    """Model times of the frames: ``frames`` of them (or ``fps * duration``; duration default:
    the run's length in model time, at most :data:`DEFAULT_DURATION`), evenly spaced from the
    first output time to the last."""
    t = np.asarray(t, dtype=float)
    if t.size < 1:
        raise LagcodegenError("the result has no output times: nothing to animate")
    if not (isinstance(fps, (int, float)) and np.isfinite(fps) and fps > 0):
        raise LagcodegenError(f"fps must be a positive number, got {fps!r}")
    if frames is None:
        span = float(t[-1] - t[0])
        if duration is None:
            duration = min(span, DEFAULT_DURATION) if span > 0 else 1.0
        if not (isinstance(duration, (int, float)) and np.isfinite(duration) and duration > 0):
            raise LagcodegenError(f"duration must be a positive number of seconds, got {duration!r}")
        frames = max(2, int(round(fps * duration)))
    elif isinstance(frames, bool) or not isinstance(frames, (int, np.integer)) or frames < 1:
        raise LagcodegenError(f"frames must be a positive integer, got {frames!r}")
    if frames > MAX_FRAMES:
        raise LagcodegenError(f"{frames} frames: at most {MAX_FRAMES} (lower fps, duration or frames)")
    return np.linspace(t[0], t[-1], int(frames))


def frame_pixels(size, dpi) -> tuple[tuple[float, float], float]:
    """(size in inches with even pixel sizes, as video codecs want them; dpi) of a frame, or a
    LagcodegenError naming ``size`` or ``dpi`` when they are not positive finite numbers or make
    a frame of fewer than 2 or more than :data:`MAX_PIXELS` pixels a side."""
    def number(v) -> bool:
        return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool) and np.isfinite(v) \
            and v > 0
    if not number(dpi):
        raise LagcodegenError(f"dpi must be a positive number of dots per inch, got {excerpt(dpi)}")
    try:
        width, height = size
    except (TypeError, ValueError):
        raise LagcodegenError(f"size must be (width, height) in inches, got {excerpt(size)}") from None
    if not (number(width) and number(height)):
        raise LagcodegenError(f"size must be (width, height), two positive numbers of inches, got {excerpt(size)}")
    pixels = [2 * round(float(v) * dpi / 2) for v in (width, height)]
    if not all(2 <= p <= MAX_PIXELS for p in pixels):
        raise LagcodegenError(f"size {excerpt(size)} at dpi {excerpt(dpi)} makes frames of {pixels[0]} x {pixels[1]} "
                              f"pixels: each side must be 2 to {MAX_PIXELS}")
    return (pixels[0] / dpi, pixels[1] / dpi), float(dpi)


def at_times(t: np.ndarray, track: np.ndarray, times: np.ndarray) -> np.ndarray:
    """``track`` (N, dim) linearly interpolated at ``times`` (exact where a time is an output time)."""
    return np.column_stack([np.interp(times, t, track[:, k]) for k in range(track.shape[1])])


class Animator:
    """The figure of an animation and its update: ``draw(k)`` puts frame k (model time
    ``times[k]``) into the artists. ``links``, ``points``, ``trails`` hold the artists by name."""

    def __init__(self, drawing: Drawing, t: np.ndarray, positions: Mapping[str, np.ndarray], times: np.ndarray, *,
                 trail: bool | float = False, title: str = "", size: tuple[float, float] = (5.0, 5.0),
                 dpi: float = 80):
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure

        self.drawing, self.times = drawing, np.asarray(times, dtype=float)
        self.dim = drawing.dim
        t = np.asarray(t, dtype=float)
        pad = (lambda a: np.column_stack([a, np.zeros(len(a))]) if a.shape[1] < self.dim else a)
        self.full = {p: pad(np.asarray(x, dtype=float)) for p, x in positions.items()}
        self.frames = {p: at_times(t, x, self.times) for p, x in self.full.items()}
        self.pivots = {n: np.array(list(v) + [0.0] * (self.dim - len(v)), dtype=float)
                       for n, v in drawing.pivots.items()}
        self.trail = trail
        self.t = t
        self.fig = Figure(figsize=size, dpi=dpi)
        FigureCanvasAgg(self.fig)
        if self.dim == 3:
            self.ax = self.fig.add_subplot(projection="3d")
        else:
            self.ax = self.fig.add_subplot()
        self.ax.set_title(title or drawing.name)
        self._limits()
        moving = [p for p in drawing.points if p not in drawing.fixed]
        self.links = {}
        for a, b in drawing.links:
            (line,) = self.ax.plot(*([[0, 0]] * self.dim), color="0.25", lw=2, zorder=2, animated=True)
            self.links[(a, b)] = line
        self.springs = {}
        for a, b in drawing.springs:
            (line,) = self.ax.plot(*([[0, 0]] * self.dim), color="tab:olive", lw=1.2, zorder=2, animated=True)
            self.springs[(a, b)] = line
        self.axes_lines = {}
        for tip, (body, axis) in drawing.body_axes.items():
            if tip in self.full and body in self.full:
                (line,) = self.ax.plot(*([[0, 0]] * self.dim), color={"x": "tab:red", "y": "tab:green"}.get(
                    axis, "tab:blue"), lw=2, zorder=2, animated=True)
                self.axes_lines[tip] = line
        self.trails = {}
        if trail:
            for i, p in enumerate(moving):
                (line,) = self.ax.plot(*([[]] * self.dim), color=f"C{i % 10}", lw=1, alpha=0.5, zorder=1,
                                       animated=True)
                self.trails[p] = line
        self.points = {}
        for i, p in enumerate(moving):
            (line,) = self.ax.plot(*([[0]] * self.dim), "o", color=f"C{i % 10}", ms=10, zorder=3, label=p,
                                   animated=True)
            self.points[p] = line
        for p in list(drawing.fixed) + list(self.pivots):
            x = self.pivots[p] if p in self.pivots else self.full[p][0]
            self.ax.plot(*[[c] for c in x], "s", color="k", ms=7, zorder=3)
        text = self.ax.text if self.dim == 2 else self.ax.text2D
        self.clock = text(0.02, 0.96, "", transform=self.ax.transAxes, va="top", animated=True)
        self.background = None

    def _limits(self) -> None:
        pts = [x for x in self.full.values()] + [v[None, :] for v in self.pivots.values()]
        allp = np.vstack(pts) if pts else np.zeros((1, self.dim))
        allp = allp[np.isfinite(allp).all(axis=1)]  # a failed run's last rows may be NaN
        if not allp.size:
            allp = np.zeros((1, self.dim))
        lo, hi = allp.min(axis=0), allp.max(axis=0)
        centre, half = (lo + hi) / 2, max(float((hi - lo).max()) / 2, 1e-9) * 1.1
        self.spring_width = SPRING_WIDTH * half
        ax = self.ax
        ax.set_xlim(centre[0] - half, centre[0] + half)
        ax.set_ylim(centre[1] - half, centre[1] + half)
        if self.dim == 3:
            ax.set_zlim(centre[2] - half, centre[2] + half)
            ax.set_box_aspect((1, 1, 1))
            ax.set_xlabel("x")
            ax.set_ylabel("y")
            ax.set_zlabel("z")
        else:
            ax.set_aspect("equal")
            ax.set_xlabel("x")
            ax.set_ylabel("y")
            ax.grid(alpha=0.3)

    def position(self, name: str, k: int) -> np.ndarray:
        """Position of point or pivot ``name`` in frame ``k``."""
        if name in self.pivots:
            return self.pivots[name]
        return self.frames[name][k]

    def _set(self, line, xyz: np.ndarray) -> None:
        """Put points (m, dim) into a line artist."""
        if self.dim == 3:
            line.set_data_3d(xyz[:, 0], xyz[:, 1], xyz[:, 2])
        else:
            line.set_data(xyz[:, 0], xyz[:, 1])

    def draw(self, k: int) -> list:
        """Frame ``k``: every artist updated; returns them."""
        for (a, b), line in self.links.items():
            self._set(line, np.vstack([self.position(a, k), self.position(b, k)]))
        for (a, b), line in self.springs.items():
            self._set(line, zigzag(self.position(a, k), self.position(b, k), self.spring_width))
        for tip, line in self.axes_lines.items():
            self._set(line, np.vstack([self.frames[self.drawing.body_axes[tip][0]][k], self.frames[tip][k]]))
        for p, line in self.points.items():
            self._set(line, self.frames[p][k][None, :])
        tk = self.times[k]
        for p, line in self.trails.items():
            first = self.t[0] if self.trail is True else tk - float(self.trail)
            sel = (self.t >= first) & (self.t <= tk)
            self._set(line, np.vstack([self.full[p][sel], self.frames[p][k][None, :]]))
        self.clock.set_text(f"t = {tk:.3g}")
        return [*self.links.values(), *self.springs.values(), *self.axes_lines.values(), *self.points.values(), *self.trails.values(),
                self.clock]

    def render(self, k: int) -> np.ndarray:
        """Frame ``k`` as an RGBA image (height, width, 4): the static part (axes, pivots) drawn
        once, then only the moving artists on top of it (blitting: a frame costs the moving
        artists, not the axes' ticks and labels)."""
        canvas = self.fig.canvas
        if self.background is None:
            canvas.draw()
            self.background = canvas.copy_from_bbox(self.fig.bbox)
        canvas.restore_region(self.background)
        for artist in self.draw(k):
            self.ax.draw_artist(artist)
        return np.asarray(canvas.buffer_rgba())

    def pixel(self, xy) -> tuple[float, float]:
        """Pixel (column, row from the top) of a 2-D data point in the rendered frames."""
        x, y = self.ax.transData.transform(np.asarray(xy, dtype=float)[:2])
        return float(x), float(self.fig.bbox.height - y)

    def data(self, line) -> np.ndarray:
        """The points (m, dim) a line artist holds (for checks)."""
        if self.dim == 3:
            return np.column_stack(line.get_data_3d())
        return np.column_stack(line.get_data())


def zigzag(a: np.ndarray, b: np.ndarray, width: float, coils: int = SPRING_COILS) -> np.ndarray:
    """The points (2 coils + 4, dim) of a spring drawn from ``a`` to ``b``: straight ends of a
    tenth of its length each, ``coils`` zigzags of half-width ``width`` between them,
    perpendicular to a-b (in 3-D, in the plane of a-b and the axis it is least aligned with)."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    d = b - a
    length = float(np.linalg.norm(d))
    if length == 0.0 or not np.isfinite(length):
        return np.vstack([a, b])
    u = d / length
    other = np.zeros_like(u)
    other[int(np.argmin(np.abs(u)))] = 1.0
    n = other - u * float(other @ u)
    n /= np.linalg.norm(n)
    s = np.linspace(0.1, 0.9, 2 * coils + 1)
    side = np.where(np.arange(s.size) % 2 == 1, 1.0, 0.0) * np.where(np.arange(s.size) % 4 == 1, 1.0, -1.0)
    middle = a + np.outer(s, d) + np.outer(side * width, n)
    return np.vstack([a, middle, b])


class _Frame:
    """What matplotlib's movie writers see as the figure: its size, and ``savefig`` handing
    over the current blitted frame (raw RGBA, or PNG for the HTML player) instead of drawing
    the whole figure again."""

    def __init__(self, animator: Animator):
        self.animator = animator
        self.image: np.ndarray | None = None
        self.dpi = animator.fig.dpi

    def get_size_inches(self):
        return self.animator.fig.get_size_inches()

    def set_size_inches(self, *args, **kwargs) -> None:
        pass  # the frames keep the figure's size

    def savefig(self, fh, format: str = "png", **kwargs) -> None:  # noqa: A002 - matplotlib's name
        if format in ("rgba", "raw"):
            fh.write(self.image.tobytes())
            return
        from PIL import Image
        Image.fromarray(self.image[:, :, :3].copy()).save(fh, format=format.upper())


def _gif_writer(fps: float):
    """matplotlib's PillowWriter, whose frames share one palette (made once from a few frames
    and mapped without dithering: a few ms a frame, where Pillow would quantize each frame on
    its own, tens of ms)."""
    from matplotlib import animation
    from PIL import Image

    class SharedPaletteWriter(animation.PillowWriter):
        def finish(self):
            frames = self._frames
            if frames and all(f.mode == "RGB" for f in frames):
                picks = frames[:: max(1, len(frames) // 8)][:8]
                w, h = picks[0].size
                mosaic = Image.new("RGB", (w, h * len(picks)))
                for i, f in enumerate(picks):
                    mosaic.paste(f, (0, h * i))
                palette = mosaic.quantize(colors=255, dither=Image.Dither.NONE)
                self._frames = [f.quantize(palette=palette, dither=Image.Dither.NONE) for f in frames]
            super().finish()

    return SharedPaletteWriter(fps=fps)


def ffmpeg_available() -> bool:
    """True if matplotlib finds ffmpeg (MP4 output)."""
    from matplotlib import animation
    return animation.writers.is_available("ffmpeg")


def animate(path: str | os.PathLike, drawing: Drawing, t: np.ndarray, positions: Mapping[str, np.ndarray], *,
            fps: float = 25, duration: float | None = None, frames: int | None = None, trail: bool | float = False,
            title: str = "", size: tuple[float, float] = (5.0, 5.0), dpi: float = 80) -> Path:
    """Write the animation of ``positions`` ({point: (N, dim)} at the times ``t``) to ``path``,
    atomically: ``.gif`` (matplotlib's PillowWriter), ``.mp4`` (its FFMpegWriter) or ``.html``
    (its HTMLWriter with embedded frames: the player of ``to_jshtml``). Frames: see
    :func:`frame_times`; ``trail``: True the whole path behind each moving point, a number the
    last that many units of model time."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in FORMATS:
        raise LagcodegenError(f"{path}: animations are written as {', '.join(FORMATS)}")
    if not path.parent.is_dir():
        raise LagcodegenError(f"{path}: the folder {path.parent} does not exist")
    if suffix == ".mp4" and not ffmpeg_available():
        raise LagcodegenError(f"{path}: MP4 needs ffmpeg, which is not installed here: write a .gif or .html")
    if isinstance(trail, bool) or (isinstance(trail, (int, float)) and np.isfinite(trail) and trail >= 0):
        pass
    else:
        raise LagcodegenError(f"trail must be True, False or a length of model time >= 0, got {trail!r}")
    times = frame_times(t, fps=fps, duration=duration, frames=frames)
    size, dpi = frame_pixels(size, dpi)
    anim = Animator(drawing, t, positions, times, trail=trail, title=title, size=size, dpi=dpi)
    from matplotlib import animation

    if suffix == ".gif":
        writer = _gif_writer(fps)
    elif suffix == ".mp4":
        writer = animation.FFMpegWriter(fps=fps)
    else:
        writer = animation.HTMLWriter(fps=fps, embed_frames=True, default_mode="loop")
    frame = _Frame(anim)
    with staged_outputs([path]) as staged:  # the movie appears whole or not at all
        tmp = str(staged[path])
        writer.setup(frame, tmp, dpi=anim.fig.dpi)
        try:
            for k in range(len(times)):
                frame.image = anim.render(k)
                writer.grab_frame()
        finally:
            writer.finish()
    return path
