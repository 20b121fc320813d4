"""Stress tests: long horizons, near-singular configurations, stiff ratios, chaos, large n.

Every outcome is a number in a table; every failure is reported as a limit with its
threshold (the LIMITS section at the end).

A. Long horizons (native CVODE, Adams, rtol 1e-10, atol 1e-12, 20001 output times): the drift
   max_t |I(t) - I(0)| / max(1, |I(0)|) of every invariant the model has -- energy T + V,
   Jacobi h, the integral p_phi = C of the spherical pendulum, the constraint residuals f(q)
   and A q' of the Cartesian pendulum -- over 1e4..1e6 periods (--quick: 1e2..1e3), and the
   time at which each drift first exceeds 1e-6.
B. Near-singular configurations:
   B1 spherical pendulum through the pole region: theta0 = 0.5, theta0' = 0, phi0' such that
      C = sin^2(theta0) phi0' = 1e-1 ... 1e-8, t in [0, 10]: full coordinates (M = diag(1,
      sin^2 theta) nearly singular near theta = 0) vs the Routhian-reduced model, both native
      Adams rtol 1e-10; smallest theta reached, steps, drift of energy (full) / h (reduced).
   B2 the full model started at theta0 = 1e-2 ... 1e-10 (M singular numerically when
      sin^2(theta0) < 2 eps): the start is refused below the threshold.
   (theta = 0, the bottom, is the pole of the spherical coordinates.)
   B3 double pendulum folded (theta2 = theta1 + pi) with m1 -> 0: det M ~ m1 + m2 sin^2(theta1 - theta2)
      vanishes at the fold; m1 = 1 ... 1e-10, t in [0, 10], native Adams rtol 1e-10.
C. Stiff parameter ratios: the 20-mass chain (benchmarks/_harness.spring_chain) with stiff/soft
   ratio 1e2 ... 1e8, critically damped (zeta = 1) and undamped (zeta = 0) dimers, t in [0, 10],
   rtol 1e-8: steps, RHS and Jacobian evaluations, wall time of native Adams and BDF (dense),
   and BDF with the band solver.
D. Chaotic sensitivity: double pendulum theta1 = theta2 = 2 rad at rest, t in [0, 40]
   (--quick: 20), native Adams at rtol 1e-4 ... 1e-13: the time until the trajectory at rtol and
   at rtol/10 (and at the tightest rtol) differ by 1e-2 rad in an angle; a Lyapunov exponent
   estimate from the slope of that time against ln(1/rtol).
E. Large n: planar n-link pendulum, n = 20, 30, 50 (--quick: 20): derive, generate (outputs
   energy; without Jacobian, and with it for n <= 30), compile, integrate 10 s from 0.5 rad
   (Adams, rtol 1e-8, difference-quotient Jacobian), energy drift.

Wall times are single runs (these are outcomes, not micro-benchmarks). With --out DIR:
stress.txt, stress.csv and stress_chaos.png (divergence time vs rtol).

Usage::

    python benchmarks/stress.py [--quick] [--out DIR] [--sections ABCDE]
"""

from __future__ import annotations

import argparse
import contextlib
import math
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _harness as H  # noqa: E402

from lagcodegen import Scene, build_code, compile_reduction, derive, generate_c, systems  # noqa: E402
from lagcodegen.errors import LagcodegenError, SingularMassMatrixError  # noqa: E402

TAG = "stress"
DRIFT_LIMIT = 1e-6
TOL = dict(rtol=1e-10, atol=1e-12)


def progress(message: str) -> None:
    H.progress(TAG, message)


def parse_args(argv=None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="short horizons, fewer cases (< 2 min)")
    ap.add_argument("--out", metavar="DIR", type=Path, help="write stress.txt, stress.csv, stress_chaos.png")
    ap.add_argument("--sections", default="ABCDE", help="subset of ABCDE (default: all)")
    return ap.parse_args(argv)


@contextlib.contextmanager
def c_stdout_to_stderr():
    """Send what C code prints to stdout (SUNDIALS' "t + h = t" warnings near a singularity)
    to stderr for the duration of the block, so that stdout holds the tables only."""
    sys.stdout.flush()
    saved = os.dup(1)
    try:
        os.dup2(2, 1)
        yield
    finally:
        os.dup2(saved, 1)
        os.close(saved)


