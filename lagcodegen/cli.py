"""The ``lagcodegen`` command: generate, simulate, info.

Model files with a [constraints] table are constrained systems (notes, sec. 4): ``simulate``
integrates them in the file's formulation (``--formulation`` overrides) and reports the events
found; ``generate`` writes ``<prefix>_dae.h`` and ``<prefix>_dae.c`` (or ``.f90``; ``--bundle``:
with Makefile, CMakeLists.txt, RK4 example and README), in minimal coordinates the reduced
model's sources; ``info`` also prints the constraints, their differential form (eq. 4.2) and
the equations with multipliers (eq. 4.5).

One job: the command line, from the options (each checked before any work) to the exit code;
every subcommand hands the work to the pipeline's modules.

Exit codes:
    0  success
    1  bad model or input (the message names the file, key and token)
    2  bad command line
    3  the C compiler failed
    4  the integration failed
    5  ``generate --check``: the output folder is out of date
  130  interrupted (Ctrl-C); 143: terminated (SIGTERM). No partial output file is left.
"""

from __future__ import annotations

import argparse
import difflib
import math
import signal
import sys
import time
from pathlib import Path

import numpy as np
import sympy as sp

from . import progress
from .api import build, compile_constrained
from .buildstep import (cmake_dir, generator_record, input_record, load_source, manifest_matches, manifest_name,
                        manifest_outdated, manifest_text, read_manifest, split_python_spec, stale_by_manifest,
                        touch_stamp, write_depfile)
from .codegen.bundle import render_bundle, render_constrained_bundle, stale_files, write_files
from .codegen.c import generate_c
from .codegen.constrained import generate_constrained
from .codegen.languages import generate_code
from .derivation import derive
from .errors import CompileError, LagcodegenError, ModelError, SolverError
from .formulation.scene import Scene
from .fmu import export_fmu
from .modelfile import FORMULATIONS, constrained_method, constrained_outputs
from .modelfile.loader import MAX_STEPS
from .sweep import HELP as SWEEP_HELP, SweepOptionError, add_sweep_options, run_sweep, spec_from_namespace
from .theory.minimal import reduced_model, solve_constraints
from .util import EXCERPT, Terminated, excerpt, output_problem, sigterm_raises
from .version import __version__

EXIT_OK, EXIT_INPUT, EXIT_USAGE, EXIT_COMPILE, EXIT_SOLVER, EXIT_OUTDATED = 0, 1, 2, 3, 4, 5


class UsageError(Exception):
    """A bad command-line option (exit 2), found before any work."""


def _progress(msg: str, quiet: bool) -> None:
    if not quiet:
        print(f"lagcodegen: {msg}", file=sys.stderr, flush=True)


def _csv(text: str | None) -> list[str] | None:
    if text is None:
        return None
    return [s.strip() for s in text.split(",") if s.strip()]


def _name(name: str) -> str:
    """A name given on the command line, as it is, or an excerpt if it is long."""
    return name if len(name) <= EXCERPT else excerpt(name)


def _assignments(items: list[str]) -> dict[str, float]:
    out = {}
    for item in items or []:
        name, sep, value = item.partition("=")
        if not sep:
            raise UsageError(f"--set expects NAME=VALUE, got {excerpt(item)}")
        try:
            out[name.strip()] = float(value)
        except ValueError:
            raise UsageError(f"--set {_name(name.strip())}: {excerpt(value)} is not a number") from None
    return out


def _check_parameter_names(mf, args) -> None:
    """Every --set names a parameter of the loaded model (exit 2 otherwise), checked before any
    derivation: a misspelt name must not be ignored."""
    params = [p.name for p in mf.model.params]
    for name in _assignments(getattr(args, "set", None)):
        if name not in params:
            close = difflib.get_close_matches(name, params, n=1) or [p for p in params if p.lower() == name.lower()]
            hint = f"; did you mean {close[0]!r}?" if close else ""
            raise UsageError(f"--set {_name(name)}: not a parameter of {mf.model.name}{hint} "
                             f"(parameters: {', '.join(params) or 'none'})")


def _load(path: str, quiet: bool):
    """The ModelFile of a TOML model file or of FILE.py:FUNCTION (executes FILE.py)."""
    return _load_source(path, quiet).model_file


