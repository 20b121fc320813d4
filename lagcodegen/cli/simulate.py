"""``lagcodegen simulate``: a model file compiled (:func:`lagcodegen.api.compile_file`) and run
(:meth:`lagcodegen.modelfile.ModelFile.simulate`), the result written as CSV or NPZ (and PNG).

One job: the simulate command's options, progress lines and output files.
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import numpy as np

from ..api import compile_file
from ..modelfile.loader import MAX_STEPS
from ..util import output_problem
from .common import (EXIT_OK, MODEL_HELP, UsageError, add_formulation_option, add_scene_options,
                     apply_options, assignments, check_parameter_names, input_tables, load, say)

HELP = "compile a model file and integrate it; write the result as CSV or NPZ (and a PNG plot)"

DESCRIPTION = """Derive, generate and compile the model, integrate it from the file's initial state
over its [simulation] times, and write the trajectory (states and outputs at every output
time) as CSV or NPZ, with a PNG plot if asked. Options override the file's [simulation]
settings.

Model files with [constraints] run in the file's formulation (--formulation overrides); the
events found and the largest constraint residual are reported.

    lagcodegen simulate examples/double_pendulum.toml -o out/dp.csv --plot out/dp.png"""


def add_parser(sub) -> None:
    s = sub.add_parser("simulate", help=HELP, description=DESCRIPTION,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    s.add_argument("model", help=MODEL_HELP)
    s.add_argument("-o", "--output", required=True, help="result file (.csv or .npz)")
    s.add_argument("--plot", help="also save a PNG plot")
    s.add_argument("--t-end", type=float, help="end time (default: the file's t_end)")
    s.add_argument("--n-out", type=int, help="number of output times (at least 2)")
    s.add_argument("--method", choices=["adams", "bdf", "taylor", "auto"],
                   help="adams/bdf: CVODE; taylor: the generated Taylor integrator (files without "
                        "[constraints]); auto: Taylor or Adams by the model's size")
    s.add_argument("--max-steps", type=int, help="step budget of the whole run (default 1000000)")
    s.add_argument("--rtol", type=float, help="relative tolerance (default: the file's)")
    s.add_argument("--atol", type=float, help="absolute tolerance (default: the file's)")
    s.add_argument("--backend", choices=["native", "sksundae"], default="native",
                   help="native: the compiled driver (default); sksundae: scikit-sundae calling the same "
                        "functions from Python")
    add_formulation_option(s)
    s.add_argument("--project-initial", action="store_true",
                   help="files with [constraints]: project the initial state onto the constraints instead of "
                        "requiring it to satisfy them")
    s.add_argument("--input", action="append", metavar="NAME=FILE[:KIND]",
                   help="an input's table: FILE has two columns t, value; KIND linear (default), zoh or cubic "
                        "(repeatable)")
    add_scene_options(s)
    s.set_defaults(func=run)


def check_args(args) -> None:
    """Every option of ``simulate`` checked before any work (exit 2 on a bad one)."""
    problem = output_problem(args.output, args.plot, "results are")
    if problem:
        raise UsageError(problem)
    if args.n_out is not None and not 2 <= args.n_out <= 10_000_000:
        raise UsageError(f"--n-out {args.n_out}: give between 2 and 10000000 output times")
    if args.max_steps is not None and args.max_steps < 1:
        raise UsageError(f"--max-steps {args.max_steps}: give a positive step budget")
    if args.max_steps is not None and args.max_steps > MAX_STEPS:
        raise UsageError(f"--max-steps {args.max_steps}: give at most {MAX_STEPS} steps")
    assignments(args.set)  # NAME=VALUE pairs; the names are checked against the model once it is loaded
    args.input_tables = input_tables(args.input)
    for name in ("t_end", "rtol", "atol"):
        value = getattr(args, name)
        if value is not None and not (math.isfinite(value) and (value > 0 if name == "t_end" else value >= 0)):
            raise UsageError(f"--{name.replace('_', '-')} {value}: give a finite "
                             f"{'positive' if name == 't_end' else 'non-negative'} number")


def run(args) -> int:
    check_args(args)
    mf = load(args.model, args.quiet).model_file
    check_parameter_names(mf, args)
    mf = apply_options(mf, args)
    t0 = time.perf_counter()
    sim = compile_file(mf, verbose=not args.quiet)
    formulation = f" ({sim.formulation})" if mf.constrained is not None else ""
    say(f"derived, generated and compiled{formulation} in {time.perf_counter() - t0:.3f} s"
        f"{' (cached)' if getattr(sim, 'cached', False) else ''}", args.quiet)
    options: dict = {"backend": args.backend}
    if args.method:
        options["method"] = args.method
    if mf.constrained is not None:
        options["initial"] = "project" if args.project_initial else "check"
    if args.input_tables:
        options["inputs"] = args.input_tables
    t0 = time.perf_counter()
    res = mf.simulate(sim, **options)
    run_kind = f" ({sim.formulation}, {res.method})" if mf.constrained is not None else ""
    say(f"integrated t = {res.t[0]:g}..{res.t[-1]:g}{run_kind} in {time.perf_counter() - t0:.4f} s: "
        f"{res.stats.get('steps')} steps, {res.stats.get('rhs_evals')} RHS evaluations", args.quiet)
    if mf.constrained is None:
        return write_result(res, args)
    for ev in res.events:
        state = ", ".join(f"{k} = {v:.10g}" for k, v in ev.q.items())
        say(f"event {ev.name} at t = {ev.t:.12g} (direction {ev.direction:+d}"
            f"{', terminal: run stopped' if ev.terminal else ''}): {state}", args.quiet)
    residuals = [k for k in res.outputs if k.startswith(("g_", "gdot_"))]
    if residuals:
        worst = max(residuals, key=lambda k: float(np.max(np.abs(res[k]))))
        say(f"largest constraint residual: max |{worst}| = {float(np.max(np.abs(res[worst]))):.3e}", args.quiet)
    coords = [q.name for q in mf.model.coords]  # minimal coordinates: the eliminated ones are outputs
    plotted = [c for c in coords if c in res.state_names or c in res.outputs]
    return write_result(res, args, plotted + [k for k in res.outputs if k.startswith("lambda_")])


def write_result(res, args, plotted: list[str] | None = None) -> int:
    """Save the result (CSV/NPZ), the plot if asked, and report the drift of the energy."""
    out = Path(args.output)
    out.parent.mkdir(parents=True, exist_ok=True)
    res.save(out)
    say(f"wrote {out}", args.quiet)
    if args.plot:
        plot = Path(args.plot)
        plot.parent.mkdir(parents=True, exist_ok=True)
        res.plot(plot, plotted)
        say(f"wrote {plot}", args.quiet)
    if "energy" in res.outputs:
        say(f"energy drift over the run: {res.drift('energy'):.3e} (relative)", args.quiet)
    return EXIT_OK
