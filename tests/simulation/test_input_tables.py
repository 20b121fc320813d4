"""Input tables (lagcodegen.Table, simulate(inputs=...)): a signal u(t) interpolated in C by the
native CVODE driver at each evaluation time, the run stopped and restarted where u jumps or kinks.
Checked against analytic responses of a damped oscillator m x'' + c x' + k x = F(t): a step force
(zero-order hold), a sine sampled into linear and cubic tables; the rejected steps with and
without the restarts; ensembles with a table per member; bad tables and names rejected."""

import numpy as np
import pytest
import sympy as sp

import lagcodegen as lcg
from lagcodegen.errors import LagcodegenError

M, K, C = 1.0, 4.0, 0.4
W0, ZETA = np.sqrt(K / M), C / (2 * np.sqrt(K * M))
WD = W0 * np.sqrt(1 - ZETA ** 2)


def oscillator():
    """m x'' + c x' + k x = F, the force F an input (lagcodegen.systems.forced_oscillator)."""
    return lcg.systems.forced_oscillator("osc_table", m=M, k=K, c=C)


@pytest.fixture(scope="module")
def sim():
    return lcg.compile_model(oscillator(), outputs=["force"])


def step_response(t, t_step, F0):
    """x(t) from rest for F = F0 from t_step on (the textbook underdamped step response)."""
    s = np.clip(t - t_step, 0.0, None)
    x = F0 / K * (1 - np.exp(-ZETA * W0 * s) * (np.cos(WD * s) + ZETA / np.sqrt(1 - ZETA ** 2) * np.sin(WD * s)))
    return np.where(t >= t_step, x, 0.0)


def sine_response(t, w):
    """x(t) from rest for F = sin(w t): the steady oscillation plus the decaying free motion."""
    X = 1.0 / ((K - M * w * w) + 1j * C * w)
    xp, vp = np.imag(X * np.exp(1j * w * t)), np.imag(1j * w * X * np.exp(1j * w * t))
    A = -np.imag(X)
    B = (-np.real(w * X) + ZETA * W0 * A) / WD
    assert vp is not None
    return xp + np.exp(-ZETA * W0 * t) * (A * np.cos(WD * t) + B * np.sin(WD * t))


def test_a_step_force_table_gives_the_analytic_step_response(sim):
    t = np.linspace(0.0, 10.0, 201)
    tab = lcg.Table([0.0, 1.3], [0.0, 2.0], kind="zoh")
    for method in ("adams", "bdf"):
        res = sim.simulate(t, q0=[0.0], inputs={"F": tab}, rtol=1e-10, atol=1e-12, method=method)
        assert np.max(np.abs(res["x"] - step_response(t, 1.3, 2.0))) < 1e-8
        assert np.array_equal(res["force"], np.where(t >= 1.3, 2.0, 0.0))  # right-continuous hold
        assert res.stats["restarts"] == 1
    # a pair (times, values) is a linear table; the input's default stays in p
    res = sim.simulate(t, q0=[0.0], inputs={"F": ([0.0, 10.0], [0.0, 10.0])}, rtol=1e-10, atol=1e-12)
    assert np.allclose(res["force"], t, rtol=0, atol=1e-12)
    assert res.parameters["F"] == 0.0


def test_restarts_at_the_jumps_cut_the_rejected_steps(sim):
    """A square wave of 20 jumps: with the restarts at the jumps the error-test failures drop by
    a factor of 3 or more and the answer is the superposition of step responses."""
    t = np.linspace(0.0, 20.0, 201)
    tb = np.concatenate([[0.0], np.arange(0.5, 20.0, 1.0)])
    vals = np.concatenate([[0.0], np.where(np.arange(tb.size - 1) % 2 == 0, 1.0, -1.0)])
    exact = sum(step_response(t, tb[i], vals[i] - vals[i - 1]) for i in range(1, tb.size))
    for method in ("adams", "bdf"):
        fails = {}
        for restart in ("auto", False):
            tab = lcg.Table(tb, vals, kind="zoh", restart=restart)
            res = sim.simulate(t, q0=[0.0], inputs={"F": tab}, rtol=1e-8, atol=1e-10, method=method)
            # a step straddling a jump loses accuracy too
            assert np.max(np.abs(res["x"] - exact)) < (1e-6 if restart else 1e-4)
            fails[restart] = res.stats["err_test_fails"]
            assert res.stats["restarts"] == (20 if restart else 0)
        assert fails["auto"] * 3 < fails[False], fails


