"""Forward sensitivities of constrained systems (lagcodegen.solvers.cvode.sensitivity_constrained,
index-1 on CVODE; minimal coordinates through the ODE's): against fourth-order central
differences of simulate() at optimal steps, and against the same pendulum written as an
unconstrained ODE in its angle (d theta/d l, d theta/d g and the multiplier's sensitivities
mapped from the Cartesian ones)."""

import subprocess

import numpy as np
import pytest
import sympy as sp

import lagcodegen as lcg
from lagcodegen.codegen.sensitivity_constrained import constrained_sensitivity_source
from lagcodegen.errors import LagcodegenError

from helpers import STRICT_CFLAGS, atwood, cartesian_pendulum, knife_edge, mixed_system, pendulum_q0

TH0 = 1.0
NAMES = ["l", "g", "m", "x(0)", "x_dot(0)", "y_dot(0)"]


@pytest.fixture(scope="module")
def cart():
    return lcg.compile_constrained(cartesian_pendulum("sens_cpend"), "index1")


@pytest.fixture(scope="module")
def theta_pendulum():
    return lcg.compile_model(lcg.systems.pendulum("sens_tpend"))


def _central(sim, t, q0, v0, name, h=2e-4, **options):
    """Fourth-order central differences (8 (f(h) - f(-h)) - (f(2h) - f(-2h))) / 12h of every state
    and output of rtol 1e-13 runs, the perturbed initial states projected onto the constraints
    (initial="project", as the sensitivities' initial values are)."""
    base = dict(zip(sim.param_names, sim.parameter_vector(None)))
    coords = sim.state_names[:sim.n]
    runs = {}
    for sign in (2, 1, -1, -2):
        q, v, p = np.array(q0, float), np.array(v0, float), dict(base)
        if name.endswith("_dot(0)"):
            i = coords.index(name[:-7])
            step = h * max(1.0, abs(v[i]))
            v[i] += sign * step
        elif name.endswith("(0)"):
            i = coords.index(name[:-3])
            step = h * max(1.0, abs(q[i]))
            q[i] += sign * step
        else:
            step = h * abs(p[name])
            p[name] += sign * step
        r = sim.simulate(t, q0=q, v0=v, params=p, rtol=1e-13, atol=1e-15, initial="project", events=False,
                         **options)
        runs[sign] = np.column_stack([r.y] + [r.outputs[o] for o in sim.output_names])
    return (8 * (runs[1] - runs[-1]) - (runs[2] - runs[-2])) / (12 * step)


def _check_central(sim, res, t, q0, v0, tol=1e-6, **options):
    """Every direction of ``res`` against central differences: relative ``tol`` per state and
    output, relative to the largest sensitivity of the states (at least 0.1: the differences'
    noise, some 1e-8, stays below 1e-6 of it) where a column is identically zero (quantities the
    direction does not move). The constraint residuals'
    sensitivities (g_<j>, gdot_<j>: zero on the constraints, the differences of drift at the
    level of the runs' rounding) below 1e-6 of that scale."""
    values = res.sensitivity_values
    resid = np.array([v.startswith(("g_", "gdot_")) for v in values])
    for j, name in enumerate(res.sensitivity_names):
        ref = _central(sim, t, q0, v0, name, **options)
        got = res.sensitivities[:, j, :]
        floor = max(np.max(np.abs(ref[:, :2 * sim.n])), 0.1)
        err = np.max(np.abs(got - ref), axis=0) / np.maximum(np.max(np.abs(ref), axis=0), floor)
        assert np.all(err[~resid] < tol), (name, dict(zip(values, err)))
        assert np.all(np.max(np.abs(got[:, resid]), axis=0) < 1e-6 * floor), (name, dict(zip(values, err)))


