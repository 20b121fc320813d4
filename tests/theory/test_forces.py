"""Generalized forces (eqs. 2.6, 2.7, 3.4, 3.14) against hand derivations, and a charge in
uniform E and B fields: Lorentz force, cyclotron motion, E x B drift, conserved h."""

import math

import numpy as np
import pytest
import sympy as sp

import lagcodegen as lcg
from lagcodegen import ModelError, derive, systems
from lagcodegen.theory.energy import check_jacobi, is_zero
from lagcodegen.theory.forces import (accelerations, dissipative_force, generalized_force_from_cartesian,
                               generalized_force_from_generalized_potential, generalized_force_from_potential,
                               total_time_derivative)
from lagcodegen.model.systems import charged_particle

t = sp.Symbol("t")
e, B, E, m = sp.symbols("e B Ex m")


def lorentz(v, E_vec, B_vec):
    """e (E + v x B), 3-D."""
    return e * (sp.Matrix(E_vec) + sp.Matrix(v).cross(sp.Matrix(B_vec)))


# ---------------------------------------------------------------------------- eqs. 2.6, 2.7, 3.14
def test_cartesian_force_on_double_pendulum_bob():
    # Horizontal force F on bob 2 at x2 = l1 sin(theta1) + l2 sin(theta2): Q_i = F l_i cos(theta_i).
    t1, t2 = sp.symbols("theta1 theta2")
    l1, l2, F = sp.symbols("l1 l2 F")
    x2 = [l1 * sp.sin(t1) + l2 * sp.sin(t2), -l1 * sp.cos(t1) - l2 * sp.cos(t2)]
    Q = generalized_force_from_cartesian([F, 0], x2, [t1, t2])
    assert is_zero(Q - sp.Matrix([F * l1 * sp.cos(t1), F * l2 * sp.cos(t2)]))
    # The derivation maps Model.force the same way.
    model = systems.double_pendulum()
    model.parameter("F", 0.2)
    model.force("bob2", (F, 0))
    assert is_zero(derive(model).Q - Q)


def test_potential_force_equals_mapped_cartesian_gradient():
    # Central potential V = -k/rho: Cartesian F = -grad V = -k (x, y)/rho^3; in polar coordinates
    # eq. 2.6 and eq. 2.7 must both give Q = (-k/r^2, 0).
    r, phi, k = sp.symbols("r phi k", positive=True)
    X, Y = sp.symbols("X Y")
    V_cart = -k / sp.sqrt(X**2 + Y**2)
    F_cart = [-sp.diff(V_cart, X), -sp.diff(V_cart, Y)]
    pos = {X: r * sp.cos(phi), Y: r * sp.sin(phi)}
    x = [pos[X], pos[Y]]
    Q26 = generalized_force_from_cartesian([f.subs(pos) for f in F_cart], x, [r, phi])
    Q27 = generalized_force_from_potential(V_cart.subs(pos), [r, phi])
    assert is_zero(sp.simplify(Q26 - sp.Matrix([-k / r**2, 0])))
    assert is_zero(sp.simplify(Q27 - sp.Matrix([-k / r**2, 0])))
    # Pendulum gravity: Q = -m g l sin(theta).
    th, l, g = sp.symbols("theta l g")
    assert is_zero(generalized_force_from_potential(-m * g * l * sp.cos(th), [th])[0] + m * g * l * sp.sin(th))


def test_generalized_potential_force_contains_accelerations():
    # U = k x x'^2: dU/dx' = 2 k x x', d/dt of it = 2 k x'^2 + 2 k x x'', dU/dx = k x'^2,
    # so Q = k x'^2 + 2 k x x'' (eq. 3.4).
    x, xd, k = sp.symbols("x x_dot k")
    xdd, = accelerations([x])
    assert xdd.name == "x_ddot"
    Q = generalized_force_from_generalized_potential(k * x * xd**2, [x], [xd], t)
    assert is_zero(Q[0] - (k * xd**2 + 2 * k * x * xdd))
    # A velocity-independent U reduces to eq. 2.7.
    assert is_zero(generalized_force_from_generalized_potential(k * x**4, [x], [xd], t)
                   - generalized_force_from_potential(k * x**4, [x]))


def test_dissipative_force_equals_mapped_viscous_force():
    # Eq. 3.14: the Cartesian friction F = -c v at bob 2, mapped by eq. 2.6, is -dD/dq' with
    # D = c/2 |v|^2 from Model.damper (dx'/dq' = dx/dq).
    model = systems.double_pendulum()
    c, = model.parameters(c=0.3)
    model.damper("bob2", c)
    eom = derive(model)
    x2 = model.points["bob2"].position
    v2 = x2.applyfunc(model.time_derivative)
    Q_cart = generalized_force_from_cartesian(-c * v2, x2, model.coords)
    assert is_zero(dissipative_force(eom.D, model.speeds) - Q_cart)
    # Pendulum by hand: D = c l^2 theta'^2 / 2, Q = -c l^2 theta'.
    thd, l = sp.symbols("theta_dot l")
    assert is_zero(dissipative_force(c * l**2 * thd**2 / 2, [thd])[0] + c * l**2 * thd)


