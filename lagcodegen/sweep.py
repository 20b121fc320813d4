"""Sweeps: one ensemble over a grid or random samples of a model file's parameters and initial
values, written as one row per member (CSV or NPZ), with an optional PNG of a final value
against the swept quantity. :func:`lagcodegen.api.run_sweep` runs one (the command
``lagcodegen sweep``); this module holds its steps: the options checked (:func:`check_options`,
:func:`check_names`), the members drawn (:func:`member_values`), the compile options
(:func:`compile_options`), the ensemble run and the table (:func:`run_plan`), the files.

The swept names are the model's parameters (made run-time parameters for the run), its
coordinates (initial values) and their velocities ``<q>_dot``. ``--grid NAME=START:STOP:NUM``
(NUM evenly spaced values, both ends included) or ``--grid NAME=V1,V2,...``; several ``--grid``
give their Cartesian product (the first varies slowest). ``--sample NAME=DIST:A:B`` with
``--n N`` draws N members (uniform:LOW:HIGH, normal:MEAN:SD, loguniform:LOW:HIGH) from
``numpy.random.default_rng(--seed)`` in the order the options are given, so a seed repeats a
sample exactly. Grids and samples exclude each other.

Every member runs from the file's ``t_start`` to ``--t-end`` (default the file's) in ONE call into
the generated C (:meth:`lagcodegen.CompiledModel.ensemble`, or the ``ensemble`` of the
constrained formulation for files with [constraints]). The table's columns: the swept
values, ``status`` (0 success, negative: the member's failure flag, see
:class:`lagcodegen.solvers.ensemble_result.EnsembleResult`), ``t_reached``, then ``final_<name>`` for
every state and output at the last time reached. A failed member is a row like the others (its
final values at the time it stopped, NaN if never run); only a sweep whose every member failed
is an error (after writing the table).

The options are checked before any work: their syntax and ranges before the file is read, the
names against the model before it is derived and compiled, and ``--plot-y`` against the compiled
states and outputs before the integration (:class:`SweepOptionError`, exit 2 from the command).
Ctrl-C stops the ensemble within about a second; nothing is written then.
"""

from __future__ import annotations

import math
import secrets
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np

from .errors import LagcodegenError, SolverError
from .modelfile import FORMULATIONS, constrained_method, constrained_outputs
from .solvers.ensemble import EnsembleInterrupted
from .util import atomic_binary, output_problem, staged_outputs

#: Distributions of ``--sample``, with the meaning of their two numbers.
DISTRIBUTIONS = {"uniform": "LOW:HIGH", "normal": "MEAN:SD", "loguniform": "LOW:HIGH (0 < LOW)"}
#: At most this many members (a row of ~10 doubles each: 8 GB of table at the limit).
MAX_MEMBERS = 100_000_000
#: Messages of failed members printed on stderr (the NPZ keeps them all).
SHOWN_FAILURES = 3


class SweepOptionError(LagcodegenError):
    """A bad option of ``lagcodegen sweep`` (the command exits 2), found before any work."""


@dataclass
class SweepSpec:
    """The options of a sweep, as the command line gives them (the option names of
    ``lagcodegen sweep``, :mod:`lagcodegen.cli.sweep`)."""

    model: str
    output: str
    grid: Sequence[str] = ()
    sample: Sequence[str] = ()
    n: int | None = None
    seed: int | None = None
    set: Sequence[str] = ()
    plot: str | None = None
    plot_y: str | None = None
    threads: int | None = None
    method: str | None = None
    rtol: float | None = None
    atol: float | None = None
    t_end: float | None = None
    max_steps: int | None = None
    max_wall: float | None = None
    formulation: str | None = None
    project_initial: bool = False
    outputs: str | None = None
    quiet: bool = False
    #: input tables shared by every member (name -> Table or (times, values); CLI: --input)
    inputs: Any = None


@dataclass
class Plan:
    """The checked options: axes, sizes and the seed."""

    spec: SweepSpec
    kind: str                                     # "grid" or "sample"
    grids: list = field(default_factory=list)     # [(name, values)]
    samples: list = field(default_factory=list)   # [(name, dist, a, b)]
    sets: dict = field(default_factory=dict)
    n_members: int = 0
    seed: int | None = None

    @property
    def names(self) -> list[str]:
        return [g[0] for g in self.grids] + [s[0] for s in self.samples]


