"""Rigid-body trees (Model.link): placements, joints, M and F along the tree, the generated code,
checked against Pinocchio built from the same data (CRBA, RNEA, ABA) and against conservation
of the Jacobi energy."""

import ctypes

import numpy as np
import pytest
import symengine as se
import sympy as sp

import lagcodegen as lcg
from lagcodegen.errors import ModelError

pin = pytest.importorskip("pinocchio")

RTOL = 1e-12


def rotation(rng):
    return pin.rpy.rpyToMatrix(*rng.uniform(-3, 3, 3))


def inertia(rng):
    A = rng.normal(size=(3, 3))
    return A @ A.T + 0.1 * np.eye(3)


def six(I):
    return (I[0, 0], I[1, 1], I[2, 2], I[0, 1], I[0, 2], I[1, 2])


def build(n, kinds="R", parents=None, seed=0, axes=None):
    """A random tree of n links built twice, here and in Pinocchio: joint kinds cycle through
    ``kinds`` (R revolute, P prismatic), ``parents[i]`` the parent link index (-1: world; default
    a chain); axes cycle through z, x, y and an unaligned one."""
    rng = np.random.default_rng(seed)
    m = lcg.Model("tree")
    g, = m.parameters(g=9.81)
    m.gravity(g)
    pm = pin.Model()
    pm.gravity = pin.Motion(np.array([0, 0, -9.81, 0, 0, 0]))
    parents = parents or [i - 1 for i in range(n)]
    jid = {-1: 0}
    for i in range(n):
        R, t = rotation(rng), rng.uniform(-0.5, 0.5, 3)
        ax = np.array(axes[i % len(axes)] if axes else [(0, 0, 1), (1, 0, 0), (0, 1, 0), tuple(rng.normal(size=3))][i % 4],
                      dtype=float)
        ax /= np.linalg.norm(ax)
        mass, c, I = rng.uniform(0.5, 2), rng.uniform(-0.2, 0.2, 3), inertia(rng)
        kind = kinds[i % len(kinds)]
        joint = (lcg.Joint.revolute if kind == "R" else lcg.Joint.prismatic)(f"j{i}", tuple(ax))
        m.link(f"l{i}", parent=None if parents[i] < 0 else f"l{parents[i]}", joint=joint,
               origin=lcg.Placement(tuple(t), rotation=R.tolist()), mass=mass, com=tuple(c), inertia=six(I))
        jm = pin.JointModelRevoluteUnaligned(ax) if kind == "R" else pin.JointModelPrismaticUnaligned(ax)
        jid[i] = pm.addJoint(jid[parents[i]], jm, pin.SE3(R, t), f"j{i}")
        pm.appendBodyToJoint(jid[i], pin.Inertia(mass, c, I), pin.SE3.Identity())
    return m, pm


def evaluate(eom, q, v):
    """M and F of the derived equations (symengine DAGs) at one state."""
    sub = {se.Symbol(s.name): x for s, x in zip(eom.model.coords, q)}
    sub.update({se.Symbol(s.name): x for s, x in zip(eom.model.speeds, v)})
    sub.update({se.Symbol(s.name): x for s, x in eom.model.params.items()})
    M = np.array([[float(se.sympify(e).xreplace(sub)) for e in row] for row in eom.M_se])
    F = np.array([float(se.sympify(e).xreplace(sub)) for e in eom.F_se])
    return M, F


def pin_mass(pm, data, q):
    M = pin.crba(pm, data, q)
    return np.triu(M) + np.triu(M, 1).T


def check_against_pinocchio(m, pm, states=20, seed=1):
    eom = lcg.derive(m)
    data = pm.createData()
    rng = np.random.default_rng(seed)
    n = m.n
    for _ in range(states):
        q, v = rng.uniform(-3, 3, n), rng.uniform(-2, 2, n)
        M, F = evaluate(eom, q, v)
        Mp = pin_mass(pm, data, q)
        bias = pin.rnea(pm, data, q, v, np.zeros(n))
        assert np.abs(M - Mp).max() <= RTOL * np.abs(Mp).max()
        assert np.abs(F + bias).max() <= RTOL * np.abs(bias).max()
        a = np.linalg.solve(M, F)
        ref = pin.aba(pm, data, q, v, np.zeros(n))
        assert np.abs(a - ref).max() <= 1e-10 * np.abs(ref).max()
    return eom


