"""``lagcodegen sweep``: one ensemble over a grid or a random sample of a model file's
parameters and initial values (:func:`lagcodegen.api.run_sweep`), one row per member.

One job: the sweep command's options, as a :class:`lagcodegen.sweep.SweepSpec`.
"""

from __future__ import annotations

import argparse

from ..api import run_sweep
from ..sweep import SweepOptionError, SweepSpec
from .common import EXIT_OK, MODEL_HELP, UsageError, add_formulation_option, add_progress_option, input_tables

HELP = "run one ensemble over a grid or a random sample of parameters and initial values; write a table"

DESCRIPTION = """Run one ensemble over a grid or a random sample of the model's parameters and
initial values (coordinates by name, velocities as <q>_dot), all members in one call into the
generated C over a thread pool, and write one row per member: the swept values, status (0
success, negative: the member failed), t_reached, final_<state> and final_<output>.

    lagcodegen sweep pendulum.toml --grid g=9.7:9.9:101 -o g.csv --plot g.png
    lagcodegen sweep pendulum.toml --sample l=uniform:0.9:1.1 --sample theta=normal:1:0.1 \\
        --n 10000 --seed 1 -o mc.npz --plot mc.png --plot-y energy

Options are checked before any work (exit 2); Ctrl-C stops within about a second, writing
nothing (exit 130); a sweep whose every member failed exits 4 (after writing the table)."""


def add_parser(sub) -> None:
    """The sweep command; its options' names are the attribute names of
    :class:`lagcodegen.sweep.SweepSpec`."""
    p = sub.add_parser("sweep", help=HELP, description=DESCRIPTION,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("model", help=MODEL_HELP)
    p.add_argument("-o", "--output", required=True, help="table, one row per member (.csv or .npz)")
    p.add_argument("--grid", action="append", metavar="NAME=START:STOP:NUM",
                   help="NUM values from START to STOP (or NAME=V1,V2,...); several give the product")
    p.add_argument("--sample", action="append", metavar="NAME=DIST:A:B",
                   help="random values: uniform:LOW:HIGH, normal:MEAN:SD, loguniform:LOW:HIGH (repeatable)")
    p.add_argument("--n", type=int, help="--sample: number of members")
    p.add_argument("--seed", type=int, help="--sample: seed of numpy's default_rng (default: a random one, printed)")
    p.add_argument("--set", action="append", metavar="NAME=VALUE", help="fixed parameter value (repeatable)")
    p.add_argument("--plot", help="PNG of a final value against the first swept quantity")
    p.add_argument("--plot-y", help="--plot: the state or output plotted (default: the first coordinate)")
    p.add_argument("--threads", type=int, help="threads of the ensemble call (default: every core)")
    p.add_argument("--method", choices=["adams", "bdf", "taylor", "auto"],
                   help="integration method (default: the file's; files with [constraints]: adams or bdf)")
    p.add_argument("--rtol", type=float, help="relative tolerance (default: the file's)")
    p.add_argument("--atol", type=float, help="absolute tolerance (default: the file's)")
    p.add_argument("--t-end", type=float, help="end time of every member (default: the file's t_end)")
    p.add_argument("--max-steps", type=int, help="step budget of each member")
    p.add_argument("--max-wall", type=float, help="wall-clock limit of each member, seconds")
    p.add_argument("--outputs", help="comma-separated outputs (default: the file's)")
    add_formulation_option(p)
    p.add_argument("--project-initial", action="store_true",
                   help="files with [constraints]: project each member's initial state onto the constraints")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress messages")
    p.add_argument("--input", action="append", metavar="NAME=FILE[:KIND]",
                   help="an input's table, the same for every member: FILE has two columns t, value; KIND linear "
                        "(default), zoh or cubic (repeatable); FILE a regular file of at most 64 MiB")
    add_progress_option(p)
    p.set_defaults(func=run)


def spec_from_namespace(args) -> SweepSpec:
    """A :class:`SweepSpec` from an argparse namespace with the same attribute names."""
    names = SweepSpec.__dataclass_fields__
    spec = {k: getattr(args, k) for k in names if hasattr(args, k) and getattr(args, k) is not None}
    if getattr(args, "input", None):
        spec["inputs"] = input_tables(args.input)
    return SweepSpec(**spec)


def run(args) -> int:
    try:
        run_sweep(spec_from_namespace(args))
    except SweepOptionError as exc:
        raise UsageError(str(exc)) from None
    return EXIT_OK
