"""Contacts with restitution on the Taylor method (``simulate(method="taylor")``: the Taylor contact
driver, lagcodegen/runtime/lcg_taylor_imp.c, on the contact jet of lagcodegen.codegen.taylor.contacts),
checked against the same independent facts as the index-1 driver in tests/test_impacts.py (the
closed-form bouncing ball, Newton's cradle, the particle leaving the sphere, the floor that pulls,
the rocking block's impact ratio) and against the index-1 driver's runs of the same systems; its
ensembles; the refusals by name; the generated C strict and under the sanitizers."""

from __future__ import annotations

import math
import subprocess

import numpy as np
import pytest
import sympy as sp

import lagcodegen as lcg
from lagcodegen.api import compile_constrained
from lagcodegen.errors import LagcodegenError, ModelError
from lagcodegen.solvers.family import Request
from test_impacts import G, _ball, _rocking_block, housner_block, lifting_floor, newtons_cradle, sphere_contact
from test_impacts_solvers import _ball_system, _pendulum_wall

TIGHT = {"rtol": 1e-12, "atol": 1e-14}


@pytest.fixture(scope="module")
def ball():
    return _ball(0.8)


@pytest.mark.parametrize("formulation", ["index1", "minimal"])
def test_bouncing_ball_impact_times_apex_heights_zeno_and_resting_contact(formulation):
    """The bounds of tests/test_impacts.py's bouncing ball: impact times, rebound speeds, Newton's
    law and impulses, apex heights, the accumulation into persistent contact, lambda = m g at rest."""
    sim = _ball(0.8, formulation)
    e, h0 = 0.8, 1.0
    t1 = math.sqrt(2 * h0 / G)
    speed = 1e-6
    res = sim.simulate(np.linspace(0, 6, 6001), q0=[h0], v0=[0.0], method="taylor",
                       contacts=lcg.ContactOptions(contact_speed=speed), **TIGHT)
    assert res.method == "taylor" and res.formulation == formulation
    bounces = res.impacts.select("bounce")
    assert len(bounces) >= 20
    k = np.arange(20)
    t_exact = t1 + 2 * t1 * e * (1 - e**k) / (1 - e)
    t_found = np.array([r.t for r in bounces[:20]])
    assert np.max(np.abs(t_found / t_exact - 1)) < 1e-9
    w_after = np.array([r.w_after for r in bounces[:20]])
    assert np.max(np.abs(w_after / (e ** (k + 1) * math.sqrt(2 * G * h0)) - 1)) < 1e-9
    for r in bounces[:20]:
        assert r.w_after == pytest.approx(-e * r.w_before, rel=1e-12)
        assert r.impulse == pytest.approx(-(1 + e) * r.w_before, rel=1e-12)
    apex = w_after**2 / (2 * G)
    assert np.max(np.abs(apex / (h0 * e ** (2 * (k + 1))) - 1)) < 1e-9
    # the apexes on the output grid: the largest y between impacts k and k+1 (the grid's step
    # 1e-3 s bounds how far below the apex a grid point may be: g dt^2 / 8)
    for j in range(5):
        between = (res.t > t_found[j]) & (res.t < t_found[j + 1])
        assert h0 * e ** (2 * (j + 1)) - res["y"][between].max() < G * 1e-6 / 8 + 1e-12
    t_zeno = t1 * (1 + e) / (1 - e)
    sticks = res.impacts.select("stick")
    assert len(sticks) == 1
    assert t_zeno - 2 * (speed / e) / (G * (1 - e)) - 1e-9 <= sticks[0].t <= t_zeno + 1e-9
    assert res.impacts.final_modes == {0: "contact"}
    assert res.impacts.accumulation_time(0) == pytest.approx(t_zeno, rel=1e-9)
    after = res.t > t_zeno + 1e-3
    assert np.max(np.abs(res["lambda_ineq_0"][after] - G)) < 1e-9
    assert np.max(np.abs(res["y"][after])) < 1e-9
    assert np.all(res["lambda_ineq_0"][res.t < sticks[0].t] == 0.0)
    assert res["y"].min() > -1e-12  # never through the floor


