"""Taylor jets of rigid-body trees built from the tree's recorded program (issue 38), checked
against Pinocchio (aba for the order-1 coefficient, central differences of aba for order 2) and
against CVODE Adams; and ``method="auto"`` following the model's measured costs (injected here,
not timed)."""

import math

import numpy as np
import pytest

import lagcodegen as lcg
from lagcodegen.errors import ModelError
from lagcodegen.formulation.scene import Scene
from lagcodegen.solvers import auto
from lagcodegen.solvers.auto import MethodCosts, adams_evaluations_per_taylor_step, choose_method
from lagcodegen.solvers.cvode import CVODE
from lagcodegen.solvers.registry import resolve
from lagcodegen.solvers.taylor import Taylor
from lagcodegen.codegen.taylor.decompose import decompose
from lagcodegen.solvers.taylor.run import taylor_module

pin = pytest.importorskip("pinocchio")
ROBOTS = __import__("pathlib").Path(pin.__file__).resolve().parents[4] / "share" / "example-robot-data" / "robots"


def spatial_chain(n: int, seed: int = 0):
    """A random spatial chain of n revolute links (axes z, x, y and an unaligned one in turn,
    random placements, full inertias) as a lagcodegen model and its Pinocchio twin."""
    rng = np.random.default_rng(seed)
    m = lcg.Model(f"taylor_chain{n}")
    g, = m.parameters(g=9.81)
    m.gravity(g)
    pm = pin.Model()
    pm.gravity = pin.Motion(np.array([0, 0, -9.81, 0, 0, 0]))
    parent, jid = None, 0
    for i in range(n):
        R, t = pin.rpy.rpyToMatrix(*rng.uniform(-3, 3, 3)), rng.uniform(-0.3, 0.3, 3)
        ax = np.array([(0, 0, 1), (1, 0, 0), (0, 1, 0), tuple(rng.normal(size=3))][i % 4], dtype=float)
        ax /= np.linalg.norm(ax)
        A = rng.normal(size=(3, 3))
        mass, c, inertia = rng.uniform(0.5, 2), rng.uniform(-0.2, 0.2, 3), A @ A.T + 0.1 * np.eye(3)
        parent = m.link(f"l{i}", parent=parent, joint=lcg.Joint.revolute(f"j{i}", tuple(ax)),
                        origin=lcg.Placement(tuple(t), rotation=R.tolist()), mass=mass, com=tuple(c),
                        inertia=(inertia[0, 0], inertia[1, 1], inertia[2, 2], inertia[0, 1], inertia[0, 2],
                                 inertia[1, 2])).name
        jm = {0: pin.JointModelRZ, 1: pin.JointModelRX, 2: pin.JointModelRY}.get(i % 4)
        jid = pm.addJoint(jid, jm() if jm else pin.JointModelRevoluteUnaligned(ax), pin.SE3(R, t), f"j{i}")
        pm.appendBodyToJoint(jid, pin.Inertia(mass, c, inertia), pin.SE3.Identity())
    return m, pm


def urdf_damping(pm, file) -> np.ndarray:
    out = np.zeros(pm.nv)
    for name, joint in lcg.urdf.read(file).joints.items():
        if pm.existJointName(name) and joint.dynamics is not None:
            out[pm.joints[pm.getJointId(name)].idx_v] = joint.dynamics.damping
    return out


def check_jet_against_pinocchio(cm, pm, damping, seeds=3):
    """The jet's order-1 coefficients of the speeds are aba's accelerations (to 1e-12), those of
    the coordinates the kinematics; order 2 is half the time derivative of aba along the motion
    (central differences, step 1e-5: agreement to 1e-6)."""
    module = taylor_module(cm)
    data = pm.createData()
    nq = pm.nq
    p = np.asarray(cm.code.param_defaults, dtype=float)
    for seed in range(seeds):
        rng = np.random.default_rng(seed)
        q = pin.randomConfiguration(pm, -np.ones(pm.nq), np.ones(pm.nq))
        v = rng.normal(size=pm.nv)
        jet = module.jet(0.0, np.concatenate([q, v]), p, 3)
        a = pin.aba(pm, data, q, v, -damping * v)
        assert np.abs(jet[nq:, 1] - a).max() <= 1e-12 * max(1.0, np.abs(a).max())
        assert np.allclose(jet[:, 1], cm.rhs(0.0, np.concatenate([q, v])), rtol=1e-12, atol=1e-12)
        h = 1e-5

        def aba_at(s):
            qs = pin.integrate(pm, q, s * v + 0.5 * s * s * a)
            return pin.aba(pm, data, qs, v + s * a, -damping * (v + s * a))
        da = (aba_at(h) - aba_at(-h)) / (2 * h)
        assert np.abs(2 * jet[nq:, 2] - da).max() <= 1e-6 * max(1.0, np.abs(da).max())
    return module


