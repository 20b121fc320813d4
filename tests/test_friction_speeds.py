"""Coulomb friction on models with generalized speeds (quaternion free joints) and 3-D friction
with the exact circular cone (issue 39), checked against closed-form facts: a sphere launched
sliding with backspin (slip end 2 (v0 + R w0) / (7 mu g), rolling speed (5 v0 - 2 R w0) / 7) in
quaternions and in Z-Y-X angles (Lagrange's form), a sphere sliding diagonally (the planar law
along the slip direction), a block on an incline in 3-D (sticks when tan(alpha) <= mu, else
slides at g (sin alpha - mu cos alpha))."""

from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp

import lagcodegen as lcg
from lagcodegen.api import compile_constrained
from lagcodegen.errors import ModelError

G = 9.81
TIGHT = {"rtol": 1e-12, "atol": 1e-14}
MU, RADIUS, MASS = 0.2, 0.3, 1.0


def _quat_rotation(qx, qy, qz, qw):
    """The rotation matrix of the (not necessarily unit) quaternion (x, y, z, w)."""
    n = qx**2 + qy**2 + qz**2 + qw**2
    return sp.Matrix([
        [1 - 2 * (qy**2 + qz**2) / n, 2 * (qx * qy - qw * qz) / n, 2 * (qx * qz + qw * qy) / n],
        [2 * (qx * qy + qw * qz) / n, 1 - 2 * (qx**2 + qz**2) / n, 2 * (qy * qz - qw * qx) / n],
        [2 * (qx * qz - qw * qy) / n, 2 * (qy * qz + qw * qx) / n, 1 - 2 * (qx**2 + qy**2) / n]])


def _sphere(rotation: str, tangents: str, mu: float = MU):
    """The compiled :func:`_sphere_system`."""
    return compile_constrained(_sphere_system(mu, 0.0, rotation, tangents), "index1", outputs=["energy"])


def _sphere_system(mu: float, e: float, rotation: str = "quaternion", tangents: str = "xy"):
    """A uniform sphere (I = 2/5 m R^2) on a free joint above the floor z = 0: the slip velocity of
    its touching point, v_centre + w x (0, 0, -R) = (x' - R w_y, y' + R w_x) with w the world
    angular velocity, given as the tangent(s) ``tangents`` ("y" or "xy")."""
    m = lcg.Model(f"sphere_{rotation.lower()}_{tangents}{'_bouncy' if e else ''}")
    inertia = 0.4 * MASS * RADIUS**2
    m.link("ball", joint=lcg.Joint.free("root", rotation=rotation), mass=MASS,
           inertia=(inertia, inertia, inertia, 0, 0, 0))
    m.gravity(G)
    c = {s.name: s for s in m.coords}
    rate = {s.name: s for s in m.speeds}
    if rotation == "quaternion":
        v = {s.name: s for s in m.velocities}
        w = _quat_rotation(c["root_qx"], c["root_qy"], c["root_qz"], c["root_qw"]) * sp.Matrix(
            [v["root_wx"], v["root_wy"], v["root_wz"]])
    else:  # R = Rz(yaw) Ry(pitch) Rx(roll): w = yaw' z + pitch' Rz y + roll' Rz Ry x
        yaw, pitch = c["root_yaw"], c["root_pitch"]
        w = sp.Matrix([rate["root_roll_dot"] * sp.cos(yaw) * sp.cos(pitch) - rate["root_pitch_dot"] * sp.sin(yaw),
                       rate["root_roll_dot"] * sp.sin(yaw) * sp.cos(pitch) + rate["root_pitch_dot"] * sp.cos(yaw),
                       0])
    slip = {"x": rate["root_x_dot"] - RADIUS * w[1], "y": rate["root_y_dot"] + RADIUS * w[0]}
    tangent = tuple(slip[a] for a in tangents)
    contact = lcg.Inequality(c["root_z"] - RADIUS, restitution=e, tangent=tangent if len(tangent) > 1 else tangent[0],
                             friction=mu)
    return lcg.ConstrainedSystem(m, inequalities=[contact])


