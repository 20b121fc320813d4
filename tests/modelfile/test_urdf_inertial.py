"""Inertial parameters at run time (urdf.load(inertial_parameters=...)) and the inverse-dynamics
regressor (CompiledModel.inverse_dynamics_regressor), against Pinocchio: its
computeJointTorqueRegressor, rnea and aba, and its bodies' dynamic parameters
(Inertia.toDynamicParameters), on the UR5 and the Panda of example-robot-data."""

import subprocess
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import lagcodegen as lcg
from lagcodegen import urdf
from lagcodegen.errors import LagcodegenError, ModelError

from helpers import STRICT_CFLAGS

ROBOTS = Path(pin.__file__).resolve().parents[4] / "share" / "example-robot-data" / "robots"
UR5 = ROBOTS / "ur_description" / "urdf" / "ur5_robot.urdf"
PANDA = ROBOTS / "panda_description" / "urdf" / "panda.urdf"
ROBOT_CASES = [(UR5, {}), (PANDA, {"mimic": "independent"})]
SUFFIXES = ["m", "mx", "my", "mz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz"]

_COMPILED: dict = {}


def compiled(path, **load):
    """compile_model(urdf.load(path, **load)), once per session."""
    key = (str(path), tuple(sorted((k, repr(v)) for k, v in load.items())))
    if key not in _COMPILED:
        _COMPILED[key] = lcg.compile_model(urdf.load(path, **load), jacobian=False)
    return _COMPILED[key]


def pin_state(pm, sim, q, v, a):
    """Pinocchio's (q, v, a) of lagcodegen's (continuous joints as (cos, sin)), and the rows of
    Pinocchio's velocity vector in lagcodegen's coordinate order."""
    joints = [pm.joints[pm.getJointId(name)] for name in sim.state_names[:sim.n]]
    qp, vp, ap = pin.neutral(pm), np.zeros(pm.nv), np.zeros(pm.nv)
    for i, j in enumerate(joints):
        if j.nq == 2:
            qp[j.idx_q:j.idx_q + 2] = np.cos(q[i]), np.sin(q[i])
        else:
            qp[j.idx_q] = q[i]
        vp[j.idx_v], ap[j.idx_v] = v[i], a[i]
    return qp, vp, ap, [j.idx_v for j in joints]


def body_joints(pm, path, sim):
    """Pinocchio's joint id of each body of the regressor (its link is the child of that joint)."""
    robot = urdf.read(path)
    by_child = {j.child: name for name, j in robot.joints.items()}
    return [pm.getJointId(by_child[link]) for link in sim.regressor_bodies]


@pytest.mark.parametrize("path, load", ROBOT_CASES, ids=["ur5", "panda"])
def test_regressor_matches_pinocchio(path, load):
    """Y(q, v, a) is Pinocchio's joint-torque regressor (rows and column blocks matched by joint
    names), Y pi is rnea, and pi is Pinocchio's bodies' dynamic parameters, to 1e-12."""
    sim = compiled(path, **load)
    pm = pin.buildModelFromUrdf(str(path))
    data = pm.createData()
    bj = body_joints(pm, path, sim)
    assert len(bj) == pm.njoints - 1 == sim.n  # every moving joint carries one body
    cols = np.concatenate([np.arange(10 * (j - 1), 10 * j) for j in bj])
    pi = sim.regressor_parameters()
    pi_pin = np.concatenate([pm.inertias[j].toDynamicParameters() for j in bj])
    np.testing.assert_allclose(pi, pi_pin, rtol=0, atol=1e-12 * np.abs(pi_pin).max())
    rng = np.random.default_rng(3)
    for _ in range(5):
        q, v, a = rng.uniform(-np.pi, np.pi, sim.n), rng.normal(size=sim.n), rng.normal(size=sim.n)
        qp, vp, ap, rows = pin_state(pm, sim, q, v, a)
        Y = sim.inverse_dynamics_regressor(q, v, a)
        assert Y.shape == (sim.n, 10 * sim.n)
        Y_pin = pin.computeJointTorqueRegressor(pm, data, qp, vp, ap)[np.ix_(rows, cols)]
        assert np.abs(Y - Y_pin).max() <= 1e-12 * np.abs(Y_pin).max()
        tau = pin.rnea(pm, data, qp, vp, ap)[rows]
        assert np.abs(Y @ pi_pin - tau).max() <= 1e-12 * np.abs(tau).max()


