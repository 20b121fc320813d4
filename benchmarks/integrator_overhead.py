"""Per-call Python overhead of the integrator object (``CompiledModel.integrator``) and of
``simulate()``, beside the C work they wrap.

For the pendulum (n = 1, q0 = 0.1 at rest) and the double pendulum (n = 2), rtol = atol = 1e-8,
on the Taylor integrator and on CVODE (Adams), each call advancing by dt (1 ms: a control period;
0.1 s: a few steps), these are timed per call, in batches, rounds interleaved, medians:

* ``cffi no-op``     the stepper's C function called through cffi with nothing to do (t = now):
                     the cost of a cffi call;
* ``C call``         the stepper's C function through cffi advancing by dt (the C work + a cffi call);
* ``propagate_for``  ``integ.propagate_for(dt)``;
* ``closed loop``    ``integ.params[k] = u; integ.propagate_for(dt)`` (a parameter written in place,
                     u = g (1 + 1e-3 q) new at every call: the Taylor stepper recomputes its run
                     constants, CVODE restarts) against the C call after the same write;
* ``propagate_grid`` ``integ.propagate_grid(times)`` over 10 times spanning dt (a new times array
                     and a new result array each call), against the C call with preallocated arrays;
* ``propagate_grid, out=``  the same with preallocated arrays, as the C call has them
                     (``np.add(integ.time, offsets, out=times); integ.propagate_grid(times, out=rows)``);
* ``step``           ``integ.step()`` against the C call of one step;
* ``simulate``       ``sim.simulate(np.array([0, dt]), y0=..., method=...)`` against the run
                     driver called through cffi with prepared arguments (after the first call with
                     these options: the fast path);
* ``simulate, full path``  the same call on the full path (every option resolved and checked each
                     call, ``CompiledModel._simulate``): what every call cost before the fast path;
* ``module run``     (Taylor) the compiled Taylor integrator's own ``TaylorModule.simulate`` on
                     checked arrays, the layer the full path runs through, against the same run
                     driver call (no target of its own).

The Python overhead of a call is its time minus the C work, the C work being the C call minus
the cffi no-op (so the cffi call's own cost counts as overhead). Targets of the small-systems
issue: at most 2 us for the integrator object, 8 us for ``simulate()`` at n = 1.

Usage::

    python benchmarks/integrator_overhead.py [--quick] [--out DIR] [--rounds N] [--methods taylor,adams,bdf]
                                             [--clock cpu|wall]
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
from lagcodegen import systems  # noqa: E402
from lagcodegen.solvers.taylor.run import taylor_module  # noqa: E402

TAG = "integrator_overhead"
INF = float("inf")
TOL = 1e-8
Q0 = 0.1
TARGET_INTEGRATOR_US = 2.0
TARGET_SIMULATE_US = 8.0


def progress(message: str) -> None:
    H.progress(TAG, message)


def parse_args(argv=None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="n = 1 only, 5 rounds (< 2 min)")
    ap.add_argument("--out", metavar="DIR", type=Path, help="write integrator_overhead.txt and .csv")
    ap.add_argument("--rounds", type=int, help="rounds per median (default 15; quick 5)")
    ap.add_argument("--methods", default="taylor,adams", help="comma-separated: taylor, adams, bdf (default "
                    "taylor,adams)")
    ap.add_argument("--clock", choices=("cpu", "wall"), default="wall",
                    help="time batches by wall time (default) or by the CPU time of the calling thread, which a "
                         "loaded machine's preemption does not inflate")
    ap.add_argument("--batch", type=float, default=0.02, help="seconds per timed batch (default 0.02)")
    return ap.parse_args(argv)


def make(sim, method: str):
    return sim.integrator(q0=[Q0] * sim.n, method=method, rtol=TOL, atol=TOL)


def raw_driver(sim, method: str, dt: float):
    """The run driver of simulate() called through cffi with prepared arguments: a function of no
    arguments running [0, dt] from the initial state."""
    t = np.array([0.0, dt])
    y0 = np.array([Q0] * sim.n + [0.0] * sim.n)
    p = sim.parameter_vector()
    if method == "taylor":
        module = taylor_module(sim)
        module.simulate(t, y0, p, rtol=TOL, atol=TOL)  # sets the options struct
        ffi = module.ffi
        yout, out = np.empty((2, sim.ny)), np.empty(1)
        args = (module._ptr(p, 0), module._ptr(y0, 1), 2, module._ptr(t, 2), ffi.from_buffer("double[]", yout),
                ffi.from_buffer("double[]", out), module._opt, module._st, ffi.NULL)
        fn = module._solve
    else:
        ffi = sim.ffi
        yout, out = np.empty((2, sim.ny)), np.empty((2, 1))
        opt = ffi.new(f"{sim.options_type} *")
        opt.method, opt.jacobian = {"adams": 1, "bdf": 2}[method], int(bool(sim.code.jacobian))
        opt.rtol, opt.atol, opt.atol_vec, opt.max_steps = TOL, TOL, ffi.NULL, 1_000_000
        st = ffi.new(sim.stats_type)
        args = (sim.c_params(p), ffi.from_buffer("double[]", y0), 2, ffi.from_buffer("double[]", t),
                ffi.from_buffer("double[]", yout), ffi.from_buffer("double[]", out), opt, st)
        fn = sim.native_solve
    return lambda: fn(*args)


def cases(sim, method: str, dt: float) -> dict:
    """name -> a function running one call (each on an integrator of its own)."""
    grid_n = 10
    objs = {}

    def integ(name):
        objs[name] = make(sim, method)
        return objs[name]

    noop_i = integ("noop")
    noop_c = noop_i._stepper.until
    c_i = integ("c")
    c_until = c_i._stepper.until
    c_mem = c_i._mem
    pf_i = integ("propagate_for")
    pf = pf_i.propagate_for
    cl_c = integ("closed_c")
    cl_c_until, cl_c_mem, k_par = cl_c._stepper.until, cl_c._mem, 1 + sim.ny  # the first parameter
    cl_i = integ("closed")
    cl_params, cl_state, cl_pf = cl_i.params, cl_i.state, cl_i.propagate_for
    g0 = float(cl_params[0])
    gr_c = integ("grid_c")
    gr_grid, gr_mem = gr_c._stepper.grid, gr_c._mem
    gr_yout = np.empty((grid_n, sim.ny))
    gr_ffi = gr_c._stepper.ffi
    offsets = np.linspace(dt / grid_n, dt, grid_n)
    gr_times = np.empty(grid_n)
    gr_tp = gr_ffi.from_buffer("double[]", gr_times)
    gr_yp = gr_ffi.from_buffer("double[]", gr_yout)
    gr_i = integ("grid")
    gro_i = integ("grid_out")
    gro_times, gro_rows = np.empty(grid_n), np.empty((grid_n, sim.ny))
    st_c = integ("step_c")
    st_step = st_c._stepper.step
    st_i = integ("step")
    raw = raw_driver(sim, method, dt)
    y0 = np.array([Q0] * sim.n + [0.0] * sim.n)
    t_sim = np.array([0.0, dt])

    def c_grid():
        np.add(gr_mem[0], offsets, out=gr_times)
        return gr_grid(grid_n, gr_tp, gr_yp)

    def grid():
        return gr_i.propagate_grid(gr_i.time + offsets)

    def grid_out():
        np.add(gro_i.time, offsets, out=gro_times)
        return gro_i.propagate_grid(gro_times, out=gro_rows)

    def closed_c():
        cl_c_mem[k_par] = g0 * (1 + 1e-3 * cl_c_mem[1])
        return cl_c_until(cl_c_mem[0] + dt)

    def closed():
        cl_params[0] = g0 * (1 + 1e-3 * cl_state[0])
        return cl_pf(dt)

    fns = {
        "cffi no-op": lambda: noop_c(noop_i._mem[0]),
        "C call": lambda: c_until(c_mem[0] + dt),
        "propagate_for": lambda: pf(dt),
        "C call, input written": closed_c,
        "closed loop": closed,
        "C call, grid": c_grid,
        "propagate_grid": grid,
        "propagate_grid, out=": grid_out,
        "C call, one step": lambda: st_step(INF),
        "step": st_i.step,
        "run driver": raw,
        "simulate": lambda: sim.simulate(t_sim, y0=y0, method=method, rtol=TOL, atol=TOL),
    }
    if method == "taylor":
        module, p = taylor_module(sim), sim.parameter_vector()
        fns["module run"] = lambda: module.simulate(t_sim, y0, p, rtol=TOL, atol=TOL)
    full_path = getattr(sim, "_simulate", None)  # absent before the fast path: simulate() was the full path
    if full_path is not None:
        fns["simulate, full path"] = lambda: full_path(t_sim, y0=y0, method=method, rtol=TOL, atol=TOL)
    return fns, objs


def measure(sim, method: str, dt: float, rounds: int, batch: float, clock=time.perf_counter) -> dict:
    fns, objs = cases(sim, method, dt)
    counts = {}
    for name, fn in fns.items():  # warm up, and calls per batch of about `batch` seconds
        fn()
        start = clock()
        k = 0
        while clock() - start < batch / 4:
            fn()
            k += 1
        counts[name] = max(1, int(4 * k))
    times = {name: [] for name in fns}
    for _ in range(rounds):  # interleaved: machine noise hits every variant alike
        for name, fn in fns.items():
            k = counts[name]
            start = clock()
            for _ in range(k):
                fn()
            times[name].append((clock() - start) / k)
    for integ in objs.values():
        integ.close()
    return ({name: 1e6 * statistics.median(v) for name, v in times.items()},
            {name: 1e6 * min(v) for name, v in times.items()})


def rows_of(label: str, n: int, method: str, dt: float, timed) -> list[dict]:
    med, best = timed
    noop = med["cffi no-op"]
    pairs = [("propagate_for", "C call"), ("closed loop", "C call, input written"),
             ("propagate_grid", "C call, grid"), ("propagate_grid, out=", "C call, grid"), ("step", "C call, one step"),
             ("simulate", "run driver"), ("simulate, full path", "run driver"), ("module run", "run driver")]
    rows = []
    for call, c_call in pairs:
        if call not in med:
            continue
        c_work = med[c_call] - noop
        overhead = med[call] - c_work
        best_overhead = best[call] - (best[c_call] - best["cffi no-op"])
        target = (TARGET_SIMULATE_US if call.startswith("simulate") else None if call == "module run"
                  else TARGET_INTEGRATOR_US)
        rows.append(dict(model=label, n=n, method=method, dt=dt, call=call, call_us=med[call], c_call_us=med[c_call],
                         cffi_noop_us=noop, c_work_us=c_work, overhead_us=overhead,
                         wrapper_us=med[call] - med[c_call], best_overhead_us=best_overhead, target_us=target,
                         met=None if target is None else "yes" if overhead <= target else "NO"))
    return rows


def main(argv=None) -> int:
    args = parse_args(argv)
    rounds = args.rounds or (5 if args.quick else 15)
    clock = time.thread_time if args.clock == "cpu" else time.perf_counter
    clock_text = "CPU time of the calling thread" if args.clock == "cpu" else "wall time"
    load_start = H.load_average()
    models = [("pendulum", systems.n_link_pendulum(1, name="ovh_pendulum"))]
    if not args.quick:
        models.append(("double pendulum", systems.n_link_pendulum(2, name="ovh_double")))
    dts = (1e-3,) if args.quick else (1e-3, 0.1)
    rows = []
    for label, model in models:
        progress(f"{label}: compile")
        sim = lcg.compile_model(model)
        for method in args.methods.split(","):
            for dt in dts:
                progress(f"{label}: {method}, dt = {dt:g}: {rounds} rounds")
                rows += rows_of(label, sim.n, method, dt, measure(sim, method, dt, rounds, args.batch, clock))
    columns = [("model", "model", "{}"), ("method", "method", "{}"), ("dt", "dt [s]", "{:g}"),
               ("call", "call", "{}"), ("call_us", "call [us]", "{:.2f}"), ("c_call_us", "C call [us]", "{:.2f}"),
               ("cffi_noop_us", "cffi no-op [us]", "{:.2f}"), ("overhead_us", "Python overhead [us]", "{:.2f}"),
               ("wrapper_us", "beyond the C call [us]", "{:.2f}"),
               ("best_overhead_us", "overhead, fastest rounds [us]", "{:.2f}"), ("target_us", "target [us]", "{:g}"),
               ("met", "met", "{}")]
    text = "\n".join(H.machine_lines("Integrator object and simulate(): per-call Python overhead",
                                     (load_start, H.load_average()))
                     + [f"rtol = atol = {TOL:g}, q0 = {Q0} at rest; medians of {rounds} interleaved rounds of "
                        f"batches of about {args.batch:g} s ({clock_text}); overhead = call - (C call - cffi no-op) "
                        "of the medians "
                        "(and of each variant's fastest round: on a loaded machine the medians carry its noise)", "",
                        H.format_table(columns, rows)])
    print(text)
    if args.out:
        H.write_report(args.out, TAG, text, rows)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