def _parameters(sim, args) -> tuple[list[str] | None, dict[str, float], dict[str, float]]:
    """(run-time parameter names or None for all, every value given by the file or --set, the
    values of the folded ones) from the file's settings and the command line."""
    runtime = sim.runtime_parameters
    if getattr(args, "fold_all", False):
        runtime = []
    elif getattr(args, "runtime_parameters", None) is not None:
        runtime = _csv(args.runtime_parameters)
    values = dict(sim.parameters)
    values.update(_assignments(getattr(args, "set", None)))
    folded_values = {k: v for k, v in values.items() if runtime is not None and k not in runtime}
    return runtime, values, folded_values


def _scene(mf, args, quiet: bool):
    t0 = time.perf_counter()
    eom = mf.derive()  # derivation errors carry the file and line
    _progress(f"derived Lagrange's equations in {time.perf_counter() - t0:.3f} s", quiet)
    sim = mf.simulation
    outputs = _csv(args.outputs) if getattr(args, "outputs", None) is not None else list(sim.outputs)
    runtime, values, folded_values = _parameters(sim, args)
    scene = Scene(eom, jacobian=not getattr(args, "no_jacobian", False) and sim.jacobian, outputs=outputs,
                  runtime_parameters=runtime, values=folded_values, prefix=getattr(args, "prefix", None))
    runtime_values = {k: v for k, v in values.items() if k in scene.runtime_parameters}
    return scene, runtime_values


def _formulation(mf, args, quiet: bool) -> tuple[str, tuple[float, float] | str, bool]:
    """(formulation, baumgarte, projection) of a constrained file, ``--formulation`` overriding."""
    sim = mf.simulation
    formulation = getattr(args, "formulation", None) or sim.formulation or "index1"
    baumgarte, projection = sim.baumgarte, sim.projection
    if formulation != "index1":
        dropped = [name for name, used in (("baumgarte", baumgarte not in ((0.0, 0.0), "auto")),
                                           ("projection", projection))
                   if used]
        if dropped:
            _progress(f"formulation {formulation}: ignoring the file's {' and '.join(dropped)} (index1 only)", quiet)
        baumgarte, projection = (0.0, 0.0), False
    return formulation, baumgarte, projection


def _constrained(mf, args, quiet: bool) -> tuple[dict, dict, str]:
    """compile_constrained options of a constrained file (with the scene options of the command
    line), all parameter values by name, and the formulation."""
    t0 = time.perf_counter()
    mf.derive()  # derivation errors carry the file and line
    _progress(f"derived Lagrange's equations in {time.perf_counter() - t0:.3f} s", quiet)
    system, sim = mf.constrained, mf.simulation
    formulation, baumgarte, projection = _formulation(mf, args, quiet)
    requested = _csv(args.outputs) if getattr(args, "outputs", None) is not None else list(sim.outputs)
    runtime, values, folded_values = _parameters(sim, args)
    options = dict(formulation=formulation, outputs=constrained_outputs(system, requested, formulation),
                   events=list(mf.events), runtime_parameters=runtime, values=folded_values,
                   prefix=getattr(args, "prefix", None),
                   jacobian=not getattr(args, "no_jacobian", False) and sim.jacobian)
    if formulation == "index1":
        options.update(baumgarte=baumgarte, projection=projection)
    _progress(f"{system.J} equality constraint(s), {len(system.inequalities)} inequality constraint(s), "
              f"{len(mf.events)} event(s); formulation {formulation}", quiet)
    return options, {**{p.name: v for p, v in system.model.params.items()}, **values}, formulation


def _runtime_values(options: dict, values: dict) -> dict:
    runtime = options["runtime_parameters"]
    return {k: v for k, v in values.items() if runtime is None or k in runtime}


