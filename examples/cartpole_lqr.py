"""Cart-pole balanced by an LQR controller, closed in Python through the integrator object.

A cart (mass M, position x) carries a pole (point mass m at length l, angle th from upright) and
is pushed by a horizontal force F, declared as an input (``Model.input``: a run-time parameter
the controller writes). ``lagcodegen.linearize`` gives y' = A y about upright (y = (x, th, x',
th')); since F enters linearly, the accelerations per unit force at upright (``a0`` of the
linearization with F = 1) give B. The gain K of u = -K y comes from the continuous algebraic
Riccati equation (``scipy.linalg.solve_continuous_are``). Every control period (5 ms) the
controller reads the state (a view, no copy), writes F into the integrator's parameters (in
place) and advances it by one period: a zero-order hold, as a digital controller acts.

Writes out/cartpole_lqr.png (angle and force against time).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import scipy.linalg
import sympy as sp

import lagcodegen as lcg

PARAMS = {"M": 1.0, "m": 0.2, "l": 0.6, "g": 9.81}


def cartpole() -> lcg.Model:
    """The cart-pole with the force input F on the cart."""
    model = lcg.Model("cartpole")
    x, th = model.coordinates("x th")
    M, m, l, g = model.parameters(**PARAMS)
    F = model.input("F")
    model.particle("cart", M, (x, 0))
    model.particle("bob", m, (x - l * sp.sin(th), l * sp.cos(th)))  # th = 0: upright
    model.gravity(g)
    model.generalized_force(x, F)
    return model


def lqr_gain(model: lcg.Model, Q=np.diag([1.0, 100.0, 1.0, 10.0]), R: float = 0.01) -> np.ndarray:
    """K of u = -K y minimizing the integral of y'Qy + R u^2 for the linearization about upright."""
    eom = lcg.derive(model)
    lin = lcg.linearize(eom, q0=[0.0, 0.0], params={"F": 0.0})
    A = lin.A
    b = lcg.linearize(eom, q0=[0.0, 0.0], params={"F": 1.0}).a0  # accelerations per unit force
    B = np.concatenate([np.zeros(2), np.asarray(b, dtype=float)])[:, None]
    P = scipy.linalg.solve_continuous_are(A, B, Q, np.array([[R]]))
    return (B.T @ P / R).ravel()


def run(*, th0: float = 0.2, t_end: float = 10.0, period: float = 0.005, method: str = "taylor",
        sim=None, gain=None):
    """The closed loop from th = ``th0`` at rest: (t, states, F) at the control instants."""
    model = cartpole()
    sim = sim or lcg.compile_model(model)
    K = lqr_gain(model) if gain is None else gain
    steps = int(round(t_end / period))
    t = np.empty(steps + 1)
    ys = np.empty((steps + 1, 4))
    forces = np.empty(steps + 1)
    with sim.integrator(q0=[0.0, th0], method=method, rtol=1e-10, atol=1e-10) as integ:
        state = integ.state                       # a view of the integrator's memory
        params = integ.params                     # likewise: writing it sets the input
        k_force = integ.param_names.index("F")
        for k in range(steps + 1):
            u = -float(K @ state)
            t[k], ys[k], forces[k] = integ.time, state, u
            if k == steps:
                break
            params[k_force] = u                    # held for one period
            integ.propagate_until((k + 1) * period)
    return t, ys, forces


def main() -> None:
    out = Path("out")
    out.mkdir(exist_ok=True)
    t, ys, forces = run()
    th = ys[:, 1]
    inside = int(np.argmax(np.abs(th) < 0.05))
    print(f"within 0.05 rad of upright from t = {t[inside]:.3f} s on (max |th| after: "
          f"{np.max(np.abs(th[inside:])):.4f} rad); final th {th[-1]:.1e} rad, x {ys[-1, 0]:.1e} m; "
          f"max |F| {np.max(np.abs(forces)):.1f} N")
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, (ax1, ax2) = plt.subplots(2, 1, sharex=True, figsize=(7, 5))
    ax1.plot(t, th)
    ax1.axhline(0.05, color="grey", lw=0.5, ls="--")
    ax1.axhline(-0.05, color="grey", lw=0.5, ls="--")
    ax1.set_ylabel("pole angle from upright [rad]")
    ax2.step(t, forces, where="post")
    ax2.set_ylabel("force F [N]")
    ax2.set_xlabel("t [s]")
    fig.suptitle("cart-pole, LQR at a 5 ms control period")
    fig.tight_layout()
    fig.savefig(out / "cartpole_lqr.png", dpi=120)
    print("wrote out/cartpole_lqr.png")


if __name__ == "__main__":
    main()
