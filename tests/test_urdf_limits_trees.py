"""Joint limits on a large rigid-body tree (issue 38): example-robot-data's Talos (30 joints with
its grippers locked, 60 stops) generates and builds in seconds, not the 20 minutes the
constrained code took when M and F were common-subexpression eliminated as closed forms
(their DAG expressions copied apart and compared node by node); its M and F now come from the
tree's recorded program, in pieces, in both the index-1 code (``_dae.c``) and the contact code
(``_impact.c``). Checked against Pinocchio: the free accelerations (aba) from the index-1 code,
and, with the torso held at its stop by gravity, the stop's multiplier from the contact
code against crba/nle (M a + h = G^T lambda, G a = 0)."""

import time
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import lagcodegen as lcg

ROBOTS = Path(pin.__file__).resolve().parents[4] / "share" / "example-robot-data" / "robots"
TALOS = ROBOTS / "talos_data" / "robots" / "talos_full_v2.urdf"

#: Generation and build of the constrained code of Talos with limits, cold: some 15 s on two busy
#: cores (the unconstrained model's ~6 s plus the index-1 and contact files); it took 1280 s.
MAX_BUILD_SECONDS = 120.0


@pytest.fixture(scope="module")
def talos():
    """(lagcodegen's system and compiled simulation, Pinocchio's model with the grippers locked,
    lagcodegen's coordinate i -> Pinocchio's index, build seconds)."""
    if not TALOS.is_file():
        pytest.fail(f"example-robot-data's Talos is missing: {TALOS} (pip install example-robot-data)")
    full = pin.buildModelFromUrdf(str(TALOS))
    grippers = [name for name in full.names[1:] if name.startswith("gripper")]
    model = pin.buildReducedModel(full, [full.getJointId(name) for name in grippers], pin.neutral(full))
    with pytest.warns(UserWarning, match="Coulomb friction"):
        system = lcg.urdf.load(TALOS, limits=True, lock=grippers)
    start = time.perf_counter()
    sim = lcg.compile_constrained(system)
    seconds = time.perf_counter() - start
    order = np.array([model.joints[model.getJointId(q.name)].idx_q for q in system.model.coords])
    return system, sim, model, order, seconds


def _limits(system):
    rows = [float(g.subs({s: 0 for s in g.free_symbols})) for g in system.inequalities]
    return -np.array(rows[0::2]), np.array(rows[1::2])


def _to_pin(order, x):
    out = np.empty(len(x))
    out[order] = x
    return out


def test_talos_with_limits_builds_in_seconds_and_runs_its_tree_program(talos):
    system, sim, model, _, seconds = talos
    assert system.model.n == 30 and len(system.contacts) == 60
    assert seconds < MAX_BUILD_SECONDS
    dae = next(text for name, text in sim.compiled.code.files.items() if name.endswith("_dae.c"))
    impact = next(text for name, text in sim.compiled.code.files.items() if name.endswith("_impact.c"))
    for text in (dae, impact):  # M and F from the tree's program, in pieces
        assert "static NOINLINE void mass_force0(" in text and "mass_force1(t, y, p, v, M, F);" in text


def test_talos_free_accelerations_are_pinocchios_aba(talos):
    """Away from every stop the index-1 code's q'' (no row held) is Pinocchio's aba, with the
    URDF's joint damping as the torque -damping q'."""
    system, sim, model, order, _ = talos
    lower, upper = _limits(system)
    rng = np.random.default_rng(38)
    data = model.createData()
    for _ in range(3):
        q = lower + (upper - lower) * rng.uniform(0.2, 0.8, len(lower))
        v = rng.normal(0.0, 0.5, len(q))
        acc, _lam = sim.kkt(0.0, np.concatenate([q, v]))
        vp = _to_pin(order, v)
        want = pin.aba(model, data, _to_pin(order, q), vp, -model.damping * vp)  # the URDF's joint damping
        np.testing.assert_allclose(_to_pin(order, acc), want, rtol=1e-10, atol=1e-10 * np.abs(want).max())


