"""Joint limits enforced through the main API (issue 38): ``compile_urdf(path, limits=...)`` on
example-robot-data's UR5 runs on the impact driver, the stops as unilateral contacts g >= 0
(eq. 4.3) with Newton's restitution. Checked against independent facts: the free model's motion
up to the first impact (the same equations without limits), the energy (conserved by the UR5,
which has no damping, except at impacts with e < 1, so every loss must be a logged impact),
Newton's law, and the multipliers against Pinocchio's statics (computeGeneralizedGravity) and
constrained dynamics (crba, nle: M a + h = G^T lambda with G a = 0 on the active stops)."""

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import lagcodegen as lcg

ROBOTS = Path(pin.__file__).resolve().parents[4] / "share" / "example-robot-data" / "robots"
UR5 = ROBOTS / "ur_description" / "urdf" / "ur5_robot.urdf"
T = np.linspace(0.0, 3.0, 601)
TOL = dict(rtol=1e-10, atol=1e-12)


@pytest.fixture(scope="module")
def pinocchio_ur5():
    if not UR5.is_file():
        pytest.fail(f"example-robot-data's UR5 is missing: {UR5} (pip install example-robot-data)")
    model = pin.buildModelFromUrdf(str(UR5))
    return model, model.createData()


def _limits(sim):
    """(lower, upper) of each joint from the system's inequalities: q - lower, upper - q per joint."""
    rows = [float(g.subs({s: 0 for s in g.free_symbols})) for g in sim.system.inequalities]
    return -np.array(rows[0::2]), np.array(rows[1::2])


def _contact_rows(k: int) -> tuple[int, float]:
    """Contact k's joint and the sign of its row G_k = dg_k/dq (+1 lower stop, -1 upper stop)."""
    return k // 2, 1.0 if k % 2 == 0 else -1.0


def _pinocchio_multipliers(pin_model, data, q, v, active):
    """The multipliers of the stops ``active`` held (G a = 0), from Pinocchio's mass matrix and
    bias forces: [M -G^T; G 0] [a; lambda] = [-h; 0]."""
    n = len(q)
    M = pin.crba(pin_model, data, q).copy()
    M = np.triu(M) + np.triu(M, 1).T
    h = pin.nle(pin_model, data, q, v).copy()
    G = np.zeros((len(active), n))
    for row, k in enumerate(active):
        joint, sign = _contact_rows(k)
        G[row, joint] = sign
    K = np.block([[M, -G.T], [G, np.zeros((len(active), len(active)))]])
    return np.linalg.solve(K, np.concatenate([-h, np.zeros(len(active))]))[n:]


@pytest.mark.parametrize("limits", [True, ("stop", 0.5)], ids=["plastic", "e=0.5"])
def test_ur5_with_limits_runs_three_seconds_through_its_impacts(limits, pinocchio_ur5):
    """The UR5 released from rest near two stops (shoulder lift at 2 pi - 0.4, elbow at -pi + 0.3)
    falls into them: the run reaches t = 3, no joint passes a limit by 1e-8 rad, the first impact
    is where the free model (compile_urdf without limits) reaches the elbow's stop, each bounce
    obeys Newton's law, the energy is constant between logged impacts (so none is missing) and
    drops at them; stuck at its stops (plastic), the arm's multipliers are Pinocchio's."""
    sim = lcg.compile_urdf(UR5, limits=limits)
    e = 0.0 if limits is True else 0.5
    lower, upper = _limits(sim)
    q0 = np.array([0.0, upper[1] - 0.4, lower[2] + 0.3, 0.2, 0.1, 0.0])
    res = sim.simulate(T, q0=q0, v0=np.zeros(6), **TOL)
    assert res.success and res.t[-1] == 3.0
    q = res.y[:, :6]
    assert max((lower - q).max(), (q - upper).max(), res.stats["max_penetration"]) <= 1e-8
    impacts = [r for r in res.impacts if r.kind in ("bounce", "stick")]
    assert {r.contact for r in impacts} == {3, 4}  # the shoulder's upper stop, the elbow's lower one
    for r in impacts:
        assert r.w_before < 0 and r.w_after == pytest.approx(-e * r.w_before if r.kind == "bounce" else 0.0,
                                                             abs=1e-12)
        assert r.kind == ("stick" if e == 0 else "bounce") or abs(r.w_before) < 1e-3  # slow ones stick
    first = impacts[0]
    assert first.contact == 4
    free = lcg.compile_urdf(UR5).simulate([0.0, first.t], q0=q0, v0=np.zeros(6), **TOL)
    assert free.y[-1, 2] == pytest.approx(lower[2], abs=1e-8)  # the free arm reaches the stop then
    before = T < first.t
    np.testing.assert_allclose(q[before], lcg.compile_urdf(UR5).simulate(T[before], q0=q0, v0=np.zeros(6),
                                                                         **TOL).y[:, :6], atol=1e-8)
    # the energy changes only across a sample interval holding a logged impact, and drops there
    energy = res["energy"]
    hit = np.zeros(len(T) - 1, dtype=bool)
    for r in impacts:
        hit[min(np.searchsorted(T, r.t) - 1, len(hit) - 1)] = True
    jumps = np.diff(energy)
    assert np.abs(jumps[~hit]).max() < 1e-8 * abs(energy[0])
    assert np.all(jumps[hit] < 0)
    if e == 0:  # both stops hold to the end: their multipliers against Pinocchio's constrained dynamics
        assert res.impacts.final_modes[3] == "contact" and res.impacts.final_modes[4] == "contact"
        pin_model, data = pinocchio_ur5
        late = np.flatnonzero(T > impacts[-1].t + 0.01)
        lam = np.array([[res["lambda_ineq_3"][i], res["lambda_ineq_4"][i]] for i in late])
        want = np.array([_pinocchio_multipliers(pin_model, data, res.y[i, :6], res.y[i, 6:], [3, 4]) for i in late])
        assert np.all(lam > 0)
        np.testing.assert_allclose(lam, want, rtol=1e-9, atol=1e-9)


