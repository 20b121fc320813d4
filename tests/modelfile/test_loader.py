"""TOML model files: the examples against lagcodegen.systems, the expression whitelist, errors."""

from pathlib import Path

import numpy as np
import pytest
import sympy as sp

import lagcodegen
from lagcodegen import Model, ModelError, derive, systems
from lagcodegen.theory.constraints import ConstrainedSystem
from lagcodegen.model.events import Event
from lagcodegen.modelfile import (FORMULATIONS, ModelFile, ModelFileError, SimulationSettings, constrained_method,
                                  constrained_outputs, load_model, loads_model, parse_expression)

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"

# A valid pendulum; error cases edit it. Line numbers below refer to this text.
BASE = """\
[model]
name = "p"
coordinates = ["theta"]

[parameters]
l = 1.0
g = 9.81
m = 1.0

[[particles]]
name = "bob"
mass = "m"
position = ["l*sin(theta)", "-l*cos(theta)"]

[gravity]
g = "g"
"""
MASS_LINE = 12  # `mass = "m"` in BASE
N_BASE = len(BASE.splitlines())


def is_zero(expr) -> bool:
    return sp.simplify(sp.expand_trig(sp.simplify(expr))) == 0


def same_equations(a, b) -> bool:
    return (a.M.shape == b.M.shape
            and all(is_zero(e) for e in a.M - b.M) and all(is_zero(e) for e in a.F - b.F))


def load_error(text: str, filename: str = "bad.toml") -> ModelError:
    with pytest.raises(ModelError) as info:
        loads_model(text, filename)
    return info.value


def assert_error(err: ModelError, *, line: int | None, key: str, token: str, filename: str = "bad.toml"):
    msg = str(err)
    prefix = f"{filename}:{line}: " if line else f"{filename}: "
    assert msg.startswith(prefix), msg
    assert key in msg, msg
    assert token in msg, msg
    assert isinstance(err, ModelFileError)
    assert (err.line, err.key) == (line, key)


# ============================================================================ examples
@pytest.mark.parametrize("filename, factory", [
    ("pendulum.toml", systems.pendulum),
    ("double_pendulum.toml", systems.double_pendulum),
    ("damped_driven_oscillator.toml", systems.damped_driven_oscillator),
    ("central_potential.toml", systems.central_potential),
])
def test_example_files_match_the_systems_module(filename, factory):
    mf = load_model(EXAMPLES / filename)
    assert isinstance(mf, ModelFile) and isinstance(mf.simulation, SimulationSettings)
    assert mf.path == EXAMPLES / filename
    reference = factory()
    assert [q.name for q in mf.model.coords] == [q.name for q in reference.coords]
    assert {s.name: v for s, v in mf.model.params.items()} == {s.name: v for s, v in reference.params.items()}
    assert same_equations(derive(mf.model), derive(reference))


def test_damped_driven_oscillator_file_equation():
    eom = load_model(EXAMPLES / "damped_driven_oscillator.toml").derive()
    x, xd, xdd, t = sp.symbols("x x_dot x_ddot t")
    m, k, c, F0, w = sp.symbols("m k c F0 w")
    assert is_zero(eom.equations()[0] - (m * xdd + c * xd + k * x - F0 * sp.cos(w * t)))


def test_central_potential_file_has_an_elliptic_orbit():
    mf = load_model(EXAMPLES / "central_potential.toml")
    init = mf.simulation.initial
    energy = 0.5 * (init["r_dot"] ** 2 + init["r"] ** 2 * init["phi_dot"] ** 2) - 1.0 / init["r"]
    assert energy < 0 and init["phi_dot"] ** 2 * init["r"] != 1.0  # bound, not circular
    period = 2 * np.pi * (-1 / (2 * energy)) ** 1.5
    assert mf.simulation.t_end >= 3 * period


def test_settings_and_helpers():
    mf = loads_model(BASE + """
[simulation]
t_start = 1.0
t_end = "2*pi"
n_out = 11
method = "bdf"
rtol = 1e-6
atol = 1e-9
initial = { theta = "pi/4", theta_dot = -0.5 }
outputs = ["energy", "p_theta", "bob_x"]
runtime_parameters = ["g"]
parameters = { g = 1.62, m = 2 }
jacobian = false
""", "p.toml")
    s = mf.simulation
    assert (s.t_start, s.t_end, s.n_out, s.method, s.rtol, s.atol, s.jacobian) == \
        (1.0, pytest.approx(2 * np.pi), 11, "bdf", 1e-6, 1e-9, False)
    assert s.outputs == ["energy", "p_theta", "bob_x"]
    assert s.runtime_parameters == ["g"] and s.parameters == {"g": 1.62, "m": 2.0}
    assert mf.initial_state() == ([pytest.approx(np.pi / 4)], [-0.5])
    assert np.allclose(mf.times(), np.linspace(1.0, 2 * np.pi, 11))
    assert mf.path == Path("p.toml")


def test_defaults_when_simulation_table_is_absent():
    mf = loads_model(BASE.replace('name = "p"\n', ""), "my_pendulum.toml")
    assert mf.model.name == "my_pendulum"  # the file's stem
    assert mf.simulation == SimulationSettings()
    assert mf.initial_state() == ([0.0], [0.0])
    assert mf.times().size == 1001


