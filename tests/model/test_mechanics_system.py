"""sympy.physics.mechanics System models (joints, bodies, loads, actuators) through
lagcodegen.derive and compile_model: mass matrix and forcing against sympy's own
System.form_eoms(), a simulation against a hand-written lagcodegen model; Systems whose speeds
are not q' go through Kane's equations (tests/model/test_kane.py), constrained ones without
dependent speeds are refused clearly."""

import os
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
import sympy as sp
import sympy.physics.mechanics as me

import lagcodegen as lcg
from lagcodegen.model import mechanics
from lagcodegen.errors import ModelError

t = me.dynamicsymbols._t


def double_pendulum(*, rods=True, lagrange_speeds=False):
    """Two links on PinJoints about z, gravity along -y. ``rods``: links with inertia and the
    second joint below the first link's centre; otherwise point masses (bob 2 hangs l2 below
    bob 1, bob 1 l1 below the pivot: lagcodegen.systems.double_pendulum with theta2 = q1 + q2)."""
    q1, q2 = me.dynamicsymbols("q1 q2")
    m1, m2, l1, l2, g = sp.symbols("m1 m2 l1 l2 g")
    ground = me.RigidBody("ground")
    N = ground.frame
    if rods:
        link1, link2 = me.RigidBody("link1", mass=m1), me.RigidBody("link2", mass=m2)
        below = -l1 * link1.frame.y
    else:
        link1, link2 = me.RigidBody("bob1", mass=m1), me.RigidBody("bob2", mass=m2)
        for link in (link1, link2):  # point masses: no inertia about the centre of mass
            link.inertia = (me.inertia(link.frame, 0, 0, 0), link.masscenter)
        below = None  # at the first bob
    speeds = ([q1.diff(t), q2.diff(t)] if lagrange_speeds else me.dynamicsymbols("u1 u2"))
    system = me.System.from_newtonian(ground)
    j1 = me.PinJoint("j1", ground, link1, coordinates=q1, speeds=speeds[0], child_point=l1 * link1.frame.y,
                     joint_axis=N.z)
    j2 = me.PinJoint("j2", link1, link2, coordinates=q2, speeds=speeds[1], parent_point=below,
                     child_point=l2 * link2.frame.y, joint_axis=link1.frame.z)
    system.add_joints(j1, j2)
    system.apply_uniform_gravity(-g * N.y)
    return system


VALUES = {"m1": 1.3, "m2": 0.7, "l1": 0.9, "l2": 0.6, "g": 9.81, "link1_izz": 0.05, "link2_izz": 0.02}


def sympy_eoms(system, values, method=me.KanesMethod):
    """sympy's own M(q) and forcing(q, u) as numpy functions, u = q'."""
    system.form_eoms(eom_method=method)
    subs = {s: values[s.name] for s in (system.mass_matrix.free_symbols | system.forcing.free_symbols)
            if s.name in values}
    q = list(system.q)
    u = list(system.u) if method is me.KanesMethod else [qi.diff(t) for qi in q]
    args = q + u
    Mf = sp.lambdify(args, system.mass_matrix.xreplace(subs))
    Ff = sp.lambdify(args, system.forcing.xreplace(subs))
    return lambda qv: (np.array(Mf(*qv), dtype=float), np.array(Ff(*qv), dtype=float).ravel())


def lagcodegen_eoms(eom, values):
    model = eom.model
    subs = {s: values[s.name] for s in model.params}
    args = list(model.coords) + list(model.speeds)
    Mf = sp.lambdify(args, eom.M.xreplace(subs))
    Ff = sp.lambdify(args, eom.F.xreplace(subs))
    return lambda qv: (np.array(Mf(*qv), dtype=float), np.array(Ff(*qv), dtype=float).ravel())


