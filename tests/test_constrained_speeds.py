"""Constrained systems with generalized speeds (issue 37): quaternion (free) joints held by
holonomic constraints on the index-1 formulation, and their impacts (the jump acts on v),
checked against independent facts: the same systems in Z-Y-X angles (Lagrange's form, the
formulation that predates generalized speeds) and the analytic bounce of a dropped body."""

import numpy as np
import pytest

import lagcodegen as lcg
from lagcodegen.errors import ModelError
from lagcodegen.theory.constraints import ConstrainedSystem, Inequality

G0 = 9.81
INERTIA = (0.1, 0.2, 0.3, 0, 0, 0)


def zyx_quaternion(yaw, pitch, roll):
    """(x, y, z, w) of R = Rz(yaw) Ry(pitch) Rx(roll)."""
    cy, sy = np.cos(yaw / 2), np.sin(yaw / 2)
    cp, sp_ = np.cos(pitch / 2), np.sin(pitch / 2)
    cr, sr = np.cos(roll / 2), np.sin(roll / 2)
    return np.array([sr * cp * cy - cr * sp_ * sy, cr * sp_ * cy + sr * cp * sy, cr * cp * sy - sr * sp_ * cy,
                     cr * cp * cy + sr * sp_ * sy])


def pinned_body(rotation, pivot):
    """A rigid body on a free joint whose body point ``pivot`` is held at the origin (3 holonomic
    constraints): a heavy top with a fixed point."""
    m = lcg.Model("pinned_" + rotation.lower())
    m.link("body", joint=lcg.Joint.free("root", rotation=rotation), mass=1.0, inertia=INERTIA)
    m.gravity(G0)
    tip = m.point_on("body", pivot, "pivot")
    return ConstrainedSystem(m, holonomic=list(tip.position))


def test_pinned_body_quaternion_agrees_with_euler_angles():
    rb, w = np.array([0.1, 0.2, 0.5]), np.array([0.7, -1.1, 2.3])
    quat = lcg.compile_constrained(pinned_body("quaternion", rb))
    euler = lcg.compile_constrained(pinned_body("ZYX", rb))
    assert quat.system.model.general and (quat.n, quat.nv, quat.ny) == (7, 6, 13)
    vlin = -np.cross(w, rb)  # the pivot at rest: v + w x r_b = 0 (child frame, R = I)
    t = np.linspace(0.0, 3.0, 301)
    rq = quat.simulate(t, np.concatenate([-rb, [0, 0, 0, 1]]), np.concatenate([vlin, w]), rtol=1e-11, atol=1e-12)
    # Z-Y-X at zero angles: body rates (roll', pitch', yaw')
    rz = euler.simulate(t, np.concatenate([-rb, [0, 0, 0]]), np.concatenate([vlin, w[::-1]]), rtol=1e-11,
                        atol=1e-12)
    assert np.ptp(rq.y[:, :3], axis=0).min() > 0.05  # it moves
    assert np.abs(rq.y[:, :3] - rz.y[:, :3]).max() < 1e-9
    assert np.abs(np.linalg.norm(rq.y[:, 3:7], axis=1) - 1).max() < 1e-9
    g, s = quat.residuals(t[-1], rq.y[-1])
    assert np.abs(g).max() < 1e-9 and np.abs(s).max() < 1e-9
    # energy is conserved by the constrained motion
    assert np.ptp(rq["energy"]) < 1e-8
    assert list(rq.v) == [v.name for v in quat.system.model.v]


def test_projection_in_q_and_v():
    rb = np.array([0.1, 0.2, 0.5])
    sim = lcg.compile_constrained(pinned_body("quaternion", rb))
    y = np.concatenate([-rb + 1e-3, zyx_quaternion(0.2, 0.1, -0.3), [0.1, 0.2, 0.3, 0.4, 0.5, 0.6]])
    yp = sim.project(0.0, y)
    g, s = sim.residuals(0.0, yp)
    assert np.abs(g).max() < 1e-12 and np.abs(s).max() < 1e-12
    assert abs(np.linalg.norm(yp[3:7]) - 1) < 1e-14  # the quaternion renormalized (f depends on its direction)


