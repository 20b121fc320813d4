"""Coulomb friction on the GGL impact driver (IDA, lagcodegen/runtime/lcg_imp_ida.c with the
friction core lcg_imp_fric.c shared with the index-1 driver): the closed-form facts that
tests/test_friction.py and tests/test_friction_speeds.py check on index-1, on the same models
(their builders, compiled with formulation="ggl"), a GGL run against the index-1 run of the same
system, and Painleve's paradox reported by name."""

from __future__ import annotations

import math

import numpy as np
import pytest

import lagcodegen as lcg
from lagcodegen.api import compile_constrained
from lagcodegen.errors import LagcodegenError

from test_friction import TIGHT, _incline, _ladder, _painleve_rod, _rod_velocity, _roller
from test_friction_speeds import MU, RADIUS, _incline_3d, _sphere_system, _start

G = 9.81
PainleveError = lcg.PainleveError


@pytest.mark.parametrize("alpha, mu", [(0.5, 0.6), (0.5, 0.3), (0.3, 0.1), (0.3, 0.31)])
def test_ggl_block_on_an_incline_sticks_when_tan_alpha_le_mu_else_slides_at_g_sin_minus_mu_cos(alpha, mu):
    sim = _incline(alpha, mu, formulation="ggl")
    t = np.linspace(0, 3, 31)
    res = sim.simulate(t, q0=[0.0, 0.0], v0=[0.0, 0.0], **TIGHT)
    assert np.max(np.abs(res["lambda_ineq_0"] / (G * math.cos(alpha)) - 1)) < 1e-9
    if math.tan(alpha) <= mu:
        assert np.max(np.abs(res["x"])) < 1e-12 and res.impacts.friction_modes == {0: "stick"}
        assert np.max(np.abs(res["lambda_t_ineq_0"] + G * math.sin(alpha))) < 1e-9
        assert res.impacts.transitions() == []
    else:
        acc = G * (math.sin(alpha) - mu * math.cos(alpha))
        assert np.max(np.abs(res["x"][1:] / (0.5 * acc * t[1:] ** 2) - 1)) < 1e-9
        assert res.impacts.friction_modes == {0: "slip+"}
        assert np.max(np.abs(res["lambda_t_ineq_0"] + mu * G * math.cos(alpha))) < 1e-9
    assert np.max(np.abs(res["y"])) < 1e-12


@pytest.mark.parametrize("k, slip_time, roll_speed", [
    (0.4, lambda v0, Rw0, mu: 2 * (v0 + Rw0) / (7 * mu * G), lambda v0, Rw0: (5 * v0 - 2 * Rw0) / 7),  # sphere
    (0.5, lambda v0, Rw0, mu: (v0 + Rw0) / (3 * mu * G), lambda v0, Rw0: (2 * v0 - Rw0) / 3),  # disc
])
def test_ggl_ball_with_backspin_slips_then_rolls(k, slip_time, roll_speed):
    mu, R, v0, w0 = 0.2, 0.3, 3.0, 4.0
    sim = _roller(k, mu, formulation="ggl")
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


