"""Constrained mechanics on the Bari test set: lagcodegen's formulations against CasADi and scipy.

Problems (benchmarks/bari_problems.py): Andrews' squeezing mechanism (7 angles, 6 holonomic
constraints, index 3, t in [0, 0.03]) and the car axis (4 coordinates, 2 constraints, one of
them time dependent, t in [0, 3], eps = 1e-2), both from the Bari test set, and, as a third
easy data point, the Cartesian pendulum of benchmarks/constraint_drift.py (t in [0, 20]).

Contenders, each run over a sweep of tolerances (rtol = atol = the swept value; 101 output
times evenly spaced over the interval, served by the integrator's interpolation unless said
otherwise):

* lagcodegen, from one ``compile_constrained`` per formulation (cold build in a fresh cache):
  index-1 plain (CVODE Adams and BDF), index-1 + Baumgarte "auto" (the default: alpha = beta =
  the natural rate of the initial state; Adams), index-1 + Baumgarte (alpha, beta) in (1e1, 1e1), (1e2, 1e2),
  (1e3, 1e3), (1e4, 1e4) (Adams and BDF), index-1 + projection (BDF, CVodeSetProjFn), GGL on
  IDA (interpolated outputs, and ``stop_at_outputs=True``); and "the default call": what a
  user who tunes nothing but rtol gets, ``compile_constrained(system)`` then
  ``sim.simulate((t0, t1), q0=..., v0=..., rtol=r)`` (1001 output times, atol 1e-10). The
  literal untuned call (rtol 1e-8 as well) is reported on its own line.
* CasADi (3.8, ``pip install casadi``; skipped when absent): IDAS on the index-1 DAE
  (x = (q, q'), z = (q'', lambda), algebraic variables out of the error test), IDAS on the GGL
  form (z = (q'', lambda, mu), atol 1e8 on z as lagcodegen's native GGL, csparse), both with
  ``jit`` (cc -O2, one build per tolerance: CasADi fixes tolerances at construction), and
  CVODES Adams (functional iteration) on the index-1 ODE with q'' = solve([M -G^T; G 0], ...)
  solved symbolically in SX and jit-compiled once (derivatives by finite differences, which
  Adams/functional never asks for).
* scipy ``solve_ivp`` methods Radau, BDF, LSODA stepped one by one (to count steps) on the
  numpy index-1 ODE of bari_problems (13 x 13 / 6 x 6 / 3 x 3 dense solve per call, no
  stabilization, finite-difference Jacobians); a run stops at --budget seconds.

Measured per (contender, rtol): wall time of the call (median over --rounds rounds; every
round runs every contender at every tolerance, so that drifts of the machine load hit all
alike; a run under 50 ms is repeated 3 times back to back in each round, all of them entering
the median; runs slower than 1 s are timed once), steps, the position error
max_i |q_i(t1) - ref_i| / |ref_i| at the end point, the multipliers' error
max_j |lambda_j(t1) - ref_j| / |ref_j| (lagcodegen: its lambda outputs; CasADi IDAS: its z;
CasADi CVODES and scipy: the augmented system at the final state) and the constraint drift
max over the output times of max_j |g_j(q, t)|. Per contender: the time to reach position
errors 1e-6, 1e-8, 1e-10 (log-log interpolation along its points, or "<=" the cheapest run
when every run is more accurate), with the drift and multiplier error of the cheapest run
reaching that error beside it; steps and microseconds per step at rtol 1e-8 (and, for
lagcodegen, the median time spent inside the generated C driver, ``stats["wall_time"]``, in the
list of every run: the rest of a call is Python); the cold build
time (lagcodegen: generate + compile in an empty cache, per formulation; CasADi: integrator
construction including jit, median over the tolerances).

Reference: by default ("computed") scipy DOP853 at rtol 1e-13, atol 1e-15 on the numpy
index-1 transcription (the pendulum: on the angle model), whose distance to DOP853 at rtol
1e-12 is printed as its uncertainty, together with its distance to the published values.
The published Andrews reference is good to about 3e-10 only in the positions (its velocities
to 5e-8, multipliers to 1e-6, and it misses its own velocity constraint G v = 0 by 1e-9):
errors near 1e-10 need the computed one. ``--reference published`` uses the published values.

Output: tables on stdout (progress on stderr); with --out DIR: bari.txt, bari.csv (every run)
and bari_<problem>.png (work-precision). The machine's load average is printed at the start
and the end. This is a measuring instrument: it asserts nothing.

Usage::

    python benchmarks/bari.py [--quick] [--out DIR] [--rounds N] [--problems andrews,caraxis,pendulum]
                              [--contenders REGEX] [--budget S] [--reference computed|published]
"""

