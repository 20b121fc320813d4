"""Generalized speeds v != q': quaternion spherical and free joints in Pinocchio's layout, the
general form q' = k(q, v, t), M v' = F, and its runs, checked against independent facts
(Euler's equations integrated on SO(3) by scipy, Pinocchio's free flyer and spherical joint)."""

from pathlib import Path

import numpy as np
import pytest
import sympy as sp
from scipy.integrate import solve_ivp

import lagcodegen as lcg
from lagcodegen.errors import ModelError

pin = pytest.importorskip("pinocchio")
ROBOTS = Path(pin.__file__).resolve().parents[4] / "share" / "example-robot-data" / "robots"
EXAMPLES = Path(__file__).resolve().parents[2] / "examples"

INERTIA = np.array([1.0, 2.0, 3.0])


def quat_matrix(q):
    x, y, z, w = q / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def so3_reference(w0, times):
    """The free rigid body on SO(3): R' = R [w]x, I w' = (I w) x w, by DOP853 at 1e-13."""
    def f(t, y):
        R, w = y[:9].reshape(3, 3), y[9:]
        W = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
        return np.concatenate([(R @ W).ravel(), np.cross(INERTIA * w, w) / INERTIA])
    sol = solve_ivp(f, (times[0], times[-1]), np.concatenate([np.eye(3).ravel(), w0]), method="DOP853",
                    rtol=1e-13, atol=1e-14, t_eval=times)
    return sol.y[:9].T.reshape(-1, 3, 3), sol.y[9:].T


def tumbling_body(rotation="quaternion"):
    m = lcg.Model("tumbler" if rotation == "quaternion" else "tumbler_zyx")
    m.link("body", joint=lcg.Joint.spherical("ball", rotation=rotation), mass=1.0, inertia=tuple(INERTIA))
    return m


def test_quaternion_joints_declare_pinocchio_layout():
    m = lcg.Model("fly")
    m.link("base", joint=lcg.Joint.free("root"), mass=1, inertia=(1, 1, 1))
    m.link("arm", parent="base", joint=lcg.Joint.revolute("elbow"), mass=1, inertia=(1, 1, 1))
    m.link("hand", parent="arm", joint=lcg.Joint.spherical("wrist"), mass=1, inertia=(1, 1, 1))
    assert [q.name for q in m.coords] == ["root_x", "root_y", "root_z", "root_qx", "root_qy", "root_qz", "root_qw",
                                          "elbow", "wrist_qx", "wrist_qy", "wrist_qz", "wrist_qw"]
    assert [v.name for v in m.v] == ["root_vx", "root_vy", "root_vz", "root_wx", "root_wy", "root_wz", "elbow_dot",
                                     "wrist_wx", "wrist_wy", "wrist_wz"]
    assert (m.nq, m.nv) == (12, 10) and m.general
    assert m.neutral() == [0, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]
    assert m.kinematics[7] == sp.Symbol("elbow_dot")  # a 1-dof joint's speed is its rate
    with pytest.raises(ModelError, match="rotation must be one of"):
        lcg.Joint.spherical("s", rotation="XYZ")


def test_free_body_equations_are_eulers():
    eom = lcg.derive(tumbling_body())
    w = sp.symbols("ball_wx ball_wy ball_wz")
    assert sp.Matrix(eom.M) == sp.diag(*[sp.Float(x) for x in INERTIA])
    # I w' = (I w) x w, component by component (Euler's equations)
    expected = [(INERTIA[1] - INERTIA[2]) * w[1] * w[2], (INERTIA[2] - INERTIA[0]) * w[2] * w[0],
                (INERTIA[0] - INERTIA[1]) * w[0] * w[1]]
    assert all(sp.simplify(sp.sympify(a) - b) == 0 for a, b in zip(eom.F, expected))


