"""Contacts with restitution (lagcodegen.Inequality): impacts, persistent contact and release on
the impact driver, checked against independent facts (closed-form bouncing ball, momentum and
energy of a cradle, the impact ratio of a rocking block, Newton's law and the energy loss of the
normal approach energy of a double pendulum hitting a wall)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp

import lagcodegen as lcg
from lagcodegen.api import compile_constrained, compile_file
from lagcodegen.derivation import derive
from lagcodegen.errors import LagcodegenError, ModelError

G = 9.81


def _ball(e: float, formulation: str = "index1", lang: str = "c"):
    """The ball on the floor y >= 0 (restitution e), compiled with its model code in ``lang``."""
    m = lcg.Model("ball")
    (y,) = m.coordinates("y")
    m.parameters(g=G, m=1.0)
    m.particle("b", sp.Symbol("m"), (0, y))
    m.gravity(sp.Symbol("g"))
    return compile_constrained(lcg.ConstrainedSystem(m, inequalities=[lcg.Inequality(y, restitution=e)]),
                               formulation, outputs=["energy"], lang=lang)


@pytest.mark.parametrize("formulation", ["index1", "ggl", "minimal"])
def test_bouncing_ball_impact_times_apex_heights_zeno_and_resting_contact(formulation):
    """The same bounds on every formulation that takes contacts (index-1 and GGL on their impact
    drivers, minimal coordinates)."""
    ball = _ball(0.8, formulation)
    e, h0 = 0.8, 1.0
    t1 = math.sqrt(2 * h0 / G)
    speed = 1e-6
    res = ball.simulate(np.linspace(0, 6, 6001), q0=[h0], v0=[0.0], rtol=1e-12, atol=1e-14,
                        contacts=lcg.ContactOptions(contact_speed=speed))
    assert res.formulation == formulation
    bounces = res.impacts.select("bounce")
    assert len(bounces) >= 20
    # impact k at t1 + 2 t1 e (1 - e^k) / (1 - e); rebound speed e^(k+1) sqrt(2 g h0)
    k = np.arange(20)
    t_exact = t1 + 2 * t1 * e * (1 - e**k) / (1 - e)
    t_found = np.array([r.t for r in bounces[:20]])
    assert np.max(np.abs(t_found / t_exact - 1)) < 1e-9
    w_after = np.array([r.w_after for r in bounces[:20]])
    assert np.max(np.abs(w_after / (e ** (k + 1) * math.sqrt(2 * G * h0)) - 1)) < 1e-9
    # Newton's law and the impulse m (1 + e) |w-| of each impact
    for r in bounces[:20]:
        assert r.w_after == pytest.approx(-e * r.w_before, rel=1e-12)
        assert r.impulse == pytest.approx(-(1 + e) * r.w_before, rel=1e-12)
    # apex heights h0 e^(2k): the maximum of y between impacts k-1 and k, from the velocity after
    # impact k-1 (apex = w+^2 / 2g) and checked on the output grid where an apex falls on it
    apex = w_after**2 / (2 * G)
    assert np.max(np.abs(apex / (h0 * e ** (2 * (k + 1))) - 1)) < 1e-9
    # accumulation (Zeno) at t1 (1 + e) / (1 - e): persistent contact begins before it, by at most
    # the flight left after a rebound of speed <= contact_speed / e, 2 (speed / e) / (g (1 - e))
    t_zeno = t1 * (1 + e) / (1 - e)
    sticks = res.impacts.select("stick")
    assert len(sticks) == 1
    assert t_zeno - 2 * (speed / e) / (G * (1 - e)) - 1e-9 <= sticks[0].t <= t_zeno + 1e-9
    assert res.impacts.final_modes == {0: "contact"}
    assert res.impacts.accumulation_time(0) == pytest.approx(t_zeno, rel=1e-9)
    # resting: y = 0, the multiplier m g (A = dy/dy = 1, lambda A = m g up)
    after = res.t > t_zeno + 1e-3
    assert np.max(np.abs(res["lambda_ineq_0"][after] - G)) < 1e-9
    assert np.max(np.abs(res["y"][after])) < 1e-9
    assert np.all(res["lambda_ineq_0"][res.t < sticks[0].t] == 0.0)


@pytest.mark.parametrize("formulation", ["index1", "ggl", "minimal"])
@pytest.mark.parametrize("e", [0.1, 0.5, 0.8])
@pytest.mark.parametrize("tolerances", [{}, {"rtol": 1e-8, "atol": 1e-10}, {"rtol": 1e-4, "atol": 1e-6}])
def test_bouncing_ball_never_tunnels_at_ordinary_tolerances(e, tolerances, formulation):
    """At default or loose tolerances the steps near the accumulation point are longer than the
    last flights: a step skips a whole flight and CVODE's sign test sees no root (the ball fell to
    y = -18 m at rtol 1e-8, -146 m at the defaults). The driver finds the skipped crossing, the
    ball rests on the floor held by m g, the gap never goes further below zero than gap_tol plus
    one step's fall, and that depth is reported (stats['max_penetration'])."""
    h0 = 1.0
    sim = _ball(e, formulation)
    res = sim.simulate(np.linspace(0, 6, 601), q0=[h0], v0=[0.0], **tolerances)
    y = res["y"]
    assert y.min() > -1e-6, y.min()
    assert abs(y[-1]) < 1e-6 and res["lambda_ineq_0"][-1] == pytest.approx(G, rel=1e-6)
    # the first impacts at the closed-form times, the accumulation at t1 (1 + e) / (1 - e)
    t1 = math.sqrt(2 * h0 / G)
    first = [r.t for r in res.impacts.select("bounce")[:3]]
    k = np.arange(len(first))
    rtol = tolerances.get("rtol", 1e-6)
    assert np.allclose(first, t1 + 2 * t1 * e * (1 - e**k) / (1 - e), rtol=max(100 * rtol, 1e-9))
    assert res.impacts.select("stick")[0].t == pytest.approx(t1 * (1 + e) / (1 - e), rel=1e-2)
    assert 0 <= res.stats["max_penetration"] < 1e-6
    assert res.stats["max_penetration"] == pytest.approx(max(0.0, -y.min()), abs=1e-12) or y.min() >= 0


