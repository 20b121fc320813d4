"""simulate()'s fast path (lagcodegen.simulation.fastpath): a call with the option values of an
earlier one runs the family's prepared run. Its results must be bit-identical to the full path's
(``CompiledModel._simulate``), its checks of what each call brings must raise the same errors, and
option values equal across types must not share a prepared run."""

import copy
import pickle
import threading

import numpy as np
import pytest

import lagcodegen as lcg
from lagcodegen import LagcodegenError, ModelError, SolverError, systems
from lagcodegen.result import Result
from lagcodegen.solvers.lazy_result import LazyResult

METHODS = ["taylor", "adams", "bdf"]


@pytest.fixture(scope="module")
def double_pendulum():
    return lcg.compile_model(systems.double_pendulum(), outputs=["energy"])


def assert_same(fast, slow):
    """Every field of two results equal, the arrays bit for bit."""
    assert isinstance(fast, Result) and isinstance(slow, Result)
    np.testing.assert_array_equal(fast.t, slow.t)
    np.testing.assert_array_equal(fast.y, slow.y)
    assert fast.y.dtype == slow.y.dtype and fast.y.shape == slow.y.shape
    assert list(fast.outputs) == list(slow.outputs)
    for name in slow.outputs:
        np.testing.assert_array_equal(fast.outputs[name], slow.outputs[name])
    assert fast.stats == slow.stats
    assert fast.parameters == slow.parameters
    assert all(type(v) is type(slow.parameters[k]) for k, v in fast.parameters.items())
    for name in ("state_names", "status", "message", "backend", "method", "n_coordinates", "events", "formulation",
                 "model_name", "impacts", "sensitivity_names", "sensitivity_values"):
        assert getattr(fast, name) == getattr(slow, name), name
    if slow.sensitivities is None:
        assert fast.sensitivities is None
    else:
        np.testing.assert_array_equal(fast.sensitivities, slow.sensitivities)
        assert fast.sensitivities.shape == slow.sensitivities.shape
    assert fast.drawing is slow.drawing


@pytest.mark.parametrize("method", METHODS)
def test_fast_path_results_are_bit_identical_to_the_full_path(double_pendulum, method):
    cm = double_pendulum
    opts = dict(method=method, rtol=1e-9, atol=1e-9)
    y0 = np.array([0.7, -0.3, 0.1, 0.0])
    first = cm.simulate(np.array([0.0, 2.0]), y0=y0, **opts)  # the full path, which prepares the run
    assert type(first) is Result
    grids = [np.array([0.0, 2.0]), np.linspace(0.0, 3.0, 31), np.array([1.0, 1.5, 4.0])]
    for t in grids:
        fast = cm.simulate(t, y0=y0, **opts)
        assert isinstance(fast, LazyResult)  # the fast path ran
        assert_same(fast, cm._simulate(t, y0=y0, **opts))
    # q0/v0 lists, parameters by name, the same arrays again after writing into them in place
    kw = dict(q0=[0.2, 0.4], v0=[0.0, -1.0], params={"m1": 1.5})
    assert_same(cm.simulate(grids[1], **kw, **opts), cm._simulate(grids[1], **kw, **opts))
    t, y = grids[1].copy(), y0.copy()
    a = cm.simulate(t, y0=y, **opts)
    y[0], t[-1] = 0.9, 3.5
    b = cm.simulate(t, y0=y, **opts)
    assert b.y[0, 0] == 0.9 and b.t[-1] == 3.5 and a.y[0, 0] == 0.7
    assert_same(b, cm._simulate(t, y0=y, **opts))
    # the result's arrays are its own: the next run writes elsewhere
    kept = a.y.copy()
    cm.simulate(grids[1], y0=y0 * 0.5, **opts)
    np.testing.assert_array_equal(a.y, kept)


