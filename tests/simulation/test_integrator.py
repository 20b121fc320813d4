"""The integrator object (lagcodegen/simulation/integrator.py, the runtime's lcg_taylor_stepper.c
and lcg_cvode_stepper.c): against simulate() (the same steps give the same numbers, bit for bit),
against analytic solutions (a step of a parameter written in place), its views, its errors and
its lifetime."""

import gc
import math
import subprocess

import numpy as np
import pytest
from scipy.special import ellipk

import lagcodegen as lcg
import lagcodegen.runtime as runtime_package
from lagcodegen import LagcodegenError, systems
from lagcodegen.build import find_sundials, runtime_sources
from lagcodegen.model.events import Event
from lagcodegen.codegen.taylor.emit import runtime_sources as taylor_runtime_sources

from helpers import STRICT_CFLAGS, TH0, cartesian_pendulum, pendulum_q0

METHODS = ["taylor", "adams", "bdf"]
TOL = dict(rtol=1e-10, atol=1e-12)


@pytest.fixture(scope="module")
def double_pendulum():
    return lcg.compile_model(systems.double_pendulum())


@pytest.fixture(scope="module")
def oscillator():
    return lcg.compile_model(systems.damped_driven_oscillator())


def step_response(t, m, k, c, F, x0, v0):
    """m x'' + c x' + k x = F (constant) from (x0, v0) at t = 0, underdamped: x(t) and x'(t)."""
    gam = c / (2 * m)
    wd = math.sqrt(k / m - gam ** 2)
    xs = F / k
    c1 = x0 - xs
    c2 = (v0 + gam * c1) / wd
    e = np.exp(-gam * t)
    x = xs + e * (c1 * np.cos(wd * t) + c2 * np.sin(wd * t))
    v = e * ((-gam * c1 + wd * c2) * np.cos(wd * t) + (-gam * c2 - wd * c1) * np.sin(wd * t))
    return x, v


# ---------------------------------------------------------------------- against simulate
@pytest.mark.parametrize("method", METHODS)
def test_grid_from_a_fresh_integrator_is_simulate_bit_for_bit(double_pendulum, method):
    times = np.linspace(0.0, 5.0, 51)
    res = double_pendulum.simulate(times, q0=[1.0, 0.5], method=method, **TOL)
    with double_pendulum.integrator(q0=[1.0, 0.5], method=method, **TOL) as integ:
        rows = integ.propagate_grid(times)
        assert integ.time == 5.0
        np.testing.assert_array_equal(integ.state, res.y[-1])
    np.testing.assert_array_equal(rows, res.y)


@pytest.mark.parametrize("method", METHODS)
def test_one_propagate_until_is_simulate_bit_for_bit(double_pendulum, method):
    res = double_pendulum.simulate(np.array([0.0, 3.0]), q0=[1.0, 0.5], method=method, **TOL)
    with double_pendulum.integrator(q0=[1.0, 0.5], method=method, **TOL) as integ:
        assert integ.propagate_until(3.0) is None
        np.testing.assert_array_equal(integ.state, res.y[-1])


@pytest.mark.parametrize("method", METHODS)
def test_propagate_in_pieces_equals_one_simulate_to_tolerance(double_pendulum, method):
    times = np.linspace(0.0, 5.0, 101)
    res = double_pendulum.simulate(times, q0=[1.0, 0.5], method=method, **TOL)
    with double_pendulum.integrator(q0=[1.0, 0.5], method=method, **TOL) as integ:
        for k, t in enumerate(times[1:], 1):
            if k % 2:
                integ.propagate_until(t)
            else:
                integ.propagate_for(t - integ.time)
            assert integ.time == pytest.approx(t, abs=1e-14)
            assert np.max(np.abs(integ.state - res.y[k])) < 1e-7
        # the end of the run reached exactly
        assert integ.time == 5.0


@pytest.mark.parametrize("method", METHODS)
def test_grid_after_pieces_and_grid_starting_at_the_current_time(double_pendulum, method):
    with double_pendulum.integrator(q0=[0.3, -0.2], method=method, **TOL) as integ:
        integ.propagate_until(1.0)
        y1 = integ.state.copy()
        rows = integ.propagate_grid([1.0, 1.5, 2.0])
        np.testing.assert_array_equal(rows[0], y1)  # the current time: the current state
        ref = double_pendulum.simulate(np.array([1.0, 1.5, 2.0]), y0=y1, method=method, **TOL)
        assert np.max(np.abs(rows - ref.y)) < 1e-8


