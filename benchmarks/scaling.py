"""Scaling with the size of the model (issue 14): planar n-link pendulum chains, measured.

For n = 10, 20, 30, 50, 100 (quick: 10, 20) and three scenes, no Jacobian ("none": CVODE's
difference quotients), the expanded Jacobian (``Scene(jacobian_form="expanded")``, up to n = 30)
and the tangent-form Jacobian (``"tangent"``), each row is built in a fresh Python process
(the model never built before; the model-independent parts, built by an untimed warm-up row,
already in the cache) that reports:

* derive, generate (C code), build (``lagcodegen.build_code``: the model's C, the cffi module and
  the native driver) wall times, the compiler's CPU time (user + system of the
  build's children: less sensitive to other load on the machine than wall time) and its peak
  resident memory (ru_maxrss of the largest child), bytes of <prefix>.c;
* end to end: derive + generate + build + the first BDF run.

Then one process loads every row's module from its cache and measures, rounds interleaved over
the rows (medians): the wall time of a stiff-ish BDF run (CVODE BDF, dense solver, rtol 1e-8,
atol 1e-10, t in [0, 2], every link starting at 0.5 rad at rest; "none" uses difference
quotients) and the C call costs of rhs and jac through cffi (the call overhead, a fraction of a
microsecond, included). The fitted growth exponent of each quantity is the least-squares slope of
log(value) against log(n). A row whose predicted build time (from the smaller sizes of its scene)
exceeds ``--budget`` seconds is skipped and reported as such.

This is a measuring instrument: it asserts nothing about the numbers it reports.

Usage::

    python benchmarks/scaling.py [--quick] [--out DIR] [--sizes 10,20,...] [--rounds N] [--budget S]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _harness as H  # noqa: E402

TAG = "scaling"
FORMS = ("none", "expanded", "tangent")
#: The expanded Jacobian is built up to this many links (its generation and build grow fastest).
EXPANDED_MAX_N = 30
#: Issue 14's targets.
TARGET_E2E_NONE_N, TARGET_E2E_NONE_S = 50, 5.0
TARGET_JAC_N, TARGET_JAC_S, TARGET_JAC_MB, TARGET_RUN_RATIO = 30, 10.0, 500.0, 1.5

# One row, cold: runs in a fresh interpreter so that the import, the caches and the compilers'
# resource usage belong to this row alone.
_BUILD = r"""
import json, resource, sys, time
args = json.loads(sys.argv[1])
start = time.perf_counter()
import numpy as np
from lagcodegen import Scene, build_code, derive, generate_c, systems
t_import = time.perf_counter() - start
n, form = args["n"], args["form"]
start = time.perf_counter()
eom = derive(systems.n_link_pendulum(n, name=args["prefix"]))
t_derive = time.perf_counter() - start
start = time.perf_counter()
scene = Scene(eom, prefix=args["prefix"], jacobian=form != "none",
              jacobian_form=form if form != "none" else "expanded")
code = generate_c(scene)
t_generate = time.perf_counter() - start
before = resource.getrusage(resource.RUSAGE_CHILDREN)
start = time.perf_counter()
cm = build_code(code)
t_build = time.perf_counter() - start
after = resource.getrusage(resource.RUSAGE_CHILDREN)
t = np.linspace(0.0, 2.0, 21)
start = time.perf_counter()
res = cm.simulate(t, q0=[0.5] * n, v0=[0.0] * n, method="bdf", rtol=1e-8, atol=1e-10, jacobian=form != "none")
t_first = time.perf_counter() - start
print(json.dumps(dict(import_s=t_import, derive_s=t_derive, gen_s=t_generate, build_s=t_build,
                      compile_cpu_s=(after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime),
                      peak_mb=after.ru_maxrss / 1024.0, bytes=len(code.files[code.source_name].encode()),
                      first_run_s=t_first, steps=res.stats.get("steps"), jac_evals=res.stats.get("jac_evals"),
                      final=list(map(float, np.asarray(res.y)[-1])))))
