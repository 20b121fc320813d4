"""Forward sensitivities on the Taylor integrator of models with generalized speeds (y = (q, v),
q' = k(q, v): quaternion joints; the variational jet carries the tangent of the kinematics,
lagcodegen.codegen.taylor.variational): a free rigid body (Joint.free), a spherical pendulum
(Joint.spherical) and a floating pendulum (a free base with a revolute arm and a spring), along
run-time parameters, initial values of coordinates and speeds and the rotations "<joint>_rx(0)"
of a quaternion joint. Checked against CVODE's forward sensitivities of the same model and
directions (an independent derivation: the generated tangent of the right-hand side, a BDF/Adams
Newton solve; measured 3e-13 .. 6e-12 relative at rtol 1e-12 on both), against central
differences of plain Taylor runs (measured 1e-12 .. 3e-10), and against a fact of the exact flow
(a rotation keeps the quaternion on the unit sphere: q . dq/d(theta) = 0). Events' time
sensitivities, the integrator object, ensembles, input tables and repeated runs (each run's
rotation s0 at its own initial state) on the same path."""

import sys
from pathlib import Path

import numpy as np
import pytest

import lagcodegen as lcg

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "model"))
from test_general_jacobian import free_flyer_with_spring  # noqa: E402
from test_general_sensitivities import perturbed  # noqa: E402

T = np.linspace(0.0, 2.0, 9)
TIGHT = dict(rtol=1e-12, atol=1e-12)


def ball_pendulum():
    """A rigid bob on a quaternion ball joint under gravity, its centre of mass off the axis."""
    m = lcg.Model("tgs_ball")
    g, l = m.parameters(g=9.81, l=0.8)
    m.link("bob", joint=lcg.Joint.spherical("ball"), mass=1.5, com=(0.1, 0, -l), inertia=(0.02, 0.03, 0.01))
    m.gravity(g)
    return m


def free_body():
    """A free rigid body (Pinocchio's free flyer layout) with a run-time principal moment."""
    m = lcg.Model("tgs_free")
    iy, = m.parameters(iy=2.0)
    m.link("body", joint=lcg.Joint.free("root"), mass=1.3, inertia=(1.0, iy, 3.0))
    return m


def unit(q, at):
    q = np.array(q, dtype=float)
    q[at:at + 4] /= np.linalg.norm(q[at:at + 4])
    return q


CASES = {
    "ball": (ball_pendulum, ["g", "l"], unit([0.2, -0.1, 0.3, 0.9], 0), [0.5, -0.4, 1.2],
             ["g", "l", "ball_wz(0)", "ball_rx(0)", "ball_ry(0)", "ball_rz(0)"], 0),
    "free": (free_body, ["iy"], unit([0.1, 0.2, -0.3, 0.3, -0.2, 0.1, 0.9], 3), [0.2, -0.1, 0.3, 0.1, 2.0, 0.05],
             ["iy", "root_x(0)", "root_wy(0)", "root_vx(0)", "root_rx(0)", "root_rz(0)"], 3),
    "flyer": (free_flyer_with_spring, ["k"], unit([0.5, -0.2, 0.1, 0.1, 0.2, 0.3, 0.9, 0.4], 3),
              [0.3, -0.2, 0.5, 0.4, -0.3, 0.8, 1.0],
              ["k", "root_x(0)", "elbow(0)", "root_wy(0)", "elbow_dot(0)", "root_rx(0)", "root_ry(0)",
               "root_rz(0)"], 3),
}

_compiled: dict = {}


def compiled(case):
    if case not in _compiled:
        make, params = CASES[case][:2]
        model = make()
        _compiled[case] = (model, lcg.compile_model(model, runtime_parameters=params, outputs=["energy"]))
    return _compiled[case]