# ---------------------------------------------------------------------- writes in place
@pytest.mark.parametrize("method", METHODS)
def test_parameter_written_in_place_is_a_step_input(oscillator, method):
    """A constant force switched on at t1 by writing params: the analytic step response."""
    m, k, c, F = 2.0, 3.0, 0.1, 1.5
    integ = oscillator.integrator(q0=[0.5], v0=[0.0], params=dict(m=m, k=k, c=c, F0=0.0, w=0.0), method=method,
                                  **TOL)
    assert integ.param_names == oscillator.param_names
    t1 = 2.0
    integ.propagate_until(t1)
    x1, v1 = step_response(np.array(t1), m, k, c, 0.0, 0.5, 0.0)
    assert np.max(np.abs(integ.state - [x1, v1])) < 1e-8
    view = integ.params
    view[oscillator.param_names.index("F0")] = F  # in place: the view is the C memory
    assert integ.params is view and integ.params[oscillator.param_names.index("F0")] == F
    times = np.linspace(t1, t1 + 8.0, 41)
    rows = integ.propagate_grid(times)
    x, v = step_response(times - t1, m, k, c, F, float(x1), float(v1))
    err = max(np.max(np.abs(rows[:, 0] - x)), np.max(np.abs(rows[:, 1] - v)))
    unforced, _ = step_response(times - t1, m, k, c, 0.0, float(x1), float(v1))
    assert err < 1e-7
    assert np.max(np.abs(rows[:, 0] - unforced)) > 0.5  # the write did change the trajectory
    integ.close()


@pytest.mark.parametrize("method", METHODS)
def test_params_written_like_simulate_params(double_pendulum, method):
    times = np.array([0.0, 1.0, 2.5])
    with double_pendulum.integrator(q0=[1.0, 0.5], method=method, **TOL) as integ:
        integ.params = {"g": 3.0}
        assert integ.params[double_pendulum.param_names.index("g")] == 3.0
        rows = integ.propagate_grid(times)
    ref = double_pendulum.simulate(times, q0=[1.0, 0.5], params={"g": 3.0}, method=method, **TOL)
    assert np.max(np.abs(rows - ref.y)) < 1e-8
    other = double_pendulum.simulate(times, q0=[1.0, 0.5], method=method, **TOL)
    assert np.max(np.abs(rows - other.y)) > 0.1


@pytest.mark.parametrize("method", METHODS)
def test_state_and_time_written_take_effect(double_pendulum, method):
    with double_pendulum.integrator(q0=[1.0, 0.5], method=method, **TOL) as integ:
        integ.propagate_until(2.0)
        integ.state[:] = [0.2, 0.1, 0.0, 0.0]   # in place
        integ.propagate_until(3.0)
        ref = double_pendulum.simulate(np.array([2.0, 3.0]), q0=[0.2, 0.1], method=method, **TOL)
        assert np.max(np.abs(integ.state - ref.y[-1])) < 1e-8
        integ.state = [0.4, 0.0, 0.0, 0.0]      # the setter
        integ.time = 10.0
        integ.propagate_until(11.0)
        ref = double_pendulum.simulate(np.array([0.0, 1.0]), q0=[0.4, 0.0], method=method, **TOL)
        assert np.max(np.abs(integ.state - ref.y[-1])) < 1e-8
        assert integ.time == 11.0


# ---------------------------------------------------------------------- step()
@pytest.mark.parametrize("method", METHODS)
def test_step_advances_monotonically_along_the_solution(double_pendulum, method):
    with double_pendulum.integrator(q0=[1.0, 0.5], method=method, **TOL) as integ:
        times = [integ.time]
        states = []
        for _ in range(30):
            times.append(integ.step())
            states.append(integ.state.copy())
        assert all(b > a for a, b in zip(times, times[1:]))
        assert integ.stats["steps"] >= 1
        last = integ.step(t_limit=times[-1] + 1e-3)   # bounded step
        assert times[-1] < last <= times[-1] + 1e-3
        assert integ.step(t_limit=last) == last       # nothing left before the limit: no step
    ref = double_pendulum.simulate(np.array(times[:31]), q0=[1.0, 0.5], method=method, **TOL)
    assert np.max(np.abs(np.array(states) - ref.y[1:])) < 1e-7


