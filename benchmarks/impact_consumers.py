"""Impacts beyond ``simulate``: the bouncing ball (restitution e = 0.8, dropped from heights
0.2 .. 2 m, 6 s: its bounces, the accumulation, resting on the floor) run

* as N members one by one with ``simulate`` (a Python loop),
* as an ensemble of N members on 1 and on 2 threads (each member one impact-driver call, its
  events and contact log kept; bit-identical to its ``simulate``),
* with the integrator object in calls of 0.01 s (one impact-driver call each) against one
  ``simulate`` over the same 6 s.

Wall-time medians of interleaved rounds; the machine's load is printed with the table (threads
gain only on idle cores). It also reports the largest relative error of the first 20 bounce times
against t1 + 2 t1 e (1 - e^k)/(1 - e) for the integrator object in short calls. This is a
measuring instrument: it asserts nothing.

Usage::

    python benchmarks/impact_consumers.py [--quick] [--repeats N] [--members N] [--out DIR]
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np
import sympy as sp

import lagcodegen as lcg
from lagcodegen.api import compile_constrained

import _harness  # noqa: E402  (benchmarks/ is on sys.path when run as a script)

E, G = 0.8, 9.81
T = np.linspace(0.0, 6.0, 601)


def ball():
    m = lcg.Model("bench_cball")
    (y,) = m.coordinates("y")
    m.parameters(g=G, m=1.0)
    m.particle("b", sp.Symbol("m"), (0, y))
    m.gravity(sp.Symbol("g"))
    return compile_constrained(lcg.ConstrainedSystem(m, inequalities=[lcg.Inequality(y, restitution=E)]), "index1")


def integrator_in_calls(sim, dt: float = 0.01):
    integ = sim.integrator(q0=[1.0], v0=[0.0], rtol=1e-12, atol=1e-14)
    records = []
    for _ in range(int(round(T[-1] / dt))):
        integ.propagate_for(dt)
        records += integ.impacts.records
    return records


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="8 members, 3 rounds")
    ap.add_argument("--repeats", type=int, default=5, help="interleaved rounds per median (default 5)")
    ap.add_argument("--members", type=int, default=64, help="ensemble members (default 64)")
    ap.add_argument("--out", type=Path, help="also write DIR/impact_consumers.txt")
    args = ap.parse_args(argv)
    load0 = _harness.load_average()
    n = 8 if args.quick else args.members
    rounds = 3 if args.quick else max(1, args.repeats)
    sim = ball()
    Q = np.linspace(0.2, 2.0, n)[:, None]
    runs = {"simulate loop": lambda: [sim.simulate(T, q0=q, v0=[0.0]) for q in Q],
            "ensemble, 1 thread": lambda: sim.ensemble(T, q0=Q, threads=1),
            "ensemble, 2 threads": lambda: sim.ensemble(T, q0=Q, threads=2),
            "simulate, 6 s, rtol 1e-12": lambda: sim.simulate(T, q0=[1.0], v0=[0.0], rtol=1e-12, atol=1e-14),
            "integrator, 600 calls of 0.01 s": lambda: integrator_in_calls(sim)}
    for f in runs.values():
        f()
    wall, _, _ = _harness.timed_medians(runs, rounds, "impact_consumers")
    bounces = [r.t for r in integrator_in_calls(sim) if r.kind == "bounce"][:20]
    t1 = math.sqrt(2 / G)
    exact = [t1 + 2 * t1 * E * (1 - E**k) / (1 - E) for k in range(len(bounces))]
    err = max(abs(a / b - 1) for a, b in zip(bounces, exact))
    lines = _harness.machine_lines(f"Impacts beyond simulate: bouncing ball, {n} members / 6 s",
                                   (load0, _harness.load_average()))
    lines += [f"wall-time medians of {rounds} interleaved rounds", ""]
    lines += [f"{name:34s} {wall[name]:.4f} s" for name in runs]
    lines += ["", f"integrator in 0.01 s calls: largest relative error of the first {len(bounces)} bounce times "
                  f"{err:.1e}"]
    text = "\n".join(lines)
    print(text)
    if args.out:
        _harness.write_report(args.out, "impact_consumers", text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
