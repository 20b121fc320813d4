"""Impacts on the consumers of the index-1 impact driver other than simulate: ensembles (every
event and impact recorded per member, bit-identical to the single runs, in this process and on a
Dask LocalCluster) and the integrator object (the jumps applied between its calls), checked
against the closed-form bouncing ball and Newton's cradle as tests/test_impacts.py checks simulate."""

from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp

import lagcodegen as lcg
from lagcodegen.api import compile_constrained

G = 9.81


def _ball(e: float, name: str = "cball"):
    m = lcg.Model(name)
    (y,) = m.coordinates("y")
    m.parameters(g=G, m=1.0)
    m.particle("b", sp.Symbol("m"), (0, y))
    m.gravity(sp.Symbol("g"))
    # apex: the velocity crossing zero downwards (non-terminal), recorded beside the impacts
    apex = lcg.Event("apex", sp.Symbol("y_dot"), direction=-1, terminal=False)
    return compile_constrained(lcg.ConstrainedSystem(m, inequalities=[lcg.Inequality(y, restitution=e)]),
                               "index1", outputs=["energy"], events=[apex])


def newtons_cradle():
    m = lcg.Model("ccradle")
    xs = m.coordinates("x1 x2 x3")
    m.parameters(m=1.0, d=0.1)
    for i, x in enumerate(xs):
        m.particle(f"b{i}", sp.Symbol("m"), (x, 0))
    d = sp.Symbol("d")
    ineqs = [lcg.Inequality(xs[1] - xs[0] - d, restitution=1.0), lcg.Inequality(xs[2] - xs[1] - d, restitution=1.0)]
    return compile_constrained(lcg.ConstrainedSystem(m, inequalities=ineqs), "index1", outputs=["energy"])


@pytest.fixture(scope="module")
def ball():
    return _ball(0.8)


@pytest.fixture(scope="module")
def cradle():
    return newtons_cradle()


def _same_records(a, b) -> None:
    """Two runs' events and contact logs equal bit for bit."""
    assert [(r.name, r.t, r.direction) for r in a.events] == [(r.name, r.t, r.direction) for r in b.events]
    for ra, rb in zip(a.events, b.events):
        assert np.array_equal(ra.y, rb.y)
    assert a.impacts is not None and b.impacts is not None
    assert a.impacts.records == b.impacts.records
    assert a.impacts.final_modes == b.impacts.final_modes


H0 = np.array([1.0, 0.5, 2.0, 0.3])
T = np.linspace(0, 3, 301)


def test_ensemble_of_a_bouncing_ball_records_every_event_and_impact_per_member(ball):
    e = 0.8
    ens = ball.ensemble(T, q0=H0[:, None], v0=np.zeros((4, 1)), save="trajectory", rtol=1e-10, atol=1e-12,
                        threads=2)
    assert (ens.status == 0).all()
    for i, h0 in enumerate(H0):
        single = ball.simulate(T, q0=[h0], v0=[0.0], rtol=1e-10, atol=1e-12)
        member = ens.member(i)
        _same_records(member, single)
        assert np.array_equal(member.y, single.y)
        assert np.array_equal(member["lambda_ineq_0"], single["lambda_ineq_0"])
        assert ens.stats["impacts"][i] == single.stats["impacts"] and ens.stats["events"][i] == len(single.events)
        # independent facts: impact k at t1 + 2 t1 e (1 - e^k) / (1 - e), apex k at h0 e^(2k)
        t1 = math.sqrt(2 * h0 / G)
        bounces = member.impacts.select("bounce")[:3]
        k = np.arange(len(bounces))
        exact = t1 + 2 * t1 * e * (1 - e**k) / (1 - e)
        assert len(bounces) == 3 and np.max(np.abs(np.array([r.t for r in bounces]) / exact - 1)) < 1e-8
        apexes = [r for r in member.events if r.name == "apex"]
        assert len(apexes) >= 3
        heights = np.array([r.y[0] for r in apexes[:3]])
        assert np.max(np.abs(heights / (h0 * e ** (2 * np.arange(1, 4))) - 1)) < 1e-8


def test_ensemble_of_newtons_cradle_keeps_each_members_impacts(cradle):
    gaps = np.array([1e-3, 2e-3, 5e-4])
    Q = np.array([[0.0, 0.1 + g, 0.2 + 2 * g] for g in gaps])
    V = np.tile([1.0, 0.0, 0.0], (3, 1))
    ens = cradle.ensemble(np.linspace(0, 1, 11), q0=Q, v0=V, rtol=1e-12, atol=1e-14)
    for i, g in enumerate(gaps):
        member = ens.member(i)
        single = cradle.simulate(np.linspace(0, 1, 11), q0=Q[i], v0=V[i], rtol=1e-12, atol=1e-14)
        assert member.impacts.records == single.impacts.records
        assert np.array_equal(ens.y[i], single.y[-1])
        assert [r.contact for r in member.impacts] == [0, 1]
        assert member.impacts[0].t == pytest.approx(g, rel=1e-10)
        assert member.impacts[1].t == pytest.approx(2 * g, rel=1e-10)
        assert np.max(np.abs(ens.y[i, 3:] - [0.0, 0.0, 1.0])) < 1e-12


