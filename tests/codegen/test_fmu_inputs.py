"""The cart-pole of examples/cartpole_fmu.py: a force table given to simulate(inputs=Table) and,
as FMPy's input, to the cart-pole's FMU (FMI 2.0 and 3.0, validated by FMPy): Co-Simulation at a
1 ms communication step agrees to 1e-6 of each state's range at rtol 1e-8; Model Exchange
(FMPy's CVODE) converges to simulate() as its tolerance tightens (1e-6 at rtol 1e-10)."""

import importlib.util
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("fmpy")

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "cartpole_fmu.py"


def load_example():
    spec = importlib.util.spec_from_file_location("cartpole_fmu", EXAMPLE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_cartpole_fmu_with_a_force_table_agrees_with_simulate(tmp_path):
    example = load_example()
    diff = example.run(out=tmp_path, plot=False)
    for version in (2, 3):
        assert (tmp_path / f"cartpole_fmi{version}.fmu").exists()
        assert diff[version, "CoSimulation", 1e-8] < 1e-6
        assert diff[version, "ModelExchange", 1e-10] < 1e-6
        # FMPy's CVODE error shrinks with its tolerance: simulate() is what it converges to
        assert diff[version, "ModelExchange", 1e-10] < diff[version, "ModelExchange", 1e-8] / 10


def test_units_stated_by_the_model_reach_the_model_description(tmp_path):
    """Model.unit (and [units] in a model file): the coordinates', velocities', derivatives',
    parameters' and inputs' units in both FMI versions, declared in UnitDefinitions; FMPy
    validates them."""
    import fmpy
    from fmpy.validation import validate_fmu

    import lagcodegen as lcg
    example = load_example()
    for version in (2, 3):
        path = lcg.export_fmu(example.cartpole(), tmp_path / f"cp{version}.fmu", fmi_version=version,
                              outputs=["force"])
        assert validate_fmu(str(path)) == []
        md = fmpy.read_model_description(str(path))
        units = {v.name: v.unit for v in md.modelVariables}
        assert (units["x"], units["x_dot"], units["der(x)"], units["der(x_dot)"]) == ("m", "m/s", "m/s", "m/s2")
        assert (units["theta_dot"], units["M"], units["g"], units["F"]) == ("rad/s", "kg", "m/s2", "N")
        assert units["force"] is None and units["time"] is None
        assert sorted(u.name for u in md.unitDefinitions) == ["N", "kg", "m", "m/s", "m/s2", "rad", "rad/s",
                                                              "rad/s2"]
    text = """
[model]
name = "slider"
coordinates = ["x"]

[parameters]
m = 2.0

[inputs]
F = 0.0

[units]
x = "m"
m = "kg"
F = "N"

[[particles]]
name = "body"
mass = "m"
position = ["x", 0]

[[generalized_forces]]
coordinate = "x"
expr = "F"
"""
    mf = lcg.modelfile.loads_model(text, "slider.toml")
    assert mf.model.units == {"x": "m", "m": "kg", "F": "N"}
    path = lcg.export_fmu(mf, tmp_path / "slider.fmu")
    assert {v.name: v.unit for v in fmpy.read_model_description(str(path)).modelVariables}["der(x_dot)"] == "m/s2"
    with pytest.raises(lcg.modelfile.ModelFileError, match="not a coordinate, parameter or input"):
        lcg.modelfile.loads_model(text.replace('F = "N"', 'G = "N"'), "slider.toml")
    plain = lcg.export_fmu(lcg.modelfile.loads_model(text.replace('[units]\nx = "m"\nm = "kg"\nF = "N"\n', ""),
                                                     "slider.toml"), tmp_path / "plain.fmu")
    assert all(v.unit is None for v in fmpy.read_model_description(str(plain)).modelVariables)


def test_the_fmpy_signal_is_the_tables_hold():
    """The structured array handed to FMPy holds the same values as the Table between its times."""
    import lagcodegen as lcg
    example = load_example()
    sig = example.fmpy_signal()
    tab = lcg.Table(example.TIMES, example.FORCE, kind="zoh")
    mids = 0.5 * (sig["time"][1:] + sig["time"][:-1])
    keep = np.diff(sig["time"]) > 0
    left = sig["F"][:-1][keep]
    assert np.array_equal(tab(mids[keep]), left)