def dropped_box(rotation, foot, e, tangent=None):
    m = lcg.Model("dropped_" + rotation.lower() + ("" if tangent is None else "_" + tangent))
    m.link("box", joint=lcg.Joint.free("root", rotation=rotation), mass=2.0, inertia=INERTIA)
    m.gravity(G0)
    if tangent is not None:  # a rough (no-slip) contact along one world axis
        return ConstrainedSystem(m, inequalities=[lcg.ground_contact(m, "box", foot, restitution=e, tangent=tangent)])
    pt = m.point_on("box", foot, "foot")
    return ConstrainedSystem(m, inequalities=[Inequality(pt.position[2], restitution=e)])


def test_floating_body_bounce_apex():
    """A body on a free joint spinning about its vertical principal axis, dropped from rest with
    its contact point h above the ground, directly below its centre of mass: after the bounce the
    contact point rises to e^2 h, at t = (1 + e) sqrt(2 h / g), its spin unchanged."""
    e, h, r, yaw, wz = 0.6, 0.4, 0.1, 0.7, 3.0
    sim = lcg.compile_constrained(dropped_box("quaternion", (0, 0, -r), e))
    t1 = np.sqrt(2 * h / G0)
    t_apex = t1 * (1 + e)
    q0 = [0, 0, h + r, 0, 0, np.sin(yaw / 2), np.cos(yaw / 2)]
    res = sim.simulate(np.array([0.0, 0.5 * t1, t_apex]), q0, [0, 0, 0, 0, 0, wz], rtol=1e-12, atol=1e-13)
    (bounce,) = res.impacts.select("bounce")
    assert bounce.t == pytest.approx(t1, abs=1e-10)
    assert bounce.w_after == pytest.approx(-e * bounce.w_before, rel=1e-10)
    y = res.y[-1]
    assert abs(y[2] - r - e * e * h) < 1e-8 and abs(y[9]) < 1e-8  # apex: height e^2 h, at rest vertically
    yaw_end = yaw + wz * t_apex
    assert np.allclose(y[3:7], [0, 0, np.sin(yaw_end / 2), np.cos(yaw_end / 2)], atol=1e-8) or \
        np.allclose(y[3:7], [0, 0, -np.sin(yaw_end / 2), -np.cos(yaw_end / 2)], atol=1e-8)


@pytest.mark.parametrize("tangent", [None, "x"])
def test_tilted_body_impact_agrees_with_euler_angles(tangent):
    """A tilted body dropped on a corner: the impulse makes it spin; the quaternion (free joint,
    jump on v) and Z-Y-X (jump on q') runs agree through the impacts, frictionless or with a
    no-slip row along x (a tangential row in v)."""
    e, foot, angles = 0.5, (0.1, 0.05, -0.1), (0.3, 0.4, -0.2)
    quat = lcg.compile_constrained(dropped_box("quaternion", foot, e, tangent))
    euler = lcg.compile_constrained(dropped_box("ZYX", foot, e, tangent))
    t = np.linspace(0.0, 0.6, 61)
    rq = quat.simulate(t, np.concatenate([[0, 0, 0.5], zyx_quaternion(*angles)]), np.zeros(6), rtol=1e-11,
                       atol=1e-12)
    rz = euler.simulate(t, np.array([0, 0, 0.5, *angles]), np.zeros(6), rtol=1e-11, atol=1e-12)
    kinds = [r.kind for r in rq.impacts]
    assert "bounce" in kinds and kinds == [r.kind for r in rz.impacts]
    assert np.allclose([r.t for r in rq.impacts], [r.t for r in rz.impacts], atol=1e-8)
    assert np.allclose([r.impulse for r in rq.impacts], [r.impulse for r in rz.impacts], rtol=1e-7, atol=1e-9)
    assert np.abs(rq.y[:, :3] - rz.y[:, :3]).max() < 1e-7
    assert np.abs(rq.y[-1, 7:10]).max() > 0.1  # it turned