def test_regressor_is_the_tree_share_of_inverse_dynamics_and_follows_gravity():
    """inverse_dynamics = Y pi + the joint damping c q' (the Panda's URDF has damping, outside
    the tree); Y follows the run-time gravity g."""
    sim = compiled(PANDA, mimic="independent")
    damping = np.array([getattr(urdf.read(PANDA).joints[c].dynamics, "damping", 0.0) for c in sim.state_names[:9]])
    assert np.any(damping)
    rng = np.random.default_rng(5)
    q, v, a = rng.normal(size=(3, 9))
    tau = sim.inverse_dynamics(q, v, a)
    Y = sim.inverse_dynamics_regressor(q, v, a)
    np.testing.assert_allclose(Y @ sim.regressor_parameters() + damping * v, tau, rtol=0,
                               atol=1e-12 * np.abs(tau).max())
    Y0 = sim.inverse_dynamics_regressor(q, v, a, params={"g": 0.0})
    Yq = sim.inverse_dynamics_regressor(q, 0 * v, 0 * a)
    assert np.abs(Y0 - Y).max() > 1e-3
    np.testing.assert_allclose(sim.inverse_dynamics_regressor(q, 0 * v, 0 * a, params={"g": 2 * 9.81}), 2 * Yq,
                               rtol=0, atol=1e-12 * np.abs(Yq).max())


@pytest.mark.parametrize("path, load", ROBOT_CASES, ids=["ur5", "panda"])
def test_inertial_parameters_at_their_defaults_give_the_plain_model(path, load):
    """Ten parameters per moving body, named after its link, defaults from the URDF; q'' of
    the compiled model equals the plain model's to 1e-12."""
    plain = compiled(path, **load)
    par = compiled(path, inertial_parameters=True, **load)
    bodies = plain.regressor_bodies
    assert par.param_names == plain.param_names + [f"{b}_{s}" for b in bodies for s in SUFFIXES]
    rng = np.random.default_rng(7)
    for _ in range(5):
        y = np.concatenate([rng.uniform(-np.pi, np.pi, plain.n), rng.normal(size=plain.n)])
        a, b = plain.rhs(0.0, y)[plain.n:], par.rhs(0.0, y)[plain.n:]
        assert np.abs(a - b).max() <= 1e-12 * np.abs(a).max()


def random_inertia(rng) -> pin.Inertia:
    L = rng.normal(size=(3, 3))
    return pin.Inertia(rng.uniform(0.5, 3.0), rng.uniform(-0.2, 0.2, 3), L @ L.T / 10 + 0.01 * np.eye(3))


def test_inertial_parameters_set_at_run_time_agree_with_pinocchio_and_stay_linear():
    """The UR5 with other inertias at run time: q'' is Pinocchio's aba with those inertias,
    the regressor's pi is the parameters themselves, and tau is linear in them (Y pi)."""
    sim = compiled(UR5, inertial_parameters=True)
    pm = pin.buildModelFromUrdf(str(UR5))
    bj = body_joints(pm, UR5, sim)
    rng = np.random.default_rng(11)
    params = {}
    for link, j in zip(sim.regressor_bodies, bj):
        pm.inertias[j] = random_inertia(rng)
        params.update(zip([f"{link}_{s}" for s in SUFFIXES], pm.inertias[j].toDynamicParameters()))
    data = pm.createData()
    pi = np.array([params[f"{link}_{s}"] for link in sim.regressor_bodies for s in SUFFIXES])
    np.testing.assert_allclose(sim.regressor_parameters(params), pi, rtol=0, atol=1e-15)
    for _ in range(4):
        q, v, a = rng.uniform(-np.pi, np.pi, 6), rng.normal(size=6), rng.normal(size=6)
        qp, vp, ap, rows = pin_state(pm, sim, q, v, a)
        acc = sim.rhs(0.0, np.concatenate([q, v]), sim.parameter_vector(params))[6:]
        ref = pin.aba(pm, data, qp, vp, np.zeros(6))[rows]
        assert np.abs(acc - ref).max() <= 1e-12 * np.abs(ref).max()
        tau = sim.inverse_dynamics(q, v, a, params=params)
        np.testing.assert_allclose(sim.inverse_dynamics_regressor(q, v, a) @ pi, tau, rtol=0,
                                   atol=1e-12 * np.abs(tau).max())