# ---------------------------------------------------------------------- placements and joints
def test_placement_rpy_is_urdf_convention():
    r, p, y = 0.3, -1.1, 2.0
    R = np.array(lcg.Placement(rpy=(r, p, y)).rotation.evalf(), dtype=float)
    assert np.allclose(R, pin.rpy.rpyToMatrix(r, p, y), atol=1e-15)
    # lower-case (extrinsic) x-y-z Euler angles are the same rotation; intrinsic ZYX reversed too
    E = np.array(lcg.Placement.euler((r, p, y), "xyz").rotation.evalf(), dtype=float)
    Z = np.array(lcg.Placement.euler((y, p, r), "ZYX").rotation.evalf(), dtype=float)
    assert np.allclose(E, R, atol=1e-15) and np.allclose(Z, R, atol=1e-15)


def test_placement_axis_angle_and_exact_folding():
    axis = np.array([1.0, 2.0, -0.5])
    R = np.array(lcg.Placement.axis_angle(axis, 0.7).rotation.evalf(), dtype=float)
    assert np.allclose(R, pin.AngleAxis(0.7, axis / np.linalg.norm(axis)).matrix(), atol=1e-15)
    # a quarter turn in floating point folds to exact 0 and +-1 (constants fold in the code)
    Rq = lcg.Placement(rpy=(np.pi / 2, 0, 0)).rotation
    assert Rq == sp.Matrix([[1, 0, 0], [0, 0, -1], [0, 1, 0]])
    th = sp.Symbol("th")
    assert lcg.Placement.axis_angle((0, 0, 1), th).rotation[0, 1] == -sp.sin(th)


@pytest.mark.parametrize("bad, message", [
    (dict(rotation=[[1, 0, 0], [0, 1, 0], [0, 0, 2]]), "not a proper rotation"),
    (dict(rpy=(0, 0, 0), rotation=np.eye(3).tolist()), "not both"),
    (dict(xyz=(0, 0)), "3 components"),
    (dict(xyz=("a", 0, 0)), "string"),
])
def test_placement_refuses_bad_input(bad, message):
    with pytest.raises(ModelError, match=message):
        lcg.Placement(**bad)


def test_link_api_coordinates_and_errors():
    m = lcg.Model("arm")
    base = m.link("base", mass=1, inertia=(1, 1, 1))
    a = m.link("a", parent="base", joint=lcg.Joint.revolute("shoulder", (0, 1, 0)), mass=1, inertia=(1, 1, 1))
    m.link("b", parent=a, joint=lcg.Joint.spherical("wrist", rotation="ZYX"), mass=1, inertia=(1, 1, 1))
    m.link("c", parent="b", joint=lcg.Joint.free("float", rotation="ZYX"), mass=1, inertia=(1, 1, 1))
    assert [q.name for q in m.coords] == ["shoulder", "wrist_yaw", "wrist_pitch", "wrist_roll", "float_x", "float_y",
                                          "float_z", "float_yaw", "float_pitch", "float_roll"]
    assert base.joint.kind == "fixed" and a.parent is base and a in base.children
    with pytest.raises(ModelError, match="no parent link named 'nope'"):
        m.link("d", parent="nope", joint=lcg.Joint.revolute("j"))
    with pytest.raises(ModelError, match="used twice"):
        m.link("e", parent="a", joint=lcg.Joint.revolute("shoulder"))
    with pytest.raises(ModelError, match="negative"):
        m.link("f", parent="a", joint=lcg.Joint.revolute("jf"), mass=-1)
    with pytest.raises(ModelError, match="not parameters"):
        m.link("g", parent="a", joint=lcg.Joint.revolute("jg"), mass=sp.Symbol("unknown"))
    with pytest.raises(ModelError, match="zero vector"):
        lcg.Joint.revolute("jz", (0, 0, 0))
    assert "jf" not in [q.name for q in m.coords]  # a refused link declares nothing


