"""Ground contacts from URDF ``<collision>`` spheres (issue 39): the reader keeps each link's
collisions, :func:`lagcodegen.modelfile.urdf.ground_contacts` makes each sphere a contact
g = z(centre) - r - ground >= 0. Checked against Pinocchio's own reading of the same file (its
collision geometry model: the spheres' radii and placements) and against statics: ANYmal B
dropped on its four foot spheres comes to rest carrying its weight (Pinocchio's total mass)."""

from pathlib import Path

import numpy as np
import pytest
import sympy as sp

import lagcodegen as lcg
from lagcodegen.modelfile import urdf
from lagcodegen.modelfile.urdfxml import URDFError
from lagcodegen.theory.constraints import ConstrainedSystem

pin = pytest.importorskip("pinocchio")

ROBOTS = Path(pin.__file__).resolve().parents[4] / "share" / "example-robot-data" / "robots"
ANYMAL = ROBOTS / "anymal_b_simple_description" / "robots" / "anymal.urdf"
FEET = ("LF_FOOT", "RF_FOOT", "LH_FOOT", "RH_FOOT")
#: example-robot-data's "standing" posture of ANYmal B (srdf/anymal.srdf)
STANDING = {f"{leg}_{j}": v for leg in ("LF", "RF", "LH", "RH")
            for j, v in zip(("HAA", "HFE", "KFE"), ((-0.1 if leg[0] == "L" else 0.1),
                                                    (0.7 if leg[1] == "F" else -0.7),
                                                    (-1.0 if leg[1] == "F" else 1.0)))}
SPHERE = """<robot name="ball"><link name="ball">
  <inertial><mass value="2.0"/><inertia ixx="{I}" ixy="0" ixz="0" iyy="{I}" iyz="0" izz="{I}"/></inertial>
  <collision><origin xyz="0 0 0"/><geometry><sphere radius="{r}"/></geometry></collision>
</link><link name="arm"><inertial><mass value="1e-9"/><inertia ixx="1e-12" ixy="0" ixz="0" iyy="1e-12" iyz="0"
izz="1e-12"/></inertial></link>
<joint name="spin" type="continuous"><parent link="ball"/><child link="arm"/><axis xyz="0 0 1"/></joint></robot>"""


def pin_model():
    return pin.buildModelFromUrdf(str(ANYMAL), pin.JointModelFreeFlyer())


def pin_q(model, m, y):
    """Pinocchio's q of the lagcodegen state ``y`` (joints matched by name)."""
    q = np.empty(model.nq)
    q[:7] = y[:7]
    for jid in range(2, model.njoints):
        q[model.idx_qs[jid]] = y[m.index(model.names[jid])]
    return q


def pin_spheres(model, path):
    """Pinocchio's collision spheres of the URDF at ``path``: parent frame (link) name -> its
    geometry object (radius, placement in the parent joint's frame)."""
    geom = pin.buildGeomFromUrdf(model, str(path), pin.GeometryType.COLLISION,
                                 package_dirs=[str(ROBOTS.parent), str(ROBOTS.parent.parent)])
    return {model.frames[o.parentFrame].name: o for o in geom.geometryObjects if type(o.geometry).__name__ == "Sphere"}


@pytest.mark.filterwarnings("ignore:.*Coulomb friction of joint")  # go1's joint friction: not used here
@pytest.mark.parametrize("path", [ANYMAL, ROBOTS / "go1_description" / "urdf" / "go1.urdf",
                                  ROBOTS / "hyq_description" / "robots" / "hyq_no_sensors.urdf"],
                         ids=["anymal_b", "go1", "hyq"])
def test_spheres_and_gaps_match_pinocchio(path):
    """The foot spheres as Pinocchio's collision model reads them (link, radius), and each
    contact's gap at random configurations of the floating robot equals the height of
    Pinocchio's sphere centre (its parent joint's placement times the collision placement)
    minus the radius, above a ground at 0.05 m."""
    robot = urdf.read(path)
    found = urdf.spheres(robot)
    model = pin.buildModelFromUrdf(str(path), pin.JointModelFreeFlyer())
    balls = pin_spheres(model, path)
    assert len(found) == 4 and sorted(link for link, _ in found) == sorted(balls)
    for link, c in found:
        assert c.radius == balls[link].geometry.radius
    m = urdf.load(path, floating=True)
    contacts = urdf.ground_contacts(m, path, restitution=0.0, ground=0.05)
    assert len(contacts) == 4 and list(m.points) == [f"{link}_sphere_0" for link, _ in found]
    gaps = sp.lambdify(m.coords, [c.expr for c in contacts], "numpy")
    data = model.createData()
    rng = np.random.default_rng(7)
    for _ in range(5):
        y = np.array(m.neutral(), dtype=float)
        y[:3] = rng.uniform(-1, 1, 3)
        quat = rng.normal(size=4)
        y[3:7] = quat / np.linalg.norm(quat)
        y[7:] = rng.uniform(-1.5, 1.5, m.nq - 7)
        pin.forwardKinematics(model, data, pin_q(model, m, y))
        expected = [(data.oMi[balls[link].parentJoint] * balls[link].placement).translation[2] - c.radius - 0.05
                    for link, c in found]
        assert np.allclose(gaps(*y), expected, rtol=0, atol=1e-12)


