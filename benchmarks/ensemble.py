"""Ensembles: per-member cost of one ensemble call (1 and 2 threads) against a Python loop over
simulate() and against heyoka's ensemble_propagate_until at equal achieved error; Dask
LocalCluster throughput; peak memory of a large ensemble (issue 12).

Members: pendulums (l = m = 1) with random g in [9.7, 9.9] and q0 in [0.1, 2.5] (at rest),
t in [0, 10], CVODE Adams at rtol 1e-8 (atol 1e-10).

1. Loop, 1 thread, 2 threads: rounds interleaved, medians reported. The Python overhead per
   member is the ensemble's wall time minus the members' own C time (summed, 1 thread), over N.
2. heyoka (``taylor_adaptive`` of theta'' = -g sin(theta), g a runtime parameter) through
   ``heyoka.ensemble_propagate_until`` (its thread pool, max_workers 1 and 2) on the same members.
   Equal error: the final-state error of every member (max over theta, theta') against a tight
   reference (heyoka at tol = eps) on the first ``--calib`` members; heyoka's tolerance is the
   largest of 1e-5 ... 1e-13 whose median error is at most the Adams run's. The generated Taylor
   method's ensemble (``method="taylor"``) is calibrated the same way and shown beside them, and
   so is one heyoka integrator reused member after member in a Python loop (heyoka's ensemble
   copies the integrator for every member).
3. Dask: a ``LocalCluster`` of 2 worker processes x 1 thread against the threaded call (2 threads)
   on the same ``--dask-n`` members (default 1e5; --quick 1e4); the chunk size is reported. The
   workers' one-off rebuild of the module (warm-up) is timed apart.
4. Memory: an ensemble of ``--mem-n`` members (default 1e6; --quick 1e5) keeping final states, in a
   fresh process started first: peak RSS before and after the call (VmHWM, and resource.getrusage,
   whose ru_maxrss Linux seeds with the parent's peak across fork and exec). The horizon there is
   t in [0, 0.1]: with save="final" the memory does not depend on it, and 1e6 members to t = 10
   would take minutes.

    python benchmarks/ensemble.py [--quick] [--out DIR] [--n N] [--rounds R] [--dask-n N] [--mem-n N]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _harness as H  # noqa: E402

import lagcodegen as lcg  # noqa: E402
from lagcodegen import systems  # noqa: E402

T = (0.0, 10.0)
OPTS = dict(rtol=1e-8, atol=1e-10)
HEYOKA_TOLS = [10.0 ** -k for k in range(5, 14)]
TAYLOR_RTOLS = [10.0 ** -k for k in range(6, 14)]


def members(n: int, seed: int = 1):
    rng = np.random.default_rng(seed)
    return rng.uniform(0.1, 2.5, (n, 1)), rng.uniform(9.7, 9.9, n)


def compile_pendulum():
    return lcg.compile_model(systems.pendulum(), outputs=["energy"], prefix="bench_ens_pendulum")


# ---------------------------------------------------------------------- heyoka
def heyoka_integrator(tol: float | None):
    import heyoka as hy
    th, om = hy.make_vars("th", "om")
    kw = {} if tol is None else {"tol": tol}
    return hy.taylor_adaptive([(th, om), (om, -hy.par[0] * hy.sin(th))], [0.0, 0.0], pars=[9.81], **kw)


def heyoka_ensemble(ta, q0, g, workers: int) -> np.ndarray:
    """Final states (N, 2) of heyoka.ensemble_propagate_until over the members."""
    import heyoka as hy

    def gen(tc, i):
        tc.time = T[0]
        tc.state[:] = (q0[i, 0], 0.0)
        tc.pars[0] = g[i]
        return tc

    out = hy.ensemble_propagate_until(ta, T[1], len(g), gen, max_workers=workers)
    bad = [r[1] for r in out if r[1] != hy.taylor_outcome.time_limit]
    if bad:
        raise RuntimeError(f"heyoka: {len(bad)} members did not reach t = {T[1]} ({bad[0]})")
    return np.array([r[0].state for r in out])


def heyoka_loop(ta, q0, g) -> np.ndarray:
    """Final states of one heyoka integrator reused member after member (a Python loop): heyoka's
    integration cost without the per-member copy of the integrator that its ensemble makes."""
    out = np.empty((len(g), 2))
    for i in range(len(g)):
        ta.time = T[0]
        ta.state[:] = (q0[i, 0], 0.0)
        ta.pars[0] = g[i]
        ta.propagate_until(T[1])
        out[i] = ta.state
    return out


def errors(final: np.ndarray, ref: np.ndarray) -> np.ndarray:
    return np.max(np.abs(final - ref), axis=1)


def equal_error(args, cm, q0, g, adams_err_median: float, ref: np.ndarray) -> dict:
    """heyoka's tolerance and the Taylor ensemble's rtol whose median error is at most Adams's."""
    nc = len(ref)
    rows = {"heyoka": [], "taylor": []}
    for tol in HEYOKA_TOLS:
        ta = heyoka_integrator(tol)
        err = errors(heyoka_ensemble(ta, q0[:nc], g[:nc], 2), ref)
        rows["heyoka"].append((tol, float(np.median(err)), float(np.max(err)), ta))
    for rtol in TAYLOR_RTOLS:
        e = cm.ensemble(T, q0=q0[:nc], params={"g": g[:nc]}, method="taylor", rtol=rtol, atol=rtol, threads=2,
                        progress=False)
        err = errors(e.y, ref)
        rows["taylor"].append((rtol, float(np.median(err)), float(np.max(err)), None))
    chosen = {}
    for name, cands in rows.items():
        ok = [c for c in cands if c[1] <= adams_err_median]
        chosen[name] = max(ok, key=lambda c: c[0]) if ok else min(cands, key=lambda c: c[1])
    H.progress("ensemble", "calibration (tol: median error): " + "; ".join(
        f"{k} " + ", ".join(f"{c[0]:.0e}: {c[1]:.1e}" for c in v) for k, v in rows.items()))
    return chosen


