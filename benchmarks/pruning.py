"""What the scene prunes, measured: the same system generated with and without each option.

Pairs (each row one generated scene):

* Jacobian:   double pendulum and 10-link pendulum, with vs without ``<prefix>_jac``
              (integration: Adams with the generated vs the difference-quotient Jacobian);
* outputs:    10-link pendulum, only ``energy`` vs every output the model has (energy, T, V,
              Jacobi h, dh/dt, momenta, positions: 35 values);
* constants:  10-link pendulum, every parameter folded into the code vs all run-time (``p[]``);
* sparse:     the stiff 20-mass chain (benchmarks/_harness.spring_chain, ratio 1e6): dense
              Jacobian + dense solver vs ``Scene(sparse_jacobian=True)`` + band solver (and
              the band solver with difference quotients), BDF;
* Routhian:   spherical pendulum, full (4 states) vs Routhian-reduced (3 states, phi by
              quadrature).

Columns: bytes and lines of the generated model files (<prefix>.c/.h, plus <prefix>_sparse.*),
generation time, compile time (cffi module + native driver, cold cache; median of --repeats),
RHS / Jacobian / sparse Jacobian ns per call (C harness, cc -O2, no Python; median of 2 x --repeats - 1
processes taken round-robin over all rows), and the wall time
of ``simulate`` (native, 1001 output times, median of 5 x --repeats runs taken round-robin over all
rows after every row is built, so that machine noise hits every row alike; the integration of each row
is stated in the table).

This is a measuring instrument: it asserts nothing about the numbers it reports.

Usage::

    python benchmarks/pruning.py [--quick] [--out DIR] [--repeats N]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from types import SimpleNamespace

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _harness as H  # noqa: E402

from lagcodegen import Scene, build_code, derive, generate_c, systems  # noqa: E402

TAG = "pruning"
ALL_OUTPUTS = ["energy", "kinetic_energy", "potential_energy", "jacobi_h", "dh_dt", "momenta", "positions"]


def progress(message: str) -> None:
    H.progress(TAG, message)


def parse_args(argv=None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="5-link instead of 10-link pendulum, 1 repeat (< 2 min)")
    ap.add_argument("--out", metavar="DIR", type=Path, help="write pruning.txt and pruning.csv")
    ap.add_argument("--repeats", type=int, help="runs per median (default 3; quick 1)")
    return ap.parse_args(argv)


@dataclass
class Variant:
    group: str
    label: str
    model: object               # lagcodegen.Model, or a callable returning EquationsOfMotion
    scene: dict                 # Scene options
    sim: dict                   # simulate options
    q0: list
    v0: list
    T: float = 10.0
    params: dict = field(default_factory=dict)
    reduce_from: object = None  # RouthReduction for the reduced model


def variants(quick: bool) -> list[Variant]:
    n = 5 if quick else 10
    link = systems.n_link_pendulum(n, name=f"pr_link{n}")
    dbl = systems.double_pendulum("pr_double")
    chain = H.spring_chain(20, 1e6, name="pr_chain")
    cq0, cv0 = H.chain_initial(20)
    tol = dict(rtol=1e-8, atol=1e-10)
    out = [
        Variant("jacobian/double", "double pendulum, with Jacobian", dbl, dict(jacobian=True), dict(method="adams", **tol),
                [0.5, 0.5], [0, 0]),
        Variant("jacobian/double", "double pendulum, no Jacobian (DQ)", dbl, dict(jacobian=False),
                dict(method="adams", **tol), [0.5, 0.5], [0, 0]),
        Variant("jacobian/n-link", f"{n}-link, with Jacobian", link, dict(jacobian=True), dict(method="adams", **tol),
                [0.5] * n, [0] * n),
        Variant("jacobian/n-link", f"{n}-link, no Jacobian (DQ)", link, dict(jacobian=False), dict(method="adams", **tol),
                [0.5] * n, [0] * n),
        Variant("outputs", f"{n}-link, outputs: energy", link, dict(jacobian=False, outputs=["energy"]),
                dict(method="adams", **tol), [0.5] * n, [0] * n),
        Variant("outputs", f"{n}-link, outputs: all", link, dict(jacobian=False, outputs=ALL_OUTPUTS),
                dict(method="adams", **tol), [0.5] * n, [0] * n),
        Variant("constants", f"{n}-link, parameters folded", link, dict(jacobian=False, runtime_parameters=[]),
                dict(method="adams", **tol), [0.5] * n, [0] * n),
        Variant("constants", f"{n}-link, parameters run-time", link, dict(jacobian=False, runtime_parameters=None),
                dict(method="adams", **tol), [0.5] * n, [0] * n),
        Variant("sparse", "chain 20, dense Jacobian, dense solver", chain, dict(jacobian=True),
                dict(method="bdf", **tol), cq0, cv0),
        Variant("sparse", "chain 20, sparse Jacobian, band solver", chain, dict(jacobian=False, sparse_jacobian=True),
                dict(method="bdf", linear_solver="band", **tol), cq0, cv0),
        Variant("sparse", "chain 20, no Jacobian, band solver (DQ)", chain, dict(jacobian=False),
                dict(method="bdf", linear_solver="band", jacobian=False, **tol), cq0, cv0),
        Variant("sparse", "chain 20, no Jacobian, dense solver (DQ)", chain, dict(jacobian=False),
                dict(method="bdf", jacobian=False, **tol), cq0, cv0),
    ]
    from lagcodegen.theory.routhian import reduce
    sph = systems.spherical_pendulum("pr_sph")
    red = reduce(sph)
    stol = dict(rtol=1e-10, atol=1e-12)
    out += [
        Variant("Routhian", "spherical pendulum, full", sph, dict(jacobian=True), dict(method="adams", **stol),
                [0.8, 0.0], [0.3, 2.0], T=50.0),
        Variant("Routhian", "spherical pendulum, Routhian-reduced", red, dict(jacobian=True),
                dict(method="adams", **stol), [0.8, 0.0], [0.3, 2.0], T=50.0, reduce_from=red),
    ]
    return out


def measure(v: Variant, k: int, settings, scratch: Path, sim_repeats: int = 0) -> dict:
    """One row; the simulation is timed here if ``sim_repeats``, else later by time_simulations."""
    progress(f"{v.group}: {v.label}")
    prefix = f"pr{k}"
    start = time.perf_counter()
    eom = v.model.eom if v.reduce_from is not None else derive(v.model)
    derive_s = time.perf_counter() - start
    scene_opts = dict(v.scene)  # the reduced scene keeps C_phi (and every parameter) run-time
    gen_times, code = [], None
    for _ in range(settings.repeats):
        start = time.perf_counter()
        code = generate_c(Scene(eom, prefix=prefix, **scene_opts))
        gen_times.append(time.perf_counter() - start)
    files = {name: text for name, text in code.files.items()}
    size = sum(len(t.encode()) for t in files.values())
    lines = sum(t.count("\n") for t in files.values())
    compile_times, cm = [], None
    for r in range(settings.repeats):
        with H.cache_at(scratch / f"cache{k}_{r}"):
            start = time.perf_counter()
            cm = build_code(code)
            compile_times.append(time.perf_counter() - start)
    exe = H.compile_harness(code, scratch / f"harness{k}")
    costs = H.c_call_costs(code, scratch / f"harness{k}", settings) if sim_repeats else {}
    t = np.linspace(0.0, v.T, 1001)
    if v.reduce_from is not None:
        y0, params = v.reduce_from.initial_state(cm, v.q0, v.v0)

        def run():
            return cm.simulate(t, y0=y0, params=params, **v.sim)
    else:
        def run():
            return cm.simulate(t, q0=v.q0, v0=v.v0, params=v.params, **v.sim)
    res = run()  # warm-up
    sim = ", ".join(f"{k_}={val}" for k_, val in v.sim.items() if k_ not in ("atol",))
    row = dict(group=v.group, variant=v.label, states=cm.ny, params=len(cm.param_names), outputs=cm.code.nout,
               bytes=size, lines=lines, derive_s=derive_s, gen_s=float(np.median(gen_times)),
               compile_s=float(np.median(compile_times)), rhs_ns=costs.get("rhs"), jac_ns=costs.get("jac"),
               jac_sparse_ns=costs.get("jac_sparse"), steps=res.stats.get("steps"),
               rhs_evals=res.stats.get("rhs_evals"), integration=f"{sim}, t in [0, {v.T:g}]")
    if sim_repeats:
        row["sim_ms"] = 1e3 * H.median_time(run, sim_repeats)[0]
    else:
        row["_run"], row["_exe"] = run, exe
    return row


def time_harnesses(rows, repeats: int, c_target: float) -> None:
    """rhs_ns, jac_ns, jac_sparse_ns of every row from its C harness, one process per row per
    round, ``repeats`` rounds (round-robin, like time_simulations)."""
    import subprocess
    samples = {id(r): {} for r in rows}
    for _ in range(repeats):
        for r in rows:
            proc = subprocess.run([str(r["_exe"]), repr(c_target)], capture_output=True, text=True, check=True)
            for line in proc.stdout.splitlines():
                name, _calls, ns = line.split()
                samples[id(r)].setdefault(name, []).append(float(ns))
    for r in rows:
        for name, values in samples[id(r)].items():
            r[f"{name}_ns"] = float(np.median(values))
        del r["_exe"]


def time_simulations(rows, repeats: int) -> None:
    """sim_ms of every row: the runs go round-robin over the rows, ``repeats`` rounds, so that
    a burst of machine noise hits every variant alike rather than one row."""
    samples = {id(r): [] for r in rows}
    for _ in range(repeats):
        for r in rows:
            start = time.perf_counter()
            r["_run"]()
            samples[id(r)].append(time.perf_counter() - start)
    for r in rows:
        r["sim_ms"] = 1e3 * float(np.median(samples[id(r)]))
        del r["_run"]


COLUMNS = [
    ("group", "group", "{}"), ("variant", "variant", "{}"), ("states", "ny", "{}"), ("params", "np", "{}"),
    ("outputs", "nout", "{}"), ("bytes", "bytes", "{}"), ("lines", "lines", "{}"), ("gen_s", "gen [s]", "{:.3f}"),
    ("compile_s", "compile [s]", "{:.2f}"), ("rhs_ns", "RHS [ns]", "{:.0f}"), ("jac_ns", "Jac [ns]", "{:.0f}"),
    ("jac_sparse_ns", "sparse Jac [ns]", "{:.0f}"), ("sim_ms", "integrate [ms]", "{:.3f}"), ("steps", "steps", "{}"),
    ("rhs_evals", "RHS evals", "{}"),
]


def ratios(rows) -> list[str]:
    """One line per group: second row relative to the first."""
    out = []
    groups: dict[str, list] = {}
    for r in rows:
        groups.setdefault(r["group"], []).append(r)
    for g, rs in groups.items():
        base = rs[0]
        for r in rs[1:]:
            parts = []
            for key, name in (("bytes", "code"), ("compile_s", "compile"), ("rhs_ns", "RHS"), ("sim_ms", "integrate")):
                if base.get(key) and r.get(key):
                    parts.append(f"{name} x{r[key] / base[key]:.2f}")
            out.append(f"{g}: '{r['variant']}' vs '{base['variant']}': " + ", ".join(parts))
    return out


def main(argv=None) -> int:
    args = parse_args(argv)
    repeats = args.repeats or (1 if args.quick else 3)
    settings = SimpleNamespace(repeats=max(1, repeats), c_target=0.05 if args.quick else 0.1)
    start, load_start = time.perf_counter(), H.load_average()
    rows = []
    with tempfile.TemporaryDirectory(prefix="lcg-pruning-") as tmp:
        scratch = Path(tmp)
        with H.cache_at(scratch / "warm"):  # one untimed build: compiler binaries in the page cache
            build_code(generate_c(Scene(derive(systems.pendulum("pr_warm")))))
        for k, v in enumerate(variants(args.quick)):
            rows.append(measure(v, k, settings, scratch))
        progress("C harness: every variant, round-robin")
        time_harnesses(rows, 2 * settings.repeats - 1, settings.c_target)
        progress("simulate: every variant, round-robin")
        time_simulations(rows, 5 * settings.repeats)
    lines = H.machine_lines("lagcodegen pruning benchmark", (load_start, H.load_average()))
    lines += [f"run:      medians of {settings.repeats} (generation, cold-cache compile), {5 * settings.repeats} (simulate) "
              f"and {2 * settings.repeats - 1} (C harness processes, ~{settings.c_target:g} s per function each)",
              "          bytes/lines: the generated model files (<prefix>.c, .h, and <prefix>_sparse.c/.h when "
              "emitted); compile: cffi module + native CVODE driver", ""]
    lines += [H.format_table(COLUMNS, rows), "", "integration of each row:"]
    lines += [f"  {r['variant']}: {r['integration']}" for r in rows]
    lines += ["", "ratios (each variant against the first of its group):"] + [f"  {x}" for x in ratios(rows)]
    text = "\n".join(lines) + "\n"
    print(text, end="")
    if args.out is not None:
        H.write_report(args.out, "pruning", text, rows)
        progress(f"wrote {args.out}/pruning.txt and pruning.csv")
    progress(f"done in {time.perf_counter() - start:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