def test_forward_kinematics_matches_pinocchio():
    m, pm = build(5, kinds="RRP")
    data = pm.createData()
    q = np.random.default_rng(3).uniform(-2, 2, 5)
    pin.forwardKinematics(pm, data, q)
    sub = {s: x for s, x in zip(m.coords, q)}
    for i, link in enumerate(m.links):
        R = np.array(link.rotation().subs(sub).evalf(), dtype=float)
        x = np.array(link.position_of((0.1, 0.2, 0.3)).subs(sub).evalf(), dtype=float).ravel()
        ref = data.oMi[i + 1]
        assert np.allclose(R, ref.rotation, atol=1e-12)
        assert np.allclose(x, ref.act(np.array([0.1, 0.2, 0.3])), atol=1e-12)


# ---------------------------------------------------------------------- M and F against Pinocchio
def test_spatial_chain_matches_crba_rnea_aba():
    check_against_pinocchio(*build(6))


def test_prismatic_and_revolute_mix_matches_pinocchio():
    check_against_pinocchio(*build(6, kinds="RPRRP", seed=4))


def test_branched_tree_matches_pinocchio():
    # depth-first order (Pinocchio's CRBA needs each subtree's joints contiguous); link 0 has
    # two children (1 and 4), link 1 two (2 and 3)
    check_against_pinocchio(*build(6, kinds="RRP", parents=[-1, 0, 1, 1, 0, 4], seed=5))


def test_large_branched_tree_takes_the_world_frame_mass_matrix():
    from lagcodegen.model import treedynamics
    parents = [-1, 0, 1, 2, 3, 2, 5, 0, 7, 8, 8, 10]  # depth-first: branches at links 0, 2 and 8
    m, pm = build(len(parents), kinds="RRPR", parents=parents, seed=22)
    assert len(parents) >= treedynamics.WORLD_CRBA_MIN_NODES
    check_against_pinocchio(m, pm, states=20, seed=23)


def test_fixed_joint_is_merged_into_its_parent():
    rng = np.random.default_rng(6)
    m = lcg.Model("fixed")
    m.gravity(9.81)
    pm = pin.Model()
    pm.gravity = pin.Motion(np.array([0, 0, -9.81, 0, 0, 0]))
    data_links = [(rotation(rng), rng.uniform(-.5, .5, 3), rng.uniform(.5, 2), rng.uniform(-.2, .2, 3), inertia(rng))
                  for _ in range(4)]
    (R0, t0, m0, c0, I0), (R1, t1, m1, c1, I1), (R2, t2, m2, c2, I2), (R3, t3, m3, c3, I3) = data_links
    m.link("a", joint=lcg.Joint.revolute("ja", (0, 0, 1)), origin=lcg.Placement(tuple(t0), rotation=R0.tolist()),
           mass=m0, com=tuple(c0), inertia=six(I0))
    m.link("f", parent="a", joint=lcg.Joint.fixed("jf"), origin=lcg.Placement(tuple(t1), rotation=R1.tolist()),
           mass=m1, com=tuple(c1), inertia=six(I1))
    m.link("b", parent="f", joint=lcg.Joint.revolute("jb", (1, 0, 0)), origin=lcg.Placement(tuple(t2), rotation=R2.tolist()),
           mass=m2, com=tuple(c2), inertia=six(I2))
    m.link("c", parent="f", joint=lcg.Joint.prismatic("jc", (0, 1, 0)), origin=lcg.Placement(tuple(t3), rotation=R3.tolist()),
           mass=m3, com=tuple(c3), inertia=six(I3))
    ja = pm.addJoint(0, pin.JointModelRZ(), pin.SE3(R0, t0), "ja")
    pm.appendBodyToJoint(ja, pin.Inertia(m0, c0, I0), pin.SE3.Identity())
    Xf = pin.SE3(R1, t1)
    pm.appendBodyToJoint(ja, pin.Inertia(m1, c1, I1), Xf)  # the fixed link's inertia at its placement
    jb = pm.addJoint(ja, pin.JointModelRX(), Xf * pin.SE3(R2, t2), "jb")
    pm.appendBodyToJoint(jb, pin.Inertia(m2, c2, I2), pin.SE3.Identity())
    jc = pm.addJoint(ja, pin.JointModelPY(), Xf * pin.SE3(R3, t3), "jc")
    pm.appendBodyToJoint(jc, pin.Inertia(m3, c3, I3), pin.SE3.Identity())
    eom = check_against_pinocchio(m, pm)
    assert len(eom.tree.nodes) == 3  # three moving frames: the fixed link adds none


