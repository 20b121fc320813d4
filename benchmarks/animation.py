"""Time to write an animation (issue 27: "watching a double pendulum swing takes 12 lines of
matplotlib and 17 s").

The double pendulum, t in [0, 10], 251 output times, drawn at 25 frames per second for 10 s (250
frames, 400 x 400 pixels):

* ``res.animate(gif)``: lagcodegen's animation (the static axes drawn once, each frame only the
  moving artists; GIF frames sharing one palette);
* ``res.animate(html)``: the same frames into the HTML player;
* ``matplotlib FuncAnimation``: what a user writes by hand, a FuncAnimation updating two lines
  and saved with PillowWriter (the whole figure drawn and quantized for every frame).

The contenders run round-robin, ``--rounds`` times (medians); the load average is printed. This is
a measuring instrument: it asserts nothing.

Usage::

    python benchmarks/animation.py [--quick] [--rounds N] [--out DIR]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _harness as H  # noqa: E402

TAG = "animation"


def by_hand(res, path: Path, frames: int, fps: int) -> None:
    """The user's 12 lines: a FuncAnimation of the two rods, saved with PillowWriter."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.animation import FuncAnimation, PillowWriter

    x1, y1 = np.sin(res["theta1"]), -np.cos(res["theta1"])
    x2, y2 = x1 + np.sin(res["theta2"]), y1 - np.cos(res["theta2"])
    idx = np.linspace(0, len(res.t) - 1, frames).round().astype(int)
    fig, ax = plt.subplots(figsize=(5, 5), dpi=80)
    ax.set_xlim(-2.2, 2.2)
    ax.set_ylim(-2.2, 2.2)
    ax.set_aspect("equal")
    (line,) = ax.plot([], [], "o-", lw=2)

    def update(k):
        i = idx[k]
        line.set_data([0, x1[i], x2[i]], [0, y1[i], y2[i]])
        return (line,)

    FuncAnimation(fig, update, frames=frames).save(path, writer=PillowWriter(fps=fps))
    plt.close(fig)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="50 frames, one round")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--out", type=Path, default=Path("benchmarks/results"))
    args = ap.parse_args(argv)
    import lagcodegen as lcg

    frames, fps = (50, 25) if args.quick else (250, 25)
    rounds = 1 if args.quick else args.rounds
    load0 = H.load_average()
    res = lcg.compile_model(lcg.systems.double_pendulum()).simulate(np.linspace(0, 10, 251), q0=[1.2, -0.4])
    contenders = {
        "res.animate(gif)": lambda p: res.animate(p / "a.gif", frames=frames, fps=fps),
        "res.animate(html)": lambda p: res.animate(p / "a.html", frames=frames, fps=fps),
        "matplotlib FuncAnimation": lambda p: by_hand(res, p / "b.gif", frames, fps),
    }
    times: dict[str, list[float]] = {name: [] for name in contenders}
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(rounds):
            for name, run in contenders.items():
                H.progress(TAG, f"{name}, {frames} frames")
                start = time.perf_counter()
                run(Path(tmp))
                times[name].append(time.perf_counter() - start)
    rows = [{"contender": name, "frames": frames, "median_s": statistics.median(t), "rounds": len(t)}
            for name, t in times.items()]
    text = "\n".join(H.machine_lines("Writing an animation of the double pendulum", (load0, H.load_average()))
                     + ["", H.format_table([("contender", "contender", "{}"), ("frames", "frames", "{}"),
                                            ("median_s", "median s", "{:.2f}")], rows)])
    print(text)
    H.write_report(args.out, TAG, text, rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