def test_ggl_3d_sphere_sliding_diagonally_slips_along_its_slip_direction_then_rolls():
    """The 3-D sphere (Z-Y-X angles: v = q', as the GGL driver takes) launched along e = (3, 4) / 5
    with backspin: the slip ends at t* = 2 (v0 + R w0) / (7 mu g), then it rolls along e at
    (5 v0 - 2 R w0) / 7; the friction force mu m g against e while slipping; all to 1e-9."""
    sim = compile_constrained(_sphere_system(MU, 0.0, "ZYX", "xy"), "ggl", outputs=["energy"])
    v0, w0, wz = 2.5, 3.0, 1.5
    e = np.array([0.6, 0.8])
    t_star = 2 * (v0 + RADIUS * w0) / (7 * MU * G)
    v_roll = (5 * v0 - 2 * RADIUS * w0) / 7
    t = np.linspace(0, 2 * t_star, 41)
    axis = np.array([-e[1], e[0]])
    q0, u0 = _start("ZYX", (v0 * e[0], v0 * e[1], 0), (-w0 * axis[0], -w0 * axis[1], wz))
    res = sim.simulate(t, q0=q0, v0=u0, **TIGHT)
    grips = res.impacts.transitions(0)
    assert [r.kind for r in grips] == ["grip"], res.impacts.records
    assert grips[0].t == pytest.approx(t_star, rel=1e-9)
    assert res.impacts.friction_modes == {0: "stick"}
    rates = res.y[:, 6:8]  # x', y' (v = q')
    before, after = res.t < t_star, res.t > t_star
    along, across = rates @ e, rates @ axis
    assert np.max(np.abs(along[before] - (v0 - MU * G * res.t[before]))) < 1e-9 * v0
    assert np.max(np.abs(along[after] / v_roll - 1)) < 1e-9
    assert np.max(np.abs(across)) < 1e-9 * v0
    lt = np.stack([res["lambda_t0_ineq_0"], res["lambda_t1_ineq_0"]], axis=1)
    assert np.max(np.abs(lt[before] + MU * G * e)) < 1e-9
    # rolling: no friction force; the outputs are IDA's unknowns lambda (index-2 multipliers, not
    # error-controlled at the default alg_atol), measured 2e-8 here (1e-8 of mu m g)
    assert np.max(np.abs(lt[after])) < 1e-7


@pytest.mark.parametrize("alpha, mu, beta", [(0.5, 0.6, 0.0), (0.5, 0.3, 0.7), (0.3, 0.1, 2.0)])
def test_ggl_block_on_an_incline_in_3d(alpha, mu, beta):
    sim = _incline_3d(alpha, mu, beta, formulation="ggl")
    t = np.linspace(0, 2, 21)
    res = sim.simulate(t, q0=[0.0, 0.0, 0.0], v0=[0.0, 0.0, 0.0], **TIGHT)
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


@pytest.mark.parametrize("alpha", [0.9, 1.2])
def test_ggl_ladder_stays_when_mu_reaches_one_over_two_tan_alpha_and_slips_below(alpha):
    mu_c = 1 / (2 * math.tan(alpha))
    t = np.linspace(0, 0.5, 11)
    for mu, stays in ((mu_c + 1e-6, True), (mu_c - 1e-6, False)):
        sim, q0 = _ladder(alpha, mu, formulation="ggl")
        res = sim.simulate(t, q0=q0, v0=[0.0, 0.0, 0.0], **TIGHT)
        foot = res["x"] + np.cos(res["theta"])
        if stays:
            assert res.impacts.friction_modes == {1: "stick"}
            assert np.max(np.abs(foot - foot[0])) < 1e-12 and np.max(np.abs(res["theta"] - alpha)) < 1e-12
            assert res["lambda_ineq_0"][-1] == pytest.approx(G * mu_c, rel=1e-9)
            assert res["lambda_t_ineq_1"][-1] == pytest.approx(-G * mu_c, rel=1e-9)
            assert res["lambda_ineq_1"][-1] == pytest.approx(G, rel=1e-9)
        else:
            assert res.impacts.friction_modes[1] == "slip+"
            assert foot[-1] > foot[0] + 1e-9 and res["theta"][-1] < alpha


#: What a GGL run of a system agrees with its index-1 run to (both at rtol 1e-12, atol 1e-14:
#: different integrators, their errors apart; measured at most 5e-11 on these runs).
AGREE = 1e-9