# ---------------------------------------------------------------------- options
def _number(text: str, what: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise SweepOptionError(f"{what}: {text!r} is not a number") from None
    if not math.isfinite(value):
        raise SweepOptionError(f"{what}: {text!r} is not a finite number")
    return value


def _name_value(item: str, option: str) -> tuple[str, str]:
    name, sep, value = item.partition("=")
    name = name.strip()
    if not sep or not name or not value.strip():
        raise SweepOptionError(f"{option} {item!r}: expected NAME=...")
    return name, value.strip()


def parse_grid(item: str) -> tuple[str, np.ndarray]:
    """``NAME=START:STOP:NUM`` (NUM values, both ends included) or ``NAME=V1,V2,...``."""
    name, text = _name_value(item, "--grid")
    what = f"--grid {item}"
    if ":" in text:
        parts = text.split(":")
        if len(parts) != 3:
            raise SweepOptionError(f"{what}: expected NAME=START:STOP:NUM or NAME=V1,V2,...")
        start, stop = _number(parts[0], what), _number(parts[1], what)
        try:
            num = int(parts[2])
        except ValueError:
            raise SweepOptionError(f"{what}: NUM {parts[2]!r} is not a whole number") from None
        if num < 1 or (num == 1 and start != stop):
            raise SweepOptionError(f"{what}: give at least 2 values between two different ends (or START:START:1)")
        if num > MAX_MEMBERS:
            raise SweepOptionError(f"{what}: at most {MAX_MEMBERS} values")
        return name, np.linspace(start, stop, num)
    values = [_number(v, what) for v in text.split(",") if v.strip()]
    if not values:
        raise SweepOptionError(f"{what}: no values")
    return name, np.array(values)


def parse_sample(item: str) -> tuple[str, str, float, float]:
    """``NAME=DIST:A:B`` with DIST one of :data:`DISTRIBUTIONS`."""
    name, text = _name_value(item, "--sample")
    what = f"--sample {item}"
    parts = text.split(":")
    if len(parts) != 3 or parts[0] not in DISTRIBUTIONS:
        raise SweepOptionError(f"{what}: expected NAME=DIST:A:B with DIST one of "
                               + ", ".join(f"{d} ({a})" for d, a in DISTRIBUTIONS.items()))
    dist, a, b = parts[0], _number(parts[1], what), _number(parts[2], what)
    if dist in ("uniform", "loguniform") and not a < b:
        raise SweepOptionError(f"{what}: LOW must be below HIGH")
    if dist == "loguniform" and a <= 0:
        raise SweepOptionError(f"{what}: loguniform needs 0 < LOW")
    if dist == "normal" and b <= 0:
        raise SweepOptionError(f"{what}: the standard deviation must be positive")
    return name, dist, a, b


def check_options(spec: SweepSpec) -> Plan:
    """Everything that can be checked without reading the model file (exit 2 on a bad one)."""
    problem = output_problem(spec.output, spec.plot, "the table is")
    if problem:
        raise SweepOptionError(problem)
    if spec.plot_y is not None and spec.plot is None:
        raise SweepOptionError("--plot-y needs --plot FILE.png")
    if spec.threads is not None and not 1 <= spec.threads <= 4096:
        raise SweepOptionError(f"--threads {spec.threads}: give between 1 and 4096 threads")
    if spec.max_steps is not None and spec.max_steps < 1:
        raise SweepOptionError(f"--max-steps {spec.max_steps}: give a positive step budget")
    for name in ("t_end", "rtol", "atol", "max_wall"):
        value = getattr(spec, name)
        positive = name in ("t_end", "max_wall")
        if value is not None and not (math.isfinite(value) and (value > 0 if positive else value >= 0)):
            raise SweepOptionError(f"--{name.replace('_', '-')} {value}: give a finite "
                                   f"{'positive' if positive else 'non-negative'} number")
    if spec.formulation is not None and spec.formulation not in FORMULATIONS:
        raise SweepOptionError(f"--formulation {spec.formulation}: one of {', '.join(FORMULATIONS)}")
    if spec.grid and spec.sample:
        raise SweepOptionError("--grid and --sample exclude each other: sweep a grid or a random sample")
    if not spec.grid and not spec.sample:
        raise SweepOptionError("nothing to sweep: give --grid NAME=START:STOP:NUM or --sample NAME=DIST:A:B --n N")
    sets = {}
    for item in spec.set or ():
        name, text = _name_value(item, "--set")
        sets[name] = _number(text, f"--set {item}")
    if spec.grid:
        if spec.n is not None or spec.seed is not None:
            raise SweepOptionError("--n and --seed apply to --sample only (a grid's size is its product)")
        grids = [parse_grid(g) for g in spec.grid]
        n_members = 1
        for _, values in grids:
            n_members *= len(values)
        plan = Plan(spec, "grid", grids=grids, n_members=n_members)
    else:
        if spec.n is None:
            raise SweepOptionError("--sample needs --n N, the number of members")
        if not 1 <= spec.n <= MAX_MEMBERS:
            raise SweepOptionError(f"--n {spec.n}: give between 1 and {MAX_MEMBERS} members")
        if spec.seed is not None and spec.seed < 0:
            raise SweepOptionError(f"--seed {spec.seed}: give a non-negative whole number")
        seed = spec.seed if spec.seed is not None else secrets.randbits(32)
        plan = Plan(spec, "sample", samples=[parse_sample(s) for s in spec.sample], n_members=spec.n, seed=seed)
    if plan.n_members > MAX_MEMBERS:
        raise SweepOptionError(f"the grid has {plan.n_members} members; at most {MAX_MEMBERS}")
    names = plan.names
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise SweepOptionError(f"swept twice: {', '.join(twice)}")
    clash = sorted(set(names) & set(sets))
    if clash:
        raise SweepOptionError(f"both swept and fixed by --set: {', '.join(clash)}")
    plan.sets = sets
    return plan


def check_names(plan: Plan, mf) -> None:
    """The swept and --set names against the model (before any derivation or compilation)."""
    model = mf.model
    params = [p.name for p in model.params]
    coords = [q.name for q in model.coords]
    speeds = [v.name for v in model.speeds]
    known = ", ".join(params + coords + speeds)
    for name in plan.names:
        if name not in params and name not in coords and name not in speeds:
            raise SweepOptionError(f"cannot sweep {name!r}: not a parameter, coordinate or velocity of "
                                   f"{model.name} ({known})")
    for name in plan.sets:
        if name not in params:
            raise SweepOptionError(f"--set {name}: not a parameter of {model.name} ({', '.join(params)})")
    spec = plan.spec
    if mf.constrained is None:
        if spec.formulation is not None:
            raise SweepOptionError("--formulation applies to files with [constraints]")
        if spec.project_initial:
            raise SweepOptionError("--project-initial applies to files with [constraints]")
    elif spec.method in ("taylor", "auto"):
        raise SweepOptionError(f"--method {spec.method}: unconstrained files only (constrained: adams or bdf)")


# ---------------------------------------------------------------------- members
def member_values(plan: Plan) -> dict[str, np.ndarray]:
    """name -> (N,) swept values: the grid's product (first axis slowest), or the sample drawn from
    ``default_rng(seed)`` in the order of the options."""
    if plan.kind == "grid":
        mesh = np.meshgrid(*[v for _, v in plan.grids], indexing="ij")
        return {name: m.ravel() for (name, _), m in zip(plan.grids, mesh)}
    rng = np.random.default_rng(plan.seed)
    out = {}
    for name, dist, a, b in plan.samples:
        if dist == "uniform":
            out[name] = rng.uniform(a, b, plan.n_members)
        elif dist == "normal":
            out[name] = rng.normal(a, b, plan.n_members)
        else:
            out[name] = np.exp(rng.uniform(math.log(a), math.log(b), plan.n_members))
    return out


def compile_options(plan: Plan, mf) -> tuple[dict[str, Any], dict[str, float]]:
    """The options of :func:`lagcodegen.api.compile_file` for the sweep (every swept parameter a
    run-time parameter; the --outputs; the --formulation), and the parameter values by name
    (model defaults < file < --set)."""
    s, spec = mf.simulation, plan.spec
    params = [p.name for p in mf.model.params]
    swept = [n for n in plan.names if n in params]
    runtime = None if s.runtime_parameters is None else \
        list(s.runtime_parameters) + [n for n in swept if n not in s.runtime_parameters]
    values = {**{p.name: float(v) for p, v in mf.model.params.items()}, **s.parameters, **plan.sets}
    options: dict[str, Any] = dict(runtime_parameters=runtime, values=values)
    requested = [o.strip() for o in spec.outputs.split(",") if o.strip()] if spec.outputs is not None else None
    if mf.constrained is not None:
        formulation = spec.formulation or s.formulation or "index1"
        options["formulation"] = formulation
        options["outputs"] = constrained_outputs(mf.constrained, requested if requested is not None
                                                 else list(s.outputs), formulation)
    elif requested is not None:
        options["outputs"] = requested
    return options, values


def run_plan(plan: Plan, mf, sim, values: dict[str, float], say: Callable[[str], None]) -> dict[str, np.ndarray]:
    """Run the checked ``plan`` on ``sim`` (compiled from ``mf`` with :func:`compile_options`)
    and write the table (and the plot); returns the table (column name -> (N,) array). Raises
    :class:`SweepOptionError` on a ``--plot-y`` the model lacks (before the run),
    :class:`~lagcodegen.errors.SolverError` when every member failed (after writing), and the
    ensemble's KeyboardInterrupt on Ctrl-C (writing nothing)."""
    spec = plan.spec
    quiet = spec.quiet
    state_names = list(sim.state_names)
    coords = [q.name for q in mf.model.coords]
    speeds = [v.name for v in mf.model.speeds]
    y_name = spec.plot_y or coords[0]
    if spec.plot is not None and y_name not in state_names and y_name not in coords + speeds:
        output_names = _output_names(sim)
        if y_name not in output_names:
            raise SweepOptionError(f"--plot-y {y_name}: not a state ({', '.join(state_names)}) nor an output "
                                   f"({', '.join(output_names) or 'none'}) of the compiled model")

    swept = member_values(plan)
    n_mem = plan.n_members
    q0, v0 = mf.initial_state()
    Q = np.tile(np.asarray(q0, dtype=float), (n_mem, 1))
    V = np.tile(np.asarray(v0, dtype=float), (n_mem, 1))
    driven = set(spec.inputs or ())  # inputs driven by tables: no value of theirs goes with them
    params: dict[str, Any] = {k: float(values[k]) for k in sim.param_names if k not in driven}
    for name, vals in swept.items():
        if name in coords:
            Q[:, coords.index(name)] = vals
        elif name in speeds:
            V[:, speeds.index(name)] = vals
        else:
            params[name] = vals
    s = mf.simulation
    t_end = spec.t_end if spec.t_end is not None else s.t_end
    if not t_end > s.t_start:
        raise SweepOptionError(f"--t-end {t_end}: must be after the file's t_start = {s.t_start}")
    options: dict[str, Any] = dict(rtol=spec.rtol if spec.rtol is not None else s.rtol,
                                   atol=spec.atol if spec.atol is not None else s.atol)
    if spec.max_steps is not None:
        options["max_steps"] = spec.max_steps
    if spec.inputs:
        options["inputs"] = spec.inputs
    if mf.constrained is not None:
        options["method"] = spec.method or constrained_method(sim.formulation, getattr(sim, "projection", False),
                                                              s.method)
        options["initial"] = "project" if spec.project_initial else "check"
    else:
        options["method"] = spec.method or s.method
    what = (" x ".join(f"{name} ({len(v)})" for name, v in plan.grids) if plan.kind == "grid" else
            ", ".join(f"{name} ~ {d}({a:g}, {b:g})" for name, d, a, b in plan.samples) + f", seed {plan.seed}")
    say(f"integrating {n_mem} members, t = {s.t_start:g}..{t_end:g}, {options['method']}, rtol {options['rtol']:g}: "
        f"{what}")
    t0 = time.perf_counter()
    try:
        ens = sim.ensemble(np.array([s.t_start, t_end]), q0=Q, v0=V, params=params, threads=spec.threads,
                           save="final", progress=False if quiet else None, max_wall=spec.max_wall or 0.0,
                           **options)
    except KeyboardInterrupt as exc:  # EnsembleInterrupted from the C call, or Ctrl-C before it began
        done = int(np.count_nonzero(exc.result.status >= 0)) if isinstance(exc, EnsembleInterrupted) else 0
        say(f"interrupted after {done} of {n_mem} members; nothing written")
        raise
    wall = time.perf_counter() - t0
    failed = int(np.count_nonzero(ens.status < 0))
    say(f"{n_mem} members in {wall:.3f} s ({n_mem / wall:.0f} members/s); "
        + (f"{failed} failed" if failed else "all succeeded"))
    if failed:
        for i in sorted(ens.messages)[:SHOWN_FAILURES]:
            say(f"member {i} ({', '.join(f'{k} = {v[i]:.10g}' for k, v in swept.items())}): "
                f"{ens.messages[i].splitlines()[0]}")

    table: dict[str, np.ndarray] = dict(swept)
    table["status"] = np.asarray(ens.status, dtype=np.int64)
    table["t_reached"] = ens.t_reached
    for name in state_names:
        table[f"final_{name}"] = ens[name]
    for name in ens.outputs:
        table[f"final_{name}"] = ens[name]
    out = Path(spec.output)
    plot = Path(spec.plot) if spec.plot is not None else None
    with staged_outputs([out, plot]) as staged:  # the table and the plot appear together, or neither
        write_table(staged[out], table, ens.messages)
        if plot is not None:
            plot_sweep(staged[plot], plan, swept, ens[y_name], ens.status, y_label=f"{y_name} at t = {t_end:g}",
                       coords=coords + speeds)
    say(f"wrote {out} ({n_mem} rows, {len(table)} columns)")
    if plot is not None:
        say(f"wrote {plot}")
    if failed == n_mem:
        first = min(ens.messages)
        t_first = float(ens.t_reached[first]) if np.isfinite(ens.t_reached[first]) else float(s.t_start)
        raise SolverError(f"every member of the sweep failed; member {first}: {ens.messages[first]}", t_first,
                          int(ens.status[first]))
    return table


def _output_names(sim) -> list[str]:
    """Output names of a compiled simulation (minimal coordinates: those of a branch's module,
    the same for every branch)."""
    names = getattr(sim, "output_names", None)
    if names is None:
        names = sim.compiled_branch(0).output_names
    return list(names)


# ---------------------------------------------------------------------- files
def write_table(path: Path, table: dict[str, np.ndarray], messages: dict | None = None) -> Path:
    """One row per member: CSV (header line, full precision) or NPZ (one array per column, the
    column order in ``columns``, the failed members' messages in ``message_members``/``message_texts``);
    written atomically."""
    names = list(table)
    if path.suffix == ".npz":
        messages = messages or {}
        data = {**table, "columns": np.array(names),
                "message_members": np.array(sorted(messages), dtype=np.int64),
                "message_texts": np.array([messages[k] for k in sorted(messages)], dtype=str)}
        with atomic_binary(path) as fh:
            np.savez(fh, **data)
        return path
    cols = np.column_stack([np.asarray(table[k], dtype=float) for k in names])
    fmt = ["%d" if k == "status" else "%.17g" for k in names]
    with atomic_binary(path) as fh:
        np.savetxt(fh, cols, fmt=fmt, delimiter=",", header=",".join(names), comments="")
    return path


def plot_sweep(path: Path, plan: Plan, swept: dict, y: np.ndarray, status: np.ndarray, *, y_label: str,
               coords: Sequence[str] = ()) -> Path:
    """PNG of ``y`` against the first swept quantity: a line for a 1-D grid, one line per value
    of the second axis of a 2-D grid, else a scatter (coloured by the second swept quantity if
    any). Failed members are left out (the title counts them)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    names = list(swept)
    x_name = names[0]
    ok = status >= 0
    label = {n: f"{n} (initial value)" if n in coords else n for n in names}
    fig, ax = plt.subplots(figsize=(7, 4.5))
    try:
        if plan.kind == "grid" and len(names) == 1:
            ax.plot(np.where(ok, swept[x_name], np.nan), np.where(ok, y, np.nan), lw=1.2)
        elif plan.kind == "grid" and len(names) == 2:
            second = plan.grids[1][1]
            cmap = plt.get_cmap("viridis")
            norm = matplotlib.colors.Normalize(second.min(), second.max() if second.max() > second.min()
                                               else second.min() + 1)
            shape = (len(plan.grids[0][1]), len(second))
            X, Y, OK = (a.reshape(shape) for a in (swept[x_name], y, ok))
            for j, value in enumerate(second):
                ax.plot(X[:, j][OK[:, j]], Y[:, j][OK[:, j]], lw=1, color=cmap(norm(value)))
            fig.colorbar(matplotlib.cm.ScalarMappable(norm=norm, cmap=cmap), ax=ax, label=label[names[1]])
        else:
            kw = dict(s=max(2.0, min(16.0, 8000.0 / max(1, int(ok.sum())))), lw=0)
            if len(names) > 1:
                sc = ax.scatter(swept[x_name][ok], y[ok], c=swept[names[1]][ok], cmap="viridis", **kw)
                fig.colorbar(sc, ax=ax, label=label[names[1]])
            else:
                ax.scatter(swept[x_name][ok], y[ok], **kw)
        ax.set_xlabel(label[x_name])
        ax.set_ylabel(y_label)
        ax.grid(alpha=0.3)
        n_failed = int(np.count_nonzero(~ok))
        ax.set_title(f"{len(status)} members" + (f", {n_failed} failed (not shown)" if n_failed else ""))
        fig.tight_layout()
        with atomic_binary(path) as fh:
            fig.savefig(fh, dpi=100, format="png")
    finally:
        plt.close(fig)
    return path
