"""Work-precision of the generated Taylor integrator against heyoka at its fastest (issues 11, 23).

Scenes: the planar n-link pendulum (unit masses and lengths, g = 9.81) for n in 1, 2, 3, 5 (10 in
the full run), every angle q_i = 0.1 or 1.0 rad at rest, t in [0, 10]. Error: max over the state
(angles and angular velocities) of |y(10) - ref(10)|, the reference from heyoka in long double
(80-bit) at tolerance 1e-19 (compact mode for n >= 5), checked against a second reference at
1e-17 (their difference is printed: errors below ~10x it are not resolved).

Contenders in one process, rounds interleaved (each round times every contender once per
tolerance, so load drift hits all alike; medians over the rounds):

* ``taylor``   lagcodegen ``simulate(method="taylor")``, rtol = atol = tol, outputs at t = 0, 5
               and 10 (its Python wrapper included);
* ``hy-lagr``  heyoka 7's ``taylor_adaptive`` on ``heyoka.lagrangian`` of the pendulum's
               Lagrangian (heyoka eliminates the mass matrix symbolically);
* ``hy-expl``  heyoka on the explicit system q'' = M^-1 F, M and F written out in closed form
               (M_ij = (n - max(i, j)) cos(q_i - q_j)) and M eliminated by hand (symbolic Gaussian
               elimination without pivoting: M is positive definite);
* ``taylor-m`` the same integrator called through its compiled module's own ``simulate`` (what
               ``simulate()`` calls after checking its inputs): the C run plus a thin wrapper,
               for the share of ``simulate()``'s Python layers (not a target contender);
* ``taylor-i`` the integrator object (``sim.integrator(method="taylor")``, created once per
               tolerance): state and time reset, ``propagate_until(10)``, as heyoka's runs are timed
               (issue 23's target there: at most 0.5x heyoka at n = 1);
* ``adams``    lagcodegen ``simulate(method="adams")`` (full run only).

Rounds: by default each round times one call of every contender at every tolerance in turn, so a
call runs after other contenders' calls, its caches and branch predictors cold (heyoka's compact JIT
code and short Python path suffer less from this than lagcodegen's longer path through Python and two
shared libraries); ``--repeat R`` times each by the median of R back-to-back calls instead (warm, as in
a loop of calls). Both are reported in the issue's notes.

Clock: ``--clock cpu`` (default) times each run by the CPU time of the calling thread
(``time.thread_time``), which a loaded machine's preemption does not inflate; ``--clock wall``
by ``time.perf_counter``. The output names the clock.

Both heyoka forms run in default mode for n <= 5 and in compact mode beyond (default mode's JIT
takes minutes there), tol = tol; timed: reset the state and the time, ``propagate_until(10)``.
The target of issue 23 is measured against the FASTER heyoka form at each error (the tables
name it): lagcodegen at most 0.7x heyoka for n <= 5 at errors 1e-4..1e-12, at most 0.4x for
n >= 10. Times are compared at EQUAL ACHIEVED ERROR: log time interpolated against log error
along each contender's tolerance sweep.

Beside the times: steps, microseconds per step and the operation counts of one order of the
jet (lagcodegen: the elementary operations of its decomposition plus the convolutions of the
mass matrix; heyoka: the length of ``taylor_adaptive.decomposition``). Build costs (gcc; heyoka's
JIT) are reported apart. A measuring instrument: it asserts nothing.

Outputs: the tables on stdout (progress on stderr); with --out DIR: taylor.txt, taylor.csv and
a PNG per case, taylor_n<N>_q<q0>.png.

Usage::

    python benchmarks/taylor.py [--quick] [--out DIR] [--ns 1,2,3] [--q0s 0.1,1.0] [--rounds R]
"""

from __future__ import annotations

import argparse
import collections
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _harness as H  # noqa: E402

import lagcodegen as lcg  # noqa: E402
from lagcodegen.solvers.taylor.run import taylor_module  # noqa: E402

T_END = 10.0
G = 9.81
TARGETS = (1e-4, 1e-6, 1e-8, 1e-10, 1e-12)
HEYOKA_FORMS = ("hy-lagr", "hy-expl")


def _pendulum_vars(n: int):
    import heyoka as hy
    return [hy.make_vars(f"q{k}") for k in range(n)], [hy.make_vars(f"v{k}") for k in range(n)]


