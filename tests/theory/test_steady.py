"""Steady motions (sec. 3.5, eq. 3.13) against textbook results."""

import math

import numpy as np
import pytest

import lagcodegen as lcg
from lagcodegen import ModelError, systems
from lagcodegen.theory.routhian import reduce
from lagcodegen.theory.steady import steady_motions
from lagcodegen.model.systems import bead_on_spinning_hoop, spherical_pendulum

G = 9.81


@pytest.fixture(scope="module")
def sph():
    return reduce(spherical_pendulum())


@pytest.fixture(scope="module")
def hoop():
    return lcg.derive(bead_on_spinning_hoop())


@pytest.mark.parametrize("theta0", [0.3, 0.7, 1.2])
def test_conical_pendulum(sph, theta0):
    # Conical pendulum: theta'' = sin cos phi'^2 - (g/l) sin = 0 gives phi'^2 = g/(l cos theta0).
    mass, l = 2.0, 1.5
    phid = math.sqrt(G / (l * math.cos(theta0)))
    C = mass * l**2 * math.sin(theta0) ** 2 * phid
    motions = steady_motions(sph, {"phi": C}, params={"m": mass, "l": l})
    upper = [s for s in motions if s.coordinates["theta"] > 0]
    assert len(upper) == 1  # one branch in (0, pi) (and its mirror theta -> -theta)
    s = upper[0]
    assert s.coordinates["theta"] == pytest.approx(theta0, abs=1e-10)
    assert s.velocities["phi"] == pytest.approx(phid, rel=1e-10)
    assert s.integrals == {"C_phi": C}
    assert s.stable
    # Small oscillations: with u = phi'^2 s^4 = C^2/(m^2 l^4), the reduced equation is
    # theta'' = f(theta) = u cos/sin^3 - (g/l) sin; f' = -u (sin^2 + 3 cos^2)/sin^4 - (g/l) cos,
    # and with g/l = phi'^2 cos at the steady motion, Omega^2 = -f' = phi'^2 (1 + 3 cos^2 theta0).
    omega = math.sqrt(G / (l * math.cos(theta0)) * (1 + 3 * math.cos(theta0) ** 2))
    assert s.frequencies == pytest.approx([omega], rel=1e-9)
    assert np.max(np.abs(s.eigenvalues.real)) < 1e-9


def test_no_rotation_gives_the_equilibria(sph):
    # With C = 0 the amended potential is -m g l cos(theta): hanging down (theta = 0 is a pole of
    # the reduced equation when C != 0, but with C = 0 it is fine) and the inverted position.
    motions = steady_motions(spherical_pendulum())
    thetas = sorted(round(s.coordinates["theta"], 9) for s in motions)
    assert thetas == [0.0, round(math.pi, 9)]


@pytest.mark.parametrize("w", [2.0, 3.0, 5.0, 8.0])
def test_bead_on_spinning_hoop(hoop, w):
    a = 1.2
    motions = steady_motions(hoop, params={"w": w, "a": a})
    thetas = {round(s.coordinates["theta"], 8): s for s in motions}
    # theta = 0 and theta = pi always; theta'' = sin(theta) (w^2 cos(theta) - g/a).
    assert 0.0 in thetas and round(math.pi, 8) in thetas
    assert not thetas[round(math.pi, 8)].stable
    bottom = thetas[0.0]
    critical = G / a
    if w**2 < critical:
        assert len(motions) == 2
        assert bottom.stable
        assert bottom.frequencies == pytest.approx([math.sqrt(critical - w**2)], rel=1e-9)
    else:
        assert not bottom.stable
        ts = math.acos(G / (a * w**2))
        assert len(motions) == 4
        for sign in (1, -1):
            s = thetas[round(sign * ts, 8)]
            assert s.coordinates["theta"] == pytest.approx(sign * ts, abs=1e-10)
            assert s.stable
            # d/dtheta [sin (w^2 cos - g/a)] = cos (w^2 cos - g/a) - w^2 sin^2; the first term
            # vanishes at cos(theta*) = g/(a w^2), so Omega^2 = w^2 sin^2(theta*).
            assert s.frequencies == pytest.approx([w * math.sin(ts)], rel=1e-9)


def test_hoop_steady_motions_do_not_depend_on_time(hoop):
    # The hoop is rheonomic (x depends on t) but L is not explicitly time dependent.
    a = {round(s.coordinates["theta"], 9) for s in steady_motions(hoop, params={"w": 5.0})}
    b = {round(s.coordinates["theta"], 9) for s in steady_motions(hoop, params={"w": 5.0}, t=0.77)}
    assert a == b and len(a) == 4


def test_kepler_circular_orbit():
    red = reduce(systems.central_potential())
    mass, k, C = 2.0, 3.0, 1.7
    [s] = steady_motions(red, {"C_phi": C}, params={"m": mass, "k": k})
    r0 = C**2 / (mass * k)
    assert s.coordinates["r"] == pytest.approx(r0, rel=1e-12)
    assert s.velocities["phi"] == pytest.approx(C / (mass * r0**2), rel=1e-12)
    # Closed Kepler orbits: the radial (epicyclic) frequency equals the orbital one.
    assert s.stable and s.frequencies == pytest.approx([s.velocities["phi"]], rel=1e-9)


