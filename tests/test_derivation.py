"""Derived equations against hand derivations (textbook forms), and bad models."""

import pytest
import sympy as sp

import lagcodegen as lcg
from lagcodegen import Model, ModelError, derive, systems


def is_zero(expr) -> bool:
    return sp.simplify(sp.expand_trig(sp.simplify(expr))) == 0


def residual(eom):
    """M q'' - F as a sympy column."""
    return eom.equations()


def test_pendulum_equation_is_textbook():
    eom = derive(systems.pendulum())
    th, thd = sp.symbols("theta theta_dot")
    l, g, m = sp.symbols("l g m")
    assert is_zero(eom.M[0, 0] - m * l**2)
    assert is_zero(eom.F[0] + m * g * l * sp.sin(th))
    assert is_zero(eom.momenta[0] - m * l**2 * thd)  # eq. 2.3
    assert is_zero(eom.T - m * l**2 * thd**2 / 2)
    assert is_zero(eom.V + m * g * l * sp.cos(th))


def test_double_pendulum_equations_are_textbook():
    eom = derive(systems.double_pendulum())
    t1, t2, w1, w2, a1, a2 = sp.symbols("theta1 theta2 theta1_dot theta2_dot theta1_ddot theta2_ddot")
    l1, l2, m1, m2, g = sp.symbols("l1 l2 m1 m2 g")
    # Hand derivation (e.g. Goldstein / any mechanics text):
    eq1 = ((m1 + m2) * l1**2 * a1 + m2 * l1 * l2 * a2 * sp.cos(t1 - t2)
           + m2 * l1 * l2 * w2**2 * sp.sin(t1 - t2) + (m1 + m2) * g * l1 * sp.sin(t1))
    eq2 = (m2 * l2**2 * a2 + m2 * l1 * l2 * a1 * sp.cos(t1 - t2)
           - m2 * l1 * l2 * w1**2 * sp.sin(t1 - t2) + m2 * g * l2 * sp.sin(t2))
    r = residual(eom)
    assert is_zero(r[0] - eq1)
    assert is_zero(r[1] - eq2)
    assert eom.M.is_symmetric()


def test_central_potential_polar_equations():
    eom = derive(systems.central_potential())
    r, phi, rd, phd, rdd, phdd = sp.symbols("r phi r_dot phi_dot r_ddot phi_ddot")
    m, k = sp.symbols("m k")
    res = residual(eom)
    assert is_zero(res[0] - (m * rdd - m * r * phd**2 + k / r**2))
    assert is_zero(res[1] - (m * r**2 * phdd + 2 * m * r * rd * phd))
    assert is_zero(eom.momenta[1] - m * r**2 * phd)  # angular momentum


def test_damped_driven_oscillator_equation():
    model = systems.damped_driven_oscillator()
    eom = derive(model)
    x, xd, xdd, t = sp.symbols("x x_dot x_ddot t")
    m, k, c, F0, w = sp.symbols("m k c F0 w")
    assert is_zero(residual(eom)[0] - (m * xdd + c * xd + k * x - F0 * sp.cos(w * t)))
    assert is_zero(eom.D - c * xd**2 / 2)  # eq. 3.15


def test_cartesian_force_maps_by_eq_2_6():
    # A horizontal force F on the bob of a pendulum: Q = F dx/dtheta = F l cos(theta).
    model = systems.pendulum()
    F, = model.parameters(F=0.3)
    model.force("bob", (F, 0))
    eom = derive(model)
    th = sp.Symbol("theta")
    l, g, m = sp.symbols("l g m")
    assert is_zero(eom.Q[0] - F * l * sp.cos(th))
    assert is_zero(eom.F[0] - (-m * g * l * sp.sin(th) + F * l * sp.cos(th)))


def test_cartesian_damper_equals_generalized_dissipation():
    # Damper on the bob: D = c/2 |v|^2 = c/2 l^2 theta'^2.
    model = systems.pendulum()
    c, = model.parameters(c=0.1)
    model.damper("bob", c)
    eom = derive(model)
    th, thd = sp.symbols("theta theta_dot")
    l, g, m = sp.symbols("l g m")
    assert is_zero(eom.D - c * l**2 * thd**2 / 2)
    assert is_zero(eom.F[0] - (-m * g * l * sp.sin(th) - c * l**2 * thd))


