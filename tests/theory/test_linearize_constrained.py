"""Linearization of constrained systems about steady motions (lagcodegen.theory.linearize, the
"Constrained systems" part), checked against independent facts: the Whipple bicycle benchmark of
Meijaard, Papadopoulos, Ruina, Schwab (2007), Proc. R. Soc. A 463:1955-1982 (its published M, C1,
K0, K2 and weave and capsize speeds), the rolling disc's upright stability (classical closed
form), and the pendulum written in Cartesian coordinates (sqrt(g/l))."""

import math
import time

import numpy as np
import pytest
import scipy.optimize
import sympy as sp

import lagcodegen as lcg
from helpers import cartesian_pendulum, knife_edge, whipple_bicycle, whipple_straight_run
from lagcodegen import ModelError
from lagcodegen.theory.constraints import ConstrainedSystem
from lagcodegen.theory.linearize import linearize

# Meijaard et al. (2007), eqs. (A 21)-(A 24) and sec. 4 (benchmark values, 14 digits)
PAPER_M = [[80.81722, 2.31941332208709], [2.31941332208709, 0.29784188199686]]
PAPER_C1 = [[0.0, 33.86641391492494], [-0.85035641456978, 1.68540397397560]]
PAPER_K0 = [[-80.95, -2.59951685249872], [-2.59951685249872, -0.80329488458618]]
PAPER_K2 = [[0.0, 76.59734589573222], [0.0, 2.65431523794604]]
PAPER_WEAVE = 4.29238253634111
PAPER_CAPSIZE = 6.02426201538837
LEAN_STEER = ["phi", "delta"]


@pytest.fixture(scope="module")
def bicycle():
    return whipple_bicycle()


def lean_steer(lin):
    """The lean/steer blocks of a reduced linearization of the bicycle (speeds phi', delta', thR')."""
    s = [lin.speeds.index(k) for k in LEAN_STEER]
    c = [lin.coordinates.index(k) for k in LEAN_STEER]
    return lin.M[np.ix_(s, s)], lin.C[np.ix_(s, s)], lin.K[np.ix_(s, c)]


def bike(bicycle, v, **params):
    q0, v0 = whipple_straight_run(v)
    return linearize(bicycle, q0, v0, params=params, independent=["phi", "delta", "thR"])


def test_bicycle_builds_fast():
    start = time.perf_counter()
    cs = whipple_bicycle()
    elapsed = time.perf_counter() - start
    assert (cs.n, cs.n_holonomic, cs.n_nonholonomic, cs.dof) == (8, 1, 4, 3)
    assert elapsed < 4.0  # about 0.8 s on a quiet machine (2 s is the target; shared CI machines are slower)


def test_bicycle_benchmark_matrices(bicycle):
    g = 9.81
    at0, at1 = bike(bicycle, 0.0), bike(bicycle, 1.0, g=0.0)
    assert at0.speeds == ["phi", "delta", "thR"] and at0.dependent_coordinates == ["theta"]
    M, C0, K = lean_steer(at0)
    _, C1, K2 = lean_steer(at1)
    assert np.allclose(M, PAPER_M, rtol=0, atol=1e-8)
    assert np.allclose(C0, 0.0, atol=1e-12)
    assert np.allclose(K / g, PAPER_K0, rtol=0, atol=1e-8)
    assert np.allclose(C1, PAPER_C1, rtol=0, atol=1e-8)  # v C1 at v = 1
    assert np.allclose(K2, PAPER_K2, rtol=0, atol=1e-8)  # g K0 + v^2 K2 at g = 0, v = 1
    # at another speed the same matrices combine as the paper's equations say
    v = 3.7
    M3, C3, K3 = lean_steer(bike(bicycle, v))
    assert np.allclose(C3, v * np.array(PAPER_C1), rtol=0, atol=1e-8)
    assert np.allclose(K3, g * np.array(PAPER_K0) + v**2 * np.array(PAPER_K2), rtol=0, atol=1e-7)


