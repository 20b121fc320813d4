"""ConstrainedSystem: Pfaffian forms (eqs. 4.2, 4.3), the Frobenius integrability test, eq. 4.5
with multipliers, and clear errors for bad constraints and inconsistent initial states."""

import numpy as np
import pytest
import sympy as sp

import lagcodegen as lcg
from lagcodegen import ModelError
from lagcodegen.theory.constraints import ConstrainedSystem, frobenius_terms, integrability


def plane_particle(name="pp"):
    m = lcg.Model(name)
    x, y = m.coordinates("x y")
    l, g, mass = m.parameters(l=1.0, g=9.81, m=1.0)
    m.particle("bob", mass, (x, y))
    m.gravity(g)
    return m, x, y, l


def knife_edge_model():
    """Knife edge (Chaplygin sled without offset) on a plane inclined by alpha."""
    m = lcg.Model("knife")
    x, y, th = m.coordinates("x y theta")
    mass, Iz, g, al = m.parameters(m=1.0, Iz=0.1, g=9.81, alpha=0.3)
    m.kinetic_energy(mass / 2 * (m.dot(x) ** 2 + m.dot(y) ** 2) + Iz / 2 * m.dot(th) ** 2)
    m.potential_energy(-mass * g * sp.sin(al) * x)
    return m, x, y, th


def disc_model():
    """Disc of radius R rolling down an incline: x along the slope, phi its rotation."""
    m = lcg.Model("disc")
    x, phi = m.coordinates("x phi")
    mass, R, g, al = m.parameters(m=1.0, R=0.5, g=9.81, alpha=0.4)
    m.kinetic_energy(mass / 2 * m.dot(x) ** 2 + mass * R ** 2 / 4 * m.dot(phi) ** 2)
    m.potential_energy(-mass * g * sp.sin(al) * x)
    return m, x, phi, R


# ---------------------------------------------------------------------- forms
def test_holonomic_constraint_in_differential_form():
    m, x, y, l = plane_particle()
    t = m.t
    cs = ConstrainedSystem(m, holonomic=[x ** 2 + y ** 2 - l ** 2, x - sp.sin(t) * y])
    assert cs.A == sp.Matrix([[2 * x, 2 * y], [1, -sp.sin(t)]])  # eq. 4.2: A_j = df_j/dq
    assert cs.A0 == sp.Matrix([0, -sp.cos(t) * y])  # and A0_j = df_j/dt
    assert cs.J == 2 and cs.dof == 0


def test_acceleration_rhs_is_minus_the_time_derivative_without_second_derivatives():
    m, x, y, l = plane_particle()
    cs = ConstrainedSystem(m, holonomic=[x ** 2 + y ** 2 - l ** 2])
    xd, yd = m.speeds
    # d/dt (2 x x' + 2 y y') = 2 x x'' + 2 y y'' + 2 x'^2 + 2 y'^2
    assert sp.simplify(cs.acceleration_rhs()[0] + 2 * xd ** 2 + 2 * yd ** 2) == 0


def test_rheonomic_pfaffian_acceleration_rhs():
    m, x, y, th = knife_edge_model()
    t = m.t
    cs = ConstrainedSystem(m, nonholonomic=[([sp.sin(th), -sp.cos(th), 0], t)])
    xd, yd, thd = m.speeds
    s = sp.sin(th) * xd - sp.cos(th) * yd + t
    expected = -(sp.diff(s, th) * thd + 1)
    assert sp.simplify(cs.acceleration_rhs()[0] - expected) == 0


def test_equations_with_multipliers_match_hand_derivation():
    m, x, y, l = plane_particle()
    cs = ConstrainedSystem(m, holonomic=[x ** 2 + y ** 2 - l ** 2])
    dyn, acc = cs.equations()
    mass, g = sp.Symbol("m"), sp.Symbol("g")
    lam = cs.multipliers[0]
    xdd, ydd = sp.Symbol("x_ddot"), sp.Symbol("y_ddot")
    assert sp.simplify(dyn[0] - (mass * xdd - 2 * x * lam)) == 0  # eq. 4.5
    assert sp.simplify(dyn[1] - (mass * ydd + mass * g - 2 * y * lam)) == 0
    assert cs.constraint_forces()[0] == sp.Matrix([2 * x * lam, 2 * y * lam])  # R = lambda A