def test_ur5_rests_at_its_stops_with_gravitys_holding_torques(pinocchio_ur5):
    """At rest with the upper arm on the shoulder's upper stop (2 pi: horizontal) and the forearm
    folded onto the elbow's lower stop (-pi), every other joint in equilibrium: the arm stays put
    for 3 s, and the stops' multipliers are the holding torques of Pinocchio's
    computeGeneralizedGravity (G^T lambda = g(q): lambda_3 = -g_lift, lambda_4 = g_elbow); the
    other stops carry nothing."""
    sim = lcg.compile_urdf(UR5, limits=True)
    lower, upper = _limits(sim)
    q = np.array([0.0, upper[1], lower[2], 0.0, 0.0, 0.0])
    res = sim.simulate(T, q0=q, v0=np.zeros(6), **TOL)
    assert res.success and res.t[-1] == 3.0 and len(res.impacts.times) == 0
    assert np.abs(res.y[:, :6] - q).max() < 1e-8 and np.abs(res.y[:, 6:]).max() < 1e-8
    pin_model, data = pinocchio_ur5
    g = pin.computeGeneralizedGravity(pin_model, data, q)
    assert -g[1] > 10 and g[2] > 10  # gravity presses both joints into their stops
    np.testing.assert_allclose(res["lambda_ineq_3"], -g[1], rtol=1e-9)
    np.testing.assert_allclose(res["lambda_ineq_4"], g[2], rtol=1e-9)
    for k in set(range(12)) - {3, 4}:
        assert not np.any(res[f"lambda_ineq_{k}"])


def test_ur5_leaves_its_stop_where_the_multiplier_would_pull(pinocchio_ur5):
    """Swinging from rest (shoulder lift -1, elbow 2.8), the elbow comes down on its lower stop
    and sticks (a plastic impact); held there, its multiplier is Pinocchio's constrained-dynamics
    one, and the stop lets go (a "release" record) where that multiplier falls to 0: positive
    before, and the elbow off its stop after."""
    sim = lcg.compile_urdf(UR5, limits=True)
    lower, _ = _limits(sim)
    res = sim.simulate(T, q0=[0.0, -1.0, 2.8, 0.0, 0.0, 0.0], v0=np.zeros(6), **TOL)
    assert res.success and res.t[-1] == 3.0
    stick = res.impacts.select("stick", contact=4)
    release = res.impacts.select("release", contact=4)
    assert len(stick) == 1 and len(release) == 1 and stick[0].t < release[0].t
    pin_model, data = pinocchio_ur5
    held = np.flatnonzero((T > stick[0].t) & (T < release[0].t))
    lam = res["lambda_ineq_4"][held]
    want = [_pinocchio_multipliers(pin_model, data, res.y[i, :6], res.y[i, 6:], [4])[0] for i in held]
    assert len(held) > 10 and np.all(lam > 0)
    np.testing.assert_allclose(lam, want, rtol=1e-9, atol=1e-9)
    assert lam[-1] < 0.1 * lam.max()  # falling to 0 at the release
    after = T > release[0].t + 0.02
    assert np.all(res.y[after, 2] - lower[2] > 1e-6) and not np.any(res["lambda_ineq_4"][after])