def lifting_floor():
    """A ball resting on a moving floor y_f(t) = t^2/2 - 10 t^3/3 (y_f'' = 1 - 20 t), index-1."""
    m = lcg.Model("lift")
    (y,) = m.coordinates("y")
    m.parameters(g=G, m=1.0)
    m.particle("b", sp.Symbol("m"), (0, y))
    m.gravity(sp.Symbol("g"))
    t = m.t
    floor = 0.5 * t**2 - sp.Rational(10, 3) * t**3
    return compile_constrained(lcg.ConstrainedSystem(m, inequalities=[lcg.Inequality(y - floor, restitution=0.5)]),
                               "index1")


def test_ball_released_when_the_floor_would_pull():
    # a moving floor y_f(t) with y_f'' = 1 - 20 t: the ball resting on it is pushed with the
    # multiplier lambda = m (g + y_f'') = m (g + 1 - 20 t), released where that turns negative,
    # at t = (g + 1) / 20, then flies freely above the floor (which accelerates downwards
    # faster than g)
    sim = lifting_floor()
    res = sim.simulate(np.linspace(0, 0.8, 81), q0=[0.0], v0=[0.0], rtol=1e-11, atol=1e-13)
    releases = res.impacts.select("release")
    assert releases, res.impacts.records
    assert releases[0].t == pytest.approx((G + 1) / 20, rel=1e-8)
    t_off = releases[0].t
    before, after = res.t < t_off, res.t > t_off
    assert np.all(np.abs(res["lambda_ineq_0"][before] - (G + 1 - 20 * res.t[before])) < 1e-8)
    assert np.all(res["lambda_ineq_0"][after] == 0.0)
    tt = res.t[after]
    assert np.all(res["y"][after] > 0.5 * tt**2 - 10 / 3 * tt**3)
    assert len(res.impacts) == 1


def sphere_contact(formulation: str):
    """A particle outside the sphere x^2 + y^2 >= R^2 (R = 1) as a plastic contact."""
    m = lcg.Model("sphere_contact")
    x, y = m.coordinates("x y")
    m.parameters(R=1.0, g=G, m=1.0)
    m.particle("p", sp.Symbol("m"), (x, y))
    m.gravity(sp.Symbol("g"))
    contact = lcg.Inequality(x**2 + y**2 - sp.Symbol("R") ** 2, restitution=0.0)
    return compile_constrained(lcg.ConstrainedSystem(m, inequalities=[contact]), formulation, outputs=["energy"])


