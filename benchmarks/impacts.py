"""Impacts: the impact driver against a scipy solve_ivp event loop on the same compiled
right-hand side, on two problems with exact impact times:

* ball:     dropped from h0 = 1 onto a floor with restitution e = 0.8 (the contact y >= 0,
  lagcodegen.Inequality), its first N = 20 impacts (t_end just past impact N, before the
  accumulation): impact k at t1 + 2 t1 e (1 - e^k)/(1 - e), t1 = sqrt(2 h0/g). Its motion is a
  parabola, which every Runge-Kutta method of order >= 2 integrates exactly.
* pendulum: a pendulum (l = 1) released from theta0 = 2.5 rad against a wall at theta = 0
  (theta >= 0, e = 0.8), its first N = 10 impacts: the first at T(theta0)/4, then one every half
  period T(theta_k)/2 of the amplitude after impact k, cos(theta_k) = 1 - l w_k^2/(2 g),
  w_k = e^k w_0, T(a) = 4 sqrt(l/g) K(sin^2(a/2)) (scipy.special.ellipk).

The event-location error is the largest relative error of the N impact times.

* lagcodegen: ``simulate`` of the compiled system: CVODE (Adams) with root finding, the impulse
  applied in the generated C and CVODE reinitialized, in one call of the impact driver;
* lcg GGL:    the same system compiled with formulation "ggl": IDA on the GGL residual of the rows
  held, the same impact law, IDA restarted (lagcodegen/runtime/lcg_imp_ida.c);
* lcg minimal: formulation "minimal" (no equality to eliminate: the same index-1 impact driver);
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
import statistics
import time
from pathlib import Path

import numpy as np
import sympy as sp
from scipy.integrate import solve_ivp
from scipy.special import ellipk

import lagcodegen as lcg
from lagcodegen.api import compile_constrained

import _harness  # noqa: E402  (benchmarks/ is on sys.path when run as a script)

E, H0, G = 0.8, 1.0, 9.81
THETA0 = 2.5


def ball_times(n):
    t1 = math.sqrt(2 * H0 / G)
    return np.array([t1 + 2 * t1 * E * (1 - E**k) / (1 - E) for k in range(n)])


def pendulum_times(n):
    def period(a):
        return 4 * math.sqrt(1 / G) * float(ellipk(math.sin(a / 2) ** 2))
    w = math.sqrt(2 * G * (1 - math.cos(THETA0)))
    out = [period(THETA0) / 4]
    for _ in range(n - 1):
        w *= E
        out.append(out[-1] + period(math.acos(1 - w**2 / (2 * G))) / 2)
    return np.array(out)


def problem(name):
    """(compiled system, q0, exact impact times, t_end between impacts N and N + 1)."""
    m = lcg.Model(f"bench_{name}")
    if name == "ball":
        (q,) = m.coordinates("y")
        m.parameters(g=G, m=1.0)
        m.particle("ball", sp.Symbol("m"), (0, q))
        q0, exact = H0, ball_times(21)
        n = 20
    else:
        (q,) = m.coordinates("theta")
        m.parameters(g=G, m=1.0)
        m.particle("bob", sp.Symbol("m"), (sp.sin(q), -sp.cos(q)))
        q0, exact = THETA0, pendulum_times(11)
        n = 10
    m.gravity(sp.Symbol("g"))
    system = lcg.ConstrainedSystem(m, inequalities=[lcg.Inequality(q, restitution=E)])
    sims = {f: compile_constrained(system, f) for f in ("index1", "ggl", "minimal")}
    return sims, q0, exact[:n], 0.5 * (exact[n - 1] + exact[n])


def run_lagcodegen(case, rtol, formulation="index1"):
    sims, q0, exact, t_end = case
    res = sims[formulation].simulate(np.array([0.0, t_end]), q0=[q0], v0=[0.0], rtol=rtol, atol=rtol / 100)
    return np.array([r.t for r in res.impacts.select("bounce")][: exact.size])


def run_scipy(case, rtol, method):
    sims, q0, exact, t_end = case
    sim = sims["index1"]
    p = sim.parameter_vector()

    def rhs(t, y):
        acc, _ = sim.kkt(t, y, p)
        return [y[1], acc[0]]

    def contact(t, y):
        return y[0]
    contact.terminal, contact.direction = True, -1
    t, y, times = 0.0, [q0, 0.0], []
    while len(times) < exact.size and t < t_end:
        sol = solve_ivp(rhs, (t, t_end), y, method=method, rtol=rtol, atol=rtol / 100, events=contact)
        if sol.status != 1:
            break
        t = float(sol.t_events[0][0])
        y = [0.0, -E * float(sol.y_events[0][0][1])]
        times.append(t)
    return np.array(times)


def error(times, exact):
    if times.size < exact.size:
        return float("nan")
    return float(np.max(np.abs(times / exact - 1)))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="two tolerances, 3 rounds")
    ap.add_argument("--repeats", type=int, default=7, help="interleaved rounds per median (default 7)")
    ap.add_argument("--out", type=Path, help="also write DIR/impacts.txt and DIR/impacts.csv")
    args = ap.parse_args(argv)
    load0 = _harness.load_average()
    rtols = [1e-6, 1e-10] if args.quick else [1e-6, 1e-8, 1e-10, 1e-12]
    rounds = 3 if args.quick else max(1, args.repeats)
    runners = {"lagcodegen": run_lagcodegen, "lcg GGL": lambda c, r: run_lagcodegen(c, r, "ggl"),
               "lcg minimal": lambda c, r: run_lagcodegen(c, r, "minimal"),
               "scipy DOP853": lambda c, r: run_scipy(c, r, "DOP853"),
               "scipy LSODA": lambda c, r: run_scipy(c, r, "LSODA")}
    rows = []
    for name in ("ball", "pendulum"):
        case = problem(name)
        for fn in runners.values():  # warm-up: the impact driver's runtime loaded, caches filled
            fn(case, rtols[0])
        rows += measure(name, case, runners, rtols, rounds)
    cols = [("problem", "problem", "{}"), ("rtol", "rtol", "{:.0e}")]
    for name in runners:
        cols += [(f"{name} error", f"{name} err", "{:.1e}"), (f"{name} s", f"{name} s", "{:.2e}")]
    for name in ("scipy DOP853", "scipy LSODA"):
        cols += [(f"{name}/lcg time", f"{name.split()[1]}/lcg t", "{:.0f}"),
                 (f"{name}/lcg error", f"{name.split()[1]}/lcg err", "{:.1e}")]
    text = "\n".join(_harness.machine_lines("Impacts: ball (20 impacts) and pendulum at a wall (10), e = 0.8",
                                            (load0, _harness.load_average()))
                     + [f"medians of {rounds} interleaved rounds; error: max relative error of the impact times "
                        "against the exact ones; atol = rtol/100; lagcodegen s: the whole simulate() call", "",
                        _harness.format_table(cols, rows)])
    print(text)
    if args.out:
        _harness.write_report(args.out, "impacts", text, rows)
    return 0


def measure(problem_name, case, runners, rtols, rounds):
    rows = []
    for rtol in rtols:
        times = {k: [] for k in runners}
        found = {}
        for _ in range(rounds):  # interleaved rounds
            for name, fn in runners.items():
                start = time.perf_counter()
                found[name] = fn(case, rtol)
                times[name].append(time.perf_counter() - start)
        row = {"problem": problem_name, "rtol": rtol}
        for name in runners:
            row[f"{name} error"] = error(found[name], case[2])
            row[f"{name} s"] = statistics.median(times[name])
        for name in ("scipy DOP853", "scipy LSODA"):
            row[f"{name}/lcg time"] = row[f"{name} s"] / row["lagcodegen s"]
            row[f"{name}/lcg error"] = row[f"{name} error"] / max(row["lagcodegen error"], 1e-16)
        rows.append(row)
        _harness.progress("impacts", f"{problem_name}, rtol {rtol:g} done")
    return rows


if __name__ == "__main__":
    raise SystemExit(main())
