"""Loading a model file: the TOML document, section by section, into a Model.

One job: :class:`_Loader` reads each table (the format: see :mod:`lagcodegen.modelfile`) into
:class:`~lagcodegen.model.Model` calls, the [constraints] into a
:class:`~lagcodegen.theory.constraints.ConstrainedSystem`, the [[events]] into
:class:`~lagcodegen.model.events.Event` items and the [simulation] table into
:class:`~.document.SimulationSettings`, checking names and combinations as it goes;
:func:`load_model` and :func:`loads_model` are its entry points.
"""

from __future__ import annotations

import difflib
import math
import re
import sys
from pathlib import Path
from typing import Sequence

import sympy as sp

from ..errors import ModelError
from ..model.events import DIRECTIONS, Event
from ..model.model import Model
from ..model.outputs import CONSTRAINT_OUTPUT_GROUPS, OUTPUT_GROUPS
from ..theory.constraints import FORMULATIONS, ConstrainedSystem, Inequality
from ..util import excerpt
from .document import ModelFile, SimulationSettings, constrained_method, constrained_outputs
from .expressions import FUNCTIONS, ExpressionError, parse_expression
from . import schema
from .locate import ModelFileError, _format_key, _Key
from .schema import MAX_N_OUT, MAX_STEPS
from .values import _Reader, _type_name

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

# The names the package exported from here before it was split (lagcodegen.api imports
# constrained_outputs from this module).
__all__ = ["FORMULATIONS", "FUNCTIONS", "ExpressionError", "ModelFile", "ModelFileError", "SimulationSettings",
           "constrained_method", "constrained_outputs", "load_model", "loads_model", "parse_expression"]

METHODS = ("adams", "bdf")
#: What [constraints] integrable = ... may say (see ConstrainedSystem).
_INTEGRABLE = ("error", "allow")
#: The tables and their keys: the declarative schema (also the source of docs/model-files.md).
_TOP_LEVEL = schema.TOP_LEVEL
_SIMULATION_KEYS = tuple(schema.keys("simulation")["optional"])
_CONSTRAINT_KEYS = tuple(schema.keys("constraints")["optional"])
_CONSTRAINT_PATH = re.compile(r"\b(nonholonomic|holonomic|inequality) constraint (\d+)")
_POSITION_ONLY = "velocities are allowed only in forces, kinetic energy, dissipation, outputs and events"


