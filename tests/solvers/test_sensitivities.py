"""Forward sensitivities on CVODE (lagcodegen.solvers.cvode.sensitivity): against closed forms
(the harmonic oscillator), central differences at optimal steps, and CasADi's forward
sensitivities (CVODES) of an independently written double pendulum."""

import subprocess

import numpy as np
import pytest
import sympy as sp

import lagcodegen as lcg
from lagcodegen.codegen.sensitivity import sensitivity_source
from lagcodegen.errors import LagcodegenError, ModelError
from lagcodegen.runtime import sources as runtime_files

from helpers import STRICT_CFLAGS


def oscillator():
    m = lcg.Model("oscillator")
    x, = m.coordinates("x")
    k, mass = m.parameters(k=4.0, m=1.0)
    m.particle("body", mass, (x, 0))
    m.potential_energy(k * x ** 2 / 2)
    return m


@pytest.fixture(scope="module")
def osc():
    return lcg.compile_model(oscillator(), outputs=["energy"])


@pytest.fixture(scope="module")
def dp():
    return lcg.compile_model(lcg.systems.double_pendulum(), outputs=["energy"])


def test_harmonic_oscillator_closed_forms(osc):
    """x = x0 cos(w t) + v0 sin(w t)/w, w = sqrt(k/m): dx/dk, dx/dm, dx/dx0, dx/dv0 and the
    energy's E = (m v0^2 + k x0^2)/2 (dE/dk = x0^2/2 at every time)."""
    t = np.linspace(0.0, 10.0, 201)
    x0, v0, k, m = 0.7, 0.3, 4.0, 1.0
    res = osc.simulate(t, q0=[x0], v0=[v0], rtol=1e-10, atol=1e-12,
                       sensitivities=["k", "m", "x(0)", "x_dot(0)"])
    w = np.sqrt(k / m)
    # dx/dw = -x0 t sin(wt) + v0 (t cos(wt)/w - sin(wt)/w^2)
    dxdw = -x0 * t * np.sin(w * t) + v0 * (t * np.cos(w * t) / w - np.sin(w * t) / w ** 2)
    scale = np.max(np.abs(dxdw))
    assert np.max(np.abs(res.sensitivity("x", "k") - dxdw / (2 * np.sqrt(k * m)))) < 1e-7 * scale
    assert np.max(np.abs(res.sensitivity("x", "m") - dxdw * (-np.sqrt(k) / (2 * m ** 1.5)))) < 1e-7 * scale
    assert np.max(np.abs(res.sensitivity("x", "x(0)") - np.cos(w * t))) < 1e-8
    assert np.max(np.abs(res.sensitivity("x", "x_dot(0)") - np.sin(w * t) / w)) < 1e-8
    assert np.max(np.abs(res.sensitivity("x_dot", "x(0)") + w * np.sin(w * t))) < 1e-7
    assert np.max(np.abs(res.sensitivity("energy", "k") - x0 ** 2 / 2)) < 1e-8
    assert np.max(np.abs(res.sensitivity("energy", "x_dot(0)") - m * v0)) < 1e-8
    # the whole array: (nt, directions, states + outputs)
    assert res.sensitivities.shape == (t.size, 4, 3)
    assert res.sensitivity_names == ["k", "m", "x(0)", "x_dot(0)"]
    assert res.sensitivity_values == ["x", "x_dot", "energy"]
    # the trajectory itself is the plain run's
    plain = osc.simulate(t, q0=[x0], v0=[v0], rtol=1e-10, atol=1e-12)
    assert np.max(np.abs(res["x"] - plain["x"])) < 1e-8