from __future__ import annotations

import argparse
import contextlib
import gc
import importlib.util
import math
import os
import re
import shutil
import statistics
import sys
import tempfile
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _harness as H  # noqa: E402
import bari_problems as BP  # noqa: E402

TAG = "bari"
TARGETS = (1e-6, 1e-8, 1e-10)
N_GRID = 101
STEP_RTOL = 1e-8  # steps and per-step cost are reported at this rtol
SLOW_RUN = 1.0    # runs slower than this (s) are timed in the first round only
FAST_RUN = 0.05   # runs faster than this (s) are repeated back to back, up to INNER times per round
INNER = 3
BAUMGARTE = ((1e1, 1e1), (1e2, 1e2), (1e3, 1e3), (1e4, 1e4))
PROBLEMS = ("andrews", "caraxis", "pendulum")
DEFAULT_LABEL = "lcg default call (rtol only)"
JIT_DIRS: list = []  # working folders of CasADi's jit (it leaves jit_tmp*.c sources behind)


def progress(message: str) -> None:
    H.progress(TAG, message)


# --------------------------------------------------------------------------- settings
@dataclass
class Settings:
    rtols: list
    rounds: int = 5
    budget: float = 5.0
    problems: tuple = PROBLEMS
    contenders: str | None = None
    reference: str = "computed"
    quick: bool = False


def parse_args(argv=None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true",
                    help="rtol 1e-5, 1e-7, 1e-9; 2 rounds; no CasADi CVODES; 1 s scipy budget (< 2 min)")
    ap.add_argument("--out", metavar="DIR", type=Path, help="write bari.txt, bari.csv and bari_<problem>.png")
    ap.add_argument("--rounds", type=int, help="interleaved rounds per median (default 5; quick 2)")
    ap.add_argument("--problems", help=f"comma-separated subset of {','.join(PROBLEMS)}")
    ap.add_argument("--contenders", metavar="REGEX", help="only contenders whose label matches REGEX")
    ap.add_argument("--budget", type=float, help="seconds a scipy run may take (default 5; quick 1)")
    ap.add_argument("--reference", choices=("computed", "published"), default="computed",
                    help="reference of the errors (default: computed, see the module docstring)")
    return ap.parse_args(argv)


def settings_from(args) -> Settings:
    if args.quick:
        s = Settings(rtols=[1e-5, 1e-7, 1e-9], rounds=2, budget=1.0, quick=True)
    else:
        s = Settings(rtols=[10.0 ** -k for k in range(4, 13)])
    if args.rounds is not None:
        s.rounds = max(1, args.rounds)
    if args.budget is not None:
        s.budget = args.budget
    if args.problems:
        names = tuple(x.strip() for x in args.problems.split(",") if x.strip())
        bad = [x for x in names if x not in PROBLEMS]
        if bad:
            raise SystemExit(f"bari: unknown problem(s) {', '.join(bad)} (known: {', '.join(PROBLEMS)})")
        s.problems = names
    s.contenders = args.contenders
    s.reference = args.reference
    return s


# --------------------------------------------------------------------------- contenders
@dataclass
class Outcome:
    """One run: wall seconds, final positions and multipliers, steps, drift."""

    wall: float
    q_end: np.ndarray | None = None
    lam_end: np.ndarray | None = None
    steps: int | None = None
    drift: float = float("nan")
    status: str = "ok"
    c_wall: float | None = None  # lagcodegen: seconds spent in the generated C driver