def test_pfaffian_given_as_dict_and_matrix():
    m, x, y, th = knife_edge_model()
    a = ConstrainedSystem(m, nonholonomic=[({"x": sp.sin(th), "y": -sp.cos(th)}, 0)])
    b = ConstrainedSystem(m, nonholonomic=[sp.Matrix([sp.sin(th), -sp.cos(th), 0])])
    assert a.A == b.A == sp.Matrix([[sp.sin(th), -sp.cos(th), 0]])


# ---------------------------------------------------------------------- integrability
def test_knife_edge_constraint_is_not_integrable():
    m, x, y, th = knife_edge_model()
    cs = ConstrainedSystem(m, nonholonomic=[([sp.sin(th), -sp.cos(th), 0], 0)])
    rep = cs.is_integrable(0)
    assert not rep.integrable and rep.proven
    # w ^ dw on dx^dy^dtheta: sin(th)(-sin th) + (-cos th)(cos th) = -1
    assert sp.simplify(rep.obstruction[("x", "y", "theta")] + 1) == 0


def test_rolling_without_slipping_written_as_pfaffian_is_integrable():
    m, x, phi, R = disc_model()
    with pytest.raises(ModelError, match="integrable: it is holonomic"):
        ConstrainedSystem(m, nonholonomic=[([1, -R], 0)])  # x' - R phi' = 0 is d(x - R phi) = 0
    cs = ConstrainedSystem(m, nonholonomic=[([1, -R], 0)], integrable="allow")
    assert cs.is_integrable(0).integrable


def test_disguised_exact_form_with_integrating_factor_is_integrable():
    m, x, y, th = knife_edge_model()
    # (1 + y^2) d(x theta): an exact form times an integrating factor
    A = [(1 + y ** 2) * th, 0, (1 + y ** 2) * x]
    rep = integrability(A, 0, m.coords, m.t)
    assert rep.integrable
    with pytest.raises(ModelError, match="integrable: it is holonomic"):
        ConstrainedSystem(m, nonholonomic=[(A, 0)])


def test_time_counts_in_the_frobenius_test():
    m, x, y, th = knife_edge_model()
    t = m.t
    # dx - t dy = 0 is nonholonomic: the dx^dy^dt component is 1
    rep = integrability([1, -t, 0], 0, m.coords, t)
    assert not rep.integrable and rep.obstruction[("x", "y", "t")] == 1
    # dx + dt = 0 is d(x + t) = 0: holonomic (rheonomic)
    assert integrability([1, 0, 0], 1, m.coords, t).integrable


def test_frobenius_terms_count():
    m, x, y, th = knife_edge_model()
    assert len(frobenius_terms([1, 2, 3], 0, m.coords, m.t)) == 4  # C(4, 3) triples of (x, y, theta, t)


# ---------------------------------------------------------------------- bad input
def test_unknown_symbol_is_named():
    m, x, y, l = plane_particle()
    with pytest.raises(ModelError, match=r"holonomic constraint 0 uses unknown symbol\(s\): L"):
        ConstrainedSystem(m, holonomic=[x ** 2 + y ** 2 - sp.Symbol("L") ** 2])
    with pytest.raises(ModelError, match=r"nonholonomic constraint 0.*unknown symbol\(s\): k"):
        ConstrainedSystem(m, nonholonomic=[([sp.Symbol("k"), 1], 0)])
    with pytest.raises(ModelError, match=r"inequality constraint 0 uses unknown symbol\(s\): h"):
        ConstrainedSystem(m, inequalities=[y - sp.Symbol("h")])