def test_ensemble_with_contacts_rejects_members_and_takes_contact_options(ball):
    # a member starting below the floor is rejected by name; the others run
    ens = ball.ensemble((0, 1), q0=[[1.0], [-0.5]], v0=[[0.0], [0.0]])
    assert ens.status[0] == 0 and ens.status[1] == -84
    assert "contact" in ens.messages[1] and "violated" in ens.messages[1]
    assert ens.member(1).impacts is None
    with pytest.raises(lcg.LagcodegenError, match="ContactOptions"):
        ball.ensemble((0, 1), q0=[[1.0]], contacts={"contact_speed": 1})
    opts = lcg.ContactOptions(contact_speed=0.5)
    ens = ball.ensemble((0, 3), q0=[[1.0]], contacts=opts)
    single = ball.simulate((0, 3), q0=[1.0], v0=[0.0], contacts=opts)
    assert ens.member(0).impacts.records == single.impacts.records


def test_ensemble_with_contacts_on_a_dask_local_cluster(ball):
    distributed = pytest.importorskip("distributed")
    q0 = H0[:, None]
    ref = ball.ensemble(T, q0=q0, rtol=1e-10, atol=1e-12)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
                                  silence_logs=40) as cluster, distributed.Client(cluster) as client:
        ens = ball.ensemble(T, q0=q0, rtol=1e-10, atol=1e-12, executor=client, chunk_size=2)
    assert np.array_equal(ens.y, ref.y) and (ens.status == 0).all()
    for i in range(len(H0)):
        single = ball.simulate(T, q0=q0[i], v0=[0.0], rtol=1e-10, atol=1e-12)
        _same_records(ens.member(i), single)


# ---------------------------------------------------------------------- the integrator object
def test_integrator_over_the_whole_grid_is_the_simulate_run(ball):
    T6 = np.linspace(0, 6, 601)
    ref = ball.simulate(T6, q0=[1.0], v0=[0.0], rtol=1e-12, atol=1e-14)
    with ball.integrator(q0=[1.0], v0=[0.0], rtol=1e-12, atol=1e-14) as integ:
        out = integ.propagate_grid(T6)
        assert np.array_equal(out, ref.y)
        assert integ.impacts.records == ref.impacts.records
        assert [(r.name, r.t) for r in integ.events] == [(r.name, r.t) for r in ref.events]
        with pytest.raises(lcg.LagcodegenError, match="step .*not available for systems with contacts"):
            integ.step()


def test_integrator_in_short_calls_bounces_rests_as_the_closed_form(ball):
    # the bouncing ball stepped 0.01 s at a time: impacts located inside the calls, the jumps
    # applied, then resting on the floor with lambda = m g; to test_impacts.py's bounds (1e-9)
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


def test_integrator_newtons_cradle_and_release(cradle):
    gap = 1e-3
    integ = cradle.integrator(q0=[0.0, 0.1 + gap, 0.2 + 2 * gap], v0=[1.0, 0.0, 0.0], rtol=1e-12, atol=1e-14)
    grid = integ.propagate_grid(np.linspace(0.0005, 0.0025, 5))  # both impacts inside this call
    assert [r.contact for r in integ.impacts] == [0, 1]
    assert integ.impacts[0].t == pytest.approx(gap, rel=1e-10)
    assert integ.impacts[1].t == pytest.approx(2 * gap, rel=1e-10)
    assert np.max(np.abs(grid[:, 3:].sum(axis=1) - 1.0)) < 1e-12
    integ.propagate_until(1.0)
    assert len(integ.impacts) == 0
    integ.propagate_for(0.0)  # a call that does not advance: no records, the modes as they are
    assert len(integ.impacts) == 0 and integ.impacts.final_modes == {0: "free", 1: "free"}
    v = integ.state[3:]
    assert abs(v[0]) < 1e-12 and abs(v[1]) < 1e-12 and abs(v[2] - 1.0) < 1e-12
    # the ball on a floor that accelerates down faster than g: released at t = (g + 1) / 20
    m = lcg.Model("clift")
    (y,) = m.coordinates("y")
    m.parameters(g=G, m=1.0)
    m.particle("b", sp.Symbol("m"), (0, y))
    m.gravity(sp.Symbol("g"))
    floor = 0.5 * m.t**2 - sp.Rational(10, 3) * m.t**3
    lift = compile_constrained(lcg.ConstrainedSystem(m, inequalities=[lcg.Inequality(y - floor, restitution=0.5)]),
                               "index1")
    integ = lift.integrator(q0=[0.0], v0=[0.0], rtol=1e-11, atol=1e-13)
    records = []
    for _ in range(80):
        integ.propagate_for(0.01)
        records += integ.impacts.records
    releases = [r for r in records if r.kind == "release"]
    assert releases and releases[0].t == pytest.approx((G + 1) / 20, rel=1e-8)
    # at most a plastic re-contact at the same instant (a closing speed ~1e-10 after the release,
    # impulse ~1e-10), released again there: nothing after the release time
    assert all(abs(r.t - releases[0].t) < 1e-12 and r.impulse < 1e-9 for r in records)
    assert integ.impacts.final_modes == {0: "free"}
    tt = integ.time
    assert integ.state[0] > 0.5 * tt**2 - 10 / 3 * tt**3