@pytest.mark.parametrize("vx, mu, e, t_end", [(4.0, 0.1, 0.0, 1.5), (1.0, 0.5, 0.5, 0.5), (4.0, 0.1, 0.5, 0.5)])
def test_ggl_run_agrees_with_the_index1_run_trajectory_records_multipliers(vx, mu, e, t_end):
    """A disc dropped spinning onto the rough floor: a plastic impact with a sliding impulse, then
    sliding until it grips and rolls; or bounces (e = 0.5) with sticking or sliding tangential
    impulses. GGL and index-1 give the same records (kinds and contacts; times, impulses and
    velocities to AGREE), final modes, trajectory and multipliers."""
    runs = {}
    t = np.linspace(0, t_end, 61)
    for form in ("index1", "ggl"):
        sim = _roller(0.5, mu, e, formulation=form)
        runs[form] = sim.simulate(t, q0=[0.0, 0.4, 0.0], v0=[vx, -2.0, 3.0], **TIGHT)
    a, b = runs["index1"], runs["ggl"]
    ra, rb = a.impacts.records, b.impacts.records
    assert [(r.kind, r.contact) for r in ra] == [(r.kind, r.contact) for r in rb]
    assert any(r.kind == "tangential_impulse" for r in ra)
    if e == 0.0:
        assert [r.kind for r in a.impacts.transitions()] == ["grip"]
    for x, y in zip(ra, rb):
        assert abs(x.t - y.t) < AGREE
        for f in ("impulse", "w_before", "w_after"):
            assert abs(getattr(x, f) - getattr(y, f)) < AGREE * (1 + abs(getattr(x, f)))
    assert a.impacts.friction_modes == b.impacts.friction_modes
    # the trajectory and the multipliers, away from the switches (within AGREE of them the two
    # runs may be on either side)
    times = np.array([r.t for r in ra])
    away = np.min(np.abs(t[:, None] - times[None, :]), axis=1) > 1e-6
    assert np.max(np.abs(a.y[away] - b.y[away])) < AGREE
    for name in ("lambda_ineq_0", "lambda_t_ineq_0"):
        assert np.max(np.abs(a[name][away] - b[name][away])) < AGREE * G


def test_ggl_painleve_rod_is_reported_by_name_not_integrated():
    theta0 = math.atan(2.0)
    sim, q0 = _painleve_rod(2.0, theta0, formulation="ggl")
    with pytest.raises(PainleveError, match="Painleve's paradox \\(inconsistency\\)"):
        sim.simulate(np.linspace(0, 1, 11), q0=q0, v0=[-1.0, 0.0, 0.0], **TIGHT)
    spin = 1.2 * math.sqrt(G / math.sin(theta0))
    with pytest.raises(PainleveError, match="Painleve's paradox \\(indeterminacy\\)") as err:
        sim.simulate(np.linspace(0, 1, 11), q0=q0, v0=_rod_velocity(theta0, -1.0, spin), **TIGHT)
    assert err.value.t == 0.0
    res = sim.simulate(np.linspace(0, 0.05, 6), q0=q0, v0=[1.0, 0.0, 0.0], **TIGHT)
    assert res.impacts.friction_modes in ({0: "slip+"}, {0: "free"})


def test_ggl_painleve_rod_sliding_into_the_paradox_is_stopped_before_the_problem_turns_singular():
    """The rod of test_friction's singular case: index-1 stops at the determinant's zero; GGL where
    it has fallen to 1e-4 of its value (IDA cannot step up to the zero: lambda, an unknown, grows
    without bound), measured 2.3e-5 relative before the index-1 time."""
    theta0 = math.radians(30)
    t = np.linspace(0, 0.3, 31)
    stops = {}
    for form in ("index1", "ggl"):
        sim, q0 = _painleve_rod(2.0, theta0, formulation=form)
        with pytest.raises(PainleveError, match="Painleve's paradox at t = .*became singular") as err:
            sim.simulate(t, q0=q0, v0=[-20.0, 0.0, 0.0], rtol=1e-10, atol=1e-12)
        stops[form] = err.value.t
        assert err.value.t == float(str(err.value).split("t = ")[1].split(":")[0])
    assert stops["ggl"] < stops["index1"] and stops["ggl"] == pytest.approx(stops["index1"], rel=1e-4)


