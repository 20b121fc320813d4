"""Work-precision of the generated Taylor integrator against heyoka and CVODE Adams (issue 11).

Scenes: the planar n-link pendulum (unit masses and lengths, g = 9.81) for n in 1, 2, 3, 5, 10,
20, every angle q_i = 0.1 or 1.0 rad at rest, t in [0, 10]. Error: max over the state (angles
and angular velocities) of |y(10) - ref(10)|, the reference from heyoka in long double
(80-bit) at tolerance 1e-19 (compact mode for n >= 5), checked against a second reference at
1e-17 (their difference is printed: errors below ~10x it are not resolved).

Contenders in one run, rounds interleaved (each round times every contender once per
tolerance, so load drift hits all alike; medians over the rounds):

* ``taylor``  lagcodegen ``simulate(method="taylor")``, rtol = atol = tol;
* ``adams``   lagcodegen ``simulate(method="adams")`` (native CVODE, generated Jacobian up to
              n = 8), rtol = atol = tol;
* ``heyoka``  heyoka 7's ``taylor_adaptive`` on ``heyoka.lagrangian`` of the same Lagrangian,
              tol = tol (compact mode for n >= 10, as its JIT takes seconds otherwise);
              timed: reset the state, ``propagate_until(10)``.

Both lagcodegen contenders return the state at t = 0, 5 and 10 through ``simulate()`` (its
Python wrapper included); heyoka integrates to t = 10 only. Build costs are reported apart:
gcc (a cold build of the Taylor module and of the CVODE module) and heyoka's JIT (construction
of the integrator). Targets (issue 11): taylor <= 1.0x heyoka for n <= 5 at errors 1e-6..1e-12;
the best lagcodegen method <= 0.5x heyoka for n >= 10; taylor >= 3x faster than Adams at
n <= 5, errors <= 1e-8.

Outputs: the tables on stdout (progress on stderr); with --out DIR: taylor.txt, taylor.csv and
a PNG per case, taylor_n<N>_q<q0>.png. A measuring instrument: it asserts nothing.

Usage::

    python benchmarks/taylor.py [--quick] [--out DIR] [--ns 1,2,3] [--rounds R]
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _harness as H  # noqa: E402

import lagcodegen as lcg  # noqa: E402

T_END = 10.0
G = 9.81


def heyoka_pendulum(n: int, fp_type=float, tol: float = 0.0, compact: bool = False, q0: float = 0.1):
    """heyoka's integrator of the n-link pendulum (Lagrangian -> heyoka.lagrangian), state
    ordered (q_1..q_n, v_1..v_n) as lagcodegen's."""
    import heyoka as hy
    qs = [hy.make_vars(f"q{k}") for k in range(n)]
    vs = [hy.make_vars(f"v{k}") for k in range(n)]
    x = y = xd = yd = hy.expression(0.0)
    T = V = hy.expression(0.0)
    for q, v in zip(qs, vs):
        x, y = x + hy.sin(q), y - hy.cos(q)
        xd, yd = xd + hy.cos(q) * v, yd + hy.sin(q) * v
        T = T + 0.5 * (xd * xd + yd * yd)
        V = V + G * y
    sys_ = hy.lagrangian(T - V, qs, vs)
    order = {str(lhs): k for k, (lhs, _) in enumerate(sys_)}
    perm = [order[f"q{k}"] for k in range(n)] + [order[f"v{k}"] for k in range(n)]
    state = np.zeros(2 * n, dtype=fp_type)
    state[perm[:n]] = q0
    kw = dict(tol=fp_type(tol)) if tol else {}
    ta = hy.taylor_adaptive(sys_, list(state) if fp_type is not float else state, fp_type=fp_type,
                            compact_mode=compact, **kw)
    return ta, perm


def reference(n: int, q0: float, tol: float) -> np.ndarray:
    ta, perm = heyoka_pendulum(n, np.longdouble, tol, compact=n >= 5, q0=q0)
    ta.propagate_until(np.longdouble(T_END))
    return np.array(ta.state[perm], dtype=np.longdouble)


