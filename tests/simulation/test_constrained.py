"""Constrained dynamics (eq. 4.5) in generated C: index-1 on CVODE (Baumgarte, projection),
GGL on IDA (native and scikit-sundae), minimal coordinates; checked against independent facts."""

import dataclasses
import importlib
import subprocess

import numpy as np
import pytest
import sympy as sp

import lagcodegen as lcg
from lagcodegen import ModelError, SolverError
from lagcodegen.build import driver_sources, find_sundials
from lagcodegen.theory.constraints import ConstrainedSystem
from lagcodegen.api import compile_constrained
from lagcodegen.codegen.constrained import generate_constrained_c
from lagcodegen.model.events import Event

from helpers import G, STRICT_CFLAGS, TH0, atwood, cartesian_pendulum, knife_edge, mixed_system, pendulum_q0


def disc_on_incline(pfaffian: bool, name="disc"):
    """Uniform disc (I = m R^2/2) rolling down a slope alpha: x' = R phi'."""
    m = lcg.Model(name)
    x, phi = m.coordinates("x phi")
    mass, R, g, al = m.parameters(m=2.0, R=0.5, g=G, alpha=0.4)
    m.kinetic_energy(mass / 2 * m.dot(x) ** 2 + mass * R ** 2 / 4 * m.dot(phi) ** 2)
    m.potential_energy(-mass * g * sp.sin(al) * x)
    if pfaffian:
        return ConstrainedSystem(m, nonholonomic=[([1, -R], 0)], integrable="allow")
    return ConstrainedSystem(m, holonomic=[x - R * phi])


@pytest.fixture(scope="module")
def cpend():
    cs = cartesian_pendulum()
    out = ["energy", "lambda", "residuals", "constraint_forces"]
    return {"system": cs,
            "index1": compile_constrained(cs, "index1", outputs=out),
            "ggl": compile_constrained(cs, "ggl", outputs=out),
            "minimal": compile_constrained(cs, "minimal")}


@pytest.fixture(scope="module")
def angle_run():
    sim = lcg.compile_model(lcg.systems.pendulum(), outputs=["positions"])
    return sim.simulate(np.linspace(0, 10, 201), q0=[TH0], rtol=1e-12, atol=1e-14)


CASES = [("index1", "native", {}), ("index1", "sksundae", {}), ("index1", "native", {"projection": True}),
         ("index1", "native", {"baumgarte": (5.0, 5.0)}), ("ggl", "native", {}), ("ggl", "sksundae", {}),
         ("ggl", "native", {"jacobian": False}), ("ggl", "native", {"suppress_alg": False}),
         ("minimal", "native", {})]


# ---------------------------------------------------------------------- pendulum
@pytest.mark.parametrize("formulation,backend,opts", CASES)
def test_cartesian_pendulum_matches_angle_model(cpend, angle_run, formulation, backend, opts):
    res = cpend[formulation].simulate(angle_run.t, q0=pendulum_q0(), v0=[0, 0], rtol=1e-10, atol=1e-12,
                                      backend=backend, **opts)
    assert res.success and res.formulation == formulation
    assert np.max(np.abs(res["x"] - angle_run["bob_x"])) < 2e-6
    assert np.max(np.abs(res["y"] - angle_run["bob_y"])) < 2e-6
    assert np.max(np.abs(res["g_0"])) < 1e-6
    assert res.drift("energy") < 1e-6


@pytest.mark.parametrize("formulation", ["index1", "ggl"])
def test_rod_tension_is_the_multiplier(cpend, angle_run, formulation):
    """T = m (g cos(theta) + l theta'^2); with f = x^2 + y^2 - l^2, R = lambda A = lambda (2x, 2y)
    points away from the pivot for lambda > 0, so the tension is T = -lambda |A| = -2 l lambda."""
    res = cpend[formulation].simulate(angle_run.t, q0=pendulum_q0(), v0=[0, 0], rtol=1e-10, atol=1e-12)
    th, thd = angle_run["theta"], angle_run["theta_dot"]
    tension = 1.0 * (G * np.cos(th) + 1.0 * thd ** 2)
    assert np.max(np.abs(-2.0 * res["lambda_0"] - tension)) < 1e-5 * np.max(tension)
    force = np.hypot(res["R_0_x"], res["R_0_y"])  # |R_j| (sec. 4.3)
    assert np.max(np.abs(force - tension)) < 1e-5 * np.max(tension)


def test_minimal_coordinates_eliminate_y_and_have_no_multipliers(cpend):
    sim = cpend["minimal"]
    assert [q.name for q in sim.eliminated] == ["y"]
    assert sim.state_names == ["x", "x_dot"]
    assert len(sim.branches) == 2  # y = +-sqrt(l^2 - x^2), chosen from q0
    res = sim.simulate([0, 1], q0=pendulum_q0(), v0=[0, 0])
    assert res["y"][0] < 0 and res.stats["branch"] in (0, 1)
    with pytest.raises(ModelError, match="no Lagrange multipliers"):
        compile_constrained(cpend["system"], "minimal", outputs=["lambda"])


def test_minimal_coordinates_errors():
    # nonholonomic constraints are not eliminated from the coordinates: the system is reduced to
    # independent speeds instead (tests/theory/test_speeds.py)
    from lagcodegen.simulation.speeds import IndependentSpeedsSimulation
    assert isinstance(compile_constrained(knife_edge(), "minimal"), IndependentSpeedsSimulation)
    with pytest.raises(ModelError, match="nonholonomic constraints .* cannot be eliminated"):
        lcg.theory.minimal.solve_constraints(knife_edge())
    m = lcg.Model("hard")
    x, y = m.coordinates("x y")
    m.particle("p", 1, (x, y))
    cs = ConstrainedSystem(m, holonomic=[x * y + sp.cos(x) + sp.cos(y)])
    with pytest.raises(ModelError, match="sympy cannot solve the holonomic constraints"):
        compile_constrained(cs, "minimal")


