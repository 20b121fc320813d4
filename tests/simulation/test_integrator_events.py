"""Events of the CVODE integrator object on the ODE of a scene (lcg_cvode_stepper.c: CVODE's root
finding as the run driver's lcg_cvode_solve_events), checked against the pendulum's period: the
pendulum released at rest from theta0 crosses theta = 0 at (2j + 1) T/4, T = 4 K(k) sqrt(l/g),
k = sin(theta0/2); and against simulate(..., events=...) on CVODE and the Taylor integrator."""

import math

import numpy as np
import pytest
from scipy.special import ellipk

import lagcodegen as lcg
from lagcodegen import LagcodegenError

G, L = 9.81, 1.0
THETA0 = 2.0
TIGHT = dict(rtol=1e-12, atol=1e-14)
CVODE = ["adams", "bdf"]


def period(theta0: float = THETA0) -> float:
    """T = 4 K(k) sqrt(l/g), k = sin(theta0/2)."""
    return 4 * ellipk(math.sin(theta0 / 2) ** 2) * math.sqrt(L / G)


def crossing(j: int) -> float:
    """The j-th time of theta = 0 (j = 0, 1, ...): (2j + 1) T/4; decreasing for even j."""
    return (2 * j + 1) * period() / 4


@pytest.fixture(scope="module")
def pend():
    return lcg.compile_model(lcg.systems.pendulum("integ_ev_pend"))


@pytest.mark.parametrize("method", CVODE)
def test_non_terminal_crossings_at_odd_quarter_periods_as_simulate(pend, method):
    """propagate_until records every crossing of the call (1e-9 relative to (2j + 1) T/4, directions
    alternating, 'up' only the increasing ones), the same events as simulate(events=) on CVODE, and
    ends at the end time."""
    events = [lcg.Event("down", "theta", 0, False), lcg.Event("up", "theta", 1, False)]
    t_end = 10.0
    ref = pend.simulate([0, t_end], q0=[THETA0], method=method, events=events, **TIGHT)
    with pend.integrator(q0=[THETA0], method=method, events=events, **TIGHT) as integ:
        assert integ.propagate_until(t_end) is None and integ.stopped_by is None
        assert integ.time == t_end
        found = integ.events
    down = [e for e in found if e.name == "down"]
    up = [e for e in found if e.name == "up"]
    expect = np.array([crossing(j) for j in range(int(t_end / (period() / 2)) + 2)])
    expect = expect[expect <= t_end]
    assert len(down) == len(expect) == 8 and len(up) == 4 and len(found) == 12
    assert np.max(np.abs(np.array([e.t for e in down]) - expect) / expect) < 1e-9
    assert [e.direction for e in down] == [-1 if j % 2 == 0 else 1 for j in range(len(down))]
    assert [e.t for e in up] == [e.t for e in down if e.direction == 1]
    assert all(abs(e.q["theta"]) < 1e-9 and not e.terminal for e in found)
    # simulate's events: the same ones, in the same order, at the same times to the tolerance
    assert [(e.name, e.direction) for e in found] == [(e.name, e.direction) for e in ref.events]
    assert np.allclose([e.t for e in found], [e.t for e in ref.events], rtol=1e-10, atol=0)


@pytest.mark.parametrize("method", CVODE)
def test_root_finding_leaves_the_steps_alone(pend, method):
    """Non-terminal events change nothing of the integration: the grid with them is the grid
    without them, bit for bit."""
    times = np.linspace(0.0, 5.5, 23)  # four crossings (9T/4 is 6.0)
    with pend.integrator(q0=[THETA0], method=method, **TIGHT) as plain:
        y0 = plain.propagate_grid(times)
    with pend.integrator(q0=[THETA0], method=method, events=[lcg.Event("down", "theta", 0, False)],
                         **TIGHT) as integ:
        y1 = integ.propagate_grid(times)
        assert len(integ.events) == 4 and integ.stopped_by is None
    assert np.array_equal(y0, y1)


@pytest.mark.parametrize("method", CVODE)
def test_terminal_stop_and_resume_finds_each_next_crossing(pend, method):
    """A terminal event stops propagate_until at each crossing in turn (the call after a stop goes
    on from the event without finding it again); propagate_for likewise."""
    with pend.integrator(q0=[THETA0], method=method, events=[lcg.Event("zero", "theta", 0, True)],
                         **TIGHT) as integ:
        for j in range(4):
            stop = integ.propagate_until(20.0)
            assert stop is not None and stop is integ.stopped_by and integ.events == [stop]
            assert stop.name == "zero" and stop.terminal and stop.direction == (-1 if j % 2 == 0 else 1)
            assert abs(stop.t - crossing(j)) < 1e-9 * crossing(j)
            assert integ.time == stop.t and np.array_equal(integ.state, stop.y)
            assert abs(integ.state[0]) < 1e-9
        stop = integ.propagate_for(0.75 * period())  # the next crossing lies T/2 ahead
        assert stop is not None and abs(stop.t - crossing(4)) < 1e-9 * crossing(4)
        assert integ.propagate_for(0.1) is None and integ.events == [] and integ.stopped_by is None
        assert integ.time == stop.t + 0.1