@pytest.mark.parametrize("formulation", ["index1", "ggl"])
def test_particle_leaves_the_sphere_in_the_same_run(formulation):
    # the sphere x^2 + y^2 >= R^2 as a contact: the particle starts on top at rest relative to
    # it (persistent contact, multiplier > 0), is released where the multiplier turns negative,
    # at cos(theta) = (2 + v0^2 / (g R)) / 3, and flies on in the same call
    sim = sphere_contact(formulation)
    v0 = 1e-3
    res = sim.simulate(np.linspace(0, 3.2, 321), q0=[0.0, 1.0], v0=[v0, 0.0], rtol=1e-11, atol=1e-13)
    assert [r.kind for r in res.impacts] == ["release"]
    t_off = res.impacts[0].t
    if formulation == "ggl":  # the contact a row of the GGL residual: x^2 + y^2 = R^2 held to the Newton tolerance
        on = res.t < t_off
        assert np.max(np.abs(res["x"][on] ** 2 + res["y"][on] ** 2 - 1.0)) < 1e-10
    at = sim.simulate(np.array([0.0, t_off]), q0=[0.0, 1.0], v0=[v0, 0.0], rtol=1e-11, atol=1e-13)
    assert at["y"][-1] == pytest.approx((2 + v0**2 / G) / 3, rel=1e-8)
    assert np.all(res["lambda_ineq_0"][res.t > t_off] == 0.0)
    assert np.all(res["lambda_ineq_0"][res.t < t_off] > 0.0)
    assert np.max(np.abs(res["energy"] - res["energy"][0])) < 1e-8
    # free flight after leaving: a parabola from the release state
    tau = res.t[res.t > t_off + 0.1] - t_off
    yq = at["y"][-1] + at["y_dot"][-1] * tau - G / 2 * tau**2
    assert np.max(np.abs(res["y"][res.t > t_off + 0.1] - yq)) < 1e-7
    assert res.impacts.final_modes == {0: "free"}


def newtons_cradle(formulation: str = "index1", lang: str = "c"):
    """Three balls of diameter d = 0.1 on a line, elastic contacts between neighbours, compiled
    with ``formulation`` and its model code in ``lang``."""
    m = lcg.Model("cradle")
    xs = m.coordinates("x1 x2 x3")
    m.parameters(m=1.0, d=0.1)
    for i, x in enumerate(xs):
        m.particle(f"b{i}", sp.Symbol("m"), (x, 0))
    d = sp.Symbol("d")
    ineqs = [lcg.Inequality(xs[1] - xs[0] - d, restitution=1.0), lcg.Inequality(xs[2] - xs[1] - d, restitution=1.0)]
    return compile_constrained(lcg.ConstrainedSystem(m, inequalities=ineqs), formulation, outputs=["energy"],
                               lang=lang)


@pytest.mark.parametrize("formulation", ["index1", "ggl", "minimal"])
def test_newtons_cradle_passes_the_velocity_to_the_last_ball(formulation):
    sim = newtons_cradle(formulation)
    gap = 1e-3
    res = sim.simulate(np.linspace(0, 1, 11), q0=[0.0, 0.1 + gap, 0.2 + 2 * gap], v0=[1.0, 0.0, 0.0],
                       rtol=1e-12, atol=1e-14)
    v = res.y[-1, 3:]
    assert abs(v[0]) < 1e-12 and abs(v[1]) < 1e-12 and abs(v[2] - 1.0) < 1e-12
    assert [r.contact for r in res.impacts] == [0, 1]
    assert [r.kind for r in res.impacts] == ["bounce", "bounce"]
    assert res.impacts[0].t == pytest.approx(gap, rel=1e-10)
    assert res.impacts[1].t == pytest.approx(2 * gap, rel=1e-10)
    momentum = res.y[:, 3:].sum(axis=1)
    assert np.max(np.abs(momentum - 1.0)) < 1e-12
    assert np.max(np.abs(res["energy"] - 0.5)) < 1e-12


