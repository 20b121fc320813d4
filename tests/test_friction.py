"""Coulomb friction on contacts (lagcodegen.Inequality(..., tangent=..., friction=mu); issue 39):
stick, slip and their transitions in persistent contact, frictional impacts and Painleve's
paradox on the impact driver, checked against closed-form facts (a block on an incline, a sphere
and a disc launched with backspin, the ladder's threshold, the impact of a disc on a rough floor,
Painleve's rod)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp

import lagcodegen as lcg
from lagcodegen.api import compile_constrained
from lagcodegen.errors import LagcodegenError, ModelError
PainleveError = lcg.PainleveError

G = 9.81
TIGHT = {"rtol": 1e-12, "atol": 1e-14}


def _incline(alpha: float, mu: float, *, formulation: str = "index1", lang: str = "c"):
    """A particle on an incline of angle alpha: x down the slope, y normal to it (both lengths);
    compiled with ``formulation`` (the GGL tests, tests/test_friction_ggl.py, use it too), its
    model code in ``lang``."""
    m = lcg.Model("incline")
    x, y = m.coordinates("x y")
    m.parameters(g=G, m=1.0, alpha=alpha)
    a = sp.Symbol("alpha")
    m.particle("b", sp.Symbol("m"), (x * sp.cos(a) + y * sp.sin(a), -x * sp.sin(a) + y * sp.cos(a)))
    m.gravity(sp.Symbol("g"))
    system = lcg.ConstrainedSystem(m, inequalities=[lcg.Inequality(y, restitution=0.0, tangent=x, friction=mu)])
    return compile_constrained(system, formulation, outputs=["energy"], lang=lang)


@pytest.mark.parametrize("alpha, mu", [(0.5, 0.6), (0.5, 0.3), (0.3, 0.1), (0.3, 0.31)])
def test_block_on_an_incline_sticks_when_tan_alpha_le_mu_else_slides_at_g_sin_minus_mu_cos(alpha, mu):
    sim = _incline(alpha, mu)
    t = np.linspace(0, 3, 31)
    res = sim.simulate(t, q0=[0.0, 0.0], v0=[0.0, 0.0], **TIGHT)
    lam_n = res["lambda_ineq_0"]
    assert np.max(np.abs(lam_n / (G * math.cos(alpha)) - 1)) < 1e-9  # N = m g cos(alpha)
    if math.tan(alpha) <= mu:
        assert np.max(np.abs(res["x"])) < 1e-12 and res.impacts.friction_modes == {0: "stick"}
        # the sticking force holds the block: lambda_t = -m g sin(alpha) (up the slope)
        assert np.max(np.abs(res["lambda_t_ineq_0"] + G * math.sin(alpha))) < 1e-9
        assert res.impacts.transitions() == []
    else:
        acc = G * (math.sin(alpha) - mu * math.cos(alpha))
        assert np.max(np.abs(res["x"][1:] / (0.5 * acc * t[1:] ** 2) - 1)) < 1e-9
        assert res.impacts.friction_modes == {0: "slip+"}
        assert np.max(np.abs(res["lambda_t_ineq_0"] + mu * G * math.cos(alpha))) < 1e-9
    assert np.max(np.abs(res["y"])) < 1e-12


def _roller(inertia_factor: float, mu: float, e: float = 0.0, *, formulation: str = "index1"):
    """A sphere (I = 2/5 m R^2) or a disc (1/2 m R^2) of radius R on the floor y = 0: the slip
    velocity of the touching point is x' + R phi' (phi counterclockwise), the tangent x + R phi."""
    m = lcg.Model("roller")
    x, y, phi = m.coordinates("x y phi")
    m.parameters(g=G, m=1.0, R=0.3)
    mass, R = sp.symbols("m R")
    m.planar_body("ball", mass, inertia_factor * mass * R**2, (x, y), phi)
    m.gravity(sp.Symbol("g"))
    contact = lcg.Inequality(y - R, restitution=e, tangent=x + R * phi, friction=mu)
    return compile_constrained(lcg.ConstrainedSystem(m, inequalities=[contact]), formulation, outputs=["energy"])


@pytest.mark.parametrize("body, k, slip_time, roll_speed", [
    # sphere: u' = -mu g (1 + m R^2 / I) = -7/2 mu g; v* = v0 - mu g t*
    ("sphere", 0.4, lambda v0, Rw0, mu: 2 * (v0 + Rw0) / (7 * mu * G), lambda v0, Rw0: (5 * v0 - 2 * Rw0) / 7),
    # disc: u' = -3 mu g, t* = (v0 + R w0) / (3 mu g), v* = (2 v0 - R w0) / 3
    ("disc", 0.5, lambda v0, Rw0, mu: (v0 + Rw0) / (3 * mu * G), lambda v0, Rw0: (2 * v0 - Rw0) / 3),
])
def test_ball_with_backspin_slips_then_rolls(body, k, slip_time, roll_speed):
    mu, R, v0, w0 = 0.2, 0.3, 3.0, 4.0  # w0 > 0: backspin (counterclockwise while moving to +x)
    sim = _roller(k, mu)
    t_star = slip_time(v0, R * w0, mu)
    t = np.linspace(0, 2 * t_star, 40)  # t* between output times
    res = sim.simulate(t, q0=[0.0, R, 0.0], v0=[v0, 0.0, w0], **TIGHT)
    grips = res.impacts.transitions(0)
    assert [r.kind for r in grips] == ["grip"], res.impacts.records
    assert grips[0].t == pytest.approx(t_star, rel=1e-9)
    after = res.t > t_star
    v_roll = roll_speed(v0, R * w0)
    assert np.max(np.abs(res["x_dot"][after] / v_roll - 1)) < 1e-9
    assert np.max(np.abs(res["phi_dot"][after] * R + res["x_dot"][after])) < 1e-9 * abs(v_roll)  # rolling
    assert res.impacts.friction_modes == {0: "stick"}
    # the energy lost is the friction work mu m g |u| integrated: u falls linearly to 0 at t*
    work = mu * G * (v0 + R * w0) * t_star / 2
    lost = res["energy"][0] - res["energy"][-1]
    assert lost == pytest.approx(work, rel=1e-9)
    before = res.t < t_star
    assert np.max(np.abs(res["lambda_t_ineq_0"][before] + mu * G)) < 1e-9
    assert np.max(np.abs(res["lambda_t_ineq_0"][after])) < 1e-9


def _ladder(alpha: float, mu: float, L: float = 2.0, *, formulation: str = "index1"):
    """A uniform ladder (length L, angle theta with the floor) against a frictionless wall x >= 0
    on a rough floor y >= 0: the top (x - L/2 cos theta, y + L/2 sin theta) on the wall, the foot
    (x + L/2 cos theta, y - L/2 sin theta) on the floor."""
    m = lcg.Model("ladder")
    x, y, th = m.coordinates("x y theta")
    m.parameters(g=G, m=1.0, L=L)
    mass, Ls = sp.symbols("m L")
    m.planar_body("ladder", mass, mass * Ls**2 / 12, (x, y), th)
    m.gravity(sp.Symbol("g"))
    wall = lcg.Inequality(x - Ls / 2 * sp.cos(th), restitution=0.0)
    floor = lcg.Inequality(y - Ls / 2 * sp.sin(th), restitution=0.0, tangent=x + Ls / 2 * sp.cos(th), friction=mu)
    sim = compile_constrained(lcg.ConstrainedSystem(m, inequalities=[wall, floor]), formulation)
    q0 = [L / 2 * math.cos(alpha), L / 2 * math.sin(alpha), alpha]
    return sim, q0


@pytest.mark.parametrize("alpha", [0.9, 1.2])
def test_ladder_stays_when_mu_reaches_one_over_two_tan_alpha_and_slips_below(alpha):
    mu_c = 1 / (2 * math.tan(alpha))
    t = np.linspace(0, 0.5, 11)
    for mu, stays in ((mu_c + 1e-6, True), (mu_c - 1e-6, False)):
        sim, q0 = _ladder(alpha, mu)
        res = sim.simulate(t, q0=q0, v0=[0.0, 0.0, 0.0], **TIGHT)
        foot = res["x"] + np.cos(res["theta"])
        if stays:
            assert res.impacts.friction_modes == {1: "stick"}
            assert np.max(np.abs(foot - foot[0])) < 1e-12 and np.max(np.abs(res["theta"] - alpha)) < 1e-12
            # the wall's push mg / (2 tan alpha), the floor's friction as much the other way, N = mg
            assert res["lambda_ineq_0"][-1] == pytest.approx(G * mu_c, rel=1e-9)
            assert res["lambda_t_ineq_1"][-1] == pytest.approx(-G * mu_c, rel=1e-9)
            assert res["lambda_ineq_1"][-1] == pytest.approx(G, rel=1e-9)
        else:
            assert res.impacts.friction_modes[1] == "slip+"
            assert foot[-1] > foot[0] + 1e-9 and res["theta"][-1] < alpha


def _painleve_rod(mu: float, theta0: float, *, formulation: str = "index1"):
    """Painleve's rod: a uniform rod (half-length l, I = m l^2 / 3) with its lower end A on a rough
    floor; A = (x - l cos theta, y - l sin theta)."""
    m = lcg.Model("painleve")
    x, y, th = m.coordinates("x y theta")
    m.parameters(g=G, m=1.0, l=1.0)
    mass, l = sp.symbols("m l")
    m.planar_body("rod", mass, mass * l**2 / 3, (x, y), th)
    m.gravity(sp.Symbol("g"))
    end = lcg.Inequality(y - l * sp.sin(th), restitution=0.0, tangent=x - l * sp.cos(th), friction=mu)
    sim = compile_constrained(lcg.ConstrainedSystem(m, inequalities=[end]), formulation)
    return sim, [math.cos(theta0), math.sin(theta0), theta0]


def test_painleve_rod_is_reported_by_name_not_integrated():
    # G M^-1 (G - sigma mu T)^T = (1 + 3 cos^2 - 3 sigma mu sin cos) / m < 0 for the end sliding
    # with u < 0 (sigma = -1: the end moving to -x) at tan(theta) = 2, mu = 2 (the least mu is 4/3):
    # the contact force would have to be negative (inconsistency) when gravity pulls the end down;
    # with a spin that lifts the end freely, both contact and lift-off are consistent
    # (indeterminacy). Both are Painleve's paradox: an error naming it, never a silent branch.
    theta0 = math.atan(2.0)
    sim, q0 = _painleve_rod(2.0, theta0)
    with pytest.raises(PainleveError, match="Painleve's paradox \\(inconsistency\\)"):
        sim.simulate(np.linspace(0, 1, 11), q0=q0, v0=[-1.0, 0.0, 0.0], **TIGHT)
    spin = 1.2 * math.sqrt(G / math.sin(theta0))  # l sin(theta) theta'^2 > g: the free end rises
    with pytest.raises(PainleveError, match="Painleve's paradox \\(indeterminacy\\)") as err:
        sim.simulate(np.linspace(0, 1, 11), q0=q0, v0=_rod_velocity(theta0, -1.0, spin), **TIGHT)
    assert err.value.t == 0.0
    # sliding the other way the same rod is an ordinary slip: no error
    res = sim.simulate(np.linspace(0, 0.05, 6), q0=q0, v0=[1.0, 0.0, 0.0], **TIGHT)
    assert res.impacts.friction_modes in ({0: "slip+"}, {0: "free"})
    # a small mu, either way: no paradox
    sim2, _ = _painleve_rod(0.3, theta0)
    sim2.simulate(np.linspace(0, 0.05, 6), q0=q0, v0=[-1.0, 0.0, 0.0], **TIGHT)


def _rod_velocity(theta, u, spin):
    """(x', y', theta') with the end A sliding at u along x and not moving normally: A' = (x' +
    l sin(theta) theta', y' - l cos(theta) theta')."""
    return [u - math.sin(theta) * spin, math.cos(theta) * spin, spin]


@pytest.mark.parametrize("vx, mu, sticks", [(1.0, 0.5, True), (4.0, 0.1, False)])
def test_frictional_impact_of_a_disc_sticks_within_the_cone_else_slides_with_mu_pn(vx, mu, sticks):
    # A disc (I = m R^2 / 2) without spin hits the rough floor with (vx, -vy), e = 0.5. Newton's
    # law: P_n = m (1 + e) vy. Sticking needs P_t = -m u / 3 (the tangential effective mass
    # m / (1 + m R^2 / I) = m / 3), admissible when |P_t| <= mu P_n; else P_t = -mu P_n.
    e, R, vy, h = 0.5, 0.3, 2.0, 0.1
    sim = _roller(0.5, mu, e)
    t_hit = (-vy + math.sqrt(vy**2 + 2 * G * h)) / G
    v_hit = vy + G * t_hit
    res = sim.simulate(np.array([0.0, t_hit + 1e-3]), q0=[0.0, R + h, 0.0], v0=[vx, -vy, 0.0], **TIGHT)
    bounce = res.impacts.select("bounce")
    assert len(bounce) == 1 and bounce[0].t == pytest.approx(t_hit, rel=1e-10)
    pn = (1 + e) * v_hit
    assert bounce[0].impulse == pytest.approx(pn, rel=1e-10)
    tang = res.impacts.select("tangential_impulse")
    assert len(tang) == 1
    if sticks:
        assert abs(vx / 3) <= mu * pn
        assert tang[0].impulse == pytest.approx(-vx / 3, rel=1e-10)
        assert abs(tang[0].w_after) < 1e-12  # the touching point stops sliding
        vx_after, w_after = 2 * vx / 3, -2 * vx / (3 * R)
    else:
        assert abs(vx / 3) > mu * pn
        assert tang[0].impulse == pytest.approx(-mu * pn, rel=1e-10)
        vx_after, w_after = vx - mu * pn, -2 * mu * pn / R
        assert tang[0].w_after == pytest.approx(vx_after + R * w_after, rel=1e-10)
        assert tang[0].w_after > 0
    # after the impact the disc flies: x' and phi' are constant
    assert res["x_dot"][-1] == pytest.approx(vx_after, rel=1e-10)
    assert res["phi_dot"][-1] == pytest.approx(w_after, rel=1e-10)


def test_friction_input_errors():
    y, x = sp.symbols("y x")
    with pytest.raises(ModelError, match="friction needs a tangent"):
        lcg.Inequality(y, restitution=0.0, friction=0.5)
    with pytest.raises(ModelError, match="friction must be a finite number >= 0"):
        lcg.Inequality(y, restitution=0.0, tangent=x, friction=-0.1)
    with pytest.raises(ModelError, match="friction must be a finite number >= 0"):
        lcg.Inequality(y, restitution=0.0, tangent=x, friction="rough")
    with pytest.raises(ModelError, match="friction must be a finite number >= 0"):
        lcg.Inequality(y, restitution=0.0, tangent=x, friction=math.inf)
    with pytest.raises(TypeError):
        lcg.Inequality(y, 0.0, x, 0.5)  # friction is keyword-only


def test_existing_contacts_generate_no_friction_table():
    from lagcodegen.codegen.constrained import generate_constrained
    m = lcg.Model("nofr")
    (x, y) = m.coordinates("x y")
    m.parameters(g=G, m=1.0)
    m.particle("b", sp.Symbol("m"), (x, y))
    m.gravity(sp.Symbol("g"))
    plain = lcg.ConstrainedSystem(m, inequalities=[lcg.Inequality(y, restitution=0.5, tangent=x)])
    code, _ = generate_constrained(plain)
    assert "imp_friction" not in code.files["nofr_impact.c"]
    rough = lcg.ConstrainedSystem(m, inequalities=[lcg.Inequality(y, restitution=0.5, tangent=x, friction=0.2)])
    code, _ = generate_constrained(rough)
    assert "nofr_imp_friction_table" in code.files["nofr_impact.c"]


def test_stick_to_slip_located_where_the_sticking_force_reaches_mu_n():
    # A block on a floor that accelerates horizontally at c t (tangent x - c t^3 / 6): it sticks,
    # held by lambda_t = m c t, until m c t = mu m g at t_s = mu g / c, then slips behind the floor
    # with x'' = mu g.
    mu, c = 0.4, 3.0
    m = lcg.Model("belt")
    x, y = m.coordinates("x y")
    m.parameters(g=G, m=1.0)
    m.particle("b", sp.Symbol("m"), (x, y))
    m.gravity(sp.Symbol("g"))
    t = m.t
    floor = lcg.Inequality(y, restitution=0.0, tangent=x - c * t**3 / 6, friction=mu)
    sim = compile_constrained(lcg.ConstrainedSystem(m, inequalities=[floor]), "index1")
    ts = mu * G / c
    tt = np.linspace(0, 2 * ts, 40)
    res = sim.simulate(tt, q0=[0.0, 0.0], v0=[0.0, 0.0], **TIGHT)
    slips = res.impacts.transitions(0)
    assert [r.kind for r in slips] == ["slip"]
    assert slips[0].t == pytest.approx(ts, rel=1e-9)
    assert slips[0].impulse == pytest.approx(mu * G, rel=1e-9)  # lambda_t = mu lambda_n there
    before, after = tt < ts, tt > ts
    assert np.max(np.abs(res["x"][before] - c * tt[before] ** 3 / 6)) < 1e-12
    tau = tt[after] - ts
    x_exact = c * ts**3 / 6 + c * ts**2 / 2 * tau + mu * G * tau**2 / 2
    assert np.max(np.abs(res["x"][after] / x_exact - 1)) < 1e-9
    assert res.impacts.friction_modes == {0: "slip-"}
    assert res.stats["stick_slip"] == 1


@pytest.mark.parametrize("alpha, mu", [(0.5, 0.3), (0.5, 0.7)])
def test_block_sent_up_an_incline_stops_then_sticks_or_slides_back(alpha, mu):
    # x down the slope; launched up (x' = -v0) it decelerates at g (sin + mu cos) and stops at
    # t1 = v0 / (g (sin + mu cos)); there the slip velocity crosses zero: it sticks if
    # tan(alpha) <= mu ("grip"), else slides back down at g (sin - mu cos) ("reverse").
    v0 = 2.0
    sim = _incline(alpha, mu)
    a_up = G * (math.sin(alpha) + mu * math.cos(alpha))
    t1 = v0 / a_up
    tt = np.linspace(0, 2 * t1, 40)
    res = sim.simulate(tt, q0=[0.0, 0.0], v0=[-v0, 0.0], **TIGHT)
    trans = res.impacts.transitions(0)
    assert len(trans) == 1 and trans[0].t == pytest.approx(t1, rel=1e-9)
    x1 = -v0 * t1 + a_up * t1**2 / 2
    before, after = tt < t1, tt > t1
    assert np.max(np.abs(res["x"][before] - (-v0 * tt[before] + a_up * tt[before] ** 2 / 2))) < 1e-9 * abs(x1)
    if math.tan(alpha) <= mu:
        assert trans[0].kind == "grip" and res.impacts.friction_modes == {0: "stick"}
        assert np.max(np.abs(res["x"][after] / x1 - 1)) < 1e-9
    else:
        assert trans[0].kind == "reverse" and res.impacts.friction_modes == {0: "slip+"}
        a_down = G * (math.sin(alpha) - mu * math.cos(alpha))
        tau = tt[after] - t1
        assert np.max(np.abs(res["x"][after] / (x1 + a_down * tau**2 / 2) - 1)) < 1e-9


def test_friction_is_refused_by_solvers_that_cannot_take_it_naming_them():
    sim = _incline(0.5, 0.3)
    with pytest.raises(LagcodegenError, match="solver CVODE \\(backend 'sksundae'\\) cannot take it"):
        sim.simulate((0, 1), q0=[0.0, 0.0], v0=[0.0, 0.0], backend="sksundae")
    from lagcodegen.solvers.taylor.options import Taylor  # the Taylor contact driver takes it (its tests:
    res = sim.simulate((0, 1), q0=[0.0, 0.0], v0=[0.0, 0.0], solver=Taylor())  # tests/test_friction_taylor.py)
    assert res.method == "taylor" and res.impacts.friction_modes == {0: "slip+"}
    # ensembles run each member on the impact driver: friction included, as the single run
    ens = sim.ensemble((0, 1), q0=[[0.0, 0.0]], v0=[[-1.0, 0.0]])
    single = sim.simulate((0, 1), q0=[0.0, 0.0], v0=[-1.0, 0.0])
    assert ens.member(0).impacts.records == single.impacts.records and single.impacts.transitions(0)
    assert ens.member(0).impacts.friction_modes == single.impacts.friction_modes
    assert np.array_equal(ens.y[0], single.y[-1])


SLIDER_FILE = """
[model]
name = "slider"
coordinates = ["x", "y"]

[parameters]
g = 9.81
m = 1.0

[[particles]]
name = "block"
mass = "m"
position = ["x", "y"]

[gravity]
g = "g"

[constraints]
inequalities = [{ expr = "y", restitution = 0.0, tangent = "x", friction = 0.25 }]

[simulation]
formulation = "index1"
t_end = 2.0
n_out = 21
rtol = 1e-12
atol = 1e-14
initial = { x = 0.0, y = 0.0, x_dot = 3.0 }
"""


def test_model_file_friction_slides_to_rest_at_v0_over_mu_g():
    from lagcodegen.api import compile_file
    from lagcodegen.modelfile import ModelFileError, loads_model

    mf = loads_model(SLIDER_FILE)
    res = mf.simulate(compile_file(mf))
    t_stop = 3.0 / (0.25 * G)
    grips = res.impacts.select("grip")
    assert len(grips) == 1 and grips[0].t == pytest.approx(t_stop, rel=1e-9)
    assert res["x"][-1] == pytest.approx(3.0 * t_stop / 2, rel=1e-9)
    with pytest.raises(ModelFileError, match="friction"):
        loads_model(SLIDER_FILE.replace("friction = 0.25", "friction = -1"))
    with pytest.raises(ModelFileError, match="friction"):
        loads_model(SLIDER_FILE.replace('tangent = "x", ', ""))
    with pytest.raises(ModelFileError, match="friction \\(a rough contact\\) needs a restitution"):
        loads_model(SLIDER_FILE.replace('restitution = 0.0, tangent = "x", ', ""))


def test_painleve_rod_sliding_into_the_paradox_is_stopped_where_the_contact_problem_turns_singular():
    # mu = 2: G M^-1 (G + mu T)^T = (1 + 3 cos^2 - 6 sin cos) / m < 0 for 3 - sqrt(5) < tan(theta)
    # < 3 + sqrt(5). The rod sliding fast with its end moving to -x from theta = 30 degrees turns
    # up into that range: the normal force grows without bound as the effective mass tends to 0,
    # and the run stops there with Painleve's name (root of the contact problem's determinant).
    theta0 = math.radians(30)
    sim, q0 = _painleve_rod(2.0, theta0)
    with pytest.raises(PainleveError, match="Painleve's paradox at t = .*became singular") as err:
        sim.simulate(np.linspace(0, 0.3, 31), q0=q0, v0=[-20.0, 0.0, 0.0], rtol=1e-10, atol=1e-12)
    part = err.value.result
    assert 0 < err.value.t < 0.3
    assert np.all(np.tan(part["theta"]) < 3 - math.sqrt(5))  # the outputs before it: outside the range
    assert math.tan(part["theta"][-1]) > 0.98 * (3 - math.sqrt(5))  # the last output, 2 ms before


def _box_on_incline(alpha: float, mu: float, b: float = 0.4, h: float = 0.1):
    """A box (half-width b, half-height h) resting flat on an incline on its two bottom corners,
    each a contact with Coulomb friction: x down the slope, y normal to it, phi its tilt."""
    m = lcg.Model("box_incline")
    x, y, phi = m.coordinates("x y phi")
    m.parameters(g=G, m=1.0, alpha=alpha, b=b, h=h)
    a, mass, B, H = sp.symbols("alpha m b h")
    m.planar_body("box", mass, mass * (B**2 + H**2) / 3, (x * sp.cos(a) + y * sp.sin(a),
                                                         -x * sp.sin(a) + y * sp.cos(a)), phi)
    m.gravity(sp.Symbol("g"))
    corners = [(x - B * sp.cos(phi) + H * sp.sin(phi), y - B * sp.sin(phi) - H * sp.cos(phi)),
               (x + B * sp.cos(phi) + H * sp.sin(phi), y + B * sp.sin(phi) - H * sp.cos(phi))]
    system = lcg.ConstrainedSystem(m, inequalities=[lcg.Inequality(cy, restitution=0.0, tangent=cx, friction=mu)
                                                    for cx, cy in corners])
    return compile_constrained(system, "index1"), [0.0, h, 0.0]


@pytest.mark.parametrize("alpha, mu", [(0.3, 0.4), (0.3, 0.2)])
def test_box_on_two_rough_corners_sticks_or_slides_as_one_contact(alpha, mu):
    # Two simultaneous contacts solved together: sticking on both (dependent rows: the box's
    # three motions held by four rows) while tan(alpha) <= mu, else both slide, the box at
    # g (sin - mu cos) without tipping; the normal forces add up to m g cos(alpha).
    sim, q0 = _box_on_incline(alpha, mu)
    t = np.linspace(0, 1, 11)
    res = sim.simulate(t, q0=q0, v0=[0.0, 0.0, 0.0], **TIGHT)
    total = res["lambda_ineq_0"] + res["lambda_ineq_1"]
    assert np.max(np.abs(total / (G * math.cos(alpha)) - 1)) < 1e-8
    assert np.max(np.abs(res["phi"])) < 1e-10
    if math.tan(alpha) <= mu:
        assert res.impacts.friction_modes == {0: "stick", 1: "stick"}
        assert np.max(np.abs(res["x"])) < 1e-12
    else:
        assert res.impacts.friction_modes == {0: "slip+", 1: "slip+"}
        acc = G * (math.sin(alpha) - mu * math.cos(alpha))
        assert np.max(np.abs(res["x"][1:] / (0.5 * acc * t[1:] ** 2) - 1)) < 1e-9


def test_ctrl_c_stops_a_long_stick_slip_run(tmp_path):
    """The friction modes run inside the impact driver with no Python in the loop, which polls
    for Ctrl-C as before: a block pushed back and forth on a rough floor by A sin(w t) > mu m g
    (a stick -> slip -> stick cycle each half period) for 1e7 s stops on SIGINT within seconds."""
    import textwrap

    from helpers import interrupt_when_ready
    script = tmp_path / "long.py"
    script.write_text(textwrap.dedent("""
        import sys
        import numpy as np
        import sympy as sp
        import lagcodegen as lcg
        from lagcodegen.api import compile_constrained
        m = lcg.Model("ctrlc_shaker")
        x, y = m.coordinates("x y")
        m.parameters(g=9.81, m=1.0)
        m.particle("b", sp.Symbol("m"), (x, y))
        m.gravity(sp.Symbol("g"))
        m.generalized_force(x, 5.0 * sp.sin(3.0 * m.t))
        floor = lcg.Inequality(y, restitution=0.0, tangent=x, friction=0.3)
        sim = compile_constrained(lcg.ConstrainedSystem(m, inequalities=[floor]), "index1")
        # while the block sticks its state is constant; the contact forces, integrated in CVODE's
        # state, keep its steps below the forcing's period (else limits are crossed unseen)
        res = sim.simulate(np.array([0.0, 10.0]), q0=[0.0, 0.0], v0=[0.0, 0.0])
        assert res.stats["stick_slip"] >= 18, res.impacts.records
        print("ready", flush=True)
        try:
            sim.simulate(np.array([0.0, 1e7]), q0=[0.0, 0.0], v0=[0.0, 0.0], max_steps=10**15,
                         contacts=lcg.ContactOptions(max_records=10))
        except KeyboardInterrupt:
            print("interrupted", file=sys.stderr)
            sys.exit(130)
    """))
    returncode, err, took = interrupt_when_ready(script)
    assert returncode == 130, err
    assert "interrupted" in err and took < 10


def test_painleve_time_is_the_located_root():
    sim, q0 = _painleve_rod(2.0, math.radians(30))
    with pytest.raises(PainleveError) as err:
        sim.simulate(np.linspace(0, 0.3, 31), q0=q0, v0=[-20.0, 0.0, 0.0], rtol=1e-10, atol=1e-12)
    t_root = float(str(err.value).split("t = ")[1].split(":")[0])
    assert err.value.t == t_root


@pytest.mark.parametrize("vx, sticks", [(3.0, False), (1.0, True)])
def test_box_landing_flat_on_two_rough_corners(vx, sticks):
    # A box dropped flat from height d with speed vx lands on both corners at once (plastic): the
    # normal impulses add up to m vy (vy = sqrt(2 g d)), and the tangential one stops the slip when
    # m vx <= mu m vy (the rows of the two corners then dependent), else it is mu m vy and the box
    # slides on at vx - mu vy, decelerating at mu g to rest.
    mu, d = 0.5, 0.5
    sim, q0 = _box_on_incline(0.0, mu)
    q0 = [q0[0], q0[1] + d, q0[2]]
    t1 = math.sqrt(2 * d / G)
    vy = G * t1
    res = sim.simulate(np.linspace(0, 2.0, 21), q0=q0, v0=[vx, 0.0, 0.0], **TIGHT)
    hits = res.impacts.select("stick")
    assert sorted(r.contact for r in hits) == [0, 1] and all(r.t == pytest.approx(t1, rel=1e-10) for r in hits)
    assert sum(r.impulse for r in hits) == pytest.approx(vy, rel=1e-9)
    tang = res.impacts.select("tangential_impulse")
    assert sum(r.impulse for r in tang) == pytest.approx(-vx if sticks else -mu * vy, rel=1e-9)
    x_end = vx * t1 + (0.0 if sticks else (vx - mu * vy) ** 2 / (2 * mu * G))
    assert res["x"][-1] == pytest.approx(x_end, rel=1e-9)
    assert np.max(np.abs(res["phi"])) < 1e-10
    assert res.impacts.friction_modes == {0: "stick", 1: "stick"}
    assert [r.kind for r in res.impacts.transitions()] == ([] if sticks else ["grip", "grip"])


def test_generated_friction_code_compiles_strictly(tmp_path):
    import subprocess
    from lagcodegen.codegen.constrained import generate_constrained
    from lagcodegen.runtime import sources as runtime_files
    m = lcg.Model("strict_fr")
    x, y = m.coordinates("x y")
    m.parameters(g=G, m=1.0)
    m.particle("b", sp.Symbol("m"), (x, y))
    m.gravity(sp.Symbol("g"))
    system = lcg.ConstrainedSystem(m, inequalities=[
        lcg.Inequality(y, restitution=0.2, tangent=x, friction=0.4), lcg.Inequality(2 - x, restitution=0.5)])
    code, _ = generate_constrained(system)
    files = dict(code.files)
    for name, text in files.items():
        (tmp_path / name).write_text(text)
    for name, text in runtime_files(("lcg_dae_model.h", "lcg_model.h")).items():
        if not (tmp_path / name).exists():
            (tmp_path / name).write_text(text)
    from lagcodegen.codes import c_header
    if not (tmp_path / "lcg_codes.h").exists():
        (tmp_path / "lcg_codes.h").write_text(c_header())
    proc = subprocess.run(["cc", "-Wall", "-Wextra", "-Werror", "-std=c99", "-pedantic", "-c", "strict_fr_impact.c",
                           "-o", "/dev/null"], cwd=tmp_path, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    assert "strict_fr_imp_friction_table" in files["strict_fr_impact.c"]


def test_friction_with_an_equality_constraint_drags_a_second_mass():
    # The incline's block tied by the holonomic constraint z = x to a second mass m2 moving on a
    # horizontal line (no force along it): the pair slides at m1 g (sin - mu cos) / (m1 + m2).
    alpha, mu, m2 = 0.5, 0.3, 0.5
    m = lcg.Model("incline_pair")
    x, y, z = m.coordinates("x y z")
    m.parameters(g=G, m=1.0, m2=m2)
    a = sp.Float(alpha)
    m.particle("b", sp.Symbol("m"), (x * sp.cos(a) + y * sp.sin(a), -x * sp.sin(a) + y * sp.cos(a)))
    m.particle("c", sp.Symbol("m2"), (z, 5))
    m.gravity(sp.Symbol("g"))
    system = lcg.ConstrainedSystem(m, holonomic=[z - x], inequalities=[
        lcg.Inequality(y, restitution=0.0, tangent=x, friction=mu)])
    sim = compile_constrained(system, "index1")
    t = np.linspace(0, 2, 21)
    res = sim.simulate(t, q0=[0.0, 0.0, 0.0], v0=[0.0, 0.0, 0.0], **TIGHT)
    acc = G * (math.sin(alpha) - mu * math.cos(alpha)) / (1 + m2)
    assert np.max(np.abs(res["x"][1:] / (0.5 * acc * t[1:] ** 2) - 1)) < 1e-9
    assert np.max(np.abs(res["z"] - res["x"])) < 1e-12
    # the multiplier of z - x = 0 pulls the second mass: lambda_0 (dz - dx) . force = m2 z''
    assert np.max(np.abs(res["lambda_0"] - m2 * acc)) < 1e-9


def test_command_line_reports_the_stick_slip_transitions(tmp_path):
    import os
    import subprocess
    import sys
    from pathlib import Path
    root = Path(__file__).resolve().parents[1]
    model = tmp_path / "slider.toml"
    model.write_text(SLIDER_FILE)
    out = tmp_path / "slider.csv"
    proc = subprocess.run([sys.executable, "-m", "lagcodegen", "simulate", str(model), "-o", str(out)],
                          capture_output=True, text=True, env=dict(os.environ, PYTHONPATH=str(root)), timeout=600)
    assert proc.returncode == 0, proc.stderr
    assert "1 stick/slip transition(s), final friction modes 0: stick" in proc.stderr
    assert "Coulomb friction" in proc.stderr and "energy drift" not in proc.stderr


def test_ladder_on_a_frictionless_floor_leaves_the_wall_at_two_thirds_of_its_height():
    # mu = 0 (Coulomb with no friction: it always slips): the classic sliding ladder leaves the
    # wall where sin(theta) = 2/3 sin(alpha); the release is the normal multiplier's root on the
    # friction path, recorded, and the floor slips on.
    alpha = 1.2
    sim, q0 = _ladder(alpha, 0.0)
    res = sim.simulate(np.linspace(0, 2.0, 201), q0=q0, v0=[0.0, 0.0, 0.0], **TIGHT)
    releases = res.impacts.select("release", contact=0)
    assert len(releases) >= 1
    t_off = releases[0].t
    at = sim.simulate(np.array([0.0, t_off]), q0=q0, v0=[0.0, 0.0, 0.0], **TIGHT)
    assert math.sin(at["theta"][-1]) == pytest.approx(2 / 3 * math.sin(alpha), rel=1e-8)
    assert res.impacts.friction_modes[1] == "slip+"


def _shaker_times(A, w, mu, t_end):
    """Stick-slip of a block (m = 1) pushed by A sin(w t) on a rough floor: slip j begins where
    A sin(w t) = (-1)^j mu g, s_j = (asin(mu g / A) + j pi) / w, and grips where its velocity
    v = A / w (cos(w s_j) - cos(w t)) - (-1)^j mu g (t - s_j) returns to 0 (after the forcing falls
    back through the friction limit, at s_j + (pi - 2 asin(mu g / A)) / w); each grip comes before
    the next slip for these numbers (else the block would reverse)."""
    from scipy.optimize import brentq
    a = math.asin(mu * G / A)
    out, j = [], 0
    while (a + j * math.pi) / w < t_end:
        sj, sign = (a + j * math.pi) / w, (-1) ** j

        def v(t, s0=sj, sg=sign):
            return sg * (A / w * (math.cos(w * s0) - math.cos(w * t)) - sg * mu * G * (t - s0))
        t_grip = brentq(v, sj + (math.pi - 2 * a) / w, sj + 2 * math.pi / w, xtol=1e-15, rtol=1e-15)
        assert t_grip < (a + (j + 1) * math.pi) / w
        out += [("slip", sj), ("grip", t_grip)]
        j += 1
    return [(k, t) for k, t in out if t < t_end]


def test_shaken_block_stick_slip_times_at_tight_and_default_tolerances():
    A, w, mu = 5.0, 3.0, 0.3
    m = lcg.Model("shaker")
    x, y = m.coordinates("x y")
    m.parameters(g=G, m=1.0)
    m.particle("b", sp.Symbol("m"), (x, y))
    m.gravity(sp.Symbol("g"))
    m.generalized_force(x, A * sp.sin(w * m.t))
    floor = lcg.Inequality(y, restitution=0.0, tangent=x, friction=mu)
    sim = compile_constrained(lcg.ConstrainedSystem(m, inequalities=[floor]), "index1")
    exact = _shaker_times(A, w, mu, 10.0)
    assert len(exact) >= 18
    tight = sim.simulate(np.array([0.0, 10.0]), q0=[0.0, 0.0], v0=[0.0, 0.0], **TIGHT).impacts.transitions()
    assert [r.kind for r in tight] == [k for k, _ in exact]
    assert np.max(np.abs(np.array([r.t for r in tight]) / np.array([t for _, t in exact]) - 1)) < 1e-9
    # default tolerances, two output times: the steps stay below the forcing's period while it sticks
    loose = sim.simulate(np.array([0.0, 10.0]), q0=[0.0, 0.0], v0=[0.0, 0.0]).impacts.transitions()
    assert [r.kind for r in loose] == [k for k, _ in exact]
    assert np.max(np.abs(np.array([r.t for r in loose]) - np.array([t for _, t in exact]))) < 1e-4


def test_more_contact_modes_than_the_driver_enumerates_is_a_clear_error():
    # Seven blocks resting on a rough floor: 4^7 stick/slip+/slip-/release combinations, more
    # than the 4096 the driver enumerates: an error saying so (not a Painleve error), no run.
    m = lcg.Model("seven")
    coords = m.coordinates(" ".join(f"x{i} y{i}" for i in range(7)))
    m.parameters(g=G, m=1.0)
    ineqs = []
    for i in range(7):
        x, y = coords[2 * i], coords[2 * i + 1]
        m.particle(f"b{i}", sp.Symbol("m"), (x, y))
        ineqs.append(lcg.Inequality(y, restitution=0.0, tangent=x, friction=0.5))
    m.gravity(sp.Symbol("g"))
    sim = compile_constrained(lcg.ConstrainedSystem(m, inequalities=ineqs), "index1")
    with pytest.raises(lcg.SolverError, match="more than 4096 stick/slip/release modes") as err:
        sim.simulate((0, 1), q0=[0.0] * 14, v0=[0.0] * 14)
    assert not isinstance(err.value, PainleveError)
