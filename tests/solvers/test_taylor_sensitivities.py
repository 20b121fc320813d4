"""Forward sensitivities on the Taylor integrator (lagcodegen.codegen.taylor.variational and
lagcodegen.solvers.taylor.sensitivity: jet transport of the variational equations): against closed
forms (the harmonic oscillator), CVODE's sensitivities at tight tolerance (an independent
derivation: symbolic derivatives of M and F, a BDF/Adams Newton solve), central differences of plain
Taylor runs, and a model that uses every elementary operation of the jet."""

import subprocess

import numpy as np
import pytest
import sympy as sp

import lagcodegen as lcg
from lagcodegen.errors import LagcodegenError
from lagcodegen.codegen.taylor.decompose import decompose
from lagcodegen.codegen.taylor.schedule import GROUP, Fused, schedule
from lagcodegen.codegen.taylor.variational import variational
from lagcodegen.codegen.taylor.variational_source import variational_sources

from helpers import STRICT_CFLAGS

DP_NAMES = ["l1", "l2", "m1", "m2", "g", "theta1(0)", "theta2(0)", "theta1_dot(0)", "theta2_dot(0)"]


def oscillator():
    m = lcg.Model("oscillator")
    x, = m.coordinates("x")
    k, mass = m.parameters(k=4.0, m=1.0)
    m.particle("body", mass, (x, 0))
    m.potential_energy(k * x ** 2 / 2)
    return m


def gadget():
    """Two coordinates whose equations take every kind of jet operation: quotients (a mass
    matrix 1 + x^2/b and a/(1 + y^2)), sin/cos of a difference, exp, log, sqrt, tan, cosh, a power
    with a parameter as exponent, a damper and a forcing in time."""
    m = lcg.Model("gadget")
    x, y = m.coordinates("x y")
    a, b, c, w = m.parameters(a=0.7, b=1.3, c=0.4, w=2.0)
    xd, yd = m.dot(x), m.dot(y)
    m.kinetic_energy((1 + x ** 2 / b) * xd ** 2 / 2 + a * yd ** 2 / (2 * (1 + y ** 2))
                     + c * sp.cos(x - y) * xd * yd / 4)
    m.potential_energy(x ** 2 / 2 + y ** 2 + c * sp.log(1 + x ** 2) + a * sp.sqrt(1 + y ** 2)
                       + sp.tan(x / 4) / 5 + sp.cosh(y / 3) / 3 + (1 + y ** 2) ** b / 10 + sp.exp(-x ** 2) / 7)
    m.dissipation(c * xd ** 2 / 2)
    m.generalized_force(x, sp.sin(w * m.t) / 10)
    return m


@pytest.fixture(scope="module")
def osc():
    return lcg.compile_model(oscillator(), outputs=["energy"])


@pytest.fixture(scope="module")
def gadget_cm():
    return lcg.compile_model(gadget(), outputs=["energy"], prefix="taylor_sens_gadget")


@pytest.fixture(scope="module")
def dp():
    return lcg.compile_model(lcg.systems.double_pendulum(), outputs=["energy"])


