"""The Taylor-series integrator emitted as C (lagcodegen.solvers.taylor), checked against
closed-form solutions, independently computed Taylor coefficients and the compiler."""

from __future__ import annotations

import math
import shutil
import subprocess

import numpy as np
import pytest
import sympy as sp
from scipy.special import ellipj, ellipk

import lagcodegen as lcg
from lagcodegen.build import DEFAULT_CFLAGS
from lagcodegen.derivation import derive
from lagcodegen.errors import ModelError
from lagcodegen.formulation.scene import Scene
from lagcodegen.model.events import Event
from lagcodegen.codegen.taylor.decompose import decompose
from lagcodegen.codegen.taylor.emit import taylor_code, taylor_sources
from lagcodegen.solvers.taylor import build_taylor
from lagcodegen.theory.routhian import reduce as routh_reduce


def module(model_or_eom, outputs=(), events=(), **scene):
    eom = derive(model_or_eom) if isinstance(model_or_eom, lcg.Model) else model_or_eom
    sc = Scene(eom, jacobian=False, outputs=outputs, **scene)
    return build_taylor(sc, events=events), np.array(sc.default_parameters(), dtype=float)


def falling_ball(name="ball"):
    m = lcg.Model(name)
    x, y = m.coordinates("x y")
    g, mass = m.parameters(g=9.81, m=2.0)
    m.particle("ball", mass, (x, y))
    m.gravity(g)
    return m


@pytest.fixture(scope="module")
def pendulum():
    return module(lcg.systems.pendulum(), outputs=["energy"],
                  events=[Event("down", sp.Symbol("theta"), 0, False), Event("up", sp.Symbol("theta"), 1, False)])


@pytest.fixture(scope="module")
def ball():
    return module(falling_ball(), events=[Event("ground", sp.Symbol("y"), -1, True)])


def exact_pendulum(t, theta0, w):
    """theta(t) of theta'' = -w^2 sin(theta), theta(0) = theta0, theta'(0) = 0:
    sin(theta/2) = k sn(K - w t | k^2), k = sin(theta0/2)."""
    k = math.sin(theta0 / 2)
    m = k * k
    K = ellipk(m)
    u = np.mod(K - w * t, 4 * K)  # sn has period 4K: keep the argument small
    sn, cn, dn, _ = ellipj(u, m)
    theta = 2 * np.arcsin(k * sn)
    # theta' = 2 k cn dn * (-w) / cos(theta/2)
    return theta, -2 * k * w * cn * dn / np.sqrt(1 - (k * sn) ** 2)



def test_order_rule_and_error_below_the_tolerance(pendulum):
    """The order from the tolerance, p = ceil(-ln(tol)/2 + 3) (tuned at equal achieved error), and
    the error of whole runs against the closed-form solution below the tolerance they were given."""
    tm, p = pendulum
    theta0, w = 1.0, math.sqrt(9.81)
    t = np.linspace(0.0, 10.0, 11)
    theta, omega = exact_pendulum(t, theta0, w)
    for tol in (1e-4, 1e-6, 1e-8, 1e-10, 1e-12):
        res = tm.simulate(t, np.array([theta0, 0.0]), p, rtol=tol, atol=tol)
        assert res.success, res.message
        assert res.stats["order"] == math.ceil(-math.log(tol) / 2 + 3)
        err = max(np.abs(res["theta"] - theta).max(), np.abs(res["theta_dot"] - omega).max())
        assert err < tol, (tol, err)

def test_large_amplitude_pendulum_against_elliptic_functions(pendulum):
    tm, p = pendulum
    theta0, w = 3.0, math.sqrt(9.81)
    t = np.linspace(0.0, 100.0, 2001)
    res = tm.simulate(t, np.array([theta0, 0.0]), p, rtol=1e-12, atol=1e-12)
    assert res.success, res.message
    theta, omega = exact_pendulum(t, theta0, w)
    # Near the separatrix (theta0 = 3.0 of pi) the period depends strongly on the energy, so
    # local errors of 1e-12 grow into a phase error of a few 1e-8 over 30 swings.
    assert np.abs(res["theta"] - theta).max() < 1e-7
    assert np.abs(res["theta_dot"] - omega).max() < 1e-6
    assert abs(res["energy"] - res["energy"][0]).max() < 1e-10 * abs(res["energy"][0])
    assert res.stats["order"] == 17 and res.stats["steps"] < 3000  # ceil(-ln(1e-12)/2 + 3)
    # a looser tolerance is looser: the error tracks the tolerance
    loose = tm.simulate(t, np.array([theta0, 0.0]), p, rtol=1e-6, atol=1e-6)
    err = np.abs(loose["theta"] - theta).max()
    assert 1e3 * np.abs(res["theta"] - theta).max() < err < 0.1


