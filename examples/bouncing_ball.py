"""A ball dropped from h0 = 1 onto a floor with restitution e = 0.8 (bouncing_ball.toml).

The floor y >= 0 is a contact (lagcodegen.Inequality with a restitution, eq. 4.3): at every
impact the generated C applies the impulse that gives y'+ = -e y'- (Newton's law) and the run
goes on in the same call of the driver. The impacts accumulate (Zeno) at t1 (1 + e)/(1 - e);
once the rebounds are slower than ContactOptions.contact_speed the ball rests on the floor,
held by the multiplier lambda_ineq_0 = m g.
"""

import math

import numpy as np
import sympy as sp

import lagcodegen as lcg
from lagcodegen.api import compile_constrained

e, h0, g = 0.8, 1.0, 9.81
m = lcg.Model("bouncing_ball")
(y,) = m.coordinates("y")
m.parameters(g=g, m=1.0)
m.particle("ball", sp.Symbol("m"), (0, y))
m.gravity(sp.Symbol("g"))
system = lcg.ConstrainedSystem(m, inequalities=[lcg.Inequality(y, restitution=e)])
sim = compile_constrained(system, "index1", outputs=["energy"])

res = sim.simulate(np.linspace(0, 6, 601), q0=[h0], v0=[0.0], rtol=1e-12, atol=1e-14)
t1 = math.sqrt(2 * h0 / g)
bounces = res.impacts.select("bounce")
print(f"{len(bounces)} bounces, then persistent contact at t = {res.impacts.select('stick')[0].t:.7f} "
      f"(accumulation time t1 (1 + e)/(1 - e) = {t1 * (1 + e) / (1 - e):.7f})")
print(f"accumulation time extrapolated from the impacts: {res.impacts.accumulation_time(0):.10f}")
worst = max(abs(r.t / (t1 + 2 * t1 * e * (1 - e**k) / (1 - e)) - 1) for k, r in enumerate(bounces[:20]))
print(f"impact times, first 20: largest relative error {worst:.1e}")
apex = [r.w_after**2 / (2 * g) for r in bounces[:5]]
print("apex heights", ", ".join(f"{a:.6f}" for a in apex), "(h0 e^(2k):",
      ", ".join(f"{h0 * e ** (2 * k):.6f}" for k in range(1, 6)) + ")")
print(f"resting: y = {res['y'][-1]:.1e}, multiplier {res['lambda_ineq_0'][-1]:.6f} (m g = {g})")