@pytest.mark.parametrize("method, rtol, bound", [("adams", 1e-11, 1e-8), ("bdf", 1e-11, 1e-7), ("bdf", 1e-12, 1e-8),
                                                 ("taylor", 1e-11, 1e-9)])
def test_tumbling_through_gimbal_lock_attitudes_quaternion_vs_so3(method, rtol, bound):
    """A body spun about its middle axis (unstable) with a small perturbation turns over again and
    again, through the attitudes where Z-Y-X angles are singular; the quaternion joint follows the
    SO(3) reference to 1e-8 at rtol 1e-11 on Adams, 4e-11 on Taylor (BDF, of lower order: 6e-8
    there, 7e-9 at 1e-12; Euler angles: 4e-3, 8e-3 and 1e-4) and its norm stays within 1e-8 of 1."""
    times = np.linspace(0.0, 40.0, 401)
    w0 = np.array([0.01, 2.0, 0.01])
    R_ref, w_ref = so3_reference(w0, times)
    cm = lcg.compile_model(tumbling_body())
    res = cm.simulate(times, v0=w0, method=method, rtol=rtol, atol=rtol / 10, max_steps=10**6)
    q = res.y[:, :4]
    R = np.array([quat_matrix(x) for x in q])
    assert np.abs(R - R_ref).max() < bound
    assert np.abs(res.y[:, 4:7] - w_ref).max() < 2 * bound
    assert np.abs(np.linalg.norm(q, axis=1) - 1).max() < 1e-8
    # the body really lies flat: its z axis sweeps through the horizontal plane (pitch = +-pi/2 of Z-Y-X)
    assert np.abs(R_ref[:, 2, 0]).max() > 0.999


def test_euler_angles_on_request_are_what_they_were():
    """rotation="ZYX" keeps the three angles and their rates (the joint of earlier versions)."""
    m = tumbling_body("ZYX")
    assert [q.name for q in m.coords] == ["ball_yaw", "ball_pitch", "ball_roll"] and not m.general
    assert lcg.derive(m).M.shape == (3, 3)


def pinocchio_check(model, pin_model, rng, trials=4, file=None):
    """v' and q' of the compiled model against Pinocchio (aba, with the URDF ``file``'s joint
    damping as torques -c v; the quaternion and free-flyer kinematics) at random states in the
    same layout."""
    cm = lcg.compile_model(model, jacobian=False)
    data = pin_model.createData()
    assert (cm.nq, cm.nv) == (pin_model.nq, pin_model.nv)
    damping = np.zeros(pin_model.nv)
    if file is not None:
        for name, joint in lcg.urdf.read(file).joints.items():
            if pin_model.existJointName(name) and joint.dynamics is not None:
                damping[pin_model.joints[pin_model.getJointId(name)].idx_v] = joint.dynamics.damping
    for _ in range(trials):
        q = pin.randomConfiguration(pin_model, -np.ones(pin_model.nq), np.ones(pin_model.nq))
        v = rng.normal(size=pin_model.nv)
        ydot = cm.rhs(0.0, np.concatenate([q, v]))
        a = pin.aba(pin_model, data, q, v, -damping * v)
        assert np.abs(ydot[cm.nq:] - a).max() <= 1e-10 * max(1.0, np.abs(a).max())
        # q' against the map Pinocchio integrates with: q(t + h) = integrate(q, h v), central differences
        h = 1e-6
        qd = (pin.integrate(pin_model, q, h * v) - pin.integrate(pin_model, q, -h * v)) / (2 * h)
        assert np.abs(ydot[:cm.nq] - qd).max() <= 1e-7 * max(1.0, np.abs(qd).max())
    return cm


@pytest.mark.parametrize("form", ["tree", "closed"])
def test_floating_arm_agrees_with_pinocchio_free_flyer(form):
    file = EXAMPLES / "ur_like_arm.urdf"
    model = lcg.urdf.load(file, floating=True, form=form)
    assert [c.name for c in model.coords[:7]] == ["root_joint_x", "root_joint_y", "root_joint_z", "root_joint_qx",
                                                  "root_joint_qy", "root_joint_qz", "root_joint_qw"]
    pinocchio_check(model, pin.buildModelFromUrdf(str(file), pin.JointModelFreeFlyer()), np.random.default_rng(3),
                    file=file)


