"""``lagcodegen fit``: run-time parameters (and initial values) of a model file fitted to measured
data (:func:`lagcodegen.fitting.fit`, the exact Jacobian from forward sensitivities); the
estimates written as CSV, with a PNG of the data against the fitted trajectory if asked.

One job: the fit command's options, its data file, progress lines and output files.
"""

from __future__ import annotations

import argparse
import io
import math
import sys
import time
from pathlib import Path

import numpy as np

from ..api import compile_file
from ..errors import LagcodegenError
from ..fitting import STATIONARITY, fit
from ..solvers.direction import SPELLING, Direction
from ..util import atomic_binary, atomic_write, folder_problem, staged_outputs
from .common import (EXIT_NOT_CONVERGED, EXIT_OK, MODEL_HELP, UsageError, add_scene_options, apply_options,
                     check_parameter_names, csv, load, say)

HELP = "fit run-time parameters of a model file to measured data (CSV); write the estimates (and a PNG)"

DESCRIPTION = """Fit the parameters named by --fit (run-time parameters, or initial values written
'<coordinate>(0)' / '<coordinate>_dot(0)') so that the model's states or outputs match the data:
a CSV file whose header is 't' and the observed names (states or outputs of the model), one row
per time (the first time is the initial time of the run, from the file's initial state; with
[constraints], formulation index1 or minimal, projected onto the constraints). Starting
values: the file's parameter values (--set overrides) and initial state. Least squares with the
exact Jacobian from forward sensitivities; the estimates with their standard errors (from the
residual variance) are printed and, with -o, written as CSV (name,estimate,stderr). A data
column named twice is refused.

A fit that does not converge (the optimizer out of evaluations, or stopped where the
residuals still have a component along the Jacobian: the model cannot follow the data) prints
"fit not converged" and exits with code 6; its estimates are still printed and written.

    lagcodegen fit model.toml data.csv --fit l,c -o fit.csv --plot fit.png"""


def add_parser(sub) -> None:
    s = sub.add_parser("fit", help=HELP, description=DESCRIPTION, formatter_class=argparse.RawDescriptionHelpFormatter)
    s.add_argument("model", help=MODEL_HELP)
    s.add_argument("data", help="measured data: CSV with a header 't,<name>,...'")
    s.add_argument("--fit", required=True, help="comma-separated names to fit (parameters, '<q>(0)', '<q>_dot(0)')")
    s.add_argument("--observe", help="comma-separated data columns to fit (default: every column but t)")
    s.add_argument("--sigma", type=float, help="standard deviation of the measurements (default 1: the "
                                               "standard errors then come from the residuals alone)")
    s.add_argument("-o", "--output", help="write the estimates as CSV (name,estimate,stderr)")
    s.add_argument("--plot", help="save a PNG of the data against the fitted trajectory")
    s.add_argument("--rtol", type=float, help="relative tolerance (default: the file's)")
    s.add_argument("--atol", type=float, help="absolute tolerance (default: the file's)")
    add_scene_options(s)
    s.set_defaults(func=run)


def check_args(args) -> None:
    """Every option of ``fit`` checked before any work (exit 2 on a bad one)."""
    for option, name in (("-o", args.output), ("--plot", args.plot)):
        problem = None if name is None else folder_problem(Path(name).parent)
        if problem:
            raise UsageError(f"{option} {name}: {problem}")
        if name is not None and not Path(name).parent.exists():
            raise UsageError(f"{name}: its folder does not exist")
    if args.plot is not None and not args.plot.lower().endswith(".png"):
        raise UsageError(f"--plot {args.plot}: give a .png file")
    if not csv(args.fit):
        raise UsageError("--fit: name at least one parameter")
    if args.sigma is not None and not (math.isfinite(args.sigma) and args.sigma > 0):
        raise UsageError(f"--sigma {args.sigma}: give a positive number")
    for name in ("rtol", "atol"):
        value = getattr(args, name)
        if value is not None and not (math.isfinite(value) and value >= 0):
            raise UsageError(f"--{name} {value}: give a finite non-negative number")
    if not Path(args.data).is_file():
        raise UsageError(f"{args.data}: no such data file")