@pytest.mark.parametrize("e", [0.1, 0.5, 0.8])
@pytest.mark.parametrize("tolerances", [{}, {"rtol": 1e-8, "atol": 1e-10}, {"rtol": 1e-4, "atol": 1e-6}])
def test_bouncing_ball_never_tunnels(e, tolerances):
    """Every root of a step's gap polynomial is isolated, so no flight is skipped at any
    tolerance: the ball rests on the floor held by m g, the first impacts at the closed form."""
    h0 = 1.0
    res = _ball(e).simulate(np.linspace(0, 6, 601), q0=[h0], v0=[0.0], method="taylor", **tolerances)
    y = res["y"]
    assert y.min() > -1e-9, y.min()
    assert abs(y[-1]) < 1e-9 and res["lambda_ineq_0"][-1] == pytest.approx(G, rel=1e-9)
    t1 = math.sqrt(2 * h0 / G)
    first = [r.t for r in res.impacts.select("bounce")[:3]]
    k = np.arange(len(first))
    rtol = tolerances.get("rtol", 1e-6)
    assert np.allclose(first, t1 + 2 * t1 * e * (1 - e**k) / (1 - e), rtol=max(100 * rtol, 1e-9))
    assert res.impacts.select("stick")[0].t == pytest.approx(t1 * (1 + e) / (1 - e), rel=1e-2)


@pytest.mark.parametrize("formulation", ["index1", "minimal"])
def test_newtons_cradle_passes_the_velocity_to_the_last_ball(formulation):
    sim = newtons_cradle(formulation)
    gap = 1e-3
    res = sim.simulate(np.linspace(0, 1, 11), q0=[0.0, 0.1 + gap, 0.2 + 2 * gap], v0=[1.0, 0.0, 0.0],
                       method="taylor", **TIGHT)
    v = res.y[-1, 3:]
    assert abs(v[0]) < 1e-12 and abs(v[1]) < 1e-12 and abs(v[2] - 1.0) < 1e-12
    assert [r.contact for r in res.impacts] == [0, 1]
    assert [r.kind for r in res.impacts] == ["bounce", "bounce"]
    assert res.impacts[0].t == pytest.approx(gap, rel=1e-10)
    assert res.impacts[1].t == pytest.approx(2 * gap, rel=1e-10)
    momentum = res.y[:, 3:].sum(axis=1)
    assert np.max(np.abs(momentum - 1.0)) < 1e-12
    assert np.max(np.abs(res["energy"] - 0.5)) < 1e-12


def test_particle_leaves_the_sphere_at_arccos_two_thirds():
    """On top of the sphere, nearly at rest: persistent contact, released where the multiplier
    reaches 0, at cos(theta) = (2 + v0^2 / (g R)) / 3 (arccos(2/3) from rest), then a parabola."""
    sim = sphere_contact("index1")
    v0 = 1e-3
    res = sim.simulate(np.linspace(0, 3.2, 321), q0=[0.0, 1.0], v0=[v0, 0.0], method="taylor",
                       rtol=1e-11, atol=1e-13)
    assert [r.kind for r in res.impacts] == ["release"]
    t_off = res.impacts[0].t
    at = sim.simulate(np.array([0.0, t_off]), q0=[0.0, 1.0], v0=[v0, 0.0], method="taylor", rtol=1e-11, atol=1e-13)
    assert at["y"][-1] == pytest.approx((2 + v0**2 / G) / 3, rel=1e-8)
    assert math.acos(at["y"][-1]) == pytest.approx(math.acos(2 / 3), abs=1e-5)
    assert np.all(res["lambda_ineq_0"][res.t > t_off] == 0.0)
    assert np.all(res["lambda_ineq_0"][res.t < t_off] > 0.0)
    assert np.max(np.abs(res["energy"] - res["energy"][0])) < 1e-8
    tau = res.t[res.t > t_off + 0.1] - t_off
    yq = at["y"][-1] + at["y_dot"][-1] * tau - G / 2 * tau**2
    assert np.max(np.abs(res["y"][res.t > t_off + 0.1] - yq)) < 1e-7
    assert res.impacts.final_modes == {0: "free"}
    index1 = sim.simulate(np.linspace(0, 3.2, 321), q0=[0.0, 1.0], v0=[v0, 0.0], rtol=1e-11, atol=1e-13)
    assert t_off == pytest.approx(index1.impacts[0].t, rel=1e-8)


