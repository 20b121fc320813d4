"""Events: root functions from inequality constraints, user expressions and multipliers; switched
(hybrid) runs. The particle sliding off a sphere leaves it where cos(theta) = 2/3 (for a start at
the top with speed v0: cos(theta) = (2 + v0^2/(g R))/3), then flies on a parabola."""

import numpy as np
import pytest
import sympy as sp
from scipy.special import ellipk

import lagcodegen as lcg
from lagcodegen import ModelError
from lagcodegen.theory.constraints import ConstrainedSystem
from lagcodegen.api import compile_constrained
from lagcodegen.model.events import Event, event_list
from lagcodegen.simulation.hybrid import simulate_with_switch

G = 9.81
V0 = 1e-3  # initial speed at the top of the sphere


def particle(name):
    m = lcg.Model(name)
    x, y = m.coordinates("x y")
    R, g, mass = m.parameters(R=1.0, g=G, m=1.0)
    m.particle("p", mass, (x, y))
    m.gravity(g)
    return m


def on_sphere(name="sphere"):
    """Particle on a sphere (circle) x^2 + y^2 = R^2; A = (2x, 2y) points outwards, so the normal
    force lambda A pushes the particle off the surface while lambda > 0."""
    m = particle(name)
    x, y = m.coords
    R = sp.Symbol("R")
    return ConstrainedSystem(m, holonomic=[x ** 2 + y ** 2 - R ** 2])


@pytest.fixture(scope="module")
def sphere():
    cs = on_sphere()
    leave = Event("leave", cs.multipliers[0], direction=-1, terminal=True)
    out = ["energy", "lambda", "residuals"]
    return {"index1": compile_constrained(cs, "index1", events=[leave], outputs=out),
            "ggl": compile_constrained(cs, "ggl", events=[leave], outputs=out),
            "free": lcg.compile_model(particle("free"), outputs=["energy"])}


@pytest.mark.parametrize("formulation,backend", [("index1", "native"), ("ggl", "native"), ("index1", "sksundae"),
                                                 ("ggl", "sksundae")])
def test_particle_leaves_the_sphere_at_cos_two_thirds_then_flies_freely(sphere, formulation, backend):
    t = np.linspace(0, 3.2, 321)
    hr = simulate_with_switch(sphere[formulation], sphere["free"], t, q0=[0, 1], v0=[V0, 0], rtol=1e-11,
                              atol=1e-13, backend=backend)
    rec = hr.switch
    assert rec is not None and rec.name == "leave" and rec.direction == -1
    cos_leave = rec.q["y"] / 1.0
    assert abs(cos_leave - (2 + V0 ** 2 / G) / 3) < 1e-6
    assert abs(cos_leave - 2 / 3) < 1e-6
    first, free = hr.phases
    assert first.t[-1] == rec.t and abs(first["lambda_0"][-1]) < 1e-8  # normal force zero there
    assert np.all(first["lambda_0"][:-1] > 0)
    # speed at the event: v^2 = v0^2 + 2 g R (1 - cos theta) (energy, eq. 3.5)
    v2 = rec.v["x"] ** 2 + rec.v["y"] ** 2
    assert abs(v2 - (V0 ** 2 + 2 * G * (1 - cos_leave))) < 1e-8
    # free flight: a parabola from the event state
    tau = free.t - rec.t
    assert free.t[0] == rec.t and free.t[-1] == t[-1]
    assert np.max(np.abs(free["x"] - (rec.q["x"] + rec.v["x"] * tau))) < 1e-9
    assert np.max(np.abs(free["y"] - (rec.q["y"] + rec.v["y"] * tau - G / 2 * tau ** 2))) < 1e-9
    # the joined table: every time once, energy conserved across the switch
    assert np.all(np.diff(hr.t) > 0) and hr.t.size == hr["x"].size
    assert np.max(np.abs(hr["energy"] - hr["energy"][0])) < 1e-7


def test_without_the_event_the_constraint_pulls_the_particle_around(sphere):
    """With root finding off the bilateral constraint holds it: lambda changes sign (the event is real)."""
    res = sphere["index1"].simulate(np.linspace(0, 3.2, 321), q0=[0, 1], v0=[V0, 0], rtol=1e-10, atol=1e-12,
                                    events=False)
    assert not res.events and res.t[-1] == 3.2 and np.min(res["lambda_0"]) < 0


def test_non_terminal_events_count_pendulum_crossings():
    """x crosses 0 upwards at 3T/4 + k T with T = 4 K(sin(theta0/2)) sqrt(l/g)."""
    m = particle("pend")
    x, y = m.coords
    R = sp.Symbol("R")
    cs = ConstrainedSystem(m, holonomic=[x ** 2 + y ** 2 - R ** 2])
    cross = Event("cross", x, direction=+1, terminal=False)
    sim = compile_constrained(cs, "index1", events=[cross, ("low", y + 0.999, -1, False)])
    th0 = 1.0
    res = sim.simulate(np.linspace(0, 10, 101), q0=[np.sin(th0), -np.cos(th0)], v0=[0, 0], rtol=1e-11,
                       atol=1e-13)
    period = 4 * ellipk(np.sin(th0 / 2) ** 2) * np.sqrt(1.0 / G)
    times = [e.t for e in res.events if e.name == "cross"]
    expected = [0.75 * period + k * period for k in range(10) if 0.75 * period + k * period < 10]
    assert len(times) == len(expected) and np.allclose(times, expected, atol=1e-8)
    assert all(e.direction == 1 for e in res.events if e.name == "cross")
    assert res.t[-1] == 10  # non-terminal: the run goes on
    assert all(e.name in ("cross", "low") for e in res.events)


def test_inequality_constraint_becomes_a_terminal_event():
    m = particle("bead")
    x, y = m.coords
    R = sp.Symbol("R")
    # on the circle, but a wall at x = 0.5 (x <= 0.5, i.e. 0.5 - x >= 0)
    cs = ConstrainedSystem(m, holonomic=[x ** 2 + y ** 2 - R ** 2], inequalities=[sp.Rational(1, 2) - x])
    assert [e.name for e in event_list(cs)] == ["ineq_0"]
    sim = compile_constrained(cs, "ggl")
    res = sim.simulate(np.linspace(0, 2, 201), q0=[0, -1], v0=[3, 0], rtol=1e-10, atol=1e-12)
    ev = res.events[-1]
    assert ev.name == "ineq_0" and ev.terminal and abs(ev.q["x"] - 0.5) < 1e-9
    # reached from the bottom with v^2 = 9 - 2 g (y + 1)
    assert abs(ev.v["x"] ** 2 + ev.v["y"] ** 2 - (9 - 2 * G * (ev.q["y"] + 1))) < 1e-7
    assert res.t[-1] == ev.t


def test_event_input_errors():
    cs = on_sphere("bad")
    with pytest.raises(ModelError, match=r"event 'e' uses unknown symbol\(s\): lambda_1 \(multipliers: lambda_0\)"):
        event_list(cs, [Event("e", sp.Symbol("lambda_1"))])
    with pytest.raises(ModelError, match="direction must be -1, 0 or \\+1"):
        Event("e", 1, direction=2)
    with pytest.raises(ModelError, match="used twice"):
        event_list(cs, [("a", cs.model.coords[0]), ("a", cs.model.coords[1])])
    with pytest.raises(ModelError, match="must be an identifier"):
        Event("not a name", 1)
