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
    """A uniform sphere (I = 2/5 m R^2) on a free joint above the floor z = 0: the slip velocity of
    its touching point, v_centre + w x (0, 0, -R) = (x' - R w_y, y' + R w_x) with w the world
    angular velocity, given as the tangent(s) ``tangents`` ("y" or "xy")."""
    m = lcg.Model(f"sphere_{rotation.lower()}_{tangents}")
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
    contact = lcg.Inequality(c["root_z"] - RADIUS, restitution=0.0, tangent=tangent if len(tangent) > 1 else tangent[0],
                             friction=mu)
    return compile_constrained(lcg.ConstrainedSystem(m, inequalities=[contact]), "index1", outputs=["energy"])


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