def _minimal_scene(mf, options: dict, values: dict, quiet: bool):
    """The Scene of the reduced model (minimal coordinates) on the branch of the file's initial state."""
    system = mf.constrained
    model = system.model
    if options["events"] or system.inequalities:
        raise ModelError("minimal coordinates: events and inequality constraints need formulation 'index1' or 'ggl'")
    eliminated, branches = solve_constraints(system)
    q0, _ = mf.initial_state()
    subs = {**dict(zip(model.coords, q0)), model.t: mf.simulation.t_start,
            **{p: values[p.name] for p in model.params}}
    errors = []
    for sol in branches:
        try:
            errors.append(max(abs(complex(sp.sympify(sol[qe]).xreplace(subs).evalf()) - q0[model.index(qe)])
                              for qe in eliminated))
        except (TypeError, ValueError):
            errors.append(float("inf"))
    b = min(range(len(branches)), key=errors.__getitem__)
    if not errors[b] <= 1e-8 * (1 + max(map(abs, q0))):
        raise ModelError(f"minimal coordinates: no solution branch of the constraints matches the initial state "
                         f"(closest differs by {errors[b]:.3g})")
    _progress(f"minimal coordinates: {', '.join(q.name for q in eliminated)} eliminated (branch {b}: "
              + ", ".join(f"{q.name} = {branches[b][q]}" for q in eliminated) + ")", quiet)
    red = reduced_model(system, branches[b], name=model.name)
    python_side = ("residuals", "inequalities")
    outputs = [o for o in options["outputs"] if o not in python_side and not o.startswith(("g_", "gdot_"))]
    outputs += [q.name for q in eliminated] + [f"{q.name}_dot" for q in eliminated]
    return Scene(derive(red), jacobian=options["jacobian"], outputs=outputs,
                 runtime_parameters=options["runtime_parameters"], values=options["values"],
                 prefix=options["prefix"]), eliminated


def _constrained_files(mf, args) -> dict[str, str]:
    """Files of ``generate`` for a constrained model file."""
    options, values, formulation = _constrained(mf, args, args.quiet)
    sim = mf.simulation
    q0, v0 = mf.initial_state()
    runtime_values = _runtime_values(options, values)
    if formulation == "minimal":
        scene, eliminated = _minimal_scene(mf, options, values, args.quiet)
        code = generate_code(scene, args.lang)
        if not args.bundle:
            return dict(code.files)
        keep = [i for i, q in enumerate(mf.constrained.model.coords) if q not in eliminated]
        return render_bundle(scene, args.lang, y0=[q0[i] for i in keep] + [v0[i] for i in keep],
                             params={k: v for k, v in runtime_values.items() if k in scene.runtime_parameters},
                             t_start=sim.t_start, t_end=sim.t_end, code=code)
    ggl = formulation == "ggl"
    if args.bundle:
        return render_constrained_bundle(mf.constrained, args.lang, outputs=options["outputs"],
                                         events=options["events"], runtime_parameters=options["runtime_parameters"],
                                         values=options["values"], prefix=options["prefix"], ggl=ggl,
                                         baumgarte=options.get("baumgarte", (0.0, 0.0)), y0=q0 + v0,
                                         params=runtime_values, t_start=sim.t_start, t_end=sim.t_end)
    code, _ = generate_constrained(mf.constrained, ggl=ggl, ggl_jacobian=options["jacobian"],
                                     outputs=options["outputs"], events=options["events"],
                                     runtime_parameters=options["runtime_parameters"], values=options["values"],
                                     prefix=options["prefix"], lang=args.lang)
    dae = [name for name in code.files if name.startswith(f"{code.prefix}_dae.")]
    return {name: code.files[name] for name in dae}


def _generated_files(mf, args) -> dict[str, str]:
    """The files ``generate`` writes for the loaded model (derives the model)."""
    if mf.constrained is not None:
        return _constrained_files(mf, args)
    if args.formulation:
        _progress("--formulation ignored: the file has no [constraints]", args.quiet)
    scene, runtime_values = _scene(mf, args, args.quiet)
    code = generate_code(scene, args.lang)
    if not args.bundle:
        return dict(code.files)
    q0, v0 = mf.initial_state()
    sim = mf.simulation
    return render_bundle(scene, args.lang, y0=q0 + v0, params=runtime_values, t_start=sim.t_start,
                         t_end=sim.t_end, code=code, method=args.method or "bdf")


def _generate_options(args) -> dict:
    """The command-line options that shape the generated files (recorded in the manifest)."""
    return {"lang": args.lang, "prefix": args.prefix, "bundle": args.bundle, "outputs": args.outputs,
            "runtime_parameters": args.runtime_parameters, "fold_all": args.fold_all, "set": args.set or [],
            "no_jacobian": args.no_jacobian, "formulation": args.formulation, "method": args.method}


