"""The dense analytic Jacobian, expanded vs tangent form (issue 14), measured.

Part 1, the code (planar n-link pendulum, every parameter run-time, n = 5, 10, 20, 30; quick:
5, 10): for ``Scene(jacobian_form="expanded")`` (every entry of dr/dy as an expression) and
``"tangent"`` (forward-mode differentiation of the right-hand side's program, one loop over the
columns), and for no Jacobian at all as the baseline: bytes of <prefix>.c, generation time,
``gcc -O2 -c <prefix>.c`` wall time and the compiler's peak resident memory (ru_maxrss of the
children of a helper process that runs only the compiler), and ns per call of rhs and jac
(the C harness of _harness.py, linked to that object). The compiles and the harness processes
go round-robin over the rows, ``--repeats`` rounds (a compile longer than 30 s is not
repeated), so that machine noise hits every row alike.

Part 2, what the Jacobian buys at run time: the stiff spring chain (ratio 1e6, damped dimers,
_harness.spring_chain) integrated with CVODE BDF, dense linear solver, rtol 1e-8, atol 1e-10,
t in [0, 10], with CVODE's difference quotients (DQ), the expanded and the tangent Jacobian:
build time (cold cache, cffi module and native driver) and median integration wall time
(round-robin over the rows), and the largest difference of the final states to the DQ run.

This is a measuring instrument: it asserts nothing about the numbers it reports.

Usage::

    python benchmarks/jacobian.py [--quick] [--out DIR] [--repeats N] [--sizes 5,10,...]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _harness as H  # noqa: E402

from lagcodegen import Scene, build_code, derive, generate_c, systems  # noqa: E402

TAG = "jacobian"
FORMS = ("none", "expanded", "tangent")
#: A compile longer than this many seconds is measured once.
REPEAT_COMPILE_BELOW = 30.0

# Runs one command and prints its wall time and the peak RSS of its process tree's largest
# child (the compiler proper, cc1), from getrusage(RUSAGE_CHILDREN) of this helper process.
_MEASURE = r"""
import json, resource, subprocess, sys, time
start = time.perf_counter()
proc = subprocess.run(sys.argv[2:], cwd=sys.argv[1], capture_output=True, text=True)
wall = time.perf_counter() - start
rss = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
print(json.dumps(dict(rc=proc.returncode, wall=wall, maxrss_kb=rss, err=proc.stderr[-2000:])))
"""


def progress(message: str) -> None:
    H.progress(TAG, message)


def parse_args(argv=None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="n = 5, 10 and chains of 10, 20; 1 repeat (< 2 min)")
    ap.add_argument("--out", metavar="DIR", type=Path, help="write jacobian.txt and jacobian.csv")
    ap.add_argument("--repeats", type=int, help="rounds per median (default 3; quick 1)")
    ap.add_argument("--sizes", help="comma-separated n of part 1 (default 5,10,20,30; quick 5,10)")
    ap.add_argument("--chains", help="comma-separated chain lengths of part 2 (default 10,20,30,50; quick 10,20)")
    return ap.parse_args(argv)


def measured_compile(folder: Path, args: list[str]) -> dict:
    """Wall time and peak compiler memory of one compiler run (in a helper process)."""
    proc = subprocess.run([sys.executable, "-c", _MEASURE, str(folder), *args], capture_output=True, text=True,
                          check=True)
    out = json.loads(proc.stdout)
    if out["rc"] != 0:
        raise RuntimeError(f"{' '.join(args)} failed:\n{out['err']}")
    return out


# --------------------------------------------------------------------------- part 1: code
def code_row(n: int, form: str, scratch: Path) -> dict:
    progress(f"n-link pendulum n = {n}: generate ({form})")
    eom = derive(systems.n_link_pendulum(n, name=f"jb_link{n}"))
    prefix = f"jb{n}_{form}"
    start = time.perf_counter()
    scene = Scene(eom, prefix=prefix, jacobian=form != "none",
                  jacobian_form=form if form != "none" else "expanded")
    code = generate_c(scene)
    gen_s = time.perf_counter() - start
    folder = scratch / prefix
    folder.mkdir(parents=True)
    code.write(folder)
    (folder / "harness.c").write_text(H.harness_source(code))
    return dict(n=n, form=form, bytes=len(code.files[code.source_name].encode()), gen_s=gen_s,
                _folder=folder, _code=code, _compile=[], _rss=[])


def compile_round(rows: list[dict], first: bool) -> None:
    for r in rows:
        if not first and r["_compile"][0] > REPEAT_COMPILE_BELOW:
            continue
        if first:
            progress(f"n = {r['n']}: gcc -O2 ({r['form']})")
        out = measured_compile(r["_folder"], [H.c_compiler(), "-O2", "-std=c99", "-c", r["_code"].source_name,
                                              "-o", "model.o"])
        r["_compile"].append(out["wall"])
        r["_rss"].append(out["maxrss_kb"] / 1024.0)


def link_harness(r: dict) -> None:
    cmd = [H.c_compiler(), "-O2", "-std=c99", "harness.c", "model.o", "-o", "harness", "-lm"]
    subprocess.run(cmd, cwd=r["_folder"], check=True, capture_output=True)


def harness_round(rows: list[dict], c_target: float) -> None:
    for r in rows:
        proc = subprocess.run([str(r["_folder"] / "harness"), repr(c_target)], capture_output=True, text=True,
                              check=True)
        for line in proc.stdout.splitlines():
            name, _calls, ns = line.split()
            r.setdefault(f"_{name}", []).append(float(ns))


def finish_code_rows(rows: list[dict]) -> None:
    for r in rows:
        r["compile_s"] = float(np.median(r.pop("_compile")))
        r["peak_mb"] = float(np.max(r.pop("_rss")))
        r["rhs_ns"] = float(np.median(r.pop("_rhs")))
        jac = r.pop("_jac", None)
        r["jac_ns"] = float(np.median(jac)) if jac else None
        for k in ("_folder", "_code"):
            del r[k]


def growth(rows: list[dict], form: str, key: str) -> float | None:
    """Fitted exponent of ``key`` against n (least squares in log-log) over the sizes >= 10."""
    pts = [(r["n"], r[key]) for r in rows if r["form"] == form and r.get(key) and r["n"] >= 10]
    if len(pts) < 2:
        return None
    x, y = np.log([p[0] for p in pts]), np.log([p[1] for p in pts])
    return float(np.polyfit(x, y, 1)[0])


# --------------------------------------------------------------------------- part 2: stiff chain
def chain_row(n: int, form: str, scratch: Path, k: int) -> dict:
    progress(f"spring chain n = {n}: build ({form})")
    eom = derive(H.spring_chain(n, 1e6, name=f"jb_chain{n}"))
    scene = Scene(eom, prefix=f"jbc{n}_{form}", jacobian=form != "none",
                  jacobian_form=form if form != "none" else "expanded")
    with H.cache_at(scratch / f"cache{k}"):
        start = time.perf_counter()
        cm = build_code(generate_c(scene))
        build_s = time.perf_counter() - start
    q0, v0 = H.chain_initial(n)
    t = np.linspace(0.0, 10.0, 101)

    def run():
        return cm.simulate(t, q0=q0, v0=v0, method="bdf", rtol=1e-8, atol=1e-10, jacobian=form != "none")
    res = run()
    return dict(n=n, form=form, build_s=build_s, steps=res.stats.get("steps"), rhs_evals=res.stats.get("rhs_evals"),
                jac_evals=res.stats.get("jac_evals"), _run=run, _times=[], _final=np.asarray(res.y)[-1])


def simulate_round(rows: list[dict]) -> None:
    for r in rows:
        start = time.perf_counter()
        r["_run"]()
        r["_times"].append(time.perf_counter() - start)


def finish_chain_rows(rows: list[dict]) -> None:
    base = {r["n"]: r["_final"] for r in rows if r["form"] == "none"}
    for r in rows:
        r["sim_ms"] = 1e3 * float(np.median(r.pop("_times")))
        final = r.pop("_final")
        r["diff_dq"] = float(np.max(np.abs(final - base[r["n"]]))) if r["n"] in base else None
        del r["_run"]


CODE_COLUMNS = [("n", "n", "{}"), ("form", "Jacobian", "{}"), ("bytes", "C bytes", "{}"),
                ("gen_s", "generate [s]", "{:.2f}"), ("compile_s", "gcc -O2 [s]", "{:.2f}"),
                ("peak_mb", "gcc peak [MB]", "{:.0f}"), ("rhs_ns", "rhs [ns]", "{:.0f}"),
                ("jac_ns", "jac [ns]", "{:.0f}")]
CHAIN_COLUMNS = [("n", "n", "{}"), ("form", "Jacobian", "{}"), ("build_s", "build [s]", "{:.2f}"),
                 ("sim_ms", "BDF run [ms]", "{:.1f}"), ("steps", "steps", "{}"), ("rhs_evals", "rhs evals", "{}"),
                 ("jac_evals", "jac evals", "{}"), ("diff_dq", "|y_end - DQ's|", "{:.1e}")]


def sizes(text: str | None, default: list[int]) -> list[int]:
    return [int(s) for s in text.split(",")] if text else default


def main(argv=None) -> int:
    args = parse_args(argv)
    repeats = max(1, args.repeats or (1 if args.quick else 3))
    settings = SimpleNamespace(repeats=repeats, c_target=0.05 if args.quick else 0.1)
    ns = sizes(args.sizes, [5, 10] if args.quick else [5, 10, 20, 30])
    chains = sizes(args.chains, [10, 20] if args.quick else [10, 20, 30, 50])
    start, load_start = time.perf_counter(), H.load_average()
    with tempfile.TemporaryDirectory(prefix="lcg-jacobian-") as tmp:
        scratch = Path(tmp)
        with H.cache_at(scratch / "warm"):  # one untimed build: compiler binaries in the page cache
            build_code(generate_c(Scene(derive(systems.pendulum("jb_warm")))))
        code_rows = [code_row(n, form, scratch) for n in ns for form in FORMS]
        for k in range(repeats):
            compile_round(code_rows, first=k == 0)
        for r in code_rows:
            link_harness(r)
        progress("C harness: every row, round-robin")
        for _ in range(2 * repeats - 1):
            harness_round(code_rows, settings.c_target)
        finish_code_rows(code_rows)
        chain_rows = [chain_row(n, form, scratch, k) for k, (n, form) in
                      enumerate((n, form) for n in chains for form in FORMS)]
        progress("BDF runs: every row, round-robin")
        for _ in range(3 * repeats):
            simulate_round(chain_rows)
        finish_chain_rows(chain_rows)
    lines = H.machine_lines("lagcodegen Jacobian-form benchmark (issue 14)", (load_start, H.load_average()))
    lines += [f"run:      medians of {repeats} compiles (one above {REPEAT_COMPILE_BELOW:g} s), "
              f"{2 * repeats - 1} harness processes (~{settings.c_target:g} s per function each), "
              f"{3 * repeats} BDF runs; round-robin over the rows", "",
              "Part 1: planar n-link pendulum, every parameter run-time; <prefix>.c alone, gcc -O2 -c", "",
              H.format_table(CODE_COLUMNS, code_rows), ""]
    for form in FORMS:
        exps = {key: growth(code_rows, form, key) for key in ("bytes", "compile_s", "peak_mb", "jac_ns")}
        text = ", ".join(f"{k} n^{v:.2f}" for k, v in exps.items() if v is not None)
        if text:
            lines.append(f"growth ({form}, n >= 10): {text}")
    for n in ns:
        e = next((r for r in code_rows if r["n"] == n and r["form"] == "expanded"), None)
        t = next((r for r in code_rows if r["n"] == n and r["form"] == "tangent"), None)
        if e and t and e.get("jac_ns") and t.get("jac_ns"):
            lines.append(f"n = {n}: tangent / expanded: C bytes x{t['bytes'] / e['bytes']:.2f}, "
                         f"compile x{t['compile_s'] / e['compile_s']:.2f}, "
                         f"peak memory x{t['peak_mb'] / e['peak_mb']:.2f}, "
                         f"jac call x{t['jac_ns'] / e['jac_ns']:.2f}")
    lines += ["", "Part 2: stiff spring chain (ratio 1e6), CVODE BDF, dense solver, rtol 1e-8, atol 1e-10, "
              "t in [0, 10]; build = cffi module + native driver, cold cache", "",
              H.format_table(CHAIN_COLUMNS, chain_rows)]
    text = "\n".join(lines) + "\n"
    print(text, end="")
    if args.out is not None:
        H.write_report(args.out, "jacobian", text, [dict(part="code", **r) for r in code_rows]
                       + [dict(part="chain", **r) for r in chain_rows])
        progress(f"wrote {args.out}/jacobian.txt and jacobian.csv")
    progress(f"done in {time.perf_counter() - start:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