def heyoka_lagrangian_system(n: int):
    """(system, permutation to (q, v) order) of heyoka.lagrangian on the pendulum's Lagrangian."""
    import heyoka as hy
    qs, vs = _pendulum_vars(n)
    x = y = xd = yd = hy.expression(0.0)
    T = V = hy.expression(0.0)
    for q, v in zip(qs, vs):
        x, y = x + hy.sin(q), y - hy.cos(q)
        xd, yd = xd + hy.cos(q) * v, yd + hy.sin(q) * v
        T = T + 0.5 * (xd * xd + yd * yd)
        V = V + G * y
    sys_ = hy.lagrangian(T - V, qs, vs)
    order = {str(lhs): k for k, (lhs, _) in enumerate(sys_)}
    return sys_, [order[f"q{k}"] for k in range(n)] + [order[f"v{k}"] for k in range(n)]


def heyoka_explicit_system(n: int):
    """(system, identity permutation) of q'' = M^-1 F in closed form: unit masses and lengths,
    M_ij = (n - max(i, j)) cos(q_i - q_j), F_i = -g (n - i) sin q_i - sum_j (n - max(i, j))
    sin(q_i - q_j) v_j^2 (0-based i), M eliminated symbolically (Gaussian elimination; M is
    positive definite, no pivoting)."""
    import heyoka as hy
    qs, vs = _pendulum_vars(n)

    def w(i, j):
        return float(n - max(i, j))

    A = [[hy.expression(w(i, i)) if i == j else w(i, j) * hy.cos(qs[i] - qs[j]) for j in range(n)] for i in range(n)]
    b = []
    for i in range(n):
        f = -G * float(n - i) * hy.sin(qs[i])
        for j in range(n):
            if j != i:
                f = f - w(i, j) * hy.sin(qs[i] - qs[j]) * (vs[j] * vs[j])
        b.append(f)
    acc = H.eliminate(A, b)
    return [(q, v) for q, v in zip(qs, vs)] + [(v, a) for v, a in zip(vs, acc)], list(range(2 * n))


def heyoka_integrator(form: str, n: int, tol: float, q0: float, fp_type=float, compact: bool = False):
    """(taylor_adaptive, permutation to (q, v)) of heyoka's ``form`` ("hy-lagr"/"hy-expl")."""
    import heyoka as hy
    sys_, perm = heyoka_lagrangian_system(n) if form == "hy-lagr" else heyoka_explicit_system(n)
    state = np.zeros(2 * n, dtype=fp_type)
    state[perm[:n]] = q0
    kw = dict(tol=fp_type(tol)) if tol else {}
    ta = hy.taylor_adaptive(sys_, list(state) if fp_type is not float else state, fp_type=fp_type,
                            compact_mode=compact, **kw)
    return ta, perm


def reference(n: int, q0: float, tol: float) -> np.ndarray:
    ta, perm = heyoka_integrator("hy-lagr", n, tol, q0, np.longdouble, compact=n >= 5)
    ta.propagate_until(np.longdouble(T_END))
    return np.array(ta.state[perm], dtype=np.longdouble)


def our_operations(sim) -> dict:
    """Operations of one order of lagcodegen's jet: counts by kind, convolutions of M."""
    d = taylor_module(sim).decomposition
    kinds = collections.Counter(op.kind for op in d.ops)
    conv = sum(1 for row in d.M for entry in row if isinstance(entry, int))
    text = " ".join(f"{k} {v}" for k, v in sorted(kinds.items()))
    return dict(ops=len(d.ops), conv=conv, kinds=text, cost=d.cost)


class Heyokas:
    """heyoka's integrators of one n, both forms, every tolerance: built once (their JIT is the
    expensive part), reset for each state."""

    def __init__(self, n: int, tols):
        self.compact = n > 5
        self.by = {}
        self.jit = {}
        self.size = {}
        for form in HEYOKA_FORMS:
            start = time.perf_counter()
            for tol in tols:
                self.by[(form, tol)] = heyoka_integrator(form, n, tol, 0.0, compact=self.compact)
            self.jit[form] = (time.perf_counter() - start) / len(tols)
            self.size[form] = len(self.by[(form, tols[0])][0].decomposition)

    def runner(self, form: str, tol: float, n: int, q0: float):
        ta, perm = self.by[(form, tol)]
        state0 = np.zeros(2 * n)
        state0[perm[:n]] = q0

        def run():
            ta.time = 0.0
            ta.state[:] = state0
            outcome = ta.propagate_until(T_END)
            return lambda: (np.array(ta.state)[perm], outcome[3])  # read after the timing
        return run


