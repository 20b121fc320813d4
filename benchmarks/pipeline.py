"""Measure the lagcodegen pipeline: derive -> generate C -> compile -> evaluate -> integrate.

For the double pendulum and the planar n-link pendulum (n = 1, 2, 3, 5, 8, 10) this prints
one row per system:

* derive [s]        ``lagcodegen.derive(model)``, median of a few runs;
* gen / compile [s] ``generate_c(Scene(eom, outputs=["energy"]))`` and ``build(code)`` from a
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
import contextlib
import csv
import datetime
import importlib.metadata
import io
import os
import platform
import shutil
import statistics
import string
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

import lagcodegen
from lagcodegen import Scene, build, derive, generate_c, systems
from lagcodegen.build import find_sundials

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


def c_compiler() -> str:
    """The compiler build() uses, so that the harness sees the same code generation."""
    return os.environ.get("CC") or "cc"


# --------------------------------------------------------------------------- environment
def cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def compiler_version(cc: str) -> str:
    try:
        out = subprocess.run([cc, "--version"], capture_output=True, text=True, timeout=30).stdout
    except (OSError, subprocess.TimeoutExpired):
        return f"{cc} (not runnable)"
    return out.splitlines()[0] if out else cc


def load_average() -> str:
    """1-minute load average, to judge how busy the machine was."""
    try:
        return f"{os.getloadavg()[0]:.2f}"
    except OSError:
        return "n/a"


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


# --------------------------------------------------------------------------- timing helpers
def median_time(fn, repeats: int, budget: float = float("inf")):
    """Median wall time of ``fn()`` over up to ``repeats`` runs (fewer once ``budget`` seconds
    are spent), and the value of the last run."""
    times, value = [], None
    while len(times) < repeats and sum(times) < budget:
        start = time.perf_counter()
        value = fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times), value


@contextlib.contextmanager
def cache_at(folder: Path):
    """Point LAGCODEGEN_CACHE at ``folder`` for the duration of the block."""
    old = os.environ.get("LAGCODEGEN_CACHE")
    os.environ["LAGCODEGEN_CACHE"] = str(folder)
    try:
        yield
    finally:
        if old is None:
            del os.environ["LAGCODEGEN_CACHE"]
        else:
            os.environ["LAGCODEGEN_CACHE"] = old


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
        cm = build(code)
    compiled = time.perf_counter()
    if cm.cached:
        raise RuntimeError(f"{cache} was expected to be empty, but build() found the module cached")
    return code, cm, generated - start, compiled - generated


# --------------------------------------------------------------------------- C harness
HARNESS = string.Template(r"""
/* Timing harness for ${prefix}_rhs and ${prefix}_jac (generated by benchmarks/pipeline.py). */
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "${prefix}.h"

#define NQ ${PREFIX}_NQ
#define NY ${PREFIX}_NY

static const double p[] = {${params}};
static double y0[NY], y[NY], ydot[NY], jac[NY * NY];
static volatile double sink;
static long failures;

static double now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* A slightly different state on every call, so that no result can be reused. */
static void perturb(long k)
{
    double d = 1e-9 * (double)(k & 1023);
    int i;
    for (i = 0; i < NY; ++i)
        y[i] = y0[i] + d;
}

static double run_rhs(long calls)
{
    double start = now();
    long k;
    for (k = 0; k < calls; ++k) {
        perturb(k);
        failures += ${prefix}_rhs(0.0, y, p, ydot) != 0;
        sink += ydot[NY - 1];
    }
    return now() - start;
}

static double run_jac(long calls)
{
    double start = now();
    long k;
    for (k = 0; k < calls; ++k) {
        perturb(k);
        failures += ${prefix}_jac(0.0, y, ydot, p, jac) != 0;
        sink += jac[NY * NY - 1];
    }
    return now() - start;
}