def test_floating_solo12_agrees_with_pinocchio_free_flyer():
    file = ROBOTS / "solo_description" / "robots" / "solo12.urdf"
    pinocchio_check(lcg.urdf.load(file, floating=True), pin.buildModelFromUrdf(str(file), pin.JointModelFreeFlyer()),
                    np.random.default_rng(4), trials=3, file=file)


def test_spherical_joint_chain_agrees_with_pinocchio():
    """A revolute link carrying a ball-jointed link under gravity, placements rotated."""
    rng = np.random.default_rng(5)
    R1 = pin.rpy.rpyToMatrix(*rng.uniform(-1, 1, 3))
    t1 = rng.uniform(-0.5, 0.5, 3)
    m = lcg.Model("ballchain")
    m.gravity(9.81)
    m.link("upper", joint=lcg.Joint.revolute("hinge", (0, 1, 0)), mass=1.2, com=(0.1, 0, -0.3),
           inertia=(0.05, 0.06, 0.02))
    m.link("lower", parent="upper", joint=lcg.Joint.spherical("ball"), origin=lcg.Placement(tuple(t1), rotation=R1),
           mass=0.8, com=(0.02, -0.01, -0.25), inertia=(0.03, 0.025, 0.01, 0.001, -0.002, 0.0005))
    pm = pin.Model()
    pm.gravity = pin.Motion(np.array([0, 0, -9.81, 0, 0, 0]))
    j = pm.addJoint(0, pin.JointModelRY(), pin.SE3.Identity(), "hinge")
    pm.appendBodyToJoint(j, pin.Inertia(1.2, np.array([0.1, 0, -0.3]), np.diag([0.05, 0.06, 0.02])),
                         pin.SE3.Identity())
    j = pm.addJoint(j, pin.JointModelSpherical(), pin.SE3(R1, t1), "ball")
    I = np.array([[0.03, 0.001, -0.002], [0.001, 0.025, 0.0005], [-0.002, 0.0005, 0.01]])
    pm.appendBodyToJoint(j, pin.Inertia(0.8, np.array([0.02, -0.01, -0.25]), I), pin.SE3.Identity())
    cm = pinocchio_check(m, pm, rng)
    # energy is conserved along a run (T + V of the general form)
    cm2 = lcg.compile_model(m, jacobian=False, outputs=["energy"])
    res = cm2.simulate(np.linspace(0, 3, 31), q0=[0.3, 0.1, 0.2, 0.0, 1.0], v0=[1.0, 2.0, -1.0, 0.5],
                       rtol=1e-11, atol=1e-12)
    e = res["energy"]
    assert np.abs(e - e[0]).max() < 1e-8 * abs(e[0])


def test_a_model_of_its_own_speeds_matches_lagrange():
    """Model.generalized_speeds: a particle in the plane in polar coordinates with the speeds
    u1 = r', u2 = r theta' (the tangential velocity), against the Lagrangian model in q'."""
    def model(speeds):
        m = lcg.Model("polar_u" if speeds else "polar")
        r, th = m.coordinates("r theta")
        k, mass = m.parameters(k=3.0, m=1.5)
        m.particle("p", mass, (r * sp.cos(th), r * sp.sin(th)))
        m.potential_energy(k / 2 * (r - 1) ** 2)
        if speeds:
            u1, u2 = sp.symbols("u1 u2")
            m.generalized_speeds(["u1", "u2"], {r: u1, th: u2 / r})
        return m
    a = lcg.compile_model(model(True), jacobian=False)
    b = lcg.compile_model(model(False))
    t = np.linspace(0, 5, 51)
    ra = a.simulate(t, q0=[1.2, 0.0], v0=[0.1, 1.2 * 0.8], rtol=1e-11, atol=1e-12)
    rb = b.simulate(t, q0=[1.2, 0.0], v0=[0.1, 0.8], rtol=1e-11, atol=1e-12)
    assert np.abs(ra.y[:, :2] - rb.y[:, :2]).max() < 1e-8
    assert np.abs(ra.y[:, 3] - rb.y[:, 0] * rb.y[:, 3]).max() < 1e-8  # u2 = r theta'
    with pytest.raises(ModelError, match="not linear in the generalized speeds"):
        m = lcg.Model("bad")
        x, = m.coordinates("x")
        m.particle("p", 1, (x,))
        m.generalized_speeds(["u"], {x: sp.Symbol("u") ** 2})
        lcg.derive(m)


