"""Independent speeds (Maggi, Voronets, Kane): nonholonomic systems reduced to ODEs in (q, u),
checked against analytic solutions and against the index-1 form."""

import numpy as np
import pytest
import sympy as sp

import lagcodegen as lcg
from lagcodegen.errors import ModelError
from lagcodegen.theory.speeds import choose_independent, independent_speeds_model


def knife_edge():
    """A knife edge (skate) on a horizontal plane: x, y of its contact point, heading theta; the
    contact cannot slide sideways, x' sin(theta) - y' cos(theta) = 0."""
    m = lcg.Model("skate")
    x, y, th = m.coordinates("x y theta")
    mass, inertia = m.parameters(m=2.0, J=0.3)
    m.kinetic_energy(mass / 2 * (m.dot(x) ** 2 + m.dot(y) ** 2) + inertia / 2 * m.dot(th) ** 2)
    return lcg.ConstrainedSystem(m, nonholonomic=[(sp.sin(th), -sp.cos(th), 0)]), m


def test_knife_edge_in_independent_speeds_follows_its_circle():
    """theta' = w and the speed along the blade V stay constant: the contact point runs on a circle
    of radius V/w, x = (V/w) sin(w t), y = (V/w)(1 - cos(w t)) from the origin heading along x.
    With y' eliminated (y' = x' tan(theta)) the choice is singular at theta = pi/2: the run stays
    below (theta up to 1.4)."""
    system, _ = knife_edge()
    sim = lcg.compile_constrained(system, "minimal", eliminate=["y"])
    V, w = 1.5, 0.7
    t = np.linspace(0, 2, 81)
    res = sim.simulate(t, q0=[0, 0, 0], v0=[V, 0, w], rtol=1e-12, atol=1e-13)
    assert res.state_names == ["x", "y", "theta", "x_dot", "theta_dot"]
    cm = sim.compiled(sim.choose([0, 0, 0]), [0, 0, 0])
    assert (cm.nq, cm.nv) == (3, 2)
    assert np.abs(res["x"] - V / w * np.sin(w * t)).max() < 1e-9
    assert np.abs(res["y"] - V / w * (1 - np.cos(w * t))).max() < 1e-9
    assert np.abs(res["theta"] - w * t).max() < 1e-10


def test_the_speeds_follow_the_index1_form():
    """The same system on index-1 CVODE (multipliers, projection) and in independent speeds chosen
    by pivoting, from a general state: both on the analytic circle (theta = theta0 + w t, the
    blade's speed V constant), the speeds' run to 1e-10, the index-1 run to 1e-7, and the two
    within 1e-7."""
    system, _ = knife_edge()
    a = lcg.compile_constrained(system, "minimal")
    b = lcg.compile_constrained(system, "index1")
    q0, v0 = np.array([0.2, -0.1, 0.4]), [1.2 * np.cos(0.4), 1.2 * np.sin(0.4), -0.5]
    t = np.linspace(0, 2, 51)  # theta from 0.4 to -0.6: y' = x' tan(theta), chosen by pivoting at q0, is regular
    assert a.choose(q0) == [0, 2]
    ra = a.simulate(t, q0=q0, v0=v0, rtol=1e-11, atol=1e-12)
    rb = b.simulate(t, q0=q0, v0=v0, rtol=1e-11, atol=1e-12)
    V, w, th = 1.2, -0.5, 0.4 - 0.5 * t
    exact = np.column_stack([0.2 + V / w * (np.sin(th) - np.sin(0.4)), -0.1 - V / w * (np.cos(th) - np.cos(0.4)), th])
    assert np.abs(ra.y[:, :3] - exact).max() < 1e-10
    assert np.abs(rb.y[:, :3] - exact).max() < 1e-7
    assert np.abs(ra.y[:, :3] - rb.y[:, :3]).max() < 1e-7


def test_independent_speeds_are_checked_by_name():
    system, _ = knife_edge()
    with pytest.raises(ModelError, match="2 given, but 3 coordinates and 1 constraints leave 2|1 given"):
        independent_speeds_model(system, independent=["x"])
    # x and y together are never both dependent-free when theta is: A_dep = [sin, -cos] for (x, y) is fine,
    # but eliminating theta alone leaves A_dep = 0
    with pytest.raises(ModelError, match="cannot be solved for the rates of theta"):
        independent_speeds_model(system, independent=["x", "y"])
    ind, dep = choose_independent(system)
    assert len(ind) == 2 and len(dep) == 1 and dep[0] in (0, 1)


def test_rates_off_the_constraint_are_refused_by_name():
    system, _ = knife_edge()
    sim = lcg.compile_constrained(system, "minimal")
    with pytest.raises(ModelError, match="v0 does not satisfy the velocity constraints: row 0"):
        sim.simulate([0, 1], q0=[0, 0, 0], v0=[0, 1, 0])


def test_whipple_bicycle_in_independent_speeds_follows_the_index1_run():
    """The Whipple bicycle (Meijaard et al. 2007; 8 coordinates, 1 holonomic and 4 nonholonomic
    constraints) at 5 m/s with a lean-rate kick: the ODE in 3 independent speeds (lean, steer and
    rear-wheel rates, chosen by pivoting at the upright state) and the index-1 run agree to 1e-8
    over 5 s; the holonomic constraint, held through its rate only, drifts below 1e-9."""
    from helpers import whipple_bicycle, whipple_straight_run
    bike = whipple_bicycle()
    speeds = lcg.compile_constrained(bike, "minimal")
    index1 = lcg.compile_constrained(bike, "index1")
    q0, v0 = whipple_straight_run(5.0)
    ind = speeds.choose(q0)
    assert [bike.model.coords[i].name for i in ind] == ["phi", "delta", "thR"]
    A = speeds._matrix(speeds._A, q0, 0.0, None)
    A0 = speeds._matrix(speeds._A0, q0, 0.0, None).ravel()
    v = np.array(v0, dtype=float)
    v[3] = 0.5  # the lean rate; the dependent rates from the constraints
    dep = [i for i in range(8) if i not in ind]
    v[dep] = np.linalg.solve(A[:, dep], -(A[:, ind] @ v[ind] + A0))
    t = np.linspace(0, 5, 51)
    a = speeds.simulate(t, q0=q0, v0=v, rtol=1e-11, atol=1e-12)
    b = index1.simulate(t, q0=q0, v0=v, rtol=1e-11, atol=1e-12)
    assert a.state_names[8:] == ["phi_dot", "delta_dot", "thR_dot"]
    assert np.ptp(a["phi"]) > 0.05  # it really leans and weaves
    assert np.abs(a.y[:, :8] - b.y[:, :8]).max() < 1e-8
    assert np.abs(a["g_0"]).max() < 1e-9