def run_case(n: int, q0: float, tols, rounds: int, out: Path | None) -> list[dict]:
    H.progress("taylor", f"n = {n}, q0 = {q0}: references")
    ref = reference(n, q0, 1e-19)
    ref_unc = float(np.max(np.abs(ref - reference(n, q0, 1e-17))))
    model = lcg.systems.n_link_pendulum(n, name=f"tb{n}")
    t = np.array([0.0, T_END / 2, T_END])
    y0 = np.concatenate([np.full(n, q0), np.zeros(n)])

    with tempfile.TemporaryDirectory() as cold, H.cache_at(Path(cold)):
        start = time.perf_counter()
        sim = lcg.compile_model(model)
        build_cvode = time.perf_counter() - start
        start = time.perf_counter()
        sim.simulate(t, y0=y0, method="taylor")  # builds the Taylor module
        build_taylor = time.perf_counter() - start

        compact = n >= 10
        start = time.perf_counter()
        hy_ta, perm = heyoka_pendulum(n, float, 1e-8, compact=compact, q0=q0)
        jit = time.perf_counter() - start
        hy_by_tol = {}
        for tol in tols:
            hy_by_tol[tol] = heyoka_pendulum(n, float, tol, compact=compact, q0=q0)[0]
        hy_state0 = np.array(hy_ta.state)

        def lcg_run(method, tol):
            res = sim.simulate(t, y0=y0, method=method, rtol=tol, atol=tol, raise_on_error=False)
            return res.y[-1] if res.success else None, res.stats.get("steps")

        def hy_run(tol):
            ta = hy_by_tol[tol]
            ta.time = 0.0
            ta.state[:] = hy_state0
            outcome = ta.propagate_until(T_END)
            return np.array(ta.state)[perm], outcome[3]

        contenders = {
            "taylor": lambda tol: lcg_run("taylor", tol),
            "adams": lambda tol: lcg_run("adams", tol),
            "heyoka": hy_run,
        }
        times = {(c, tol): [] for c in contenders for tol in tols}
        results = {}
        for r in range(rounds):
            for tol in tols:
                for name, fn in contenders.items():
                    start = time.perf_counter()
                    state, steps = fn(tol)
                    times[(name, tol)].append(time.perf_counter() - start)
                    results[(name, tol)] = (state, steps)
        rows = []
        for name in contenders:
            for tol in tols:
                state, steps = results[(name, tol)]
                err = float(np.max(np.abs(np.asarray(state, dtype=np.longdouble) - ref))) if state is not None \
                    else float("nan")
                sec = float(np.median(times[(name, tol)]))
                rows.append(dict(n=n, q0=q0, contender=name, tol=tol, error=err, seconds=sec, steps=steps,
                                 us_per_step=1e6 * sec / steps if steps else None))
    curves = {name: [(r["error"], r["seconds"]) for r in rows if r["contender"] == name] for name in contenders}
    summary = []
    for target in (1e-4, 1e-6, 1e-8, 1e-10, 1e-12):
        at = {name: H.time_at(curves[name], target)[0] for name in contenders}
        best = min((v for k, v in at.items() if k != "heyoka" and v), default=None)
        summary.append(dict(n=n, q0=q0, target=target, taylor=at["taylor"], adams=at["adams"], heyoka=at["heyoka"],
                            taylor_vs_heyoka=at["taylor"] / at["heyoka"] if at["taylor"] and at["heyoka"] else None,
                            best_vs_heyoka=best / at["heyoka"] if best and at["heyoka"] else None,
                            adams_vs_taylor=at["adams"] / at["taylor"] if at["adams"] and at["taylor"] else None))
    builds = dict(n=n, q0=q0, gcc_cvode=build_cvode, gcc_taylor=build_taylor, heyoka_jit=jit, ref_unc=ref_unc)
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        H.work_precision_plot(out / f"taylor_n{n}_q{q0}.png",
                              f"{n}-link pendulum, q0 = {q0}, t in [0, 10] (gcc {build_taylor:.2f} s, "
                              f"heyoka JIT {jit:.2f} s)", {k: v for k, v in curves.items()},
                              "max |error| of the final state", ref_unc)
    return rows, summary, builds