def compiled(model, prefix, outputs=(), jacobian=True, **scene):
    return build_code(generate_c(Scene(derive(model), prefix=prefix, outputs=list(outputs), jacobian=jacobian, **scene)))


def drift_series(x: np.ndarray) -> np.ndarray:
    return np.abs(x - x[0]) / max(1.0, abs(x[0]))


def first_exceed(t: np.ndarray, d: np.ndarray, limit: float) -> float | None:
    idx = np.nonzero(d > limit)[0]
    return float(t[idx[0]]) if idx.size else None


# --------------------------------------------------------------------------- A. long horizons
def pendulum_period(theta0: float, g: float = 9.81, l: float = 1.0) -> float:
    from scipy.special import ellipk
    return 4.0 * math.sqrt(l / g) * float(ellipk(math.sin(theta0 / 2) ** 2))


def long_cases(quick: bool):
    """(label, runner, period estimate, periods); runner(t) -> (Result, {invariant: series})."""
    cases = []

    def ode(model, prefix, q0, v0, outputs, invariants):
        cm = compiled(model, prefix, outputs)

        def run(t):
            res = cm.simulate(t, q0=q0, v0=v0, max_steps=2_000_000_000, **TOL)
            return res, {name: res[key] for name, key in invariants}
        return run

    scale = 0.01 if quick else 1.0
    cases.append(("pendulum theta0 = 1", ode(systems.pendulum("st_pend"), "st_pend", [1.0], [0.0], ["energy"],
                                               [("energy", "energy")]), pendulum_period(1.0), 1e6 * scale))
    cases.append(("double pendulum 0.1 rad", ode(systems.double_pendulum("st_dbl"), "st_dbl", [0.1, 0.1], [0, 0],
                                                 ["energy"], [("energy", "energy")]),
                  2 * math.pi / math.sqrt(9.81 * (2 - math.sqrt(2))), 1e5 * scale))
    cases.append(("spherical theta0 = 0.8, phi' = 2",
                  ode(systems.spherical_pendulum("st_sph"), "st_sph", [0.8, 0.0], [0.3, 2.0],
                      ["energy", "p_phi", "jacobi_h"], [("energy", "energy"), ("C = p_phi", "p_phi"),
                                                        ("jacobi h", "jacobi_h")]), 50.0 / 35.0, 1e5 * scale))

    from lagcodegen.theory.routhian import reduce
    red = reduce(systems.spherical_pendulum("st_sph"))
    cmr = compile_reduction(red, outputs=("jacobi_h",), prefix="st_sph_routh")

    def run_red(t):
        res = red.simulate(cmr, t, q0=[0.8, 0.0], v0=[0.3, 2.0], max_steps=2_000_000_000, **TOL)
        return res, {"h_R (= energy)": res["jacobi_h"]}
    cases.append(("spherical, Routh-reduced", run_red, 50.0 / 35.0, 1e5 * scale))
    w = 5.0
    cases.append(("hoop w = 5, theta0 = 1", ode(systems.bead_on_spinning_hoop("st_hoop"), "st_hoop", [1.0], [0.0],
                                                 ["jacobi_h"], [("jacobi h", "jacobi_h")]),
                  2 * math.pi / (w * math.sqrt(1 - (9.81 / w**2) ** 2)), 1e5 * scale))

    from lagcodegen.api import compile_constrained
    system = H.cartesian_pendulum()
    q0, v0 = [math.sin(1.0), -math.cos(1.0)], [0.0, 0.0]
    for label, form, opts in (("index-1", "index1", {}), ("index-1 + Baumgarte(10,10)", "index1",
                                                             {"baumgarte": (10.0, 10.0)}),
                              ("GGL native IDA", "ggl", {}), ("minimal coordinates", "minimal", {})):
        sim = compile_constrained(system, form, prefix=f"st_c_{form}")

        def run_c(t, sim=sim, opts=opts):
            res = sim.simulate(t, q0=q0, v0=v0, max_steps=2_000_000_000, **TOL, **opts)
            return res, {"energy": res["energy"], "|f(q)|": res["g_0"], "|A q'|": res["gdot_0"]}
        cases.append((f"Cartesian pendulum, {label}", run_c, pendulum_period(1.0), 1e4 * scale))
    return cases