"""

# Every row's run-time measurements, rounds interleaved over the rows.
_RUN = r"""
import json, sys, time
import numpy as np
from lagcodegen import Scene, build_code, derive, generate_c, systems
rows, rounds = json.loads(sys.argv[1]), int(sys.argv[2])
models = []
for r in rows:
    eom = derive(systems.n_link_pendulum(r["n"], name=r["prefix"]))
    scene = Scene(eom, prefix=r["prefix"], jacobian=r["form"] != "none",
                  jacobian_form=r["form"] if r["form"] != "none" else "expanded")
    models.append(build_code(generate_c(scene)))  # from the cache the row's build filled
t = np.linspace(0.0, 2.0, 21)
out = [dict(bdf=[], rhs=[], jac=[]) for _ in rows]

def per_call(fn, budget=0.05):
    calls, start = 0, time.perf_counter()
    while True:
        for _ in range(10):
            fn()
        calls += 10
        elapsed = time.perf_counter() - start
        if elapsed > budget:
            return elapsed / calls

for _ in range(rounds):
    for r, cm, o in zip(rows, models, out):
        n = r["n"]
        start = time.perf_counter()
        cm.simulate(t, q0=[0.5] * n, v0=[0.0] * n, method="bdf", rtol=1e-8, atol=1e-10, jacobian=r["form"] != "none")
        o["bdf"].append(time.perf_counter() - start)
        y = np.array([0.5] * n + [0.1] * n)
        p = cm.parameter_vector()
        ydot = cm.rhs(0.0, y, p)
        J = np.empty((cm.ny, cm.ny))
        args = [cm._ptr(y), cm._ptr(p), cm.ffi.from_buffer("double[]", ydot)]
        o["rhs"].append(per_call(lambda: cm.c_rhs(0.0, args[0], args[1], args[2])))
        if cm.c_jac is not None:
            jp = cm.ffi.from_buffer("double[]", J)
            o["jac"].append(per_call(lambda: cm.c_jac(0.0, args[0], args[2], args[1], jp)))
