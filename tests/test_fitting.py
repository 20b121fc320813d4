"""lagcodegen.fit: parameters from noisy synthetic trajectories, with the exact Jacobian from the
forward sensitivities (least squares; covariance from J^T J and the residual variance)."""

import numpy as np
import pytest

import lagcodegen as lcg
from lagcodegen.errors import LagcodegenError


@pytest.fixture(scope="module")
def sim():
    return lcg.compile_model(lcg.systems.damped_pendulum())


def _data(sim, t, q0, true, noise, seed):
    ref = sim.simulate(t, q0=q0, params=true, rtol=1e-11, atol=1e-13)
    rng = np.random.default_rng(seed)
    return ref["theta"] + noise * rng.standard_normal(t.size)


def test_damped_pendulum_l_and_c_recovered_within_three_sigma(sim):
    """200 samples of theta with 1% noise (of the amplitude 1, seeded): l and c within 3 reported
    standard deviations of the truth, in at most 20 iterations; the residuals' variance is the
    noise's."""
    t = np.linspace(0.0, 10.0, 200)
    true = {"l": 1.0, "c": 0.3}
    noise = 0.01
    data = _data(sim, t, [1.0], true, noise, seed=20241)
    f = lcg.fit(sim, t, data[:, None], params={"l": 0.9, "c": 0.05}, observe=["theta"], q0=[1.0], sigma=noise)
    assert f.success
    assert f.iterations <= 20
    for name, value in true.items():
        assert abs(f.params[name] - value) < 3 * f.stderr[name], (name, f.params[name], f.stderr[name])
        assert f.stderr[name] > 0
    # sigma = noise: the residual variance is ~1 (chi-square with 198 degrees of freedom: 1 +- 0.1)
    assert 0.7 < f.residual_variance < 1.3
    assert f.cov.shape == (2, 2) and np.allclose(np.sqrt(np.diag(f.cov)), [f.stderr["l"], f.stderr["c"]])
    assert f.residuals.shape == (200,)
    assert f.cost_history[0] > 100 * f.cost_history[-1]
    assert np.isfinite(f.condition) and f.condition >= 1


def test_two_experiments_with_bounds_and_an_initial_value(sim):
    """Two initial states fitted together; an initial velocity fitted as well (both experiments
    share it here); bounds respected."""
    t = np.linspace(0.0, 6.0, 120)
    true = {"l": 1.2, "c": 0.2}
    noise = 0.005
    d1 = _data(sim, t, [0.8], true, noise, seed=1)
    d2 = _data(sim, t, [-0.4], true, noise, seed=2)
    f = lcg.fit(sim, params={"l": 1.0, "c": 0.1}, observe="theta", bounds={"c": (0.0, 1.0), "l": (0.5, 2.0)},
                experiments=[dict(t=t, data=d1, q0=[0.8]), dict(t=t, data=d2, q0=[-0.4])], sigma=noise)
    for name, value in true.items():
        assert abs(f.params[name] - value) < 3 * f.stderr[name]
    assert f.residuals.shape == (240,)
    g = lcg.fit(sim, t, d1, params={"l": 1.0, "c": 0.1, "theta_dot(0)": 0.3}, observe=["theta"], q0=[0.8],
                sigma=noise, bounds={"theta_dot(0)": (-1.0, 1.0)})
    assert abs(g.params["theta_dot(0)"]) < 3 * g.stderr["theta_dot(0)"]
    assert abs(g.params["l"] - 1.2) < 3 * g.stderr["l"]


def test_bad_input_is_named(sim):
    t = np.linspace(0, 1, 10)
    d = np.zeros((10, 1))
    with pytest.raises(LagcodegenError, match="shape"):
        lcg.fit(sim, t, np.zeros((9, 1)), params={"l": 1.0}, observe=["theta"], q0=[1.0])
    with pytest.raises(LagcodegenError, match="'phi' is neither a state nor an output"):
        lcg.fit(sim, t, d, params={"l": 1.0}, observe=["phi"], q0=[1.0])
    with pytest.raises(LagcodegenError, match="'L' is neither a run-time parameter"):
        lcg.fit(sim, t, d, params={"L": 1.0}, observe=["theta"], q0=[1.0])
    with pytest.raises(LagcodegenError, match="bounds of 'l'"):
        lcg.fit(sim, t, d, params={"l": 1.0}, observe=["theta"], q0=[1.0], bounds={"l": (2.0, 3.0)})
    with pytest.raises(LagcodegenError, match="both fitted and fixed"):
        lcg.fit(sim, t, d, params={"l": 1.0}, observe=["theta"], q0=[1.0], fixed={"l": 2.0})
    with pytest.raises(LagcodegenError, match="experiment 0 needs"):
        lcg.fit(sim, params={"l": 1.0}, observe=["theta"], experiments=[dict(t=t)])


def test_prepared_runs_give_what_simulate_gives(sim, monkeypatch):
    """The fit's runs prepared once (the solver resolved, the driver's arrays reused) against
    every evaluation through simulate: the same estimates, covariance and cost history; a run
    that fails still names the experiment and the parameters."""
    import lagcodegen.fitting as fitting
    t = np.linspace(0.0, 5.0, 60)
    true = {"l": 1.1, "c": 0.25}
    data = np.column_stack([_data(sim, t, [0.9], true, 0.01, seed=5),
                            sim.simulate(t, q0=[0.9], params=true)["theta_dot"]])
    kw = dict(params={"l": 1.0, "c": 0.1, "theta(0)": 0.85}, observe=["theta", "theta_dot"], q0=[0.9], sigma=0.01)
    fast = lcg.fit(sim, t, data, method="bdf", **kw)
    monkeypatch.setattr(fitting, "_prepared_runs", lambda *args, **kwargs: None)
    slow = lcg.fit(sim, t, data, method="bdf", **kw)
    assert fast.nfev == slow.nfev and fast.iterations == slow.iterations
    for name in kw["params"]:
        assert fast.params[name] == pytest.approx(slow.params[name], rel=1e-12, abs=1e-14)
    assert np.allclose(fast.cov, slow.cov, rtol=1e-10, atol=0)
    assert np.allclose(fast.cost_history, slow.cost_history, rtol=1e-12, atol=0)
    monkeypatch.undo()
    with pytest.raises(LagcodegenError, match="fit: the run of experiment 0 failed at parameters"):
        lcg.fit(sim, t, data, max_steps=5, **kw)
