"""Ensembles: per-member cost of one ensemble call (1 and 2 threads) against a Python loop over
simulate(), on pendulums with random g and q0, t in [0, 10], rtol 1e-8 (issue 12).

Rounds are interleaved (loop, 1 thread, 2 threads, [Dask], loop, ...) and medians reported. The
Python overhead per member is the ensemble's wall time minus the members' own C time (summed,
1 thread), divided by N. ``--dask`` adds a LocalCluster of 2 worker processes x 1 thread.

    python benchmarks/ensemble.py [--quick] [--out DIR] [--n N] [--dask]
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


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer members and rounds (< 2 min)")
    ap.add_argument("--out", type=Path)
    ap.add_argument("--n", type=int, help="members (default 10000, quick 2000)")
    ap.add_argument("--rounds", type=int, help="rounds (default 5, quick 3)")
    ap.add_argument("--dask", action="store_true", help="also a dask LocalCluster (2 processes x 1 thread)")
    args = ap.parse_args(argv)
    n = args.n or (2000 if args.quick else 10_000)
    rounds = args.rounds or (3 if args.quick else 5)
    n_loop = min(n, 300 if args.quick else 1000)

    cm = lcg.compile_model(systems.pendulum(), outputs=["energy"], prefix="bench_ens_pendulum")
    rng = np.random.default_rng(1)
    q0 = rng.uniform(0.1, 2.5, (n, 1))
    g = rng.uniform(9.7, 9.9, n)
    t = (0.0, 10.0)
    opts = dict(rtol=1e-8, atol=1e-10)
    cm.ensemble(t, q0=q0[:10], params={"g": g[:10]}, **opts)  # warm up (module, thread pool code)

    client = cluster = None
    if args.dask:
        import distributed
        cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                           dashboard_address=None, silence_logs=40)
        client = distributed.Client(cluster)
    chunk = max(1, n // 8)

    times: dict[str, list] = {"loop": [], "threads1": [], "threads2": [], "overhead1": []}
    if client is not None:
        times["dask"] = []
    for r in range(rounds):
        H.progress("ensemble", f"round {r + 1}/{rounds}")
        start = time.perf_counter()
        for i in range(n_loop):
            cm.simulate(t, q0=q0[i], v0=[0.0], params={"g": g[i]}, **opts)
        times["loop"].append((time.perf_counter() - start) / n_loop)
        for th in (1, 2):
            start = time.perf_counter()
            e = cm.ensemble(t, q0=q0, params={"g": g}, threads=th, progress=False, **opts)
            wall = time.perf_counter() - start
            assert (e.status == 0).all()
            times[f"threads{th}"].append(wall / n)
            if th == 1:
                times["overhead1"].append((wall - float(e.stats["wall"].sum())) / n)
        if client is not None:
            start = time.perf_counter()
            e = cm.ensemble(t, q0=q0, params={"g": g}, executor=client, chunk_size=chunk, **opts)
            times["dask"].append((time.perf_counter() - start) / n)
            assert (e.status == 0).all()
    if client is not None:
        client.close()
        cluster.close()

    med = {k: statistics.median(v) for k, v in times.items()}
    steps = float(np.mean(cm.ensemble(t, q0=q0[:200], params={"g": g[:200]}, **opts).stats["steps"]))
    rows = [
        {"case": "python loop of simulate()", "us_per_member": 1e6 * med["loop"], "members_per_s": 1 / med["loop"],
         "vs_loop": 1.0},
        {"case": "ensemble, 1 thread", "us_per_member": 1e6 * med["threads1"], "members_per_s": 1 / med["threads1"],
         "vs_loop": med["loop"] / med["threads1"]},
        {"case": "ensemble, 2 threads", "us_per_member": 1e6 * med["threads2"],
         "members_per_s": 1 / med["threads2"], "vs_loop": med["loop"] / med["threads2"]},
    ]
    if "dask" in med:
        rows.append({"case": f"dask LocalCluster 2x1, chunks of {chunk}", "us_per_member": 1e6 * med["dask"],
                     "members_per_s": 1 / med["dask"], "vs_loop": med["loop"] / med["dask"]})
    lines = [f"Ensemble of {n} pendulums (random g, q0), t in [0, 10], rtol 1e-8, {steps:.0f} steps per member on "
             f"average; medians of {rounds} interleaved rounds (loop: {n_loop} members).",
             f"Machine: {H.cpu_model()}, load average {H.load_average()}.", "",
             f"{'case':<40} {'us/member':>10} {'members/s':>11} {'vs loop':>8}"]
    for row in rows:
        lines.append(f"{row['case']:<40} {row['us_per_member']:>10.1f} {row['members_per_s']:>11.0f} "
                     f"{row['vs_loop']:>8.2f}")
    lines += ["", f"2 threads vs 1 thread: {med['threads1'] / med['threads2']:.2f}x",
              f"Python overhead per member of the ensemble call (1 thread): {1e6 * med['overhead1']:.2f} us"]
    text = "\n".join(lines)
    print(text)
    if args.out:
        H.write_report(args.out, "ensemble", text, rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