def test_ball_released_when_the_floor_would_pull():
    """The multiplier m (g + 1 - 20 t) of a ball on the accelerating floor, released at (g + 1) / 20."""
    res = lifting_floor().simulate(np.linspace(0, 0.8, 81), q0=[0.0], v0=[0.0], method="taylor",
                                   rtol=1e-11, atol=1e-13)
    assert [r.kind for r in res.impacts] == ["release"]
    t_off = res.impacts[0].t
    assert t_off == pytest.approx((G + 1) / 20, rel=1e-12)
    before, after = res.t < t_off, res.t > t_off
    assert np.all(np.abs(res["lambda_ineq_0"][before] - (G + 1 - 20 * res.t[before])) < 1e-9)
    assert np.all(res["lambda_ineq_0"][after] == 0.0)
    tt = res.t[after]
    assert np.all(res["y"][after] > 0.5 * tt**2 - 10 / 3 * tt**3)


def _agree(sim, t, q0, v0, dt: float, dy: float, **options):
    """The Taylor run of ``sim`` and the index-1 driver's: the same records (kinds, contacts), their
    times within ``dt``, the states and multipliers within ``dy``."""
    a = sim.simulate(t, q0=q0, v0=v0, **TIGHT, **options)
    b = sim.simulate(t, q0=q0, v0=v0, method="taylor", **TIGHT, **options)
    assert [(r.contact, r.kind) for r in b.impacts] == [(r.contact, r.kind) for r in a.impacts]
    assert np.max(np.abs(np.array([r.t for r in b.impacts]) - [r.t for r in a.impacts])) < dt
    assert np.max(np.abs(b.y - a.y)) < dy
    for k in a.impacts.final_modes:
        assert np.max(np.abs(b[f"lambda_ineq_{k}"] - a[f"lambda_ineq_{k}"])) < dy
    assert b.impacts.final_modes == a.impacts.final_modes
    return a, b


def test_agrees_with_the_index1_driver_on_equality_rows_no_slip_rows_and_minimal_coordinates(ball):
    # the last impacts before the accumulation (rebounds of 1e-6 m/s) are located by CVODE to about
    # atol / speed = 1e-8 s
    _agree(ball, np.linspace(0, 6, 601), [1.0], [0.0], 1e-7, 1e-8)
    # a pendulum in Cartesian coordinates (an equality row) hitting a wall: index-1 and minimal
    _agree(compile_constrained(_pendulum_wall(0.5), "index1"), np.linspace(0, 3, 301), [-0.6, -0.8], [0.0, 0.0],
           1e-9, 1e-9)
    _agree(compile_constrained(_pendulum_wall(0.5), "minimal"), np.linspace(0, 3, 301), [-0.6, -0.8], [0.0, 0.0],
           1e-9, 1e-9)
    # Housner's block on no-slip corners (the tangential rows held with their contact)
    b, h, phi0 = 0.2, 0.6, 0.1
    q0 = [-b + b * math.cos(phi0) - h * math.sin(phi0), h * math.cos(phi0) + b * math.sin(phi0), phi0]
    _agree(compile_constrained(housner_block("thousner", b, h), "index1"), np.linspace(0, 1.0, 101), q0,
           [0.0, 0.0, 0.0], 1e-9, 1e-8)


def test_floating_body_with_generalized_speeds_bounces_as_on_the_index1_driver():
    """A body on a free joint (quaternion, generalized speeds: the rows act on v, q' = k(q, v, t))
    spinning about its vertical axis, dropped onto the ground: the bounce at sqrt(2 h / g), the
    apex e^2 h, and the index-1 driver's run."""
    from test_constrained_speeds import dropped_box
    e, r, yaw, wz, h = 0.6, 0.1, 0.7, 3.0, 0.4
    sim = compile_constrained(dropped_box("quaternion", (0, 0, -r), e))
    q0 = [0, 0, h + r, 0, 0, math.sin(yaw / 2), math.cos(yaw / 2)]
    v0 = [0, 0, 0, 0, 0, wz]
    t1 = math.sqrt(2 * h / G)
    a, b = _agree(sim, np.linspace(0, t1 * (1 + e), 51), q0, v0, 1e-12, 1e-10)
    (bounce,) = b.impacts.select("bounce")
    assert bounce.t == pytest.approx(t1, rel=1e-12)
    assert b.y[-1, 2] - r == pytest.approx(e * e * h, rel=1e-10)


