"""Events in runs with forward sensitivities on the Taylor integrator
(lagcodegen.solvers.taylor.sensitivity: the variational jet's table carries the event rows;
lagcodegen.solvers.event_sensitivity: the event times' sensitivities): against CVODE's
sensitivity run with the same events, central differences of the event times of plain Taylor
runs, and the pendulum's exact scaling law (every crossing time from rest is proportional to
sqrt(l/g)); a non-terminal event leaves the states and sensitivities as the run without it;
ensemble members as their runs alone (the integrator object: test_sensitivity_integrator.py)."""

import subprocess

import numpy as np
import pytest
import sympy as sp

import lagcodegen as lcg
from lagcodegen.errors import LagcodegenError
from lagcodegen.formulation.events import scene_events
from lagcodegen.codegen.taylor.decompose import decompose
from lagcodegen.codegen.taylor.variational_source import variational_sources

from helpers import STRICT_CFLAGS

TH = sp.Symbol("theta")
NAMES = ["l", "g", "theta(0)", "theta_dot(0)"]
T = np.linspace(0.0, 3.0, 31)
TOL = dict(rtol=1e-12, atol=1e-14)


def events():
    """A non-terminal event whose function depends on a parameter (theta = l/4, either way: its
    time's sensitivity has a dg/dl term), then the terminal first downward crossing of theta = 0."""
    return [lcg.Event("shifted", TH - sp.Symbol("l") / 4, 0, False), lcg.Event("bottom", TH, -1, True)]


@pytest.fixture(scope="module")
def pend():
    return lcg.compile_model(lcg.systems.pendulum(), outputs=["energy"])


@pytest.fixture(scope="module")
def runs(pend):
    """(Taylor, CVODE) sensitivity runs from theta = 0.5 at rest with the two events."""
    tay = pend.simulate(T, q0=[0.5], events=events(), sensitivities=NAMES, method="taylor", **TOL)
    cv = pend.simulate(T, q0=[0.5], events=events(), sensitivities=NAMES, method="bdf", **TOL)
    return tay, cv


def _plain_events(pend, theta0=0.5, params=None):
    """The events of a plain Taylor run (no sensitivities) at rtol 1e-13."""
    res = pend.simulate(np.linspace(0.0, 3.0, 4), q0=[theta0], params=params, events=events(), method="taylor",
                        rtol=1e-13, atol=1e-15)
    return res.events


def test_event_records_agree_with_cvode(runs):
    tay, cv = runs
    assert tay.status == 0 and [e.name for e in tay.events] == ["shifted", "bottom"] == [e.name for e in cv.events]
    assert tay.stats["events"] == 2 and tay.stats["terminated"] == 1
    for a, b in zip(tay.events, cv.events):
        assert a.direction == b.direction == -1 and a.terminal == b.terminal
        assert abs(a.t - b.t) < 1e-9
        for name in NAMES:
            assert abs(a.t_sensitivity[name] - b.t_sensitivity[name]) < 1e-7 * max(1.0, abs(b.t_sensitivity[name]))
            assert np.max(np.abs(a.y_sensitivity[name] - b.y_sensitivity[name])) < 1e-7
    # the terminal event ends both runs: its state and s(t_e) (states and the output) the last row
    bottom = tay.events[-1]
    assert tay.t[-1] == bottom.t and np.array_equal(tay.y[-1], bottom.y)
    assert tay.t.size == cv.t.size and tay.sensitivities.shape == (tay.t.size, 4, 3)
    assert np.max(np.abs(tay.sensitivities[-1] - cv.sensitivities[-1])) < 1e-7
    assert abs(tay["energy"][-1] - cv["energy"][-1]) < 1e-9


def test_event_times_sensitivities_against_central_differences_and_scaling(pend, runs):
    tay, _ = runs
    shifted, bottom = tay.events
    l, g = 1.0, 9.81
    # the bottom crossing from rest: t_e = sqrt(l/g) T(theta0) exactly
    assert abs(bottom.t_sensitivity["l"] - bottom.t / (2 * l)) < 1e-9 * bottom.t
    assert abs(bottom.t_sensitivity["g"] + bottom.t / (2 * g)) < 1e-9 * bottom.t
    assert abs(bottom.t_sensitivity["theta_dot(0)"]) > 1e-3  # a direction that does move it
    # theta = 0 at the bottom whatever the parameters: the state's total sensitivity there too
    assert all(abs(bottom.y_sensitivity[n][0]) < 1e-10 for n in NAMES)
    # theta = l/4 at the shifted event: d theta(t_e)/dl = 1/4, 0 along the others
    assert abs(shifted.y_sensitivity["l"][0] - 0.25) < 1e-10
    assert all(abs(shifted.y_sensitivity[n][0]) < 1e-10 for n in NAMES if n != "l")
    h = 1e-4
    for name, plus, minus in [("theta(0)", (0.5 + h, None), (0.5 - h, None)),
                              ("l", (0.5, {"l": l + h}), (0.5, {"l": l - h}))]:
        up, down = _plain_events(pend, *plus), _plain_events(pend, *minus)
        for k, rec in enumerate(tay.events):
            fd = (up[k].t - down[k].t) / (2 * h)
            assert abs(rec.t_sensitivity[name] - fd) < 1e-6 * max(1.0, abs(fd))
            fdy = (up[k].y - down[k].y) / (2 * h)
            assert np.max(np.abs(rec.y_sensitivity[name] - fdy)) < 1e-6 * max(1.0, np.max(np.abs(fdy)))


