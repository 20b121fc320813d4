"""Contacts on the Taylor method: the bouncing ball on the Taylor contact driver
(``simulate(method="taylor")``, lagcodegen/runtime/lcg_taylor_imp.c: impacts located as roots of
the gap's Taylor polynomial) against the index-1 CVODE impact driver (``method="adams"``, CVODE's
root finding), at equal ACHIEVED error.

* ball: dropped from h0 = 1 onto a floor (the contact y >= 0, lagcodegen.Inequality) with
  restitution e = 0.8, its first N = 20 bounces (t_end the apex after bounce N, before the
  accumulation at t1 (1 + e) / (1 - e)). Closed form: bounce k at t_k = t1 + 2 t1 e (1 - e^k)/(1 - e),
  t1 = sqrt(2 h0 / g), the apex after it at t_k + e^(k+1) sqrt(2 g h0) / g, of height h0 e^(2(k+1)).
  The flight is a parabola: both methods integrate it to rounding; what differs is how the impacts
  are located (CVODE: its root finding on the interpolant, to about its tolerances; Taylor: the
  root of the step's polynomial, to rounding).
* pendulum (a motion that is not a polynomial): a pendulum (l = 1) released from theta0 = 2.5 rad
  against a wall at theta = 0 (theta >= 0, e = 0.8), its first 10 impacts: the first at
  T(theta0)/4, then one every half period T(theta_k)/2 of the amplitude after impact k,
  cos(theta_k) = 1 - l w_k^2/(2 g), w_k = e^k w_0, T(a) = 4 sqrt(l/g) K(sin^2(a/2)); the apex
  after impact k at T(theta_(k+1))/4, of height 1 - cos(theta_(k+1)) above the bottom.

The output times are the exact apex times; the error of a run is the largest relative error of the
height there against the closed form (what a wrongly located impact, a wrong rebound speed or the
integration error between impacts shows).

Each method runs over several tolerances (atol = rtol / 100); wall time is the median of
interleaved rounds of the whole simulate() call. The second table gives the time of each method
at equal achieved error (interpolated in log-log between its runs; "bound" where every run of the
method is more accurate than the target: the cheapest run, an upper bound) and the ratio. The
machine's load is printed with the tables. This is a measuring instrument: it asserts nothing.

Usage::

    python benchmarks/taylor_contacts.py [--quick] [--repeats N] [--out DIR]
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import time
from pathlib import Path

import numpy as np
import sympy as sp
from scipy.special import ellipk

import lagcodegen as lcg
from lagcodegen.api import compile_constrained

import _harness  # noqa: E402  (benchmarks/ is on sys.path when run as a script)

E, H0, G, N = 0.8, 1.0, 9.81, 20
THETA0, N_PENDULUM = 2.5, 10


def closed_form(n: int = N) -> tuple[np.ndarray, np.ndarray]:
    """(the apex times after bounces 0..n-1, their heights)."""
    t1 = math.sqrt(2 * H0 / G)
    k = np.arange(n)
    bounces = t1 + 2 * t1 * E * (1 - E**k) / (1 - E)
    speeds = E ** (k + 1) * math.sqrt(2 * G * H0)
    return bounces + speeds / G, H0 * E ** (2 * (k + 1))


def pendulum_closed_form(n: int = N_PENDULUM) -> tuple[np.ndarray, np.ndarray]:
    """(the apex times after impacts 0..n-1 of the pendulum at the wall, their heights 1 - cos(theta))."""
    def period(a):
        return 4 * math.sqrt(1 / G) * float(ellipk(math.sin(a / 2) ** 2))
    w = math.sqrt(2 * G * (1 - math.cos(THETA0)))
    t_hit, times, heights = period(THETA0) / 4, [], []
    for _ in range(n):
        w *= E
        amplitude = math.acos(1 - w**2 / (2 * G))
        times.append(t_hit + period(amplitude) / 4)
        heights.append(1 - math.cos(amplitude))
        t_hit += period(amplitude) / 2
    return np.array(times), np.array(heights)


def problem(name: str):
    """(compiled system, q0, the exact apex times, their heights, the height of a row of y)."""
    m = lcg.Model(f"bench_t{name}")
    m.parameters(g=G, m=1.0)
    if name == "ball":
        (q,) = m.coordinates("y")
        m.particle("ball", sp.Symbol("m"), (0, q))
        q0, (times, heights) = H0, closed_form()
    else:
        (q,) = m.coordinates("theta")
        m.particle("bob", sp.Symbol("m"), (sp.sin(q), -sp.cos(q)))
        q0, (times, heights) = THETA0, pendulum_closed_form()
    m.gravity(sp.Symbol("g"))
    sim = compile_constrained(lcg.ConstrainedSystem(m, inequalities=[lcg.Inequality(q, restitution=E)]), "index1")
    height = (lambda y: y) if name == "ball" else (lambda theta: 1 - np.cos(theta))
    return sim, q0, times, heights, height


def ball():
    """The bouncing ball's compiled system."""
    return problem("ball")[0]