def test_budgets_and_ctrl_c_stop_a_run(tmp_path, ball):
    from lagcodegen.errors import SolverError
    with pytest.raises(SolverError, match="max_steps = 5"):
        ball.simulate((0, 6), q0=[1.0], v0=[0.0], method="taylor", max_steps=5)
    res = ball.simulate((0, 6), q0=[1.0], v0=[0.0], method="taylor", max_steps=5, raise_on_error=False)
    assert res.status == -1 and len(res.impacts) == 5 and res.stats["steps"] == 5  # a step to each impact
    import textwrap

    from helpers import interrupt_when_ready
    script = tmp_path / "long.py"
    script.write_text(textwrap.dedent("""
        import sys
        import numpy as np
        import sympy as sp
        import lagcodegen as lcg
        from lagcodegen.api import compile_constrained
        m = lcg.Model("ctrlc_tball")
        (y,) = m.coordinates("y")
        m.parameters(g=9.81, m=1.0)
        m.particle("b", sp.Symbol("m"), (0, y))
        m.gravity(sp.Symbol("g"))
        sim = compile_constrained(lcg.ConstrainedSystem(m, inequalities=[lcg.Inequality(y, restitution=1.0)]))
        sim.simulate(np.array([0.0, 1.0]), q0=[1.0], v0=[0.0], method="taylor")
        print("ready", flush=True)
        try:
            sim.simulate(np.array([0.0, 1e9]), q0=[1.0], v0=[0.0], max_steps=10**15, method="taylor",
                         contacts=lcg.ContactOptions(max_records=10))
        except KeyboardInterrupt:
            print("interrupted", file=sys.stderr)
            sys.exit(130)
    """))
    returncode, err, took = interrupt_when_ready(script)
    assert returncode == 130, err
    assert "interrupted" in err and took < 10


def test_rocking_block_impact_ratio_and_rest_after_the_accumulation():
    """The frictionless block's first impact: the left corner released, the right one plastic,
    w+/w- = (1 - 3 sin^2 a) / (1 + 3 sin^2 a) (tests/test_impacts.py); the rocking accumulates at
    a finite time, after which the block rests flat on both corners (their multipliers m g / 2)."""
    b, h, phi0 = 0.2, 0.6, 0.1
    sim = _rocking_block()
    y0 = h * math.cos(phi0) + b * math.sin(phi0)
    res = sim.simulate(np.linspace(0, 1.0, 101), q0=[0.0, y0, phi0], v0=[0.0, 0.0, 0.0], method="taylor", **TIGHT)
    first = res.impacts.select("stick")[0]
    t_hit = first.t
    assert [(r.contact, r.kind) for r in res.impacts if r.t <= t_hit] == [(0, "release"), (1, "stick")]
    near = sim.simulate(np.array([0.0, t_hit - 1e-9, t_hit + 1e-9]), q0=[0.0, y0, phi0], v0=[0.0, 0.0, 0.0],
                        method="taylor", **TIGHT)
    w_minus, w_plus = near["phi_dot"][1], near["phi_dot"][2]
    sin2 = b**2 / (b**2 + h**2)
    assert w_plus / w_minus == pytest.approx((1 - 3 * sin2) / (1 + 3 * sin2), rel=1e-7)
    assert res.impacts.final_modes == {0: "contact", 1: "contact"}
    rest = res.t > 0.5
    assert np.max(np.abs(res["lambda_ineq_0"][rest] - G / 2)) < 1e-6
    assert np.max(np.abs(res["lambda_ineq_1"][rest] - G / 2)) < 1e-6
    assert np.max(np.abs(res["phi"][rest])) < 1e-9 and np.max(np.abs(res["x"])) < 1e-12


