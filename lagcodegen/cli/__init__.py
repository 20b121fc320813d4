"""The ``lagcodegen`` command (also ``python -m lagcodegen``): :func:`main` parses the command
line and runs one command, a module each (:mod:`.generate`, :mod:`.simulate`, :mod:`.info`,
:mod:`.sweep`, :mod:`.fit`; what they share in :mod:`.common`), and turns what went wrong into an exit code.

One job: the command line, from the options (each checked before any work) to the exit code;
the pipeline runs in :mod:`lagcodegen.api`.
"""

from __future__ import annotations

import argparse
import re
import signal
import sys

from .. import progress
from ..buildstep import cmake_dir
from ..errors import CompileError, LagcodegenError, SolverError
from ..util import Terminated, sigterm_raises
from ..version import __version__
from . import fit, generate, info, simulate, sweep
from .common import EXIT_COMPILE, EXIT_INPUT, EXIT_SOLVER, EXIT_USAGE, UsageError

#: The commands, in the order ``lagcodegen --help`` lists them.
COMMANDS = (simulate, generate, info, sweep, fit)

DESCRIPTION = """Lagrangian mechanics to C and Fortran: derive a model's equations of motion
(Lagrange's equations, M q'' = F) from a model file (TOML, a URDF robot, or FILE.py:FUNCTION),
write their C or Fortran sources, or compile and integrate them. `lagcodegen COMMAND --help`
describes each command.

    lagcodegen simulate examples/double_pendulum.toml -o out/dp.csv --plot out/dp.png
    lagcodegen generate examples/double_pendulum.toml -o dp_bundle --bundle
    lagcodegen info examples/pendulum.toml
    lagcodegen sweep examples/pendulum.toml --grid g=9.7:9.9:101 -o g.csv
    lagcodegen fit model.toml data.csv --fit l,c -o fit.csv --plot fit.png

exit codes:
    0  success
    1  bad model or input (the message names the file, key and token)
    2  bad command line
    3  the C compiler failed
    4  the integration failed
    5  generate --check: the output folder is out of date
    6  fit: the fit did not converge (the estimates are printed, marked not converged)
  130  interrupted (Ctrl-C); 143: terminated (SIGTERM). No partial output file is left, and a
       command's files (-o, --plot, --animate) appear together or not at all."""


class _CMakeDir(argparse.Action):
    def __call__(self, parser, namespace, values, option_string=None):
        print(cmake_dir())
        parser.exit()


def parser() -> argparse.ArgumentParser:
    """The parser of the whole command line, one subparser per command."""
    ap = argparse.ArgumentParser(prog="lagcodegen", description=DESCRIPTION,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--version", action="version", version=f"lagcodegen {__version__}")
    ap.add_argument("--cmake-dir", action=_CMakeDir, nargs=0,
                    help="print the folder of lagcodegen's CMake package (for lagcodegen_DIR) and exit")
    sub = ap.add_subparsers(dest="command", required=True)
    for command in COMMANDS:
        command.add_parser(sub)
    return ap


def _show_progress(args) -> bool:
    """--progress/--no-progress; by default on when stderr is a terminal and -q is not given."""
    if getattr(args, "progress", None) is not None:
        return args.progress
    try:
        return sys.stderr.isatty() and not getattr(args, "quiet", False)
    except (AttributeError, ValueError):
        return False


#: A negative number as argparse would not take it for an option's value ("-1e-6", "-inf").
_NEGATIVE = re.compile(r"-(?:(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?|inf|infinity|nan)", re.I)


def _valued_options(ap: argparse.ArgumentParser) -> set[str]:
    """The option strings (of ``ap`` and its commands) that take one value."""
    out = set()
    for action in ap._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in action.choices.values():
                out |= _valued_options(sub)
        elif action.option_strings and action.nargs is None:
            out.update(action.option_strings)
    return out


def join_negative_values(ap: argparse.ArgumentParser, argv: list[str]) -> list[str]:
    """``argv`` with ``--rtol -1e-6`` written ``--rtol=-1e-6``: argparse reads a value that starts
    with "-" and is not a plain decimal as an unknown option ("expected one argument"), where the
    command's own check says what is wrong with the number."""
    valued = _valued_options(ap)
    out: list[str] = []
    i = 0
    while i < len(argv):
        if argv[i] in valued and i + 1 < len(argv) and _NEGATIVE.fullmatch(argv[i + 1]):
            out.append(f"{argv[i]}={argv[i + 1]}")
            i += 2
        else:
            out.append(argv[i])
            i += 1
    return out


def main(argv: list[str] | None = None) -> int:
    """Run the command line ``argv`` (default: ``sys.argv[1:]``); returns the exit code."""
    ap = parser()
    args = ap.parse_args(join_negative_values(ap, sys.argv[1:] if argv is None else list(argv)))
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