@dataclass
class Contender:
    label: str
    family: str                     # lagcodegen / casadi / scipy
    run: Callable                   # run(rtol) -> Outcome
    build_s: float | None = None    # cold build time
    prepare: Callable | None = None  # prepare(rtol) -> seconds (CasADi: one integrator per rtol)
    rtols: list | None = None       # None: the sweep
    builds: list = field(default_factory=list)


def _grid(pr) -> np.ndarray:
    return np.linspace(pr.t0, pr.t1, N_GRID)


def lagcodegen_contenders(pr, system, settings, tmp: Path) -> list[Contender]:
    """The lagcodegen configurations, compiled in the (empty) cache folder ``tmp``."""
    from lagcodegen.api import compile_constrained

    sims, build = {}, {}
    with H.cache_at(tmp):
        for form in ("index1", "ggl"):
            start = time.perf_counter()
            sims[form] = compile_constrained(system, form)
            build[form] = time.perf_counter() - start
            progress(f"{pr.name}: compile_constrained(system, {form!r}) cold: {build[form]:.2f} s")
    grid = _grid(pr)
    n, c = pr.n, pr.nc

    def make(form, t_arg=None, **opts):
        sim = sims[form]

        def run(rtol):
            times = grid if t_arg is None else t_arg
            kw = dict(opts)
            if rtol is not None:
                kw["rtol"] = rtol
                if t_arg is None:
                    kw["atol"] = rtol
            start = time.perf_counter()
            res = sim.simulate(times, q0=pr.q0, v0=pr.v0, **kw)
            wall = time.perf_counter() - start
            q = res.y[:, :n]
            lam = np.array([res[f"lambda_{j}"][-1] for j in range(c)])
            drift = max(float(np.max(np.abs(res[f"g_{j}"]))) for j in range(c))
            return Outcome(wall, q[-1].copy(), lam, int(res.stats.get("steps", 0)), drift,
                           c_wall=res.stats.get("wall_time"))
        return run

    out = [Contender("lcg index-1 Adams", "lagcodegen", make("index1", method="adams", baumgarte=(0, 0)),
                     build["index1"]),
           Contender("lcg index-1 BDF", "lagcodegen", make("index1", method="bdf", baumgarte=(0, 0)), build["index1"]),
           Contender("lcg index-1 + Baumgarte auto Adams", "lagcodegen", make("index1", method="adams"),
                     build["index1"])]
    for ab in BAUMGARTE:
        tag = f"({ab[0]:.0e},{ab[1]:.0e})".replace("e+0", "e")
        for method, name in (("adams", "Adams"), ("bdf", "BDF")):
            out.append(Contender(f"lcg index-1 + Baumgarte{tag} {name}", "lagcodegen",
                                 make("index1", method=method, baumgarte=ab), build["index1"]))
    out += [Contender("lcg index-1 + projection BDF", "lagcodegen", make("index1", projection=True), build["index1"]),
            Contender("lcg GGL IDA", "lagcodegen", make("ggl"), build["ggl"]),
            Contender("lcg GGL IDA stop_at_outputs", "lagcodegen", make("ggl", stop_at_outputs=True), build["ggl"]),
            Contender(DEFAULT_LABEL, "lagcodegen", make("index1", t_arg=(pr.t0, pr.t1)), build["index1"]),
            Contender("lcg default call as is", "lagcodegen", make("index1", t_arg=(pr.t0, pr.t1)), build["index1"],
                      rtols=[None])]
    return out


@contextlib.contextmanager
def in_dir(folder: Path):
    """Run the block in ``folder``: CasADi's jit writes its jit_tmp*.c sources to the working
    directory and leaves some behind."""
    old = os.getcwd()
    os.chdir(folder)
    try:
        yield
    finally:
        os.chdir(old)