def load_model(path: str | Path) -> ModelFile:
    """Load a TOML model file (see :mod:`lagcodegen.modelfile` for the format)."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ModelFileError(f"cannot read model file: {exc}", str(path), None, "", None) from None
    return _Loader(text, str(path), path).load()


def loads_model(text: str, filename: str = "<string>") -> ModelFile:
    """Load a model from TOML text; ``filename`` is used in messages and as ``ModelFile.path``."""
    return _Loader(text, filename, Path(filename)).load()


class _Loader(_Reader):
    """Reads one TOML document into a Model and SimulationSettings."""

    def __init__(self, text: str, filename: str, path: Path):
        super().__init__(text, filename)
        self.path = path
        self.model: Model | None = None
        self.system: ConstrainedSystem | None = None
        self.events: list[Event] = []

    # ------------------------------------------------------------------ values
    def point_ref(self, path: Sequence[_Key], value: object) -> str | list[sp.Expr]:
        """A point: the name of a declared point, or a position array."""
        assert self.model is not None
        if isinstance(value, str):
            if value not in self.model.points:
                known = ", ".join(self.model.points) or "none"
                raise self.error(path, f"no point named {excerpt(value)} (points: {known})", token=value)
            return value
        if isinstance(value, list):
            return self.vector(path, value)
        raise self.error(path, f"must be a point name or a position array, got {_type_name(value)}",
                         token=repr(value))

    # ------------------------------------------------------------------ sections
    def load(self) -> ModelFile:
        try:
            data = tomllib.loads(self.text)
        except tomllib.TOMLDecodeError as exc:
            m = re.search(r"line (\d+)", str(exc))
            line = int(m.group(1)) if m else None
            raise ModelFileError(f"invalid TOML: {exc}", self.filename, line, "", None) from None
        except ValueError as exc:  # tomllib's int() of a literal beyond Python's digit limit
            digits = re.search(r"\d{%d,}" % (sys.get_int_max_str_digits() + 1), self.text) \
                if sys.get_int_max_str_digits() else None
            line = self.text.count("\n", 0, digits.start()) + 1 if digits else None
            what = f"an integer of more than {sys.get_int_max_str_digits()} digits" if digits else excerpt(str(exc))
            raise ModelFileError(f"invalid TOML: {what}, too large to read", self.filename, line, "", None) from None
        except RecursionError:  # tomllib parses nested arrays and inline tables recursively
            raise ModelFileError("invalid TOML: arrays or inline tables nested too deeply (beyond Python's recursion "
                                 f"limit, {sys.getrecursionlimit()} calls)", self.filename, None, "", None) from None
        for key in data:
            if key not in _TOP_LEVEL:
                close = difflib.get_close_matches(key, _TOP_LEVEL, n=1)
                hint = f"; did you mean {close[0]!r}?" if close else ""
                raise self.error([key], f"unknown top-level table {excerpt(key)}{hint} "
                                 f"(allowed: {', '.join(_TOP_LEVEL)})",
                                 token=key, needle=key)
        if "model" not in data:
            raise ModelFileError("missing required table [model]", self.filename, None, "", "model")
        self.load_model_table(self.table(["model"], data["model"]))
        self.load_parameters(self.table(["parameters"], data.get("parameters", {})))
        self.load_inputs(self.table(["inputs"], data.get("inputs", {})))
        self.load_units(self.table(["units"], data.get("units", {})))
        for section, loader in (("points", self.load_point), ("particles", self.load_particle),
                                ("planar_bodies", self.load_planar_body), ("rigid_bodies", self.load_rigid_body)):
            for i, entry in enumerate(self.tables([section], data.get(section, []))):
                loader([section, i], entry)
        if "gravity" in data:
            self.load_gravity(self.table(["gravity"], data["gravity"]))
        for section, loader in (("springs", self.load_spring), ("dampers", self.load_damper),
                                ("forces", self.load_force), ("generalized_forces", self.load_generalized_force)):
            for i, entry in enumerate(self.tables([section], data.get(section, []))):
                loader([section, i], entry)
        self.load_energy(self.table(["energy"], data.get("energy", {})))
        self.load_outputs(self.table(["outputs"], data.get("outputs", {})))
        assert self.model is not None
        with self.at(["model"]):
            self.model.validate()
        if "constraints" in data:
            self.load_constraints(self.table(["constraints"], data["constraints"]))
        events = self.tables(["events"], data.get("events", []))
        for i, entry in enumerate(events):
            self.events.append(self.load_event(["events", i], entry))
        simulation = self.load_simulation(self.table(["simulation"], data.get("simulation", {})))
        return ModelFile(model=self.model, simulation=simulation, path=self.path, source=self.text,
                         constrained=self.system, events=list(self.events))

    def load_model_table(self, table: dict) -> None:
        self.fields(["model"], table, **schema.keys("model"))
        if "name" in table:
            name = self.string(["model", "name"], table["name"])
        else:
            stem = self.path.stem
            name = stem if stem.isidentifier() else "model"
        with self.at(["model", "name"], needle=name):
            self.model = Model(name)
        coords = self.strings(["model", "coordinates"], table["coordinates"])
        if not coords:
            raise self.error(["model", "coordinates"], "at least one coordinate is needed", token="coordinates")
        for i, name in enumerate(coords):
            self.declare_name(["model", "coordinates", i], name)
            with self.at(["model", "coordinates", i], needle=name):
                q = self.model.coordinate(name)
            v = self.model.dot(q)
            self.symbols[q.name] = q
            self.symbols[v.name] = v
            self.velocities[v.name] = _POSITION_ONLY
        self.symbols["t"] = self.model.t
        self.symbols["pi"] = sp.pi

    def declare_name(self, path: Sequence[_Key], name: str) -> None:
        if name in FUNCTIONS:
            raise self.error(path, f"name {excerpt(name)} is taken by the function {name}()", token=name, needle=name)

    def load_parameters(self, table: dict) -> None:
        assert self.model is not None
        for name, value in table.items():
            path = ["parameters", name]
            self.declare_name(path, name)
            number = self.constant(path, value)
            with self.at(path, needle=name):
                self.symbols[name] = self.model.parameter(name, number)

    def load_inputs(self, table: dict) -> None:
        """[inputs]: name = default value (an input signal u(t), :meth:`Model.input`)."""
        assert self.model is not None
        for name, value in table.items():
            path = ["inputs", name]
            self.declare_name(path, name)
            number = self.constant(path, value)
            with self.at(path, needle=name):
                self.symbols[name] = self.model.input(name, number)

    def load_units(self, table: dict) -> None:
        """[units]: name = "unit" (of a coordinate, parameter or input, :meth:`Model.unit`)."""
        assert self.model is not None
        for name, value in table.items():
            path = ["units", name]
            unit = self.string(path, value)
            with self.at(path, needle=name):
                self.model.unit(name, unit)

    def load_point(self, path: list[_Key], entry: dict) -> None:
        assert self.model is not None
        self.fields(path, entry, **schema.keys("points"))
        name = self.string([*path, "name"], entry["name"])
        position = self.vector([*path, "position"], entry["position"], sizes=(1, 2, 3))
        with self.at([*path, "name"], needle=name):
            self.model.point(name, position)

    def load_particle(self, path: list[_Key], entry: dict) -> None:
        assert self.model is not None
        self.fields(path, entry, **schema.keys("particles"))
        name = self.string([*path, "name"], entry["name"])
        mass = self.expr([*path, "mass"], entry["mass"])
        position = self.vector([*path, "position"], entry["position"], sizes=(1, 2, 3))
        with self.at([*path, "name"], needle=name):
            self.model.particle(name, mass, position)

    def load_planar_body(self, path: list[_Key], entry: dict) -> None:
        assert self.model is not None
        self.fields(path, entry, **schema.keys("planar_bodies"))
        name = self.string([*path, "name"], entry["name"])
        mass = self.expr([*path, "mass"], entry["mass"])
        inertia = self.expr([*path, "inertia"], entry["inertia"])
        position = self.vector([*path, "position"], entry["position"], sizes=(2,))
        angle = self.expr([*path, "angle"], entry["angle"])
        with self.at([*path, "name"], needle=name):
            self.model.planar_body(name, mass, inertia, position, angle)

    def load_rigid_body(self, path: list[_Key], entry: dict) -> None:
        assert self.model is not None
        self.fields(path, entry, **schema.keys("rigid_bodies"))
        name = self.string([*path, "name"], entry["name"])
        mass = self.expr([*path, "mass"], entry["mass"])
        raw = entry["inertia"]
        if isinstance(raw, list) and raw and all(isinstance(r, list) for r in raw):
            inertia = self.matrix3([*path, "inertia"], raw)
        else:
            inertia = sp.diag(*self.vector([*path, "inertia"], raw, sizes=(3,)))
        position = self.vector([*path, "position"], entry["position"], sizes=(3,))
        orientation = self.matrix3([*path, "orientation"], entry["orientation"])
        with self.at([*path, "name"], needle=name):
            self.model.rigid_body(name, mass, inertia, position, orientation)

    def load_gravity(self, table: dict) -> None:
        assert self.model is not None
        self.fields(["gravity"], table, **schema.keys("gravity"))
        g = self.expr(["gravity", "g"], table["g"])
        up = self.vector(["gravity", "up"], table["up"], sizes=(1, 2, 3)) if "up" in table else None
        with self.at(["gravity"]):
            self.model.gravity(g, up)

    def load_spring(self, path: list[_Key], entry: dict) -> None:
        assert self.model is not None
        self.fields(path, entry, **schema.keys("springs"))
        a = self.point_ref([*path, "a"], entry["a"])
        b = self.point_ref([*path, "b"], entry["b"])
        k = self.expr([*path, "k"], entry["k"])
        rest = self.expr([*path, "rest_length"], entry["rest_length"]) if "rest_length" in entry else 0
        label = self.string([*path, "label"], entry["label"]) if "label" in entry else None
        with self.at(path):
            self.model.spring(a, b, k, rest_length=rest, label=label)

    def load_damper(self, path: list[_Key], entry: dict) -> None:
        assert self.model is not None
        self.fields(path, entry, **schema.keys("dampers"))
        a = self.point_ref([*path, "point"], entry["point"])
        c = self.expr([*path, "c"], entry["c"])
        b = self.point_ref([*path, "b"], entry["b"]) if "b" in entry else None
        label = self.string([*path, "label"], entry["label"]) if "label" in entry else None
        with self.at(path):
            self.model.damper(a, c, b=b, label=label)

    def load_force(self, path: list[_Key], entry: dict) -> None:
        assert self.model is not None
        self.fields(path, entry, **schema.keys("forces"))
        point = self.point_ref([*path, "point"], entry["point"])
        vector = self.vector([*path, "vector"], entry["vector"], velocities=True, sizes=(1, 2, 3))
        label = self.string([*path, "label"], entry["label"]) if "label" in entry else None
        with self.at([*path, "vector"]):
            self.model.force(point, vector, label=label)

    def load_generalized_force(self, path: list[_Key], entry: dict) -> None:
        assert self.model is not None
        self.fields(path, entry, **schema.keys("generalized_forces"))
        coord = self.string([*path, "coordinate"], entry["coordinate"])
        names = [q.name for q in self.model.coords]
        if coord not in names:
            raise self.error([*path, "coordinate"], f"{excerpt(coord)} is not a coordinate (coordinates: "
                             f"{', '.join(names)})", token=coord)
        expr = self.expr([*path, "expr"], entry["expr"], velocities=True)
        label = self.string([*path, "label"], entry["label"]) if "label" in entry else None
        self.model.generalized_force(coord, expr, label=label)

    def load_energy(self, table: dict) -> None:
        assert self.model is not None
        self.fields(["energy"], table, **schema.keys("energy"))
        if "kinetic" in table:
            self.model.kinetic_energy(self.expr(["energy", "kinetic"], table["kinetic"], velocities=True),
                                      label="energy.kinetic")
        if "potential" in table:
            self.model.potential_energy(self.expr(["energy", "potential"], table["potential"]),
                                        label="energy.potential")
        if "dissipation" in table:
            self.model.dissipation(self.expr(["energy", "dissipation"], table["dissipation"], velocities=True),
                                   label="energy.dissipation")

    def builtin_outputs(self) -> list[str]:
        """Output names a scene provides by itself (see :class:`lagcodegen.formulation.scene.Scene`)."""
        assert self.model is not None
        names = list(OUTPUT_GROUPS) + [f"p_{q.name}" for q in self.model.coords]
        names += [f"{pt.name}_{axis}" for pt in self.model.points.values() for axis in "xyz"[:pt.dim]]
        return names

    def load_outputs(self, table: dict) -> None:
        assert self.model is not None
        builtin = self.builtin_outputs()
        for name, value in table.items():
            path = ["outputs", name]
            if name in builtin:
                raise self.error(path, f"output name {excerpt(name)} is taken by a built-in output", token=name,
                                 needle=name)
            states = [q.name for q in self.model.coords] + [v.name for v in self.model.speeds] + ["t"]
            if name in states:
                raise self.error(path, f"output name {excerpt(name)} is the name of a state (state: "
                                 f"{', '.join(states[:-1])}; and the time t): its column would replace the state's "
                                 "(rename the output)", token=name, needle=name)
            expr = self.expr(path, value, velocities=True)
            with self.at(path, needle=name):
                self.model.output(name, expr)

    def load_constraints(self, table: dict) -> None:
        """[constraints]: holonomic f(q, t) = 0, nonholonomic A . q' + A0 = 0, inequalities g >= 0."""
        assert self.model is not None
        path = ["constraints"]
        self.fields(path, table, optional=_CONSTRAINT_KEYS)
        coords = set(self.model.coords)
        holonomic = []
        for i, value in enumerate(self.array([*path, "holonomic"], table.get("holonomic", []))):
            f = self.expr([*path, "holonomic", i], value)
            if not f.free_symbols & coords:
                raise self.error([*path, "holonomic", i], f"holonomic constraint {excerpt(f)} = 0 involves no "
                                 "coordinate "
                                 f"({', '.join(q.name for q in self.model.coords)})", token=str(value),
                                 needle=str(value))
            holonomic.append(f)
        nonholonomic = [self.load_pfaffian([*path, "nonholonomic", i], entry) for i, entry in
                        enumerate(self.tables([*path, "nonholonomic"], table.get("nonholonomic", [])))]
        inequalities = [self.load_inequality([*path, "inequalities", i], value) for i, value in
                        enumerate(self.array([*path, "inequalities"], table.get("inequalities", [])))]
        integrable = "error"
        if "integrable" in table:
            integrable = self.string([*path, "integrable"], table["integrable"])
            if integrable not in _INTEGRABLE:
                raise self.error([*path, "integrable"], f"must be one of {', '.join(map(repr, _INTEGRABLE))}, got "
                                 f"{excerpt(integrable)}", token=integrable)
        if not (holonomic or nonholonomic or inequalities):
            raise self.error(path, "the [constraints] table gives no constraint (holonomic, nonholonomic or "
                             "inequalities)", token="constraints", needle="")
        n, J = self.model.n, len(holonomic) + len(nonholonomic)
        if J > n:
            raise self.error(path, f"{J} equality constraints ({len(holonomic)} holonomic, {len(nonholonomic)} "
                             f"nonholonomic) but only {n} coordinates: at most {n} are possible",
                             token="constraints", needle="")
        params = {p.name for p in self.model.params}
        for j in range(J):
            name = f"lambda_{j}"
            if name in params:
                raise self.error(["parameters", name], f"the name {name!r} is reserved for the Lagrange multiplier "
                                 f"of constraint {j}: rename the parameter", token=name, needle=name)
            if name in self.symbols:
                raise self.error(["model", "coordinates"], f"the name {excerpt(name)} is reserved for the Lagrange "
                                 f"multiplier of constraint {j}: rename the coordinate", token=name, needle=name)
        try:
            self.system = ConstrainedSystem(self.model, holonomic, nonholonomic, inequalities, integrable=integrable)
        except ModelError as exc:
            m = _CONSTRAINT_PATH.search(str(exc))
            where: list[_Key] = path
            if m:
                kind = "inequalities" if m.group(1) == "inequality" else m.group(1)
                where = [*path, kind, int(m.group(2))]
            message = str(exc).replace("pass integrable='allow'", 'set integrable = "allow" in [constraints]')
            raise self.error(where, message, token=_format_key(where)) from None

    def load_inequality(self, path: list[_Key], value: object):
        """An inequality g(q, t) >= 0: an expression (monitored: the terminal event ineq_<k>) or a
        contact ``{ expr = "...", restitution = e }`` (impacts with Newton's law, 0 <= e <= 1;
        ``tangent = "..."``: no slip along that expression while touching; with ``friction = mu``:
        Coulomb friction along it instead; ``tangent = ["...", "..."]``: two tangents, 3-D friction
        on the circular cone)."""
        if not isinstance(value, dict):
            return self.expr(path, value)
        self.fields(path, value, required=("expr",), optional=("restitution", "tangent", "friction"))
        expr = self.expr([*path, "expr"], value["expr"])
        e = value.get("restitution")
        tangent = value.get("tangent")
        if isinstance(tangent, list):  # 3-D friction: two tangents (the circular cone)
            if len(tangent) != 2:
                raise self.error([*path, "tangent"], f"a tangent is one expression or a list of two (3-D friction), "
                                 f"got {len(tangent)}", token="tangent")
            tangent = tuple(self.expr([*path, "tangent", i], item) for i, item in enumerate(tangent))
        elif tangent is not None:
            tangent = self.expr([*path, "tangent"], tangent)
        if e is None:
            if "friction" in value:
                raise self.error([*path, "friction"], "friction (a rough contact) needs a restitution and a tangent",
                                 token="friction")
            if tangent is not None:
                raise self.error([*path, "tangent"], "a tangent (no-slip contact) needs a restitution",
                                 token="tangent")
            return Inequality(expr)
        if isinstance(e, bool) or not isinstance(e, (int, float)) or not 0 <= e <= 1:
            raise self.error([*path, "restitution"], f"must be a number in [0, 1] (Newton's law w+ = -e w-), got "
                             f"{excerpt(e)}", token=repr(e))
        mu = value.get("friction")
        if mu is not None and (tangent is None or isinstance(mu, bool) or not isinstance(mu, (int, float))
                               or not 0 <= mu < float("inf")):
            raise self.error([*path, "friction"], "friction needs a tangent = \"...\" and is a finite number >= 0 "
                             f"(the Coulomb coefficient mu), got {excerpt(mu)}", token=repr(mu))
        return Inequality(expr, restitution=float(e), tangent=tangent, friction=None if mu is None else float(mu))

    def load_pfaffian(self, path: list[_Key], entry: dict) -> tuple[tuple, sp.Expr]:
        """A nonholonomic constraint: ``{A = [...], A0 = ...}`` or ``{coefficients = {q = ...}, A0 = ...}``."""
        assert self.model is not None
        self.fields(path, entry, **schema.keys("constraints.nonholonomic"))
        names = [q.name for q in self.model.coords]
        if ("A" in entry) == ("coefficients" in entry):
            what = "both 'A' and 'coefficients' given" if "A" in entry else "missing key 'A' or 'coefficients'"
            raise self.error(path, f"{what}: give one (A: an array of one coefficient per coordinate, "
                             f"{', '.join(names)}; coefficients: a table by coordinate name, missing ones 0)",
                             token="A" if "A" in entry else "coefficients", needle="")
        if "A" in entry:
            raw = entry["A"]
            if not isinstance(raw, list) or len(raw) != len(names):
                got = f"{len(raw)} coefficients" if isinstance(raw, list) else _type_name(raw)
                raise self.error([*path, "A"], f"must be an array of {len(names)} expressions, one per coordinate "
                                 f"({', '.join(names)}), got {got}", token=repr(raw))
            A = [self.expr([*path, "A", i], v) for i, v in enumerate(raw)]
        else:
            A = [sp.Integer(0)] * len(names)
            for name, value in self.table([*path, "coefficients"], entry["coefficients"]).items():
                if name not in names:
                    close = difflib.get_close_matches(name, names, n=1)
                    hint = f"; did you mean {close[0]!r}?" if close else ""
                    raise self.error([*path, "coefficients", name], f"{excerpt(name)} is not a coordinate{hint} "
                                     f"(coordinates: {', '.join(names)})", token=name, needle=name)
                A[names.index(name)] = self.expr([*path, "coefficients", name], value)
        A0 = self.expr([*path, "A0"], entry["A0"]) if "A0" in entry else sp.Integer(0)
        if all(a == 0 for a in A):
            raise self.error(path, "every coefficient is zero: not a constraint on the velocities",
                             token="A" if "A" in entry else "coefficients", needle="")
        return tuple(A), A0

    def load_event(self, path: list[_Key], entry: dict) -> Event:
        """[[events]]: name, expr (q, q', t, parameters; constrained files: lambda_<j>; others: the
        names of the [outputs]), direction, terminal."""
        assert self.model is not None
        self.fields(path, entry, **schema.keys("events"))
        name = self.string([*path, "name"], entry["name"])
        if not name.isidentifier():
            raise self.error([*path, "name"], f"event name {excerpt(name)} must be an identifier", token=name)
        inequalities = self.system.inequalities if self.system is not None else []
        taken = [f"ineq_{k}" for k in range(len(inequalities))] + [e.name for e in self.events]
        if name in taken:
            what = "is used twice" if name in (e.name for e in self.events) else \
                "is taken by the event of an inequality constraint"
            raise self.error([*path, "name"], f"event name {excerpt(name)} {what}", token=name)
        if self.system is not None:
            extra = {lam.name: lam for lam in self.system.multipliers}
        else:  # the scene's outputs stand for their expressions (lagcodegen.formulation.events)
            names = [n for n in self.builtin_outputs() if n not in ("momenta", "positions")] + list(self.model.outputs)
            extra = {name: sp.Symbol(name) for name in names if name not in self.symbols}
        expr = self.expr([*path, "expr"], entry["expr"], velocities=True, extra=extra)
        direction = entry.get("direction", 0)
        if isinstance(direction, bool) or direction not in DIRECTIONS:
            raise self.error([*path, "direction"], f"must be -1 (decreasing), 0 (both) or 1 (increasing), got "
                             f"{excerpt(direction)}", token=repr(direction))
        terminal = entry.get("terminal", True)
        if not isinstance(terminal, bool):
            raise self.error([*path, "terminal"], f"must be true or false, got {excerpt(terminal)}",
                             token=repr(terminal))
        with self.at(path):
            return Event(name, expr, int(direction), terminal)

    def load_simulation(self, table: dict) -> SimulationSettings:
        assert self.model is not None
        self.fields(["simulation"], table, optional=_SIMULATION_KEYS)
        s = SimulationSettings()
        sim = ["simulation"]
        if "t_start" in table:
            s.t_start = self.constant([*sim, "t_start"], table["t_start"])
        if "t_end" in table:
            s.t_end = self.constant([*sim, "t_end"], table["t_end"])
        if not s.t_end > s.t_start:
            raise self.error([*sim, "t_end"], f"t_end ({s.t_end:g}) must be greater than t_start ({s.t_start:g})",
                             token="t_end")
        if not math.isfinite(s.t_end - s.t_start):
            raise self.error([*sim, "t_end"], f"t_end - t_start ({s.t_end:g} - {s.t_start:g}) is not a finite "
                             "number", token="t_end")
        if "n_out" in table:
            s.n_out = self.integer([*sim, "n_out"], table["n_out"], 2, MAX_N_OUT)
        if "max_steps" in table:
            s.max_steps = self.integer([*sim, "max_steps"], table["max_steps"], 1, MAX_STEPS)
        if "method" in table:
            method = self.string([*sim, "method"], table["method"])
            if method not in METHODS:
                raise self.error([*sim, "method"], f"unknown method {excerpt(method)} "
                                 f"(use one of: {', '.join(METHODS)})",
                                 token=method)
            s.method = method
        for key in ("rtol", "atol"):
            if key in table:
                value = self.constant([*sim, key], table[key])
                if value < 0:
                    raise self.error([*sim, key], f"must not be negative, got {value:g}", token=key)
                setattr(s, key, value)
        if s.rtol == 0 and s.atol == 0:
            key = "atol" if "atol" in table else "rtol"
            raise self.error([*sim, key], "rtol and atol are both 0: no error tolerance at all; give rtol > 0 or "
                             "atol > 0", token=key)
        for key in ("jacobian", "projection"):
            if key in table and not isinstance(table[key], bool):
                raise self.error([*sim, key], f"must be true or false, got {excerpt(table[key])}", token=key)
        if "jacobian" in table:
            s.jacobian = table["jacobian"]
        self.load_formulation(table, s)
        s.initial = self.load_initial(self.table([*sim, "initial"], table.get("initial", {})))
        params = [p.name for p in self.model.params]
        if "parameters" in table:
            for name, value in self.table([*sim, "parameters"], table["parameters"]).items():
                if name not in params:
                    raise self.error([*sim, "parameters", name], f"{excerpt(name)} is not a parameter (parameters: "
                                     f"{', '.join(params) or 'none'})", token=name)
                s.parameters[name] = self.constant([*sim, "parameters", name], value)
        if "runtime_parameters" in table:
            path = [*sim, "runtime_parameters"]
            runtime = self.strings(path, table["runtime_parameters"])
            for i, name in enumerate(runtime):
                if name not in params:
                    raise self.error([*path, i], f"{excerpt(name)} is not a parameter (parameters: "
                                     f"{', '.join(params) or 'none'})", token=name)
                if runtime.index(name) != i:
                    raise self.error([*path, i], f"parameter {excerpt(name)} is listed twice", token=name)
            s.runtime_parameters = runtime
        if "outputs" in table:
            path = [*sim, "outputs"]
            known = self.builtin_outputs() + list(self.model.outputs) + self.constraint_outputs()
            for i, name in enumerate(self.strings(path, table["outputs"])):
                if s.formulation == "minimal" and (name in ("lambda", "constraint_forces") or
                                                   name.startswith(("lambda_", "R_"))):
                    raise self.error([*path, i], f"output {excerpt(name)}: minimal coordinates have no Lagrange "
                                     "multipliers (use formulation 'index1' or 'ggl')", token=name)
                if name not in known:
                    close = difflib.get_close_matches(name, known, n=1)
                    hint = f"; did you mean {close[0]!r}?" if close else ""
                    raise self.error([*path, i], f"unknown output {excerpt(name)}{hint} (known: {', '.join(known)})",
                                     token=name)
                s.outputs.append(name)
        return s

    def constraint_outputs(self) -> list[str]:
        """Output names a constrained system adds (groups and single names), none without constraints."""
        if self.system is None:
            return []
        system = self.system
        names = list(CONSTRAINT_OUTPUT_GROUPS)
        names += [f"lambda_{j}" for j in range(system.J)]
        names += [f"R_{j}_{q.name}" for j in range(system.J) for q in system.model.coords]
        names += [f"g_{j}" for j in range(system.n_holonomic)] + [f"gdot_{j}" for j in range(system.J)]
        names += [f"ineq_{k}" for k in range(len(system.inequalities))]
        return names

    def load_formulation(self, table: dict, s: SimulationSettings) -> None:
        """formulation, baumgarte and projection (constrained files only)."""
        sim = ["simulation"]
        if self.system is None:
            for key in ("formulation", "baumgarte", "projection"):
                if key in table:
                    raise self.error([*sim, key], f"{key!r} applies to constrained models only (this file has no "
                                     "[constraints] table)", token=key)
            return
        s.formulation = "index1"
        if "formulation" in table:
            formulation = self.string([*sim, "formulation"], table["formulation"])
            if formulation not in FORMULATIONS:
                close = difflib.get_close_matches(formulation, FORMULATIONS, n=1)
                hint = f"; did you mean {close[0]!r}?" if close else ""
                raise self.error([*sim, "formulation"], f"unknown formulation {excerpt(formulation)}{hint} "
                                 f"(use one of: {', '.join(FORMULATIONS)})", token=formulation)
            s.formulation = formulation
        if "baumgarte" in table:
            path = [*sim, "baumgarte"]
            raw = table["baumgarte"]
            if raw == "auto":
                s.baumgarte = "auto"
            else:
                if not isinstance(raw, list) or len(raw) != 2:
                    raise self.error(path, f"must be \"auto\" or an array [alpha, beta] of two numbers, got "
                                     f"{excerpt(raw)}", token=repr(raw))
                values = tuple(self.constant([*path, i], v) for i, v in enumerate(raw))
                for i, value in enumerate(values):
                    if value < 0:
                        raise self.error([*path, i], f"must not be negative, got {value:g}", token=repr(raw[i]))
                s.baumgarte = (values[0], values[1])
        if "projection" in table:
            s.projection = table["projection"]
        for key, used in (("baumgarte", s.baumgarte not in ((0.0, 0.0), "auto")), ("projection", s.projection)):
            if used and s.formulation != "index1":
                raise self.error([*sim, key], f"{key!r} applies to formulation 'index1' only (the formulation is "
                                 f"{s.formulation!r})", token=key)
        if "method" in table and s.method != "bdf":
            if s.formulation == "ggl":
                raise self.error([*sim, "method"], f"formulation 'ggl' integrates with IDA, BDF only: method "
                                 f"{s.method!r} is not possible (use \"bdf\" or leave method out)", token=s.method)
            if s.projection:
                raise self.error([*sim, "method"], f"projection onto the constraints needs method \"bdf\" (CVODE "
                                 f"projects with BDF only), got {s.method!r}", token=s.method)

    def load_initial(self, table: dict) -> dict[str, float]:
        assert self.model is not None
        names = [q.name for q in self.model.coords] + [v.name for v in self.model.speeds]
        initial = {}
        for name, value in table.items():
            path = ["simulation", "initial", name]
            if name not in names:
                raise self.error(path, f"{excerpt(name)} is not a coordinate or velocity (state: {', '.join(names)})",
                                 token=name)
            initial[name] = self.constant(path, value)
        return initial