def test_generalized_speeds_refused_where_not_supported():
    system = pinned_body("quaternion", (0.1, 0.2, 0.5))
    with pytest.raises(ModelError, match="generalized speeds.*formulation 'minimal' does not take"):
        lcg.compile_constrained(system, "minimal")
    # GGL (test_ggl_with_generalized_speeds_agrees_with_index1) and Fortran
    # (tests/codegen/test_fortran_constrained.py) take them
    # bundles take them (tests/codegen/test_bundle_constrained.py)


def test_integrator_and_ensemble_with_generalized_speeds():
    rb, w = np.array([0.1, 0.2, 0.5]), np.array([0.7, -1.1, 2.3])
    sim = lcg.compile_constrained(pinned_body("quaternion", rb))
    q0, v0 = np.concatenate([-rb, [0, 0, 0, 1]]), np.concatenate([-np.cross(w, rb), w])
    it = sim.integrator(q0=q0, v0=v0, rtol=1e-11, atol=1e-12)
    it.propagate_until(1.5)
    res = sim.simulate(np.array([0.0, 1.5]), q0, v0, rtol=1e-11, atol=1e-12)
    assert np.asarray(it.state).shape == (13,) and np.abs(np.asarray(it.state) - res.y[-1]).max() < 1e-12
    # an ensemble (one native call over a thread pool) is simulate member by member, bit for bit
    spins = [w, 2 * w, -0.5 * w]
    V0 = np.array([np.concatenate([-np.cross(x, rb), x]) for x in spins])
    t = np.linspace(0.0, 1.5, 4)
    ens = sim.ensemble(t, q0=q0, v0=V0, save="trajectory", threads=2, rtol=1e-11, atol=1e-12)
    assert ens.y.shape == (3, 13) and np.all(ens.status >= 0)
    for i in range(3):
        one = sim.simulate(t, q0, V0[i], rtol=1e-11, atol=1e-12)
        assert np.array_equal(ens.member(i).y, one.y) and np.array_equal(ens.y[i], one.y[-1])
        assert np.array_equal(ens["root_wz"][i], one["root_wz"]) and np.array_equal(ens["energy"][i], one["energy"])
    with pytest.raises(lcg.LagcodegenError, match="v0 has shape"):
        sim.ensemble(t, q0=q0, v0=np.zeros((3, 7)))


def test_ggl_with_generalized_speeds_agrees_with_index1():
    """The GGL form on IDA (q' - k(q, v) - Aq^T mu, M v' - F - A_v^T lambda, f, A_v v) of the pinned
    quaternion body: the same motion as the index-1 run, on the constraints, mu ~ 0, |q| = 1; its
    integrator object and ensemble are its runs; the Fortran functions run as the C ones."""
    rb, w = np.array([0.1, 0.2, 0.5]), np.array([0.7, -1.1, 2.3])
    system = pinned_body("quaternion", rb)
    ggl = lcg.compile_constrained(system, "ggl")
    ref = lcg.compile_constrained(system)
    assert (ggl.n, ggl.nv, ggl.ny, ggl.info.ng) == (7, 6, 13, 19)
    q0, v0 = np.concatenate([-rb, [0, 0, 0, 1]]), np.concatenate([-np.cross(w, rb), w])
    t = np.linspace(0.0, 3.0, 31)
    res = ggl.simulate(t, q0, v0, rtol=1e-10, atol=1e-12)
    exact = ref.simulate(t, q0, v0, rtol=1e-12, atol=1e-13)
    assert res.y.shape == (31, 13) and np.ptp(res.y[:, :3], axis=0).min() > 0.05
    assert np.abs(res.y - exact.y).max() < 1e-7
    assert np.abs(np.linalg.norm(res.y[:, 3:7], axis=1) - 1).max() < 1e-8
    g, s = ggl.residuals(t[-1], res.y[-1])
    assert np.abs(g).max() < 1e-12 and np.abs(s).max() < 1e-12  # GGL holds both levels
    assert max(np.abs(res[f"mu_{k}"]).max() for k in range(3)) < 1e-6
    assert np.ptp(res["energy"]) < 1e-7
    it = ggl.integrator(q0=q0, v0=v0, rtol=1e-10, atol=1e-12)
    it.propagate_until(1.5)
    half = ggl.simulate(np.array([0.0, 1.5]), q0, v0, rtol=1e-10, atol=1e-12)
    assert np.asarray(it.state).shape == (13,) and np.abs(np.asarray(it.state) - half.y[-1]).max() < 1e-9
    V0 = np.array([v0, np.concatenate([-np.cross(2 * w, rb), 2 * w])])
    ens = ggl.ensemble(t, q0=q0, v0=V0, rtol=1e-10, atol=1e-12)
    assert np.array_equal(ens.y[0], res.y[-1])
    fortran = lcg.compile_constrained(system, "ggl", lang="fortran")
    assert np.abs(fortran.simulate(t, q0, v0, rtol=1e-10, atol=1e-12).y - res.y).max() < 1e-12


