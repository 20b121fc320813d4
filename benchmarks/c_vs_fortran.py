"""Cost of one right-hand side (and Jacobian) call: generated C vs generated Fortran.

For the planar n-link pendulum (n = 1..10; ``--quick``: n = 1..4) this generates the same
scene (all parameters at run time, Jacobian, no outputs) with both backends under two
prefixes (``c_pendulum<n>``, ``f_pendulum<n>``), compiles the C with ``cc -O2 -std=c99`` and
the Fortran with ``gfortran -O2 -std=f2008`` (build()'s default optimization), and links
both into ONE small C timing harness, which measures them side by side: rounds alternate
C and Fortran, each measurement a loop of calls timed with clock_gettime(CLOCK_MONOTONIC)
(about ``target`` seconds), the state perturbed on every call so that nothing is reused.
The table shows the median of 5 measurements (``--quick``: 3) in ns per call, the ratio
Fortran / C, and the largest relative difference between the two results at the initial
state (0 when both compilers produce bit-identical arithmetic).

This is a measuring instrument: it asserts nothing about the times it reports.

Usage::

    python benchmarks/c_vs_fortran.py [--quick] [--out DIR]
"""

from __future__ import annotations

import argparse
import datetime
import os
import platform
import statistics
import string
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import lagcodegen
from lagcodegen import Scene, derive, generate_c, generate_fortran, systems

import _harness  # noqa: E402  (benchmarks/ is on sys.path when run as a script)

Q0 = 0.5  # initial angle of every link [rad]; velocities 0.1


def parse_args(argv=None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="n = 1..4, 3 repeats, short measurements")
    ap.add_argument("--out", metavar="DIR", type=Path,
                    help="also write the table to DIR/c_vs_fortran.txt and DIR/c_vs_fortran.csv")
    return ap.parse_args(argv)


def progress(message: str) -> None:
    print(f"[c_vs_fortran] {message}", file=sys.stderr, flush=True)


def tool(env: str, default: str) -> str:
    return os.environ.get(env) or default


def first_line(cmd: list[str]) -> str:
    try:
        out = subprocess.run([*cmd, "--version"], capture_output=True, text=True, timeout=30).stdout
    except (OSError, subprocess.TimeoutExpired):
        return f"{cmd[0]} (not runnable)"
    return out.splitlines()[0] if out else cmd[0]


def cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