# ---------------------------------------------------------------------- textbook systems
@pytest.mark.parametrize("formulation", ["index1", "ggl"])
def test_atwood_machine_acceleration_and_tension(formulation):
    sim = compile_constrained(atwood(), formulation)
    m1, m2 = 3.0, 1.0
    a_exact = (m1 - m2) * G / (m1 + m2)
    tension = 2 * m1 * m2 * G / (m1 + m2)
    t = np.linspace(0, 1, 11)
    res = sim.simulate(t, q0=[0.5, 1.5], v0=[0, 0], rtol=1e-10, atol=1e-12)
    assert np.allclose(res["x1"], 0.5 + a_exact * t ** 2 / 2, atol=1e-8)
    assert np.allclose(res["x2"], 1.5 - a_exact * t ** 2 / 2, atol=1e-8)
    # m1 x1'' = m1 g + lambda (A = (1, 1)): the tension pulls up, T = -lambda
    assert np.allclose(-res["lambda_0"], tension, rtol=1e-7)
    acc, lam = sim.kkt(0.0, [0.5, 1.5, 0, 0])
    assert np.allclose(acc, [a_exact, -a_exact], rtol=1e-12) and np.isclose(-lam[0], tension, rtol=1e-12)


@pytest.mark.parametrize("pfaffian", [False, True], ids=["holonomic", "pfaffian"])
def test_disc_rolling_down_an_incline(pfaffian):
    """x'' = 2 g sin(alpha)/3 and the friction force lambda = -m g sin(alpha)/3 on x."""
    sim = compile_constrained(disc_on_incline(pfaffian, name=f"disc{int(pfaffian)}"), "index1")
    al, mass = 0.4, 2.0
    a_exact = 2 * G * np.sin(al) / 3
    t = np.linspace(0, 2, 21)
    res = sim.simulate(t, q0=[0, 0], v0=[0, 0], rtol=1e-10, atol=1e-12)
    assert np.allclose(res["x"], a_exact * t ** 2 / 2, atol=1e-8)
    assert np.allclose(res["phi"], a_exact * t ** 2 / 2 / 0.5, atol=1e-8)
    assert np.allclose(res["lambda_0"], -mass * G * np.sin(al) / 3, rtol=1e-7)


def test_disc_in_minimal_coordinates_agrees():
    sim = compile_constrained(disc_on_incline(False, name="discmin"), "minimal")
    t = np.linspace(0, 2, 21)
    res = sim.simulate(t, q0=[0, 0], v0=[0, 0], rtol=1e-10, atol=1e-12)
    assert np.allclose(res["x"], 2 * G * np.sin(0.4) / 3 * t ** 2 / 2, atol=1e-8)


@pytest.mark.parametrize("formulation,opts", [("index1", {}), ("index1", {"baumgarte": (5.0, 0.0)}),
                                              ("index1", {"projection": True}), ("ggl", {})])
def test_knife_edge_keeps_energy_and_its_nonholonomic_constraint(formulation, opts):
    sim = compile_constrained(knife_edge(name=f"knife_{formulation}"), formulation)
    res = sim.simulate(np.linspace(0, 30, 301), q0=[0, 0, 0], v0=[0, 0, 1.5], rtol=1e-10, atol=1e-12, **opts)
    assert res.drift("energy") < 1e-6  # ideal, scleronomic constraint: no work
    assert np.max(np.abs(res["gdot_0"])) < 1e-7
    assert np.ptp(res["y"]) > 0.1  # it does move across the slope (not a trivial run)
    if opts.get("projection") or formulation == "ggl":
        assert np.max(np.abs(res["gdot_0"])) < 1e-9


def test_index1_without_constraints_is_the_plain_model():
    """Only an inequality: J = 0, the augmented system is M q'' = F (code paths with empty arrays)."""
    m = lcg.Model("ball")
    x, y = m.coordinates("x y")
    m.particle("b", 1.0, (x, y))
    m.gravity(G)
    cs = ConstrainedSystem(m, inequalities=[y])
    sim = compile_constrained(cs, "index1", outputs=["energy", "inequalities"])
    res = sim.simulate(np.linspace(0, 1, 11), q0=[0, 1], v0=[1, 0], rtol=1e-10, atol=1e-12)
    t_hit = np.sqrt(2 / G)
    assert res.events and res.events[0].name == "ineq_0" and abs(res.events[0].t - t_hit) < 1e-8
    assert res.t[-1] == res.events[0].t and abs(res["y"][-1]) < 1e-8


