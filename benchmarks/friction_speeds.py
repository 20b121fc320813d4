"""Figures of Coulomb friction with generalized speeds and 3-D friction (issue 39): the errors of
the tests' systems (tests/test_friction_speeds.py) against their closed-form facts.

- a sphere on a free joint launched with backspin (planar friction, one tangent), quaternion and
  Z-Y-X: the slip end against 2 (v0 + R w0) / (7 mu g), the rolling speed against
  (5 v0 - 2 R w0) / 7;
- the same launched diagonally on the exact circular cone (two tangents): the same two facts
  along the slip direction, and the largest velocity across it;
- a particle on an incline in 3-D, tangents turned by beta: its position against
  g (sin alpha - mu cos alpha) t^2 / 2 where it slides, its drift where it sticks;
- the incline's particle launched across the slope (its slip turning downhill) against scipy's
  DOP853 on the closed-form equations;
- a spinning sphere's 3-D frictional impact: the tangential impulse against 2/7 m |u-| (stick) or
  mu P_n (slide).

    PYTHONPATH=. python benchmarks/friction_speeds.py [--quick] [--out DIR]
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
sys.path.insert(0, str(Path(__file__).resolve().parent))
import _harness as H  # noqa: E402
import test_friction_speeds as T  # noqa: E402
from lagcodegen.api import compile_constrained  # noqa: E402

G, MU, R = T.G, T.MU, T.RADIUS


def backspin(rotation, tangents):
    """(|t_grip / t* - 1|, max |v / v_roll - 1| after, max |v across|) of the sphere's launch."""
    v0, w0 = 3.0, 4.0
    e = np.array([0.0, 1.0]) if tangents == "y" else np.array([0.6, 0.8])
    axis = np.array([-e[1], e[0]])
    sim = T._sphere(rotation, tangents)
    t_star, v_roll = 2 * (v0 + R * w0) / (7 * MU * G), (5 * v0 - 2 * R * w0) / 7
    q0, u0 = T._start(rotation, (v0 * e[0], v0 * e[1], 0), (-w0 * axis[0], -w0 * axis[1], 0.0))
    res = sim.simulate(np.linspace(0, 2 * t_star, 41), q0=q0, v0=u0, **T.TIGHT)
    grip = [r.t for r in res.impacts.transitions(0) if r.kind == "grip"][0]
    rates = np.array([sim.compiled.rhs(tt, yy)[:2] for tt, yy in zip(res.t, res.y)])
    after = res.t > t_star
    return abs(grip / t_star - 1), np.abs(rates[after] @ e / v_roll - 1).max(), np.abs(rates @ axis).max()


def incline(alpha, mu, beta):
    sim = T._incline_3d(alpha, mu, beta)
    t = np.linspace(0, 2, 21)
    res = sim.simulate(t, q0=[0.0, 0.0, 0.0], v0=[0.0, 0.0, 0.0], **T.TIGHT)
    if math.tan(alpha) <= mu:
        return "sticks", np.abs(res.y[:, :3]).max()
    acc = G * (math.sin(alpha) - mu * math.cos(alpha))
    return "slides", np.abs(res["x"][1:] / (0.5 * acc * t[1:] ** 2) - 1).max()


def across(mu):
    """(max |xy - DOP853's|, |t_grip / t_stop - 1| or None) of the incline's particle launched across."""
    from scipy.integrate import solve_ivp

    alpha, vy0 = 0.5, 3.0
    sim = T._incline_3d(alpha, mu, 0.3)
    n = G * math.cos(alpha)

    def f(t, s):
        speed = math.hypot(s[2], s[3])
        return [s[2], s[3], G * math.sin(alpha) - mu * n * s[2] / speed, -mu * n * s[3] / speed]

    def stops(t, s):
        return math.hypot(s[2], s[3]) - 1e-9
    stops.terminal = True
    ref = solve_ivp(f, (0, 3.0), [0, 0, 0, vy0], method="DOP853", rtol=1e-13, atol=1e-14, events=stops,
                    dense_output=True)
    sticks = mu > math.tan(alpha)
    t = np.linspace(0, ref.t[-1] * 0.999 if sticks else 3.0, 31)
    res = sim.simulate(np.append(t, 3.0) if sticks else t, q0=[0.0, 0.0, 0.0], v0=[0.0, vy0, 0.0], **T.TIGHT)
    err = np.abs(res.y[: t.size, :2] - ref.sol(t)[:2].T).max()
    grip = [r.t for r in res.impacts.transitions(0) if r.kind == "grip"]
    return err, abs(grip[0] / ref.t_events[0][0] - 1) if sticks and grip else None