def test_generalized_speeds_take_an_analytic_jacobian():
    """The analytic Jacobian of a quaternion model (tests/model/test_general_jacobian.py checks its
    values): jacobian=None turns it on; the expanded form of a rigid-body tree is refused by name."""
    from lagcodegen.formulation.scene import Scene
    cm = lcg.compile_model(tumbling_body())
    assert cm.c_jac is not None
    with pytest.raises(ModelError, match="expanded Jacobian of a rigid-body tree"):
        lcg.generate_code(Scene(lcg.derive(tumbling_body()), jacobian_form="expanded"))


def test_fortran_agrees_with_c_on_a_floating_arm():
    model = lcg.urdf.load(EXAMPLES / "ur_like_arm.urdf", floating=True)
    c, f = lcg.compile_model(model), lcg.compile_model(model, lang="fortran")
    rng = np.random.default_rng(6)
    y = np.r_[rng.normal(size=3), rng.normal(size=4), rng.uniform(-1, 1, 6), rng.normal(size=12)]
    assert np.abs(c.rhs(0.0, y) - f.rhs(0.0, y)).max() <= 1e-12 * np.abs(c.rhs(0.0, y)).max()


def test_what_does_not_take_generalized_speeds_yet_says_so():
    from lagcodegen.errors import LagcodegenError
    m = tumbling_body()
    cm = lcg.compile_model(m)
    t = np.linspace(0, 1, 3)
    # forward sensitivities run (tests/model/test_general_sensitivities.py checks their values);
    # a quaternion component as a direction is refused by name
    res = cm.simulate(t, v0=[0, 1, 0], sensitivities=["ball_wx(0)"])
    assert res.sensitivities[0, 0, 4] == 1.0  # d(ball_wx)/d(ball_wx(0)) at t = 0
    with pytest.raises(LagcodegenError, match="one component of the unit quaternion of joint 'ball'"):
        cm.simulate(t, v0=[0, 1, 0], sensitivities=["ball_qw(0)"])
    # linearize takes them at rest and moving (tests/theory/test_linearize_speeds.py)
    # ConstrainedSystem takes them (index-1 and impacts: tests/test_constrained_speeds.py)
    with pytest.raises(ModelError, match="steady_motions: model 'tumbler' has generalized speeds"):
        lcg.steady_motions(m)
    ens = cm.ensemble(t, q0=[0, 0, 0, 1], v0=np.array([[0, 1, 0], [0, 2, 0]]))
    assert np.allclose(ens.y[:, 4:], [[0, 1, 0], [0, 2, 0]])  # save="final": each member's last state