def casadi_contenders(pr, settings, jit_dir: Path) -> list[Contender]:
    import casadi as ca

    n, c = pr.n, pr.nc
    q, v, a = ca.SX.sym("q", n), ca.SX.sym("v", n), ca.SX.sym("a", n)
    lam, mu, t = ca.SX.sym("lam", c), ca.SX.sym("mu", c), ca.SX.sym("t")
    M, f, g, G, gdd = pr.terms([q[i] for i in range(n)], [v[i] for i in range(n)], t, pr.params, ca)
    M = ca.blockcat([[ca.SX(x) for x in row] for row in M])
    G = ca.blockcat([[ca.SX(x) for x in row] for row in G])
    f, g, gdd = (ca.vertcat(*[ca.SX(x) for x in vec]) for vec in (f, g, gdd))
    x = ca.vertcat(q, v)
    a0, lam0 = pr.kkt(pr.q0, pr.v0, pr.t0)
    x0 = np.concatenate([pr.q0, pr.v0])
    grid = _grid(pr)
    jit = dict(jit=True, compiler="shell", jit_options={"flags": ["-O2"], "verbose": False})

    def finish(F, zf_lam, start):
        """Call F, collect the outcome (zf_lam: slice of z holding lambda, or None)."""
        def call(z0):
            t1 = time.perf_counter()
            r = F(x0=x0, z0=z0) if z0 is not None else F(x0=x0)
            wall = time.perf_counter() - t1
            xf = np.array(r["xf"])
            qs = xf[:n, :].T
            qs = np.vstack([pr.q0, qs])
            if zf_lam is not None:
                lam_end = np.array(r["zf"])[zf_lam, -1]
            else:
                _, lam_end = pr.kkt(xf[:n, -1], xf[n:, -1], pr.t1)
            st = F.stats()
            return Outcome(wall, qs[-1].copy(), lam_end, int(st.get("nsteps", 0)), pr.max_g(qs, grid))
        return call

    def idas(form):
        if form == "index1":
            dae = {"x": x, "z": ca.vertcat(a, lam), "t": t, "ode": ca.vertcat(v, a),
                   "alg": ca.vertcat(M @ a - f - G.T @ lam, G @ a + gdd)}
            z0, zl = np.concatenate([a0, lam0]), slice(n, n + c)
        else:
            gdot = G @ v + ca.jacobian(g, t)
            dae = {"x": x, "z": ca.vertcat(a, lam, mu), "t": t, "ode": ca.vertcat(v + G.T @ mu, a),
                   "alg": ca.vertcat(M @ a - f - G.T @ lam, g, gdot)}
            z0, zl = np.concatenate([a0, lam0, np.zeros(c)]), slice(n, n + c)
        integrators = {}

        def prepare(rtol):
            opts = dict(reltol=rtol, abstol=rtol, max_num_steps=10**7, suppress_algebraic=True, calc_ic=False,
                        init_xdot=list(np.concatenate([pr.v0, a0])), linear_solver="csparse", **jit)
            if form == "ggl":  # lambda, mu: loose, as lagcodegen's native GGL (see lagcodegen.solvers.ida)
                opts["abstolv"] = [rtol] * (2 * n) + [1e8] * (n + 2 * c)
            start = time.perf_counter()
            with in_dir(jit_dir):
                integrators[rtol] = ca.integrator(f"bari_{pr.name}_{form}", "idas", dae, pr.t0, list(grid[1:]), opts)
            return time.perf_counter() - start

        def run(rtol):
            return finish(integrators[rtol], zl, None)(z0)
        label = "CasADi IDAS index-1 DAE jit" if form == "index1" else "CasADi IDAS GGL jit"
        return Contender(label, "casadi", run, prepare=prepare)

    out = [idas("index1"), idas("ggl")]
    if not settings.quick:
        K = ca.blockcat([[M, -G.T], [G, ca.SX.zeros(c, c)]])
        acc = ca.solve(K, ca.vertcat(f, -gdd))[:n]
        start = time.perf_counter()
        with in_dir(jit_dir):
            rhs = ca.Function(f"bari_{pr.name}_rhs", [x, t], [ca.vertcat(v, acc)],
                              dict(enable_fd=True, enable_forward=False, enable_reverse=False, enable_jacobian=False,
                                   fd_method="forward", **jit))
        X, T = ca.MX.sym("x", 2 * n), ca.MX.sym("t")
        rhs_build = time.perf_counter() - start
        integrators = {}

        def prepare_ode(rtol):
            start = time.perf_counter()
            with in_dir(jit_dir):
                integrators[rtol] = ca.integrator(f"bari_{pr.name}_ode", "cvodes", {"x": X, "t": T, "ode": rhs(X, T)},
                                                  pr.t0, list(grid[1:]),
                                                  dict(reltol=rtol, abstol=rtol, max_num_steps=10**7,
                                                       linear_multistep_method="adams",
                                                       nonlinear_solver_iteration="functional"))
            return time.perf_counter() - start + rhs_build

        out.append(Contender("CasADi CVODES Adams index-1 ODE jit", "casadi",
                             lambda rtol: finish(integrators[rtol], None, None)(None), prepare=prepare_ode))
    return out