def test_ctrl_c_stops_an_ensemble_with_impacts(tmp_path):
    """SIGINT during an ensemble of long runs with impacts (two elastic balls bouncing for 1e7 s
    on two threads): EnsembleInterrupted within seconds (a bound), its result holding the members
    stopped with -80 (cancelled)."""
    import textwrap

    from helpers import interrupt_when_ready
    script = tmp_path / "long.py"
    script.write_text(textwrap.dedent("""
        import sys
        import numpy as np
        import sympy as sp
        import lagcodegen as lcg
        from lagcodegen.api import compile_constrained
        from lagcodegen.solvers.ensemble_result import EnsembleInterrupted
        m = lcg.Model("ctrlc_eball")
        (y,) = m.coordinates("y")
        m.parameters(g=9.81, m=1.0)
        m.particle("b", sp.Symbol("m"), (0, y))
        m.gravity(sp.Symbol("g"))
        sim = compile_constrained(lcg.ConstrainedSystem(m, inequalities=[lcg.Inequality(y, restitution=1.0)]),
                                  "index1")
        sim.ensemble(np.array([0.0, 1.0]), q0=[[1.0]])
        print("ready", flush=True)
        try:
            sim.ensemble(np.array([0.0, 1e7]), q0=[[1.0], [0.5]], threads=2, max_steps=10**15,
                         contacts=lcg.ContactOptions(max_records=10))
        except EnsembleInterrupted as exc:
            print("interrupted", exc.result.status.tolist(), file=sys.stderr)
            sys.exit(130)
    """))
    returncode, err, took = interrupt_when_ready(script)
    assert returncode == 130, err
    assert "interrupted [-80, -80]" in err and took < 10


def test_floating_body_with_contacts_in_an_ensemble_and_the_integrator_object():
    """A body on a free joint (quaternion, generalized speeds) spinning about its vertical axis,
    dropped with its contact point h above the ground: the bounce at t1 = sqrt(2 h / g), the apex
    e^2 h at t1 (1 + e) (as tests/test_constrained_speeds.py checks simulate), through the
    integrator object in 50 calls and in an ensemble of two drop heights."""
    from test_constrained_speeds import dropped_box
    e, r, yaw, wz = 0.6, 0.1, 0.7, 3.0
    sim = compile_constrained(dropped_box("quaternion", (0, 0, -r), e))
    heights = [0.4, 0.25]
    Q = np.array([[0, 0, h + r, 0, 0, math.sin(yaw / 2), math.cos(yaw / 2)] for h in heights])
    V = np.tile([0, 0, 0, 0, 0, wz], (2, 1))
    t1 = math.sqrt(2 * heights[0] / G)
    T = np.linspace(0, t1 * (1 + e), 51)
    ens = sim.ensemble(T, q0=Q, v0=V, rtol=1e-12, atol=1e-13, save="trajectory")
    for i, h in enumerate(heights):
        single = sim.simulate(T, Q[i], V[i], rtol=1e-12, atol=1e-13)
        assert ens.member(i).impacts.records == single.impacts.records
        assert np.array_equal(ens.member(i).y, single.y)
        (bounce,) = single.impacts.select("bounce")
        assert bounce.t == pytest.approx(math.sqrt(2 * h / G), abs=1e-10)
    integ = sim.integrator(q0=Q[0], v0=V[0], rtol=1e-12, atol=1e-13)
    records = []
    for k in range(50):
        integ.propagate_until(T[k + 1])
        records += integ.impacts.records
    assert [rec.kind for rec in records] == ["bounce"] and records[0].t == pytest.approx(t1, abs=1e-10)
    y = integ.state
    assert abs(y[2] - r - e * e * heights[0]) < 1e-8 and abs(y[9]) < 1e-8  # apex: e^2 h, at rest vertically
