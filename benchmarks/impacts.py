"""Impacts: the impact driver against a scipy solve_ivp event loop on the same compiled
right-hand side.

A ball dropped from h0 = 1 onto a floor with restitution e = 0.8 (the contact y >= 0,
lagcodegen.Inequality) over its first N impacts (N = 20; t_end just past impact N, before the
accumulation). Impact k comes at t1 + 2 t1 e (1 - e^k)/(1 - e), t1 = sqrt(2 h0/g), so the
event-location error is exact: the largest relative error of the N impact times.

* lagcodegen: ``simulate`` of the compiled system: CVODE (Adams) with root finding, the impulse
  applied in the generated C and CVODE reinitialized, in one call of the impact driver;
* scipy:      ``solve_ivp`` (DOP853 and LSODA) with a terminal event y = 0 (direction -1),
  restarted after each event with y' -> -e y' by a Python loop; its right-hand side calls the
  same compiled function (the model's augmented-system solve, ``kkt``, through its table).

Columns per tolerance rtol (atol = rtol / 100): the event-location error and the median wall
time of each, and the ratios scipy / lagcodegen side by side. Rounds interleave the runs; the
machine's load is printed with the table. This is a measuring instrument: it asserts nothing.

Usage::

    python benchmarks/impacts.py [--quick] [--repeats N] [--out DIR]
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import time
from pathlib import Path

import numpy as np
import sympy as sp
from scipy.integrate import solve_ivp

import lagcodegen as lcg
from lagcodegen.api import compile_constrained

import _harness  # noqa: E402  (benchmarks/ is on sys.path when run as a script)

E, H0, G, N = 0.8, 1.0, 9.81, 20
T1 = math.sqrt(2 * H0 / G)
EXACT = np.array([T1 + 2 * T1 * E * (1 - E**k) / (1 - E) for k in range(N)])
T_END = 0.5 * (EXACT[-1] + T1 + 2 * T1 * E * (1 - E**N) / (1 - E))  # between impacts N and N + 1


def ball():
    m = lcg.Model("bench_ball")
    (y,) = m.coordinates("y")
    m.parameters(g=G, m=1.0)
    m.particle("ball", sp.Symbol("m"), (0, y))
    m.gravity(sp.Symbol("g"))
    return compile_constrained(lcg.ConstrainedSystem(m, inequalities=[lcg.Inequality(y, restitution=E)]), "index1")


def run_lagcodegen(sim, rtol):
    res = sim.simulate(np.array([0.0, T_END]), q0=[H0], v0=[0.0], rtol=rtol, atol=rtol / 100)
    return np.array([r.t for r in res.impacts.select("bounce")][:N])


def run_scipy(sim, rtol, method):
    p = sim.parameter_vector()

    def rhs(t, y):
        acc, _ = sim.kkt(t, y, p)
        return [y[1], acc[0]]

    def floor(t, y):
        return y[0]
    floor.terminal, floor.direction = True, -1
    t, y, times = 0.0, [H0, 0.0], []
    while len(times) < N and t < T_END:
        sol = solve_ivp(rhs, (t, T_END), y, method=method, rtol=rtol, atol=rtol / 100, events=floor)
        if sol.status != 1:
            break
        t = float(sol.t_events[0][0])
        y = [0.0, -E * float(sol.y_events[0][0][1])]
        times.append(t)
    return np.array(times)


def error(times):
    if times.size < N:
        return float("nan")
    return float(np.max(np.abs(times / EXACT - 1)))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="two tolerances, 3 rounds")
    ap.add_argument("--repeats", type=int, default=7, help="interleaved rounds per median (default 7)")
    ap.add_argument("--out", type=Path, help="also write DIR/impacts.txt and DIR/impacts.csv")
    args = ap.parse_args(argv)
    load0 = _harness.load_average()
    rtols = [1e-6, 1e-10] if args.quick else [1e-6, 1e-8, 1e-10, 1e-12]
    rounds = 3 if args.quick else max(1, args.repeats)
    sim = ball()
    runners = {"lagcodegen": lambda r: run_lagcodegen(sim, r), "scipy DOP853": lambda r: run_scipy(sim, r, "DOP853"),
               "scipy LSODA": lambda r: run_scipy(sim, r, "LSODA")}
    for fn in runners.values():  # warm-up: the impact driver's runtime loaded, caches filled
        fn(rtols[0])
    rows = []
    for rtol in rtols:
        times = {k: [] for k in runners}
        found = {}
        for _ in range(rounds):  # interleaved rounds
            for name, fn in runners.items():
                start = time.perf_counter()
                found[name] = fn(rtol)
                times[name].append(time.perf_counter() - start)
        row = {"rtol": rtol}
        for name in runners:
            row[f"{name} error"] = error(found[name])
            row[f"{name} s"] = statistics.median(times[name])
        for name in ("scipy DOP853", "scipy LSODA"):
            row[f"{name}/lcg time"] = row[f"{name} s"] / row["lagcodegen s"]
            row[f"{name}/lcg error"] = row[f"{name} error"] / max(row["lagcodegen error"], 1e-16)
        rows.append(row)
        _harness.progress("impacts", f"rtol {rtol:g} done")
    cols = [("rtol", "rtol", "{:.0e}")]
    for name in runners:
        cols += [(f"{name} error", f"{name} err", "{:.1e}"), (f"{name} s", f"{name} s", "{:.2e}")]
    for name in ("scipy DOP853", "scipy LSODA"):
        cols += [(f"{name}/lcg time", f"{name.split()[1]}/lcg t", "{:.0f}"),
                 (f"{name}/lcg error", f"{name.split()[1]}/lcg err", "{:.1e}")]
    text = "\n".join(_harness.machine_lines("Impacts: bouncing ball, e = 0.8, first 20 impacts",
                                            (load0, _harness.load_average()))
                     + [f"medians of {rounds} interleaved rounds; error: max relative error of the 20 impact "
                        "times (exact: t1 + 2 t1 e (1 - e^k)/(1 - e)); atol = rtol/100", "",
                        _harness.format_table(cols, rows)])
    print(text)
    if args.out:
        _harness.write_report(args.out, "impacts", text, rows)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