def test_taylor_on_a_floating_arm_agrees_with_cvode_and_locates_events():
    """The Taylor jet of a tree with a free-flyer root (quaternion kinematics in the jet) against
    Adams at tight tolerances, and an event on the base's height located on both."""
    model = lcg.urdf.load(EXAMPLES / "ur_like_arm.urdf", floating=True)
    cm = lcg.compile_model(model)
    q0 = np.r_[0, 0, 1.0, 0.1, 0.2, 0.0, 1.0, np.linspace(-0.5, 0.5, 6)]
    v0 = np.r_[0.3, -0.2, 0.5, 0.4, -0.3, 0.8, np.linspace(1, -1, 6)]
    t = np.linspace(0, 0.5, 11)
    ev = [lcg.Event("drop", "root_joint_z - 0.5", direction=-1)]
    a = cm.simulate(t, q0=q0, v0=v0, method="adams", rtol=1e-12, atol=1e-13, events=ev)
    b = cm.simulate(t, q0=q0, v0=v0, method="taylor", rtol=1e-12, atol=1e-13, events=ev)
    assert np.abs(a.y - b.y).max() < 1e-8
    assert len(a.events) == len(b.events) == 1 and abs(a.events[0].t - b.events[0].t) < 1e-9


def test_floating_base_regressor_matches_pinocchio_free_flyer():
    """The inverse-dynamics regressor of a tree with a free-flyer root (its six speeds as rows,
    the root body's ten columns first) is Pinocchio's computeJointTorqueRegressor, and
    Y pi = rnea, in the same layout."""
    file = EXAMPLES / "ur_like_arm.urdf"
    cm = lcg.compile_model(lcg.urdf.load(file, floating=True, inertial_parameters=True))
    pm = pin.buildModelFromUrdf(str(file), pin.JointModelFreeFlyer())
    data = pm.createData()
    rng = np.random.default_rng(9)
    pi = cm.regressor_parameters()
    pi_pin = np.concatenate([pm.inertias[j].toDynamicParameters() for j in range(1, pm.njoints)])
    assert np.abs(pi - pi_pin).max() <= 1e-12 * np.abs(pi_pin).max()
    for _ in range(3):
        q = pin.randomConfiguration(pm, -np.ones(pm.nq), np.ones(pm.nq))
        v, a = rng.normal(size=pm.nv), rng.normal(size=pm.nv)
        Y = cm.inverse_dynamics_regressor(q, v, a)
        Y_pin = pin.computeJointTorqueRegressor(pm, data, q, v, a)
        assert Y.shape == Y_pin.shape and np.abs(Y - Y_pin).max() <= 1e-12 * np.abs(Y_pin).max()
        tau = pin.rnea(pm, data, q, v, a)
        assert np.abs(Y @ pi - tau).max() <= 1e-11 * np.abs(tau).max()


def test_rhs_batch_is_rhs_row_by_row():
    """rhs_batch: one call into C for many states (shared or per-row parameters), equal to rhs
    row by row; a bad shape or a singular row is named."""
    from lagcodegen.errors import LagcodegenError, SingularMassMatrixError
    cm = lcg.compile_model(lcg.systems.double_pendulum(), runtime_parameters=["g"])
    rng = np.random.default_rng(10)
    Y = rng.normal(size=(50, 4))
    P = rng.uniform(1, 10, size=(50, 1))
    assert np.array_equal(cm.rhs_batch(0.0, Y), np.array([cm.rhs(0.0, y) for y in Y]))
    assert np.array_equal(cm.rhs_batch(0.0, Y, P), np.array([cm.rhs(0.0, y, p) for y, p in zip(Y, P)]))
    with pytest.raises(LagcodegenError, match="N x 4 array"):
        cm.rhs_batch(0.0, Y[:, :3])
    masses = lcg.compile_model(lcg.systems.double_pendulum(), runtime_parameters=["m1", "m2"])
    P = np.ones((3, 2))
    P[1] = 0.0  # no mass: M is singular in the row 1
    with pytest.raises(SingularMassMatrixError, match="row 1"):
        masses.rhs_batch(0.0, Y[:3], P)