def test_compound_pendulum_planar_body():
    # Uniform bar of length 2a pivoting at one end: (I_G + m a^2) theta'' = -m g a sin(theta).
    model = Model("bar")
    th, = model.coordinates("theta")
    m, a, g = model.parameters(m=2.0, a=0.5, g=9.81)
    IG = m * (2 * a) ** 2 / 12
    model.planar_body("bar", m, IG, (a * sp.sin(th), -a * sp.cos(th)), th)
    model.gravity(g)
    eom = derive(model)
    assert is_zero(eom.M[0, 0] - (IG + m * a**2))
    assert is_zero(eom.F[0] + m * g * a * sp.sin(th))


def euler_zxz(phi, theta, psi):
    def Rz(a):
        return sp.Matrix([[sp.cos(a), -sp.sin(a), 0], [sp.sin(a), sp.cos(a), 0], [0, 0, 1]])

    def Rx(a):
        return sp.Matrix([[1, 0, 0], [0, sp.cos(a), -sp.sin(a)], [0, sp.sin(a), sp.cos(a)]])
    return Rz(phi) * Rx(theta) * Rz(psi)


def test_heavy_symmetric_top_kinetic_energy():
    # Lagrange top, Euler angles (z-x-z), fixed tip, centre of mass at distance h on the axis.
    # Textbook: T = A/2 (theta'^2 + phi'^2 sin^2 theta) + C/2 (psi' + phi' cos theta)^2,
    # V = m g h cos(theta), with A the moment about the tip.
    model = Model("top")
    phi, theta, psi = model.coordinates("phi theta psi")
    m, h, A0, C, g = model.parameters(m=1.0, h=0.3, A0=0.2, C=0.1, g=9.81)
    R = euler_zxz(phi, theta, psi)
    position = R * sp.Matrix([0, 0, h])
    model.rigid_body("top", m, (A0, A0, C), position, R)
    model.gravity(g)
    eom = derive(model)
    phd, thd, psd = sp.symbols("phi_dot theta_dot psi_dot")
    A = A0 + m * h**2
    T = A / 2 * (thd**2 + phd**2 * sp.sin(theta) ** 2) + C / 2 * (psd + phd * sp.cos(theta)) ** 2
    assert is_zero(eom.T - T)
    assert is_zero(eom.V - m * g * h * sp.cos(theta))


def test_direct_kinetic_energy_equals_bodies():
    direct = Model("direct")
    th, = direct.coordinates("theta")
    l, g, m = direct.parameters(l=1.0, g=9.81, m=1.0)
    direct.kinetic_energy(m * l**2 * direct.dot(th) ** 2 / 2)
    direct.potential_energy(-m * g * l * sp.cos(th))
    a, b = derive(direct), derive(systems.pendulum())
    assert is_zero(a.M[0, 0] - b.M[0, 0]) and is_zero(a.F[0] - b.F[0])


def test_time_dependent_input_torque():
    model = systems.pendulum()
    A, w = model.parameters(A=0.5, w=2.0)
    th = model.coords[0]
    model.generalized_force(th, A * sp.sin(w * model.t))
    eom = derive(model)
    assert is_zero(eom.F[0] - (-sp.Symbol("m") * sp.Symbol("g") * sp.Symbol("l") * sp.sin(th)
                               + A * sp.sin(w * model.t)))


def test_twenty_link_pendulum_derives_with_symmetric_mass_matrix():
    eom = derive(systems.n_link_pendulum(20))
    assert eom.n == 20
    assert all(eom.M_se[i][j] == eom.M_se[j][i] for i in range(20) for j in range(20))
    print(f"20-link derivation: {eom.derivation_seconds:.3f} s")


# ---------------------------------------------------------------------------- bad input
def test_coordinate_that_appears_nowhere():
    model = systems.pendulum()
    model.coordinate("ghost")
    with pytest.raises(ModelError, match="ghost.*appears nowhere"):
        derive(model)


def test_unknown_symbol_in_position():
    model = Model("bad")
    x, = model.coordinates("x")
    model.particle("p", 1, (x * sp.Symbol("zeta"), 0))
    with pytest.raises(ModelError, match="position of point 'p'.*zeta"):
        derive(model)


def test_velocity_in_potential_rejected():
    model = systems.pendulum()
    model.potential_energy(model.speeds[0] ** 2)
    with pytest.raises(ModelError, match="velocity not allowed.*theta_dot"):
        derive(model)


@pytest.mark.parametrize("value", [float("nan"), float("inf"), "abc"])
def test_non_finite_parameter(value):
    model = Model("p")
    with pytest.raises(ModelError, match="parameter 'k'"):
        model.parameter("k", value)


def test_bad_names():
    model = Model("m")
    with pytest.raises(ModelError, match="not a valid identifier"):
        model.coordinates(["1x"])
    model.coordinates("x")
    with pytest.raises(ModelError, match="declared twice"):
        model.parameter("x", 1.0)
    with pytest.raises(ModelError, match="reserved"):
        model.parameter("t", 1.0)


