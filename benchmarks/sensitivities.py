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
  directions of |error| / max |reference| per direction; with the sensitivities in the error
  test (the default) and without (``sensitivity_errcon=False``).
* cost is reported as wall time and as the calling thread's CPU time (``time.thread_time``): on
  a machine loaded beyond its cores a millisecond run is often preempted for a scheduler quantum,
  which wall-time medians of short runs do not always absorb; the CPU time is not affected.
* cost: ``simulate`` with p sensitivities against the plain run (same rtol 1e-8, Adams, 201
  output times), both with sensitivity error control on (the default) and off; medians over
  interleaved rounds. Target: at most 1 + 0.7 p.
* against CasADi (``casadi_rows``): d y(10) / d p for all run-time parameters by CasADi's CVODES
  interface in several configurations (``CASADI_CONFIGS``; --quick: vm-bdf, vm-adams, jit-adams):
  its defaults on the SX virtual machine (BDF, the Jacobian of the integrator call), and Adams like
  ours with the forward seeds as ``nfwd`` columns and the block Newton matrix
  (``second_order_correction=False``, as ours), on the virtual machine and JIT-compiled
  (``jit=True, compiler="shell"``, -O3; left out with a note when no compiler works), the
  accelerations by a symbolic Cholesky factor of M or by ``solve(M, F)``, with QR or CSparse LU,
  the Jacobian form, functional iteration. All at rtol 1e-8, atol 1e-10 (CasADi's
  sensitivities are in the error test as ours with errcon on); ours with the same directions and
  two output times. Setup (build, JIT compile, first call) timed apart; medians of interleaved
  rounds (a contender stops after 30 s of calls); each contender's achieved error against ours at
  rtol 1e-13, itself checked against CasADi at rtol 1e-12; ours also at rtol 1e-6 .. 1e-10 for its
  CPU time at each CasADi configuration's achieved error (log-log, ``H.time_at``). Target: ours at
  most 0.5x the fastest CasADi configuration (by CPU time), which the printed target line names
  with its options.
* fit: ``lagcodegen.fit`` (exact Jacobian from the sensitivities) against
  ``scipy.optimize.least_squares`` with a 2-point finite-difference Jacobian on ``simulate``
  (same residuals, start, bounds and tolerances): the damped pendulum's l and c from 200 samples
  of theta with 1% noise (seeded). Target: >= 3x faster.

* Taylor (``--taylor``): ``simulate(method="taylor")`` with p sensitivities (jet transport of the
  variational equations) against the plain Taylor run (same rtol 1e-8, 201 output times, error
  control on and off; CPU-time medians of interleaved rounds; target 1 + 0.7 p) beside the same
  ratio of heyoka's variational equations (``var_ode_sys``, order 1, along the same directions, on
  the explicit system q'' = M^-1 F of the same M and F, tolerance 1e-8, ``propagate_grid`` over the
  same times; with its step counts plain/variational), and against
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
import atexit
import contextlib
import os
import shutil
import statistics
import sys
import tempfile
import time
from dataclasses import dataclass
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


def mass_and_forces(model, sim, funcs: dict, values: list):
    """M (rows) and F (entries) of ``model`` (sympy) evaluated on another tool's expressions:
    ``funcs`` its sin, cos, ... (lambdify's modules), ``values`` its expressions for q, q' and the
    run-time parameters in the scene's order."""
    import sympy as sp
    eom = lcg.derive(model)
    q = [sp.Symbol(s.name) for s in model.coords]
    v = [sp.Symbol(s.name) for s in model.speeds]
    prm = [sp.Symbol(name) for name in sim.param_names]
    modules = [dict(funcs, ImmutableDenseMatrix=lambda rows: rows), "math"]
    M = sp.lambdify(q + v + prm, eom.M, modules=modules)(*values)
    F = sp.lambdify(q + v + prm, eom.F, modules=modules)(*values)
    return [list(row) for row in M], [row[0] for row in F]