def test_cartesian_pendulum_against_central_differences(cart):
    """x^2 + y^2 = l^2 (eq. 4.1): the states, the energy and the multiplier lambda_0 in six
    directions (three parameters, a position and two velocities, which leave the constraint and
    are projected back) relative 1e-6 at rtol 1e-8; the constraint residuals' sensitivities stay
    at the level of the drift."""
    t = np.linspace(0.0, 3.0, 31)
    q0, v0 = pendulum_q0(TH0), [0.0, 0.0]
    res = cart.simulate(t, q0=q0, v0=v0, rtol=1e-8, atol=1e-10, sensitivities=NAMES)
    assert res.sensitivity_values == ["x", "y", "x_dot", "y_dot", "energy", "lambda_0", "g_0", "gdot_0"]
    assert res.sensitivities.shape == (t.size, len(NAMES), 8)
    _check_central(cart, res, t, q0, v0)
    # the trajectory is the plain run's
    plain = cart.simulate(t, q0=q0, v0=v0, rtol=1e-8, atol=1e-10)
    assert np.max(np.abs(res.y - plain.y)) < 1e-6
    assert res.stats["alpha"] == plain.stats["alpha"] > 0


def test_projection_after_each_step(cart):
    """projection=True (BDF, no Baumgarte): each sensitivity block projected with the state
    (the projection linearized at the projected state): against central differences of runs
    with projection, relative 1e-6 at rtol 1e-8 (the energy's, zero in the velocity directions
    from rest, 2e-6 of the states' scale: BDF conserves it less well than the Adams runs), and
    within 1e-6 of the Baumgarte-stabilized run's sensitivities."""
    t = np.linspace(0.0, 3.0, 31)
    q0, v0 = pendulum_q0(TH0), [0.0, 0.0]
    names = ["l", "x(0)", "y_dot(0)"]
    res = cart.simulate(t, q0=q0, v0=v0, rtol=1e-8, atol=1e-10, sensitivities=names, projection=True)
    assert res.stats["projection"] and res.method == "bdf" and res.stats["alpha"] == 0.0
    _check_central(cart, res, t, q0, v0, tol=2e-6, projection=True)
    stab = cart.simulate(t, q0=q0, v0=v0, rtol=1e-8, atol=1e-10, sensitivities=names)
    scale = np.max(np.abs(stab.sensitivities[:, :, :4]))
    assert np.max(np.abs(res.sensitivities[:, :, :4] - stab.sensitivities[:, :, :4])) < 1e-6 * scale


def test_cartesian_pendulum_against_the_angle_pendulum(cart, theta_pendulum):
    """The same pendulum as an ODE in theta = atan2(x, -y): d theta/d(l, g) from the Cartesian
    sensitivities (d theta = (x dy - y dx)/l^2) match the angle model's own, relative 1e-6 at rtol
    1e-8; the multiplier lambda_0 = -T/(2l), T = m (g cos theta + l theta'^2) the rod tension, has
    d lambda_0/d(l, g) of the angle model's sensitivities through that formula; and the direction
    x(0), projected onto the circle, moves theta(0) by -y0/l^2 = cos(theta0): the angle model's
    theta(0) direction scaled by it."""
    t = np.linspace(0.0, 3.0, 31)
    l, g, m = 1.0, 9.81, 1.0
    res = cart.simulate(t, q0=pendulum_q0(TH0), rtol=1e-8, atol=1e-10, sensitivities=["l", "g", "x(0)"])
    ref = theta_pendulum.simulate(t, q0=[TH0], rtol=1e-11, atol=1e-13, sensitivities=["l", "g", "theta(0)"])
    x, y = res["x"], res["y"]
    th, w = ref["theta"], ref["theta_dot"]
    for cart_dir, ang_dir, factor in (("l", "l", 1.0), ("g", "g", 1.0), ("x(0)", "theta(0)", np.cos(TH0))):
        dth = (x * res.sensitivity("y", cart_dir) - y * res.sensitivity("x", cart_dir)) / l ** 2
        want = factor * ref.sensitivity("theta", ang_dir)
        assert np.max(np.abs(dth - want)) < 1e-6 * np.max(np.abs(want)), cart_dir
        # lambda = -m (g cos(th) + l w^2) / (2 l)
        dlam = -m * (-g * np.sin(th) * ref.sensitivity("theta", ang_dir)
                     + 2 * l * w * ref.sensitivity("theta_dot", ang_dir)) / (2 * l) * factor
        if ang_dir == "l":
            dlam = dlam + m * g * np.cos(th) / (2 * l ** 2)  # explicit: d/dl of -m g cos/(2l) - m w^2/2
        if ang_dir == "g":
            dlam = dlam - m * np.cos(th) / (2 * l)
        got = res.sensitivity("lambda_0", cart_dir)
        assert np.max(np.abs(got - dlam)) < 1e-6 * np.max(np.abs(dlam)), cart_dir
    lam = -m * (g * np.cos(th) + l * w ** 2) / (2 * l)
    assert np.max(np.abs(res["lambda_0"] - lam)) < 1e-6 * np.max(np.abs(lam))


