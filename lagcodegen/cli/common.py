"""What the commands share: exit codes, progress lines, the options that shape a model's code,
and the command line applied to a loaded model file's settings.

One job: turning command-line options into the settings the api takes (each checked before
any work); the commands call :mod:`lagcodegen.api` for everything else.
"""

from __future__ import annotations

import argparse
import dataclasses
import difflib
import sys
import time

from ..buildstep import ModelSource, load_source, split_python_spec
from ..modelfile import FORMULATIONS, ModelFile
from ..util import EXCERPT, FileProblem, excerpt, read_bounded

EXIT_OK, EXIT_INPUT, EXIT_USAGE, EXIT_COMPILE, EXIT_SOLVER, EXIT_OUTDATED = 0, 1, 2, 3, 4, 5
EXIT_NOT_CONVERGED = 6  # fit: the optimizer did not reach a minimum

#: The help of the model argument of every command.
MODEL_HELP = ("model file (.toml), or FILE.py:FUNCTION (executes FILE.py; FUNCTION() returns a Model, a "
              "ConstrainedSystem or a ModelFile)")


class UsageError(Exception):
    """A bad command-line option (exit 2), found before any work."""


def say(msg: str, quiet: bool) -> None:
    """A progress line on stderr (none with -q)."""
    if not quiet:
        print(f"lagcodegen: {msg}", file=sys.stderr, flush=True)


def csv(text: str | None) -> list[str] | None:
    """The items of a comma-separated option, or None when it is not given."""
    if text is None:
        return None
    return [s.strip() for s in text.split(",") if s.strip()]


def _name(name: str) -> str:
    """A name given on the command line, as it is, or an excerpt if it is long."""
    return name if len(name) <= EXCERPT else excerpt(name)


#: The largest input table file --input reads, in bytes (64 MiB: millions of rows t, value); a
#: larger one, or a file that is not a regular file (a FIFO, a device such as /dev/zero, a
#: folder), is a usage error naming it, found before anything is read beyond the cap.
INPUT_TABLE_MAX_BYTES = 64 * 2**20


def _shown(path: str) -> str:
    """A file's path as a message shows it: whole as far as any file system allows (a path is
    not an input value to cut at 80 characters), quoted."""
    return excerpt(str(path), limit=4096)


def read_input_table(path: str, *, what: str, max_bytes: int | None = None) -> str:
    """The text of the input table file ``path`` (``what`` names it in errors, "--input F"):
    a regular file (a FIFO or device is opened without blocking and refused), of at most
    ``max_bytes`` bytes (default :data:`INPUT_TABLE_MAX_BYTES`; read in chunks, never more
    than ``max_bytes + 1``), UTF-8."""
    max_bytes = INPUT_TABLE_MAX_BYTES if max_bytes is None else max_bytes
    try:
        data = read_bounded(path, max_bytes=max_bytes)
    except FileProblem as exc:
        if exc.kind == "unreadable":
            raise UsageError(f"{what}: cannot read {_shown(path)}: {exc.detail}") from None
        if exc.kind == "not regular":
            raise UsageError(f"{what}: {_shown(path)} is {exc.detail}, not a regular file of two columns t, value") \
                from None
        raise UsageError(f"{what}: {_shown(path)} is larger than the input table limit of {max_bytes} bytes "
                         f"({max_bytes / 2**20:.3g} MiB)") from None
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise UsageError(f"{what}: {_shown(path)} is not UTF-8 text (byte {exc.start})") from None


def input_tables(items: list[str] | None) -> dict:
    """The tables of --input NAME=FILE[:KIND] (FILE: two columns t, value, whitespace or commas;
    KIND: linear (default), zoh or cubic), as simulate(inputs=...) takes them. FILE is a
    regular file of at most :data:`INPUT_TABLE_MAX_BYTES` (:func:`read_input_table`)."""
    import io

    import numpy as np

    from ..errors import LagcodegenError
    from ..solvers.inputs import KINDS, Table
    out = {}
    for item in items or []:
        name, sep, rest = item.partition("=")
        name = name.strip()
        path, _, kind = rest.rpartition(":") if rest.rsplit(":", 1)[-1] in KINDS else (rest, "", "linear")
        if not sep or not name or not path:
            raise UsageError(f"--input expects NAME=FILE[:{'|'.join(KINDS)}], got {excerpt(item)}")
        text = read_input_table(path, what=f"--input {_name(name)}")
        try:
            rows = np.loadtxt(io.StringIO(text), delimiter="," if path.endswith(".csv") else None, ndmin=2)
        except (OSError, ValueError) as exc:
            raise UsageError(f"--input {_name(name)}: cannot read {_shown(path)} as two columns t, value: "
                             f"{excerpt(str(exc))}") from None
        if rows.shape[1] != 2:
            raise UsageError(f"--input {_name(name)}: {_shown(path)} has {rows.shape[1]} columns, expected 2 "
                             "(t, value)")
        try:
            out[name] = Table(rows[:, 0], rows[:, 1], kind=kind, name=f"--input {_name(name)}")
        except LagcodegenError as exc:
            raise UsageError(str(exc)) from None
    return out