def casadi_dynamics(model, sim, solve: str = "solve"):
    """The same M q'' = F as CasADi SX expressions (sympy -> casadi): (casadi, x, p, ode), or None
    without casadi. The accelerations by ``solve``: "solve" CasADi's symbolic ``solve(M, F)``,
    "chol" its symbolic Cholesky factor M = R^T R (M is symmetric positive definite) and two
    triangular solves (fewer operations: 1544 against 2042 for the chain n = 5)."""
    try:
        import casadi as ca
    except ImportError:
        return None
    n, npar = sim.n, len(sim.param_names)
    x = ca.SX.sym("x", 2 * n)
    pp = ca.SX.sym("p", npar)
    Mrows, Frows = mass_and_forces(model, sim, {"sin": ca.sin, "cos": ca.cos},
                                   [x[i] for i in range(2 * n)] + [pp[k] for k in range(npar)])
    Mc = ca.vertcat(*[ca.horzcat(*row) for row in Mrows])
    Fc = ca.vertcat(*Frows)
    if solve == "chol":
        R = ca.chol(Mc)
        acc = ca.solve(R, ca.solve(R.T, Fc))
    else:
        acc = ca.solve(Mc, Fc)
    return ca, x, pp, ca.vertcat(x[n:], acc)


@dataclass(frozen=True)
class CasadiConfig:
    """One way of getting d y(T) / d p from CasADi's CVODES interface: ``options`` of
    ``integrator(..., "cvodes", ...)`` besides the tolerances; ``form`` "jacobian" (the Jacobian
    of an MX call of the integrator w.r.t. p: CasADi builds the forward-sensitivity integrator on
    demand) or "nfwd" (option nfwd = p: the forward seeds are extra columns of x0 and p, one call);
    ``jit`` compiles the integrator's generated functions (the DAE and its derivatives) with the C
    compiler (``compiler="shell"``, -O3) instead of running them on CasADi's SX virtual machine;
    ``dynamics`` the form of the accelerations (:func:`casadi_dynamics`)."""
    label: str
    options: dict
    form: str
    jit: bool
    dynamics: str = "chol"


#: CasADi's configurations timed in the cost section. CasADi integrates the forward
#: sensitivities as part of one augmented ODE (x and its p seed columns), so they are always in
#: CVODES's error test, like ours with sensitivity_errcon on (fsens_err_con changes no step).
#: ``second_order_correction=False`` keeps the states' Newton matrix on the diagonal of the
#: augmented one and nothing below it, as ours does; with it on (CasADi's default) every Newton
#: iteration also evaluates the directional derivatives of the sensitivity equations. The
#: accelerations by a symbolic Cholesky factor of M (ours factor M numerically), but in vm-bdf
#: (the configuration of earlier versions of this benchmark) and jit-adams-solve.
ADAMS_BLOCK = {"linear_multistep_method": "adams", "second_order_correction": False}
CASADI_CONFIGS = {
    "vm-bdf": CasadiConfig("VM, defaults (BDF), Jacobian of the call, solve(M, F)", {}, "jacobian", False, "solve"),
    "vm-adams": CasadiConfig("VM, Adams, nfwd, block Newton", ADAMS_BLOCK, "nfwd", False),
    "jit-adams": CasadiConfig("JIT, Adams, nfwd, block Newton", ADAMS_BLOCK, "nfwd", True),
    "jit-adams-solve": CasadiConfig("JIT, Adams, nfwd, block Newton, solve(M, F)", ADAMS_BLOCK, "nfwd", True,
                                    "solve"),
    "jit-adams-csparse": CasadiConfig("JIT, Adams, nfwd, block Newton, CSparse LU",
                                      dict(ADAMS_BLOCK, linear_solver="csparse"), "nfwd", True),
    "jit-adams-jacobian": CasadiConfig("JIT, Adams, Jacobian of the call, block Newton", ADAMS_BLOCK, "jacobian",
                                       True),
    "jit-adams-functional": CasadiConfig("JIT, Adams, nfwd, functional iteration",
                                         dict(ADAMS_BLOCK, nonlinear_solver_iteration="functional"), "nfwd", True),
}
CASADI_QUICK = ("vm-bdf", "vm-adams", "jit-adams")
#: Ours also at these tolerances (atol rtol / 100) against CasADi: its time at each CasADi
#: configuration's achieved error, interpolated in log-log.
OURS_TOLERANCES = (1e-6, 1e-7, 1e-9, 1e-10)


