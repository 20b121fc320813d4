"""The Taylor integrator's order rule at equal ACHIEVED error (issue 23): which order offset above
Jorba & Zou's p = ceil(-ln(tol)/2 + 1) reaches a given error in the least time.

Scene: the planar n-link pendulum (as in benchmarks/taylor.py: unit masses and lengths, g = 9.81,
every angle q0 = 0.1 or 1.0 rad at rest, t in [0, 10]); error: max over the state of
|y(10) - ref(10)|, the reference from heyoka in long double at 1e-19 (taylor.reference).

Method, made for a busy machine: steps and errors of a run are deterministic, times are not. So
each variant (order = ceil(-ln(tol)/2 + 1) + offset, given as the ``order`` option, which keeps
the step rule's safety factors of that order and tolerance) is run once per tolerance on a fine
grid for its steps and error, and its time is modelled as steps x the cost of one step of its
order, measured apart (fixed-order runs, the smallest of several timings, fitted by a quadratic
in the order). Times at equal achieved error are log-log interpolations along each variant's
tolerance sweep, compared with offset 0; also reported: the achieved error over the tolerance.
The driver's rule (lagcodegen's tl_order) is offset 2. A measuring instrument: it asserts nothing.

Usage::

    python benchmarks/taylor_order.py [--ns 1,2,3,5] [--offsets -1,0,1,2,3,4]
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _harness as H  # noqa: E402
import taylor as B  # noqa: E402

import lagcodegen as lcg  # noqa: E402
from lagcodegen.solvers.taylor.run import taylor_module  # noqa: E402

TARGETS = [10.0 ** -k for k in range(4, 13)]


def classic_order(tol: float) -> int:
    return max(2, math.ceil(-math.log(tol) / 2 + 1))


def step_costs(tm, p, n: int, orders, seconds: float) -> np.ndarray:
    """Polynomial (in the order) of the seconds per step, from fixed-order runs (q0 = 1.0, tol 1e-8)."""
    t = np.array([0.0, 5.0, B.T_END])
    y0 = np.concatenate([np.full(n, 1.0), np.zeros(n)])
    per = []
    for order in orders:
        res = tm.simulate(t, y0, p, rtol=1e-8, atol=1e-8, order=order)
        best, end = math.inf, time.perf_counter() + seconds
        while time.perf_counter() < end:
            start = time.thread_time()
            tm.simulate(t, y0, p, rtol=1e-8, atol=1e-8, order=order)
            best = min(best, time.thread_time() - start)
        per.append(best / res.stats["steps"])
    return np.polyfit(np.array(orders, dtype=float), np.array(per), 2)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--ns", default="1,2,3,5")
    ap.add_argument("--offsets", default="-1,0,1,2,3,4")
    ap.add_argument("--seconds", type=float, default=0.3, help="timing budget per order for the step costs")
    args = ap.parse_args(argv)
    ns = [int(x) for x in args.ns.split(",")]
    offsets = [int(x) for x in args.offsets.split(",")]
    tols = [10.0 ** (-k / 4) for k in range(4, 57)]
    load0 = H.load_average()
    rows, summary = [], []
    for n in ns:
        sim = lcg.compile_model(lcg.systems.n_link_pendulum(n, name=f"to{n}"))
        sim.simulate(np.array([0.0, 1e-3]), y0=np.zeros(2 * n), method="taylor")
        tm = taylor_module(sim)
        p = np.array(sim.code.scene.default_parameters(), dtype=float)
        H.progress("taylor_order", f"n = {n}: step costs")
        cost = step_costs(tm, p, n, list(range(4, 26)), args.seconds)
        t = np.array([0.0, 5.0, B.T_END])
        for q0 in (0.1, 1.0):
            H.progress("taylor_order", f"n = {n}, q0 = {q0}: sweeps")
            ref = B.reference(n, q0, 1e-19)
            y0 = np.concatenate([np.full(n, q0), np.zeros(n)])
            curves = {}
            for off in offsets:
                pts = []
                for tol in tols:
                    order = min(30, classic_order(tol) + off)
                    res = tm.simulate(t, y0, p, rtol=tol, atol=tol, order=order)
                    if res.status != 0:
                        continue
                    err = float(np.max(np.abs(np.asarray(res.y[-1], dtype=np.longdouble) - ref)))
                    model = res.stats["steps"] * float(np.polyval(cost, order))
                    pts.append((err, model))
                    rows.append(dict(n=n, q0=q0, offset=off, tol=tol, order=order, steps=res.stats["steps"],
                                     error=err, err_tol=err / tol, model_us=1e6 * model))
                curves[off] = pts
            for off in offsets:
                ratios = []
                for target in TARGETS:
                    a, b = H.interpolate_time(curves[off], target), H.interpolate_time(curves.get(0, []), target)
                    ratios.append(a / b if a and b else None)
                et = [r["err_tol"] for r in rows if (r["n"], r["q0"], r["offset"]) == (n, q0, off)
                      and 1e-12 <= r["tol"] <= 1e-4]
                row = dict(n=n, q0=q0, offset=off, err_tol_median=float(np.median(et)), err_tol_max=max(et))
                row.update({f"{target:.0e}": r for target, r in zip(TARGETS, ratios)})
                summary.append(row)
    load1 = H.load_average()
    overall = []
    for off in offsets:
        rs = [r for s in summary if s["offset"] == off for r in (s[f"{t:.0e}"] for t in TARGETS) if r]
        overall.append(dict(offset=off, geo=math.exp(sum(map(math.log, rs)) / len(rs)) if rs else None,
                            worst=max(rs) if rs else None, cells=len(rs),
                            med=float(np.median([s["err_tol_median"] for s in summary if s["offset"] == off])),
                            max=max(s["err_tol_max"] for s in summary if s["offset"] == off)))
    lines = H.machine_lines("benchmarks/taylor_order.py: the Taylor order rule at equal achieved error",
                            (load0, load1))
    lines += ["", "modelled time (steps x cost per step of the order) at equal achieved error, / offset 0",
              H.format_table([("n", "n", "{}"), ("q0", "q0", "{}"), ("offset", "offset", "{:+d}")]
                             + [(f"{t:.0e}", f"{t:.0e}", "{:.2f}") for t in TARGETS]
                             + [("err_tol_median", "err/tol med.", "{:.3f}"), ("err_tol_max", "err/tol max", "{:.2f}")],
                             summary),
              "", "over every case and error (geometric mean and worst cell of the ratios; err/tol for tol 1e-4..1e-12)",
              H.format_table([("offset", "offset", "{:+d}"), ("geo", "time ratio (geo. mean)", "{:.3f}"),
                              ("worst", "worst cell", "{:.2f}"), ("cells", "cells", "{}"),
                              ("med", "err/tol median", "{:.3f}"), ("max", "err/tol max", "{:.2f}")], overall)]
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