def agrees_with_adams(cm, pm, t_end, bound):
    q = pin.randomConfiguration(pm, -np.ones(pm.nq), np.ones(pm.nq))
    v = np.random.default_rng(7).normal(size=pm.nv)
    t = np.linspace(0.0, t_end, 5)
    kw = dict(y0=np.concatenate([q, v]), rtol=1e-12, atol=1e-12, max_steps=10**6)
    a = cm.simulate(t, method="adams", **kw)
    b = cm.simulate(t, method="taylor", **kw)
    assert np.abs(a.y - b.y).max() < bound * max(1.0, np.abs(a.y).max())
    return b


@pytest.fixture(scope="module")
def chain12():
    m, pm = spatial_chain(12)
    return lcg.compile_model(m, jacobian=False), pm


def test_twelve_joint_chain_jet_is_built_from_the_program_linearly(chain12):
    """The jet's operations come from the recorded program, statement by statement: their number
    grows like the program's (6 -> 12 joints), not like the DAG's paths, and the 12-joint chain's
    jet (whose DAG decomposition did not finish in 100 s) forms in a fraction of a second."""
    from lagcodegen.formulation.kernels import symbol_map, tree_rhs
    sizes = {}
    for n in (6, 12):
        scene = Scene(lcg.derive(spatial_chain(n)[0]), jacobian=False)
        d = decompose(scene)
        program = tree_rhs(scene.eom, symbol_map(scene))
        assert d.form == "program"
        assert len(d.ops) <= len(program.defs) + len(program.targets)  # at most one operation per statement
        sizes[n] = (len(d.ops), len(program.defs))
    ops_ratio, program_ratio = sizes[12][0] / sizes[6][0], sizes[12][1] / sizes[6][1]
    assert ops_ratio <= 1.2 * program_ratio
    cm, pm = chain12
    check_jet_against_pinocchio(cm, pm, np.zeros(pm.nv))


def test_twelve_joint_chain_taylor_run_agrees_with_adams(chain12):
    cm, pm = chain12
    res = agrees_with_adams(cm, pm, 0.5, 1e-8)
    assert res.stats["order"] == math.ceil(-0.5 * math.log(1e-12) + 3)


def test_ur5_taylor_jet_and_run_against_pinocchio_and_adams():
    file = ROBOTS / "ur_description" / "urdf" / "ur5_robot.urdf"
    pm = pin.buildModelFromUrdf(str(file))
    pm.gravity = pin.Motion(np.array([0, 0, -9.81, 0, 0, 0]))
    cm = lcg.compile_model(lcg.urdf.load(file), jacobian=False)
    check_jet_against_pinocchio(cm, pm, urdf_damping(pm, file))
    agrees_with_adams(cm, pm, 1.0, 1e-8)


def test_floating_solo12_taylor_jet_and_run_against_pinocchio_and_adams():
    """Generalized speeds (the free flyer's quaternion): the coordinates' rates in closed form,
    the speeds' equations from the tree's program."""
    file = ROBOTS / "solo_description" / "robots" / "solo12.urdf"
    pm = pin.buildModelFromUrdf(str(file), pin.JointModelFreeFlyer())
    cm = lcg.compile_model(lcg.urdf.load(file, floating=True), jacobian=False)
    assert (cm.nq, cm.nv) == (19, 18)
    module = check_jet_against_pinocchio(cm, pm, urdf_damping(pm, file))
    assert module.decomposition.form == "program" and module.decomposition.kin is not None
    agrees_with_adams(cm, pm, 0.5, 1e-8)


def test_taylor_sensitivities_of_a_tree_agree_with_cvode():
    """The variational jet is built over the program's operations too."""
    cm = lcg.compile_model(spatial_chain(4)[0], jacobian=False)
    t = np.linspace(0.0, 1.0, 5)
    kw = dict(q0=[0.3] * 4, rtol=1e-12, atol=1e-12, sensitivities=["g"])
    a = cm.simulate(t, method="taylor", **kw).sensitivities
    b = cm.simulate(t, method="adams", **kw).sensitivities
    assert np.abs(b).max() > 0.1 and np.abs(a - b).max() < 1e-9


def test_program_form_is_a_trees_only():
    with pytest.raises(ModelError, match="form 'program' is a rigid-body tree's"):
        decompose(Scene(lcg.derive(lcg.systems.n_link_pendulum(2)), jacobian=False), form="program")
    with pytest.raises(ModelError, match="unknown form 'dag'"):
        decompose(Scene(lcg.derive(lcg.systems.n_link_pendulum(2)), jacobian=False), form="dag")