def test_a_link_welded_by_fixed_joints_is_moved_into_its_body():
    """panda_hand sits on panda_link8, welded to panda_link7 (Pinocchio merges it into joint 7's
    body as lagcodegen does): its parameters at run time move joint 7's inertia by the hand's
    placement, as Pinocchio's Inertia.se3Action says."""
    lock = ["panda_finger_joint1", "panda_finger_joint2"]
    sim = compiled(PANDA, lock=lock, inertial_parameters=["panda_hand"])
    assert sim.param_names == ["g"] + [f"panda_hand_{s}" for s in SUFFIXES]
    full = pin.buildModelFromUrdf(str(PANDA))
    pm = pin.buildReducedModel(full, [full.getJointId(n) for n in lock], pin.neutral(full))
    frame = pm.frames[pm.getFrameId("panda_hand")]
    j7 = pm.getJointId("panda_joint7")
    assert frame.parentJoint == j7
    default = dict(zip(sim.param_names[1:], sim.parameter_vector()[1:]))
    old = pin.Inertia.FromDynamicParameters(np.array([default[f"panda_hand_{s}"] for s in SUFFIXES]))
    new = random_inertia(np.random.default_rng(2))
    params = dict(zip([f"panda_hand_{s}" for s in SUFFIXES], new.toDynamicParameters()))
    X = frame.placement
    # The fingers (locked, welded to the hand) stay in joint 7's body, Pinocchio's too.
    pm.inertias[j7] = pin.Inertia.FromDynamicParameters(pm.inertias[j7].toDynamicParameters()
                                                        - X.act(old).toDynamicParameters()
                                                        + X.act(new).toDynamicParameters())
    data = pm.createData()
    rng = np.random.default_rng(4)
    for _ in range(4):
        q, v = rng.uniform(-2, 2, 7), rng.normal(size=7)
        acc = sim.rhs(0.0, np.concatenate([q, v]), sim.parameter_vector(params))[7:]
        damping = np.array([urdf.read(PANDA).joints[f"panda_joint{i}"].dynamics.damping for i in range(1, 8)])
        ref = pin.aba(pm, data, q, v, -damping * v)
        assert np.abs(acc - ref).max() <= 1e-12 * np.abs(ref).max()


def test_regressor_sources_compile_strictly(tmp_path, cc):
    """The regressor's C compiles with -Wall -Wextra -Werror -std=c99 -pedantic."""
    from lagcodegen.simulation.regressor import compiled_regressor
    sources = compiled_regressor(compiled(PANDA, mimic="independent")).sources
    assert sorted(sources) == ["panda_regressor.c", "panda_regressor.h"]
    for name, text in sources.items():
        (tmp_path / name).write_text(text)
    proc = subprocess.run([cc, *STRICT_CFLAGS, "-O0", "-c", "panda_regressor.c", "-o", "x.o"], cwd=tmp_path,
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]


def test_compile_urdf_cache_key_holds_the_option(tmp_path):
    """compile_urdf with and without inertial_parameters: two cache entries, each its own
    parameters (the option is part of the key), and the second call of each from the cache."""
    path = tmp_path / "ur5.urdf"
    path.write_bytes(UR5.read_bytes())
    plain = lcg.compile_urdf(path)
    par = lcg.compile_urdf(path, load={"inertial_parameters": ["wrist_3_link"]})
    assert plain.param_names == ["g"] and par.param_names == ["g"] + [f"wrist_3_link_{s}" for s in SUFFIXES]
    again = lcg.compile_urdf(path, load={"inertial_parameters": ["wrist_3_link"]})
    assert again.code.files == par.code.files and again.param_names == par.param_names
    q, v, a = np.full(6, 0.3), np.full(6, -0.2), np.full(6, 0.5)
    # from the cache, the regressor derives the scene again
    np.testing.assert_array_equal(again.inverse_dynamics_regressor(q, v, a), par.inverse_dynamics_regressor(q, v, a))
    assert lcg.compile_urdf(path).param_names == ["g"]