def section_a(quick: bool, limits: list) -> list[dict]:
    rows = []
    for label, run, period, periods in long_cases(quick):
        T = period * periods
        t = np.linspace(0.0, T, 20001)
        progress(f"A: {label}, {periods:.0e} periods (T = {T:.3g})")
        start = time.perf_counter()
        try:
            res, inv = run(t)
        except LagcodegenError as exc:
            limits.append(f"A {label}: failed over {periods:.0e} periods: {exc}")
            rows.append(dict(section="A", case=label, periods=periods, T=T, status="failed"))
            continue
        wall = time.perf_counter() - start
        for name, series in inv.items():
            if name.startswith("|"):
                d = np.abs(series)  # residuals: absolute values, zero at the start
            else:
                d = drift_series(series)
            t_exc = first_exceed(res.t, d, DRIFT_LIMIT)
            rows.append(dict(section="A", case=label, periods=periods, T=T, wall_s=wall, steps=res.stats.get("steps"),
                             invariant=name, drift=float(np.max(d)), drift_per_1e4_periods=float(np.max(d)) / periods * 1e4,
                             periods_to_1e6=None if t_exc is None else t_exc / period, status="ok"))
            if t_exc is not None:
                limits.append(f"A {label}: {name} drifts past {DRIFT_LIMIT:g} after {t_exc / period:.3g} periods "
                              f"(rtol {TOL['rtol']:g}; max {np.max(d):.2e} over {periods:.0e} periods)")
    return rows


# --------------------------------------------------------------------------- B. near-singular
def turning_theta(theta0: float, C: float, g: float = 9.81) -> float:
    """Smallest theta of the spherical pendulum (m = l = 1) released at theta0 with theta' = 0 and
    momentum C: the root of C^2 / (2 sin^2 theta) - g cos theta = E below theta0."""
    from scipy.optimize import brentq
    E = C**2 / (2 * math.sin(theta0) ** 2) - g * math.cos(theta0)

    def f(th):
        return C**2 / (2 * math.sin(th) ** 2) - g * math.cos(th) - E
    if C == 0:
        return 0.0
    lo = min(C, 1e-3) * 1e-3  # f(lo) > 0: the centrifugal barrier dominates there
    return float(brentq(f, lo, theta0 * (1 - 1e-9), xtol=1e-300, rtol=1e-14))