def test_the_physics_of_a_fast_run(double_pendulum):
    """Energy conserved along a fast-path run (an independent fact, not a comparison of paths)."""
    t = np.linspace(0.0, 5.0, 51)
    for _ in range(2):
        res = double_pendulum.simulate(t, q0=[1.0, 0.5], method="taylor", rtol=1e-12, atol=1e-12)
    assert isinstance(res, LazyResult)
    assert res.drift("energy") < 1e-9


@pytest.mark.parametrize("method", ["taylor", "adams"])
def test_fast_path_checks_what_each_call_brings(double_pendulum, method):
    cm = double_pendulum
    opts = dict(method=method, rtol=1e-6, atol=1e-6)
    t = np.array([0.0, 0.5])
    y0 = np.array([0.1, 0.2, 0.0, 0.0])
    cm.simulate(t, y0=y0, **opts)
    assert isinstance(cm.simulate(t, y0=y0, **opts), LazyResult)
    with pytest.raises(LagcodegenError, match="non-finite"):
        cm.simulate(t, y0=np.array([0.1, np.nan, 0.0, 0.0]), **opts)
    with pytest.raises(LagcodegenError, match="y0 has 3 values"):
        cm.simulate(t, y0=np.array([0.1, 0.2, 0.0]), **opts)
    with pytest.raises(LagcodegenError, match="y0 must be an array"):
        cm.simulate(t, y0="abcd", **opts)
    with pytest.raises(LagcodegenError, match="strictly increasing"):
        cm.simulate(np.array([0.5, 0.0]), y0=y0, **opts)
    with pytest.raises(LagcodegenError, match="strictly increasing"):
        cm.simulate(np.array([0.0, np.inf]), y0=y0, **opts)
    with pytest.raises(LagcodegenError, match="strictly increasing"):
        cm.simulate(np.array([0.0, np.nan, 1.0]), y0=y0, **opts)
    with pytest.raises(ModelError, match="q0 has 1 values"):
        cm.simulate(t, q0=[0.1], **opts)
    with pytest.raises(ModelError, match="non-finite"):
        cm.simulate(t, q0=[0.1, np.inf], **opts)
    with pytest.raises(LagcodegenError, match="not a run-time parameter"):
        cm.simulate(t, y0=y0, params={"nope": 1.0}, **opts)
    with pytest.raises(LagcodegenError, match="give either y0 or q0/v0"):
        cm.simulate(t, y0=y0, q0=[0.1, 0.2], **opts)
    # a float32 or strided y0 is converted, as on the full path
    for y in (y0.astype(np.float32), np.repeat(y0, 2)[::2]):
        assert_same(cm.simulate(t, y0=y, **opts), cm._simulate(t, y0=y, **opts))


def test_output_times_are_checked_as_on_the_full_path(double_pendulum):
    """The fast path's own check of a few output times (two, three, more) refuses what
    output_times refuses: equal, decreasing and non-finite times anywhere."""
    cm = double_pendulum
    y0 = np.array([0.1, 0.2, 0.0, 0.0])
    cm.simulate(np.array([0.0, 1.0]), y0=y0, method="taylor")
    bad = [[0.0, 0.0], [0.0, 2.0, 1.0], [0.0, 0.0, 1.0], [0.0, 1.0, 1.0], [np.nan, 0.5, 1.0],
           [0.0, 0.5, np.inf], [0.0, 0.5, 0.7, 0.6, 1.0], [0.0, 0.5, 0.5, 1.0], [0.0, np.nan, 0.7, 1.0]]
    for times in bad:
        for run in (cm.simulate, cm._simulate):
            with pytest.raises(LagcodegenError, match="strictly increasing"):
                run(np.array(times), y0=y0, method="taylor")
    for times in ([0.0, 1.0], [0.0, 0.5, 1.0], [-1.0, 0.0, 0.25, 1.0]):
        fast = cm.simulate(np.array(times), y0=y0, method="taylor")
        assert isinstance(fast, LazyResult)
        assert_same(fast, cm._simulate(np.array(times), y0=y0, method="taylor"))