def _central(sim, t, q0, v0, params, name, rtol=1e-13, atol=1e-15, h=2e-4):
    """Central differences of every state and output in the direction ``name``: the fourth-order
    stencil (8 (f(h) - f(-h)) - (f(2h) - f(-2h))) / 12h of rtol 1e-13 runs at the step h |value|
    where its truncation (~h^4) and the runs' noise (~rtol/h) meet: on the double pendulum over 3 s
    the stencil agrees with converged sensitivities to 3e-9 at h = 1e-4 .. 3e-4 (1e-6 at 3e-3, 5e-8
    at 1e-5; the second-order stencil reaches 3e-8 at best)."""
    base = dict(zip(sim.param_names, sim.parameter_vector(params)))
    runs = {}
    for sign in (2, 1, -1, -2):
        q, v, p = np.array(q0, float), np.array(v0, float), dict(base)
        if name.endswith("_dot(0)"):
            i = sim.state_names.index(name[:-7])
            step = h * max(1.0, abs(v[i]))
            v[i] += sign * step
        elif name.endswith("(0)"):
            i = sim.state_names.index(name[:-3])
            step = h * max(1.0, abs(q[i]))
            q[i] += sign * step
        else:
            step = h * abs(p[name])
            p[name] += sign * step
        r = sim.simulate(t, q0=q, v0=v, params=p, rtol=rtol, atol=atol)
        runs[sign] = np.column_stack([r.y] + [r.outputs[o] for o in sim.output_names])
    return (8 * (runs[1] - runs[-1]) - (runs[2] - runs[-2])) / (12 * step)


def test_double_pendulum_against_central_differences(dp):
    """Every direction (5 parameters, 4 initial values): the states relative 1e-6 at rtol 1e-8
    against central differences of rtol 1e-12 runs; the energy (a sum of terms some ten times its
    size) 1e-5, and its sensitivity constant in time (energy is conserved) to 2e-6."""
    t = np.linspace(0.0, 3.0, 61)
    q0, v0 = [1.0, -0.5], [0.2, 0.1]
    names = ["l1", "l2", "m1", "m2", "g", "theta1(0)", "theta2(0)", "theta1_dot(0)", "theta2_dot(0)"]
    res = dp.simulate(t, q0=q0, v0=v0, rtol=1e-8, atol=1e-10, sensitivities=names)
    for j, name in enumerate(names):
        ref = _central(dp, t, q0, v0, None, name)
        got = res.sensitivities[:, j, :]
        err = np.max(np.abs(got - ref), axis=0) / np.max(np.abs(ref), axis=0).clip(1e-300)
        assert np.all(err[:4] < 1e-6), (name, err)
        assert err[4] < 1e-5, (name, err)
        dE = res.sensitivity("energy", name)
        assert np.max(np.abs(dE - dE[0])) < 2e-6 * max(abs(dE[0]), np.max(np.abs(got[:, :4]))), name


def test_bdf_and_difference_quotient_jacobian_agree(dp):
    t = np.linspace(0.0, 2.0, 21)
    kw = dict(q0=[0.6, 0.2], rtol=1e-10, atol=1e-12, sensitivities=["l2", "theta1(0)"])
    a = dp.simulate(t, **kw)
    b = dp.simulate(t, method="bdf", **kw)
    c = dp.simulate(t, jacobian=False, **kw)
    scale = np.max(np.abs(a.sensitivities))
    assert np.max(np.abs(a.sensitivities - b.sensitivities)) < 1e-6 * scale
    assert np.max(np.abs(a.sensitivities - c.sensitivities)) < 1e-6 * scale
    assert c.stats["jac_evals"] > 0 and c.stats["block_solves"] > 0


def test_error_control_off_takes_no_more_steps(dp):
    """errcon off (CVODES's errconS false): the steps are the states' own; the sensitivities are
    still close (the tolerances here are tight), and the run takes no more steps than with it on."""
    t = np.linspace(0.0, 2.0, 21)
    kw = dict(q0=[0.6, 0.2], rtol=1e-9, atol=1e-11, sensitivities=["l1", "g"])
    on = dp.simulate(t, **kw)
    off = dp.simulate(t, sensitivity_errcon=False, **kw)
    assert off.stats["steps"] <= on.stats["steps"]
    scale = np.max(np.abs(on.sensitivities))
    assert np.max(np.abs(on.sensitivities - off.sensitivities)) < 1e-4 * scale