def test_an_inequality_that_cannot_act_is_refused_naming_it():
    """An inequality in no coordinate (0*y, 5 - t) got "augmented matrix singular" as a contact, or
    was silently never active; one with a repeated factor (y**2) was silently never active: its
    gradient vanishes where it is zero."""
    m, x, y, l = plane_particle()
    t = m.t
    for g in (0 * y, 5 - t, l - 1):
        for item in (g, lcg.Inequality(g, restitution=0.5)):
            with pytest.raises(ModelError, match=r"inequality constraint 1 \(.* >= 0\) involves no coordinate"):
                ConstrainedSystem(m, inequalities=[y + 2, item])
    for g, factor in ((y ** 2, "'y' to the power 2"), (-3 * (x - l) ** 2 * y, "'-l \\+ x' to the power 2"),
                      (sp.sin(x) ** 3, r"'sin\(x\)' to the power 3")):
        with pytest.raises(ModelError, match=rf"inequality constraint 0 \(.* >= 0\) has the factor {factor}"):
            ConstrainedSystem(m, inequalities=[lcg.Inequality(g, restitution=0.0)])
    # the message shows a bounded excerpt of a long inequality
    long = sum(l ** k / (k + 1) for k in range(120)) + t
    with pytest.raises(ModelError) as err:
        ConstrainedSystem(m, inequalities=[long])
    assert "involves no coordinate" in str(err.value) and "characters)" in str(err.value)
    assert len(str(err.value)) < 400
    # inequalities that act are kept: a factor once, a repeated factor in parameters or time only
    for g in (y, y ** 2 - l ** 2, l ** 2 * y, (t - 1) ** 2 * y, x ** 2 + y ** 2 + 1):
        assert ConstrainedSystem(m, inequalities=[g]).inequalities == [g]


def test_model_file_inequalities_that_cannot_act_are_located():
    from lagcodegen.modelfile import ModelFileError, loads_model
    base = ('[model]\nname = "b"\ncoordinates = ["y"]\n[[particles]]\nname = "b"\nmass = 1\n'
            'position = ["0", "y"]\n[gravity]\ng = 9.81\n[constraints]\n')
    for text, expect in (("y**2", "has the factor 'y' to the power 2"), ("5 - t", "involves no coordinate")):
        with pytest.raises(ModelFileError) as err:
            loads_model(base + f'inequalities = ["y + 1", {{ expr = "{text}", restitution = 0.5 }}]\n', "b.toml")
        msg = str(err.value)
        assert msg.startswith("b.toml:11:") and "constraints.inequalities[1]" in msg and expect in msg, msg


def test_velocities_are_not_allowed_in_constraint_coefficients():
    m, x, y, l = plane_particle()
    with pytest.raises(ModelError, match="velocity not allowed"):
        ConstrainedSystem(m, holonomic=[x * m.speeds[0]])


def test_more_constraints_than_coordinates():
    m, x, y, l = plane_particle()
    with pytest.raises(ModelError, match="3 equality constraints .* only 2 coordinates"):
        ConstrainedSystem(m, holonomic=[x - 1, y - 1], nonholonomic=[([1, 1], 0)])


def test_wrong_length_pfaffian_row_and_empty_constraint():
    m, x, y, l = plane_particle()
    with pytest.raises(ModelError, match="A has 3 coefficients, the model has 2 coordinates"):
        ConstrainedSystem(m, nonholonomic=[([1, 2, 3], 0)])
    with pytest.raises(ModelError, match="every coefficient A_i is zero"):
        ConstrainedSystem(m, nonholonomic=[([0, 0], 1)])
    with pytest.raises(ModelError, match="involves no coordinate"):
        ConstrainedSystem(m, holonomic=[l - 1])


def test_inconsistent_initial_conditions_name_the_residuals():
    m, x, y, l = plane_particle()
    cs = ConstrainedSystem(m, holonomic=[x ** 2 + y ** 2 - l ** 2])
    with pytest.raises(ModelError, match=r"inconsistent initial conditions.*holonomic constraint 0 .* residual 0.25"):
        cs.check_initial([0.5, -1.0], [0, 0])
    with pytest.raises(ModelError, match=r"velocity constraint 0 .* residual -2"):
        cs.check_initial([0.0, -1.0], [0, 1.0])  # moving along the rod
    vals = cs.check_initial([np.sin(0.3), -np.cos(0.3)], [np.cos(0.3), np.sin(0.3)])
    assert vals["rank"] == 1 and abs(vals["g"][0]) < 1e-15
    # parameters by name
    cs.check_initial([0.0, -2.0], [0, 0], params={"l": 2.0})