# ---------------------------------------------------------------------- drift over long runs
def test_long_cartesian_pendulum_runs_drift(cpend, capsys):
    """t = 100 under every formulation: max |f(q)|, max |A q'|, energy drift."""
    t = np.linspace(0, 100, 2001)
    q0, rows = pendulum_q0(), {}
    runs = {"index1": ("index1", {"baumgarte": (0, 0)}), "index1 default": ("index1", {}),
            "index1+baumgarte": ("index1", {"baumgarte": (10.0, 10.0)}),
            "index1+projection": ("index1", {"projection": True}), "ggl native": ("ggl", {}),
            "ggl sksundae": ("ggl", {"backend": "sksundae"}), "minimal": ("minimal", {})}
    for name, (form, opts) in runs.items():
        res = cpend[form].simulate(t, q0=q0, v0=[0, 0], rtol=1e-10, atol=1e-12, **opts)
        rows[name] = (np.max(np.abs(res["g_0"])), np.max(np.abs(res["gdot_0"])), res.drift("energy"))
    with capsys.disabled():
        print("\n%-20s %10s %10s %10s" % ("t = 100", "max|f|", "max|Aq'|", "dE"))
        for name, (g, s, e) in rows.items():
            print("%-20s %10.2e %10.2e %10.2e" % (name, g, s, e))
    assert rows["ggl native"][0] <= 2e-10  # rtol 1e-10: 0.8-1.2e-10 as last bits of the initial state change
    assert rows["index1+projection"][0] <= 1e-10 and rows["index1+projection"][1] <= 1e-9
    assert rows["minimal"][0] <= 1e-13
    assert rows["index1+baumgarte"][0] < rows["index1"][0] / 100  # stabilization works
    assert rows["index1 default"][0] < rows["index1"][0] / 100  # and is on by default ("auto")
    assert all(e < 1e-4 for _, _, e in rows.values())


def test_default_stabilization_is_the_natural_rate(cpend):
    """At the bottom, at rest, the Cartesian pendulum's index-1 Jacobian has d x''/d x = -g/l
    (small oscillations x'' = -(g/l) x): its natural rate is sqrt(g/l). The default run takes
    alpha = beta = the rate of its initial state (native and scikit-sundae alike); "auto" with
    projection and (0, 0) turn it off."""
    sim = cpend["index1"]
    assert sim.natural_rate(0.0, [0.0, -1.0, 0.0, 0.0]) == pytest.approx(np.sqrt(G), rel=1e-6)
    y0 = np.array([*pendulum_q0(), 0.0, 0.0])
    rate = sim.natural_rate(0.0, y0)
    for backend in ("native", "sksundae"):
        res = sim.simulate([0, 1], q0=pendulum_q0(), v0=[0, 0], backend=backend)
        assert res.stats["alpha"] == res.stats["beta"] == pytest.approx(rate, rel=1e-15)
    assert sim.simulate([0, 1], q0=pendulum_q0(), v0=[0, 0], baumgarte=(0, 0)).stats["alpha"] == 0.0
    assert sim.simulate([0, 1], q0=pendulum_q0(), v0=[0, 0], projection=True).stats["beta"] == 0.0
    with pytest.raises(ModelError, match="'auto' or"):
        sim.simulate([0, 1], q0=pendulum_q0(), v0=[0, 0], baumgarte="fast")


def test_augmented_solve_where_the_mass_matrix_is_singular():
    """Bead on a rod spun at the rate w (polar r, z; z = w t): M = diag(m, m r^2) is singular at
    r = 0 and not numerically positive definite at r = 1e-9, where the generated solve falls
    back from the Schur complement of M to the LU of the whole (regular) augmented system.
    Textbook: r'' = r w^2, and the torque holding the rod is |lambda| = 2 m r r' w."""
    m = lcg.Model("spun_bead")
    r, z = m.coordinates("r z")
    mass, w = m.parameters(m=2.0, w=3.0)
    m.kinetic_energy(mass / 2 * (m.dot(r) ** 2 + r ** 2 * m.dot(z) ** 2))
    sim = compile_constrained(ConstrainedSystem(m, holonomic=[z - w * m.t]), "index1")
    for r0, v0 in ((0.3, 0.5), (1e-9, 0.5), (0.0, 0.0)):
        acc, lam = sim.kkt(0.7, np.array([r0, 3.0 * 0.7, v0, 3.0]))
        assert acc[0] == pytest.approx(r0 * 9.0, rel=1e-13, abs=1e-300) and acc[1] == pytest.approx(0.0, abs=1e-15)
        assert abs(lam[0]) == pytest.approx(2 * 2.0 * r0 * v0 * 3.0, rel=1e-12, abs=1e-300)
    res = sim.simulate([0, 1], q0=[1e-9, 0.0], v0=[0.0, 3.0], rtol=1e-10, atol=1e-20)
    assert res["r"][-1] == pytest.approx(1e-9 * np.cosh(3.0), rel=1e-6)  # r = r0 cosh(w t)


# ---------------------------------------------------------------------- bad input
def test_inconsistent_initial_conditions_are_rejected_or_projected(cpend):
    sim = cpend["index1"]
    with pytest.raises(ModelError, match=r"inconsistent initial conditions.*g_0 .* residual 0.44"):
        sim.simulate([0, 1], q0=[1.2, 0.0], v0=[0, 0])
    with pytest.raises(ModelError, match="velocity constraint 0"):
        cpend["ggl"].simulate([0, 1], q0=[1.0, 0.0], v0=[1.0, 0.3])
    res = sim.simulate([0, 1], q0=[1.2, 0.0], v0=[0.5, 0.3], initial="project")
    assert abs(res["g_0"][0]) < 1e-12 and abs(res["gdot_0"][0]) < 1e-12
    assert res["x"][0] == pytest.approx(1.0) and res["x_dot"][0] == pytest.approx(0.0, abs=1e-12)


def test_projection_that_cannot_succeed_reports_residual_norms():
    m = lcg.Model("noreal")
    x, y = m.coordinates("x y")
    l, = m.parameters(l=1.0)
    m.particle("p", 1.0, (x, y))
    cs = ConstrainedSystem(m, holonomic=[x ** 2 + y ** 2 + l ** 2])  # no real solution
    sim = compile_constrained(cs, "index1")
    with pytest.raises(ModelError, match=r"cannot project the initial state .* \|f\(q\)\| = "):
        sim.simulate([0, 1], q0=[0.3, 0.4], v0=[0, 0], initial="project")