def test_values_equal_across_types_do_not_share_a_prepared_run(double_pendulum):
    cm = double_pendulum
    t = np.array([0.0, 0.5])
    loose = dict(rtol=1e-4, atol=1e-4)
    cm.simulate(t, q0=[0.1, 0.2], method="taylor", order=2, **loose)
    assert isinstance(cm.simulate(t, q0=[0.1, 0.2], method="taylor", order=2, **loose), LazyResult)
    with pytest.raises(LagcodegenError, match="order must be an integer"):
        cm.simulate(t, q0=[0.1, 0.2], method="taylor", order=2.0, **loose)
    cm.simulate(t, q0=[0.1, 0.2], method="taylor", max_steps=1000)
    assert isinstance(cm.simulate(t, q0=[0.1, 0.2], method="taylor", max_steps=1000), LazyResult)
    with pytest.raises(LagcodegenError, match="max_steps must be a positive integer"):
        cm.simulate(t, q0=[0.1, 0.2], method="taylor", max_steps=1000.0)
    with pytest.raises(LagcodegenError, match="max_steps must be a positive integer"):
        cm.simulate(t, q0=[0.1, 0.2], method="taylor", max_steps=True)
    # another option value: a run of its own (a low order takes more steps)
    a = cm.simulate(t, q0=[0.1, 0.2], method="taylor", order=3, rtol=1e-6, atol=1e-6)
    b = cm.simulate(t, q0=[0.1, 0.2], method="taylor", order=8, rtol=1e-6, atol=1e-6)
    assert a.stats["order"] == 3 and b.stats["order"] == 8 and a.stats["steps"] > b.stats["steps"]


@pytest.mark.parametrize("method", METHODS)
def test_a_failed_fast_run_fails_as_on_the_full_path(double_pendulum, method):
    cm = double_pendulum
    t = np.linspace(0.0, 50.0, 11)
    opts = dict(q0=[1.0, 2.0], method=method, max_steps=20, raise_on_error=False)
    slow = cm._simulate(t, **opts)
    cm.simulate(t, **opts)
    fast = cm.simulate(t, **opts)
    assert isinstance(fast, LazyResult) and not fast.success and fast.status < 0
    assert_same(fast, slow)
    assert 1 <= fast.t.size < t.size
    with pytest.raises(SolverError) as info:
        cm.simulate(t, q0=[1.0, 2.0], method=method, max_steps=20)
    with pytest.raises(SolverError) as full:
        cm._simulate(t, q0=[1.0, 2.0], method=method, max_steps=20)
    assert str(info.value) == str(full.value) and "max_steps" in str(info.value)
    assert_same(info.value.result, slow)


def test_a_lazy_result_pickles_and_copies_as_a_plain_result(double_pendulum):
    cm = double_pendulum
    t = np.linspace(0.0, 1.0, 5)
    cm.simulate(t, q0=[0.3, 0.1], method="adams")
    res = cm.simulate(t, q0=[0.3, 0.1], method="adams")
    assert isinstance(res, LazyResult)
    for other in (pickle.loads(pickle.dumps(res)), copy.copy(res), copy.deepcopy(res)):
        assert type(other) is Result
        other.drawing = res.drawing  # a deferred drawing pickles as a new object
        assert_same(other, res)
    res.stats["restarts"] = 3  # the lazy members are kept once made
    assert res.stats["restarts"] == 3
    with pytest.raises(AttributeError):
        res.no_such_member  # noqa: B018


def from_two_threads(call, count: int) -> list:
    """call(k) for k = 0..count-1, 20 times each, from two threads at once (k alternating between
    them): the last result of each."""
    got = [None] * count

    def work(ks):
        for k in ks:
            for _ in range(20):
                got[k] = call(k)

    threads = [threading.Thread(target=work, args=(range(i, count, 2),)) for i in range(2)]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    return got