def test_nonholonomic_and_time_dependent_rows_against_central_differences():
    """The knife edge (a nonholonomic row, Baumgarte s' + alpha s = 0) and the Atwood machine (a
    parameter L in the holonomic row moves the initial state with the constraint)."""
    t = np.linspace(0.0, 2.0, 21)
    knife = lcg.compile_constrained(knife_edge("sens_knife"), "index1")
    q0, v0 = [0.0, 0.0, 0.3], [np.cos(0.3), np.sin(0.3), 0.5]
    res = knife.simulate(t, q0=q0, v0=v0, rtol=1e-8, atol=1e-10, sensitivities=["alpha", "g", "theta(0)",
                                                                                   "theta_dot(0)", "x_dot(0)"])
    _check_central(knife, res, t, q0, v0)
    machine = lcg.compile_constrained(atwood("sens_atwood"), "index1")
    q0, v0 = [0.5, 1.5], [0.1, -0.1]
    res = machine.simulate(t, q0=q0, v0=v0, rtol=1e-8, atol=1e-10, sensitivities=["m1", "L", "x1(0)", "x1_dot(0)"])
    _check_central(machine, res, t, q0, v0)
    # L moves x2 one for one (x1 + x2 = L, projected at the start); x1(0) splits between both
    assert np.allclose(res.sensitivity("x2", "L"), 1.0 - res.sensitivity("x1", "L"), atol=1e-9)
    assert res.sensitivity("x1", "x1(0)")[0] == pytest.approx(0.5)


def test_minimal_coordinates(cart):
    """The Cartesian pendulum in minimal coordinates (y eliminated, y = -sqrt(l^2 - x^2)): the
    ODE's sensitivities of the branch; d x/d g is the index-1 form's (the same start); the
    eliminated y has its sensitivities as an output (d y/d g from d x/d g: y dy = -x dx); x(0)
    moves x only (y follows it), the index-1 form's projected direction scaled by l^2/y0^2;
    the eliminated coordinate's initial value is refused by name."""
    sim = lcg.compile_constrained(cartesian_pendulum("sens_cpend_min"), "minimal")
    t = np.linspace(0.0, 2.0, 21)
    q0 = pendulum_q0(0.6)
    res = sim.simulate(t, q0=q0, rtol=1e-8, atol=1e-10, sensitivities=["g", "x(0)"])
    idx = cart.simulate(t, q0=q0, rtol=1e-8, atol=1e-10, sensitivities=["g", "x(0)"])
    for d, scale in (("g", 1.0), ("x(0)", 1.0 / q0[1] ** 2)):
        want = idx.sensitivity("x", d) * scale
        assert np.max(np.abs(res.sensitivity("x", d) - want)) < 1e-6 * np.max(np.abs(want)), d
        dy = -res["x"] * res.sensitivity("x", d) / res["y"]
        assert np.max(np.abs(res.sensitivity("y", d) - dy)) < 1e-7 * np.max(np.abs(dy)), d
    with pytest.raises(LagcodegenError, match="'y\\(0\\)': y is eliminated in minimal coordinates"):
        sim.simulate(t, q0=q0, sensitivities=["y(0)"])
    with pytest.raises(LagcodegenError, match="y is eliminated"):
        sim.simulate(t, q0=q0, sensitivities=["g", "y_dot(0)"])