def test_error_test_blocks(dp):
    """CVODE's error test on the augmented vector is ||e_y||^2 + sum_k ||e_(s_k)||^2 <= 1 in the
    blocks' own norms (lcg_cvsens.c, sens_ewt): without error control on the sensitivities, the
    states' test of the plain run (about its steps: 604 against 639 here; a WRMS norm spread over
    all 8 blocks took 520), and with it the states and each direction within the tolerance (the
    states no less accurate than the plain run's)."""
    t = np.linspace(0.0, 10.0, 11)
    names = list(dp.param_names) + ["theta1(0)", "theta2(0)"]
    kw = dict(q0=[0.5, 0.5], rtol=1e-8, atol=1e-10)
    ref = dp.simulate(t, q0=[0.5, 0.5], rtol=1e-12, atol=1e-14)
    plain = dp.simulate(t, **kw)
    off = dp.simulate(t, sensitivities=names, sensitivity_errcon=False, **kw)
    on = dp.simulate(t, sensitivities=names, **kw)
    assert 0.9 * plain.stats["steps"] <= off.stats["steps"] < on.stats["steps"]
    err_plain = np.max(np.abs(plain.y - ref.y))
    assert np.max(np.abs(on.y - ref.y)) <= err_plain and np.max(np.abs(off.y - ref.y)) <= 2 * err_plain


def test_double_pendulum_against_casadi_cvodes(dp):
    """CasADi's CVODES forward sensitivities (the Jacobian of its integrator) of the double
    pendulum written here by hand: d(theta1, theta2, theta1', theta2')/d(l1, l2, m1, m2, g)."""
    ca = pytest.importorskip("casadi")
    x = ca.SX.sym("x", 4)
    prm = ca.SX.sym("p", 5)
    th1, th2, w1, w2 = x[0], x[1], x[2], x[3]
    l1, l2, m1, m2, g = prm[0], prm[1], prm[2], prm[3], prm[4]
    d = th1 - th2
    M = ca.vertcat(ca.horzcat((m1 + m2) * l1 ** 2, m2 * l1 * l2 * ca.cos(d)),
                   ca.horzcat(m2 * l1 * l2 * ca.cos(d), m2 * l2 ** 2))
    F = ca.vertcat(-m2 * l1 * l2 * ca.sin(d) * w2 ** 2 - (m1 + m2) * g * l1 * ca.sin(th1),
                   m2 * l1 * l2 * ca.sin(d) * w1 ** 2 - m2 * g * l2 * ca.sin(th2))
    acc = ca.solve(M, F)
    T = 2.5
    F_int = ca.integrator("F", "cvodes", {"x": x, "p": prm, "ode": ca.vertcat(w1, w2, acc)}, 0.0, T,
                          {"abstol": 1e-12, "reltol": 1e-12})
    y0 = np.array([1.0, -0.5, 0.2, 0.1])
    pv = np.array([1.2, 0.8, 1.0, 1.5, 9.81])
    xf = ca.MX.sym("xf", 4)
    pf = ca.MX.sym("pf", 5)
    jac = ca.Function("J", [xf, pf], [ca.jacobian(F_int(x0=xf, p=pf)["xf"], pf)])
    ref = np.array(jac(y0, pv))  # (4 states, 5 parameters)
    res = dp.simulate(np.array([0.0, T]), y0=y0, params=dict(zip(["l1", "l2", "m1", "m2", "g"], pv)),
                      rtol=1e-8, atol=1e-10, sensitivities=["l1", "l2", "m1", "m2", "g"])
    got = res.sensitivities[-1, :, :4].T
    assert np.max(np.abs(got - ref)) < 1e-6 * np.max(np.abs(ref))