def test_every_table_maps_to_the_model_api():
    # Pendulum with a point, a spring to an anchor, a damper, a Cartesian force, a torque,
    # directly given energies and a user output; compared with the same model in Python.
    text = """
[model]
name = "everything"
coordinates = ["theta"]

[parameters]
l = 1.0
g = 9.81
m = 1.0
k = 2.0
c = 0.1
F = 0.3
A = 0.5
w = 2.0

[[points]]
name = "anchor"
position = [1, 0]

[[particles]]
name = "bob"
mass = "m"
position = ["l*sin(theta)", "-l*cos(theta)"]

[gravity]
g = "g"
up = [0, 1]

[[springs]]
a = "bob"
b = "anchor"
k = "k"
rest_length = 0.5
label = "spring"

[[dampers]]
point = "bob"
c = "c"
b = [0, 0]

[[forces]]
point = "bob"
vector = ["F*cos(t)", "-c*theta_dot"]

[[generalized_forces]]
coordinate = "theta"
expr = "A*sin(w*t)"

[energy]
kinetic = "m*l**2*theta_dot**2/2"
potential = "k*theta**2/2"
dissipation = "c*theta_dot**2/2"

[outputs]
height = "-l*cos(theta)"
"""
    mf = loads_model(text)
    py = Model("everything")
    th, = py.coordinates("theta")
    l, g, m, k, c, F, A, w = py.parameters(l=1.0, g=9.81, m=1.0, k=2.0, c=0.1, F=0.3, A=0.5, w=2.0)
    thd, t = py.dot(th), py.t
    py.point("anchor", (1, 0))
    py.particle("bob", m, (l * sp.sin(th), -l * sp.cos(th)))
    py.gravity(g, (0, 1))
    py.spring("bob", "anchor", k, rest_length=sp.Rational(1, 2))
    py.damper("bob", c, b=(0, 0))
    py.force("bob", (F * sp.cos(t), -c * thd))
    py.generalized_force(th, A * sp.sin(w * t))
    py.kinetic_energy(m * l**2 * thd**2 / 2)
    py.potential_energy(k * th**2 / 2)
    py.dissipation(c * thd**2 / 2)
    assert same_equations(derive(mf.model), derive(py))
    assert mf.model.outputs == {"height": -l * sp.cos(th)}
    assert set(mf.model.points) == {"anchor", "bob"}


def test_planar_and_rigid_bodies():
    text = """
[model]
name = "bodies"
coordinates = ["theta", "phi", "psi"]

[parameters]
m = 2.0
a = 0.5
g = 9.81
A0 = 0.2
C = 0.1
h = 0.3

[[planar_bodies]]
name = "bar"
mass = "m"
inertia = "m*(2*a)**2/12"
position = ["a*sin(theta)", "-a*cos(theta)"]
angle = "theta"

[[rigid_bodies]]
name = "top"
mass = "m"
inertia = ["A0", "A0", "C"]
position = ["h*sin(phi)*sin(psi)", "-h*cos(phi)*sin(psi)", "h*cos(psi)"]
orientation = [
    ["cos(phi)", "-sin(phi)*cos(psi)", "sin(phi)*sin(psi)"],
    ["sin(phi)", "cos(phi)*cos(psi)", "-cos(phi)*sin(psi)"],
    [0, "sin(psi)", "cos(psi)"],
]

[[rigid_bodies]]
name = "wheel"
mass = 1
inertia = [["A0", 0, 0], [0, "A0", 0], [0, 0, "C"]]
position = [0, 0, 0]
orientation = [["cos(psi)", "-sin(psi)", 0], ["sin(psi)", "cos(psi)", 0], [0, 0, 1]]
"""
    mf = loads_model(text)
    py = Model("bodies")
    th, ph, ps = py.coordinates("theta phi psi")
    m, a, g, A0, C, h = py.parameters(m=2.0, a=0.5, g=9.81, A0=0.2, C=0.1, h=0.3)
    py.planar_body("bar", m, m * (2 * a) ** 2 / 12, (a * sp.sin(th), -a * sp.cos(th)), th)
    R = sp.Matrix([[sp.cos(ph), -sp.sin(ph) * sp.cos(ps), sp.sin(ph) * sp.sin(ps)],
                   [sp.sin(ph), sp.cos(ph) * sp.cos(ps), -sp.cos(ph) * sp.sin(ps)],
                   [0, sp.sin(ps), sp.cos(ps)]])
    py.rigid_body("top", m, (A0, A0, C), R * sp.Matrix([0, 0, h]), R)
    Rz = sp.Matrix([[sp.cos(ps), -sp.sin(ps), 0], [sp.sin(ps), sp.cos(ps), 0], [0, 0, 1]])
    py.rigid_body("wheel", 1, sp.diag(A0, A0, C), (0, 0, 0), Rz)
    assert same_equations(derive(mf.model), derive(py))


# ============================================================================ expressions
def test_expressions_build_exact_sympy_objects():
    x, l = sp.symbols("x l")
    names = {"x": x, "l": l, "t": sp.Symbol("t"), "pi": sp.pi}
    assert parse_expression("1/2*l*x**2", names) == l * x**2 / 2  # ints stay exact
    assert parse_expression("-x + +l", names) == l - x
    assert parse_expression("atan2(x, l) + abs(x) + sign(l)", names) == sp.atan2(x, l) + sp.Abs(x) + sp.sign(l)
    assert parse_expression("sqrt(x)*exp(t)*log(l)", names) == sp.sqrt(x) * sp.exp(sp.Symbol("t")) * sp.log(l)
    assert parse_expression("pi", names) is sp.pi
    assert parse_expression("0.5*x", names) == sp.Float(0.5) * x
    long_sum = " + ".join(f"{i}*x" for i in range(2000))  # deeper than Python's recursion limit
    assert parse_expression(long_sum, names) == sum(range(2000)) * x


@pytest.mark.parametrize("text, token", [
    ("__import__('os').system('touch x')", "__import__"),
    ("sin.__class__", "__class__"),
    ("().__class__.__bases__[0].__subclasses__()", "__subclasses__"),
    ("open('/etc/passwd')", "open"),
    ("eval('1')", "eval"),
    ("sin(x=1)", "x="),
    ("x[0]", "x[0]"),
    ("lambda: 1", "lambda"),
    ("[x for x in l]", "[x for x in l]"),
    ("x if l else 0", "x if l else 0"),
    ("x < l", "x < l"),
    ("'text'", "'text'"),
    ("True", "True"),
    ("1j", "1j"),
    ("x^2", "^"),
    ("x // 2", "//"),
    ("sin(*l)", "*l"),
    ("9**9**9", "9**9**9"),
    ("1/0", "1/0"),
    ("log(0)", "log(0)"),
    ("sqrt(-1)", "sqrt(-1)"),
    ("sin", "sin"),
])
def test_expression_whitelist_rejects(text, token):
    names = {"x": sp.Symbol("x"), "l": sp.Symbol("l")}
    with pytest.raises(ModelError) as info:
        parse_expression(text, names)
    assert token in str(info.value)


