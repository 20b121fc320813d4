"""The ``lagcodegen`` command: generate, simulate, info.

Exit codes:
    0  success
    1  bad model or input (the message names the file, key and token)
    2  bad command line
    3  the C compiler failed
    4  the integration failed
    5  ``generate --check``: the output folder is out of date
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from .errors import CompileError, LagcodegenError, ModelError, SolverError

EXIT_OK, EXIT_INPUT, EXIT_USAGE, EXIT_COMPILE, EXIT_SOLVER, EXIT_OUTDATED = 0, 1, 2, 3, 4, 5


def _progress(msg: str, quiet: bool) -> None:
    if not quiet:
        print(f"lagcodegen: {msg}", file=sys.stderr, flush=True)


def _csv(text: str | None) -> list[str] | None:
    if text is None:
        return None
    return [s.strip() for s in text.split(",") if s.strip()]


def _assignments(items: list[str]) -> dict[str, float]:
    out = {}
    for item in items or []:
        name, sep, value = item.partition("=")
        if not sep:
            raise ModelError(f"--set expects NAME=VALUE, got {item!r}")
        try:
            out[name.strip()] = float(value)
        except ValueError:
            raise ModelError(f"--set {name.strip()}: {value!r} is not a number") from None
    return out


def _load(path: str, quiet: bool):
    from .modelfile import load_model
    t0 = time.perf_counter()
    mf = load_model(path)
    _progress(f"loaded {path} ({mf.model.n} coordinates) in {time.perf_counter() - t0:.3f} s", quiet)
    return mf


def _scene(mf, args, quiet: bool):
    from .scene import Scene
    t0 = time.perf_counter()
    eom = mf.derive()  # derivation errors carry the file and line
    _progress(f"derived Lagrange's equations in {time.perf_counter() - t0:.3f} s", quiet)
    sim = mf.simulation
    outputs = _csv(args.outputs) if getattr(args, "outputs", None) is not None else list(sim.outputs)
    runtime = sim.runtime_parameters
    if getattr(args, "fold_all", False):
        runtime = []
    elif getattr(args, "runtime_parameters", None) is not None:
        runtime = _csv(args.runtime_parameters)
    values = dict(sim.parameters)
    values.update(_assignments(getattr(args, "set", None)))
    folded_values = {k: v for k, v in values.items() if runtime is not None and k not in runtime}
    scene = Scene(eom, jacobian=not getattr(args, "no_jacobian", False) and sim.jacobian, outputs=outputs,
                  runtime_parameters=runtime, values=folded_values, prefix=getattr(args, "prefix", None))
    runtime_values = {k: v for k, v in values.items() if k in scene.runtime_parameters}
    return scene, runtime_values


def cmd_generate(args) -> int:
    from .bundle import render_bundle, stale_files, write_files
    from .codegen import generate_code
    mf = _load(args.model, args.quiet)
    scene, runtime_values = _scene(mf, args, args.quiet)
    code = generate_code(scene, args.lang)
    files = dict(code.files)
    if args.bundle:
        q0, v0 = mf.initial_state()
        sim = mf.simulation
        files = render_bundle(scene, args.lang, y0=q0 + v0, params=runtime_values, t_start=sim.t_start,
                              t_end=sim.t_end, code=code)
    out = Path(args.output)
    if args.check:
        stale = stale_files(out, files)
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
    return EXIT_OK


def cmd_simulate(args) -> int:
    import numpy as np
    from .build import build
    from .codegen import generate_c
    mf = _load(args.model, args.quiet)
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
                      backend=args.backend, jacobian=scene.jacobian)
    _progress(f"integrated t = {times[0]:g}..{times[-1]:g} in {time.perf_counter() - t0:.4f} s: "
              f"{res.stats.get('steps')} steps, {res.stats.get('rhs_evals')} RHS evaluations", args.quiet)
    out = Path(args.output)
    out.parent.mkdir(parents=True, exist_ok=True)
    res.save(out)
    _progress(f"wrote {out}", args.quiet)
    if args.plot:
        plot = Path(args.plot)
        plot.parent.mkdir(parents=True, exist_ok=True)
        res.plot(plot)
        _progress(f"wrote {plot}", args.quiet)
    for name in res.outputs:
        if name in ("energy",):
            _progress(f"{name} drift over the run: {res.drift(name):.3e} (relative)", args.quiet)
    return EXIT_OK


def cmd_info(args) -> int:
    import sympy as sp
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
    for title, expr in sections:
        print(f"\n{title}:")
        simplify = args.simplify if args.simplify is not None else model.n <= 3
        print(show(sp.simplify(expr) if simplify else expr))
    return EXIT_OK


def parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="lagcodegen", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--version", action="version", version=f"lagcodegen {__import__('lagcodegen').__version__}")
    sub = ap.add_subparsers(dest="command", required=True)

    def scene_options(p):
        p.add_argument("--outputs", help="comma-separated outputs (energy, momenta, positions, ...)")
        p.add_argument("--runtime-parameters", help="comma-separated parameters kept adjustable")
        p.add_argument("--fold-all", action="store_true", help="fold every parameter as a constant")
        p.add_argument("--set", action="append", metavar="NAME=VALUE", help="parameter value (repeatable)")
        p.add_argument("--no-jacobian", action="store_true", help="do not emit the Jacobian")
        p.add_argument("-q", "--quiet", action="store_true", help="no progress messages")

    g = sub.add_parser("generate", help="model file -> C or Fortran sources in a folder")
    g.add_argument("model")
    g.add_argument("-o", "--output", required=True, help="output folder")
    g.add_argument("--prefix", help="C identifier prefix (default: the model name)")
    g.add_argument("--lang", choices=["c", "fortran"], default="c",
                   help="language of the model code: C99 (<prefix>.c) or Fortran 2008 (<prefix>.f90); "
                        "the C header <prefix>.h comes with both")
    g.add_argument("--bundle", action="store_true",
                   help="also write Makefile, CMakeLists.txt, rk4_example.c, cvode_example.c and README.md")
    g.add_argument("--check", action="store_true",
                   help="exit 5 if any file to be written is missing or differs, write nothing")
    scene_options(g)
    g.set_defaults(func=cmd_generate)

    s = sub.add_parser("simulate", help="model file -> compile -> integrate -> CSV/NPZ (+PNG)")
    s.add_argument("model")
    s.add_argument("-o", "--output", required=True, help="result file (.csv or .npz)")
    s.add_argument("--plot", help="also save a PNG plot")
    s.add_argument("--t-end", type=float)
    s.add_argument("--n-out", type=int)
    s.add_argument("--method", choices=["adams", "bdf"])
    s.add_argument("--rtol", type=float)
    s.add_argument("--atol", type=float)
    s.add_argument("--backend", choices=["native", "sksundae"], default="native")
    scene_options(s)
    s.set_defaults(func=cmd_simulate)

    i = sub.add_parser("info", help="print the derived equations")
    i.add_argument("model")
    i.add_argument("--latex", action="store_true", help="LaTeX instead of pretty text")
    i.add_argument("--simplify", action=argparse.BooleanOptionalAction, default=None,
                   help="simplify before printing (default: only for up to 3 coordinates)")
    i.set_defaults(func=cmd_info)
    return ap


def main(argv: list[str] | None = None) -> int:
    args = parser().parse_args(argv)
    try:
        return args.func(args)
    except CompileError as exc:
        print(f"lagcodegen: error: {exc}", file=sys.stderr)
        return EXIT_COMPILE
    except SolverError as exc:
        print(f"lagcodegen: integration failed: {exc}", file=sys.stderr)
        return EXIT_SOLVER
    except (LagcodegenError, OSError) as exc:
        print(f"lagcodegen: error: {exc}", file=sys.stderr)
        return EXIT_INPUT


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
