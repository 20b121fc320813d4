"""Coulomb friction (planar and 3-D) on the Taylor method (``simulate(method="taylor")``: the
Taylor contact driver lagcodegen/runtime/lcg_taylor_imp.c with the friction core
lagcodegen/runtime/lcg_imp_fric.c, the jet's slipping rows from tl_slip), checked against
closed-form facts (a block on an incline, a sphere and a disc launched with backspin), against the
index-1 CVODE run of the same system (a disc dropped spinning onto a rough floor: frictional
impacts, slip, grip), Painleve's rod raising PainleveError; 3-D friction (two tangents: the 3-D incline, a block
sliding across it, a sphere with backspin, the table on four legs)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp

import lagcodegen as lcg
from test_friction import G, _incline, _painleve_rod, _rod_velocity, _roller
from test_friction_speeds import MU, RADIUS, _incline_3d, _sphere, _sphere_system, _start, _table_on_incline

TIGHT = {"rtol": 1e-12, "atol": 1e-14, "method": "taylor"}


def roller_system(inertia_factor: float, mu: float, e: float = 0.0) -> lcg.ConstrainedSystem:
    """The system of tests/test_friction.py's ``_roller`` (a sphere or disc on the floor y = 0 with
    Coulomb friction on its touching point), uncompiled (the strict-compile test takes it)."""
    m = lcg.Model("roller")
    x, y, phi = m.coordinates("x y phi")
    m.parameters(g=G, m=1.0, R=0.3)
    mass, R = sp.symbols("m R")
    m.planar_body("ball", mass, inertia_factor * mass * R**2, (x, y), phi)
    m.gravity(sp.Symbol("g"))
    return lcg.ConstrainedSystem(m, inequalities=[lcg.Inequality(y - R, restitution=e, tangent=x + R * phi,
                                                                 friction=mu)])


@pytest.mark.parametrize("alpha, mu", [(0.5, 0.6), (0.5, 0.3), (0.3, 0.1), (0.3, 0.31)])
def test_block_on_an_incline_sticks_when_tan_alpha_le_mu_else_slides_at_g_sin_minus_mu_cos(alpha, mu):
    sim = _incline(alpha, mu)
    t = np.linspace(0, 3, 31)
    res = sim.simulate(t, q0=[0.0, 0.0], v0=[0.0, 0.0], **TIGHT)
    assert res.method == "taylor"
    assert np.max(np.abs(res["lambda_ineq_0"] / (G * math.cos(alpha)) - 1)) < 1e-9  # N = m g cos(alpha)
    if math.tan(alpha) <= mu:
        assert np.max(np.abs(res["x"])) < 1e-12 and res.impacts.friction_modes == {0: "stick"}
        assert np.max(np.abs(res["lambda_t_ineq_0"] + G * math.sin(alpha))) < 1e-9
        assert res.impacts.transitions() == []
    else:
        a = G * (math.sin(alpha) - mu * math.cos(alpha))
        assert np.max(np.abs(res["x"][1:] / (0.5 * a * t[1:] ** 2) - 1)) < 1e-9
        assert np.max(np.abs(res["x_dot"][1:] / (a * t[1:]) - 1)) < 1e-9
        assert res.impacts.friction_modes == {0: "slip+"}
        assert np.max(np.abs(res["lambda_t_ineq_0"] + mu * G * math.cos(alpha))) < 1e-9


@pytest.mark.parametrize("body, k, slip_time, roll_speed", [
    ("sphere", 0.4, lambda v0, Rw0, mu: 2 * (v0 + Rw0) / (7 * mu * G), lambda v0, Rw0: (5 * v0 - 2 * Rw0) / 7),
    ("disc", 0.5, lambda v0, Rw0, mu: (v0 + Rw0) / (3 * mu * G), lambda v0, Rw0: (2 * v0 - Rw0) / 3),
])
def test_ball_with_backspin_slips_then_rolls(body, k, slip_time, roll_speed):
    mu, R, v0, w0 = 0.2, 0.3, 3.0, 4.0
    sim = _roller(k, mu)
    t_star = slip_time(v0, R * w0, mu)
    t = np.linspace(0, 2 * t_star, 40)
    res = sim.simulate(t, q0=[0.0, R, 0.0], v0=[v0, 0.0, w0], **TIGHT)
    grips = res.impacts.transitions(0)
    assert [r.kind for r in grips] == ["grip"], res.impacts.records
    assert grips[0].t == pytest.approx(t_star, rel=1e-9)
    after, before = res.t > t_star, res.t < t_star
    v_roll = roll_speed(v0, R * w0)
    assert np.max(np.abs(res["x_dot"][after] / v_roll - 1)) < 1e-9
    assert np.max(np.abs(res["phi_dot"][after] * R + res["x_dot"][after])) < 1e-9 * abs(v_roll)
    assert res.impacts.friction_modes == {0: "stick"}
    work = mu * G * (v0 + R * w0) * t_star / 2
    assert res["energy"][0] - res["energy"][-1] == pytest.approx(work, rel=1e-9)
    assert np.max(np.abs(res["lambda_t_ineq_0"][before] + mu * G)) < 1e-9
    assert np.max(np.abs(res["lambda_t_ineq_0"][after])) < 1e-9


@pytest.mark.parametrize("rotation", ["quaternion", "ZYX"])
def test_sphere_on_generalized_speeds_slips_then_rolls(rotation):
    """Planar friction (one tangent, along y) on a free-flying sphere (generalized speeds): the
    slip ends at t* = 2 (v0 + R w0) / (7 mu g), then it rolls at (5 v0 - 2 R w0) / 7, to 1e-9."""
    v0, w0 = 3.0, 4.0
    sim = _sphere(rotation, "y")
    t_star = 2 * (v0 + RADIUS * w0) / (7 * MU * G)
    v_roll = (5 * v0 - 2 * RADIUS * w0) / 7
    t = np.linspace(0, 2 * t_star, 40)
    q0, u0 = _start(rotation, (0, v0, 0), (w0, 0, 0))
    res = sim.simulate(t, q0=q0, v0=u0, **TIGHT)
    grips = res.impacts.transitions(0)
    assert [r.kind for r in grips] == ["grip"], res.impacts.records
    assert grips[0].t == pytest.approx(t_star, rel=1e-9)
    after = res.t > t_star
    vy = res.y[:, sim.system.model.nq + 1]
    if rotation == "quaternion":  # v in the body frame: the world velocity from q' (y')
        vy = np.array([sim.compiled.rhs(tt, yy)[1] for tt, yy in zip(res.t, res.y)])
    assert np.max(np.abs(vy[after] / v_roll - 1)) < 1e-9
    assert np.max(np.abs(res.y[:, 2] - RADIUS)) < 1e-10
    work = MU * G * (v0 + RADIUS * w0) * t_star / 2
    assert res["energy"][0] - res["energy"][-1] == pytest.approx(work, rel=1e-9)
    assert res.impacts.friction_modes == {0: "stick"}


@pytest.mark.parametrize("v0", [[1.0, 0.0, 12.0], [4.0, 0.0, 0.0], [1.0, 0.0, -20.0]])
def test_dropped_spinning_disc_agrees_with_the_index1_cvode_run(v0):
    """A disc dropped spinning onto a rough floor (e = 0, mu = 0.3): a plastic frictional impact
    (sliding impulse), slipping in persistent contact, the grip. The Taylor run's records (kinds,
    times) and states at the output times agree with the index-1 CVODE run's to 1e-9 (measured:
    about 1e-12), the impact at the closed form sqrt(2 h / g)."""
    sim = _roller(0.5, 0.3, e=0.0)
    t = np.linspace(0, 1.5, 151)
    kw = dict(q0=[0.0, 0.5, 0.0], v0=v0, rtol=1e-12, atol=1e-14)
    tay = sim.simulate(t, method="taylor", **kw)
    cv = sim.simulate(t, method="bdf", **kw)
    assert [r.kind for r in tay.impacts.records] == [r.kind for r in cv.impacts.records] == \
        ["stick", "tangential_impulse", "grip"]
    assert tay.impacts.records[0].t == pytest.approx(math.sqrt(2 * 0.2 / G), rel=1e-12)
    for a, b in zip(tay.impacts.records, cv.impacts.records):
        assert abs(a.t - b.t) < 1e-9
    assert np.max(np.abs(tay.y - cv.y)) < 1e-9
    assert np.max(np.abs(tay["lambda_t_ineq_0"] - cv["lambda_t_ineq_0"])) < 1e-7
    assert tay.impacts.friction_modes == cv.impacts.friction_modes == {0: "stick"}


def test_stick_to_slip_located_where_the_sticking_force_reaches_mu_n():
    """A block on a floor accelerating at c t: it sticks until m c t = mu m g at t_s = mu g / c
    (the root of mu lambda_n - lambda_t on the step's polynomial), then slips at x'' = mu g."""
    mu, c = 0.4, 3.0
    m = lcg.Model("belt")
    x, y = m.coordinates("x y")
    m.parameters(g=G, m=1.0)
    m.particle("b", sp.Symbol("m"), (x, y))
    m.gravity(sp.Symbol("g"))
    floor = lcg.Inequality(y, restitution=0.0, tangent=x - c * m.t**3 / 6, friction=mu)
    sim = lcg.api.compile_constrained(lcg.ConstrainedSystem(m, inequalities=[floor]), "index1")
    ts = mu * G / c
    tt = np.linspace(0, 2 * ts, 40)
    res = sim.simulate(tt, q0=[0.0, 0.0], v0=[0.0, 0.0], **TIGHT)
    slips = res.impacts.transitions(0)
    assert [r.kind for r in slips] == ["slip"]
    assert slips[0].t == pytest.approx(ts, rel=1e-9)
    before, after = tt < ts, tt > ts
    assert np.max(np.abs(res["x"][before] - c * tt[before] ** 3 / 6)) < 1e-12
    tau = tt[after] - ts
    x_exact = c * ts**3 / 6 + c * ts**2 / 2 * tau + mu * G * tau**2 / 2
    assert np.max(np.abs(res["x"][after] / x_exact - 1)) < 1e-9
    assert res.impacts.friction_modes == {0: "slip-"}


@pytest.mark.parametrize("alpha, mu", [(0.5, 0.3), (0.5, 0.7)])
def test_block_sent_up_an_incline_stops_then_sticks_or_slides_back(alpha, mu):
    """Launched up the slope it stops at t1 = v0 / (g (sin + mu cos)) (the root of the slip
    velocity), then sticks ("grip") if tan(alpha) <= mu, else slides back ("reverse"), to 1e-9."""
    v0 = 2.0
    sim = _incline(alpha, mu)
    a_up = G * (math.sin(alpha) + mu * math.cos(alpha))
    t1 = v0 / a_up
    tt = np.linspace(0, 2 * t1, 40)
    res = sim.simulate(tt, q0=[0.0, 0.0], v0=[-v0, 0.0], **TIGHT)
    trans = res.impacts.transitions(0)
    assert len(trans) == 1 and trans[0].t == pytest.approx(t1, rel=1e-9)
    x1 = -v0 * t1 + a_up * t1**2 / 2
    after = tt > t1
    if math.tan(alpha) <= mu:
        assert trans[0].kind == "grip" and res.impacts.friction_modes == {0: "stick"}
        assert np.max(np.abs(res["x"][after] / x1 - 1)) < 1e-9
    else:
        assert trans[0].kind == "reverse" and res.impacts.friction_modes == {0: "slip+"}
        tau = tt[after] - t1
        a_down = G * (math.sin(alpha) - mu * math.cos(alpha))
        assert np.max(np.abs(res["x"][after] / (x1 + a_down * tau**2 / 2) - 1)) < 1e-9


def test_painleve_rod_raises_painleve_error_on_taylor():
    theta0 = math.atan(2.0)
    sim, q0 = _painleve_rod(2.0, theta0)
    with pytest.raises(lcg.PainleveError, match="Painleve's paradox \\(inconsistency\\)"):
        sim.simulate(np.linspace(0, 1, 11), q0=q0, v0=[-1.0, 0.0, 0.0], **TIGHT)
    spin = 1.2 * math.sqrt(G / math.sin(theta0))
    with pytest.raises(lcg.PainleveError, match="Painleve's paradox \\(indeterminacy\\)"):
        sim.simulate(np.linspace(0, 1, 11), q0=q0, v0=_rod_velocity(theta0, -1.0, spin), **TIGHT)
    res = sim.simulate(np.linspace(0, 0.05, 6), q0=q0, v0=[1.0, 0.0, 0.0], **TIGHT)
    assert res.impacts.friction_modes in ({0: "slip+"}, {0: "free"})


def test_painleve_rod_sliding_into_the_paradox_is_stopped_where_the_contact_problem_turns_singular():
    """The rod of tests/test_friction.py sliding into the paradox: the determinant's root located on
    the step's polynomial raises PainleveError there (CVODE Adams: 0.1618462597; measured: 4e-10
    apart), the outputs before it outside the range 3 - sqrt(5) < tan(theta)."""
    sim, q0 = _painleve_rod(2.0, math.radians(30))
    with pytest.raises(lcg.PainleveError, match="Painleve's paradox at t = .*became singular") as err:
        sim.simulate(np.linspace(0, 0.3, 31), q0=q0, v0=[-20.0, 0.0, 0.0], method="taylor", rtol=1e-10,
                     atol=1e-12)
    assert err.value.t == pytest.approx(0.16184625970, abs=1e-8)
    part = err.value.result
    assert np.all(np.tan(part["theta"]) < 3 - math.sqrt(5))


@pytest.mark.parametrize("alpha, mu, beta", [(0.5, 0.6, 0.0), (0.5, 0.3, 0.0), (0.5, 0.3, 0.7), (0.3, 0.31, 1.1),
                                             (0.3, 0.1, 2.0)])
def test_block_on_an_incline_in_3d_sticks_when_tan_alpha_le_mu_else_slides_down_the_slope(alpha, mu, beta):
    """3-D friction (two tangents turned by beta, the circular cone): sticks when tan(alpha) <= mu,
    else slides straight down at g (sin alpha - mu cos alpha), position to 1e-9 relative."""
    sim = _incline_3d(alpha, mu, beta)
    t = np.linspace(0, 2, 21)
    res = sim.simulate(t, q0=[0.0, 0.0, 0.0], v0=[0.0, 0.0, 0.0], **TIGHT)
    assert np.max(np.abs(res["lambda_ineq_0"] / (G * math.cos(alpha)) - 1)) < 1e-9
    cb, sb = math.cos(beta), math.sin(beta)
    l0, l1 = res["lambda_t0_ineq_0"], res["lambda_t1_ineq_0"]
    fx, fy = cb * l0 + sb * l1, -sb * l0 + cb * l1
    if math.tan(alpha) <= mu:
        assert np.max(np.abs(res.y[:, :3])) < 1e-12 and res.impacts.friction_modes == {0: "stick"}
        assert np.max(np.abs(fx + G * math.sin(alpha))) < 1e-9 and np.max(np.abs(fy)) < 1e-9
    else:
        acc = G * (math.sin(alpha) - mu * math.cos(alpha))
        assert np.max(np.abs(res["x"][1:] / (0.5 * acc * t[1:] ** 2) - 1)) < 1e-9
        assert np.max(np.abs(res["y"])) < 1e-9 * np.max(res["x"])
        assert res.impacts.friction_modes == {0: "slip"}
        assert np.max(np.abs(fx + mu * G * math.cos(alpha))) < 1e-9 and np.max(np.abs(fy)) < 1e-9
    assert np.max(np.abs(res["z"])) < 1e-12


def test_3d_slide_that_curves_agrees_with_the_index1_cvode_run():
    """A block launched across a 3-D incline: its slip direction d = u/|u| turns along the motion
    (the jet's series of u/|u|); the Taylor run agrees with CVODE Adams's to 1e-8 (measured: 2e-9)."""
    sim = _incline_3d(0.5, 0.3, 0.3)
    t = np.linspace(0, 2, 21)
    kw = dict(q0=[0.0, 0.0, 0.0], v0=[0.0, 2.0, 0.0], rtol=1e-12, atol=1e-14)
    tay, ad = sim.simulate(t, method="taylor", **kw), sim.simulate(t, method="adams", **kw)
    assert tay.impacts.friction_modes == ad.impacts.friction_modes == {0: "slip"}
    assert np.max(np.abs(tay.y - ad.y)) < 1e-8


@pytest.mark.parametrize("side", [0.0, 1.0])
def test_3d_sphere_with_backspin_slips_then_rolls(side):
    """A sphere on two tangents (3-D friction, quaternion, generalized speeds) launched with
    backspin (and a sideways velocity and spin): the slip ends at t* = 2 (v0 + R w0) / (7 mu g)
    (straight along y) to 1e-9, and the runs agree with CVODE Adams's to 1e-9."""
    v0, w0 = 3.0, 4.0
    sim = _sphere("quaternion", "xy")
    t_star = 2 * (v0 + RADIUS * w0) / (7 * MU * G)
    t = np.linspace(0, 2 * t_star, 40)
    q0, u0 = _start("quaternion", (side, v0, 0), (w0, side, 0))
    tay = sim.simulate(t, q0=q0, v0=u0, **TIGHT)
    ad = sim.simulate(t, q0=q0, v0=u0, method="adams", rtol=1e-12, atol=1e-14)
    grips = tay.impacts.transitions(0)
    assert [r.kind for r in grips] == ["grip"] == [r.kind for r in ad.impacts.transitions(0)]
    if side == 0.0:
        assert grips[0].t == pytest.approx(t_star, rel=1e-9)
    assert abs(grips[0].t - ad.impacts.transitions(0)[0].t) < 1e-9
    assert np.max(np.abs(tay.y - ad.y)) < 1e-9
    assert tay.impacts.friction_modes == {0: "stick"}


@pytest.mark.parametrize("alpha, mu, yaw", [(0.5, 0.3, 0.0), (0.5, 0.3, 0.4), (0.2, 0.3, 0.4)])
def test_table_on_four_legs_slides_down_an_incline_or_sticks(alpha, mu, yaw):
    """Four coupled 3-D contacts leaving the cone together from rest: the table slides down the
    slope at g (sin alpha - mu cos alpha) to 1e-9 relative, or sticks where tan(alpha) <= mu."""
    m, sim, q0 = _table_on_incline(mu, alpha, yaw)
    t = np.linspace(0.0, 1.0, 11)
    res = sim.simulate(t, q0, np.zeros(m.nv), **TIGHT)
    down = res.y[:, 0] * math.cos(yaw) + res.y[:, 1] * math.sin(yaw)
    across = -res.y[:, 0] * math.sin(yaw) + res.y[:, 1] * math.cos(yaw)
    normal = np.array([res[f"lambda_ineq_{k}"] for k in range(4)])
    assert np.max(np.abs(normal.sum(axis=0) / (2.0 * G * math.cos(alpha)) - 1)) < 1e-9
    if math.tan(alpha) <= mu:
        assert res.impacts.friction_modes == {k: "stick" for k in range(4)}
        assert np.max(np.abs(res.y[:, :3] - q0[:3])) < 1e-12
        return
    acc = G * (math.sin(alpha) - mu * math.cos(alpha))
    assert res.impacts.friction_modes == {k: "slip" for k in range(4)}
    assert np.max(np.abs(down[1:] / (0.5 * acc * t[1:] ** 2) - 1)) < 1e-9
    assert np.max(np.abs(across)) < 1e-9 * down[-1]


def test_ensemble_and_integrator_object_with_friction_on_taylor():
    """The ensemble's members and the integrator object (propagated across the grip) give the
    single Taylor run's records and states."""
    mu, R, v0, w0 = 0.2, 0.3, 3.0, 4.0
    sim = _roller(0.4, mu)
    t = np.linspace(0, 4 * (v0 + R * w0) / (7 * mu * G), 9)
    kw = dict(method="taylor", rtol=1e-12, atol=1e-14)
    single = sim.simulate(t, q0=[0.0, R, 0.0], v0=[v0, 0.0, w0], **kw)
    ens = sim.ensemble(t, q0=[[0.0, R, 0.0]] * 2, v0=[[v0, 0.0, w0]] * 2, save="trajectory", **kw)
    assert ens.member(1).impacts.records == single.impacts.records and len(single.impacts.records) == 1
    assert np.max(np.abs(ens.member(1).y - single.y)) == 0.0
    integ = sim.integrator(q0=[0.0, R, 0.0], v0=[v0, 0.0, w0], **kw)
    for tt in t[1:]:
        integ.propagate_until(tt)
    assert np.max(np.abs(np.asarray(integ.state) - single.y[-1])) < 1e-12


FRICTION_MAIN = r"""
#include <stdio.h>
#include <string.h>
#include "lcg_taylor_imp.h"

extern const lcg_taylor_contact tsroll_taylor_contact;
const lcg_imp_model *tsroll_imp_model_table(void);
const lcg_imp_friction *tsroll_imp_friction_table(void);
void (*tsroll_taylor_contact_slip(void))(void *, const int *, const double *);

int main(void)
{
    double p[3] = {9.81, 1.0, 0.3}, y0[6] = {0.0, 0.3, 0.0, 3.0, 0.0, 4.0}, t[3] = {0.0, 0.5, 1.2};
    double yout[18], out[3 * 64], lam[3 * 2], e[1] = {0.0}, set[3] = {1e-6, 1e-9, 1e-9}, rec[6 * 20];
    double stab[2] = {-1.0, -1.0}, mu[1] = {0.2};
    int active[1] = {0}, n_rec = 0, flag;
    lcg_taylor_options opt;
    lcg_taylor_stats st;
    lcg_taylor_friction fric;

    memset(&opt, 0, sizeof opt);
    opt.rtol = 1e-12;
    opt.atol = 1e-14;
    opt.max_steps = 100000;
    fric.slip = tsroll_taylor_contact_slip();
    fric.fr = tsroll_imp_friction_table();
    fric.mu = mu;
    flag = lcg_taylor_imp_solve(&tsroll_taylor_contact, tsroll_imp_model_table(), p, y0, 3, t, yout, out, lam,
                                &opt, e, set, active, 20, rec, &n_rec, &st, stab, NULL, &fric);
    printf("%d %d %.17g %.17g %d\n", flag, n_rec, rec[0], yout[15], active[0]);
    return 0;
}
"""


FRICTION_MAIN_3D = FRICTION_MAIN.replace(
    "double p[3] = {9.81, 1.0, 0.3}, y0[6] = {0.0, 0.3, 0.0, 3.0, 0.0, 4.0}, t[3] = {0.0, 0.5, 1.2};",
    "double p[1] = {0.0}, y0[12] = {0, 0, 0.3, 0, 0, 0, 0, 3.0, 0, 0, 0, 4.0}, t[3] = {0.0, 0.5, 1.2};").replace(
    "double yout[18], out[3 * 64], lam[3 * 2]", "double yout[36], out[3 * 64], lam[3 * 3]").replace(
    "yout[15]", "yout[31]")


@pytest.mark.parametrize("cone", [False, True])
def test_friction_driver_runs_clean_under_sanitizers(tmp_path, cc, cone):
    """The contact jet with friction, the Taylor contact driver, the impact law and the friction
    core, run from C under ASan/UBSan. Planar: the roller's grip at t* = 2 (v0 + R w0) / (7 mu g),
    then rolling at (5 v0 - 2 R w0) / 7. 3-D (cone): a sphere on two tangents with the same
    launch (d = u/|u| in the jet): the same grip."""
    import subprocess

    from lagcodegen.build import dae_table_source, table_source, types_headers
    from lagcodegen.codegen.constrained import generate_constrained
    from lagcodegen.codegen.record import scene_of_code
    from lagcodegen.codegen.taylor.contacts import contact_jet_sources
    from lagcodegen.codegen.taylor.emit import runtime_sources
    from lagcodegen.runtime import sources as runtime_files
    from lagcodegen.simulation.taylor_impacts import RUNTIME_FILES

    system = roller_system(0.4, 0.2) if not cone else _sphere_system(0.2, 0.0, "ZYX", "xy")
    code, _ = generate_constrained(system, prefix="tsroll")
    code.write(tmp_path)
    files = {**runtime_sources(), **runtime_files(RUNTIME_FILES), **table_source(code), **dae_table_source(code),
             **types_headers(("dae",)), **contact_jet_sources(system, scene_of_code(code, "test"))}
    for name, text in files.items():
        (tmp_path / name).write_text(text)
    (tmp_path / "main.c").write_text(FRICTION_MAIN_3D if cone else FRICTION_MAIN)
    model_c = sorted(n.name for n in tmp_path.glob("tsroll*.c") if n.name != "tsroll_taylor_contact.c")
    san = [cc, "-std=c99", "-g", "-O1", "-fsanitize=address,undefined", "-fno-sanitize-recover=all"]
    proc = subprocess.run([*san, "main.c", "tsroll_taylor_contact.c", "lcg_taylor_imp.c", "lcg_imp_law.c",
                           "lcg_imp_fric.c", *model_c, "-o", "run", "-lm", "-pthread"], cwd=tmp_path,
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    run = subprocess.run(["./run"], cwd=tmp_path, capture_output=True, text=True,
                         env={"ASAN_OPTIONS": "detect_leaks=1", "PATH": "/usr/bin:/bin"})
    assert run.returncode == 0, run.stdout + run.stderr
    flag, n_rec, t_grip, x_dot_end, active = run.stdout.split()
    v0, Rw0, mu = 3.0, 0.3 * 4.0, 0.2
    assert int(flag) == 0 and int(n_rec) == 1 and int(active) == 1
    assert float(t_grip) == pytest.approx(2 * (v0 + Rw0) / (7 * mu * G), rel=1e-9)
    assert float(x_dot_end) == pytest.approx((5 * v0 - 2 * Rw0) / 7, rel=1e-9)
