"""``lagcodegen simulate``: a model file compiled (:func:`lagcodegen.api.compile_file`) and run
(:meth:`lagcodegen.modelfile.ModelFile.simulate`), the result written as CSV or NPZ (and PNG).

One job: the simulate command's options, progress lines and output files.
"""

from __future__ import annotations

import argparse
import dataclasses
import difflib
import math
import time
from pathlib import Path

import numpy as np
import sympy as sp

from ..animation import FORMATS, ffmpeg_available
from ..api import compile_file, compile_urdf
from ..codegen.record import stored_scene
from ..modelfile import constrained_outputs
from ..modelfile.loader import MAX_STEPS
from ..theory.energy import is_natural
from ..util import atomic_binary, excerpt, output_problem, staged_outputs
from .common import (EXIT_OK, MODEL_HELP, UsageError, add_formulation_option, add_scene_options,
                     apply_options, assignments, check_parameter_names, csv, input_tables, load, say,
                     urdf_options)

HELP = "compile a model file and integrate it; write the result as CSV or NPZ (and a PNG plot)"

DESCRIPTION = """Derive Lagrange's equations of the model (M q'' = F, eq. 3.16 of the notes),
generate and compile them, integrate them from the file's initial state over its [simulation]
times, and write the trajectory (states and outputs at every output time) as CSV or NPZ; with
--plot a PNG plot, with --animate a picture of the mechanism moving. Options override the
file's [simulation] settings; --initial changes single initial values.

Model files with [constraints] run in the file's formulation (--formulation overrides) and
report the largest constraint residual; the events found are reported for every file. When the
energy is an output, its relative change over the run is reported: a drift (an error of the integration) for a
model that conserves it, a change it may have for a model with dissipation, forces, inputs or
explicit time dependence.

    lagcodegen simulate examples/double_pendulum.toml -o out/dp.csv --plot out/dp.png
    lagcodegen simulate examples/pendulum.toml -o out/p.csv --initial theta=2.5 --animate out/p.gif
    lagcodegen simulate examples/central_potential.toml -o out/orbit.csv --plot out/orbit.png --plot-xy body_x,body_y"""


def add_parser(sub) -> None:
    s = sub.add_parser("simulate", help=HELP, description=DESCRIPTION,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    s.add_argument("model", help=MODEL_HELP)
    s.add_argument("-o", "--output", required=True, help="result file (.csv or .npz)")
    s.add_argument("--plot", metavar="PNG", help="also save a plot: the coordinates and the requested outputs "
                                                 "against time, a panel each (kinds of output share one)")
    s.add_argument("--plot-y", metavar="NAMES",
                   help="with --plot: the columns to plot against time, comma-separated; NAME+NAME shares a "
                        "panel (e.g. theta1+theta2,energy)")
    s.add_argument("--plot-xy", metavar="X,Y",
                   help="with --plot: column Y against column X instead of against time (e.g. bob_x,bob_y: "
                        "the bob's path; r,r_dot: a phase portrait); or a point's name: its path in the plane")
    s.add_argument("--animate", metavar="FILE",
                   help="also draw the mechanism moving (its points, bodies and rods) into FILE: .gif, .mp4 "
                        "(needs ffmpeg) or .html (a player for the browser)")
    s.add_argument("--initial", metavar="NAME=VALUE,...", action="append",
                   help="initial values by coordinate name, velocities as <q>_dot (e.g. theta=0.3,theta_dot=0); "
                        "they replace the file's [simulation] initial values of those names, the others keep "
                        "the file's (0 where it has none); repeatable")
    s.add_argument("--t-end", type=float, help="end time (default: the file's t_end)")
    s.add_argument("--n-out", type=int, help="number of output times (at least 2)")
    s.add_argument("--method", choices=["adams", "bdf", "taylor", "auto"],
                   help="adams/bdf: CVODE; taylor: the generated Taylor integrator (files without "
                        "[constraints], or whose constraints include contacts); auto: Taylor or Adams by "
                        "the model's size")
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
                        "(repeatable); FILE a regular file of at most 64 MiB")
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
    initial_values(args.initial)
    if (args.plot_y or args.plot_xy) and not args.plot:
        raise UsageError(f"--plot-{'y' if args.plot_y else 'xy'} chooses what --plot draws: give --plot FILE.png too")
    if args.plot_y and args.plot_xy:
        raise UsageError("give --plot-y (against time) or --plot-xy (one column against another), not both")
    if args.plot_xy is not None and (len(csv(args.plot_xy)) not in (1, 2) or "+" in args.plot_xy):
        raise UsageError(f"--plot-xy {excerpt(args.plot_xy)}: give two column names X,Y or one point's name")
    if args.animate is not None:
        if Path(args.animate).is_dir():
            raise UsageError(f"--animate {excerpt(args.animate)}: is a folder; give a file name ending in "
                             f"{', '.join(FORMATS)}")
        if Path(args.animate).suffix.lower() not in FORMATS:
            raise UsageError(f"--animate {excerpt(args.animate)}: give a file ending in {', '.join(FORMATS)}")
        if Path(args.animate).suffix.lower() == ".mp4" and not ffmpeg_available():
            raise UsageError(f"--animate {excerpt(args.animate)}: an MP4 needs ffmpeg, which is not installed; "
                             "give a .gif or .html file")
    args.input_tables = input_tables(args.input)
    for name in ("t_end", "rtol", "atol"):
        value = getattr(args, name)
        if value is not None and not (math.isfinite(value) and (value > 0 if name == "t_end" else value >= 0)):
            raise UsageError(f"--{name.replace('_', '-')} {value}: give a finite "
                             f"{'positive' if name == 't_end' else 'non-negative'} number")