def section_b(quick: bool, limits: list) -> list[dict]:
    from lagcodegen.theory.routhian import reduce
    rows = []
    full = compiled(systems.spherical_pendulum("st_sphn"), "st_sphn", ["energy", "p_phi"])
    red = reduce(systems.spherical_pendulum("st_sphn"))
    cmr = compile_reduction(red, outputs=("jacobi_h",), prefix="st_sphn_routh")
    theta0 = 0.5
    t = np.linspace(0.0, 10.0, 2001)
    Cs = [1e-1, 1e-3, 1e-6] if quick else [1e-1, 1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8]
    fails = {"full": [], "reduced": []}
    for C in Cs:
        phidot = C / math.sin(theta0) ** 2
        for label in ("full", "reduced"):
            progress(f"B1: C = {C:.0e}, {label}")
            start = time.perf_counter()
            if label == "full":
                res = full.simulate(t, q0=[theta0, 0.0], v0=[0.0, phidot], max_steps=5_000_000,
                                    raise_on_error=False, **TOL)
            else:
                res = red.simulate(cmr, t, q0=[theta0, 0.0], v0=[0.0, phidot], max_steps=5_000_000,
                                   raise_on_error=False, **TOL)
            wall = time.perf_counter() - start
            row = dict(section="B1", case=f"spherical near pole, {label}", C=C, wall_s=wall,
                       steps=res.stats.get("steps"), t_reached=float(res.t[-1]) if res.t.size else 0.0,
                       min_theta=turning_theta(theta0, C),
                       status="ok" if res.success else f"failed ({res.message[:50]})")
            if res.t.size > 1:
                key = "energy" if label == "full" else "jacobi_h"
                row["energy_drift"] = float(np.max(drift_series(res[key])))
                if label == "full":
                    row["C_drift"] = float(np.max(np.abs(res["p_phi"] - C)) / C)
            rows.append(row)
            bad = not res.success or (row.get("energy_drift") or 0) > DRIFT_LIMIT or (row.get("C_drift") or 0) > 1e-4
            if bad:
                fails[label].append(C)
    for label, cs in fails.items():
        if cs:
            ok = [C for C in Cs if C not in cs and C > max(cs)]
            limits.append(f"B1 spherical pendulum near the pole, {label} coordinates (theta_min ~ 0.65 C): fails or "
                          f"drifts (energy > {DRIFT_LIMIT:g} or C > 1e-4 relative) at C = "
                          f"{', '.join(f'{c:.0e}' for c in cs)}"
                          + (f"; fine down to C = {min(ok):.0e}" if ok else "")
                          + "; see the table for the steps it costs")
    # B2: starting near theta = 0
    thetas = [1e-2, 1e-6, 1e-8, 1e-9] if quick else [1e-2, 1e-4, 1e-6, 1e-7, 1e-8, 2e-8, 1e-9, 1e-10]
    refused, failed = [], []
    for th in thetas:
        progress(f"B2: start at theta0 = {th:.0e}")
        row = dict(section="B2", case="spherical, start near the pole (full)", theta0=th)
        try:
            start = time.perf_counter()
            res = full.simulate(np.linspace(0, 1, 101), q0=[th, 0.0], v0=[0.0, 1e-3],
                                max_steps=5_000_000, raise_on_error=False, **TOL)
            row.update(wall_s=time.perf_counter() - start, steps=res.stats.get("steps"),
                       status="ok" if res.success else f"failed ({res.message[:50]})")
            if not res.success:
                failed.append(th)
        except SingularMassMatrixError:
            row["status"] = "refused: singular M at the initial state"
            refused.append(th)
        rows.append(row)
    if refused:
        limits.append(f"B2 spherical pendulum in full coordinates: a start at theta0 <= {max(refused):.0e} is refused "
                      f"(M = diag(1, sin^2 theta) is singular to the factorization's tolerance 2 eps max|M_ii|: "
                      f"sin^2(theta) < 4.4e-16, theta < 2.1e-8)")
    if failed:
        limits.append(f"B2 spherical pendulum in full coordinates: started at theta0 <= {max(failed):.0e} with "
                      f"theta0' = 0 and phi0' = 1e-3, the bob passes within 2.1e-8 of the pole and the run stops "
                      f"with 'the mass matrix is singular'")
    # B3: folded double pendulum
    dbl = compiled(systems.double_pendulum("st_fold"), "st_fold", ["energy"])
    m1s = [1.0, 1e-4, 1e-8] if quick else [1.0, 1e-2, 1e-4, 1e-6, 1e-8, 1e-10, 1e-12]
    bad = []
    for m1 in m1s:
        progress(f"B3: folded double pendulum, m1 = {m1:.0e}")
        start = time.perf_counter()
        res = dbl.simulate(np.linspace(0.0, 10.0, 2001), q0=[0.5, 0.5 + math.pi], v0=[0.0, 0.0], params={"m1": m1},
                           max_steps=5_000_000, raise_on_error=False, **TOL)
        drift = float(np.max(drift_series(res["energy"]))) if res.t.size > 1 else None
        rows.append(dict(section="B3", case="double pendulum folded, m2 = 1", m1=m1, wall_s=time.perf_counter() - start,
                         steps=res.stats.get("steps"), t_reached=float(res.t[-1]), energy_drift=drift,
                         status="ok" if res.success else f"failed ({res.message[:50]})"))
        if not res.success or (drift or 0) > DRIFT_LIMIT:
            bad.append(m1)
    if bad:
        limits.append(f"B3 folded double pendulum: fails or drifts (energy > {DRIFT_LIMIT:g}) for m1/m2 <= {max(bad):.0e}")
    return rows


