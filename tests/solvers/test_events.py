"""Events on the ODE of a compiled scene on every CVODE backend (lagcodegen.solvers.cvode.events,
the runtime's lcg_cvode_solve_events, scikit-sundae's eventsfn), checked against the pendulum's
elliptic-integral period, Kepler's third law, the Taylor method's events and the compiler."""

from __future__ import annotations

import math
import shutil
import subprocess

import numpy as np
import pytest
import sympy as sp
from scipy.special import ellipk

import lagcodegen as lcg
from lagcodegen.codegen.events import events_source
from lagcodegen.errors import LagcodegenError, ModelError
from lagcodegen.formulation.events import scene_events
from lagcodegen.formulation.scene import Scene
from lagcodegen.theory.routhian import reduce

from helpers import STRICT_CFLAGS, cartesian_pendulum, pendulum_q0

G, L = 9.81, 1.0
TIGHT = dict(rtol=1e-12, atol=1e-14)


def period(theta0: float, l: float = L, g: float = G) -> float:
    """T = 4 K(k) sqrt(l/g), k = sin(theta0/2): the pendulum released at rest from theta0."""
    return 4 * ellipk(math.sin(theta0 / 2) ** 2) * math.sqrt(l / g)


@pytest.fixture(scope="module")
def pend():
    return lcg.compile_model(lcg.systems.pendulum("ev_pend"), outputs=["energy", "p_theta", "positions"])


def crossings(theta0: float, t_end: float) -> np.ndarray:
    """Times of theta = 0: (2j + 1) T/4 up to t_end."""
    T = period(theta0)
    j = np.arange(int(t_end / (T / 2)) + 2)
    t = (2 * j + 1) * T / 4
    return t[t <= t_end]


@pytest.mark.parametrize("method", ["adams", "bdf"])
def test_pendulum_crossings_at_odd_quarter_periods(pend, method):
    """theta = 0 at (2j + 1) T/4 to 1e-9 relative, decreasing first, then alternating; 'up' keeps
    the increasing ones; neither is terminal: the run reaches its end with its output times."""
    theta0, t_end = 2.0, 20.0
    t = np.linspace(0.0, t_end, 11)
    events = [lcg.Event("down", "theta", 0, False), lcg.Event("up", "theta", 1, False)]
    res = pend.simulate(t, q0=[theta0], method=method, events=events, **TIGHT)
    assert res.success and np.array_equal(res.t, t)
    down = [e for e in res.events if e.name == "down"]
    up = [e for e in res.events if e.name == "up"]
    expect = crossings(theta0, t_end)
    assert len(down) == len(expect) == 15 and res.stats["events"] == len(res.events) == 15 + 7
    rel = np.abs(np.array([e.t for e in down]) - expect) / expect
    assert rel.max() < 1e-9
    assert [e.direction for e in down] == [-1 if j % 2 == 0 else 1 for j in range(len(down))]
    assert [e.t for e in up] == [e.t for e in down if e.direction == 1]
    assert all(e.index == 1 and not e.terminal for e in up)
    assert all(abs(e.q["theta"]) < 1e-9 for e in res.events)
    # the state at the event: |theta'| from the energy, sqrt(2 g/l (1 - cos theta0))
    assert all(abs(abs(e.v["theta"]) - math.sqrt(2 * G / L * (1 - math.cos(theta0)))) < 1e-8 for e in down)


def test_direction_filter_and_terminal_event(pend):
    """direction = -1 keeps the decreasing crossings (j even); a terminal one ends the run at the
    first: its state is the last row (outputs included), after the output times before it."""
    theta0 = 1.2
    T = period(theta0)
    res = pend.simulate([0, 10], q0=[theta0], events=[lcg.Event("down", "theta", -1, False)], **TIGHT)
    expect = crossings(theta0, 10.0)[::2]
    assert np.abs(np.array([e.t for e in res.events]) - expect).max() < 1e-9 * expect.max()
    assert {e.direction for e in res.events} == {-1}
    stop = pend.simulate([0, 10], q0=[theta0], events=[("stop", "theta", -1, True)], **TIGHT)
    [ev] = stop.events
    assert ev.terminal and ev.direction == -1 and abs(ev.t - T / 4) < 1e-9 * T
    assert stop.success and stop.t[-1] == ev.t and stop.t[-2] < ev.t and abs(stop["theta"][-1]) < 1e-9
    assert stop.t.size == int(ev.t / 0.01) + 2  # the output times before the event, then the event
    e0 = -G * L * math.cos(theta0)  # m = 1: the energy at rest
    assert abs(stop["energy"][-1] - e0) < 1e-9 and abs(stop["bob_y"][-1] + L) < 1e-12