def scipy_contenders(pr, settings) -> list[Contender]:
    from scipy.integrate import BDF, LSODA, Radau

    grid = _grid(pr)
    n = pr.n
    y0 = np.concatenate([pr.q0, pr.v0])

    def make(cls):
        def run(rtol):
            deadline = time.perf_counter() + settings.budget
            start = time.perf_counter()
            solver = cls(pr.index1_rhs, pr.t0, y0, pr.t1, rtol=rtol, atol=rtol)
            rows, k, steps = [y0], 1, 0
            while solver.status == "running":
                solver.step()
                steps += 1
                if k < N_GRID and grid[k] <= solver.t:
                    dense = solver.dense_output()
                    while k < N_GRID and grid[k] <= solver.t:
                        rows.append(dense(grid[k]))
                        k += 1
                if (steps & 15) == 0 and time.perf_counter() > deadline:
                    return Outcome(time.perf_counter() - start, steps=steps, status="budget")
            wall = time.perf_counter() - start
            if solver.status != "finished" or k < N_GRID:
                return Outcome(wall, steps=steps, status="failed")
            ys = np.array(rows)
            _, lam = pr.kkt(ys[-1, :n], ys[-1, n:], pr.t1)
            return Outcome(wall, ys[-1, :n].copy(), lam, steps, pr.max_g(ys[:, :n], grid))
        return run

    return [Contender(f"scipy {name} index-1 ODE", "scipy", make(cls), build_s=0.0)
            for name, cls in (("Radau", Radau), ("BDF", BDF), ("LSODA", LSODA))]


# --------------------------------------------------------------------------- reference
def compute_reference(pr):
    """(q, v, lambda) at t1 at rtol 1e-13 and its distance (positions, multipliers) to rtol 1e-12."""
    from scipy.integrate import solve_ivp
    if pr.name == "pendulum":
        tight, loose = BP.pendulum_reference(1e-13), BP.pendulum_reference(1e-12)
    else:
        y0 = np.concatenate([pr.q0, pr.v0])
        out = []
        for rtol in (1e-13, 1e-12):
            sol = solve_ivp(pr.index1_rhs, (pr.t0, pr.t1), y0, method="DOP853", rtol=rtol, atol=rtol / 100)
            y = sol.y[:, -1]
            out.append((y[:pr.n], y[pr.n:], pr.kkt(y[:pr.n], y[pr.n:], pr.t1)[1]))
        tight, loose = out
    unc = (float(np.max(np.abs(tight[0] - loose[0]) / np.abs(tight[0]))),
           float(np.max(np.abs(tight[2] - loose[2]) / np.abs(tight[2]))))
    return tight, unc


def rel(a, b) -> float:
    return float(np.max(np.abs(np.asarray(a) - np.asarray(b)) / np.abs(np.asarray(b))))


