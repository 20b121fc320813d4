"""Kepler problem through the Routhian: phi is ignorable, C = m r^2 phi' (angular momentum).

R = -m r'^2/2 + C^2/(2 m r^2) - k/r (eq. 3.9) leaves the radial equation (3.10); phi follows
by quadrature phi' = dR/dC = C/(m r^2) (eq. 3.11). The circular orbit is the steady motion
dR/dr = 0 (eq. 3.13): r0 = C^2/(m k); an elliptic orbit's period is 2 pi a^{3/2} sqrt(m/k).
"""

import math
from pathlib import Path

import numpy as np

from lagcodegen import compile_reduction, systems
from lagcodegen.theory.routhian import reduce
from lagcodegen.theory.steady import steady_motions

out = Path("out")
out.mkdir(exist_ok=True)

m, k = 2.0, 3.0
params = {"m": m, "k": k}
red = reduce(systems.central_potential())
print(f"R = {red.R}; phi' = dR/dC = {red.reconstruction[0]}")
cm = compile_reduction(red, outputs=["jacobi_h"])

# Circular orbit as a steady motion.
C = 1.7
[s] = steady_motions(red, {"C_phi": C}, params=params)
print(f"circular orbit for C = {C}: r0 = {s.coordinates['r']:.12f} (C^2/(m k) = {C**2 / (m * k):.12f}), "
      f"phi' = {s.velocities['phi']:.12f}, radial frequency {s.frequencies[0]:.12f} "
      f"({'stable' if s.stable else 'unstable'}; equal to phi' for closed Kepler orbits)")

# Elliptic orbit: r0 = 1 at periapsis, phi' = 1.6 (eccentricity 0.71).
r0, w0 = 1.0, 1.6
a = 1.0 / (2.0 / r0 - m * (r0 * w0) ** 2 / k)
period = 2 * math.pi * a**1.5 * math.sqrt(m / k)
t = np.linspace(0.0, 3 * period, 3001)
res = red.simulate(cm, t, [r0, 0.0], [0.0, w0], params=params, rtol=1e-12, atol=1e-13)
i1 = np.argmin(np.abs(t - period))
print(f"elliptic orbit: a = {a:.9f}, period 2 pi a^1.5 sqrt(m/k) = {period:.9f}")
print(f"  after 3 periods: r = {res['r'][-1]:.10f} (r0 = {r0}), phi / 2 pi = {res['phi'][-1] / (2 * math.pi):.10f}")
print(f"  apoapsis r_max = {res['r'].max():.8f} (2a - r0 = {2 * a - r0:.8f}); "
      f"C = {res.parameters['C_phi']:.12f}; h drift {res.drift('jacobi_h'):.1e}")

import matplotlib  # noqa: E402
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

fig, axes = plt.subplots(1, 2, figsize=(10, 4.5))
axes[0].plot(res["r"] * np.cos(res["phi"]), res["r"] * np.sin(res["phi"]), lw=0.8)
axes[0].plot([0], [0], "k*")
axes[0].set_aspect("equal")
axes[0].set_title("orbit from (r, r', phi) of the reduced system")
rr = np.linspace(0.2, 6.0, 400)
for Ci in (1.0, C, 2.4):
    axes[1].plot(rr, Ci**2 / (2 * m * rr**2) - k / rr, label=f"C = {Ci}")
axes[1].axvline(s.coordinates["r"], color="k", lw=0.5)
axes[1].set_ylim(-4, 2)
axes[1].set_xlabel("r")
axes[1].set_title("amended potential C^2/(2 m r^2) - k/r")
axes[1].legend()
fig.tight_layout()
fig.savefig(out / "kepler_routhian.png", dpi=100)
print("wrote out/kepler_routhian.png")
