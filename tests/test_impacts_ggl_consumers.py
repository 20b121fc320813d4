"""Contacts on the GGL impact driver (IDA, lagcodegen/runtime/lcg_imp_ida.c) in the consumers
other than simulate, as tests/test_impact_consumers.py checks the index-1 driver: ensembles (each
member one run of the driver, its events and contact log kept, bit-identical to its single run)
and the integrator object (one driver run per propagate call, the contacts' modes carried from
call to call), against the closed-form bouncing ball and, with Coulomb friction, the block on an
incline and the disc launched with backspin."""

from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp

import lagcodegen as lcg
from lagcodegen.api import compile_constrained

from test_friction import TIGHT, _incline, _roller

G = 9.81


def _ball(e: float):
    m = lcg.Model("gcball")
    (y,) = m.coordinates("y")
    m.parameters(g=G, m=1.0)
    m.particle("b", sp.Symbol("m"), (0, y))
    m.gravity(sp.Symbol("g"))
    apex = lcg.Event("apex", sp.Symbol("y_dot"), direction=-1, terminal=False)
    return compile_constrained(lcg.ConstrainedSystem(m, inequalities=[lcg.Inequality(y, restitution=e)]),
                               "ggl", outputs=["energy"], events=[apex])


@pytest.fixture(scope="module")
def ball():
    return _ball(0.8)


def _same_run(a, b) -> None:
    """Two runs equal bit for bit: trajectory, outputs, events, contact log."""
    assert np.array_equal(a.t, b.t) and np.array_equal(a.y, b.y)
    assert a.outputs.keys() <= b.outputs.keys() or b.outputs.keys() <= a.outputs.keys()
    for name in a.outputs.keys() & b.outputs.keys():
        assert np.array_equal(a[name], b[name]), name
    assert [(r.name, r.t, r.direction) for r in a.events] == [(r.name, r.t, r.direction) for r in b.events]
    for ra, rb in zip(a.events, b.events):
        assert np.array_equal(ra.y, rb.y)
    assert a.impacts.records == b.impacts.records
    assert a.impacts.final_modes == b.impacts.final_modes
    assert a.impacts.friction_modes == b.impacts.friction_modes


H0 = np.array([1.0, 0.5, 2.0, 0.3])
T = np.linspace(0, 3, 301)


def test_ggl_ensemble_member_is_its_simulate_run_bit_for_bit(ball):
    e = 0.8
    ens = ball.ensemble(T, q0=H0[:, None], v0=np.zeros((4, 1)), save="trajectory", rtol=1e-10, atol=1e-12,
                        threads=2)
    assert (ens.status == 0).all() and ens.formulation == "ggl"
    for i, h0 in enumerate(H0):
        single = ball.simulate(T, q0=[h0], v0=[0.0], rtol=1e-10, atol=1e-12)
        member = ens.member(i)
        _same_run(member, single)
        assert ens.stats["impacts"][i] == single.stats["impacts"] and ens.stats["events"][i] == len(single.events)
        t1 = math.sqrt(2 * h0 / G)
        bounces = member.impacts.select("bounce")[:3]
        k = np.arange(len(bounces))
        exact = t1 + 2 * t1 * e * (1 - e**k) / (1 - e)
        assert len(bounces) == 3 and np.max(np.abs(np.array([r.t for r in bounces]) / exact - 1)) < 1e-8
    # a member starting below the floor is rejected by name; the others run
    ens = ball.ensemble((0, 1), q0=[[1.0], [-0.5]], v0=[[0.0], [0.0]])
    assert ens.status[0] == 0 and ens.status[1] == -84 and "violated" in ens.messages[1]


@pytest.mark.parametrize("alpha, mu", [(0.5, 0.6), (0.5, 0.3)])
def test_ggl_ensemble_with_friction_members_are_their_runs(alpha, mu):
    sim = _incline(alpha, mu, formulation="ggl")
    V = np.array([[0.0, 0.0], [-1.0, 0.0], [1.5, 0.0]])
    t = np.linspace(0, 2, 41)
    ens = sim.ensemble(t, q0=np.zeros((3, 2)), v0=V, save="trajectory", **TIGHT)
    assert (ens.status == 0).all()
    for i in range(3):
        single = sim.simulate(t, q0=[0.0, 0.0], v0=V[i], **TIGHT)
        _same_run(ens.member(i), single)
    # the member launched up the slope: stops at v0 / (g (sin + mu cos)), then grips or slides back
    trans = ens.member(1).impacts.transitions(0)
    t1 = 1.0 / (G * (math.sin(alpha) + mu * math.cos(alpha)))
    assert len(trans) == 1 and trans[0].t == pytest.approx(t1, rel=1e-9)
    assert trans[0].kind == ("grip" if math.tan(alpha) <= mu else "reverse")


