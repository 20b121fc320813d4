"""Events in runs with forward sensitivities: the accuracy of the event times' sensitivities on
CVODE and on the Taylor method against the pendulum's closed form, and what the events cost a
sensitivity run.

The pendulum (lagcodegen.systems.pendulum, l = 1, g = 9.81) released at rest from theta0 = 2.0
crosses theta = 0 at t_j = (2j + 1) T/4, T = 4 K(k) sqrt(l/g), k = sin(theta0/2): 15 crossings
over t in [0, 20], located by a non-terminal event on theta. Their sensitivities in closed form:
dt_j/dl = t_j/(2l), dt_j/dg = -t_j/(2g), dt_j/dtheta0 = (2j + 1) sqrt(l/g) K'(k) cos(theta0/2)/2
with K'(k) = E(k)/(k (1 - k^2)) - K(k)/k (scipy's ellipk, ellipe take m = k^2). Each family
runs ``sensitivities=["l", "g", "theta(0)"]`` at rtol = 1e-6 ... 1e-12 (atol = rtol/100);
reported: the largest relative error of the 45 time sensitivities, and the wall time of one run
with the event and of the same run without it (medians over interleaved rounds: every run once
per round). The 1-minute load average at start and end is printed: other work on the machine
stretches the times.

This is a measuring instrument: it asserts nothing about the times it reports.

Usage::

    python benchmarks/sensitivity_events.py [--quick] [--out DIR]
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np
from scipy.special import ellipe, ellipk

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _harness as H  # noqa: E402

import lagcodegen as lcg  # noqa: E402

THETA0, T_END, G, L = 2.0, 20.0, 9.81, 1.0
NAMES = ["l", "g", "theta(0)"]


def exact() -> tuple[np.ndarray, np.ndarray]:
    """(crossing times (J,), their sensitivities (J, 3) along NAMES) in closed form."""
    k = math.sin(THETA0 / 2)
    K, E = ellipk(k * k), ellipe(k * k)
    T = 4 * K * math.sqrt(L / G)
    j = np.arange(int(T_END / (T / 2)) + 2)
    t = (2 * j + 1) * T / 4
    j, t = j[t <= T_END], t[t <= T_END]
    dK = E / (k * (1 - k * k)) - K / k
    dtheta = (2 * j + 1) * math.sqrt(L / G) * dK * math.cos(THETA0 / 2) / 2
    return t, np.column_stack([t / (2 * L), -t / (2 * G), dtheta])


def runs(sim, method: str, rtol: float) -> dict:
    """name -> function() of the runs with and without the event, returning the Result."""
    t = np.array([0.0, T_END])
    event = [lcg.Event("zero", "theta", 0, False)]
    opts = dict(q0=[THETA0], sensitivities=NAMES, method=method, rtol=rtol, atol=rtol / 100)
    return {"with the event": lambda: sim.simulate(t, events=event, **opts),
            "without": lambda: sim.simulate(t, **opts)}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="rtol 1e-6, 1e-9, 1e-12; 3 rounds")
    ap.add_argument("--out", type=Path, help="write DIR/sensitivity_events.txt and .csv")
    args = ap.parse_args(argv)
    rtols = [1e-6, 1e-9, 1e-12] if args.quick else [1e-6, 1e-8, 1e-10, 1e-12]
    rounds = 3 if args.quick else 7
    load_start = H.load_average()
    sim = lcg.compile_model(lcg.systems.pendulum("bench_sens_events"))
    t_exact, s_exact = exact()
    cases = {(m, rtol): runs(sim, m, rtol) for m in ("bdf", "taylor") for rtol in rtols}
    found = {key: fns["with the event"]() for key, fns in cases.items()}  # builds everything first
    med = H.timed_medians({(key, name): fn for key, fns in cases.items() for name, fn in fns.items()}, rounds,
                          "events")[0]  # wall-time medians of interleaved rounds
    rows = []
    for (method, rtol), res in found.items():
        row = dict(method="CVODE BDF" if method == "bdf" else "Taylor", rtol=rtol, found=len(res.events),
                   ms_events=1e3 * med[(method, rtol), "with the event"],
                   ms_plain=1e3 * med[(method, rtol), "without"])
        row["ratio"] = row["ms_events"] / row["ms_plain"]
        if len(res.events) == len(t_exact):
            got = np.array([[e.t_sensitivity[n] for n in NAMES] for e in res.events])
            row["max_rel_err"] = float(np.max(np.abs(got - s_exact) / np.abs(s_exact)))
        else:
            row["max_rel_err"] = math.nan
        rows.append(row)
    lines = H.machine_lines("Events in sensitivity runs: pendulum zero crossings (benchmarks/sensitivity_events.py)",
                            (load_start, H.load_average()))
    lines += [f"theta0 = {THETA0}, t in [0, {T_END}], {len(t_exact)} crossings, sensitivities {', '.join(NAMES)}; "
              f"atol = rtol/100; median of {rounds} interleaved rounds", ""]
    lines.append(H.format_table([("method", "method", "{}"), ("rtol", "rtol", "{:.0e}"), ("found", "found", "{}"),
                                 ("max_rel_err", "max rel. error of dt_j", "{:.1e}"),
                                 ("ms_events", "ms/run with event", "{:.3f}"),
                                 ("ms_plain", "ms/run without", "{:.3f}"), ("ratio", "ratio", "{:.2f}")], rows))
    text = "\n".join(lines)
    print(text)
    if args.out:
        H.write_report(args.out, "sensitivity_events", text, rows)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