def test_bicycle_lean_steer_decouple(bicycle):
    """The ignorable coordinates (x, y, yaw, wheel angles) and the forward speed leave the lean and
    steer equations (the paper's decoupling by symmetry), and the reduced system's eigenvalues are
    those of the lean/steer equations plus zeros."""
    lin = bike(bicycle, 5.0)
    rows = [lin.speeds.index(k) for k in LEAN_STEER]
    others_q = [i for i, k in enumerate(lin.coordinates) if k not in LEAN_STEER]
    assert np.max(np.abs(lin.K[np.ix_(rows, others_q)])) < 1e-10
    th = lin.speeds.index("thR")
    assert np.max(np.abs(lin.M[rows, th])) < 1e-12 and np.max(np.abs(lin.C[rows, th])) < 1e-12
    M, C, K = lean_steer(lin)
    A4 = np.block([[np.zeros((2, 2)), np.eye(2)], [-np.linalg.solve(M, K), -np.linalg.solve(M, C)]])
    ev4 = np.linalg.eigvals(A4)
    ev = lin.eigenvalues
    assert len(ev) == 10
    big = ev[np.abs(ev) > 1e-6]
    assert np.allclose(np.sort_complex(big), np.sort_complex(ev4), rtol=1e-10)
    # the paper's Table 2 at v = 5 m/s: weave -0.775341882 +- 4.46486771i, capsize -0.322866429,
    # castering -14.0783897
    assert np.allclose(np.sort_complex(ev4), np.sort_complex(
        [-14.0783897, -0.775341882 - 4.46486771j, -0.775341882 + 4.46486771j, -0.322866429]), atol=1e-8)


def lean_steer_eigenvalues(bicycle, v):
    M, C, K = lean_steer(bike(bicycle, v))
    return np.linalg.eigvals(np.block([[np.zeros((2, 2)), np.eye(2)],
                                       [-np.linalg.solve(M, K), -np.linalg.solve(M, C)]]))


def test_bicycle_weave_and_capsize_speeds(bicycle):
    def weave(v):
        ev = lean_steer_eigenvalues(bicycle, v)
        return float(np.max(ev[np.abs(ev.imag) > 1e-6].real))

    def capsize(v):
        return float(np.max(lean_steer_eigenvalues(bicycle, v).real))

    vw = scipy.optimize.brentq(weave, 4.0, 4.6, xtol=1e-13, rtol=1e-15)
    vc = scipy.optimize.brentq(capsize, 5.5, 6.5, xtol=1e-13, rtol=1e-15)
    assert vw == pytest.approx(PAPER_WEAVE, abs=1e-8)
    assert vc == pytest.approx(PAPER_CAPSIZE, abs=1e-8)
    # self-stable in between, unstable outside (the paper's Fig. 3)
    assert capsize(5.0) < 0 and weave(3.0) > 0 and capsize(7.0) > 0


def test_bicycle_independent_choice(bicycle):
    q0, v0 = whipple_straight_run(5.0)
    auto = linearize(bicycle, q0, v0)
    named = bike(bicycle, 5.0)
    by_coordinates = linearize(bicycle, q0, v0, independent=["x", "y", "psi", "phi", "delta", "thR", "thF"])
    other = linearize(bicycle, q0, v0, independent=["phi", "delta", "thF"])  # the front wheel's rate instead
    assert other.speeds == ["phi", "delta", "thF"]
    for lin in (auto, by_coordinates, other):
        assert np.allclose(np.sort_complex(lin.eigenvalues), np.sort_complex(named.eigenvalues), atol=1e-9)
    with pytest.raises(ModelError, match=r"independent speeds \(psi, delta, thF\) cannot be chosen.*phi"):
        linearize(bicycle, q0, v0, independent=["psi", "delta", "thF"])  # lean rate: no row of A has it
    with pytest.raises(ModelError, match="give the 3 independent speeds or the 7 independent coordinates"):
        linearize(bicycle, q0, v0, independent=["phi", "delta"])
    with pytest.raises(ModelError, match="unknown coordinate"):
        linearize(bicycle, q0, v0, independent=["phi", "delta", "speed"])


def test_bicycle_refuses_states_that_are_not_steady(bicycle):
    q0, v0 = whipple_straight_run(5.0)
    leaning = list(q0)
    leaning[3], leaning[5] = 0.1, 0.3  # leaning and steered: the upright pitch lifts the front wheel
    with pytest.raises(ModelError, match="holonomic constraint 0 .* has residual"):
        linearize(bicycle, leaning, v0)
    skidding = list(v0)
    skidding[1] = 0.5  # sideways speed: the rear wheel slips
    with pytest.raises(ModelError, match="velocity constraint"):
        linearize(bicycle, q0, skidding)