# ------------------------------------------------------------------------- method="auto"
def test_auto_follows_the_measured_costs():
    """Within the size rule's Taylor region, Taylor only where a step costs less than Adams's
    evaluations over the same interval (E(rtol) of them)."""
    for rtol in (1e-4, 1e-8, 1e-12):
        limit = adams_evaluations_per_taylor_step(rtol) * 1e-6
        assert choose_method(3, rtol, lambda r: MethodCosts(adams_evaluation=1e-6, taylor_step=0.9 * limit)) == "taylor"
        assert choose_method(3, rtol, lambda r: MethodCosts(adams_evaluation=1e-6, taylor_step=1.1 * limit)) == "adams"
    # the costs at the run's tolerance are asked for
    asked = []
    choose_method(2, 3e-7, lambda r: asked.append(r) or None)
    assert asked == [3e-7]


def test_auto_measures_nothing_where_the_size_rule_says_adams():
    def never(rtol):
        raise AssertionError("costs measured for a model the size rule keeps on Adams")
    assert choose_method(50, 1e-12, never) == "adams"
    assert choose_method(8, 1e-4, never) == "adams"
    assert choose_method(math.inf, 1e-12, never) == "adams"  # generalized speeds
    assert choose_method(3, 1e-8, lambda r: None) == "taylor"  # not measurable: the size rule
    assert choose_method(3, 1e-8) == "taylor"


def test_adams_evaluations_per_taylor_step_interpolates_the_measured_envelope():
    points = auto.EVALUATIONS
    for digits, value in points:
        assert adams_evaluations_per_taylor_step(10.0 ** -digits) == pytest.approx(value)
    (d0, e0), (d1, e1) = points[2], points[3]
    mid = adams_evaluations_per_taylor_step(10.0 ** -((d0 + d1) / 2))
    assert mid == pytest.approx((e0 + e1) / 2)
    values = [adams_evaluations_per_taylor_step(10.0 ** -k) for k in range(1, 17)]
    assert values == sorted(values)  # tighter tolerances: more Adams evaluations per Taylor step
    assert values[0] == points[0][1] and values[-1] == points[-1][1]  # the nearest outside


def test_resolve_and_simulate_follow_injected_costs(monkeypatch):
    cheap_taylor = MethodCosts(adams_evaluation=1e-6, taylor_step=1e-7)
    dear_taylor = MethodCosts(adams_evaluation=1e-6, taylor_step=1e-3)
    assert resolve("ode", None, {"method": "auto"}, n=2, rtol=1e-8, costs=lambda r: cheap_taylor) == Taylor()
    assert resolve("ode", None, {"method": "auto"}, n=2, rtol=1e-8, costs=lambda r: dear_taylor) == \
        CVODE(method="adams")
    from lagcodegen.solvers.taylor import probe
    calls = []
    monkeypatch.setattr(probe, "measure_costs", lambda cm, rtol: calls.append(rtol) or dear_taylor)
    cm = lcg.compile_model(lcg.systems.n_link_pendulum(2), jacobian=False)
    res = cm.simulate([0, 1], q0=[0.3, 0.2], method="auto", rtol=1e-9, atol=1e-9)
    assert "jet_evals" not in res.stats and res.stats["steps"] > 0  # Adams ran
    cm.simulate([0, 1], q0=[0.3, 0.2], method="auto", rtol=1.1e-9, atol=1e-9)
    assert len(calls) == 1  # kept with the model for the order
    monkeypatch.setattr(probe, "measure_costs", lambda cm, rtol: cheap_taylor)
    cm2 = lcg.compile_model(lcg.systems.n_link_pendulum(2), jacobian=False)
    assert "jet_evals" in cm2.simulate([0, 1], q0=[0.3, 0.2], method="auto", rtol=1e-9, atol=1e-9).stats


def test_measured_costs_of_a_model_are_positive_and_kept():
    from lagcodegen.solvers.taylor.probe import measure_costs, run_order
    cm = lcg.compile_model(lcg.systems.n_link_pendulum(1), jacobian=False)
    costs = measure_costs(cm, 1e-8, budget=0.002)
    assert 0 < costs.adams_evaluation < 1e-3 and 0 < costs.taylor_step < 1e-3
    assert run_order(1e-8) == math.ceil(-0.5 * math.log(1e-8) + 3)
    assert cm.method_costs(1e-8) is cm.method_costs(1.2e-8)  # one measurement per order