def run(args) -> int:
    check_args(args)
    mf = load(args.model, args.quiet, args.urdf).model_file
    check_parameter_names(mf, args)
    mf = apply_initial(apply_options(mf, args), initial_values(args.initial))
    t0 = time.perf_counter()
    sim = compile_urdf_file(mf, args) if urdf_cacheable(mf, args.model) else compile_file(mf, verbose=not args.quiet)
    formulation = f" ({sim.formulation})" if mf.constrained is not None else ""
    code = getattr(getattr(sim, "compiled", sim), "code", None)  # a constrained simulation's, a model's
    if code is not None and stored_scene(code) is None:  # the pipeline cache's entry: nothing derived
        say(f"loaded{formulation} from the cache (nothing derived) in {time.perf_counter() - t0:.3f} s", args.quiet)
    else:
        say(f"derived, generated and compiled{formulation} in {time.perf_counter() - t0:.3f} s"
            f"{' (cached)' if getattr(sim, 'cached', False) else ''}", args.quiet)
    options: dict = {"backend": args.backend}
    if args.method:
        options["method"] = args.method
    if mf.constrained is not None:
        options["initial"] = "project" if args.project_initial else "check"
    known = getattr(sim, "output_names", None)
    if known is not None:  # else (minimal coordinates) the columns are known after the run, before any file
        check_columns(args, [*sim.state_names, *known])
    if args.input_tables:
        options["inputs"] = args.input_tables
    t0 = time.perf_counter()
    res = mf.simulate(sim, **options)
    check_columns(args, [*res.state_names, *res.outputs])
    run_kind = f" ({sim.formulation}, {res.method})" if mf.constrained is not None else ""
    say(f"integrated t = {res.t[0]:g}..{res.t[-1]:g}{run_kind} in {time.perf_counter() - t0:.4f} s: "
        f"{res.stats.get('steps')} steps, {res.stats.get('rhs_evals')} RHS evaluations", args.quiet)
    for ev in res.events:
        state = ", ".join(f"{k} = {v:.10g}" for k, v in ev.q.items())
        say(f"event {ev.name} at t = {ev.t:.12g} (direction {ev.direction:+d}"
            f"{', terminal: run stopped' if ev.terminal else ''}): {state}", args.quiet)
    if mf.constrained is None:
        return write_result(res, args, None, not_conserved(mf))
    impacts = getattr(res, "impacts", None)
    if impacts is not None:
        deepest = res.stats.get("max_penetration", 0.0)
        say(f"{len(impacts.times)} impact(s)" + (f"; a contact was found {deepest:.3e} below its surface after a step "
                                                  "had skipped its flight (located there)" if deepest > 0 else "")
            + (f"; {res.stats['stick_slip']} stick/slip transition(s), final friction modes "
               + ", ".join(f"{k}: {v}" for k, v in impacts.friction_modes.items()) if "stick_slip" in res.stats
               else ""), args.quiet)
        for line in contact_log_lines(impacts, mf.constrained.inequalities):
            say(line, args.quiet)
    residuals = [k for k in res.outputs if k.startswith(("g_", "gdot_"))]
    if residuals:
        worst = max(residuals, key=lambda k: float(np.max(np.abs(res[k]))))
        say(f"largest constraint residual: max |{worst}| = {float(np.max(np.abs(res[worst]))):.3e}", args.quiet)
    coords = [q.name for q in mf.model.coords]  # minimal coordinates: the eliminated ones are outputs
    plotted = [c for c in coords if c in res.state_names or c in res.outputs]
    return write_result(res, args, plotted + [k for k in res.outputs if k.startswith("lambda_")], not_conserved(mf))