def _load_source(spec: str, quiet: bool):
    t0 = time.perf_counter()
    source = load_source(spec)
    kind = "executed" if split_python_spec(spec) else "loaded"
    _progress(f"{kind} {spec} ({source.model_file.model.n} coordinates) in {time.perf_counter() - t0:.3f} s",
              quiet)
    return source


def _finish_build_step(args, out: Path, names, manifest: str, source) -> None:
    """Depfile and stamp of a successful run (or of a run that found everything up to date).
    The stamp lists the files of the folder as --list-outputs prints them."""
    if args.depfile:
        write_depfile(args.depfile, [args.stamp or str(out / manifest)], source.inputs)
    if args.stamp:
        touch_stamp(args.stamp, _listing(out, names))


def _listing(out: Path, names) -> str:
    return "".join(f"{out / name}\n" for name in sorted(names))


def _generate_fmu(args) -> int:
    """``generate --fmu FILE [--fmi 3]``: the model file as an FMU (lagcodegen.fmu.export_fmu)."""
    if args.bundle or args.check or args.list_outputs or args.lang != "c":
        raise UsageError("--fmu writes one FMU file: --bundle, --check, --list-outputs and --lang fortran do not apply")
    mf = _load(args.model, args.quiet)
    _check_parameter_names(mf, args)
    t0 = time.perf_counter()
    tunable = [] if args.fold_all else _csv(args.runtime_parameters)
    path = export_fmu(mf, args.fmu, fmi_version=args.fmi, outputs=_csv(args.outputs), tunable=tunable,
                      values=_assignments(args.set), model_identifier=args.prefix)
    _progress(f"wrote {path} (FMI {args.fmi}.0) in {time.perf_counter() - t0:.3f} s", args.quiet)
    return EXIT_OK


def cmd_generate(args) -> int:
    if args.fmu:
        return _generate_fmu(args)
    if not args.output:
        raise UsageError("generate needs -o/--output FOLDER (or --fmu FILE)")
    if args.check and args.list_outputs:
        print("lagcodegen generate: --check and --list-outputs exclude each other", file=sys.stderr)
        return EXIT_USAGE
    source = _load_source(args.model, args.quiet)
    mf = source.model_file
    _check_parameter_names(mf, args)
    out = Path(args.output)
    manifest = manifest_name(args.prefix or mf.model.name)
    inputs, options, generator = input_record(source), _generate_options(args), generator_record()
    record = read_manifest(out, args.prefix or mf.model.name)
    if manifest_matches(record, inputs, options, generator):
        # the folder was generated from these inputs with these options: no derivation needed
        if args.list_outputs:
            print(_listing(out, [*record["files"], manifest]), end="")
            return EXIT_OK
        stale = stale_by_manifest(out, record)
        if not stale:
            _progress(f"{out} is up to date (manifest {manifest})", args.quiet)
            if not args.check:
                _finish_build_step(args, out, [*record["files"], manifest], manifest, source)
            return EXIT_OK
        if args.check:
            print(f"lagcodegen: {out} is out of date: {', '.join(stale)}", file=sys.stderr)
            return EXIT_OUTDATED
    files = _generated_files(mf, args)
    files[manifest] = manifest_text(inputs, options, generator, files)
    if args.list_outputs:
        print(_listing(out, files), end="")
        return EXIT_OK
    if args.check:
        stale = stale_files(out, {name: text for name, text in files.items() if name != manifest})
        if manifest_outdated(out, args.prefix or mf.model.name, files[manifest]):
            stale.append(manifest)
        if stale:
            print(f"lagcodegen: {out} is out of date: {', '.join(stale)}", file=sys.stderr)
            return EXIT_OUTDATED
        _progress(f"{out} is up to date", args.quiet)
        return EXIT_OK
    written = write_files(out, files)
    for path in written:
        _progress(f"wrote {path}", args.quiet)
    if len(written) < len(files):
        _progress(f"{len(files) - len(written)} file(s) in {out} already up to date", args.quiet)
    _finish_build_step(args, out, files, manifest, source)
    return EXIT_OK


