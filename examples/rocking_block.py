"""Housner's rocking block: a rectangular block (half-width b, half-height h) rocking on its
bottom corners.

The corners are contacts (lagcodegen.Inequality, restitution 0, eq. 4.3) that do not slip
(``tangent``: the corner's x held while it touches). Leaning on its left corner the block
pivots about it and falls back; at phi = 0 the right corner hits plastically and the left one
lifts off (its impulse would pull: the impact's active set leaves it out). The angular momentum
about the new corner is kept, so w+/w- = 1 - 2 m R^2 sin^2 a / I_0 = 1 - 1.5 sin^2 a
(I_0 = (4/3) m R^2 about a corner, sin a = b/R; Housner 1963) for any rectangle. The same block
on a frictionless floor (corners without ``tangent``) has no horizontal impulse and the ratio
(1 - 3 sin^2 a)/(1 + 3 sin^2 a).
"""

import math

import numpy as np
import sympy as sp

import lagcodegen as lcg
from lagcodegen.api import compile_constrained

b, h, g = 0.2, 0.6, 9.81


def block(no_slip: bool):
    m = lcg.Model("rocking_block" if no_slip else "sliding_block")
    x, y, phi = m.coordinates("x y phi")
    m.parameters(m=1.0, b=b, h=h, g=g)
    mass, B, H = sp.symbols("m b h")
    m.planar_body("block", mass, mass * (B**2 + H**2) / 3, (x, y), phi)
    m.gravity(sp.Symbol("g"))
    corners = [(x - B * sp.cos(phi) + H * sp.sin(phi), y - B * sp.sin(phi) - H * sp.cos(phi)),
               (x + B * sp.cos(phi) + H * sp.sin(phi), y + B * sp.sin(phi) - H * sp.cos(phi))]
    contacts = [lcg.Inequality(cy, restitution=0.0, tangent=cx if no_slip else None) for cx, cy in corners]
    return compile_constrained(lcg.ConstrainedSystem(m, inequalities=contacts), "index1", outputs=["energy"])


phi0 = 0.1
q0 = [-b + b * math.cos(phi0) - h * math.sin(phi0), h * math.cos(phi0) + b * math.sin(phi0), phi0]
sin2 = b**2 / (b**2 + h**2)
for no_slip, theory, name in ((True, 1 - 1.5 * sin2, "no slip (Housner): 1 - 1.5 sin^2 a"),
                              (False, (1 - 3 * sin2) / (1 + 3 * sin2), "frictionless: (1 - 3 sin^2 a)/(1 + 3 sin^2 a)")):
    sim = block(no_slip)
    res = sim.simulate(np.linspace(0, 1.5, 1501), q0=q0, v0=[0.0, 0.0, 0.0], rtol=1e-12, atol=1e-14)
    hits = res.impacts.select("stick")
    t_hit = hits[0].t
    near = sim.simulate(np.array([0.0, t_hit - 1e-9, t_hit + 1e-9]), q0=q0, v0=[0.0, 0.0, 0.0], rtol=1e-12,
                        atol=1e-14)
    print(f"{name}: impacts at {', '.join(f'{r.t:.5f}' for r in hits[:4])} ...; "
          f"w+/w- = {near['phi_dot'][2] / near['phi_dot'][1]:.9f}, theory {theory:.9f}")