def test_harmonic_oscillator_closed_forms(osc):
    """x = x0 cos(w t) + v0 sin(w t)/w, w = sqrt(k/m): dx/dk, dx/dm, dx/dx0, dx/dv0 and the
    energy's (dE/dk = x0^2/2, dE/dv0 = m v0) at tolerance 1e-8, relative 1e-6."""
    t = np.linspace(0.0, 10.0, 201)
    x0, v0, k, m = 0.7, 0.3, 4.0, 1.0
    names = ["k", "m", "x(0)", "x_dot(0)"]
    res = osc.simulate(t, q0=[x0], v0=[v0], rtol=1e-8, atol=1e-10, method="taylor", sensitivities=names)
    assert res.method == "taylor" and res.status == 0
    w = np.sqrt(k / m)
    dxdw = -x0 * t * np.sin(w * t) + v0 * (t * np.cos(w * t) / w - np.sin(w * t) / w ** 2)
    scale = np.max(np.abs(dxdw))
    assert np.max(np.abs(res.sensitivity("x", "k") - dxdw / (2 * np.sqrt(k * m)))) < 1e-6 * scale / 2
    assert np.max(np.abs(res.sensitivity("x", "m") - dxdw * (-np.sqrt(k) / (2 * m ** 1.5)))) < 1e-6 * scale / 2
    assert np.max(np.abs(res.sensitivity("x", "x(0)") - np.cos(w * t))) < 1e-6
    assert np.max(np.abs(res.sensitivity("x", "x_dot(0)") - np.sin(w * t) / w)) < 1e-6
    assert np.max(np.abs(res.sensitivity("x_dot", "x(0)") + w * np.sin(w * t))) < 2e-6
    assert np.max(np.abs(res.sensitivity("energy", "k") - x0 ** 2 / 2)) < 1e-6
    assert np.max(np.abs(res.sensitivity("energy", "x_dot(0)") - m * v0)) < 1e-6
    assert res.sensitivities.shape == (t.size, 4, 3)
    assert res.sensitivity_names == names and res.sensitivity_values == ["x", "x_dot", "energy"]
    # the trajectory is the plain Taylor run's to the tolerance
    plain = osc.simulate(t, q0=[x0], v0=[v0], rtol=1e-8, atol=1e-10, method="taylor")
    assert np.max(np.abs(res["x"] - plain["x"])) < 1e-7
    # the same run from a solver object
    obj = osc.simulate(t, q0=[x0], v0=[v0], rtol=1e-8, atol=1e-10,
                       solver=lcg.Taylor(sensitivities=tuple(names), sensitivity_errcon=True))
    assert np.array_equal(obj.sensitivities, res.sensitivities)


def test_double_pendulum_against_cvode_and_central_differences(dp):
    """Every direction (5 parameters, 4 initial values) at rtol 1e-8: relative 1e-6 against
    CVODE's sensitivities at rtol 1e-12 (states and energy), and against fourth-order central
    differences of plain Taylor runs at rtol 1e-13 for a parameter in M and an initial value."""
    t = np.linspace(0.0, 3.0, 61)
    q0, v0 = [1.0, -0.5], [0.2, 0.1]
    res = dp.simulate(t, q0=q0, v0=v0, rtol=1e-8, atol=1e-10, method="taylor", sensitivities=DP_NAMES)
    ref = dp.simulate(t, q0=q0, v0=v0, rtol=1e-12, atol=1e-14, sensitivities=DP_NAMES)
    assert res.sensitivity_values == ref.sensitivity_values
    for j, name in enumerate(DP_NAMES):
        got, want = res.sensitivities[:, j, :], ref.sensitivities[:, j, :]
        err = np.max(np.abs(got - want), axis=0) / np.max(np.abs(want), axis=0).clip(1e-300)
        assert np.all(err[:4] < 1e-6), (name, err)
        assert np.max(np.abs(got[:, 4] - want[:, 4])) < 1e-6 * np.max(np.abs(got[:, :4])), name
    h = 2e-4
    for name in ("l1", "theta2_dot(0)"):
        runs = {}
        for sign in (2, 1, -1, -2):
            q, v, p = list(q0), list(v0), dict(zip(dp.param_names, dp.parameter_vector(None)))
            if name == "l1":
                step = h * p["l1"]
                p["l1"] += sign * step
            else:
                step = h
                v[1] += sign * step
            r = dp.simulate(t, q0=q, v0=v, params=p, rtol=1e-13, atol=1e-15, method="taylor")
            runs[sign] = r.y
        cd = (8 * (runs[1] - runs[-1]) - (runs[2] - runs[-2])) / (12 * step)
        got = res.sensitivities[:, DP_NAMES.index(name), :4]
        assert np.max(np.abs(got - cd)) < 1e-6 * np.max(np.abs(cd)), name


