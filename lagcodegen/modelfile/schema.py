"""The model-file format as data: every table, its keys, their types, defaults and meaning.

One job: the schema. The loader (:mod:`.loader`) takes the allowed tables and each table's
required and optional keys from here (:func:`keys`), and ``tools/model_file_reference.py``
writes ``docs/model-files.md`` from it (:func:`reference`), so the reference cannot drift from
what the loader accepts. Defaults of the [simulation] keys are read from
:class:`~.document.SimulationSettings`.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

from .document import SimulationSettings

#: Ranges of the [simulation] integers (n_out: as the CLI's --n-out; max_steps: fits a C long everywhere).
MAX_N_OUT = 10_000_000
MAX_STEPS = 2**31 - 1

#: Types of values, as the reference names them.
TYPES = {
    "string": "a TOML string",
    "identifier": "a string that is a name (letters, digits, _; not starting with a digit)",
    "expression": "a TOML number or a string expression (see Expressions)",
    "constant": "a finite number, or a string expression of numbers, pi and the functions (\"pi/2\")",
    "vector": "an array of 2 or 3 expressions (1 for the position of a particle or point on a line)",
    "point": "the name of a point or body (string), or a position (array of expressions)",
    "inertia3": "an array of 3 principal moments, or a 3x3 array of expressions",
    "matrix3": "a 3x3 array of expressions (array of 3 rows)",
    "strings": "an array of strings",
    "expressions": "an array of expressions",
    "boolean": "true or false",
    "integer": "a TOML integer",
}


@dataclass(frozen=True)
class Key:
    """One key of a table: ``type`` (a key of :data:`TYPES`, or prose), required or not, the
    default when it is left out (prose), and what it means."""

    name: str
    type: str
    meaning: str
    required: bool = False
    default: str = ""


@dataclass(frozen=True)
class Table:
    """A table of the file: ``kind`` "table" ([name]), "array" ([[name]], one table per item),
    or "map" (free names, each ``name = value`` of ``entry_type``); ``maps_to``: the
    :class:`~lagcodegen.model.Model` call or object it becomes."""

    name: str
    kind: str
    meaning: str
    keys: tuple[Key, ...] = ()
    entry_type: str = ""
    maps_to: str = ""
    required: bool = False

    def required_keys(self) -> list[str]:
        return [k.name for k in self.keys if k.required]

    def optional_keys(self) -> list[str]:
        return [k.name for k in self.keys if not k.required]


def _settings_default(name: str) -> str:
    """The default of a [simulation] key, as SimulationSettings states it."""
    value = {f.name: f for f in fields(SimulationSettings)}[name]
    default = getattr(SimulationSettings(), name)
    if value.name == "max_steps" and default is None:
        return "the solver's budget (1000000)"
    if isinstance(default, bool):
        return "true" if default else "false"
    if isinstance(default, (list, dict)) and not default:
        return "none"
    if name == "runtime_parameters" and default is None:
        return "every parameter"
    if name == "formulation" and default is None:
        return '"index1" (constrained files)'
    if isinstance(default, str):
        return f'"{default}"'
    return f"{default:g}" if isinstance(default, float) else str(default)


_LABEL = Key("label", "string", "a name for messages and listings", default="made from the points")

SCHEMA: tuple[Table, ...] = (
    Table("model", "table", "The model's name and generalized coordinates (eq. 1.1).", required=True, keys=(
        Key("name", "identifier", "the model's name (C prefix of the generated functions)",
            default="the file's stem, or \"model\""),
        Key("coordinates", "strings", "names of the generalized coordinates q; each brings its velocity "
            "<q>_dot", required=True),
    ), maps_to="Model(name).coordinates(...)"),
    Table("parameters", "map", "Parameters and their default values (adjustable at run time or folded "
          "into the code as constants).", entry_type="constant", maps_to="Model.parameter(name, value)"),
    Table("inputs", "map", "Input signals u(t): name = default value. An input enters like a parameter that "
          "varies in time (piecewise constant: no du/dt terms); it stays a run-time parameter, set by "
          "`simulate(params=...)` or by an FMU importer.", entry_type="constant", maps_to="Model.input(name, default)"),
    Table("units", "map", "Units of coordinates, parameters and inputs: name = \"unit\" (\"m\", \"rad\", \"kg\"). "
          "Documentation only (not checked); FMUs carry them in their modelDescription (velocities and "
          "derivatives in \"<unit>/s\", \"<unit>/s2\").", entry_type="string", maps_to="Model.unit(name, unit)"),
    Table("points", "array", "Named points: anchors and attachment points of springs, dampers and forces.",
          keys=(Key("name", "identifier", "the point's name", required=True),
                Key("position", "vector", "its position x(q, t)", required=True)),
          maps_to="Model.point"),
    Table("particles", "array", "Point masses: T += m/2 |x'|^2 (eq. 2.2).", keys=(
        Key("name", "identifier", "the particle's name (also a point)", required=True),
        Key("mass", "expression", "its mass", required=True),
        Key("position", "vector", "its position x(q, t), 2 or 3 components, or 1 for a particle on a line "
            "(T += m/2 x'^2)", required=True),
    ), maps_to="Model.particle"),
    Table("planar_bodies", "array", "Rigid bodies moving in a plane: T += m/2 |x_G'|^2 + I_G/2 angle'^2.", keys=(
        Key("name", "identifier", "the body's name (also a point, at its centre of mass)", required=True),
        Key("mass", "expression", "its mass", required=True),
        Key("inertia", "expression", "its moment of inertia about the centre of mass", required=True),
        Key("position", "vector", "the centre of mass x_G(q, t), 2 components", required=True),
        Key("angle", "expression", "its rotation angle in the plane", required=True),
    ), maps_to="Model.planar_body"),
    Table("rigid_bodies", "array", "3-D rigid bodies: T += m/2 |x_G'|^2 + 1/2 w^T I w, [w]x = R^T R'.", keys=(
        Key("name", "identifier", "the body's name (also a point, at its centre of mass)", required=True),
        Key("mass", "expression", "its mass", required=True),
        Key("inertia", "inertia3", "its inertia about the centre of mass, in body axes", required=True),
        Key("position", "vector", "the centre of mass x_G(q, t), 3 components", required=True),
        Key("orientation", "matrix3", "the rotation R(q, t) taking body axes to world axes", required=True),
    ), maps_to="Model.rigid_body"),
    Table("gravity", "table", "Uniform gravity on every body: V += m g (x . up).", keys=(
        Key("g", "expression", "the acceleration of gravity", required=True),
        Key("up", "vector", "the upward direction (normalized)",
            default="the last axis (y in 2-D, z in 3-D); particles on a line need [1] (a vertical line, pointing "
                    "up) or [-1]"),
    ), maps_to="Model.gravity"),
    Table("springs", "array", "Linear springs: V += k/2 (|x_a - x_b| - rest_length)^2.", keys=(
        Key("a", "point", "one end", required=True),
        Key("b", "point", "the other end", required=True),
        Key("k", "expression", "the stiffness", required=True),
        Key("rest_length", "expression", "the unstretched length", default="0"),
        _LABEL,
    ), maps_to="Model.spring"),
    Table("dampers", "array", "Linear viscous dampers: D += c/2 |v_point - v_b|^2 (eq. 3.15).", keys=(
        Key("point", "point", "the damped point", required=True),
        Key("c", "expression", "the damping coefficient", required=True),
        Key("b", "point", "a second point the velocity is taken relative to", default="none (absolute velocity)"),
        _LABEL,
    ), maps_to="Model.damper"),
    Table("forces", "array", "Cartesian forces F(q, q', t) at points, mapped to generalized forces by eq. 2.6.",
          keys=(Key("point", "point", "where the force acts", required=True),
                Key("vector", "vector", "the force (velocities allowed)", required=True),
                _LABEL),
          maps_to="Model.force"),
    Table("generalized_forces", "array", "Non-potential generalized forces Q*_i(q, q', t) (eq. 3.16).", keys=(
        Key("coordinate", "string", "the coordinate it acts on", required=True),
        Key("expr", "expression", "the force (velocities allowed)", required=True),
        _LABEL,
    ), maps_to="Model.generalized_force"),
    Table("energy", "table", "Energies given directly (besides those of bodies, gravity and springs).", keys=(
        Key("kinetic", "expression", "kinetic energy T(q, q', t)", default="none"),
        Key("potential", "expression", "potential V(q, t) (eq. 2.7)", default="none"),
        Key("dissipation", "expression", "Rayleigh dissipation D(q, q', t) (eq. 3.15)", default="none"),
    ), maps_to="Model.kinetic_energy, potential_energy, dissipation"),
    Table("outputs", "map", "User outputs: name = expression in q, q', t (not the name of a state or a "
          "built-in output).", entry_type="expression", maps_to="Model.output(name, expr)"),
    Table("constraints", "table", "Constraints (notes, sec. 4): the file describes a ConstrainedSystem; "
          "constraint j (holonomic ones first) has the multiplier lambda_<j>.", keys=(
        Key("holonomic", "expressions", "f(q, t) = 0 (eq. 4.1)", default="none"),
        Key("nonholonomic", "array of tables", "A . q' + A0 = 0 (eq. 4.3), each {A = [...], A0 = ...} or "
            "{coefficients = {q = ...}, A0 = ...} (see [constraints].nonholonomic)", default="none"),
        Key("inequalities", "expressions or tables", "g(q, t) >= 0, monitored by the terminal events ineq_<k>; "
            "a table { expr = \"...\", restitution = e } is a contact with impacts instead (Newton's law, "
            "0 <= e <= 1; formulations index1, ggl and minimal; tangent = \"...\": no slip along it while touching; "
            "friction = mu with a tangent: Coulomb friction along it instead (index1); "
            "tangent = [\"...\", \"...\"]: two tangents, 3-D friction on the circular cone)", default="none"),
        Key("integrable", "string", '"error" refuses an integrable Pfaffian row, "allow" keeps it',
            default='"error"'),
    ), maps_to="ConstrainedSystem"),
    Table("events", "array", "Root functions located by every solver and formulation (CVODE, IDA, Taylor; plain "
          "and constrained files, minimal coordinates too), found in the result's events.",
          keys=(Key("name", "identifier", "the event's name", required=True),
                Key("expr", "expression", "the root function in q, q', t and the parameters; constrained files: the "
                    "multipliers lambda_<j> too (not in minimal coordinates), others: output names (energy, p_<q>, <point>_x, "
                    "[outputs])",
                    required=True),
                Key("direction", "integer", "-1 decreasing, 0 both, 1 increasing", default="0"),
                Key("terminal", "boolean", "stop the run at the event", default="true")),
          maps_to="Event"),
    Table("simulation", "table", "How to run the model (build steps, `lagcodegen simulate`).", keys=(
        Key("t_start", "constant", "initial time", default=_settings_default("t_start")),
        Key("t_end", "constant", "final time (greater than t_start)", default=_settings_default("t_end")),
        Key("n_out", "integer", f"output times, evenly spaced (2 to {MAX_N_OUT})", default=_settings_default("n_out")),
        Key("method", "string", '"adams" (nonstiff) or "bdf" (stiff)', default=_settings_default("method")),
        Key("rtol", "constant", "relative tolerance (>= 0)", default=_settings_default("rtol")),
        Key("atol", "constant", "absolute tolerance (>= 0; not both 0)", default=_settings_default("atol")),
        Key("max_steps", "integer", f"step budget of the whole run (1 to {MAX_STEPS})",
            default=_settings_default("max_steps")),
        Key("initial", "table", "initial values by coordinate or velocity name (constants); others 0",
            default=_settings_default("initial")),
        Key("outputs", "strings", "outputs to compute: groups (energy, momenta, positions, ...) or single names",
            default=_settings_default("outputs")),
        Key("runtime_parameters", "strings", "parameters kept adjustable at run time; the others folded",
            default=_settings_default("runtime_parameters")),
        Key("parameters", "table", "overrides of the parameter defaults (constants)",
            default=_settings_default("parameters")),
        Key("jacobian", "boolean", "emit the analytic Jacobian", default=_settings_default("jacobian")),
        Key("formulation", "string", 'constrained files: "index1", "ggl" or "minimal"',
            default=_settings_default("formulation")),
        Key("baumgarte", "array of 2 constants or \"auto\"", "index1: Baumgarte (alpha, beta); [0, 0] none",
            default=_settings_default("baumgarte")),
        Key("projection", "boolean", 'index1: project onto the constraints after each step (method "bdf")',
            default=_settings_default("projection")),
    ), maps_to="SimulationSettings"),
)

#: Tables inside tables: [constraints].nonholonomic entries.
NESTED: tuple[Table, ...] = (
    Table("constraints.nonholonomic", "array", "One Pfaffian constraint A . q' + A0 = 0: give A or coefficients.",
          keys=(Key("A", "expressions", "one coefficient per coordinate, in the coordinates' order",
                    default="(give A or coefficients)"),
                Key("coefficients", "table", "coefficients by coordinate name; missing ones 0",
                    default="(give A or coefficients)"),
                Key("A0", "expression", "the velocity-free term", default="0")),
          maps_to="ConstrainedSystem(nonholonomic=...)"),
)

_BY_NAME = {t.name: t for t in SCHEMA + NESTED}

#: Top-level tables, in the order of the reference.
TOP_LEVEL = tuple(t.name for t in SCHEMA)


def table(name: str) -> Table:
    return _BY_NAME[name]


def keys(name: str) -> dict[str, list[str]]:
    """``required`` and ``optional`` key names of a table, as the loader checks them."""
    t = _BY_NAME[name]
    return {"required": t.required_keys(), "optional": t.optional_keys()}


def reference() -> str:
    """The model-file reference (Markdown) of every table and key."""
    out = ["# Model-file reference", "",
           "<!-- Generated by tools/model_file_reference.py from lagcodegen/modelfile/schema.py,",
           "     the tables the loader validates against. Do not edit by hand. -->", "",
           "A model file is TOML. Each table below becomes one call on a `lagcodegen.Model` (or the",
           "constraints, events and simulation settings); unknown tables and keys are refused with the",
           "file, line and key path. Only `[model]` is required.", "",
           "## Value types", "", "| type | what it is |", "|---|---|"]
    out += [f"| {name} | {_cell(text)} |" for name, text in TYPES.items()]
    out += ["", "## Expressions", "",
            "Strings such as `\"-l1*cos(theta1)\"`: numbers, names, `+ - * / **`, unary `-`/`+` and calls of",
            "the functions " + ", ".join(f"`{f}`" for f in _functions()) + ".",
            "Names are the coordinates, their velocities `<q>_dot` (only in forces, kinetic energy,",
            "dissipation, outputs and events), the parameters, `t` and `pi`. Nothing is evaluated.",
            "Integer powers of expressions are limited to " + str(_max_power()) + "; numbers must stay within",
            "double precision.", ""]
    for t in SCHEMA + NESTED:
        header = {"table": f"[{t.name}]", "array": f"[[{t.name}]]", "map": f"[{t.name}]"}[t.kind]
        if t.name == "constraints.nonholonomic":
            header = "[constraints].nonholonomic entries"
        out += [f"## {header}", "", _md(t.meaning) + (" Required." if t.required else ""), ""]
        if t.maps_to:
            out += [f"Becomes: `{t.maps_to}`.", ""]
        if t.kind == "map":
            out += [f"Every key is a free name; its value is {_md(TYPES.get(t.entry_type, t.entry_type))}.", ""]
            continue
        out += ["| key | type | required | default | meaning |", "|---|---|---|---|---|"]
        for k in t.keys:
            out.append(f"| `{k.name}` | {_cell(k.type)} | {'yes' if k.required else 'no'} | "
                       f"{'' if k.required else _cell(k.default)} | {_cell(k.meaning)} |")
        out.append("")
    return "\n".join(out)


def _md(text: str) -> str:
    """Prose for Markdown: angle brackets as entities (``<q>_dot`` is not an HTML tag)."""
    return text.replace("<", "&lt;").replace(">", "&gt;")


def _cell(text: str) -> str:
    """A table cell: prose with the column bars escaped."""
    return _md(text).replace("|", "\\|")


def _functions() -> list[str]:
    from .expressions import FUNCTIONS
    return list(FUNCTIONS)


def _max_power() -> int:
    from .expressions import MAX_POWER
    return MAX_POWER
