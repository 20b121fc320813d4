"""Routh's reduction (sec. 3.4) against hand derivations, conservation laws and the full model."""

import math

import numpy as np
import pytest
import sympy as sp

import lagcodegen as lcg
from lagcodegen import ModelError, systems
from lagcodegen.theory.routhian import ignorable_coordinates, reduce
from lagcodegen.model.systems import bead_on_spinning_hoop, spherical_pendulum

th, ph, r = sp.symbols("theta phi r")
thd, phd, rd = sp.symbols("theta_dot phi_dot r_dot")
m, l, g, k = sp.symbols("m l g k")
C = sp.Symbol("C_phi")


def same(a, b) -> bool:
    return sp.simplify(sp.sympify(a) - sp.sympify(b)) == 0


@pytest.fixture(scope="module")
def sph():
    return reduce(spherical_pendulum())


@pytest.fixture(scope="module")
def kepler():
    return reduce(systems.central_potential())


# ---------------------------------------------------------------------- detection
def test_ignorable_coordinates_detected():
    assert ignorable_coordinates(lcg.derive(spherical_pendulum())) == [ph]  # L has cos^2 phi + sin^2 phi
    assert ignorable_coordinates(lcg.derive(systems.central_potential())) == [ph]
    assert ignorable_coordinates(lcg.derive(systems.double_pendulum())) == []
    assert ignorable_coordinates(lcg.derive(bead_on_spinning_hoop())) == []
    assert ignorable_coordinates(lcg.derive(systems.damped_driven_oscillator())) == []


def test_forces_and_dissipation_spoil_ignorability():
    # phi absent from L, but a torque or a damper acts on it: p_phi is not conserved (eq. 3.16).
    torqued = systems.central_potential("torqued")
    torqued.generalized_force("phi", sp.Symbol("k") * 0.1)
    assert ignorable_coordinates(lcg.derive(torqued)) == []
    damped = systems.central_potential("damped")
    damped.dissipation(sp.Symbol("k") * sp.Symbol("phi_dot") ** 2 / 2)
    assert ignorable_coordinates(lcg.derive(damped)) == []
    # phi in the force on r: not ignorable either.
    coupled = systems.central_potential("coupled")
    coupled.generalized_force("r", sp.cos(sp.Symbol("phi")))
    assert ignorable_coordinates(lcg.derive(coupled)) == []
    # A radial damper leaves phi ignorable, and carries over to the reduced model.
    # So does a radial force that depends on phi': phi' = C/(m r^2) is substituted.
    radial = systems.central_potential("radial")
    radial.dissipation(sp.Symbol("k") * sp.Symbol("r_dot") ** 2 / 2)
    radial.generalized_force("r", sp.Symbol("k") * sp.Symbol("phi_dot"))
    red = reduce(radial)
    assert red.ignorable == [ph]
    assert same(red.model_dissipation, k * rd**2 / 2)
    assert same(red.model_forces[0], k * C / (m * r**2))
    # Hand: m r'' = m r phi'^2 - k/r^2 - k r' + k phi' with phi' = C/(m r^2) (damping and force
    # coefficients both k here), from eq. 3.10 with the forces of eq. 3.16 and from L_R = -R.
    hand = (C**2 / (m * r**3) - k / r**2 - k * rd + k * C / (m * r**2)) / m
    assert same(sp.solve(red.equations()[0], sp.Symbol("r_ddot"))[0], hand)
    assert same(red.eom.F[0] / red.eom.M[0, 0], hand)


# ---------------------------------------------------------------------- spherical pendulum
def test_spherical_pendulum_integral_and_velocity(sph):
    assert sph.ignorable == [ph] and sph.coordinates == [th] and sph.integrals == [C]
    assert same(sph.momenta[0], m * l**2 * sp.sin(th) ** 2 * phd)  # eq. 3.8
    assert same(sph.velocity_solution[phd], C / (m * l**2 * sp.sin(th) ** 2))


def test_spherical_pendulum_routhian_matches_hand_derivation(sph):
    # L = m l^2/2 (theta'^2 + sin^2 theta phi'^2) + m g l cos theta (V = -m g l cos theta);
    # R = -L + C phi' with phi' = C/(m l^2 sin^2 theta)  (eq. 3.9):
    hand = -m * l**2 * thd**2 / 2 + C**2 / (2 * m * l**2 * sp.sin(th) ** 2) - m * g * l * sp.cos(th)
    assert same(sph.R, hand)
    assert not (sph.R.free_symbols & {ph, phd})