def test_every_jet_operation_against_cvode(gadget_cm):
    """The gadget (quotients, exp, log, sqrt, tan, cosh, a parameter exponent, damping, forcing
    in t): Taylor sensitivities along every parameter and two initial values against CVODE's at
    rtol 1e-12, relative 1e-6; the variational program holds a tangent of every kind."""
    cm = gadget_cm
    names = ["a", "b", "c", "w", "x(0)", "y_dot(0)"]
    t = np.linspace(0.0, 4.0, 41)
    kw = dict(q0=[0.4, -0.3], v0=[0.2, 0.5])
    res = cm.simulate(t, rtol=1e-8, atol=1e-10, method="taylor", sensitivities=names, **kw)
    ref = cm.simulate(t, rtol=1e-12, atol=1e-14, sensitivities=names, **kw)
    for j, name in enumerate(names):
        got, want = res.sensitivities[:, j, :], ref.sensitivities[:, j, :]
        assert np.max(np.abs(want[:, :4])) > 1e-2, name  # the direction is exercised
        assert np.max(np.abs(got - want)) < 1e-6 * np.max(np.abs(want)), name
    v = variational(decompose(cm.code.scene), [("param", 1), ("state", 0)])
    kinds = {op.kind for op in v.ops_a + v.ops_b}
    assert {"div", "cdiv", "dot", "lin", "log"} <= kinds  # log: the tangent of the power in b


def test_schedule_keeps_every_dependency(gadget_cm):
    """The tangent operations in fused levels (schedule): each operation once, each reading only
    rows written by an earlier item (or outside the tangent program), no loop over GROUP
    products, and some loops holding several operations."""
    d = decompose(gadget_cm.code.scene)
    v = variational(d, [("param", 0), ("param", 1), ("state", 0), ("state", 3)])
    for ops in (v.ops_a[len(d.ops):], v.ops_b):
        items = schedule(ops)
        flat = [op for item in items for op in (item.ops if isinstance(item, Fused) else (item,))]
        assert sorted(map(id, flat)) == sorted(map(id, ops))
        written_by_ops = {o for op in ops for o in op.out}
        done: set = set()
        for item in items:
            group = item.ops if isinstance(item, Fused) else (item,)
            for op in group:
                reads = set(op.args) | {r for pr in op.pairs if pr is not None for r in pr}
                assert not (reads & written_by_ops) - done - set(op.out), op
            done.update(o for op in group for o in op.out)
            if isinstance(item, Fused):
                assert all(op.kind == "dot" for op in item.ops) and len(item.pairs) <= GROUP
    assert any(isinstance(i, Fused) and len(i.ops) > 1 for i in schedule(v.ops_a[len(d.ops):]))


def test_fused_loops_give_the_same_numbers(dp, monkeypatch):
    """The fused tangent loops against the tangent operations one loop each in program order:
    bit-identical states and sensitivities (each sum added in the same order)."""
    from lagcodegen.codegen.taylor import variational_source
    from lagcodegen.solvers.taylor import sensitivity
    t = np.linspace(0.0, 3.0, 31)
    names = ["l1", "m2", "theta2(0)"]
    fused = dp.simulate(t, q0=[0.5, 0.5], method="taylor", sensitivities=names)
    names_, dirs, s0 = sensitivity.directions_of(dp, names)
    monkeypatch.setattr(variational_source, "schedule", lambda ops, tangent=None: list(ops))
    monkeypatch.setattr(variational_source, "GROUP", 1)
    module = sensitivity.VariationalModule(dp, dp.code.scene, names_, dirs, s0)
    assert "a0 +=" not in (module.path.parent / "double_pendulum_taylor_var.c").read_text()
    y0 = np.array([0.5, 0.5, 0.0, 0.0])
    plain = module.simulate(t, y0, dp.parameter_vector(), rtol=1e-8, atol=1e-10)
    assert np.array_equal(fused.y, plain.y)
    assert np.array_equal(fused.sensitivities, plain.sensitivities)