def _rocking_block():
    m = lcg.Model("block")
    x, y, phi = m.coordinates("x y phi")
    m.parameters(m=1.0, b=0.2, h=0.6, g=G)
    mass, b, h = sp.symbols("m b h")
    m.planar_body("block", mass, mass * (b**2 + h**2) / 3, (x, y), phi)
    m.gravity(sp.Symbol("g"))
    # heights of the bottom corners (-b, -h) (contact 0) and (b, -h) (contact 1), rotated by phi
    left = y - b * sp.sin(phi) - h * sp.cos(phi)
    right = y + b * sp.sin(phi) - h * sp.cos(phi)
    system = lcg.ConstrainedSystem(m, inequalities=[lcg.Inequality(left, restitution=0.0),
                                                    lcg.Inequality(right, restitution=0.0)])
    return compile_constrained(system, "index1", outputs=["energy"])


def test_rocking_block_impact_ratio_on_a_frictionless_floor():
    # The block (half-width b, half-height h, I_c = m R^2 / 3) leans on its left corner at rest and
    # falls back; at phi = 0 the right corner hits plastically and the left one lifts off.
    # Frictionless contacts: no horizontal impulse, so from the angular momentum about the centre
    # and the vertical momentum (I_c + m b^2) w+ = (I_c - m b^2) w-, the ratio
    # (1 - 3 sin^2 a) / (1 + 3 sin^2 a) with sin a = b / R (Housner's block, which does not slip,
    # has 1 - 1.5 sin^2 a; this model's contacts have no friction).
    b, h, phi0 = 0.2, 0.6, 0.1
    sim = _rocking_block()
    y0 = h * math.cos(phi0) + b * math.sin(phi0)  # on the left corner
    res = sim.simulate(np.linspace(0, 1.0, 101), q0=[0.0, y0, phi0], v0=[0.0, 0.0, 0.0], rtol=1e-12, atol=1e-14)
    first = res.impacts.select("stick")[0]
    assert first.contact == 1
    t_hit = first.t
    # the impulse of the left corner would pull: it is left out of the impact and released
    assert [(r.contact, r.kind, r.t) for r in res.impacts if r.t <= t_hit] == [(0, "release", t_hit),
                                                                                (1, "stick", t_hit)]
    assert np.max(np.abs(res["x"])) < 1e-12  # no horizontal force
    dt = 1e-9
    near = sim.simulate(np.array([0.0, t_hit - dt, t_hit + dt]), q0=[0.0, y0, phi0], v0=[0.0, 0.0, 0.0],
                        rtol=1e-12, atol=1e-14)
    w_minus, w_plus = near["phi_dot"][1], near["phi_dot"][2]
    # w- from the energy: m g (y0 - h) = 1/2 (m b^2 + I_c) w-^2 (vy = b w on the left corner at phi = 0)
    Ic = (b**2 + h**2) / 3
    assert abs(w_minus) == pytest.approx(math.sqrt(2 * G * (y0 - h) / (b**2 + Ic)), rel=1e-7)
    sin2 = b**2 / (b**2 + h**2)
    assert w_plus / w_minus == pytest.approx((1 - 3 * sin2) / (1 + 3 * sin2), rel=1e-7)
    # the impulse of the right corner: m (vy+ - vy-) = m b (w+ + w-) ... with vy- = b w-, vy+ = -b w+
    assert first.impulse == pytest.approx(-b * (w_plus + w_minus), rel=1e-6)


@pytest.mark.parametrize("rtol", [1e-12, 1e-8])
def test_rocking_block_rocks_down_to_rest_flat_on_both_corners(rtol):
    """After the first impact the frictionless block rocks with amplitudes shrinking by the ratio
    above; the rocks accumulate and it comes to rest flat on both corners, each carrying half its
    weight (m g / 2 by symmetry), at rest. The contacts touching at rest are chosen together at each
    switch (the LCP of the impact law): before, the corners alternated ever faster and the step
    budget was used up at t = 1.96 s at rtol 1e-12."""
    b, h, phi0 = 0.2, 0.6, 0.1
    sim = _rocking_block()
    y0 = h * math.cos(phi0) + b * math.sin(phi0)
    res = sim.simulate(np.linspace(0, 3.0, 301), q0=[0.0, y0, phi0], v0=[0.0, 0.0, 0.0], rtol=rtol, atol=rtol * 1e-2)
    assert res.success and len(res.impacts.records) < 200
    assert res.impacts.final_modes == {0: "contact", 1: "contact"}
    assert abs(res["phi"][-1]) < 1e-9 and abs(res["y"][-1] - h) < 1e-9
    assert np.abs(res.y[-1, 3:]).max() < 1e-9
    assert res["lambda_ineq_0"][-1] == pytest.approx(G / 2, rel=1e-6)
    assert res["lambda_ineq_1"][-1] == pytest.approx(G / 2, rel=1e-6)


