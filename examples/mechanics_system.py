"""A sympy.physics.mechanics System (PinJoints, gravity, a torsion spring actuator) compiled by
lagcodegen: derive and compile_model take the System itself, since its speeds are q' (the
PinJoints' kinematic equations u = q')."""

import numpy as np
import sympy as sp
import sympy.physics.mechanics as me

import lagcodegen as lcg
from lagcodegen.model import mechanics

q1, q2 = me.dynamicsymbols("q1 q2")
m1, m2, l1, l2, g, k = sp.symbols("m1 m2 l1 l2 g k")

ground = me.RigidBody("ground")
N = ground.frame
upper, lower = me.RigidBody("upper", mass=m1), me.RigidBody("lower", mass=m2)
system = me.System.from_newtonian(ground)
shoulder = me.PinJoint("shoulder", ground, upper, coordinates=q1, child_point=l1 / 2 * upper.frame.y, joint_axis=N.z)
elbow = me.PinJoint("elbow", upper, lower, coordinates=q2, parent_point=-l1 / 2 * upper.frame.y,
                    child_point=l2 / 2 * lower.frame.y, joint_axis=upper.frame.z)
system.add_joints(shoulder, elbow)
system.apply_uniform_gravity(-g * N.y)
system.add_actuators(me.TorqueActuator(-k * q2, N.z, lower, upper))  # a torsion spring at the elbow

values = {"m1": 1.0, "m2": 0.6, "l1": 1.0, "l2": 0.7, "g": 9.81, "k": 2.0,
          "upper_izz": 1.0 / 12, "lower_izz": 0.6 * 0.49 / 12}
model = mechanics.from_system(system, parameters=values, name="two_rods")
eom = lcg.derive(model)
print("M =", sp.simplify(eom.M))

sim = lcg.compile_model(system, values=values, outputs=["energy", "positions"])
res = sim.simulate(np.linspace(0, 10, 1001), q0=[1.2, -0.5], rtol=1e-10, atol=1e-12)
# the spring's torque is a generalized force here (not a potential), so T + V is not conserved:
# it trades energy with the spring's k q2^2 / 2
total = res["energy"] + 0.5 * values["k"] * res["q2"] ** 2
print(f"q1(10) = {res['q1'][-1]:.6f}, q2(10) = {res['q2'][-1]:.6f}, "
      f"drift of T + V + k q2^2/2: {np.ptp(total) / abs(total[0]):.2e}")
