"""Newton's cradle: three equal balls on a line, e = 1, small gaps between them.

The gaps x2 - x1 - d >= 0 and x3 - x2 - d >= 0 are contacts (lagcodegen.Inequality with
restitution 1, eq. 4.3). Ball 1 comes in with speed 1; with the gaps the impacts are separate
instants and each passes the whole velocity on (equal masses, e = 1), so ball 3 leaves with
speed 1 and balls 1, 2 stop. Momentum and energy are conserved across the impacts. (Balls that
touch at the same instant would be solved together by Newton's law on the joint system, which is
not the pairwise sequence: see lagcodegen.simulation.constrained_impacts.)
"""

import numpy as np
import sympy as sp

import lagcodegen as lcg
from lagcodegen.api import compile_constrained

m = lcg.Model("newtons_cradle")
xs = m.coordinates("x1 x2 x3")
m.parameters(m=1.0, d=0.1)
for i, x in enumerate(xs):
    m.particle(f"ball{i + 1}", sp.Symbol("m"), (x, 0))
d = sp.Symbol("d")
contacts = [lcg.Inequality(xs[1] - xs[0] - d, restitution=1.0), lcg.Inequality(xs[2] - xs[1] - d, restitution=1.0)]
sim = compile_constrained(lcg.ConstrainedSystem(m, inequalities=contacts), "index1", outputs=["energy"])

gap = 1e-3
res = sim.simulate(np.linspace(0, 1, 101), q0=[0.0, 0.1 + gap, 0.2 + 2 * gap], v0=[1.0, 0.0, 0.0],
                   rtol=1e-12, atol=1e-14)
for r in res.impacts:
    print(f"t = {r.t:.9f}: contact {r.contact} {r.kind}, impulse {r.impulse:.12f}, "
          f"normal speed {r.w_before:+.12f} -> {r.w_after:+.12f}")
print("final velocities", res.y[-1, 3:])
print(f"momentum drift {np.max(np.abs(res.y[:, 3:].sum(axis=1) - 1)):.1e}, "
      f"energy drift {np.max(np.abs(res['energy'] - 0.5)):.1e}")