@pytest.mark.parametrize("case", ["ball", "free", "flyer"])
def test_against_cvode_and_central_differences(case):
    """Taylor's sensitivities of the states and the energy along every direction agree with
    CVODE's to 1e-8 relative (measured <= 6e-12) and with central differences of Taylor runs to
    2e-8 (measured <= 3e-10); a rotation keeps |q| = 1: q . dq/d(theta) = 0 to 1e-12."""
    model, cm = compiled(case)
    _, _, q0, v0, names, at = CASES[case]
    ta = cm.simulate(T, q0=q0, v0=v0, method="taylor", sensitivities=names, **TIGHT)
    cv = cm.simulate(T, q0=q0, v0=v0, sensitivities=names, **TIGHT)
    assert ta.status == 0 and ta.method == "taylor" and ta.sensitivity_names == names
    assert ta.sensitivities.shape == cv.sensitivities.shape == (T.size, len(names), cm.ny + 1)
    assert np.abs(ta.y - cv.y).max() < 1e-9
    defaults = {s.name: value for s, value in model.params.items()}
    h = 1e-5
    for j, name in enumerate(names):
        s, ref = ta.sensitivities[:, j], cv.sensitivities[:, j]
        assert np.abs(s - ref).max() < 1e-8 * np.abs(ref).max(), (name, np.abs(s - ref).max())
        runs = []
        for sign in (1, -1):
            if name in cm.param_names:
                r = cm.simulate(T, q0=q0, v0=v0, params={name: defaults[name] + sign * h}, method="taylor", **TIGHT)
            else:
                q, v = perturbed(model, q0, v0, name, sign * h)
                r = cm.simulate(T, q0=q, v0=v, method="taylor", **TIGHT)
            runs.append(np.column_stack([r.y, r["energy"]]))
        fd = (runs[0] - runs[1]) / (2 * h)
        assert np.abs(s - fd).max() < 2e-8 * max(1.0, np.abs(fd).max()), (name, np.abs(s - fd).max())
        if name[-6:-3] in ("_rx", "_ry", "_rz"):
            assert np.abs(np.sum(ta.y[:, at:at + 4] * s[:, at:at + 4], axis=1)).max() < 1e-12


def test_rotation_starts_as_cvode_forms_it():
    """At t0 a rotation's sensitivity is CVODE's s0: d q / d theta = q x (e/2, 0) (Hamilton product,
    body axis e), zero elsewhere; here for q = (s, 0, 0, s) about z: (0, -s/2, s/2, 0)."""
    _, cm = compiled("free")
    s = np.sqrt(0.5)
    q0 = [0.1, 0.2, -0.3, s, 0.0, 0.0, s]
    v0 = CASES["free"][3]
    names = ["root_rz(0)", "root_rx(0)"]
    ta = cm.simulate(T, q0=q0, v0=v0, method="taylor", sensitivities=names, **TIGHT)
    cv = cm.simulate(T, q0=q0, v0=v0, sensitivities=names, **TIGHT)
    assert np.array_equal(ta.sensitivities[0, :, :cm.ny], cv.sensitivities[0, :, :cm.ny])
    assert np.allclose(ta.sensitivities[0, 0, :cm.ny], [0, 0, 0, 0, -s / 2, s / 2, 0] + [0] * 6, rtol=0, atol=1e-15)


def test_event_time_sensitivities_against_cvode():
    """The floating pendulum's base crossing root_x = 0 (terminal): the event time's and state's
    sensitivities along a parameter, a speed and a rotation as CVODE's (1e-8 relative)."""
    model, cm = compiled("flyer")
    _, _, q0, v0, _, _ = CASES["flyer"]
    ev = [lcg.Event("cross", "root_x", direction=-1, terminal=True)]
    t = np.linspace(0.0, 3.0, 4)
    names = ["k", "root_vx(0)", "root_rz(0)"]
    ta = cm.simulate(t, q0=q0, v0=v0, sensitivities=names, events=ev, method="taylor", **TIGHT)
    cv = cm.simulate(t, q0=q0, v0=v0, sensitivities=names, events=ev, **TIGHT)
    assert len(ta.events) == len(cv.events) == 1
    a, b = ta.events[0], cv.events[0]
    assert abs(a.t - b.t) < 1e-10
    for name in names:
        assert abs(a.t_sensitivity[name] - b.t_sensitivity[name]) < 1e-8 * max(1.0, abs(b.t_sensitivity[name]))
        ya, yb = np.asarray(a.y_sensitivity[name]), np.asarray(b.y_sensitivity[name])
        assert np.abs(ya - yb).max() < 1e-8 * max(1.0, np.abs(yb).max()), name
    # the terminal event's row: the run's last, its sensitivities CVODE's
    assert ta.t[-1] == a.t
    assert np.abs(ta.sensitivities[-1] - cv.sensitivities[-1]).max() < 1e-8 * np.abs(cv.sensitivities[-1]).max()


def test_integrator_object_starts_with_the_rotation_and_runs_as_simulate():
    _, cm = compiled("flyer")
    _, _, q0, v0, _, _ = CASES["flyer"]
    names = ["k", "root_rx(0)", "elbow_dot(0)"]
    ref = cm.simulate(T, q0=q0, v0=v0, method="taylor", sensitivities=names, **TIGHT)
    integ = cm.integrator(q0=q0, v0=v0, method="taylor", sensitivities=names, **TIGHT)
    assert np.array_equal(integ.sensitivities, ref.sensitivities[0, :, :cm.ny].T)
    y, S = integ.propagate_grid(T)
    assert np.array_equal(y, ref.y)
    assert np.array_equal(S, ref.sensitivities[:, :, :cm.ny].transpose(0, 2, 1))


