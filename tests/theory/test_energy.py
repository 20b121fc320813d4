"""T = T2 + T1 + T0 (eq. 2.2), Jacobi's h (eqs. 3.5-3.7) and dh/dt = -2D (eq. 3.15), against
hand derivations and simulations."""

import dataclasses

import numpy as np
import pytest
import symengine
import sympy as sp
from scipy.integrate import cumulative_trapezoid

import lagcodegen as lcg
from lagcodegen import DerivationError, Model, derive, systems
from lagcodegen.theory.energy import check_jacobi, is_natural, is_zero, jacobi_h, kinetic_split
from lagcodegen.model.systems import charged_particle, damped_pendulum, rotating_frame_particle


def spinning_hoop() -> Model:
    """Bead on a hoop of radius a spinning at the constant rate w about the vertical z axis.

    theta is measured from the bottom: x = (a sin(theta) cos(w t), a sin(theta) sin(w t), -a cos(theta)).
    """
    model = Model("hoop")
    th, = model.coordinates("theta")
    m, a, g, w = model.parameters(m=1.0, a=1.0, g=9.81, w=5.0)
    t = model.t
    model.particle("bead", m, (a * sp.sin(th) * sp.cos(w * t), a * sp.sin(th) * sp.sin(w * t), -a * sp.cos(th)))
    model.gravity(g)
    return model


def driven_support_pendulum() -> Model:
    """Pendulum whose pivot is moved horizontally, x_pivot = A cos(W t): L depends on t explicitly."""
    model = Model("driven_support")
    th, = model.coordinates("theta")
    l, g, m, A, W = model.parameters(l=1.0, g=9.81, m=1.0, A=0.1, W=3.0)
    model.particle("bob", m, (A * sp.cos(W * model.t) + l * sp.sin(th), -l * sp.cos(th)))
    model.gravity(g)
    return model


def spun_rotor(kind: str) -> Model:
    """A rotor at rest in position whose angle is theta + W t (planar or 3-D body): T1 != 0 through the angle."""
    model = Model(f"rotor_{kind}")
    th, = model.coordinates("theta")
    J, W, m = model.parameters(J=0.5, W=2.0, m=1.0)
    angle = th + W * model.t
    if kind == "planar":
        model.planar_body("rotor", m, J, (0, 0), angle)
    else:
        c, s = sp.cos(angle), sp.sin(angle)
        model.rigid_body("rotor", m, (J, J, J), (0, 0, 0), sp.Matrix([[c, -s, 0], [s, c, 0], [0, 0, 1]]))
    return model


def moving_frame_direct() -> Model:
    """Kinetic energy given directly, of a particle seen from a frame moving at speed u: T = m/2 (x' + u)^2."""
    model = Model("moving_frame")
    x, = model.coordinates("x")
    m, u, k = model.parameters(m=1.0, u=0.5, k=1.0)
    model.kinetic_energy(m / 2 * (model.dot(x) + u) ** 2)
    model.potential_energy(k * x**2 / 2)
    return model


# ---------------------------------------------------------------------------- T = T2 + T1 + T0
def test_spinning_hoop_split_is_the_hand_derivation():
    # |x'|^2 = a^2 theta'^2 (cos^2 + sin^2 of the meridian) + a^2 w^2 sin^2(theta) (the hoop's turning):
    # no cross term because the meridian and azimuthal directions are orthogonal.
    eom = derive(spinning_hoop())
    th, thd = sp.symbols("theta theta_dot")
    m, a, g, w = sp.symbols("m a g w")
    split = kinetic_split(eom)
    assert is_zero(split.T2 - m * a**2 * thd**2 / 2)
    assert split.T1 == 0
    assert is_zero(split.T0 - m * a**2 * w**2 * sp.sin(th) ** 2 / 2)
    assert is_zero(split.alpha[0, 0] - m * a**2) and is_zero(split.gamma - split.T0)
    assert not split.natural and not is_natural(eom.model)
    assert is_zero(split.T - eom.T)


def test_spinning_hoop_h_is_T2_minus_T0_plus_V():
    eom = derive(spinning_hoop())
    th, thd = sp.symbols("theta theta_dot")
    m, a, g, w = sp.symbols("m a g w")
    h_hand = m * a**2 * thd**2 / 2 - m * a**2 * w**2 * sp.sin(th) ** 2 / 2 - m * g * a * sp.cos(th)
    assert is_zero(jacobi_h(eom) - h_hand)
    check = check_jacobi(eom)
    assert check.lagrangian and not check.explicit_time and check.conserved and check.holds
    assert check.equals_T2_minus_T0_plus_V and not check.equals_T_plus_V


@pytest.mark.parametrize("make", [systems.pendulum, systems.double_pendulum])
def test_pendulums_are_natural_and_h_is_T_plus_V(make):
    eom = derive(make())
    split = kinetic_split(eom)
    assert split.natural and is_natural(eom.model)
    assert split.T1 == 0 and split.T0 == 0
    assert is_zero(split.T2 - eom.T)
    assert split.alpha.is_symmetric() and is_zero(split.alpha - eom.M)  # V has no velocities: alpha = M
    check = check_jacobi(eom)
    assert check.equals_T_plus_V and check.equals_T2_minus_T0_plus_V
    assert check.conserved and check.holds and check.matches_derivation