def run(case, method: str, rtol: float) -> float:
    """The achieved error of one run of ``case`` (:func:`problem`; a compiled ball: that problem):
    the max relative error of the apex heights."""
    if not isinstance(case, tuple):
        case = (case, H0, *closed_form(), lambda y: y)
    sim, q0, t_apex, h_apex, height = case
    t = np.concatenate([[0.0], t_apex])
    res = sim.simulate(t, q0=[q0], v0=[0.0], method=method, rtol=rtol, atol=rtol / 100)
    return float(np.max(np.abs(height(res.y[1:, 0]) / h_apex - 1)))


def measure(case, methods: dict, rtols: list, rounds: int, name: str = "ball") -> list[dict]:
    rows = []
    for rtol in rtols:
        times = {m: [] for m in methods}
        errs = {}
        for _ in range(rounds):  # interleaved rounds
            for m, method in methods.items():
                start = time.perf_counter()
                errs[m] = run(case, method, rtol)
                times[m].append(time.perf_counter() - start)
        for m in methods:
            rows.append({"problem": name, "method": m, "rtol": rtol, "error": errs[m],
                         "s": statistics.median(times[m])})
        _harness.progress("taylor_contacts", f"{name}, rtol {rtol:g} done")
    return rows


def equal_error(rows: list, methods: dict, targets: list, name: str = "ball") -> list[dict]:
    out = []
    for target in targets:
        row = {"problem": name, "error": target}
        for m in methods:
            points = [(r["error"], r["s"]) for r in rows if r["method"] == m and r.get("problem", name) == name]
            row[f"{m} s"], row[f"{m} how"] = _harness.time_at(points, target)
        a, b = row["CVODE Adams s"], row["Taylor s"]
        row["Adams/Taylor"] = a / b if a is not None and b is not None else None
        out.append(row)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="three tolerances, 3 rounds")
    ap.add_argument("--repeats", type=int, default=9, help="interleaved rounds per median (default 9)")
    ap.add_argument("--out", type=Path, help="also write DIR/taylor_contacts.txt and .csv")
    args = ap.parse_args(argv)
    load0 = _harness.load_average()
    rtols = [1e-4, 1e-8, 1e-12] if args.quick else [1e-4, 1e-6, 1e-8, 1e-10, 1e-12]
    rounds = 3 if args.quick else max(1, args.repeats)
    methods = {"CVODE Adams": "adams", "Taylor": "taylor"}
    targets = [1e-4, 1e-6, 1e-8, 1e-10, 1e-12]
    rows, eq = [], []
    for name in ("ball", "pendulum"):
        case = problem(name)
        for method in methods.values():  # warm-up: the drivers and the contact jet built and loaded
            run(case, method, rtols[0])
        these = measure(case, methods, rtols, rounds, name)
        rows += these
        eq += equal_error(these, methods, targets, name)
    cols = [("problem", "problem", "{}"), ("method", "method", "{}"), ("rtol", "rtol", "{:.0e}"),
            ("error", "achieved error", "{:.1e}"), ("s", "median s", "{:.2e}")]
    eq_cols = [("problem", "problem", "{}"), ("error", "error", "{:.0e}")]
    for name in methods:
        eq_cols += [(f"{name} s", f"{name} s", "{:.2e}"), (f"{name} how", "", "{}")]
    eq_cols.append(("Adams/Taylor", "Adams/Taylor", "{:.2f}"))
    text = "\n".join(_harness.machine_lines(f"Taylor contacts: bouncing ball ({N} bounces) and pendulum at a wall "
                                            f"({N_PENDULUM} impacts), e = {E}",
                                            (load0, _harness.load_average()))
                     + [f"medians of {rounds} interleaved rounds of the whole simulate() call; error: max relative "
                        "error of the apex heights at the exact apex times; atol = rtol/100", "",
                        _harness.format_table(cols, rows), "", "At equal achieved error:", "",
                        _harness.format_table(eq_cols, eq)])
    print(text)
    if args.out:
        _harness.write_report(args.out, "taylor_contacts", text, rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
