"""Forward sensitivities of models with generalized speeds on native CVODE (to 2e-8 of central
differences at rtol 1e-11; measured 1e-10 .. 2e-9): parameter
directions, initial values of coordinates and speeds by name, rotations of a quaternion joint
("<joint>_rx(0)"), each against central differences of whole runs."""

import sys
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

import lagcodegen as lcg
from lagcodegen.errors import LagcodegenError

sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_general_jacobian import free_flyer_with_spring, polar  # noqa: E402

T = np.linspace(0.0, 1.5, 7)
TOL = dict(rtol=1e-11, atol=1e-12)


def quat_mul(a, b):
    """Hamilton product in Pinocchio's layout (x, y, z, w)."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return np.array([aw * bx + ax * bw + ay * bz - az * by, aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw, aw * bw - ax * bx - ay * by - az * bz])


def perturbed(model, q0, v0, name, h):
    """(q0, v0, params) with the initial value or rotation ``name`` moved by h; a rotation turns
    the quaternion by q x exp(h e / 2) (the body's axis e)."""
    q0, v0 = np.array(q0, float), np.array(v0, float)
    coords = [c.name for c in model.coords]
    speeds = [v.name for v in model.v]
    base = name[:-3]
    if base in coords:
        q0[coords.index(base)] += h
    elif base in speeds:
        v0[speeds.index(base)] += h
    else:
        joint, axis = base[:-3], base[-1]
        i = coords.index(f"{joint}_qx")
        e = np.zeros(3)
        e["xyz".index(axis)] = 1.0
        q0[i:i + 4] = quat_mul(q0[i:i + 4], np.r_[np.sin(h / 2) * e, np.cos(h / 2)])
    return q0, v0


def check(cm, model, q0, v0, names, params=None, bound=2e-8):
    res = cm.simulate(T, q0=q0, v0=v0, sensitivities=names, params=params, **TOL)
    assert res.sensitivity_names == list(names)
    h = 1e-5
    for j, name in enumerate(names):
        runs = []
        for sign in (1, -1):
            if name in cm.param_names:
                p = dict(params or {})
                p[name] = p.get(name, {s.name: val for s, val in model.params.items()}[name]) + sign * h
                r = cm.simulate(T, q0=q0, v0=v0, params=p, **TOL)
            else:
                q, v = perturbed(model, q0, v0, name, sign * h)
                r = cm.simulate(T, q0=q, v0=v, params=params, **TOL)
            runs.append(np.column_stack([r.y] + [r[o] for o in cm.output_names]))
        fd = (runs[0] - runs[1]) / (2 * h)
        s = res.sensitivities[:, j, :]  # the states' and the outputs'
        assert s.shape == fd.shape
        assert np.abs(s - fd).max() < bound * max(1.0, np.abs(fd).max()), (name, np.abs(s - fd).max())
    return res


def test_polar_model_of_its_own_speeds():
    model = polar()
    cm = lcg.compile_model(model, runtime_parameters=["k", "m"], outputs=["energy", "p_x"])
    check(cm, model, [1.2, 0.3], [0.1, 0.9], ["k", "m", "r(0)", "theta(0)", "u1(0)", "u2(0)"])


def test_free_flyer_parameters_speeds_and_rotations():
    model = free_flyer_with_spring()
    cm = lcg.compile_model(model, runtime_parameters=["k"])
    q = np.array([0.5, -0.2, 0.1, 0.1, 0.2, 0.3, 0.9, 0.4])
    q[3:7] /= np.linalg.norm(q[3:7])
    v = [0.3, -0.2, 0.5, 0.4, -0.3, 0.8, 1.0]
    check(cm, model, q, v, ["k", "root_x(0)", "elbow(0)", "root_wy(0)", "elbow_dot(0)",
                            "root_rx(0)", "root_ry(0)", "root_rz(0)"])


def test_quaternion_component_directions_are_refused_by_name():
    model = free_flyer_with_spring()
    cm = lcg.compile_model(model)
    q = [0, 0, 0, 0, 0, 0, 1, 0]
    with pytest.raises(LagcodegenError, match="'root_qx\\(0\\)' perturbs one component of the unit quaternion of "
                                              "joint 'root'.*'root_rx\\(0\\)'"):
        cm.simulate(T, q0=q, v0=np.zeros(7), sensitivities=["root_qx(0)"])
    with pytest.raises(LagcodegenError, match="'nope\\(0\\)' is neither a run-time parameter"):
        cm.simulate(T, q0=q, v0=np.zeros(7), sensitivities=["nope(0)"])


def test_taylor_sensitivities_of_a_model_of_its_own_speeds():
    """The Taylor method's sensitivities (the variational jet with the kinematics' tangent) of the
    polar model (q' = k(q, u) in closed form: r' = u1, theta' = u2 / r) against CVODE's of the same
    directions; more: tests/solvers/test_taylor_general_sensitivities.py."""
    model = polar()
    cm = lcg.compile_model(model, runtime_parameters=["k", "m"], outputs=["energy"])
    names = ["k", "m", "r(0)", "theta(0)", "u1(0)", "u2(0)"]
    tight = dict(rtol=1e-12, atol=1e-12)
    ta = cm.simulate(T, q0=[1.2, 0.3], v0=[0.1, 0.9], method="taylor", sensitivities=names, **tight)
    cv = cm.simulate(T, q0=[1.2, 0.3], v0=[0.1, 0.9], sensitivities=names, **tight)
    assert ta.method == "taylor" and ta.sensitivity_names == names
    scale = np.abs(cv.sensitivities).max(axis=(0, 2))
    assert np.all(np.abs(ta.sensitivities - cv.sensitivities).max(axis=(0, 2)) < 1e-8 * scale)


def test_repeated_runs_take_each_runs_rotation():
    """simulate's repeated runs (the prepared fast path) compute a rotation's s0 at each run's
    initial state: two attitudes, each equal to its first run's sensitivities."""
    model = free_flyer_with_spring()
    cm = lcg.compile_model(model)
    v = [0.3, -0.2, 0.5, 0.4, -0.3, 0.8, 1.0]
    qa = np.r_[0.5, -0.2, 0.1, 0, 0, 0, 1, 0.4]
    qb = np.r_[0.5, -0.2, 0.1, np.sqrt(0.5), 0, 0, np.sqrt(0.5), 0.4]
    runs = [cm.simulate(T, q0=q, v0=v, sensitivities=["root_rz(0)"], **TOL).sensitivities for q in (qa, qb, qa, qb)]
    assert np.abs(runs[0] - runs[1]).max() > 1e-3
    assert np.abs(runs[2] - runs[0]).max() < 1e-12 and np.abs(runs[3] - runs[1]).max() < 1e-12
    # the start: d q / d theta = q x (0, 0, 1/2, 0) (x, y, z, w), for qb = (s, 0, 0, s)
    s = np.sqrt(0.5)
    assert np.allclose(runs[1][0, 0, 3:7], [0, -s / 2, s / 2, 0], atol=1e-15)


def test_event_time_sensitivities():
    """The sensitivity of an event's time (the base crossing x = 0, in q and, through the rate,
    the kinematics) along a parameter, a speed and a rotation, against central differences of
    the event times of whole runs."""
    model = free_flyer_with_spring()
    cm = lcg.compile_model(model, runtime_parameters=["k"])
    q = np.array([0.5, -0.2, 0.1, 0.1, 0.2, 0.3, 0.9, 0.4])
    q[3:7] /= np.linalg.norm(q[3:7])
    v = [0.3, -0.2, 0.5, 0.4, -0.3, 0.8, 1.0]
    ev = [lcg.Event("cross", "root_x", direction=-1, terminal=True)]
    t = np.linspace(0, 3, 4)
    names = ["k", "root_vx(0)", "root_rz(0)"]
    res = cm.simulate(t, q0=q, v0=v, sensitivities=names, events=ev, **TOL)
    assert len(res.events) == 1
    h = 1e-5
    for name in names:
        times = []
        for sign in (1, -1):
            if name == "k":
                r = cm.simulate(t, q0=q, v0=v, params={"k": 3.0 + sign * h}, events=ev, **TOL)
            else:
                qq, vv = perturbed(model, q, v, name, sign * h)
                r = cm.simulate(t, q0=qq, v0=vv, events=ev, **TOL)
            times.append(r.events[0].t)
        fd = (times[0] - times[1]) / (2 * h)
        assert abs(res.events[0].t_sensitivity[name] - fd) < 1e-7 * max(1.0, abs(fd)), (name, fd)
