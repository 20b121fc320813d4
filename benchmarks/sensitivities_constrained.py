"""Forward sensitivities of constrained systems (index-1 on CVODE): accuracy and cost.

Scenes: the pendulum and the double pendulum in Cartesian coordinates (bobs at (x_i, y_i), rods
as holonomic constraints, eq. 4.1), from angles 1.0 and 0.5 rad at rest, t in [0, 5]; the same
pendulums in their angles as unconstrained ODEs (lagcodegen.systems.pendulum, double_pendulum).
Directions: every run-time parameter, then x1(0), x1_dot(0).

* accuracy: the sensitivities of a rtol 1e-8 run (atol 1e-10, Baumgarte "auto") against (a) the
  fourth-order central-difference stencil of rtol 1e-13 runs (h = 2e-4 relative, the perturbed
  starts projected onto the constraints as the sensitivities' are) at 26 times, and (b) for the
  parameters (of a chain those not in the constraints: a length moves the Cartesian start
  through the projection, not along the angles), the angle ODE's own sensitivities (rtol 1e-12)
  against those of the angles
  theta_i = atan2(u_i, w_i), u_i = x_i - x_{i-1}, w_i = y_{i-1} - y_i, from the Cartesian ones:
  d theta_i = (w_i du_i - u_i dw_i) / (u_i^2 + w_i^2). Max over states (or angles) and
  directions of |error| / max |reference| per direction (that size at least 1e-2 of the largest
  direction's: a mass moves neither); also with projection=True (BDF) in place of Baumgarte.
* cost: ``simulate`` with p sensitivities against the plain index-1 run (rtol 1e-8, Adams, 201
  output times), and the angle ODE's sensitivity run against its plain run for comparison;
  medians over interleaved rounds (wall and the calling thread's CPU time). Target of issue 24:
  at most 1 + 0.7 p.

Outputs: the tables on stdout (progress on stderr); with --out DIR: sensitivities_constrained.txt
and .csv. A measuring instrument: it asserts nothing.

Usage::

    python benchmarks/sensitivities_constrained.py [--quick] [--out DIR] [--rounds R]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _harness as H  # noqa: E402

import lagcodegen as lcg  # noqa: E402
from lagcodegen.theory.constraints import ConstrainedSystem  # noqa: E402

T_END = 5.0


def cartesian_chain(n: int) -> ConstrainedSystem:
    """n bobs at (x_i, y_i) on rods of lengths l_i from the previous bob (the first from the
    origin), masses m_i, gravity g: the parameters of lcg.systems.pendulum / double_pendulum."""
    m = lcg.Model(f"bench_csens_chain{n}")
    coords = m.coordinates(" ".join(f"x{i} y{i}" for i in range(1, n + 1)))
    if n == 1:
        ls, ms = [m.parameters(l=1.0)[0]], [m.parameters(m=1.0)[0]]
        g = m.parameters(g=9.81)[0]
    else:
        ls = list(m.parameters(**{f"l{i}": 1.0 for i in range(1, n + 1)}))
        ms = list(m.parameters(**{f"m{i}": 1.0 for i in range(1, n + 1)}))
        g = m.parameters(g=9.81)[0]
    rows, px, py = [], 0, 0
    for i in range(n):
        x, y = coords[2 * i], coords[2 * i + 1]
        m.particle(f"bob{i + 1}", ms[i], (x, y))
        rows.append((x - px) ** 2 + (y - py) ** 2 - ls[i] ** 2)
        px, py = x, y
    m.gravity(g)
    return ConstrainedSystem(m, holonomic=rows)


def scenes(quick: bool):
    out = [("pendulum", cartesian_chain(1), lcg.systems.pendulum("bench_csens_angle1"), [1.0])]
    if not quick:
        out.append(("double pendulum", cartesian_chain(2), lcg.systems.double_pendulum("bench_csens_angle2"),
                    [1.0, 0.5]))
    return out


def start(angles) -> tuple[np.ndarray, np.ndarray]:
    q, x, y = [], 0.0, 0.0
    for a in angles:
        x, y = x + np.sin(a), y - np.cos(a)
        q += [x, y]
    return np.array(q), np.zeros(len(q))


def directions(sim) -> list[str]:
    return list(sim.param_names) + ["x1(0)", "x1_dot(0)"]


def angles_of(res, n: int, d: str | None = None) -> np.ndarray:
    """The angles of a Cartesian run (d None), or their sensitivities in the direction d."""
    out, px, py, dpx, dpy = [], 0.0, 0.0, 0.0, 0.0
    for i in range(1, n + 1):
        x, y = res[f"x{i}"], res[f"y{i}"]
        if d is None:
            out.append(np.arctan2(x - px, py - y))
        else:
            dx, dy = res.sensitivity(f"x{i}", d), res.sensitivity(f"y{i}", d)
            ux, uy = x - px, py - y
            out.append((uy * (dx - dpx) - ux * (dpy - dy)) / (ux ** 2 + uy ** 2))
            dpx, dpy = dx, dy
        px, py = x, y
    return np.column_stack(out)


def central(sim, t, q0, v0, name, projection: bool, h=2e-4):
    base = dict(zip(sim.param_names, sim.parameter_vector(None)))
    coords = sim.state_names[:sim.n]
    runs = {}
    for sign in (2, 1, -1, -2):
        q, v, p = q0.copy(), v0.copy(), dict(base)
        if name.endswith("_dot(0)"):
            step = h
            v[coords.index(name[:-7])] += sign * step
        elif name.endswith("(0)"):
            step = h
            q[coords.index(name[:-3])] += sign * step
        else:
            step = h * abs(p[name])
            p[name] += sign * step
        r = sim.simulate(t, q0=q, v0=v, params=p, rtol=1e-13, atol=1e-15, initial="project", projection=projection)
        runs[sign] = r.y
    return (8 * (runs[1] - runs[-1]) - (runs[2] - runs[-2])) / (12 * step)


def same_start(sim, angle) -> list[str]:
    """The parameters whose sensitivities the two models define alike: a rod length moves the
    Cartesian start through the projection onto the new constraints, which keeps the angle of a
    single pendulum (radially) but not of a chain; so the chain's lengths are left out."""
    rods = set().union(*(f.free_symbols for f in sim.system.holonomic))
    return [p for p in angle.param_names if sim.n == 2 or p not in {s.name for s in rods}]


