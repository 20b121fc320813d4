"""Inputs (Model.input, [inputs] in model files): a signal u(t) that enters the model as a
parameter, stays a run-time parameter of every scene, is listed as an input in the generated
code's record, and is held constant by simulate(params=...)."""

import numpy as np
import pytest
import sympy as sp

import lagcodegen as lcg
from lagcodegen.errors import ModelError
from lagcodegen.modelfile import ModelFileError


def forced_oscillator():
    """m x'' + c x' + k x = F, with the force F an input."""
    m = lcg.Model("forced")
    x, = m.coordinates("x")
    mass, k, c = m.parameters(m=2.0, k=8.0, c=0.8)
    F = m.input("F", default=0.5)
    m.particle("mass", mass, (x, 0))
    m.potential_energy(k * x ** 2 / 2)
    m.dissipation(c * m.dot(x) ** 2 / 2)
    m.generalized_force(x, F)
    m.output("force", F)
    return m


def test_an_input_is_a_run_time_parameter_marked_as_input():
    model = forced_oscillator()
    assert model.inputs == ["F"] and model.params[sp.Symbol("F")] == 0.5
    eom = lcg.derive(model)
    # M a = F_x: the input enters the force vector like a parameter (eq. 3.16)
    assert sp.simplify(sp.sympify(str(eom.F_se[0])) - sp.sympify("F - c*x_dot - k*x")) == 0
    scene = lcg.Scene(eom, runtime_parameters=["c"], outputs=["force"])  # folds m and k, never F
    assert scene.runtime_parameters == ["c", "F"] and scene.input_names == ["F"]
    assert set(scene.folded) == {"m", "k"}
    code = lcg.generate_code(scene, "c")
    assert code.param_names == ["c", "F"] and code.input_names == ["F"]
    assert code.param_defaults == [0.8, 0.5]
    plain = lcg.generate_code(lcg.Scene(lcg.derive(lcg.systems.pendulum())), "c")
    assert plain.input_names == []


def deflection(t, F, m=2.0, k=8.0, c=0.8):
    """m x'' + c x' + k x = F (constant) from rest at 0, underdamped: the textbook solution."""
    w0, zeta = np.sqrt(k / m), c / (2 * np.sqrt(k * m))
    wd = w0 * np.sqrt(1 - zeta ** 2)
    return F / k * (1 - np.exp(-zeta * w0 * t) * (np.cos(wd * t) + zeta / np.sqrt(1 - zeta ** 2) * np.sin(wd * t)))


def test_simulate_holds_a_constant_input():
    """A constant force F from rest: the analytic response (tending to the static deflection F/k),
    and the output force is F; without params the input's default applies."""
    cm = lcg.compile_model(forced_oscillator(), outputs=["force"], runtime_parameters=[])
    assert cm.param_names == ["F"]
    t = np.linspace(0.0, 20.0, 401)
    res = cm.simulate(t, q0=[0.0], params={"F": 2.0}, rtol=1e-10, atol=1e-12)
    assert np.max(np.abs(res["x"] - deflection(t, 2.0))) < 1e-7
    assert np.all(res["force"] == 2.0)
    default = cm.simulate(t, q0=[0.0], rtol=1e-10, atol=1e-12)
    assert np.max(np.abs(default["x"] - deflection(t, 0.5))) < 1e-7


def test_input_names_are_checked_like_parameters():
    model = forced_oscillator()
    with pytest.raises(ModelError, match="declared twice"):
        model.input("k")
    with pytest.raises(ModelError, match="taken by the velocity"):
        model.input("x_dot")
    with pytest.raises(ModelError, match="not a valid identifier"):
        model.input("2F")
    with pytest.raises(ModelError, match="input .G. must be finite"):
        model.input("G", float("nan"))


FILE = """[model]
name = "forced"
coordinates = ["x"]

[parameters]
m = 2.0
k = 8.0

[inputs]
F = 0.25

[[particles]]
name = "mass"
mass = "m"
position = ["x", 0]

[energy]
potential = "k*x**2/2"

[[generalized_forces]]
coordinate = "x"
expr = "F"
"""


def test_model_file_inputs_section():
    mf = lcg.modelfile.loads_model(FILE, "forced.toml")
    assert mf.model.inputs == ["F"] and mf.model.params[sp.Symbol("F")] == 0.25
    cm = lcg.compile_file(mf, runtime_parameters=[])
    assert cm.param_names == ["F"]


@pytest.mark.parametrize("edit, line, key, token", [
    ("F = 0.25", "F = \"zz\"", "inputs.F", "zz"),
    ("F = 0.25", "k = 1.0", "inputs.k", "k"),
    ("F = 0.25", "sin = 1.0", "inputs.sin", "sin"),
])
def test_model_file_input_errors_name_file_line_and_key(edit, line, key, token):
    with pytest.raises(ModelFileError) as info:
        lcg.modelfile.loads_model(FILE.replace(edit, line), "bad.toml")
    err = info.value
    assert str(err).startswith("bad.toml:10: ") and err.line == 10 and err.key == key
    assert token in str(err)