def test_anymal_foot_spheres():
    """ANYmal B's four foot spheres (radius 0.031, 2.325 cm above the foot frames, which fixed
    joints weld to the shanks), its other collisions kept by kind; links= picks some."""
    robot = urdf.read(ANYMAL)
    found = urdf.spheres(robot)
    assert [link for link, _ in found] == list(FEET)
    assert all(c.radius == 0.031 and c.xyz == (0.0, 0.0, 0.02325) for _, c in found)
    kinds = {c.kind for lk in robot.links.values() for c in lk.collisions}
    assert kinds == {"sphere", "box", "cylinder"}
    m = urdf.load(ANYMAL, floating=True)
    contacts = urdf.ground_contacts(m, ANYMAL, restitution=0.0)
    gaps = sp.lambdify(m.coords, [c.expr for c in contacts], "numpy")
    model = pin_model()
    data = model.createData()
    y = np.array(m.neutral(), dtype=float)
    y[:7] = [0.1, -0.2, 0.5, 0.1, 0.2, -0.3, 0.927]
    y[3:7] /= np.linalg.norm(y[3:7])
    for name, ref in STANDING.items():
        y[m.index(name)] = ref
    pin.framesForwardKinematics(model, data, pin_q(model, m, y))
    assert np.allclose(gaps(*y), [(data.oMf[model.getFrameId(f)].act(np.array([0, 0, 0.02325])))[2] - 0.031
                                  for f in FEET], rtol=0, atol=1e-12)
    m2 = urdf.load(ANYMAL, floating=True)
    assert len(urdf.ground_contacts(m2, ANYMAL, restitution=0.0, links=["LF_FOOT", "RH_FOOT"])) == 2
    assert list(m2.points) == ["LF_FOOT_sphere_0", "RH_FOOT_sphere_0"]


def test_bad_input_names_file_and_link(tmp_path):
    m = urdf.load(ANYMAL, floating=True)
    with pytest.raises(URDFError, match=r"anymal\.urdf.*link 'LF_SHANK' has no <collision> sphere.*box"):
        urdf.ground_contacts(m, ANYMAL, restitution=0.0, links=["LF_SHANK"])
    with pytest.raises(URDFError, match=r"anymal\.urdf.*no link named 'LF_TOE'"):
        urdf.ground_contacts(m, ANYMAL, restitution=0.0, links=["LF_TOE"])
    text = ANYMAL.read_text()
    for radius, why in (("0.0", "is not positive"), ("-0.031", "is not positive"), ("inf", "is not finite"),
                        ("nan", "is not finite")):
        bad = tmp_path / "bad.urdf"
        bad.write_text(text.replace('<sphere radius="0.031"/>', f'<sphere radius="{radius}"/>', 1))
        robot = urdf.read(bad)  # the dynamics do not use collisions: the file still loads
        with pytest.raises(URDFError, match=rf"bad\.urdf:\d+: link 'LF_FOOT' <collision> <sphere>.*{why}"):
            urdf.ground_contacts(m, robot, restitution=0.0)
    fixed = SPHERE.format(I=0.01, r=0.1)  # the ball is the root of a fixed base
    with pytest.raises(URDFError, match="link 'ball' is welded to the fixed base"):
        urdf.ground_contacts(urdf.loads(fixed), urdf.parse(fixed), restitution=0.0, links=["ball"])
    assert urdf.ground_contacts(urdf.loads(fixed), urdf.parse(fixed), restitution=0.0) == []
    with pytest.raises(URDFError, match="tangent must be"):
        urdf.ground_contacts(m, ANYMAL, restitution=0.0, tangent="z")