@pytest.mark.parametrize("method", ["taylor", "adams"])
def test_end_and_grid_times_within_rounding_of_the_current_time_take_its_state(double_pendulum, method):
    """An end or grid time one or two ulps past the integrator's time (a step ended there) gives
    the state there, not a step below the resolution of t (the Taylor stepper failed on it)."""
    with double_pendulum.integrator(q0=[1.0, 0.5], method=method, **TOL) as integ:
        for _ in range(5):
            integ.step()
        t, state = integ.time, integ.state.copy()
        integ.propagate_until(np.nextafter(np.nextafter(t, 1e9), 1e9))
        assert abs(integ.time - t) <= 4 * np.spacing(t) and np.allclose(integ.state, state, rtol=0, atol=1e-14)
        out = integ.propagate_grid(np.array([integ.time, np.nextafter(integ.time, 1e9)]))
        assert np.allclose(out, state, rtol=0, atol=1e-14)


def test_taylor_steps_are_the_steps_of_simulate(double_pendulum):
    """step() takes the run driver's steps: 40 of them end where simulate's 40th step ends."""
    with double_pendulum.integrator(q0=[1.0, 0.5], method="taylor", **TOL) as integ:
        for _ in range(40):
            integ.step()
        t40 = integ.time
    res = double_pendulum.simulate(np.array([0.0, 1e3]), q0=[1.0, 0.5], method="taylor", max_steps=40, **TOL,
                                   raise_on_error=False)
    assert res.stats["steps"] == 40
    assert res.stats["t_reached"] == t40


# ---------------------------------------------------------------------- events
def test_terminal_event_stops_propagate_and_is_reported(double_pendulum):
    q1 = double_pendulum.code.scene.eom.q[0]
    ev = Event("q1_zero", q1, direction=-1)
    ref = double_pendulum.simulate([0, 5], q0=[1.0, 0.5], method="taylor", events=[ev], **TOL)
    with double_pendulum.integrator(q0=[1.0, 0.5], method="taylor", events=[ev], **TOL) as integ:
        stop = integ.propagate_until(5.0)
        assert stop is not None and stop is integ.stopped_by
        assert stop.name == "q1_zero" and stop.direction == -1
        assert stop.t == pytest.approx(ref.events[-1].t, abs=1e-12)
        assert integ.time == pytest.approx(stop.t, abs=1e-15)
        assert abs(integ.state[0]) < 1e-10
        # again: the root at the start is not found twice; the next crossing (downward) is later
        stop2 = integ.propagate_until(5.0)
        assert stop2 is None or stop2.t > stop.t + 0.1


@pytest.mark.parametrize("method", ["adams", "bdf"])
def test_terminal_event_stops_the_cvode_integrator_as_simulate(double_pendulum, method):
    """CVODE's integrator object stops at the terminal event where simulate(events=) on CVODE does
    (more in test_integrator_events.py)."""
    q1 = double_pendulum.code.scene.eom.q[0]
    ev = Event("q1_zero", q1, direction=-1)
    ref = double_pendulum.simulate([0, 5], q0=[1.0, 0.5], method=method, events=[ev], **TOL)
    with double_pendulum.integrator(q0=[1.0, 0.5], method=method, events=[ev], **TOL) as integ:
        stop = integ.propagate_until(5.0)
        assert stop is not None and stop is integ.stopped_by and ref.events[-1].terminal
        assert stop.name == "q1_zero" and stop.direction == -1
        assert stop.t == pytest.approx(ref.events[-1].t, rel=1e-8)
        assert integ.time == stop.t and abs(integ.state[0]) < 1e-8
        stop2 = integ.propagate_until(5.0)
        assert stop2 is None or stop2.t > stop.t + 0.1