def test_spherical_pendulum_reduced_equation(sph):
    # eq. 3.10: d/dt(dR/dtheta') - dR/dtheta = -m l^2 theta'' + C^2 cos/(m l^2 sin^3) - m g l sin = 0
    eq = sph.equations()
    assert eq.shape == (1, 1)
    thdd = sp.Symbol("theta_ddot")
    hand = C**2 * sp.cos(th) / (m**2 * l**4 * sp.sin(th) ** 3) - g / l * sp.sin(th)
    assert same(sp.solve(eq[0], thdd)[0], hand)
    # The derived reduced model (L_R = -R) gives the same acceleration.
    eom = sph.eom
    assert same(eom.F[0] / eom.M[0, 0], hand)


def test_reconstruction_and_jacobi_function(sph):
    # eq. 3.11: dR/dC equals the eliminated velocity; eq. 3.12: h_R equals the full h.
    assert same(sph.reconstruction[0], sph.velocity_solution[phd])
    full_h = sph.full.h.xreplace(sph.velocity_solution)
    assert same(sph.h_R, full_h)
    assert same(sph.eom.h, sph.h_R)  # the reduced model's Jacobi h is eq. 3.12


def test_reduced_model_layout(sph):
    red = sph.model
    assert [q.name for q in red.coords] == ["theta"] and [v.name for v in red.speeds] == ["theta_dot"]
    assert {s.name: v for s, v in red.params.items()} == {"m": 1.0, "l": 1.0, "g": 9.81, "C_phi": 0.0}
    assert sph.eom.quadratures[0][0] == "phi"


def test_two_coupled_ignorable_coordinates():
    # T = m/2 (r'^2 + r^2 phi'^2 + z'^2) + b phi' z', V = k r^2/2: phi and z ignorable, their
    # velocity block [[m r^2, b], [b, m]] must be solved as a 2 x 2 system.
    mod = lcg.Model("helix")
    rr, phi, z = mod.coordinates("r phi z")
    mm, kk, b = mod.parameters(m=1.0, k=2.0, b=0.3)
    v = {q: mod.dot(q) for q in (rr, phi, z)}
    mod.kinetic_energy(mm / 2 * (v[rr] ** 2 + rr**2 * v[phi] ** 2 + v[z] ** 2) + b * v[phi] * v[z])
    mod.potential_energy(kk * rr**2 / 2)
    red = reduce(mod)
    assert red.ignorable == [phi, z]
    Cp, Cz = red.integrals
    for vi, rate in zip((v[phi], v[z]), red.reconstruction):
        assert same(rate, red.velocity_solution[vi])
    # Check the solution solves the momenta equations (eq. 3.8).
    for Ci, p in zip((Cp, Cz), red.momenta):
        assert same(p.xreplace(red.velocity_solution), Ci)
    assert same(red.h_R, red.full.h.xreplace(red.velocity_solution))


# ---------------------------------------------------------------------- simulation
@pytest.fixture(scope="module")
def sph_compiled(sph):
    full = lcg.compile_model(spherical_pendulum(), outputs=["jacobi_h", "p_phi"])
    return full, lcg.compile_reduction(sph, outputs=["jacobi_h"])


def test_reduced_and_full_trajectories_agree(sph, sph_compiled):
    full, cm = sph_compiled
    assert cm.state_names == ["theta", "theta_dot", "phi"]
    q0, v0 = [0.8, 0.1], [0.3, 2.0]
    t = np.linspace(0.0, 70.0, 2801)
    opts = dict(rtol=1e-11, atol=1e-12)
    rf = full.simulate(t, q0=q0, v0=v0, **opts)
    rr = sph.simulate(cm, t, q0, v0, **opts)
    periods = np.count_nonzero(np.diff(np.sign(rf["theta_dot"])) != 0) / 2
    assert periods >= 45  # about 50 oscillations of theta
    assert rr.parameters["C_phi"] == pytest.approx(math.sin(0.8) ** 2 * 2.0, rel=1e-14)
    errs = {k: float(np.max(np.abs(rf[k] - rr[k]))) for k in ("theta", "phi", "theta_dot", "phi_dot")}
    print(f"{periods:.0f} periods: max |full - reduced| = {errs}")
    assert max(errs.values()) < 3e-7
    assert set(rr.q) == {"theta", "phi"}
    # h of the reduced system (eq. 3.12) is the full h, and both are conserved.
    assert rr["jacobi_h"][0] == pytest.approx(rf["jacobi_h"][0], rel=1e-13)
    assert rr.drift("jacobi_h") < 1e-8 and rf.drift("p_phi") < 1e-8