def test_singular_constraint_jacobian_at_the_initial_state_is_rejected(cpend):
    m = cpend["system"].model
    x, y = m.coords
    l = sp.Symbol("l")
    cs = ConstrainedSystem(m, holonomic=[x ** 2 + y ** 2 - l ** 2, x - l])  # tangent at (l, 0)
    sim = compile_constrained(cs, "index1", prefix="tangent")
    for initial in ("check", "project"):
        with pytest.raises(ModelError, match="singular constraint Jacobian at the initial state"):
            sim.simulate([0, 1], q0=[1.0, 0.0], v0=[0, 0], initial=initial)


def test_option_errors(cpend):
    with pytest.raises(lcg.LagcodegenError, match="needs method='bdf'"):
        cpend["index1"].simulate([0, 1], q0=pendulum_q0(), projection=True, method="adams")
    with pytest.raises(lcg.LagcodegenError, match="no projection"):
        cpend["index1"].simulate([0, 1], q0=pendulum_q0(), projection=True, backend="sksundae")
    with pytest.raises(ModelError, match="formulation must be one of"):
        compile_constrained(cpend["system"], "index3")
    with pytest.raises(ModelError, match="unknown output 'tension'"):
        compile_constrained(cpend["system"], "index1", outputs=["tension"])


def test_solver_failure_is_reported(cpend):
    with pytest.raises(SolverError, match="max_steps"):
        cpend["ggl"].simulate([0, 10], q0=pendulum_q0(), v0=[0, 0], max_steps=50)


# ---------------------------------------------------------------------- the call path (issue 16)
def consistent_state(th=TH0, w=0.7):
    """(q0, v0) on the pendulum's constraint manifold: v tangent to the circle."""
    return pendulum_q0(th), [w * np.cos(th), w * np.sin(th)]


@pytest.mark.parametrize("formulation", ["index1", "ggl"])
@pytest.mark.parametrize("initial,scale", [("check", 1.0), ("project", 1.01), ("none", 1.0)])
def test_initial_state_in_one_call_is_the_checks_function_by_function(cpend, formulation, initial, scale):
    """The generated <prefix>_initial_state gives bit for bit the state (and the GGL initial
    values) of the Python-driven checks, projection and augmented-system solve."""
    sim = cpend[formulation]
    q0, v0 = consistent_state()
    q0 = [scale * x for x in q0]
    p = sim.parameter_vector()
    y0, yy0, yp0 = sim._initial_values(0.0, q0, v0, p, initial, 1e-8, formulation == "ggl")
    ref = sim.consistent_initial_state(0.0, q0, v0, p, initial=initial)
    assert np.array_equal(y0, ref)
    if formulation == "ggl":
        ref_yy, ref_yp = sim._ggl_initial(0.0, ref, p)
        assert np.array_equal(yy0, ref_yy) and np.array_equal(yp0, ref_yp)
    else:
        assert yy0 is None and yp0 is None


def test_initial_state_in_one_call_with_inequalities_and_mixed_rows():
    """Holonomic and nonholonomic rows and an inequality (its root function checked at t0): the
    one-call path agrees with the function-by-function checks, and rejects what they reject
    with their message."""
    sim = compile_constrained(mixed_system(), "ggl", prefix="mixed_init")
    p = sim.parameter_vector()
    x, t0, th = 0.5, 0.2, 0.3
    vx = x * np.cos(t0) / 4 / (np.tan(th) - np.sin(t0) / 4)  # y' = x' sin(t)/4 + x cos(t)/4, y' = tan(th) x'
    q0, v0 = [x, x * np.sin(t0) / 4, th], [vx, np.tan(th) * vx, 0.4]
    for initial in ("check", "project"):
        y0, yy0, yp0 = sim._initial_values(0.2, q0, v0, p, initial, 1e-8, True)
        ref = sim.consistent_initial_state(0.2, q0, v0, p, initial=initial)
        assert np.array_equal(y0, ref)
        assert all(np.array_equal(a, b) for a, b in zip((yy0, yp0), sim._ggl_initial(0.2, ref, p)))
    bad = [4.0, 4.0 * np.sin(0.2) / 4, 0.3]  # x > 3: the inequality 3 - x >= 0 is violated
    with pytest.raises(ModelError) as fast:
        sim.simulate([0.2, 1], q0=bad, v0=v0)
    with pytest.raises(ModelError) as slow:
        sim.consistent_initial_state(0.2, bad, v0, p)
    assert str(fast.value) == str(slow.value)


@pytest.mark.parametrize("formulation", ["index1", "ggl"])
def test_simulate_does_no_symbolic_work(cpend, formulation, monkeypatch):
    """A consistent initial state is checked by compiled code only: no sympy in the call."""
    def symbolic(*args, **kwargs):
        raise AssertionError("symbolic work in simulate()")
    monkeypatch.setattr(ConstrainedSystem, "evaluate", symbolic)
    monkeypatch.setattr(ConstrainedSystem, "check_initial", symbolic)
    q0, v0 = consistent_state()
    for initial in ("check", "project", "none"):
        assert cpend[formulation].simulate((0, 1), q0=q0, v0=v0, initial=initial).success