def read_data(path: str) -> tuple[list[str], np.ndarray]:
    """(header, rows) of the data CSV; LagcodegenError naming the file and what is wrong."""
    text = Path(path).read_text()
    lines = [ln for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
    if not lines:
        raise LagcodegenError(f"{path}: no data")
    header = [h.strip() for h in lines[0].split(",")]
    if not header or header[0] != "t" or len(header) < 2:
        raise LagcodegenError(f"{path}: the header must be 't' followed by observed names, got {lines[0]!r}")
    twice = sorted({h for h in header if header.count(h) > 1})
    if twice:
        raise LagcodegenError(f"{path}: column {', '.join(map(repr, twice))} appears more than once in the header; "
                              "give each observed name one column (a repeated column counts the same "
                              "measurements twice and shrinks the standard errors)")
    try:
        rows = np.loadtxt(io.StringIO("\n".join(lines[1:])), delimiter=",", ndmin=2)
    except ValueError as exc:
        raise LagcodegenError(f"{path}: not a table of numbers ({exc})") from None
    if rows.shape[1] != len(header) or rows.shape[0] < 2:
        raise LagcodegenError(f"{path}: expected at least two rows of {len(header)} numbers, got {rows.shape}")
    return header, rows


def run(args) -> int:
    check_args(args)
    header, rows = read_data(args.data)
    mf = load(args.model, args.quiet, args.urdf).model_file
    check_parameter_names(mf, args)
    mf = apply_options(mf, args)
    names = csv(args.fit)
    observe = csv(args.observe) or header[1:]
    twice = sorted({o for o in observe if observe.count(o) > 1})
    if twice:
        raise UsageError(f"--observe: {', '.join(twice)} given more than once")
    missing = [o for o in observe if o not in header]
    if missing:
        raise UsageError(f"--observe {','.join(missing)}: not a column of {args.data} ({', '.join(header)})")
    if mf.constrained is not None and mf.simulation.formulation == "ggl":
        raise UsageError("fit: models with [constraints] are fitted in the index-1 formulation or in minimal "
                         "coordinates (formulation = \"index1\" or \"minimal\"), not GGL")
    t0 = time.perf_counter()
    sim = compile_file(mf, verbose=not args.quiet)
    say(f"derived, generated and compiled in {time.perf_counter() - t0:.3f} s", args.quiet)
    s = mf.simulation
    q0, v0 = mf.initial_state()
    values = {p.name: float(v) for p, v in mf.model.params.items()}
    values.update(s.parameters)
    start = {}
    coords = [q.name for q in mf.model.coords]
    for name in names:
        try:
            d = Direction.parse(name, params=list(values), coords=coords, what=f"--fit {name}")
        except LagcodegenError:
            raise UsageError(f"--fit {name}: neither a parameter of {mf.model.name} nor an initial value "
                             f"({SPELLING})") from None
        start[name] = values[name] if d.kind == "parameter" else \
            (q0 if d.kind == "position" else v0)[coords.index(d.target)]
    fixed = {k: v for k, v in s.parameters.items() if k in sim.param_names and k not in names}
    t = rows[:, 0]
    data = rows[:, [header.index(o) for o in observe]]
    t0 = time.perf_counter()
    extra = {} if mf.constrained is None else {"events": False}  # as for ODE files: the fit locates no events
    result = fit(sim, t, data, params=start, observe=observe, sigma=args.sigma, fixed=fixed, q0=q0, v0=v0, **extra,
                 rtol=args.rtol if args.rtol is not None else s.rtol,
                 atol=args.atol if args.atol is not None else s.atol)
    say(f"fitted {', '.join(names)} to {data.size} values in {time.perf_counter() - t0:.3f} s: "
        f"{result.iterations} iterations, cost {result.cost:.6g}, cond(J^T J) {result.condition:.3g}", args.quiet)
    for name in names:
        print(f"{name} = {result.params[name]:.12g} +- {result.stderr[name]:.3g}")
    if not result.converged:
        print(f"lagcodegen: fit not converged ({result.message.rstrip('.')}; cost {result.cost:.6g}, stationarity "
              f"{result.stationarity:.3g} > {STATIONARITY:g} or the optimizer stopped early): the estimates are not "
              "a minimum of the least squares; check the starting values (--set), the observed names and the "
              f"data (exit code {EXIT_NOT_CONVERGED})", file=sys.stderr)
    out = Path(args.output) if args.output else None
    plot = Path(args.plot) if args.plot else None
    with staged_outputs([out, plot]) as staged:  # the estimates and the plot appear together, or neither
        if out is not None:
            lines = ["name,estimate,stderr"] + [f"{n},{result.params[n]!r},{result.stderr[n]!r}" for n in names]
            atomic_write(staged[out], "\n".join(lines) + "\n")
        if plot is not None:
            _plot(sim, mf, result, t, data, observe, q0, v0, fixed, staged[plot])
    for path in (out, plot):
        if path is not None:
            say(f"wrote {path}", args.quiet)
    return EXIT_OK if result.converged else EXIT_NOT_CONVERGED


def _plot(sim, mf, result, t, data, observe, q0, v0, fixed, path) -> None:
    """PNG: the data (points) against the fitted trajectory (line), a panel per observed name."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    params = {**fixed, **{k: v for k, v in result.params.items() if k in sim.param_names}}
    coords = [q.name for q in mf.model.coords]
    q0, v0 = list(q0), list(v0)
    for k, v in result.params.items():
        d = Direction.parse(k, params=(), coords=coords) if Direction.initial(k) else None
        if d is not None:
            (q0 if d.kind == "position" else v0)[coords.index(d.target)] = v
    fine = np.linspace(t[0], t[-1], max(1001, 4 * t.size))
    extra = {} if mf.constrained is None else {"initial": "project"}  # the fitted start, onto its constraints
    res = sim.simulate(fine, q0=q0, v0=v0, params=params, rtol=mf.simulation.rtol, atol=mf.simulation.atol, **extra)
    fig = Figure(figsize=(8, 2.2 * len(observe) + 1))
    axes = fig.subplots(len(observe), 1, sharex=True, squeeze=False)[:, 0]
    for ax, name, col in zip(axes, observe, data.T):
        ax.plot(t, col, ".", ms=3, label="data")
        ax.plot(fine, res[name], lw=1.0, label="fit")
        ax.set_ylabel(name)
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper right")
    axes[0].set_title(f"{mf.model.name}: " + ", ".join(f"{k} = {v:.6g}" for k, v in result.params.items()))
    axes[-1].set_xlabel("t")
    FigureCanvasAgg(fig)
    with atomic_binary(Path(path)) as fh:
        fig.savefig(fh, format="png", dpi=100)