def test_unknown_and_folded_names_are_named(osc, dp):
    t = np.linspace(0, 1, 5)
    with pytest.raises(LagcodegenError, match="'kk' is neither a run-time parameter"):
        osc.simulate(t, q0=[1.0], sensitivities=["kk"])
    with pytest.raises(LagcodegenError, match="'y\\(0\\)' names no initial value"):
        osc.simulate(t, q0=[1.0], sensitivities=["y(0)"])
    with pytest.raises(LagcodegenError, match="given twice"):
        osc.simulate(t, q0=[1.0], sensitivities=["k", "k"])
    with pytest.raises(LagcodegenError, match="at least one"):
        osc.simulate(t, q0=[1.0], sensitivities=[])
    with pytest.raises(LagcodegenError, match="'kk' is neither a run-time parameter"):
        osc.simulate(t, q0=[1.0], method="taylor", sensitivities=["kk"])  # Taylor's take the same names
    with pytest.raises(LagcodegenError, match="linear_solver 'band'"):
        osc.simulate(t, q0=[1.0], linear_solver="band", sensitivities=["k"])
    folded = lcg.compile_model(oscillator(), runtime_parameters=["m"])
    with pytest.raises(LagcodegenError, match="'k' is folded into the code"):
        folded.simulate(t, q0=[1.0], sensitivities=["k"])
    with pytest.raises(LagcodegenError, match="need atol > 0 in every state component"):
        osc.simulate(t, q0=[1.0], v0=[0.5], rtol=1e-8, atol=0.0, sensitivities=["k"])  # s_k(0) = 0
    res = osc.simulate(t, q0=[1.0], sensitivities=["k"])
    with pytest.raises(LagcodegenError, match="not a sensitivity direction"):
        res.sensitivity("x", "m")
    with pytest.raises(LagcodegenError, match="neither a state nor an output"):
        res.sensitivity("v", "k")
    with pytest.raises(LagcodegenError, match="no sensitivities"):
        osc.simulate(t, q0=[1.0]).sensitivity("x", "k")
    # events (tests/solvers/test_sensitivity_events.py): x = cos(w t) crosses 0 at t = pi / (2 w),
    # w = sqrt(k/m): dt/dk = -t / (2 k)
    hit = osc.simulate(t, q0=[1.0], sensitivities=["k"], events=[lcg.Event("x0", sp.Symbol("x"))]).events[-1]
    assert abs(hit.t_sensitivity["k"] + hit.t / 8.0) < 1e-7
    # the same run from a solver object
    obj = osc.simulate(t, q0=[1.0], solver=lcg.CVODE(sensitivities=("k",), sensitivity_errcon=True))
    assert np.array_equal(obj.sensitivities, res.sensitivities)
    # and from the integrator object (tests/solvers/test_sensitivity_integrator.py)
    _, S = osc.integrator(q0=[1.0], method="adams", sensitivities=["k"]).propagate_grid(t)
    assert np.array_equal(S[:, :, 0], res.sensitivities[:, 0, :2])


def test_rigid_body_tree_has_no_expanded_tangent():
    """A tree's M and F are programs: the expanded dr/dy is refused, the per-direction sweep of
    its program is what "auto" generates."""
    m = lcg.Model("arm")
    m.link("a", joint=lcg.Joint.revolute("shoulder", (0, 1, 0)), mass=1, com=(0.5, 0, 0), inertia=(1, 1, 1))
    m.gravity(9.81)
    eom = lcg.derive(m)
    assert eom.tree is not None
    with pytest.raises(ModelError, match="rigid-body tree"):
        sensitivity_source(lcg.Scene(eom, jacobian=False), "arm", form="expanded")
    text = sensitivity_source(lcg.Scene(eom, jacobian=False), "arm")["arm_sens.c"]
    assert "sweep seeded by (s, s')" in text
    with pytest.raises(ModelError, match="sensitivity form 'tangent'"):
        sensitivity_source(lcg.Scene(eom, jacobian=False), "arm", form="tangent")