/* Number of calls that take about `target` seconds. */
static long calibrate(double (*run)(long), double target)
{
    long calls = 16;
    double s;
    while ((s = run(calls)) < 0.01 && calls < (1L << 40))
        calls *= 4;
    calls = (long)((double)calls * target / s);
    return calls > 0 ? calls : 1;
}

static void measure(const char *name, double (*run)(long), double target)
{
    long calls = calibrate(run, target);
    printf("%s %ld %.6e\n", name, calls, 1e9 * run(calls) / (double)calls);
}

/* One measurement of each function, about `target` (argv[1], seconds) long. */
int main(int argc, char **argv)
{
    double target = argc > 1 ? atof(argv[1]) : 0.2;
    int i;

    for (i = 0; i < NQ; ++i) {
        y0[i] = ${q0};
        y0[NQ + i] = 0.1;
    }
    perturb(0);
    if (${prefix}_rhs(0.0, y, p, ydot) != 0) {
        fprintf(stderr, "${prefix}_rhs fails at the initial state\n");
        return 1;
    }
    measure("rhs", run_rhs, target);
    measure("jac", run_jac, target);
    if (failures) {
        fprintf(stderr, "%ld calls returned an error\n", failures);
        return 1;
    }
    return 0;
}
""")


def harness_source(code) -> str:
    params = ", ".join(repr(float(v)) for v in code.param_defaults) or "0.0"
    return HARNESS.substitute(prefix=code.prefix, PREFIX=code.prefix.upper(), params=params, q0=repr(Q0))


def compile_harness(code, folder: Path) -> Path:
    """Write the generated sources and the harness into ``folder`` and compile them."""
    code.write(folder)
    (folder / "harness.c").write_text(harness_source(code))
    exe = folder / "harness"
    cmd = [c_compiler(), "-O2", "-std=c99", "harness.c", code.source_name, "-o", exe.name, "-lm"]
    proc = subprocess.run(cmd, cwd=folder, capture_output=True, text=True)
    if proc.returncode != 0:
        raise RuntimeError(f"compiling the harness failed:\n{' '.join(cmd)}\n{proc.stdout}{proc.stderr}")
    return exe


def c_call_costs(code, folder: Path, settings: Settings) -> dict[str, float]:
    """Median ns per call of rhs and jac over ``settings.repeats`` runs of the harness.

    Each repeat is a separate process, so that a short burst of machine noise (common on
    virtual machines) spoils one sample rather than all of them.
    """
    exe = compile_harness(code, folder)
    samples: dict[str, list[float]] = {}
    for _ in range(settings.repeats):
        proc = subprocess.run([str(exe), repr(settings.c_target)], capture_output=True, text=True)
        if proc.returncode != 0:
            raise RuntimeError(f"the timing harness failed: {proc.stderr.strip()}")
        for line in proc.stdout.splitlines():
            name, _calls, ns = line.split()
            samples.setdefault(name, []).append(float(ns))
    return {name: statistics.median(values) for name, values in samples.items()}


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


def format_table(columns, rows) -> str:
    """Plain-text table; text columns left-aligned, numbers right-aligned."""
    cells = [[fmt.format(row[key]) if row.get(key) is not None else "-" for key, _, fmt in columns]
             for row in rows]
    headings = [heading for _, heading, _ in columns]
    widths = [max([len(h)] + [len(r[i]) for r in cells]) for i, h in enumerate(headings)]
    left = [all(isinstance(row.get(key), str) for row in rows) for key, _, _ in columns]

    def line(values):
        padded = (v.ljust(w) if lft else v.rjust(w) for v, w, lft in zip(values, widths, left))
        return "  ".join(padded).rstrip()

    rule = "  ".join("-" * w for w in widths)
    return "\n".join([line(headings), rule, *(line(r) for r in cells)])


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


def write_csv(path: Path, rows) -> None:
    keys = []
    for row in rows:
        keys += [k for k in row if k not in keys]
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=keys, lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    path.write_text(buf.getvalue())


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