@pytest.fixture(scope="module")
def anymal_on_the_ground():
    """ANYmal B on Pinocchio's free flyer, its 12 joints held by PD torques about the standing
    posture, plastic frictionless contacts at its four foot spheres; the base 2 cm above where
    the feet touch."""
    m = urdf.load(ANYMAL, floating=True)
    for name, ref in STANDING.items():
        q = m.coords[m.index(name)]
        m.generalized_force(q, -400.0 * (q - ref) - 10.0 * m.dot(q))
    contacts = urdf.ground_contacts(m, ANYMAL, restitution=0.0)
    sim = lcg.compile_constrained(ConstrainedSystem(m, inequalities=contacts))
    y = np.array(m.neutral(), dtype=float)
    for name, ref in STANDING.items():
        y[m.index(name)] = ref
    gaps = sp.lambdify(m.coords, [c.expr for c in contacts], "numpy")
    y[2] = -min(gaps(*y)) + 0.02
    return m, sim, y


def test_anymal_dropped_on_foot_spheres_rests_on_its_weight(anymal_on_the_ground):
    """ANYmal B (PD-held joints) dropped from 2 cm: the four foot spheres land, it comes to rest
    on them, and the normal multipliers (in newtons: the gaps are lengths) sum to m g with m
    Pinocchio's total mass, to 1e-6 relative; the feet's lowest points are on the ground by
    Pinocchio's kinematics."""
    m, sim, y0 = anymal_on_the_ground
    res = sim.simulate(np.linspace(0.0, 3.0, 31), y0[:m.nq], np.zeros(m.nv), rtol=1e-8, atol=1e-10, method="bdf")
    landed = {r.contact for r in res.impacts}
    assert landed == {0, 1, 2, 3}
    # the posture held, it falls freely until the four feet land at once, after sqrt(2 h / g)
    assert [r.t for r in res.impacts] == pytest.approx([np.sqrt(2 * 0.02 / 9.81)] * 4, rel=1e-6)  # rtol=1e-8
    assert res.impacts.final_modes == {k: "contact" for k in range(4)}
    assert np.abs(res.y[-1, m.nq:]).max() < 1e-6  # at rest
    model = pin_model()
    weight = pin.computeTotalMass(model) * 9.81
    normal = np.array([res[f"lambda_ineq_{k}"][-1] for k in range(4)])
    assert np.all(normal > 0.1 * weight / 4)
    assert normal.sum() == pytest.approx(weight, rel=1e-6)
    data = model.createData()
    pin.framesForwardKinematics(model, data, pin_q(model, m, res.y[-1]))
    lowest = [data.oMf[model.getFrameId(f)].act(np.array([0, 0, 0.02325]))[2] - 0.031 for f in FEET]
    assert np.abs(lowest).max() < 1e-8


#: A uniform ball (I = 2/5 m R^2) whose link frame is off its centre, the sphere on a second link
#: welded to it by a fixed joint: the collision origin and the welded placement both count.
BALL = """<robot name="urdf_ball"><link name="base">
  <inertial><origin xyz="0.1 0 0"/><mass value="{m}"/><inertia ixx="{I}" ixy="0" ixz="0" iyy="{I}" iyz="0" izz="{I}"/>
  </inertial></link>
<link name="shell"><collision><origin xyz="0 0.1 -0.2" rpy="0.3 0.2 0.1"/><geometry><sphere radius="{r}"/></geometry>
  </collision><collision><geometry><box size="1 1 1"/></geometry></collision></link>
<joint name="weld" type="fixed"><parent link="base"/><child link="shell"/><origin xyz="0.1 -0.1 0.2"/></joint>
</robot>"""


@pytest.mark.parametrize("tangent", ["y", "xy"])
def test_urdf_ball_with_backspin_slips_then_rolls(tangent):
    """A URDF ball on a floating base, its collision sphere as a rough contact (Coulomb mu,
    planar along y or 3-D on the circular cone): launched along +y with backspin on the
    ground, it slips until t* = 2 (v0 + R w0) / (7 mu g) and then rolls at (5 v0 - 2 R w0) / 7,
    both to 1e-9 relative: the slip velocity is the touching material point's."""
    mass, radius, mu, v0, w0, g0 = 1.0, 0.3, 0.2, 3.0, 4.0, 9.81
    text = BALL.format(m=mass, I=0.4 * mass * radius**2, r=radius)
    m = urdf.loads(text, floating=True)
    contacts = urdf.ground_contacts(m, urdf.parse(text), restitution=0.0, tangent=tangent, friction=mu)
    sim = lcg.compile_constrained(ConstrainedSystem(m, inequalities=contacts))
    t_star = 2 * (v0 + radius * w0) / (7 * mu * g0)
    t = np.linspace(0, 2 * t_star, 21)
    # the centre, (0.1, 0, 0) in the link frame, at (0, 0, R); backspin w_x = +w0 (the link
    # frame's origin is on the spin axis through the centre: its velocity is the centre's)
    res = sim.simulate(t, q0=[-0.1, 0, radius, 0, 0, 0, 1], v0=[0, v0, 0, w0, 0, 0], rtol=1e-12, atol=1e-14)
    grips = res.impacts.transitions(0)
    assert [r.kind for r in grips] == ["grip"], res.impacts.records
    assert grips[0].t == pytest.approx(t_star, rel=1e-9)
    centre = sp.lambdify(m.coords, m.points["shell_sphere_0"].position, "numpy")
    zc = np.array([np.ravel(centre(*y[:m.nq]))[2] for y in res.y])
    assert np.abs(zc - radius).max() < 1e-10  # on the ground throughout
    yc = np.array([np.ravel(centre(*y[:m.nq]))[1] for y in res.y])
    after = res.t > t_star + 1e-6
    speed = np.diff(yc[after]) / np.diff(res.t[after])
    assert np.abs(speed / ((5 * v0 - 2 * radius * w0) / 7) - 1).max() < 1e-9


