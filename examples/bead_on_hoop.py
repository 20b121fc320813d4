"""Bead on a spinning hoop: Jacobi's h = T2 - T0 + V is conserved (eqs. 3.6, 3.7), T + V is not.

The hoop (radius a) turns at the constant rate w about the vertical z axis; theta is the bead's
angle from the bottom. The map q -> x depends on t, so the system is not natural (eq. 2.2):
T = m a^2 theta'^2/2 (T2) + m a^2 w^2 sin^2(theta)/2 (T0), and the motor driving the hoop does work.
"""

from pathlib import Path

import matplotlib
import numpy as np
import sympy as sp

import lagcodegen as lcg
from lagcodegen.theory.energy import check_jacobi, kinetic_split

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

out = Path("out")
out.mkdir(exist_ok=True)

model = lcg.Model("hoop")
th, = model.coordinates("theta")
m, a, g, w = model.parameters(m=1.0, a=1.0, g=9.81, w=5.0)
t = model.t
model.particle("bead", m, (a * sp.sin(th) * sp.cos(w * t), a * sp.sin(th) * sp.sin(w * t), -a * sp.cos(th)))
model.gravity(g)

eom = lcg.derive(model)
split = kinetic_split(eom)
check = check_jacobi(eom)
print(f"T2 = {split.T2}\nT1 = {split.T1}\nT0 = {split.T0}\nh  = {sp.simplify(eom.h)}")
print(f"natural: {split.natural}; h conserved (dL/dt = 0): {check.conserved}; "
      f"h = T2 - T0 + V: {check.equals_T2_minus_T0_plus_V}; h = T + V: {check.equals_T_plus_V}")

sim = lcg.compile_model(model, outputs=["energy", "jacobi_h"])
res = sim.simulate(np.linspace(0, 60, 6001), q0=[0.3], rtol=1e-11, atol=1e-12)
E, h = res["energy"], res["jacobi_h"]
print(f"stable equilibrium theta* = arccos(g/(a w^2)) = {np.arccos(9.81 / 25):.4f}; "
      f"theta ranges over [{res['theta'].min():.4f}, {res['theta'].max():.4f}]")
print(f"h drift {res.drift('jacobi_h'):.2e}; T+V ranges over [{E.min():.4f}, {E.max():.4f}]")

fig, axes = plt.subplots(2, 1, figsize=(8, 5), sharex=True)
axes[0].plot(res.t, res["theta"], lw=1)
axes[0].set_ylabel("theta")
axes[1].plot(res.t, E, lw=1, label="T + V")
axes[1].plot(res.t, h, lw=1.5, label="h = T2 - T0 + V")
axes[1].set_ylabel("energy")
axes[1].set_xlabel("t")
axes[1].legend()
for ax in axes:
    ax.grid(alpha=0.3)
fig.tight_layout()
fig.savefig(out / "bead_on_hoop.png", dpi=100)
print("wrote out/bead_on_hoop.png")