def test_spherical_and_free_joints_match_pinocchio_euler_joints():
    """A free joint is a translation in the parent frame then Z-Y-X Euler angles, a spherical joint
    those angles: Pinocchio's JointModelTranslation and JointModelSphericalZYX (whose velocities
    are the angles' rates too)."""
    rng = np.random.default_rng(7)
    m = lcg.Model("floating")
    m.gravity(9.81)
    pm = pin.Model()
    pm.gravity = pin.Motion(np.array([0, 0, -9.81, 0, 0, 0]))
    I0, c0, I1, c1 = inertia(rng), rng.uniform(-.3, .3, 3), inertia(rng), rng.uniform(-.3, .3, 3)
    R1, t1 = rotation(rng), rng.uniform(-.5, .5, 3)
    m.link("body", joint=lcg.Joint.free("base", rotation="ZYX"), origin=lcg.Placement((0.1, 0.2, 0.3)), mass=1.5,
           com=tuple(c0),
           inertia=six(I0))
    m.link("arm", parent="body", joint=lcg.Joint.spherical("ball", rotation="ZYX"), origin=lcg.Placement(tuple(t1), rotation=R1.tolist()),
           mass=0.7, com=tuple(c1), inertia=six(I1))
    j = pm.addJoint(0, pin.JointModelTranslation(), pin.SE3(np.eye(3), np.array([0.1, 0.2, 0.3])), "t")
    j = pm.addJoint(j, pin.JointModelSphericalZYX(), pin.SE3.Identity(), "r")
    pm.appendBodyToJoint(j, pin.Inertia(1.5, c0, I0), pin.SE3.Identity())
    j = pm.addJoint(j, pin.JointModelSphericalZYX(), pin.SE3(R1, t1), "ball")
    pm.appendBodyToJoint(j, pin.Inertia(0.7, c1, I1), pin.SE3.Identity())
    check_against_pinocchio(m, pm, seed=8)


def test_energy_views_and_momenta():
    m, pm = build(4, kinds="RP", seed=9)
    eom = lcg.derive(m)
    data = pm.createData()
    rng = np.random.default_rng(10)
    q, v = rng.uniform(-2, 2, 4), rng.uniform(-2, 2, 4)
    sub = {**{se.Symbol(s.name): x for s, x in zip(m.coords, q)}, **{se.Symbol(s.name): x for s, x in zip(m.speeds, v)},
           se.Symbol("g"): 9.81}
    T, V = float(eom.T_se.xreplace(sub)), float(eom.V_se.xreplace(sub))
    assert T == pytest.approx(pin.computeKineticEnergy(pm, data, q, v), rel=1e-12)
    assert V == pytest.approx(pin.computePotentialEnergy(pm, data, q), rel=1e-12, abs=1e-12)
    assert float(eom.h_se.xreplace(sub)) == pytest.approx(T + V, rel=1e-12)
    p = np.array([float(e.xreplace(sub)) for e in eom.p_se])
    assert np.allclose(p, pin_mass(pm, data, q) @ v, rtol=1e-12, atol=1e-12)
    # small trees keep their sympy views; deep ones refuse them with a message (never expanded)
    assert eom.M.shape == (4, 4)
    deep = lcg.derive(build(14, seed=11)[0])
    with pytest.raises(ModelError, match="kept as a program"):
        deep.F