def test_refusals_are_named(cart):
    t = np.linspace(0.0, 1.0, 5)
    q0 = pendulum_q0(TH0)
    with pytest.raises(LagcodegenError, match="'L' is neither a run-time parameter"):
        cart.simulate(t, q0=q0, sensitivities=["L"])
    with pytest.raises(LagcodegenError, match="'z\\(0\\)' names no initial value"):
        cart.simulate(t, q0=q0, sensitivities=["z(0)"])
    with pytest.raises(LagcodegenError, match="given twice"):
        cart.simulate(t, q0=q0, sensitivities=["l", "l"])
    with pytest.raises(LagcodegenError, match="ensembles do not compute sensitivities"):
        cart.ensemble(t, q0=np.tile(q0, (2, 1)), sensitivities=["l"])
    with pytest.raises(LagcodegenError, match="integrator object does not compute sensitivities"):
        cart.integrator(q0=q0, sensitivities=["l"])
    with pytest.raises(LagcodegenError, match="sensitivities need backend='native'"):
        cart.simulate(t, q0=q0, sensitivities=["l"], backend="sksundae")
    folded = lcg.compile_constrained(cartesian_pendulum("sens_cpend_folded"), "index1", runtime_parameters=["g"])
    with pytest.raises(LagcodegenError, match="'l' is folded into the code"):
        folded.simulate(t, q0=q0, sensitivities=["l"])
    ggl = lcg.compile_constrained(cartesian_pendulum("sens_cpend_ggl"), "ggl")
    with pytest.raises(LagcodegenError, match="not for GGL on IDA"):
        ggl.simulate(t, q0=q0, sensitivities=["l"])


def test_events_are_refused():
    sim = lcg.compile_constrained(mixed_system(), "index1")
    y = sim.project(0.0, [0.4, 0.0, 0.3, 1.0, 0.0, 0.5])
    with pytest.raises(LagcodegenError, match="sensitivities with events"):
        sim.simulate([0.0, 1.0], q0=y[:3], v0=y[3:], sensitivities=["g"])
    res = sim.simulate(np.linspace(0.0, 1.0, 11), q0=y[:3], v0=y[3:], sensitivities=["theta_dot(0)"], events=False)
    # theta'' = 0 (no force on theta, no constraint row in it): theta moves by t per unit theta'(0)
    assert np.allclose(res.sensitivity("theta", "theta_dot(0)"), res.t, atol=1e-9)


def test_fit_of_a_constrained_pendulum(cart):
    """lagcodegen.fit on the index-1 form: l and g of the Cartesian pendulum from 150 noisy
    samples of x and y (noise 0.002, seeded), the start projected onto each trial's circle; both
    within 3 standard errors; and in minimal coordinates g alone from x."""
    t = np.linspace(0.0, 4.0, 150)
    true = {"l": 1.2, "g": 9.5}
    q0 = pendulum_q0(TH0, 1.2)
    ref = cart.simulate(t, q0=q0, params=true, rtol=1e-11, atol=1e-13)
    rng = np.random.default_rng(11)
    noise = 0.002
    data = np.column_stack([ref["x"], ref["y"]]) + noise * rng.standard_normal((t.size, 2))
    f = lcg.fit(cart, t, data, params={"l": 1.0, "g": 9.81}, observe=["x", "y"], q0=pendulum_q0(TH0), sigma=noise)
    assert f.success and f.iterations <= 20
    for name, value in true.items():
        assert abs(f.params[name] - value) < 3 * f.stderr[name], (name, f.params[name], f.stderr[name])
    assert 0.7 < f.residual_variance < 1.3
    sim = lcg.compile_constrained(cartesian_pendulum("sens_cpend_min2"), "minimal", values={"l": 1.2})
    g = lcg.fit(sim, t, data[:, :1], params={"g": 9.0}, observe=["x"], q0=q0, sigma=noise)
    assert abs(g.params["g"] - 9.5) < 3 * g.stderr["g"]