def test_quadrature_state_and_outputs_of_a_routhian():
    """Kepler reduced by its ignorable angle (states r, r', phi; phi' = C/(m r^2) a quadrature):
    the sensitivities of phi and of the outputs against CVODE's at rtol 1e-12."""
    from lagcodegen.theory.routhian import reduce as routh_reduce
    red = routh_reduce(lcg.systems.central_potential())
    cm = lcg.compile_reduction(red, outputs=("jacobi_h",), prefix="taylor_sens_kepler_routh")
    t = np.linspace(0.0, 5.0, 26)
    kw = dict(y0=[1.0, 0.1, 0.0], params={"m": 1.0, "k": 1.0, "C_phi": 1.3})
    names = ["C_phi", "k", "r(0)", "phi(0)"]
    res = cm.simulate(t, rtol=1e-8, atol=1e-10, method="taylor", sensitivities=names, **kw)
    ref = cm.simulate(t, rtol=1e-12, atol=1e-14, sensitivities=names, **kw)
    assert res.sensitivity_values == ["r", "r_dot", "phi", "phi_dot", "jacobi_h"]
    for j, name in enumerate(names[:3]):
        want = ref.sensitivities[:, j, :]
        assert np.max(np.abs(want[:, 2])) > 1e-2
        assert np.max(np.abs(res.sensitivities[:, j, :] - want)) < 1e-6 * np.max(np.abs(want)), name
    assert np.allclose(res.sensitivity("phi", "phi(0)"), 1.0, rtol=0, atol=1e-14)
    assert np.allclose(res.sensitivity("r", "phi(0)"), 0.0, rtol=0, atol=1e-14)


def test_error_control_off_takes_no_more_steps(dp):
    """errcon off: the steps are the states' own (the sensitivities' weights infinite); the
    sensitivities are still close at this tolerance, and the run takes no more steps."""
    t = np.linspace(0.0, 2.0, 21)
    kw = dict(q0=[0.6, 0.2], rtol=1e-9, atol=1e-11, method="taylor", sensitivities=["l1", "g"])
    on = dp.simulate(t, **kw)
    off = dp.simulate(t, sensitivity_errcon=False, **kw)
    plain = dp.simulate(t, q0=[0.6, 0.2], rtol=1e-9, atol=1e-11, method="taylor")
    assert off.stats["steps"] == plain.stats["steps"] <= on.stats["steps"]
    scale = np.max(np.abs(on.sensitivities))
    assert np.max(np.abs(on.sensitivities - off.sensitivities)) < 1e-5 * scale


def test_a_direction_is_one_block_of_the_step_size_rule(dp):
    """With error control, a direction's sensitivities take their relative tolerance on the
    direction's largest |s| (lcg_taylor_options.rel_block): a component crossing zero does not
    ask for atol while the others are large. Over t in [0, 10] the run then takes at most 1.2x
    (p = 1) and 1.25x (p = 7) the plain run's steps (each component on its own |s_i|: 1.25x and
    1.38x), and the sensitivities stay within 1e-6 of CVODE's at rtol 1e-12."""
    t = np.linspace(0.0, 10.0, 11)
    names = list(dp.param_names) + ["theta1(0)", "theta2(0)"]
    kw = dict(q0=[0.5, 0.5], rtol=1e-8, atol=1e-10)
    plain = dp.simulate(t, method="taylor", **kw)
    ref = dp.simulate(t, q0=[0.5, 0.5], rtol=1e-12, atol=1e-14, sensitivities=names)
    for p, bound in ((1, 1.2), (7, 1.25)):
        res = dp.simulate(t, method="taylor", sensitivities=names[:p], **kw)
        assert plain.stats["steps"] < res.stats["steps"] <= bound * plain.stats["steps"], p
        s, r = res.sensitivities[:, :, :4], ref.sensitivities[:, :p, :4]
        assert np.all(np.max(np.abs(s - r), axis=(0, 2)) < 1e-6 * np.max(np.abs(r), axis=(0, 2))), p