# ---------------------------------------------------------------------- generated code
def test_compiled_rhs_matches_aba_and_tangent_jacobian_matches_differences():
    m, pm = build(5, kinds="RRP", seed=12)
    sim = lcg.compile_model(m, jacobian=True)
    data = pm.createData()
    rng = np.random.default_rng(13)
    for _ in range(20):
        q, v = rng.uniform(-3, 3, 5), rng.uniform(-2, 2, 5)
        a = sim.rhs(0.0, np.r_[q, v])[5:]
        ref = pin.aba(pm, data, q, v, np.zeros(5))
        assert np.abs(a - ref).max() <= 1e-11 * np.abs(ref).max()
    y = np.r_[rng.uniform(-1, 1, 5), rng.uniform(-1, 1, 5)]
    J = sim.jac(0.0, y)
    h = 1e-6
    Jfd = np.array([(sim.rhs(0.0, y + h * e) - sim.rhs(0.0, y - h * e)) / (2 * h) for e in np.eye(10)]).T
    assert np.abs(J - Jfd).max() <= 1e-6 * np.abs(Jfd).max()


def test_inverse_dynamics_function_matches_rnea():
    from lagcodegen.build import plain_library
    from lagcodegen.codegen import generate_code

    m, pm = build(6, kinds="RPR", parents=[-1, 0, 1, 0, 3, 4], seed=14)
    code = generate_code(lcg.Scene(lcg.derive(m), jacobian=False))
    assert "tree_dynamics.c" in code.files and "tree_inverse_dynamics" in code.files["tree_dynamics.h"]
    lib, _, _ = plain_library("inverse dynamics test", "tree", dict(code.files))
    fn = lib.tree_inverse_dynamics
    fn.restype = ctypes.c_int
    dp = ctypes.POINTER(ctypes.c_double)
    fn.argtypes = [ctypes.c_double, dp, dp, dp, dp]
    data = pm.createData()
    rng = np.random.default_rng(15)
    for _ in range(20):
        q, v, acc = rng.uniform(-3, 3, 6), rng.uniform(-2, 2, 6), rng.uniform(-5, 5, 6)
        y, p, tau = np.r_[q, v], np.array([9.81]), np.zeros(6)
        assert fn(0.0, y.ctypes.data_as(dp), acc.ctypes.data_as(dp), p.ctypes.data_as(dp), tau.ctypes.data_as(dp)) == 0
        ref = pin.rnea(pm, data, q, v, acc)
        assert np.abs(tau - ref).max() <= RTOL * np.abs(ref).max()


def test_compiled_model_inverse_dynamics_matches_rnea_and_closes_the_loop():
    m, pm = build(4, kinds="RPR", parents=[-1, 0, 1, 0], seed=21)
    sim = lcg.compile_model(m, jacobian=False)
    data = pm.createData()
    rng = np.random.default_rng(22)
    for _ in range(10):
        q, v, acc = rng.uniform(-2, 2, 4), rng.uniform(-2, 2, 4), rng.uniform(-3, 3, 4)
        tau = sim.inverse_dynamics(q, v, acc)
        ref = pin.rnea(pm, data, q, v, acc)
        assert np.abs(tau - ref).max() <= RTOL * np.abs(ref).max()
        # a second method: the forward dynamics of the compiled right-hand side gives back acc
        # where tau is zero, i.e. at tau = M a - F = 0 the accelerations are the rhs's
        free = sim.rhs(0.0, np.r_[q, v])[4:]
        assert np.abs(sim.inverse_dynamics(q, v, free)).max() <= 1e-10 * max(1.0, np.abs(ref).max())
    with pytest.raises(lcg.LagcodegenError, match="q has 3 values, expected 4"):
        sim.inverse_dynamics(np.zeros(3), np.zeros(4), np.zeros(4))
    plain = lcg.compile_model(lcg.systems.pendulum(), jacobian=False)
    with pytest.raises(lcg.LagcodegenError, match="rigid-body tree"):
        plain.inverse_dynamics([0.1], [0.0], [0.0])


