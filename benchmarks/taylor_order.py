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

``--caps 1.0,1.3,1.7,2.0`` studies the step rule's cap instead (h <= rho e^-c, the driver's
LCG_TAYLOR_CAP, 1.7 by default): at the driver's order rule, each cap a standalone Taylor build
compiled with ``-DLCG_TAYLOR_CAP=c`` (the cap changes the steps, not the cost of a step of a given
order, so the same cost model holds), compared with the cap 1.7.

Usage::

    python benchmarks/taylor_order.py [--quick] [--out DIR] [--ns 1,2,3,5] [--offsets -1,0,1,2,3,4]
    python benchmarks/taylor_order.py --caps 1.0,1.3,2.0 [--ns 1,2,3]
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
from lagcodegen.build import DEFAULT_CFLAGS  # noqa: E402
from lagcodegen.solvers.taylor.run import scene_of, taylor_module  # noqa: E402
from lagcodegen.solvers.taylor.runner import build_taylor  # noqa: E402

TARGETS = [10.0 ** -k for k in range(4, 13)]
DRIVER_CAP = 1.7  # the driver's LCG_TAYLOR_CAP (templates/taylor/_driver.j2): the cap study's base


def classic_order(tol: float) -> int:
    return max(2, math.ceil(-math.log(tol) / 2 + 1))


def step_costs(tm, p, n: int, orders, seconds: float, rounds: int = 4) -> np.ndarray:
    """Polynomial (in the order) of the seconds per step, from fixed-order runs (q0 = 1.0, tol 1e-8):
    the smallest of the timings of each order over ``rounds`` rounds through every order (a drift
    of the machine's load between orders does not bend the curve), ``seconds`` per order in all."""
    t = np.array([0.0, 5.0, B.T_END])
    y0 = np.concatenate([np.full(n, 1.0), np.zeros(n)])
    steps = {order: tm.simulate(t, y0, p, rtol=1e-8, atol=1e-8, order=order).stats["steps"] for order in orders}
    best = dict.fromkeys(orders, math.inf)
    for _ in range(rounds):
        for order in orders:
            end = time.perf_counter() + seconds / rounds
            while time.perf_counter() < end:
                start = time.thread_time()
                tm.simulate(t, y0, p, rtol=1e-8, atol=1e-8, order=order)
                best[order] = min(best[order], time.thread_time() - start)
    per = [best[order] / steps[order] for order in orders]
    return np.polyfit(np.array(orders, dtype=float), np.array(per), 2)


def cap_modules(sim, caps) -> dict:
    """Standalone Taylor builds of ``sim``'s scene, one per cap, compiled with -DLCG_TAYLOR_CAP=c."""
    scene = scene_of(sim)
    return {c: build_taylor(scene, runtime=False, cflags=(*DEFAULT_CFLAGS, f"-DLCG_TAYLOR_CAP={c!r}")) for c in caps}


def sweep(tm, p, n: int, q0: float, ref, tols, order_of) -> list[dict]:
    """The rows (tolerance, order, steps, error) of a tolerance sweep of ``tm`` (failed runs left
    out); ``order_of(tol)``: the order option (None: the driver's rule)."""
    t = np.array([0.0, 5.0, B.T_END])
    y0 = np.concatenate([np.full(n, q0), np.zeros(n)])
    rows = []
    for tol in tols:
        res = tm.simulate(t, y0, p, rtol=tol, atol=tol, order=order_of(tol))
        if res.status != 0:
            continue
        err = float(np.max(np.abs(np.asarray(res.y[-1], dtype=np.longdouble) - ref)))
        rows.append(dict(n=n, q0=q0, tol=tol, order=res.stats["order"], steps=res.stats["steps"], error=err,
                         err_tol=err / tol))
    return rows


def compare(n: int, q0: float, label: str, variants: dict, base, runs: dict, cost) -> list[dict]:
    """Rows of the ratios (time at equal achieved error / the ``base`` variant's) of each variant."""
    curves = {v: [(r["error"], r["steps"] * float(np.polyval(cost, r["order"]))) for r in runs[v]] for v in variants}
    out = []
    for v in variants:
        ratios = []
        for target in TARGETS:
            a, b = H.interpolate_time(curves[v], target), H.interpolate_time(curves.get(base, []), target)
            ratios.append(a / b if a and b else None)
        et = [r["err_tol"] for r in runs[v] if 1e-12 <= r["tol"] <= 1e-4]
        row = {"n": n, "q0": q0, label: v, "err_tol_median": float(np.median(et)), "err_tol_max": max(et)}
        row.update({f"{target:.0e}": r for target, r in zip(TARGETS, ratios)})
        out.append(row)
    return out


