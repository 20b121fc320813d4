"""Identification of a robot arm's inertial parameters by least squares on the inverse-dynamics
regressor (tau = Y(q, q', q'') pi, ``CompiledModel.inverse_dynamics_regressor``).

The arm is the Franka Panda of example-robot-data (7 joints, the fingers locked), loaded with the
hand's inertial as run-time parameters (``urdf.load(..., inertial_parameters=["panda_hand"])``):
the "true" robot carries a payload in its hand (0.8 kg, off the flange), which the URDF does not
know. It follows an exciting trajectory, a finite Fourier series per joint (5 harmonics of
0.25 Hz, about 0.5 rad); the joint torques it takes are its inverse dynamics (computed torques,
``inverse_dynamics``, joint damping included), measured with Gaussian noise (``SIGMA``).

The regressor's 70 columns (10 per body) are not all identifiable: some parameters never act
(the first body turns about a fixed vertical axis), others only in combinations. A QR
factorization with column pivoting of the stacked regressor [Y | diag(q')] (the viscous damping
identified too) finds its rank r and the base parameters: beta = pi_1 + R11^-1 R12 pi_2, with
pi_1 the r columns the pivoting chose (Gautier 1991): r = 50, the 43 inertial base parameters
Gaz et al. (2019) found for the Panda and the 7 damping coefficients. Ordinary least squares gives beta and its
standard errors s (R11^T R11)^-1/2, s^2 the residual variance; the true beta follows from the
true pi (``regressor_parameters`` at the true parameters). Each estimate lies within 3 standard
errors of the truth with probability 0.997, all 50 together with about 0.87: the noise of seed 0
keeps them all inside (the largest |z| 2.4, quick or not); seeds 4 and 5 of 1-10 put one just
outside (|z| 3.2, 3.3) with ``--quick``.

    python examples/identify_arm.py            # 8 s at 200 Hz
    python examples/identify_arm.py --quick    # 4 s at 100 Hz
"""

from __future__ import annotations

import argparse
import site
from pathlib import Path

import numpy as np
import scipy.linalg

import lagcodegen as lcg
from lagcodegen import urdf

FINGERS = ["panda_finger_joint1", "panda_finger_joint2"]
#: The standard deviation of the torque measurements (N m).
SIGMA = 0.05
#: The payload in the hand: mass (kg), centre of mass in the hand's frame (m).
PAYLOAD = (0.8, np.array([0.02, -0.01, 0.12]))


def panda_urdf() -> Path:
    """example-robot-data's panda.urdf (installed with Pinocchio under the cmeel prefix)."""
    for base in site.getsitepackages():
        path = Path(base) / "cmeel.prefix/share/example-robot-data/robots/panda_description/urdf/panda.urdf"
        if path.exists():
            return path
    raise FileNotFoundError("example-robot-data's panda.urdf (pip install example-robot-data)")


def compile_arm(path: Path | None = None) -> lcg.CompiledModel:
    """The Panda arm, fingers locked, the hand's 10 inertial parameters at run time."""
    return lcg.compile_urdf(path or panda_urdf(), load={"lock": FINGERS, "inertial_parameters": ["panda_hand"]})


def true_parameters(sim) -> dict:
    """The hand with the payload (a point mass) added: the run-time parameters of the true robot."""
    p = dict(zip(sim.param_names, sim.parameter_vector()))
    m, c = PAYLOAD
    Io = m * (c @ c * np.eye(3) - np.outer(c, c))  # a point mass about the hand frame's origin
    extra = [m, *(m * c), Io[0, 0], Io[0, 1], Io[1, 1], Io[0, 2], Io[1, 2], Io[2, 2]]
    for suffix, value in zip(["m", "mx", "my", "mz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz"], extra):
        p[f"panda_hand_{suffix}"] += value
    return p


