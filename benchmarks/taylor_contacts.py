"""Contacts on the Taylor method: the bouncing ball on the Taylor contact driver
(``simulate(method="taylor")``, lagcodegen/runtime/lcg_taylor_imp.c: impacts located as roots of
the gap's Taylor polynomial) against the index-1 CVODE impact driver (``method="adams"``, CVODE's
root finding), at equal ACHIEVED error.

Problem: a ball dropped from h0 = 1 onto a floor (the contact y >= 0, lagcodegen.Inequality) with
restitution e = 0.8, its first N = 20 bounces (t_end just past the apex after bounce N, before the
accumulation at t1 (1 + e) / (1 - e)). Closed form: bounce k at t_k = t1 + 2 t1 e (1 - e^k)/(1 - e),
t1 = sqrt(2 h0 / g), the apex after it at t_k + e^(k+1) sqrt(2 g h0) / g, of height h0 e^(2(k+1)).
The output times are the exact apex times; the error of a run is the largest relative error of the
ball's height there against h0 e^(2(k+1)) (what a wrongly located impact or a wrong rebound speed
shows). The flight is a parabola: both methods integrate it to rounding; what differs is how the
impacts are located (CVODE: its root finding on the interpolant, to about its tolerances; Taylor:
the root of the step's polynomial, to rounding).

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

import lagcodegen as lcg
from lagcodegen.api import compile_constrained

import _harness  # noqa: E402  (benchmarks/ is on sys.path when run as a script)

E, H0, G, N = 0.8, 1.0, 9.81, 20


def closed_form(n: int = N) -> tuple[np.ndarray, np.ndarray]:
    """(the apex times after bounces 0..n-1, their heights)."""
    t1 = math.sqrt(2 * H0 / G)
    k = np.arange(n)
    bounces = t1 + 2 * t1 * E * (1 - E**k) / (1 - E)
    speeds = E ** (k + 1) * math.sqrt(2 * G * H0)
    return bounces + speeds / G, H0 * E ** (2 * (k + 1))


def ball():
    m = lcg.Model("bench_tball")
    (y,) = m.coordinates("y")
    m.parameters(g=G, m=1.0)
    m.particle("ball", sp.Symbol("m"), (0, y))
    m.gravity(sp.Symbol("g"))
    return compile_constrained(lcg.ConstrainedSystem(m, inequalities=[lcg.Inequality(y, restitution=E)]), "index1")


def run(sim, method: str, rtol: float) -> float:
    """The achieved error of one run (max relative error of the apex heights)."""
    t_apex, h_apex = closed_form()
    t = np.concatenate([[0.0], t_apex])
    res = sim.simulate(t, q0=[H0], v0=[0.0], method=method, rtol=rtol, atol=rtol / 100)
    return float(np.max(np.abs(res["y"][1:] / h_apex - 1)))


def measure(sim, methods: dict, rtols: list, rounds: int) -> list[dict]:
    rows = []
    for rtol in rtols:
        times = {name: [] for name in methods}
        errs = {}
        for _ in range(rounds):  # interleaved rounds
            for name, method in methods.items():
                start = time.perf_counter()
                errs[name] = run(sim, method, rtol)
                times[name].append(time.perf_counter() - start)
        for name in methods:
            rows.append({"method": name, "rtol": rtol, "error": errs[name], "s": statistics.median(times[name])})
        _harness.progress("taylor_contacts", f"rtol {rtol:g} done")
    return rows


def equal_error(rows: list, methods: dict, targets: list) -> list[dict]:
    out = []
    for target in targets:
        row = {"error": target}
        for name in methods:
            points = [(r["error"], r["s"]) for r in rows if r["method"] == name]
            row[f"{name} s"], row[f"{name} how"] = _harness.time_at(points, target)
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
    sim = ball()
    for method in methods.values():  # warm-up: the drivers and the contact jet built and loaded
        run(sim, method, rtols[0])
    rows = measure(sim, methods, rtols, rounds)
    targets = [1e-4, 1e-6, 1e-8, 1e-10, 1e-12]
    eq = equal_error(rows, methods, targets)
    cols = [("method", "method", "{}"), ("rtol", "rtol", "{:.0e}"), ("error", "achieved error", "{:.1e}"),
            ("s", "median s", "{:.2e}")]
    eq_cols = [("error", "error", "{:.0e}")]
    for name in methods:
        eq_cols += [(f"{name} s", f"{name} s", "{:.2e}"), (f"{name} how", "", "{}")]
    eq_cols.append(("Adams/Taylor", "Adams/Taylor", "{:.2f}"))
    text = "\n".join(_harness.machine_lines(f"Taylor contacts: bouncing ball, {N} bounces, e = {E}",
                                            (load0, _harness.load_average()))
                     + [f"medians of {rounds} interleaved rounds of the whole simulate() call; error: max relative "
                        "error of the apex heights h0 e^(2k) at the exact apex times; atol = rtol/100", "",
                        _harness.format_table(cols, rows), "", "At equal achieved error:", "",
                        _harness.format_table(eq_cols, eq)])
    print(text)
    if args.out:
        _harness.write_report(args.out, "taylor_contacts", text, rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