def test_bad_lengths():
    x, y = sp.symbols("x y")
    with pytest.raises(ModelError, match="F has 1 components, x has 2"):
        generalized_force_from_cartesian([1], [x, y], [x])
    with pytest.raises(ModelError, match="different lengths"):
        total_time_derivative(x, [x, y], [sp.Symbol("x_dot")], t)


# ---------------------------------------------------------------------------- charge: symbolic
@pytest.mark.parametrize("with_E", [False, True])
def test_lorentz_force_from_generalized_potential_cartesian(with_E):
    # U = e (phi - v . A), phi = -E x, A = (-B y/2, B x/2, 0): B = curl A = (0, 0, B), E = -grad phi.
    x, y, xd, yd = sp.symbols("x y x_dot y_dot")
    Ex = E if with_E else 0
    U = e * (-Ex * x - (xd * (-B * y / 2) + yd * (B * x / 2)))
    Q = generalized_force_from_generalized_potential(U, [x, y], [xd, yd], t)
    F = lorentz([xd, yd, 0], [Ex, 0, 0], [0, 0, B])
    assert F[2] == 0
    # Cartesian coordinates: eq. 2.6 is the identity map.
    assert is_zero(Q - generalized_force_from_cartesian(F[:2], [x, y], [x, y]))
    assert is_zero(Q - sp.Matrix([e * Ex + e * B * yd, -e * B * xd]))
    # The model builder states the same U.
    model = charged_particle()
    if not with_E:
        model.generalized_potential_terms[0] = ("electromagnetic",
                                                model.generalized_potential_terms[0][1].subs(E, 0))
    assert is_zero(model.generalized_potential_terms[0][1] - U)


@pytest.mark.parametrize("with_E", [False, True])
def test_lorentz_force_from_generalized_potential_polar(with_E):
    # x = r cos(theta), y = r sin(theta): v . A = B/2 (x y' - y x') = B r^2 theta'/2, so by hand
    # U = -e E r cos(theta) - e B r^2 theta'/2. Eq. 3.4 on U must equal the Lorentz force mapped by eq. 2.6.
    r, th, rd, thd = sp.symbols("r theta r_dot theta_dot")
    Ex = E if with_E else 0
    U = -e * Ex * r * sp.cos(th) - e * B * r**2 * thd / 2
    model = charged_particle(polar=True)
    assert is_zero(model.generalized_potential_terms[0][1].subs(E, Ex) - U)
    Q = generalized_force_from_generalized_potential(U, [r, th], [rd, thd], t)
    x = [r * sp.cos(th), r * sp.sin(th)]
    v = [total_time_derivative(c, [r, th], [rd, thd], t) for c in x] + [0]
    F = lorentz(v, [Ex, 0, 0], [0, 0, B])
    Q26 = generalized_force_from_cartesian(F[:2], x, [r, th])
    assert is_zero(Q - Q26)
    # By hand: v x B = B (v_y, -v_x); dx/dr = (cos, sin), dx/dtheta = r (-sin, cos), and
    # v_y cos - v_x sin = r theta', v_x cos + v_y sin = r', so
    # Q_r = e E cos(theta) + e B r theta', Q_theta = -e E r sin(theta) - e B r r'.
    assert is_zero(Q - sp.Matrix([e * Ex * sp.cos(th) + e * B * r * thd, -e * Ex * r * sp.sin(th) - e * B * r * rd]))


def test_gauge_change_leaves_the_force_unchanged():
    # Landau gauge A' = (-B y, 0, 0) = A + grad(chi), chi = -B x y/2: same B, same Q.
    x, y, xd, yd = sp.symbols("x y x_dot y_dot")
    U_sym = -e * (xd * (-B * y / 2) + yd * (B * x / 2))
    U_landau = -e * (xd * (-B * y))
    q, qd = [x, y], [xd, yd]
    assert is_zero(generalized_force_from_generalized_potential(U_sym, q, qd, t)
                   - generalized_force_from_generalized_potential(U_landau, q, qd, t))
    assert not is_zero(U_sym - U_landau)


def test_derived_equations_are_lagrange_with_the_generalized_force():
    # Eq. 3.3 with L = T - U is eq. 3.2 with Q from eq. 3.4: d/dt(dT/dq') - dT/dq = Q_U.
    eom = derive(charged_particle(polar=True))
    T = eom.T
    U = eom.model.generalized_potential_terms[0][1]
    Q = generalized_force_from_generalized_potential(U, eom.q, eom.qd, t)
    lhs = sp.Matrix([total_time_derivative(sp.diff(T, v), eom.q, eom.qd, t) - sp.diff(T, q)
                     for q, v in zip(eom.q, eom.qd)])
    assert is_zero(eom.equations() - (lhs - Q))