# --------------------------------------------------------------------------- C. stiff ratios
def section_c(quick: bool, limits: list) -> list[dict]:
    rows = []
    n = 20
    ratios = [1e2, 1e6] if quick else [1e2, 1e4, 1e6, 1e8]
    q0, v0 = H.chain_initial(n)
    t = np.linspace(0.0, 10.0, 201)
    for zeta in (1.0, 0.0):
        cm = compiled(H.spring_chain(n, 1e6, zeta, name=f"st_chain{int(zeta)}"), f"st_chain{int(zeta)}",
                      sparse_jacobian=True)
        for ratio in ratios:
            c = zeta * 2.0 * math.sqrt(ratio * 0.5)
            for method, ls in (("adams", "dense"), ("bdf", "dense"), ("bdf", "band")):
                progress(f"C: ratio {ratio:.0e}, zeta {zeta:g}, {method} {ls}")
                start = time.perf_counter()
                res = cm.simulate(t, q0=q0, v0=v0, params={"ratio": ratio, "c": c}, method=method, linear_solver=ls,
                                  rtol=1e-8, atol=1e-10, max_steps=5_000_000, raise_on_error=False)
                s = res.stats
                rows.append(dict(section="C", case=f"chain n={n}, zeta={zeta:g}", ratio=ratio, method=method,
                                 linear_solver=ls, wall_s=time.perf_counter() - start, steps=s.get("steps"),
                                 rhs_evals=s.get("rhs_evals"), jac_evals=s.get("jac_evals"),
                                 status="ok" if res.success else f"failed ({res.message[:40]})"))
                if not res.success:
                    limits.append(f"C chain zeta={zeta:g}, {method} {ls}: fails at stiffness ratio {ratio:.0e} "
                                  f"({res.message[:60]})")
    # steps Adams / BDF
    for zeta in (1.0, 0.0):
        for ratio in ratios:
            a = [r for r in rows if r["case"].endswith(f"zeta={zeta:g}") and r["ratio"] == ratio]
            ad = next(r for r in a if r["method"] == "adams")
            bd = next(r for r in a if r["method"] == "bdf" and r["linear_solver"] == "dense")
            if ad.get("steps") and bd.get("steps"):
                ad["adams_over_bdf_steps"] = ad["steps"] / bd["steps"]
    return rows


# --------------------------------------------------------------------------- D. chaos
def section_d(quick: bool, limits: list) -> tuple[list[dict], dict]:
    cm = compiled(systems.double_pendulum("st_chaos"), "st_chaos")
    T = 20.0 if quick else 40.0
    t = np.arange(0.0, T + 1e-9, 0.01)
    rtols = [10.0 ** -k for k in (range(4, 11) if quick else range(4, 14))]
    traj = {}
    for rtol in rtols:
        progress(f"D: rtol {rtol:.0e}")
        res = cm.simulate(t, q0=[2.0, 2.0], v0=[0.0, 0.0], rtol=rtol, atol=rtol * 1e-2, max_steps=50_000_000)
        traj[rtol] = res.y[:, :2]
    tight = rtols[-1]

    def t_div(a, b):
        d = np.max(np.abs(traj[a] - traj[b]), axis=1)
        idx = np.nonzero(d > 1e-2)[0]
        return float(t[idx[0]]) if idx.size else None

    rows = []
    for k, rtol in enumerate(rtols):
        rows.append(dict(section="D", case="double pendulum 2 rad, chaotic", rtol=rtol,
                         t_div_next=t_div(rtol, rtols[k + 1]) if k + 1 < len(rtols) else None,
                         t_div_tightest=t_div(rtol, tight) if rtol != tight else None))
    pts = [(math.log(1 / r["rtol"]), r["t_div_next"]) for r in rows if r["t_div_next"] is not None]
    lyap = None
    if len(pts) >= 3:
        slope = np.polyfit([p[0] for p in pts], [p[1] for p in pts], 1)[0]
        lyap = 1.0 / slope if slope > 0 else None
    last = rows[-2]["t_div_next"] if len(rows) >= 2 else None
    if last is not None:
        limits.append(f"D chaotic double pendulum: beyond t = {last:.3g} s even rtol {rtols[-2]:.0e} and "
                      f"{rtols[-1]:.0e} disagree by 1e-2 rad (Lyapunov exponent ~ "
                      f"{lyap:.2f} /s from the divergence times)" if lyap else
                      f"D chaotic double pendulum: beyond t = {last:.3g} s rtol {rtols[-2]:.0e} and {rtols[-1]:.0e} "
                      f"disagree by 1e-2 rad")
    return rows, dict(lyapunov=lyap, T=T)


