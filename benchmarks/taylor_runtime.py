"""The Taylor integrator's two builds side by side (issue 14): the per-model integrator
(``build_taylor(scene, runtime=False)``: ``<prefix>_taylor.c``, driver and jet compiled together
with the sizes as constants, a cffi module per model) against the model-independent driver of
the Taylor runtime (``runtime=True``, the default: ``lcg_taylor.c`` compiled once per
installation, taking the table of the model's jet, a plain library per model).

Run time: the planar n-link pendulum (unit masses and lengths, g = 9.81), every angle 1.0 rad at
rest, t in [0, T] (T = 10; ``--t-end``) with outputs at 0, T/2, T, rtol = atol = tol; one
``TaylorModule.simulate`` call per integration (its lean Python wrapper included). Rounds
interleave the builds (each round times a batch of calls of each, batches of about ``--batch``
seconds, the order alternating); the table gives medians over rounds per call, per step, and
their ratio. The results of all are compared bit for bit.

Build time: a model never built before (a fresh cache folder, a new model name each time), the
runtime already built: ``build_taylor`` from the scene to a loaded module, code generation
included (about the same in both; given apart). Builds alternate between the two kinds. The
runtime's own build (once per installation) is timed apart.

``--baseline TREE`` adds a third contender to the run times: the per-model integrator as the
lagcodegen in the source tree TREE generates it (e.g. a checkout of the release before the
split), its C built and called by this lagcodegen (the same Python wrapper).

A measuring instrument: it asserts nothing but the bit-identity of the results.

Usage::

    python benchmarks/taylor_runtime.py [--quick] [--ns 1,2,3,5] [--rounds R] [--t-end T] [--baseline TREE]
                                        [--out DIR]
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

import lagcodegen as lcg  # noqa: E402
from lagcodegen.derivation import derive  # noqa: E402
from lagcodegen.formulation.scene import Scene  # noqa: E402
from lagcodegen.build import DEFAULT_CFLAGS, build  # noqa: E402
from lagcodegen.codegen.taylor.emit import jet_code, taylor_code  # noqa: E402
from lagcodegen.solvers.taylor import TaylorModule, build_taylor  # noqa: E402
from lagcodegen.solvers.taylor import runner  # noqa: E402
from lagcodegen.solvers.taylor.runner import taylor_runtime  # noqa: E402

KINDS = ("per-model", "runtime")


def scene(n: int, name: str) -> Scene:
    return Scene(derive(lcg.systems.n_link_pendulum(n, name=name)), jacobian=False)


BASELINE_SCRIPT = """
import json, sys
import lagcodegen as lcg
from lagcodegen.derivation import derive
from lagcodegen.formulation.scene import Scene
try:
    from lagcodegen.codegen.taylor.emit import taylor_code
except ImportError:  # a tree from before the Taylor code generation moved to lagcodegen.codegen.taylor
    from lagcodegen.solvers.taylor import taylor_code
code = taylor_code(Scene(derive(lcg.systems.n_link_pendulum(int(sys.argv[1]), name=sys.argv[2])), jacobian=False))[0]
print(json.dumps(dict(files=code.files, cdef_extra=code.cdef_extra, headers=code.cffi_headers,
                      where=lcg.__file__)))
