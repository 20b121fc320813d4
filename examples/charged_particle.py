"""A charge in uniform fields B (along z) and E (along x), through a generalized potential (eq. 3.4).

U = e (phi - v . A) with phi = -E x and A = (-B y/2, B x/2, 0). The orbit is a circle of radius
m v/(e B) run at the cyclotron frequency e B/m, carried along -y at the E x B drift speed E/B.
Jacobi's h = m v^2/2 + e phi is conserved: the magnetic force does no work.
"""

import math
from pathlib import Path

import matplotlib
import numpy as np
import sympy as sp

import lagcodegen as lcg
from lagcodegen.theory.forces import generalized_force_from_generalized_potential
from lagcodegen.model.systems import charged_particle

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

out = Path("out")
out.mkdir(exist_ok=True)

model = charged_particle()
U = model.generalized_potential_terms[0][1]
Q = generalized_force_from_generalized_potential(U, model.coords, model.speeds, model.t)
print(f"U = {U}\nQ (eq. 3.4) = {[sp.simplify(c) for c in Q]}  (= e (E + v x B))")

sim = lcg.compile_model(model, outputs=["jacobi_h"])
m, e, B = 2.0, 0.5, 3.0
w_c = e * B / m
period = 2 * math.pi / w_c
v0 = (1.2, 0.4)
t = np.linspace(0, 6 * period, 6 * 200 + 1)
runs = {}
for Ex in (0.0, 0.6):
    runs[Ex] = res = sim.simulate(t, q0=[0.0, 0.0], v0=v0, params=dict(m=m, e=e, B=B, Ex=Ex),
                                  rtol=1e-12, atol=1e-13)
    # Seen from the frame drifting at (0, -E/B) the velocity turns uniformly at -e B/m.
    angle = np.unwrap(np.arctan2(res["y_dot"] + Ex / B, res["x_dot"]))
    rate = np.polyfit(res.t, angle, 1)[0]
    drift = (res["y"][-1] - res["y"][0]) / res.t[-1]
    print(f"E = {Ex}: velocity (drifting frame) turns at {rate:.10f} (-e B/m = {-w_c}); y drift {drift:.10f} "
          f"(-E/B = {-Ex / B:.10f}); back to x(0) after 6 periods: {abs(res['x'][-1] - res['x'][0]):.1e}; "
          f"h drift {res.drift('jacobi_h'):.1e}")
res = runs[0.0]
# Least-squares circle x^2 + y^2 + a x + b y + c = 0 through the E = 0 path.
x, y = res["x"], res["y"]
ca, cb, cc = np.linalg.lstsq(np.column_stack([x, y, np.ones_like(x)]), -(x**2 + y**2), rcond=None)[0]
centre = np.array([-ca / 2, -cb / 2])
radius = math.sqrt(centre @ centre - cc)
print(f"fitted radius {radius:.10f} (m v/(e B) = {m * math.hypot(*v0) / (e * B):.10f}), "
      f"max |distance - radius| {np.max(np.abs(np.hypot(x - centre[0], y - centre[1]) - radius)):.1e}")

fig, ax = plt.subplots(figsize=(6, 6))
for Ex, r in runs.items():
    ax.plot(r["x"], r["y"], lw=1, label=f"E = {Ex}")
ax.set_aspect("equal")
ax.set_xlabel("x")
ax.set_ylabel("y")
ax.set_title("cyclotron orbit and E x B drift (B along +z)")
ax.legend()
ax.grid(alpha=0.3)
fig.tight_layout()
fig.savefig(out / "charged_particle.png", dpi=100)
print("wrote out/charged_particle.png")
