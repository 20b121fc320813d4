"""The Python part of a constrained ``simulate()`` call: the whole call against the native driver alone.

For a Cartesian pendulum (2 coordinates, 1 constraint) and a planar 3-link chain in Cartesian
coordinates (6 coordinates, 3 constraints), each released at rest from 0.5 rad per link, under
the index-1 (CVODE) and GGL (IDA) formulations with the default options (rtol 1e-8, atol 1e-10),
over t in [0, 1] given three ways -- the pair (0, 1) (1001 output times), an array of 1001 times,
and the array [0, 1] (two output times) -- it times, interleaved:

* driver [us]     ``lcg_cvc_solve`` / ``lcg_ida_solve`` on the model's table (index-1: the default
                  "auto" stabilization), called through cffi with every argument prepared
                  beforehand (the consistent initial values, the options struct simulate()
                  builds, preallocated outputs): the C integration alone;
* simulate [us]   ``ConstrainedSimulation.simulate(t, q0=..., v0=...)``: the checks of the
                  arguments, the initial-state check (and projection), the options, the driver
                  call, the Result;
* python [us]     the Python part of the call: simulate()'s time minus that of the driver call
                  inside it (``stats["wall_time"]``), median and minimum over the runs.
                  Target: at most 20 us;
* vs driver [us]  simulate - driver (medians): the Python part plus what the driver itself
                  costs more inside simulate() (output arrays that are new, hence not in the
                  caches, where the driver alone writes into the same arrays every time).

Wall clock; the driver and simulate() take the same steps (checked: equal step counts and
final states).

A second table checks that output times are served by interpolation: steps and right-hand-side
(residual) evaluations of a run over t in [0, 10] with 11 and with 1001 output times, for every
formulation and backend (native index-1, GGL; scikit-sundae index-1, GGL; minimal coordinates)
-- equal but for CVODE's estimate of the first step, which looks at the first output interval,
when the integrator is never made to stop at an output time. (scikit-sundae's step count also
counts the one-step calls that return a step already taken, after each interpolated output:
compare its evaluations.)

Usage::

    python benchmarks/constrained_overhead.py [--quick] [--repeats N] [--out DIR]
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
from lagcodegen.api import compile_constrained  # noqa: E402
from lagcodegen.theory.constraints import ConstrainedSystem  # noqa: E402

TAG = "constrained_overhead"
TARGET_US = 20.0
RTOL, ATOL, ALG_ATOL = 1e-8, 1e-10, 1e8  # simulate()'s defaults (ALG_ATOL: ida.ALGEBRAIC_ATOL)
THETA0 = 0.5
TIMES = (("(0, 1)", (0.0, 1.0)), ("1001 times", np.linspace(0.0, 1.0, 1001)), ("[0, 1]", np.array([0.0, 1.0])))
POLL_EVERY = 0.05  # solvers.control.POLL_EVERY


def progress(message: str) -> None:
    H.progress(TAG, message)


def chain(links: int, name: str) -> ConstrainedSystem:
    """A planar chain of ``links`` unit point masses on massless rods of length 1 in Cartesian
    coordinates (x_i, y_i): one holonomic constraint per rod."""
    m = lcg.Model(name)
    coords = m.coordinates(" ".join(f"x{i} y{i}" for i in range(links)))
    g, = m.parameters(g=9.81)
    rods, px, py = [], 0, 0
    for i in range(links):
        x, y = coords[2 * i], coords[2 * i + 1]
        m.particle(f"b{i}", 1.0, (x, y))
        rods.append((x - px) ** 2 + (y - py) ** 2 - 1)
        px, py = x, y
    m.gravity(g)
    return ConstrainedSystem(m, holonomic=rods)


def chain_q0(links: int) -> list[float]:
    """Every link at THETA0 from the vertical, at rest."""
    q, px, py = [], 0.0, 0.0
    for _ in range(links):
        px, py = px + np.sin(THETA0), py - np.cos(THETA0)
        q += [px, py]
    return q


SYSTEMS = (("pendulum", 1), ("3-link chain", 3))


def driver_call(sim, t: np.ndarray, q0):
    """A function running the native driver of ``sim`` once through cffi, every argument prepared
    as simulate() prepares it with the default options; it returns (steps, final state)."""
    ffi, pre, n = sim.ffi, sim.info.prefix, sim.n
    p = sim.parameter_vector()
    y0 = sim.consistent_initial_state(float(t[0]), q0, None, p)
    poll = sim.compiled.poll
    nt, nout = t.size, max(len(sim.info.output_names), 1)
    keep = [p, t]
    if sim.formulation == "index1":
        yout, out = np.empty((nt, 2 * n)), np.empty((nt, nout))
        opt = ffi.new(f"{sim.cvc_options_type} *")
        st = ffi.new(sim.cvc_stats_type)
        for name, value in dict(method=1, rtol=RTOL, atol=ATOL, atol_vec=ffi.NULL, max_steps=1_000_000,
                                alpha=-1.0, beta=-1.0, projection=0, proj_tol=1e-12, proj_maxit=10, proj_err=1,
                                roots=0, poll=poll, poll_every=POLL_EVERY, max_wall=0.0).items():
            setattr(opt, name, value)
        fn = sim.c_cvc_solve  # the runtime's lcg_cvc_solve on the model's table
        args = (ffi.from_buffer("double[]", p) if p.size else ffi.NULL, ffi.from_buffer("double[]", y0), nt,
                ffi.from_buffer("double[]", t), ffi.from_buffer("double[]", yout), ffi.from_buffer("double[]", out),
                opt, st, ffi.NULL)
    else:
        ng = sim.info.ng
        acc, lam = sim.kkt(float(t[0]), y0, p)
        yy0 = np.concatenate([y0, lam, np.zeros(sim.info.JH)])
        yp0 = np.concatenate([y0[n:], acc, np.zeros(sim.info.J + sim.info.JH)])
        atol = np.full(ng, ATOL)
        atol[2 * n:] = ALG_ATOL
        yout, out = np.empty((nt, ng)), np.empty((nt, nout))
        keep += [yy0, yp0, atol]
        opt = ffi.new(f"{sim.ida_options_type} *")
        st = ffi.new(sim.ida_stats_type)
        for name, value in dict(rtol=RTOL, atol=ATOL, atol_vec=ffi.from_buffer("double[]", atol),
                                max_steps=1_000_000, suppress_alg=1, jacobian=int(sim.info.ggl_jac), calc_ic=1,
                                ic_alg_atol=ALG_ATOL, roots=0, stop_at_outputs=0, poll=poll, poll_every=POLL_EVERY,
                                max_wall=0.0).items():
            setattr(opt, name, value)
        fn = sim.c_ida_solve  # the runtime's lcg_ida_solve on the model's table
        args = (ffi.from_buffer("double[]", p) if p.size else ffi.NULL, ffi.from_buffer("double[]", yy0),
                ffi.from_buffer("double[]", yp0), nt, ffi.from_buffer("double[]", t),
                ffi.from_buffer("double[]", yout), ffi.from_buffer("double[]", out), opt, st, ffi.NULL)

    def call():
        if fn(*args) != 0:
            raise RuntimeError(f"{pre}: the driver failed: {ffi.string(st.message).decode()}")
        return st.nsteps, yout[-1, : 2 * n].copy()
    call.keep = keep
    return call


def measure(label: str, sim, q0, repeats: int) -> list[dict]:
    """Rows of the overhead table for one compiled system (every way of giving t)."""
    now = time.perf_counter
    rows = []
    for tlabel, tspec in TIMES:
        t = np.linspace(tspec[0], tspec[1], 1001) if isinstance(tspec, tuple) else tspec
        call = driver_call(sim, t, q0)

        def simulate():
            return sim.simulate(tspec, q0=q0)
        steps, y_end = call()
        res = simulate()
        drv, tot, py = [], [], []
        for _ in range(repeats):  # interleaved, so that machine noise hits both alike
            start = now()
            call()
            drv.append(now() - start)
            start = now()
            res = simulate()
            tot.append(now() - start)
            py.append(tot[-1] - res.stats["wall_time"])
        d, s = statistics.median(drv), statistics.median(tot)
        rows.append(dict(system=label, n=sim.n, formulation=sim.formulation, t=tlabel, nt=int(t.size),
                         steps=int(steps), driver_us=1e6 * d, simulate_us=1e6 * s,
                         python_us=1e6 * statistics.median(py), python_min_us=1e6 * min(py),
                         vs_driver_us=1e6 * (s - d),
                         same=bool(res.stats["steps"] == steps and np.array_equal(res.y[-1], y_end))))
    return rows


def step_rows(sims: dict, q0, t_end: float = 10.0) -> list[dict]:
    """Steps over [0, t_end] with 11 and with 1001 output times, every formulation and backend."""
    rows = []
    runs = (("index1", "native"), ("index1", "sksundae"), ("ggl", "native"), ("ggl", "sksundae"),
            ("minimal", "native"))
    for form, backend in runs:
        steps, evals = [], []
        for nt in (11, 1001):
            res = sims[form].simulate(np.linspace(0.0, t_end, nt), q0=q0, backend=backend)
            steps.append(int(res.stats["steps"]))
            evals.append(int(res.stats["rhs_evals"]))
        rows.append(dict(formulation=form, backend=backend, steps_11=steps[0], steps_1001=steps[1],
                         difference=steps[1] - steps[0], evals_11=evals[0], evals_1001=evals[1]))
    return rows


COLUMNS = [
    ("system", "system", "{}"), ("formulation", "formulation", "{}"), ("t", "t", "{}"), ("nt", "outputs", "{}"),
    ("steps", "steps", "{}"), ("driver_us", "driver [us]", "{:.1f}"), ("simulate_us", "simulate [us]", "{:.1f}"),
    ("python_us", "python [us]", "{:.1f}"), ("python_min_us", "python min [us]", "{:.1f}"),
    ("vs_driver_us", "vs driver [us]", "{:.1f}"), ("same", "same run", "{}"),
]
STEP_COLUMNS = [
    ("formulation", "formulation", "{}"), ("backend", "backend", "{}"), ("steps_11", "steps (11 outputs)", "{}"),
    ("steps_1001", "steps (1001 outputs)", "{}"), ("difference", "difference", "{}"),
    ("evals_11", "evaluations (11)", "{}"), ("evals_1001", "evaluations (1001)", "{}"),
]


def parse_args(argv=None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="31 repeats, the pendulum only (< 30 s)")
    ap.add_argument("--repeats", type=int, help="runs per median (default 301; quick 31)")
    ap.add_argument("--out", metavar="DIR", type=Path, help="write constrained_overhead.txt and .csv")
    return ap.parse_args(argv)


def main(argv=None) -> int:
    args = parse_args(argv)
    repeats = args.repeats or (31 if args.quick else 301)
    start, load_start = time.perf_counter(), H.load_average()
    rows, steps = [], []
    for label, links in SYSTEMS[:1] if args.quick else SYSTEMS:
        system = chain(links, f"ovh_c{links}")
        q0 = chain_q0(links)
        sims = {}
        for form in ("index1", "ggl", "minimal") if links == 1 else ("index1", "ggl"):
            progress(f"{label}: compile {form}")
            sims[form] = compile_constrained(system, form, prefix=f"ovh_c{links}_{form}")
        for form in ("index1", "ggl"):
            progress(f"{label}: {form}, {repeats} runs per configuration")
            rows += measure(label, sims[form], q0, repeats)
        if links == 1:
            progress(f"{label}: steps with 11 and 1001 output times")
            steps = step_rows(sims, q0)
    lines = H.machine_lines("lagcodegen constrained simulate(): the Python part of a call",
                            (load_start, H.load_average()))
    lines += [f"run:      t in [0, 1], every link {THETA0} rad at rest, rtol {RTOL:g}, atol {ATOL:g} (the defaults); "
              f"medians of {repeats} interleaved runs", "",
              H.format_table(COLUMNS, rows), ""]
    worst = max(rows, key=lambda r: r["python_us"])
    lines.append(f"target {TARGET_US:g} us: python worst {worst['python_us']:.1f} us ({worst['system']}, "
                 f"{worst['formulation']}, t = {worst['t']}): " + ("met" if worst["python_us"] <= TARGET_US else "MISSED"))
    if steps:
        lines += ["", "steps over t in [0, 10] with 11 and 1001 output times (pendulum, default options):", "",
                  H.format_table(STEP_COLUMNS, steps)]
    text = "\n".join(lines) + "\n"
    print(text, end="")
    if args.out is not None:
        H.write_report(args.out, TAG, text, rows)
        progress(f"wrote {args.out}/{TAG}.txt and .csv")
    progress(f"done in {time.perf_counter() - start:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