# ---------------------------------------------------------------------- bad input
@pytest.mark.parametrize("method", ["taylor", "adams"])
def test_bad_input_raises_clear_errors(double_pendulum, method):
    with pytest.raises(LagcodegenError, match="3 values"):
        double_pendulum.integrator(y0=[1.0, 0.5, 0.0], method=method)
    with pytest.raises(LagcodegenError, match="not an option"):
        double_pendulum.integrator(q0=[1.0, 0.5], method=method, bogus=3)
    with double_pendulum.integrator(q0=[1.0, 0.5], method=method, **TOL) as integ:
        integ.propagate_until(1.0)
        with pytest.raises(LagcodegenError, match="backward"):
            integ.propagate_until(0.5)
        with pytest.raises(LagcodegenError, match="backward"):
            integ.propagate_for(-0.1)
        with pytest.raises(LagcodegenError, match="backward"):
            integ.propagate_until(float("nan"))
        with pytest.raises(LagcodegenError, match="must be a number"):
            integ.propagate_until("2")
        with pytest.raises(LagcodegenError, match="backward"):
            integ.propagate_grid([1.5, 1.2, 2.0])
        with pytest.raises(LagcodegenError, match="backward"):
            integ.propagate_grid([0.5, 2.0])
        with pytest.raises(LagcodegenError, match="one-dimensional"):
            integ.propagate_grid([[1.5, 2.0]])
        with pytest.raises(LagcodegenError, match="array of numbers"):
            integ.propagate_grid(["a", "b"])
        with pytest.raises(LagcodegenError, match="shape"):
            integ.state = [1.0, 2.0]
        with pytest.raises(LagcodegenError, match="4 numbers"):
            integ.state = ["x", 1, 2, 3]
        with pytest.raises(LagcodegenError, match="non-finite"):
            integ.state = [np.nan, 0, 0, 0]
        with pytest.raises(LagcodegenError, match="shape"):
            integ.params = [1.0]
        with pytest.raises(LagcodegenError, match="not a run-time parameter"):
            integ.params = {"gee": 1.0}
        with pytest.raises(LagcodegenError, match="finite"):
            integ.time = float("inf")
        # nothing above moved it
        assert integ.time == 1.0
        integ.propagate_until(1.5)
        assert integ.time == 1.5


# ---------------------------------------------------------------------- lifetime
@pytest.mark.parametrize("method", ["taylor", "adams"])
def test_use_after_close_raises_and_memory_is_freed(double_pendulum, method):
    integ = double_pendulum.integrator(q0=[1.0, 0.5], method=method, **TOL)
    integ.propagate_until(0.5)
    state = integ.state
    integ.close()
    assert integ.closed
    integ.close()  # idempotent
    for call in (lambda: integ.propagate_until(1.0), lambda: integ.propagate_for(1.0),
                 lambda: integ.propagate_grid([0.5, 1.0]), integ.step, lambda: integ.stats):
        with pytest.raises(LagcodegenError, match="closed"):
            call()
    assert state[0] == integ.state[0]  # the views stay readable: they are the object's array
    with double_pendulum.integrator(q0=[1.0, 0.5], method=method) as integ2:
        integ2.propagate_until(0.1)
    assert integ2.closed
    integ3 = double_pendulum.integrator(q0=[1.0, 0.5], method=method)
    finalizer = integ3._finalizer
    del integ3
    gc.collect()
    assert not finalizer.alive  # freed by the garbage collector


def test_integrator_does_not_pickle(double_pendulum):
    import pickle
    with double_pendulum.integrator(q0=[1.0, 0.5], method="taylor") as integ:
        with pytest.raises(LagcodegenError, match="does not pickle"):
            pickle.dumps(integ)


# ---------------------------------------------------------------------- the C
def test_stepper_sources_compile_strictly(tmp_path, cc):
    sources = {**runtime_sources(find_sundials()), **taylor_runtime_sources(),
               **runtime_package.sources(["lcg_cvode_stepper.c", "lcg_cvode_stepper.h", "lcg_cvc_stepper.c",
                                          "lcg_cvc_stepper.h", "lcg_ida_stepper.c", "lcg_ida_stepper.h",
                                          "lcg_taylor_stepper.c", "lcg_taylor_stepper.h", "lcg_stepper.h"])}
    for name, text in sources.items():
        (tmp_path / name).write_text(text)
    for name in ("lcg_cvode_stepper.c", "lcg_cvc_stepper.c", "lcg_ida_stepper.c", "lcg_taylor_stepper.c"):
        proc = subprocess.run([cc, *STRICT_CFLAGS, "-O2", "-c", name, "-o", name[:-2] + ".o"], cwd=tmp_path,
                              capture_output=True, text=True)
        assert proc.returncode == 0, proc.stderr


def test_grid_takes_any_sequence_and_fills_out(double_pendulum):
    with double_pendulum.integrator(q0=[1.0, 0.5], method="taylor", **TOL) as a, \
            double_pendulum.integrator(q0=[1.0, 0.5], method="taylor", **TOL) as b:
        strided = np.linspace(0.0, 2.0, 21)[::2]       # not contiguous
        out = np.empty((11, 4))
        rows = a.propagate_grid(strided, out=out)
        assert rows is out
        np.testing.assert_array_equal(rows, b.propagate_grid(list(strided)))
        with pytest.raises(LagcodegenError, match="shape"):
            a.propagate_grid([2.5, 3.0], out=np.empty((3, 4)))
        with pytest.raises(LagcodegenError, match="at least one"):
            a.propagate_grid([])


