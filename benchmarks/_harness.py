"""Shared pieces of the benchmark scripts: machine description, timing, the C timing harness,
reference solutions, error metrics, work-precision interpolation, tables, CSV and plots.

Nothing here asserts anything about the numbers it measures.
"""

from __future__ import annotations

import contextlib
import csv
import datetime
import io
import math
import os
import platform
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

Q0 = 0.5  # coordinate value of every coordinate in the C harness state


# --------------------------------------------------------------------------- environment
def progress(tag: str, message: str) -> None:
    print(f"[{tag}] {message}", file=sys.stderr, flush=True)


def c_compiler() -> str:
    """The compiler build() uses, so that the harness sees the same code generation."""
    return os.environ.get("CC") or "cc"


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


def machine_lines(title: str, load: tuple[str, str] | None = None) -> list[str]:
    """Header lines: title with date, machine, load, versions, compiler."""
    import importlib.metadata
    import lagcodegen
    versions = {"lagcodegen": lagcodegen.__version__}
    for pkg in ("numpy", "scipy", "sympy", "symengine", "scikit-sundae"):
        try:
            versions[pkg] = importlib.metadata.version(pkg)
        except importlib.metadata.PackageNotFoundError:
            versions[pkg] = "absent"
    lines = [f"{title}, {datetime.datetime.now().isoformat(timespec='seconds')}",
             f"machine:  {cpu_model()}, os.cpu_count() = {os.cpu_count()}, {platform.platform()}"]
    if load is not None:
        lines.append(f"load:     1-minute load average {load[0]} at start, {load[1]} at end")
    lines += [f"python:   {platform.python_version()}; " + ", ".join(f"{k} {v}" for k, v in versions.items()),
              f"compiler: {compiler_version(c_compiler())}"]
    return lines


# --------------------------------------------------------------------------- timing
def cpu_medians(runs: dict, rounds: int, label: str, warm: bool = True) -> dict:
    """Median thread CPU time of each run of ``runs`` (name -> callable) over interleaved rounds
    (after one call each, unless ``warm`` is False); progress lines tagged ``label``."""
    if warm:
        for f in runs.values():
            f()
    cpu = {k: [] for k in runs}
    for r in range(rounds):
        progress(label, f"round {r + 1}/{rounds}")
        for k, f in runs.items():
            start = time.thread_time()
            f()
            cpu[k].append(time.thread_time() - start)
    return {k: statistics.median(v) for k, v in cpu.items()}


def timed_medians(runs: dict, rounds: int, label: str, budget: float = float("inf")) -> tuple[dict, dict, dict]:
    """(wall-time medians, thread-CPU-time medians, numbers of timed calls) of each run of ``runs`` (name -> callable)
    over interleaved rounds (no warm-up call: make them first); a run stops being timed once its
    wall times add up to ``budget`` seconds. Progress lines tagged ``label``."""
    wall = {k: [] for k in runs}
    cpu = {k: [] for k in runs}
    for r in range(rounds):
        progress(label, f"round {r + 1}/{rounds}")
        for k, f in runs.items():
            if wall[k] and sum(wall[k]) > budget:
                continue
            start, start_cpu = time.perf_counter(), time.thread_time()
            f()
            cpu[k].append(time.thread_time() - start_cpu)
            wall[k].append(time.perf_counter() - start)
    return ({k: statistics.median(v) for k, v in wall.items()}, {k: statistics.median(v) for k, v in cpu.items()},
            {k: len(v) for k, v in wall.items()})


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


# --------------------------------------------------------------------------- C harness
HARNESS_HEAD = r"""
/* Timing harness for the functions of ${prefix} (generated by benchmarks/_harness.py). */
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "${prefix}.h"
${includes}
#define NQ ${PREFIX}_NQ
#define NY ${PREFIX}_NY

static const double p[] = {${params}};
static double y0[NY], y[NY], ydot[NY];
${buffers}
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
"""

HARNESS_JAC = r"""
static double run_${name}(long calls)
{
    double start = now();
    long k;
    for (k = 0; k < calls; ++k) {
        perturb(k);
        failures += ${call} != 0;
        sink += ${last};
    }
    return now() - start;
}
"""

HARNESS_MAIN = r"""
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
${measures}    if (failures) {
        fprintf(stderr, "%ld calls returned an error\n", failures);
        return 1;
    }
    return 0;
}
"""