def assignments(items: list[str] | None) -> dict[str, float]:
    """The NAME=VALUE pairs of --set."""
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


def check_parameter_names(mf: ModelFile, args) -> None:
    """Every --set names a parameter of the loaded model (exit 2 otherwise), checked before any
    derivation: a misspelt name must not be ignored."""
    params = [p.name for p in mf.model.params]
    for name in assignments(getattr(args, "set", None)):
        if name not in params:
            close = difflib.get_close_matches(name, params, n=1) or [p for p in params if p.lower() == name.lower()]
            hint = f"; did you mean {close[0]!r}?" if close else ""
            raise UsageError(f"--set {_name(name)}: not a parameter of {mf.model.name}{hint} "
                             f"(parameters: {', '.join(params) or 'none'})")


#: --urdf KEY=VALUE: the keywords of lagcodegen.modelfile.urdf.load the command line takes.
URDF_KEYS = ("floating", "mimic", "limits", "lock", "gravity", "friction", "friction_velocity", "form", "name",
             "inertial_parameters", "rotation")


class _UrdfOption(argparse.Action):
    """``--KEY VALUE`` for a URDF loading option: the item ``KEY=VALUE`` of ``--urdf``."""

    def __call__(self, parser, namespace, values, option_string=None):
        items = list(getattr(namespace, self.dest, None) or [])
        items.append(f"{option_string.lstrip('-')}={values}")
        setattr(namespace, self.dest, items)


def urdf_options(items: list[str] | None) -> dict:
    """``--urdf KEY=VALUE`` items as the keywords of :func:`lagcodegen.modelfile.urdf.load`:
    floating=true|false|NAME, mimic=driven|error|independent|coupled, limits=true|false|stop|monitor|stop:E,
    lock=JOINT[:POSITION],..., gravity=X,Y,Z, friction=ignore|smooth, friction_velocity=V,
    form=tree|closed, name=NAME, inertial_parameters=true|false|LINK,..., rotation=quaternion|ZYX."""
    out: dict = {}
    for item in items or []:
        key, sep, value = item.partition("=")
        key = key.strip()
        if not sep or key not in URDF_KEYS:
            raise UsageError(f"--urdf {item!r:.80}: give KEY=VALUE with KEY one of {', '.join(URDF_KEYS)}")
        low = value.strip().lower()
        try:
            if key in ("floating", "limits") and low in ("true", "false", "yes", "no", "1", "0"):
                out[key] = low in ("true", "yes", "1")
            elif key == "inertial_parameters":
                out[key] = low in ("true", "yes", "1") if low in ("true", "false", "yes", "no", "1", "0") \
                    else [n.strip() for n in value.split(",") if n.strip()]
            elif key == "limits" and low.startswith("stop:"):
                out[key] = ("stop", float(low[5:]))
            elif key == "lock":
                pairs = [p.partition(":") for p in value.split(",") if p.strip()]
                out[key] = {n.strip(): float(v) for n, _, v in pairs} if any(s for _, s, _ in pairs) \
                    else [n.strip() for n, _, _ in pairs]
            elif key == "gravity":
                out[key] = tuple(float(x) for x in value.split(","))
            elif key == "friction_velocity":
                out[key] = float(value)
            else:
                out[key] = value.strip()
        except ValueError:
            raise UsageError(f"--urdf {item!r:.80}: {key} takes a number where this has none") from None
    return out


def load(spec: str, quiet: bool, urdf: list[str] | None = None) -> ModelSource:
    """The model named on the command line (:func:`lagcodegen.buildstep.load_source`: a model file
    by its suffix, or FILE.py:FUNCTION; ``urdf``: --urdf KEY=VALUE items), with a progress line."""
    t0 = time.perf_counter()
    source = load_source(spec, urdf=urdf_options(urdf))
    kind = "executed" if split_python_spec(spec) else "loaded"
    say(f"{kind} {spec} ({source.model_file.model.n} coordinates) in {time.perf_counter() - t0:.3f} s", quiet)
    return source


