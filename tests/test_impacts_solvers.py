"""Contacts with restitution on the solvers besides index-1 CVODE (issue 39): minimal coordinates
and GGL on IDA. tests/test_impacts.py holds the bouncing ball, Newton's cradle and the particle
leaving the sphere to its bounds on every formulation; here: a pendulum in Cartesian coordinates
hitting a wall (quadrature, Newton's law, the index-1 run), Housner's block on GGL, apex events,
the shipped model file, loose tolerances, and the refusals (Taylor on GGL, friction on GGL, ...)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp
from scipy.integrate import quad

import lagcodegen as lcg
from lagcodegen.api import compile_constrained
from lagcodegen.errors import LagcodegenError, ModelError

G = 9.81


def _ball_system(e: float):
    m = lcg.Model("sball")
    (y,) = m.coordinates("y")
    m.parameters(g=G, m=1.0)
    m.particle("b", sp.Symbol("m"), (0, y))
    m.gravity(sp.Symbol("g"))
    return lcg.ConstrainedSystem(m, inequalities=[lcg.Inequality(y, restitution=e)])


def _pendulum_wall(e: float):
    m = lcg.Model("pwall")
    x, y = m.coordinates("x y")
    m.parameters(g=G, m=1.0, l=1.0, d=0.3)
    m.particle("b", sp.Symbol("m"), (x, y))
    m.gravity(sp.Symbol("g"))
    return lcg.ConstrainedSystem(m, holonomic=[x**2 + y**2 - sp.Symbol("l") ** 2],
                                 inequalities=[lcg.Inequality(sp.Symbol("d") - x, restitution=e)])


def test_minimal_contacts_refuse_what_the_impact_driver_does_not_run():
    sim = compile_constrained(_pendulum_wall(0.5), "minimal")
    q0, v0 = [-0.6, -0.8], [0.0, 0.0]
    with pytest.raises(LagcodegenError, match="integrator object does not run systems with contacts"):
        sim.integrator(q0=q0, v0=v0)
    with pytest.raises(LagcodegenError, match="ensembles of systems with contacts"):
        sim.ensemble((0, 1), q0=[q0], v0=[v0])
    with pytest.raises(ModelError, match="violated"):
        sim.simulate((0, 1), q0=[0.6, -0.8], v0=v0)


@pytest.mark.parametrize("formulation", ["minimal", "ggl"])
def test_pendulum_hits_a_wall_on_minimal_and_ggl(formulation):
    """A pendulum x^2 + y^2 = l^2 released at x = -0.6 hits the wall x = d = 0.3: the impact at the
    time of the quadrature of the energy integral, w+ = -e w- (Newton's law), the kinetic energy
    after it e^2 of that before (one degree of freedom), and the swing after it as the index-1 run
    of the full system. Minimal coordinates eliminate y (x remains); GGL holds the circle as a row
    with the contact's row beside it. The contacts were ignored in minimal coordinates before
    (the pendulum swung through the wall)."""
    e, l, d, x0 = 0.7, 1.0, 0.3, -0.6
    system = _pendulum_wall(e)
    sim = compile_constrained(system, formulation, outputs=["energy"])
    t = np.linspace(0, 2, 201)
    q0 = [x0, -math.sqrt(l**2 - x0**2)]
    res = sim.simulate(t, q0=q0, v0=[0.0, 0.0], rtol=1e-12, atol=1e-14)
    assert res.state_names == (["x", "x_dot"] if formulation == "minimal" else ["x", "y", "x_dot", "y_dot"])
    assert res["x"].max() <= d + 1e-12
    first = res.impacts[0]
    assert first.kind == "bounce" and first.contact == 0
    # theta from the vertical, x = l sin(theta): t = int dtheta / sqrt(2 g (cos th - cos th0) / l)
    th0, th1 = math.asin(x0 / l), math.asin(d / l)
    t_hit = quad(lambda th: 1 / math.sqrt(2 * G * (math.cos(th) - math.cos(th0)) / l), th0, th1, limit=200)[0]
    assert first.t == pytest.approx(t_hit, rel=1e-9)
    # w = -x' at the wall, x' = l cos(th1) th', th'^2 = 2 g (cos th1 - cos th0) / l
    w_minus = -l * math.cos(th1) * math.sqrt(2 * G * (math.cos(th1) - math.cos(th0)) / l)
    assert first.w_before == pytest.approx(w_minus, rel=1e-9)
    assert first.w_after == pytest.approx(-e * first.w_before, rel=1e-12)
    k = np.searchsorted(res.t, first.t)
    E = res["energy"]
    E_wall = G * -math.sqrt(l**2 - d**2)  # the potential energy m g y at the wall (m = 1), y = -sqrt(l^2 - d^2)
    assert E[k] - E_wall == pytest.approx(e**2 * (E[k - 1] - E_wall), rel=1e-9)
    full = compile_constrained(system, "index1").simulate(t, q0=q0, v0=[0.0, 0.0], rtol=1e-12, atol=1e-14)
    assert [r.kind for r in full.impacts] == [r.kind for r in res.impacts]
    assert np.max(np.abs(full["x"] - res["x"])) < 1e-8
    assert np.max(np.abs(full["y"] - res["y"])) < 1e-8
    assert np.max(np.abs(res["x"] ** 2 + res["y"] ** 2 - l**2)) < 1e-10


def test_ggl_contacts_refuse_what_the_driver_does_not_take():
    # (Coulomb friction, ensembles and the integrator object run on GGL: tests/test_friction_ggl.py,
    # tests/test_impacts_ggl_consumers.py)
    sim = compile_constrained(_ball_system(0.5), "ggl")
    with pytest.raises(LagcodegenError, match="stop_at_outputs"):
        sim.simulate((0, 1), q0=[1.0], v0=[0.0], stop_at_outputs=True)
    with pytest.raises(LagcodegenError, match="native IDA driver"):
        sim.simulate((0, 1), q0=[1.0], v0=[0.0], backend="sksundae")
    with pytest.raises(ModelError, match="violated"):
        sim.simulate((0, 1), q0=[-0.5], v0=[0.0])


@pytest.mark.parametrize("formulation", ["ggl", "minimal"])
def test_model_file_contact_on_ggl_and_minimal(formulation):
    """examples/bouncing_ball.toml compiled in another formulation: the first impacts at the closed-form
    times and the ball at rest on the floor held by m g."""
    from pathlib import Path

    from lagcodegen.api import compile_file
    from lagcodegen.modelfile import load_model

    mf = load_model(Path(__file__).resolve().parent.parent / "examples" / "bouncing_ball.toml")
    res = mf.simulate(compile_file(mf, formulation=formulation))
    assert res.formulation == formulation
    t1 = math.sqrt(2 / G)
    first = [r.t for r in res.impacts.select("bounce")][:3]
    exact = [t1 + 2 * t1 * 0.8 * (1 - 0.8**k) / 0.2 for k in range(3)]
    assert np.max(np.abs(np.array(first) / exact - 1)) < 1e-9
    assert res["lambda_ineq_0"][-1] == pytest.approx(G, rel=1e-9)
    assert abs(res["y"][-1]) < 1e-9


def test_taylor_runs_contacts_on_index1_and_minimal_and_ggl_refuses_it():
    """Both spellings of the Taylor method run contacts on the index-1 and minimal formulations
    (tests/test_impacts_taylor.py checks them); GGL takes its contacts on IDA."""
    for formulation in ("index1", "minimal"):
        sim = compile_constrained(_ball_system(0.5), formulation)
        for options in ({"method": "taylor"}, {"solver": lcg.Taylor()}):
            res = sim.simulate((0, 1), q0=[1.0], v0=[0.0], **options)
            assert res.method == "taylor" and res.impacts.select("bounce")[0].t == pytest.approx(math.sqrt(2 / G))
    sim = compile_constrained(_ball_system(0.5), "ggl")
    with pytest.raises(LagcodegenError, match="IDA integrates with BDF only"):
        sim.simulate((0, 1), q0=[1.0], v0=[0.0], method="taylor")
    with pytest.raises(LagcodegenError, match="Taylor integrates .* not a constrained system in the GGL form"):
        sim.simulate((0, 1), q0=[1.0], v0=[0.0], solver=lcg.Taylor())


def test_ggl_housner_block_on_no_slip_corners():
    """Housner's block on rough (no-slip) corners on GGL: the corner it leans on stays put (its
    normal and tangential rows held in the residual), it falls back in the time of the pendulum
    about the corner (quadrature), the other corner hits plastically while the first is released
    at the same instant, and w+/w- = 1 - 1.5 sin^2 a (Housner 1963), as test_impacts.py checks on
    index-1."""
    from test_impacts import housner_block
    b, h, phi0 = 0.2, 0.6, 0.1
    sim = compile_constrained(housner_block("ghousner", b, h), "ggl")
    q0 = [-b + b * math.cos(phi0) - h * math.sin(phi0), h * math.cos(phi0) + b * math.sin(phi0), phi0]
    res = sim.simulate(np.linspace(0, 1.0, 101), q0=q0, v0=[0.0, 0.0, 0.0], rtol=1e-12, atol=1e-14)
    sticks = res.impacts.select("stick")
    assert [r.contact for r in sticks[:2]] == [1, 0]
    t_hit = sticks[0].t
    assert [(r.contact, r.kind) for r in res.impacts if r.t == t_hit] == [(0, "release"), (1, "stick")]
    before = res.t < t_hit
    xl = res["x"] - b * np.cos(res["phi"]) + h * np.sin(res["phi"])
    yl = res["y"] - b * np.sin(res["phi"]) - h * np.cos(res["phi"])
    assert np.max(np.abs(xl[before] + b)) < 1e-9 and np.max(np.abs(yl[before])) < 1e-10
    assert np.all(res["lambda_ineq_0"][before] > 0) and "lambda_t_ineq_0" in res.outputs
    R, a = math.hypot(b, h), math.atan2(b, h)
    I0 = 4 / 3 * R**2
    fall = quad(lambda p: 1 / math.sqrt(2 * G * R * (math.cos(a - phi0) - math.cos(a - p)) / I0), 0, phi0,
                limit=200)[0]
    assert t_hit == pytest.approx(fall, rel=1e-7)
    dt = 1e-9
    near = sim.simulate(np.array([0.0, t_hit - dt, t_hit + dt]), q0=q0, v0=[0.0, 0.0, 0.0], rtol=1e-12, atol=1e-14)
    w_minus, w_plus = near["phi_dot"][1], near["phi_dot"][2]
    assert w_minus == pytest.approx(-math.sqrt(2 * G * R * (math.cos(a - phi0) - math.cos(a)) / I0), rel=1e-7)
    assert w_plus / w_minus == pytest.approx(1 - 1.5 * math.sin(a) ** 2, rel=1e-7)


@pytest.mark.parametrize("formulation", ["index1", "ggl", "minimal"])
def test_apex_events_between_impacts(formulation):
    """A compiled event y' = 0 (decreasing, not terminal) between the impacts: apex k at
    t1 + 2 t1 e (1 - e^k) / (1 - e) + e^(k+1) t1 with height h0 e^(2k+2), to 1e-9."""
    from lagcodegen.model.events import Event

    e, h0 = 0.8, 1.0
    system = _ball_system(e)
    (y,) = system.model.coords
    sim = compile_constrained(system, formulation, events=[Event("apex", system.model.dot(y), -1, False)])
    res = sim.simulate(np.linspace(0, 3, 301), q0=[h0], v0=[0.0], rtol=1e-12, atol=1e-14)
    apexes = [ev for ev in res.events if ev.name == "apex"]
    assert len(apexes) == 6 and len(res.impacts.select("bounce")) == 6
    t1 = math.sqrt(2 * h0 / G)
    k = np.arange(6)
    t_exact = t1 + 2 * t1 * e * (1 - e**k) / (1 - e) + e ** (k + 1) * t1
    assert np.max(np.abs(np.array([ev.t for ev in apexes]) / t_exact - 1)) < 1e-9
    assert np.max(np.abs(np.array([ev.y[0] for ev in apexes]) / (h0 * e ** (2 * k + 2)) - 1)) < 1e-9


@pytest.mark.parametrize("e", [0.3, 0.8, 0.95])
def test_ggl_finds_a_flight_its_step_skipped(e):
    """At loose tolerances IDA's steps near the accumulation outgrow the last flights: a step ends
    with the ball below the floor and still falling, which the sign test of the roots cannot see.
    The GGL driver locates the crossing on IDA's interpolant (or, for a flight that began within
    the step, takes a plastic impact at its end), so the ball comes to rest on the floor held by
    m g, never deeper than the tolerance-sized depth it reports."""
    sim = compile_constrained(_ball_system(e), "ggl")
    res = sim.simulate(np.linspace(0, 60, 61), q0=[1.0], v0=[0.0], rtol=1e-2, atol=1e-3)
    assert res.stats["contact_retries"] >= 1
    assert 0 < res.stats["max_penetration"] < 1e-6
    assert res["y"].min() > -1e-6 and abs(res["y"][-1]) < 1e-9
    assert res["lambda_ineq_0"][-1] == pytest.approx(G, rel=1e-9)
    assert res.impacts.final_modes == {0: "contact"}
    t1 = math.sqrt(2 / G)
    assert res.impacts.select("stick")[-1].t == pytest.approx(t1 * (1 + e) / (1 - e), rel=0.05)