print(json.dumps([{k: float(np.median(v)) if v else None for k, v in o.items()} for o in out]))
"""


def progress(message: str) -> None:
    H.progress(TAG, message)


def parse_args(argv=None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="n = 10, 20; 3 rounds (< 2 min)")
    ap.add_argument("--out", metavar="DIR", type=Path, help="write scaling.txt, scaling.csv and scaling.png")
    ap.add_argument("--sizes", help="comma-separated n (default 10,20,30,50,100; quick 10,20)")
    ap.add_argument("--rounds", type=int, help="interleaved rounds of the run-time measurements (default 5; quick 3)")
    ap.add_argument("--budget", type=float, default=600.0,
                    help="skip a row whose predicted build time exceeds this many seconds (default 600)")
    return ap.parse_args(argv)


def fit(points: list[tuple[float, float]]) -> tuple[float, float] | None:
    """(exponent, log-prefactor) of value ~ n^exponent by least squares in log-log."""
    pts = [(n, v) for n, v in points if v and v > 0]
    if len(pts) < 2:
        return None
    slope, icept = np.polyfit(np.log([p[0] for p in pts]), np.log([p[1] for p in pts]), 1)
    return float(slope), float(icept)


def predicted(rows: list[dict], form: str, n: int, key: str = "build_s") -> float | None:
    """``key`` at ``n`` extrapolated from the measured rows of ``form`` (None below two rows)."""
    f = fit([(r["n"], r.get(key)) for r in rows if r["form"] == form and not r.get("skipped")])
    return None if f is None else float(np.exp(f[1]) * n ** f[0])


def build_row(n: int, form: str, scratch: Path, budget: float) -> dict:
    prefix = f"sc{n}_{form}"
    env = dict(os.environ, LAGCODEGEN_CACHE=str(scratch / "cache"))
    progress(f"n = {n}: derive, generate, build, first run ({form})")
    proc = subprocess.run([sys.executable, "-c", _BUILD, json.dumps(dict(n=n, form=form, prefix=prefix))],
                          capture_output=True, text=True, env=env, timeout=max(60.0, 3 * budget))
    if proc.returncode != 0:
        raise RuntimeError(f"row n = {n} {form} failed:\n{proc.stderr[-3000:]}")
    row = dict(n=n, form=form, prefix=prefix, **json.loads(proc.stdout.splitlines()[-1]))
    row["e2e_s"] = row["derive_s"] + row["gen_s"] + row["build_s"] + row["first_run_s"]
    return row


def run_rows(rows: list[dict], scratch: Path, rounds: int) -> None:
    """The run-time measurements of every built row, in one process, rounds interleaved."""
    todo = [r for r in rows if not r.get("skipped")]
    progress(f"BDF runs and call costs: {len(todo)} rows, {rounds} interleaved rounds")
    env = dict(os.environ, LAGCODEGEN_CACHE=str(scratch / "cache"))
    proc = subprocess.run([sys.executable, "-c", _RUN, json.dumps([dict(n=r["n"], form=r["form"], prefix=r["prefix"])
                                                                    for r in todo]), str(rounds)],
                          capture_output=True, text=True, env=env)
    if proc.returncode != 0:
        raise RuntimeError(f"run phase failed:\n{proc.stderr[-3000:]}")
    for r, m in zip(todo, json.loads(proc.stdout.splitlines()[-1])):
        r["bdf_ms"] = 1e3 * m["bdf"]
        r["rhs_us"] = 1e6 * m["rhs"]
        r["jac_us"] = 1e6 * m["jac"] if m["jac"] is not None else None


COLUMNS = [("n", "n", "{}"), ("form", "Jacobian", "{}"), ("bytes", "C bytes", "{}"), ("derive_s", "derive [s]", "{:.2f}"),
           ("gen_s", "generate [s]", "{:.2f}"), ("build_s", "build [s]", "{:.2f}"),
           ("compile_cpu_s", "cc CPU [s]", "{:.2f}"), ("peak_mb", "cc peak [MB]", "{:.0f}"),
           ("e2e_s", "end to end [s]", "{:.2f}"), ("bdf_ms", "BDF run [ms]", "{:.1f}"), ("rhs_us", "rhs [us]", "{:.2f}"),
           ("jac_us", "jac [us]", "{:.2f}"), ("jac_evals", "jac evals", "{}")]
GROWTH_KEYS = ("bytes", "derive_s", "gen_s", "build_s", "compile_cpu_s", "peak_mb", "e2e_s", "bdf_ms", "rhs_us", "jac_us")


def plot(path: Path, rows: list[dict]) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    panels = [("gen_s", "generate [s]"), ("build_s", "build [s]"), ("peak_mb", "compiler peak [MB]"),
              ("e2e_s", "end to end [s]"), ("bdf_ms", "BDF run [ms]"), ("jac_us", "jac call [us]")]
    fig, axes = plt.subplots(2, 3, figsize=(14, 8))
    for ax, (key, label) in zip(axes.flat, panels):
        for form, style, color in zip(FORMS, ("o-", "s--", "^-"), ("C0", "C1", "C2")):
            pts = [(r["n"], r[key]) for r in rows if r["form"] == form and r.get(key)]
            if pts:
                ax.loglog(*zip(*pts), style, color=color, label=form)
        ax.set_xlabel("links n")
        ax.set_ylabel(label)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
    fig.suptitle("lagcodegen scaling: planar n-link pendulum (issue 14)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def summary(rows: list[dict]) -> list[str]:
    lines = []
    for form in FORMS:
        parts = []
        for key in GROWTH_KEYS:
            f = fit([(r["n"], r.get(key)) for r in rows if r["form"] == form and not r.get("skipped")])
            if f is not None:
                parts.append(f"{key} n^{f[0]:.2f}")
        if parts:
            lines.append(f"growth ({form}): " + ", ".join(parts))
    lines.append("")

    def row(n, form):
        return next((r for r in rows if r["n"] == n and r["form"] == form and not r.get("skipped")), None)
    r = row(TARGET_E2E_NONE_N, "none")
    if r:
        lines.append(f"target: n = {TARGET_E2E_NONE_N} end to end without the Jacobian <= {TARGET_E2E_NONE_S:g} s: "
                     f"{r['e2e_s']:.1f} s ({'met' if r['e2e_s'] <= TARGET_E2E_NONE_S else 'missed'})")
    for form in ("expanded", "tangent"):
        r = row(TARGET_JAC_N, form)
        if r:
            ok = r["e2e_s"] <= TARGET_JAC_S and r["peak_mb"] <= TARGET_JAC_MB
            lines.append(f"target: n = {TARGET_JAC_N} with the {form} Jacobian <= {TARGET_JAC_S:g} s and "
                         f"{TARGET_JAC_MB:g} MB: {r['e2e_s']:.1f} s, {r['peak_mb']:.0f} MB ({'met' if ok else 'missed'})")
    for n in sorted({r["n"] for r in rows}):
        e, t = row(n, "expanded"), row(n, "tangent")
        if e and t and e.get("jac_us") and t.get("jac_us"):
            ratio_run, ratio_jac = t["bdf_ms"] / e["bdf_ms"], t["jac_us"] / e["jac_us"]
            lines.append(f"n = {n}: tangent / expanded: BDF run x{ratio_run:.2f}, jac call x{ratio_jac:.2f}, "
                         f"build x{t['build_s'] / e['build_s']:.2f}, compiler peak x{t['peak_mb'] / e['peak_mb']:.2f}, "
                         f"generate x{t['gen_s'] / e['gen_s']:.2f} (target run time <= x{TARGET_RUN_RATIO:g})")
        for r in (e, t):
            if r is not None and row(n, "none"):
                lines.append(f"n = {n}: {r['form']} Jacobian / difference quotients: BDF run "
                             f"x{r['bdf_ms'] / row(n, 'none')['bdf_ms']:.2f}, build x{r['build_s'] / row(n, 'none')['build_s']:.2f}")
    skipped = [r for r in rows if r.get("skipped")]
    for r in skipped:
        lines.append(f"skipped: n = {r['n']} {r['form']} ({r['skipped']})")
    return lines


def main(argv=None) -> int:
    args = parse_args(argv)
    sizes = [int(s) for s in args.sizes.split(",")] if args.sizes else ([10, 20] if args.quick else [10, 20, 30, 50, 100])
    rounds = max(1, args.rounds or (3 if args.quick else 5))
    start, load_start = time.perf_counter(), H.load_average()
    rows: list[dict] = []
    with tempfile.TemporaryDirectory(prefix="lcg-scaling-") as tmp:
        scratch = Path(tmp)
        build_row(3, "none", scratch, args.budget)  # untimed: compiler and interpreter files in the page cache
        for n in sizes:
            for form in FORMS:
                if form == "expanded" and n > EXPANDED_MAX_N:
                    rows.append(dict(n=n, form=form, skipped=f"expanded above n = {EXPANDED_MAX_N}"))
                    continue
                guess = predicted(rows, form, n)
                if guess is not None and guess > args.budget:
                    rows.append(dict(n=n, form=form, skipped=f"predicted build {guess:.0f} s > budget {args.budget:g} s"))
                    continue
                rows.append(build_row(n, form, scratch, args.budget))
        run_rows(rows, scratch, rounds)
    lines = H.machine_lines("lagcodegen scaling benchmark (issue 14)", (load_start, H.load_average()))
    lines += [f"run:      each row built cold in a fresh process; BDF runs and call costs: medians of {rounds} "
              "rounds interleaved over the rows, in one process", "",
              "planar n-link pendulum, every parameter run-time; build = lagcodegen.build_code (model C, cffi module, "
              "native driver), model never built before; end to end = derive + generate + build + first BDF run", "",
              H.format_table(COLUMNS, [r for r in rows if not r.get("skipped")]), ""]
    lines += summary(rows)
    text = "\n".join(lines) + "\n"
    print(text, end="")
    if args.out is not None:
        H.write_report(args.out, "scaling", text, [{k: v for k, v in r.items() if k != "final"} for r in rows])
        plot(args.out / "scaling.png", [r for r in rows if not r.get("skipped")])
        progress(f"wrote {args.out}/scaling.txt, scaling.csv and scaling.png")
    progress(f"done in {time.perf_counter() - start:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