HARNESS = string.Template(r"""
/* Side-by-side timing of c_${name}_rhs/jac (C) and f_${name}_rhs/jac (Fortran). */
#define _POSIX_C_SOURCE 199309L
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "c_${name}.h"
#include "f_${name}.h"

#define NQ ${NQ}
#define NY ${NY}

typedef int (*rhs_fn)(double, const double *, const double *, double *);
typedef int (*jac_fn)(double, const double *, const double *, const double *, double *);

static const double p[] = {${params}};
static double y0[NY], y[NY], ydot[NY], ydot_f[NY], jac[NY * NY], jac_f[NY * NY];
static volatile double sink;
static long failures;
static rhs_fn rhs_now;
static jac_fn jac_now;

static double now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

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
        failures += rhs_now(0.0, y, p, ydot) != 0;
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
        failures += jac_now(0.0, y, ydot, p, jac) != 0;
        sink += jac[NY * NY - 1];
    }
    return now() - start;
}

static long calibrate(double (*run)(long), double target)
{
    long calls = 16;
    double s;
    while ((s = run(calls)) < 0.01 && calls < (1L << 40))
        calls *= 4;
    calls = (long)((double)calls * target / s);
    return calls > 0 ? calls : 1;
}

static double max_rel_diff(const double *a, const double *b, int n)
{
    double scale = 0.0, diff = 0.0;
    int i;
    for (i = 0; i < n; ++i) {
        if (fabs(a[i]) > scale)
            scale = fabs(a[i]);
        if (fabs(a[i] - b[i]) > diff)
            diff = fabs(a[i] - b[i]);
    }
    return scale > 0.0 ? diff / scale : diff;
}

int main(int argc, char **argv)
{
    double target = argc > 1 ? atof(argv[1]) : 0.2;
    int repeats = argc > 2 ? atoi(argv[2]) : 5, i, r, lang;
    rhs_fn rhs[2] = {c_${name}_rhs, f_${name}_rhs};
    jac_fn jacs[2] = {c_${name}_jac, f_${name}_jac};
    const char *names[2] = {"c", "fortran"};
    long rhs_calls[2], jac_calls[2];

    for (i = 0; i < NQ; ++i) {
        y0[i] = ${q0};
        y0[NQ + i] = 0.1;
    }
    perturb(0);
    if (c_${name}_rhs(0.0, y, p, ydot) != 0 || f_${name}_rhs(0.0, y, p, ydot_f) != 0) {
        fprintf(stderr, "rhs fails at the initial state\n");
        return 1;
    }
    printf("diff rhs %.3e\n", max_rel_diff(ydot, ydot_f, NY));
    if (c_${name}_jac(0.0, y, ydot, p, jac) != 0 || f_${name}_jac(0.0, y, ydot, p, jac_f) != 0) {
        fprintf(stderr, "jac fails at the initial state\n");
        return 1;
    }
    printf("diff jac %.3e\n", max_rel_diff(jac, jac_f, NY * NY));

    for (lang = 0; lang < 2; ++lang) { /* calibrate once per function: same call count per round */
        rhs_now = rhs[lang];
        jac_now = jacs[lang];
        rhs_calls[lang] = calibrate(run_rhs, target);
        jac_calls[lang] = calibrate(run_jac, target);
    }
    for (r = 0; r < repeats; ++r)
        for (lang = 0; lang < 2; ++lang) { /* C, Fortran, C, Fortran, ... */
            rhs_now = rhs[lang];
            jac_now = jacs[lang];
            printf("rhs %s %.6e\n", names[lang], 1e9 * run_rhs(rhs_calls[lang]) / (double)rhs_calls[lang]);
            printf("jac %s %.6e\n", names[lang], 1e9 * run_jac(jac_calls[lang]) / (double)jac_calls[lang]);
        }
    if (failures) {
        fprintf(stderr, "%ld calls returned an error\n", failures);
        return 1;
    }
    return 0;
}
""")


def measure(n: int, folder: Path, target: float, repeats: int, cc: str, fc: str) -> dict:
    """One row: generate both backends for the n-link pendulum, build the harness, run it."""
    name = f"pendulum{n}"
    progress(f"n = {n}: derive and generate")
    t0 = time.perf_counter()
    eom = derive(systems.n_link_pendulum(n))
    c_code = generate_c(Scene(eom, prefix=f"c_{name}"))
    f_code = generate_fortran(Scene(eom, prefix=f"f_{name}"))
    gen_s = time.perf_counter() - t0
    folder.mkdir(parents=True, exist_ok=True)
    c_code.write(folder)
    f_code.write(folder)
    params = ", ".join(repr(float(v)) for v in c_code.param_defaults) or "0.0"
    (folder / "harness.c").write_text(HARNESS.substitute(name=name, NQ=n, NY=c_code.ny, params=params,
                                                         q0=repr(Q0)))
    progress(f"n = {n}: compile")
    cmds = [[fc, "-O2", "-std=f2008", "-c", f"f_{name}.f90", "-o", f"f_{name}.o"],
            [cc, "-O2", "-std=c99", "-c", f"c_{name}.c", "-o", f"c_{name}.o"],
            [cc, "-O2", "-std=c99", "harness.c", f"c_{name}.o", f"f_{name}.o", "-o", "harness", "-lgfortran",
             "-lm"]]
    for cmd in cmds:
        proc = subprocess.run(cmd, cwd=folder, capture_output=True, text=True)
        if proc.returncode != 0:
            raise RuntimeError(f"{' '.join(cmd)} failed:\n{proc.stdout}{proc.stderr}")
    progress(f"n = {n}: measure")
    proc = subprocess.run([str(folder / "harness"), repr(target), str(repeats)], capture_output=True, text=True)
    if proc.returncode != 0:
        raise RuntimeError(f"the harness failed: {proc.stderr.strip()}")
    samples: dict[tuple[str, str], list[float]] = {}
    diff = {}
    for line in proc.stdout.splitlines():
        what, lang, value = line.split()
        if what == "diff":
            diff[lang] = float(value)
        else:
            samples.setdefault((what, lang), []).append(float(value))
    med = {key: statistics.median(values) for key, values in samples.items()}
    return dict(n=n, ny=c_code.ny, gen_s=gen_s,
                rhs_c=med["rhs", "c"], rhs_f=med["rhs", "fortran"], rhs_ratio=med["rhs", "fortran"] / med["rhs", "c"],
                jac_c=med["jac", "c"], jac_f=med["jac", "fortran"], jac_ratio=med["jac", "fortran"] / med["jac", "c"],
                diff_rhs=diff["rhs"], diff_jac=diff["jac"])