def test_non_terminal_event_leaves_the_sensitivities(pend, runs):
    """The rows before the terminal event are those of the run without events (the same steps:
    the event rows are located on each step's polynomial, nothing is reset)."""
    tay, _ = runs
    alone = pend.simulate(T, q0=[0.5], sensitivities=NAMES, method="taylor", **TOL)
    rows = tay.t.size - 1  # the last row is the terminal event's
    assert rows == int((T < tay.events[-1].t).sum()) and tay.events[0].t < T[rows - 1]
    assert np.array_equal(tay.y[:rows], alone.y[:rows])
    assert np.array_equal(tay.sensitivities[:rows], alone.sensitivities[:rows])


def test_ensemble_members_are_their_runs_alone(pend):
    """Members with the events, on 2 threads: event counts, final state, sensitivities and t_reached
    those of each run alone (bit-identical), the trajectory the output times before a terminal
    event; the member from -0.3 crosses theta = l/4 upward and back before its bottom crossing."""
    q0 = np.array([[0.5], [0.3], [-0.3]])
    ens = pend.ensemble(T, q0=q0, events=events(), save="trajectory", sensitivities=NAMES, method="taylor",
                        threads=2, **TOL)
    assert list(ens.stats["events"]) == [2, 2, 3] and list(ens.stats["terminated"]) == [1, 1, 1]
    for i in range(3):
        alone = pend.simulate(T, q0=q0[i], events=events(), sensitivities=NAMES, method="taylor", **TOL)
        assert ens.t_reached[i] == alone.t[-1] == alone.events[-1].t
        assert np.array_equal(ens.y[i], alone.y[-1]) and np.array_equal(ens.sensitivities[i], alone.sensitivities[-1])
        rows = int(ens.nt_done[i])
        assert rows == (T <= alone.t[-1]).sum() and np.isnan(ens.sensitivity_trajectories[i, rows:]).all()
        assert np.array_equal(ens.sensitivity_trajectories[i, :rows], alone.sensitivities[:rows])


def test_refusals(pend):
    ev = [lcg.Event("bottom", TH, -1, True)]
    # (no longer refused: Taylor ensembles with events and no sensitivities record each member's events)
    ens = pend.ensemble(T, q0=np.array([[0.1], [0.2]]), method="taylor", events=ev)
    alone = pend.simulate(T, q0=[0.2], method="taylor", events=ev)
    assert [(e.t, e.name) for e in ens.member(1).events] == [(e.t, e.name) for e in alone.events]
    with pytest.raises(lcg.ModelError, match="unknown"):
        pend.simulate(T, q0=[0.5], method="taylor", sensitivities=["l"], events=[lcg.Event("odd", "nope")])


def test_variational_jet_with_events_compiles_strictly(tmp_path, cc):
    """The variational jet's table with the event rows (those of the states' jet, shifted past the
    sensitivity rows) under the strict flags; without events the table has none."""
    scene = lcg.Scene(lcg.derive(lcg.systems.pendulum()), outputs=["energy"])
    checked = scene_events(scene, events())
    files, v = variational_sources(scene, [("param", 0), ("state", 0)], ["l", "theta(0)"], events=checked)
    text = files["pendulum_taylor_var.c"]
    # the states' jet's rows: a state row stays, an operation's moves past the 2 sensitivity blocks
    base = decompose(scene, checked)
    assert v.events == [r if r < 2 else r + 2 * 2 for r in base.events] and v.events[1] == 0
    assert not any(2 <= r < 6 for r in v.events)
    assert f"tl_event_row[2] = {{ {v.events[0]}, {v.events[1]} }}" in text
    assert "tl_event_direction[2] = { 0, -1 }" in text and "tl_event_terminal[2] = { 0, 1 }" in text
    plain, _ = variational_sources(scene, [("param", 0)], ["l"])
    assert "tl_event_row" not in plain["pendulum_taylor_var.c"]
    for name, body in files.items():
        (tmp_path / name).write_text(body)
    proc = subprocess.run([cc, *STRICT_CFLAGS, "-O1", "-c", "pendulum_taylor_var.c", "-o", "var.o"], cwd=tmp_path,
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