def test_minimal_coordinates_integrator_follows_the_pendulum_angle():
    """The Cartesian pendulum in minimal coordinates (x kept, y eliminated) through the integrator:
    x(t) = l sin(theta(t)) of the angle model, and its grid is simulate()'s bit for bit."""
    sim = lcg.compile_constrained(cartesian_pendulum("cpend_integ"), "minimal")
    angle = lcg.compile_model(systems.pendulum())
    times = np.linspace(0.0, 3.0, 31)
    ref = angle.simulate(times, q0=[TH0], rtol=1e-12, atol=1e-14)
    with sim.integrator(q0=pendulum_q0(), v0=[0, 0], method="taylor", **TOL) as integ:
        assert integ.state_names == sim.state_names == ["x", "x_dot"]
        rows = integ.propagate_grid(times)
    assert np.max(np.abs(rows[:, 0] - np.sin(ref["theta"]))) < 1e-8
    np.testing.assert_array_equal(rows, sim.simulate(times, q0=pendulum_q0(), v0=[0, 0], method="taylor",
                                                     **TOL).y)
    with pytest.raises(LagcodegenError):
        sim.integrator(q0=[0.5, 0.5], v0=[0, 0])  # off the constraint


@pytest.fixture(scope="module")
def cpend_index1():
    cs = cartesian_pendulum("cpend_integ1")
    x = cs.model.coords[0]
    return lcg.compile_constrained(cs, "index1", outputs=["energy"], events=[Event("x_zero", x, -1)])


def test_index1_integrator_is_simulate_and_stops_at_a_quarter_period(cpend_index1):
    """The Cartesian pendulum's index-1 form on CVODE: a grid equals simulate() bit for bit; the
    terminal event x = 0 (downward) stops propagate_until at a quarter of the exact period."""
    sim = cpend_index1
    times = np.linspace(0.0, 0.4, 9)
    ref = sim.simulate(times, q0=pendulum_q0(), v0=[0, 0], rtol=1e-10, atol=1e-12)
    with sim.integrator(q0=pendulum_q0(), v0=[0, 0], rtol=1e-10, atol=1e-12) as integ:
        assert integ.state_names == sim.state_names
        np.testing.assert_array_equal(integ.propagate_grid(times), ref.y)
        quarter = math.sqrt(1.0 / 9.81) * ellipk(math.sin(TH0 / 2) ** 2)
        stop = integ.propagate_until(5.0)
        assert stop is integ.stopped_by and stop.name == "x_zero" and stop.terminal
        assert stop.t == pytest.approx(quarter, abs=1e-7)
        assert integ.time == stop.t and abs(integ.state[0]) < 1e-8
        assert integ.stats["alpha"] > 0  # "auto" Baumgarte: the natural rate at the start
        for _ in range(3):  # steps go on past the event
            assert integ.step() > stop.t


def test_index1_integrator_pieces_and_parameter_write(cpend_index1):
    """Pieces to tolerance; g written in place: the period follows sqrt(l/g)."""
    sim = cpend_index1
    with sim.integrator(q0=pendulum_q0(0.2), v0=[0, 0], rtol=1e-10, atol=1e-12, events=False) as integ:
        ref = sim.simulate(np.array([0.0, 1.0]), q0=pendulum_q0(0.2), v0=[0, 0], rtol=1e-10, atol=1e-12,
                           events=False)
        for t in np.linspace(0.1, 1.0, 10):
            integ.propagate_until(t)
        assert np.max(np.abs(integ.state - ref.y[-1])) < 1e-7
    with sim.integrator(q0=pendulum_q0(0.2), v0=[0, 0], rtol=1e-10, atol=1e-12) as integ:
        integ.params = {"g": 4 * 9.81}  # quarter period halves
        stop = integ.propagate_until(5.0)
        assert stop.t == pytest.approx(0.5 * math.sqrt(1.0 / 9.81) * ellipk(math.sin(0.1) ** 2), abs=1e-7)


@pytest.fixture(scope="module")
def cpend_ggl():
    cs = cartesian_pendulum("cpend_integ_ggl")
    x = cs.model.coords[0]
    return lcg.compile_constrained(cs, "ggl", outputs=["energy", "lambda"], events=[Event("x_zero", x, -1)])