# --------------------------------------------------------------------------- measuring
def measure_problem(name: str, settings: Settings):
    pr = BP.PROBLEMS[name]()
    progress(f"{name}: reference")
    (q_c, v_c, lam_c), unc = compute_reference(pr)
    ref_lines = [f"  reference used: {settings.reference}; computed = scipy DOP853 rtol 1e-13 on "
                 + ("the angle model" if name == "pendulum" else "the numpy index-1 transcription")
                 + f" (vs rtol 1e-12: positions {unc[0]:.1e}, multipliers {unc[1]:.1e})",
                 f"  published ({pr.source}) vs computed: positions {rel(pr.ref_q, q_c):.1e}, "
                 f"velocities {rel(pr.ref_v, v_c):.1e}, multipliers {rel(pr.ref_lam, lam_c):.1e}"]
    if "ref_fortran" in pr.extra:
        rf = pr.extra["ref_fortran"]
        ref_lines.append(f"  caraxis.f carsoln vs computed: positions {rel(rf[:4], q_c):.1e}, velocities "
                         f"{rel(rf[4:8], v_c):.1e}, multipliers {rel(rf[8:], lam_c):.1e}")
    if settings.reference == "computed":
        pr.ref_q, pr.ref_v, pr.ref_lam = q_c, v_c, lam_c
    system = pr.system(f"bari_{name}")
    cache_dir = Path(tempfile.mkdtemp(prefix="bari_cache_"))
    jit_dir = Path(tempfile.mkdtemp(prefix="bari_casadi_jit_"))
    contenders = lagcodegen_contenders(pr, system, settings, cache_dir)
    if importlib.util.find_spec("casadi") is not None:
        contenders += casadi_contenders(pr, settings, jit_dir)
    else:
        ref_lines.append("  CasADi not installed (pip install casadi): skipped")
    contenders += scipy_contenders(pr, settings)
    if settings.contenders:
        contenders = [c for c in contenders if re.search(settings.contenders, c.label)]
    for con in contenders:
        if con.prepare is not None:
            for rtol in con.rtols or settings.rtols:
                try:
                    con.builds.append(con.prepare(rtol))
                except Exception as exc:  # a CasADi build that fails: reported, not fatal
                    progress(f"{name}: {con.label} rtol {rtol:g}: build failed: {exc}")
            con.build_s = statistics.median(con.builds) if con.builds else None
            progress(f"{name}: {con.label}: built {len(con.builds)} integrators, median {con.build_s or 0:.2f} s")

    runs: dict = {}
    dead: set = set()  # (label, rtol) not to run again
    for rnd in range(settings.rounds):
        progress(f"{name}: round {rnd + 1}/{settings.rounds}, load {H.load_average()}")
        for con in contenders:
            stopped = False
            for rtol in con.rtols or settings.rtols:
                key = (con.label, rtol)
                if stopped or key in dead:
                    continue
                outs = []
                while len(outs) < INNER and (not outs or outs[-1].status == "ok" and outs[-1].wall < FAST_RUN):
                    with warnings.catch_warnings():
                        warnings.simplefilter("ignore")
                        try:
                            outs.append(con.run(rtol))
                        except Exception as exc:
                            outs.append(Outcome(float("nan"), status=f"failed: {str(exc).splitlines()[-1][:80]}"))
                out = outs[-1]
                runs.setdefault(key, []).extend(outs)
                if out.status != "ok":
                    dead.add(key)
                    if con.family != "lagcodegen" or out.status == "budget":
                        stopped = True  # tighter tolerances only cost more
                        dead.update((con.label, r) for r in settings.rtols if r is not None and rtol is not None
                                    and r < rtol)
                elif out.wall > SLOW_RUN:
                    dead.add(key)
    rows = []
    for con in contenders:
        for rtol in con.rtols or settings.rtols:
            outs = runs.get((con.label, rtol))
            if not outs:
                continue
            ok = [o for o in outs if o.status == "ok"]
            last = ok[-1] if ok else outs[-1]
            wall = statistics.median(o.wall for o in ok) if ok else float("nan")
            c_walls = [o.c_wall for o in ok if o.c_wall is not None]
            rows.append(dict(problem=name, contender=con.label, family=con.family,
                             rtol=rtol if rtol is not None else 1e-8, err=pr.position_error(last.q_end) if ok else None,
                             lam_err=pr.multiplier_error(last.lam_end) if ok else None,
                             drift=last.drift if ok else None, steps=last.steps, wall_ms=1e3 * wall,
                             c_ms=1e3 * statistics.median(c_walls) if c_walls else None,
                             runs=len(ok), status=last.status, build_s=con.build_s))
    shutil.rmtree(cache_dir, ignore_errors=True)  # the modules stay loaded; their files are not needed
    if any(jit_dir.iterdir()):
        JIT_DIRS.append(jit_dir)  # removed at the end of main(), once CasADi has let go of its libraries
    else:
        jit_dir.rmdir()
    return pr, contenders, rows, ref_lines


