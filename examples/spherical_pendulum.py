"""Spherical pendulum, full (theta, phi) and Routhian-reduced (theta; phi by quadrature).

phi is ignorable: C = m l^2 sin^2(theta) phi' is conserved (eq. 3.8) and the Routhian
R = -1/2 m l^2 theta'^2 + C^2/(2 m l^2 sin^2 theta) - m g l cos theta (eq. 3.9) leaves one
equation (3.10). Both systems are compiled and integrated from the same state; then the
conical pendulum is found as a steady motion (eq. 3.13): phi'^2 = g/(l cos theta0), with
small oscillations at Omega^2 = phi'^2 (1 + 3 cos^2 theta0).
"""

import math
from pathlib import Path

import numpy as np

import lagcodegen as lcg
from lagcodegen.theory.routhian import reduce
from lagcodegen.theory.steady import steady_motions
from lagcodegen.model.systems import spherical_pendulum

out = Path("out")
out.mkdir(exist_ok=True)

model = spherical_pendulum()
red = reduce(model)
print(f"ignorable: {[q.name for q in red.ignorable]}, integral {red.integrals[0]} = {red.momenta[0]}")
print(f"Routhian R = {red.R}")
full = lcg.compile_model(model, outputs=["jacobi_h", "p_phi"])
cm = lcg.compile_reduction(red, outputs=["jacobi_h"])

# ----------------------------------------------------------- full vs reduced trajectory
q0, v0 = [0.8, 0.0], [0.3, 2.0]
t = np.linspace(0.0, 40.0, 4001)
rf = full.simulate(t, q0=q0, v0=v0, rtol=1e-11, atol=1e-12)
rr = red.simulate(cm, t, q0, v0, rtol=1e-11, atol=1e-12)
print(f"C_phi = {rr.parameters['C_phi']:.12f}; states: full {full.state_names}, reduced {cm.state_names}")
for k in ("theta", "phi", "theta_dot", "phi_dot"):
    print(f"  max |full - reduced| {k:9s} = {np.max(np.abs(rf[k] - rr[k])):.2e}")
print(f"  h: full {rf['jacobi_h'][0]:.12f}, reduced (eq. 3.12) {rr['jacobi_h'][0]:.12f}; "
      f"drifts {rf.drift('jacobi_h'):.1e}, {rr.drift('jacobi_h'):.1e}; p_phi drift {rf.drift('p_phi'):.1e}")

# ----------------------------------------------------------- conical pendulum
g, l = 9.81, 1.0
theta0 = 0.9
phid = math.sqrt(g / (l * math.cos(theta0)))
C = l**2 * math.sin(theta0) ** 2 * phid
[s] = [s for s in steady_motions(red, {"C_phi": C}) if s.coordinates["theta"] > 0]
omega = phid * math.sqrt(1 + 3 * math.cos(theta0) ** 2)
print(f"conical pendulum for C = {C:.9f}: theta = {s.coordinates['theta']:.12f} (expected {theta0}), "
      f"phi' = {s.velocities['phi']:.12f} (expected {phid:.12f}), {'stable' if s.stable else 'unstable'}")
print(f"  small-oscillation frequency {s.frequencies[0]:.12f} (textbook {omega:.12f})")
# Nudge the conical motion: theta oscillates about theta0 with period 2 pi / Omega.
period = 2 * math.pi / omega
rc = red.simulate(cm, np.linspace(0.0, 5 * period, 2001), [theta0, 0.0], [1e-4, phid], rtol=1e-12, atol=1e-13)
dev = rc["theta"] - theta0
print(f"  nudged (theta' = 1e-4): amplitude {np.max(np.abs(dev)):.3e} (1e-4/Omega = {1e-4 / omega:.3e}), "
      f"theta - theta0 after 5 periods 2 pi/Omega: {dev[-1]:.1e}; mean phi' = {rc['phi'][-1] / (5 * period):.9f}")

import matplotlib  # noqa: E402
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

fig, axes = plt.subplots(3, 1, figsize=(8, 7), sharex=True)
axes[0].plot(t, rf["theta"], lw=1.5, label="full")
axes[0].plot(t, rr["theta"], "--", lw=1, label="reduced")
axes[0].set_ylabel("theta")
axes[0].legend(loc="upper right")
axes[1].plot(t, rf["phi"], lw=1.5)
axes[1].plot(t, rr["phi"], "--", lw=1)
axes[1].set_ylabel("phi")
axes[2].semilogy(t, np.abs(rf["theta"] - rr["theta"]) + 1e-17, lw=0.8, label="|d theta|")
axes[2].semilogy(t, np.abs(rf["phi"] - rr["phi"]) + 1e-17, lw=0.8, label="|d phi|")
axes[2].set_ylabel("full - reduced")
axes[2].set_xlabel("t")
axes[2].legend(loc="lower right")
fig.tight_layout()
fig.savefig(out / "spherical_pendulum.png", dpi=100)

x = l * np.sin(rc["theta"]) * np.cos(rc["phi"])
y = l * np.sin(rc["theta"]) * np.sin(rc["phi"])
fig, ax = plt.subplots(figsize=(5, 5))
ax.plot(x, y, lw=0.8)
ax.set_aspect("equal")
ax.set_title(f"conical pendulum, theta0 = {theta0}, nudged")
fig.savefig(out / "conical_pendulum.png", dpi=100)
print("wrote out/spherical_pendulum.png, out/conical_pendulum.png")