def test_ensemble_members_are_their_single_runs(ball):
    h0 = np.array([[1.0], [0.5], [2.0]])
    t = np.linspace(0, 3, 301)
    ens = ball.ensemble(t, q0=h0, v0=np.zeros((3, 1)), method="taylor", save="trajectory", **TIGHT)
    for i in range(3):
        single = ball.simulate(t, q0=h0[i], v0=[0.0], method="taylor", **TIGHT)
        member = ens.member(i)
        assert member.impacts.records == single.impacts.records
        assert member.impacts.final_modes == single.impacts.final_modes
        assert np.array_equal(member.y, single.y)
        first = single.impacts.select("bounce")[0]
        assert first.t == pytest.approx(math.sqrt(2 * h0[i, 0] / G), rel=1e-12)


def test_events_on_the_polynomials_apexes_and_a_terminal_stop():
    """The compiled events of a system with contacts, located on each step's polynomial: the apex
    (y' = 0 downwards) after each bounce at the closed form's time and height, as the index-1
    driver records them; a terminal event ends the run there (the row appended, as on CVODE)."""
    m = lcg.Model("tball_ev")
    (y,) = m.coordinates("y")
    m.parameters(g=G, m=1.0)
    m.particle("b", sp.Symbol("m"), (0, y))
    m.gravity(sp.Symbol("g"))
    apex = lcg.Event("apex", sp.Symbol("y_dot"), direction=-1, terminal=False)
    stop = lcg.Event("stop", m.t - 2.5, direction=1, terminal=True)
    sim = compile_constrained(lcg.ConstrainedSystem(m, inequalities=[lcg.Inequality(y, restitution=0.8)]),
                              "index1", events=[apex, stop])
    t = np.linspace(0, 3, 301)
    res = sim.simulate(t, q0=[1.0], v0=[0.0], method="taylor", **TIGHT)
    ref = sim.simulate(t, q0=[1.0], v0=[0.0], **TIGHT)
    assert [(r.name, r.direction) for r in res.events] == [(r.name, r.direction) for r in ref.events]
    assert res.events[-1].name == "stop" and res.t[-1] == pytest.approx(2.5, abs=1e-14)
    assert res.stats["t_reached"] == pytest.approx(2.5, abs=1e-14)
    e, t1 = 0.8, math.sqrt(2 / G)
    apexes = [r for r in res.events if r.name == "apex"]
    for k, r in enumerate(apexes):
        speed = e ** (k + 1) * math.sqrt(2 * G)
        t_apex = t1 + 2 * t1 * e * (1 - e**k) / (1 - e) + speed / G
        assert r.t == pytest.approx(t_apex, rel=1e-12)
        assert r.y[0] == pytest.approx(e ** (2 * (k + 1)), rel=1e-10)
    assert np.max(np.abs(np.array([r.t for r in apexes]) - [r.t for r in ref.events if r.name == "apex"])) < 1e-8
    # the integrator object's calls and the ensembles' members record them as well
    integ = sim.integrator(q0=[1.0], v0=[0.0], method="taylor", **TIGHT)
    integ.propagate_until(1.0)
    assert [r.name for r in integ.events] == ["apex"] and integ.events[0].t == pytest.approx(apexes[0].t, rel=1e-12)
    ens = sim.ensemble(t, q0=[[1.0], [0.5]], v0=[[0.0], [0.0]], method="taylor", **TIGHT)
    assert [(r.name, r.t) for r in ens.member(0).events] == [(r.name, r.t) for r in res.events]


def test_integrator_object_is_the_simulate_run_and_bounces_in_short_calls(ball):
    """propagate_grid over a run's times is that run (one driver call, bit for bit); 600 short
    calls (the modes carried between them) bounce at the closed form's times and rest on the floor."""
    t = np.linspace(0, 6, 601)
    res = ball.simulate(t, q0=[1.0], v0=[0.0], method="taylor", **TIGHT)
    integ = ball.integrator(q0=[1.0], v0=[0.0], method="taylor", **TIGHT)
    assert integ.family == "taylor"
    assert np.array_equal(integ.propagate_grid(t), res.y)
    assert integ.impacts.records == res.impacts.records
    integ = ball.integrator(q0=[1.0], v0=[0.0], method="taylor", **TIGHT)
    records = []
    for tk in t[1:]:
        integ.propagate_until(tk)
        records += integ.impacts.records
    e, t1 = 0.8, math.sqrt(2 / G)
    bounces = [r.t for r in records if r.kind == "bounce"][:20]
    k = np.arange(20)
    assert np.max(np.abs(np.array(bounces) / (t1 + 2 * t1 * e * (1 - e**k) / (1 - e)) - 1)) < 1e-9
    assert integ.impacts.final_modes == {0: "contact"} and abs(integ.state[0]) < 1e-12
    with pytest.raises(LagcodegenError, match="Integrator.step"):
        integ.step()