# ---------------------------------------------------------------------- the rolling disc
def rolling_disc(name="disc"):
    """A rolling disc (knife edge, point contact), radius a, mass m, moments A (diameter) and
    C (axle): contact (x, y), yaw psi, lean phi, spin theta; no slip at the contact."""
    m = lcg.Model(name)
    x, y, psi, phi, th = m.coordinates("x y psi phi theta")
    a, mass, A, C, g = m.parameters(a=0.4, m=2.0, A=0.3, C=0.5, g=9.81)
    Rz = sp.Matrix([[sp.cos(psi), -sp.sin(psi), 0], [sp.sin(psi), sp.cos(psi), 0], [0, 0, 1]])
    Rx = sp.Matrix([[1, 0, 0], [0, sp.cos(phi), -sp.sin(phi)], [0, sp.sin(phi), sp.cos(phi)]])
    Ry = sp.Matrix([[sp.cos(th), 0, sp.sin(th)], [0, 1, 0], [-sp.sin(th), 0, sp.cos(th)]])
    centre = sp.Matrix([x, y, 0]) + Rz * Rx * sp.Matrix([0, 0, a])  # z up
    m.rigid_body("disc", mass, [A, C, A], centre, Rz * Rx * Ry)
    m.gravity(g)
    # the contact point's material velocity: v_centre + w x (contact - centre), w = psi' e_z +
    # phi' (Rz e_x) + theta' (Rz Rx e_y); its horizontal components vanish
    qd = [m.dot(q) for q in (x, y, psi, phi, th)]
    vc = sp.Matrix([sum(sp.diff(comp, q) * v for q, v in zip((x, y, psi, phi, th), qd)) for comp in centre])
    w = m.dot(psi) * sp.Matrix([0, 0, 1]) + m.dot(phi) * Rz * sp.Matrix([1, 0, 0]) \
        + m.dot(th) * Rz * Rx * sp.Matrix([0, 1, 0])
    vel = vc + w.cross(sp.Matrix([x, y, 0]) - centre)
    rows = [[sp.diff(vel[k], v) for v in qd] for k in (0, 1)]
    return ConstrainedSystem(m, nonholonomic=rows)


@pytest.mark.parametrize("omega", [2.0, 3.5, 6.0])
def test_rolling_disc_upright(omega):
    """Upright rolling at spin rate omega (speed a omega): the lean mode has
    lambda^2 = (m g a - (C + m a^2) C omega^2 / A) / (A + m a^2) (the yaw equation A psi'' = C omega
    phi' integrated into the lean equation); stable iff omega^2 > m g a A / (C (C + m a^2))."""
    a, m, A, C, g = 0.4, 2.0, 0.3, 0.5, 9.81
    cs = rolling_disc()
    # rolling along x (z up): the spin theta' = omega about the axle (y) moves the centre by +a omega
    lin = linearize(cs, [0.0] * 5, [a * omega, 0, 0, 0, omega])
    lam2 = (m * g * a - (C + m * a * a) * C * omega**2 / A) / (A + m * a * a)
    ev = lin.eigenvalues
    big = ev[np.abs(ev) > 1e-6]
    expected = [math.sqrt(lam2), -math.sqrt(lam2)] if lam2 > 0 else [1j * math.sqrt(-lam2), -1j * math.sqrt(-lam2)]
    assert np.allclose(np.sort_complex(big), np.sort_complex(expected), rtol=1e-10)
    critical = math.sqrt(m * g * a * A / (C * (C + m * a * a)))  # 3.24 rad/s for these numbers
    assert lin.stable() == (omega > critical)


def test_rolling_disc_at_rest_leans_over():
    lin = linearize(rolling_disc(), [0.0] * 5, [0.0] * 5)
    a, m, A = 0.4, 2.0, 0.3
    rate = math.sqrt(m * 9.81 * a / (A + m * a * a))  # an inverted pendulum about the contact
    assert np.max(lin.eigenvalues.real) == pytest.approx(rate, rel=1e-12)


# ---------------------------------------------------------------------- holonomic rows
def test_cartesian_pendulum_bottom_and_top():
    """x^2 + y^2 = l^2 (eq. 4.1): one independent coordinate; the multiplier's curvature term
    d(A^T lambda0)/dq gives the stiffness: w^2 = g/l at the bottom, an instability g/l at the top."""
    cs = cartesian_pendulum()
    l, g = 0.8, 9.5
    lin = linearize(cs, [0.0, -l], [0.0, 0.0], params={"l": l, "g": g})
    assert lin.coordinates == ["x"] and lin.speeds == ["x"] and lin.dependent_coordinates == ["y"]
    assert lin.frequencies == pytest.approx([math.sqrt(g / l)], rel=1e-12)
    assert lin.multipliers[0] == pytest.approx(-9.5 / (2 * l), rel=1e-12)  # tension m g = -2 l lambda
    top = linearize(cs, [0.0, l], [0.0, 0.0], params={"l": l, "g": g})
    assert np.max(top.eigenvalues.real) == pytest.approx(math.sqrt(g / l), rel=1e-12)
    with pytest.raises(ModelError, match=r"independent coordinates and speeds \(y\) cannot be chosen.*\(x\)"):
        linearize(cs, [0.0, -l], [0.0, 0.0], params={"l": l}, independent=["y"])