def urdf_cacheable(mf, spec: str) -> bool:
    """Whether the model is a .urdf file whose settings :func:`lagcodegen.api.compile_urdf` takes
    (no events; a constrained one in the index-1 formulation with its default stabilization), so
    that its code is cached by the file's content and options."""
    s = mf.simulation
    return (Path(str(spec)).suffix.lower() == ".urdf" and not mf.events
            and (mf.constrained is None or (s.formulation in (None, "index1") and s.baumgarte == "auto"
                                            and not s.projection)))


def compile_urdf_file(mf, args):
    """The .urdf file's model through :func:`lagcodegen.api.compile_urdf` (the pipeline cache: a
    new process given the same file and options loads the compiled model without deriving), with
    the settings :func:`lagcodegen.api.compile_file` would use, the file's initial state its default."""
    s = mf.simulation
    if mf.constrained is None:
        options = dict(jacobian=s.jacobian and not mf.model.general, outputs=list(s.outputs))
    else:
        options = dict(jacobian=None, outputs=constrained_outputs(mf.constrained, s.outputs, "index1"))
    sim = compile_urdf(args.model, load=urdf_options(args.urdf), runtime_parameters=s.runtime_parameters,
                       values=dict(s.parameters), **options)
    sim.initial_defaults = mf.initial_state()
    return sim


#: The contact records ``simulate`` prints at most (the first ones; a line counts the rest).
MAX_LOG_LINES = 40


def contact_log_lines(impacts, inequalities) -> list[str]:
    """The run's contact log (``Result.impacts``) as lines, one a record: time, contact k with
    its inequality g_k >= 0 (a URDF joint's stop: ``q - lower`` or ``upper - q``), kind, impulse
    and normal velocity before and after; at most :data:`MAX_LOG_LINES`, then how many more."""
    lines = []
    for r in impacts.records[:MAX_LOG_LINES]:
        g = str(inequalities[r.contact]) if 0 <= r.contact < len(inequalities) else "?"
        g = g if len(g) <= 60 else g[:57] + "..."
        lines.append(f"  t = {r.t:.9g}: contact {r.contact} (g = {g}) {r.kind}, impulse {r.impulse:.6g}, "
                     f"w {r.w_before:.6g} -> {r.w_after:.6g}")
    if len(impacts.records) > MAX_LOG_LINES:
        lines.append(f"  ... and {len(impacts.records) - MAX_LOG_LINES} more contact record(s)")
    if getattr(impacts, "truncated", False):
        lines.append("  (the log is truncated: more records than ContactOptions.max_records)")
    return lines


def initial_values(items: list[str] | None) -> dict[str, float]:
    """The NAME=VALUE pairs of --initial (each option comma-separated)."""
    out = {}
    for item in items or []:
        for pair in csv(item):
            name, sep, value = pair.partition("=")
            if not sep or not name.strip():
                raise UsageError(f"--initial expects NAME=VALUE pairs separated by commas, got {excerpt(pair)}")
            try:
                number = float(value)
            except ValueError:
                raise UsageError(f"--initial {name.strip()}: {excerpt(value)} is not a number") from None
            if not math.isfinite(number):
                raise UsageError(f"--initial {name.strip()}: give a finite number, got {excerpt(value)}")
            out[name.strip()] = number
    return out


def apply_initial(mf, values: dict[str, float]):
    """``mf`` with --initial's values over its [simulation] initial values; every name must be a
    coordinate or a velocity ``<q>_dot`` of the model (exit 2 otherwise)."""
    if not values:
        return mf
    names = [q.name for q in mf.model.coords] + [v.name for v in mf.model.speeds]
    for name in values:
        if name not in names:
            raise UsageError(f"--initial {excerpt(name)}: not a coordinate or velocity of {mf.model.name}"
                             f"{_did_you_mean(name, names)} "
                             f"(coordinates: {', '.join(names[:len(names) // 2])}; velocities: <q>_dot)")
    s = mf.simulation
    return dataclasses.replace(mf, simulation=dataclasses.replace(s, initial={**s.initial, **values}))