def excitation(t: np.ndarray, n: int, seed: int = 1) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(q, q', q'') (len(t) x n): a finite Fourier series per joint, 5 harmonics of 0.25 Hz."""
    rng = np.random.default_rng(seed)
    w = 2 * np.pi * 0.25
    k = np.arange(1, 6)
    a, b = rng.normal(scale=0.35, size=(2, n, 5)) / k
    q0 = np.array([0.0, -0.3, 0.0, -2.0, 0.0, 1.8, 0.8])[:n]
    wt = np.outer(t, k * w)  # (N, 5)
    s, c = np.sin(wt), np.cos(wt)
    q = q0 + (s @ (a / (k * w)).T) - (c @ (b / (k * w)).T)
    v = c @ a.T + s @ b.T
    acc = -(s @ (a * k * w).T) + c @ (b * k * w).T
    return q, v, acc


def stacked_regressor(sim, q: np.ndarray, v: np.ndarray, a: np.ndarray) -> np.ndarray:
    """[Y(q_k, q'_k, q''_k) | diag(q'_k)] stacked over the samples k: (N n) x (10 nb + n)."""
    return np.vstack([np.hstack([sim.inverse_dynamics_regressor(qk, vk, ak), np.diag(vk)])
                      for qk, vk, ak in zip(q, v, a)])


def base_parameters(W: np.ndarray, tol: float = 1e-8) -> tuple[np.ndarray, int, np.ndarray]:
    """(the column permutation, the rank r, K = R11^-1 R12) of W's QR with column pivoting: the
    base parameters are beta = pi[perm[:r]] + K pi[perm[r:]]."""
    _, R, perm = scipy.linalg.qr(W, mode="economic", pivoting=True)
    d = np.abs(np.diag(R))
    r = int(np.sum(d > tol * d[0]))
    K = scipy.linalg.solve_triangular(R[:r, :r], R[:r, r:])
    return perm, r, K


def identify(W: np.ndarray, tau: np.ndarray, perm: np.ndarray, r: int) -> tuple[np.ndarray, np.ndarray, float]:
    """(beta, its standard errors, the residual's standard deviation) by least squares."""
    W1 = W[:, perm[:r]]
    Q, R = np.linalg.qr(W1)
    beta = scipy.linalg.solve_triangular(R, Q.T @ tau)
    resid = tau - W1 @ beta
    s2 = resid @ resid / (len(tau) - r)
    Rinv = scipy.linalg.solve_triangular(R, np.eye(r))
    return beta, np.sqrt(s2 * np.sum(Rinv ** 2, axis=1)), float(np.sqrt(s2))


def run(quick: bool = False, seed: int = 0, path: Path | None = None) -> dict:
    """The identification; a dict of what it found and the truth."""
    path = path or panda_urdf()
    sim = compile_arm(path)
    n = sim.n
    duration, rate = (4.0, 100.0) if quick else (8.0, 200.0)
    t = np.arange(0.0, duration, 1.0 / rate)
    q, v, a = excitation(t, n)
    truth = true_parameters(sim)
    tau = np.array([sim.inverse_dynamics(qk, vk, ak, params=truth) for qk, vk, ak in zip(q, v, a)])
    rng = np.random.default_rng(seed)
    measured = (tau + rng.normal(scale=SIGMA, size=tau.shape)).ravel()
    W = stacked_regressor(sim, q, v, a)
    robot = urdf.read(path)
    damping = np.array([robot.joints[name].dynamics.damping for name in sim.state_names[:n]])
    pi = np.concatenate([sim.regressor_parameters(truth), damping])
    perm, r, K = base_parameters(W)
    beta_true = pi[perm[:r]] + K @ pi[perm[r:]]
    beta, se, s = identify(W, measured, perm, r)
    z = (beta - beta_true) / se
    names = [f"{b}_{x}" for b in sim.regressor_bodies for x in ["m", "mx", "my", "mz", "Ixx", "Ixy", "Iyy", "Ixz",
                                                                  "Iyz", "Izz"]] + [f"{c}_damping" for c in
                                                                                    sim.state_names[:n]]
    return dict(samples=len(t), columns=W.shape[1], rank=r, beta=beta, beta_true=beta_true, se=se, z=z,
                sigma_hat=s, names=[names[i] for i in perm[:r]], W=W, perm=perm, tau=tau, q=q, v=v, a=a, sim=sim)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="4 s at 100 Hz instead of 8 s at 200 Hz")
    parser.add_argument("--seed", type=int, default=0, help="the noise's seed")
    args = parser.parse_args(argv)
    out = run(quick=args.quick, seed=args.seed)
    print(f"{out['samples']} samples x 7 joints, {out['columns']} regressor columns, {out['rank']} base parameters")
    print(f"residual standard deviation {out['sigma_hat']:.4f} N m (noise {SIGMA} N m)")
    print(f"{'base parameter (leading column)':36s} {'estimate':>12s} {'std. error':>11s} {'truth':>12s} {'z':>6s}")
    for name, b, e, bt, z in zip(out["names"], out["beta"], out["se"], out["beta_true"], out["z"]):
        print(f"{name:36s} {b:12.5f} {e:11.5f} {bt:12.5f} {z:6.2f}")
    worst = np.abs(out["z"]).max()
    print(f"largest |estimate - truth| / std. error: {worst:.2f}; within 2 standard errors: "
          f"{np.mean(np.abs(out['z']) < 2):.0%}")
    return 0 if worst < 3 else 1


if __name__ == "__main__":
    raise SystemExit(main())