def test_energy_is_conserved_cvode_and_taylor():
    m, _ = build(3, kinds="R", seed=16)
    sim = lcg.compile_model(m, jacobian=False, outputs=["jacobi_h"])
    rng = np.random.default_rng(17)
    q0, v0 = rng.uniform(-1, 1, 3), rng.uniform(-1, 1, 3)
    res = sim.simulate([0, 10], q0=q0, v0=v0, rtol=1e-11, atol=1e-12)
    h = res["jacobi_h"]
    assert np.abs(h - h[0]).max() <= 1e-7 * max(1.0, abs(h[0]))
    res = sim.simulate([0, 10], q0=q0, v0=v0, method="taylor", rtol=1e-12, atol=1e-12)
    h = res["jacobi_h"]
    assert np.abs(h - h[0]).max() <= 1e-9 * max(1.0, abs(h[0]))


def test_fortran_and_ensembles_on_a_tree():
    m, pm = build(3, kinds="RP", seed=18)
    sim_c = lcg.compile_model(m, jacobian=False)
    sim_f = lcg.compile_model(m, jacobian=False, lang="fortran")
    rng = np.random.default_rng(19)
    data = pm.createData()
    for _ in range(5):
        q, v = rng.uniform(-2, 2, 3), rng.uniform(-2, 2, 3)
        ref = pin.aba(pm, data, q, v, np.zeros(3))
        assert np.abs(sim_f.rhs(0.0, np.r_[q, v])[3:] - ref).max() <= 1e-11 * np.abs(ref).max()
        assert np.abs(sim_c.rhs(0.0, np.r_[q, v])[3:] - ref).max() <= 1e-11 * np.abs(ref).max()
    q0 = rng.uniform(-1, 1, (4, 3))
    ens = sim_c.ensemble(np.linspace(0, 1, 5), q0=q0, v0=np.zeros((4, 3)))
    for k in range(4):
        one = sim_c.simulate(np.linspace(0, 1, 5), q0=q0[k], v0=np.zeros(3))
        assert np.allclose(np.asarray(ens.final)[k][:3], one.y[-1, :3], rtol=1e-6, atol=1e-8)


def test_point_mass_and_spring_on_a_link():
    """A particle on the last link adds its inertia there (Pinocchio: an extra body of that mass at
    that point); a spring from a link point to the world conserves h with it."""
    m, pm = build(3, kinds="R", seed=20)
    pt = m.point_on("l2", (0.3, -0.1, 0.2), name="tip")
    m.particle("blob", 0.8, pt.position)
    anchor = m.point("anchor", (0.5, 0.5, 0.5))
    m.spring("tip", anchor, 40.0, rest_length=0.2)
    pm.appendBodyToJoint(3, pin.Inertia(0.8, np.array([0.3, -0.1, 0.2]), np.zeros((3, 3))), pin.SE3.Identity())
    eom = lcg.derive(m)
    data = pm.createData()
    rng = np.random.default_rng(21)
    for _ in range(20):
        q, v = rng.uniform(-3, 3, 3), rng.uniform(-2, 2, 3)
        M, _ = evaluate(eom, q, v)
        Mp = pin_mass(pm, data, q)
        assert np.abs(M - Mp).max() <= RTOL * np.abs(Mp).max()
    sim = lcg.compile_model(m, jacobian=False, outputs=["jacobi_h"])
    res = sim.simulate([0, 10], q0=rng.uniform(-1, 1, 3), v0=np.zeros(3), rtol=1e-11, atol=1e-12)
    h = res["jacobi_h"]
    assert np.abs(h - h[0]).max() <= 1e-7 * max(1.0, abs(h[0]))