def energy_drift(periods: int, tol: float) -> list[dict]:
    """Relative energy drift of the simple pendulum (q0 = 1 rad, l = 1, g = 9.81) over
    ``periods`` periods, Taylor beside Adams at the same tolerance (builds excluded)."""
    from scipy.special import ellipk
    sim = lcg.compile_model(lcg.systems.pendulum(), outputs=["energy"])
    period = 4 * math.sqrt(1.0 / G) * ellipk(math.sin(0.5) ** 2)  # 2.138 s
    t = np.linspace(0.0, periods * period, 2001)
    rows = []
    for method in ("taylor", "adams"):
        sim.simulate(t[:3], q0=[1.0], method=method)  # builds the Taylor module
        start = time.perf_counter()
        res = sim.simulate(t, q0=[1.0], method=method, rtol=tol, atol=tol, max_steps=10**9)
        rows.append(dict(method=method, periods=periods, tol=tol, drift=res.drift("energy"),
                         steps=res.stats["steps"], seconds=time.perf_counter() - start))
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="n = 1, 2, 3; q0 = 1.0; 3 tolerances; 3 rounds")
    ap.add_argument("--out", type=Path)
    ap.add_argument("--ns", default=None, help="comma-separated n (default 1,2,3,5,10,20)")
    ap.add_argument("--rounds", type=int, default=None)
    args = ap.parse_args(argv)
    ns = [int(x) for x in args.ns.split(",")] if args.ns else ([1, 2, 3] if args.quick else [1, 2, 3, 5, 10, 20])
    q0s = [1.0] if args.quick else [0.1, 1.0]
    tols = [1e-5, 1e-8, 1e-11] if args.quick else [10.0 ** -k for k in range(4, 14)]
    rounds = args.rounds or (3 if args.quick else 7)
    load0 = H.load_average()
    all_rows, summaries, builds = [], [], []
    for n in ns:
        for q0 in q0s:
            rows, summary, build = run_case(n, q0, tols, rounds, args.out)
            all_rows += rows
            summaries += summary
            builds.append(build)
    lines = H.machine_lines("benchmarks/taylor.py: Taylor vs heyoka vs Adams", (load0, H.load_average()))
    lines += ["", "runs (median wall time over rounds; error: max |y(10) - ref(10)| over the state)",
              H.format_table([("n", "n", "{}"), ("q0", "q0", "{}"), ("contender", "contender", "{}"),
                              ("tol", "tol", "{:.0e}"), ("error", "error", "{:.2e}"), ("seconds", "time [s]", "{:.3e}"),
                              ("steps", "steps", "{}"), ("us_per_step", "us/step", "{:.3f}")], all_rows),
              "", "time at equal achieved error (log-log interpolation; ratios < 1: the first is faster)",
              H.format_table([("n", "n", "{}"), ("q0", "q0", "{}"), ("target", "error", "{:.0e}"),
                              ("taylor", "taylor [s]", "{:.2e}"), ("adams", "adams [s]", "{:.2e}"),
                              ("heyoka", "heyoka [s]", "{:.2e}"), ("taylor_vs_heyoka", "taylor/heyoka", "{:.2f}"),
                              ("best_vs_heyoka", "best/heyoka", "{:.2f}"), ("adams_vs_taylor", "adams/taylor", "{:.1f}")],
                             summaries),
              "", "build cost (cold gcc builds; heyoka's JIT at construction), reference uncertainty",
              H.format_table([("n", "n", "{}"), ("q0", "q0", "{}"), ("gcc_cvode", "gcc CVODE [s]", "{:.2f}"),
                              ("gcc_taylor", "gcc Taylor [s]", "{:.2f}"), ("heyoka_jit", "heyoka JIT [s]", "{:.2f}"),
                              ("ref_unc", "ref. unc.", "{:.1e}")], builds)]
    drift = energy_drift(1000 if args.quick else 10000, 1e-10)
    lines += ["", "energy drift of the pendulum (q0 = 1 rad) over many periods, rtol = atol = 1e-10",
              H.format_table([("method", "method", "{}"), ("periods", "periods", "{}"), ("drift", "rel. drift", "{:.2e}"),
                              ("steps", "steps", "{}"), ("seconds", "time [s]", "{:.3f}")], drift)]
    text = "\n".join(lines)
    print(text)
    if args.out is not None:
        H.write_report(args.out, "taylor", text, all_rows + summaries + builds)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