def test_event_time_of_the_oscillator(osc):
    """x = cos(w t), w = sqrt(k/m), crosses 0 at t_e = pi/(2 w): dt_e/dk = -pi/(4 w k) = -pi/32 at
    k = 4, m = 1, and 0 along the amplitude x(0); the run ends there with x's sensitivity
    (tests/solvers/test_taylor_sensitivity_events.py: against CVODE and central differences)."""
    t = np.linspace(0, 1, 5)
    res = osc.simulate(t, q0=[1.0], method="taylor", sensitivities=["k", "x(0)"], rtol=1e-12, atol=1e-14,
                       events=[lcg.Event("x0", sp.Symbol("x"))])
    rec, = res.events
    assert abs(rec.t - np.pi / 4) < 1e-12 and res.t[-1] == rec.t
    assert abs(rec.t_sensitivity["k"] + np.pi / 32) < 1e-11 and abs(rec.t_sensitivity["x(0)"]) < 1e-12
    # x(t_e) = 0 whatever k: dx/dk at the fixed time t_e is -x'(t_e) dt_e/dk = -2 pi/32
    assert abs(res.sensitivity("x", "k")[-1] + 2 * np.pi / 32) < 1e-10


def test_refusals_are_named(osc):
    t = np.linspace(0, 1, 5)
    with pytest.raises(LagcodegenError, match="'kk' is neither a run-time parameter"):
        osc.simulate(t, q0=[1.0], method="taylor", sensitivities=["kk"])
    with pytest.raises(LagcodegenError, match="sensitivities must be a list of names"):
        lcg.Taylor(sensitivities=3)


def test_generated_code_compiles_strictly(tmp_path, cc, gadget_cm):
    """The variational jet with every operation kind, with quadratures, without outputs or
    parameters: -Wall -Wextra -Werror -std=c99 -pedantic."""
    cases = [(gadget_cm.code.scene, [("param", 1), ("state", 3)], ["b", "y_dot(0)"]),
             (lcg.Scene(lcg.derive(lcg.systems.double_pendulum()), outputs=[]), [("state", 0)], ["theta1(0)"]),
             (lcg.Scene(lcg.derive(lcg.systems.pendulum("p0")), runtime_parameters=[], outputs=[]), [("state", 1)],
              ["theta_dot(0)"])]
    for scene, dirs, names in cases:
        files, _ = variational_sources(scene, dirs, names)
        for name, text in files.items():
            (tmp_path / name).write_text(text)
        name = f"{scene.prefix}_taylor_var.c"
        proc = subprocess.run([cc, *STRICT_CFLAGS, "-O2", "-c", name, "-o", name + ".o"], cwd=tmp_path,
                              capture_output=True, text=True)
        assert proc.returncode == 0, proc.stderr


def test_fit_on_the_taylor_integrator(osc):
    """lagcodegen.fit with method="taylor" (its Jacobian from the Taylor sensitivities): the
    oscillator's k and initial velocity from 100 noisy samples of x = x0 cos(w t) + v0 sin(w t)/w
    (1% noise, seeded), within 3 reported standard deviations of the truth."""
    t = np.linspace(0.0, 5.0, 100)
    k, x0, v0 = 4.0, 0.7, 0.3
    w = np.sqrt(k)
    noise = 0.01
    data = x0 * np.cos(w * t) + v0 * np.sin(w * t) / w + noise * np.random.default_rng(7).standard_normal(t.size)
    fit = lcg.fit(osc, t, data[:, None], params={"k": 3.5, "x_dot(0)": 0.0}, observe=["x"], q0=[x0], sigma=noise,
                  method="taylor")
    assert abs(fit.params["k"] - k) < 3 * fit.stderr["k"] and fit.stderr["k"] < 0.01
    assert abs(fit.params["x_dot(0)"] - v0) < 3 * fit.stderr["x_dot(0)"]
    assert fit.iterations <= 20


