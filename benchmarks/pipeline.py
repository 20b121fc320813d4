"""Measure the lagcodegen pipeline: derive -> generate C -> compile -> evaluate -> integrate.

For the double pendulum and the planar n-link pendulum (n = 1, 2, 3, 5, 8, 10) this prints
one row per system:

* derive [s]        ``lagcodegen.derive(model)``, median of a few runs;
* gen / compile [s] ``generate_c(Scene(eom, outputs=["energy"]))`` and ``build_code(code)`` from a
                    cold cache (a fresh, empty LAGCODEGEN_CACHE folder per system);
* rhs / jac [ns]    cost of one call of ``<prefix>_rhs`` / ``<prefix>_jac``, measured in C by a
                    small harness compiled with ``cc -O2 -std=c99`` (no Python involved);
* native / sksundae [ms]  ``simulate`` over t in [0, 10] from q0 = 0.5 rad, Adams, rtol 1e-8,
                    atol 1e-10, with both backends; RHS evaluations of each and the largest
                    difference between their final states.

A derivation-only row follows for n = 20 (with ``--large``: a full row for n = 20 and a
derivation-only row for n = 50). A second table compares BDF and Adams, analytic and
difference-quotient Jacobian, for the double pendulum on the native backend.

This is a measuring instrument: it asserts nothing about the times it reports.

Usage::

    python benchmarks/pipeline.py [--quick | --large] [--out DIR]
"""

from __future__ import annotations

import argparse
import datetime
import importlib.metadata
import os
import platform
import shutil
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

import lagcodegen
from lagcodegen import Scene, build_code, derive, generate_c, systems
from lagcodegen.build import find_sundials

sys.path.insert(0, str(Path(__file__).resolve().parent))
# The C timing harness and the shared helpers (also imported from here by older scripts).
from _harness import (c_call_costs, c_compiler, cache_at, compile_harness, compiler_version,  # noqa: E402,F401
                      cpu_model, format_table, harness_source, load_average, median_time, write_csv)

T_GRID = np.linspace(0.0, 10.0, 1001)
Q0 = 0.5                      # initial angle of every link [rad]
TOLERANCES = dict(rtol=1e-8, atol=1e-10)
DERIVE_BUDGET = 5.0           # seconds: stop repeating a derivation after this much


# --------------------------------------------------------------------------- settings
@dataclass(frozen=True)
class Settings:
    """How much to measure: which systems, how many repeats, how long per C timing."""

    links: tuple[int, ...]           # n-link pendulums with a full row
    derive_only: tuple[int, ...]     # n-link pendulums with a derivation-only row
    repeats: int                     # runs per median (derive, simulate, C timing)
    c_target: float                  # seconds per C timing measurement