"""


def baseline_module(tree: str, n: int, name: str, sc: Scene) -> TaylorModule:
    """The per-model integrator of the n-link pendulum as the lagcodegen at ``tree`` generates it,
    built here (same prefix and interface: only its C differs)."""
    proc = subprocess.run([sys.executable, "-c", BASELINE_SCRIPT, str(n), name], capture_output=True, text=True,
                          env={**os.environ, "PYTHONPATH": tree}, cwd="/", check=True)
    theirs = json.loads(proc.stdout)
    if not theirs["where"].startswith(str(Path(tree).resolve())):
        raise SystemExit(f"--baseline {tree}: its lagcodegen was not imported ({theirs['where']})")
    code, d, events = taylor_code(sc)
    code.files, code.cdef_extra, code.cffi_headers = theirs["files"], theirs["cdef_extra"], theirs["headers"]
    return TaylorModule(code, build(code, native=False).module, d, events)


def run_times(n: int, tols, rounds: int, batch: float, t_end: float = 10.0, baseline: str | None = None) -> list[dict]:
    sc = scene(n, f"trt{n}")
    mods = {"per-model": build_taylor(sc, runtime=False), "runtime": build_taylor(sc)}
    if baseline:
        mods["baseline"] = baseline_module(baseline, n, f"trt{n}", sc)
    kinds = tuple(mods)
    t = np.array([0.0, t_end / 2, t_end])
    y0 = np.concatenate([np.full(n, 1.0), np.zeros(n)])
    p = np.array(sc.default_parameters(), dtype=float)
    rows = []
    for tol in tols:
        res = {k: m.simulate(t, y0, p, rtol=tol, atol=tol) for k, m in mods.items()}
        a = res["per-model"]
        identical = all(np.array_equal(a.y, b.y) and a.stats["steps"] == b.stats["steps"] for b in res.values())
        if not identical:
            raise SystemExit(f"n = {n}, tol = {tol}: the two builds differ")
        start = time.perf_counter()
        mods["runtime"].simulate(t, y0, p, rtol=tol, atol=tol)
        calls = max(1, int(batch / max(time.perf_counter() - start, 1e-7)))
        per_call = {k: [] for k in kinds}
        for r in range(rounds):
            for kind in (kinds if r % 2 == 0 else kinds[::-1]):
                m = mods[kind]
                start = time.perf_counter()
                for _ in range(calls):
                    m.simulate(t, y0, p, rtol=tol, atol=tol)
                per_call[kind].append((time.perf_counter() - start) / calls)
        steps = a.stats["steps"]
        med = {k: float(np.median(v)) for k, v in per_call.items()}
        rows.append(dict(n=n, t_end=t_end, tol=tol, order=a.stats["order"], steps=steps, calls=calls,
                         per_model_us=1e6 * med["per-model"], runtime_us=1e6 * med["runtime"],
                         per_model_ns_step=1e9 * med["per-model"] / steps, runtime_ns_step=1e9 * med["runtime"] / steps,
                         ratio=med["runtime"] / med["per-model"], identical=identical,
                         baseline_us=1e6 * med["baseline"] if baseline else None,
                         ratio_baseline=med["runtime"] / med["baseline"] if baseline else None))
        H.progress("taylor_runtime", f"n = {n}, tol = {tol:.0e}: ratio {rows[-1]['ratio']:.3f}")
    return rows


def build_times(n: int, reps: int) -> list[dict]:
    """Cold builds of never-built models, the runtime built (in every fresh cache too)."""
    rows = []
    for rep in range(reps):
        for kind in (KINDS if rep % 2 == 0 else KINDS[::-1]):
            name = f"trb{n}_{kind[0]}{rep}_{time.time_ns() % 10**9}"
            with tempfile.TemporaryDirectory() as cold, H.cache_at(Path(cold)):
                taylor_runtime()  # loaded once per process (built into the first cache)
                sc = scene(n, name)
                start = time.perf_counter()
                (taylor_code if kind == "per-model" else jet_code)(sc)
                generate = time.perf_counter() - start
                start = time.perf_counter()
                build_taylor(sc, runtime=kind == "runtime")
                total = time.perf_counter() - start
            rows.append(dict(n=n, kind=kind, generate=generate, total=total))
    out = []
    for kind in KINDS:
        mine = [r for r in rows if r["kind"] == kind]
        out.append(dict(n=n, kind=kind, reps=len(mine), generate=float(np.median([r["generate"] for r in mine])),
                        total=float(np.median([r["total"] for r in mine]))))
    return out


def runtime_build_time() -> float:
    """Seconds to build the Taylor runtime itself into an empty cache (once per installation)."""
    with tempfile.TemporaryDirectory() as cold, H.cache_at(Path(cold)):
        start = time.perf_counter()
        runner._taylor_runtime.__wrapped__(H.c_compiler(), DEFAULT_CFLAGS)  # not memoized
        return time.perf_counter() - start


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="n = 1, 2; two tolerances; 5 rounds; 1 build each")
    ap.add_argument("--ns", default=None, help="comma-separated n (default 1,2,3,5)")
    ap.add_argument("--rounds", type=int, default=None)
    ap.add_argument("--batch", type=float, default=0.02, help="seconds per timed batch (default 0.02)")
    ap.add_argument("--builds", type=int, default=None, help="cold builds of each kind per n (default 3)")
    ap.add_argument("--t-end", type=float, default=10.0, help="end of the integrations (default 10)")
    ap.add_argument("--baseline", default=None, help="source tree of a lagcodegen whose per-model integrator "
                    "is timed too (e.g. /work/main)")
    ap.add_argument("--out", type=Path)
    args = ap.parse_args(argv)
    ns = [int(x) for x in args.ns.split(",")] if args.ns else ([1, 2] if args.quick else [1, 2, 3, 5])
    tols = [1e-6, 1e-12] if args.quick else [1e-6, 1e-9, 1e-12, 1e-15]
    rounds = args.rounds or (5 if args.quick else 21)
    builds = args.builds or (1 if args.quick else 3)
    load0 = H.load_average()
    with tempfile.TemporaryDirectory() as warm, H.cache_at(Path(warm)):
        taylor_runtime()
        runs = [row for n in ns for row in run_times(n, tols, rounds, args.batch, args.t_end, args.baseline)]
    cold = [row for n in ns for row in build_times(n, builds)]
    rt_build = runtime_build_time()
    lines = H.machine_lines("benchmarks/taylor_runtime.py: per-model Taylor integrator vs the runtime's driver",
                            (load0, H.load_average()))
    lines += ["", f"run time per integration (median of {rounds} interleaved rounds; ratio = runtime / per-model; "
                  "results bit-identical)",
              H.format_table([("n", "n", "{}"), ("t_end", "T", "{:g}"), ("tol", "tol", "{:.0e}"), ("order", "order", "{}"),
                              ("steps", "steps", "{}"), ("per_model_us", "per-model [us]", "{:.2f}"),
                              ("runtime_us", "runtime [us]", "{:.2f}"),
                              ("per_model_ns_step", "per-model [ns/step]", "{:.0f}"),
                              ("runtime_ns_step", "runtime [ns/step]", "{:.0f}"), ("ratio", "ratio", "{:.3f}")]
                             + ([("baseline_us", "baseline [us]", "{:.2f}"),
                                 ("ratio_baseline", "runtime/baseline", "{:.3f}")] if args.baseline else []), runs),
              "", f"cold build of a never-built model, the runtime cached (median of {builds}; generate: the C text)",
              H.format_table([("n", "n", "{}"), ("kind", "kind", "{}"), ("generate", "generate [s]", "{:.3f}"),
                              ("total", "build_taylor [s]", "{:.3f}")], cold),
              "", f"the Taylor runtime itself, built once per installation into an empty cache: {rt_build:.2f} s"]
    text = "\n".join(lines)
    print(text)
    if args.out is not None:
        H.write_report(args.out, "taylor_runtime", text, runs + cold)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