def test_ggl_integrator_over_the_whole_grid_is_the_simulate_run(ball):
    T6 = np.linspace(0, 3, 301)
    ref = ball.simulate(T6, q0=[1.0], v0=[0.0], rtol=1e-12, atol=1e-14)
    with ball.integrator(q0=[1.0], v0=[0.0], rtol=1e-12, atol=1e-14) as integ:
        assert integ.family == "ida"
        out = integ.propagate_grid(T6)
        assert np.array_equal(out, ref.y)
        assert integ.impacts.records == ref.impacts.records
        assert [(r.name, r.t) for r in integ.events] == [(r.name, r.t) for r in ref.events]
        with pytest.raises(lcg.LagcodegenError, match="step .*not available for systems with contacts"):
            integ.step()


def test_ggl_integrator_in_short_calls_bounces_rests_as_the_closed_form(ball):
    # the bouncing ball stepped 0.01 s at a time on the GGL driver: impacts located inside the
    # calls, the jumps applied, then resting on the floor; the bounce times, rebound heights and
    # the switch to persistent contact to test_impact_consumers.py's bounds (1e-9)
    e, h0, speed = 0.8, 1.0, 1e-6
    integ = ball.integrator(q0=[h0], v0=[0.0], rtol=1e-12, atol=1e-14,
                            contacts=lcg.ContactOptions(contact_speed=speed))
    records, apexes = [], []
    for _ in range(600):
        integ.propagate_for(0.01)
        records += integ.impacts.records
        apexes += [r for r in integ.events if r.name == "apex"]
    t1 = math.sqrt(2 * h0 / G)
    bounces = [r for r in records if r.kind == "bounce"]
    assert len(bounces) >= 20
    k = np.arange(20)
    t_exact = t1 + 2 * t1 * e * (1 - e**k) / (1 - e)
    assert np.max(np.abs(np.array([r.t for r in bounces[:20]]) / t_exact - 1)) < 1e-9
    w_after = np.array([r.w_after for r in bounces[:20]])
    assert np.max(np.abs(w_after**2 / (2 * G) / (h0 * e ** (2 * (k + 1))) - 1)) < 1e-9
    heights = np.array([r.y[0] for r in apexes[:5]])
    assert np.max(np.abs(heights / (h0 * e ** (2 * np.arange(1, 6))) - 1)) < 1e-9
    t_zeno = t1 * (1 + e) / (1 - e)
    sticks = [r for r in records if r.kind == "stick"]
    assert len(sticks) == 1
    assert t_zeno - 2 * (speed / e) / (G * (1 - e)) - 1e-9 <= sticks[0].t <= t_zeno + 1e-9
    assert integ.impacts.final_modes == {0: "contact"}
    assert abs(integ.state[0]) < 1e-9 and abs(integ.state[1]) < 1e-9
    assert integ.time == pytest.approx(6.0, rel=1e-12)


def test_ggl_integrator_with_friction_carries_the_modes_across_calls():
    # the disc launched sliding with backspin, in calls of 0.02 s: it slides (mode slip+ carried
    # from call to call), grips at t* = (v0 + R w0) / (3 mu g) inside a call and rolls at
    # (2 v0 - R w0) / 3
    mu, R, v0, w0 = 0.2, 0.3, 3.0, 4.0
    sim = _roller(0.5, mu, formulation="ggl")
    t_star = (v0 + R * w0) / (3 * mu * G)
    integ = sim.integrator(q0=[0.0, R, 0.0], v0=[v0, 0.0, w0], **TIGHT)
    grips, modes = [], []
    while integ.time < 1.5 * t_star:
        integ.propagate_for(0.02)
        grips += [r for r in integ.impacts.records if r.kind == "grip"]
        modes.append(integ.impacts.friction_modes[0])
    assert len(grips) == 1 and grips[0].t == pytest.approx(t_star, rel=1e-9)
    assert modes[0] == "slip+" and modes[-1] == "stick"
    assert integ.state[3] == pytest.approx((2 * v0 - R * w0) / 3, rel=1e-9)
    assert integ.state[3] + R * integ.state[5] == pytest.approx(0.0, abs=1e-9)


def test_ggl_integrator_with_contacts_refuses_multipliers_by_name(ball):
    with ball.integrator(q0=[1.0], v0=[0.0]) as integ:
        integ.propagate_for(0.1)
        with pytest.raises(lcg.LagcodegenError, match="multipliers is not available for systems with contacts"):
            integ.multipliers


def test_ggl_contact_run_stops_on_the_ensembles_cancel_flag(ball):
    # the flag an ensemble sets on Ctrl-C (tests/test_impact_consumers.py's subprocess test on
    # index-1) reaches IDA: a member's run stops with -80
    from lagcodegen.solvers.registry import resolve
    p = ball._default_p
    y0 = np.array([1.0, 0.0])
    run = ball.contact_run(resolve("ggl", None, {}), 0.0, y0, p, 1e-10, 1e-12, True, None)
    t = np.linspace(0, 3, 31)
    stopped = run.execute(t, y0, p, cancel=np.ones(1, dtype=np.intc))
    assert stopped.status == -80 and stopped.t.size == 1
    full = run.execute(t, y0, p, cancel=np.zeros(1, dtype=np.intc))
    assert full.status == 0 and full.t.size == t.size