def _start(rotation: str, vel, spin):
    """q0, v0 of the sphere resting on the floor at the origin with centre velocity vel (world)
    and world angular velocity spin (the body axes along the world's at t = 0)."""
    if rotation == "quaternion":
        return [0, 0, RADIUS, 0, 0, 0, 1], [*vel, *spin]
    return [0, 0, RADIUS, 0, 0, 0], [*vel, spin[2], spin[1], spin[0]]  # (yaw', pitch', roll') at zero angles


@pytest.mark.parametrize("rotation", ["quaternion", "ZYX"])
def test_sphere_with_backspin_slips_then_rolls_on_generalized_speeds(rotation):
    """Planar friction (one tangent, along y) on a free-flying sphere: the slip ends at
    t* = 2 (v0 + R w0) / (7 mu g), then it rolls at (5 v0 - 2 R w0) / 7, to 1e-9; the energy lost
    is the friction work."""
    v0, w0 = 3.0, 4.0  # moving along +y, backspin: w_x = +w0 (rolling forward has w_x = -y'/R)
    sim = _sphere(rotation, "y")
    t_star = 2 * (v0 + RADIUS * w0) / (7 * MU * G)
    v_roll = (5 * v0 - 2 * RADIUS * w0) / 7
    t = np.linspace(0, 2 * t_star, 40)
    q0, u0 = _start(rotation, (0, v0, 0), (w0, 0, 0))
    res = sim.simulate(t, q0=q0, v0=u0, **TIGHT)
    grips = res.impacts.transitions(0)
    assert [r.kind for r in grips] == ["grip"], res.impacts.records
    assert grips[0].t == pytest.approx(t_star, rel=1e-9)
    after = res.t > t_star
    vy = res.y[:, sim.system.model.nq + 1]  # the centre's y speed (world = body frame while only w_x spins)
    if rotation == "quaternion":  # v in the body frame: the world velocity from q' (y')
        vy = np.array([sim.compiled.rhs(tt, yy)[1] for tt, yy in zip(res.t, res.y)])
    assert np.max(np.abs(vy[after] / v_roll - 1)) < 1e-9
    assert np.max(np.abs(res.y[:, 2] - RADIUS)) < 1e-10
    work = MU * G * (v0 + RADIUS * w0) * t_star / 2
    assert res["energy"][0] - res["energy"][-1] == pytest.approx(work, rel=1e-9)
    assert res.impacts.friction_modes == {0: "stick"}
    before = res.t < t_star
    assert np.max(np.abs(res["lambda_t_ineq_0"][before] + MU * G)) < 1e-9
    assert np.max(np.abs(res["lambda_ineq_0"] / G - 1)) < 1e-9


@pytest.mark.parametrize("rotation", ["quaternion", "ZYX"])
def test_sphere_sliding_diagonally_slips_along_its_slip_direction_on_the_circular_cone(rotation):
    """3-D friction (two tangents, the exact circular cone) on the sphere (quaternion; Z-Y-X angles,
    Lagrange's form, as a second method) launched along
    e = (3, 4) / 5 with backspin about the horizontal axis across e (and a spin about the vertical,
    which a sphere's slip does not feel): the slip stays along e and falls at 7/2 mu g, ending at
    t* = 2 (v0 + R w0) / (7 mu g); then it rolls along e at (5 v0 - 2 R w0) / 7; the friction force
    during the slip is mu m g against e; all to 1e-9."""
    v0, w0, wz = 2.5, 3.0, 1.5
    e = np.array([0.6, 0.8])
    sim = _sphere(rotation, "xy")
    t_star = 2 * (v0 + RADIUS * w0) / (7 * MU * G)
    v_roll = (5 * v0 - 2 * RADIUS * w0) / 7
    t = np.linspace(0, 2 * t_star, 41)
    axis = np.array([-e[1], e[0]])  # z x e
    spin = (-w0 * axis[0], -w0 * axis[1], wz)  # backspin: w = -w0 (z x e)
    q0, u0 = _start(rotation, (v0 * e[0], v0 * e[1], 0), spin)
    res = sim.simulate(t, q0=q0, v0=u0, **TIGHT)
    grips = res.impacts.transitions(0)
    assert [r.kind for r in grips] == ["grip"], res.impacts.records
    assert grips[0].t == pytest.approx(t_star, rel=1e-9)
    assert res.impacts.friction_modes == {0: "stick"}
    rates = np.array([sim.compiled.rhs(tt, yy)[:2] for tt, yy in zip(res.t, res.y)])  # world x', y'
    before, after = res.t < t_star, res.t > t_star
    # along e: v0 - mu g t while slipping, v_roll after; across e: 0
    along, across = rates @ e, rates @ axis
    assert np.max(np.abs(along[before] - (v0 - MU * G * res.t[before]))) < 1e-9 * v0
    assert np.max(np.abs(along[after] / v_roll - 1)) < 1e-9
    assert np.max(np.abs(across)) < 1e-9 * v0
    lt = np.stack([res["lambda_t0_ineq_0"], res["lambda_t1_ineq_0"]], axis=1)  # the force along (x, y)
    assert np.max(np.abs(lt[before] + MU * G * e)) < 1e-9
    assert np.max(np.abs(lt[after])) < 1e-9