def worst(pairs) -> float:
    """max over (got, reference) pairs of max |got - ref| / max |ref|, the reference's size at
    least 1e-2 of the largest (a direction the quantities do not depend on, such as a mass of
    the pendulum, has a reference of rounding noise)."""
    top = max(float(np.max(np.abs(ref))) for _, ref in pairs)
    return max(float(np.max(np.abs(got - ref))) / max(float(np.max(np.abs(ref))), 1e-2 * top) for got, ref in pairs)


def accuracy_rows(label, sim, angle, angles0, quick: bool):
    t = np.linspace(0.0, T_END, 26)
    q0, v0 = start(angles0)
    n = len(angles0)
    names = directions(sim)
    rows = []
    ref_angle = angle.simulate(t, q0=list(angles0), rtol=1e-12, atol=1e-14,
                               sensitivities=list(angle.param_names))
    for projection in (False, True):
        H.progress("accuracy", f"{label}, projection={projection}")
        res = sim.simulate(t, q0=q0, v0=v0, rtol=1e-8, atol=1e-10, sensitivities=names, projection=projection)
        pairs = []
        for j, name in enumerate(names if not quick else names[:2]):
            pairs.append((res.sensitivities[:, j, :2 * sim.n], central(sim, t, q0, v0, name, projection)))
        worst_c = worst(pairs)
        pairs = []
        for name in same_start(sim, angle):
            want = np.column_stack([ref_angle.sensitivity(f"theta{i}" if n > 1 else "theta", name)
                                    for i in range(1, n + 1)])
            pairs.append((angles_of(res, n, name), want))
        worst_a = worst(pairs)
        rows.append(dict(scene=label, projection=projection, p=len(names), vs_central=worst_c, vs_angles=worst_a,
                         steps=res.stats["steps"]))
    return rows