def run_case(n: int, q0: float, tols, rounds: int, heyokas: Heyokas, sim, with_adams: bool,
             out: Path | None, clock=time.thread_time, repeat: int = 1) -> tuple[list, list]:
    H.progress("taylor", f"n = {n}, q0 = {q0}: references")
    ref = reference(n, q0, 1e-19)
    ref_unc = float(np.max(np.abs(ref - reference(n, q0, 1e-17))))
    t = np.array([0.0, T_END / 2, T_END])
    y0 = np.concatenate([np.full(n, q0), np.zeros(n)])

    def lcg_runner(method, tol):
        def run():
            res = sim.simulate(t, y0=y0, method=method, rtol=tol, atol=tol, raise_on_error=False)
            return lambda: ((res.y[-1] if res.success else None), res.stats.get("steps"))  # read after the timing
        return run

    tm = taylor_module(sim)
    p = np.array(sim.code.scene.default_parameters(), dtype=float)

    def module_runner(tol):
        def run():
            res = tm.simulate(t, y0, p, rtol=tol, atol=tol)
            return lambda: ((res.y[-1] if res.status == 0 else None), res.stats.get("steps"))
        return run

    integrators = {}

    def integrator_runner(tol):
        integ = integrators[tol] = sim.integrator(y0=y0, method="taylor", rtol=tol, atol=tol)

        def run():
            integ.time = 0.0
            integ.state[:] = y0
            integ.propagate_until(T_END)
            return lambda: (integ.state.copy(), integ.stats.get("steps"))
        return run

    contenders = {"taylor": lambda tol: lcg_runner("taylor", tol), "taylor-m": module_runner,
                  "taylor-i": integrator_runner}
    if with_adams:
        contenders["adams"] = lambda tol: lcg_runner("adams", tol)
    for form in HEYOKA_FORMS:
        contenders[form] = lambda tol, form=form: heyokas.runner(form, tol, n, q0)
    runs = {(c, tol): make(tol) for c, make in contenders.items() for tol in tols}
    for run in runs.values():  # warm-up (first calls allocate)
        run()
    H.progress("taylor", f"n = {n}, q0 = {q0}: {rounds} rounds")
    times = {key: [] for key in runs}
    results = {}
    for _ in range(rounds):
        for tol in tols:
            for name in contenders:
                run = runs[(name, tol)]
                batch = []
                for _ in range(repeat):  # repeat > 1: the median of back-to-back calls (warm caches)
                    start = clock()
                    results[(name, tol)] = run()
                    batch.append(clock() - start)
                times[(name, tol)].append(float(np.median(batch)))
    rows = []
    for name in contenders:
        for tol in tols:
            state, steps = results[(name, tol)]()
            err = float(np.max(np.abs(np.asarray(state, dtype=np.longdouble) - ref))) if state is not None \
                else float("nan")
            sec = float(np.median(times[(name, tol)]))
            rows.append(dict(n=n, q0=q0, contender=name, tol=tol, error=err, seconds=sec, steps=steps,
                             us_per_step=1e6 * sec / steps if steps else None))
    curves = {name: [(r["error"], r["seconds"]) for r in rows if r["contender"] == name] for name in contenders}
    summary = []
    for target in TARGETS:
        at = {name: H.time_at(curves[name], target)[0] for name in contenders}
        hy = {form: at[form] for form in HEYOKA_FORMS if at[form]}
        faster = min(hy, key=hy.get) if hy else None
        row = dict(n=n, q0=q0, target=target, taylor=at["taylor"], hy_lagr=at["hy-lagr"], hy_expl=at["hy-expl"],
                   faster=faster, ratio=at["taylor"] / hy[faster] if at["taylor"] and faster else None,
                   taylor_m=at["taylor-m"], ratio_m=at["taylor-m"] / hy[faster] if at["taylor-m"] and faster else None,
                   taylor_i=at["taylor-i"], ratio_i=at["taylor-i"] / hy[faster] if at["taylor-i"] and faster else None)
        if with_adams:
            row["adams"] = at["adams"]
        summary.append(row)
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        H.work_precision_plot(out / f"taylor_n{n}_q{q0}.png", f"{n}-link pendulum, q0 = {q0}, t in [0, 10]",
                              curves, "max |error| of the final state", ref_unc)
    for r in summary:
        r["ref_unc"] = ref_unc
    return rows, summary


