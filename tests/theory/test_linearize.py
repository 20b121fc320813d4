"""Linearization M dq'' + C dq' + K dq = 0 against textbook small-oscillation results."""

import math

import numpy as np
import pytest
import sympy as sp

import lagcodegen as lcg
from lagcodegen import ModelError, systems
from lagcodegen.theory.linearize import linearize


@pytest.fixture(scope="module")
def pendulum():
    return lcg.derive(systems.pendulum())


def test_pendulum_bottom(pendulum):
    l, g = 0.7, 9.5
    lin = linearize(pendulum, [0.0], params={"l": l, "g": g, "m": 3.0})
    assert lin.frequencies == pytest.approx([math.sqrt(g / l)], rel=1e-12)
    assert lin.stable()
    assert np.allclose(lin.eigenvalues, [-1j * math.sqrt(g / l), 1j * math.sqrt(g / l)], rtol=1e-12)
    assert np.array_equal(lin.a0, [0.0])


def test_pendulum_top_is_unstable(pendulum):
    lin = linearize(pendulum, {"theta": math.pi})
    assert not lin.stable()
    assert np.max(lin.eigenvalues.real) == pytest.approx(math.sqrt(9.81), rel=1e-12)
    assert lin.frequencies.size == 0


def test_pendulum_symbolic(pendulum):
    lin = linearize(pendulum, symbolic=True)
    m, l, g, th = sp.symbols("m l g theta")
    assert sp.simplify(lin.K[0, 0] - m * g * l * sp.cos(th)) == 0
    assert sp.simplify(lin.M[0, 0] - m * l**2) == 0
    assert lin.C == sp.zeros(1, 1)
    with pytest.raises(ModelError, match="numeric"):
        lin.A
    # At a given angle the symbolic result takes the value.
    at = linearize(pendulum, [sp.pi / 3], symbolic=True)
    assert sp.simplify(at.K[0, 0] - m * g * l / 2) == 0


def test_double_pendulum_normal_modes():
    # Equal masses and lengths: M = m l^2 [[2, 1], [1, 1]], K = m g l [[2, 0], [0, 1]],
    # det(K - w^2 M) = 0 gives w^2 = (g/l)(2 -+ sqrt(2)).
    l, g = 1.3, 9.81
    eom = lcg.derive(systems.double_pendulum())
    lin = linearize(eom, [0.0, 0.0], params={"l1": l, "l2": l, "m1": 0.5, "m2": 0.5, "g": g})
    expected = [math.sqrt(g / l * (2 - math.sqrt(2))), math.sqrt(g / l * (2 + math.sqrt(2)))]
    assert lin.frequencies == pytest.approx(expected, rel=1e-12)
    assert lin.conservative and lin.stable()


def test_damped_oscillator_has_damping_matrix():
    # m x'' + c x' + k x = F0 cos(w t): M = m, C = c, K = k, eigenvalues -c/(2m) +- i wd.
    eom = lcg.derive(systems.damped_driven_oscillator())
    m, k, c = 2.0, 8.0, 0.6
    lin = linearize(eom, [0.0], params={"m": m, "k": k, "c": c, "F0": 0.0})
    assert (lin.M[0, 0], lin.C[0, 0], lin.K[0, 0]) == pytest.approx((m, c, k), rel=1e-14)
    wd = math.sqrt(k / m - (c / (2 * m)) ** 2)
    assert not lin.conservative
    assert lin.frequencies == pytest.approx([wd], rel=1e-12)
    assert lin.eigenvalues.real == pytest.approx([-c / (2 * m)] * 2, rel=1e-12)
    assert lin.stable()


def test_system_matrix_is_the_jacobian_away_from_equilibrium():
    # At a moving state (a0 != 0), A must equal df/dy of y' = (q', M^-1 F): compare with
    # central differences of the compiled right-hand side (independent numerics).
    model = systems.double_pendulum()
    cm = lcg.compile_model(model)
    q0, v0 = np.array([0.7, -0.4]), np.array([0.9, 1.3])
    lin = linearize(lcg.derive(model), q0, v0)
    y0 = np.concatenate([q0, v0])
    fd = np.empty((4, 4))
    for j in range(4):
        h = 1e-6 * max(1.0, abs(y0[j]))
        e = np.zeros(4)
        e[j] = h
        fd[:, j] = (cm.rhs(0.0, y0 + e) - cm.rhs(0.0, y0 - e)) / (2 * h)
    assert np.allclose(lin.a0, cm.rhs(0.0, y0)[2:], rtol=1e-12)
    assert np.max(np.abs(lin.A - fd)) < 1e-7
    assert np.max(np.abs(lin.C)) > 0.1  # velocity-dependent (Coriolis) terms at this state


def test_errors(pendulum):
    with pytest.raises(ModelError, match="q0 is required"):
        linearize(pendulum)
    with pytest.raises(ModelError, match="not a parameter"):
        linearize(pendulum, [0.0], params={"C_phi": 1.0})
    with pytest.raises(ModelError, match="expected 1"):
        linearize(pendulum, [0.0, 1.0])