def test_an_event_at_the_restart_time_is_not_found_again(pend):
    """Restarted from a terminal event's state, the same event is located at the next crossing,
    half a period on, not at the restart time (where g is zero to rounding, of either sign)."""
    theta0 = 2.5
    T = period(theta0)
    events = [lcg.Event("zero", "theta", 0, True)]
    first = pend.simulate([0, 10], q0=[theta0], events=events, **TIGHT)
    [ev] = first.events
    assert abs(ev.t - T / 4) < 1e-9 * T
    for backend in ("native", "sksundae"):
        again = pend.simulate(np.array([ev.t, ev.t + T]), y0=ev.y, events=events, backend=backend, **TIGHT)
        [nxt] = again.events
        assert abs(nxt.t - 3 * T / 4) < 1e-8 * T and nxt.direction == -ev.direction
    # p_theta = m l^2 theta' is exactly 0 at the start (released at rest): its zeros are the
    # turning points at T/2, T, ..., never t = 0
    res = pend.simulate([0, 2 * T + 0.1], q0=[theta0], events=[lcg.Event("turn", "p_theta", 0, False)], **TIGHT)
    assert np.abs(np.array([e.t for e in res.events]) - np.array([T / 2, T, 3 * T / 2, 2 * T])).max() < 1e-8 * T


def test_events_on_outputs_and_the_taylor_method_agree(pend):
    """An event on an output (the bob's height bob_y = -l cos(theta), a scene output name) is the
    event on its expression; the Taylor method finds the same events at the same times."""
    theta0, theta1 = 2.0, 1.0
    on_output = [lcg.Event("high", f"bob_y + {L * math.cos(theta1)}", 1, False),
                 lcg.Event("down", "theta", 0, False)]
    direct = [lcg.Event("high", sp.Symbol("l") * (math.cos(theta1) - sp.cos(sp.Symbol("theta"))), 1, False),
              lcg.Event("down", "theta", 0, False)]
    a = pend.simulate([0, 10], q0=[theta0], events=on_output, **TIGHT)
    b = pend.simulate([0, 10], q0=[theta0], events=direct, **TIGHT)
    c = pend.simulate([0, 10], q0=[theta0], events=on_output, method="taylor", **TIGHT)
    assert [(e.name, e.direction) for e in a.events] == [(e.name, e.direction) for e in b.events] \
        == [(e.name, e.direction) for e in c.events]
    ta, tb, tc = (np.array([e.t for e in r.events]) for r in (a, b, c))
    assert np.abs(ta - tb).max() < 1e-12 and np.abs(ta - tc).max() < 1e-9
    high = [e for e in a.events if e.name == "high"]
    assert len(high) >= 6 and all(abs(abs(e.q["theta"]) - theta1) < 1e-9 for e in high)


def test_scikit_sundae_finds_the_events_of_the_native_driver(pend):
    events = [lcg.Event("down", "theta", 0, False), lcg.Event("stop", "t - 7.5", 1, True)]
    nat = pend.simulate([0, 10], q0=[1.5], events=events, **TIGHT)
    sks = pend.simulate([0, 10], q0=[1.5], events=events, backend="sksundae", **TIGHT)
    assert [(e.name, e.direction) for e in sks.events] == [(e.name, e.direction) for e in nat.events]
    assert np.abs(np.array([e.t for e in sks.events]) - np.array([e.t for e in nat.events])).max() < 1e-9
    assert nat.t[-1] == sks.t[-1] == pytest.approx(7.5, abs=1e-12) and sks.backend == "sksundae"
    assert sks.stats["events"] == nat.stats["events"] == len(nat.events)


def test_band_and_fixed_point_solvers_locate_events_too():
    """The band solver integrates the interleaved state: the event functions still see (q, q')."""
    cm = lcg.compile_model(lcg.systems.n_link_pendulum(3, name="ev_chain"))
    events = [lcg.Event("cross", "q1", 0, False), lcg.Event("cross2", "q3 - q1", 0, False)]
    ref = cm.simulate([0, 3], q0=[0.5, -0.2, 0.3], events=events, **TIGHT)
    assert len(ref.events) > 4
    for opts in (dict(linear_solver="band"), dict(linear_solver="fixedpoint")):
        res = cm.simulate([0, 3], q0=[0.5, -0.2, 0.3], events=events, **TIGHT, **opts)
        assert [e.name for e in res.events] == [e.name for e in ref.events]
        assert np.abs(np.array([e.t for e in res.events]) - np.array([e.t for e in ref.events])).max() < 1e-8
        assert np.abs(np.array([e.y for e in res.events]) - np.array([e.y for e in ref.events])).max() < 1e-7


