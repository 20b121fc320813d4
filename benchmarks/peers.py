"""lagcodegen against its peers on the planar n-link pendulum (n = 1..10).

Peers (optional: ``pip install ".[bench]"`` or ``pip install casadi pydy cython``; a peer that
is not installed is reported and skipped):

* sympy     ``sympy.physics.mechanics.LagrangesMethod`` (derivation), ``sympy.lambdify`` of
            the full mass matrix and forcing (cse) + ``numpy.linalg.solve`` per call,
            integrated by scipy's DOP853;
* PyDy      ``KanesMethod`` (derivation) and PyDy's code generation with the Cython backend
            (``generate_ode_function(..., generator="cython")``), integrated by scipy's DOP853;
* CasADi    the Lagrangian in CasADi SX, M and F by its automatic differentiation,
            q'' = solve(M, F) symbolically; RHS cost from its C code generation
            (``Function.generate``, compiled with cc -O2 and timed by a C harness); integration
            by CasADi's own CVODES (Adams);
* lagcodegen ``derive`` + ``generate_c`` + ``build`` (no Jacobian, so that its code size
            matches the peers' RHS), RHS cost from the C harness of benchmarks/_harness.py,
            integration by the native CVODE driver (Adams, difference-quotient Jacobian).

Measured per n: derivation time, code generation + compilation time, RHS ns per call (in C
where the peer generates C: lagcodegen, CasADi; through the Python call otherwise, and the
Python-call cost of lagcodegen's cm.rhs for comparison), and the integration time to a
matched error: t in [0, 5] from every angle 0.5 rad at rest, 101 output times, rtol swept
(1e-4 ... 1e-10; --quick 1e-4, 1e-6, 1e-8; atol = rtol/100), error = max relative component
error against scipy DOP853 at rtol 1e-13 on lagcodegen's compiled RHS, and the time at error
1e-6 interpolated log-log. Ratios: peer / lagcodegen.

Times are medians of --repeats runs (derivations: one run, skipped once the previous n took
more than --budget seconds / growth). This is a measuring instrument: it asserts nothing.

Usage::

    python benchmarks/peers.py [--quick] [--out DIR] [--links 1,2,3] [--budget S]
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import statistics
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path
from types import SimpleNamespace

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _harness as H  # noqa: E402

from lagcodegen import Scene, build_code, derive, generate_c, systems  # noqa: E402

TAG = "peers"
T_END = 5.0
TARGET = 1e-6
G, L, M = 9.81, 1.0, 1.0
PEERS = ("lagcodegen", "sympy", "pydy", "casadi")


def progress(message: str) -> None:
    H.progress(TAG, message)


def parse_args(argv=None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="n = 1, 2, 3; three tolerances; 1 repeat (< 2 min)")
    ap.add_argument("--out", metavar="DIR", type=Path, help="write peers.txt, peers.csv, peers.png")
    ap.add_argument("--links", help="comma-separated n (default 1,2,3,4,5,6,8,10; quick 1,2,3)")
    ap.add_argument("--budget", type=float, help="seconds a derivation may take (default 120; quick 20)")
    ap.add_argument("--repeats", type=int, help="runs per median (default 3; quick 1)")
    ap.add_argument("--peers", default=",".join(PEERS), help=f"subset of {','.join(PEERS)}")
    return ap.parse_args(argv)


def available() -> dict[str, str | None]:
    """Peer -> None if usable, else the reason it is not."""
    out = {"lagcodegen": None}
    for peer, mods in (("sympy", ("sympy",)), ("pydy", ("pydy", "Cython")), ("casadi", ("casadi",))):
        missing = [m for m in mods if importlib.util.find_spec(m) is None]
        out[peer] = f"not installed ({', '.join(missing)}): pip install {' '.join(m.lower() for m in missing)}" \
            if missing else None
    return out


# --------------------------------------------------------------------------- common measurement
def python_call_ns(fn, y, repeats: int, target: float = 0.05) -> float:
    """ns per Python call of fn(y), median of ``repeats`` timed batches."""
    calls = 1
    while True:
        start = time.perf_counter()
        for _ in range(calls):
            fn(y)
        if time.perf_counter() - start > 0.01:
            break
        calls *= 4
    calls = max(1, int(calls * target / max(time.perf_counter() - start, 1e-9)))
    samples = []
    for _ in range(repeats):
        start = time.perf_counter()
        for _ in range(calls):
            fn(y)
        samples.append(1e9 * (time.perf_counter() - start) / calls)
    return statistics.median(samples)


def sweep(run, rtols, ref, scales, repeats: int, budget: float) -> tuple[list, float | None]:
    """(points [(error, seconds)], time at TARGET) of run(rtol) -> y on the grid."""
    pts, spent = [], 0.0
    for rtol in rtols:
        if spent > budget:
            break
        times, y = [], None
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            for _ in range(repeats):
                start = time.perf_counter()
                y = run(rtol)
                times.append(time.perf_counter() - start)
                if times[-1] > 0.5:
                    break
        spent += sum(times)
        pts.append((H.errors(y, ref, scales)[1], statistics.median(times)))
    sec, _ = H.time_at(pts, TARGET)
    return pts, sec


# --------------------------------------------------------------------------- peers
def peer_lagcodegen(n, ctx, scratch: Path) -> dict:
    start = time.perf_counter()
    eom = derive(systems.n_link_pendulum(n, name=f"peer_lcg{n}"))
    derive_s = time.perf_counter() - start
    start = time.perf_counter()
    with H.cache_at(scratch / f"lcg{n}"):
        code = generate_c(Scene(eom, jacobian=False, prefix=f"peer_lcg{n}"))
        cm = build_code(code)
    codegen_s = time.perf_counter() - start
    c_ns = H.c_call_costs(code, scratch / f"lcg_h{n}", ctx.settings)["rhs"]
    p = cm.parameter_vector()
    py_ns = python_call_ns(lambda y: cm.rhs(0.0, y, p), ctx.y_test, ctx.settings.repeats)

    def run(rtol):
        return cm.simulate(ctx.t, y0=ctx.y0, rtol=rtol, atol=rtol * 1e-2, jacobian=False, max_steps=10_000_000).y
    pts, sec = sweep(run, ctx.rtols, ctx.ref, ctx.scales, ctx.settings.repeats, ctx.budget)
    return dict(derive_s=derive_s, codegen_s=codegen_s, rhs_c_ns=c_ns, rhs_py_ns=py_ns, points=pts, t_target=sec,
                integrator="native CVODE Adams (DQ Jacobian)")


def sympy_lagranges(n):
    import sympy as sp
    import sympy.physics.mechanics as me
    q = me.dynamicsymbols(f"q1:{n + 1}")
    g, l, m = sp.symbols("g l m")
    N = me.ReferenceFrame("N")
    O = me.Point("O")
    O.set_vel(N, 0)
    P, parts = O, []
    for i in range(n):
        Pi = P.locatenew(f"P{i}", l * sp.sin(q[i]) * N.x - l * sp.cos(q[i]) * N.y)
        Pi.set_vel(N, Pi.pos_from(O).dt(N))
        pa = me.Particle(f"pa{i}", Pi, m)
        pa.potential_energy = m * g * Pi.pos_from(O).dot(N.y)
        parts.append(pa)
        P = Pi
    lm = me.LagrangesMethod(me.Lagrangian(N, *parts), q)
    lm.form_lagranges_equations()
    return lm, q, (g, l, m)


def peer_sympy(n, ctx, scratch: Path) -> dict:
    import sympy as sp
    import sympy.physics.mechanics as me
    start = time.perf_counter()
    lm, q, (g, l, m) = sympy_lagranges(n)
    Mf, Ff = lm.mass_matrix_full, lm.forcing_full
    derive_s = time.perf_counter() - start
    start = time.perf_counter()
    qd = [qi.diff(me.dynamicsymbols._t) for qi in q]
    xs = sp.symbols(f"x0:{2 * n}")
    sub = {**dict(zip(qd, xs[n:])), **dict(zip(q, xs[:n])), g: G, l: L, m: M}
    Ms, Fs = me.msubs(Mf, sub), me.msubs(Ff, sub)
    fn = sp.lambdify([xs], [Ms, Fs], modules="numpy", cse=True)
    codegen_s = time.perf_counter() - start

    def f(y):
        Mv, Fv = fn(y)
        return np.linalg.solve(np.asarray(Mv, dtype=float), np.asarray(Fv, dtype=float).ravel())

    py_ns = python_call_ns(f, ctx.y_test, ctx.settings.repeats)

    def run(rtol):
        y, _, _ = H.scipy_solution(lambda _t, y: f(y), ctx.t, ctx.y0, "DOP853", rtol, rtol * 1e-2)
        return y
    pts, sec = sweep(run, ctx.rtols, ctx.ref, ctx.scales, ctx.settings.repeats, ctx.budget)
    return dict(derive_s=derive_s, codegen_s=codegen_s, rhs_py_ns=py_ns, points=pts, t_target=sec,
                integrator="scipy DOP853 on lambdify(M, F) + numpy.linalg.solve")


def peer_pydy(n, ctx, scratch: Path) -> dict:
    import sympy as sp
    import sympy.physics.mechanics as me
    from pydy.codegen.ode_function_generators import generate_ode_function
    start = time.perf_counter()
    q = me.dynamicsymbols(f"q1:{n + 1}")
    u = me.dynamicsymbols(f"u1:{n + 1}")
    g, l, m = sp.symbols("g l m")
    N = me.ReferenceFrame("N")
    O = me.Point("O")
    O.set_vel(N, 0)
    P, parts, forces, kd = O, [], [], []
    for i in range(n):
        Ai = N.orientnew(f"A{i}", "Axis", [q[i], N.z])
        Ai.set_ang_vel(N, u[i] * N.z)
        Pi = P.locatenew(f"P{i}", -l * Ai.y)
        Pi.v2pt_theory(P, N, Ai)
        parts.append(me.Particle(f"pa{i}", Pi, m))
        forces.append((Pi, -m * g * N.y))
        kd.append(q[i].diff() - u[i])
        P = Pi
    km = me.KanesMethod(N, q_ind=q, u_ind=u, kd_eqs=kd)
    km.kanes_equations(parts, forces)
    derive_s = time.perf_counter() - start
    start = time.perf_counter()
    cwd = os.getcwd()
    os.chdir(scratch)  # PyDy's Cython backend builds in the working directory
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            f = generate_ode_function(km.forcing_full, q, u, [g, l, m], mass_matrix=km.mass_matrix_full,
                                      generator="cython")
    finally:
        os.chdir(cwd)
    codegen_s = time.perf_counter() - start
    p = np.array([G, L, M])
    py_ns = python_call_ns(lambda y: f(y, 0.0, p), ctx.y_test, ctx.settings.repeats)

    def run(rtol):
        y, _, _ = H.scipy_solution(lambda t, y: f(y, t, p), ctx.t, ctx.y0, "DOP853", rtol, rtol * 1e-2)
        return y
    pts, sec = sweep(run, ctx.rtols, ctx.ref, ctx.scales, ctx.settings.repeats, ctx.budget)
    return dict(derive_s=derive_s, codegen_s=codegen_s, rhs_py_ns=py_ns, points=pts, t_target=sec,
                integrator="scipy DOP853 on the PyDy Cython RHS")


CASADI_HARNESS = r"""
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
#include "NAME.h"