@pytest.mark.parametrize("method", ["taylor", "adams"])
def test_fast_runs_from_several_threads(double_pendulum, method):
    """Each fast run has its own statistics and arrays: runs from two threads at once give the
    results of the same runs one after the other."""
    cm = double_pendulum
    t = np.linspace(0.0, 2.0, 21)
    starts = [[0.1 * k, -0.05 * k] for k in range(1, 9)]
    cm.simulate(t, q0=starts[0], method=method)
    serial = [cm._simulate(t, q0=q, method=method) for q in starts]
    got = from_two_threads(lambda k: cm.simulate(t, q0=starts[k], method=method), len(starts))
    for a, b in zip(got, serial):
        assert isinstance(a, LazyResult)
        assert_same(a, b)


@pytest.mark.parametrize("method", METHODS)
def test_fast_path_of_a_model_without_outputs(method):
    cm = lcg.compile_model(systems.pendulum())
    assert cm.code.nout == 0
    t = np.linspace(0.0, 2.0, 11)
    cm.simulate(t, q0=[2.0], method=method)
    fast = cm.simulate(t, q0=[2.0], method=method)
    assert isinstance(fast, LazyResult) and fast.outputs == {}
    assert_same(fast, cm._simulate(t, q0=[2.0], method=method))
    # the pendulum is symmetric: the run from -q0 is the mirror image of the run from q0
    np.testing.assert_allclose(fast.y[:, 0], cm.simulate(t, q0=[-2.0], method=method).y[:, 0] * -1, rtol=0,
                               atol=1e-6)


def test_runs_a_prepared_run_does_not_honour_take_the_full_path(double_pendulum):
    """scikit-sundae stays on the full path on every call; a family with a field set beyond those
    its prepared run honours prepares none."""
    from lagcodegen.solvers.cvode import CVODE
    from lagcodegen.solvers.taylor import Taylor
    cm = double_pendulum
    t = np.linspace(0.0, 0.5, 6)
    for _ in range(2):
        res = cm.simulate(t, q0=[0.3, 0.1], backend="sksundae")
        assert type(res) is Result and res.backend == "sksundae"
    assert Taylor().defaults_beside(frozenset()) and CVODE().defaults_beside(frozenset())
    assert not Taylor(order=3).defaults_beside(frozenset({"max_steps"}))
    assert Taylor(order=3).defaults_beside(frozenset({"order"}))


def assert_same_with_events(fast, slow):
    """assert_same, the event records field by field (their states bit for bit)."""
    import dataclasses
    assert [(e.name, e.index, e.t, e.direction, e.terminal, e.state_names) for e in fast.events] == \
        [(e.name, e.index, e.t, e.direction, e.terminal, e.state_names) for e in slow.events]
    for a, b in zip(fast.events, slow.events):
        np.testing.assert_array_equal(a.y, b.y)
    assert_same(dataclasses.replace(fast, events=[]), dataclasses.replace(slow, events=[]))


def test_taylor_event_runs_take_the_fast_path_bit_identically(double_pendulum):
    """A Taylor run with events (the second call with the same events) runs the prepared run with
    those events: the same records, rows and statistics as the full path, also for a terminal
    event (its state the last row) and a failed run; CVODE's event runs stay on the full path."""
    import sympy as sp
    from lagcodegen.model.events import Event
    cm = double_pendulum
    th = sp.Symbol(cm.state_names[0])
    opts = dict(method="taylor", rtol=1e-9, atol=1e-9)
    y0 = np.array([0.7, -0.3, 0.1, 0.0])
    t = np.linspace(0.0, 3.0, 7)
    crossing, stop = Event("cross", th, 0, False), Event("stop", th + 0.5, -1, True)
    for events in ([crossing], [stop], [crossing, stop]):
        first = cm.simulate(t, y0=y0, events=events, **opts)
        assert type(first) is Result
        fast = cm.simulate(t, y0=y0, events=events, **opts)
        assert isinstance(fast, LazyResult) and fast.events and fast.stats["events"] >= len(fast.events)
        assert_same_with_events(fast, cm._simulate(t, y0=y0, events=events, **opts))
        if stop in events:  # ended at theta_1 = -0.5, falling, its state the last row
            assert fast.events[-1].name == "stop" and fast.t[-1] == fast.events[-1].t < t[-1]
            assert abs(fast.y[-1, 0] + 0.5) < 1e-9 and fast.y[-1, 2] < 0
            assert np.array_equal(fast.y[-1], fast.events[-1].y) and fast.outputs["energy"].shape == fast.t.shape
    short = dict(opts, max_steps=3)
    cm.simulate(t, y0=y0, events=[crossing], raise_on_error=False, **short)
    fast = cm.simulate(t, y0=y0, events=[crossing], raise_on_error=False, **short)
    assert isinstance(fast, LazyResult) and fast.status == -1
    assert_same_with_events(fast, cm._simulate(t, y0=y0, events=[crossing], raise_on_error=False, **short))
    with pytest.raises(SolverError, match="max_steps"):
        cm.simulate(t, y0=y0, events=[crossing], **short)
    for _ in range(2):
        assert type(cm.simulate(t, y0=y0, events=[crossing], method="adams")) is Result


