"""Forward sensitivities on CVODE (issue 24): accuracy, cost, and the fit they drive.

Scenes: the double pendulum (5 run-time parameters) and the planar n-link chain with a length
and a mass per link (n = 5, 10; 2n + 1 parameters; not in --quick), every angle 0.5 rad at
rest, t in [0, 10].
Directions: the run-time parameters in their order, then initial angles, p = 1, 3, 10 (at most
the directions there are).

* accuracy: the sensitivities of a rtol 1e-8 run (atol 1e-10) against (a) the fourth-order
  central-difference stencil of rtol 1e-13 runs at h = 2e-4 relative (its optimal step on these
  scenes: truncation ~h^4, noise ~rtol/h) at 21 times, and (b) CasADi's forward sensitivities
  (CVODES, the Jacobian of ``casadi.integrator`` w.r.t. the parameters at t = 10; the same M and
  F converted from sympy, rtol 1e-12) for the parameter directions. Max over states and
  directions of |error| / max |reference| per direction.
* cost is reported as wall time and as the calling thread's CPU time (``time.thread_time``): on
  a machine loaded beyond its cores a millisecond run is often preempted for a scheduler quantum,
  which wall-time medians of short runs do not always absorb; the CPU time is not affected.
* cost: ``simulate`` with p sensitivities against the plain run (same rtol 1e-8, Adams, 201
  output times), both with sensitivity error control on (the default) and off; medians over
  interleaved rounds. Target: at most 1 + 0.7 p. CasADi: its forward-sensitivity integration at
  rtol 1e-8 (the Jacobian function called; median of up to 5 calls within 60 s) against ours with
  the parameter directions and two output times; target: ours at most 0.5x.
* fit: ``lagcodegen.fit`` (exact Jacobian from the sensitivities) against
  ``scipy.optimize.least_squares`` with a 2-point finite-difference Jacobian on ``simulate``
  (same residuals, start, bounds and tolerances): the damped pendulum's l and c from 200 samples
  of theta with 1% noise (seeded). Target: >= 3x faster.

* Taylor (``--taylor``): ``simulate(method="taylor")`` with p sensitivities (jet transport of the
  variational equations) against the plain Taylor run (same rtol 1e-8, 201 output times, error
  control on and off; CPU-time medians of interleaved rounds; target 1 + 0.7 p), and against
  CVODE's sensitivities (Adams) at equal achieved error: both at rtol 1e-5 .. 1e-12 (atol
  rtol/100), the error of the sensitivities along the first min(p, 3) directions against
  CVODE's at rtol 1e-13 (max over states, directions and 21 times of |error| / max |reference|),
  the CPU time at errors 1e-6 and 1e-8 interpolated in log-log (``H.time_at``).

Outputs: the tables on stdout (progress on stderr); with --out DIR: sensitivities.txt and
sensitivities.csv. A measuring instrument: it asserts nothing.

Usage::

    python benchmarks/sensitivities.py [--quick] [--out DIR] [--rounds R] [--max-n 5] [--taylor]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _harness as H  # noqa: E402

import lagcodegen as lcg  # noqa: E402

T_END = 10.0
Q0 = 0.5


def scenes(quick: bool, max_n: int = 10):
    out = [("double pendulum", lcg.systems.double_pendulum())]
    if not quick:
        out += [(f"chain n={n}", lcg.systems.n_link_pendulum(n, name=f"sens_chain{n}", shared_parameters=False))
                for n in (5, 10) if n <= max_n]
    return out


def directions(sim, p: int) -> list[str]:
    names = list(sim.param_names) + [f"{c}(0)" for c in sim.state_names[:sim.n]]
    return names[:p]


def central(sim, t, name, rtol=1e-13, atol=1e-15, h=2e-4) -> np.ndarray:
    """Fourth-order central differences of the states in the direction ``name`` (nt, ny)."""
    base = dict(zip(sim.param_names, sim.parameter_vector()))
    runs = {}
    for sign in (2, 1, -1, -2):
        q, p = np.full(sim.n, Q0), dict(base)
        if name.endswith("(0)"):
            i = sim.state_names.index(name[:-3])
            step = h * max(1.0, abs(q[i]))
            q[i] += sign * step
        else:
            step = h * abs(p[name])
            p[name] += sign * step
        runs[sign] = sim.simulate(t, q0=q, params=p, rtol=rtol, atol=atol).y
    return (8 * (runs[1] - runs[-1]) - (runs[2] - runs[-2])) / (12 * step)


def casadi_jacobian(model, sim, rtol: float):
    """CasADi's CVODES integrator of the same M q'' = F (sympy -> casadi) and the Function giving
    d y(T) / d p (ny x np) for the run-time parameters; None without casadi."""
    try:
        import casadi as ca
    except ImportError:
        return None
    import sympy as sp
    eom = lcg.derive(model)
    n = sim.n
    q = [sp.Symbol(s.name) for s in model.coords]
    v = [sp.Symbol(s.name) for s in model.speeds]
    prm = [sp.Symbol(name) for name in sim.param_names]
    x = ca.SX.sym("x", 2 * n)
    pp = ca.SX.sym("p", len(prm))
    args = q + v + prm
    M = sp.lambdify(args, eom.M, modules=[{"sin": ca.sin, "cos": ca.cos, "ImmutableDenseMatrix": lambda rows: rows},
                                          "math"])
    F = sp.lambdify(args, eom.F, modules=[{"sin": ca.sin, "cos": ca.cos, "ImmutableDenseMatrix": lambda rows: rows},
                                          "math"])
    vals = [x[i] for i in range(2 * n)] + [pp[k] for k in range(len(prm))]
    Mrows, Frows = M(*vals), F(*vals)
    Mc = ca.vertcat(*[ca.horzcat(*row) for row in Mrows])
    Fc = ca.vertcat(*[row[0] for row in Frows])
    acc = ca.solve(Mc, Fc)
    ode = ca.vertcat(x[n:], acc)
    integ = ca.integrator("I", "cvodes", {"x": x, "p": pp, "ode": ode}, 0.0, T_END,
                          {"abstol": rtol * 1e-2, "reltol": rtol, "max_num_steps": 1000000})
    xf, pf = ca.MX.sym("xf", 2 * n), ca.MX.sym("pf", len(prm))
    return ca.Function("J", [xf, pf], [ca.jacobian(integ(x0=xf, p=pf)["xf"], pf)])


def accuracy_rows(label, model, sim, ps, quick):
    t = np.linspace(0.0, T_END, 21)
    rows = []
    ref_ca = None
    J = casadi_jacobian(model, sim, 1e-12)
    y0 = np.concatenate([np.full(sim.n, Q0), np.zeros(sim.n)])
    if J is not None:
        ref_ca = np.array(J(y0, sim.parameter_vector()))
    refs: dict = {}
    for p in ps:
        names = directions(sim, p)
        res = sim.simulate(t, q0=np.full(sim.n, Q0), rtol=1e-8, atol=1e-10, sensitivities=names)
        worst_fd, worst_ca = 0.0, None
        for j, name in enumerate(names[: (2 if quick else 3)]):
            if name not in refs:
                H.progress("accuracy", f"{label} {name}: central differences")
                refs[name] = central(sim, t, name)
            ref = refs[name]
            worst_fd = max(worst_fd, float(np.max(np.abs(res.sensitivities[:, j, :2 * sim.n] - ref))
                                            / np.max(np.abs(ref))))
        if ref_ca is not None:
            worst_ca = 0.0
            for j, name in enumerate(names):
                if name in sim.param_names:
                    col = ref_ca[:, sim.param_names.index(name)]
                    worst_ca = max(worst_ca, float(np.max(np.abs(res.sensitivities[-1, j, :2 * sim.n] - col))
                                                   / np.max(np.abs(col))))
        rows.append(dict(scene=label, p=p, vs_central=worst_fd, vs_casadi=worst_ca, steps=res.stats["nsteps"]))
    return rows


def cost_rows(label, model, sim, ps, rounds):
    t = np.linspace(0.0, T_END, 201)
    q0 = np.full(sim.n, Q0)
    runs = {"plain": lambda: sim.simulate(t, q0=q0, rtol=1e-8, atol=1e-10)}
    for p in ps:
        names = directions(sim, p)
        runs[f"p{p}"] = (lambda names=names: sim.simulate(t, q0=q0, rtol=1e-8, atol=1e-10, sensitivities=names))
        runs[f"p{p} off"] = (lambda names=names: sim.simulate(t, q0=q0, rtol=1e-8, atol=1e-10, sensitivities=names,
                                                              sensitivity_errcon=False))
    # CasADi at equal tolerance, parameter directions, the state at T only; ours likewise
    J = casadi_jacobian(model, sim, 1e-8)
    y0 = np.concatenate([q0, np.zeros(sim.n)])
    pv = sim.parameter_vector()
    two = np.array([0.0, T_END])
    vs: dict = {}
    if J is not None:  # timed apart (CasADi's seconds per call would stretch every round)
        H.progress("cost", f"{label}: CasADi's forward sensitivities")
        ours = (lambda: sim.simulate(two, y0=y0, rtol=1e-8, atol=1e-10, sensitivities=list(sim.param_names)))
        ours()
        vs["casadi"] = H.median_time(lambda: J(y0, pv), 5, budget=60.0)[0]
        vs["ours vs casadi"] = H.median_time(ours, 5 * rounds)[0]
    for f in runs.values():  # builds, first calls
        f()
    times = {k: [] for k in runs}
    cpu = {k: [] for k in runs}
    for r in range(rounds):
        H.progress("cost", f"{label} round {r + 1}/{rounds}")
        for k, f in runs.items():
            start, start_cpu = time.perf_counter(), time.thread_time()
            f()
            cpu[k].append(time.thread_time() - start_cpu)
            times[k].append(time.perf_counter() - start)
    med = {k: statistics.median(v) for k, v in times.items()}
    mcpu = {k: statistics.median(v) for k, v in cpu.items()}
    rows = []
    for p in ps:
        rows.append(dict(scene=label, p=p, plain_ms=1e3 * med["plain"], sens_ms=1e3 * med[f"p{p}"],
                         ratio=med[f"p{p}"] / med["plain"], ratio_errcon_off=med[f"p{p} off"] / med["plain"],
                         cpu_ratio=mcpu[f"p{p}"] / mcpu["plain"],
                         cpu_ratio_errcon_off=mcpu[f"p{p} off"] / mcpu["plain"], target=1 + 0.7 * p))
    casadi = None
    if J is not None:
        casadi = dict(scene=label, p=len(sim.param_names), ours_ms=1e3 * vs["ours vs casadi"],
                      casadi_ms=1e3 * vs["casadi"], ratio=vs["ours vs casadi"] / vs["casadi"], target=0.5)
    return rows, casadi


def fit_rows(rounds):
    from scipy.optimize import least_squares
    sim = lcg.compile_model(lcg.systems.damped_pendulum())
    t = np.linspace(0.0, 10.0, 200)
    true = {"l": 1.0, "c": 0.3}
    noise = 0.01
    ref = sim.simulate(t, q0=[1.0], params=true, rtol=1e-11, atol=1e-13)
    data = ref["theta"] + noise * np.random.default_rng(20241).standard_normal(t.size)
    start = {"l": 0.9, "c": 0.05}
    ls = dict(xtol=1e-8, ftol=1e-8, gtol=1e-8, max_nfev=100)

    def exact():
        return lcg.fit(sim, t, data[:, None], params=start, observe=["theta"], q0=[1.0], sigma=noise,
                       solver_options=ls)

    def fd():
        def residuals(x):
            r = sim.simulate(t, q0=[1.0], params={"l": x[0], "c": x[1]}, rtol=1e-8, atol=1e-10)
            return (r["theta"] - data) / noise
        return least_squares(residuals, [start["l"], start["c"]], jac="2-point", method="trf", x_scale="jac", **ls)

    exact(), fd()
    te, tf, ce, cf = [], [], [], []
    for r in range(rounds):
        H.progress("fit", f"round {r + 1}/{rounds}")
        a, b = time.perf_counter(), time.thread_time()
        fe = exact()
        te.append(time.perf_counter() - a)
        ce.append(time.thread_time() - b)
        a, b = time.perf_counter(), time.thread_time()
        ff = fd()
        tf.append(time.perf_counter() - a)
        cf.append(time.thread_time() - b)
    me, mf = statistics.median(te), statistics.median(tf)
    mce, mcf = statistics.median(ce), statistics.median(cf)
    return [dict(method="exact Jacobian (sensitivities)", ms=1e3 * me, cpu_ms=1e3 * mce, iterations=fe.iterations,
                 nfev=fe.nfev, l=fe.params["l"], c=fe.params["c"], speedup=mf / me, cpu_speedup=mcf / mce),
            dict(method="2-point finite differences", ms=1e3 * mf, cpu_ms=1e3 * mcf, iterations=int(ff.njev or 0),
                 nfev=int(ff.nfev), l=float(ff.x[0]), c=float(ff.x[1]), speedup=1.0, cpu_speedup=1.0),
            dict(method="stderr l, c (truth 1.0, 0.3)", ms=None, cpu_ms=None, iterations=None, nfev=None,
                 l=fe.stderr["l"], c=fe.stderr["c"], speedup=None, cpu_speedup=None)]


def _cpu_medians(runs: dict, rounds: int, label: str) -> dict:
    """Median thread CPU time of each run over interleaved rounds (after one call each)."""
    for f in runs.values():
        f()
    cpu = {k: [] for k in runs}
    for r in range(rounds):
        H.progress("taylor", f"{label} round {r + 1}/{rounds}")
        for k, f in runs.items():
            start = time.thread_time()
            f()
            cpu[k].append(time.thread_time() - start)
    return {k: statistics.median(v) for k, v in cpu.items()}


def taylor_cost_rows(label, sim, ps, rounds):
    """Taylor with p sensitivities / the plain Taylor run (CPU-time medians)."""
    t = np.linspace(0.0, T_END, 201)
    q0 = np.full(sim.n, Q0)
    kw = dict(q0=q0, rtol=1e-8, atol=1e-10, method="taylor")
    runs = {"plain": lambda: sim.simulate(t, **kw)}
    for p in ps:
        names = directions(sim, p)
        runs[f"p{p}"] = (lambda names=names: sim.simulate(t, sensitivities=names, **kw))
        runs[f"p{p} off"] = (lambda names=names: sim.simulate(t, sensitivities=names, sensitivity_errcon=False, **kw))
    med = _cpu_medians(runs, rounds, label)
    steps = {k: f().stats["steps"] for k, f in runs.items()}
    return [dict(scene=label, p=p, plain_ms=1e3 * med["plain"], sens_ms=1e3 * med[f"p{p}"],
                 ratio=med[f"p{p}"] / med["plain"], ratio_errcon_off=med[f"p{p} off"] / med["plain"],
                 steps_plain=steps["plain"], steps=steps[f"p{p}"], target=1 + 0.7 * p) for p in ps]


def taylor_vs_cvode_rows(label, sim, p, rounds, tolerances=(1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-12)):
    """CPU time of Taylor and CVODE (Adams) sensitivity runs at equal achieved error."""
    t = np.linspace(0.0, T_END, 21)
    q0 = np.full(sim.n, Q0)
    names = directions(sim, p)
    ref = sim.simulate(t, q0=q0, rtol=1e-13, atol=1e-15, sensitivities=names).sensitivities[:, :, :2 * sim.n]
    scale = np.max(np.abs(ref), axis=(0, 2))
    points = {"taylor": [], "adams": []}
    for tol in tolerances:
        for method in points:
            def run(method=method, tol=tol):
                return sim.simulate(t, q0=q0, rtol=tol, atol=tol / 100, method=method, sensitivities=names)
            res = run()
            err = float(np.max(np.max(np.abs(res.sensitivities[:, :, :2 * sim.n] - ref), axis=(0, 2)) / scale))
            cpu = _cpu_medians({"run": run}, rounds, f"{label} {method} rtol {tol:g}")["run"]
            points[method].append((err, cpu))
    rows = []
    for target in (1e-6, 1e-8):
        (tt, how_t), (tc, how_c) = H.time_at(points["taylor"], target), H.time_at(points["adams"], target)
        rows.append(dict(scene=label, p=p, error=target, taylor_ms=None if tt is None else 1e3 * tt,
                         cvode_ms=None if tc is None else 1e3 * tc,
                         ratio=None if tt is None or tc is None else tt / tc, how=f"{how_t}/{how_c}"))
    return rows, points


def taylor_lines(cost, equal, rounds) -> list[str]:
    return ["", f"Taylor (jet transport of the variational equations): a run with p sensitivities / the plain Taylor "
            f"run (CPU-time medians of {rounds} interleaved rounds; target 1 + 0.7 p):",
            H.format_table([("scene", "scene", "{}"), ("p", "p", "{}"), ("plain_ms", "plain ms", "{:.3f}"),
                            ("sens_ms", "sens ms", "{:.3f}"), ("ratio", "ratio", "{:.2f}"),
                            ("ratio_errcon_off", "ratio (errcon off)", "{:.2f}"), ("steps_plain", "steps plain", "{}"),
                            ("steps", "steps sens", "{}"), ("target", "target", "{:.1f}")], cost),
            "", "Taylor against CVODE (Adams) sensitivities at equal achieved error (CPU ms, log-log interpolated; "
            "how: interp, or bound = every run more accurate):",
            H.format_table([("scene", "scene", "{}"), ("p", "p", "{}"), ("error", "error", "{:.0e}"),
                            ("taylor_ms", "Taylor ms", "{:.3f}"), ("cvode_ms", "CVODE ms", "{:.3f}"),
                            ("ratio", "Taylor/CVODE", "{:.2f}"), ("how", "how", "{}")], equal)]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="small configuration (under 2 minutes)")
    ap.add_argument("--out", type=Path, default=None)
    ap.add_argument("--rounds", type=int, default=None)
    ap.add_argument("--max-n", type=int, default=10, help="largest chain (5 or 10; the double pendulum always)")
    ap.add_argument("--taylor", action="store_true", help="the Taylor integrator's sensitivities only")
    args = ap.parse_args(argv)
    if args.taylor:
        return taylor_main(args)
    rounds = args.rounds or (5 if args.quick else 21)
    ps_all = [1, 3] if args.quick else [1, 3, 10]
    load0 = H.load_average()
    acc, cost, cas = [], [], []
    for label, model in scenes(args.quick, args.max_n):
        H.progress("build", label)
        sim = lcg.compile_model(model)
        nd = len(sim.param_names) + sim.n
        ps = sorted({min(p, nd) for p in ps_all})
        acc += accuracy_rows(label, model, sim, ps, args.quick)
        rows, c = cost_rows(label, model, sim, ps, rounds)
        cost += rows
        if c:
            cas.append(c)
    fits = fit_rows(1 if args.quick else 7)
    lines = H.machine_lines("Forward sensitivities on CVODE (benchmarks/sensitivities.py)", (load0, H.load_average()))
    lines += ["", "Accuracy at rtol 1e-8 (max relative error per direction, worst direction):",
              H.format_table([("scene", "scene", "{}"), ("p", "p", "{}"), ("vs_central", "vs central diff.", "{:.1e}"),
                              ("vs_casadi", "vs CasADi", "{:.1e}"), ("steps", "steps", "{}")], acc),
              "", f"Cost of a run with p sensitivities / the plain run (medians of {rounds} interleaved rounds; "
              "target 1 + 0.7 p):",
              H.format_table([("scene", "scene", "{}"), ("p", "p", "{}"), ("plain_ms", "plain ms", "{:.3f}"),
                              ("sens_ms", "sens ms", "{:.3f}"), ("ratio", "ratio", "{:.2f}"),
                              ("ratio_errcon_off", "ratio (errcon off)", "{:.2f}"),
                              ("cpu_ratio", "CPU ratio", "{:.2f}"), ("cpu_ratio_errcon_off", "CPU ratio (off)", "{:.2f}"),
                              ("target", "target", "{:.1f}")], cost)]
    if cas:
        lines += ["", "Against CasADi's forward sensitivities (CVODES), all parameters, state at t = 10, rtol 1e-8 "
                  "(target ours/CasADi <= 0.5):",
                  H.format_table([("scene", "scene", "{}"), ("p", "p", "{}"), ("ours_ms", "ours ms", "{:.3f}"),
                                  ("casadi_ms", "CasADi ms", "{:.3f}"), ("ratio", "ours/CasADi", "{:.2f}")], cas)]
    lines += ["", "Fit of the damped pendulum's l and c (200 samples, 1% noise; target speedup >= 3):",
              H.format_table([("method", "method", "{}"), ("ms", "ms", "{:.1f}"), ("cpu_ms", "CPU ms", "{:.1f}"),
                              ("iterations", "iterations", "{}"), ("nfev", "nfev", "{}"), ("l", "l", "{:.6f}"),
                              ("c", "c", "{:.6f}"), ("speedup", "speedup", "{:.2f}"),
                              ("cpu_speedup", "CPU speedup", "{:.2f}")], fits)]
    text = "\n".join(lines)
    print(text)
    if args.out:
        H.write_report(args.out, "sensitivities", text, acc + cost + cas + fits)
    return 0


def taylor_main(args) -> int:
    """``--taylor``: the Taylor sections alone."""
    rounds = args.rounds or (5 if args.quick else 21)
    ps_all = [1, 3] if args.quick else [1, 3, 10]
    load0 = H.load_average()
    cost, equal = [], []
    for label, model in scenes(args.quick, args.max_n):
        H.progress("build", label)
        sim = lcg.compile_model(model)
        nd = len(sim.param_names) + sim.n
        ps = sorted({min(p, nd) for p in ps_all})
        cost += taylor_cost_rows(label, sim, ps, rounds)
        equal += taylor_vs_cvode_rows(label, sim, min(3, nd), max(3, rounds // 3))[0]
    lines = H.machine_lines("Forward sensitivities on the Taylor integrator (benchmarks/sensitivities.py --taylor)",
                            (load0, H.load_average()))
    text = "\n".join(lines + taylor_lines(cost, equal, rounds))
    print(text)
    if args.out:
        H.write_report(args.out, "sensitivities_taylor", text, cost + equal)
    return 0


if __name__ == "__main__":
    sys.exit(main())