def ratio_grid(summaries, key: str = "ratio") -> str:
    """The issue's table: lagcodegen / faster heyoka at equal achieved error, by n, state, error."""
    head = "| n | state | " + " | ".join(f"{t:.0e}" for t in TARGETS) + " |"
    lines = [head, "|" + "---|" * (2 + len(TARGETS))]
    keys = sorted({(s["n"], s["q0"]) for s in summaries})
    for n, q0 in keys:
        cells = []
        for target in TARGETS:
            s = next((s for s in summaries if (s["n"], s["q0"], s["target"]) == (n, q0, target)), None)
            cells.append("-" if s is None or s[key] is None else
                         f"{s[key]:.2f} ({'L' if s['faster'] == 'hy-lagr' else 'E'})")
        lines.append(f"| {n} | q = {q0} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


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
    ap.add_argument("--quick", action="store_true", help="n = 1, 2, 3; q0 = 1.0; 3 tolerances; 3 rounds; no Adams")
    ap.add_argument("--out", type=Path)
    ap.add_argument("--ns", default=None, help="comma-separated n (default 1,2,3,5,10)")
    ap.add_argument("--q0s", default=None, help="comma-separated initial angles (default 0.1,1.0)")
    ap.add_argument("--tols", default=None, help="comma-separated tolerances (default 1e-2..1e-13: both "
                    "integrators reach an error of 1e-4 only from tolerances looser than 1e-4)")
    ap.add_argument("--rounds", type=int, default=None)
    ap.add_argument("--no-adams", action="store_true", help="leave CVODE Adams out of the full run")
    ap.add_argument("--repeat", type=int, default=1,
                    help="time each contender by the median of this many back-to-back calls within a round (default "
                    "1: one call between other contenders' calls, caches and branch predictors cold; more: warm, as "
                    "in a loop of calls)")
    ap.add_argument("--clock", choices=("cpu", "wall"), default="cpu",
                    help="time runs by the calling thread's CPU time (default) or by wall time")
    args = ap.parse_args(argv)
    clock = time.thread_time if args.clock == "cpu" else time.perf_counter
    ns = [int(x) for x in args.ns.split(",")] if args.ns else ([1, 2, 3] if args.quick else [1, 2, 3, 5, 10])
    q0s = [float(x) for x in args.q0s.split(",")] if args.q0s else ([1.0] if args.quick else [0.1, 1.0])
    tols = ([float(x) for x in args.tols.split(",")] if args.tols else
            [1e-4, 1e-8, 1e-12] if args.quick else [10.0 ** -k for k in range(2, 14)])
    rounds = args.rounds or (3 if args.quick else 7)
    with_adams = not (args.quick or args.no_adams)
    load0 = H.load_average()
    all_rows, summaries, builds, ops = [], [], [], []
    for n in ns:
        with tempfile.TemporaryDirectory() as cold, H.cache_at(Path(cold)):
            H.progress("taylor", f"n = {n}: builds")
            start = time.perf_counter()
            sim = lcg.compile_model(lcg.systems.n_link_pendulum(n, name=f"tb{n}"))
            build_cvode = time.perf_counter() - start
            start = time.perf_counter()
            sim.simulate(np.array([0.0, 1e-3]), y0=np.zeros(2 * n), method="taylor")  # builds the Taylor module
            build_taylor = time.perf_counter() - start
            heyokas = Heyokas(n, tols)
            ours = our_operations(sim)
            for q0 in q0s:
                rows, summary = run_case(n, q0, tols, rounds, heyokas, sim, with_adams, args.out, clock,
                                         max(1, args.repeat))
                all_rows += rows
                summaries += summary
        builds.append(dict(n=n, gcc_cvode=build_cvode, gcc_taylor=build_taylor, jit_lagr=heyokas.jit["hy-lagr"],
                           jit_expl=heyokas.jit["hy-expl"], mode="compact" if heyokas.compact else "default"))
        ops.append(dict(n=n, ours=ours["ops"] + ours["conv"], ops=ours["ops"], conv=ours["conv"], kinds=ours["kinds"],
                        hy_lagr=heyokas.size["hy-lagr"], hy_expl=heyokas.size["hy-expl"]))
    load1 = H.load_average()
    lines = H.machine_lines("benchmarks/taylor.py: lagcodegen's Taylor integrator vs heyoka (both forms)",
                            (load0, load1))
    clock_text = "CPU time of the calling thread" if args.clock == "cpu" else "wall time"
    warm = f", each round's time the median of {args.repeat} back-to-back calls" if args.repeat > 1 else \
        ", one call per contender and tolerance per round"
    lines += [f"clock:    {clock_text}; medians over {rounds} interleaved rounds{warm}",
              "", "runs (median time over interleaved rounds; error: max |y(10) - ref(10)| over the state)",
              H.format_table([("n", "n", "{}"), ("q0", "q0", "{}"), ("contender", "contender", "{}"),
                              ("tol", "tol", "{:.0e}"), ("error", "error", "{:.2e}"), ("seconds", "time [s]", "{:.3e}"),
                              ("steps", "steps", "{}"), ("us_per_step", "us/step", "{:.3f}")], all_rows),
              "", "operations per order of the jet (lagcodegen: elementary operations + convolutions of M;"
              " heyoka: len(taylor_adaptive.decomposition))",
              H.format_table([("n", "n", "{}"), ("ours", "lagcodegen", "{}"), ("ops", "ops", "{}"),
                              ("conv", "M conv.", "{}"), ("kinds", "kinds", "{}"), ("hy_lagr", "hy-lagr", "{}"),
                              ("hy_expl", "hy-expl", "{}")], ops),
              "", "time at equal achieved error (log-log interpolation); ratio = taylor / the faster heyoka form",
              H.format_table([("n", "n", "{}"), ("q0", "q0", "{}"), ("target", "error", "{:.0e}"),
                              ("taylor", "taylor [s]", "{:.2e}"), ("hy_lagr", "hy-lagr [s]", "{:.2e}"),
                              ("hy_expl", "hy-expl [s]", "{:.2e}")]
                             + ([("adams", "adams [s]", "{:.2e}")] if with_adams else [])
                             + [("faster", "faster heyoka", "{}"), ("ratio", "taylor/faster", "{:.2f}"),
                                ("ratio_m", "taylor-m/faster", "{:.2f}"), ("ratio_i", "taylor-i/faster", "{:.2f}"),
                                ("ref_unc", "ref. unc.", "{:.1e}")], summaries),
              "", "the target table: taylor / faster heyoka form at equal achieved error "
              "(L: hy.lagrangian faster, E: explicit form faster; target <= 0.7 for n <= 5, <= 0.4 beyond)",
              ratio_grid(summaries),
              "", "the same through the compiled module's own simulate (taylor-m: C run + thin wrapper)",
              ratio_grid(summaries, "ratio_m"),
              "", "through the integrator object (taylor-i: state and time reset, propagate_until(10), as heyoka's "
              "runs; target <= 0.5 at n = 1)",
              ratio_grid(summaries, "ratio_i"),
              "", "build cost (cold gcc builds; heyoka's JIT per integrator, mean over the tolerances)",
              H.format_table([("n", "n", "{}"), ("gcc_cvode", "gcc CVODE [s]", "{:.2f}"),
                              ("gcc_taylor", "gcc Taylor [s]", "{:.2f}"), ("mode", "heyoka mode", "{}"),
                              ("jit_lagr", "JIT hy-lagr [s]", "{:.2f}"), ("jit_expl", "JIT hy-expl [s]", "{:.2f}")],
                             builds)]
    if not args.quick:
        drift = energy_drift(10000, 1e-10)
        lines += ["", "energy drift of the pendulum (q0 = 1 rad) over many periods, rtol = atol = 1e-10",
                  H.format_table([("method", "method", "{}"), ("periods", "periods", "{}"),
                                  ("drift", "rel. drift", "{:.2e}"), ("steps", "steps", "{}"),
                                  ("seconds", "time [s]", "{:.3f}")], drift)]
    text = "\n".join(lines)
    print(text)
    if args.out is not None:
        H.write_report(args.out, "taylor", text, all_rows + summaries + builds + ops)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