def housner_block(name: str, b: float, h: float) -> lcg.ConstrainedSystem:
    """A block of half-width b and half-height h (coordinates x, y, phi of its centre) on two
    rough corners: plastic contacts that do not slip while touching (tangent = the corner's x)."""
    m = lcg.Model(name)
    x, y, phi = m.coordinates("x y phi")
    m.parameters(m=1.0, b=b, h=h, g=G)
    mass, B, H = sp.symbols("m b h")
    m.planar_body("block", mass, mass * (B**2 + H**2) / 3, (x, y), phi)
    m.gravity(sp.Symbol("g"))
    corners = [(x - B * sp.cos(phi) + H * sp.sin(phi), y - B * sp.sin(phi) - H * sp.cos(phi)),
               (x + B * sp.cos(phi) + H * sp.sin(phi), y + B * sp.sin(phi) - H * sp.cos(phi))]
    return lcg.ConstrainedSystem(m, inequalities=[lcg.Inequality(cy, restitution=0.0, tangent=cx)
                                                  for cx, cy in corners])


def test_housner_rocking_block_on_no_slip_corners():
    # Rough corners (Inequality(..., tangent=x of the corner): no slip while touching): the block
    # pivots on one corner; at phi = 0 the other corner hits plastically (the first one's impulse
    # would pull: released), and the angular momentum about the new corner is kept:
    # w+/w- = 1 - 2 m R^2 sin^2 a / I_0 = 1 - 1.5 sin^2 a with I_0 = (4/3) m R^2 (Housner 1963)
    b, h, phi0 = 0.2, 0.6, 0.1
    sim = compile_constrained(housner_block("housner", b, h), "index1", outputs=["energy"])
    # leaning on the left corner, which stays at x = -b
    q0 = [-b + b * math.cos(phi0) - h * math.sin(phi0), h * math.cos(phi0) + b * math.sin(phi0), phi0]
    res = sim.simulate(np.linspace(0, 1.0, 101), q0=q0, v0=[0.0, 0.0, 0.0], rtol=1e-12, atol=1e-14)
    sticks = res.impacts.select("stick")
    assert [r.contact for r in sticks[:2]] == [1, 0]
    t_hit = sticks[0].t
    assert [(r.contact, r.kind) for r in res.impacts if r.t == t_hit] == [(0, "release"), (1, "stick")]
    # before the impact the left corner does not move: x_L = -b, y_L = 0
    before = res.t < t_hit
    xl = res["x"] - b * np.cos(res["phi"]) + h * np.sin(res["phi"])
    assert np.max(np.abs(xl[before] + b)) < 1e-9
    # the time to fall back: the pendulum about the corner, I_0 phi'' = m g R sin(a - phi), from rest
    R, a = math.hypot(b, h), math.atan2(b, h)
    I0 = 4 / 3 * R**2
    from scipy.integrate import quad
    fall = quad(lambda p: 1 / math.sqrt(2 * G * R * (math.cos(a - phi0) - math.cos(a - p)) / I0), 0, phi0,
                limit=200)[0]
    assert t_hit == pytest.approx(fall, rel=1e-7)
    dt = 1e-9
    near = sim.simulate(np.array([0.0, t_hit - dt, t_hit + dt]), q0=q0, v0=[0.0, 0.0, 0.0], rtol=1e-12, atol=1e-14)
    w_minus, w_plus = near["phi_dot"][1], near["phi_dot"][2]
    assert w_minus == pytest.approx(-math.sqrt(2 * G * R * (math.cos(a - phi0) - math.cos(a)) / I0), rel=1e-7)
    assert w_plus / w_minus == pytest.approx(1 - 1.5 * math.sin(a) ** 2, rel=1e-7)