@pytest.mark.parametrize("option, message", [
    (["no_such_link"], r"inertial_parameters: no link named 'no_such_link'"),
    (["base_link"], r"inertial_parameters: link 'base_link' is fixed to the world"),
    ("forearm", r"no link named 'forearm'"),
    ([1, 2], r"inertial_parameters must be True, False or a list of link names"),
    (3.5, r"inertial_parameters must be True, False or a list of link names"),
])
def test_bad_inertial_parameters_are_refused_by_name(option, message):
    with pytest.raises(ModelError, match=message):
        urdf.load(UR5, inertial_parameters=option)


def test_inertial_parameters_need_the_tree_form():
    with pytest.raises(ModelError, match="inertial_parameters need form='tree'"):
        urdf.load(UR5, inertial_parameters=True, form="closed")


def test_regressor_of_a_model_without_tree_is_refused():
    sim = lcg.compile_model(lcg.systems.pendulum(), jacobian=False)
    with pytest.raises(LagcodegenError, match="no inverse-dynamics regressor"):
        sim.inverse_dynamics_regressor([0.1], [0.0], [0.0])


def test_model_link_dynamic_parameters_are_checked():
    model = lcg.Model("m")
    with pytest.raises(ModelError, match="10 values"):
        model.link("a", joint=lcg.Joint.revolute("j", (0, 0, 1)), dynamic_parameters=[1, 2, 3])
    with pytest.raises(ModelError, match="not both"):
        model.link("a", joint=lcg.Joint.revolute("j", (0, 0, 1)), mass=1.0, dynamic_parameters=[1] + [0] * 9)
    with pytest.raises(ModelError, match="mass is negative"):
        model.link("a", joint=lcg.Joint.revolute("j", (0, 0, 1)), dynamic_parameters=[-1] + [0] * 9)


def test_sensitivities_and_fit_work_on_inertial_parameters():
    """The UR5 swinging under gravity: forward sensitivities to a link's mass and inertia agree
    with central differences of runs, and fit recovers a changed mass of the forearm from the
    joint angles (noise-free: to 1e-6)."""
    sim = compiled(UR5, inertial_parameters=["forearm_link", "wrist_1_link"])
    t = np.linspace(0.0, 0.5, 11)
    q0 = [0.1, -1.0, 0.8, -0.5, 0.6, 0.2]
    names = ["forearm_link_m", "wrist_1_link_Izz"]
    res = sim.simulate(t, q0, rtol=1e-11, atol=1e-12, sensitivities=names)
    base = dict(zip(sim.param_names, sim.parameter_vector()))
    for name in names:
        h = 1e-4 * max(1.0, abs(base[name]))
        up = sim.simulate(t, q0, params={name: base[name] + h}, rtol=1e-11, atol=1e-12).y
        down = sim.simulate(t, q0, params={name: base[name] - h}, rtol=1e-11, atol=1e-12).y
        fd = (up - down) / (2 * h)
        s = np.column_stack([res.sensitivity(state, name) for state in sim.state_names])
        assert np.abs(s - fd).max() <= 1e-5 * np.abs(fd).max()
    truth = base["forearm_link_m"] * 1.3
    data = sim.simulate(t, q0, params={"forearm_link_m": truth}, rtol=1e-11, atol=1e-12).y[:, :6]
    fitted = lcg.fit(sim, t, data, params={"forearm_link_m": base["forearm_link_m"]}, observe=sim.state_names[:6],
                     q0=q0, rtol=1e-11, atol=1e-12)
    assert fitted.params["forearm_link_m"] == pytest.approx(truth, rel=1e-6)
    masses = base["forearm_link_m"] * np.array([0.8, 1.0, 1.3])
    ens = sim.ensemble(t, q0, params={"forearm_link_m": masses}, rtol=1e-11, atol=1e-12, threads=1)
    np.testing.assert_array_equal(ens.y[2], sim.simulate(t, q0, params={"forearm_link_m": masses[2]}, rtol=1e-11,
                                                         atol=1e-12).y[-1])