@pytest.mark.parametrize("place, edit", [
    ("mass", lambda expr: BASE.replace('mass = "m"', f'mass = "{expr}"')),
    ("parameter", lambda expr: BASE.replace("l = 1.0", f'l = "{expr}"')),
    ("initial", lambda expr: BASE + f'\n[simulation]\ninitial = {{ theta = "{expr}" }}\n'),
    ("t_end", lambda expr: BASE + f'\n[simulation]\nt_end = "{expr}"\n'),
    ("output", lambda expr: BASE + f'\n[outputs]\nevil = "{expr}"\n'),
    ("gravity", lambda expr: BASE.replace('g = "g"', f'g = "{expr}"')),
])
def test_malicious_file_executes_nothing(tmp_path, place, edit):
    marker = tmp_path / "pwned"
    for expr in (f"__import__('os').system('touch {marker}')",
                 f"open('{marker}', 'w')",
                 f"[c for c in ().__class__.__base__.__subclasses__()][0]('touch {marker}')"):
        err = load_error(edit(expr))
        assert "bad.toml:" in str(err)
        assert not marker.exists()
    assert not marker.exists()


def test_import_os_system_is_rejected_and_not_run():
    pwned = Path("/tmp/pwned")
    existed = pwned.exists()
    err = load_error(BASE.replace('mass = "m"', """mass = "__import__('os').system('touch /tmp/pwned')\""""))
    assert_error(err, line=MASS_LINE, key="particles[0].mass", token="__import__")
    assert pwned.exists() == existed
    if not existed:
        assert not pwned.exists()


# ============================================================================ errors
def test_toml_syntax_error_names_file_and_line():
    err = load_error(BASE + "x = \n")
    assert str(err).startswith(f"bad.toml:{N_BASE + 1}: invalid TOML:")
    assert f"line {N_BASE + 1}" in str(err)  # tomllib's own message


def test_unknown_symbol_in_expression():
    text = BASE + """
[[particles]]
name = "bob2"
mass = "m"
position = [
    "l*sin(theta)",
    "-zeta*cos(theta)",
]
"""
    err = load_error(text)
    assert_error(err, line=N_BASE + 7, key="particles[1].position[1]", token="'zeta'")
    assert "-zeta*cos(theta)" in str(err)


def test_velocity_not_allowed_in_position():
    err = load_error(BASE.replace('["l*sin(theta)"', '["l*sin(theta)*theta_dot"'))
    assert_error(err, line=13, key="particles[0].position[0]", token="'theta_dot'")


def test_non_whitelisted_function():
    err = load_error(BASE.replace('mass = "m"', 'mass = "gamma(m)"'))
    assert_error(err, line=MASS_LINE, key="particles[0].mass", token="'gamma'")


@pytest.mark.parametrize("expr, token", [
    ("sin.__class__", "__class__"),
    ("m.__dict__", "__dict__"),
    ("__builtins__", "__builtins__"),
    ("getattr(m, 'x')", "getattr"),
])
def test_attribute_access_and_dunder_tricks(expr, token):
    err = load_error(BASE.replace('mass = "m"', f'mass = "{expr}"'))
    assert_error(err, line=MASS_LINE, key="particles[0].mass", token=token)


def test_wrong_arity():
    err = load_error(BASE.replace('mass = "m"', 'mass = "atan2(m)"'))
    assert_error(err, line=MASS_LINE, key="particles[0].mass", token="'atan2'")
    assert "takes 2 arguments, got 1" in str(err)


def test_unknown_top_level_table():
    err = load_error(BASE + '\n[[partciles]]\nname = "b"\n')
    assert_error(err, line=N_BASE + 2, key="partciles", token="'partciles'")
    assert "did you mean 'particles'" in str(err)


@pytest.mark.parametrize("text, line, key", [
    (BASE + '\n[[particles]]\nname = "b2"\nmas = "m"\nposition = [0, 0]\n', N_BASE + 4, "particles[1].mas"),
    (BASE.replace('coordinates = ["theta"]', 'coordinates = ["theta"]\ncoordinate = "x"'), 4, "model.coordinate"),
    (BASE + '\n[simulation]\nt_ed = 5\n', N_BASE + 3, "simulation.t_ed"),
    (BASE.replace('g = "g"', 'g = "g"\nupp = [0, 1]'), N_BASE + 1, "gravity.upp"),
])
def test_unknown_key_inside_a_table(text, line, key):
    err = load_error(text)
    assert_error(err, line=line, key=key, token=repr(key.rsplit(".", 1)[1]))
    assert "unknown key" in str(err)


def test_missing_required_keys():
    err = load_error(BASE + '\n[[particles]]\nname = "b2"\nposition = [0, 0]\n')
    assert_error(err, line=N_BASE + 2, key="particles[1]", token="'mass'")
    assert "missing required key" in str(err)
    err = load_error(BASE.replace('coordinates = ["theta"]\n', ""))
    assert_error(err, line=1, key="model", token="'coordinates'")
    with pytest.raises(ModelError, match=r"missing required table \[model\]"):
        loads_model("[parameters]\nk = 1\n")