SANITIZE_MAIN = r"""
#include <stdio.h>
#include <string.h>
#include "lcg_taylor.h"

const lcg_taylor_model *taylor_sens_gadget_taylor_var_table(void);

int main(void)
{
    double p[4] = {0.7, 1.3, 0.4, 2.0}, y0[12] = {0.4, -0.3, 0.2, 0.5, 0, 0, 0, 0, 0, 0, 0, 1};
    double t[4] = {0.0, 0.5, 1.5, 3.0}, yout[4 * 12], out[4 * 3];
    lcg_taylor_options opt;
    lcg_taylor_stats st;
    int flag, k;

    memset(&opt, 0, sizeof opt);
    opt.rtol = 1e-10;
    opt.atol = 1e-12;
    opt.max_steps = 100000;
    opt.rel_block = 4; /* each direction's sensitivities one block of the step-size rule, as the runs */
    flag = lcg_taylor_solve(taylor_sens_gadget_taylor_var_table(), p, y0, 4, t, yout, out, &opt, &st, NULL);
    printf("%d %d", flag, st.nt_done);
    for (k = 0; k < 4 * 12; ++k)
        printf(" %.17g", yout[k]);
    for (k = 0; k < 4 * 3; ++k)
        printf(" %.17g", out[k]);
    printf("\n");
    return flag;
}
"""


def test_variational_jet_runs_clean_under_sanitizers(tmp_path, cc, gadget_cm):
    """The gadget's variational jet (directions b and y_dot(0)) driven by lcg_taylor.c under
    ASan/UBSan: the same states, sensitivities and outputs as the run in this process."""
    from lagcodegen.codegen.taylor.emit import runtime_sources
    files, _ = variational_sources(gadget_cm.code.scene, [("param", 1), ("state", 3)], ["b", "y_dot(0)"])
    files = {**runtime_sources(), **files}
    for name, text in files.items():
        (tmp_path / name).write_text(text)
    (tmp_path / "main.c").write_text(SANITIZE_MAIN)
    # -O0: at -O1 the sanitizers' instrumentation of the jet takes gcc ten times longer
    san = ["-std=c99", "-g", "-O0", "-fsanitize=address,undefined", "-fno-sanitize-recover=all"]
    sources = [name for name in files if name.endswith(".c")]
    proc = subprocess.run([cc, *san, "main.c", *sources, "-o", "run", "-lm", "-pthread"], cwd=tmp_path,
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    run = subprocess.run(["./run"], cwd=tmp_path, capture_output=True, text=True,
                         env={"ASAN_OPTIONS": "detect_leaks=1", "PATH": "/usr/bin:/bin"})
    assert run.returncode == 0, run.stdout + run.stderr
    flag, done, *values = run.stdout.split()
    assert int(flag) == 0 and int(done) == 4
    values = np.array(values, dtype=float)
    yout, out = values[:48].reshape(4, 12), values[48:].reshape(4, 3)
    res = gadget_cm.simulate(np.array([0.0, 0.5, 1.5, 3.0]), q0=[0.4, -0.3], v0=[0.2, 0.5], rtol=1e-10, atol=1e-12,
                      method="taylor", sensitivities=["b", "y_dot(0)"])
    assert np.allclose(yout[:, :4], res.y, rtol=1e-12, atol=1e-14)
    assert np.allclose(yout[:, 4:].reshape(4, 2, 4), res.sensitivities[:, :, :4], rtol=1e-12, atol=1e-14)
    assert np.allclose(out, np.column_stack([res["energy"], res.sensitivities[:, :, 4]]), rtol=1e-12, atol=1e-14)
    assert np.max(np.abs(yout[:, 4:])) > 0.1  # the sensitivities moved
