"""Constraint drift of the Cartesian pendulum under every formulation of lagcodegen.compile_constrained.

The bob at (x, y) with x^2 + y^2 = l^2 (eq. 4.1), l = 1, g = 9.81, released from 1 rad at rest,
integrated over t in [0, T] (T = 100, and 1000 unless --quick) with rtol 1e-10, atol 1e-12 and
output every 0.05 time units, in six ways:

* index-1 plain        CVODE (Adams), accelerations and multiplier from the augmented system;
* index-1 + Baumgarte  the same with alpha = beta = 10 (f'' + 2 alpha f' + beta^2 f = 0);
* index-1 + projection CVODE (BDF) with CVodeSetProjFn: Gauss-Newton onto f = 0, then A q' = 0;
* GGL native IDA       stabilized index 2, generated residual Jacobian, IDASetSuppressAlg;
* GGL sksundae IDA     the same compiled residual through scikit-sundae (huge atol on lambda, mu);
* minimal              y = -sqrt(l^2 - x^2) eliminated symbolically, CVODE (Adams) on x.

Columns: max |f(q)| and max |A q'| over the output times, energy drift max |E - E0| / max(1, |E0|),
wall time of the simulate() call (after compilation; median of --repeats runs) and steps
(scikit-sundae does not report a step count).

This is a measuring instrument: it asserts nothing.

Usage::

    python benchmarks/constraint_drift.py [--quick] [--repeats N] [--out DIR]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

import lagcodegen as lcg
from lagcodegen.theory.constraints import ConstrainedSystem
from lagcodegen.api import compile_constrained

import _harness  # noqa: E402  (benchmarks/ is on sys.path when run as a script)

TOL = dict(rtol=1e-10, atol=1e-12)
THETA0 = 1.0
DT_OUT = 0.05
RUNS = [
    ("index-1 plain", "index1", {}),
    ("index-1 + Baumgarte(10,10)", "index1", {"baumgarte": (10.0, 10.0)}),
    ("index-1 + projection", "index1", {"projection": True}),
    ("GGL native IDA", "ggl", {}),
    ("GGL sksundae IDA", "ggl", {"backend": "sksundae"}),
    ("minimal coordinates", "minimal", {}),
]


def cartesian_pendulum() -> ConstrainedSystem:
    m = lcg.Model("drift_pendulum")
    x, y = m.coordinates("x y")
    l, g, mass = m.parameters(l=1.0, g=9.81, m=1.0)
    m.particle("bob", mass, (x, y))
    m.gravity(g)
    return ConstrainedSystem(m, holonomic=[x**2 + y**2 - l**2])


def parse_args(argv=None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="T = 100 only, one repeat")
    ap.add_argument("--repeats", type=int, default=3, help="runs per wall-time median (default 3)")
    ap.add_argument("--out", metavar="DIR", type=Path,
                    help="also write the table to DIR/constraint_drift.txt and DIR/constraint_drift.csv")
    return ap.parse_args(argv)


def main(argv=None) -> int:
    args = parse_args(argv)
    horizons = [100.0] if args.quick else [100.0, 1000.0]
    repeats = 1 if args.quick else max(1, args.repeats)
    system = cartesian_pendulum()
    sims, compile_s = {}, {}
    for form in ("index1", "ggl", "minimal"):
        start = time.perf_counter()
        sims[form] = compile_constrained(system, form)
        if form == "minimal":  # compile the branch used below now, not inside the timed run
            sims[form].compiled_branch(sims[form]._branch_for(
                np.array([np.sin(THETA0), -np.cos(THETA0)]), 0.0, {"l": 1.0, "g": 9.81, "m": 1.0}, 1e-8))
        compile_s[form] = time.perf_counter() - start
    q0, v0 = [np.sin(THETA0), -np.cos(THETA0)], [0.0, 0.0]
    rows = []
    for T in horizons:
        t = np.arange(0.0, T + DT_OUT / 2, DT_OUT)
        for label, form, opts in RUNS:
            walls, res = [], None
            for _ in range(repeats):
                start = time.perf_counter()
                res = sims[form].simulate(t, q0=q0, v0=v0, max_steps=50_000_000, **TOL, **opts)
                walls.append(time.perf_counter() - start)
            steps = res.stats.get("steps")
            rows.append(dict(T=T, formulation=label, max_f=float(np.max(np.abs(res["g_0"]))),
                             max_Aqdot=float(np.max(np.abs(res["gdot_0"]))), energy_drift=res.drift("energy"),
                             wall_s=statistics.median(walls), steps="" if steps is None else int(steps)))
            print(f"  T = {T:g}: {label} done", file=sys.stderr, flush=True)
    head = f"{'T':>6}  {'formulation':<28}{'max|f(q)|':>11}{'max|Aq_dot|':>13}{'energy drift':>14}" \
           f"{'wall [s]':>10}{'steps':>10}"
    lines = [f"Cartesian pendulum, theta0 = {THETA0} rad, rtol = {TOL['rtol']:g}, atol = {TOL['atol']:g}, "
             f"outputs every {DT_OUT}", head, "-" * len(head)]
    for r in rows:
        lines.append(f"{r['T']:>6g}  {r['formulation']:<28}{r['max_f']:>11.2e}{r['max_Aqdot']:>13.2e}"
                     f"{r['energy_drift']:>14.2e}{r['wall_s']:>10.3f}{str(r['steps']):>10}")
    lines.append("compile [s]: " + ", ".join(f"{k} {v:.2f}" for k, v in compile_s.items())
                 + " (cached builds are reused)")
    text = "\n".join(lines)
    print(text)
    if args.out:
        _harness.write_report(args.out, "constraint_drift", text, rows)
        print(f"wrote {args.out / 'constraint_drift.txt'}, {args.out / 'constraint_drift.csv'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
