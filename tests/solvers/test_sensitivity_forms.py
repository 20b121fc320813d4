"""The two forms of the generated sensitivity equations (lagcodegen.formulation.sensitivity): the
per-direction sweep of the right-hand side's program against the expanded dr/dy, dr/dp (the
same numbers from two differentiations), and sensitivities of a rigid-body tree (its recorded
program, parameters inside a link's mass and placement) against the same arm written in closed
form and against central differences."""

import ctypes

import numpy as np
import pytest
import sympy as sp

import lagcodegen as lcg
from lagcodegen.build import plain_library
from lagcodegen.codegen.sensitivity import sensitivity_source

from helpers import G

# A two-link arm swinging about x, centres of mass off the plane of motion and products of
# inertia (which a planar swing must not feel); the second link's mass and the first link's
# length are run-time parameters.
L1, M1, M2 = 0.8, 1.3, 0.9
C1, C2 = (0.05, 0.0, -0.4), (-0.03, 0.0, -0.3)
I1, I2 = (0.07, 0.05, 0.02, 0.004, -0.003, 0.001), (0.03, 0.025, 0.01, -0.002, 0.001, 0.002)
Q0, V0 = [0.9, -0.4], [0.3, -1.2]
DIRECTIONS = ["g", "m2", "l1", "a(0)", "b_dot(0)"]


def arm_tree(name):
    m = lcg.Model(name)
    g, m2, l1 = m.parameters(g=G, m2=M2, l1=L1)
    m.gravity(g)
    m.link("l1", joint=lcg.Joint.revolute("a", (1, 0, 0)), mass=M1, com=C1, inertia=I1)
    m.link("l2", parent="l1", joint=lcg.Joint.revolute("b", (1, 0, 0)), origin=lcg.Placement((0, 0, -l1)),
           mass=m2, com=C2, inertia=I2)
    return m


def arm_closed(name):
    """The same arm in closed form: angles a and a + b from the downward vertical in the y-z
    plane; T of each link = 1/2 m |v_G|^2 + 1/2 Ixx(G) w^2, V = g sum m z_G."""
    m = lcg.Model(name)
    a, b = m.coordinates("a b")
    g, m2, l1 = m.parameters(g=G, m2=M2, l1=L1)
    ad, bd = m.dot(a), m.dot(b)
    r1, r2 = -C1[2], -C2[2]
    y1, z1 = r1 * sp.sin(a), -r1 * sp.cos(a)
    y2, z2 = l1 * sp.sin(a) + r2 * sp.sin(a + b), -l1 * sp.cos(a) - r2 * sp.cos(a + b)
    v1 = (sp.diff(y1, a) * ad) ** 2 + (sp.diff(z1, a) * ad) ** 2
    v2 = (sp.diff(y2, a) * ad + sp.diff(y2, b) * bd) ** 2 + (sp.diff(z2, a) * ad + sp.diff(z2, b) * bd) ** 2
    m.kinetic_energy(M1 * v1 / 2 + I1[0] * ad ** 2 / 2 + m2 * v2 / 2 + I2[0] * (ad + bd) ** 2 / 2)
    m.potential_energy(g * (M1 * z1 + m2 * z2))
    return m


@pytest.fixture(scope="module")
def tree():
    sim = lcg.compile_model(arm_tree("sens_arm_tree"), outputs=["energy"], jacobian=False)
    assert lcg.derive(arm_tree("check")).tree is not None
    return sim


