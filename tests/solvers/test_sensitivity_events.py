"""Events in runs with forward sensitivities (CVODE): the sensitivities of an event's time
against the pendulum's exact scaling law (the time of any crossing is proportional to sqrt(l/g)
at every amplitude), the small-angle period 2 pi sqrt(l/g) and central differences of the event
times of plain runs; non-terminal events leave the sensitivities as they are."""

import numpy as np
import pytest
import sympy as sp

import lagcodegen as lcg

TH = sp.Symbol("theta")


@pytest.fixture(scope="module")
def pend():
    return lcg.compile_model(lcg.systems.pendulum(), outputs=["energy"])


def _event_time(pend, theta0, params=None):
    """The time of the first downward zero crossing of a plain run (rtol 1e-13)."""
    ev = lcg.Event("bottom", TH, -1, True)
    res = pend.simulate(np.linspace(0.0, 3.0, 4), q0=[theta0], params=params, events=[ev], rtol=1e-13,
                        atol=1e-15)
    return res.events[-1].t, res.events[-1].y


def test_terminal_event_time_sensitivities(pend):
    ev = lcg.Event("bottom", TH, -1, True)
    names = ["l", "g", "theta(0)", "theta_dot(0)"]
    t = np.linspace(0.0, 3.0, 31)
    res = pend.simulate(t, q0=[0.5], events=[ev], sensitivities=names, rtol=1e-10, atol=1e-12)
    rec = res.events[-1]
    assert rec.terminal and len(res.events) == 1
    te, l, g = rec.t, 1.0, 9.81
    # exact: t_e(l, g) = sqrt(l/g) T(theta0), at every amplitude
    assert abs(rec.t_sensitivity["l"] - te / (2 * l)) < 1e-8 * te
    assert abs(rec.t_sensitivity["g"] + te / (2 * g)) < 1e-8 * te
    # the run ends at the event: its last row is the event's state, with its sensitivities s(t_e)
    assert res.t[-1] == te and res.sensitivities.shape == (res.t.size, 4, 3)
    # central differences of the event times and states of plain runs
    h = 1e-4
    for name, plus, minus in [("theta(0)", (0.5 + h, None), (0.5 - h, None)),
                              ("l", (0.5, {"l": 1.0 + h}), (0.5, {"l": 1.0 - h}))]:
        (tp, yp), (tm, ym) = _event_time(pend, *plus), _event_time(pend, *minus)
        assert abs(rec.t_sensitivity[name] - (tp - tm) / (2 * h)) < 1e-6 * max(1.0, abs(rec.t_sensitivity[name]))
        fd = (yp - ym) / (2 * h)
        assert np.max(np.abs(rec.y_sensitivity[name] - fd)) < 1e-6 * max(1.0, np.max(np.abs(fd)))
    # the state's angle is zero at the event whatever the parameters: its total sensitivity too
    assert all(abs(rec.y_sensitivity[n][0]) < 1e-9 for n in names)
    # the last row's sensitivities are those of the fixed time t_e: theta's rate times the time's
    s_l = res.sensitivity("theta", "l")[-1]
    assert abs(s_l + rec.y[1] * rec.t_sensitivity["l"]) < 1e-8


def test_small_angle_quarter_period(pend):
    """theta0 = 1e-3: t_e = (pi/2) sqrt(l/g) (1 + theta0^2/16 + ...), so dt_e/dl = (pi/4)/sqrt(l g)
    to relative 1e-7."""
    ev = lcg.Event("bottom", TH, -1, True)
    res = pend.simulate(np.linspace(0.0, 1.0, 3), q0=[1e-3], params={"l": 2.0}, events=[ev],
                        sensitivities=["l", "g"], rtol=1e-11, atol=1e-15)
    rec = res.events[-1]
    l, g = 2.0, 9.81
    assert abs(rec.t - np.pi / 2 * np.sqrt(l / g)) < 1e-6 * rec.t
    assert abs(rec.t_sensitivity["l"] - np.pi / 4 / np.sqrt(l * g)) < 1e-6 * rec.t_sensitivity["l"]
    assert abs(rec.t_sensitivity["g"] + np.pi / 4 * np.sqrt(l) / g ** 1.5) < 1e-6 * abs(rec.t_sensitivity["g"])


