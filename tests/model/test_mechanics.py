"""Models imported from sympy.physics.mechanics against lagcodegen's own models and LagrangesMethod."""

import math

import numpy as np
import pytest
import sympy as sp
from sympy.physics.mechanics import (LagrangesMethod, Lagrangian, Particle, Point, ReferenceFrame,
                                     RigidBody, Torque, dynamicsymbols, inertia)

import lagcodegen as lcg
from lagcodegen import Model, ModelError, systems
from lagcodegen.model.mechanics import from_bodies, from_lagrangian

DP_VALUES = {"l1": 1.0, "l2": 1.0, "m1": 1.0, "m2": 1.0, "g": 9.81}


def assert_same(a, b):
    """Symbolic equality (sympy.simplify of the difference is zero) of matrices or scalars."""
    diff = sp.simplify(sp.sympify(a) - sp.sympify(b))
    if isinstance(diff, sp.MatrixBase):
        assert diff == sp.zeros(*diff.shape), diff
    else:
        assert diff == 0, diff


def plain(expr, coords):
    """Independently of lagcodegen.mechanics: q(t) -> q, q'(t) -> q_dot, q''(t) -> q_ddot."""
    t = dynamicsymbols._t
    repl = {}
    for q in coords:
        name = q.func.__name__
        repl[q.diff(t, 2)] = sp.Symbol(f"{name}_ddot")
        repl[q.diff(t)] = sp.Symbol(f"{name}_dot")
        repl[q] = sp.Symbol(name)
    out = sp.sympify(expr).xreplace(repl)
    # assumptions (positive=True) dropped: plain symbols of the same names
    return out.xreplace({s: sp.Symbol(s.name) for s in out.free_symbols})


@pytest.fixture
def double_pendulum_me():
    """The planar double pendulum in sympy.physics.mechanics: two Particles, angles from the vertical."""
    th1, th2 = dynamicsymbols("theta1 theta2")
    l1, l2, m1, m2, g = sp.symbols("l1 l2 m1 m2 g", positive=True)
    N = ReferenceFrame("N")
    A = N.orientnew("A", "Axis", [th1, N.z])
    B = N.orientnew("B", "Axis", [th2, N.z])
    O = Point("O")
    O.set_vel(N, 0)
    P1 = O.locatenew("P1", -l1 * A.y)
    P1.v2pt_theory(O, N, A)
    P2 = P1.locatenew("P2", -l2 * B.y)
    P2.v2pt_theory(P1, N, B)
    bob1, bob2 = Particle("bob1", P1, m1), Particle("bob2", P2, m2)
    bob1.potential_energy = m1 * g * P1.pos_from(O).dot(N.y)
    bob2.potential_energy = m2 * g * P2.pos_from(O).dot(N.y)
    return {"N": N, "O": O, "bodies": [bob1, bob2], "q": [th1, th2]}


@pytest.fixture(scope="module")
def reference():
    return lcg.derive(systems.double_pendulum())


# ------------------------------------------------------------------ (a), (b), (c)
def test_from_bodies_double_pendulum_matches_lagcodegen(double_pendulum_me, reference):
    s = double_pendulum_me
    model = from_bodies(s["N"], s["bodies"], s["q"], parameters=DP_VALUES, name="dp_bodies")
    assert [c.name for c in model.coords] == ["theta1", "theta2"]
    assert [v.name for v in model.speeds] == ["theta1_dot", "theta2_dot"]
    assert model.params == {sp.Symbol(k): v for k, v in DP_VALUES.items()}
    assert [label for label, _ in model.kinetic_terms] == ["T[bob1]", "T[bob2]"]
    eom = lcg.derive(model)
    assert_same(eom.M, reference.M)
    assert_same(eom.F, reference.F)
    assert_same(eom.T, reference.T)  # T and V kept apart
    assert_same(eom.V, reference.V)


def test_from_lagrangian_double_pendulum_matches_lagcodegen(double_pendulum_me, reference):
    s = double_pendulum_me
    L = Lagrangian(s["N"], *s["bodies"])
    params = {sp.Symbol(k, positive=True): v for k, v in DP_VALUES.items()}  # keyed by symbol
    eom = lcg.derive(from_lagrangian(L, s["q"], parameters=params, name="dp_lagrangian"))
    assert_same(eom.M, reference.M)
    assert_same(eom.F, reference.F)
    # split V = -L(q, 0): the true energies of this natural system
    assert_same(eom.T, reference.T)
    assert_same(eom.V, reference.V)
    assert_same(eom.momenta, reference.momenta)