def _incline_3d(alpha: float, mu: float, beta: float, *, formulation: str = "index1"):
    """A particle on an incline of angle alpha: x down the slope, y across it, z normal to it; the
    contact's two tangents the in-slope axes turned by beta (the cone must not care)."""
    m = lcg.Model("incline_3d")
    x, y, z = m.coordinates("x y z")
    m.parameters(g=G, m=1.0)
    m.particle("b", sp.Symbol("m"), (x * math.cos(alpha) + z * math.sin(alpha), y,
                                     -x * math.sin(alpha) + z * math.cos(alpha)))
    m.gravity(sp.Symbol("g"))
    cb, sb = math.cos(beta), math.sin(beta)
    contact = lcg.Inequality(z, restitution=0.0, tangent=(cb * x - sb * y, sb * x + cb * y), friction=mu)
    return compile_constrained(lcg.ConstrainedSystem(m, inequalities=[contact]), formulation, outputs=["energy"])


@pytest.mark.parametrize("alpha, mu, beta", [(0.5, 0.6, 0.0), (0.5, 0.3, 0.0), (0.5, 0.3, 0.7), (0.3, 0.31, 1.1),
                                             (0.3, 0.1, 2.0)])
def test_block_on_an_incline_in_3d_sticks_when_tan_alpha_le_mu_else_slides_down_the_slope(alpha, mu, beta):
    sim = _incline_3d(alpha, mu, beta)
    t = np.linspace(0, 2, 21)
    res = sim.simulate(t, q0=[0.0, 0.0, 0.0], v0=[0.0, 0.0, 0.0], **TIGHT)
    assert np.max(np.abs(res["lambda_ineq_0"] / (G * math.cos(alpha)) - 1)) < 1e-9  # N = m g cos(alpha)
    # the friction force in (x, y): the tangents' multipliers turned back by -beta
    cb, sb = math.cos(beta), math.sin(beta)
    l0, l1 = res["lambda_t0_ineq_0"], res["lambda_t1_ineq_0"]
    fx, fy = cb * l0 + sb * l1, -sb * l0 + cb * l1
    if math.tan(alpha) <= mu:
        assert np.max(np.abs(res.y[:, :3])) < 1e-12 and res.impacts.friction_modes == {0: "stick"}
        assert np.max(np.abs(fx + G * math.sin(alpha))) < 1e-9 and np.max(np.abs(fy)) < 1e-9
        assert res.impacts.transitions() == []
    else:
        acc = G * (math.sin(alpha) - mu * math.cos(alpha))
        assert np.max(np.abs(res["x"][1:] / (0.5 * acc * t[1:] ** 2) - 1)) < 1e-9
        assert np.max(np.abs(res["y"])) < 1e-9 * np.max(res["x"])  # straight down the slope
        assert res.impacts.friction_modes == {0: "slip"}
        assert np.max(np.abs(fx + mu * G * math.cos(alpha))) < 1e-9 and np.max(np.abs(fy)) < 1e-9
    assert np.max(np.abs(res["z"])) < 1e-12