def test_fast_event_runs_from_several_threads(double_pendulum):
    """Concurrent Taylor runs with events never share an events struct: runs from two threads at
    once record the events of the same runs one after the other."""
    import sympy as sp
    from lagcodegen.model.events import Event
    cm = double_pendulum
    events = [Event("cross", sp.Symbol(cm.state_names[0]), 0, False)]
    t = np.linspace(0.0, 4.0, 5)
    starts = [[0.2 * k, -0.1 * k] for k in range(1, 7)]
    cm.simulate(t, q0=starts[0], method="taylor", events=events)
    serial = [cm._simulate(t, q0=q, method="taylor", events=events) for q in starts]
    assert all(r.events for r in serial)
    got = from_two_threads(lambda k: cm.simulate(t, q0=starts[k], method="taylor", events=events), len(starts))
    for a, b in zip(got, serial):
        assert isinstance(a, LazyResult)
        assert_same_with_events(a, b)


def assert_same_sensitivities(fast, slow):
    """assert_same (the sensitivities bit for bit with their names among its fields), the
    statistics but for the wall time."""
    fast_stats, slow_stats = dict(fast.stats), dict(slow.stats)
    assert fast_stats.pop("wall_time") > 0 and slow_stats.pop("wall_time") > 0
    assert fast_stats == slow_stats
    kept = slow.stats
    try:
        slow.stats = fast.stats
        assert_same(fast, slow)
    finally:
        slow.stats = kept


