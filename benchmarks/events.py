"""Event location on the ODE of a scene: error and run time of every way to find the pendulum's
zero crossings, against the elliptic-integral period.

The pendulum (lagcodegen.systems.pendulum, l = 1, g = 9.81) released at rest from theta0 = 2.0
crosses theta = 0 at (2j + 1) T/4, T = 4 K(k) sqrt(l/g), k = sin(theta0/2) (scipy's ellipk): 15
crossings over t in [0, 20], all located by a non-terminal event on theta with two output
times. Contenders, each at rtol = 1e-6 ... 1e-12 (atol = rtol/100):

* ``CVODE Adams (native)``, ``CVODE BDF (native)``: lcg_cvode_solve_events, the event function
  compiled (lagcodegen.solvers.cvode.events), CVODE's root finding;
* ``CVODE Adams (sksundae)``: scikit-sundae's eventsfn on the same compiled functions;
* ``Taylor``: roots of each step's polynomial;
* ``scipy DOP853 events (cm.rhs)``: scipy.integrate.solve_ivp with an event function, on the
  compiled right-hand side called from Python (cm.rhs) -- a user's loop with the same C.

Reported per run: the largest relative error of the 15 crossing times, the number found, and the
wall time of one run (median over interleaved rounds: every contender once per round). The run
time of the same CVODE run without events is given for the cost of root finding. The 1-minute
load average at start and end is printed: other work on the machine stretches the times.

This is a measuring instrument: it asserts nothing about the times it reports.

Usage::

    python benchmarks/events.py [--quick] [--out DIR]
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import time
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp
from scipy.special import ellipk

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _harness as H  # noqa: E402

import lagcodegen as lcg  # noqa: E402

THETA0, T_END, G, L = 2.0, 20.0, 9.81, 1.0


def exact_crossings() -> np.ndarray:
    T = 4 * ellipk(math.sin(THETA0 / 2) ** 2) * math.sqrt(L / G)
    j = np.arange(int(T_END / (T / 2)) + 2)
    t = (2 * j + 1) * T / 4
    return t[t <= T_END]


def contenders(sim):
    """name -> function(rtol) returning the crossing times found."""
    event = [lcg.Event("zero", "theta", 0, False)]
    t = np.array([0.0, T_END])

    def lcg_run(**opts):
        def run(rtol):
            res = sim.simulate(t, q0=[THETA0], events=event, rtol=rtol, atol=rtol / 100, **opts)
            return np.array([e.t for e in res.events])
        return run

    def plain(rtol):
        sim.simulate(t, q0=[THETA0], rtol=rtol, atol=rtol / 100)
        return None

    p = sim.parameter_vector()

    def scipy_run(rtol):
        def g(_t, y):
            return y[0]
        g.terminal = False
        sol = solve_ivp(lambda tt, y: sim.rhs(tt, y, p), (0.0, T_END), [THETA0, 0.0], method="DOP853", rtol=rtol,
                        atol=rtol / 100, events=g)
        return np.asarray(sol.t_events[0])

    return {"CVODE Adams (native)": lcg_run(), "CVODE BDF (native)": lcg_run(method="bdf"),
            "CVODE Adams (sksundae)": lcg_run(backend="sksundae"), "Taylor": lcg_run(method="taylor"),
            "scipy DOP853 events (cm.rhs)": scipy_run, "CVODE Adams, no events": plain}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="rtol 1e-6, 1e-9, 1e-12; 3 rounds")
    ap.add_argument("--out", type=Path, help="write DIR/events.txt and DIR/events.csv")
    args = ap.parse_args(argv)
    rtols = [1e-6, 1e-9, 1e-12] if args.quick else [1e-6, 1e-8, 1e-10, 1e-12]
    rounds = 3 if args.quick else 7
    load_start = H.load_average()
    sim = lcg.compile_model(lcg.systems.pendulum("bench_events"))
    runs = contenders(sim)
    for run in runs.values():  # build everything first (event libraries, the Taylor jet)
        run(1e-6)
    exact = exact_crossings()
    times = {(name, rtol): [] for name in runs for rtol in rtols}
    found = {}
    for _ in range(rounds):  # interleaved: every contender once per round
        for rtol in rtols:
            for name, run in runs.items():
                start = time.perf_counter()
                found[name, rtol] = run(rtol)
                times[name, rtol].append(time.perf_counter() - start)
    rows = []
    for name in runs:
        for rtol in rtols:
            ts = found[name, rtol]
            row = dict(contender=name, rtol=rtol, ms=1e3 * statistics.median(times[name, rtol]))
            if ts is not None:
                row["found"] = len(ts)
                row["max_rel_err"] = (float(np.max(np.abs(ts - exact) / exact)) if len(ts) == len(exact)
                                      else math.nan)
            rows.append(row)
    lines = H.machine_lines("Event location: pendulum zero crossings (benchmarks/events.py)",
                            (load_start, H.load_average()))
    lines += [f"theta0 = {THETA0}, t in [0, {T_END}], {len(exact)} crossings; atol = rtol/100; median of "
              f"{rounds} interleaved rounds", ""]
    lines.append(H.format_table([("contender", "contender", "{}"), ("rtol", "rtol", "{:.0e}"),
                                 ("ms", "ms/run", "{:.3f}"), ("found", "found", "{}"),
                                 ("max_rel_err", "max rel. error", "{:.1e}")], rows))
    text = "\n".join(lines)
    print(text)
    if args.out:
        H.write_report(args.out, "events", text, rows)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
