"""``lagcodegen generate``: a model file's sources (:func:`lagcodegen.api.generate_file`) written
into a folder, with the manifest, depfile and stamp of a build step (:mod:`lagcodegen.buildstep`).

One job: the generate command's options and what it writes; the sources come from the api.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from ..api import generate_file
from ..fmu import export_fmu
from ..buildstep import (generator_record, input_record, manifest_matches, manifest_name, manifest_outdated,
                         manifest_text, read_manifest, stale_by_manifest, touch_stamp, write_depfile)
from ..codegen.bundle import stale_files, write_files
from ..util import fmu_path_problem, folder_problem
from ..codegen.languages import BACKENDS, LANGUAGES, backend
from .common import (EXIT_OK, EXIT_OUTDATED, EXIT_USAGE, MODEL_HELP, UsageError, add_formulation_option,
                     add_scene_options, apply_options, assignments, check_parameter_names, csv, load, say)

HELP = "write a model file's C or Fortran sources into a folder"

DESCRIPTION = """Write the model's C or Fortran sources into a folder, with the manifest
<prefix>.lagcodegen.json (input digests, options, versions of lagcodegen, sympy and symengine).
Files whose content is unchanged are not rewritten. When the manifest matches the inputs and
options, generate, --check and --list-outputs answer without deriving the model.

Model files with [constraints] give <prefix>_dae.h and <prefix>_dae.c (or .f90) in the file's
formulation (--formulation overrides); in minimal coordinates the reduced model's sources.
--bundle adds a Makefile, CMakeLists.txt, examples and a README, to build without lagcodegen.

A Python model, FILE.py:FUNCTION, is executed: FILE.py runs as Python code (with its folder on
sys.path) and FUNCTION() must return a Model, a ConstrainedSystem or a ModelFile. Name only
files you trust; TOML model files are parsed, never executed.

As a build step: --depfile FILE and --stamp FILE for Ninja, Make, Meson and CMake's DEPFILE;
--list-outputs to learn the file names at configure time.