def test_double_pendulum_hitting_a_wall_loses_1_minus_e2_of_its_normal_approach_energy():
    m = lcg.Model("dpwall")
    th1, th2 = m.coordinates("th1 th2")
    m.parameters(m1=1.0, m2=0.7, l1=1.0, l2=0.8, g=G, d=0.9)
    m1, m2, l1, l2, d = sp.symbols("m1 m2 l1 l2 d")
    x1, y1 = l1 * sp.sin(th1), -l1 * sp.cos(th1)
    x2, y2 = x1 + l2 * sp.sin(th2), y1 - l2 * sp.cos(th2)
    m.particle("p1", m1, (x1, y1))
    m.particle("p2", m2, (x2, y2))
    m.gravity(sp.Symbol("g"))
    e = 0.6
    system = lcg.ConstrainedSystem(m, inequalities=[lcg.Inequality(d - x2, restitution=e)])  # wall at x = d
    sim = compile_constrained(system, "index1", outputs=["energy"])
    res = sim.simulate(np.linspace(0, 3, 301), q0=[-0.8, -1.2], v0=[0.0, 0.0], rtol=1e-12, atol=1e-14)
    hits = res.impacts.select("bounce")
    assert len(hits) >= 2
    # the mass matrix from the derivation (sympy), G = dg/dq, at each impact state
    eom = derive(m)
    vals = {s: v for s, v in m.params.items()}
    g_expr = d - x2
    Gq = [sp.diff(g_expr, q) for q in (th1, th2)]
    Mf = sp.lambdify((th1, th2), eom.M.subs(vals))
    Gf = sp.lambdify((th1, th2), sp.Matrix([Gq]).subs(vals))
    for r in hits[:2]:
        k = np.searchsorted(res.t, r.t)  # energy is constant between impacts: compare around it
        E_before, E_after = res["energy"][k - 1], res["energy"][k]
        assert r.w_after == pytest.approx(-e * r.w_before, rel=1e-10)
        # the state at the impact: integrate to it (the jump changes only velocities)
        at = sim.simulate(np.array([0.0, r.t]), q0=[-0.8, -1.2], v0=[0.0, 0.0], rtol=1e-12, atol=1e-14)
        q = at.y[-1, :2]
        M = np.array(Mf(*q), dtype=float)
        Gr = np.array(Gf(*q), dtype=float).reshape(1, 2)
        normal_energy = 0.5 * r.w_before**2 / (Gr @ np.linalg.solve(M, Gr.T)).item()
        assert E_before - E_after == pytest.approx((1 - e**2) * normal_energy, rel=1e-7)


def test_contact_input_errors():
    with pytest.raises(ModelError, match="restitution must be in"):
        lcg.Inequality(sp.Symbol("y"), restitution=1.5)
    with pytest.raises(ModelError, match="restitution must be a number"):
        lcg.Inequality(sp.Symbol("y"), restitution="high")
    with pytest.raises(LagcodegenError, match="contact_speed"):
        lcg.ContactOptions(contact_speed=-1.0)
    m = lcg.Model("ball2")
    (y,) = m.coordinates("y")
    m.parameters(g=G, m=1.0)
    m.particle("b", sp.Symbol("m"), (0, y))
    m.gravity(sp.Symbol("g"))
    system = lcg.ConstrainedSystem(m, inequalities=[lcg.Inequality(y, restitution=0.5)])
    sim = compile_constrained(system, "index1")
    with pytest.raises(ModelError, match="violated"):
        sim.simulate((0, 1), q0=[-0.5], v0=[0.0])
    with pytest.raises(LagcodegenError, match="projection"):
        sim.simulate((0, 1), q0=[0.5], v0=[0.0], projection=True)
    with pytest.raises(LagcodegenError, match="projection"):
        sim.ensemble((0, 1), q0=[[0.5]], v0=[[0.0]], projection=True)
    with pytest.raises(LagcodegenError, match="projection"):
        sim.integrator(q0=[0.5], v0=[0.0], projection=True)
    with pytest.raises(ModelError, match="violated"):
        sim.integrator(q0=[-0.5], v0=[0.0])