def apply_options(mf: ModelFile, args) -> ModelFile:
    """``mf`` with its ``[simulation]`` settings overridden by the command line (outputs,
    run-time and folded parameters, --set values, Jacobian, formulation, times, tolerances, step
    budget). Options a command lacks leave the setting as it is. Says what a formulation other
    than index1 leaves out of the file's settings."""
    s = mf.simulation
    changes: dict = {}
    if getattr(args, "outputs", None) is not None:
        changes["outputs"] = csv(args.outputs)
    if getattr(args, "fold_all", False):
        changes["runtime_parameters"] = []
    elif getattr(args, "runtime_parameters", None) is not None:
        changes["runtime_parameters"] = csv(args.runtime_parameters)
    changes["parameters"] = {**s.parameters, **assignments(getattr(args, "set", None))}
    if getattr(args, "no_jacobian", False):
        changes["jacobian"] = False
    for name in ("t_end", "n_out", "rtol", "atol", "max_steps"):
        if getattr(args, name, None) is not None:
            changes[name] = getattr(args, name)
    quiet = getattr(args, "quiet", False)
    formulation = getattr(args, "formulation", None)
    if mf.constrained is None:
        if formulation:
            say("--formulation ignored: the file has no [constraints]", quiet)
    else:
        formulation = formulation or s.formulation or "index1"
        changes["formulation"] = formulation
        if formulation != "index1":
            dropped = [name for name, used in (("baumgarte", s.baumgarte not in ((0.0, 0.0), "auto")),
                                               ("projection", s.projection)) if used]
            if dropped:
                say(f"formulation {formulation}: ignoring the file's {' and '.join(dropped)} (index1 only)", quiet)
            changes.update(baumgarte=(0.0, 0.0), projection=False)
        system = mf.constrained
        say(f"{system.J} equality constraint(s), {len(system.inequalities)} inequality constraint(s), "
            f"{len(mf.events)} event(s); formulation {formulation}", quiet)
    return dataclasses.replace(mf, simulation=dataclasses.replace(s, **changes))


def add_formulation_option(p: argparse.ArgumentParser) -> None:
    p.add_argument("--formulation", choices=list(FORMULATIONS),
                   help="files with [constraints]: the formulation instead of the file's (index1, ggl, minimal)")


def add_progress_option(p: argparse.ArgumentParser) -> None:
    p.add_argument("--progress", action=argparse.BooleanOptionalAction, default=None,
                   help="a line on stderr naming the running stage (derive, formulate, cse, compile) and how "
                        "far it is, once a stage lasts a second (default: when stderr is a terminal and "
                        "without -q)")


def add_scene_options(p: argparse.ArgumentParser) -> None:
    """The options that shape the model's code (outputs, parameters, Jacobian), -q, --progress."""
    p.add_argument("--outputs", help="comma-separated outputs (energy, momenta, positions, ...)")
    p.add_argument("--runtime-parameters", help="comma-separated parameters kept adjustable")
    p.add_argument("--fold-all", action="store_true", help="fold every parameter as a constant")
    p.add_argument("--set", action="append", metavar="NAME=VALUE", help="parameter value (repeatable)")
    p.add_argument("--no-jacobian", action="store_true", help="do not emit the Jacobian")
    p.add_argument("--urdf", action="append", metavar="KEY=VALUE",
                   help="a URDF model's loading option (repeatable): floating=true|NAME, "
                        "mimic=independent|coupled|error, "
                        "limits=true|stop:E|monitor, lock=JOINT[:POSITION],..., gravity=X,Y,Z, friction=smooth, "
                        "form=tree|closed, name=NAME, inertial_parameters=true|LINK,... (the links' inertials as "
                        "run-time parameters <link>_m, _mx, ..., _Izz), rotation=ZYX (Euler angles on free "
                        "joints instead of quaternions)")
    p.add_argument("--floating", action="append_const", dest="urdf", const="floating=true",
                   help="a URDF model's root on a free joint root_joint (--urdf floating=true): Pinocchio's free-flyer "
                        "layout, q (x, y, z, qx, qy, qz, qw), v (linear, angular velocity in the root's frame)")
    for key, meta, text in (("mimic", "driven|independent|coupled|error", "how <mimic> joints load"),
                            ("lock", "JOINT[:POSITION],...", "joints held fixed"),
                            ("limits", "true|stop:E|monitor", "joint limits as hard stops"),
                            ("friction", "ignore|smooth", "the URDF's Coulomb joint friction")):
        p.add_argument(f"--{key}", action=_UrdfOption, dest="urdf", metavar=meta,
                       help=f"a URDF model's {text} (--urdf {key}=...)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress messages")
    add_progress_option(p)
