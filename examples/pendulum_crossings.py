"""Zero crossings of a large-amplitude pendulum located as events on CVODE and on the Taylor
method, against the elliptic-integral period: theta = 0 at (2j + 1) T/4, T = 4 K(k) sqrt(l/g),
k = sin(theta0/2); the turning points (p_theta = 0, an output) at j T/2; a terminal event."""

import math

import numpy as np
from scipy.special import ellipk

import lagcodegen as lcg

sim = lcg.compile_model(lcg.systems.pendulum(), outputs=["energy", "p_theta"])
theta0, l, g = 2.0, 1.0, 9.81
T = 4 * ellipk(math.sin(theta0 / 2) ** 2) * math.sqrt(l / g)
events = [lcg.Event("zero", "theta", 0, False),        # both directions, not terminal
          lcg.Event("turn", "p_theta", 1, False)]      # an output's name; increasing only
for method in ("adams", "bdf", "taylor"):
    res = sim.simulate([0, 20], q0=[theta0], method=method, events=events, rtol=1e-12, atol=1e-14)
    zeros = np.array([e.t for e in res.events if e.name == "zero"])
    exact = (2 * np.arange(zeros.size) + 1) * T / 4
    turns = np.array([e.t for e in res.events if e.name == "turn"])
    print(f"{method:6s}: {zeros.size} crossings, max relative error {np.max(np.abs(zeros - exact) / exact):.1e}; "
          f"{turns.size} increasing turning points, first at {turns[0]:.12f} (T = {T:.12f})")

stop = sim.simulate([0, 20], q0=[theta0], events=[lcg.Event("bottom", "theta", -1, True)], rtol=1e-12, atol=1e-14)
[ev] = stop.events
print(f"terminal event {ev.name} at t = {ev.t:.12f} (T/4 = {T / 4:.12f}), theta' = {ev.v['theta']:.9f}; "
      f"the run ends there: last row t = {stop.t[-1]:.12f}")
ens = sim.ensemble([0, 20], q0=np.linspace(0.2, 3.0, 8)[:, None], events=[lcg.Event("bottom", "theta", -1, True)],
                   rtol=1e-12, atol=1e-14)
print("quarter periods of 8 amplitudes (ensemble t_reached):", np.round(ens.t_reached, 6))