# --------------------------------------------------------------------------- summaries
def summarize(pr, contenders, rows):
    """Per contender: times at the targets (with drift, multiplier error), steps and us/step."""
    out = []
    for con in contenders:
        mine = [r for r in rows if r["contender"] == con.label and r["status"] == "ok" and r["err"] is not None]
        pts = [(r["err"], r["wall_ms"] / 1e3) for r in mine]
        s = dict(contender=con.label, family=con.family, build_s=con.build_s)
        for target in TARGETS:
            sec, how = H.time_at(pts, target)
            key = f"{target:.0e}"
            s[f"ms {key}"] = None if sec is None else 1e3 * sec
            s[f"how {key}"] = how
            reach = [r for r in mine if r["err"] <= target]
            best = max(reach, key=lambda r: r["err"]) if reach else None
            s[f"drift {key}"] = best["drift"] if best else None
            s[f"lam {key}"] = best["lam_err"] if best else None
        at = [r for r in mine if math.isclose(r["rtol"], STEP_RTOL)]
        if at:
            s["steps"] = at[0]["steps"]
            s["us/step"] = 1e3 * at[0]["wall_ms"] / at[0]["steps"] if at[0]["steps"] else None
        out.append(s)
    return out


def fmt(x, spec="{:.2f}"):
    return "-" if x is None or (isinstance(x, float) and not math.isfinite(x)) else spec.format(x)


def summary_table(summ) -> str:
    head = ["contender"]
    for target in TARGETS:
        k = f"{target:.0e}"
        head += [f"ms@{k}", "|g|", "lam err"]
    head += ["steps@1e-8", "us/step", "build s"]
    lines = []
    for s in summ:
        row = [s["contender"]]
        for target in TARGETS:
            k = f"{target:.0e}"
            ms = s[f"ms {k}"]
            row += [("<=" if s[f"how {k}"] == "bound" else "") + fmt(ms), fmt(s[f"drift {k}"], "{:.0e}"),
                    fmt(s[f"lam {k}"], "{:.0e}")]
        row += [fmt(s.get("steps"), "{:d}"), fmt(s.get("us/step"), "{:.1f}"), fmt(s["build_s"])]
        lines.append(row)
    widths = [max(len(h), *(len(r[i]) for r in lines)) for i, h in enumerate(head)]

    def line(vals):
        return "  ".join(v.ljust(w) if i == 0 else v.rjust(w) for i, (v, w) in enumerate(zip(vals, widths)))
    return "\n".join([line(head), "  ".join("-" * w for w in widths)] + [line(r) for r in lines])


def detail_table(rows) -> str:
    cols = [("contender", "contender", "{}"), ("rtol", "rtol", "{:.0e}"), ("err", "pos err", "{:.2e}"),
            ("lam_err", "lam err", "{:.1e}"), ("drift", "max|g|", "{:.1e}"), ("steps", "steps", "{}"),
            ("wall_ms", "ms", "{:.3f}"), ("c_ms", "C ms", "{:.3f}"), ("runs", "runs", "{}"), ("status", "status", "{}")]
    return H.format_table(cols, rows)