def casadi_options(config: CasadiConfig, rtol: float, nfwd: int) -> dict:
    """The complete options of ``integrator(..., "cvodes", ...)`` for ``config`` at ``rtol``
    (atol rtol / 100, as ours)."""
    opts = {"abstol": rtol * 1e-2, "reltol": rtol, "max_num_steps": 1000000, **config.options}
    if config.form == "nfwd":
        opts["nfwd"] = nfwd
    if config.jit:
        opts.update(jit=True, compiler="shell", jit_options={"compiler": H.c_compiler(), "flags": ["-O3"]})
    return opts


_JIT_DIR: list[str] = []


@contextlib.contextmanager
def in_jit_directory():
    """Run the block in a temporary folder (removed at exit): CasADi's JIT writes its C sources
    and libraries into the working directory (and leaves some), not the repository's."""
    if not _JIT_DIR:
        folder = tempfile.mkdtemp(prefix="sens_casadi_jit_")
        atexit.register(shutil.rmtree, folder, ignore_errors=True)
        _JIT_DIR.append(folder)
    old = os.getcwd()
    os.chdir(_JIT_DIR[0])
    try:
        yield
    finally:
        os.chdir(old)


def casadi_sensitivity_fn(dyn, sim, rtol: float, config: CasadiConfig):
    """A function (y0, p) -> d y(T) / d p (ny x np) by CasADi's CVODES in ``config``; ``dyn``
    from :func:`casadi_dynamics`. A JIT configuration compiles here (CasADi raises without a
    compiler): build it and make its first call inside :func:`in_jit_directory`."""
    ca, x, pp, ode = dyn
    ny, np_ = x.numel(), pp.numel()
    integ = ca.integrator("I", "cvodes", {"x": x, "p": pp, "ode": ode}, 0.0, T_END,
                          casadi_options(config, rtol, np_))
    if config.form == "nfwd":
        seeds_x, seeds_p = np.zeros((ny, np_)), np.eye(np_)

        def fn(y0, p):
            out = integ(x0=np.column_stack([y0, seeds_x]), p=np.column_stack([p, seeds_p]))["xf"]
            return np.array(out)[:, 1:]
        return fn
    xf, pf = ca.MX.sym("xf", ny), ca.MX.sym("pf", np_)
    J = ca.Function("J", [xf, pf], [ca.jacobian(integ(x0=xf, p=pf)["xf"], pf)])
    return lambda y0, p: np.array(J(y0, p))


def casadi_jacobian(model, sim, rtol: float):
    """CasADi's CVODES integrator of the same M q'' = F (its defaults, SX virtual machine) and a
    function (y0, p) -> d y(T) / d p (ny x np) for the run-time parameters; None without casadi."""
    config = CASADI_CONFIGS["vm-bdf"]
    dyn = casadi_dynamics(model, sim, config.dynamics)
    return None if dyn is None else casadi_sensitivity_fn(dyn, sim, rtol, config)


def direction_error(s: np.ndarray, ref: np.ndarray) -> float:
    """Max over directions (rows) of max |s - ref| / max |ref| along the direction."""
    return float(np.max(np.max(np.abs(s - ref), axis=1) / np.max(np.abs(ref), axis=1)))


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
        row = dict(scene=label, p=p)
        for errcon, tag in ((True, ""), (False, "_off")):
            res = sim.simulate(t, q0=np.full(sim.n, Q0), rtol=1e-8, atol=1e-10, sensitivities=names,
                               sensitivity_errcon=errcon)
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
            row.update({f"vs_central{tag}": worst_fd, f"vs_casadi{tag}": worst_ca, f"steps{tag}": res.stats["steps"]})
        rows.append(row)
    return rows