def test_linearize_pinned_quaternion_body_at_rest_and_spinning():
    """linearize of a constrained system with generalized speeds (tangent coordinates, one per
    speed): the body on a free joint pinned at a body point above its centre of mass is the
    pendulum on a ball joint. At rest its frequencies are those of the same pinned body on Z-Y-X
    angles and of the body on a spherical joint; spinning at 3 rad/s about the vertical (a steady
    motion whose coefficients in body-frame speeds stay constant) those of the spherical joint's
    on quaternions and on Z-Y-X angles (unconstrained, their own linearization), and those of the
    pinned body on Z-Y-X angles."""
    rb = np.array([0.0, 0.0, 0.5])

    def ball(rotation):
        m = lcg.Model("ball_" + rotation.lower())
        m.gravity(G0)
        m.link("body", joint=lcg.Joint.spherical("ball", rotation=rotation), mass=1.0, com=tuple(-rb),
               inertia=INERTIA[:3])
        return lcg.derive(m)

    def same(a, b):
        return np.allclose(np.sort_complex(np.round(a, 9)), np.sort_complex(np.round(b, 9)), rtol=0, atol=1e-8)

    q0 = np.concatenate([-rb, [0, 0, 0, 1]])
    rest = lcg.linearize(pinned_body("quaternion", rb), q0=q0)
    assert rest.coordinates == ["root_wx", "root_wy", "root_wz"] and rest.dependent_speeds == ["root_vx", "root_vy",
                                                                                              "root_vz"]
    euler = lcg.linearize(pinned_body("ZYX", rb), q0=np.concatenate([-rb, [0, 0, 0]]))
    assert same(rest.eigenvalues, euler.eigenvalues)
    assert same(rest.eigenvalues, lcg.linearize(ball("quaternion"), q0=[0, 0, 0, 1]).eigenvalues)
    w = 3.0
    spin = lcg.linearize(pinned_body("quaternion", rb), q0=q0, v0=[0, 0, 0, 0, 0, w])
    assert np.max(np.abs(spin.multipliers - [0, 0, G0])) < 1e-12  # the pivot holds the weight (m = 1)
    free_q = lcg.linearize(ball("quaternion"), q0=[0, 0, 0, 1], v0=[0, 0, w])
    free_e = lcg.linearize(ball("ZYX"), q0=[0, 0, 0], v0=[w, 0, 0])
    assert same(spin.eigenvalues, free_q.eigenvalues) and same(spin.eigenvalues, free_e.eigenvalues)
    # on Z-Y-X angles the dependent speeds (the world-frame velocity of the body's origin) turn with the
    # yaw along this motion: the basis' rates B0', D' enter (frozen, the frequencies were 5.03 and 3.13)
    spin_e = lcg.linearize(pinned_body("ZYX", rb), q0=np.concatenate([-rb, [0, 0, 0]]), v0=[0, 0, 0, w, 0, 0])
    assert same(spin_e.eigenvalues, free_e.eigenvalues)
    assert np.ptp(np.abs(spin.eigenvalues.imag)) > 1.0 and spin.stable()