def test_cli_fit_of_a_constrained_model_file(tmp_path):
    """lagcodegen fit on examples/cartesian_pendulum.toml (index-1, [constraints]): g recovered
    from x measured on a pendulum with g = 9.0."""
    import os
    import sys
    from pathlib import Path
    root = Path(__file__).resolve().parents[2]
    t = np.linspace(0.0, 3.0, 61)
    ref = lcg.compile_constrained(cartesian_pendulum("sens_cpend_cli"), "index1").simulate(
        t, q0=pendulum_q0(TH0), params={"g": 9.0}, rtol=1e-11, atol=1e-13)
    x = ref["x"] + 0.002 * np.random.default_rng(3).standard_normal(t.size)
    data = tmp_path / "data.csv"
    data.write_text("t,x\n" + "\n".join(f"{float(a)!r},{float(b)!r}" for a, b in zip(t, x)) + "\n")
    proc = subprocess.run([sys.executable, "-m", "lagcodegen", "fit", str(root / "examples" / "cartesian_pendulum.toml"),
                           str(data), "--fit", "g", "--sigma", "0.002", "-o", str(tmp_path / "fit.csv"), "--plot",
                           str(tmp_path / "fit.png")], capture_output=True, text=True, cwd=tmp_path,
                          env=dict(os.environ, PYTHONPATH=str(root)), timeout=600)
    assert proc.returncode == 0, proc.stderr
    name, est, err = (tmp_path / "fit.csv").read_text().splitlines()[1].split(",")
    assert name == "g" and abs(float(est) - 9.0) < 3 * float(err) and 0 < float(err) < 0.05
    assert (tmp_path / "fit.png").read_bytes()[:4] == b"\x89PNG"


def test_generated_c_compiles_strictly(tmp_path, cc):
    """<prefix>_csens.c of holonomic, nonholonomic, mixed time-dependent rows with an inequality,
    and of a system without run-time parameters or outputs."""
    from lagcodegen.build import generated_headers
    from lagcodegen.codegen.constrained import generate_constrained
    from lagcodegen.runtime import sources as runtime_files
    cases = [(cartesian_pendulum("sc1"), {}), (knife_edge("sc2"), {}), (mixed_system(), {}),
             (atwood("sc4"), {"runtime_parameters": [], "outputs": []})]
    headers = {**runtime_files(["lcg_model.h"]), **generated_headers()}
    for name, text in headers.items():
        (tmp_path / name).write_text(text)
    for system, options in cases:
        code, info = generate_constrained(system, **options)
        for name, text in constrained_sensitivity_source(system, code.scene, info.output_names, code.prefix).items():
            (tmp_path / name).write_text(text)
            proc = subprocess.run([cc, *STRICT_CFLAGS, "-O2", "-c", name, "-o", name + ".o"], cwd=tmp_path,
                                  capture_output=True, text=True)
            assert proc.returncode == 0, proc.stderr


def test_rigid_body_tree_is_refused():
    """A constrained rigid-body tree (M and F are programs, not expressions): refused by name."""
    from lagcodegen.codegen.constrained import generate_constrained
    from lagcodegen.errors import ModelError
    from lagcodegen.theory.constraints import ConstrainedSystem
    m = lcg.Model("sens_arm")
    m.link("a", joint=lcg.Joint.revolute("s", (0, 1, 0)), mass=1, com=(0.5, 0, 0), inertia=(1, 1, 1))
    m.gravity(9.81)
    system = ConstrainedSystem(m, inequalities=[m.coords[0] + 3])
    code, info = generate_constrained(system)
    assert code.scene.eom.tree is not None
    with pytest.raises(ModelError, match="rigid-body tree"):
        constrained_sensitivity_source(system, code.scene, info.output_names, code.prefix)
