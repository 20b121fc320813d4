"""Taylor on rigid-body trees (issue 38): jets built from the tree's recorded program.

Models: a random 12-joint spatial chain (benchmarks/multibody.py's ``chain(12)``), the floating
Solo12 (example-robot-data, ``urdf.load(path, floating=True)``: 19 coordinates, 18 speeds) and
the UR5 (6 joints).

Per model:

* **first run**, in a new process with a new, empty cache (``LAGCODEGEN_CACHE``): the seconds of
  ``compile_model`` and of the first ``simulate(method="taylor")`` (the jet generated and compiled,
  and the Taylor runtime, which an installation compiles once, unless ``--warm-runtime``: then
  the runtime is compiled into the new cache by a first process and the timed process finds it);
  the target is <= 10 s for the first Taylor run of the floating Solo12 and the 12-joint chain;
* **jet**: its operations, and its order-1 coefficient of the speeds against Pinocchio's ``aba``
  at random states (max relative error; the URDF's joint damping as torques), the order-2 one
  against central differences of ``aba`` along the motion (relative, limited by the differences);
* **runs**: Taylor against CVODE Adams at rtol = atol = 1e-12 over t in [0, 1] (max difference
  of the state), and a work-precision sweep: each method at rtol = atol = tol, its error at
  t = 1 against Taylor at 1e-15 (checked against Adams at 1e-14) and its CPU time (the calling
  thread's, least of ``--rounds`` runs), Adams's time at the same error interpolated, and what
  ``method="auto"`` picks at that tolerance (with the model's measured costs).

With ``--evaluations``: the Adams right-hand side evaluations per Taylor step over t in [0, 10]
on the pendulums and chains behind :data:`lagcodegen.solvers.auto.EVALUATIONS`.

A measuring instrument: it asserts nothing.

Usage::

    python benchmarks/taylor_trees.py [--quick] [--models chain12,solo12,ur5] [--rounds R] [--warm-runtime] [--out DIR]
    python benchmarks/taylor_trees.py --evaluations
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

TOLS = (1e-6, 1e-8, 1e-10, 1e-12)
QUICK_TOLS = (1e-8, 1e-12)
T_END = 1.0


def robots() -> Path:
    import pinocchio as pin
    return Path(pin.__file__).resolve().parents[4] / "share" / "example-robot-data" / "robots"


def model(name: str):
    """(lagcodegen model, Pinocchio model, URDF file or None)."""
    import pinocchio as pin

    from lagcodegen import urdf
    if name == "chain12":
        from multibody import chain
        m, pm = chain(12)
        return m, pm, None
    if name == "solo12":
        file = robots() / "solo_description" / "robots" / "solo12.urdf"
        return urdf.load(file, floating=True), pin.buildModelFromUrdf(str(file), pin.JointModelFreeFlyer()), file
    if name == "ur5":
        file = robots() / "ur_description" / "urdf" / "ur5_robot.urdf"
        return urdf.load(file), pin.buildModelFromUrdf(str(file)), file
    raise SystemExit(f"unknown model {name!r} (chain12, solo12, ur5)")


def damping(pm, file) -> np.ndarray:
    from lagcodegen import urdf
    out = np.zeros(pm.nv)
    if file is not None:
        for name, joint in urdf.read(file).joints.items():
            if pm.existJointName(name) and joint.dynamics is not None:
                out[pm.joints[pm.getJointId(name)].idx_v] = joint.dynamics.damping
    return out


def initial(pm, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    import pinocchio as pin
    rng = np.random.default_rng(seed)
    q = pin.randomConfiguration(pm, -np.ones(pm.nq), np.ones(pm.nq))
    return q, rng.normal(size=pm.nv)


# --------------------------------------------------------------------------- first run (child)
def first_run(name: str) -> dict:
    """Run in a new process: compile_model and the first Taylor run, timed."""
    import resource

    import lagcodegen as lcg

    def cpu():  # this process's and its finished children's (gcc's) CPU seconds
        own, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
        return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime
    m, pm, _ = model(name)
    t0, c0 = time.perf_counter(), cpu()
    cm = lcg.compile_model(m, jacobian=False)
    t1, c1 = time.perf_counter(), cpu()
    q, v = initial(pm)
    res = cm.simulate([0.0, T_END], y0=np.concatenate([q, v]), method="taylor", rtol=1e-10, atol=1e-10)
    t2, c2 = time.perf_counter(), cpu()
    return dict(compile=t1 - t0, first_taylor=t2 - t1, compile_cpu=c1 - c0, first_taylor_cpu=c2 - c1,
                steps=res.stats["steps"])


def fresh(name: str, warm_runtime: bool) -> dict:
    with tempfile.TemporaryDirectory(prefix="lcg_taylor_trees_") as cache:
        env = dict(os.environ, LAGCODEGEN_CACHE=cache)
        if warm_runtime:  # the installation's Taylor runtime, compiled once, found by the timed process
            subprocess.run([sys.executable, "-c", "from lagcodegen.solvers.taylor.runner import taylor_runtime; "
                            "taylor_runtime()"], env=env, check=True)
        proc = subprocess.run([sys.executable, __file__, "--child", name], env=env, capture_output=True, text=True)
        if proc.returncode:
            raise RuntimeError(proc.stderr[-2000:])
        return json.loads(proc.stdout.strip().splitlines()[-1])


# --------------------------------------------------------------------------- checks and sweep
def jet_checks(cm, pm, file, module) -> dict:
    import pinocchio as pin
    data = pm.createData()
    c = damping(pm, file)
    e1 = e2 = 0.0
    nq, nv = pm.nq, pm.nv
    p = np.asarray(cm.code.param_defaults, dtype=float)
    for seed in range(5):
        q, v = initial(pm, seed + 1)
        jet = module.jet(0.0, np.concatenate([q, v]), p, 3)
        a = pin.aba(pm, data, q, v, -c * v)
        e1 = max(e1, float(np.abs(jet[nq:, 1] - a).max() / max(1.0, np.abs(a).max())))
        h = 1e-5  # a' = d/dt aba(q(t), v(t)) by central differences; the jet's order 2 is a'/2

        def aba_at(s):
            qs = pin.integrate(pm, q, s * v + 0.5 * s * s * a)
            return pin.aba(pm, data, qs, v + s * a, -c * (v + s * a))
        da = (aba_at(h) - aba_at(-h)) / (2 * h)
        e2 = max(e2, float(np.abs(2 * jet[nq:, 2] - da).max() / max(1.0, np.abs(da).max())))
    return dict(order1_vs_aba=e1, order2_vs_differences=e2)


def timed(run, rounds: int) -> tuple[float, object]:
    """The least CPU time of the calling thread over ``rounds`` calls of ``run`` (the runs are in
    this thread; a loaded machine's preemption does not inflate it), and the last result."""
    best, res = np.inf, None
    for _ in range(rounds):
        t0 = time.thread_time()
        res = run()
        best = min(best, time.thread_time() - t0)
    return best, res


def sweep(cm, pm, tols, rounds: int) -> tuple[dict, dict]:
    """Each method at each tolerance: seconds, error at T_END against Taylor at 1e-15 (checked
    against Adams at 1e-14: ``checks``), steps; and what auto picks, with the costs it weighs."""
    from lagcodegen.solvers.auto import choose_method
    q, v = initial(pm)
    y0 = np.concatenate([q, v])

    def run(method, tol):
        return cm.simulate([0.0, T_END], y0=y0, method=method, rtol=tol, atol=tol, max_steps=10**7)
    ref = run("taylor", 1e-15).y[-1]
    checks = dict(adams_1e14_vs_reference=float(np.abs(run("adams", 1e-14).y[-1] - ref).max()),
                  taylor_vs_adams_1e12=float(np.abs(run("taylor", 1e-12).y[-1] - run("adams", 1e-12).y[-1]).max()))
    rows = {}
    for method in ("taylor", "adams"):
        for tol in tols + ((1e-13, 1e-14) if method == "adams" else ()):
            seconds, res = timed(lambda: run(method, tol), rounds)
            rows[method, tol] = dict(seconds=seconds, error=float(np.abs(res.y[-1] - ref).max()),
                                     steps=res.stats["steps"])
    for tol in tols:
        costs = cm.method_costs(tol)
        rows["auto", tol] = dict(method=choose_method(cm.method_size, tol, cm.method_costs),
                                 costs=None if costs is None else (costs.adams_evaluation, costs.taylor_step))
    return rows, checks


def adams_at_error(rows: dict, error: float) -> float | None:
    """Adams's seconds at the achieved ``error``, log-log interpolated along its sweep (None
    outside the errors it reached)."""
    pts = sorted((r["error"], r["seconds"]) for (m, _), r in rows.items() if m == "adams" and r["error"] > 0)
    for (e0, s0), (e1, s1) in zip(pts, pts[1:]):
        if e0 <= error <= e1:
            w = (np.log(error) - np.log(e0)) / (np.log(e1) - np.log(e0))
            return float(np.exp(np.log(s0) + w * (np.log(s1) - np.log(s0))))
    return None


def evaluations() -> None:
    """Adams's rhs evaluations per Taylor step (lagcodegen.solvers.auto.EVALUATIONS: the least
    ratio at each tolerance, printed last): the pendulums compiled with their Jacobian (Adams's
    Newton iterations use it) and without (difference quotients: more evaluations), the chains
    without."""
    import lagcodegen as lcg
    from multibody import chain
    cases = [(f"pendulum{n}{'' if jac else '-nojac'}", lcg.systems.n_link_pendulum(n), [1.0] * n, jac)
             for n in (1, 3, 5) for jac in (True, False)]
    cases += [(f"chain{n}-nojac", chain(n)[0], list(np.random.default_rng(1).uniform(-1, 1, n)), False) for n in (4, 8)]
    tols = (1e-3, 1e-4, 1e-6, 1e-9, 1e-12, 1e-14)
    least = {tol: np.inf for tol in tols}
    print(f"{'model':<16} {'tol':>7} {'adams rhs':>9} {'taylor steps':>12} {'ratio':>6}")
    for name, m, q0, jac in cases:
        cm = lcg.compile_model(m, jacobian=jac)
        for tol in tols:
            a = cm.simulate([0, 10], q0=q0, method="adams", rtol=tol, atol=tol, max_steps=10**7)
            t = cm.simulate([0, 10], q0=q0, method="taylor", rtol=tol, atol=tol, max_steps=10**7)
            ratio = a.stats["rhs_evals"] / t.stats["steps"]
            least[tol] = min(least[tol], ratio)
            print(f"{name:<16} {tol:7.0e} {a.stats['rhs_evals']:9d} {t.stats['steps']:12d} {ratio:6.2f}", flush=True)
    print("least: " + ", ".join(f"({-np.log10(tol):.0f}, {r:.2f})" for tol, r in least.items()))


class Tee:
    """Writes to several streams."""

    def __init__(self, *streams):
        self.streams = streams

    def write(self, text):
        for s in self.streams:
            s.write(text)

    def flush(self):
        for s in self.streams:
            s.flush()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="the 12-joint chain only, two tolerances, one round (< 60 s)")
    ap.add_argument("--models", default=None)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--warm-runtime", action="store_true")
    ap.add_argument("--evaluations", action="store_true")
    ap.add_argument("--out", default=None, help="also write the tables to DIR/taylor_trees.txt")
    ap.add_argument("--child", default=None, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        print(json.dumps(first_run(args.child)))
        return
    if args.out:  # the tables into DIR/taylor_trees.txt too
        Path(args.out).mkdir(parents=True, exist_ok=True)
        sys.stdout = Tee(sys.stdout, open(Path(args.out) / "taylor_trees.txt", "w", encoding="utf-8"))
    if args.evaluations:
        evaluations()
        return
    import lagcodegen as lcg
    from lagcodegen.solvers.taylor.run import taylor_module
    names = (args.models or ("chain12" if args.quick else "chain12,solo12,ur5")).split(",")
    tols, rounds = (QUICK_TOLS, 1) if args.quick else (TOLS, args.rounds)
    for name in names:
        first = fresh(name, args.warm_runtime)
        print(f"== {name}: first run in a new cache{' (runtime compiled before)' if args.warm_runtime else ''}: "
              f"compile_model {first['compile']:.2f} s (CPU {first['compile_cpu']:.2f} s), first Taylor run (jet "
              f"included) {first['first_taylor']:.2f} s (CPU {first['first_taylor_cpu']:.2f} s; {first['steps']} steps)",
              flush=True)
        m, pm, file = model(name)
        cm = lcg.compile_model(m, jacobian=False)
        module = taylor_module(cm)
        checks = jet_checks(cm, pm, file, module)
        print(f"   jet: {len(module.decomposition.ops)} operations ({module.decomposition.form} form); order 1 vs "
              f"pin.aba {checks['order1_vs_aba']:.1e}, order 2 vs differences of aba "
              f"{checks['order2_vs_differences']:.1e}", flush=True)
        rows, checks = sweep(cm, pm, tols, rounds)
        print(f"   reference: Taylor at 1e-15 (Adams at 1e-14 differs by {checks['adams_1e14_vs_reference']:.1e}); "
              f"Taylor vs Adams at rtol = atol = 1e-12 over [0, {T_END}]: max |dy| {checks['taylor_vs_adams_1e12']:.1e}")
        print(f"   {'method':>6} {'tol':>7} {'seconds':>9} {'error':>8} {'steps':>6}  Adams's s at that error / Taylor's; "
              "auto; costs weighed (Adams per evaluation, Taylor step) us")
        for (method, tol), r in rows.items():
            if method == "auto":
                continue
            extra = ""
            if method == "taylor":
                a = adams_at_error(rows, r["error"])
                auto = rows["auto", tol]
                costs = "-" if auto["costs"] is None else f"{auto['costs'][0] * 1e6:.2f}, {auto['costs'][1] * 1e6:.1f}"
                ratio = "beyond Adams's sweep" if a is None else f"{a / r['seconds']:.2f}"
                extra = f"  {ratio}; auto {auto['method']}; {costs}"
            print(f"   {method:>6} {tol:7.0e} {r['seconds']:9.4f} {r['error']:8.1e} {r['steps']:6d}{extra}", flush=True)


if __name__ == "__main__":
    main()
