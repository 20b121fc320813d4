"""Damped pendulum: energy decays at the rate dh/dt = -2D (eqs. 3.6, 3.15, 3.16).

A damper c on the bob gives D = c l^2 theta'^2/2, homogeneous quadratic in theta', so
sum_i q_i' dD/dq_i' = 2D and h(t) - h(0) = -2 int_0^t D dt.
"""

from pathlib import Path

import matplotlib
import numpy as np
import sympy as sp
from scipy.integrate import cumulative_trapezoid

import lagcodegen as lcg
from lagcodegen.model.systems import damped_pendulum

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

out = Path("out")
out.mkdir(exist_ok=True)

model = damped_pendulum()
eom = lcg.derive(model)
print(f"D = {sp.simplify(eom.D)}\ndh/dt = {sp.simplify(eom.dhdt)}  (= -2D)")
sim = lcg.compile_model(model, outputs=["energy", "jacobi_h", "dh_dt", "dissipation"])
t = np.linspace(0, 15, 150_001)
res = sim.simulate(t, q0=[1.2], rtol=1e-11, atol=1e-13)
h, D = res["jacobi_h"], res["dissipation"]
lost = -2 * cumulative_trapezoid(D, t, initial=0.0)
print(f"h: {h[0]:.6f} -> {h[-1]:.6f}")
print(f"max |dh_dt + 2D| = {np.max(np.abs(res['dh_dt'] + 2 * D)):.1e}")
print(f"max |h - h(0) + 2 int D| = {np.max(np.abs(h - h[0] - lost)):.1e} (trapezoid, dt = {t[1] - t[0]:g})")

fig, axes = plt.subplots(2, 1, figsize=(8, 5), sharex=True)
axes[0].plot(t, h - h[0], lw=2, label="h(t) - h(0)")
axes[0].plot(t, lost, "--", lw=1.5, label="-2 int D dt")
axes[0].set_ylabel("energy change")
axes[0].legend()
axes[1].plot(t, h - h[0] - lost, lw=1)
axes[1].set_ylabel("difference")
axes[1].set_xlabel("t")
for ax in axes:
    ax.grid(alpha=0.3)
fig.tight_layout()
fig.savefig(out / "damped_energy_decay.png", dpi=100)
print("wrote out/damped_energy_decay.png")