@pytest.mark.parametrize("formulation", ["index1", "ggl"])
def test_repeated_calls_reuse_nothing_visible(cpend, formulation):
    """Runs with other options in between give bit for bit the first run's result (the option
    structs kept across calls), and no result shares its arrays with the next one."""
    sim = cpend[formulation]
    q0, v0 = consistent_state()
    first = sim.simulate((0, 1), q0=q0, v0=v0, rtol=1e-6)
    sim.simulate(np.linspace(0, 1, 11), q0=q0, v0=v0, rtol=1e-9, atol=np.linspace(1e-11, 1e-10, 4))
    sim.simulate((0, 0.5), q0=q0, v0=v0, rtol=1e-6, max_step=0.01)
    first_t, first_y = first.t.copy(), first.y.copy()
    first.t[:] = -1.0  # the caller owns its result
    first.y[:] = np.nan
    again = sim.simulate((0, 1), q0=q0, v0=v0, rtol=1e-6)
    assert np.array_equal(again.t, first_t) and np.array_equal(again.y, first_y)
    assert again.stats["steps"] == first.stats["steps"] and again.t.flags.writeable
    assert all(np.array_equal(v, first.outputs[k]) for k, v in again.outputs.items())


def test_terminal_events_repeat_exactly():
    """The events structs kept across calls: the same events and final row every time."""
    m = lcg.Model("ball_again")
    x, y = m.coordinates("x y")
    m.particle("b", 1.0, (x, y))
    m.gravity(G)
    sim = compile_constrained(ConstrainedSystem(m, inequalities=[y]), "index1", outputs=["energy"])
    runs = [sim.simulate(np.linspace(0, 1, 11), q0=[0, 1], v0=[1, 0], max_events=k) for k in (10, 10, 3, 10)]
    for res in runs[1:]:
        assert [(e.name, e.t) for e in res.events] == [(e.name, e.t) for e in runs[0].events]
        assert np.array_equal(res.t, runs[0].t) and np.array_equal(res.y, runs[0].y)
        assert np.array_equal(res.events[0].y, runs[0].events[0].y)


def test_concurrent_calls_give_the_sequential_results(cpend):
    """The structs kept across calls are shared safely between threads (cffi releases the GIL
    in the drivers): runs with different options from 4 threads give the sequential results."""
    from concurrent.futures import ThreadPoolExecutor
    for formulation in ("index1", "ggl"):
        sim = cpend[formulation]
        jobs = [dict(t=(0, 1 + i % 3), q0=pendulum_q0(0.5 + 0.1 * (i % 5)), rtol=10.0 ** -(5 + i % 4),
                     atol=1e-10 if i % 2 else 1e-9) for i in range(40)]
        ref = [sim.simulate(**job) for job in jobs]
        with ThreadPoolExecutor(4) as ex:
            got = list(ex.map(lambda job: sim.simulate(**job), jobs))
        for a, b in zip(ref, got):
            assert np.array_equal(a.t, b.t) and np.array_equal(a.y, b.y) and a.stats["steps"] == b.stats["steps"]


@pytest.mark.parametrize("formulation,backend", [("index1", "native"), ("ggl", "native"), ("index1", "sksundae"),
                                                 ("ggl", "sksundae")])
def test_output_times_are_interpolated_not_stepped_to(cpend, formulation, backend):
    """t = (t0, t1) (1001 output times) takes the integrator's own steps: the same work with 11
    and with 1001 output times (CVODE's first step is estimated from the first output interval,
    hence "within a few"). scikit-sundae's step counter also counts the calls that return an
    already reached step after an interpolated output, so there the right-hand-side evaluations
    are compared."""
    q0, v0 = consistent_state()
    runs = [cpend[formulation].simulate(t, q0=q0, v0=v0, backend=backend)
            for t in (np.linspace(0, 2, 11), np.linspace(0, 2, 1001), (0, 2))]
    key = "steps" if backend == "native" else "rhs_evals"
    work = [r.stats[key] for r in runs]
    assert abs(work[1] - work[0]) <= 5 and work[2] == work[1], work
    assert runs[2].t.size == 1001 and np.array_equal(runs[2].t, np.linspace(0, 2, 1001))


def test_overhead_benchmark_runs():
    """benchmarks/constrained_overhead.py measures what simulate() runs (one repeat)."""
    import sys
    from pathlib import Path
    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
    import constrained_overhead as co
    sim = compile_constrained(co.chain(1, "tb_ovc"), "ggl", prefix="tb_ovc")
    rows = co.measure("pendulum", sim, co.chain_q0(1), 1)
    assert len(rows) == len(co.TIMES)
    for r in rows:
        assert r["same"] and r["steps"] > 0 and r["driver_us"] > 0 and r["simulate_us"] > 0


# ---------------------------------------------------------------------- generated code
def test_ggl_jacobian_matches_central_differences(cpend):
    sim = compile_constrained(knife_edge(name="knife_jac"), "ggl")
    rng = np.random.default_rng(1)
    for s in (sim, cpend["ggl"]):
        ng = s.info.ng
        yy, yp, cj = rng.normal(size=ng), rng.normal(size=ng), 37.0
        J = s.ggl_jacobian(0.3, cj, yy, yp)
        eps = 1e-6
        Jn = np.empty((ng, ng))
        for j in range(ng):
            d = np.zeros(ng)
            d[j] = eps
            Jn[:, j] = (s.ggl_residual(0.3, yy + d, yp) - s.ggl_residual(0.3, yy - d, yp)) / (2 * eps)
            Jn[:, j] += cj * (s.ggl_residual(0.3, yy, yp + d) - s.ggl_residual(0.3, yy, yp - d)) / (2 * eps)
        assert np.max(np.abs(J - Jn)) < 1e-6 * max(1.0, np.max(np.abs(J)))