def test_singular_constraint_jacobian_at_the_initial_state():
    m, x, y, l = plane_particle()
    # a circle and a tangent line meet at (l, 0) where their gradients are parallel
    cs = ConstrainedSystem(m, holonomic=[x ** 2 + y ** 2 - l ** 2, x - l])
    with pytest.raises(ModelError, match=r"singular constraint Jacobian .* rank 1 < 2 .* constraint 1 is "
                                         r"linearly dependent on constraint\(s\) 0"):
        cs.check_initial([1.0, 0.0], [0, 0])
    cs0 = ConstrainedSystem(m, holonomic=[x ** 2 + y ** 2 - l ** 2])
    with pytest.raises(ModelError, match="constraint 0 has a zero gradient"):
        cs0.check_initial([0.0, 0.0], [0, 0])


def test_multiplier_names_may_not_clash_with_the_model():
    m = lcg.Model("clash")
    x, = m.coordinates("x")
    m.parameters(lambda_0=1.0)
    m.particle("p", 1, (x, 0))
    with pytest.raises(ModelError, match="reserved for Lagrange multipliers"):
        ConstrainedSystem(m, holonomic=[x - 1])


def tan_exact_model():
    m = lcg.Model("tanexact")
    x, y, z = m.coordinates("x y z")
    m.kinetic_energy((m.dot(x) ** 2 + m.dot(y) ** 2 + m.dot(z) ** 2) / 2)
    return m, x, y, z


def test_frobenius_budget_decides_large_terms_by_samples(monkeypatch):
    """d(z tan x + y) written with 1/cos^2 x: w ^ dw = 1/cos^2 x - (1 + tan^2 x) is zero, but only
    simplify shows it; over the budget the samples decide (integrable, not proven)."""
    from lagcodegen.theory import integrability as frobenius
    m, x, y, z = tan_exact_model()
    A = [z / sp.cos(x) ** 2, 1, sp.tan(x)]
    rep = frobenius.integrability(A, 0, m.coords, m.t)
    assert rep.integrable and rep.proven
    monkeypatch.setattr(frobenius, "FROBENIUS_SIMPLIFY_OPS", 0)
    rep = frobenius.integrability(A, 0, m.coords, m.t)
    assert rep.integrable and not rep.proven
    # a nonintegrable form is decided by the samples whatever the budget
    assert not frobenius.integrability([sp.sin(z), -sp.cos(z), 0], 0, m.coords, m.t).integrable


def test_integrability_check_is_optional():
    m, x, phi, R = disc_model()
    # x' - R phi' = 0 is integrable: refused by default, kept unchecked with check_integrability=False
    with pytest.raises(ModelError, match="integrable: it is holonomic"):
        ConstrainedSystem(m, nonholonomic=[([1, -R], 0)])
    cs = ConstrainedSystem(m, nonholonomic=[([1, -R], 0)], check_integrability=False)
    assert cs.integrability_reports == {} and not cs.integrability_checked
    assert cs.is_integrable(0).integrable  # on demand
    with pytest.raises(ModelError, match="no nonholonomic constraint 3"):
        cs.is_integrable(3)
    with pytest.raises(ModelError, match="check_integrability must be True or False"):
        ConstrainedSystem(m, nonholonomic=[([1, -R], 0)], check_integrability="no")


def test_whipple_bicycle_builds_with_its_frobenius_test():
    """The four rolling constraints of the bicycle are nonintegrable (decided from the samples: no
    simplification needed)."""
    import time
    from helpers import whipple_bicycle
    start = time.perf_counter()
    cs = whipple_bicycle(check_integrability=True)
    elapsed = time.perf_counter() - start
    assert all(not cs.is_integrable(j).integrable and cs.is_integrable(j).proven for j in range(4))
    assert elapsed < 10.0  # 1.5 s on a quiet machine, 0.8 s without the test (5.4 s for the test before)