def test_tree_sensitivities_match_the_closed_form_and_central_differences(tree):
    """d(a, b, a', b')/d(g, m2, l1, a(0), b'(0)) of the tree (rtol 1e-8) against the closed-form
    arm's (a different derivation: Lagrange's equations of T and V written out) and, for the
    parameters inside the links and an initial velocity, against the fourth-order central
    differences of rtol 1e-13 runs of the tree: 1e-6 relative. Both models without a Jacobian
    (the driver's Newton matrix by differences)."""
    t = np.linspace(0.0, 4.0, 41)
    closed = lcg.compile_model(arm_closed("sens_arm_closed"), outputs=["energy"], jacobian=False)
    res = tree.simulate(t, q0=Q0, v0=V0, rtol=1e-8, atol=1e-10, sensitivities=DIRECTIONS)
    ref = closed.simulate(t, q0=Q0, v0=V0, rtol=1e-8, atol=1e-10, sensitivities=DIRECTIONS)
    for j, name in enumerate(DIRECTIONS):
        got, want = res.sensitivities[:, j, :], ref.sensitivities[:, j, :]
        assert np.max(np.abs(got - want)) < 1e-6 * np.max(np.abs(want)), name
        assert np.max(np.abs(got[:, :4])) > 1e-2, name  # the direction moves the arm
    h = 1e-4
    params = {"g": G, "m2": M2, "l1": L1}
    for j, name in enumerate(DIRECTIONS):
        if name in ("g", "a(0)"):  # as the others, checked against the closed form above
            continue
        runs = {}
        for sign in (2, 1, -1, -2):
            q0, v0, p = np.array(Q0), np.array(V0), dict(params)
            if name == "a(0)":
                step = h
                q0[0] += sign * step
            elif name == "b_dot(0)":
                step = h
                v0[1] += sign * step
            else:
                step = h * params[name]
                p[name] += sign * step
            r = tree.simulate(t, q0=q0, v0=v0, params=p, rtol=1e-13, atol=1e-15)
            runs[sign] = np.column_stack([r.y, r["energy"]])
        fd = (8 * (runs[1] - runs[-1]) - (runs[2] - runs[-2])) / (12 * step)
        assert np.max(np.abs(res.sensitivities[:, j, :] - fd)) < 1e-6 * np.max(np.abs(fd)), name


def _sens_rhs(scene, form, t, y, p, which, s):
    prefix = f"{scene.prefix}_{form}"
    library = plain_library("sensitivity functions", prefix, sensitivity_source(scene, prefix, form=form))[0]
    fn = getattr(library, f"{prefix}_sens_rhs")
    D, I = ctypes.POINTER(ctypes.c_double), ctypes.POINTER(ctypes.c_int)
    fn.argtypes = [ctypes.c_double, D, D, ctypes.c_int, I, D, D, D]
    ydot, sdot = np.zeros(y.size), np.zeros(s.size)
    which = np.asarray(which, dtype=np.intc)
    rc = fn(t, y.ctypes.data_as(D), p.ctypes.data_as(D), len(which), which.ctypes.data_as(I), s.ctypes.data_as(D),
            ydot.ctypes.data_as(D), sdot.ctypes.data_as(D))
    assert rc == 0
    return ydot, sdot


@pytest.mark.parametrize("model", [
    lcg.systems.double_pendulum(),
    lcg.systems.n_link_pendulum(3, name="sens_forms_chain3", shared_parameters=False),
    "kepler_routh",
])
def test_direction_form_agrees_with_the_expanded_form(model):
    """sens_rhs of both forms at random states, parameters and seeds (every parameter direction
    and two initial-value directions): the same right-hand side and sensitivity rates to 1e-12
    relative. The reduced Kepler problem has a quadrature state (phi' = C/(m r^2)) and C_phi as a
    run-time parameter."""
    if model == "kepler_routh":
        from lagcodegen.theory.routhian import reduce as routh_reduce
        red = routh_reduce(lcg.systems.central_potential())
        scene = lcg.Scene(red.eom, jacobian=False, outputs=["phi_dot"], prefix="sens_forms_kepler")
        assert red.eom.quadratures and "C_phi" in scene.runtime_parameters
    else:
        scene = lcg.Scene(lcg.derive(model), jacobian=False)
    eom = scene.eom
    n, nz, npar = eom.model.n, len(eom.quadratures), len(scene.runtime_parameters)
    ny = 2 * n + nz
    rng = np.random.default_rng(7)
    which = list(range(npar)) + [-1, -1]
    for _ in range(3):
        y = rng.uniform(-1.0, 1.0, ny)
        y[:n] += 1.5  # away from r = 0 for Kepler
        p = rng.uniform(0.5, 1.5, max(npar, 1))
        s = rng.uniform(-1.0, 1.0, len(which) * ny)
        yd_e, sd_e = _sens_rhs(scene, "expanded", 0.3, y, p, which, s)
        yd_d, sd_d = _sens_rhs(scene, "direction", 0.3, y, p, which, s)
        assert np.max(np.abs(yd_d - yd_e)) <= 1e-12 * np.max(np.abs(yd_e))
        assert np.max(np.abs(sd_d - sd_e)) <= 1e-12 * np.max(np.abs(sd_e))
        if nz:  # the quadrature's sensitivity rate is exercised
            assert np.max(np.abs(sd_e.reshape(len(which), ny)[:, 2 * n:])) > 1e-3