@pytest.mark.parametrize("which", ["pendulum", "knife", "mixed", "free"])
def test_generated_constrained_code_compiles_with_strict_warnings(tmp_path, cc, which):
    if which == "free":
        m = lcg.Model("free")
        x, = m.coordinates("x")
        m.particle("p", 1.0, (x, 0))
        cs = ConstrainedSystem(m, inequalities=[x])
    else:
        cs = {"pendulum": cartesian_pendulum, "knife": knife_edge, "mixed": mixed_system}[which]()
    events = [Event("lam", cs.multipliers[0], -1, False)] if cs.J else []
    code, info = generate_constrained_c(cs, ggl=True, events=events,
                                        outputs=["energy", "lambda", "residuals", "constraint_forces"])
    code.write(tmp_path)
    for fname, text in driver_sources(code, find_sundials()).items():
        (tmp_path / fname).write_text(text)
    sources = sorted(f for f in code.files if f.endswith(".c"))
    # the model's tables and the runtime's model-independent constrained drivers too
    assert {f"{code.prefix}_table.c", f"{code.prefix}_dae_table.c", "lcg_cvc.c", "lcg_ida.c"} <= set(
        driver_sources(code, find_sundials()))
    for src in sources + [f"{code.prefix}_table.c", f"{code.prefix}_dae_table.c", "lcg_cvc.c", "lcg_ida.c"]:
        proc = subprocess.run([cc, *STRICT_CFLAGS, "-c", src, "-o", "x.o"], cwd=tmp_path, capture_output=True,
                              text=True)
        assert proc.returncode == 0, src + "\n" + proc.stderr