def test_ggl_friction_refuses_what_it_cannot_take_by_name():
    sim = _incline(0.5, 0.3, formulation="ggl")
    with pytest.raises(LagcodegenError, match="native IDA driver"):
        sim.simulate((0, 1), q0=[0.0, 0.0], v0=[0.0, 0.0], backend="sksundae")


@pytest.mark.parametrize("tangents", ["y", "xy"])
def test_ggl_quaternion_sphere_with_backspin_slips_then_rolls(tangents):
    """Generalized speeds on the GGL driver (a free joint in quaternions, the positions corrected
    along the speeds' images q' - k(q, v + R_h^T mu)): the sphere launched with backspin slips
    until t* = 2 (v0 + R w0) / (7 mu g), then rolls at (5 v0 - 2 R w0) / 7, both to 1e-9; the
    quaternion keeps its unit norm and the centre its height."""
    v0, w0 = 3.0, 4.0
    sim = compile_constrained(_sphere_system(MU, 0.0, "quaternion", tangents), "ggl")
    t_star = 2 * (v0 + RADIUS * w0) / (7 * MU * G)
    t = np.linspace(0, 2 * t_star, 40)
    q0, u0 = _start("quaternion", (0, v0, 0), (w0, 0, 0))
    res = sim.simulate(t, q0=q0, v0=u0, **TIGHT)
    grips = res.impacts.transitions(0)
    assert [r.kind for r in grips] == ["grip"], res.impacts.records
    assert grips[0].t == pytest.approx(t_star, rel=1e-9)
    vy = np.array([sim.compiled.rhs(tt, yy)[1] for tt, yy in zip(res.t, res.y)])  # the centre's world y'
    assert np.max(np.abs(vy[res.t > t_star] / ((5 * v0 - 2 * RADIUS * w0) / 7) - 1)) < 1e-9
    assert np.max(np.abs(np.linalg.norm(res.y[:, 3:7], axis=1) - 1)) < 1e-9
    assert np.max(np.abs(res.y[:, 2] - RADIUS)) < 1e-10


def test_ggl_friction_code_and_the_impact_runtime_compile_strictly(tmp_path):
    """The generated <prefix>_impact.c of a GGL system with friction (the lcg_imp_friction table)
    and the impact runtime (the drivers lcg_imp.c, lcg_imp_ida.c and the friction core
    lcg_imp_fric.c) compile with -Wall -Wextra -Werror -std=c99 -pedantic."""
    import subprocess

    import sympy as sp
    from helpers import STRICT_CFLAGS

    from lagcodegen.build import config_header, find_sundials, generated_headers, types_headers
    from lagcodegen.codegen.constrained import generate_constrained
    from lagcodegen.runtime import sources as runtime_files
    from lagcodegen.simulation.constrained_impacts import RUNTIME_FILES
    m = lcg.Model("strict_ggl_fr")
    x, y = m.coordinates("x y")
    m.parameters(g=G, m=1.0)
    m.particle("b", sp.Symbol("m"), (x, y))
    m.gravity(sp.Symbol("g"))
    system = lcg.ConstrainedSystem(m, inequalities=[
        lcg.Inequality(y, restitution=0.2, tangent=x, friction=0.4), lcg.Inequality(2 - x, restitution=0.5)])
    code, _ = generate_constrained(system, ggl=True)
    files = {**runtime_files(RUNTIME_FILES), "lcg_config.h": config_header(find_sundials()), **generated_headers(),
             **types_headers(("dae", "cvc", "ida")), **code.files}
    for name, text in files.items():
        (tmp_path / name).write_text(text)
    assert "strict_ggl_fr_imp_friction_table" in files["strict_ggl_fr_impact.c"]
    for name in ("strict_ggl_fr_impact.c", "lcg_imp_fric.c", "lcg_imp.c", "lcg_imp_ida.c", "lcg_imp_law.c"):
        proc = subprocess.run(["cc", *STRICT_CFLAGS, "-c", name, "-o", "/dev/null"], cwd=tmp_path, capture_output=True,
                              text=True)
        assert proc.returncode == 0, (name, proc.stderr)