def test_refusals_and_bad_input_name_the_problem(ball):
    with pytest.raises(LagcodegenError, match="scalar atol"):
        ball.simulate((0, 1), q0=[1.0], v0=[0.0], method="taylor", atol=[1e-8, 1e-8])
    with pytest.raises(LagcodegenError, match="tolerances must be finite"):
        ball.simulate((0, 1), q0=[1.0], v0=[0.0], method="taylor", rtol=-1.0)
    with pytest.raises(LagcodegenError, match="order must be an integer"):
        ball.simulate((0, 1), q0=[1.0], v0=[0.0], method="taylor", order=1)
    with pytest.raises(LagcodegenError, match="sensitivities of systems with contacts"):
        ball.simulate((0, 1), q0=[1.0], v0=[0.0], method="taylor", sensitivities=["g"])
    with pytest.raises(ModelError, match="violated"):
        ball.simulate((0, 1), q0=[-0.5], v0=[0.0], method="taylor")
    with pytest.raises(LagcodegenError, match="baumgarte must be 'auto' or"):
        ball.simulate((0, 1), q0=[1.0], v0=[0.0], method="taylor", baumgarte="fast")
    res = ball.simulate((0, 1), q0=[1.0], v0=[0.0], method="taylor", baumgarte=(5.0, 5.0))
    assert res.stats["alpha"] == 5.0 and res.stats["beta"] == 5.0
    # an event whose expression uses a multiplier is not a row of the jet: refused when located
    m = lcg.Model("tpwall_ev")
    x, y = m.coordinates("x y")
    m.parameters(g=G, m=1.0, l=1.0, d=0.3)
    m.particle("b", sp.Symbol("m"), (x, y))
    m.gravity(sp.Symbol("g"))
    system = lcg.ConstrainedSystem(m, holonomic=[x**2 + y**2 - sp.Symbol("l") ** 2],
                                   inequalities=[lcg.Inequality(sp.Symbol("d") - x, restitution=0.5)])
    pull = lcg.Event("pull", system.multipliers[0] + 5, direction=0, terminal=False)
    sim = compile_constrained(system, "index1", events=[pull])
    with pytest.raises(LagcodegenError, match="does not locate the event.s. pull: their expressions use a multiplier"):
        sim.simulate((0, 1), q0=[-0.6, -0.8], v0=[0.0, 0.0], method="taylor")
    assert sim.simulate((0, 3), q0=[-0.6, -0.8], v0=[0.0, 0.0], method="taylor", events=False).impacts.select("bounce")
    assert lcg.Taylor().supports("index1", Request(kind="stepper", roots=True, contacts=lcg.ContactOptions()))
    # constrained systems have no prepared runs (the fast path is the ODE face's): refused by the table
    with pytest.raises(LagcodegenError, match="Taylor has no prepared run runner for a constrained system"):
        lcg.Taylor().check("index1", Request(kind="prepared", contacts=lcg.ContactOptions()))
    # GGL takes its contacts on IDA; constrained systems without contacts stay on CVODE / IDA
    with pytest.raises(LagcodegenError, match="IDA integrates with BDF only"):
        compile_constrained(_ball_system(0.5), "ggl").simulate((0, 1), q0=[1.0], v0=[0.0], method="taylor")
    m2 = lcg.Model("tpend_nc")
    x2, y2 = m2.coordinates("x y")
    m2.parameters(g=G, m=1.0)
    m2.particle("b", sp.Symbol("m"), (x2, y2))
    m2.gravity(sp.Symbol("g"))
    plain = compile_constrained(lcg.ConstrainedSystem(m2, holonomic=[x2**2 + y2**2 - 1]), "index1")
    with pytest.raises(LagcodegenError, match="Taylor method integrates constrained systems with contacts"):
        plain.simulate((0, 1), q0=[0.6, -0.8], v0=[0.0, 0.0], method="taylor")
    with pytest.raises(LagcodegenError, match="Taylor method integrates constrained systems with contacts"):
        plain.integrator(q0=[0.6, -0.8], v0=[0.0, 0.0], method="taylor")
    with pytest.raises(LagcodegenError, match="Taylor has no ensemble runner"):
        plain.ensemble((0, 1), q0=[[0.6, -0.8]], v0=[[0.0, 0.0]], method="taylor")