SANITIZER_MAIN = r"""
#include <math.h>
#include <stdio.h>
#include <string.h>
#include "P_dae.h"
#include "lcg_cvc.h"
#include "lcg_ida.h"

extern const lcg_dae_model P_dae_model;

#define M 5
#define NT 41

int main(void)
{
    const lcg_dae_model *m = &P_dae_model;
    lcg_dae_model bad;
    double p[U_DAE_NP + 1], y[U_DAE_NY], yn[U_DAE_NY], err[U_DAE_NY], acc[U_DAE_NQ], lam[U_DAE_NJ];
    double yd[U_DAE_NY], g[U_DAE_NJH], s[U_DAE_NJ], out[U_DAE_NOUT], gout[U_DAE_NROOT];
    double yy[U_DAE_NG], yp[U_DAE_NG], rr[U_DAE_NG], jac[U_DAE_NG * U_DAE_NG], yy2[U_DAE_NG], yp2[U_DAE_NG];
    double tout[NT], yout[NT * U_DAE_NG], outs[NT * U_DAE_NOUT], evt[8], evy[8 * U_DAE_NG], atol[U_DAE_NG];
    double y0s[M * 2 * U_DAE_NG], final[M * (U_DAE_NG + U_DAE_NOUT)], traj[M * NT * 2], t_reached[M], wall[M];
    long counts[M * 8], member[4];
    int which[8], dir[8], rootdir[U_DAE_NROOT], terminal[U_DAE_NROOT], flag[M], nt_done[M], col[2] = {0, 1};
    char messages[4 * 256];
    lcg_events ev = {8, 0, evt, evy, which, dir, rootdir, terminal, 0};
    lcg_cvc_options co = {2, 1e-8, 1e-10, NULL, 100000, 0.0, 0.0, 0.0, 0, 1.0, 1.0, 1, 1e-12, 10, 1, 1};
    lcg_ida_options io = {1e-8, 1e-10, atol, 100000, 0.0, 0.0, 0.0, 0, 1, 1, 1, 1e8, 1, 1};
    lcg_cvc_stats cs;
    lcg_ida_stats is;
    lcg_cvc_ensemble ce;
    lcg_ida_ensemble ie;
    int i, k, ok, rc = 0;

    for (i = 0; i < U_DAE_NP; ++i)
        p[i] = PARAMS[i];
    for (i = 0; i < U_DAE_NG; ++i)
        atol[i] = i < U_DAE_NY ? 1e-10 : 1e8; /* lambda, mu: see ALGEBRAIC_ATOL in dae.py */
    for (i = 0; i < U_DAE_NROOT; ++i) {
        rootdir[i] = 0;
        terminal[i] = 0;
    }
    y[0] = sin(1.0); y[1] = -cos(1.0); y[2] = 0.1; y[3] = 0.2;
    rc |= m->kkt(0.1, y, p, 1.0, 2.0, acc, lam);
    rc |= m->crhs(0.1, y, p, 0.0, 0.0, yd);
    rc |= m->residuals(0.1, y, p, g, s);
    for (i = 0; i < U_DAE_NY; ++i)
        err[i] = 1e-3 * (i + 1);
    rc |= m->project(0.1, y, p, 1e-14, 20, yn, err);
    rc |= m->coutputs(0.1, yn, NULL, p, out);
    rc |= m->roots(0.1, yn, lam, p, gout);
    rc |= m->kkt(0.0, yn, p, 0.0, 0.0, acc, lam);
    rc |= lcg_dae_initial_state(m, 0.1, y, p, 2, 1e-8, 0, yy2, yp2);   /* project */
    rc |= lcg_dae_initial_state(m, 0.1, yy2, p, 1, 1e-8, 0, yy2, yp2); /* check the projected state */
    (void)lcg_dae_initial_state(m, 0.1, yy2, p, 1, 1e-8, 1, yy2, yp2);  /* root 0 (lambda) taken for an inequality */
    rc |= lcg_dae_initial_state(m, 0.1, yy2, p, 0, 1e-8, 0, yy2, NULL); /* as it is, index-1 layout */
    if (lcg_dae_initial_state(m, 0.1, y, p, 1, 1e-8, 0, yy2, yp2) != 1) /* y is off the constraints: rejected */
        rc |= 1;
    for (i = 0; i < U_DAE_NG; ++i)
        yy[i] = yp[i] = 0.0;
    for (i = 0; i < U_DAE_NY; ++i)
        yy[i] = yn[i];
    for (i = 0; i < U_DAE_NQ; ++i) {
        yp[i] = yn[U_DAE_NQ + i];
        yp[U_DAE_NQ + i] = acc[i];
    }
    for (i = 0; i < U_DAE_NJ; ++i)
        yy[U_DAE_NY + i] = lam[i];
    rc |= m->ggl_res(0.0, yy, yp, p, rr);
    rc |= m->ggl_jac(0.0, 10.0, yy, yp, p, jac);
    for (i = 0; i < NT; ++i)
        tout[i] = 0.05 * i;
    rc |= lcg_cvc_solve(m, p, yn, NT, tout, yout, outs, &co, &cs, &ev);
    printf("cvc rc=%d steps=%ld proj=%ld events=%d g_end=%.3g\n", rc, cs.nsteps, cs.nproj, ev.n_events,
           outs[(NT - 1) * U_DAE_NOUT + 2]);
    rc |= lcg_ida_solve(m, p, yy, yp, NT, tout, yout, outs, &io, &is, &ev);
    printf("ida rc=%d steps=%ld events=%d g_end=%.3g\n", rc, is.nsteps, ev.n_events, outs[(NT - 1) * U_DAE_NOUT + 2]);
    rc |= cs.nt_done != NT || is.nt_done != NT;

    /* a table of another layout version is refused, with a message */
    bad = *m;
    bad.abi = LCG_DAE_MODEL_ABI + 1;
    k = lcg_cvc_solve(&bad, p, yn, NT, tout, yout, outs, &co, &cs, &ev);
    printf("bad rc=%d ida=%d init=%d message=%s\n", k, lcg_ida_solve(&bad, p, yy, yp, NT, tout, yout, outs, &io, &is,
           NULL), lcg_dae_initial_state(&bad, 0.1, y, p, 0, 1e-8, 0, yy2, NULL), strstr(cs.message, "version") ? "yes"
           : "no");

    /* ensembles on 3 threads, M members: index 1 with velocities that differ (off the constraints a
       little: the driver takes the state as given), GGL from the consistent state */
    for (i = 0; i < M; ++i) {
        for (k = 0; k < U_DAE_NG; ++k) {
            y0s[i * 2 * U_DAE_NG + k] = yy[k];
            y0s[i * 2 * U_DAE_NG + U_DAE_NG + k] = yp[k];
        }
        y0s[i * 2 * U_DAE_NG + U_DAE_NQ] += 0.01 * i; /* velocities differ */
        flag[i] = -82;
    }
    memset(&ce, 0, sizeof ce);
    ce.model = m; ce.nmem = M; ce.nthreads = 3; ce.p = p; ce.p_stride = 0; ce.y0 = y0s; ce.y0_stride = 2 * U_DAE_NG;
    ce.nt = NT; ce.tout = tout; ce.final = final; ce.traj = traj; ce.ncol = 2; ce.col = col; ce.flag = flag;
    ce.nt_done = nt_done; ce.t_reached = t_reached; ce.wall = wall; ce.counts = counts; ce.messages = messages;
    ce.max_messages = 4; ce.message_member = member; ce.max_events = 4; ce.rootdir = rootdir; ce.terminal = terminal;
    co.projection = 0;
    k = lcg_cvc_solve_many(&ce, &co);
    for (i = 0, ok = 0; i < M; ++i)
        ok += flag[i] == 0 && nt_done[i] == NT;
    printf("cvc_many rc=%d ok=%d done=%ld\n", k, ok, ce.done);
    rc |= k != 0 || ok != M;
    memset(&ie, 0, sizeof ie);
    for (i = 0; i < M; ++i) {
        y0s[i * 2 * U_DAE_NG + U_DAE_NQ] = yy[U_DAE_NQ];
        flag[i] = -82;
    }
    ie.model = m; ie.nmem = M; ie.nthreads = 3; ie.p = p; ie.p_stride = 0; ie.y0 = y0s; ie.y0_stride = 2 * U_DAE_NG;
    ie.yp0 = y0s + U_DAE_NG; ie.yp0_stride = 2 * U_DAE_NG;
    ie.nt = NT; ie.tout = tout; ie.final = final; ie.traj = traj; ie.ncol = 2; ie.col = col; ie.flag = flag;
    ie.nt_done = nt_done; ie.t_reached = t_reached; ie.wall = wall; ie.counts = counts; ie.messages = messages;
    ie.max_messages = 4; ie.message_member = member; ie.max_events = 4; ie.rootdir = rootdir; ie.terminal = terminal;
    k = lcg_ida_solve_many(&ie, &io);
    for (i = 0, ok = 0; i < M; ++i)
        ok += flag[i] == 0 && nt_done[i] == NT;
    printf("ida_many rc=%d ok=%d done=%ld\n", k, ok, ie.done);
    rc |= k != 0 || ok != M;
    return rc != 0;
}
"""


