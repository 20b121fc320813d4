"""Damped driven oscillator m x'' + c x' + k x = F0 cos(w t) against its analytic solution."""

import math
from pathlib import Path

import numpy as np

import lagcodegen as lcg

out = Path("out")
out.mkdir(exist_ok=True)
sim = lcg.compile_model(lcg.systems.damped_driven_oscillator(), outputs=["energy", "dissipation"])
t = np.linspace(0, 40, 2001)
x0, v0 = 1.0, 0.0
res = sim.simulate(t, q0=[x0], v0=[v0], rtol=1e-10, atol=1e-12)
p = res.parameters
m, k, c, F0, w = (p[n] for n in ("m", "k", "c", "F0", "w"))
D = (k - m * w**2) ** 2 + (c * w) ** 2
A, B = F0 * (k - m * w**2) / D, F0 * c * w / D
gam, wd = c / (2 * m), math.sqrt(k / m - (c / (2 * m)) ** 2)
C1 = x0 - A
C2 = (v0 - B * w + gam * C1) / wd
exact = np.exp(-gam * t) * (C1 * np.cos(wd * t) + C2 * np.sin(wd * t)) + A * np.cos(w * t) + B * np.sin(w * t)
print(f"max |x - analytic| = {np.max(np.abs(res['x'] - exact)):.2e}")
print(f"steady-state amplitude |F0|/sqrt((k - m w^2)^2 + (c w)^2) = {math.hypot(A, B):.6f}; "
      f"max |x| over the last 5 time units: {np.abs(res['x'][t > 35]).max():.6f}")
res.save(out / "oscillator.csv")
res.plot(out / "oscillator.png", ["x", "x_dot", "energy"])
print("wrote out/oscillator.csv, out/oscillator.png")