def test_simulate_takes_dicts_and_rejects_integrals(sph, sph_compiled):
    _, cm = sph_compiled
    a = sph.simulate(cm, [0.0, 1.0], {"theta": 0.8}, {"phi": 2.0, "theta": 0.3}, params={"g": 9.0})
    b = sph.simulate(cm, [0.0, 1.0], [0.8, 0.0], [0.3, 2.0], params={"g": 9.0})
    assert np.array_equal(a.y, b.y) and a.parameters["g"] == 9.0
    with pytest.raises(lcg.LagcodegenError, match="computed from the initial state"):
        sph.simulate(cm, [0.0, 1.0], [0.8, 0.0], [0.3, 2.0], params={"C_phi": 1.0})


def test_kepler_angular_momentum_is_conserved_in_full_model(kepler):
    cm = lcg.compile_model(systems.central_potential(), outputs=["p_phi"])
    res = cm.simulate(np.linspace(0, 60, 601), q0=[1.0, 0.0], v0=[0.1, 1.2], rtol=1e-11, atol=1e-13)
    assert res.drift("p_phi") < 1e-9
    assert same(kepler.momenta[0], m * r**2 * phd)  # C = m r^2 phi'


def test_kepler_period_from_reduced_simulation(kepler):
    # E = m v^2/2 - k/r0 = -k/(2a), so a = 1/(2/r0 - m v^2/k); period 2 pi a^{3/2} sqrt(m/k) (Kepler's third law).
    mm, kk = 2.0, 3.0
    r0, w0 = 1.0, 1.3  # r0 phi' = 1.3 < sqrt(2 k/(m r0)): bound orbit
    a = 1.0 / (2.0 / r0 - mm * (r0 * w0) ** 2 / kk)
    period = 2 * math.pi * a**1.5 * math.sqrt(mm / kk)
    cm = lcg.compile_reduction(kepler)
    res = kepler.simulate(cm, [0.0, period / 2, period], [r0, 0.0], [0.0, w0], params={"m": mm, "k": kk},
                          rtol=1e-12, atol=1e-13)
    assert res["r"][1] == pytest.approx(2 * a - r0, rel=1e-8)  # apoapsis
    assert res["phi"][1] == pytest.approx(math.pi, abs=1e-8)
    assert res["r"][2] == pytest.approx(r0, rel=1e-8) and abs(res["r_dot"][2]) < 1e-7
    assert res["phi"][2] == pytest.approx(2 * math.pi, abs=1e-8)  # phi advances by 2 pi per period


# ---------------------------------------------------------------------- errors
def test_no_ignorable_coordinate():
    with pytest.raises(ModelError, match=r"no ignorable coordinate: every coordinate appears in L.*"
                                         r"theta \(it appears in L\)"):
        reduce(bead_on_spinning_hoop())
    with pytest.raises(ModelError, match="no ignorable coordinate"):
        reduce(systems.double_pendulum())


def test_declared_coordinate_not_ignorable():
    with pytest.raises(ModelError, match="'r' is not ignorable: it appears in L"):
        reduce(systems.central_potential(), ["r"])
    damped = systems.central_potential("damped")
    damped.dissipation(sp.Symbol("k") * sp.Symbol("phi_dot") ** 2 / 2)
    with pytest.raises(ModelError, match="'phi' is not ignorable: D depends on phi_dot"):
        reduce(damped, ["phi"])
    coupled = systems.central_potential("coupled")
    coupled.generalized_force("r", sp.cos(sp.Symbol("phi")))
    with pytest.raises(ModelError, match="'phi' is not ignorable: it appears in the generalized force on r"):
        reduce(coupled, ["phi"])
    with pytest.raises(ModelError, match="'x' is not a coordinate"):
        reduce(systems.central_potential(), ["x"])


def test_singular_velocity_elimination():
    # L = theta'^2/2 + theta phi' - theta^2/2: phi is absent from L, but L is linear in phi'.
    mod = lcg.Model("linear_in_phidot")
    theta, phi = mod.coordinates("theta phi")
    mod.kinetic_energy(mod.dot(theta) ** 2 / 2 + theta * mod.dot(phi))
    mod.potential_energy(theta**2 / 2)
    with pytest.raises(ModelError, match="velocity elimination is singular"):
        reduce(mod)
    with pytest.raises(ModelError, match="velocity elimination is singular"):
        reduce(mod, ["phi"])


def test_integral_name_clash():
    mod = systems.central_potential("clash")
    mod.parameter("C_phi", 1.0)
    with pytest.raises(ModelError, match="'C_phi'"):
        reduce(mod)