def test_generated_and_runtime_c_compile_strictly(tmp_path, cc):
    scenes = [lcg.Scene(lcg.derive(model), outputs=["energy"])
              for model in (lcg.systems.double_pendulum(), lcg.systems.damped_pendulum(), oscillator())]
    # no run-time parameter, no output: the arrays of size zero are avoided
    scenes.append(lcg.Scene(lcg.derive(lcg.systems.pendulum("p0")), runtime_parameters=[], outputs=[]))
    for scene in scenes:
        for name, text in sensitivity_source(scene, scene.prefix).items():
            (tmp_path / name).write_text(text)
            proc = subprocess.run([cc, *STRICT_CFLAGS, "-O2", "-c", name, "-o", name + ".o"], cwd=tmp_path,
                                  capture_output=True, text=True)
            assert proc.returncode == 0, proc.stderr
    from lagcodegen.solvers.cvode.sensitivity import _sources
    for name, text in _sources().items():
        (tmp_path / name).write_text(text)
    proc = subprocess.run([cc, *STRICT_CFLAGS, "-O2", "-c", "lcg_cvsens.c", "-o", "lcg_cvsens.o"], cwd=tmp_path,
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    assert "lcg_cvsens_solve" in runtime_files(["lcg_cvsens.h"])["lcg_cvsens.h"]


def test_max_wall_and_ctrl_c_stop_a_long_run(tmp_path, dp):
    """The sensitivity driver's run control: max_wall ends a run of hours with flag -81, SIGINT
    raises KeyboardInterrupt within seconds (a bound, not a measurement)."""
    import os
    import signal
    import sys
    import textwrap
    from pathlib import Path
    res = dp.simulate([0.0, 1e7], q0=[1.0, 1.0], sensitivities=["l1"], max_wall=0.3, raise_on_error=False)
    assert res.status == -81 and "max_wall" in res.message
    root = Path(__file__).resolve().parents[2]
    script = tmp_path / "long.py"
    script.write_text(textwrap.dedent("""
        import sys
        import lagcodegen as lcg
        sim = lcg.compile_model(lcg.systems.double_pendulum())
        sim.simulate([0.0, 1.0], q0=[1.0, 1.0], sensitivities=["l1"])
        print("ready", flush=True)
        try:
            sim.simulate([0.0, 1e7], q0=[1.0, 1.0], sensitivities=["l1"])
        except KeyboardInterrupt:
            print("interrupted", file=sys.stderr)
            sys.exit(130)
    """))
    env = dict(os.environ, PYTHONPATH=str(root))
    proc = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=env)
    try:
        assert proc.stdout.readline().strip() == "ready"
        import time
        time.sleep(0.5)
        proc.send_signal(signal.SIGINT)
        err = proc.communicate(timeout=60)[1]
    finally:
        proc.kill()
    assert proc.returncode == 130, err
    assert "interrupted" in err


def test_routhian_reduction_with_a_quadrature_state():
    """Kepler reduced by its ignorable angle: states (r, r', phi), phi a quadrature state
    phi' = C/(m r^2), C_phi a run-time parameter. Sensitivities of r, r', phi and the outputs
    (phi_dot, jacobi_h) to C_phi, k and r(0) against the fourth-order central differences."""
    from lagcodegen.theory.routhian import reduce as routh_reduce
    red = routh_reduce(lcg.systems.central_potential())
    cm = lcg.compile_reduction(red, outputs=("jacobi_h",), prefix="sens_kepler_routh")
    assert cm.state_names == ["r", "r_dot", "phi"] and "C_phi" in cm.param_names
    t = np.linspace(0.0, 5.0, 26)
    params = {"m": 1.0, "k": 1.0, "C_phi": 1.3}
    y0 = [1.0, 0.1, 0.0]
    res = cm.simulate(t, y0=y0, params=params, rtol=1e-9, atol=1e-11, sensitivities=["C_phi", "k", "r(0)", "phi(0)"])
    h = 2e-4
    for j, name in enumerate(["C_phi", "k", "r(0)"]):
        runs = {}
        for sign in (2, 1, -1, -2):
            p, y = dict(params), list(y0)
            if name == "r(0)":
                y[0] += sign * h
            else:
                p[name] += sign * h * params[name]
            r = cm.simulate(t, y0=y, params=p, rtol=1e-13, atol=1e-15)
            runs[sign] = np.column_stack([r.y, r["phi_dot"], r["jacobi_h"]])
        step = h if name == "r(0)" else h * params[name]
        ref = (8 * (runs[1] - runs[-1]) - (runs[2] - runs[-2])) / (12 * step)
        got = res.sensitivities[:, j, :]
        assert np.max(np.abs(got - ref)) < 1e-6 * np.max(np.abs(ref)), name
        assert np.max(np.abs(got[:, 2])) > 1e-3  # d phi / d(direction) is exercised
    # a quadrature state's initial value moves it one for one, nothing else
    assert np.allclose(res.sensitivity("phi", "phi(0)"), 1.0)
    assert np.allclose(res.sensitivity("r", "phi(0)"), 0.0)