def test_ground_contact_refusals():
    m = lcg.Model("contact_refusals")
    m.link("box", joint=lcg.Joint.free("root"), mass=1.0, inertia=INERTIA)
    with pytest.raises(ModelError, match="friction needs a tangent direction"):
        lcg.ground_contact(m, "box", (0, 0, -0.1), restitution=0.0, friction=1.0)
    with pytest.raises(ModelError, match="tangent must be None, 'x', 'y' .* or 'xy'"):
        lcg.ground_contact(m, "box", (0, 0, -0.1), restitution=0.0, tangent="z")
    rough = lcg.ground_contact(m, "box", (0, 0, -0.1), restitution=0.0, tangent="xy", friction=0.5)
    assert isinstance(rough.tangent, tuple) and len(rough.tangent) == 2  # 3-D: both world axes


SOLO12_POSE = {f"{leg}_{j}": v for leg in ("FL", "FR", "HL", "HR")
               for j, v in zip(("HAA", "HFE", "KFE"), (0.0, 0.8, -1.6) if leg[0] == "F" else (0.0, -0.8, 1.6))}


def solo12_path():
    """example-robot-data's Solo12 URDF (installed with Pinocchio)."""
    from pathlib import Path

    pin = pytest.importorskip("pinocchio")
    return (Path(pin.__file__).resolve().parents[4] / "share" / "example-robot-data" / "robots" / "solo_description"
            / "robots" / "solo12.urdf")


def solo12_feet(path):
    """The foot points: the URDF's fixed foot frames, as (lower-leg link, xyz in its frame)."""
    import xml.etree.ElementTree as ET

    feet = {}
    for joint in ET.parse(path).getroot().findall("joint"):
        if joint.find("child").get("link").endswith("_FOOT"):
            feet[joint.find("parent").get("link")] = [float(x) for x in joint.find("origin").get("xyz").split()]
    assert len(feet) == 4
    return feet


def solo12_on_the_ground(friction=None, formulation="index1"):
    """Solo12 on Pinocchio's free flyer, its 12 joints held by PD torques -20 (q - q_ref) - 0.5 q'
    about a standing posture, restitution-0 contacts at the four feet: frictionless, or with
    ``friction`` mu on the exact circular cone (ground_contact(tangent="xy")). Returns (model,
    compiled system, q0 with the base at 0.3 m)."""
    from lagcodegen.modelfile import urdf

    path = solo12_path()
    m = urdf.load(path, floating=True)
    for name, ref in SOLO12_POSE.items():
        q = m.coords[m.index(name)]
        m.generalized_force(q, -20.0 * (q - ref) - 0.5 * m.dot(q))
    rough = {} if friction is None else {"tangent": "xy", "friction": friction}
    contacts = [lcg.ground_contact(m, link, xyz, restitution=0.0, **rough) for link, xyz in solo12_feet(path).items()]
    options = {"jacobian": False} if formulation == "ggl" else {}  # the contact driver's own residual
    sim = lcg.compile_constrained(ConstrainedSystem(m, inequalities=contacts), formulation, **options)
    q0 = np.array(m.neutral())
    for name, ref in SOLO12_POSE.items():
        q0[m.index(name)] = ref
    q0[2] = 0.3
    return m, sim, q0


