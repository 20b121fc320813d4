"""Work-precision of the spherical pendulum: full model vs Routhian-reduced model.

Full:    y = (theta, phi, theta', phi')   4 states, lagcodegen.systems.spherical_pendulum()
Reduced: y = (theta, theta', phi)         3 states, Routh's reduction over phi (eqs. 3.9-3.11):
         theta'' from L_R = -R, phi' = dR/dC as a quadrature state.

Both are generated and compiled by lagcodegen and integrated by the native CVODE driver
(Adams, analytic Jacobian) from theta = 0.8, phi = 0, theta' = 0.3, phi' = 2.0 over
t in [0, T] (T = 50: about 35 oscillations of theta), for rtol = 1e-6 ... 1e-12 with
atol = rtol/100, each with no outputs but the states.

Reference: ``scipy.integrate.solve_ivp`` (DOP853, rtol 1e-13, atol 1e-14) on a hand-written
numpy right-hand side of the full equations

    theta'' = sin(theta) cos(theta) phi'^2 - (g/l) sin(theta)
    phi''   = -2 cos(theta) theta' phi' / sin(theta)

(not the generated code). Its own uncertainty is estimated by a second run at rtol 1e-12.

Reported per run: wall time (median of 5, 3 with --quick) of ``simulate``, steps and RHS
evaluations, the error in (theta, phi) at T and the max over the 2001-point output grid.
RHS/Jac cost per call is measured in C by the harness of benchmarks/_harness.py (no Python,
cc -O2). The time ratio full/reduced at matched error interpolates log(time) against
log(max error) of each model.

This is a measuring instrument: it asserts nothing about the times it reports.

Usage::

    python benchmarks/routhian.py [--quick] [--out DIR]
"""

from __future__ import annotations

import argparse
import datetime
import math
import os
import platform
import statistics
import sys
import tempfile
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
from scipy.integrate import solve_ivp

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _harness  # noqa: E402  (the C timing harness)

import lagcodegen as lcg  # noqa: E402
from lagcodegen import Scene, build_code, generate_c  # noqa: E402
from lagcodegen.theory.routhian import reduce  # noqa: E402
from lagcodegen.model.systems import spherical_pendulum  # noqa: E402

Q0 = (0.8, 0.0)
V0 = (0.3, 2.0)
T_END = 50.0
N_GRID = 2001
G, L = 9.81, 1.0


def progress(message: str) -> None:
    print(f"[routhian] {message}", file=sys.stderr, flush=True)


def parse_args(argv=None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="rtol 1e-6, 1e-8, 1e-10 only, 3 repeats")
    ap.add_argument("--out", metavar="DIR", type=Path,
                    help="write DIR/routhian.txt (the table) and DIR/routhian.png (work-precision plot)")
    return ap.parse_args(argv)


# --------------------------------------------------------------------------- reference
def reference(t: np.ndarray, rtol: float, atol: float) -> np.ndarray:
    """(theta, phi) on the grid from DOP853 on the hand-written full equations."""
    def rhs(_t, y):
        th, ph, thd, phd = y
        s, c = math.sin(th), math.cos(th)
        return [thd, phd, s * c * phd**2 - G / L * s, -2.0 * c * thd * phd / s]
    sol = solve_ivp(rhs, (t[0], t[-1]), [*Q0, *V0], method="DOP853", t_eval=t, rtol=rtol, atol=atol)
    if not sol.success:
        raise RuntimeError(f"reference integration failed: {sol.message}")
    return sol.y[:2].T


# --------------------------------------------------------------------------- models
def compile_models(C: float):
    """Full and reduced CompiledModel (no outputs) and the reduction."""
    model = spherical_pendulum()
    full = build_code(generate_c(Scene(lcg.derive(model), prefix="sph_full")))
    red = reduce(model)
    reduced = build_code(generate_c(Scene(red.eom, prefix="sph_routh", values={"C_phi": C})))
    return full, reduced, red


def run(label: str, cm, simulate, t: np.ndarray, ref: np.ndarray, rtol: float, repeats: int) -> dict:
    times, res = [], None
    for _ in range(repeats):
        start = time.perf_counter()
        res = simulate(t, rtol)
        times.append(time.perf_counter() - start)
    err = np.abs(np.column_stack([res["theta"], res["phi"]]) - ref)
    return dict(model=label, states=cm.ny, rtol=rtol, wall=statistics.median(times), steps=res.stats["steps"],
                rhs=res.stats["rhs_evals"], err_final=float(np.max(err[-1])), err_max=float(np.max(err)))


def matched_ratios(rows: list[dict], targets) -> list[tuple[float, float, float, float]]:
    """(error, full time, reduced time, ratio) at the target max errors both curves reach."""
    def curve(label):
        pts = sorted((r["err_max"], r["wall"]) for r in rows if r["model"] == label)
        return np.log10([p[0] for p in pts]), np.log10([p[1] for p in pts])
    out = []
    ef, tf = curve("full")
    er, tr = curve("reduced")
    for e in targets:
        le = math.log10(e)
        if not (ef.min() <= le <= ef.max() and er.min() <= le <= er.max()):
            continue
        a, b = 10 ** np.interp(le, ef, tf), 10 ** np.interp(le, er, tr)
        out.append((e, a, b, a / b))
    return out