def test_matches_sympy_lagranges_method(double_pendulum_me):
    s = double_pendulum_me
    L = Lagrangian(s["N"], *s["bodies"])
    lm = LagrangesMethod(L, s["q"])
    lm.form_lagranges_equations()
    eom = lcg.derive(from_lagrangian(L, s["q"], parameters=DP_VALUES))
    assert_same(eom.M, plain(lm.mass_matrix, s["q"]))
    assert_same(eom.F, plain(lm.forcing, s["q"]))


def test_matches_lagranges_method_with_forces_and_torques(double_pendulum_me):
    """A horizontal push on the lower bob and a motor torque between the links."""
    s = double_pendulum_me
    N, (bob1, bob2), (th1, th2) = s["N"], s["bodies"], s["q"]
    F, tau = sp.symbols("F tau")
    A, B = N.orientnew("A2", "Axis", [th1, N.z]), N.orientnew("B2", "Axis", [th2, N.z])
    loads = [(bob2.point, F * sp.cos(dynamicsymbols._t) * N.x),
             (A, -tau * N.z), Torque(B, tau * N.z)]
    L = Lagrangian(N, bob1, bob2)
    lm = LagrangesMethod(L, s["q"], forcelist=loads, frame=N)
    lm.form_lagranges_equations()
    model = from_lagrangian(L, s["q"], parameters={**DP_VALUES, "F": 0.3, "tau": 0.2}, forces=loads, frame=N)
    eom = lcg.derive(model)
    assert_same(eom.M, plain(lm.mass_matrix, s["q"]))
    assert_same(eom.F, plain(lm.forcing, s["q"]))
    Fs, taus, t = sp.Symbol("F"), sp.Symbol("tau"), model.t
    l1, l2 = sp.symbols("l1 l2")
    th1s, th2s = model.coords
    assert_same(eom.Q, sp.Matrix([Fs * sp.cos(t) * l1 * sp.cos(th1s) - taus,
                                  Fs * sp.cos(t) * l2 * sp.cos(th2s) + taus]))


# ------------------------------------------------------------------ (d) rigid body
def compound_pendulum_me():
    """A uniform bar of length l pivoting at one end about N.z."""
    th = dynamicsymbols("theta")
    m, l, g = sp.symbols("m l g")
    N, O = ReferenceFrame("N"), Point("O")
    O.set_vel(N, 0)
    B = ReferenceFrame("B")
    B.orient_axis(N, N.z, th)
    G = O.locatenew("G", -l / 2 * B.y)
    G.v2pt_theory(O, N, B)
    bar = RigidBody("bar", G, B, m, (inertia(B, 0, 0, m * l**2 / 12), G))
    bar.potential_energy = m * g * G.pos_from(O).dot(N.y)
    return N, O, B, bar, th


def compound_pendulum_lcg(name="bar_lcg"):
    model = Model(name)
    th, = model.coordinates("theta")
    m, l, g = model.parameters(m=2.0, l=1.5, g=9.81)
    model.planar_body("bar", m, m * l**2 / 12, (l / 2 * sp.sin(th), -l / 2 * sp.cos(th)), th)
    model.gravity(g)
    return model


def test_rigid_body_compound_pendulum_matches_planar_body():
    N, O, B, bar, th = compound_pendulum_me()
    values = {"m": 2.0, "l": 1.5, "g": 9.81}
    ref = lcg.derive(compound_pendulum_lcg())
    for model in (from_bodies(N, [bar], [th], parameters=values, origin=O),
                  from_lagrangian(Lagrangian(N, bar), [th], parameters=values)):
        eom = lcg.derive(model)
        assert_same(eom.M, ref.M)  # m l^2 / 3 about the pivot
        assert_same(eom.M[0, 0], sp.Symbol("m") * sp.Symbol("l") ** 2 / 3)
        assert_same(eom.F, ref.F)
        assert_same(eom.T + eom.V, ref.T + ref.V)
    pos = from_bodies(N, [bar], [th], parameters=values, origin=O).points["bar"].position
    assert_same(pos, sp.Matrix([sp.Symbol("l") / 2 * sp.sin(sp.Symbol("theta")),
                                -sp.Symbol("l") / 2 * sp.cos(sp.Symbol("theta")), 0]))