def _simulate_constrained(mf, args):
    """Compile and integrate a constrained model file; returns the Result."""
    options, values, formulation = _constrained(mf, args, args.quiet)
    t0 = time.perf_counter()
    sim = compile_constrained(mf.constrained, verbose=not args.quiet, **options)
    _progress(f"generated and compiled ({formulation}) in {time.perf_counter() - t0:.3f} s", args.quiet)
    s = mf.simulation
    t_end = args.t_end if args.t_end is not None else s.t_end
    n_out = args.n_out if args.n_out is not None else s.n_out
    times = np.linspace(s.t_start, t_end, n_out)
    q0, v0 = mf.initial_state()
    method = args.method or constrained_method(formulation, options.get("projection", False), s.method)
    t0 = time.perf_counter()
    res = sim.simulate(times, q0=q0, v0=v0, params={k: v for k, v in values.items() if k in sim.param_names},
                       method=method, rtol=args.rtol if args.rtol is not None else s.rtol,
                       atol=args.atol if args.atol is not None else s.atol, backend=args.backend,
                       initial="project" if args.project_initial else "check", **_max_steps(args, s))
    _progress(f"integrated t = {res.t[0]:g}..{res.t[-1]:g} ({formulation}, {res.method}) in "
              f"{time.perf_counter() - t0:.4f} s: {res.stats.get('steps')} steps, "
              f"{res.stats.get('rhs_evals')} RHS evaluations", args.quiet)
    for ev in res.events:
        state = ", ".join(f"{k} = {v:.10g}" for k, v in ev.q.items())
        _progress(f"event {ev.name} at t = {ev.t:.12g} (direction {ev.direction:+d}"
                  f"{', terminal: run stopped' if ev.terminal else ''}): {state}", args.quiet)
    residuals = [k for k in res.outputs if k.startswith(("g_", "gdot_"))]
    if residuals:
        worst = max(residuals, key=lambda k: float(np.max(np.abs(res[k]))))
        _progress(f"largest constraint residual: max |{worst}| = {float(np.max(np.abs(res[worst]))):.3e}",
                  args.quiet)
    return res


def _check_simulate_args(args) -> None:
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
    _assignments(args.set)  # NAME=VALUE pairs; the names are checked against the model once it is loaded
    for name in ("t_end", "rtol", "atol"):
        value = getattr(args, name)
        if value is not None and not (math.isfinite(value) and (value > 0 if name == "t_end" else value >= 0)):
            raise UsageError(f"--{name.replace('_', '-')} {value}: give a finite "
                             f"{'positive' if name == 't_end' else 'non-negative'} number")


def _max_steps(args, sim) -> dict:
    """The step budget of the whole run: --max-steps, else the file's [simulation] max_steps."""
    max_steps = args.max_steps if args.max_steps is not None else sim.max_steps
    return {} if max_steps is None else {"max_steps": max_steps}


def cmd_simulate(args) -> int:
    _check_simulate_args(args)
    mf = _load(args.model, args.quiet)
    _check_parameter_names(mf, args)
    if mf.constrained is not None:
        res = _simulate_constrained(mf, args)
        coords = [q.name for q in mf.model.coords]  # minimal: the eliminated ones are outputs
        plotted = [c for c in coords if c in res.state_names or c in res.outputs]
        return _write_result(res, args, plotted + [k for k in res.outputs if k.startswith("lambda_")])
    if args.formulation:
        _progress("--formulation ignored: the file has no [constraints]", args.quiet)
    scene, runtime_values = _scene(mf, args, args.quiet)
    t0 = time.perf_counter()
    code = generate_c(scene)
    cm = build(code, verbose=not args.quiet)
    _progress(f"generated and compiled in {time.perf_counter() - t0:.3f} s"
              f"{' (cached)' if cm.cached else ''}", args.quiet)
    sim = mf.simulation
    t_end = args.t_end if args.t_end is not None else sim.t_end
    n_out = args.n_out if args.n_out is not None else sim.n_out
    times = np.linspace(sim.t_start, t_end, n_out)
    q0, v0 = mf.initial_state()
    t0 = time.perf_counter()
    res = cm.simulate(times, q0=q0, v0=v0, params=runtime_values, method=args.method or sim.method,
                      rtol=args.rtol if args.rtol is not None else sim.rtol,
                      atol=args.atol if args.atol is not None else sim.atol,
                      backend=args.backend, jacobian=scene.jacobian, **_max_steps(args, sim))
    _progress(f"integrated t = {times[0]:g}..{times[-1]:g} in {time.perf_counter() - t0:.4f} s: "
              f"{res.stats.get('steps')} steps, {res.stats.get('rhs_evals')} RHS evaluations", args.quiet)
    return _write_result(res, args)