# ---------------------------------------------------------------------- memory (a fresh process)
def vm_hwm_mb() -> float:
    """Peak resident set of this process's own address space (VmHWM), MB."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024
    return float("nan")


def memory_child(n: int) -> dict:
    """Linux keeps, across fork and exec, the parent's peak in getrusage's ru_maxrss (the mm the
    exec replaced counts): the child reports it and VmHWM, which starts afresh at exec."""
    cm = compile_pendulum()
    q0, g = members(n, seed=2)
    cm.ensemble((0.0, 0.1), q0=q0[:10], params={"g": g[:10]}, **OPTS)
    base, base_ru = vm_hwm_mb(), resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    start = time.perf_counter()
    e = cm.ensemble((0.0, 0.1), q0=q0, params={"g": g}, save="final", progress=False, **OPTS)
    wall = time.perf_counter() - start
    peak, peak_ru = vm_hwm_mb(), resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    result_mb = (e.final.nbytes + e.status.nbytes + e.t_reached.nbytes + e.nt_done.nbytes
                 + sum(v.nbytes for v in e.stats.values())) / 2 ** 20
    return dict(n=n, base_mb=base, peak_mb=peak, base_ru_mb=base_ru, peak_ru_mb=peak_ru, wall=wall, result_mb=result_mb, inputs_mb=(q0.nbytes + g.nbytes) / 2 ** 20,
                ok=int(np.count_nonzero(e.status == 0)), y_shape=list(e.y.shape))


def run_memory(n: int) -> dict:
    env = dict(os.environ)
    proc = subprocess.run([sys.executable, __file__, "--memory-child", str(n)], capture_output=True, text=True,
                          env=env, timeout=3600)
    if proc.returncode != 0:
        raise RuntimeError(f"memory check failed:\n{proc.stderr}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


# ---------------------------------------------------------------------- main
def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer members (< 2 min)")
    ap.add_argument("--out", type=Path, help="write ensemble.txt and ensemble.csv there")
    ap.add_argument("--n", type=int, help="members of the throughput rounds (default 10000, quick 2000)")
    ap.add_argument("--rounds", type=int, help="rounds (default 3)")
    ap.add_argument("--calib", type=int, help="members of the error calibration (default 500, quick 200)")
    ap.add_argument("--dask-n", type=int, help="members of the Dask comparison (default 100000, quick 10000; 0: skip)")
    ap.add_argument("--mem-n", type=int, help="members of the memory check (default 1000000, quick 100000; 0: skip)")
    ap.add_argument("--no-heyoka", action="store_true")
    ap.add_argument("--dask", action="store_true", help=argparse.SUPPRESS)  # the default now; kept for old scripts
    ap.add_argument("--memory-child", type=int, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.memory_child:
        print(json.dumps(memory_child(args.memory_child)))
        return 0
    n = args.n or (2000 if args.quick else 10_000)
    rounds = args.rounds or 3
    n_loop = min(n, 300 if args.quick else 1000)
    n_calib = min(n, args.calib or (200 if args.quick else 500))
    dask_n = (10_000 if args.quick else 100_000) if args.dask_n is None else args.dask_n
    mem_n = (100_000 if args.quick else 1_000_000) if args.mem_n is None else args.mem_n
    load_before = H.load_average()
    mem = None
    if mem_n:  # first, while this process is small (see memory_child)
        H.progress("ensemble", f"memory: {mem_n} members in a fresh process")
        mem = run_memory(mem_n)

    cm = compile_pendulum()
    q0, g = members(n)
    cm.ensemble(T, q0=q0[:10], params={"g": g[:10]}, **OPTS)  # warm up (module, thread pool code)

    # ------------------------------------------------------------------ error calibration
    hy_ta = hy_tol = tay_rtol = None
    calib = {}
    if not args.no_heyoka:
        H.progress("ensemble", f"reference (heyoka, tol = eps) and calibration on {n_calib} members")
        ref = heyoka_ensemble(heyoka_integrator(None), q0[:n_calib], g[:n_calib], 2)
        adams = cm.ensemble(T, q0=q0[:n_calib], params={"g": g[:n_calib]}, threads=2, progress=False, **OPTS)
        err = errors(adams.y, ref)
        calib["adams"] = (OPTS["rtol"], float(np.median(err)), float(np.max(err)))
        chosen = equal_error(args, cm, q0, g, calib["adams"][1], ref)
        hy_tol, hy_med, hy_max, hy_ta = chosen["heyoka"]
        tay_rtol, tay_med, tay_max, _ = chosen["taylor"]
        calib["heyoka"] = (hy_tol, hy_med, hy_max)
        calib["taylor"] = (tay_rtol, tay_med, tay_max)

    # ------------------------------------------------------------------ throughput rounds
    keys = ["loop", "threads1", "threads2", "overhead1"]
    if hy_ta is not None:
        keys += ["heyoka1", "heyoka2", "heyoka_loop", "taylor1", "taylor2"]
    times: dict[str, list] = {k: [] for k in keys}
    for r in range(rounds):
        H.progress("ensemble", f"round {r + 1}/{rounds}")
        start = time.perf_counter()
        for i in range(n_loop):
            cm.simulate(T, q0=q0[i], v0=[0.0], params={"g": g[i]}, **OPTS)
        times["loop"].append((time.perf_counter() - start) / n_loop)
        for th in (1, 2):
            start = time.perf_counter()
            e = cm.ensemble(T, q0=q0, params={"g": g}, threads=th, progress=False, **OPTS)
            wall = time.perf_counter() - start
            assert (e.status == 0).all()
            times[f"threads{th}"].append(wall / n)
            if th == 1:
                times["overhead1"].append((wall - float(e.stats["wall"].sum())) / n)
            if hy_ta is not None:
                start = time.perf_counter()
                heyoka_ensemble(hy_ta, q0, g, th)
                times[f"heyoka{th}"].append((time.perf_counter() - start) / n)
                if th == 1:
                    start = time.perf_counter()
                    heyoka_loop(hy_ta, q0, g)
                    times["heyoka_loop"].append((time.perf_counter() - start) / n)
                start = time.perf_counter()
                e = cm.ensemble(T, q0=q0, params={"g": g}, threads=th, progress=False, method="taylor",
                                rtol=tay_rtol, atol=tay_rtol)
                times[f"taylor{th}"].append((time.perf_counter() - start) / n)
                assert (e.status == 0).all()
    med = {k: statistics.median(v) for k, v in times.items()}
    steps = float(np.mean(cm.ensemble(T, q0=q0[:200], params={"g": g[:200]}, progress=False, **OPTS).stats["steps"]))

    # ------------------------------------------------------------------ Dask
    dask = None
    if dask_n:
        import distributed
        qd, gd = members(dask_n, seed=3)
        H.progress("ensemble", f"threaded call, {dask_n} members, 2 threads")
        start = time.perf_counter()
        e = cm.ensemble(T, q0=qd, params={"g": gd}, threads=2, progress=False, **OPTS)
        threaded = time.perf_counter() - start
        assert (e.status == 0).all()
        H.progress("ensemble", "dask LocalCluster 2 x 1")
        with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
                                      silence_logs=40) as cluster, distributed.Client(cluster) as client:
            start = time.perf_counter()
            cm.ensemble(T, q0=qd[:8], params={"g": gd[:8]}, executor=client, chunk_size=4, **OPTS)  # rebuild there
            warm = time.perf_counter() - start
            start = time.perf_counter()
            ed = cm.ensemble(T, q0=qd, params={"g": gd}, executor=client, **OPTS)
            dask_wall = time.perf_counter() - start
        assert (ed.status == 0).all() and np.array_equal(ed.y, e.y)
        dask = dict(n=dask_n, threaded=threaded, dask=dask_wall, chunk=ed.chunk_size, warm=warm,
                    chunks=-(-dask_n // ed.chunk_size))

    # ------------------------------------------------------------------ report
    def row(case, per, **extra):
        return {"case": case, "us_per_member": 1e6 * per, "members_per_s": 1 / per, "vs_loop": med["loop"] / per,
                **extra}

    rows = [row("python loop of simulate()", med["loop"]),
            row("ensemble, 1 thread", med["threads1"]),
            row("ensemble, 2 threads", med["threads2"])]
    if hy_ta is not None:
        rows += [row(f"heyoka ensemble_propagate_until tol {hy_tol:.0e}, 1 thread", med["heyoka1"]),
                 row(f"heyoka ensemble_propagate_until tol {hy_tol:.0e}, 2 threads", med["heyoka2"]),
                 row(f"heyoka one integrator reused, Python loop, tol {hy_tol:.0e}", med["heyoka_loop"]),
                 row(f"ensemble method=taylor rtol {tay_rtol:.0e}, 1 thread", med["taylor1"]),
                 row(f"ensemble method=taylor rtol {tay_rtol:.0e}, 2 threads", med["taylor2"])]
    if dask:
        rows += [{"case": f"threaded call 2 threads, {dask['n']} members", "us_per_member": 1e6 * dask["threaded"] / dask["n"],
                  "members_per_s": dask["n"] / dask["threaded"]},
                 {"case": f"dask LocalCluster 2x1, {dask['n']} members, chunks of {dask['chunk']}",
                  "us_per_member": 1e6 * dask["dask"] / dask["n"], "members_per_s": dask["n"] / dask["dask"]}]
    lines = [f"Ensemble of {n} pendulums (random g, q0), t in [0, 10], CVODE Adams rtol 1e-8 (atol 1e-10), "
             f"{steps:.0f} steps per member on average; medians of {rounds} interleaved rounds (loop: {n_loop} members).",
             f"Machine: {H.cpu_model()}, {os.cpu_count()} cores, load average {load_before} before, "
             f"{H.load_average()} after.", "",
             f"{'case':<58} {'us/member':>10} {'members/s':>11} {'vs loop':>8}"]
    for r_ in rows[: len(rows) - (2 if dask else 0)]:
        lines.append(f"{r_['case']:<58} {r_['us_per_member']:>10.1f} {r_['members_per_s']:>11.0f} {r_['vs_loop']:>8.2f}")
    lines += ["", f"2 threads vs 1 thread: {med['threads1'] / med['threads2']:.2f}x",
              f"Python overhead per member of the ensemble call (1 thread): {1e6 * med['overhead1']:.2f} us"]
    if hy_ta is not None:
        lines += ["", f"Equal error (final state vs heyoka at tol = eps, {n_calib} members; median / max of "
                      "max(|d theta|, |d theta'|)):"]
        for name, (tol, emed, emax) in calib.items():
            label = {"adams": "lagcodegen Adams rtol", "heyoka": "heyoka tol", "taylor": "lagcodegen taylor rtol"}[name]
            lines.append(f"  {label:<24} {tol:.0e}: {emed:.2e} / {emax:.2e}")
        lines += [f"Adams ensemble vs heyoka at equal error, members/s: {med['heyoka1'] / med['threads1']:.2f}x "
                  f"(1 thread), {med['heyoka2'] / med['threads2']:.2f}x (2 threads)",
                  f"Taylor ensemble vs heyoka at equal error, members/s: {med['heyoka1'] / med['taylor1']:.2f}x "
                  f"(1 thread), {med['heyoka2'] / med['taylor2']:.2f}x (2 threads)"]
    if dask:
        lines += ["", f"Dask LocalCluster (2 worker processes x 1 thread) on {dask['n']} members, "
                      f"{dask['chunks']} chunks of {dask['chunk']} (the default chunk size):",
                  f"  threaded call (2 threads): {dask['threaded']:.2f} s, {dask['n'] / dask['threaded']:.0f} members/s",
                  f"  dask:                      {dask['dask']:.2f} s, {dask['n'] / dask['dask']:.0f} members/s "
                  f"= {dask['threaded'] / dask['dask']:.2f}x the threaded call (results bit-identical)",
                  f"  workers' first call (module rebuilt from the sources): {dask['warm']:.2f} s, not counted"]
    if mem:
        lines += ["", f"Memory: {mem['n']} members, save='final', t in [0, 0.1], in a fresh process (started first): "
                      f"peak RSS {mem['peak_mb']:.0f} MB (VmHWM; {mem['base_mb']:.0f} MB before the call; inputs "
                      f"{mem['inputs_mb']:.0f} MB, result arrays {mem['result_mb']:.0f} MB); getrusage ru_maxrss "
                      f"{mem['peak_ru_mb']:.0f} MB ({mem['base_ru_mb']:.0f} MB before the call: Linux carries the "
                      f"parent's peak into a child's ru_maxrss); {mem['ok']} members succeeded in {mem['wall']:.1f} s"]
        rows.append({"case": f"memory, {mem['n']} members (save='final')", "peak_rss_mb": mem["peak_mb"],
                     "base_rss_mb": mem["base_mb"], "result_mb": mem["result_mb"]})
    text = "\n".join(lines)
    print(text)
    if args.out:
        H.write_report(args.out, "ensemble", text, rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