@pytest.mark.parametrize("value, token", [
    ("nan", "got nan"), ("inf", "got inf"), ("-inf", "got -inf"), ('"1/0"', "division by zero"),
    ('"exp(1000)"', "exp(1000)"), ("true", "boolean"), ('"x"', "unknown name 'x'"),
])
def test_non_finite_or_non_numeric_parameter(value, token):
    err = load_error(BASE.replace("g = 9.81", f"g = {value}"))
    assert_error(err, line=7, key="parameters.g", token=token)


def test_unused_coordinate_is_reported_by_derive():
    mf = loads_model(BASE.replace('coordinates = ["theta"]', 'coordinates = ["theta", "ghost"]'), "bad.toml")
    with pytest.raises(ModelError, match="ghost"):
        derive(mf.model)
    with pytest.raises(ModelFileError) as info:
        mf.derive()  # the same error, located in the file
    assert_error(info.value, line=3, key="model.coordinates", token="'ghost'")


def test_initial_state_key_that_is_not_a_coordinate():
    err = load_error(BASE + "\n[simulation]\ninitial = { theta = 1.0, theta3 = 2 }\n")
    assert_error(err, line=N_BASE + 3, key="simulation.initial.theta3", token="'theta3'")
    err = load_error(BASE + "\n[simulation.initial]\ntheta = 1.0\ntheta3 = 2\n")
    assert_error(err, line=N_BASE + 4, key="simulation.initial.theta3", token="'theta3'")


def test_bad_method_name():
    err = load_error(BASE + '\n[simulation]\nt_end = 5\nmethod = "rk45"\n')
    assert_error(err, line=N_BASE + 4, key="simulation.method", token="'rk45'")
    assert "adams" in str(err) and "bdf" in str(err)


@pytest.mark.parametrize("extra, line, key, token", [
    ('\n[simulation]\noutputs = ["energy", "enrgy"]\n', N_BASE + 3, "simulation.outputs[1]", "'enrgy'"),
    ('\n[simulation]\nruntime_parameters = ["G"]\n', N_BASE + 3, "simulation.runtime_parameters[0]", "'G'"),
    ('\n[simulation]\nparameters = { gg = 1 }\n', N_BASE + 3, "simulation.parameters.gg", "'gg'"),
    ('\n[simulation]\nt_end = -1\n', N_BASE + 3, "simulation.t_end", "t_start"),
    ('\n[simulation]\nn_out = 1\n', N_BASE + 3, "simulation.n_out", "1"),
    ('\n[simulation]\njacobian = "yes"\n', N_BASE + 3, "simulation.jacobian", "'yes'"),
    ('\n[[springs]]\na = "bob"\nb = "anchr"\nk = 1\n', N_BASE + 4, "springs[0].b", "'anchr'"),
    ('\n[[generalized_forces]]\ncoordinate = "phi"\nexpr = 1\n', N_BASE + 3, "generalized_forces[0].coordinate",
     "'phi'"),
    ('\n[[forces]]\npoint = "bob"\nvector = [1, 2, 3]\n', N_BASE + 4, "forces[0].vector", "3 components"),
    ('\n[energy]\npotential = "theta_dot**2"\n', N_BASE + 3, "energy.potential", "'theta_dot'"),
    ('\n[outputs]\nenergy = "m"\n', N_BASE + 3, "outputs.energy", "'energy'"),
    # [[points]] load before the bodies, so the particle's name is the duplicate
    ('\n[[points]]\nname = "bob"\nposition = [0, 0]\n', 11, "particles[0].name", "declared twice"),
])
def test_other_mistakes_are_located(extra, line, key, token):
    assert_error(load_error(BASE + extra), line=line, key=key, token=token)


def test_names_and_types_are_checked():
    err = load_error(BASE.replace('name = "p"', 'name = "p q"'))
    assert_error(err, line=2, key="model.name", token="'p q'")
    err = load_error(BASE.replace("l = 1.0", "sin = 1.0"))
    assert_error(err, line=6, key="parameters.sin", token="'sin'")
    err = load_error(BASE.replace('mass = "m"', "mass = true"))
    assert_error(err, line=MASS_LINE, key="particles[0].mass", token="boolean")
    err = load_error(BASE.replace("[[particles]]", "[particles]"))
    assert_error(err, line=10, key="particles", token="array of tables")


def test_load_model_reports_the_path(tmp_path):
    path = tmp_path / "typo.toml"
    path.write_text(BASE.replace('mass = "m"', 'mass = "mm"'))
    with pytest.raises(ModelFileError) as info:
        load_model(path)
    assert_error(info.value, filename=str(path), line=MASS_LINE, key="particles[0].mass", token="'mm'")
    with pytest.raises(ModelError, match="cannot read"):
        load_model(tmp_path / "missing.toml")


# ============================================================================ end to end
def test_pendulum_file_compiles_and_simulates():
    mf = load_model(EXAMPLES / "pendulum.toml")
    q0, v0 = mf.initial_state()
    s = mf.simulation
    res = lagcodegen.compile_model(mf.model, outputs=s.outputs).simulate(
        mf.times(), q0=q0, v0=v0, method=s.method, rtol=s.rtol, atol=s.atol)
    assert res.success and res.t.size == s.n_out
    assert np.all(np.isfinite(res.y))
    assert all(np.all(np.isfinite(v)) for v in res.outputs.values())
    assert set(res.outputs) >= {"energy", "p_theta", "bob_x", "bob_y"}
    assert np.ptp(res.outputs["energy"]) < 1e-5  # conservative system
    assert res["theta"][0] == pytest.approx(1.0)


