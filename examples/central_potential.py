"""Kepler orbit in polar coordinates: period, angular momentum and energy conservation."""

import math
from pathlib import Path

import numpy as np

import lagcodegen as lcg

out = Path("out")
out.mkdir(exist_ok=True)
sim = lcg.compile_model(lcg.systems.central_potential(), outputs=["energy", "momenta", "positions"])
r0, v0 = 1.0, 1.2  # k = m = 1: a = 1/(2/r0 - v0^2)
a = 1 / (2 / r0 - v0**2)
period = 2 * math.pi * a**1.5
res = sim.simulate(np.linspace(0, 5 * period, 5001), q0=[r0, 0.0], v0=[0.0, v0 / r0], rtol=1e-11, atol=1e-12)
print(f"semi-major axis {a:.6f}, period {period:.6f}")
print(f"after 5 periods: r = {res['r'][-1]:.9f} (r0 = {r0}), phi/2pi = {res['phi'][-1] / (2 * math.pi):.9f}")
print(f"angular momentum p_phi drift {res.drift('p_phi'):.2e}, energy drift {res.drift('energy'):.2e}")
res.save(out / "orbit.csv")
import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

fig, ax = plt.subplots(figsize=(5, 5))
ax.plot(res["body_x"], res["body_y"], lw=0.8)
ax.plot([0], [0], "k*")
ax.set_aspect("equal")
fig.savefig(out / "orbit.png", dpi=100)
print("wrote out/orbit.csv, out/orbit.png")