def harness_source(code, q0: float = Q0) -> str:
    """C source timing ``<prefix>_rhs`` and, where the code has them, ``<prefix>_jac`` and
    ``<prefix>_jac_sparse`` (state: every coordinate ``q0``, every velocity 0.1)."""
    from string import Template
    pre, PRE = code.prefix, code.prefix.upper()
    sparse = bool(getattr(code, "sparse_jacobian", False))
    includes, buffers, funcs, measures = "", "", "", ""
    if code.jacobian:
        buffers += "static double jac[NY * NY];\n"
        funcs += Template(HARNESS_JAC).substitute(name="jac", call=f"{pre}_jac(0.0, y, ydot, p, jac)",
                                                  last="jac[NY * NY - 1]")
        measures += '    measure("jac", run_jac, target);\n'
    if sparse:
        includes += f'#include "{pre}_sparse.h"\n'
        buffers += f"static double vals[{PRE}_JAC_NNZ];\n"
        funcs += Template(HARNESS_JAC).substitute(name="jac_sparse",
                                                  call=f"{pre}_jac_sparse(0.0, y, ydot, p, vals)",
                                                  last=f"vals[{PRE}_JAC_NNZ - 1]")
        measures += '    measure("jac_sparse", run_jac_sparse, target);\n'
    params = ", ".join(repr(float(v)) for v in code.param_defaults) or "0.0"
    text = Template(HARNESS_HEAD).substitute(prefix=pre, PREFIX=PRE, params=params, includes=includes,
                                             buffers=buffers)
    text += funcs
    text += Template(HARNESS_MAIN).substitute(prefix=pre, q0=repr(q0), measures=measures)
    return text


def compile_harness(code, folder: Path, q0: float = Q0) -> Path:
    """Write the generated sources and the harness into ``folder`` and compile them
    (``cc -O2 -std=c99``, like build())."""
    folder.mkdir(parents=True, exist_ok=True)
    code.write(folder)
    (folder / "harness.c").write_text(harness_source(code, q0))
    exe = folder / "harness"
    sources = [name for name in sorted(code.files) if name.endswith(".c")]
    cmd = [c_compiler(), "-O2", "-std=c99", "harness.c", *sources, "-o", exe.name, "-lm"]
    proc = subprocess.run(cmd, cwd=folder, capture_output=True, text=True)
    if proc.returncode != 0:
        raise RuntimeError(f"compiling the harness failed:\n{' '.join(cmd)}\n{proc.stdout}{proc.stderr}")
    return exe


def c_call_costs(code, folder: Path, settings, q0: float = Q0) -> dict[str, float]:
    """Median ns per call of rhs (and jac, jac_sparse where present) over ``settings.repeats``
    runs of the harness, each about ``settings.c_target`` seconds per function.

    Each repeat is a separate process, so that a short burst of machine noise (common on
    virtual machines) spoils one sample rather than all of them.
    """
    exe = compile_harness(code, folder, q0)
    samples: dict[str, list[float]] = {}
    for _ in range(settings.repeats):
        proc = subprocess.run([str(exe), repr(settings.c_target)], capture_output=True, text=True)
        if proc.returncode != 0:
            raise RuntimeError(f"the timing harness failed: {proc.stderr.strip()}")
        for line in proc.stdout.splitlines():
            name, _calls, ns = line.split()
            samples.setdefault(name, []).append(float(ns))
    return {name: statistics.median(values) for name, values in samples.items()}


# --------------------------------------------------------------------------- models
from lagcodegen.model.systems import spring_chain  # noqa: E402,F401  (re-exported for the scripts)


def chain_initial(n: int) -> tuple[list[float], list[float]]:
    """The first dimer displaced rigidly by 0.1 (its stiff spring unstretched), all at rest."""
    q0 = [0.0] * n
    q0[0] = q0[1] = 0.1
    return q0, [0.0] * n


def cartesian_pendulum():
    """The bob at (x, y) with x^2 + y^2 = l^2 (eq. 4.1), l = 1, g = 9.81, m = 1."""
    import lagcodegen as lcg
    from lagcodegen.theory.constraints import ConstrainedSystem
    m = lcg.Model("cart_pendulum")
    x, y = m.coordinates("x y")
    l, g, mass = m.parameters(l=1.0, g=9.81, m=1.0)
    m.particle("bob", mass, (x, y))
    m.gravity(g)
    return ConstrainedSystem(m, holonomic=[x**2 + y**2 - l**2])


# --------------------------------------------------------------------------- references and errors
def scipy_solution(fun, t: np.ndarray, y0, method: str, rtol: float, atol, jac=None, budget: float | None = None):
    """solve_ivp on ``fun`` at the times ``t``: (y on the grid (nt x ny), wall seconds, nfev).
    Raises RuntimeError on failure, TimeoutError if it would run past ``budget`` seconds."""
    from scipy.integrate import solve_ivp
    deadline = None if budget is None else time.perf_counter() + budget
    calls = [0]

    def f(tt, y):
        calls[0] += 1
        if deadline is not None and (calls[0] & 255) == 0 and time.perf_counter() > deadline:
            raise TimeoutError(f"{method}: over the time budget of {budget:g} s")
        return fun(tt, y)

    kwargs = {}
    if jac is not None and method in ("Radau", "BDF", "LSODA"):
        kwargs["jac"] = jac
    start = time.perf_counter()
    sol = solve_ivp(f, (t[0], t[-1]), np.asarray(y0, dtype=float), method=method, t_eval=t, rtol=rtol,
                    atol=atol, **kwargs)
    wall = time.perf_counter() - start
    if not sol.success:
        raise RuntimeError(f"solve_ivp {method} failed: {sol.message}")
    return sol.y.T.copy(), wall, int(sol.nfev)