def test_model_file_simulate_uses_its_settings():
    mf = load_model(EXAMPLES / "central_potential.toml")
    res = mf.simulate(lagcodegen.compile_file(mf))
    assert res.success and res.t[-1] == pytest.approx(mf.simulation.t_end)
    assert np.ptp(res.outputs["energy"]) < 1e-6
    assert np.ptp(res.outputs["angular_momentum"]) < 1e-6
    r = res["r"]
    assert r.min() == pytest.approx(1.0, abs=1e-6) and r.max() > 2.0  # ellipse: perihelion 1, aphelion 2.57

    moon = loads_model(BASE + '\n[simulation]\nruntime_parameters = ["g"]\nparameters = { g = 1.62, m = 3 }\n'
                       "initial = { theta = 0.1 }\n", "moon.toml")
    res = moon.simulate(lagcodegen.compile_file(moon))
    assert res.parameters == {"g": 1.62}
    omega = np.sqrt(1.62 / 1.0)  # small oscillation: theta ~ 0.1 cos(omega t)
    assert res["theta"][-1] == pytest.approx(0.1 * np.cos(omega * res.t[-1]), abs=2e-3)


# ============================================================================ constraints and events
# A valid constrained file (Cartesian pendulum); error cases edit it. Lines below refer to it.
CBASE = """\
[model]
name = "cp"
coordinates = ["x", "y"]

[parameters]
l = 1.0
g = 9.81
m = 1.0

[[particles]]
name = "bob"
mass = "m"
position = ["x", "y"]

[gravity]
g = "g"

[constraints]
holonomic = ["x**2 + y**2 - l**2"]
"""
HOLONOMIC_LINE = 19
N_CBASE = len(CBASE.splitlines())

# Knife edge on an incline: three coordinates, one nonholonomic constraint.
KNIFE = """\
[model]
coordinates = ["x", "y", "theta"]

[parameters]
m = 1.0
Iz = 0.1
g = 9.81
alpha = 0.3

[energy]
kinetic = "m/2*(x_dot**2 + y_dot**2) + Iz/2*theta_dot**2"
potential = "-m*g*sin(alpha)*x"
"""
N_KNIFE = len(KNIFE.splitlines())


def python_cartesian_pendulum():
    """The Cartesian pendulum of examples/cartesian_pendulum.py."""
    m = Model("cartesian_pendulum")
    x, y = m.coordinates("x y")
    l, g, mass = m.parameters(l=1.0, g=9.81, m=1.0)
    m.particle("bob", mass, (x, y))
    m.gravity(g)
    return ConstrainedSystem(m, holonomic=[x ** 2 + y ** 2 - l ** 2])


def same_matrix(a, b) -> bool:
    return a.shape == b.shape and all(is_zero(e) for e in a - b)


def test_formulations_are_those_of_compile_constrained():
    from lagcodegen.theory.constraints import FORMULATIONS as DAE_FORMULATIONS
    assert FORMULATIONS == DAE_FORMULATIONS


def test_cartesian_pendulum_file_is_the_python_system():
    mf = load_model(EXAMPLES / "cartesian_pendulum.toml")
    cs, ref = mf.constrained, python_cartesian_pendulum()
    assert isinstance(cs, ConstrainedSystem) and mf.events == []
    assert (cs.n_holonomic, cs.n_nonholonomic, len(cs.inequalities), cs.dof) == (1, 0, 0, 1)
    assert [s.name for s in cs.multipliers] == ["lambda_0"]
    assert is_zero(cs.holonomic[0] - ref.holonomic[0])
    assert same_matrix(cs.A, ref.A) and same_matrix(cs.A0, ref.A0)
    x, y = sp.symbols("x y")
    assert same_matrix(cs.A, sp.Matrix([[2 * x, 2 * y]]))
    assert same_matrix(cs.acceleration_rhs(), ref.acceleration_rhs())
    for mine, theirs in zip(cs.equations(), ref.equations()):
        assert same_matrix(mine, theirs)
    s = mf.simulation
    assert (s.formulation, s.baumgarte, s.projection, s.method) == ("index1", (5.0, 5.0), False, "adams")
    q0, v0 = mf.initial_state()
    assert q0 == pytest.approx([np.sin(1.0), -np.cos(1.0)]) and v0 == [0.0, 0.0]
    ref.check_initial(q0, v0)  # consistent with the constraint


def test_sliding_off_sphere_file_has_its_event():
    mf = load_model(EXAMPLES / "sliding_off_sphere.toml")
    lam = mf.constrained.multipliers[0]
    assert mf.events == [Event("leave", lam, -1, True)]
    assert mf.events[0].expr is lam  # the multiplier symbol of the ConstrainedSystem


def test_unconstrained_files_have_no_constrained_system():
    mf = loads_model(BASE, "p.toml")
    assert mf.constrained is None and mf.events == [] and mf.simulation.formulation is None
    mf = loads_model(CBASE, "cp.toml")  # constrained, no [simulation]: index1 by default
    assert mf.simulation.formulation == "index1" and mf.simulation.baumgarte == "auto"


def test_nonholonomic_forms_agree():
    from helpers import knife_edge
    ref = knife_edge()
    by_row = loads_model(KNIFE + '[constraints]\nnonholonomic = [{ A = ["sin(theta)", "-cos(theta)", 0], A0 = 0 }]\n')
    by_name = loads_model(KNIFE + '[constraints]\nnonholonomic = [{ coefficients = { x = "sin(theta)", '
                          'y = "-cos(theta)" } }]\n')
    by_header = loads_model(KNIFE + '[[constraints.nonholonomic]]\ncoefficients = { y = "-cos(theta)", '
                            'x = "sin(theta)" }\nA0 = "0"\n')
    for mf in (by_row, by_name, by_header):
        cs = mf.constrained
        assert (cs.n_holonomic, cs.n_nonholonomic) == (0, 1)
        assert same_matrix(cs.A, ref.A) and same_matrix(cs.A0, ref.A0)
        assert not cs.is_integrable(0)