@pytest.mark.parametrize("kind, n, tol", [("linear", 2001, 2e-5), ("cubic", 201, 1e-6), ("cubic", 2001, 1e-8)])
def test_linear_and_cubic_tables_of_a_sampled_sine(sim, kind, n, tol):
    """F = sin(1.3 t) sampled at n points: the interpolation error of the force (O(h^2) linear,
    O(h^4) cubic) is what separates the run from the analytic response."""
    w = 1.3
    ts = np.linspace(0.0, 20.0, n)
    tab = lcg.Table(ts, np.sin(w * ts), kind=kind)
    t = np.linspace(0.0, 20.0, 101)
    res = sim.simulate(t, q0=[0.0], inputs={"F": tab}, rtol=1e-11, atol=1e-13)
    err = np.max(np.abs(res["x"] - sine_response(t, w)))
    assert err < tol
    # the force the driver used at the output times is the table's value
    assert np.allclose(res["force"], tab(t), rtol=0, atol=1e-14)
    if kind == "cubic":  # a C2 spline: no restart inside the run
        assert res.stats["restarts"] == 0
    else:
        assert res.stats["restarts"] == n - 2


def test_taylor_takes_each_tables_piece_on_each_segment(sim):
    """Taylor: the input is a cubic of t in the jet, the run split at every breakpoint, so a step
    force costs nothing (the step response to rounding, in a handful of steps) and sampled sines
    agree with the CVODE driver's runs of the same tables."""
    t = np.linspace(0.0, 10.0, 201)
    tab = lcg.Table([0.0, 1.3], [0.0, 2.0], kind="zoh")
    res = sim.simulate(t, q0=[0.0], inputs={"F": tab}, rtol=1e-12, atol=1e-14, method="taylor")
    assert np.max(np.abs(res["x"] - step_response(t, 1.3, 2.0))) < 1e-13
    assert np.array_equal(res.t, t) and np.array_equal(res["force"], np.where(t >= 1.3, 2.0, 0.0))
    assert res.stats["restarts"] == 1 and res.stats["steps"] < 40
    w, tt = 1.3, np.linspace(0.0, 20.0, 101)
    for kind, n, tol in (("linear", 501, 2e-4), ("cubic", 201, 1e-6)):
        ts = np.linspace(0.0, 20.0, n)
        tab = lcg.Table(ts, np.sin(w * ts), kind=kind)
        tay = sim.simulate(tt, q0=[0.0], inputs={"F": tab}, rtol=1e-12, atol=1e-14, method="taylor")
        cvode = sim.simulate(tt, q0=[0.0], inputs={"F": tab}, rtol=1e-12, atol=1e-14)
        assert np.max(np.abs(tay["x"] - sine_response(tt, w))) < tol
        assert np.max(np.abs(tay["x"] - cvode["x"])) < 1e-9
        assert np.allclose(tay["force"], tab(tt), rtol=0, atol=1e-14)


def test_table_values_and_restart_times():
    tab = lcg.Table([0.0, 1.0, 2.0], [1.0, 3.0, 3.0], kind="linear")
    assert tab(np.array([-1.0, 0.5, 1.0, 1.5, 5.0])).tolist() == [1.0, 2.0, 3.0, 3.0, 3.0]
    assert tab.restart_times().tolist() == [0.0, 1.0]  # kinks; none where the slope stays 0
    zoh = lcg.Table([0.0, 1.0, 2.0, 3.0], [1.0, 1.0, 2.0, 2.0], kind="zoh")
    assert zoh(np.array([0.999, 1.0, 2.0, 3.5])).tolist() == [1.0, 1.0, 2.0, 2.0]
    assert zoh.restart_times().tolist() == [2.0]  # where the value changes
    ts = np.linspace(0, 3, 31)
    cub = lcg.Table(ts, ts ** 3, kind="cubic")  # not-a-knot reproduces a cubic exactly
    assert np.allclose(cub(np.array([0.123, 1.777, 2.5])), np.array([0.123, 1.777, 2.5]) ** 3, atol=1e-12)
    assert cub.derivative(1.5) == pytest.approx(3 * 1.5 ** 2)
    assert cub.restart_times().tolist() == [3.0]  # the held end: slope 27 -> 0 (slope 0 at t = 0)