def _arm(tool_inertial: dict | None = None, tool_parameters=None) -> lcg.Model:
    """A spherical joint, a revolute joint and a tool on a fixed joint (placed and turned): the
    tool by ``tool_inertial`` (mass, com, inertia), or by ``tool_parameters`` (name -> default)
    declared as run-time parameters and given as its dynamic parameters."""
    m = lcg.Model("arm")
    m.gravity(9.81)
    m.link("a", joint=lcg.Joint.spherical("ball", rotation="ZYX"), mass=1.2, com=(0.1, 0, -0.3), inertia=(0.02, 0.03, 0.01))
    m.link("b", parent="a", joint=lcg.Joint.revolute("j", (1, 0, 0)), origin=lcg.Placement(xyz=(0, 0, -0.6)),
           mass=0.7, com=(0, 0.1, -0.2), inertia=(0.01, 0.01, 0.02))
    if tool_parameters is not None:
        tool_inertial = dict(dynamic_parameters=[m.parameter(k, v) for k, v in tool_parameters.items()])
    m.link("tool", parent="b", origin=lcg.Placement(xyz=(0.1, 0.2, -0.3), rpy=(0.3, -0.2, 0.5)), **tool_inertial)
    return m


def test_model_link_dynamic_parameters_on_a_fixed_joint_agree_with_the_inertia_they_stand_for():
    """Model.link(dynamic_parameters=...) of a tool on a fixed joint, the values Pinocchio's
    Inertia.toDynamicParameters gives for its mass, centre of mass and inertia, as run-time
    parameters: q'' is that of the tool stated by mass, com and inertia; the tool's body (b)
    in the regressor has pi moved by the fixed joint's placement (Pinocchio's SE3.act); Y pi is
    the inverse dynamics (the spherical joint's massless intermediate frames bring no columns)."""
    mass, com = 0.4, np.array([0.05, 0.0, 0.1])
    I = np.array([[0.003, 0.0001, 0.0], [0.0001, 0.002, 0.0], [0.0, 0.0, 0.001]])
    plain = lcg.compile_model(_arm(dict(mass=mass, com=tuple(com), inertia=(0.003, 0.002, 0.001, 0.0001, 0, 0))),
                              jacobian=False)
    values = pin.Inertia(mass, com, I).toDynamicParameters()
    par = lcg.compile_model(_arm(tool_parameters={f"tool_{s}": float(x) for s, x in zip(SUFFIXES, values)}),
                            jacobian=False)
    assert par.param_names == [f"tool_{s}" for s in SUFFIXES]
    assert par.regressor_bodies == ["a", "b"]
    rng = np.random.default_rng(8)
    for _ in range(4):
        y = rng.normal(size=8)
        ref = plain.rhs(0.0, y)
        assert np.abs(par.rhs(0.0, y) - ref).max() <= 1e-12 * np.abs(ref).max()
        q, v, a = rng.normal(size=(3, 4))
        tau = par.inverse_dynamics(q, v, a)
        np.testing.assert_allclose(par.inverse_dynamics_regressor(q, v, a) @ par.regressor_parameters(), tau,
                                   rtol=0, atol=1e-12 * np.abs(tau).max())
    X = pin.SE3(pin.rpy.rpyToMatrix(0.3, -0.2, 0.5), np.array([0.1, 0.2, -0.3]))
    b = pin.Inertia(0.7, np.array([0, 0.1, -0.2]), np.diag([0.01, 0.01, 0.02]))
    merged = (b + X.act(pin.Inertia(mass, com, I))).toDynamicParameters()
    np.testing.assert_allclose(par.regressor_parameters()[10:], merged, rtol=0, atol=1e-14)


def test_command_line_urdf_option():
    """--urdf inertial_parameters=true|false|LINK,LINK reads as urdf.load's keyword."""
    from lagcodegen.cli.common import urdf_options
    assert urdf_options(["inertial_parameters=true"]) == {"inertial_parameters": True}
    assert urdf_options(["inertial_parameters=no"]) == {"inertial_parameters": False}
    assert urdf_options(["inertial_parameters=forearm_link, wrist_3_link"]) == {
        "inertial_parameters": ["forearm_link", "wrist_3_link"]}