def _table_on_incline(mu: float, alpha: float, yaw: float):
    """A rigid table (a free body on a quaternion joint) standing on four legs, each a 3-D rough
    contact with the exact circular cone, on an incline of angle alpha: gravity tilted so that
    the slope falls along the horizontal direction at angle ``yaw`` from x. Four coupled contacts
    (one more normal row than the body's three out-of-plane freedoms) that reach the cone
    together when released from rest."""
    m = lcg.Model("table_on_incline")
    m.link("top", joint=lcg.Joint.free("root", rotation="quaternion"), mass=2.0, inertia=(0.1, 0.2, 0.25, 0, 0, 0))
    m.gravity(G, up=[-math.sin(alpha) * math.cos(yaw), -math.sin(alpha) * math.sin(yaw), math.cos(alpha)])
    legs = [(0.3, 0.2, -0.1), (0.3, -0.2, -0.1), (-0.3, 0.2, -0.1), (-0.3, -0.2, -0.1)]
    contacts = [lcg.ground_contact(m, "top", leg, restitution=0.0, tangent="xy", friction=mu, name=f"leg{i}")
                for i, leg in enumerate(legs)]
    sim = compile_constrained(lcg.ConstrainedSystem(m, inequalities=contacts))
    q0 = np.array(m.neutral())
    q0[2] = 0.1  # the legs on the ground
    return m, sim, q0


@pytest.mark.parametrize("alpha, mu, yaw", [(0.5, 0.3, 0.0), (0.5, 0.3, 0.4), (0.2, 0.3, 0.4)])
def test_table_on_four_legs_slips_on_all_together_down_an_incline_or_sticks(alpha, mu, yaw):
    """Four coupled 3-D contacts leaving the cone together from rest (their slip directions found
    jointly; the driver before reported a false Painleve inconsistency at t = 0): the table slides
    down the slope at g (sin alpha - mu cos alpha) to 1e-9 relative (CVODE Adams at rtol 1e-12),
    the normal forces sum to m g cos alpha and each leg's friction is mu times its normal force,
    opposing the slide; with tan(alpha) <= mu it sticks and stays where it stands."""
    m, sim, q0 = _table_on_incline(mu, alpha, yaw)
    t = np.linspace(0.0, 1.0, 11)
    res = sim.simulate(t, q0, np.zeros(m.nv), method="adams", **TIGHT)
    down = res.y[:, 0] * math.cos(yaw) + res.y[:, 1] * math.sin(yaw)
    across = -res.y[:, 0] * math.sin(yaw) + res.y[:, 1] * math.cos(yaw)
    normal = np.array([res[f"lambda_ineq_{k}"] for k in range(4)])
    friction = np.array([[res[f"lambda_t0_ineq_{k}"], res[f"lambda_t1_ineq_{k}"]] for k in range(4)])
    assert np.max(np.abs(normal.sum(axis=0) / (2.0 * G * math.cos(alpha)) - 1)) < 1e-9
    assert res.impacts.transitions() == []
    if math.tan(alpha) <= mu:
        assert res.impacts.friction_modes == {k: "stick" for k in range(4)}
        assert np.max(np.abs(res.y[:, :3] - q0[:3])) < 1e-12
        return
    acc = G * (math.sin(alpha) - mu * math.cos(alpha))
    assert res.impacts.friction_modes == {k: "slip" for k in range(4)}
    assert np.max(np.abs(down[1:] / (0.5 * acc * t[1:] ** 2) - 1)) < 1e-9
    assert np.max(np.abs(across)) < 1e-9 * down[-1] and np.max(np.abs(res.y[:, 2] - q0[2])) < 1e-12
    magnitude = np.hypot(friction[:, 0], friction[:, 1])
    assert np.max(np.abs(magnitude[:, 1:] / (mu * normal[:, 1:]) - 1)) < 1e-9
    along = (friction[:, 0] * math.cos(yaw) + friction[:, 1] * math.sin(yaw)) / magnitude
    assert np.max(np.abs(along[:, 1:] + 1)) < 1e-9  # against the slide: up the slope