def test_torque_on_rigid_body_is_a_generalized_force():
    N, O, B, bar, th = compound_pendulum_me()
    tau = sp.Symbol("tau")
    model = from_bodies(N, [bar], [th], parameters={"m": 2.0, "l": 1.5, "g": 9.81, "tau": 0.5},
                        forces=[(B, tau * N.z)])
    ref_model = compound_pendulum_lcg()
    ref_model.parameter("tau", 0.5)
    ref_model.generalized_force("theta", sp.Symbol("tau"))
    eom, ref = lcg.derive(model), lcg.derive(ref_model)
    assert_same(eom.M, ref.M)
    assert_same(eom.F, ref.F)


# ------------------------------------------------------------------ (e) forces
def damped_pendulum_me():
    th = dynamicsymbols("theta")
    m, l, g, c = sp.symbols("m l g c")
    N, O = ReferenceFrame("N"), Point("O")
    O.set_vel(N, 0)
    P = O.locatenew("P", l * sp.sin(th) * N.x - l * sp.cos(th) * N.y)  # velocity from set_pos
    bob = Particle("bob", P, m)
    bob.potential_energy = m * g * P.pos_from(O).dot(N.y)
    return N, P, bob, th, c


def damped_pendulum_lcg(with_force: bool = True) -> Model:
    model = Model("damped")
    th, = model.coordinates("theta")
    m, l, g, c = model.parameters(m=1.0, l=1.0, g=9.81, c=0.3)
    bob = model.particle("bob", m, (l * sp.sin(th), -l * sp.cos(th)))
    model.gravity(g)
    if with_force:
        velocity = bob.point.position.applyfunc(model.time_derivative)
        model.force("bob", -c * velocity)
    else:
        model.damper("bob", c)
    return model


def test_damping_force_matches_model_force():
    N, P, bob, th, c = damped_pendulum_me()
    values = {"m": 1.0, "l": 1.0, "g": 9.81, "c": 0.3}
    forces = [(P, -c * P.vel(N))]
    ref = lcg.derive(damped_pendulum_lcg(with_force=True))
    for model in (from_bodies(N, [bob], [th], parameters=values, forces=forces),
                  from_lagrangian(Lagrangian(N, bob), [th], parameters=values, forces=forces, frame=N)):
        eom = lcg.derive(model)
        assert_same(eom.M, ref.M)
        assert_same(eom.F, ref.F)
        assert_same(eom.Q, ref.Q)  # -c l^2 theta'


def test_rayleigh_dissipation_matches_damper():
    N, P, bob, th, c = damped_pendulum_me()
    D = c / 2 * P.vel(N).dot(P.vel(N))
    model = from_lagrangian(Lagrangian(N, bob), [th], dissipation=D,
                            parameters={"m": 1.0, "l": 1.0, "g": 9.81, "c": 0.3})
    eom, ref = lcg.derive(model), lcg.derive(damped_pendulum_lcg(with_force=False))
    assert_same(eom.D, ref.D)
    assert_same(eom.F, ref.F)


def test_hand_written_lagrangian_with_time_and_custom_time_symbol():
    """A driven oscillator L = m x'^2/2 - k x^2/2 + x F0 cos(w t), written with another time symbol."""
    tau = sp.Symbol("tau")
    x = sp.Function("x")(tau)
    m, k, F0, w = sp.symbols("m k F0 w")
    L = m * x.diff(tau) ** 2 / 2 - k * x**2 / 2 + x * F0 * sp.cos(w * tau)
    model = from_lagrangian(L, [x], time=tau, parameters={"m": 1.0, "k": 4.0, "F0": 1.0, "w": 1.5})
    eom = lcg.derive(model)
    xs, t = sp.Symbol("x"), model.t
    assert_same(eom.M, sp.Matrix([[sp.Symbol("m")]]))
    assert_same(eom.F, sp.Matrix([-sp.Symbol("k") * xs + sp.Symbol("F0") * sp.cos(sp.Symbol("w") * t)]))


# ------------------------------------------------------------------ (f) bad input
def test_missing_parameter_value_is_named(double_pendulum_me):
    s = double_pendulum_me
    values = {k: v for k, v in DP_VALUES.items() if k != "g"}
    with pytest.raises(ModelError, match=r"no value given for parameter\(s\) g"):
        from_bodies(s["N"], s["bodies"], s["q"], parameters=values)
    with pytest.raises(ModelError, match="g"):
        from_lagrangian(Lagrangian(s["N"], *s["bodies"]), s["q"], parameters=values)