def solo12_feet_world(m):
    """A function of a state y of ``m`` (Solo12 on the free flyer) giving the four feet's world
    positions (FL, FR, HL, HR; 4 x 3) by Pinocchio's forward kinematics (an independent check)."""
    pin = pytest.importorskip("pinocchio")
    model = pin.buildModelFromUrdf(str(solo12_path()), pin.JointModelFreeFlyer())
    data = model.createData()
    frames = [model.getFrameId(f"{leg}_FOOT") for leg in ("FL", "FR", "HL", "HR")]

    def feet(y):
        q = np.empty(model.nq)
        q[:7] = y[:7]
        for name in SOLO12_POSE:
            q[model.idx_qs[model.getJointId(name)]] = y[m.index(name)]
        pin.framesForwardKinematics(model, data, q)
        return np.array([data.oMf[f].translation for f in frames])

    return feet


def test_solo12_lands_on_four_feet_and_rests_without_slipping():
    """Solo12 (PD-held joints) dropped with its base at 0.3 m onto a floor with Coulomb friction
    mu = 1 at its four feet (3-D, circular cone): it lands on the four feet at once, with
    tangential impulses within the cone, comes to rest sticking (no slip transition; the feet's
    slip velocities ~0), the contact forces carry its weight (total mass by Pinocchio's
    computeTotalMass) to 1e-6 and each foot's friction force is within mu times its normal force.
    (The frictionless drop, the same system without tangents, is in
    benchmarks/constrained_speeds.py and benchmarks/contact_mujoco.py.)"""
    pin = pytest.importorskip("pinocchio")
    m, sim, q0 = solo12_on_the_ground(friction=1.0)
    res = sim.simulate(np.linspace(0.0, 3.0, 61), q0, np.zeros(m.nv), rtol=1e-8, atol=1e-10, method="bdf")
    lands = [r for r in res.impacts if r.kind == "stick"]
    assert sorted(r.contact for r in lands) == [0, 1, 2, 3]
    assert np.ptp([r.t for r in lands]) < 1e-9  # the four feet at once (a symmetric posture)
    tangential = {r.contact: r for r in res.impacts if r.kind == "tangential_impulse"}
    for r in lands:  # the landing impulses within the cone, the feet's slip stopped by them
        assert tangential[r.contact].impulse <= 1.0 * r.impulse and abs(tangential[r.contact].w_after) < 1e-9
    assert res.impacts.transitions() == []  # never slips
    assert res.impacts.final_modes == {k: "contact" for k in range(4)}
    assert res.impacts.friction_modes == {k: "stick" for k in range(4)}
    assert np.abs(res.y[-1, m.nq:]).max() < 1e-6  # at rest
    weight = pin.computeTotalMass(pin.buildModelFromUrdf(str(solo12_path()), pin.JointModelFreeFlyer())) * 9.81
    normal = np.array([res[f"lambda_ineq_{k}"][-1] for k in range(4)])
    assert normal.sum() == pytest.approx(weight, rel=1e-6)
    friction = np.array([np.hypot(res[f"lambda_t0_ineq_{k}"][-1], res[f"lambda_t1_ineq_{k}"][-1]) for k in range(4)])
    assert np.all(friction > 0.1 * normal) and np.all(friction <= 1.0 * normal)  # held by friction, within the cone
    # no foot slips: the feet's world x, y by Pinocchio's kinematics stay where they landed
    feet_xy = solo12_feet_world(m)
    after = res.y[res.t > lands[0].t + 1e-9]
    landed = feet_xy(after[0])
    assert np.abs(landed[:, 2]).max() < 1e-8  # on the floor
    drift = max(np.abs(feet_xy(y)[:, :2] - landed[:, :2]).max() for y in after)
    assert drift < 1e-8
    assert np.abs(res.y[-1, :2]).max() < 1e-8  # no horizontal drift of the base