def casadi_rows(label, model, sim, rounds, configs=CASADI_QUICK, notes=None, budget: float = 30.0):
    """Ours against CasADi's forward sensitivities in each of ``configs`` (keys of
    :data:`CASADI_CONFIGS`): all run-time parameters, the state at t = 10, rtol 1e-8 (atol 1e-10)
    for every contender. Each contender's setup (integrator built, JIT compiled, first call) is
    timed apart; then interleaved rounds, a contender leaving once its calls took ``budget`` s
    (at least one timed call each). Achieved error of each against ours at rtol 1e-13 (max over
    directions of max |error| / max |reference|), the reference itself checked against CasADi's
    (VM, Adams) at rtol 1e-12; ours also at :data:`OURS_TOLERANCES`, for its CPU time at each
    contender's error (``equal_error_over``: that time / the contender's). A JIT configuration
    that cannot be built (no C compiler) is left out with a line in ``notes``. Rows: ours first,
    then each CasADi configuration; [] without casadi."""
    dyn = {"chol": casadi_dynamics(model, sim, "chol")}
    if dyn["chol"] is None:
        return []
    notes = [] if notes is None else notes
    n, names = sim.n, list(sim.param_names)
    y0 = np.concatenate([np.full(n, Q0), np.zeros(n)])
    pv = sim.parameter_vector()
    two = np.array([0.0, T_END])

    def ours():
        return sim.simulate(two, y0=y0, rtol=1e-8, atol=1e-10, sensitivities=names).sensitivities[-1, :, :2 * n]

    H.progress("casadi", f"{label}: references")
    ref = sim.simulate(two, y0=y0, rtol=1e-13, atol=1e-15, sensitivities=names).sensitivities[-1, :, :2 * n]
    check = casadi_sensitivity_fn(dyn["chol"], sim, 1e-12, CASADI_CONFIGS["vm-adams"])(y0, pv).T
    runs, setup, error, options = {"ours": ours}, {}, {}, {}
    start = time.perf_counter()
    error["ours"] = direction_error(ours(), ref)
    setup["ours"] = time.perf_counter() - start
    cc = H.c_compiler()
    for key in configs:
        config = CASADI_CONFIGS[key]
        if config.jit and shutil.which(cc) is None:
            notes.append(f"{label}: CasADi {key} left out: no C compiler {cc!r} for its JIT")
            H.progress("casadi", notes[-1])
            continue
        H.progress("casadi", f"{label}: {key} (build{', JIT' if config.jit else ''}, first call)")
        start = time.perf_counter()
        try:
            with in_jit_directory():
                if config.dynamics not in dyn:
                    dyn[config.dynamics] = casadi_dynamics(model, sim, config.dynamics)
                fn = casadi_sensitivity_fn(dyn[config.dynamics], sim, 1e-8, config)
                value = fn(y0, pv)
        except Exception as exc:  # noqa: BLE001 -- CasADi raises RuntimeError for a failed JIT
            if not config.jit:
                raise
            first = str(exc).strip().splitlines()[-1] if str(exc).strip() else type(exc).__name__
            notes.append(f"{label}: CasADi {key} left out: its JIT failed ({first[:160]})")
            H.progress("casadi", notes[-1])
            continue
        setup[key] = time.perf_counter() - start
        error[key] = direction_error(value.T, ref)
        options[key] = casadi_options(config, 1e-8, len(names))
        runs[key] = (lambda fn=fn: fn(y0, pv))
    med, mcpu, calls = H.timed_medians(runs, rounds, f"casadi {label}", budget=budget)
    # ours at other tolerances: its CPU time at each contender's achieved error (log-log)
    points = [(error["ours"], mcpu["ours"])]
    for tol in OURS_TOLERANCES:
        def run(tol=tol):
            return sim.simulate(two, y0=y0, rtol=tol, atol=tol / 100,
                                sensitivities=names).sensitivities[-1, :, :2 * n]
        err = direction_error(run(), ref)
        times = []
        for _ in range(max(3, rounds)):
            start_cpu = time.thread_time()
            run()
            times.append(time.thread_time() - start_cpu)
        points.append((err, statistics.median(times)))
    rows = []
    for k in runs:
        equal, how = H.time_at(points, error[k])
        rows.append(dict(scene=label, p=len(names), contender="ours" if k == "ours" else f"CasADi {k}",
                         config=k, setup_s=setup[k], ms=1e3 * med[k], cpu_ms=1e3 * mcpu[k], calls=calls[k],
                         error=error[k], ref_check=direction_error(check, ref),
                         ours_over=med["ours"] / med[k], cpu_ours_over=mcpu["ours"] / mcpu[k],
                         equal_error_over=None if equal is None else equal / mcpu[k], equal_how=how,
                         options=repr(options[k]) if k in options else ""))
    return rows