def test_no_kinetic_energy():
    model = Model("m")
    x, = model.coordinates("x")
    model.potential_energy(x**2)
    with pytest.raises(ModelError, match="no kinetic energy"):
        derive(model)


def test_velocity_free_coordinate_is_a_derivation_error():
    model = Model("m")
    x, y = model.coordinates("x y")
    model.kinetic_energy(model.dot(x) ** 2 / 2)
    model.potential_energy(y**2 + x**2)
    with pytest.raises(lcg.DerivationError, match="y_dot"):
        derive(model)


# ---------------------------------------------------------------------------- point masses by Jacobians
def _mixed_model():
    """Bodies moved by many coordinates (point-mass terms by velocity Jacobians) beside every other
    kind of term: a driven support (x depends on t), a 3-D particle, a planar body, a rigid body, a
    mass depending on a coordinate (differentiated symbolically), T given directly, a spring,
    dissipation and a generalized force."""
    m = Model("mixed")
    q = m.coordinates("a b c d e")
    g, l, mass, k, A, w = m.parameters(g=9.81, l=0.7, m=1.3, k=2.0, A=0.3, w=1.7)
    t = m.t
    x = A * sp.sin(w * t)
    y = sp.Integer(0)
    for i, qi in enumerate(q[:4], start=1):
        x, y = x + l * sp.sin(qi), y - l * sp.cos(qi)
        m.particle(f"bob{i}", mass * i, (x, y))
    m.particle("far", mass, (x + q[4], y * sp.cos(q[4]), l * sp.sin(q[0] + q[4])))
    m.planar_body("plate", 2 * mass, mass * l**2 / 3, (x - y, y + q[4]), q[1] + q[3] + q[4])
    m.rigid_body("disc", mass, (1, 2, 3), (q[0] + q[1], q[2] + q[3], q[4] * q[0]),
                 sp.rot_axis3(q[4]) * sp.rot_axis1(q[0]))
    m.particle("heavy", mass * (2 + sp.cos(q[2])), (x * q[2], y + q[1], q[3] - q[4]))
    m.kinetic_energy(mass * m.speeds[4] ** 2 * (1 + q[0] ** 2) / 2, label="extra")
    m.gravity(g)
    m.spring("bob4", (0, 0), k)
    m.damper("bob2", k / 10)
    m.generalized_force(q[2], A * sp.cos(w * t) * m.speeds[2], label="drive")
    return m


def test_point_masses_by_jacobians_give_the_symbolic_equations(monkeypatch):
    """derivation.SPLIT_POINT_MASSES: the same M, F and momenta as differentiating all of L, on
    random values (to rounding), also with time-dependent positions and every other kind of term."""
    import numpy as np
    import symengine as se
    from lagcodegen import derivation

    model = _mixed_model()
    eoms = {}
    for split in (False, True):
        monkeypatch.setattr(derivation, "SPLIT_POINT_MASSES", split)
        eoms[split] = derive(model)
    syms = ([se.Symbol(s.name) for s in model.coords] + [se.Symbol(s.name) for s in model.speeds]
            + [se.Symbol(s.name) for s in model.params] + [se.Symbol("t")])
    rng = np.random.default_rng(7)
    for _ in range(10):
        vals = rng.uniform(-2, 2, len(syms))
        got = {}
        for split, eom in eoms.items():
            exprs = [x for r in eom.M_se for x in r] + list(eom.F_se) + list(eom.p_se) + [eom.h_se, eom.T_se]
            got[split] = np.array(se.Lambdify(syms, exprs)(vals), dtype=float).ravel()
        assert np.allclose(got[True], got[False], rtol=1e-12, atol=1e-12 * np.max(np.abs(got[False])))
    assert all(eoms[True].M_se[i][j] == eoms[True].M_se[j][i] for i in range(5) for j in range(5))
    assert list(eoms[True].F_se) != list(eoms[False].F_se)  # the split path did run


def test_chain_forces_grow_like_the_square_of_the_links():
    """The terms of dT/dq and d/dt dT/dq' that cancel only after expansion are never formed: the
    chain's F has O(n^2) operations (30 links: 178 000 before, 11 600 with point-mass Jacobians)."""
    import symengine as se

    ops = {n: se.count_ops(*derive(systems.n_link_pendulum(n)).F_se) for n in (10, 20)}
    assert ops[20] < 5 * ops[10]
    assert ops[20] < 10 * 20 ** 2 * 2