def test_ensemble_members_locate_their_events(pend):
    """Each member stops at its own first crossing K(k_i) sqrt(l/g); the members are the runs
    alone, bit for bit."""
    theta0 = np.array([0.3, 1.0, 2.0, 2.8])
    stop = [lcg.Event("stop", "theta", -1, True)]
    ens = pend.ensemble([0, 10], q0=theta0[:, None], events=stop, threads=2, **TIGHT)
    expect = np.array([period(a) / 4 for a in theta0])
    assert (ens.status == 0).all() and np.abs(ens.t_reached - expect).max() < 1e-9 * expect.max()
    assert list(ens.stats["events"]) == [1] * 4 and list(ens.stats["terminated"]) == [1] * 4
    assert np.abs(ens.y[:, 0]).max() < 1e-9  # the final state is the event's
    counting = [lcg.Event("down", "theta", 0, False)]
    traj = pend.ensemble([0, 10], q0=theta0[:, None], events=counting, threads=2, save="trajectory", **TIGHT)
    assert list(traj.stats["events"]) == [len(crossings(a, 10.0)) for a in theta0]
    alone = pend.simulate([0, 10], q0=[theta0[2]], events=counting, **TIGHT)
    assert np.array_equal(traj.member(2).y, alone.y)
    taylor = pend.ensemble([0, 10], q0=theta0[:, None], events=counting, method="taylor", threads=2, **TIGHT)
    assert list(taylor.stats["events"]) == [len(crossings(a, 10.0)) for a in theta0]
    for i, a in enumerate(theta0):
        assert np.abs(np.array([e.t for e in taylor.member(i).events]) - crossings(a, 10.0)).max() < 1e-9


def test_routhian_kepler_apsides_as_events():
    """The Routhian-reduced Kepler problem (r, r', phi as a quadrature state): r' = 0 decreasing
    at the apoapsis, half the period 2 pi a^(3/2) sqrt(m/k) after the periapsis; phi = pi there
    (an event on the quadrature state)."""
    kepler = reduce(lcg.systems.central_potential())
    cm = lcg.compile_reduction(kepler)
    mm, kk, r0, w0 = 2.0, 3.0, 1.0, 1.3
    a = 1.0 / (2.0 / r0 - mm * (r0 * w0) ** 2 / kk)
    T = 2 * math.pi * a ** 1.5 * math.sqrt(mm / kk)
    events = [lcg.Event("apo", "r_dot", -1, False), lcg.Event("half", sp.Symbol("phi") - sp.pi, 1, False)]
    res = kepler.simulate(cm, [0.0, 1.5 * T], [r0, 0.0], [0.0, w0], params={"m": mm, "k": kk}, events=events,
                          **TIGHT)
    apo = [e for e in res.events if e.name == "apo"]
    half = [e for e in res.events if e.name == "half"]
    assert len(apo) == 1 and abs(apo[0].t - T / 2) < 1e-8 * T
    assert abs(apo[0].q["r"] - (2 * a - r0)) < 1e-8
    assert len(half) == 1 and abs(half[0].t - T / 2) < 1e-8 * T