def main(argv=None) -> int:
    args = parse_args(argv)
    rtols = [1e-6, 1e-8, 1e-10] if args.quick else [10.0**-k for k in range(6, 13)]
    repeats = 3 if args.quick else 5
    # c_call_costs reads only .repeats and .c_target of its settings.
    settings = SimpleNamespace(repeats=repeats, c_target=0.05 if args.quick else 0.2)
    t = np.linspace(0.0, T_END, N_GRID)

    progress("reference (DOP853, rtol 1e-13) ...")
    ref = reference(t, 1e-13, 1e-14)
    ref_check = reference(t, 1e-12, 1e-13)
    ref_unc = float(np.max(np.abs(ref - ref_check)))
    C = L**2 * math.sin(Q0[0]) ** 2 * V0[1]  # m = 1

    progress("compiling the full and the reduced model ...")
    full, reduced, red = compile_models(C)
    y0_red, p_red = red.initial_state(reduced, Q0, V0)
    assert abs(p_red["C_phi"] - C) < 1e-14

    def sim_full(tt, rtol):
        return full.simulate(tt, q0=Q0, v0=V0, rtol=rtol, atol=rtol / 100)

    def sim_red(tt, rtol):
        return reduced.simulate(tt, y0=y0_red, params=p_red, rtol=rtol, atol=rtol / 100)

    progress("C harness: RHS / Jacobian cost per call ...")
    costs = {}
    with tempfile.TemporaryDirectory(prefix="lcg-routh-bench-") as tmp:
        for label, cm in (("full", full), ("reduced", reduced)):
            costs[label] = _harness.c_call_costs(cm.code, Path(tmp) / label, settings)

    rows = []
    for rtol in rtols:
        for label, cm, fn in (("full", full, sim_full), ("reduced", reduced, sim_red)):
            progress(f"{label:7s} rtol {rtol:.0e} ...")
            rows.append(run(label, cm, fn, t, ref, rtol, repeats))

    lines = [
        f"lagcodegen Routhian benchmark (spherical pendulum), {datetime.datetime.now().isoformat(timespec='seconds')}",
        f"machine:  {_harness.cpu_model()}, os.cpu_count() = {os.cpu_count()}, {platform.platform()}",
        f"compiler: {_harness.compiler_version(_harness.c_compiler())}; lagcodegen {lcg.__version__}",
        f"run:      theta0 = {Q0[0]}, phi0 = {Q0[1]}, theta0' = {V0[0]}, phi0' = {V0[1]} (C_phi = {C:.6f}), "
        f"t in [0, {T_END:g}], {N_GRID} output times, native CVODE Adams, analytic Jacobian, atol = rtol/100",
        f"          wall: median of {repeats} simulate() calls; error: |(theta, phi) - reference|, reference DOP853 "
        f"rtol 1e-13 (its change from rtol 1e-12: {ref_unc:.1e})",
        "          RHS/Jac ns per call: C harness of benchmarks/pipeline.py (cc -O2), medians",
        "",
        f"{'model':8s} {'states':>6s} {'rhs ns':>8s} {'jac ns':>8s}",
    ]
    for label, cm in (("full", full), ("reduced", reduced)):
        lines.append(f"{label:8s} {cm.ny:6d} {costs[label]['rhs']:8.1f} {costs[label]['jac']:8.1f}")
    lines += ["", f"{'model':8s} {'rtol':>7s} {'steps':>7s} {'rhs evals':>9s} {'wall ms':>9s} "
                  f"{'err(T)':>9s} {'max err':>9s}"]
    for r in rows:
        lines.append(f"{r['model']:8s} {r['rtol']:7.0e} {r['steps']:7d} {r['rhs']:9d} {1e3 * r['wall']:9.3f} "
                     f"{r['err_final']:9.2e} {r['err_max']:9.2e}")
    lines += ["", "time at matched max error (log-log interpolation):",
              f"{'max err':>9s} {'full ms':>9s} {'reduced ms':>10s} {'full/reduced':>12s}"]
    for e, a, b, ratio in matched_ratios(rows, [10.0**-k for k in range(3, 12)]):
        lines.append(f"{e:9.0e} {1e3 * a:9.3f} {1e3 * b:10.3f} {ratio:12.2f}")
    text = "\n".join(lines)
    print(text)

    if args.out:
        _harness.write_report(args.out, "routhian", text)
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, ax = plt.subplots(figsize=(6.5, 4.5))
        for label, marker in (("full", "o-"), ("reduced", "s-")):
            pts = [r for r in rows if r["model"] == label]
            ax.loglog([r["err_max"] for r in pts], [1e3 * r["wall"] for r in pts], marker,
                      label=f"{label} ({pts[0]['states']} states)")
            for r in pts:
                ax.annotate(f"{r['rtol']:.0e}", (r["err_max"], 1e3 * r["wall"]), fontsize=6,
                            textcoords="offset points", xytext=(3, 3))
        ax.set_xlabel("max error in (theta, phi) over t in [0, 50]")
        ax.set_ylabel("wall time [ms]")
        ax.set_title("spherical pendulum: full vs Routhian-reduced")
        ax.grid(alpha=0.3, which="both")
        ax.legend()
        fig.tight_layout()
        fig.savefig(args.out / "routhian.png", dpi=110)
        plt.close(fig)
        progress(f"wrote {args.out / 'routhian.txt'} and {args.out / 'routhian.png'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
