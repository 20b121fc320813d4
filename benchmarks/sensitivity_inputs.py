"""Forward sensitivities of runs driven by input tables, on CVODE and on the Taylor method: their
accuracy against a second integrator and what they cost over the plain table-driven run.

The damped oscillator m x'' + c x' + k x = F(t) (m = 1, k = 4, c = 0.4, x(0) = 0.3) driven by a
piecewise-linear force table with kinks at t = 1, 2.5, 4, over t in [0, 8] (161 output times);
sensitivities to k, c and x(0). The reference is scipy's DOP853 at rtol 1e-13 on the augmented
ODE (x, v and each direction's s, s'), restarted at each kink. Each family runs at rtol = 1e-6
... 1e-12 (atol = rtol/100); reported: the largest error of dx/d(direction) relative to its
largest magnitude, and the wall time of one sensitivity run and of the plain run with the same
table (medians over interleaved rounds: every run once per round). The 1-minute load average at
start and end is printed: other work on the machine stretches the times.

This is a measuring instrument: it asserts nothing about the times it reports.

Usage::

    python benchmarks/sensitivity_inputs.py [--quick] [--out DIR]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _harness as H  # noqa: E402

import lagcodegen as lcg  # noqa: E402

M, K, C, X0 = 1.0, 4.0, 0.4, 0.3
TIMES, VALUES = [0.0, 1.0, 2.5, 4.0, 6.0], [0.0, 1.5, -0.5, 1.0, 1.0]
NAMES = ["k", "c", "x(0)"]


def oscillator():
    """m x'' + c x' + k x = F, the force F an input (lagcodegen.systems.forced_oscillator)."""
    return lcg.systems.forced_oscillator("bench_sens_inputs", m=M, k=K, c=C)


def reference(t: np.ndarray, table) -> np.ndarray:
    """dx/d(k, c, x(0)) at ``t`` (nt, 3) from DOP853 on the augmented ODE, restarted at the kinks."""
    def f(tt, z):
        x, v, sk, vk, sc, vc, s0, v0 = z
        return [v, (table(tt) - C * v - K * x) / M, vk, (-x - C * vk - K * sk) / M,
                vc, (-v - C * vc - K * sc) / M, v0, (-C * v0 - K * s0) / M]
    edges = [t[0], *[b for b in TIMES if t[0] < b < t[-1]], t[-1]]
    z = np.array([X0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0])
    out = np.empty((t.size, 8))
    for a, b in zip(edges[:-1], edges[1:]):
        sel = (t >= a) & (t <= b)
        sol = solve_ivp(f, (a, b), z, method="DOP853", rtol=1e-13, atol=1e-15, t_eval=t[sel], dense_output=True)
        out[sel] = sol.y.T
        z = sol.sol(b)
    return out[:, [2, 4, 6]]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="rtol 1e-6, 1e-9, 1e-12; 3 rounds")
    ap.add_argument("--out", type=Path, help="write DIR/sensitivity_inputs.txt and .csv")
    args = ap.parse_args(argv)
    rtols = [1e-6, 1e-9, 1e-12] if args.quick else [1e-6, 1e-8, 1e-10, 1e-12]
    rounds = 3 if args.quick else 9
    load_start = H.load_average()
    sim = lcg.compile_model(oscillator())
    table = lcg.Table(TIMES, VALUES)
    t = np.linspace(0.0, 8.0, 161)
    s_ref = reference(t, table)
    cases = {}
    for method in ("adams", "taylor"):
        for rtol in rtols:
            opts = dict(q0=[X0], inputs={"F": table}, method=method, rtol=rtol, atol=rtol / 100)
            cases[method, rtol] = {"sens": lambda o=opts: sim.simulate(t, sensitivities=NAMES, **o),
                                   "plain": lambda o=opts: sim.simulate(t, **o)}
    found = {key: fns["sens"]() for key, fns in cases.items()}  # builds everything first
    med = H.timed_medians({(key, name): fn for key, fns in cases.items() for name, fn in fns.items()}, rounds,
                          "inputs")[0]  # wall-time medians of interleaved rounds
    rows = []
    for (method, rtol), res in found.items():
        err = np.max(np.abs(res.sensitivities[:, :, 0] - s_ref), axis=0) / np.max(np.abs(s_ref), axis=0)
        row = dict(method="CVODE Adams" if method == "adams" else "Taylor", rtol=rtol,
                   max_rel_err=float(np.max(err)), steps=int(res.stats["steps"]),
                   ms_sens=1e3 * med[(method, rtol), "sens"],
                   ms_plain=1e3 * med[(method, rtol), "plain"])
        row["ratio"] = row["ms_sens"] / row["ms_plain"]
        rows.append(row)
    lines = H.machine_lines("Sensitivities of table-driven runs: forced oscillator "
                            "(benchmarks/sensitivity_inputs.py)", (load_start, H.load_average()))
    lines += [f"t in [0, 8], 161 outputs, kinks at 1, 2.5, 4; sensitivities {', '.join(NAMES)}; "
              f"atol = rtol/100; median of {rounds} interleaved rounds", ""]
    lines.append(H.format_table([("method", "method", "{}"), ("rtol", "rtol", "{:.0e}"), ("steps", "steps", "{}"),
                                 ("max_rel_err", "max rel. error of dx/dtheta", "{:.1e}"),
                                 ("ms_sens", "ms/run with sens.", "{:.3f}"),
                                 ("ms_plain", "ms/plain run", "{:.3f}"), ("ratio", "ratio", "{:.2f}")], rows))
    text = "\n".join(lines)
    print(text)
    if args.out:
        H.write_report(args.out, "sensitivity_inputs", text, rows)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