def test_collisions_kept_by_kind_with_their_problems():
    """The reader keeps every <collision> (kind, origin, a sphere's radius, name); a collision's
    problem does not stop the file from loading and is raised, located, when it is used."""
    from lagcodegen.modelfile import urdfxml

    text = """<robot name="r"><link name="a">
      <collision name="c0"><origin xyz="1 2 3" rpy="0 0 0.5"/><geometry><sphere radius="0.2"/></geometry></collision>
      <collision><geometry><mesh filename="a.stl"/></geometry></collision>
      <collision><origin xyz="1 2"/><geometry><sphere radius="0.2"/></geometry></collision>
      <collision></collision></link>
      <link name="b"/><joint name="j" type="revolute"><parent link="a"/><child link="b"/></joint></robot>"""
    a = urdfxml.parse(text, filename="r.urdf").links["a"]
    c0, mesh, bad_origin, empty = a.collisions
    assert (c0.kind, c0.xyz, c0.rpy, c0.radius, c0.name, c0.problem) == ("sphere", (1, 2, 3), (0, 0, 0.5), 0.2, "c0",
                                                                         None)
    assert (mesh.kind, mesh.radius, mesh.problem) == ("mesh", None, None)
    with pytest.raises(URDFError, match=r"r\.urdf:4: link 'a' <collision> <origin>.*needs 3 numbers"):
        bad_origin.check()
    with pytest.raises(URDFError, match=r"r\.urdf:5: link 'a' <collision>.*missing <geometry>"):
        empty.check()
    with pytest.raises(URDFError, match=r"r\.urdf:4: link 'a' <collision> <origin>"):
        urdf.spheres(urdfxml.parse(text, filename="r.urdf"))


def test_locked_joints_and_models_from_other_options():
    """With lock= (the same as load's) the spheres ride on the merged bodies: the gaps equal
    Pinocchio's with the locked knee at its position; a model loaded with other options, or in
    closed form, is refused by name."""
    m = urdf.load(ANYMAL, floating=True, lock={"LF_KFE": -1.0})
    contacts = urdf.ground_contacts(m, ANYMAL, restitution=0.0, lock={"LF_KFE": -1.0})
    model = pin_model()
    data = model.createData()
    y = np.array(m.neutral(), dtype=float)
    y[:7] = [0.1, -0.2, 0.5, 0.1, 0.2, -0.3, 0.927]
    y[3:7] /= np.linalg.norm(y[3:7])
    q = np.empty(model.nq)
    q[:7] = y[:7]
    for jid in range(2, model.njoints):
        name = model.names[jid]
        q[model.idx_qs[jid]] = -1.0 if name == "LF_KFE" else 0.3 * jid
        if name != "LF_KFE":
            y[m.index(name)] = 0.3 * jid
    pin.framesForwardKinematics(model, data, q)
    gaps = sp.lambdify(m.coords, [c.expr for c in contacts], "numpy")
    assert np.allclose(gaps(*y), [data.oMf[model.getFrameId(f)].act(np.array([0, 0, 0.02325]))[2] - 0.031
                                  for f in FEET], rtol=0, atol=1e-12)
    with pytest.raises(URDFError, match="has no link 'LF_SHANK'.*pass the lock= given to load"):
        urdf.ground_contacts(urdf.load(ANYMAL, floating=True, lock={"LF_KFE": -1.0}), ANYMAL, restitution=0.0)
    with pytest.raises(URDFError, match="has no links: load the robot with form='tree'"):
        urdf.ground_contacts(urdf.loads(BALL.format(m=1, I=0.1, r=0.1), floating=True, form="closed"),
                             urdf.parse(BALL.format(m=1, I=0.1, r=0.1)), restitution=0.0)