def test_talos_torso_held_at_its_stop_has_pinocchios_multiplier(talos):
    """Released from rest mid-range with the torso bent forward onto its pitch joint's upper stop
    (torso_2_joint), which gravity presses it into: for 0.05 s no other stop is reached, the
    torso stays on its stop (no impact) with a positive multiplier equal to Pinocchio's constrained
    dynamics' (crba, nle and the joint damping with that stop held: M a + h = G^T lambda, G a = 0)."""
    system, sim, model, order, _ = talos
    lower, upper = _limits(system)
    names = [q.name for q in system.model.coords]
    joint = names.index("torso_2_joint")
    q0 = (lower + upper) / 2
    q0[joint] = upper[joint]
    data = model.createData()
    free = pin.aba(model, data, _to_pin(order, q0), np.zeros(model.nv), np.zeros(model.nv))
    assert free[order[joint]] > 1.0  # gravity presses the torso into its upper stop
    t = np.linspace(0.0, 0.05, 11)
    res = sim.simulate(t, q0=q0, v0=np.zeros(30), rtol=1e-10, atol=1e-12)
    assert res.success and res.t[-1] == t[-1]
    contact = 2 * joint + 1  # contact k: the lower stop of joint k // 2 (k even), its upper one (k odd)
    assert len(res.impacts.times) == 0 and res.impacts.final_modes[contact] == "contact"
    assert all(mode == "free" for k, mode in res.impacts.final_modes.items() if k != contact)
    q, v = res.y[:, :30], res.y[:, 30:]
    assert np.abs(q[:, joint] - upper[joint]).max() < 1e-8
    assert np.all(q >= lower - 1e-8) and np.all(q <= upper + 1e-8)
    G = np.zeros((1, 30))
    G[0, order[joint]] = -1.0  # the row of upper - q
    lam = res[f"lambda_ineq_{contact}"]
    for i in range(len(t)):
        qp, vp = _to_pin(order, q[i]), _to_pin(order, v[i])
        M = pin.crba(model, data, qp).copy()
        M = np.triu(M) + np.triu(M, 1).T
        h = pin.nle(model, data, qp, vp) + model.damping * vp
        K = np.block([[M, -G.T], [G, np.zeros((1, 1))]])
        sol = np.linalg.solve(K, np.concatenate([-h, [0.0]]))
        assert lam[i] > 0
        assert lam[i] == pytest.approx(sol[30], rel=1e-8)


def test_talos_falling_onto_many_stops_runs_without_chatter_and_only_loses_energy(talos):
    """Released from rest with every joint 1e-3 rad inside its limits nearest zero, Talos (fixed
    base) falls onto many stops at once, some coupled through the tree: stops touching at rest
    that a release would leave to sink are held together with the others (the contacts' LCP),
    and a stop that another's impulse would push into its limit takes part in that impact. The
    run reaches 1 s with fewer than 2000 contact records (before, stops chattered: 80,584 records
    and four minutes for the same second); the joints stay within their limits; and
    the energy by Pinocchio (kinetic plus potential) never increases (joint damping and plastic
    impacts only dissipate)."""
    system, sim, model, order, _ = talos
    lower, upper = _limits(system)
    q0 = np.clip(np.zeros(len(lower)), lower + 1e-3, upper - 1e-3)
    t = np.linspace(0.0, 1.0, 51)
    res = sim.simulate(t, q0=q0, v0=np.zeros(30), rtol=1e-8, atol=1e-10)
    assert res.success and res.t[-1] == t[-1]
    assert len(res.impacts.records) < 2000 and len(res.impacts.select("stick")) > 10
    q, v = res.y[:, :30], res.y[:, 30:]
    assert np.all(q >= lower - 1e-6) and np.all(q <= upper + 1e-6)
    for k, mode in res.impacts.final_modes.items():
        if mode == "contact":
            assert res[f"lambda_ineq_{k}"][-1] >= -1e-9
    data = model.createData()
    energy = np.array([pin.computeKineticEnergy(model, data, _to_pin(order, q[i]), _to_pin(order, v[i]))
                       + pin.computePotentialEnergy(model, data, _to_pin(order, q[i])) for i in range(len(t))])
    assert np.all(np.diff(energy) <= 1e-9 * np.abs(energy).max()), np.diff(energy).max()
    assert energy[-1] < energy[0] - 1.0  # it fell onto its stops
