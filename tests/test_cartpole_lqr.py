"""examples/cartpole_lqr.py: the LQR closed loop through the integrator object keeps the pole
upright, agrees with the same loop on CVODE and with the loop's linear (zero-order-hold)
prediction, and writes its plot."""

import importlib.util
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg

import lagcodegen as lcg

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "cartpole_lqr.py"


@pytest.fixture(scope="module")
def example():
    spec = importlib.util.spec_from_file_location("cartpole_lqr", EXAMPLE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def setup(example):
    model = example.cartpole()
    return model, lcg.compile_model(model), example.lqr_gain(model)


@pytest.fixture(scope="module")
def loop(example, setup):
    _, sim, K = setup
    return example.run(sim=sim, gain=K)


def test_pole_kept_within_0_05_rad_for_10_s_from_0_2_rad(loop):
    t, ys, forces = loop
    th = ys[:, 1]
    assert t[0] == 0.0 and t[-1] == pytest.approx(10.0) and th[0] == 0.2
    inside = int(np.argmax(np.abs(th) < 0.05))
    assert t[inside] < 0.5                          # caught within half a second
    assert np.max(np.abs(th[inside:])) < 0.05      # and kept within 0.05 rad until t = 10 s
    assert np.max(np.abs(th)) <= 0.2 + 1e-9         # never falls further than the start
    assert abs(th[-1]) < 1e-4 and abs(ys[-1, 0]) < 1e-3  # upright, the cart back at the origin
    assert np.all(np.isfinite(forces)) and abs(forces[0]) > 1.0


def test_same_loop_on_cvode(example, setup, loop):
    _, sim, K = setup
    t, ys, _ = example.run(sim=sim, gain=K, method="adams", t_end=3.0)
    n = t.size
    assert np.max(np.abs(ys - loop[1][:n])) < 1e-6


def test_loop_follows_its_linear_zero_order_hold_prediction(setup, loop):
    """For small angles the closed loop is y_{k+1} = Ad y_k + Bd u_k, u_k = -K y_k (the linearization
    discretized exactly over the 5 ms hold); from 0.2 rad the nonlinear loop stays near it."""
    model, _, K = setup
    eom = lcg.derive(model)
    A = lcg.linearize(eom, q0=[0.0, 0.0], params={"F": 0.0}).A
    b = lcg.linearize(eom, q0=[0.0, 0.0], params={"F": 1.0}).a0
    B = np.concatenate([np.zeros(2), b])[:, None]
    h = 0.005
    E = scipy.linalg.expm(np.block([[A, B], [np.zeros((1, 5))]]) * h)
    Ad, Bd = E[:4, :4], E[:4, 4:]
    t, ys, _ = loop
    y = ys[0].copy()
    lin = [y]
    for _ in range(t.size - 1):
        y = Ad @ y + Bd[:, 0] * (-K @ y)
        lin.append(y)
    lin = np.array(lin)
    assert np.max(np.abs(ys[:, 1] - lin[:, 1])) < 0.02
    assert np.max(np.abs(ys[200:, 1] - lin[200:, 1])) < 2e-3  # after 1 s, the angle is small: closer


def test_example_writes_its_plot(example, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    example.main()
    assert (tmp_path / "out" / "cartpole_lqr.png").stat().st_size > 10_000