# --------------------------------------------------------------------------- E. large n
def section_e(quick: bool, limits: list) -> list[dict]:
    rows = []
    cases = [(20, False)] if quick else [(20, False), (20, True), (30, False), (30, True), (50, False)]
    with tempfile.TemporaryDirectory(prefix="lcg-stress-") as tmp:
        for n, jac in cases:
            progress(f"E: n = {n}, jacobian = {jac}")
            row = dict(section="E", case=f"{n}-link pendulum", n=n, jacobian=jac)
            start = time.perf_counter()
            eom = derive(systems.n_link_pendulum(n, name=f"st_link{n}"))
            row["derive_s"] = time.perf_counter() - start
            start = time.perf_counter()
            code = generate_c(Scene(eom, jacobian=jac, outputs=["energy"], prefix=f"st_link{n}_{int(jac)}"))
            row["gen_s"] = time.perf_counter() - start
            row["c_kib"] = len(code.files[code.source_name]) / 1024
            start = time.perf_counter()
            with H.cache_at(Path(tmp) / f"{n}_{int(jac)}"):
                try:
                    cm = build_code(code)
                except LagcodegenError as exc:
                    row["status"] = f"compile failed: {str(exc)[:50]}"
                    limits.append(f"E n = {n}: compilation failed: {exc}")
                    rows.append(row)
                    continue
            row["compile_s"] = time.perf_counter() - start
            start = time.perf_counter()
            res = cm.simulate(np.linspace(0, 10, 1001), q0=[0.5] * n, rtol=1e-8, atol=1e-10, jacobian=False,
                              max_steps=10_000_000, raise_on_error=False)
            row.update(sim_s=time.perf_counter() - start, steps=res.stats.get("steps"),
                       energy_drift=float(np.max(drift_series(res["energy"]))) if res.t.size > 1 else None,
                       status="ok" if res.success else f"failed ({res.message[:40]})")
            if not res.success:
                limits.append(f"E n = {n}: integration failed: {res.message}")
            rows.append(row)
    return rows


# --------------------------------------------------------------------------- report
COLUMNS = {
    "A": [("case", "case", "{}"), ("periods", "periods", "{:.0e}"), ("T", "T [s]", "{:.4g}"),
          ("wall_s", "wall [s]", "{:.2f}"), ("steps", "steps", "{}"), ("invariant", "invariant", "{}"),
          ("drift", "max drift", "{:.2e}"), ("drift_per_1e4_periods", "per 1e4 periods", "{:.2e}"),
          ("periods_to_1e6", "periods to 1e-6", "{:.3g}"), ("status", "status", "{}")],
    "B1": [("case", "case", "{}"), ("C", "C", "{:.0e}"), ("wall_s", "wall [s]", "{:.3f}"), ("steps", "steps", "{}"),
           ("min_theta", "min theta (exact)", "{:.2e}"), ("energy_drift", "energy/h drift", "{:.2e}"),
           ("C_drift", "C drift (rel)", "{:.2e}"), ("t_reached", "t reached", "{:.3g}"), ("status", "status", "{}")],
    "B2": [("case", "case", "{}"), ("theta0", "theta0", "{:.0e}"), ("wall_s", "wall [s]", "{:.3f}"),
           ("steps", "steps", "{}"), ("status", "status", "{}")],
    "B3": [("case", "case", "{}"), ("m1", "m1", "{:.0e}"), ("wall_s", "wall [s]", "{:.3f}"), ("steps", "steps", "{}"),
           ("energy_drift", "energy drift", "{:.2e}"), ("t_reached", "t reached", "{:.3g}"), ("status", "status", "{}")],
    "C": [("case", "case", "{}"), ("ratio", "ratio", "{:.0e}"), ("method", "method", "{}"),
          ("linear_solver", "linear solver", "{}"), ("wall_s", "wall [s]", "{:.4f}"), ("steps", "steps", "{}"),
          ("rhs_evals", "RHS evals", "{}"), ("jac_evals", "Jac evals", "{}"),
          ("adams_over_bdf_steps", "Adams/BDF steps", "{:.1f}"), ("status", "status", "{}")],
    "D": [("rtol", "rtol", "{:.0e}"), ("t_div_next", "t(|d theta| > 1e-2) vs rtol/10 [s]", "{:.2f}"),
          ("t_div_tightest", "vs tightest rtol [s]", "{:.2f}")],
    "E": [("case", "case", "{}"), ("jacobian", "jacobian", "{}"), ("derive_s", "derive [s]", "{:.2f}"),
          ("gen_s", "gen [s]", "{:.2f}"), ("c_kib", "C [KiB]", "{:.0f}"), ("compile_s", "compile [s]", "{:.1f}"),
          ("sim_s", "integrate 10 s [s]", "{:.3f}"), ("steps", "steps", "{}"), ("energy_drift", "energy drift", "{:.1e}"),
          ("status", "status", "{}")],
}