def cost_rows(label, sim, angle, angles0, rounds):
    t = np.linspace(0.0, T_END, 201)
    q0, v0 = start(angles0)
    names = directions(sim)
    ps = sorted({1, 3, len(names)})
    runs = {"plain": lambda: sim.simulate(t, q0=q0, v0=v0, rtol=1e-8, atol=1e-10),
            "angle plain": lambda: angle.simulate(t, q0=list(angles0), rtol=1e-8, atol=1e-10)}
    for p in ps:
        runs[f"p{p}"] = (lambda p=p: sim.simulate(t, q0=q0, v0=v0, rtol=1e-8, atol=1e-10, sensitivities=names[:p]))
        an = list(angle.param_names)[:p] if p <= len(angle.param_names) else None
        if an:
            runs[f"angle p{p}"] = (lambda an=an: angle.simulate(t, q0=list(angles0), rtol=1e-8, atol=1e-10,
                                                                 sensitivities=an))
    for f in runs.values():  # builds, first calls
        f()
    med, mcpu, _ = H.timed_medians(runs, rounds, f"cost {label}")
    rows = []
    for p in ps:
        ang = f"angle p{p}"
        rows.append(dict(scene=label, p=p, plain_ms=1e3 * med["plain"], sens_ms=1e3 * med[f"p{p}"],
                         ratio=med[f"p{p}"] / med["plain"], cpu_ratio=mcpu[f"p{p}"] / mcpu["plain"],
                         angle_ratio=(med[ang] / med["angle plain"]) if ang in med else None,
                         angle_cpu_ratio=(mcpu[ang] / mcpu["angle plain"]) if ang in mcpu else None,
                         target=1 + 0.7 * p))
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="the pendulum only, two directions checked (under a minute)")
    ap.add_argument("--out", type=Path, default=None)
    ap.add_argument("--rounds", type=int, default=None)
    args = ap.parse_args(argv)
    rounds = args.rounds or (5 if args.quick else 21)
    load0 = H.load_average()
    acc, cost = [], []
    for label, system, model, angles0 in scenes(args.quick):
        H.progress("build", label)
        sim = lcg.compile_constrained(system, "index1")
        angle = lcg.compile_model(model)
        acc += accuracy_rows(label, sim, angle, angles0, args.quick)
        cost += cost_rows(label, sim, angle, angles0, rounds)
    lines = H.machine_lines("Forward sensitivities of index-1 constrained systems "
                            "(benchmarks/sensitivities_constrained.py)", (load0, H.load_average()))
    lines += ["", "Accuracy at rtol 1e-8 (max relative error per direction, worst direction):",
              H.format_table([("scene", "scene", "{}"), ("projection", "projection", "{}"), ("p", "p", "{}"),
                              ("vs_central", "vs central diff.", "{:.1e}"),
                              ("vs_angles", "vs angle ODE", "{:.1e}"), ("steps", "steps", "{}")], acc),
              "", f"Cost of a run with p sensitivities / the plain index-1 run (medians of {rounds} interleaved "
              "rounds; target 1 + 0.7 p); the angle ODE's ratio beside it:",
              H.format_table([("scene", "scene", "{}"), ("p", "p", "{}"), ("plain_ms", "plain ms", "{:.3f}"),
                              ("sens_ms", "sens ms", "{:.3f}"), ("ratio", "ratio", "{:.2f}"),
                              ("cpu_ratio", "CPU ratio", "{:.2f}"), ("angle_ratio", "angle ODE ratio", "{:.2f}"),
                              ("angle_cpu_ratio", "angle ODE CPU ratio", "{:.2f}"),
                              ("target", "target", "{:.1f}")], cost)]
    text = "\n".join(lines)
    print(text)
    if args.out:
        H.write_report(args.out, "sensitivities_constrained", text, acc + cost)
    return 0


if __name__ == "__main__":
    sys.exit(main())