def test_ensemble_members_take_their_own_tables(sim):
    t = np.linspace(0.0, 6.0, 61)
    tabs = [lcg.Table([0.0, ts], [0.0, F0], kind="zoh") for ts, F0 in ((0.5, 1.0), (1.0, -2.0), (2.5, 3.0))]
    ens = sim.ensemble(t, q0=np.zeros((3, 1)), inputs={"F": tabs}, save="trajectory", rtol=1e-10, atol=1e-12,
                       threads=2)
    assert (ens.status == 0).all()
    for i, tab in enumerate(tabs):
        alone = sim.simulate(t, q0=[0.0], inputs={"F": tab}, rtol=1e-10, atol=1e-12)
        assert np.array_equal(ens.member(i)["x"], alone["x"])  # bit-identical to the single run
        assert np.max(np.abs(alone["x"] - step_response(t, tab.times[1], tab.values[1]))) < 1e-8
    shared = sim.ensemble(t, q0=np.zeros((2, 1)), params={"k": [4.0, 9.0]}, inputs={"F": tabs[1]},
                          save="trajectory",
                          rtol=1e-10, atol=1e-12)
    alone = sim.simulate(t, q0=[0.0], params={"k": 9.0}, inputs={"F": tabs[1]}, rtol=1e-10, atol=1e-12)
    assert np.array_equal(shared.member(1)["x"], alone["x"])


def test_bad_inputs_are_named(sim):
    t = [0.0, 1.0]
    with pytest.raises(LagcodegenError, match=r"input 'F': times must increase strictly.*times\[1\]"):
        sim.simulate(t, q0=[0.0], inputs={"F": ([0.0, 2.0, 1.0], [0.0, 1.0, 2.0])})
    with pytest.raises(LagcodegenError, match="input 'F': 3 times but 2 values"):
        sim.simulate(t, q0=[0.0], inputs={"F": ([0.0, 1.0, 2.0], [0.0, 1.0])})
    with pytest.raises(LagcodegenError, match=r"input 'F': values\[1\] is not finite"):
        sim.simulate(t, q0=[0.0], inputs={"F": ([0.0, 1.0], [0.0, np.nan])})
    with pytest.raises(LagcodegenError, match="'G' is not an input of model 'osc_table'.*F"):
        sim.simulate(t, q0=[0.0], inputs={"G": ([0.0, 1.0], [0.0, 1.0])})
    with pytest.raises(LagcodegenError, match="kind must be one of zoh, linear, cubic"):
        lcg.Table([0.0, 1.0], [0.0, 1.0], kind="spline")
    with pytest.raises(LagcodegenError, match="events with input tables"):
        sim.simulate(t, q0=[0.0], inputs={"F": ([0.0, 1.0], [0.0, 1.0])}, method="taylor",
                     events=[lcg.Event("x0", sp.Symbol("x"))])
    with pytest.raises(LagcodegenError, match="ensembles do not take them"):
        sim.ensemble(t, q0=np.zeros((2, 1)), inputs={"F": ([0.0, 1.0], [0.0, 1.0])}, method="taylor")
    with pytest.raises(LagcodegenError, match="input tables need backend='native'"):
        sim.simulate(t, q0=[0.0], inputs={"F": ([0.0, 1.0], [0.0, 1.0])}, backend="sksundae")
    with pytest.raises(LagcodegenError, match="input 'F': 2 tables for 3 members"):
        sim.ensemble(t, q0=np.zeros((3, 1)), inputs={"F": [([0.0], [1.0]), ([0.0], [2.0])]})
    plain = lcg.compile_model(lcg.systems.pendulum())
    with pytest.raises(LagcodegenError, match="declares no inputs"):
        plain.simulate(t, q0=[0.1], inputs={"F": ([0.0, 1.0], [0.0, 1.0])})