def test_solo12_with_low_friction_lands_and_its_four_feet_slip_together_then_rest():
    """The same drop with mu = 0.2: after landing the legs splay, the four feet reach the cone
    within 1e-4 s of one another and slip together (coupled 3-D slips, their directions found
    jointly; the driver before stopped with a false Painleve inconsistency at t = 0.173 s), then
    grip again and the robot comes to rest: the normal forces carry its weight to 1e-6, each foot's
    friction within the cone, while slipping mu times its normal force; the feet moved apart (by
    Pinocchio's kinematics). MuJoCo's run of the same drop (benchmarks/contact_mujoco.py) agrees
    on the resting height and the feet's final spread."""
    pin = pytest.importorskip("pinocchio")
    m, sim, q0 = solo12_on_the_ground(friction=0.2)
    res = sim.simulate(np.linspace(0.0, 1.5, 301), q0, np.zeros(m.nv), rtol=1e-8, atol=1e-10, method="bdf")
    land = min(r.t for r in res.impacts if r.kind == "stick")
    slips = {r.contact: r.t for r in res.impacts.transitions() if r.kind == "slip"}
    grips = {r.contact: r.t for r in res.impacts.transitions() if r.kind == "grip"}
    assert sorted(slips) == [0, 1, 2, 3] and sorted(grips) == [0, 1, 2, 3]
    assert np.ptp(list(slips.values())) < 1e-4 and min(slips.values()) > land
    assert res.impacts.final_modes == {k: "contact" for k in range(4)}
    assert res.impacts.friction_modes == {k: "stick" for k in range(4)}
    assert np.abs(res.y[-1, m.nq:]).max() < 1e-6
    weight = pin.computeTotalMass(pin.buildModelFromUrdf(str(solo12_path()), pin.JointModelFreeFlyer())) * 9.81
    normal = np.array([res[f"lambda_ineq_{k}"] for k in range(4)])
    friction = np.array([np.hypot(res[f"lambda_t0_ineq_{k}"], res[f"lambda_t1_ineq_{k}"]) for k in range(4)])
    assert normal[:, -1].sum() == pytest.approx(weight, rel=1e-6)
    on = res.t > land + 1e-9
    assert np.all(friction[:, on] <= 0.2 * normal[:, on] * (1 + 1e-9) + 1e-12)
    sliding = (res.t > max(slips.values()) + 1e-6) & (res.t < min(grips.values()) - 1e-6)
    assert sliding.sum() >= 3
    assert np.allclose(friction[:, sliding], 0.2 * normal[:, sliding], rtol=1e-9, atol=0)
    feet = solo12_feet_world(m)
    spread = [np.linalg.norm(f[:, :2] - f[:, :2].mean(axis=0), axis=1) for f in (feet(res.y[on][0]), feet(res.y[-1]))]
    assert np.all(spread[1] > spread[0] + 1e-3)  # each foot slid outward by more than a millimetre
    assert np.abs(feet(res.y[-1])[:, 2]).max() < 1e-8


def test_solo12_with_low_friction_on_ggl_rests_where_index1_rests():
    """The mu = 0.2 drop on the GGL driver (IDA; the floating base's quaternion corrected along the
    speeds' images): it lands at the index-1 run's landing time, its four feet slip and grip
    again, and it comes to rest at the index-1 run's base pose to 1e-6 with the normal forces
    carrying its weight to 1e-6."""
    pin = pytest.importorskip("pinocchio")
    t = np.linspace(0.0, 1.5, 31)
    runs = {}
    for formulation in ("index1", "ggl"):
        m, sim, q0 = solo12_on_the_ground(friction=0.2, formulation=formulation)
        runs[formulation] = sim.simulate(t, q0, np.zeros(m.nv), rtol=1e-8, atol=1e-10)
    ggl, index1 = runs["ggl"], runs["index1"]
    land = {f: min(r.t for r in res.impacts if r.kind == "stick") for f, res in runs.items()}
    assert land["ggl"] == pytest.approx(land["index1"], abs=1e-9)
    assert sorted({r.contact for r in ggl.impacts.transitions() if r.kind == "slip"}) == [0, 1, 2, 3]
    assert ggl.impacts.friction_modes == {k: "stick" for k in range(4)}
    assert np.abs(ggl.y[-1, :7] - index1.y[-1, :7]).max() < 1e-6
    weight = pin.computeTotalMass(pin.buildModelFromUrdf(str(solo12_path()), pin.JointModelFreeFlyer())) * 9.81
    assert sum(ggl[f"lambda_ineq_{k}"][-1] for k in range(4)) == pytest.approx(weight, rel=1e-6)