@pytest.mark.parametrize("method", METHODS)
def test_sensitivity_runs_take_the_fast_path_bit_identically(double_pendulum, method):
    """simulate(sensitivities=[...]) on CVODE and Taylor: the second call with the same names (a list, or the
    family's tuple) runs the prepared sensitivity run, bit-identical to the full path, with its
    own arrays; a list and a tuple of the same names do not share a prepared run; the
    sensitivities themselves agree with central differences of the fast path's own runs."""
    from lagcodegen.solvers.cvode import CVODE
    from lagcodegen.solvers.taylor import Taylor
    cm = double_pendulum
    names = ["g", "theta1(0)", "theta2_dot(0)"]
    opts = dict(method=method, rtol=1e-9, atol=1e-9, sensitivities=names)
    y0 = np.array([0.7, -0.3, 0.1, 0.0])
    first = cm.simulate(np.array([0.0, 2.0]), y0=y0, **opts)
    assert type(first) is Result
    for t in (np.array([0.0, 2.0]), np.linspace(0.0, 3.0, 31)):
        fast = cm.simulate(t, y0=y0, **opts)
        assert isinstance(fast, LazyResult) and fast.sensitivities.shape == (t.size, 3, 5)
        assert_same_sensitivities(fast, cm._simulate(t, y0=y0, **opts))
    kept = fast.sensitivities.copy()
    cm.simulate(np.linspace(0.0, 3.0, 31), y0=y0 * 0.5, **opts)
    np.testing.assert_array_equal(fast.sensitivities, kept)
    kw = dict(q0=[0.2, 0.4], params={"g": 9.0})
    assert_same_sensitivities(cm.simulate(np.linspace(0.0, 1.0, 5), **kw, **opts),
                              cm._simulate(np.linspace(0.0, 1.0, 5), **kw, **opts))
    # the tuple of the same names is another key: its first call takes the full path
    as_tuple = dict(opts, sensitivities=tuple(names))
    assert type(cm.simulate(np.array([0.0, 1.0]), y0=y0, **as_tuple)) is Result
    assert isinstance(cm.simulate(np.array([0.0, 1.0]), y0=y0, **as_tuple), LazyResult)
    solver = (Taylor if method == "taylor" else CVODE)(sensitivities=("g",), **({} if method == "taylor" else
                                                                                 {"method": method}))
    cm.simulate(np.array([0.0, 1.0]), y0=y0, solver=solver, rtol=1e-9, atol=1e-9)
    res = cm.simulate(np.array([0.0, 1.0]), y0=y0, solver=solver, rtol=1e-9, atol=1e-9)
    assert isinstance(res, LazyResult) and res.sensitivity_names == ["g"]
    # d theta1(T) / d g against central differences of plain fast runs
    t = np.array([0.0, 1.0])
    h = 1e-4
    plain = dict(method=method, rtol=1e-11, atol=1e-11)
    up = cm.simulate(t, y0=y0, params={"g": 9.81 + h}, **plain).y[-1, 0]
    down = cm.simulate(t, y0=y0, params={"g": 9.81 - h}, **plain).y[-1, 0]
    np.testing.assert_allclose(res.sensitivity("theta1", "g")[-1], (up - down) / (2 * h), rtol=1e-5, atol=1e-9)


@pytest.mark.parametrize("method", METHODS)
def test_a_failed_fast_sensitivity_run_fails_as_on_the_full_path(double_pendulum, method):
    cm = double_pendulum
    t = np.linspace(0.0, 50.0, 11)
    opts = dict(q0=[1.0, 2.0], max_steps=20, raise_on_error=False, sensitivities=["g"], method=method)
    slow = cm._simulate(t, **opts)
    cm.simulate(t, **opts)
    fast = cm.simulate(t, **opts)
    assert isinstance(fast, LazyResult) and not fast.success and fast.status < 0
    assert 1 <= fast.t.size < t.size and fast.sensitivities.shape[0] == fast.t.size
    assert_same_sensitivities(fast, slow)
    with pytest.raises(SolverError) as info:
        cm.simulate(t, q0=[1.0, 2.0], max_steps=20, sensitivities=["g"], method=method)
    with pytest.raises(SolverError) as full:
        cm._simulate(t, q0=[1.0, 2.0], max_steps=20, sensitivities=["g"], method=method)
    assert str(info.value) == str(full.value)
    with pytest.raises(LagcodegenError, match="non-finite"):
        cm.simulate(t, y0=np.array([np.nan, 0.0, 0.0, 0.0]), sensitivities=["g"], method=method)


def test_the_fast_sensitivity_run_honours_the_corrector(double_pendulum):
    """sensitivity_corrector="simultaneous" on the fast path: bit-identical to its full path, and
    another run than the staggered default's (different Newton counts)."""
    cm = double_pendulum
    t = np.linspace(0.0, 2.0, 11)
    opts = dict(q0=[0.7, -0.3], rtol=1e-9, atol=1e-9, sensitivities=["g", "l1"], sensitivity_corrector="simultaneous")
    cm.simulate(t, **opts)
    fast = cm.simulate(t, **opts)
    assert isinstance(fast, LazyResult)
    assert_same_sensitivities(fast, cm._simulate(t, **opts))
    staggered = cm.simulate(t, **dict(opts, sensitivity_corrector="staggered"))
    assert staggered.stats["nonlin_iters"] != fast.stats["nonlin_iters"]