def test_unknown_parameter_value_is_named(double_pendulum_me):
    s = double_pendulum_me
    with pytest.raises(ModelError, match="unknown parameter.*gg"):
        from_bodies(s["N"], s["bodies"], s["q"], parameters={**DP_VALUES, "gg": 1.0})


def test_stray_dynamicsymbol_is_named():
    q, u = dynamicsymbols("q u")
    t = dynamicsymbols._t
    m = sp.Symbol("m")
    with pytest.raises(ModelError, match="'u'.*not.*coordinate"):
        from_lagrangian(m * q.diff(t) ** 2 / 2 - u * q, [q], parameters={"m": 1.0})
    with pytest.raises(ModelError, match="'u'"):
        from_lagrangian(m * q.diff(t) ** 2 / 2 + m * u.diff(t) * q, [q], parameters={"m": 1.0})


def test_second_derivative_is_named():
    q = dynamicsymbols("q")
    t = dynamicsymbols._t
    with pytest.raises(ModelError, match="order 2 of 'q'"):
        from_lagrangian(q.diff(t) ** 2 / 2 + q * q.diff(t, 2), [q])


def test_other_bad_input():
    q = dynamicsymbols("q")
    t = dynamicsymbols._t
    N, P = ReferenceFrame("N"), Point("P")
    P.set_vel(N, q.diff(t) * N.x)
    L = q.diff(t) ** 2 / 2
    with pytest.raises(ModelError, match="not a dynamicsymbol"):
        from_lagrangian(L, [sp.Symbol("q")])
    with pytest.raises(ModelError, match="frame"):
        from_lagrangian(L, [q], forces=[(P, N.x)])
    with pytest.raises(ModelError, match="Particle or RigidBody"):
        from_bodies(N, [P], [q])
    with pytest.raises(ModelError, match="q_dot"):  # a symbol shadowing a velocity
        from_lagrangian(L + sp.Symbol("q_dot"), [q], parameters={"q_dot": 1.0})


# ------------------------------------------------------------------ numerics
@pytest.mark.parametrize("how", ["bodies", "lagrangian"])
def test_imported_double_pendulum_conserves_energy(double_pendulum_me, how):
    s = double_pendulum_me
    if how == "bodies":
        model = from_bodies(s["N"], s["bodies"], s["q"], parameters=DP_VALUES, name="dp_me_bodies")
    else:
        model = from_lagrangian(Lagrangian(s["N"], *s["bodies"]), s["q"], parameters=DP_VALUES,
                                name="dp_me_lagrangian")
    res = lcg.compile_model(model, outputs=["energy"]).simulate([0, 5], q0=[1.0, 0.5])
    energy = res["energy"]
    assert energy[0] == pytest.approx(-9.81 * (2 * math.cos(1.0) + math.cos(0.5)), rel=1e-12)
    assert np.max(np.abs(energy - energy[0])) < 1e-6
    assert np.ptp(res["theta1"]) > 0.5  # it actually moved


def test_actuator_loads_are_expanded():
    """A LinearSpring actuator (a force pair along a pathway) acts like lagcodegen's spring potential."""
    from sympy.physics.mechanics import LinearPathway, LinearSpring

    x, y = dynamicsymbols("x y")
    m, k, L0 = sp.symbols("m k L0")
    N, O = ReferenceFrame("N"), Point("O")
    O.set_vel(N, 0)
    P = O.locatenew("P", x * N.x + y * N.y)
    spring = LinearSpring(k, LinearPathway(O, P), L0)
    model = from_bodies(N, [Particle("mass", P, m)], [x, y], forces=[spring],
                        parameters={"m": 1.0, "k": 4.0, "L0": 0.5})
    ref_model = Model("spring")
    xs, ys = ref_model.coordinates("x y")
    ms, ks, L0s = ref_model.parameters(m=1.0, k=4.0, L0=0.5)
    ref_model.particle("mass", ms, (xs, ys))
    ref_model.spring("mass", (0, 0), ks, L0s)
    eom, ref = lcg.derive(model), lcg.derive(ref_model)
    assert_same(eom.M, ref.M)
    assert_same(eom.F, ref.F)