TITLES = {
    "A": f"A. Long horizons: invariant drift (native CVODE Adams, rtol {TOL['rtol']:g}, atol {TOL['atol']:g})",
    "B1": "B1. Spherical pendulum through the pole region (theta0 = 0.5, theta0' = 0, C = sin^2(theta0) phi0')",
    "B2": "B2. Spherical pendulum started near the pole theta = 0, full coordinates (theta0' = 0, phi0' = 1e-3, t in [0, 1])",
    "B3": "B3. Double pendulum folded (theta2 = theta1 + pi), m1 -> 0",
    "C": "C. Stiff chain (20 masses), stiffness ratio sweep, rtol 1e-8",
    "D": "D. Chaotic sensitivity: double pendulum theta1 = theta2 = 2 rad",
    "E": "E. Large n: n-link pendulum",
}


def report(rows, limits, chaos, load) -> str:
    lines = H.machine_lines("lagcodegen stress benchmark", load) + [""]
    for key, title in TITLES.items():
        sel = [r for r in rows if r["section"] == key]
        if not sel:
            continue
        lines += [title, "", H.format_table(COLUMNS[key], sel), ""]
        if key == "D" and chaos.get("lyapunov"):
            lines += [f"Lyapunov exponent estimate (1 / slope of t_div against ln(1/rtol)): {chaos['lyapunov']:.2f} /s",
                      ""]
    lines += ["LIMITS", ""] + ([f"* {x}" for x in limits] or ["(none found)"])
    return "\n".join(lines) + "\n"


def chaos_plot(path: Path, rows) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    d = [r for r in rows if r["section"] == "D"]
    fig, ax = plt.subplots(figsize=(6, 4))
    for key, label in (("t_div_next", "vs rtol/10"), ("t_div_tightest", "vs tightest rtol")):
        pts = [(r["rtol"], r[key]) for r in d if r.get(key) is not None]
        if pts:
            ax.semilogx([p[0] for p in pts], [p[1] for p in pts], "o-", label=label)
    ax.set_xlabel("rtol")
    ax.set_ylabel("time until |d theta| > 1e-2 [s]")
    ax.set_title("chaotic double pendulum: divergence time vs tolerance", fontsize=10)
    ax.grid(alpha=0.3, which="both")
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None) -> int:
    args = parse_args(argv)
    start, load_start = time.perf_counter(), H.load_average()
    rows, limits, chaos = [], [], {}
    sections = args.sections.upper()
    with c_stdout_to_stderr():
        if "A" in sections:
            rows += section_a(args.quick, limits)
        if "B" in sections:
            rows += section_b(args.quick, limits)
        if "C" in sections:
            rows += section_c(args.quick, limits)
        if "D" in sections:
            d_rows, chaos = section_d(args.quick, limits)
            rows += d_rows
        if "E" in sections:
            rows += section_e(args.quick, limits)
    text = report(rows, limits, chaos, (load_start, H.load_average()))
    print(text, end="")
    if args.out is not None:
        H.write_report(args.out, "stress", text, rows)
        if any(r["section"] == "D" for r in rows):
            chaos_plot(args.out / "stress_chaos.png", rows)
        progress(f"wrote {args.out}/stress.txt, stress.csv, stress_chaos.png")
    progress(f"done in {time.perf_counter() - start:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
