"""URDF import (lagcodegen.urdf): robots from files agree with Pinocchio's CRBA and ABA, the
two-link arm with its closed-form mass matrix, and every bad file gives an error naming the file,
the line, the element and the attribute."""

import warnings
from pathlib import Path

import numpy as np
import pytest
import symengine as se
import sympy as sp

import lagcodegen as lcg
from lagcodegen import urdf
from lagcodegen.errors import ModelError

from helpers import MIMIC_ARM

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
#: The ways a URDF robot can be stated (urdf.FORMS) whose equations are checked here.
FORMS = ["closed", "tree"]


def numeric(model):
    """(M(q, q'), F(q, q')) of the derived equations as numpy functions of (q, v)."""
    eom = lcg.derive(model)
    n = model.n
    args = list(model.coords) + list(model.speeds) + list(model.params)
    f = se.Lambdify(args, [e for row in eom.M_se for e in row] + list(eom.F_se), cse=True, backend="lambda")
    p = [model.params[s] for s in model.params]

    def evaluate(q, v):
        out = np.array(f(np.concatenate([q, v, p])), dtype=float).ravel()
        return out[:n * n].reshape(n, n), out[n * n:]
    return evaluate


def test_lagcodegen_urdf_is_the_modelfile_module():
    import lagcodegen
    from lagcodegen.modelfile import urdf as inner
    module = lagcodegen.urdf
    assert module is inner is urdf and module.load is inner.load


