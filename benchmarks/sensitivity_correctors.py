"""The two correctors of CVODE's sensitivity driver (lcg_cvsens.c), staggered and simultaneous,
side by side: where the cost of a run with p sensitivities goes, and what it costs.

Scenes and runs as in benchmarks/sensitivities.py (the double pendulum, the 5-link chain; every
angle 0.5 rad at rest, t in [0, 10], 201 output times, Adams, rtol 1e-8, atol 1e-10), with the
sensitivities in the error test (the default) and without.

* counts per step: steps (and their ratio to the plain run's), the sensitivity right-hand sides
  (<prefix>_sens_rhs: the states and every direction) and the states' right-hand sides of the
  staggered corrector's Newton iterations, Newton iterations, Jacobians, factorizations;
* cost: the calling thread's CPU time (``time.thread_time``) of each run over the plain run's,
  medians of interleaved rounds in one process (both correctors on the same fast path).

A measuring instrument: it asserts nothing. Usage::

    python benchmarks/sensitivity_correctors.py [--rounds R] [--quick] [--out DIR]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _harness as H  # noqa: E402

import lagcodegen as lcg  # noqa: E402

CORRECTORS = ("staggered", "simultaneous")


def scenes(quick: bool):
    out = [("double pendulum", lcg.systems.double_pendulum(), (1, 3, 7))]
    if not quick:
        out.append(("chain n=5", lcg.systems.n_link_pendulum(5, name="sens_chain5", shared_parameters=False),
                    (1, 3, 10)))
    return out


def rows_of(label, model, ps, rounds):
    sim = lcg.compile_model(model)
    t = np.linspace(0.0, 10.0, 201)
    q0 = np.full(sim.n, 0.5)
    names = list(sim.param_names) + [f"{c}(0)" for c in sim.state_names[:sim.n]]
    runs = {"plain": lambda: sim.simulate(t, q0=q0, rtol=1e-8, atol=1e-10)}
    for p in ps:
        for errcon in (True, False):
            for c in CORRECTORS:
                runs[(p, errcon, c)] = (lambda p=p, e=errcon, c=c: sim.simulate(
                    t, q0=q0, rtol=1e-8, atol=1e-10, sensitivities=names[:p], sensitivity_errcon=e,
                    sensitivity_corrector=c))
    stats = {k: f().stats for k, f in runs.items()}
    med = H.cpu_medians(runs, rounds, f"correctors {label}", warm=False)
    plain = stats["plain"]
    rows = [dict(scene=label, p=0, errcon="-", corrector="plain", steps=plain["steps"], steps_ratio=1.0,
                 sens_rhs=None, states_rhs=plain["rhs_evals"] / plain["steps"],
                 nni=plain["nonlin_iters"] / plain["steps"], jac=plain["jac_evals"],
                 fact=plain["lin_setups"] / plain["steps"], cpu_ms=1e3 * med["plain"], ratio=1.0, target=None)]
    for p in ps:
        for errcon in (True, False):
            for c in CORRECTORS:
                s = stats[(p, errcon, c)]
                n = s["steps"]
                rows.append(dict(scene=label, p=p, errcon="on" if errcon else "off", corrector=c, steps=n,
                                 steps_ratio=n / plain["steps"], sens_rhs=s["rhs_evals"] / n,
                                 states_rhs=s["rhs_evals_states"] / n if c == "staggered" else None,
                                 nni=s["nonlin_iters"] / n, jac=s["jac_evals"],
                                 fact=s["factorizations"] / n, cpu_ms=1e3 * med[(p, errcon, c)],
                                 ratio=med[(p, errcon, c)] / med["plain"], target=1 + 0.7 * p))
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=9)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args(argv)
    rows = []
    load0 = H.load_average()
    for label, model, ps in scenes(args.quick):
        rows += rows_of(label, model, ps, 3 if args.quick else args.rounds)
    lines = H.machine_lines("Sensitivity correctors (benchmarks/sensitivity_correctors.py)", (load0, H.load_average()))
    lines += ["", "Per step: sensitivity RHS (states and every direction), the states' RHS of the staggered Newton",
              "iterations (plain run: its RHS), Newton iterations, factorizations; CPU time over the plain run's",
              f"(medians of {3 if args.quick else args.rounds} interleaved rounds; target 1 + 0.7 p):"]
    columns = [("scene", "scene", "{}"), ("p", "p", "{}"), ("errcon", "errcon", "{}"), ("corrector", "corrector", "{}"),
               ("steps", "steps", "{}"), ("steps_ratio", "x plain", "{:.2f}"), ("sens_rhs", "sens RHS", "{:.2f}"),
               ("states_rhs", "states RHS", "{:.2f}"), ("nni", "Newton it.", "{:.2f}"), ("jac", "Jacobians", "{}"),
               ("fact", "factor.", "{:.2f}"), ("cpu_ms", "CPU ms", "{:.3f}"), ("ratio", "ratio", "{:.2f}"),
               ("target", "target", "{:.1f}")]
    lines.append(H.format_table(columns, rows))
    text = "\n".join(lines)
    print(text)
    if args.out is not None:
        H.write_report(args.out, "sensitivity_correctors", text, rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