def test_constraints_with_time_inequalities_and_integrable_rows():
    mf = loads_model(KNIFE + """
[constraints]
holonomic = ["x - t**2/2"]
nonholonomic = [{ coefficients = { y = 1, theta = "-2" }, A0 = "-cos(t)" }]
inequalities = ["2 - y", "theta + pi"]
integrable = "allow"

[[events]]
name = "fast"
expr = "theta_dot - 3 + 0*lambda_1"
direction = 1
terminal = false
""")
    cs = mf.constrained
    t = sp.Symbol("t")
    assert same_matrix(cs.A, sp.Matrix([[1, 0, 0], [0, 1, -2]]))
    assert same_matrix(cs.A0, sp.Matrix([-t, -sp.cos(t)]))
    assert [str(g) for g in cs.inequalities] == ["2 - y", "theta + pi"]
    assert cs.is_integrable(0)  # y - 2 theta - sin(t) = const: kept because integrable = "allow"
    assert mf.events == [Event("fast", sp.Symbol("theta_dot") - 3, 1, False)]
    assert mf.simulation.formulation == "index1"
    assert constrained_outputs(cs, [], "index1") == ["energy", "lambda", "residuals", "inequalities"]
    assert constrained_outputs(cs, ["lambda_0", "residuals"], "ggl") == ["lambda_0", "residuals", "lambda",
                                                                       "inequalities"]
    assert constrained_outputs(python_cartesian_pendulum(), ["positions"], "minimal") == ["positions", "residuals"]
    assert [constrained_method(f, p, "adams") for f, p in
            [("index1", False), ("index1", True), ("ggl", False), ("minimal", False)]] == \
        ["adams", "bdf", "bdf", "adams"]


def test_simulation_keys_of_constrained_files():
    mf = loads_model(CBASE + """
[simulation]
formulation = "index1"
baumgarte = ["pi", 2]
projection = true
outputs = ["energy", "constraint_forces", "R_0_x", "g_0", "lambda_0"]
""")
    s = mf.simulation
    assert (s.formulation, s.baumgarte, s.projection) == ("index1", (pytest.approx(np.pi), 2.0), True)
    assert s.outputs == ["energy", "constraint_forces", "R_0_x", "g_0", "lambda_0"]
    assert loads_model(CBASE + '\n[simulation]\nformulation = "ggl"\nmethod = "bdf"\n').simulation.method == "bdf"
    assert loads_model(CBASE + '\n[simulation]\nformulation = "minimal"\n').simulation.formulation == "minimal"


def test_model_file_simulate_leaves_the_sphere_at_two_thirds():
    mf = load_model(EXAMPLES / "sliding_off_sphere.toml")
    res = mf.simulate(lagcodegen.compile_file(mf))
    assert res.success and res.formulation == "index1"
    (ev,) = res.events
    v0, g, R = mf.simulation.initial["x_dot"], 9.81, 1.0
    assert ev.name == "leave" and ev.terminal and ev.direction == -1
    assert ev.q["y"] / R == pytest.approx((2 + v0 ** 2 / (g * R)) / 3, abs=1e-8)
    assert ev.q["y"] / R == pytest.approx(2 / 3, abs=1e-6)
    assert res.t[-1] == ev.t < mf.simulation.t_end  # the terminal event's row ends the result
    assert abs(res["lambda_0"][-1]) < 1e-6