def study(ns, *, caps=None, offsets=(0, 2), tols=None, seconds: float = 0.3, rounds: int = 4) -> tuple[str, list, list]:
    """(label, rows per case and variant, rows over every case) of the order-offset study, or of
    the cap study when ``caps`` are given (1.7, the driver's, always among them): time at equal
    achieved error over the base variant's (offset 0, cap 1.7), err/tol of each sweep."""
    caps = sorted({DRIVER_CAP, *caps}) if caps else None
    label, base = ("cap", DRIVER_CAP) if caps else ("offset", 0)
    tols = tols or [10.0 ** (-k / 4) for k in range(4, 57)]
    summary = []
    for n in ns:
        sim = lcg.compile_model(lcg.systems.n_link_pendulum(n, name=f"to{n}"))
        sim.simulate(np.array([0.0, 1e-3]), y0=np.zeros(2 * n), method="taylor")
        tm = taylor_module(sim)
        p = np.array(sim.code.scene.default_parameters(), dtype=float)
        if caps:
            H.progress("taylor_order", f"n = {n}: builds of {len(caps)} caps")
            modules = cap_modules(sim, caps)
            variants = {c: (modules[c], lambda tol: None) for c in caps}
        else:
            variants = {off: (tm, lambda tol, off=off: min(30, classic_order(tol) + off)) for off in offsets}
        H.progress("taylor_order", f"n = {n}: step costs")
        cost = step_costs(tm, p, n, list(range(4, 26)), seconds, rounds)
        for q0 in (0.1, 1.0):
            H.progress("taylor_order", f"n = {n}, q0 = {q0}: sweeps")
            ref = B.reference(n, q0, 1e-19)
            runs = {v: sweep(module, p, n, q0, ref, tols, order_of) for v, (module, order_of) in variants.items()}
            summary += compare(n, q0, label, variants, base, runs, cost)
    overall = []
    for v in (caps or offsets):
        rs = [r for s in summary if s[label] == v for r in (s[f"{t:.0e}"] for t in TARGETS) if r]
        overall.append({label: v, "geo": math.exp(sum(map(math.log, rs)) / len(rs)) if rs else None,
                        "worst": max(rs) if rs else None, "cells": len(rs),
                        "med": float(np.median([s["err_tol_median"] for s in summary if s[label] == v])),
                        "max": max(s["err_tol_max"] for s in summary if s[label] == v)})
    return label, summary, overall


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="n = 1, tolerances every half decade, short timings")
    ap.add_argument("--out", type=Path, help="also write DIR/taylor_order.txt and .csv")
    ap.add_argument("--ns", default=None, help="comma-separated n (default 1,2,3,5; with --caps 1,2,3)")
    ap.add_argument("--offsets", default="-1,0,1,2,3,4")
    ap.add_argument("--caps", default=None, help="comma-separated step caps c (h <= rho e^-c) to compare with 1.7 "
                    "instead of the order offsets")
    ap.add_argument("--seconds", type=float, default=0.3, help="timing budget per order for the step costs")
    args = ap.parse_args(argv)
    caps = [float(x) for x in args.caps.split(",")] if args.caps else None
    ns = [int(x) for x in (args.ns or ("1" if args.quick else "1,2,3" if caps else "1,2,3,5")).split(",")]
    offsets = [int(x) for x in args.offsets.split(",")]
    tols = [10.0 ** (-k / 2) for k in range(2, 25)] if args.quick else None
    load0 = H.load_average()
    label, summary, overall = study(ns, caps=caps, offsets=offsets, tols=tols,
                                    seconds=0.05 if args.quick else args.seconds, rounds=2 if args.quick else 4)
    load1 = H.load_average()
    fmt, base, what = (("{:.2f}", DRIVER_CAP, "the step cap c (h <= rho e^-c)") if label == "cap"
                       else ("{:+d}", 0, "the Taylor order rule"))
    lines = H.machine_lines(f"benchmarks/taylor_order.py: {what} at equal achieved error", (load0, load1))
    lines += ["", f"modelled time (steps x cost per step of the order) at equal achieved error, / {label} "
              + fmt.format(base),
              H.format_table([("n", "n", "{}"), ("q0", "q0", "{}"), (label, label, fmt)]
                             + [(f"{t:.0e}", f"{t:.0e}", "{:.2f}") for t in TARGETS]
                             + [("err_tol_median", "err/tol med.", "{:.3f}"), ("err_tol_max", "err/tol max", "{:.2f}")],
                             summary),
              "", "over every case and error (geometric mean and worst cell of the ratios; err/tol for tol 1e-4..1e-12)",
              H.format_table([(label, label, fmt), ("geo", "time ratio (geo. mean)", "{:.3f}"),
                              ("worst", "worst cell", "{:.2f}"), ("cells", "cells", "{}"),
                              ("med", "err/tol median", "{:.3f}"), ("max", "err/tol max", "{:.2f}")], overall)]
    text = "\n".join(lines)
    print(text)
    if args.out is not None:
        H.write_report(args.out, "taylor_order", text, summary)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
