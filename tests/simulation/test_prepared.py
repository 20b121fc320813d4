"""Prepared runs made explicit (lagcodegen.simulation.prepared): ``sim.prepare(t, **options)``
returns a run to call with initial states and parameters; each call must equal
``simulate(t, ..., **options)`` bit for bit, on every family and with sensitivities, events,
input tables and array tolerances (those two on the full path), and raise the same errors."""

import numpy as np
import pytest
import sympy as sp

import lagcodegen as lcg
from lagcodegen import LagcodegenError, SolverError, systems
from lagcodegen.model.events import Event
from lagcodegen.simulation.prepared import PreparedRun


@pytest.fixture(scope="module")
def double_pendulum():
    return lcg.compile_model(systems.double_pendulum(), outputs=["energy"])


def assert_identical(a, b):
    """Every array bit for bit, the statistics but for the wall time, the events and names."""
    np.testing.assert_array_equal(a.t, b.t)
    np.testing.assert_array_equal(a.y, b.y)
    assert list(a.outputs) == list(b.outputs)
    for name in b.outputs:
        np.testing.assert_array_equal(a.outputs[name], b.outputs[name])
    sa, sb = dict(a.stats), dict(b.stats)
    sa.pop("wall_time", None), sb.pop("wall_time", None)
    assert sa == sb
    assert a.parameters == b.parameters and a.status == b.status and a.message == b.message
    assert [(e.name, e.t, e.direction) for e in a.events] == [(e.name, e.t, e.direction) for e in b.events]
    if b.sensitivities is None:
        assert a.sensitivities is None
    else:
        np.testing.assert_array_equal(a.sensitivities, b.sensitivities)
        assert a.sensitivity_names == b.sensitivity_names


@pytest.mark.parametrize("options", [
    dict(method="adams"), dict(method="bdf", rtol=1e-10, atol=1e-12), dict(method="taylor", rtol=1e-9),
    dict(method="bdf", sensitivities=["g", "theta1(0)"]), dict(method="adams", max_steps=20000, jacobian=False),
])
def test_prepared_runs_equal_simulate_bit_for_bit(double_pendulum, options):
    cm = double_pendulum
    t = np.linspace(0.0, 2.0, 21)
    run = cm.prepare(t, **options)
    assert isinstance(run, PreparedRun) and run.prepared
    for q0, params in (([0.7, -0.3], None), ([1.2, 0.4], {"g": 3.7}), ({"theta1": 0.1, "theta2": 0.2}, {"l1": 2.0})):
        assert_identical(run(q0=q0, params=params), cm.simulate(t, q0=q0, params=params, **options))
    y0 = np.array([0.3, 0.2, -0.1, 0.05])
    assert_identical(run(y0=y0), cm._simulate(t, y0=y0, **options))  # the full path itself too


def test_prepared_taylor_runs_with_events(double_pendulum):
    cm = double_pendulum
    th = sp.Symbol(cm.state_names[0])
    events = [Event("cross", th, 0, False), Event("stop", th + 0.5, -1, True)]
    t = np.linspace(0.0, 3.0, 7)
    run = cm.prepare(t, method="taylor", events=events)
    assert run.prepared
    got, want = run(q0=[0.7, -0.3]), cm._simulate(t, q0=[0.7, -0.3], method="taylor", events=events)
    assert got.events and got.events[-1].name == "stop"
    assert_identical(got, want)


def test_runs_the_families_do_not_prepare_take_the_full_path(double_pendulum):
    """Input tables and array tolerances: each call is simulate()'s full path with the options
    fixed at prepare; CVODE's events too. Same results all the same."""
    cm = double_pendulum
    t = np.linspace(0.0, 1.0, 11)
    atol = np.full(cm.ny, 1e-10)
    run = cm.prepare(t, method="bdf", atol=atol)
    assert not run.prepared
    assert_identical(run(q0=[0.5, 0.1]), cm.simulate(t, q0=[0.5, 0.1], method="bdf", atol=atol))
    events = [Event("cross", sp.Symbol(cm.state_names[0]), 0, False)]
    run = cm.prepare(t, method="adams", events=events)
    assert_identical(run(q0=[0.5, 0.1]), cm.simulate(t, q0=[0.5, 0.1], method="adams", events=events))


def test_prepare_checks_options_once_and_calls_check_what_they_bring(double_pendulum):
    cm = double_pendulum
    t = np.linspace(0.0, 1.0, 5)
    with pytest.raises(LagcodegenError, match="frobnicate"):
        cm.prepare(t, frobnicate=3)
    with pytest.raises(LagcodegenError):
        cm.prepare(np.array([1.0, 0.0]))  # decreasing times
    with pytest.raises(LagcodegenError):
        cm.prepare(t, rtol=-1.0)
    run = cm.prepare(t, method="adams", max_steps=3)
    with pytest.raises(SolverError, match="max_steps"):
        run(q0=[0.5, 0.1])
    partial = run(q0=[0.5, 0.1], raise_on_error=False)
    assert partial.status < 0
    good = cm.prepare(t)
    for bad in ([0.1], [0.1, np.nan], {"nope": 1.0}):
        with pytest.raises(LagcodegenError) as got:
            good(q0=bad)
        with pytest.raises(LagcodegenError) as want:
            cm.simulate(t, q0=bad)
        assert str(got.value) == str(want.value)
    with pytest.raises(LagcodegenError):
        good(q0=[0.1, 0.2], params={"nope": 1.0})
    assert good.t.flags.writeable is False and "5 output times" in repr(good)