@pytest.mark.parametrize("text, line, key, token", [
    # an unknown symbol in a constraint
    (CBASE.replace("- l**2", "- L**2"), HOLONOMIC_LINE, "constraints.holonomic[0]", "'L'"),
    # a velocity in a holonomic constraint, one without a coordinate, too many constraints
    (CBASE.replace("- l**2", "- x_dot"), HOLONOMIC_LINE, "constraints.holonomic[0]", "'x_dot'"),
    (CBASE.replace('"x**2 + y**2 - l**2"', '"l - 1"'), HOLONOMIC_LINE, "constraints.holonomic[0]",
     "involves no coordinate"),
    (CBASE.replace('"x**2 + y**2 - l**2"', '"x", "y", "x + y"'), N_CBASE - 1, "constraints", "at most 2"),
    (CBASE.replace("holonomic = ", "holonomc = "), HOLONOMIC_LINE, "constraints.holonomc", "'holonomc'"),
    (CBASE.replace('holonomic = ["x**2 + y**2 - l**2"]', ""), N_CBASE - 1, "constraints", "no constraint"),
    (CBASE.replace("holonomic = [", "holonomic = 1 #"), HOLONOMIC_LINE, "constraints.holonomic", "integer"),
    (CBASE + 'inequalities = ["y_dot"]\n', N_CBASE + 1, "constraints.inequalities[0]", "'y_dot'"),
    (CBASE + 'integrable = "maybe"\n', N_CBASE + 1, "constraints.integrable", "'maybe'"),
    # nonholonomic constraints: a coefficient of an unknown coordinate (inline and [[...]] forms)
    (KNIFE + '[constraints]\nnonholonomic = [\n  { A = [1, 0, 0] },\n  { coefficients = { x = 1, thet = "-2" } },\n]\n',
     N_KNIFE + 4, "constraints.nonholonomic[1].coefficients.thet", "'thet'"),
    (KNIFE + '[[constraints.nonholonomic]]\nA = [1, 0, 0]\n\n[[constraints.nonholonomic]]\n'
     'coefficients = { x = 1, thet = "-2" }\n', N_KNIFE + 5, "constraints.nonholonomic[1].coefficients.thet",
     "'thet'"),
    (KNIFE + '[constraints]\nnonholonomic = [{ A = [1, 0] }]\n', N_KNIFE + 2, "constraints.nonholonomic[0].A",
     "2 coefficients"),
    (KNIFE + '[constraints]\nnonholonomic = [{ A = [1, 0, 0], coefficients = { x = 1 } }]\n', N_KNIFE + 2,
     "constraints.nonholonomic[0]", "'A'"),
    (KNIFE + '[constraints]\nnonholonomic = [{ A0 = 1 }]\n', N_KNIFE + 2, "constraints.nonholonomic[0]",
     "'coefficients'"),
    (KNIFE + '[constraints]\nnonholonomic = [{ A = [0, 0, 0], A0 = 1 }]\n', N_KNIFE + 2,
     "constraints.nonholonomic[0]", "every coefficient is zero"),
    (KNIFE + '[constraints]\nnonholonomic = [{ A = [1, 0, 0], A0 = "x_dot" }]\n', N_KNIFE + 2,
     "constraints.nonholonomic[0].A0", "'x_dot'"),
    (KNIFE + '[constraints]\nnonholonomic = [{ A = [1, 0, "-theta"] }]\n', N_KNIFE + 2,
     "constraints.nonholonomic[0]", 'integrable = "allow"'),
    (KNIFE + '[constraints]\nnonholonomic = [{ A = [1, 0, 0], B = 1 }]\n', N_KNIFE + 2,
     "constraints.nonholonomic[0].B", "'B'"),
    # events: a call of a function not on the whitelist, unknown multipliers, bad values, no constraints
    (CBASE + '\n[[events]]\nname = "e"\nexpr = "__import__(\'os\').system(\'true\')"\n', N_CBASE + 4,
     "events[0].expr", "__import__"),
    (CBASE + '\n[[events]]\nname = "e"\nexpr = "gamma(lambda_0)"\n', N_CBASE + 4, "events[0].expr", "'gamma'"),
    (CBASE + '\n[[events]]\nname = "e"\nexpr = "lambda_1"\n', N_CBASE + 4, "events[0].expr", "'lambda_1'"),
    (CBASE + '\n[[events]]\nname = "e"\nexpr = "y"\ndirection = 2\n', N_CBASE + 5, "events[0].direction", "2"),
    (CBASE + '\n[[events]]\nname = "e"\nexpr = "y"\ndirection = true\n', N_CBASE + 5, "events[0].direction",
     "True"),
    (CBASE + '\n[[events]]\nname = "e"\nexpr = "y"\nterminal = 1\n', N_CBASE + 5, "events[0].terminal", "1"),
    (CBASE + '\n[[events]]\nname = "e f"\nexpr = "y"\n', N_CBASE + 3, "events[0].name", "'e f'"),
    (CBASE + '\n[[events]]\nname = "e"\nexpr = "y"\n\n[[events]]\nname = "e"\nexpr = "x"\n', N_CBASE + 7,
     "events[1].name", "used twice"),
    (CBASE + 'inequalities = ["y + 2"]\n\n[[events]]\nname = "ineq_0"\nexpr = "x"\n', N_CBASE + 4,
     "events[0].name", "inequality"),
    (CBASE + '\n[[events]]\nexpr = "y"\n', N_CBASE + 2, "events[0]", "'name'"),
    (CBASE + '\n[[events]]\nname = "e"\nexpr = "y"\ndir = 1\n', N_CBASE + 5, "events[0].dir", "'dir'"),
    (BASE + '\n[[events]]\nname = "e"\nexpr = "thetta"\n', N_BASE + 4, "events[0].expr", "'thetta'"),
    (BASE + '\n[[events]]\nname = "e"\nexpr = "theta"\ndirection = -2\n', N_BASE + 5, "events[0].direction", "-2"),
    # [simulation]: formulation and its options
    (CBASE + '\n[simulation]\nformulation = "index2"\n', N_CBASE + 3, "simulation.formulation", "'index2'"),
    (CBASE + '\n[simulation]\nformulation = 1\n', N_CBASE + 3, "simulation.formulation", "integer"),
    (BASE + '\n[simulation]\nformulation = "ggl"\n', N_BASE + 3, "simulation.formulation", "[constraints]"),
    (BASE + '\n[simulation]\nprojection = true\n', N_BASE + 3, "simulation.projection", "[constraints]"),
    (CBASE + '\n[simulation]\nformulation = "ggl"\nmethod = "adams"\n', N_CBASE + 4, "simulation.method",
     "'adams'"),
    (CBASE + '\n[simulation]\nprojection = true\nmethod = "adams"\n', N_CBASE + 4, "simulation.method", "bdf"),
    (CBASE + '\n[simulation]\nformulation = "ggl"\nbaumgarte = [1, 1]\n', N_CBASE + 4, "simulation.baumgarte",
     "index1"),
    (CBASE + '\n[simulation]\nformulation = "minimal"\nprojection = true\n', N_CBASE + 4, "simulation.projection",
     "index1"),
    (CBASE + '\n[simulation]\nbaumgarte = [1]\n', N_CBASE + 3, "simulation.baumgarte", "[1]"),
    (CBASE + '\n[simulation]\nbaumgarte = [1, "-2"]\n', N_CBASE + 3, "simulation.baumgarte[1]", "negative"),
    (CBASE + '\n[simulation]\nprojection = "yes"\n', N_CBASE + 3, "simulation.projection", "'yes'"),
    (CBASE + '\n[simulation]\nformulation = "minimal"\noutputs = ["energy", "lambda"]\n', N_CBASE + 4,
     "simulation.outputs[1]", "'lambda'"),
    (CBASE + '\n[simulation]\noutputs = ["lambda_1"]\n', N_CBASE + 3, "simulation.outputs[0]", "'lambda_1'"),
    # the multipliers' names are reserved
    (CBASE.replace("m = 1.0", "m = 1.0\nlambda_0 = 2"), 9, "parameters.lambda_0", "'lambda_0'"),
])
def test_constraint_and_event_mistakes_are_located(text, line, key, token):
    assert_error(load_error(text), line=line, key=key, token=token)


def test_constraint_error_in_a_file_names_the_file(tmp_path):
    path = tmp_path / "typo.toml"
    path.write_text(CBASE.replace("- l**2", "- L**2"))
    with pytest.raises(ModelFileError) as info:
        load_model(path)
    assert_error(info.value, filename=str(path), line=HOLONOMIC_LINE, key="constraints.holonomic[0]", token="'L'")
    assert "known names: x, y, t, pi, l, g, m" in str(info.value)