static double now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

int main(int argc, char **argv)
{
    double target = argc > 1 ? atof(argv[1]) : 0.2, s, x[NY], xd[NY], x0[NY];
    volatile double sink = 0.0;
    casadi_int sz_arg, sz_res, sz_iw, sz_w;
    const double **arg;
    double **res, *w;
    casadi_int *iw;
    long calls = 16, k;
    int i;

    NAME_work(&sz_arg, &sz_res, &sz_iw, &sz_w);
    arg = malloc(sizeof(double *) * (sz_arg + 1));
    res = malloc(sizeof(double *) * (sz_res + 1));
    iw = malloc(sizeof(casadi_int) * (sz_iw + 1));
    w = malloc(sizeof(double) * (sz_w + 1));
    for (i = 0; i < NY; ++i)
        x0[i] = i < NY / 2 ? 0.5 : 0.1;
    arg[0] = x;
    res[0] = xd;
    for (;;) {
        double start = now();
        for (k = 0; k < calls; ++k) {
            for (i = 0; i < NY; ++i)
                x[i] = x0[i] + 1e-9 * (double)(k & 1023);
            NAME(arg, res, iw, w, 0);
            sink += xd[NY - 1];
        }
        s = now() - start;
        if (s > 0.01)
            break;
        calls *= 4;
    }
    calls = (long)((double)calls * target / s);
    if (calls < 1)
        calls = 1;
    {
        double start = now();
        for (k = 0; k < calls; ++k) {
            for (i = 0; i < NY; ++i)
                x[i] = x0[i] + 1e-9 * (double)(k & 1023);
            NAME(arg, res, iw, w, 0);
            sink += xd[NY - 1];
        }
        printf("rhs %ld %.6e\n", calls, 1e9 * (now() - start) / (double)calls);
    }
    return 0;
}
"""


def peer_casadi(n, ctx, scratch: Path) -> dict:
    import casadi as ca
    start = time.perf_counter()
    q, qd = ca.SX.sym("q", n), ca.SX.sym("qd", n)
    y = vx = vy = T = V = 0
    for i in range(n):
        y = y - L * ca.cos(q[i])
        vx = vx + L * ca.cos(q[i]) * qd[i]
        vy = vy + L * ca.sin(q[i]) * qd[i]
        T = T + M / 2 * (vx**2 + vy**2)
        V = V + M * G * y
    Lag = T - V
    p = ca.gradient(Lag, qd)
    Mm = ca.jacobian(p, qd)
    F = ca.gradient(Lag, q) - ca.mtimes(ca.jacobian(p, q), qd)
    X = ca.vertcat(q, qd)
    ode = ca.vertcat(qd, ca.solve(Mm, F))
    name = f"casrhs{n}"
    f = ca.Function(name, [X], [ode])
    derive_s = time.perf_counter() - start
    folder = scratch / f"cas{n}"
    folder.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    cwd = os.getcwd()
    os.chdir(folder)
    try:
        f.generate(f"{name}.c", {"with_header": True})
    finally:
        os.chdir(cwd)
    (folder / "harness.c").write_text(CASADI_HARNESS.replace("NAME", name).replace("NY", str(2 * n)))
    cmd = [H.c_compiler(), "-O2", "harness.c", f"{name}.c", "-o", "harness", "-lm"]
    proc = subprocess.run(cmd, cwd=folder, capture_output=True, text=True)
    if proc.returncode != 0:
        raise RuntimeError(f"compiling CasADi's C code failed: {proc.stderr[:300]}")
    codegen_s = time.perf_counter() - start
    samples = []
    for _ in range(ctx.settings.repeats):
        out = subprocess.run([str(folder / "harness"), repr(ctx.settings.c_target)], capture_output=True, text=True)
        samples.append(float(out.stdout.split()[2]))
    py_ns = python_call_ns(lambda yy: f(yy), ctx.y_test, ctx.settings.repeats)
    integrators = {}

    def run(rtol):
        if rtol not in integrators:
            integrators[rtol] = ca.integrator("I", "cvodes", {"x": X, "ode": ode}, 0.0, ctx.t,
                                              {"abstol": rtol * 1e-2, "reltol": rtol, "max_num_steps": 10**7,
                                               "linear_multistep_method": "adams"})
        r = integrators[rtol](x0=ctx.y0)
        return np.array(r["xf"]).T
    for rtol in ctx.rtols:  # building the integrator is not part of the integration time
        run(rtol)
    pts, sec = sweep(run, ctx.rtols, ctx.ref, ctx.scales, ctx.settings.repeats, ctx.budget)
    return dict(derive_s=derive_s, codegen_s=codegen_s, rhs_c_ns=statistics.median(samples), rhs_py_ns=py_ns,
                points=pts, t_target=sec, integrator="CasADi CVODES Adams (SX virtual machine)")


RUNNERS = {"lagcodegen": peer_lagcodegen, "sympy": peer_sympy, "pydy": peer_pydy, "casadi": peer_casadi}


# --------------------------------------------------------------------------- main
def context(n: int, rtols, settings, budget) -> SimpleNamespace:
    cm = build_code(generate_c(Scene(derive(systems.n_link_pendulum(n, name=f"peer_ref{n}")), jacobian=False,
                                prefix=f"peer_ref{n}")))
    p = cm.parameter_vector()
    t = np.linspace(0.0, T_END, 101)
    y0 = np.array([0.5] * n + [0.0] * n)
    ref, _, _ = H.scipy_solution(lambda tt, y: cm.rhs(tt, y, p), t, y0, "DOP853", 1e-13, 1e-15)
    check, _, _ = H.scipy_solution(lambda tt, y: cm.rhs(tt, y, p), t, y0, "DOP853", 1e-12, 1e-14)
    scales = H.error_scales(ref)
    return SimpleNamespace(t=t, y0=y0, ref=ref, scales=scales, ref_unc=H.errors(check, ref, scales)[1],
                           rtols=rtols, settings=settings, budget=budget,
                           y_test=np.array([0.5] * n + [0.1] * n))


COLUMNS = [
    ("n", "n", "{}"), ("peer", "peer", "{}"), ("derive_s", "derive [s]", "{:.3f}"),
    ("codegen_s", "codegen+compile [s]", "{:.2f}"), ("rhs_c_ns", "RHS C [ns]", "{:.0f}"),
    ("rhs_py_ns", "RHS Python call [ns]", "{:.0f}"), ("t_target_ms", f"ms to err {TARGET:.0e}", "{:.3f}"),
    ("derive_ratio", "derive /lcg", "{:.1f}"), ("rhs_ratio", "RHS /lcg", "{:.1f}"),
    ("integ_ratio", "integrate /lcg", "{:.1f}"), ("status", "status", "{}"),
]


def main(argv=None) -> int:
    args = parse_args(argv)
    quick = args.quick
    links = [int(x) for x in args.links.split(",")] if args.links else ([1, 2, 3] if quick else [1, 2, 3, 4, 5, 6, 8, 10])
    budget = args.budget or (20.0 if quick else 120.0)
    repeats = args.repeats or (1 if quick else 3)
    settings = SimpleNamespace(repeats=repeats, c_target=0.05 if quick else 0.2)
    rtols = [1e-4, 1e-6, 1e-8] if quick else [10.0 ** -k for k in (4, 5, 6, 7, 8, 9, 10)]
    wanted = [p.strip() for p in args.peers.split(",") if p.strip()]
    avail = available()
    start_all, load_start = time.perf_counter(), H.load_average()
    notes = []
    for peer in wanted:
        if avail.get(peer):
            notes.append(f"{peer}: skipped, {avail[peer]}")
            progress(notes[-1])
    rows, last_derive = [], {}
    with tempfile.TemporaryDirectory(prefix="lcg-peers-") as tmp:
        scratch = Path(tmp)
        for n in links:
            progress(f"n = {n}: reference")
            ctx = context(n, rtols, settings, budget / 4)
            base = None
            for peer in wanted:
                if avail.get(peer):
                    continue
                row = dict(n=n, peer=peer)
                prev = last_derive.get(peer)
                if prev is not None and prev[1] * (n / prev[0]) ** 4 > budget:
                    row["status"] = f"skipped: derivation predicted > {budget:g} s"
                    rows.append(row)
                    continue
                progress(f"n = {n}: {peer}")
                try:
                    res = RUNNERS[peer](n, ctx, scratch)
                except Exception as exc:  # a peer's failure is a result, not a crash
                    row["status"] = f"failed: {type(exc).__name__}: {' '.join(str(exc).split())[:60]}"
                    rows.append(row)
                    continue
                last_derive[peer] = (n, res["derive_s"])
                row.update(derive_s=res["derive_s"], codegen_s=res["codegen_s"], rhs_c_ns=res.get("rhs_c_ns"),
                           rhs_py_ns=res.get("rhs_py_ns"), points=res["points"], integrator=res["integrator"],
                           t_target_ms=None if res["t_target"] is None else 1e3 * res["t_target"], status="ok")
                if peer == "lagcodegen":
                    base = row
                elif base is not None:
                    row["derive_ratio"] = row["derive_s"] / base["derive_s"]
                    rc = row.get("rhs_c_ns") or row.get("rhs_py_ns")
                    rb = base["rhs_c_ns"] if row.get("rhs_c_ns") else base["rhs_py_ns"]
                    row["rhs_ratio"] = rc / rb if rc and rb else None
                    if row["t_target_ms"] and base.get("t_target_ms"):
                        row["integ_ratio"] = row["t_target_ms"] / base["t_target_ms"]
                rows.append(row)
    lines = H.machine_lines("lagcodegen peers benchmark (planar n-link pendulum)", (load_start, H.load_average()))
    versions = []
    for mod in ("casadi", "pydy", "Cython"):
        try:
            import importlib.metadata
            versions.append(f"{mod} {importlib.metadata.version(mod)}")
        except Exception:
            versions.append(f"{mod} absent")
    lines += [f"peers:    {', '.join(versions)}",
              f"run:      t in [0, {T_END:g}], every angle 0.5 rad at rest, 101 output times, rtol "
              f"{', '.join(f'{r:.0e}' for r in rtols)}, atol = rtol/100; medians of {repeats}",
              "          RHS /lcg: C against C where the peer generates C (CasADi), Python call against lagcodegen's "
              "cm.rhs Python call otherwise", ""]
    lines += [f"note: {x}" for x in notes] + ([""] if notes else [])
    lines += [H.format_table(COLUMNS, rows), "", "integrators:"]
    seen = {}
    for r in rows:
        if r.get("integrator") and r["peer"] not in seen:
            seen[r["peer"]] = r["integrator"]
    lines += [f"  {k}: {v}" for k, v in seen.items()]
    text = "\n".join(lines) + "\n"
    print(text, end="")
    if args.out is not None:
        H.write_report(args.out, "peers", text, [{k: v for k, v in r.items() if k != "points"} for r in rows])
        biggest = max((r["n"] for r in rows if r.get("points")), default=None)
        if biggest is not None:
            curves = {r["peer"]: r["points"] for r in rows if r["n"] == biggest and r.get("points")}
            H.work_precision_plot(args.out / "peers.png", f"{biggest}-link pendulum, t in [0, {T_END:g}]: peers",
                                  curves, "max relative error over the grid (all states)")
        progress(f"wrote {args.out}/peers.txt, peers.csv, peers.png")
    progress(f"done in {time.perf_counter() - start_all:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