def test_contact_driver_and_jet_compile_strictly_and_run_clean_under_sanitizers(tmp_path, cc):
    """The contact jet of the ball (generated), the Taylor contact driver and the impact law (runtime
    files) and the ball's constrained code, compiled with -Wall -Wextra -Werror -std=c99 -pedantic,
    then run under ASan/UBSan from C: the first impact at the closed form, the ball at rest on the
    floor at the end, held by m g; a table of another version refused."""
    from lagcodegen.codegen.constrained import generate_constrained
    from lagcodegen.codegen.record import scene_of_code
    from lagcodegen.codegen.taylor.contacts import contact_jet_sources
    from lagcodegen.simulation.taylor_impacts import RUNTIME_FILES
    from lagcodegen.codegen.taylor.emit import runtime_sources
    from lagcodegen.runtime import sources as runtime_files
    from lagcodegen.build import dae_table_source, table_source, types_headers

    system = _ball_system(0.8)
    apex = lcg.Event("apex", sp.Symbol("y_dot"), direction=-1, terminal=False)
    code, info = generate_constrained(system, prefix="tsball", events=[apex])
    code.write(tmp_path)
    files = {**runtime_sources(), **runtime_files(RUNTIME_FILES), **table_source(code), **dae_table_source(code),
             **types_headers(("dae",)),
             **contact_jet_sources(system, scene_of_code(code, "test"), events=info.events)}
    for name, text in files.items():
        (tmp_path / name).write_text(text)
    strict = [cc, "-Wall", "-Wextra", "-Werror", "-std=c99", "-pedantic", "-O2", "-c"]
    for src in ("tsball_taylor_contact.c", "lcg_taylor_imp.c", "lcg_imp_law.c", "lcg_imp_fric.c"):
        proc = subprocess.run([*strict, src, "-o", "/dev/null"], cwd=tmp_path, capture_output=True, text=True)
        assert proc.returncode == 0, src + proc.stderr
    # the jets of an equality row with a contact, no-slip tangential rows, generalized speeds (a
    # jet of several chunks of operations), Coulomb friction (planar: the jet's tl_slip; 3-D: u/|u|)
    from test_constrained_speeds import dropped_box
    from test_friction_speeds import _sphere_system
    from test_friction_taylor import roller_system
    others = {"tspwall": _pendulum_wall(0.5), "tshousner": housner_block("tshousner", 0.2, 0.6),
              "tsbox": dropped_box("quaternion", (0, 0, -0.1), 0.6), "tsroller": roller_system(0.4, 0.2),
              "tssphere": _sphere_system(0.2, 0.0, "quaternion", "xy")}
    for prefix, other in others.items():
        other_code, other_info = generate_constrained(other, prefix=prefix)
        for name, text in contact_jet_sources(other, scene_of_code(other_code, "test"),
                                              events=other_info.events).items():
            (tmp_path / name).write_text(text)
        proc = subprocess.run([*strict, f"{prefix}_taylor_contact.c", "-o", "/dev/null"], cwd=tmp_path,
                              capture_output=True, text=True)
        assert proc.returncode == 0, prefix + proc.stderr
    (tmp_path / "main.c").write_text(CONTACT_MAIN)
    model_c = sorted(n.name for n in tmp_path.glob("tsball*.c") if n.name != "tsball_taylor_contact.c")
    san = [cc, "-std=c99", "-g", "-O1", "-fsanitize=address,undefined", "-fno-sanitize-recover=all"]
    proc = subprocess.run([*san, "main.c", "tsball_taylor_contact.c", "lcg_taylor_imp.c", "lcg_imp_law.c",
                           "lcg_imp_fric.c", *model_c,
                           "-o", "run", "-lm", "-pthread"], cwd=tmp_path, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    run = subprocess.run(["./run"], cwd=tmp_path, capture_output=True, text=True,
                         env={"ASAN_OPTIONS": "detect_leaks=1", "PATH": "/usr/bin:/bin"})
    assert run.returncode == 0, run.stdout + run.stderr
    flag, n_rec, t_first, y_end, lam_end, active, bad, n_events, apex_y = run.stdout.split()
    assert int(flag) == 0 and int(n_rec) > 20 and int(active) == 1 and int(bad) == -22
    assert float(t_first) == pytest.approx(math.sqrt(2 / G), rel=1e-12)
    assert int(n_events) > 20 and float(apex_y) == pytest.approx(0.8**2, rel=1e-12)
    assert abs(float(y_end)) < 1e-12 and float(lam_end) == pytest.approx(G, rel=1e-12)


CONTACT_MAIN = r"""
#include <stdio.h>
#include <string.h>
#include "lcg_taylor_imp.h"

extern const lcg_taylor_contact tsball_taylor_contact;
const lcg_imp_model *tsball_imp_model_table(void);

int main(void)
{
    double p[2] = {9.81, 1.0}, y0[2] = {1.0, 0.0}, t[3] = {0.0, 1.0, 6.0}, yout[6], out[3 * 64], lam[3];
    double e[1] = {0.8}, set[3] = {1e-6, 1e-9, 1e-9}, rec[6 * 200], stab[2] = {-1.0, -1.0};
    double et[64], ey[128];
    int active[1] = {0}, n_rec = 0, flag, bad, n1, a1, which[64], dir[64], rootdir[1] = {-1}, terminal[1] = {0};
    lcg_events ev = {64, 0, et, ey, which, dir, rootdir, terminal, 0};
    lcg_taylor_options opt;
    lcg_taylor_stats st;
    lcg_taylor_contact other = tsball_taylor_contact;

    memset(&opt, 0, sizeof opt);
    opt.rtol = 1e-12;
    opt.atol = 1e-14;
    opt.max_steps = 100000;
    flag = lcg_taylor_imp_solve(&tsball_taylor_contact, tsball_imp_model_table(), p, y0, 3, t, yout, out, lam,
                                &opt, e, set, active, 200, rec, &n_rec, &st, stab, &ev, NULL);
    n1 = n_rec;
    a1 = active[0];
    other.abi = LCG_TAYLOR_CONTACT_ABI + 1;
    bad = lcg_taylor_imp_solve(&other, tsball_imp_model_table(), p, y0, 3, t, yout, out, lam, &opt, e, set, active,
                               200, rec, &n_rec, &st, stab, NULL, NULL);
    printf("%d %d %.17g %.17g %.17g %d %d %d %.17g\n", flag, n1, rec[0], yout[4], lam[2], a1, bad, ev.n_events,
           ey[0]);
    return 0;
}
"""


def test_the_shipped_bouncing_ball_from_the_command_line_with_method_taylor(tmp_path):
    """`lagcodegen simulate examples/bouncing_ball.toml --method taylor`: the file's contacts on the
    Taylor contact driver; the ball rests on the floor, held by m g."""
    import os
    import sys
    from pathlib import Path
    root = Path(__file__).resolve().parents[1]
    out = tmp_path / "bb.csv"
    model_file = str(root / "examples" / "bouncing_ball.toml")
    proc = subprocess.run([sys.executable, "-m", "lagcodegen", "simulate", model_file, "-o", str(out), "--method",
                           "taylor"], capture_output=True, text=True, env=dict(os.environ, PYTHONPATH=str(root)),
                          timeout=600)
    assert proc.returncode == 0, proc.stderr
    data = np.loadtxt(out, delimiter=",", skiprows=1)
    header = out.read_text().splitlines()[0].split(",")
    y = data[:, header.index("y")]
    assert y.min() > -1e-12 and abs(y[-1]) < 1e-12
    assert data[-1, header.index("lambda_ineq_0")] == pytest.approx(9.81 * 1.0, rel=1e-9)  # m g (the file: m = 1)
    assert "impact(s)" in proc.stderr and "energy drift" not in proc.stderr