def _write_result(res, args, plotted: list[str] | None = None) -> int:
    """Save the result (CSV/NPZ), the plot if asked, and report the drift of the energy."""
    out = Path(args.output)
    out.parent.mkdir(parents=True, exist_ok=True)
    res.save(out)
    _progress(f"wrote {out}", args.quiet)
    if args.plot:
        plot = Path(args.plot)
        plot.parent.mkdir(parents=True, exist_ok=True)
        res.plot(plot, plotted)
        _progress(f"wrote {plot}", args.quiet)
    for name in res.outputs:
        if name in ("energy",):
            _progress(f"{name} drift over the run: {res.drift(name):.3e} (relative)", args.quiet)
    return EXIT_OK


def cmd_sweep(args) -> int:
    try:
        run_sweep(spec_from_namespace(args))
    except SweepOptionError as exc:
        raise UsageError(str(exc)) from None
    return EXIT_OK


def cmd_info(args) -> int:
    mf = _load(args.model, True)
    eom = mf.derive()
    model = mf.model
    show = sp.latex if args.latex else (lambda e: sp.pretty(e, use_unicode=False))
    print(f"model {model.name}: {model.n} coordinates")
    print("coordinates: " + ", ".join(q.name for q in model.coords))
    print("parameters:  " + ", ".join(f"{k.name} = {v:g}" for k, v in model.params.items()))
    sections = [("kinetic energy T (eq. 2.2)", eom.T), ("potential energy V (eq. 2.7)", eom.V)]
    if eom.D != 0:
        sections.append(("Rayleigh dissipation D (eq. 3.15)", eom.D))
    sections += [("generalized momenta p = dL/dq' (eq. 2.3)", eom.momenta),
                 ("mass matrix M (eq. 3.16: M q'' = F)", eom.M),
                 ("force vector F", eom.F)]
    simplify = args.simplify if args.simplify is not None else model.n <= 3
    for title, expr in sections:
        print(f"\n{title}:")
        print(show(sp.simplify(expr) if simplify else expr))
    if mf.constrained is not None:
        _info_constrained(mf, eom, show, simplify)
    return EXIT_OK


def _info_constrained(mf, eom, show, simplify: bool) -> None:
    """The constraints, their differential form (eq. 4.2) and the equations with multipliers (eq. 4.5)."""
    system = mf.constrained
    model = system.model
    simp = sp.simplify if simplify else (lambda e: e)
    sim = mf.simulation
    lam = ", ".join(m.name for m in system.multipliers) or "none"
    print(f"\nconstraints: {system.n_holonomic} holonomic, {system.n_nonholonomic} nonholonomic, "
          f"{len(system.inequalities)} inequalities; degrees of freedom n - J = {system.dof}; multipliers: {lam}; "
          f"formulation {sim.formulation}")
    for j, f in enumerate(system.holonomic):
        print(f"\nholonomic constraint {j} (eq. 4.1): f_{j}(q, t) = 0 (output g_{j}) with f_{j} =")
        print(show(simp(f)))
    for k, row in enumerate(r for r in system.rows() if not r.holonomic):
        rep = system.is_integrable(k)
        kind = "integrable (kept as a Pfaffian row)" if rep.integrable else "not integrable (Frobenius)"
        print(f"\nnonholonomic constraint {k} (eq. 4.3; row {row.index}), {kind}: A . q' + A0 = 0 with "
              "A . q' + A0 =")
        expr = sum((a * v for a, v in zip(row.A, model.speeds)), sp.Integer(0)) + row.A0
        print(show(simp(expr)))
    for k, g in enumerate(system.inequalities):
        print(f"\ninequality constraint {k} (eq. 4.3): ineq_{k}(q, t) >= 0 (terminal event ineq_{k}, "
              f"decreasing) with ineq_{k} =")
        print(show(simp(g)))
    if system.J:
        coords = ", ".join(q.name for q in model.coords)
        print(f"\ndifferential form (eq. 4.2): A dq + A0 dt = 0, A = (df/dq; Pfaffian rows) over ({coords}):")
        print(show(system.A.applyfunc(simp)))
        print("\nA0 (df/dt; Pfaffian A0):")
        print(show(system.A0.applyfunc(simp)))
        dyn, acc = system.equations(eom)
        print("\nequations with multipliers (eq. 4.5): M q'' - F - A^T lambda = 0:")
        print(show(dyn.applyfunc(simp)))
        print("\nand the constraints at acceleration level, A q'' - gamma = 0 (gamma = -(d/dt)(A q' + A0) "
              "without q''):")
        print(show(acc.applyfunc(simp)))
    for ev in mf.events:
        direction = {-1: "decreasing", 0: "either direction", 1: "increasing"}[ev.direction]
        print(f"\nevent {ev.name} ({direction}{', terminal' if ev.terminal else ''}): zero of")
        print(show(ev.expr))