def test_minimal_coordinates_events_on_kept_and_eliminated_coordinates():
    """The Cartesian pendulum in minimal coordinates (y eliminated): x = 0 at T/4, 3T/4, ...; an
    event on y (the branch's output of that name) at theta = 0.5, and the inequality
    y + cos(0.5) l >= 0 as the terminal event ineq_0 at the same time."""
    from scipy.special import ellipkinc
    cs = cartesian_pendulum("ev_min")
    x, y = cs.model.coords
    theta0, theta1 = 1.0, 0.5
    T = period(theta0)
    k = math.sin(theta0 / 2)  # theta = theta1 first at (K - F(asin(sin(theta1/2)/k) | k^2)) sqrt(l/g)
    t1 = (ellipk(k * k) - ellipkinc(math.asin(math.sin(theta1 / 2) / k), k * k)) * math.sqrt(L / G)
    sim = lcg.compile_constrained(cs, "minimal", eliminate=["y"], outputs=["energy"],
                                  events=[lcg.Event("cross", x, 0, False),
                                          lcg.Event("mid", y + L * math.cos(theta1), 0, False)])
    res = sim.simulate([0, 2 * T], q0=pendulum_q0(theta0), **TIGHT)
    assert res.formulation == "minimal" and res.state_names == ["x", "x_dot"]
    cross = [e.t for e in res.events if e.name == "cross"]
    assert np.abs(np.array(cross) - np.array([T / 4, 3 * T / 4, 5 * T / 4, 7 * T / 4])).max() < 1e-9 * T
    mid = [e for e in res.events if e.name == "mid"]
    assert len(mid) == 8 and abs(mid[0].t - t1) < 1e-9 and mid[0].direction == -1
    assert abs(mid[0].q["x"] - L * math.sin(theta1)) < 1e-9
    bounded = lcg.ConstrainedSystem(cs.model, holonomic=cs.holonomic, inequalities=[y + L * math.cos(theta1)])
    stop = lcg.compile_constrained(bounded, "minimal", eliminate=["y"]).simulate([0, T], q0=pendulum_q0(theta0),
                                                                                 **TIGHT)
    [ev] = stop.events
    assert ev.name == "ineq_0" and ev.terminal and ev.direction == -1 and abs(ev.t - t1) < 1e-9
    assert stop.t[-1] == ev.t
    ens = sim.ensemble([0, T], q0=[pendulum_q0(theta0), pendulum_q0(0.3)], **TIGHT)
    assert list(ens.stats["events"]) == [2 + 4, 2]  # theta0 = 0.3 never reaches theta = 0.5
    off = sim.simulate([0, T], q0=pendulum_q0(theta0), events=False, **TIGHT)
    assert off.events == [] and off.t[-1] == pytest.approx(T)


def test_bad_events_name_the_problem(pend):
    with pytest.raises(ModelError, match="event 'e' uses unknown symbol.*: thetta"):
        pend.simulate([0, 1], q0=[1.0], events=[lcg.Event("e", "thetta")])
    with pytest.raises(ModelError, match="event 'e': direction must be -1, 0 or \\+1, got 2"):
        pend.simulate([0, 1], q0=[1.0], events=[("e", "theta", 2)])
    with pytest.raises(ModelError, match="event name 'no good' must be an identifier"):
        pend.simulate([0, 1], q0=[1.0], events=[("no good", "theta")])
    with pytest.raises(ModelError, match="event name 'e' is used twice"):
        pend.simulate([0, 1], q0=[1.0], events=[("e", "theta"), ("e", "theta_dot")])
    with pytest.raises(ModelError, match="event 3: give an Event"):
        pend.simulate([0, 1], q0=[1.0], events=[("a", "theta"), ("b", "theta"), ("c", "theta"), 42])
    for backend in ("native", "sksundae"):
        with pytest.raises(LagcodegenError, match="event function e not finite at t = 0"):
            pend.simulate([0, 1], q0=[1.0], events=[("e", "log(theta - 2)")], backend=backend)
    # not finite later in the run (theta = 0.5 at t = 0.3): the run fails with the model's error
    res = pend.simulate([0, 1], q0=[1.0], events=[("e", "log(theta - 0.5)")], raise_on_error=False)
    assert not res.success and "not finite" in res.message and 0.2 < res.stats["t_reached"] < 0.4
    cs = cartesian_pendulum("ev_min_lam")
    with pytest.raises(ModelError, match="minimal coordinates have no Lagrange multipliers"):
        lcg.compile_constrained(cs, "minimal", events=[lcg.Event("e", sp.Symbol("lambda_0"))])


@pytest.mark.skipif(shutil.which("cc") is None, reason="needs a C compiler")
def test_event_source_compiles_cleanly_and_leaves_the_model_code_alone(tmp_path):
    """<prefix>_events.c compiles with the strict flags; the model's own files are those of a
    model without events."""
    eom = lcg.derive(lcg.systems.pendulum("ev_src"))
    scene = Scene(eom, outputs=["energy"], runtime_parameters=["g"])
    events = scene_events(scene, [lcg.Event("a", "theta", 0, False), lcg.Event("b", "energy - 1", 1, True)])
    [(name, text)] = events_source(scene, events).items()
    assert name == "ev_src_events.c" and "a (crossing either way, not terminal)" in text
    (tmp_path / name).write_text(text)
    proc = subprocess.run(["cc", *STRICT_CFLAGS, "-c", name, "-o", "e.o"], cwd=tmp_path, capture_output=True,
                          text=True)
    assert proc.returncode == 0, proc.stderr
    before = lcg.generate_c(scene).files
    cm = lcg.compile_model(lcg.systems.pendulum("ev_src"), outputs=["energy"], runtime_parameters=["g"])
    cm.simulate([0, 1], q0=[1.0], events=events)
    assert cm.code.files == before