def check_columns(args, columns: list[str]) -> None:
    """The names of --plot-y and --plot-xy are columns of the result (or, for --plot-xy, one
    point's name); exit 2 naming the unknown one."""
    wanted = [n for item in csv(args.plot_y) or [] for n in item.split("+")]
    xy = csv(args.plot_xy) or []
    if len(xy) == 2:
        wanted += xy
    for name in wanted:
        if name not in columns:
            raise UsageError(f"--plot-{'xy' if name in xy else 'y'} {excerpt(name)}: not a column of the result"
                             f"{_did_you_mean(name, columns)} (columns: {', '.join(columns)})")


def _did_you_mean(name: str, choices: list[str]) -> str:
    """"; did you mean 'x'?" with the closest of ``choices`` to ``name``, or nothing."""
    close = difflib.get_close_matches(name, choices, n=1)
    return f"; did you mean {close[0]!r}?" if close else ""


def not_conserved(mf) -> str | None:
    """Why the energy T + V of the model file's system may change along a run (dissipation,
    forces, inputs, a time-dependent Lagrangian or constraints), or None when it is conserved
    (eq. 3.7: h = T + V for a natural system with no explicit t, and dh/dt = 0 without
    non-potential forces, eq. 3.6)."""
    model = mf.model
    t = model.t
    if model.dissipation_terms:
        return "dissipation"
    if model.cartesian_forces or model.generalized_forces:
        return "applied forces"
    if model.inputs:
        return "inputs"
    if model.generalized_potential_terms:
        return "a velocity-dependent potential"
    if any(t in sp.sympify(V).free_symbols for _, V in model.potential_terms) or not is_natural(model):
        return "a Lagrangian that depends on time"
    system = mf.constrained
    if system is not None and (any(t in sp.sympify(f).free_symbols for f in system.holonomic)
                               or any(sp.sympify(A0) != 0 or any(t in sp.sympify(a).free_symbols for a in A)
                                      for A, A0 in system.nonholonomic)):
        return "constraints that depend on time"
    if system is not None and any(mu is not None and mu > 0 for mu in system.friction):
        return "contacts with Coulomb friction, losing energy while they slip"
    if system is not None and any(e is not None and e < 1 for e in system.restitution):
        return "impacts with a restitution below 1, each losing energy"
    return None


def write_result(res, args, plotted: list[str] | None = None, nonconservative: str | None = None) -> int:
    """Save the result (CSV/NPZ), the plot and the animation if asked, and report the drift of
    the energy (or, for a model that does not conserve it, how much it changed and why).

    The files are written to temporary files beside their targets and published together when
    all are complete (:func:`lagcodegen.util.staged_outputs`): Ctrl-C, SIGTERM or a failure
    while any is written leaves none of them (nor the folders made for them)."""
    out = Path(args.output)
    plot = Path(args.plot) if args.plot else None
    movie = Path(args.animate) if args.animate else None
    with staged_outputs([out, plot, movie]) as staged:
        res.save(staged[out])
        if plot is not None:
            xy = csv(args.plot_xy)
            if xy and len(xy) == 2:
                column_plot(res, xy[0], xy[1], staged[plot])
            elif xy:
                res.plot(staged[plot], xy=xy[0])
            else:
                what = [item.split("+") for item in csv(args.plot_y)] if args.plot_y else plotted
                res.plot(staged[plot], what)
        if movie is not None:
            res.animate(staged[movie])
    for path in (out, plot, movie):
        if path is not None:
            say(f"wrote {path}", args.quiet)
    if "energy" in res.outputs:
        if nonconservative is None:
            say(f"energy drift over the run: {res.drift('energy'):.3e} (relative)", args.quiet)
        else:
            say(f"energy changed over the run by {res.drift('energy'):.3e} (relative), as it may: the model has "
                f"{nonconservative}", args.quiet)
    return EXIT_OK


def column_plot(res, x: str, y: str, path: Path) -> None:
    """Column ``y`` of ``res`` against column ``x`` (:func:`column_figure`), saved as PNG at ``path``."""
    with atomic_binary(path) as fh:
        column_figure(res, x, y).savefig(fh, format="png", dpi=100)


def column_figure(res, x: str, y: str):
    """The figure of column ``y`` of ``res`` against column ``x``, titled with the model's name;
    a point's path (``<p>_x``, ``<p>_y``) in true proportions."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6, 5))
    ax = fig.add_subplot()
    ax.plot(res[x], res[y], lw=0.8)
    ax.set_xlabel(x)
    ax.set_ylabel(y)
    ax.set_title(res.title())
    ax.grid(alpha=0.3)
    if x.endswith("_x") and y.endswith("_y") and x[:-2] == y[:-2]:  # a point's path: true proportions
        ax.set_aspect("equal", adjustable="datalim")
    return fig