def test_malicious_event_executes_nothing(tmp_path):
    pwned = tmp_path / "pwned"
    text = CBASE + f'\n[[events]]\nname = "e"\nexpr = "__import__(\'os\').system(\'touch {pwned}\')"\n'
    err = load_error(text)
    assert_error(err, line=N_CBASE + 4, key="events[0].expr", token="__import__")
    assert not pwned.exists()


@pytest.mark.parametrize("extra, key, token", [
    ("n_out = 100000000000000", "simulation.n_out", "an integer <= 10000000"),
    ("n_out = 1e14", "simulation.n_out", "an integer >= 2"),
    ("max_steps = 0", "simulation.max_steps", "an integer >= 1"),
    ("max_steps = 100000000000000", "simulation.max_steps", "an integer <= 2147483647"),
    ("max_steps = 2.5", "simulation.max_steps", "an integer >= 1"),
    ("rtol = 0\natol = 0", "simulation.atol", "rtol and atol are both 0"),
    ("t_start = -1e308\nt_end = 1e308", "simulation.t_end", "is not a finite number"),
])
def test_simulation_numbers_are_range_checked_at_load(extra, key, token):
    """Out-of-range numbers of [simulation] are refused at load, with the file and line (issue 13)."""
    err = load_error(BASE + "\n[simulation]\n" + extra + "\n")
    assert_error(err, line=N_BASE + 2 + extra.count("\n") + 1, key=key, token=token)


def test_max_steps_in_the_simulation_table():
    mf = loads_model(BASE + "\n[simulation]\nmax_steps = 5\n")
    assert mf.simulation.max_steps == 5
    with pytest.raises(lagcodegen.SolverError, match="max_steps = 5"):
        mf.simulate(lagcodegen.compile_file(mf))


def test_messages_show_a_bounded_excerpt_of_a_long_input():
    """A 757-character expression is not echoed whole (twice): the message names the problem
    and shows at most about 80 characters of it, about the offending token (issue 13)."""
    long = " + ".join(f"theta*m{i}" for i in range(70))
    err = load_error(BASE.replace('mass = "m"', f'mass = "{long}"'))
    text = str(err)
    assert "unknown name 'm0' in 'theta*m0 + theta*m1" in text and f"({len(long)} characters)" in text
    assert len(text) < 400 and long not in text
    err = load_error(BASE.replace('mass = "m"', f'mass = "({long}) +* 2"'))
    assert "invalid expression syntax" in str(err) and len(str(err)) < 300
    err = load_error(BASE.replace('mass = "m"', f'mass = "{long} + 1.5e400"'))
    assert len(str(err)) < 400
    with pytest.raises(ModelError) as info:
        parse_expression(" + ".join(["theta"] * 200) + " + zeta", {"theta": sp.Symbol("theta")})
    assert "...'" in str(info.value) and "zeta" in str(info.value) and len(str(info.value)) < 300
    # short inputs: the message as before
    assert "unknown name 'zeta' in 'theta*zeta'" in str(load_error(BASE.replace('mass = "m"', 'mass = "theta*zeta"')))


# ============================================================================ events of every kind of file
def test_events_of_a_plain_file_are_located_on_cvode_and_taylor():
    """A pendulum file with [[events]] (no constraints): theta = 0 decreasing at T/4, 5T/4, ...
    (T = 4 K(k) sqrt(l/g), k = sin(theta0/2)); an event on an output name (the bob's height)."""
    from scipy.special import ellipk
    mf = loads_model(BASE + """
[outputs]
height = "l - l*cos(theta)"

[[events]]
name = "down"
expr = "theta"
direction = -1
terminal = false

[[events]]
name = "low"
expr = "bob_y + 0.5*l"
direction = 1
terminal = false

[simulation]
t_end = 10.0
rtol = 1e-12
atol = 1e-14
initial = { theta = 2.0 }
outputs = ["height"]
""")
    assert mf.constrained is None and [e.name for e in mf.events] == ["down", "low"]
    T = 4 * ellipk(np.sin(1.0) ** 2) * np.sqrt(1.0 / 9.81)
    cm = lagcodegen.compile_file(mf)
    for method in ("adams", "taylor"):
        res = mf.simulate(cm, method=method)
        down = np.array([e.t for e in res.events if e.name == "down"])
        expect = T / 4 + T * np.arange(len(down))
        assert len(down) == int((10.0 - T / 4) // T) + 1 and np.abs(down - expect).max() < 1e-9 * expect.max()
        low = [e for e in res.events if e.name == "low"]  # cos(theta) = 1/2 while rising
        assert low and all(abs(np.cos(e.q["theta"]) - 0.5) < 1e-9 and e.direction == 1 for e in low)
    with pytest.raises(ModelFileError, match="events\\[0\\].expr.*'heigth'"):
        loads_model(BASE + '\n[[events]]\nname = "e"\nexpr = "heigth"\n')


def test_events_and_inequalities_of_a_file_in_minimal_coordinates():
    mf = loads_model(CBASE.replace('holonomic = ["x**2 + y**2 - l**2"]',
                                   'holonomic = ["x**2 + y**2 - l**2"]\ninequalities = ["x + 0.35*l"]') + """
[[events]]
name = "cross"
expr = "x"
terminal = false

[simulation]
formulation = "minimal"
t_end = 3.0
initial = { x = 0.4, y = -0.916515138991168 }
""")
    sim = lagcodegen.compile_file(mf)
    res = mf.simulate(sim)  # x: 0.4 -> 0 (cross) -> -0.35 (the inequality ends the run) -> -0.4
    assert res.formulation == "minimal" and [e.name for e in res.events] == ["cross", "ineq_0"]
    cross, stop = res.events
    assert abs(cross.q["x"]) < 1e-7 and not cross.terminal
    assert stop.terminal and abs(stop.q["x"] + 0.35) < 1e-7 and res.t[-1] == stop.t < 3.0