def agree(system, values, method=me.KanesMethod, states=8):
    with pytest.warns(UserWarning, match="have no value: their default is 1.0"):
        eom = lcg.derive(system)
    ours, theirs = lagcodegen_eoms(eom, values), sympy_eoms(system, values, method)
    rng = np.random.default_rng(7)
    n = eom.n
    for _ in range(states):
        qv = np.concatenate([rng.uniform(-np.pi, np.pi, n), rng.normal(size=n)])
        M, F = ours(qv)
        M_ref, F_ref = theirs(qv)
        np.testing.assert_allclose(M, M_ref, rtol=1e-12, atol=1e-12 * np.abs(M_ref).max())
        np.testing.assert_allclose(F, F_ref, rtol=1e-11, atol=1e-12 * max(np.abs(F_ref).max(), 1))
    return eom


def test_pin_joint_double_pendulum_matches_form_eoms_kane():
    system = double_pendulum()
    eom = agree(system, VALUES)
    assert [q.name for q in eom.model.coords] == ["q1", "q2"]
    # gravity became a potential (energy outputs hold it): V = -m g . r summed over the links
    assert eom.V != 0 and not eom.model.generalized_forces
    assert set(eom.model.points) == {"link1", "link2"}


def test_speeds_written_as_q_dot_match_form_eoms_lagrange():
    agree(double_pendulum(lagrange_speeds=True), VALUES, method=me.LagrangesMethod)


def test_prismatic_cart_pole_with_actuators_and_forces_matches_form_eoms():
    """A cart on a PrismaticJoint with a pole on a PinJoint; a linear spring actuator on the
    cart, a torque actuator between cart and pole, a velocity-dependent drag force at the tip."""
    x, th = me.dynamicsymbols("x theta")
    M_c, m_p, L, g, k, T0, c = sp.symbols("M_c m_p L g k T0 c")
    ground = me.RigidBody("ground")
    N = ground.frame
    cart = me.RigidBody("cart", mass=M_c)
    pole = me.RigidBody("pole", mass=m_p)
    system = me.System.from_newtonian(ground)
    slider = me.PrismaticJoint("slider", ground, cart, coordinates=x, joint_axis=N.x)
    pin = me.PinJoint("pin", cart, pole, coordinates=th, joint_axis=cart.frame.z, child_point=-L / 2 * pole.frame.y)
    system.add_joints(slider, pin)
    system.apply_uniform_gravity(-g * N.y)
    path = me.LinearPathway(ground.masscenter, cart.masscenter)
    system.add_actuators(me.LinearSpring(k, path), me.TorqueActuator(T0, N.z, pole, cart))
    tip = pole.masscenter.locatenew("tip", L / 2 * pole.frame.y)
    tip.v2pt_theory(pole.masscenter, N, pole.frame)
    system.add_loads(me.Force(tip, -c * tip.vel(N)))
    values = {"M_c": 2.0, "m_p": 0.5, "L": 1.2, "g": 9.81, "k": 3.0, "T0": 0.4, "c": 0.3, "pole_izz": 0.06,
              "cart_izz": 0.1}
    eom = agree(system, values)
    assert [q.name for q in eom.model.coords] == ["x", "theta"]


def test_spherical_joint_pendulum_matches_form_eoms():
    """A rigid body with a full inertia tensor on a SphericalJoint (three body-fixed angles)."""
    qs = me.dynamicsymbols("a b c")
    m, l, g = sp.symbols("m l g")
    ground = me.RigidBody("ground")
    bob = me.RigidBody("bob", mass=m)
    system = me.System.from_newtonian(ground)
    system.add_joints(me.SphericalJoint("ball", ground, bob, coordinates=qs, child_point=l * bob.frame.z))
    system.apply_uniform_gravity(-g * ground.frame.z)
    values = {"m": 1.5, "l": 0.8, "g": 9.81, "bob_ixx": 0.3, "bob_iyy": 0.25, "bob_izz": 0.1, "bob_ixy": 0.01,
              "bob_iyz": -0.02, "bob_izx": 0.03}
    agree(system, values)