def cost_rows(label, model, sim, ps, rounds, casadi=CASADI_QUICK, notes=None):
    """Cost of p sensitivities against the plain run (rows) and ours against CasADi in the
    configurations ``casadi`` (:func:`casadi_rows`)."""
    t = np.linspace(0.0, T_END, 201)
    q0 = np.full(sim.n, Q0)
    runs = {"plain": lambda: sim.simulate(t, q0=q0, rtol=1e-8, atol=1e-10)}
    for p in ps:
        names = directions(sim, p)
        runs[f"p{p}"] = (lambda names=names: sim.simulate(t, q0=q0, rtol=1e-8, atol=1e-10, sensitivities=names))
        runs[f"p{p} off"] = (lambda names=names: sim.simulate(t, q0=q0, rtol=1e-8, atol=1e-10, sensitivities=names,
                                                              sensitivity_errcon=False))
    for f in runs.values():  # builds, first calls
        f()
    med, mcpu, _ = H.timed_medians(runs, rounds, f"cost {label}")
    rows = []
    for p in ps:
        rows.append(dict(scene=label, p=p, plain_ms=1e3 * med["plain"], sens_ms=1e3 * med[f"p{p}"],
                         ratio=med[f"p{p}"] / med["plain"], ratio_errcon_off=med[f"p{p} off"] / med["plain"],
                         cpu_ratio=mcpu[f"p{p}"] / mcpu["plain"],
                         cpu_ratio_errcon_off=mcpu[f"p{p} off"] / mcpu["plain"], target=1 + 0.7 * p))
    return rows, casadi_rows(label, model, sim, rounds, casadi, notes)


def fastest_casadi(rows) -> list[str]:
    """The target lines: per scene, ours / the fastest CasADi configuration (by CPU time)."""
    lines = []
    for scene in dict.fromkeys(r["scene"] for r in rows):
        mine = [r for r in rows if r["scene"] == scene]
        theirs = [r for r in mine if r["config"] != "ours"]
        if not theirs:
            continue
        best = min(theirs, key=lambda r: r["cpu_ms"])
        ours = next(r for r in mine if r["config"] == "ours")
        lines.append(f"{scene}: ours / CasADi's fastest ({best['config']}: {CASADI_CONFIGS[best['config']].label}) "
                     f"= {ours['cpu_ms'] / best['cpu_ms']:.2f} CPU, {ours['ms'] / best['ms']:.2f} wall "
                     f"(target <= 0.5); errors ours {ours['error']:.1e}, CasADi {best['error']:.1e}; at CasADi's "
                     f"error {H.fmt_value(best['equal_error_over'], '{:.2f}')} CPU (the reference against CasADi "
                     f"vm-adams at rtol 1e-12: {ours['ref_check']:.1e})")
        lines.append(f"    its options: integrator(..., \"cvodes\", dae, 0, {T_END:g}, {best['options']})"
                     + (", the Jacobian of the call w.r.t. p" if CASADI_CONFIGS[best["config"]].form == "jacobian"
                        else ", called with x0 = [x0, 0], p = [p, I] (the seeds as columns)")
                     + ("; ode: the accelerations by R = chol(M), solve(R, solve(R.T, F))"
                        if CASADI_CONFIGS[best["config"]].dynamics == "chol"
                        else "; ode: the accelerations by solve(M, F)"))
    return lines


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
    med = H.cpu_medians(runs, rounds, label)
    steps = {k: f().stats["steps"] for k, f in runs.items()}
    return [dict(scene=label, p=p, plain_ms=1e3 * med["plain"], sens_ms=1e3 * med[f"p{p}"],
                 ratio=med[f"p{p}"] / med["plain"], ratio_errcon_off=med[f"p{p} off"] / med["plain"],
                 steps_plain=steps["plain"], steps=steps[f"p{p}"], target=1 + 0.7 * p) for p in ps]