def test_recording_events_leave_the_sensitivities_as_they_are(pend):
    t = np.linspace(0.0, 3.0, 31)
    ev = lcg.Event("bottom", TH, -1, False)
    a = pend.simulate(t, q0=[0.5], events=[ev], sensitivities=["l", "theta(0)"])
    b = pend.simulate(t, q0=[0.5], sensitivities=["l", "theta(0)"])
    assert len(a.events) == 2 and a.stats["events"] == 2
    assert np.array_equal(a.sensitivities, b.sensitivities) and np.array_equal(a.y, b.y)
    # each crossing is a multiple of the first: so are the time sensitivities (scaling law)
    first, second = a.events
    assert abs(second.t_sensitivity["l"] / first.t_sensitivity["l"] - second.t / first.t) < 1e-6


def test_ensemble_members_stop_at_their_events(pend):
    """Members with a terminal event: final state, sensitivities and t_reached those of the event
    (bit-identical to each run alone), the trajectory the output times before it."""
    t = np.linspace(0.0, 1.0, 11)
    ev = lcg.Event("bottom", TH, -1, True)
    q0 = np.array([[0.1], [0.2], [-0.3]])  # the last one starts below zero: no downward crossing
    ens = pend.ensemble(t, q0=q0, events=[ev], save="trajectory", sensitivities=["l", "theta(0)"])
    assert list(ens.stats["events"]) == [1, 1, 0] and list(ens.stats["terminated"]) == [1, 1, 0]
    for i in range(3):
        alone = pend.simulate(t, q0=q0[i], events=[ev], sensitivities=["l", "theta(0)"])
        assert ens.t_reached[i] == alone.t[-1]
        assert np.array_equal(ens.y[i], alone.y[-1]) and np.array_equal(ens.sensitivities[i], alone.sensitivities[-1])
        rows = int(ens.nt_done[i])
        assert rows == (t <= alone.t[-1]).sum() and np.isnan(ens.sensitivity_trajectories[i, rows:]).all()
        assert np.array_equal(ens.sensitivity_trajectories[i, :rows], alone.sensitivities[:rows])
    # the quarter period at amplitude 0.1: (pi/2) sqrt(l/g) (1 + a^2/16 + 11 a^4/3072 + O(a^6))
    a = 0.1
    assert ens.t_reached[0] == pytest.approx(0.5 * np.pi * np.sqrt(1 / 9.81) * (1 + a ** 2 / 16 + 11 * a ** 4 / 3072),
                                             rel=1e-6)


def test_event_derivatives_compile_strictly(tmp_path, cc):
    """The generated <prefix>_events_grad.c, with and without run-time parameters, an event in t and
    the outputs' names, under the strict flags."""
    import subprocess

    from helpers import STRICT_CFLAGS
    from lagcodegen.codegen.events import events_gradient_source
    from lagcodegen.formulation.events import scene_events
    for scene in (lcg.Scene(lcg.derive(lcg.systems.pendulum()), outputs=["energy"]),
                  lcg.Scene(lcg.derive(lcg.systems.pendulum("p0")), runtime_parameters=[], outputs=[])):
        events = scene_events(scene, [lcg.Event("bottom", TH, -1, True),
                                      lcg.Event("late", sp.Symbol("t") - 2 * TH ** 2, 0, False),
                                      lcg.Event("energetic", "energy - 1", 1, False)])
        for name, text in events_gradient_source(scene, events).items():
            (tmp_path / name).write_text(text)
            proc = subprocess.run([cc, *STRICT_CFLAGS, "-O2", "-c", name, "-o", name + ".o"], cwd=tmp_path,
                                  capture_output=True, text=True)
            assert proc.returncode == 0, proc.stderr
            assert "gt[1] = 1" in text  # d(t - 2 theta^2)/dt