--fmu FILE writes an FMU instead (FMI 2.0, or 3.0 with --fmi 3): Model Exchange and
Co-Simulation in one archive, with the binary for this machine and the sources.

    lagcodegen generate examples/double_pendulum.toml -o dp_bundle --lang c --bundle
    lagcodegen generate examples/double_pendulum.toml --fmu dp.fmu --fmi 3"""


def add_parser(sub) -> None:
    g = sub.add_parser("generate", help=HELP, description=DESCRIPTION,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    g.add_argument("model", help=MODEL_HELP)
    g.add_argument("-o", "--output", help="output folder (required unless --fmu)")
    g.add_argument("--fmu", metavar="FILE", help="write an FMU (Model Exchange and Co-Simulation) instead of sources")
    g.add_argument("--fmi", type=int, choices=[2, 3], default=2, help="--fmu: the FMI version (default 2)")
    g.add_argument("--prefix", help="C identifier prefix (default: the model name)")
    g.add_argument("--lang", choices=list(LANGUAGES), default="c",
                   help="language of the model code: "
                        + " or ".join(f"{be.title} (<prefix>{be.suffix})" for be in BACKENDS.values())
                        + "; the C header <prefix>.h comes with each")
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
    g.add_argument("--sensitivities", action="store_true",
                   help="--bundle: also the forward sensitivity functions (<prefix>_sens.c, C), their prototypes "
                        "in <prefix>.h and sens_example.c")
    g.add_argument("--method", choices=["bdf", "adams"],
                   help="--bundle: the CVODE example's method (default bdf); the model code is the same")
    add_formulation_option(g)
    add_scene_options(g)
    g.set_defaults(func=run)


def _options(args) -> dict:
    """The command-line options that shape the generated files (recorded in the manifest)."""
    return {"lang": args.lang, "prefix": args.prefix, "bundle": args.bundle, "outputs": args.outputs,
            "runtime_parameters": args.runtime_parameters, "fold_all": args.fold_all, "set": args.set or [],
            "no_jacobian": args.no_jacobian, "formulation": args.formulation, "method": args.method,
            **({"urdf": args.urdf} if args.urdf else {}),
            **({"sensitivities": True} if args.sensitivities else {})}


def _listing(out: Path, names) -> str:
    return "".join(f"{out / name}\n" for name in sorted(names))


def _finish_build_step(args, out: Path, names, manifest: str, source) -> None:
    """Depfile and stamp of a successful run (or of a run that found everything up to date).
    The stamp lists the files of the folder as --list-outputs prints them."""
    if args.depfile:
        write_depfile(args.depfile, [args.stamp or str(out / manifest)], source.inputs)
    if args.stamp:
        touch_stamp(args.stamp, _listing(out, names))


def _generate_fmu(args) -> int:
    """``generate --fmu FILE [--fmi 3]``: the model file as an FMU (:func:`lagcodegen.fmu.export_fmu`)."""
    if args.bundle or args.check or args.list_outputs or not backend(args.lang).c_sources:
        raise UsageError(f"--fmu writes one FMU file: --bundle, --check, --list-outputs and --lang {args.lang} "
                         "do not apply")
    problem = fmu_path_problem(args.fmu)
    if problem:
        raise UsageError(f"--fmu {args.fmu}: {problem}")
    mf = load(args.model, args.quiet, args.urdf).model_file
    check_parameter_names(mf, args)
    t0 = time.perf_counter()
    tunable = [] if args.fold_all else csv(args.runtime_parameters)
    path = export_fmu(mf, args.fmu, fmi_version=args.fmi, outputs=csv(args.outputs), tunable=tunable,
                      values=assignments(args.set), model_identifier=args.prefix)
    say(f"wrote {path} (FMI {args.fmi}.0) in {time.perf_counter() - t0:.3f} s", args.quiet)
    return EXIT_OK


def run(args) -> int:
    if args.fmu:
        return _generate_fmu(args)
    if not args.output:
        raise UsageError("generate needs -o/--output FOLDER (or --fmu FILE)")
    if args.sensitivities and not args.bundle:
        raise UsageError("--sensitivities adds the sensitivity functions to a bundle: give --bundle too")
    if args.check and args.list_outputs:
        print("lagcodegen generate: --check and --list-outputs exclude each other", file=sys.stderr)
        return EXIT_USAGE
    problem = folder_problem(args.output)
    if problem:
        raise UsageError(f"-o {args.output}: {problem}; give the output folder")
    source = load(args.model, args.quiet, args.urdf)
    mf = source.model_file
    check_parameter_names(mf, args)
    out = Path(args.output)
    manifest = manifest_name(args.prefix or mf.model.name)
    inputs, options, generator = input_record(source), _options(args), generator_record()
    record = read_manifest(out, args.prefix or mf.model.name)
    if manifest_matches(record, inputs, options, generator):
        # the folder was generated from these inputs with these options: no derivation needed
        if args.list_outputs:
            print(_listing(out, [*record["files"], manifest]), end="")
            return EXIT_OK
        stale = stale_by_manifest(out, record)
        if not stale:
            say(f"{out} is up to date (manifest {manifest})", args.quiet)
            if not args.check:
                _finish_build_step(args, out, [*record["files"], manifest], manifest, source)
            return EXIT_OK
        if args.check:
            print(f"lagcodegen: {out} is out of date: {', '.join(stale)}", file=sys.stderr)
            return EXIT_OUTDATED
    t0 = time.perf_counter()
    files = generate_file(apply_options(mf, args), lang=args.lang, bundle=args.bundle, method=args.method,
                          prefix=args.prefix, report=lambda msg: say(msg, args.quiet),
                          **({"sensitivities": True} if args.sensitivities else {}))
    say(f"derived and generated {len(files)} file(s) in {time.perf_counter() - t0:.3f} s", args.quiet)
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
        say(f"{out} is up to date", args.quiet)
        return EXIT_OK
    written = write_files(out, files)
    for path in written:
        say(f"wrote {path}", args.quiet)
    if len(written) < len(files):
        say(f"{len(files) - len(written)} file(s) in {out} already up to date", args.quiet)
    _finish_build_step(args, out, files, manifest, source)
    return EXIT_OK