@pytest.mark.parametrize("threads", [1, 2])
def test_ensemble_members_take_their_own_rotation(threads):
    """Members at two attitudes: each member bit-identical to its run alone (its rotation's s0 at
    its own initial state), and the two differ."""
    _, cm = compiled("ball")
    _, _, q0, v0, _, _ = CASES["ball"]
    s = np.sqrt(0.5)
    Q = np.array([q0, [s, 0.0, 0.0, s]])
    names = ["g", "ball_rz(0)"]
    ens = cm.ensemble(T, q0=Q, v0=np.array([v0, v0]), save="trajectory", threads=threads, sensitivities=names,
                      method="taylor", **TIGHT)
    for i in range(2):
        alone = cm.simulate(T, q0=Q[i], v0=v0, method="taylor", sensitivities=names, **TIGHT)
        assert np.array_equal(ens.sensitivity_trajectories[i], alone.sensitivities)
    assert np.abs(ens.sensitivity_trajectories[0] - ens.sensitivity_trajectories[1]).max() > 1e-2


def test_repeated_runs_take_each_runs_rotation():
    """simulate's repeated runs (the prepared fast path) form a rotation's s0 at each run's
    initial state: two attitudes alternated, each equal to its first run bit for bit."""
    _, cm = compiled("ball")
    _, _, qa, v0, _, _ = CASES["ball"]
    s = np.sqrt(0.5)
    qb = [s, 0.0, 0.0, s]
    runs = [cm.simulate(T, q0=q, v0=v0, method="taylor", sensitivities=["ball_ry(0)"], **TIGHT).sensitivities
            for q in (qa, qb, qa, qb)]
    assert np.abs(runs[0] - runs[1]).max() > 1e-2
    assert np.array_equal(runs[2], runs[0]) and np.array_equal(runs[3], runs[1])


def test_input_tables_with_rotations_against_cvode():
    """The floating pendulum driven by a torque table on its elbow: Taylor's table-driven
    sensitivities (the rotations' s0 at the initial state, carried across the breakpoints) as
    CVODE's input-driven ones (1e-8 relative; measured 3e-11); an ensemble member is its run."""
    model = free_flyer_with_spring()
    model.generalized_force("elbow", model.input("F"))
    cm = lcg.compile_model(model, runtime_parameters=["k"], outputs=["energy"])
    _, _, q0, v0, _, _ = CASES["flyer"]
    table = lcg.Table([0.0, 0.5, 1.0, 1.5, 2.0], [0.0, 0.3, -0.2, 0.1, 0.0])
    names = ["k", "elbow(0)", "root_rx(0)", "root_ry(0)"]
    ta = cm.simulate(T, q0=q0, v0=v0, inputs={"F": table}, method="taylor", sensitivities=names, **TIGHT)
    cv = cm.simulate(T, q0=q0, v0=v0, inputs={"F": table}, sensitivities=names, **TIGHT)
    assert ta.status == 0 and ta.method == "taylor"
    for j, name in enumerate(names):
        ref = cv.sensitivities[:, j]
        assert np.abs(ta.sensitivities[:, j] - ref).max() < 1e-8 * np.abs(ref).max(), name
    free = cm.simulate(T, q0=q0, v0=v0, method="taylor", sensitivities=names, **TIGHT)
    assert np.abs(free.sensitivities - ta.sensitivities).max() > 1e-2  # the table acts
    ens = cm.ensemble(T, q0=np.array([q0, q0]), v0=np.array([v0, v0]), inputs={"F": table}, method="taylor",
                      sensitivities=names, save="trajectory", **TIGHT)
    assert np.array_equal(ens.sensitivity_trajectories[1], ta.sensitivities)


def test_quaternion_component_refused_by_name_as_on_cvode():
    """One quaternion component is not a direction (it leaves the unit sphere): refused on Taylor
    with CVODE's message, naming the rotations to give instead."""
    from lagcodegen.errors import LagcodegenError
    _, cm = compiled("ball")
    _, _, q0, v0, _, _ = CASES["ball"]
    with pytest.raises(LagcodegenError, match="'ball_qy\\(0\\)' perturbs one component of the unit quaternion of "
                                              "joint 'ball'.*'ball_rx\\(0\\)'"):
        cm.simulate(T, q0=q0, v0=v0, method="taylor", sensitivities=["ball_qy(0)"])