def parse_args(argv=None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    size = ap.add_mutually_exclusive_group()
    size.add_argument("--quick", action="store_true",
                      help="n-link pendulums up to n = 3 only, fewer repeats (well under 2 minutes)")
    size.add_argument("--large", action="store_true",
                      help="add a full row for n = 20 and a derivation-only row for n = 50")
    ap.add_argument("--out", metavar="DIR", type=Path,
                    help="also write the table to DIR/pipeline.txt and DIR/pipeline.csv")
    return ap.parse_args(argv)


def settings_from(args: argparse.Namespace) -> Settings:
    if args.quick:
        return Settings(links=(1, 2, 3), derive_only=(), repeats=3, c_target=0.05)
    if args.large:
        return Settings(links=(1, 2, 3, 5, 8, 10, 20), derive_only=(50,), repeats=5, c_target=0.2)
    return Settings(links=(1, 2, 3, 5, 8, 10), derive_only=(20,), repeats=5, c_target=0.2)


def progress(message: str) -> None:
    print(f"[pipeline] {message}", file=sys.stderr, flush=True)


# --------------------------------------------------------------------------- environment
def header_lines(settings: Settings, load: tuple[str, str]) -> list[str]:
    versions = {
        "lagcodegen": lagcodegen.__version__,
        "sympy": importlib.metadata.version("sympy"),
        "symengine": importlib.metadata.version("symengine"),
        "numpy": np.__version__,
        "scikit-sundae": importlib.metadata.version("scikit-sundae"),
    }
    return [
        f"lagcodegen pipeline benchmark, {datetime.datetime.now().isoformat(timespec='seconds')}",
        f"machine:  {cpu_model()}, os.cpu_count() = {os.cpu_count()}, {platform.platform()}",
        f"load:     1-minute load average {load[0]} at start, {load[1]} at end",
        f"python:   {platform.python_version()}; " + ", ".join(f"{k} {v}" for k, v in versions.items())
        + f"; SUNDIALS {find_sundials().version}",
        f"compiler: {compiler_version(c_compiler())}",
        f"run:      t in [0, 10], q0 = {Q0} rad for every angle, v0 = 0, Adams, rtol {TOLERANCES['rtol']:g}, "
        f"atol {TOLERANCES['atol']:g}",
        f"          medians of {settings.repeats} runs (derive: up to {settings.repeats} within "
        f"{DERIVE_BUDGET:g} s); gen/compile: one run each, cold cache (after one untimed warm-up build)",
        f"          RHS/Jac: C harness (cc -O2 -std=c99), state q = {Q0}, q' = 0.1 perturbed per call, "
        f"~{settings.c_target:g} s per measurement",
    ]


# --------------------------------------------------------------------------- pipeline stages
def time_derive(model, settings: Settings):
    """(equations of motion, median seconds of derive(model))."""
    seconds, eom = median_time(lambda: derive(model), settings.repeats, DERIVE_BUDGET)
    return eom, seconds


def time_build(eom, cache: Path):
    """Generate and compile from the empty cache folder ``cache``: (code, model, gen s, compile s)."""
    start = time.perf_counter()
    code = generate_c(Scene(eom, outputs=["energy"]))
    generated = time.perf_counter()
    with cache_at(cache):
        cm = build_code(code)
    compiled = time.perf_counter()
    if cm.cached:
        raise RuntimeError(f"{cache} was expected to be empty, but build_code() found the module cached")
    return code, cm, generated - start, compiled - generated


# --------------------------------------------------------------------------- integration
def time_simulate(cm, repeats: int, **options):
    """Median seconds of ``cm.simulate`` over T_GRID from q0 = Q0, and the result of a
    warm-up run (which is not timed: it pays for one-time imports)."""
    q0 = [Q0] * cm.n

    def run():
        return cm.simulate(T_GRID, q0=q0, **TOLERANCES, **options)

    result = run()
    seconds, _ = median_time(run, repeats)
    return seconds, result


def compare_backends(cm, settings: Settings) -> dict:
    """Adams on both backends: median times, RHS evaluations, final-state difference."""
    native_s, native = time_simulate(cm, settings.repeats, method="adams", backend="native")
    sk_s, sk = time_simulate(cm, settings.repeats, method="adams", backend="sksundae")
    return dict(native_ms=1e3 * native_s, sksundae_ms=1e3 * sk_s, ratio=sk_s / native_s,
                rhs_native=native.stats["rhs_evals"], rhs_sksundae=sk.stats["rhs_evals"],
                max_diff=float(np.max(np.abs(native.y[-1] - sk.y[-1]))))


def solver_variants(label: str, cm, settings: Settings) -> list[dict]:
    """Native backend: BDF and Adams, each with the analytic and the difference-quotient Jacobian."""
    rows = []
    for method in ("adams", "bdf"):
        for analytic in (True, False):
            seconds, res = time_simulate(cm, settings.repeats, method=method, jacobian=analytic,
                                         backend="native")
            s = res.stats
            rows.append(dict(table="solvers", system=label, n=cm.n, method=method,
                             jacobian="analytic" if analytic else "diff. quotient", wall_ms=1e3 * seconds,
                             steps=s["steps"], rhs_evals=s["rhs_evals"], rhs_evals_dq=s["rhs_evals_dq"],
                             jac_evals=s["jac_evals"]))
    return rows


# --------------------------------------------------------------------------- rows
def warm_up(scratch: Path) -> None:
    """One untimed build of the simple pendulum, so that the first measured row does not pay
    for one-time costs (compiler version probe, SUNDIALS lookup, compiler binaries not yet in
    the page cache)."""
    progress("warm-up build (not timed)")
    time_build(derive(systems.pendulum()), scratch)


def measure_system(label: str, model, settings: Settings, scratch: Path):
    """One full row of the systems table, and the compiled model."""
    n = model.n
    progress(f"{label} (n={n}): derive")
    eom, derive_s = time_derive(model, settings)
    progress(f"{label} (n={n}): generate + compile (cold cache)")
    code, cm, gen_s, compile_s = time_build(eom, scratch / "cache")
    progress(f"{label} (n={n}): rhs/jac in C")
    costs = c_call_costs(code, scratch / "harness", settings)
    progress(f"{label} (n={n}): simulate, native and sksundae")
    row = dict(table="systems", system=label, n=n, derive_s=derive_s, gen_s=gen_s, compile_s=compile_s,
               gen_compile_s=gen_s + compile_s, c_kib=len(code.files[code.source_name]) / 1024,
               rhs_ns=costs["rhs"], jac_ns=costs["jac"])
    row.update(compare_backends(cm, settings))
    return row, cm


def measure_derivation(label: str, model, settings: Settings) -> dict:
    """A derivation-only row of the systems table."""
    progress(f"{label} (n={model.n}): derive only")
    _, derive_s = time_derive(model, settings)
    return dict(table="systems", system=label, n=model.n, derive_s=derive_s)


# --------------------------------------------------------------------------- output
# (key, heading, format) of each column; a missing value prints as "-".
SYSTEM_COLUMNS = [
    ("system", "system", "{}"),
    ("n", "n", "{}"),
    ("derive_s", "derive [s]", "{:.4f}"),
    ("gen_s", "gen [s]", "{:.3f}"),
    ("compile_s", "compile [s]", "{:.2f}"),
    ("gen_compile_s", "gen+compile [s]", "{:.2f}"),
    ("c_kib", "C [KiB]", "{:.0f}"),
    ("rhs_ns", "RHS [ns/call]", "{:.0f}"),
    ("jac_ns", "Jac [ns/call]", "{:.0f}"),
    ("native_ms", "native [ms]", "{:.2f}"),
    ("sksundae_ms", "sksundae [ms]", "{:.2f}"),
    ("ratio", "sks/native", "{:.1f}"),
    ("rhs_native", "RHS evals native", "{}"),
    ("rhs_sksundae", "RHS evals sks", "{}"),
    ("max_diff", "max |dy(10)|", "{:.1e}"),
]

SOLVER_COLUMNS = [
    ("method", "method", "{}"),
    ("jacobian", "Jacobian", "{}"),
    ("wall_ms", "wall [ms]", "{:.2f}"),
    ("steps", "steps", "{}"),
    ("rhs_evals", "RHS evals", "{}"),
    ("rhs_evals_dq", "of which DQ", "{}"),
    ("jac_evals", "Jac evals", "{}"),
]


LEGEND = [
    "gen+compile: generate_c + build (cffi module with the native CVODE driver); C: size of <prefix>.c",
    "sksundae: includes its Python-side evaluation of the outputs at the 1001 output times "
    "(native: in C)",
    "sks/native: sksundae time / native time",
    "max |dy(10)|: largest |native - sksundae| over the state at t = 10",
    "rows with '-': derivation only",
]


def report(settings: Settings, load: tuple[str, str], system_rows, solver_rows) -> str:
    parts = header_lines(settings, load)
    parts += ["", "Systems", "", format_table(SYSTEM_COLUMNS, system_rows), "", *LEGEND]
    if solver_rows:
        parts += ["", f"double pendulum, rtol {TOLERANCES['rtol']:g}, BDF vs Adams, analytic vs "
                  "difference-quotient Jacobian (native backend)", "",
                  format_table(SOLVER_COLUMNS, solver_rows)]
    return "\n".join(parts) + "\n"


def write_outputs(folder: Path, text: str, rows) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "pipeline.txt").write_text(text)
    write_csv(folder / "pipeline.csv", rows)
    progress(f"wrote {folder / 'pipeline.txt'} and {folder / 'pipeline.csv'}")