def heyoka_explicit(model, sim):
    """(system, state variables, parameters) of heyoka for q'' = M^-1 F of ``model`` (M and F from
    sympy, the run-time parameters as heyoka parameters in their order; M eliminated symbolically,
    ``H.eliminate``, as benchmarks/taylor.py does); None without heyoka."""
    try:
        import heyoka as hy
    except ImportError:
        return None
    n = sim.n
    hq = [hy.make_vars(f"q{k}") for k in range(n)]
    hv = [hy.make_vars(f"v{k}") for k in range(n)]
    A, b = mass_and_forces(model, sim, {"sin": hy.sin, "cos": hy.cos, "sqrt": hy.sqrt},
                           hq + hv + [hy.par[k] for k in range(len(sim.param_names))])
    A = [[hy.expression(e) if isinstance(e, (int, float)) else e for e in row] for row in A]
    b = [hy.expression(e) if isinstance(e, (int, float)) else e for e in b]
    acc = H.eliminate(A, b)
    return [(x, y) for x, y in zip(hq, hv)] + [(y, a) for y, a in zip(hv, acc)], hq, hy


def heyoka_var_ratios(model, sim, ps, rounds, tol=1e-8):
    """heyoka's variational equations (``var_ode_sys``, order 1, along the same directions as
    ours: run-time parameters, initial angles) on the explicit system: its run with p
    sensitivities / its plain run, each ``propagate_grid`` over the same 201 times at tolerance
    ``tol`` (CPU-time medians of interleaved rounds, JIT outside the timing; compact mode for
    n >= 5, plain and variational alike). {p: (ratio, "plain steps/variational steps")}, empty
    without heyoka."""
    built = heyoka_explicit(model, sim)
    if built is None:
        return {}
    sys_, hq, hy = built
    t = np.linspace(0.0, T_END, 201)
    state0 = [Q0] * sim.n + [0.0] * sim.n
    pv = list(sim.parameter_vector())
    compact = sim.n >= 5  # its JIT of the variational chain takes minutes otherwise
    tas = {"plain": hy.taylor_adaptive(sys_, state0, pars=pv, tol=tol, compact_mode=compact)}
    for p in ps:
        args = [hy.par[sim.param_names.index(name)] if name in sim.param_names
                else hq[sim.state_names.index(name[:-3])] for name in directions(sim, p)]
        tas[f"p{p}"] = hy.taylor_adaptive(hy.var_ode_sys(sys_, args, order=1), state0, pars=pv, tol=tol,
                                          compact_mode=compact)
    runs = {}
    for key, ta in tas.items():
        start = np.array(ta.state)

        def run(ta=ta, start=start):
            ta.time = 0.0
            ta.state[:] = start
            return ta.propagate_grid(t)[3]  # its step count
        runs[key] = run
    med = H.cpu_medians(runs, rounds, "heyoka var_ode_sys")
    steps = {key: run() for key, run in runs.items()}
    return {p: (med[f"p{p}"] / med["plain"], f"{steps['plain']}/{steps[f'p{p}']}") for p in ps}


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
            cpu = H.cpu_medians({"run": run}, rounds, f"{label} {method} rtol {tol:g}")["run"]
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
                            ("steps", "steps sens", "{}"), ("heyoka_ratio", "heyoka var / plain", "{:.2f}"),
                            ("heyoka_steps", "heyoka steps", "{}"),
                            ("target", "target", "{:.1f}")], cost),
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
    acc, cost, cas, notes = [], [], [], []
    configs = CASADI_QUICK if args.quick else tuple(CASADI_CONFIGS)
    for label, model in scenes(args.quick, args.max_n):
        H.progress("build", label)
        sim = lcg.compile_model(model)
        nd = len(sim.param_names) + sim.n
        ps = sorted({min(p, nd) for p in ps_all})
        acc += accuracy_rows(label, model, sim, ps, args.quick)
        rows, c = cost_rows(label, model, sim, ps, rounds, casadi=configs, notes=notes)
        cost += rows
        cas += c
    fits = fit_rows(1 if args.quick else 7)
    lines = H.machine_lines("Forward sensitivities on CVODE (benchmarks/sensitivities.py)", (load0, H.load_average()))
    lines += ["", "Accuracy at rtol 1e-8 (max relative error per direction, worst direction):",
              H.format_table([("scene", "scene", "{}"), ("p", "p", "{}"), ("vs_central", "vs central diff.", "{:.1e}"),
                              ("vs_casadi", "vs CasADi", "{:.1e}"), ("steps", "steps", "{}"),
                              ("vs_central_off", "errcon off: vs central", "{:.1e}"),
                              ("vs_casadi_off", "vs CasADi", "{:.1e}"), ("steps_off", "steps", "{}")], acc),
              "", f"Cost of a run with p sensitivities / the plain run (medians of {rounds} interleaved rounds; "
              "target 1 + 0.7 p):",
              H.format_table([("scene", "scene", "{}"), ("p", "p", "{}"), ("plain_ms", "plain ms", "{:.3f}"),
                              ("sens_ms", "sens ms", "{:.3f}"), ("ratio", "ratio", "{:.2f}"),
                              ("ratio_errcon_off", "ratio (errcon off)", "{:.2f}"),
                              ("cpu_ratio", "CPU ratio", "{:.2f}"), ("cpu_ratio_errcon_off", "CPU ratio (off)", "{:.2f}"),
                              ("target", "target", "{:.1f}")], cost)]
    if cas or notes:
        lines += ["", "Against CasADi's forward sensitivities (CVODES), all parameters, the state at t = 10, rtol 1e-8 "
                  "(atol 1e-10) for all; error: against ours at rtol 1e-13 (checked against CasADi at rtol 1e-12 "
                  "below); setup: build, JIT compile and first call, apart from the medians; "
                  "ours/X: ratio of medians (target ours/CasADi <= 0.5 against the fastest); at X's error: ours' "
                  "CPU time at X's achieved error (ours at rtol 1e-8 and "
                  f"{', '.join(f'{t:g}' for t in OURS_TOLERANCES)}, log-log interpolated; how: interp, or bound = "
                  "all ours more accurate) / X's:",
                  H.format_table([("scene", "scene", "{}"), ("p", "p", "{}"), ("contender", "contender", "{}"),
                                  ("setup_s", "setup s", "{:.2f}"), ("ms", "ms", "{:.3f}"),
                                  ("cpu_ms", "CPU ms", "{:.3f}"), ("calls", "calls", "{}"),
                                  ("error", "error", "{:.1e}"),
                                  ("ours_over", "ours/X", "{:.2f}"), ("cpu_ours_over", "ours/X CPU", "{:.2f}"),
                                  ("equal_error_over", "ours/X CPU, X's error", "{:.2f}"), ("equal_how", "how", "{}")],
                                 cas),
                  "", "CasADi configurations (options of integrator(..., \"cvodes\", ...) besides abstol, reltol, "
                  "max_num_steps; JIT: jit=True, compiler=\"shell\", jit_options={\"compiler\": "
                  f"\"{H.c_compiler()}\", \"flags\": [\"-O3\"]}}):"]
        lines += [f"  {key}: {c.label}; {c.form}; accelerations by {c.dynamics}; {c.options}"
                  for key, c in CASADI_CONFIGS.items() if key in configs]
        lines += [f"note: {note}" for note in notes]
        lines += ["", *fastest_casadi(cas)]
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
        rows = taylor_cost_rows(label, sim, ps, rounds)
        H.progress("heyoka", label)
        hy_ratio = heyoka_var_ratios(model, sim, ps, rounds)
        for row in rows:
            row["heyoka_ratio"], row["heyoka_steps"] = hy_ratio.get(row["p"], (None, None))
        cost += rows
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
