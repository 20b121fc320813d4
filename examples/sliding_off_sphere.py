"""A particle slides from the top of a smooth sphere and leaves it where cos(theta) = 2/3.

On the sphere the normal force is the multiplier of x^2 + y^2 = R^2 (eq. 4.5; A = (2x, 2y)
points outwards, so the surface pushes while lambda > 0). The event lambda = 0 (decreasing)
ends the constrained phase; the particle then flies freely (an unconstrained model) from the
event state, on a parabola. Starting at the top with speed v0, cos(theta) = (2 + v0^2/(g R))/3.
"""

import numpy as np
import sympy as sp

import lagcodegen as lcg
from lagcodegen.theory.constraints import ConstrainedSystem
from lagcodegen.api import compile_constrained
from lagcodegen.model.events import Event
from lagcodegen.simulation.hybrid import simulate_with_switch


def particle(name):
    m = lcg.Model(name)
    x, y = m.coordinates("x y")
    m.parameters(R=1.0, g=9.81, m=1.0)
    m.particle("p", sp.Symbol("m"), (x, y))
    m.gravity(sp.Symbol("g"))
    return m


on_sphere = particle("on_sphere")
x, y = on_sphere.coords
system = ConstrainedSystem(on_sphere, holonomic=[x**2 + y**2 - sp.Symbol("R") ** 2])
leave = Event("leave", system.multipliers[0], direction=-1, terminal=True)
constrained = compile_constrained(system, "index1", events=[leave], outputs=["energy", "lambda"])
free = lcg.compile_model(particle("free"), outputs=["energy"])

v0 = 1e-3
run = simulate_with_switch(constrained, free, np.linspace(0, 3.2, 321), q0=[0.0, 1.0], v0=[v0, 0.0],
                           rtol=1e-11, atol=1e-13)
ev = run.switch
print(f"leaves at t = {ev.t:.6f}: cos(theta) = {ev.q['y']:.10f} (theory {(2 + v0**2 / 9.81) / 3:.10f}, "
      f"2/3 = {2 / 3:.10f})")
print(f"speed there {np.hypot(ev.v['x'], ev.v['y']):.6f}, theory {np.sqrt(v0**2 + 2 * 9.81 / 3):.6f}")
flight = run.phases[1]
tau = flight.t - ev.t
print("free flight vs parabola: max |dy| =",
      f"{np.max(np.abs(flight['y'] - (ev.q['y'] + ev.v['y'] * tau - 9.81 / 2 * tau**2))):.2e}")
print(f"energy drift over both phases {np.max(np.abs(run['energy'] - run['energy'][0])):.2e}")