def test_compiled_system_simulates_like_the_hand_written_double_pendulum():
    system = double_pendulum(rods=False)
    values = {"m1": 1.3, "m2": 0.7, "l1": 0.9, "l2": 0.6, "g": 9.81}
    sim = lcg.compile_model(system, values=values, outputs=["energy"])
    reference = lcg.compile_model(lcg.systems.double_pendulum(), values=values)
    times = np.linspace(0, 5, 501)
    q0 = [1.1, -0.4]
    res = sim.simulate(times, q0=q0, v0=[0.3, 0.2], rtol=1e-11, atol=1e-12)
    ref = reference.simulate(times, q0=[q0[0], q0[0] + q0[1]], v0=[0.3, 0.5], rtol=1e-11, atol=1e-12)
    np.testing.assert_allclose(res["q1"], ref["theta1"], atol=2e-7)
    np.testing.assert_allclose(res["q1"] + res["q2"], ref["theta2"], atol=2e-7)
    # gravity is a potential: the energy T + V is conserved along the motion
    assert res.drift("energy") < 1e-8


def test_compile_model_of_a_system_needs_every_value():
    with pytest.raises(ModelError, match=r"no value given for parameter\(s\) g, l1, l2, link1_izz"):
        lcg.compile_model(double_pendulum(), values={"m1": 1.0, "m2": 1.0})


def test_speeds_that_are_not_q_dot_take_kanes_equations():
    """A System whose speed is not q' (q' = r u, a wheel's spin rate) is imported through Kane's
    equations: its speed u and kinematic equation are the model's, M = m r^2."""
    q, u = me.dynamicsymbols("q u")
    m, r = sp.symbols("m r")
    N = me.ReferenceFrame("N")
    O = me.Point("O")
    O.set_vel(N, 0)
    P = O.locatenew("P", q * N.x)
    P.set_vel(N, r * u * N.x)
    system = me.System(N, O)
    system.add_coordinates(q)
    system.add_speeds(u)
    system.add_kdes(q.diff(t) - r * u)  # u is a wheel's spin rate, q' = r u
    system.add_bodies(me.Particle("ball", P, m))
    model = mechanics.from_system(system, parameters={"m": 2.0, "r": 0.5})
    assert [s.name for s in model.v] == ["u"] and model.general
    mm, rr = sp.symbols("m r")
    assert sp.simplify(model.kinematics[0] - rr * sp.Symbol("u")) == 0
    eom = lcg.derive(model)
    assert sp.simplify(eom.M[0, 0] - mm * rr**2) == 0 and eom.F[0] == 0
    assert sp.simplify(eom.T - mm * rr**2 * sp.Symbol("u") ** 2 / 2) == 0
    assert system.eom_method is None  # the System itself is left as it was


def test_constraints_without_dependent_speeds_are_refused_and_kanes_method_is_taken():
    system = double_pendulum()
    q1, q2 = system.q
    system.add_holonomic_constraints(q1 - q2)
    with pytest.raises(ModelError, match=r"the System has holonomic constraints \(q1\(t\) - q2\(t\)\); sympy cannot "
                                         r"form Kane's equations .*dependent coordinates.*lagcodegen.ConstrainedSystem"):
        lcg.derive(system)
    free = double_pendulum()
    free.form_eoms()
    with pytest.warns(UserWarning, match="have no value"):
        eom = lcg.derive(free.eom_method)
    assert [s.name for s in eom.model.v] == ["u1", "u2"]
    assert eom.M.shape == (2, 2)


def test_models_pass_through_and_no_physics_import_for_them():
    model = lcg.systems.pendulum()
    assert mechanics.as_model(model) is model
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        eom = lcg.derive(model)
    assert eom.model is model
    # deriving a lagcodegen Model does not import sympy.physics.mechanics (0.8 s)
    code = ("import sys, lagcodegen as lcg; lcg.derive(lcg.systems.pendulum()); "
            "print('sympy.physics.mechanics' in sys.modules)")
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[2]))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=300)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "False"