GENERATE_HELP = """Write the model's C or Fortran sources into a folder, with the manifest
<prefix>.lagcodegen.json (input digests, options, versions of lagcodegen, sympy and symengine).
Files whose content is unchanged are not rewritten. When the manifest matches the inputs and
options, generate, --check and --list-outputs answer without deriving the model.

A Python model, FILE.py:FUNCTION, is executed: FILE.py runs as Python code (with its folder on
sys.path) and FUNCTION() must return a Model, a ConstrainedSystem or a ModelFile. Name only
files you trust; TOML model files are parsed, never executed.

As a build step: --depfile FILE and --stamp FILE for Ninja, Make, Meson and CMake's DEPFILE;
--list-outputs to learn the file names at configure time."""


class _CMakeDir(argparse.Action):
    def __call__(self, parser, namespace, values, option_string=None):
        print(cmake_dir())
        parser.exit()


def parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="lagcodegen", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--version", action="version", version=f"lagcodegen {__version__}")
    ap.add_argument("--cmake-dir", action=_CMakeDir, nargs=0,
                    help="print the folder of lagcodegen's CMake package (for lagcodegen_DIR) and exit")
    sub = ap.add_subparsers(dest="command", required=True)

    def formulation_option(p):
        p.add_argument("--formulation", choices=list(FORMULATIONS),
                       help="constrained files: override the file's formulation (index1, ggl, minimal)")
        if p.prog.endswith("simulate"):
            p.add_argument("--project-initial", action="store_true",
                           help="constrained files: project the initial state onto the constraints "
                                "instead of requiring it to satisfy them")

    def progress_option(p):
        p.add_argument("--progress", action=argparse.BooleanOptionalAction, default=None,
                       help="a line on stderr naming the running stage (derive, formulate, cse, compile) and how "
                            "far it is, once a stage lasts a second (default: when stderr is a terminal and "
                            "without -q)")

    def scene_options(p):
        p.add_argument("--outputs", help="comma-separated outputs (energy, momenta, positions, ...)")
        p.add_argument("--runtime-parameters", help="comma-separated parameters kept adjustable")
        p.add_argument("--fold-all", action="store_true", help="fold every parameter as a constant")
        p.add_argument("--set", action="append", metavar="NAME=VALUE", help="parameter value (repeatable)")
        p.add_argument("--no-jacobian", action="store_true", help="do not emit the Jacobian")
        p.add_argument("-q", "--quiet", action="store_true", help="no progress messages")
        progress_option(p)

    g = sub.add_parser("generate", help="model file -> C or Fortran sources in a folder",
                       description=GENERATE_HELP, formatter_class=argparse.RawDescriptionHelpFormatter)
    g.add_argument("model", help="TOML model file, or FILE.py:FUNCTION (executes FILE.py; FUNCTION() returns "
                                 "a Model or ConstrainedSystem)")
    g.add_argument("-o", "--output", help="output folder (required unless --fmu)")
    g.add_argument("--fmu", metavar="FILE", help="write an FMU (Model Exchange and Co-Simulation) instead of sources")
    g.add_argument("--fmi", type=int, choices=[2, 3], default=2, help="--fmu: the FMI version (default 2)")
    g.add_argument("--prefix", help="C identifier prefix (default: the model name)")
    g.add_argument("--lang", choices=["c", "fortran"], default="c",
                   help="language of the model code: C99 (<prefix>.c) or Fortran 2008 (<prefix>.f90); "
                        "the C header <prefix>.h comes with both")
    g.add_argument("--bundle", action="store_true",
                   help="also write Makefile, CMakeLists.txt, rk4_example.c, cvode_example.c and README.md")
    g.add_argument("--check", action="store_true",
                   help="exit 5 if any file to be written is missing or differs, write nothing")
    g.add_argument("--list-outputs", action="store_true",
                   help="print the paths of the files it would write (one a line), write nothing")
    g.add_argument("--depfile", metavar="FILE",
                   help="write a Make-syntax depfile: the stamp (or the manifest) depends on the model's "
                        "input files and on lagcodegen's own files")
    g.add_argument("--stamp", metavar="FILE", help="touch FILE after every successful run")
    g.add_argument("--method", choices=["bdf", "adams"],
                   help="--bundle: the CVODE example's method (default bdf); the model code is the same")
    formulation_option(g)
    scene_options(g)
    g.set_defaults(func=cmd_generate)

    s = sub.add_parser("simulate", help="model file -> compile -> integrate -> CSV/NPZ (+PNG)")
    s.add_argument("model")
    s.add_argument("-o", "--output", required=True, help="result file (.csv or .npz)")
    s.add_argument("--plot", help="also save a PNG plot")
    s.add_argument("--t-end", type=float)
    s.add_argument("--n-out", type=int, help="number of output times (at least 2)")
    s.add_argument("--method", choices=["adams", "bdf", "taylor", "auto"],
                   help="adams/bdf: CVODE; taylor: the generated Taylor integrator (unconstrained files); "
                        "auto: Taylor or Adams by the model's size")
    s.add_argument("--max-steps", type=int, help="step budget of the whole run (default 1000000)")
    s.add_argument("--rtol", type=float)
    s.add_argument("--atol", type=float)
    s.add_argument("--backend", choices=["native", "sksundae"], default="native")
    formulation_option(s)
    scene_options(s)
    s.set_defaults(func=cmd_simulate)

    i = sub.add_parser("info", help="print the derived equations")
    i.add_argument("model")
    i.add_argument("--latex", action="store_true", help="LaTeX instead of pretty text")
    i.add_argument("--simplify", action=argparse.BooleanOptionalAction, default=None,
                   help="simplify before printing (default: only for up to 3 coordinates)")
    i.set_defaults(func=cmd_info)
    w = sub.add_parser("sweep", help="model file -> one ensemble over a grid or a random sample -> table (+PNG)",
                       description=SWEEP_HELP, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_sweep_options(w)
    progress_option(w)
    w.set_defaults(func=cmd_sweep)
    return ap


def _show_progress(args) -> bool:
    """--progress/--no-progress; by default on when stderr is a terminal and -q is not given."""
    if getattr(args, "progress", None) is not None:
        return args.progress
    try:
        return sys.stderr.isatty() and not getattr(args, "quiet", False)
    except (AttributeError, ValueError):
        return False


def main(argv: list[str] | None = None) -> int:
    args = parser().parse_args(argv)
    try:
        # SIGTERM: the atomic writers remove their temporary files
        with sigterm_raises(), progress.enabled(_show_progress(args)):
            return args.func(args)
    except UsageError as exc:
        print(f"lagcodegen: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except CompileError as exc:
        print(f"lagcodegen: error: {exc}", file=sys.stderr)
        return EXIT_COMPILE
    except SolverError as exc:
        print(f"lagcodegen: integration failed: {exc}", file=sys.stderr)
        return EXIT_SOLVER
    except (LagcodegenError, OSError) as exc:
        print(f"lagcodegen: error: {exc}", file=sys.stderr)
        return EXIT_INPUT
    except KeyboardInterrupt:  # Ctrl-C: runs stop within about a second; results are written only when complete
        print("lagcodegen: interrupted", file=sys.stderr)
        return 130
    except Terminated:  # SIGTERM: as Ctrl-C, no partial output left behind
        print("lagcodegen: terminated", file=sys.stderr)
        return 128 + signal.SIGTERM


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