def test_refusals():
    cs = cartesian_pendulum()
    with pytest.raises(ModelError, match="not a steady motion consistent with the constraints.*x''="):
        linearize(cs, [math.sin(1.0), -math.cos(1.0)], [0.0, 0.0])  # at rest off the bottom: it swings
    with pytest.raises(ModelError, match="symbolic=True is for unconstrained"):
        linearize(cs, [0.0, -1.0], symbolic=True)
    with pytest.raises(ModelError, match="is not a parameter"):
        linearize(cs, [0.0, -1.0], params={"k": 1.0})
    with pytest.raises(ModelError, match="tol must be"):
        linearize(cs, [0.0, -1.0], tol=-1)
    with pytest.raises(ModelError, match="needs EquationsOfMotion"):
        linearize("pendulum", [0.0])
    with pytest.raises(ModelError, match="independent must be a list of coordinate names"):
        linearize(cs, [0.0, -1.0], independent=5)
    with pytest.raises(ModelError, match="a name repeated"):
        linearize(cs, [0.0, -1.0], independent=["x", "x"])
    with pytest.raises(ModelError, match="for constrained systems"):
        linearize(lcg.derive(cs.model), [0.0, -1.0], independent=["x"])
    # a knife edge on an incline is accelerated down the slope: no steady motion at rest
    with pytest.raises(ModelError, match="not a steady motion"):
        linearize(knife_edge(), [0.0, 0.0, 0.3], [0.0, 0.0, 0.0])


def test_a_zero_parameter_on_a_pole_is_evaluated_exactly():
    """V = m g y + k / x: with k = 0 the pendulum at the bottom (x = 0) is the plain one, but the
    compiled double-precision evaluation meets 0 * inf there; the exact evaluation (parameters
    first) gives sqrt(g/l)."""
    m = lcg.Model("pole_pendulum")
    x, y = m.coordinates("x y")
    l, g, mass, k = m.parameters(l=0.8, g=9.5, m=1.0, k=0.0)
    m.particle("bob", mass, (x, y))
    m.gravity(g)
    m.potential_energy(k / x)
    cs = ConstrainedSystem(m, holonomic=[x**2 + y**2 - l**2])
    lin = linearize(cs, [0.0, -0.8], [0.0, 0.0])
    assert lin.frequencies == pytest.approx([math.sqrt(9.5 / 0.8)], rel=1e-12)
    with pytest.raises(ModelError, match="not finite and real at the state"):
        linearize(cs, [0.0, -0.8], [0.0, 0.0], params={"k": 1.0})


def test_a_motion_along_which_the_reduced_equations_change_is_refused():
    """A particle gliding at unit speed along x, held at z = 0, in the valley V = (1 + x^2) y^2 / 2:
    a0 = 0 there, but the stiffness across the valley (1 + x^2) changes as x moves, so frozen
    coefficients are not the motion's linearization and the state is refused as not steady; given
    a0, the instantaneous linearization has w^2 = 1 + x0^2 across the valley."""
    m = lcg.Model("valley")
    x, y, z = m.coordinates("x y z")
    m.particle("p", 1.0, (x, y, z))
    m.potential_energy((1 + x**2) * y**2 / 2)
    system = ConstrainedSystem(m, holonomic=[z])
    with pytest.raises(ModelError, match="change along this motion"):
        linearize(system, [0.5, 0.0, 0.0], [1.0, 0.0, 0.0])
    lin = linearize(system, [0.5, 0.0, 0.0], [1.0, 0.0, 0.0], a0=[0.0, 0.0, 0.0])
    assert lin.coordinates == ["x", "y"] and np.allclose(lin.K, np.diag([0.0, 1.25]), atol=1e-12)
    assert np.allclose(linearize(system, [0.5, 0.0, 0.0], [0.0, 0.0, 0.0]).K, np.diag([0.0, 1.25]), atol=1e-12)