def test_plain_inequality_keeps_its_terminal_event():
    # an expression without restitution is still the terminal event ineq_0 (no contact code)
    m = lcg.Model("ball3")
    (y,) = m.coordinates("y")
    m.parameters(g=G, m=1.0)
    m.particle("b", sp.Symbol("m"), (0, y))
    m.gravity(sp.Symbol("g"))
    sim = compile_constrained(lcg.ConstrainedSystem(m, inequalities=[lcg.Inequality(y)]), "index1")
    assert not any(name.endswith("_impact.c") for name in sim.compiled.code.files)
    res = sim.simulate((0, 2), q0=[1.0], v0=[0.0], rtol=1e-12, atol=1e-14)
    assert res.impacts is None
    assert res.events[-1].name == "ineq_0"
    assert res.events[-1].t == pytest.approx(math.sqrt(2 / G), rel=1e-10)


def test_model_file_contact_runs_like_the_python_system():
    from pathlib import Path

    from lagcodegen.modelfile import ModelFileError, load_model, loads_model

    path = Path(__file__).resolve().parent.parent / "examples" / "bouncing_ball.toml"
    mf = load_model(path)
    assert mf.constrained.restitution == [0.8]
    res = mf.simulate(compile_file(mf))
    t1 = math.sqrt(2 / G)
    first = [r.t for r in res.impacts.select("bounce")][:3]
    exact = [t1 + 2 * t1 * 0.8 * (1 - 0.8**k) / 0.2 for k in range(3)]
    assert np.max(np.abs(np.array(first) / exact - 1)) < 1e-9
    assert res["lambda_ineq_0"][-1] == pytest.approx(G, rel=1e-9)
    with pytest.raises(ModelFileError, match="restitution"):
        loads_model(path.read_text().replace("restitution = 0.8", "restitution = 1.8"))
    with pytest.raises(ModelFileError, match="unknown key"):
        loads_model(path.read_text().replace("restitution = 0.8", "restituion = 0.8"))