def eliminate(A: list, b: list) -> list:
    """x with A x = b for a matrix of symbolic expressions (heyoka's, casadi's: anything with + - * /),
    by Gaussian elimination without pivoting and back substitution: for the positive definite
    mass matrices of the benchmarks' explicit systems q'' = M^-1 F. ``A`` and ``b`` are
    overwritten."""
    n = len(b)
    for k in range(n):
        for i in range(k + 1, n):
            ratio = A[i][k] / A[k][k]
            for j in range(k + 1, n):
                A[i][j] = A[i][j] - ratio * A[k][j]
            b[i] = b[i] - ratio * b[k]
    x = [None] * n
    for i in reversed(range(n)):
        s = b[i]
        for j in range(i + 1, n):
            s = s - A[i][j] * x[j]
        x[i] = s / A[i][i]
    return x


def error_scales(ref: np.ndarray, floor: float = 1e-3) -> np.ndarray:
    """Per-component scales for relative errors: max_t |ref_i|, at least ``floor`` times the
    largest scale (so that a component that stays near zero is measured absolutely)."""
    s = np.max(np.abs(ref), axis=0)
    return np.maximum(s, floor * max(float(np.max(s)), 1e-300))


def errors(y: np.ndarray, ref: np.ndarray, scales: np.ndarray) -> tuple[float, float]:
    """(final-state error, max error over the grid), each max_i |y_i - ref_i| / scale_i."""
    if y.shape != ref.shape or not np.all(np.isfinite(y)):
        return float("nan"), float("nan")
    e = np.abs(y - ref) / scales
    return float(np.max(e[-1])), float(np.max(e))


# --------------------------------------------------------------------------- work-precision
def interpolate_time(points, target: float) -> float | None:
    """Wall time at ``target`` error from (error, seconds) points: log-log interpolation along
    the points ordered by error; None if the target lies outside the errors reached."""
    pts = sorted((e, t) for e, t in points if e > 0 and t > 0 and math.isfinite(e) and math.isfinite(t))
    if not pts:
        return None
    le = math.log10(target)
    errs = [math.log10(e) for e, _ in pts]
    times = [math.log10(t) for _, t in pts]
    if not (errs[0] <= le <= errs[-1]):
        return None
    return float(10 ** np.interp(le, errs, times))


def time_at(points, target: float) -> tuple[float | None, str]:
    """(seconds, how) to reach ``target`` error: interpolated ("interp"), or, when every run is
    more accurate than the target, the cheapest run ("bound": an upper bound); (None, "") when
    no run reaches the target."""
    interp = interpolate_time(points, target)
    if interp is not None:
        return interp, "interp"
    ok = [t for e, t in points if math.isfinite(e) and 0 <= e <= target and t > 0]
    if ok and all(e <= target for e, _ in points if math.isfinite(e)):
        return min(ok), "bound"
    return None, ""


# --------------------------------------------------------------------------- tables and files
def fmt_value(value, fmt: str) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "-"
    return fmt.format(value)


def format_table(columns, rows) -> str:
    """Plain-text table from (key, heading, format) columns; text left-aligned, numbers right."""
    cells = [[fmt_value(row.get(key), fmt) for key, _, fmt in columns] for row in rows]
    headings = [heading for _, heading, _ in columns]
    widths = [max([len(h)] + [len(r[i]) for r in cells]) for i, h in enumerate(headings)]
    left = [all(isinstance(row.get(key), str) for row in rows) for key, _, _ in columns]

    def line(values):
        padded = (v.ljust(w) if lft else v.rjust(w) for v, w, lft in zip(values, widths, left))
        return "  ".join(padded).rstrip()

    rule = "  ".join("-" * w for w in widths)
    return "\n".join([line(headings), rule, *(line(r) for r in cells)])


def write_report(out: Path, name: str, text: str, rows=None) -> None:
    """``out/name.txt`` (the printed table) and, given rows, ``out/name.csv``; creates ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    (out / f"{name}.txt").write_text(text if text.endswith("\n") else text + "\n")
    if rows is not None:
        write_csv(out / f"{name}.csv", rows)


def write_csv(path: Path, rows) -> None:
    keys = []
    for row in rows:
        keys += [k for k in row if k not in keys]
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=keys, lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    path.write_text(buf.getvalue())


def work_precision_plot(path: Path, title: str, curves: dict, xlabel: str, ref_unc: float | None = None) -> None:
    """Log-log time vs error, one line per contender: ``curves`` maps label -> [(error, seconds)]."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(7.5, 5.0))
    markers = "os^vD<>ph*Xd"
    for k, (label, pts) in enumerate(curves.items()):
        pts = sorted((e, t) for e, t in pts if e > 0 and t > 0 and math.isfinite(e))
        if not pts:
            continue
        ax.loglog([p[0] for p in pts], [1e3 * p[1] for p in pts], marker=markers[k % len(markers)],
                  linestyle="-" if k < 10 else "--", ms=4, lw=1, label=label)
    if ref_unc:
        ax.axvline(ref_unc, color="grey", lw=0.8, ls=":", label="reference uncertainty")
    ax.set_xlabel(xlabel)
    ax.set_ylabel("wall time [ms]")
    ax.set_title(title, fontsize=10)
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=6.5, ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