def test_generalized_speeds_pickle_and_run_in_other_processes():
    """A compiled quaternion model pickles with its layout (nq, nv, the neutral configuration) and
    an ensemble spread over worker processes equals the one run here, bit for bit."""
    import pickle
    from concurrent.futures import ProcessPoolExecutor
    cm = lcg.compile_model(tumbling_body())
    back = pickle.loads(pickle.dumps(cm))
    assert (back.nq, back.nv, back.code.q_neutral) == (4, 3, [0.0, 0.0, 0.0, 1.0])
    t = np.linspace(0, 1, 3)
    v0 = np.array([[0, 1, 0], [0, 2, 0.1], [0.3, 0.1, 0]])
    with ProcessPoolExecutor(2) as ex:
        spread = cm.ensemble(t, q0=[0, 0, 0, 1], v0=v0, executor=ex, chunk_size=1)
    assert np.array_equal(spread.y, cm.ensemble(t, q0=[0, 0, 0, 1], v0=v0).y)


def test_results_into_out_arrays():
    """rhs, outputs, jac and inverse_dynamics write into a caller's out= array (the same values
    as without); a wrong one is refused by name."""
    from lagcodegen.errors import LagcodegenError
    cm = lcg.compile_model(lcg.urdf.load(EXAMPLES / "ur_like_arm.urdf"), outputs=["energy"])
    rng = np.random.default_rng(13)
    y = rng.normal(size=12)
    buf = np.empty(12)
    assert cm.rhs(0.0, y, out=buf) is buf and np.array_equal(buf, cm.rhs(0.0, y))
    o = np.empty(1)
    assert cm.outputs(0.0, y, out=o) is o and np.array_equal(o, cm.outputs(0.0, y))
    J = np.empty((12, 12), order="F")
    assert cm.jac(0.0, y, out=J) is J and np.array_equal(J, cm.jac(0.0, y))
    tau = np.empty(6)
    assert cm.inverse_dynamics(y[:6], y[6:], y[:6], out=tau) is tau
    assert np.array_equal(tau, cm.inverse_dynamics(y[:6], y[6:], y[:6]))
    for bad in (np.empty(11), np.empty(12, dtype=np.float32), np.empty(24)[::2]):
        with pytest.raises(LagcodegenError, match="out must be a writable, C-contiguous float64 array of shape"):
            cm.rhs(0.0, y, out=bad)


def test_linearize_at_rest_in_tangent_coordinates():
    """A body hanging from a quaternion ball joint, linearized at rest in tangent coordinates
    (dq = G(q0) dtheta): its pendulum frequencies are sqrt(m g l / (I + m l^2)) about x and y
    (analytic) and those of the same body on Z-Y-X angles, the rotation about the vertical a
    zero mode; the coordinates are the speeds' names."""
    def hanging(rotation):
        m = lcg.Model("hang_" + rotation.lower())
        m.gravity(9.81)
        m.link("body", joint=lcg.Joint.spherical("ball", rotation=rotation), mass=2.0, com=(0, 0, -0.5),
               inertia=(0.03, 0.05, 0.02))
        return m
    quat = lcg.linearize(lcg.derive(hanging("quaternion")), q0=[0, 0, 0, 1])
    euler = lcg.linearize(lcg.derive(hanging("ZYX")), q0=[0, 0, 0])
    assert quat.coordinates == ["ball_wx", "ball_wy", "ball_wz"]
    mass, length, g = 2.0, 0.5, 9.81
    exact = sorted(np.sqrt(mass * g * length / (i + mass * length ** 2)) for i in (0.03, 0.05))
    assert np.allclose(sorted(quat.frequencies), exact, rtol=1e-12)
    assert np.allclose(sorted(quat.frequencies), sorted(euler.frequencies), rtol=1e-12)
    # tilted 0.4 rad about x, the quaternion is no longer the identity: still at rest, not in equilibrium
    tilt = lcg.linearize(lcg.derive(hanging("quaternion")), q0=[np.sin(0.2), 0, 0, np.cos(0.2)])
    assert abs(tilt.a0[0] + mass * g * length * np.sin(0.4) / (0.03 + mass * length ** 2)) < 1e-12
