"""A vertical disc rolling without slipping on a plane: two nonholonomic constraints (eq. 4.3).

Coordinates: contact point (x, y), heading theta, rolling angle phi. Rolling:
x' = R cos(theta) phi', y' = R sin(theta) phi'. The Frobenius test says neither Pfaffian form is
integrable (while x' - R phi' = 0 for a disc rolling on a line is: it is holonomic). With no
torque theta' and phi' stay constant, and the contact point runs on a circle of radius
R phi'/theta'; energy is conserved and the constraints hold (|A q'| small).
"""

import numpy as np
import sympy as sp

import lagcodegen as lcg
from lagcodegen.theory.constraints import ConstrainedSystem, integrability
from lagcodegen.api import compile_constrained

m = lcg.Model("rolling_disc")
x, y, th, phi = m.coordinates("x y theta phi")
mass, R = m.parameters(m=1.0, R=0.3)
I_roll, I_turn = mass * R**2 / 2, mass * R**2 / 4
m.kinetic_energy(mass / 2 * (m.dot(x) ** 2 + m.dot(y) ** 2) + I_roll / 2 * m.dot(phi) ** 2
                 + I_turn / 2 * m.dot(th) ** 2)
rolling = [([1, 0, 0, -R * sp.cos(th)], 0), ([0, 1, 0, -R * sp.sin(th)], 0)]
system = ConstrainedSystem(m, nonholonomic=rolling)
for j in range(2):
    rep = system.is_integrable(j)
    print(f"constraint {j}: integrable = {rep.integrable}; w ^ dw components {list(rep.obstruction.values())}")
print("x' - R phi' = 0 integrable:", integrability([1, 0, 0, -R], 0, m.coords, m.t).integrable)

sim = compile_constrained(system, "ggl", outputs=["energy", "lambda", "residuals"])
radius_disc, theta_dot, phi_dot = 0.3, 0.5, 4.0  # the default R, and the rates
v0 = [radius_disc * phi_dot, 0.0, theta_dot, phi_dot]  # heading along +x, rolling: x' = R phi'
res = sim.simulate(np.linspace(0, 40, 4001), q0=[0, 0, 0, 0], v0=v0, rtol=1e-10, atol=1e-12)
radius = radius_disc * phi_dot / theta_dot
cx, cy = 0.0, radius  # starts at the origin heading along +x, turning left
r = np.hypot(res["x"] - cx, res["y"] - cy)
print(f"circle radius {radius:.6f}: max deviation {np.max(np.abs(r - radius)):.2e}")
print(f"energy drift {res.drift('energy'):.2e}; max |A q'| {max(np.max(np.abs(res[k])) for k in ('gdot_0', 'gdot_1')):.2e}")
print(f"theta' range {np.ptp(res['theta_dot']):.2e}, phi' range {np.ptp(res['phi_dot']):.2e}")