def impact(mu):
    e, h = 0.5, 0.2
    vel, spin = np.array([3.0, -2.0, 0.0]), np.array([2.0, 3.0, 5.0])
    sim = compile_constrained(T._sphere_system(mu, e), "index1", outputs=["energy"])
    t1 = math.sqrt(2 * h / G)
    u = np.array([vel[0] - R * spin[1], vel[1] + R * spin[0]])
    pn = (1 + e) * G * t1
    sticks = np.linalg.norm(u) <= 3.5 * mu * pn
    pt = np.linalg.norm(u) / 3.5 if sticks else mu * pn
    res = sim.simulate(np.array([0.0, t1 + 0.01]), q0=[0, 0, R + h, 0, 0, 0, 1], v0=[*vel, *spin], **T.TIGHT)
    got = [r.impulse for r in res.impacts if r.kind == "tangential_impulse"][0]
    return ("sticks" if sticks else "slides"), abs(got / pt - 1)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="quaternion only, two inclines, one impact")
    ap.add_argument("--out", type=Path, help="also write the table to OUT/friction_speeds.txt")
    args = ap.parse_args(argv)
    load0 = H.load_average()
    lines = ["sphere with backspin (rtol 1e-12): slip end rel. error, rolling speed rel. error, max |v across|"]
    for rotation in ["quaternion"] if args.quick else ["quaternion", "ZYX"]:
        for tangents in ("y", "xy"):
            H.progress("friction_speeds", f"sphere {rotation} {tangents}")
            a, b, c = backspin(rotation, tangents)
            cone = "planar (1 tangent)" if tangents == "y" else "3-D cone (2 tangents)"
            lines.append(f"  {rotation:<10} {cone:<22} {a:.1e}  {b:.1e}  {c:.1e}")
    lines.append("particle on an incline in 3-D (tangents turned by beta): sliding position rel. error / sticking drift")
    cases = [(0.5, 0.3, 0.7), (0.5, 0.6, 0.0)] if args.quick else [(0.5, 0.6, 0.0), (0.5, 0.3, 0.0), (0.5, 0.3, 0.7),
                                                                   (0.3, 0.31, 1.1), (0.3, 0.1, 2.0)]
    for alpha, mu, beta in cases:
        H.progress("friction_speeds", f"incline {alpha} {mu} {beta}")
        kind, err = incline(alpha, mu, beta)
        lines.append(f"  alpha {alpha}, mu {mu}, beta {beta}: {kind}, {err:.1e}")
    lines.append("particle launched across the incline (alpha 0.5, beta 0.3): max |xy - DOP853's|, grip time rel. error")
    for mu in [0.2] if args.quick else [0.2, 0.8]:
        err, grip = across(mu)
        lines.append(f"  mu {mu}: {err:.1e}" + ("" if grip is None else f", grip {grip:.1e}"))
    lines.append("spinning sphere's 3-D frictional impact (e = 0.5): tangential impulse rel. error")
    for mu in [0.1] if args.quick else [0.1, 0.8]:
        kind, err = impact(mu)
        lines.append(f"  mu {mu}: {kind}, {err:.1e}")
    text = "\n".join(H.machine_lines("Friction with generalized speeds, 3-D friction", (load0, H.load_average()))
                     + [""] + lines)
    print(text)
    if args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)
        (args.out / "friction_speeds.txt").write_text(text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