def test_generate_and_bundle_of_a_contact_file(tmp_path, fc):
    from pathlib import Path

    from lagcodegen.api import generate_file
    from lagcodegen.modelfile import load_model

    mf = load_model(Path(__file__).resolve().parent.parent / "examples" / "bouncing_ball.toml")
    files = generate_file(mf)
    assert {"bouncing_ball_impact.c", "bouncing_ball_dae_table.c", "lcg_imp_model.h"} <= set(files)
    for name, text in files.items():
        (tmp_path / name).write_text(text)
    import subprocess
    for name in ("bouncing_ball_impact.c", "bouncing_ball_dae.c", "bouncing_ball_dae_table.c"):
        proc = subprocess.run(["cc", "-Wall", "-Wextra", "-Werror", "-std=c99", "-pedantic", "-c", name, "-o",
                               "/dev/null"], cwd=tmp_path, capture_output=True, text=True)
        assert proc.returncode == 0, proc.stderr
    # they link into a program (the tables point to the unconstrained model's table, shipped too)
    # that takes one impact: Newton's law w+ = -e w- at the floor
    (tmp_path / "main.c").write_text(
        '#include <math.h>\n#include "lcg_imp_model.h"\n'
        "const lcg_imp_model *bouncing_ball_imp_model_table(void);\n"
        "int main(void)\n{\n    const lcg_imp_model *im = bouncing_ball_imp_model_table();\n"
        "    double y[2] = {0.0, -2.0}, ynew[2], P[1], e[1] = {0.8}, p[2] = {1.0, 1.0}; /* g, m: m = 1 */\n"
        "    int on[1] = {1};\n"
        "    if (im->impact(0.0, y, p, on, e, ynew, P) != 0)\n        return 2;\n"
        "    return fabs(ynew[1] - 1.6) < 1e-12 && fabs(P[0] - 3.6) < 1e-12 ? 0 : 1;\n}\n")
    c_files = sorted(n for n in files if n.endswith(".c"))
    proc = subprocess.run(["cc", "-Wall", "-Wextra", "-Werror", "-std=c99", "-pedantic", "main.c", *c_files, "-lm",
                           "-o", "main"], cwd=tmp_path, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    assert subprocess.run([str(tmp_path / "main")]).returncode == 0
    bundle = generate_file(mf, bundle=True)  # the impact law in the bundle's C (tests/codegen/test_bundle_contacts.py)
    assert {"bouncing_ball_impact.c", "rk4_example.c", "reference.csv"} <= set(bundle)
    assert "bouncing_ball_imp_model_table()" in bundle["rk4_example.c"]
    # in Fortran: the contact functions <prefix>_impact.f90 (strict gfortran) with their C tables
    # <prefix>_impact_table.c, and the same program linked with them takes the same impact
    files = generate_file(mf, lang="fortran")
    assert {"bouncing_ball_impact.f90", "bouncing_ball_impact_table.c", "bouncing_ball.f90",
            "bouncing_ball_dae.f90"} <= set(files) and not any(n.endswith("_impact.c") for n in files)
    folder = tmp_path / "fortran"
    folder.mkdir()
    for name, text in files.items():
        (folder / name).write_text(text)
    (folder / "main.c").write_text((tmp_path / "main.c").read_text())
    from helpers import STRICT_FFLAGS
    sources = ["bouncing_ball.f90", "bouncing_ball_dae.f90", "bouncing_ball_impact.f90"]
    proc = subprocess.run([fc, *STRICT_FFLAGS, "-c", *sources], cwd=folder, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    c_files = sorted(n for n in files if n.endswith(".c"))
    proc = subprocess.run(["cc", "-Wall", "-Wextra", "-Werror", "-std=c99", "-pedantic", "main.c", *c_files,
                           *(n[:-4] + ".o" for n in sources), "-lgfortran", "-lm", "-o", "main"], cwd=folder,
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    assert subprocess.run([str(folder / "main")]).returncode == 0


@pytest.mark.parametrize("formulation", ["index1", "ggl"])
def test_ctrl_c_stops_a_long_run_with_impacts(tmp_path, formulation):
    """The impact drivers (index-1 on CVODE, GGL on IDA) poll for Ctrl-C as the other drivers do:
    SIGINT during a run of hours (an elastic ball bouncing for 1e7 s) raises KeyboardInterrupt
    within seconds (a bound)."""
    import textwrap

    from helpers import interrupt_when_ready
    script = tmp_path / "long.py"
    script.write_text(textwrap.dedent("""
        import sys
        import numpy as np
        import sympy as sp
        import lagcodegen as lcg
        from lagcodegen.api import compile_constrained
        m = lcg.Model("ctrlc_ball")
        (y,) = m.coordinates("y")
        m.parameters(g=9.81, m=1.0)
        m.particle("b", sp.Symbol("m"), (0, y))
        m.gravity(sp.Symbol("g"))
        sim = compile_constrained(lcg.ConstrainedSystem(m, inequalities=[lcg.Inequality(y, restitution=1.0)]),
                                  FORMULATION)
        sim.simulate(np.array([0.0, 1.0]), q0=[1.0], v0=[0.0])
        print("ready", flush=True)
        try:
            sim.simulate(np.array([0.0, 1e7]), q0=[1.0], v0=[0.0], max_steps=10**15,
                         contacts=lcg.ContactOptions(max_records=10))
        except KeyboardInterrupt:
            print("interrupted", file=sys.stderr)
            sys.exit(130)
    """).replace("FORMULATION", repr(formulation)))
    returncode, err, took = interrupt_when_ready(script)
    assert returncode == 130, err
    assert "interrupted" in err and took < 10


def test_the_shipped_bouncing_ball_rests_on_the_floor_from_the_command_line(tmp_path):
    """`lagcodegen simulate examples/bouncing_ball.toml --rtol 1e-8 --atol 1e-10` ended at y = -18.4 m
    with exit 0; it rests on the floor, and the energy it loses is reported as the impacts' doing,
    not as a drift of the integration."""
    import os
    import subprocess
    import sys
    from pathlib import Path
    root = Path(__file__).resolve().parents[1]
    out = tmp_path / "bb.csv"
    proc = subprocess.run([sys.executable, "-m", "lagcodegen", "simulate", str(root / "examples" / "bouncing_ball.toml"),
                           "-o", str(out), "--rtol", "1e-8", "--atol", "1e-10"], capture_output=True, text=True,
                          env=dict(os.environ, PYTHONPATH=str(root)), timeout=600)
    assert proc.returncode == 0, proc.stderr
    data = np.loadtxt(out, delimiter=",", skiprows=1)
    header = out.read_text().splitlines()[0].split(",")
    y = data[:, header.index("y")]
    assert y.min() > -1e-6 and abs(y[-1]) < 1e-6
    assert "impact(s)" in proc.stderr and "energy drift" not in proc.stderr
    assert "impacts with a restitution below 1" in proc.stderr