def test_charge_h_is_kinetic_plus_electric_energy():
    # U is linear in v: h = T + e phi (eq. 3.5), conserved since L has no explicit t (eq. 3.6).
    eom = derive(charged_particle())
    x = sp.Symbol("x")
    check = check_jacobi(eom)
    assert check.lagrangian and check.conserved and check.holds
    assert is_zero(eom.h - (eom.T - e * E * x))


# ---------------------------------------------------------------------------- charge: simulation
M_, E_CH, B_ = 2.0, 0.5, 3.0
W_C = E_CH * B_ / M_  # cyclotron frequency e B / m = 0.75
T_C = 2 * math.pi / W_C


@pytest.fixture(scope="module")
def charge():
    return lcg.compile_model(charged_particle(), outputs=["jacobi_h"])


def run(charge, Ex, periods, per_period=200, v0=(1.2, 0.4)):
    t = np.linspace(0, periods * T_C, periods * per_period + 1)
    res = charge.simulate(t, q0=[0.3, -0.2], v0=list(v0), params=dict(m=M_, e=E_CH, B=B_, Ex=Ex),
                          rtol=1e-12, atol=1e-13)
    return res, per_period


def test_cyclotron_frequency_and_radius(charge):
    res, k = run(charge, 0.0, periods=10)
    x, y, vx, vy = res["x"], res["y"], res["x_dot"], res["y_dot"]
    # Back at the start after every period 2 pi / w_c.
    ret = np.max(np.hypot(x[::k] - x[0], y[::k] - y[0]))
    # The velocity turns at -w_c (clockwise for e B > 0: m v' = e v x B, B along +z).
    angle = np.unwrap(np.arctan2(vy, vx))
    turn = np.max(np.abs(angle - angle[0] + W_C * res.t))
    # Least-squares circle through the path: x^2 + y^2 + a x + b y + c = 0.
    A = np.column_stack([x, y, np.ones_like(x)])
    a, b, c = np.linalg.lstsq(A, -(x**2 + y**2), rcond=None)[0]
    cx, cy = -a / 2, -b / 2
    radius = math.sqrt(cx**2 + cy**2 - c)
    speed = math.hypot(1.2, 0.4)
    r_expected = M_ * speed / (E_CH * B_)
    spread = np.max(np.abs(np.hypot(x - cx, y - cy) - r_expected))
    print(f"cyclotron: return error {ret:.1e}, phase error {turn:.1e}, radius {radius:.12f} "
          f"(m v/(e B) = {r_expected:.12f}), max |dist - r| {spread:.1e}")
    assert ret < 1e-8
    assert turn < 1e-8
    assert abs(radius - r_expected) < 1e-9
    assert spread < 1e-8
    assert np.max(np.abs(np.hypot(vx, vy) - speed)) < 1e-9  # the magnetic force does no work


def test_e_cross_b_drift(charge):
    # In a frame moving at u, E' = E + u x B; E' = 0 for u x B = -E. With u = (0, u_y, 0),
    # B = (0, 0, B): u x B = (u_y B, 0, 0) = (-E, 0, 0), so u_y = -E/B: drift E/B along -y.
    # Seen from that frame the motion is a circle, so r(t + T_c) - r(t) = u T_c exactly.
    Ex, periods = 0.6, 6
    res, k = run(charge, Ex, periods)
    x, y = res["x"], res["y"]
    vd_x = (x[k::k] - x[0]) / res.t[k::k]
    vd_y = (y[k::k] - y[0]) / res.t[k::k]
    err = max(np.max(np.abs(vd_x)), np.max(np.abs(vd_y + Ex / B_)))
    print(f"E x B: drift per period {vd_y[-1]:.12f} (expected {-Ex / B_}), error {err:.1e}")
    assert err < 1e-9
    # Not a pure circle: the displacement grows by |u| T_c each period.
    assert abs(y[-1] - y[0] + Ex / B_ * periods * T_C) < 1e-7


@pytest.mark.parametrize("Ex", [0.0, 0.6])
def test_charge_h_conserved(charge, Ex):
    # h = m/2 |v|^2 + e phi with phi = -E x: the magnetic field does no work.
    res, _ = run(charge, Ex, periods=6)
    h = res["jacobi_h"]
    h_hand = M_ / 2 * (res["x_dot"] ** 2 + res["y_dot"] ** 2) - E_CH * Ex * res["x"]
    drift = res.drift("jacobi_h")
    print(f"charge (E = {Ex}): h drift {drift:.1e}")
    assert np.max(np.abs(h - h_hand)) < 1e-13
    assert drift < 1e-9