def test_ggl_integrator_is_simulate_and_its_multiplier_is_the_rod_tension(cpend_ggl):
    """The GGL form on IDA: a grid equals simulate() bit for bit; lambda gives the rod tension
    T = m (g cos(theta) + l theta'^2) = -2 l lambda of the angle model; the terminal event stops
    at a quarter of the exact period."""
    sim = cpend_ggl
    times = np.linspace(0.0, 0.4, 9)
    ref = sim.simulate(times, q0=pendulum_q0(), v0=[0, 0], rtol=1e-10, atol=1e-12)
    with sim.integrator(q0=pendulum_q0(), v0=[0, 0], rtol=1e-10, atol=1e-12) as integ:
        assert integ.family == "ida"
        np.testing.assert_array_equal(integ.propagate_grid(times), ref.y)
        x, y, xd, yd = integ.state
        th, thd = math.atan2(x, -y), (x * yd - y * xd)  # l = 1
        tension = 9.81 * math.cos(th) + thd ** 2
        assert -2.0 * integ.multipliers[0] == pytest.approx(tension, rel=1e-6)
        stop = integ.propagate_until(5.0)
        quarter = math.sqrt(1.0 / 9.81) * ellipk(math.sin(TH0 / 2) ** 2)
        assert stop is not None and stop.name == "x_zero" and stop.t == pytest.approx(quarter, abs=1e-7)
        assert integ.time == stop.t and len(stop.y) == 4


def test_ggl_integrator_projects_a_written_state_onto_the_constraint(cpend_ggl):
    with cpend_ggl.integrator(q0=pendulum_q0(), v0=[0, 0], rtol=1e-10, atol=1e-12, events=False) as integ:
        integ.propagate_until(0.2)
        integ.state[:] = [0.3, -0.99, 0.0, 0.0]   # off the circle x^2 + y^2 = 1
        integ.propagate_for(0.1)
        x, y, xd, yd = integ.state
        assert x * x + y * y == pytest.approx(1.0, abs=1e-9)
        assert x * xd + y * yd == pytest.approx(0.0, abs=1e-8)
        ref = cpend_ggl.simulate(np.array([0.2, 0.3]), q0=[0.3, -0.99], v0=[0, 0], initial="project", rtol=1e-10,
                                 atol=1e-12, events=False)
        assert np.max(np.abs(integ.state - ref.y[-1])) < 1e-7
        for _ in range(3):
            integ.step()
        assert integ.time > 0.3
    with pytest.raises(LagcodegenError, match="multipliers"):
        with lcg.compile_model(systems.pendulum()).integrator(q0=[0.1]) as other:
            other.multipliers


@pytest.mark.parametrize("method,options", [("taylor", {"max_step": 0.05}), ("taylor", {"order": 12}),
                                            ("adams", {"linear_solver": "fixedpoint"}),
                                            ("bdf", {"linear_solver": "band"}), ("bdf", {"jacobian": False}),
                                            ("adams", {"max_order": 3, "max_step": 0.05})])
def test_options_and_per_state_atol_resolve_as_in_simulate(double_pendulum, method, options):
    atol = np.array([1e-11, 1e-11, 1e-9, 1e-9])
    times = np.linspace(0.0, 2.0, 21)
    ref = double_pendulum.simulate(times, q0=[1.0, 0.5], method=method, rtol=1e-9, atol=atol, **options)
    with double_pendulum.integrator(q0=[1.0, 0.5], method=method, rtol=1e-9, atol=atol, **options) as integ:
        np.testing.assert_array_equal(integ.propagate_grid(times), ref.y)
    with pytest.raises(LagcodegenError, match="baumgarte"):  # an option the ODE does not take, named
        double_pendulum.integrator(q0=[1.0, 0.5], method=method, baumgarte=(1, 1))


@pytest.mark.parametrize("form,options", [("index1", {"method": "bdf", "projection": True}),
                                          ("index1", {"baumgarte": (5.0, 5.0), "max_step": 0.02}),
                                          ("ggl", {"stop_at_outputs": True}), ("ggl", {"jacobian": False})])
def test_constrained_options_resolve_as_in_simulate(cpend_index1, cpend_ggl, form, options):
    sim = cpend_index1 if form == "index1" else cpend_ggl
    times = np.linspace(0.0, 0.3, 7)
    ref = sim.simulate(times, q0=pendulum_q0(), v0=[0, 0], rtol=1e-9, atol=1e-11, **options)
    with sim.integrator(q0=pendulum_q0(), v0=[0, 0], rtol=1e-9, atol=1e-11, **options) as integ:
        np.testing.assert_array_equal(integ.propagate_grid(times), ref.y)