def test_generated_3d_friction_code_with_generalized_speeds_compiles_strictly(tmp_path):
    """The contact code of a quaternion body with a 3-D Coulomb contact (two tangential rows, its
    friction table giving q' = k(q, v, t)) compiles with -Wall -Wextra -Werror -std=c99 -pedantic."""
    import subprocess

    from lagcodegen.codegen.constrained import generate_constrained
    from lagcodegen.codes import c_header
    from lagcodegen.runtime import sources as runtime_files

    m = lcg.Model("strict_fr3")
    m.link("box", joint=lcg.Joint.free("root"), mass=1.0, inertia=(0.1, 0.2, 0.3, 0, 0, 0))
    m.gravity(G)
    system = lcg.ConstrainedSystem(m, inequalities=[
        lcg.ground_contact(m, "box", (0.1, 0.05, -0.1), restitution=0.3, tangent="xy", friction=0.5)])
    code, _ = generate_constrained(system)
    for name, text in code.files.items():
        (tmp_path / name).write_text(text)
    for name, text in runtime_files(("lcg_dae_model.h", "lcg_model.h")).items():
        if not (tmp_path / name).exists():
            (tmp_path / name).write_text(text)
    if not (tmp_path / "lcg_codes.h").exists():
        (tmp_path / "lcg_codes.h").write_text(c_header())
    source = code.files["strict_fr3_impact.c"]
    assert "static const int tangent_of[NT] = { 0, 0 };" in source  # the contact's two rows
    proc = subprocess.run(["cc", "-Wall", "-Wextra", "-Werror", "-std=c99", "-pedantic", "-c", "strict_fr3_impact.c",
                           "-o", "/dev/null"], cwd=tmp_path, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr


def test_tangent_input_errors():
    m = lcg.Model("tangent_errors")
    x, y, z = m.coordinates("x y z")
    m.particle("b", 1.0, (x, y, z))
    with pytest.raises(ModelError, match="tangent must be one expression or two"):
        lcg.ConstrainedSystem(m, inequalities=[lcg.Inequality(z, restitution=0.0, tangent=(x, y, z), friction=0.3)])
    with pytest.raises(ModelError, match="not linear in them"):
        lcg.ConstrainedSystem(m, inequalities=[lcg.Inequality(z, restitution=0.0, tangent=m.dot(x) ** 2,
                                                              friction=0.3)])
    with pytest.raises(ModelError, match="unknown symbol"):
        lcg.ConstrainedSystem(m, inequalities=[lcg.Inequality(z, restitution=0.0, tangent=(x, sp.Symbol("w")),
                                                              friction=0.3)])


@pytest.mark.parametrize("mu, sticks", [(0.1, False), (0.8, True)])
def test_3d_frictional_impact_of_a_spinning_sphere_sticks_within_the_cone_else_slides(mu, sticks):
    """The quaternion sphere dropped from h with a horizontal velocity and a spin whose slip
    velocity u- points off both axes, bouncing with e = 0.5 on the 3-D Coulomb floor: P_n =
    m (1 + e) g t1 and the slip changes by 7/2 P_t / m (sphere: 1 + m R^2 / I); it sticks
    (u+ = 0, |P_t| = 2/7 m |u-| <= mu P_n) when |u-| <= 7/2 mu (1 + e) g t1, else slides with
    P_t = -mu P_n u- / |u-|, so the centre's horizontal velocity jumps by P_t / m; to 1e-9."""
    e, h = 0.5, 0.2
    vel, spin = np.array([3.0, -2.0, 0.0]), np.array([2.0, 3.0, 5.0])
    sim = compile_constrained(_sphere_system(mu, e), "index1", outputs=["energy"])
    t1 = math.sqrt(2 * h / G)
    u_minus = np.array([vel[0] - RADIUS * spin[1], vel[1] + RADIUS * spin[0]])
    pn = MASS * (1 + e) * G * t1
    assert (np.linalg.norm(u_minus) <= 3.5 * mu * pn / MASS) == sticks
    pt = -MASS * u_minus / 3.5 if sticks else -mu * pn * u_minus / np.linalg.norm(u_minus)
    res = sim.simulate(np.array([0.0, t1 + 0.01]), q0=[0, 0, RADIUS + h, 0, 0, 0, 1], v0=[*vel, *spin], **TIGHT)
    bounce = [r for r in res.impacts if r.kind == "bounce"]
    assert len(bounce) == 1 and bounce[0].t == pytest.approx(t1, rel=1e-9)
    assert bounce[0].impulse == pytest.approx(pn, rel=1e-9)
    tangential = [r for r in res.impacts if r.kind == "tangential_impulse"]
    assert len(tangential) == 1
    assert tangential[0].impulse == pytest.approx(np.linalg.norm(pt), rel=1e-9)
    assert tangential[0].w_before == pytest.approx(np.linalg.norm(u_minus), rel=1e-9)
    u_plus = u_minus + 3.5 * pt / MASS
    assert abs(tangential[0].w_after - np.linalg.norm(u_plus)) < 1e-9
    world = sim.compiled.rhs(res.t[-1], res.y[-1])[:3]  # the centre's velocity, in flight after the bounce
    assert np.max(np.abs(world[:2] - (vel[:2] + pt / MASS))) < 1e-9
    assert world[2] == pytest.approx(e * G * t1 - G * 0.01, rel=1e-9)


@pytest.mark.parametrize("mu", [0.2, 0.8])
def test_particle_launched_across_an_incline_curves_as_an_independent_integration(mu):
    """The 3-D incline's particle launched across the slope (alpha = 0.5, tan alpha = 0.546): its
    slip direction turns downhill (the driver renews its reference past 60 degrees), against
    scipy's DOP853 on the closed form x'' = g sin(alpha) - mu g cos(alpha) u_x / |u|,
    y'' = -mu g cos(alpha) u_y / |u|, to 1e-8; with mu = 0.8 > tan(alpha) it stops (one grip,
    at the time the closed form's speed reaches 0) and stays."""
    from scipy.integrate import solve_ivp

    alpha, vy0 = 0.5, 3.0
    sim = _incline_3d(alpha, mu, 0.3)
    n = G * math.cos(alpha)

    def f(t, s):
        speed = math.hypot(s[2], s[3])
        return [s[2], s[3], G * math.sin(alpha) - mu * n * s[2] / speed, -mu * n * s[3] / speed]

    def stops(t, s):
        return math.hypot(s[2], s[3]) - 1e-9
    stops.terminal = True
    ref = solve_ivp(f, (0, 3.0), [0, 0, 0, vy0], method="DOP853", rtol=1e-13, atol=1e-14, events=stops,
                    dense_output=True)
    t_end = ref.t[-1] if mu > math.tan(alpha) else 3.0
    t = np.linspace(0, min(t_end, 3.0) * (0.999 if mu > math.tan(alpha) else 1.0), 31)
    res = sim.simulate(np.append(t, 3.0) if mu > math.tan(alpha) else t, q0=[0.0, 0.0, 0.0], v0=[0.0, vy0, 0.0],
                       **TIGHT)
    xy = ref.sol(t)[:2].T
    assert np.abs(res.y[: t.size, :2] - xy).max() < 1e-8
    if mu > math.tan(alpha):
        grips = [r for r in res.impacts.transitions(0) if r.kind == "grip"]
        assert len(grips) == 1 and grips[0].t == pytest.approx(ref.t_events[0][0], rel=1e-7)
        assert res.impacts.friction_modes == {0: "stick"} and np.abs(res.y[-1, 3:]).max() < 1e-12
    else:
        assert res.impacts.friction_modes == {0: "slip"} and res.impacts.transitions() == []
        heading = math.atan2(res.y[-1, 4], res.y[-1, 3])
        assert abs(heading) < math.pi / 6  # turned from across the slope (90 degrees) to near downhill


INCLINE_FILE = """
[model]
name = "incline_3d_file"
coordinates = ["x", "y", "z"]

[parameters]
g = 9.81
m = 1.0

[[particles]]
name = "block"
mass = "m"
position = ["x*cos(0.5) + z*sin(0.5)", "y", "-x*sin(0.5) + z*cos(0.5)"]

[gravity]
g = "g"

[constraints]
inequalities = [{ expr = "z", restitution = 0.0, tangent = ["x", "y"], friction = 0.3 }]

[simulation]
formulation = "index1"
t_end = 1.0
n_out = 11
rtol = 1e-12
atol = 1e-14
"""


def test_model_file_3d_friction_slides_at_g_sin_minus_mu_cos():
    from lagcodegen.api import compile_file
    from lagcodegen.modelfile import ModelFileError, loads_model

    mf = loads_model(INCLINE_FILE)
    res = mf.simulate(compile_file(mf))
    acc = G * (math.sin(0.5) - 0.3 * math.cos(0.5))
    assert res["x"][-1] == pytest.approx(0.5 * acc, rel=1e-9)
    assert res.impacts.friction_modes == {0: "slip"}
    with pytest.raises(ModelFileError, match="one expression or a list of two"):
        loads_model(INCLINE_FILE.replace('tangent = ["x", "y"]', 'tangent = ["x", "y", "z"]'))