def test_double_pendulum_alpha_is_the_hand_mass_matrix():
    eom = derive(systems.double_pendulum())
    t1, t2 = sp.symbols("theta1 theta2")
    l1, l2, m1, m2 = sp.symbols("l1 l2 m1 m2")
    alpha = sp.Matrix([[(m1 + m2) * l1**2, m2 * l1 * l2 * sp.cos(t1 - t2)],
                       [m2 * l1 * l2 * sp.cos(t1 - t2), m2 * l2**2]])
    assert is_zero(sp.trigsimp(kinetic_split(eom).alpha - alpha))


def test_rotating_frame_has_coriolis_T1_and_centrifugal_T0():
    # x' = (X' - w Y, Y' + w X) rotated by w t, so |x'|^2 = X'^2 + Y'^2 + 2 w (X Y' - Y X') + w^2 (X^2 + Y^2).
    eom = derive(rotating_frame_particle())
    X, Y, Xd, Yd = sp.symbols("X Y X_dot Y_dot")
    m, w, k = sp.symbols("m w k")
    split = kinetic_split(eom)
    assert is_zero(split.beta[0] + m * w * Y) and is_zero(split.beta[1] - m * w * X)
    assert is_zero(split.gamma - m * w**2 * (X**2 + Y**2) / 2)
    assert is_zero(split.T2 - m * (Xd**2 + Yd**2) / 2)
    assert is_zero(split.T1 - m * w * (X * Yd - Y * Xd))
    assert not split.natural and not is_natural(eom.model)
    check = check_jacobi(eom)
    # h keeps T2 and T0 but not the gyroscopic T1 (eq. 3.7).
    assert check.equals_T2_minus_T0_plus_V and not check.equals_T_plus_V and check.conserved


NATURAL_CASES = {
    "pendulum": (systems.pendulum, True), "double_pendulum": (systems.double_pendulum, True),
    "central": (systems.central_potential, True), "damped_pendulum": (damped_pendulum, True),
    "charge": (charged_particle, True), "charge_polar": (lambda: charged_particle(polar=True), True),
    "hoop": (spinning_hoop, False), "rotating_frame": (rotating_frame_particle, False),
    "driven_support": (driven_support_pendulum, False), "rotor_planar": (lambda: spun_rotor("planar"), False),
    "rotor_rigid": (lambda: spun_rotor("rigid"), False), "direct_T": (moving_frame_direct, False),
}


@pytest.mark.parametrize("make,natural", NATURAL_CASES.values(), ids=NATURAL_CASES.keys())
def test_natural_criteria_agree(make, natural):
    # Remark after eq. 2.2: dx/dt = 0 for every body  <=>  T1 = T0 = 0.
    model = make()
    assert is_natural(model) is natural
    assert kinetic_split(derive(model)).natural is natural


def test_kinetic_energy_not_quadratic_is_rejected():
    # Free relativistic particle (c = 1): L = -m sqrt(1 - x'^2) is not of the form of eq. 2.2.
    model = Model("relativistic")
    x, = model.coordinates("x")
    m, k = model.parameters(m=1.0, k=1.0)
    model.kinetic_energy(-m * sp.sqrt(1 - model.dot(x) ** 2))
    model.potential_energy(k * x**2 / 2)
    eom = derive(model)
    with pytest.raises(DerivationError, match="not quadratic.*x_dot"):
        kinetic_split(eom)


def test_is_zero_needs_trig_identities_and_rejects_nonzero():
    x, y = sp.symbols("x y")
    assert is_zero(sp.sin(x) ** 2 + sp.cos(x) ** 2 - 1)
    assert is_zero(sp.cos(x - y) - sp.cos(x) * sp.cos(y) - sp.sin(x) * sp.sin(y))
    assert is_zero(sp.Matrix([0, (x**2 - 1) / (x - 1) - x - 1]))
    assert not is_zero(sp.sin(x) - x)
    assert not is_zero(sp.Matrix([0, x * y]))


# ---------------------------------------------------------------------------- eq. 3.6
def test_explicit_time_lagrangian_h_not_conserved_but_rate_is_minus_dL_dt():
    eom = derive(driven_support_pendulum())
    check = check_jacobi(eom)
    assert check.lagrangian and check.explicit_time and not check.conserved
    assert check.holds and check.matches_derivation
    th, thd, t = sp.symbols("theta theta_dot t")
    l, m, A, W = sp.symbols("l m A W")
    # L contains m/2 (-A W sin(W t) + l cos(theta) theta')^2: -dL/dt by hand.
    xdot = -A * W * sp.sin(W * t) + l * sp.cos(th) * thd
    assert is_zero(check.expected + sp.diff(m / 2 * xdot**2, t))