COLUMNS = [
    ("n", "n", "{}"),
    ("ny", "NY", "{}"),
    ("rhs_c", "RHS C [ns]", "{:.0f}"),
    ("rhs_f", "RHS Fortran [ns]", "{:.0f}"),
    ("rhs_ratio", "Fortran/C", "{:.2f}"),
    ("jac_c", "Jac C [ns]", "{:.0f}"),
    ("jac_f", "Jac Fortran [ns]", "{:.0f}"),
    ("jac_ratio", "Fortran/C", "{:.2f}"),
    ("diff_rhs", "rel. diff RHS", "{:.1e}"),
    ("diff_jac", "rel. diff Jac", "{:.1e}"),
]


def table(rows: list[dict]) -> list[str]:
    cells = [[head for _, head, _ in COLUMNS]] + [[fmt.format(r[key]) for key, _, fmt in COLUMNS] for r in rows]
    widths = [max(len(row[i]) for row in cells) for i in range(len(COLUMNS))]
    lines = ["  ".join(c.rjust(w) for c, w in zip(row, widths)) for row in cells]
    lines.insert(1, "  ".join("-" * w for w in widths))
    return lines


def main(argv=None) -> int:
    args = parse_args(argv)
    links = range(1, 5) if args.quick else range(1, 11)
    repeats, target = (3, 0.05) if args.quick else (5, 0.2)
    cc, fc = tool("CC", "cc"), tool("FC", "gfortran")
    header = [
        f"lagcodegen C vs Fortran RHS/Jacobian benchmark, {datetime.datetime.now().isoformat(timespec='seconds')}",
        f"machine:  {cpu_model()}, os.cpu_count() = {os.cpu_count()}, {platform.platform()}",
        f"lagcodegen {lagcodegen.__version__}; C: {first_line([cc])} (-O2 -std=c99); "
        f"Fortran: {first_line([fc])} (-O2 -std=f2008)",
        f"n-link pendulum, state q = {Q0}, q' = 0.1 perturbed per call; one harness calls both, alternating; "
        f"median of {repeats} measurements of ~{target:g} s each",
    ]
    rows = []
    with tempfile.TemporaryDirectory(prefix="lcg-c-vs-f-") as scratch:
        for n in links:
            rows.append(measure(n, Path(scratch) / f"n{n}", target, repeats, cc, fc))
    lines = header + [""] + table(rows)
    print("\n".join(lines))
    if args.out:
        _harness.write_report(args.out, "c_vs_fortran", "\n".join(lines), rows)
        progress(f"wrote {args.out / 'c_vs_fortran.txt'} and {args.out / 'c_vs_fortran.csv'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
