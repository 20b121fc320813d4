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