# ------------------------------------------------------------------ physics
@pytest.mark.parametrize("form", FORMS)
def test_two_link_arm_mass_matrix_and_gravity_match_the_closed_form(form):
    model = urdf.load(EXAMPLES / "two_link_arm.urdf", form=form)
    assert [c.name for c in model.coords] == ["shoulder", "elbow"]
    l1, c1, m1, I1 = 1.0, 0.5, 2.0, 2.0 / 12
    c2, m2, I2 = 0.4, 1.5, 1.5 * 0.64 / 12
    g = 9.81
    evaluate = numeric(model)
    rng = np.random.default_rng(3)
    for _ in range(5):
        q = rng.uniform(-np.pi, np.pi, 2)
        M, F = evaluate(q, np.zeros(2))
        c = np.cos(q[1])
        M12 = I2 + m2 * (c2**2 + l1 * c2 * c)
        M_ref = np.array([[I1 + I2 + m1 * c1**2 + m2 * (l1**2 + c2**2 + 2 * l1 * c2 * c), M12],
                          [M12, I2 + m2 * c2**2]])
        np.testing.assert_allclose(M, M_ref, rtol=1e-13, atol=0)
        # Hanging along -z, a rotation q about +y swings the rods towards -x: the centre of mass of
        # rod 1 sits at z = -c1 cos q1, so V = -m1 g c1 cos q1 - m2 g (l1 cos q1 + c2 cos(q1 + q2)).
        s1, s12 = np.sin(q[0]), np.sin(q[0] + q[1])
        F_ref = -np.array([m1 * g * c1 * s1 + m2 * g * (l1 * s1 + c2 * s12), m2 * g * c2 * s12])
        np.testing.assert_allclose(F, F_ref, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("form", FORMS)
def test_joint_damping_is_rayleigh_dissipation(form):
    """A single link spinning about the vertical axis (gravity does no work): F = -c q' exactly
    (eq. 3.15: D = c/2 q'^2, generalized force -dD/dq')."""
    text = """<robot name="spinner"><link name="base"/>
      <joint name="spin" type="continuous"><parent link="base"/><child link="disc"/><axis xyz="0 0 1"/>
        <dynamics damping="0.7"/></joint>
      <link name="disc"><inertial><origin xyz="0.1 0 0"/><mass value="2"/>
        <inertia ixx="0.01" iyy="0.01" izz="0.02" ixy="0" ixz="0" iyz="0"/></inertial></link></robot>"""
    model = urdf.loads(text, form=form)
    M, F = numeric(model)(np.array([0.3]), np.array([1.7]))
    np.testing.assert_allclose(M, [[0.02 + 2 * 0.1**2]], rtol=1e-14)
    np.testing.assert_allclose(F, [-0.7 * 1.7], rtol=1e-14)


def test_coulomb_friction_ignored_with_a_warning_or_smoothed():
    text = """<robot name="rub"><link name="base"/>
      <joint name="spin" type="continuous"><parent link="base"/><child link="disc"/><axis xyz="0 0 1"/>
        <dynamics damping="0" friction="0.3"/></joint>
      <link name="disc"><inertial><mass value="2"/>
        <inertia ixx="0.01" iyy="0.01" izz="0.02" ixy="0" ixz="0" iyz="0"/></inertial></link></robot>"""
    with pytest.warns(UserWarning, match=r"Coulomb friction of joint\(s\) spin ignored"):
        ignored = urdf.loads(text)
    assert not ignored.generalized_forces
    smooth = urdf.loads(text, friction="smooth", friction_velocity=0.01)
    evaluate = numeric(smooth)
    for v in (-2.0, -0.01, 0.003, 0.5):
        _, F = evaluate(np.array([0.0]), np.array([v]))
        np.testing.assert_allclose(F, [-0.3 * v / np.sqrt(v**2 + 0.01**2)], rtol=1e-14)
    _, F = evaluate(np.array([0.0]), np.array([0.08]))  # 8 v_s: within 1 % of the friction force
    assert 0.99 * 0.3 < -F[0] < 0.3


def test_limits_become_inequality_constraints():
    system = urdf.load(EXAMPLES / "two_link_arm.urdf", limits=True)
    assert isinstance(system, lcg.ConstrainedSystem)
    shoulder, elbow = system.model.coords
    assert [str(g) for g in system.inequalities] == [str(e) for e in (shoulder + 3.0, 3.0 - shoulder,
                                                                        elbow + 2.5, 2.5 - elbow)]
    assert not system.holonomic and not system.nonholonomic


STOPPED_PENDULUM = """<robot name="{name}"><link name="base"/>
  <joint name="hinge" type="revolute"><parent link="base"/><child link="rod"/><axis xyz="0 -1 0"/>
    <limit lower="-0.5" upper="0.5" effort="1" velocity="10"/></joint>
  <link name="rod"><inertial><origin xyz="0 0 -1"/><mass value="1"/>
    <inertia ixx="0" iyy="0" izz="0" ixy="0" ixz="0" iyz="0"/></inertial></link></robot>"""


@pytest.mark.parametrize("e", [0.0, 0.5])
def test_limits_are_hard_stops(e):
    """A point-mass pendulum (l = 1, m = 1) with stops at +-0.5 rad, thrown at the upper one: it
    reaches it with the speed energy conservation gives (w^2 = w0^2 + 2 g (cos 0.5 - cos q0)),
    rebounds with e times it (Newton's law), never passes the stop, and the run goes on to its end;
    with e = 0 it stops there, and the stop releases it at once: gravity pulls it back."""
    from lagcodegen.api import compile_constrained
    system = urdf.loads(STOPPED_PENDULUM.format(name=f"stopped_{int(10 * e)}"), limits=True if e == 0 else ("stop", e))
    assert system.restitution == [e, e]
    sim = compile_constrained(system, "index1")
    q0, w0, g = 0.4, 2.0, 9.81
    t = np.linspace(0.0, 2.0, 201)
    res = sim.simulate(t, q0=[q0], v0=[w0], rtol=1e-10, atol=1e-12)
    assert res.success and res.t[-1] == t[-1]
    assert np.all(np.abs(res["hinge"]) <= 0.5 + 1e-8)
    first = res.impacts.select("stick" if e == 0 else "bounce")[0]
    speed = np.sqrt(w0**2 + 2 * g * (np.cos(0.5) - np.cos(q0)))
    assert first.contact == 1 and first.w_before == pytest.approx(-speed, rel=1e-8)
    assert first.w_after == pytest.approx(e * speed, abs=1e-8)
    if e == 0:  # at the stop the pendulum is pushed back by gravity: the stop releases at once
        assert any(r.kind == "release" and r.contact == 1 for r in res.impacts)
    with pytest.raises(urdf.URDFError, match="limits must be"):
        urdf.loads(STOPPED_PENDULUM.format(name="bad"), limits=("stop", 2.0))
    monitored = urdf.loads(STOPPED_PENDULUM.format(name="monitored"), limits="monitor")
    assert monitored.restitution == [None, None]


def test_gravity_option_direction_and_parameter():
    model = urdf.load(EXAMPLES / "two_link_arm.urdf", gravity=(0, 0, -1.62))
    assert {s.name: v for s, v in model.params.items()} == {"g": pytest.approx(1.62)}
    _, F = numeric(model)(np.array([0.5, 0.0]), np.zeros(2))
    assert F[0] == pytest.approx(-(2.0 * 1.62 * 0.5 + 1.5 * 1.62 * 1.4) * np.sin(0.5), rel=1e-13)
    sideways = urdf.load(EXAMPLES / "two_link_arm.urdf", gravity=(9.81, 0, 0))
    _, F = numeric(sideways)(np.zeros(2), np.zeros(2))  # pulled along +x: the arm swings to +x
    assert F[0] == pytest.approx(-(2.0 * 9.81 * 0.5 + 1.5 * 9.81 * 1.4), rel=1e-13)
    weightless = urdf.load(EXAMPLES / "two_link_arm.urdf", gravity=(0, 0, 0))
    assert not weightless.params and weightless.gravity_spec is None


# ------------------------------------------------------------------ against Pinocchio
pin = pytest.importorskip("pinocchio")
#: example-robot-data's URDFs, installed next to Pinocchio under the cmeel prefix.
ROBOTS = Path(pin.__file__).resolve().parents[4] / "share" / "example-robot-data" / "robots"


def compare_with_pinocchio(path, model, pin_model, states=6, seed=0):
    """The largest relative error of M (CRBA), q'' (ABA, joint damping as the torque -c q') and
    the inverse dynamics M a - F (RNEA) at random states, relative to the infinity norm of
    Pinocchio's."""
    robot = urdf.read(path)
    data = pin_model.createData()
    evaluate = numeric(model)
    n = model.n
    joints = [pin_model.joints[pin_model.getJointId(c.name)] for c in model.coords]
    assert pin_model.nv == n and all(j.nv == 1 for j in joints)
    perm = [j.idx_v for j in joints]
    damping = np.array([getattr(robot.joints[c.name].dynamics, "damping", 0.0) for c in model.coords])
    rng = np.random.default_rng(seed)
    worst = 0.0
    for _ in range(states):
        q, v = rng.uniform(-np.pi, np.pi, n), rng.normal(size=n)
        qp, vp, tau = pin.neutral(pin_model), np.zeros(n), np.zeros(n)
        for i, j in enumerate(joints):
            if j.nq == 2:  # continuous: (cos, sin)
                qp[j.idx_q:j.idx_q + 2] = np.cos(q[i]), np.sin(q[i])
            else:
                qp[j.idx_q] = q[i]
            vp[j.idx_v], tau[j.idx_v] = v[i], -damping[i] * v[i]
        M, F = evaluate(q, v)
        M_pin = pin.crba(pin_model, data, qp)
        M_pin = np.triu(M_pin) + np.triu(M_pin, 1).T
        a_pin = pin.aba(pin_model, data, qp, vp, tau)
        # inverse dynamics: M a - F = RNEA(q, q', a) + c q' (F holds the damping force -c q')
        a = rng.normal(size=n)
        ap = np.zeros(n)
        ap[perm] = a
        id_pin = pin.rnea(pin_model, data, qp, vp, ap)[perm] - tau[perm]
        worst = max(worst, np.abs(M - M_pin[np.ix_(perm, perm)]).max() / np.abs(M_pin).max(),
                    np.abs(np.linalg.solve(M, F) - a_pin[perm]).max() / np.abs(a_pin).max(),
                    np.abs(M @ a - F - id_pin).max() / np.abs(id_pin).max())
    return worst


@pytest.mark.parametrize("form", FORMS)
@pytest.mark.parametrize("path", ["examples/ur_like_arm.urdf", "examples/two_link_arm.urdf",
                                  "ur_description/urdf/ur5_robot.urdf",
                                  "double_pendulum_description/urdf/double_pendulum_continuous.urdf"])
def test_arms_agree_with_pinocchio(path, form):
    file = EXAMPLES.parent / path if path.startswith("examples/") else ROBOTS / path
    model = urdf.load(file, form=form)
    assert compare_with_pinocchio(file, model, pin.buildModelFromUrdf(str(file))) < 1e-12


def test_panda_agrees_with_pinocchio():
    """The Franka Panda (7 arm joints, 2 finger joints read as independent coordinates as
    Pinocchio does), as a tree (the closed form takes minutes to evaluate numerically)."""
    file = ROBOTS / "panda_description" / "urdf" / "panda.urdf"
    model = urdf.load(file, mimic="independent")
    assert compare_with_pinocchio(file, model, pin.buildModelFromUrdf(str(file))) < 1e-12


@pytest.mark.parametrize("robot_path, form", [("solo_description/robots/solo12.urdf", "closed"),
                                              ("solo_description/robots/solo12.urdf", "tree"),
                                              ("anymal_b_simple_description/robots/anymal.urdf", "tree")])
def test_branched_quadruped_agrees_with_pinocchio(robot_path, form):
    """solo12 and ANYmal: four legs of three joints on a fixed trunk (a tree, not a chain)."""
    file = ROBOTS / robot_path
    model = urdf.load(file, form=form)
    assert model.n == 12
    parents = {lk.parent.name if lk.parent else None for lk in model.links} if model.links else None
    if parents is not None:
        assert None in parents and len([lk for lk in model.links if lk.parent is None]) == 4
    assert compare_with_pinocchio(file, model, pin.buildModelFromUrdf(str(file)), states=3) < 1e-12


TREES = ["panda_description/urdf/panda.urdf", "ur_description/urdf/ur5_robot.urdf",
         "solo_description/robots/solo12.urdf", "anymal_b_simple_description/robots/anymal.urdf",
         "examples/ur_like_arm.urdf"]


@pytest.mark.parametrize("path", TREES)
def test_tree_links_are_pinocchios_joints_placements_and_inertias(path):
    """form="tree": each link's joint placement in its parent, its mass, centre of mass and
    inertia (fixed links merged) are Pinocchio's jointPlacements and inertias, and the links'
    world poses at random q are Pinocchio's forward kinematics (oMi)."""
    file = EXAMPLES.parent / path if path.startswith("examples/") else ROBOTS / path
    model = urdf.load(file, form="tree", mimic="independent")
    pin_model = pin.buildModelFromUrdf(str(file))
    assert len(model.links) == model.n == pin_model.njoints - 1
    worst = 0.0
    for link in model.links:
        jid = pin_model.getJointId(link.joint.name)
        parent = pin_model.parents[jid]
        assert (link.parent is None) == (parent == 0)
        if link.parent is not None:
            assert link.parent.joint.name == pin_model.names[parent]
        placement, inertia = pin_model.jointPlacements[jid], pin_model.inertias[jid]
        ours = [np.array(link.origin.rotation.tolist(), dtype=float),
                np.array(link.origin.translation, dtype=float).ravel(),
                float(link.mass), np.array(link.com, dtype=float), np.array(link.inertia.tolist(), dtype=float)]
        theirs = [placement.rotation, placement.translation, inertia.mass, inertia.lever, inertia.inertia]
        worst = max(worst, *(np.abs(a - b).max() / max(np.abs(b).max(), 1.0) for a, b in zip(ours, theirs)))
    assert worst < 1e-14
    data = pin_model.createData()
    rng = np.random.default_rng(5)
    poses = sp.lambdify(model.coords, [sp.Matrix.hstack(*link.pose()) for link in model.links])
    for _ in range(3):
        q = rng.uniform(-np.pi, np.pi, model.n)
        qp = pin.neutral(pin_model)
        for c, qi in zip(model.coords, q):
            j = pin_model.joints[pin_model.getJointId(c.name)]
            qp[j.idx_q:j.idx_q + j.nq] = (np.cos(qi), np.sin(qi)) if j.nq == 2 else qi
        pin.forwardKinematics(pin_model, data, qp)
        for link, pose in zip(model.links, poses(*q)):
            oMi = data.oMi[pin_model.getJointId(link.joint.name)]
            np.testing.assert_allclose(np.array(pose, dtype=float), np.hstack([oMi.rotation, oMi.translation[:, None]]),
                                       atol=1e-13)


def _euler_maps():
    """For the free joint's R = Rz(yaw) Ry(pitch) Rx(roll): R, E (omega_body = E (yaw', pitch',
    roll')) and their time derivatives, as numpy functions of (angles, angle rates)."""
    a, ad = sp.symbols("yaw pitch roll"), sp.symbols("yaw_d pitch_d roll_d")
    yaw, pitch, roll = a
    E = sp.Matrix([[-sp.sin(pitch), 0, 1],
                   [sp.sin(roll) * sp.cos(pitch), sp.cos(roll), 0],
                   [sp.cos(roll) * sp.cos(pitch), -sp.sin(roll), 0]])
    R = sp.rot_axis3(-yaw) * sp.rot_axis2(-pitch) * sp.rot_axis1(-roll)  # sympy's rot_axis rotate frames
    dot = lambda X: sum((X.diff(x) * xd for x, xd in zip(a, ad)), sp.zeros(3, 3))  # noqa: E731
    return [sp.lambdify([*a, *ad], X) for X in (R, E, dot(R), dot(E))]


@pytest.mark.parametrize("path, form", [("double_pendulum_description/urdf/double_pendulum.urdf", "closed"),
                                        ("double_pendulum_description/urdf/double_pendulum.urdf", "tree"),
                                        ("examples/ur_like_arm.urdf", "tree"),
                                        ("solo_description/robots/solo12.urdf", "tree")])
def test_floating_base_agrees_with_pinocchio_free_flyer(path, form):
    """floating=True, rotation="ZYX": the root on a free joint (x, y, z, Z-Y-X Euler angles) against Pinocchio's
    free flyer (position, quaternion; velocity (R^T p', omega) in the body frame): with
    v = J(q) q', M = J^T M_pin J and q'' = J^-1 (a_pin - J' q')."""
    file = EXAMPLES.parent / path if path.startswith("examples/") else ROBOTS / path
    model = urdf.load(file, form=form, floating=True, rotation="ZYX")
    names = [c.name for c in model.coords]
    assert names[:6] == ["root_joint_x", "root_joint_y", "root_joint_z", "root_joint_yaw", "root_joint_pitch",
                         "root_joint_roll"]
    robot_description = urdf.read(file)
    pin_model = pin.buildModelFromUrdf(str(file), pin.JointModelFreeFlyer())
    data = pin_model.createData()
    evaluate = numeric(model)
    R_f, E_f, Rd_f, Ed_f = _euler_maps()
    n = model.n
    legs = [pin_model.joints[pin_model.getJointId(c)] for c in names[6:]]
    damping = np.array([getattr(robot_description.joints[c].dynamics, "damping", 0.0) for c in names[6:]])
    P = np.zeros((n, n))  # our order -> Pinocchio's
    P[list(range(6)) + [j.idx_v for j in legs], range(n)] = 1
    rng = np.random.default_rng(2)
    for _ in range(4):
        q, v = rng.uniform(-1.2, 1.2, n), rng.normal(size=n)
        angles = (*q[3:6], *v[3:6])
        R = np.array(R_f(*angles), dtype=float)
        J, Jd = np.eye(n), np.zeros((n, n))
        J[:3, :3], J[3:6, 3:6] = R.T, np.array(E_f(*angles), dtype=float)
        Jd[:3, :3], Jd[3:6, 3:6] = np.array(Rd_f(*angles), dtype=float).T, np.array(Ed_f(*angles), dtype=float)
        J, Jd = P @ J, P @ Jd
        qp = pin.neutral(pin_model)
        quaternion = pin.Quaternion(R)
        qp[:7] = [*q[:3], quaternion.x, quaternion.y, quaternion.z, quaternion.w]
        tau = np.zeros(n)
        for i, j in enumerate(legs):
            qp[j.idx_q:j.idx_q + j.nq] = (np.cos(q[6 + i]), np.sin(q[6 + i])) if j.nq == 2 else q[6 + i]
            tau[j.idx_v] = -damping[i] * v[6 + i]
        M, F = evaluate(q, v)
        M_pin = pin.crba(pin_model, data, qp)
        M_pin = np.triu(M_pin) + np.triu(M_pin, 1).T
        M_ref = J.T @ M_pin @ J
        a_pin = pin.aba(pin_model, data, qp, J @ v, tau)
        qdd_ref = np.linalg.solve(J, a_pin - Jd @ v)
        assert np.abs(M - M_ref).max() < 1e-12 * np.abs(M_ref).max()
        assert np.abs(np.linalg.solve(M, F) - qdd_ref).max() < 1e-11 * np.abs(qdd_ref).max()


PLANAR_ROBOT = """<robot name="sled"><link name="ground"/>
  <joint name="base" type="planar"><parent link="ground"/><child link="body"/><axis xyz="0 0 1"/></joint>
  <link name="body"><inertial><origin xyz="0.2 -0.1 0"/><mass value="3"/>
    <inertia ixx="0.2" iyy="0.3" izz="0.4" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="arm" type="continuous"><parent link="body"/><child link="rod"/><origin xyz="0.5 0 0.1"/>
    <axis xyz="0 0 1"/><dynamics damping="0.3"/></joint>
  <link name="rod"><inertial><origin xyz="0.4 0 0"/><mass value="1.5"/>
    <inertia ixx="0.01" iyy="0.05" izz="0.06" ixy="0" ixz="0" iyz="0"/></inertial></link></robot>"""


@pytest.mark.parametrize("form", FORMS)
def test_planar_joint_agrees_with_pinocchio(form):
    """A planar base (x, y, theta about z) carrying a damped arm, gravity in the plane, against
    Pinocchio's planar joint (q: x, y, cos, sin; v: (R^T (x', y'), theta') in the body frame):
    with v = J q', M = J^T M_pin J and q'' = J^-1 (a_pin - J' q')."""
    model = urdf.loads(PLANAR_ROBOT, gravity=(0.0, -9.81, 0.0), form=form)
    assert [c.name for c in model.coords] == ["base_x", "base_y", "base_theta", "arm"]
    pin_model = pin.buildModelFromXML(PLANAR_ROBOT)
    pin_model.gravity.linear = np.array([0.0, -9.81, 0.0])
    data = pin_model.createData()
    evaluate = numeric(model)
    rng = np.random.default_rng(5)
    for _ in range(4):
        q, v = rng.uniform(-2, 2, 4), rng.normal(size=4)
        c, s_ = np.cos(q[2]), np.sin(q[2])
        Rt = np.array([[c, s_], [-s_, c]])  # R(theta)^T
        dRt = v[2] * np.array([[-s_, c], [-c, -s_]])
        J, Jd = np.eye(4), np.zeros((4, 4))
        J[:2, :2], Jd[:2, :2] = Rt, dRt
        qp = np.array([q[0], q[1], c, s_, np.cos(q[3]), np.sin(q[3])])
        M, F = evaluate(q, v)
        M_pin = pin.crba(pin_model, data, qp)
        M_pin = np.triu(M_pin) + np.triu(M_pin, 1).T
        np.testing.assert_allclose(M, J.T @ M_pin @ J, rtol=0, atol=1e-12 * np.abs(M_pin).max())
        a_pin = pin.aba(pin_model, data, qp, J @ v, np.array([0, 0, 0, -0.3 * v[3]]))
        qdd_ref = np.linalg.solve(J, a_pin - Jd @ v)
        np.testing.assert_allclose(np.linalg.solve(M, F), qdd_ref, rtol=0, atol=1e-11 * np.abs(qdd_ref).max())


def test_mimic_joints_coupled_agree_with_pinocchio_mimic():
    """mimic="coupled": the mimic joint held by q2 = 0.5 q1 + 0.1 (a holonomic constraint); in
    minimal coordinates its run agrees with Pinocchio's mimic model (buildModel..(mimic=True):
    q1'' = -M^-1 nle from crba and rnea) integrated by scipy at tight tolerances."""
    from scipy.integrate import solve_ivp
    from lagcodegen.api import compile_constrained
    system = urdf.loads(MIMIC_ARM, mimic="coupled")
    assert isinstance(system, lcg.ConstrainedSystem) and len(system.holonomic) == 1
    j1, j2 = system.model.coords
    assert sp.simplify(system.holonomic[0] - (j2 - 0.5 * j1 - 0.1)) == 0
    pin_model = pin.buildModelFromXML(MIMIC_ARM, mimic=True)
    data = pin_model.createData()
    assert pin_model.nv == 1

    def rhs(_t, x):
        q, v = x[:1], x[1:]
        M = pin.crba(pin_model, data, q)
        return [v[0], -np.linalg.solve(M, pin.rnea(pin_model, data, q, v, np.zeros(1)))[0]]

    t = np.linspace(0.0, 2.0, 21)
    ref = solve_ivp(rhs, (0, 2), [0.7, -0.4], t_eval=t, rtol=1e-12, atol=1e-12, method="DOP853")
    sim = compile_constrained(system, "minimal")
    res = sim.simulate(t, q0=[0.7, 0.5 * 0.7 + 0.1], v0=[-0.4, -0.2], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(res["j1"], ref.y[0], rtol=0, atol=1e-8)
    np.testing.assert_allclose(res["j2"], 0.5 * ref.y[0] + 0.1, rtol=0, atol=1e-8)
    assert not isinstance(urdf.loads(MIMIC_ARM, mimic="independent"), lcg.ConstrainedSystem)


@pytest.mark.parametrize("form", FORMS)
def test_mimic_joints_are_driven_by_default_as_pinocchio_reads_them(form):
    """By default a <mimic> joint has no coordinate: its angle is multiplier q_leader + offset
    (Pinocchio's buildModel(..., mimic=True) layout); q'' = -M^-1 nle from Pinocchio's crba and
    rnea to 1e-12 at random states."""
    model = urdf.loads(MIMIC_ARM, form=form)
    assert [c.name for c in model.coords] == ["j1"] and not isinstance(model, lcg.ConstrainedSystem)
    pin_model = pin.buildModelFromXML(MIMIC_ARM, mimic=True)
    data = pin_model.createData()
    cm = lcg.compile_model(model)
    rng = np.random.default_rng(11)
    for _ in range(4):
        q, v = rng.uniform(-1, 1, 1), rng.normal(size=1)
        M = pin.crba(pin_model, data, q)
        a = -np.linalg.solve(M, pin.rnea(pin_model, data, q, v, np.zeros(1)))
        assert np.abs(cm.rhs(0.0, np.r_[q, v])[1:] - a).max() <= 1e-12 * max(1.0, np.abs(a).max())


def test_panda_with_its_gripper_by_default_agrees_with_pinocchio_mimic():
    """The Panda loads with its fingers by default: finger 2 driven by finger 1 (nq = 8, as
    Pinocchio's mimic model); q'' against Pinocchio's crba and rnea with the URDF's damping as
    torques (the driven finger's damping c_2 g^2 on finger 1's rate), to 1e-12."""
    file = ROBOTS / "panda_description" / "urdf" / "panda.urdf"
    model = urdf.load(file)
    assert [c.name for c in model.coords] == [f"panda_joint{i}" for i in range(1, 8)] + ["panda_finger_joint1"]
    pin_model = pin.buildModelFromUrdf(str(file), mimic=True)
    data = pin_model.createData()
    assert pin_model.nq == pin_model.nv == 8
    joints = urdf.read(file).joints
    damping = np.array([joints[f"panda_joint{i}"].dynamics.damping if joints[f"panda_joint{i}"].dynamics else 0.0
                        for i in range(1, 8)] + [0.0])
    for name, g in (("panda_finger_joint1", 1.0), ("panda_finger_joint2", joints["panda_finger_joint2"].mimic.multiplier)):
        dyn = joints[name].dynamics
        damping[7] += (dyn.damping if dyn else 0.0) * g * g
    cm = lcg.compile_model(model)
    rng = np.random.default_rng(12)
    for _ in range(4):
        q = np.r_[rng.uniform(-1, 1, 7), rng.uniform(0, 0.04)]
        v = rng.normal(size=8)
        M = pin.crba(pin_model, data, q)
        M = np.triu(M) + np.triu(M, 1).T
        a = np.linalg.solve(M, -damping * v - pin.rnea(pin_model, data, q, v, np.zeros(8)))
        assert np.abs(cm.rhs(0.0, np.r_[q, v])[8:] - a).max() <= 1e-12 * np.abs(a).max()


def test_locked_joints_agree_with_pinocchio_reduced_model():
    """UR5 with the elbow locked at 0.4 rad: Pinocchio's buildReducedModel at the same position."""
    file = ROBOTS / "ur_description" / "urdf" / "ur5_robot.urdf"
    model = urdf.load(file, lock={"elbow_joint": 0.4})
    assert "elbow_joint" not in [c.name for c in model.coords] and model.n == 5
    full = pin.buildModelFromUrdf(str(file))
    q_ref = pin.neutral(full)
    q_ref[full.joints[full.getJointId("elbow_joint")].idx_q] = 0.4
    reduced = pin.buildReducedModel(full, [full.getJointId("elbow_joint")], q_ref)
    assert compare_with_pinocchio(file, model, reduced, states=4) < 1e-12


def test_panda_loads_with_its_mimic_finger_refused_or_independent():
    file = ROBOTS / "panda_description" / "urdf" / "panda.urdf"
    with pytest.raises(ModelError, match=r"panda\.urdf:\d+: joint 'panda_finger_joint2': mimic joints are not "
                                         r"supported.*follows 'panda_finger_joint1'"):
        urdf.load(file, mimic="error")
    model = urdf.load(file, mimic="independent")
    assert [c.name for c in model.coords] == [f"panda_joint{i}" for i in range(1, 8)] + [
        "panda_finger_joint1", "panda_finger_joint2"]
    arm = urdf.load(file, lock=["panda_finger_joint1", "panda_finger_joint2"])
    assert arm.n == 7


# ------------------------------------------------------------------ errors
def robot(body: str, name="r") -> str:
    return f'<?xml version="1.0"?>\n<robot name="{name}">\n{body}\n</robot>\n'


INERTIAL = '<inertial><mass value="1"/><inertia ixx="1" iyy="1" izz="1" ixy="0" ixz="0" iyz="0"/></inertial>'
ARM = (f'<link name="a"/>\n<joint name="j" type="revolute"><parent link="a"/><child link="b"/></joint>\n'
       f'<link name="b">{INERTIAL}</link>')

ERRORS = {
    "not xml": ("<robot><link></robot>", r"bad\.urdf:1: not well-formed XML: mismatched tag"),
    "root element": ("<model/>", r"bad\.urdf:1: <model>: the root element is not <robot>"),
    "no links": (robot(""), r"robot 'r': no <link> elements"),
    "bad number": (robot(ARM.replace('<child link="b"/>', '<child link="b"/><origin xyz="0 0 0.1m"/>')),
                   r"bad\.urdf:4: joint 'j' <origin>: attribute xyz='0 0 0\.1m': '0\.1m' is not a number"),
    "not finite": (robot(ARM.replace('value="1"', 'value="nan"')),
                   r"bad\.urdf:5: link 'b' <inertial> <mass>: attribute value='nan' is not finite"),
    "short vector": (robot(ARM.replace('<child link="b"/>', '<child link="b"/><axis xyz="0 1"/>')),
                     r"bad\.urdf:4: joint 'j' <axis>: attribute xyz='0 1' needs 3 numbers, has 2"),
    "zero axis": (robot(ARM.replace('<child link="b"/>', '<child link="b"/><axis xyz="0 0 0"/>')),
                  r"bad\.urdf:4: joint 'j' <axis>: axis xyz='0 0 0' is zero"),
    "missing mass": (robot(ARM.replace('<mass value="1"/>', '')),
                     r"bad\.urdf:5: link 'b' <inertial>: missing <mass> element"),
    "missing inertia entry": (robot(ARM.replace(' iyz="0"', '')),
                              r"bad\.urdf:5: link 'b' <inertial> <inertia>: missing attribute 'iyz'"),
    "negative mass": (robot(ARM.replace('value="1"', 'value="-1"')),
                      r"link 'b' <inertial> <mass>: negative mass value=-1\.0"),
    "inertia not positive definite": (
        robot(ARM.replace('ixy="0"', 'ixy="2"')),
        r"bad\.urdf:5: link 'b' <inertial> <inertia>: inertia \(ixx=1\.0, ixy=2\.0.*\) is not positive definite: "
        r"it has the negative eigenvalue -1"),
    "missing joint type": (robot(ARM.replace(' type="revolute"', '')),
                           r"bad\.urdf:4: joint 'j': missing attribute 'type'"),
    "unknown joint type": (robot(ARM.replace('type="revolute"', 'type="hinge"')),
                           r"bad\.urdf:4: joint 'j': unknown joint type 'hinge' \(URDF types: revolute, continuous"),
    "missing parent link": (robot(ARM.replace('<parent link="a"/>', '<parent link="base"/>')),
                            r"bad\.urdf:4: joint 'j' <parent>: parent link 'base' is not a <link> of the robot"),
    "missing parent element": (robot(ARM.replace('<parent link="a"/>', '')),
                               r"bad\.urdf:4: joint 'j': missing <parent> element"),
    "several roots": (robot(ARM + '\n<link name="c"/>'),
                      r"robot 'r': several root links \(links that are no joint's child\): 'a', 'c'"),
    "cycle": (robot(ARM + '\n<link name="c"/><joint name="k" type="fixed"><parent link="b"/><child link="c"/></joint>'
                    '\n<joint name="back" type="fixed"><parent link="c"/><child link="a"/></joint>'),
              r"the joints form a cycle through links 'a' -> 'b' -> 'c' -> 'a'|cycle"),
    "two parents": (robot(ARM + '\n<link name="c"/><joint name="k" type="fixed"><parent link="c"/><child link="b"/>'
                          '</joint>'),
                    r"bad\.urdf:6: joint 'k' <child>: link 'b' is already the child of joint 'j'"),
    "duplicate link": (robot(ARM + '\n<link name="b"/>'), r"bad\.urdf:6: link 'b': link name 'b' is used twice"),
    "limits reversed": (robot(ARM.replace('<child link="b"/>', '<child link="b"/><limit lower="1" upper="-1"/>')),
                        r"bad\.urdf:4: joint 'j' <limit>: lower=1\.0 is above upper=-1\.0"),
    "mimic of nothing": (robot(ARM.replace('<child link="b"/>', '<child link="b"/><mimic joint="x"/>')),
                         r"joint 'j' <mimic>: mimics joint 'x', which does not exist"),
    "nothing moves": (robot(ARM.replace('type="revolute"', 'type="fixed"')),
                      r"robot 'r': the robot has no movable joint"),
}


@pytest.mark.parametrize("case", sorted(ERRORS))
def test_bad_files_name_file_line_element_and_attribute(case, tmp_path):
    text, message = ERRORS[case]
    path = tmp_path / "bad.urdf"
    path.write_text(text)
    with pytest.raises(urdf.URDFError, match=message) as info:
        urdf.load(path)
    assert isinstance(info.value, ModelError) and info.value.filename == str(path)


def test_a_cycle_is_reported_as_a_cycle(tmp_path):
    text = robot('<link name="root"/><link name="a"/><link name="b"/>'
                 '<joint name="ja" type="fixed"><parent link="b"/><child link="a"/></joint>'
                 '<joint name="jb" type="fixed"><parent link="a"/><child link="b"/></joint>')
    with pytest.raises(urdf.URDFError, match=r"joint '(ja|jb)': the joints form a cycle through links"):
        urdf.loads(text, filename="loop.urdf")


def deep_chain(n: int) -> str:
    """A chain of ``n`` revolute joints l0 -> l1 -> ... -> ln."""
    body = ['<link name="l0"/>']
    for i in range(1, n + 1):
        body.append(f'<joint name="j{i}" type="revolute"><parent link="l{i - 1}"/><child link="l{i}"/>'
                    f'<origin xyz="0 0 -0.1"/><axis xyz="0 1 0"/></joint><link name="l{i}">{INERTIAL}</link>')
    return robot("\n".join(body))


def test_a_chain_deeper_than_the_recursion_limit_is_read_and_walked():
    """1200 links (3000 took 128 s to parse, the cycle check scanning each link's path to the root
    once per link; the bodies' walk recursed once per link): parsed, the joints depth first, one
    body per joint in chain order."""
    import sys
    n = 1200
    assert n > sys.getrecursionlimit()
    description = urdf.parse(deep_chain(n), filename="deep.urdf")
    assert description.order == tuple(f"j{i}" for i in range(1, n + 1))
    assert [j.name for j in description.children("l7")] == ["j8"] and description.children(f"l{n}") == []
    bodies = urdf.bodies(description)
    assert [b.joint.name for b in bodies] == list(description.order)
    assert bodies[-1].parent == f"l{n - 1}"


def test_a_cycle_hanging_off_a_deep_chain_names_the_cycle():
    """Links in a cycle below the root's chain (a separate loop of three links): the one walk
    per link finds it and names it as before."""
    loop = ('<link name="x"/><link name="y"/><link name="z"/>'
            '<joint name="jx" type="fixed"><parent link="z"/><child link="x"/></joint>'
            '<joint name="jy" type="fixed"><parent link="x"/><child link="y"/></joint>'
            '<joint name="jz" type="fixed"><parent link="y"/><child link="z"/></joint>')
    text = deep_chain(300).replace("</robot>", loop + "</robot>")
    with pytest.raises(urdf.URDFError, match=r"loop\.urdf: joint 'jy': the joints form a cycle through links "
                                             r"'x' -> 'y' -> 'z' -> 'x'"):
        urdf.loads(text, filename="loop.urdf")


def test_a_urdf_that_is_not_a_regular_file_is_refused_without_blocking(tmp_path):
    """A FIFO named robot.urdf blocked urdf.load (and compile_urdf) forever in open(); it is
    opened without blocking and refused, naming the file; a folder too."""
    import os
    fifo = tmp_path / "robot.urdf"
    os.mkfifo(fifo)
    with pytest.raises(urdf.URDFError, match=r"robot\.urdf: cannot read the file: it is a FIFO, not a regular file"):
        urdf.load(fifo)
    with pytest.raises(urdf.URDFError, match=r"robot\.urdf: cannot read the file: it is a FIFO"):
        lcg.compile_urdf(fifo)
    with pytest.raises(urdf.URDFError, match="it is a folder, not a regular file"):
        urdf.load(tmp_path)


def test_a_urdf_above_the_size_cap_is_refused_before_it_is_read(tmp_path):
    """A URDF file above max_bytes (default urdf MAX_BYTES, 20 MiB: a 50 MB file took 12.5 s and
    846 MB) is a URDFError naming the file and the cap; max_bytes=None lifts it; text too."""
    from lagcodegen.modelfile import urdfxml
    assert urdfxml.MAX_BYTES == 20 * 2**20
    path = tmp_path / "padded.urdf"
    text = robot(ARM + "<!-- " + "x" * 5000 + " -->")
    path.write_text(text)
    with pytest.raises(urdf.URDFError, match=r"padded\.urdf: the URDF is \d+ bytes, above the size cap of 4096 "
                                             r"bytes .*max_bytes="):
        urdf.load(path, max_bytes=4096)
    with pytest.raises(urdf.URDFError, match=r"text\.urdf: the URDF is \d+ bytes, above the size cap of 4096"):
        urdf.loads(text, filename="text.urdf", max_bytes=4096)
    assert urdf.load(path, max_bytes=None).n == 1
    assert urdf.load(path).n == 1  # under the default cap
    with pytest.raises(urdf.URDFError, match="max_bytes must be a positive integer or None, got -1"):
        urdf.load(path, max_bytes=-1)


def test_missing_file_and_bad_options():
    with pytest.raises(urdf.URDFError, match=r"nowhere\.urdf: cannot read the file"):
        urdf.load("nowhere.urdf")
    arm = EXAMPLES / "two_link_arm.urdf"
    with pytest.raises(urdf.URDFError, match="friction must be one of ignore, smooth"):
        urdf.load(arm, friction="stick")
    with pytest.raises(urdf.URDFError, match="mimic must be one of driven, error, independent"):
        urdf.load(arm, mimic="copy")
    with pytest.raises(urdf.URDFError, match="lock: no joint named 'wrist'"):
        urdf.load(arm, lock=["wrist"])
    with pytest.raises(urdf.URDFError, match="gravity must be 3 finite numbers"):
        urdf.load(arm, gravity=(0, -9.81))


def test_dummy_links_and_point_masses_are_accepted():
    """Massless links with zero inertia (URDF's "dummy" links) and point masses (zero inertia)
    are not errors; rounding-level negative eigenvalues of written-out inertias neither."""
    text = robot('<link name="a"/><joint name="j" type="revolute"><parent link="a"/><child link="b"/>'
                 '<axis xyz="0 0 1"/></joint>'
                 '<link name="b"><inertial><origin xyz="0.2 0 0"/><mass value="1"/>'
                 '<inertia ixx="0" iyy="0" izz="0" ixy="0" ixz="0" iyz="0"/></inertial></link>'
                 '<joint name="k" type="fixed"><parent link="b"/><child link="c"/></joint>'
                 '<link name="c"><inertial><mass value="0"/><inertia ixx="1e-6" iyy="1e-6" izz="1e-6" ixy="1e-6" '
                 'ixz="1e-6" iyz="1e-6"/></inertial></link>')
    model = urdf.loads(text)
    M, _ = numeric(model)(np.zeros(1), np.zeros(1))
    # the massless link's inertia adds izz = 1e-6 (no parallel-axis term without mass)
    np.testing.assert_allclose(M, [[1 * 0.2**2 + 1e-6]], rtol=1e-14)


def test_compiled_panda_right_side_agrees_with_pinocchio_aba():
    """The Panda arm (fingers locked) compiled to C: its right side q'' at random states is
    Pinocchio's ABA on the reduced model (joint damping 0.003 as the torque -c q')."""
    file = ROBOTS / "panda_description" / "urdf" / "panda.urdf"
    fingers = ["panda_finger_joint1", "panda_finger_joint2"]
    sim = lcg.compile_model(urdf.load(file, lock=fingers), jacobian=False)
    assert sim.n == 7
    full = pin.buildModelFromUrdf(str(file))
    reduced = pin.buildReducedModel(full, [full.getJointId(name) for name in fingers], pin.neutral(full))
    assert list(reduced.names)[1:] == [c for c in sim.state_names[:7]]
    data = reduced.createData()
    damping = np.array([urdf.read(file).joints[name].dynamics.damping for name in sim.state_names[:7]])
    rng = np.random.default_rng(11)
    for _ in range(10):
        q, v = rng.uniform(-2, 2, 7), rng.normal(size=7)
        a = sim.rhs(0.0, np.concatenate([q, v]))
        a_pin = pin.aba(reduced, data, q, v, -damping * v)
        np.testing.assert_array_equal(a[:7], v)
        assert np.abs(a[7:] - a_pin).max() < 1e-12 * np.abs(a_pin).max()