def test_double_pendulum_against_heyoka_variational_equations(dp):
    """heyoka's variational equations (var_ode_sys, first order, with respect to the parameters)
    of the double pendulum's Lagrangian written here, integrated by its Taylor method at
    tolerance 1e-15 (compact mode: its JIT takes minutes otherwise): d(theta1, theta2, theta1', theta2')/d(l1, l2,
    m1, m2, g) at t = 2.5."""
    hy = pytest.importorskip("heyoka")
    q1, q2, v1, v2 = hy.make_vars("q1", "q2", "v1", "v2")
    l1, l2, m1, m2, g = (hy.par[k] for k in range(5))
    x1, y1 = l1 * hy.sin(q1), -l1 * hy.cos(q1)
    x2, y2 = x1 + l2 * hy.sin(q2), y1 - l2 * hy.cos(q2)
    xd1, yd1 = l1 * hy.cos(q1) * v1, l1 * hy.sin(q1) * v1
    xd2, yd2 = xd1 + l2 * hy.cos(q2) * v2, yd1 + l2 * hy.sin(q2) * v2
    T = 0.5 * m1 * (xd1 * xd1 + yd1 * yd1) + 0.5 * m2 * (xd2 * xd2 + yd2 * yd2)
    V = m1 * g * y1 + m2 * g * y2
    sys_ = hy.lagrangian(T - V, [q1, q2], [v1, v2])
    order = [str(lhs) for lhs, _ in sys_]
    vsys = hy.var_ode_sys(sys_, hy.var_args.params, order=1)
    y0 = {"q1": 1.0, "q2": -0.5, "v1": 0.2, "v2": 0.1}
    pv = [1.2, 0.8, 1.0, 1.5, 9.81]
    ta = hy.taylor_adaptive(vsys, [y0[name] for name in order], pars=pv, tol=1e-15, compact_mode=True)
    T_END = 2.5
    ta.propagate_until(T_END)
    ns = len(order)
    ref = np.array(ta.state[ns:]).reshape(ns, 5)  # row: state (heyoka's order), column: parameter
    ref = ref[[order.index(k) for k in ("q1", "q2", "v1", "v2")]]
    res = dp.simulate(np.array([0.0, T_END]), y0=[y0[k] for k in ("q1", "q2", "v1", "v2")],
                      params=dict(zip(["l1", "l2", "m1", "m2", "g"], pv)), rtol=1e-8, atol=1e-10,
                      sensitivities=["l1", "l2", "m1", "m2", "g"])
    got = res.sensitivities[-1, :, :4].T
    assert np.max(np.abs(got - ref)) < 1e-6 * np.max(np.abs(ref))
    # the Taylor integrator's jet transport of the variational equations too
    tay = dp.simulate(np.array([0.0, T_END]), y0=[y0[k] for k in ("q1", "q2", "v1", "v2")],
                      params=dict(zip(["l1", "l2", "m1", "m2", "g"], pv)), rtol=1e-8, atol=1e-10, method="taylor",
                      sensitivities=["l1", "l2", "m1", "m2", "g"])
    assert np.max(np.abs(tay.sensitivities[-1, :, :4].T - ref)) < 1e-6 * np.max(np.abs(ref))
    # and the trajectory itself: the states' error test is the plain run's, so within its error
    # (8.6e-7 here) and within 100 rtol
    y_ref = np.array(ta.state[:ns])[[order.index(k) for k in ("q1", "q2", "v1", "v2")]]
    plain = dp.simulate(np.array([0.0, T_END]), y0=[y0[k] for k in ("q1", "q2", "v1", "v2")],
                        params=dict(zip(["l1", "l2", "m1", "m2", "g"], pv)), rtol=1e-8, atol=1e-10)
    err = np.max(np.abs(res.y[-1] - y_ref))
    assert err <= np.max(np.abs(plain.y[-1] - y_ref)) and err < 1e-6