def ratios(summ) -> list[str]:
    lines = []

    def best(fam, k, exclude=()):
        cands = [(s[f"ms {k}"], s["contender"]) for s in summ
                 if s["family"] == fam and s[f"ms {k}"] is not None and s["contender"] not in exclude]
        return min(cands) if cands else (None, None)
    for target in TARGETS:
        k = f"{target:.0e}"
        cas, cas_name = best("casadi", k)
        lb, lb_name = best("lagcodegen", k, exclude=("lcg default call as is",))
        d = next((s[f"ms {k}"] for s in summ if s["contender"] == DEFAULT_LABEL), None)
        if cas is None:
            lines.append(f"  error {k}: no CasADi time")
            continue
        parts = [f"CasADi best {cas:.2f} ms ({cas_name})"]
        if lb is not None:
            parts.append(f"lagcodegen best {lb:.2f} ms ({lb_name}): {lb / cas:.2f}x")
        if d is not None:
            parts.append(f"default call {d:.2f} ms: {d / cas:.2f}x")
        lines.append(f"  error {k}: " + "; ".join(parts))
    return lines


def main(argv=None) -> int:
    args = parse_args(argv)
    settings = settings_from(args)
    load0 = H.load_average()
    wall0 = time.perf_counter()
    sections, all_rows, plots = [], [], {}
    for name in settings.problems:
        pr, contenders, rows, ref_lines = measure_problem(name, settings)
        summ = summarize(pr, contenders, rows)
        as_is = next((r for r in rows if r["contender"] == "lcg default call as is"), None)
        text = [f"== {pr.title}", *ref_lines, "",
                "time [ms] to reach the position error (interpolated; '<=' every run was more accurate), beside it "
                "max|g| and the multipliers' relative error of the cheapest run reaching it:", summary_table(summ), "",
                "ratios to CasADi's best (targets of issue 16: default <= 0.5x, best <= 0.3x):", *ratios(summ)]
        if as_is:
            text.append(f"  the untuned call sim.simulate((t0, t1), q0=..., v0=...): {as_is['wall_ms']:.2f} ms, position "
                        f"error {fmt(as_is['err'], '{:.1e}')}, multipliers {fmt(as_is['lam_err'], '{:.1e}')}, "
                        f"max|g| {fmt(as_is['drift'], '{:.1e}')}, {as_is['steps']} steps")
        text += ["", "every run:", detail_table(rows)]
        sections.append("\n".join(text))
        all_rows += rows
        curves = {}
        for con in contenders:
            pts = [(r["err"], r["wall_ms"] / 1e3) for r in rows
                   if r["contender"] == con.label and r["status"] == "ok" and r["err"] and con.rtols is None]
            if pts:
                curves[con.label] = pts
        plots[name] = (pr.title, curves)
        del contenders  # CasADi's integrators: unloaded (and their libraries removed) here
        print(sections[-1] + "\n", flush=True)
    gc.collect()
    for folder in JIT_DIRS:
        shutil.rmtree(folder, ignore_errors=True)
    load1 = H.load_average()
    head = H.machine_lines("Bari test set: constrained mechanics, lagcodegen vs CasADi vs scipy", (load0, load1))
    try:
        import casadi
        head.append(f"casadi:   {casadi.__version__}")
    except ImportError:
        head.append("casadi:   absent")
    head.append(f"rtols {', '.join(f'{r:.0e}' for r in settings.rtols)} (atol = rtol); {settings.rounds} rounds; "
                f"{N_GRID} output times; total {time.perf_counter() - wall0:.0f} s")
    report = "\n".join(head) + "\n\n" + "\n\n".join(sections)
    print("\n".join(head))
    if args.out:
        H.write_report(args.out, "bari", report, all_rows)
        for name, (title, curves) in plots.items():
            H.work_precision_plot(args.out / f"bari_{name}.png", title, curves,
                                  "max relative error of the positions at t1")
        print(f"wrote {args.out / 'bari.txt'}, {args.out / 'bari.csv'}, "
              + ", ".join(str(args.out / f'bari_{n}.png') for n in plots))
    return 0


if __name__ == "__main__":
    sys.exit(main())
