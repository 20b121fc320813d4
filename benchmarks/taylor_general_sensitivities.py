"""Forward sensitivities of models with generalized speeds on the Taylor method against CVODE
(issue 37: "forward sensitivities (directions in the tangent space for quaternions)").

Scene: the tumbling free body of benchmarks/generalized_speeds.py's kind (principal moments 1, iy
= 2, 3 on ``Joint.free``, spun about its middle axis with a small perturbation, through attitudes
where Z-Y-X angles are singular), t in [0, 10], 21 output times. Directions: the run-time moment
``iy``, the speed ``root_wx(0)`` and the rotations ``root_rx(0)``, ``root_rz(0)``.

For each method (taylor, adams, bdf) and rtol 1e-8, 1e-10, 1e-12 (atol rtol/10): the error of
the sensitivities against CVODE (BDF) at rtol 1e-13 (max over times, states and directions of
|error| / max |reference| per direction), the steps, and the calling thread's CPU time per run
(median of rounds, the libraries built beforehand). The reference's own error is about 2e-11
(Taylor at every rtol and Adams at 1e-12 agree with it to that level and not beyond). Measured
(2 shared cores): Taylor 12-13 steps, 0.35-0.46 ms, 2e-11 .. 1e-10 at every rtol; Adams 134-255
steps, 0.46-0.81 ms, 3e-7 (1e-8) .. 4e-11 (1e-12); BDF 174-768 steps, 0.55-1.9 ms. A measuring
instrument: it asserts nothing.

Usage::

    python benchmarks/taylor_general_sensitivities.py [--rounds R] [--quick] [--out DIR]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

import lagcodegen as lcg

NAMES = ["iy", "root_wx(0)", "root_rx(0)", "root_rz(0)"]


def tumbler():
    m = lcg.Model("bench_tgs_tumbler")
    iy, = m.parameters(iy=2.0)
    m.link("body", joint=lcg.Joint.free("root"), mass=1.0, inertia=(1.0, iy, 3.0))
    return m


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--quick", action="store_true", help="rtol 1e-10 only, one round")
    ap.add_argument("--out", default=None, help="also write the table to DIR/taylor_general_sensitivities.txt")
    args = ap.parse_args(argv)
    rounds = 1 if args.quick else args.rounds
    lines = []
    cm = lcg.compile_model(tumbler(), runtime_parameters=["iy"])
    t = np.linspace(0.0, 10.0, 21)
    q0 = np.r_[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]
    v0 = np.r_[0.1, 0.0, 0.0, 0.01, 1.0, 0.01]
    ref = cm.simulate(t, q0=q0, v0=v0, method="bdf", sensitivities=NAMES, rtol=1e-13, atol=1e-14)
    S = ref.sensitivities
    lines.append(f"tumbling free body, t in [0, 10], directions {', '.join(NAMES)}; reference BDF rtol 1e-13")
    lines.append(f"{'method':8s} {'rtol':>7s} {'steps':>7s} {'CPU ms':>9s}  error per direction")
    print("\n".join(lines))
    for rtol in ((1e-10,) if args.quick else (1e-8, 1e-10, 1e-12)):
        for method in ("taylor", "adams", "bdf"):
            opts = dict(q0=q0, v0=v0, method=method, sensitivities=NAMES, rtol=rtol, atol=rtol / 10)
            res = cm.simulate(t, **opts)  # built, and the fast path prepared
            times = []
            for _ in range(rounds):
                start = time.thread_time()
                cm.simulate(t, **opts)
                times.append(time.thread_time() - start)
            err = [np.abs(res.sensitivities[:, j] - S[:, j]).max() / np.abs(S[:, j]).max() for j in range(len(NAMES))]
            lines.append(f"{method:8s} {rtol:7.0e} {res.stats['steps']:7d} {1e3 * np.median(times):9.3f}  "
                         + " ".join(f"{e:8.1e}" for e in err))
            print(lines[-1])
    if args.out:
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        (out / "taylor_general_sensitivities.txt").write_text("\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