@pytest.mark.parametrize("method", CVODE)
def test_direction_filter_skips_the_other_crossings(pend, method):
    """direction = -1: the terminal stops are the decreasing crossings only (j even)."""
    with pend.integrator(q0=[THETA0], method=method, events=[lcg.Event("down", "theta", -1, True)],
                         **TIGHT) as integ:
        for j in (0, 2, 4):
            stop = integ.propagate_until(20.0)
            assert stop.direction == -1 and abs(stop.t - crossing(j)) < 1e-9 * crossing(j)
    with pend.integrator(q0=[THETA0], method=method, events=[lcg.Event("up", "theta", 1, False)],
                         **TIGHT) as integ:
        integ.propagate_until(crossing(5) + 0.1)
        assert [e.direction for e in integ.events] == [1, 1, 1]
        assert np.allclose([e.t for e in integ.events], [crossing(1), crossing(3), crossing(5)], rtol=1e-9, atol=0)


@pytest.mark.parametrize("method", CVODE)
def test_terminal_event_cuts_the_grid_and_step_ends_at_events(pend, method):
    """propagate_grid returns the rows before a terminal event (the state is the event's); step
    ends at an event it meets."""
    T = period()
    times = np.linspace(0.0, T, 10)  # T/9 apart: the crossing T/4 lies after the third row
    ev = [lcg.Event("zero", "theta", 0, True)]
    with pend.integrator(q0=[THETA0], method=method, events=ev, **TIGHT) as integ:
        rows = integ.propagate_grid(times)
        assert rows.shape == (3, 2) and integ.stopped_by is not None
        assert abs(integ.time - crossing(0)) < 1e-9 * crossing(0)
        ref = pend.simulate(times[:3], q0=[THETA0], method=method, **TIGHT)
        assert np.allclose(rows, ref.y, rtol=1e-9, atol=1e-10)
        # the rest of the grid from the event on: the crossing is not found again, the next one
        # (3T/4) stops it after the rows before it
        rest = integ.propagate_grid(times[times >= integ.time])
        assert abs(integ.stopped_by.t - crossing(1)) < 1e-9 * crossing(1)
        assert rest.shape == (int(np.sum((times >= crossing(0)) & (times < crossing(1)))), 2) and len(rest) == 4
    with pend.integrator(q0=[THETA0], method=method, events=[lcg.Event("zero", "theta", 0, False)],
                         **TIGHT) as integ:
        seen = []
        while integ.time < crossing(1) + 0.05:
            t = integ.step()
            seen += integ.events
            if integ.events:
                assert t == integ.events[0].t
        assert [e.direction for e in seen] == [-1, 1]
        assert np.allclose([e.t for e in seen], [crossing(0), crossing(1)], rtol=1e-9, atol=0)


@pytest.mark.parametrize("method", CVODE)
def test_restart_from_an_event_state_written_back_does_not_find_it_again(pend, method):
    """Reversing the velocity at the first crossing (a write of the state: CVODE restarts there)
    sends the pendulum back up to theta0 and down again: the next crossing is T/2 later, not the
    one at the restart."""
    with pend.integrator(q0=[THETA0], method=method, events=[lcg.Event("zero", "theta", 0, True)],
                         **TIGHT) as integ:
        first = integ.propagate_until(20.0)
        integ.state[1] = -integ.state[1]
        second = integ.propagate_until(20.0)
        assert second.direction == -1
        assert abs(second.t - (first.t + period() / 2)) < 1e-9 * second.t


def test_events_agree_with_the_taylor_integrator(pend):
    """The CVODE and Taylor integrator objects report the same crossings (to the tolerance)."""
    events = [lcg.Event("zero", "theta", 0, False)]
    found = {}
    for method in ("bdf", "taylor"):
        with pend.integrator(q0=[THETA0], method=method, events=events, **TIGHT) as integ:
            integ.propagate_until(5.0)
            found[method] = integ.events
    assert [(e.name, e.direction) for e in found["bdf"]] == [(e.name, e.direction) for e in found["taylor"]]
    assert np.allclose([e.t for e in found["bdf"]], [e.t for e in found["taylor"]], rtol=1e-9, atol=0)


def test_bad_event_is_named(pend):
    with pytest.raises(LagcodegenError, match="thetta"):
        pend.integrator(q0=[THETA0], method="adams", events=[lcg.Event("e", "thetta")])


def test_band_and_fixed_point_solvers_locate_events_too():
    """The band solver integrates the interleaved state: the event functions and the events' states
    still see y = (q, q'); every linear solver finds simulate's events."""
    cm = lcg.compile_model(lcg.systems.n_link_pendulum(3, name="integ_ev_chain"))
    events = [lcg.Event("cross", "q1", 0, False), lcg.Event("cross2", "q3 - q1", 0, False)]
    ref = cm.simulate([0, 3], q0=[0.5, -0.2, 0.3], events=events, **TIGHT)
    assert len(ref.events) > 4
    for opts in (dict(), dict(linear_solver="band"), dict(linear_solver="fixedpoint")):
        with cm.integrator(q0=[0.5, -0.2, 0.3], events=events, **TIGHT, **opts) as integ:
            integ.propagate_until(3.0)
            found = integ.events
        assert [e.name for e in found] == [e.name for e in ref.events]
        assert np.abs(np.array([e.t for e in found]) - np.array([e.t for e in ref.events])).max() < 1e-8
        assert np.abs(np.array([e.y for e in found]) - np.array([e.y for e in ref.events])).max() < 1e-7