def test_constrained_code_and_drivers_clean_under_sanitizers(tmp_path, cc):
    """The model's functions, its tables and the runtime's model-independent constrained drivers
    (single runs, the initial state, ensembles on 3 threads, a table of another version) under
    AddressSanitizer (leaks too) and UBSan."""
    cs = cartesian_pendulum(name="san")
    code, info = generate_constrained_c(cs, ggl=True, events=[Event("lam", cs.multipliers[0], 0, False)],
                                        outputs=["energy", "lambda", "residuals"])
    code.write(tmp_path)
    sundials = find_sundials()
    for fname, text in driver_sources(code, sundials).items():
        (tmp_path / fname).write_text(text)
    params = ", ".join(repr(float(v)) for v in code.param_defaults) or "0.0"
    main = SANITIZER_MAIN.replace("P_", "san_").replace("U_", "SAN_").replace("PARAMS", f"((double[]){{{params}}})")
    (tmp_path / "main.c").write_text(main)
    srcs = ["main.c", "san.c", "san_dae.c", "san_table.c", "san_dae_table.c", "lcg_cvc.c", "lcg_ida.c"]
    cmd = [cc, "-g", "-O1", "-std=c99", "-fsanitize=address,undefined", "-fno-sanitize-recover=all", *srcs,
           "-o", "main", "-pthread", *sundials.link_args(("cvode", "ida", "core")), "-lm"]
    proc = subprocess.run(cmd, cwd=tmp_path, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    run = subprocess.run(["./main"], cwd=tmp_path, capture_output=True, text=True,
                         env={"ASAN_OPTIONS": "detect_leaks=1", "UBSAN_OPTIONS": "print_stacktrace=1"})
    assert run.returncode == 0, run.stdout + run.stderr
    assert "runtime error" not in run.stderr and "AddressSanitizer" not in run.stderr
    lines = dict(line.split(" ", 1) for line in run.stdout.splitlines())
    fields = {k: dict(kv.split("=") for kv in v.split()) for k, v in lines.items()}
    assert abs(float(fields["cvc"]["g_end"])) < 1e-9 and int(fields["cvc"]["proj"]) > 0
    assert abs(float(fields["ida"]["g_end"])) < 1e-7
    assert fields["bad"] == {"rc": "-22", "ida": "-22", "init": "-22", "message": "yes"}
    assert fields["cvc_many"]["ok"] == "5" and fields["ida_many"]["ok"] == "5"


def test_constrained_models_are_plain_libraries_on_the_shared_runtime():
    """Constrained code compiles into a library without Python.h whose tables the runtime's
    model-independent drivers take: one runtime for every model and formulation, the table's
    layout that of the code; a library whose table disagrees with its code is refused."""
    build_module = importlib.import_module("lagcodegen.build")
    rt = build_module.runtime()
    sims = [compile_constrained(cartesian_pendulum("plain_lib"), form) for form in ("index1", "ggl")]
    sims.append(compile_constrained(knife_edge("plain_knife"), "ggl", jacobian=False,
                                    events=[Event("x0", knife_edge().model.coords[0], 0, False)]))
    null = rt.ffi.NULL
    for sim in sims:
        cm = sim.compiled
        assert cm.module is rt and sim.lib is rt.lib
        assert cm.path.suffix == ".so" and cm.path.name.startswith("lib_lcg_")
        binary = cm.path.read_bytes()
        assert b"PyInit_" not in binary and b"Py_" not in binary  # no Python in the model library
        t = sim.table
        assert (t.abi, t.nq, t.ny, t.nj, t.njh, t.ng, t.nout, t.nroot) == (
            1, sim.n, 2 * sim.n, sim.info.J, sim.info.JH, sim.info.ng, len(sim.info.output_names),
            len(sim.info.events))
        assert t.model == cm.table and cm.table.nq == sim.n
    assert sims[0].table.ggl_res == null and sims[0].c_ida_solve is None
    assert sims[1].table.ggl_res != null and sims[1].table.ggl_jac != null and sims[1].table.roots == null
    assert sims[2].table.ggl_jac == null and sims[2].table.roots != null and sims[2].table.njh == 0
    code = sims[1].compiled.code
    wrong = dataclasses.replace(code, dae=dataclasses.replace(code.dae, nout=code.dae.nout + 1))
    with pytest.raises(lcg.LagcodegenError, match="another layout"):
        build_module.build(wrong)
    with pytest.raises(lcg.LagcodegenError, match="native"):
        build_module.build(code, native=False)


def test_ggl_jacobian_of_a_coordinate_named_cj():
    """The GGL Jacobian's own symbol cj (IDA's coefficient) never collides with a user's coordinate
    or parameter of that name (issue 13)."""
    m = lcg.Model("cj_pendulum")
    cj, y = m.coordinates("cj y")
    mass, l, g = m.parameters(m=1.0, l=1.0, g=G)
    m.particle("bob", mass, [cj, y])
    m.gravity(g)
    sim = compile_constrained(ConstrainedSystem(m, holonomic=[cj ** 2 + y ** 2 - l ** 2]), "ggl")
    rng = np.random.default_rng(2)
    ng = sim.info.ng
    yy, yp, c = rng.normal(size=ng), rng.normal(size=ng), 37.0
    J = sim.ggl_jacobian(0.3, c, yy, yp)
    eps = 1e-6
    Jn = np.empty((ng, ng))
    for j in range(ng):
        d = np.zeros(ng)
        d[j] = eps
        Jn[:, j] = (sim.ggl_residual(0.3, yy + d, yp) - sim.ggl_residual(0.3, yy - d, yp)) / (2 * eps)
        Jn[:, j] += c * (sim.ggl_residual(0.3, yy, yp + d) - sim.ggl_residual(0.3, yy, yp - d)) / (2 * eps)
    assert np.max(np.abs(J - Jn)) < 1e-6 * max(1.0, np.max(np.abs(J)))