def quat_mul(a, b):
    """Hamilton product of (x, y, z, w) quaternions."""
    av, aw, bv, bw = np.asarray(a[:3]), a[3], np.asarray(b[:3]), b[3]
    return np.concatenate([aw * bv + bw * av + np.cross(av, bv), [aw * bw - av @ bv]])


def test_rolling_sphere_nonholonomic_rows_in_quaternion_rates():
    """A uniform ball on a free joint (quaternion) held on the plane z = r (holonomic) and rolling
    without slip (two Pfaffian rows in q': the contact point's horizontal velocity x' - r w_y,
    y' + r w_x with the world angular velocity w = 2 vec(q' q*)): its centre moves at constant
    velocity and it turns at its constant initial angular velocity, q(t) = exp(w t / 2) q0."""
    import sympy as sp

    r = 0.2
    m = lcg.Model("rolling_ball")
    m.link("ball", joint=lcg.Joint.free("root"), mass=1.0, inertia=(0.4 * r * r,) * 3 + (0, 0, 0))
    m.gravity(G0)
    qx, qy, qz, qw = (m.coords[m.index(f"root_q{c}")] for c in "xyzw")
    vec, dvec = sp.Matrix([qx, qy, qz]), sp.Matrix([m.dot(qx), m.dot(qy), m.dot(qz)])
    w = 2 * (qw * dvec - m.dot(qw) * vec + vec.cross(dvec))  # world angular velocity, |q| = 1
    x, y, z = (m.coords[m.index(f"root_{c}")] for c in "xyz")
    rows = [sp.expand(m.dot(x) - r * w[1]), sp.expand(m.dot(y) + r * w[0])]

    def pfaffian(expr):
        return [sp.diff(expr, m.dot(q)) for q in m.coords]

    system = ConstrainedSystem(m, holonomic=[z - r], nonholonomic=[pfaffian(e) for e in rows],
                               check_integrability=False)
    sim = lcg.compile_constrained(system)
    q0 = zyx_quaternion(0.4, -0.7, 1.1)
    qx0, qy0, qz0, qw0 = q0
    R0 = np.array([[1 - 2 * (qy0**2 + qz0**2), 2 * (qx0 * qy0 - qz0 * qw0), 2 * (qx0 * qz0 + qy0 * qw0)],
                   [2 * (qx0 * qy0 + qz0 * qw0), 1 - 2 * (qx0**2 + qz0**2), 2 * (qy0 * qz0 - qx0 * qw0)],
                   [2 * (qx0 * qz0 - qy0 * qw0), 2 * (qy0 * qz0 + qx0 * qw0), 1 - 2 * (qx0**2 + qy0**2)]])
    w_world = np.array([1.5, -2.0, 0.8])
    v_world = np.array([r * w_world[1], -r * w_world[0], 0.0])  # rolling: v = w x (r e_z)
    t = np.linspace(0.0, 2.0, 21)
    res = sim.simulate(t, np.concatenate([[0, 0, r], q0]), np.concatenate([R0.T @ v_world, R0.T @ w_world]),
                       rtol=1e-11, atol=1e-12)
    assert np.abs(res.y[:, :3] - np.outer(t, v_world) - [0, 0, r]).max() < 1e-8
    speed = np.linalg.norm(w_world)
    for k, tk in enumerate(t):
        turn = np.concatenate([np.sin(speed * tk / 2) * w_world / speed, [np.cos(speed * tk / 2)]])
        expected = quat_mul(turn, q0)
        assert min(np.abs(res.y[k, 3:7] - expected).max(), np.abs(res.y[k, 3:7] + expected).max()) < 1e-8