def test_double_pendulum_equilibria():
    motions = steady_motions(systems.double_pendulum())
    found = sorted((round(s.coordinates["theta1"], 8), round(s.coordinates["theta2"], 8), s.stable)
                   for s in motions)
    p = round(math.pi, 8)
    assert found == [(0.0, 0.0, True), (0.0, p, False), (p, 0.0, False), (p, p, False)]


def test_no_real_steady_motion():
    # L = q'^2/2 - (q^3/3 + q): dV/dq = q^2 + 1 > 0 has no real root.
    mod = lcg.Model("cubic")
    q, = mod.coordinates("q")
    mod.kinetic_energy(mod.dot(q) ** 2 / 2)
    mod.potential_energy(q**3 / 3 + q)
    with pytest.raises(ModelError, match="no real steady motion"):
        steady_motions(mod)
    # ... whereas q^3/3 - q has the equilibria q = -1 (unstable) and q = 1 (stable).
    mod2 = lcg.Model("cubic2")
    q, = mod2.coordinates("q")
    mod2.kinetic_energy(mod2.dot(q) ** 2 / 2)
    mod2.potential_energy(q**3 / 3 - q)
    found = [(s.coordinates["q"], s.stable) for s in steady_motions(mod2)]
    assert [round(x, 10) for x, _ in found] == [-1.0, 1.0] and [st for _, st in found] == [False, True]


def test_argument_errors(sph, hoop):
    with pytest.raises(ModelError, match="no ignorable coordinate"):
        steady_motions(hoop, {"C_phi": 1.0})
    with pytest.raises(ModelError, match="not an integral"):
        steady_motions(sph, {"C_theta": 1.0})
    with pytest.raises(ModelError, match="not a parameter"):
        steady_motions(sph, params={"C_phi": 1.0})


def test_reconstruction_with_cross_terms():
    """T = a'^2/2 + (2 + sin^2 a) b'^2/2 + cos(a) a' b'/2: b is ignorable and its rate dR/dC_b
    (eq. 3.11) holds a' (the cross term); at a steady motion a' = 0, so b' = C/(2 + sin^2 a)
    (this raised sympy's "Cannot convert expression to float")."""
    import sympy as sp
    m = lcg.Model("cross")
    a, b = m.coordinates("a b")
    k, = m.parameters(k=2.0)
    m.kinetic_energy(m.dot(a)**2 / 2 + (2 + sp.sin(a)**2) * m.dot(b)**2 / 2 + sp.cos(a) * m.dot(a) * m.dot(b) / 2)
    m.potential_energy(k * (1 - sp.cos(a)))
    C = 1.3
    motions = steady_motions(m, {"C_b": C})
    assert len(motions) >= 2
    for s in motions:
        x = s.coordinates["a"]
        assert s.velocities["b"] == pytest.approx(C / (2 + math.sin(x) ** 2), rel=1e-12)


# ---------------------------------------------------------------------- constrained systems
def test_cartesian_pendulum_equilibria():
    from helpers import cartesian_pendulum
    l, g = 0.8, 9.81
    bottom, top = steady_motions(cartesian_pendulum(), params={"l": l})
    assert (bottom.coordinates["x"], bottom.coordinates["y"]) == pytest.approx((0.0, -l), abs=1e-12)
    assert (top.coordinates["x"], top.coordinates["y"]) == pytest.approx((0.0, l), abs=1e-12)
    assert bottom.stable and not top.stable
    assert bottom.frequencies == pytest.approx([math.sqrt(g / l)], rel=1e-10)
    assert bottom.linearization.multipliers[0] == pytest.approx(-g / (2 * l), rel=1e-10)  # tension m g


def test_particle_on_a_circle_in_a_saddle_potential():
    """x^2 + y^2 = r^2, V = k x y = (k r^2 / 2) sin 2 theta: equilibria at theta = +-pi/4, +-3pi/4,
    stable where sin 2 theta < 0 with w^2 = 2 k / m."""
    import sympy as sp
    from lagcodegen.theory.constraints import ConstrainedSystem
    mod = lcg.Model("saddle")
    x, y = mod.coordinates("x y")
    k, mass, r = mod.parameters(k=3.0, m=1.5, r=0.7)
    mod.particle("p", mass, (x, y))
    mod.potential_energy(k * x * y)
    motions = steady_motions(ConstrainedSystem(mod, holonomic=[x**2 + y**2 - r**2]))
    angles = sorted(round(math.atan2(s.coordinates["y"], s.coordinates["x"]) / (math.pi / 4)) for s in motions)
    assert angles == [-3, -1, 1, 3]
    for s in motions:
        th = math.atan2(s.coordinates["y"], s.coordinates["x"])
        assert math.hypot(s.coordinates["x"], s.coordinates["y"]) == pytest.approx(0.7, rel=1e-12)
        assert s.stable == (math.sin(2 * th) < 0)
        if s.stable:
            assert s.frequencies == pytest.approx([math.sqrt(2 * 3.0 / 1.5)], rel=1e-10)
    assert sp  # (sympy only for the model's symbols)


def test_constrained_scope():
    from helpers import cartesian_pendulum, knife_edge
    with pytest.raises(ModelError, match="nonholonomic constraints .* are not searched.*linearize"):
        steady_motions(knife_edge())
    with pytest.raises(ModelError, match="integrals are for Routh"):
        steady_motions(cartesian_pendulum(), {"C_x": 1.0})