def test_pendulum_events_against_quarter_periods(pendulum):
    """theta = 0 at t = K/w (decreasing), 3K/w (increasing), 5K/w, ...; 'up' keeps only the
    increasing ones. Neither is terminal: the run goes on to the end."""
    tm, p = pendulum
    theta0, w = 2.0, math.sqrt(9.81)
    K = ellipk(math.sin(theta0 / 2) ** 2)
    t = np.linspace(0.0, 20.0, 5)
    res = tm.simulate(t, np.array([theta0, 0.0]), p, rtol=1e-12, atol=1e-12)
    assert res.success and res.t[-1] == 20.0 and len(res.t) == 5
    down = [e for e in res.events if e.name == "down"]
    up = [e for e in res.events if e.name == "up"]
    expect = (2 * np.arange(len(down)) + 1) * K / w
    assert len(down) == int((20.0 * w / K + 1) // 2) > 5
    assert np.abs(np.array([e.t for e in down]) - expect).max() < 1e-9
    assert [e.direction for e in down] == [-1 if j % 2 == 0 else 1 for j in range(len(down))]
    assert [e.t for e in up] == [e.t for e in down if e.direction == 1]
    assert all(abs(e.y[0]) < 1e-9 for e in res.events)


def test_a_scalar_then_a_per_state_atol_on_one_module(pendulum):
    """The module keeps its options while the same values come back: a per-state atol after a
    scalar one is written (not compared as an array), and the scalar one after it again gives
    the first run bit for bit."""
    tm, p = pendulum
    t = np.linspace(0.0, 2.0, 3)
    y0 = np.array([1.0, 0.0])
    a = tm.simulate(t, y0, p, rtol=1e-8, atol=1e-8)
    b = tm.simulate(t, y0, p, rtol=1e-8, atol=np.array([1e-8, 1e-2]))  # the velocity's loose
    c = tm.simulate(t, y0, p, rtol=1e-8, atol=1e-8)
    assert a.success and b.success and np.array_equal(a.y, c.y) and a.stats == c.stats
    assert not np.array_equal(a.y, b.y)  # the per-state atol was used
    theta, _ = exact_pendulum(t, 1.0, math.sqrt(9.81))
    assert np.abs(b.y[:, 0] - theta).max() < 1e-4


def test_event_runs_one_after_another_keep_their_own_records(pendulum):
    """The events struct of a finished run serves the next (its records hold copies): a second
    run, one with fewer events kept, and the first run again each find their own events, and the
    first run's records are not changed by the later runs."""
    tm, p = pendulum
    t = np.linspace(0.0, 5.0, 3)
    first = tm.simulate(t, np.array([2.0, 0.0]), p, rtol=1e-10, atol=1e-10)
    kept = [(e.name, e.t, e.y.copy(), e.direction) for e in first.events]
    other = tm.simulate(t, np.array([0.5, 0.0]), p, rtol=1e-10, atol=1e-10)  # another amplitude, period
    few = tm.simulate(t, np.array([2.0, 0.0]), p, rtol=1e-10, atol=1e-10, max_events=2)
    again = tm.simulate(t, np.array([2.0, 0.0]), p, rtol=1e-10, atol=1e-10)
    assert len(first.events) > 2 and first.stats["events"] == len(first.events)
    assert [(e.name, e.t, e.direction) for e in first.events] == [(n, te, d) for n, te, _, d in kept]
    assert all(np.array_equal(e.y, y) for e, (_, _, y, _) in zip(first.events, kept))
    assert [(e.name, e.t, e.direction) for e in again.events] == [(n, te, d) for n, te, _, d in kept]
    assert [(e.name, e.t) for e in few.events] == [(n, te) for n, te, _, _ in kept[:2]]
    assert few.stats["events"] == first.stats["events"]  # counted beyond those kept
    assert other.events[0].t != first.events[0].t and all(abs(e.y[0]) < 1e-9 for e in other.events)


def test_terminal_event_and_free_fall_is_exact(ball):
    """y(t) = y0 + vy0 t - g t^2/2 is a polynomial: the Taylor series ends, steps are long, the
    hit of the ground at t* = (vy0 + sqrt(vy0^2 + 2 g y0))/g ends the run."""
    tm, p = ball
    g, y0, vx, vy = 9.81, 10.0, 1.5, 2.0
    t = np.linspace(0.0, 5.0, 11)
    res = tm.simulate(t, np.array([0.0, y0, vx, vy]), p, rtol=1e-10, atol=1e-10)
    assert res.success and res.stats["steps"] <= 3
    hit = (vy + math.sqrt(vy**2 + 2 * g * y0)) / g
    [ev] = res.events
    assert ev.name == "ground" and ev.direction == -1 and abs(ev.t - hit) < 1e-13
    assert res.t[-1] == ev.t and res.t[-2] <= hit < res.t[-2] + 0.5
    assert abs(res["x"][-1] - vx * hit) < 1e-12 and abs(res["y"][-1]) < 1e-12
    tt = res.t[:-1]
    assert np.abs(res["y"][:-1] - (y0 + vy * tt - g * tt**2 / 2)).max() < 1e-12
    assert np.abs(res["y_dot"][:-1] - (vy - g * tt)).max() < 1e-12


def test_uniform_motion_and_free_fall_take_few_steps(ball):
    """With the ground far below no event fires; with g = 0 every coefficient beyond the first
    vanishes: one step over t = 1e3, exact, at any tolerance."""
    tm, p = ball
    t = np.linspace(0.0, 1e3, 7)
    for g in (0.0, 9.81):
        q = p.copy()
        q[0] = g
        for tol in (1e-6, 1e-12):
            res = tm.simulate(t, np.array([1.0, 1e7, -3.0, 0.5]), q, rtol=tol, atol=tol)
            assert res.success and res.stats["steps"] <= 2 and not res.events
            assert np.allclose(res["x"], 1.0 - 3.0 * t, rtol=1e-15, atol=1e-12)
            assert np.allclose(res["y"], 1e7 + 0.5 * t - g * t**2 / 2, rtol=1e-15, atol=1e-8)


def test_damped_oscillator_against_exponential_solution():
    tm, p = module(lcg.systems.damped_driven_oscillator(), values={"F0": 0.0}, runtime_parameters=[])
    t = np.linspace(0.0, 30.0, 301)
    res = tm.simulate(t, np.array([1.0, 0.0]), p, rtol=1e-12, atol=1e-14)
    gam, wd = 0.2, math.sqrt(4.0 - 0.04)  # c/(2m), sqrt(k/m - gam^2)
    x = np.exp(-gam * t) * (np.cos(wd * t) + gam / wd * np.sin(wd * t))
    assert res.success and np.abs(res["x"] - x).max() < 1e-11


def test_kepler_ellipse_returns_after_three_periods():
    tm, p = module(lcg.systems.central_potential(), outputs=["energy"], values={"m": 2.0, "k": 3.0},
                   runtime_parameters=[])
    r0, w0, m, k = 1.0, 1.6, 2.0, 3.0
    a = 1.0 / (2.0 / r0 - m * (r0 * w0) ** 2 / k)
    period = 2 * math.pi * a**1.5 * math.sqrt(m / k)
    res = tm.simulate(np.array([0.0, period, 3 * period]), np.array([r0, 0.0, 0.0, w0]), p,
                      rtol=1e-13, atol=1e-13)
    assert res.success
    assert abs(res["r"][-1] - r0) < 1e-10 and abs(res["r_dot"][-1]) < 1e-9
    assert abs(res["phi"][-1] - 6 * math.pi) < 1e-9 and abs(res["phi_dot"][-1] - w0) < 1e-9
    assert abs(res["energy"][-1] - res["energy"][0]) < 1e-12


def test_quadrature_state_of_a_routhian_reduction():
    """Kepler reduced by its ignorable angle: phi is a quadrature state z' = C/(m r^2); it
    must follow the full model's phi."""
    red = routh_reduce(lcg.systems.central_potential())
    tm_red, _ = module(red.eom, runtime_parameters=None)
    tm_full, p_full = module(lcg.systems.central_potential())
    assert tm_red.code.nz == 1 and tm_red.state_names[-1] == "phi"
    r0, w0 = 1.0, 1.3
    t = np.linspace(0.0, 20.0, 41)
    full = tm_full.simulate(t, np.array([r0, 0.0, 0.0, w0]), p_full, rtol=1e-12, atol=1e-12)
    params = dict(zip(tm_red.param_names, [1.0] * len(tm_red.param_names)))
    params["C_phi"] = r0**2 * w0  # m r^2 phi' with m = 1
    p_red = np.array([params[k] for k in tm_red.param_names])
    res = tm_red.simulate(t, np.array([r0, 0.0, 0.0]), p_red, rtol=1e-12, atol=1e-12)
    assert res.success
    assert np.abs(res["r"] - full["r"]).max() < 1e-9
    assert np.abs(res["phi"] - full["phi"]).max() < 1e-9


def all_operations_model():
    m = lcg.Model("allops")
    x, = m.coordinates("x")
    v = m.dot(x)
    k, = m.parameters(k=1.3)
    t = m.t
    m.kinetic_energy((1 + sp.Rational(1, 10) * x**2) * v**2 / 2)
    m.generalized_force(x, -k * x + sp.exp(-v) / 10 + sp.log(2 + x) / 20 + sp.tan(3 * x / 10) / 50
                        + sp.sqrt(3 + x) / 100 + (2 + x) ** sp.Float(1.7) / 100 + sp.sinh(x / 5) / 100
                        + sp.cosh(v / 10) / 100 + 3 * sp.cos(t) / (2 + x**2) / 100
                        + (2 + x) ** sp.Rational(-3, 2) / 100 + x**3 / 100 + (1 + x**2) ** k / 100 + 2**x / 100)
    return m


def test_every_recurrence_against_series_coefficients():
    """Normalized Taylor coefficients x_[2..8] at t = 0.7, x = 0.3, x' = -0.4 of a model using
    every operation kind; reference values from sympy series in 30 digits (order by order)."""
    tm, p = module(all_operations_model())
    kinds = {op.kind for op in tm.decomposition.ops}
    assert {"mul", "sqr", "div", "cdiv", "sincos", "sinhcosh", "exp", "log", "pow", "sqrt", "tan"} <= kinds
    ref = [0.3, -0.4, -0.04686657238087328, 0.08188876274720655, 0.0033666767926870496,
           -0.005741180512428886, -0.0003421140497075111, 0.00040147483794182565, 5.684598823569504e-05]
    jet = tm.jet(0.7, np.array([0.3, -0.4]), p, 8)
    assert np.abs(jet[0] - ref).max() < 1e-16
    assert np.abs(jet[1, :8] - np.arange(1, 9) * np.array(ref[1:])).max() < 1e-15


def test_difference_variables_replace_products_of_sines():
    """The double pendulum's cos(q1)cos(q2) + sin(q1)sin(q2) becomes cos(q1 - q2)."""
    d = decompose(Scene(derive(lcg.systems.n_link_pendulum(3)), jacobian=False))
    assert d.form == "trig-linearized"
    sincos_args = [d.labels[op.args[0]] for op in d.ops if op.kind == "sincos" and op.args[0] in d.labels]
    assert "y[0] - y[1]" in sincos_args and "y[1] - y[2]" in sincos_args
    assert sum(op.kind == "sincos" for op in d.ops) == 6  # 3 angles + 3 differences
    assert sum(op.kind == "mul" for op in d.ops) <= 6


@pytest.mark.parametrize("expr, name", [(sp.Abs, "Abs"), (lambda x: sp.Piecewise((x, x > 0), (0, True)), "Piecewise"),
                                        (sp.sign, "sign")])
def test_non_analytic_expressions_are_refused(expr, name):
    m = lcg.Model("kink")
    x, = m.coordinates("x")
    m.particle("b", 1, (x, 0))
    m.generalized_force(x, -expr(x))
    with pytest.raises(ModelError, match=rf"(?i)F\[x\]: it contains .*{name}\(\(?x.*not analytic"):
        taylor_code(Scene(derive(m), jacobian=False))
    with pytest.raises(ModelError, match=r"event 'e': it contains abs\(theta\)"):  # and in events
        taylor_code(Scene(derive(lcg.systems.pendulum()), jacobian=False),
                    events=[Event("e", sp.Abs(sp.Symbol("theta")) - 1)])


def test_a_run_fills_every_field_of_its_result(pendulum):
    """TaylorModule.simulate makes its Result positionally (cheaper than by keyword): every field
    must hold what its name says, the others their defaults."""
    import dataclasses

    from lagcodegen.result import Result
    tm, p = pendulum
    t = np.array([0.0, 0.5, 1.0])
    res = tm.simulate(t, np.array([0.3, 0.0]), p, rtol=1e-10, atol=1e-10)
    assert type(res) is Result
    assert res.t is t and res.y.shape == (3, 2) and res.y[0, 0] == 0.3
    assert res.state_names == ["theta", "theta_dot"] and list(res.outputs) == ["energy"]
    assert res.status == 0 and res.message == "success" and res.backend == "native" and res.method == "taylor"
    assert res.parameters == {} and res.n_coordinates == 1
    assert [e.name for e in res.events] == ["down"] and res.stats["events"] == 1  # theta = 0 once, falling
    assert res.stats["steps"] > 0 and res.stats["order"] == math.ceil(-math.log(1e-10) / 2 + 3)
    assert res.drift("energy") < 1e-9  # the run itself: energy conserved
    by_keyword = Result(t=t, y=res.y, state_names=res.state_names, outputs=res.outputs, stats=res.stats)
    for f in dataclasses.fields(Result):
        if f.name not in ("t", "y", "state_names", "outputs", "stats", "status", "message", "backend", "method",
                          "parameters", "n_coordinates", "events"):
            assert getattr(res, f.name) == getattr(by_keyword, f.name), f.name  # defaults


def test_singular_mass_matrix_and_max_steps_are_reported(pendulum):
    tm, p = module(lcg.systems.central_potential())
    res = tm.simulate(np.array([0.0, 1.0]), np.array([0.0, 0.0, 0.0, 1.0]), p, rtol=1e-8, atol=1e-8)
    assert res.status == -101 and res.message == "the mass matrix is singular" and res.stats["model_error"] == 1
    tm, p = pendulum
    res = tm.simulate(np.linspace(0, 10, 3), np.array([1.0, 0.0]), p, rtol=1e-8, atol=1e-8, max_steps=5)
    assert res.status == -1 and "max_steps = 5" in res.message and res.stats["steps"] == 5
    assert len(res.t) == 1 and res.stats["t_reached"] > 0


def test_non_finite_values_are_reported():
    m = lcg.Model("blowup")
    x, = m.coordinates("x")
    m.particle("b", 1, (x, 0))
    m.generalized_force(x, -sp.sqrt(x))  # x reaches 0 and goes negative: sqrt of a negative
    tm, p = module(m)
    res = tm.simulate(np.array([0.0, 10.0]), np.array([1.0, -1.0]), p, rtol=1e-8, atol=1e-8)
    assert res.status == -102 and res.message == "a computed value is not finite"


def generated_sources(tmp_path):
    m = all_operations_model()
    code, _, _ = taylor_code(Scene(derive(m), jacobian=False, outputs=["energy"]),
                             events=[Event("zero", sp.Symbol("x"), 0, False),
                                     Event("stop", sp.Symbol("t") - 3, 1, True)])
    code.write(tmp_path)
    red = routh_reduce(lcg.systems.central_potential())
    code2, _, _ = taylor_code(Scene(red.eom, jacobian=False, outputs=["jacobi_h"]))
    code2.write(tmp_path)
    code3, _, _ = taylor_code(Scene(derive(lcg.systems.n_link_pendulum(3)), jacobian=False))
    code3.write(tmp_path)
    return [code.prefix, code2.prefix, code3.prefix]


def test_generated_c_compiles_without_warnings(tmp_path, cc):
    for prefix in generated_sources(tmp_path):
        proc = subprocess.run([cc, "-Wall", "-Wextra", "-Werror", "-std=c99", "-pedantic", "-O2", "-c",
                               f"{prefix}_taylor.c", "-o", "/dev/null"], cwd=tmp_path, capture_output=True, text=True)
        assert proc.returncode == 0, proc.stderr
    # the header stands alone
    (tmp_path / "h.c").write_text(f'#include "{prefix}_taylor.h"\nint main(void) {{ return 0; }}\n')
    proc = subprocess.run([cc, "-Wall", "-Wextra", "-Werror", "-std=c99", "-pedantic", "h.c", "-o", "h"],
                          cwd=tmp_path, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr


def test_bundle_example_builds_with_only_a_compiler(tmp_path, cc):
    """taylor_example.c + <prefix>_taylor.c: a program; the double pendulum's energy it prints
    (an output) stays constant and its events (q1 = 0, terminal) stop the run."""
    scene = Scene(derive(lcg.systems.n_link_pendulum(2)), jacobian=False, outputs=["energy"])
    files = taylor_sources(scene, [Event("q1_zero", sp.Symbol("q1"), 0, True)], example=True, q0=0.5, t_end=5.0)
    assert sorted(files) == ["pendulum2_taylor.c", "pendulum2_taylor.h", "taylor_example.c"]
    for name, text in files.items():
        (tmp_path / name).write_text(text)
    proc = subprocess.run([cc, "-Wall", "-Wextra", "-Werror", "-std=c99", "-pedantic", "-O2", "taylor_example.c",
                           "pendulum2_taylor.c", "-lm", "-o", "ex"], cwd=tmp_path, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    run = subprocess.run(["./ex"], cwd=tmp_path, capture_output=True, text=True)
    assert run.returncode == 0, run.stdout
    lines = run.stdout.splitlines()  # a CSV; the events and the status on stderr
    assert lines[0].split(",") == ["t", "q1", "q2", "q1_dot", "q2_dot", "energy"]
    rows = [[float(x) for x in line.split(",")] for line in lines[1:]]
    energy = [r[-1] for r in rows]
    assert len(rows) >= 2 and max(energy) - min(energy) < 1e-9
    status = run.stderr.splitlines()
    assert any(line.startswith("event 0 at t = ") for line in status) and status[-1].startswith("flag 0")


SANITIZE_MAIN = r"""
#include <stdio.h>
#include "allops_taylor.h"

int main(void)
{
    double p[1] = {1.3}, y0[2] = {0.3, -0.4}, t[5] = {0.0, 0.5, 1.0, 2.0, 5.0}, yout[10], out[5];
    double et[4], ey[8];
    int which[4], dir[4];
    allops_taylor_options opt = {1e-10, 1e-10, 0, 100000, 0.0, 0};
    allops_taylor_stats st;
    allops_taylor_events ev = {4, 0, et, ey, which, dir, 0};
    int flag = allops_taylor_solve(p, y0, 5, t, yout, out, &opt, &st, &ev);
    printf("%d %ld %d %d %.17g %d\n", flag, st.nsteps, ev.n_events, ev.terminated, st.t_reached, st.nt_done);
    return flag;
}
"""


def test_sanitizers_run_clean(tmp_path, cc):
    if shutil.which(cc) is None:
        pytest.skip("no compiler")
    generated_sources(tmp_path)
    (tmp_path / "main.c").write_text(SANITIZE_MAIN)
    proc = subprocess.run([cc, "-std=c99", "-g", "-O1", "-fsanitize=address,undefined", "-fno-sanitize-recover=all",
                           "main.c", "allops_taylor.c", "-o", "run", "-lm"],  # standalone: no model.c
                          cwd=tmp_path, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    run = subprocess.run(["./run"], cwd=tmp_path, capture_output=True, text=True,
                         env={"ASAN_OPTIONS": "detect_leaks=1", "PATH": "/usr/bin:/bin"})
    assert run.returncode == 0, run.stdout + run.stderr
    flag, steps, nev, terminated, t_reached, done = run.stdout.split()
    # the terminal event t = 3 ends the run after the output at t = 2
    assert int(terminated) == 1 and abs(float(t_reached) - 3.0) < 1e-12 and int(done) == 4 and int(nev) >= 2


# --------------------------------------------------------------------------- the runtime's driver
RUNTIME_MAIN = r"""
#include <stdio.h>
#include <string.h>
#include "lcg_taylor.h"

extern const lcg_taylor_model allops_taylor_model;

int main(void)
{
    double p[2] = {1.3, 1.1}, y0[4] = {0.3, -0.4, 0.2, 0.1}, t[5] = {0.0, 0.5, 1.0, 2.0, 5.0}, yout[10], out[5];
    double et[4], ey[8], fin[2 * 3], tr[2] = {0}, wall[2];
    int which[4], dir[4], mflag[2], mdone[2], k;
    long counts[16];
    lcg_taylor_options opt;
    lcg_taylor_stats st;
    lcg_taylor_events ev = {4, 0, et, ey, which, dir, 0};
    lcg_taylor_ensemble e;
    lcg_taylor_model bad = allops_taylor_model;
    int flag;

    memset(&opt, 0, sizeof opt);
    opt.rtol = 1e-10;
    opt.atol = 1e-10;
    opt.max_steps = 100000;
    flag = lcg_taylor_solve(&allops_taylor_model, p, y0, 5, t, yout, out, &opt, &st, &ev);
    printf("%d %ld %d %d %.17g %d", flag, st.nsteps, ev.n_events, ev.terminated, st.t_reached, st.nt_done);
    for (k = 0; k < 2 * st.nt_done; ++k)
        printf(" %.17g", yout[k]);
    printf("\n");
    /* two members over two threads, no events: parameters per member, the state shared */
    memset(&e, 0, sizeof e);
    e.model = &allops_taylor_model;
    e.nmem = 2;
    e.nthreads = 2;
    e.p = p;
    e.p_stride = 1;
    e.y0 = y0;
    e.y0_stride = 0;
    e.nt = 5;
    e.tout = t;
    e.final = fin;
    e.flag = mflag;
    e.nt_done = mdone;
    e.t_reached = tr;
    e.wall = wall;
    e.counts = counts;
    flag = lcg_taylor_solve_many(&e, &opt);
    printf("%d %d %d %d %d\n", flag, mflag[0], mflag[1], mdone[0], mdone[1]);
    bad.abi = LCG_TAYLOR_ABI + 1;
    flag = lcg_taylor_solve(&bad, p, y0, 5, t, yout, out, &opt, &st, NULL);
    printf("%d %d\n", flag, lcg_taylor_jet(&bad, 0.0, y0, p, 3, yout));
    return 0;
}
"""


def runtime_sources_of(tmp_path, scene, events=()):
    from lagcodegen.codegen.taylor.emit import jet_sources, runtime_sources
    files = {**runtime_sources(), **jet_sources(scene, events)}
    for name, text in files.items():
        (tmp_path / name).write_text(text)
    return [name for name in files if name.endswith(".c")]


def test_runtime_driver_and_jets_compile_strictly(tmp_path, cc):
    scenes = [Scene(derive(all_operations_model()), jacobian=False, outputs=["energy"]),
              Scene(routh_reduce(lcg.systems.central_potential()).eom, jacobian=False, outputs=["jacobi_h"]),
              Scene(derive(lcg.systems.n_link_pendulum(3)), jacobian=False)]
    events = [[Event("zero", sp.Symbol("x"), 0, False)], [], []]
    for sc, ev in zip(scenes, events):
        for src in runtime_sources_of(tmp_path, sc, ev):
            proc = subprocess.run([cc, "-Wall", "-Wextra", "-Werror", "-std=c99", "-pedantic", "-O2", "-c", src,
                                   "-o", "/dev/null"], cwd=tmp_path, capture_output=True, text=True)
            assert proc.returncode == 0, src + proc.stderr


def test_runtime_driver_runs_clean_under_sanitizers_and_as_the_standalone_one(tmp_path, cc):
    """lcg_taylor.c with the jet of the all-operations model under ASan/UBSan: a run with events
    (the terminal one at t = 3), an ensemble of two members (k = 1.3, 1.1) over two threads, a table
    of another version refused; the run's numbers are those of the standalone integrator of the same
    scene, bit for bit."""
    m = all_operations_model()
    sc = Scene(derive(m), jacobian=False, outputs=["energy"])
    events = [Event("zero", sp.Symbol("x"), 0, False), Event("stop", sp.Symbol("t") - 3, 1, True)]
    sources = runtime_sources_of(tmp_path, sc, events)
    assert len(sc.default_parameters()) == 1  # k; main.c's p[1] is the second member's k
    (tmp_path / "main.c").write_text(RUNTIME_MAIN)
    san = ["-std=c99", "-g", "-O1", "-fsanitize=address,undefined", "-fno-sanitize-recover=all"]
    proc = subprocess.run([cc, *san, "main.c", *sources, "-o", "run", "-lm", "-pthread"], cwd=tmp_path,
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    env = {"ASAN_OPTIONS": "detect_leaks=1", "PATH": "/usr/bin:/bin"}
    run = subprocess.run(["./run"], cwd=tmp_path, capture_output=True, text=True, env=env)
    assert run.returncode == 0, run.stdout + run.stderr
    single, many, bad = run.stdout.splitlines()
    flag, steps, nev, terminated, t_reached, done, *ys = single.split()
    assert int(terminated) == 1 and abs(float(t_reached) - 3.0) < 1e-12 and int(done) == 4 and int(nev) >= 2
    assert many.split() == ["0", "0", "0", "4", "4"]  # the terminal event at t = 3 ends both members
    assert bad.split() == ["-22", "-22"]
    # the standalone integrator of the same scene (taylor.c.j2: the same driver text, sizes as constants)
    for name, text in taylor_sources(sc, events).items():
        (tmp_path / name).write_text(text)
    (tmp_path / "alone.c").write_text(SANITIZE_MAIN.replace('%d\\n", flag', '%d", flag').replace(
        "    return flag;", "    for (int k = 0; k < 2 * st.nt_done; ++k)\n        printf(\" %.17g\", yout[k]);\n"
        "    printf(\"\\n\");\n    return flag;"))
    proc = subprocess.run([cc, *san, "alone.c", "allops_taylor.c", "-o", "alone", "-lm"], cwd=tmp_path,
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    alone = subprocess.run(["./alone"], cwd=tmp_path, capture_output=True, text=True, env=env)
    assert alone.returncode == 0, alone.stdout + alone.stderr
    assert alone.stdout.split() == single.split()


def test_runtime_and_per_model_builds_agree_bit_for_bit():
    """build_taylor (the runtime's driver over the model's jet) and build_taylor(runtime=False) (the
    per-model integrator): the same states, outputs, events and statistics, a quadrature state too."""
    cases = [(lcg.systems.pendulum(), ["energy"], [Event("down", sp.Symbol("theta"), 0, False),
                                                  Event("up", sp.Symbol("theta"), 1, True)], [1.0, 0.0]),
             (routh_reduce(lcg.systems.central_potential()).eom, ["jacobi_h"], [], [1.0, 0.0, 0.0])]
    for model, outputs, events, y0 in cases:
        eom = derive(model) if isinstance(model, lcg.Model) else model
        sc = Scene(eom, jacobian=False, outputs=outputs)
        a, b = build_taylor(sc, events=events), build_taylor(sc, events=events, runtime=False)
        assert a.table is not None and b.table is None
        y0 = np.array(y0)
        p = np.array(sc.default_parameters(), dtype=float)
        if a.code.nz:  # the reduced Kepler problem: C_phi = r^2 phi' = 1.3 (test_quadrature_state_...)
            p = np.array([1.3 if k == "C_phi" else v for k, v in zip(a.param_names, p)])
        t = np.linspace(0.0, 7.0, 15)
        ra, rb = (m.simulate(t, y0, p, rtol=1e-11, atol=1e-11) for m in (a, b))
        assert ra.status == rb.status == 0 and ra.stats == rb.stats and ra.stats["steps"] > 10
        assert np.array_equal(ra.t, rb.t) and np.array_equal(ra.y, rb.y)
        assert all(np.array_equal(ra.outputs[k], rb.outputs[k]) for k in outputs)
        assert [(e.t, e.index) for e in ra.events or []] == [(e.t, e.index) for e in rb.events or []]
        assert np.array_equal(a.jet(0.3, y0, p, 9), b.jet(0.3, y0, p, 9))


def test_step_cap_macro_moves_the_steps_and_keeps_the_order():
    """LCG_TAYLOR_CAP (the step's cap h <= rho e^-c, templates/taylor/_driver.j2) through
    build_taylor's cflags: compiled as 1.7 the standalone driver is the default one bit for bit; a
    looser cap (1.0) takes fewer, longer steps of the same order, a tighter one (2.4) more, and each
    still follows the closed-form pendulum (the loose one to a looser error, as documented). The
    runtime's driver, compiled once, refuses the macro rather than ignore it."""
    sc = Scene(derive(lcg.systems.pendulum()), jacobian=False)
    with pytest.raises(lcg.LagcodegenError, match="runtime=False"):
        build_taylor(sc, cflags=(*DEFAULT_CFLAGS, "-DLCG_TAYLOR_CAP=1.3"))
    p = np.array(sc.default_parameters(), dtype=float)
    caps = {c: build_taylor(sc, runtime=False, cflags=(*DEFAULT_CFLAGS, f"-DLCG_TAYLOR_CAP={c}"))
            for c in ("1.0", "1.7", "2.4")}
    default = build_taylor(sc, runtime=False)
    t = np.linspace(0.0, 10.0, 11)
    theta, omega = exact_pendulum(t, 1.0, math.sqrt(9.81))
    y0 = np.array([1.0, 0.0])
    runs = {c: m.simulate(t, y0, p, rtol=1e-4, atol=1e-4) for c, m in caps.items()}
    ref = default.simulate(t, y0, p, rtol=1e-4, atol=1e-4)
    assert np.array_equal(runs["1.7"].y, ref.y) and runs["1.7"].stats == ref.stats
    steps = [runs[c].stats["steps"] for c in ("1.0", "1.7", "2.4")]
    assert steps[0] < 0.8 * steps[1] and steps[2] > 1.2 * steps[1], steps
    assert len({runs[c].stats["order"] for c in runs}) == 1
    err = {c: max(np.abs(r.y[:, 0] - theta).max(), np.abs(r.y[:, 1] - omega).max()) for c, r in runs.items()}
    # tol 1e-4: below it at 1.7, within a few times it at 1.0 (err/tol up to 3.3 on the n-link pendulum)
    assert err["2.4"] < err["1.7"] < 1e-4 and err["1.7"] < err["1.0"] < 5e-4, err


def test_runtime_refuses_a_table_of_another_version_and_keeps_max_wall():
    tm, p = module(lcg.systems.pendulum())
    ffi, lib = tm.ffi, tm.lib
    bad = ffi.new("lcg_taylor_model *", tm.table[0])
    bad.abi = lib.LCG_TAYLOR_ABI + 1
    opt, st = ffi.new("lcg_taylor_options *"), ffi.new("lcg_taylor_stats *")
    opt.rtol = opt.atol = 1e-8
    opt.max_steps = 100
    y0, t, yout = np.array([1.0, 0.0]), np.array([0.0, 1.0]), np.empty((2, 2))
    buf = ffi.from_buffer
    flag = lib.lcg_taylor_solve(bad, buf("double[]", p), buf("double[]", y0), 2, buf("double[]", t),
                                buf("double[]", yout), ffi.NULL, opt, st, ffi.NULL)
    assert flag == -22 and "another layout" in ffi.string(st.message).decode()
    with pytest.raises(lcg.LagcodegenError, match="y has 1 values, expected 2"):
        tm.jet(0.0, [1.0], p, 3)
    with pytest.raises(lcg.LagcodegenError, match="order must be 1..30"):
        tm.jet(0.0, y0, p, 31)
    # the runtime's run control: each member of a Taylor ensemble stops at its wall-clock limit
    sim = lcg.compile_model(lcg.systems.pendulum(), jacobian=False)
    ens = sim.ensemble((0.0, 1e7), q0=[[1.0], [0.5]], method="taylor", max_wall=0.05, rtol=1e-12, atol=1e-12,
                       max_steps=10**9, threads=1)
    assert list(ens.status) == [-81, -81]


def test_fused_products_give_the_same_jets_and_runs_bit_for_bit(monkeypatch):
    """Products used by one linear combination only are summed in its loop ("dot"), and the mass
    matrix's convolutions of a row share one loop: the same sums in the same order, so the jet and
    a whole run equal those of the unfused operations to the last bit."""
    from lagcodegen.codegen.taylor import emit
    cases = [(lcg.systems.n_link_pendulum(3, name="fused3"), [0.4, -0.3, 0.2, 0.1, 0.5, -0.2]),
             (all_operations_model(), [0.3, -0.4])]
    for model, y0 in cases:
        sc = Scene(derive(model), jacobian=False)
        fused, plain = decompose(sc), decompose(sc, fuse=False)
        assert any(op.kind == "dot" for op in fused.ops)
        assert sum(op.kind == "mul" for op in fused.ops) < sum(op.kind == "mul" for op in plain.ops)
        assert fused.cost == pytest.approx(plain.cost)
        a = build_taylor(sc)
        monkeypatch.setattr(emit, "decompose", lambda *args, **kw: decompose(*args, fuse=False, **kw))
        b = build_taylor(sc)
        monkeypatch.undo()
        assert a.decomposition.ops != b.decomposition.ops
        p = np.array(sc.default_parameters(), dtype=float)
        y0 = np.array(y0)
        assert np.array_equal(a.jet(0.7, y0, p, 12), b.jet(0.7, y0, p, 12))
        t = np.linspace(0.0, 3.0, 7)
        ra, rb = (m.simulate(t, y0, p, rtol=1e-10, atol=1e-10) for m in (a, b))
        assert ra.status == rb.status == 0 and ra.stats["steps"] > 5
        assert np.array_equal(ra.y, rb.y)


def test_sine_and_cosine_squares_cancel_in_the_mass_matrix():
    """sin(q)^2 + cos(q)^2 of a Cartesian derivation is linearized to 1: the n-link pendulum's
    mass matrix has a constant diagonal (M_ii = n - i for unit masses and lengths) and
    convolutions only for its off-diagonal entries."""
    from lagcodegen.codegen.taylor.decompose import Const, linearize_trig
    import symengine as se
    x = se.Symbol("x")
    assert se.expand(linearize_trig(3 * se.sin(x) ** 2 + 3 * se.cos(x) ** 2) - 3) == 0
    assert se.expand(linearize_trig(se.sin(x) ** 2) - (se.Rational(1, 2) - se.cos(2 * x) / 2)) == 0
    n = 5
    d = decompose(Scene(derive(lcg.systems.n_link_pendulum(n)), jacobian=False))
    assert all(isinstance(d.M[i][i], Const) for i in range(n))
    assert sum(isinstance(e, int) for row in d.M for e in row) == n * (n - 1)
    assert not any(op.kind == "sqr" and "sin(" in d.labels.get(op.out[0], "") for op in d.ops)


def test_trig_linearization_leaves_long_products_and_huge_sums_alone():
    """A product of more than MAX_TRIG_FACTORS sines and cosines stays a product (k factors
    would become 2^(k-1) terms), and a sum whose expansion exceeds MAX_LINEARIZED_TERMS is
    returned as given: the closed forms of a six-joint arm's forces (10^4 terms of up to 14
    such factors) otherwise took minutes to linearize."""
    import symengine as se
    from lagcodegen.codegen.taylor.decompose import MAX_LINEARIZED_TERMS, MAX_TRIG_FACTORS, linearize_trig
    xs = se.symbols(f"x0:{MAX_TRIG_FACTORS + 1}")
    long_product = se.Mul(*[se.sin(x) for x in xs])
    assert linearize_trig(long_product) == long_product
    short = se.Mul(*[se.sin(x) for x in xs[:2]])
    assert se.expand(linearize_trig(short) - (se.cos(xs[0] - xs[1]) - se.cos(xs[0] + xs[1])) / 2) == 0
    y = se.Symbol("y")
    huge = se.Add(*[se.Integer(k) * y ** k * se.sin(y) ** 2 for k in range(1, MAX_LINEARIZED_TERMS + 2)])
    assert linearize_trig(huge) is huge


def _shared_tower(levels: int):
    """y[0], then e -> sin(e) * e + e ``levels`` times: a few nodes per level as a DAG, about
    3^levels as a printed tree."""
    import symengine as se
    e = se.Symbol("y[0]")
    for _ in range(levels):
        e = se.sin(e) * e + e
    return e


def test_labels_of_large_shared_expressions_are_sketched_not_printed():
    """A label (or a message) prints an expression only up to LABEL_NODES tree nodes: the shared
    subexpressions of a rigid-body chain print as trees exponential in the joints (a 12-joint
    chain's jet had not finished after 395 s, nearly all of it printing 60-character labels)."""
    import importlib

    import symengine as se
    D = importlib.import_module("lagcodegen.codegen.taylor.decompose")
    small = _shared_tower(2)
    assert D._short(small, 1000) == str(small)  # small ones as before: today's generated code unchanged
    large = _shared_tower(12)  # about 10^5 nodes as a tree: not printed
    assert D._short(large) == f"sum of {len(large.args)} terms"
    assert D._short(se.cos(large)) == "cos(...)"
    assert D._tree_size(_shared_tower(60), D.LABEL_NODES) == D.LABEL_NODES + 1  # 10^28 nodes: stops at the cap


def test_trig_linearization_does_not_expand_what_would_be_dropped(monkeypatch):
    """An expression whose expansion is bounded above MAX_EXPANSION_BOUND terms is returned as
    given without calling expand (an 8-joint chain's forces: 2.4 million products, 27 s each,
    then dropped); the bound multiplies out sums, products and integer powers and stops at
    the cap."""
    import symengine as se
    from lagcodegen.codegen.taylor.decompose import MAX_EXPANSION_BOUND, expansion_bound, linearize_trig
    a, b, c, d, e = se.symbols("a b c d e")
    assert expansion_bound((a + b) * (c + d + e)) == 6
    assert expansion_bound((a + b) ** 3 * se.sin(a + b)) == 8
    assert expansion_bound(((a + b) * c + d) * e + 1) == 4
    sums = [se.Add(*se.symbols(f"x{k}_0:10")) for k in range(6)]
    big = se.Mul(*sums) * se.sin(a) * se.cos(b)  # 10^6 products
    assert expansion_bound(big) == MAX_EXPANSION_BOUND + 1

    def expand(expr):
        raise AssertionError("expanded an expression above MAX_EXPANSION_BOUND")
    monkeypatch.setattr(se, "expand", expand)
    assert linearize_trig(big) is big
    tower = _shared_tower(60)  # 2^60 products as a tree: the bound's walk stops at the cap
    assert expansion_bound(tower) == MAX_EXPANSION_BOUND + 1
    assert linearize_trig(tower) is tower


def test_decomposition_is_a_progress_stage_that_ctrl_c_stops():
    """decompose reports the stage "taylor", one step per expression (M, F, rates, events) of each
    form: the loop point where a progress callback's exception (Ctrl-C's KeyboardInterrupt)
    stops a long decomposition."""
    from lagcodegen import progress
    eom = derive(lcg.systems.double_pendulum())
    calls = []

    def record(stage, done, total, elapsed):
        calls.append((stage, done, total))
    with progress.enabled(record):
        decompose(Scene(eom, jacobian=False))
    taylor = [c for c in calls if c[0] == "taylor"]
    assert taylor and {c[2] for c in taylor} == {3 + 2}  # M's upper triangle and F
    assert max(c[1] for c in taylor) == 5

    def interrupt(stage, done, total, elapsed):
        if stage == "taylor" and done == 2:
            raise KeyboardInterrupt
    with pytest.raises(KeyboardInterrupt), progress.enabled(interrupt):
        decompose(Scene(eom, jacobian=False))