# --------------------------------------------------------------------------- main
def main(argv=None) -> int:
    args = parse_args(argv)
    settings = settings_from(args)
    if shutil.which(c_compiler()) is None:
        print(f"pipeline: C compiler {c_compiler()!r} not found (set CC)", file=sys.stderr)
        return 2
    start, load_start = time.perf_counter(), load_average()
    system_rows = []
    with tempfile.TemporaryDirectory(prefix="lagcodegen-bench-") as tmp:
        scratch = Path(tmp)
        warm_up(scratch / "warm-up")
        row, cm = measure_system("double pendulum", systems.double_pendulum(), settings, scratch / "double")
        system_rows.append(row)
        progress("double pendulum: BDF vs Adams, analytic vs difference-quotient Jacobian")
        solver_rows = solver_variants("double pendulum", cm, settings)
        for n in settings.links:
            row, _ = measure_system("n-link pendulum", systems.n_link_pendulum(n), settings,
                                    scratch / f"links{n}")
            system_rows.append(row)
    for n in settings.derive_only:
        system_rows.append(measure_derivation("n-link pendulum", systems.n_link_pendulum(n), settings))
    text = report(settings, (load_start, load_average()), system_rows, solver_rows)
    print(text, end="")
    if args.out is not None:
        write_outputs(args.out, text, system_rows + solver_rows)
    progress(f"done in {time.perf_counter() - start:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