def test_check_jacobi_detects_wrong_equations():
    # Flip the sign of gravity in F only: h no longer follows eq. 3.6 along these "equations".
    eom = derive(systems.double_pendulum())
    g = symengine.Symbol("g")
    bad = dataclasses.replace(eom, F_se=[f.subs({g: -g}) for f in eom.F_se], _cache={})
    assert not check_jacobi(bad).holds
    assert check_jacobi(eom).holds


def test_damped_systems_dhdt_is_minus_two_D_symbolically():
    # D homogeneous quadratic in q': sum q' dD/dq' = 2 D (Euler), so dh/dt = -2D without Q*.
    pend = derive(damped_pendulum())
    assert is_zero(pend.dhdt + 2 * pend.D)
    assert check_jacobi(pend).holds and not check_jacobi(pend).conserved
    osc = derive(systems.damped_driven_oscillator())
    x, xd, t = sp.symbols("x x_dot t")
    F0, w = sp.symbols("F0 w")
    # With the drive Q* = F0 cos(w t), its power x' Q* is added (eq. 3.16); F0 = 0 leaves -2D.
    assert is_zero(osc.dhdt + 2 * osc.D - xd * F0 * sp.cos(w * t))
    assert is_zero((osc.dhdt + 2 * osc.D).subs(F0, 0))
    check = check_jacobi(osc)
    assert check.holds and check.matches_derivation and not check.lagrangian


# ---------------------------------------------------------------------------- simulations
def test_spinning_hoop_conserves_h_not_T_plus_V():
    cm = lcg.compile_model(spinning_hoop(), outputs=["energy", "jacobi_h"])
    # theta* = arccos(g/(a w^2)) ~ 1.17 is the stable equilibrium for w = 5: small-oscillation
    # frequency w sin(theta*) ~ 4.6, period ~ 1.4; 60 time units are ~40 periods.
    t = np.linspace(0, 60, 6001)
    res = cm.simulate(t, q0=[0.3], v0=[0.0], rtol=1e-11, atol=1e-12)
    swings = np.count_nonzero(np.diff(np.sign(res["theta_dot"])) != 0) // 2
    h_drift = res.drift("jacobi_h")
    E = res["energy"]
    E_var = (E.max() - E.min()) / abs(E).max()
    print(f"hoop: {swings} swings, h drift {h_drift:.2e}, T+V relative variation {E_var:.3f}")
    assert swings >= 30
    assert h_drift < 1e-8
    assert E_var > 1e-2
    # h output against the hand formula T2 - T0 + V on the trajectory.
    th, thd = res["theta"], res["theta_dot"]
    h_hand = thd**2 / 2 - 25.0 * np.sin(th) ** 2 / 2 - 9.81 * np.cos(th)
    assert np.max(np.abs(res["jacobi_h"] - h_hand)) < 1e-12 * np.max(np.abs(h_hand))


@pytest.mark.parametrize("name", ["oscillator", "damped_pendulum"])
def test_damped_energy_decays_at_rate_minus_two_D(name):
    outputs = ["energy", "jacobi_h", "dh_dt", "dissipation"]
    if name == "oscillator":  # m x'' + c x' + k x = 0 (drive switched off at run time)
        cm = lcg.compile_model(systems.damped_driven_oscillator(), outputs=outputs)
        params, q0, h_min = {"F0": 0.0}, [1.0], 0.0
    else:  # pendulum with a damper on the bob; h >= -m g l
        cm = lcg.compile_model(damped_pendulum(), outputs=outputs)
        params, q0, h_min = {}, [1.2], -9.81
    t = np.linspace(0, 10, 100_001)
    res = cm.simulate(t, q0=q0, params=params, rtol=1e-11, atol=1e-13)
    h, D, rate = res["jacobi_h"], res["dissipation"], res["dh_dt"]
    assert np.max(np.abs(h - res["energy"])) < 1e-13 * np.max(np.abs(h))  # natural: h = T + V
    assert h[-1] - h_min < 0.5 * (h[0] - h_min)  # a good part of the energy is gone
    scale = np.max(np.abs(rate))
    # The emitted rate is -2D to round-off.
    rate_err = np.max(np.abs(rate + 2 * D)) / scale
    # Energy balance: h(t) - h(0) = -2 int_0^t D, trapezoid rule on the fine grid (error ~ dt^2).
    balance = np.max(np.abs((h - h[0]) + 2 * cumulative_trapezoid(D, t, initial=0.0)))
    # Rate by central differences (error ~ dt^2).
    fd = np.max(np.abs(np.gradient(h, t)[1:-1] - rate[1:-1])) / scale
    print(f"{name}: h {h[0]:.4f} -> {h[-1]:.4f}; |dh_dt + 2D|/max {rate_err:.1e}; "
          f"|h - h0 + 2 int D| {balance:.1e}; |fd - dh_dt|/max {fd:.1e}")
    assert rate_err < 1e-14
    assert balance < 1e-6
    assert fd < 1e-6
