"""A rectangular block (half-width b, half-height h) rocking on a smooth (frictionless) floor.

Its bottom corners are contacts (lagcodegen.Inequality, restitution 0, eq. 4.3): leaning on
its left corner the block falls back, the right corner hits plastically at phi = 0 and the
left one lifts off (its impulse would pull: the impact's active set drops it). With no friction
there is no horizontal impulse; the angular momentum about the centre and the vertical
momentum give w+/w- = (I_c - m b^2)/(I_c + m b^2) = (1 - 3 sin^2 a)/(1 + 3 sin^2 a) with
I_c = m R^2/3, sin a = b/R. (Housner's block, which rolls on its corners without slipping,
has 1 - 1.5 sin^2 a; that needs friction, which these contacts do not model.) The rocking
decays; each half cycle is shorter.
"""

import math

import numpy as np
import sympy as sp

import lagcodegen as lcg
from lagcodegen.api import compile_constrained

b, h, g = 0.2, 0.6, 9.81
m = lcg.Model("rocking_block")
x, y, phi = m.coordinates("x y phi")
m.parameters(m=1.0, b=b, h=h, g=g)
mass, B, H = sp.symbols("m b h")
m.planar_body("block", mass, mass * (B**2 + H**2) / 3, (x, y), phi)
m.gravity(sp.Symbol("g"))
left = y - B * sp.sin(phi) - H * sp.cos(phi)
right = y + B * sp.sin(phi) - H * sp.cos(phi)
system = lcg.ConstrainedSystem(m, inequalities=[lcg.Inequality(left, restitution=0.0),
                                                lcg.Inequality(right, restitution=0.0)])
sim = compile_constrained(system, "index1", outputs=["energy"])

phi0 = 0.1
q0 = [0.0, h * math.cos(phi0) + b * math.sin(phi0), phi0]
res = sim.simulate(np.linspace(0, 1.0, 1001), q0=q0, v0=[0.0, 0.0, 0.0], rtol=1e-12, atol=1e-14)
hits = res.impacts.select("stick")
print("impacts at", ", ".join(f"{r.t:.5f}" for r in hits[:6]), "...")
t_hit = hits[0].t
near = sim.simulate(np.array([0.0, t_hit - 1e-9, t_hit + 1e-9]), q0=q0, v0=[0.0, 0.0, 0.0], rtol=1e-12, atol=1e-14)
sin2 = b**2 / (b**2 + h**2)
print(f"w+/w- = {near['phi_dot'][2] / near['phi_dot'][1]:.9f}, (1 - 3 sin^2 a)/(1 + 3 sin^2 a) = "
      f"{(1 - 3 * sin2) / (1 + 3 * sin2):.9f} (Housner, no slip: {1 - 1.5 * sin2:.6f})")
after = [res["energy"][np.searchsorted(res.t, r.t)] for r in hits[:5]]
print("energy after each impact:", ", ".join(f"{E:.6f}" for E in after))
