"""The Bari test-set problems of benchmarks/bari_problems.py: lagcodegen's system and the numpy
transcription are two derivations of the same equations, and lagcodegen integrates both problems
to the published reference solutions."""

import math
import sys
from pathlib import Path

import numpy as np
import pytest
import symengine as se

from lagcodegen.api import compile_constrained
from lagcodegen.derivation import derive

BENCH = Path(__file__).resolve().parent.parent / "benchmarks"
sys.path.insert(0, str(BENCH))

import bari_problems as BP  # noqa: E402

NAMES = ("andrews", "caraxis")


def random_state(pr, seed=7):
    rng = np.random.default_rng(seed)
    return pr.q0 + 0.3 * rng.standard_normal(pr.n), rng.standard_normal(pr.n), 0.37


def numbers(system, eom, q, v, t):
    """lagcodegen's M, F (symengine, from the bodies and forces) and A, f, gamma (sympy, from the
    constraints) at (q, v, t)."""
    m = system.model
    vals = {**dict(zip(m.coords, q)), **dict(zip(m.speeds, v)), **m.params, m.t: t}
    se_vals = {se.Symbol(s.name): float(x) for s, x in vals.items()}
    M = np.array([[float(se.sympify(e).subs(se_vals)) for e in row] for row in eom.M_se])
    F = np.array([float(se.sympify(e).subs(se_vals)) for e in eom.F_se])
    A = np.array(system.A.subs(vals).evalf(), dtype=float)
    g = np.array([float(f.subs(vals)) for f in system.holonomic])
    gamma = np.array(system.acceleration_rhs().subs(vals).evalf(), dtype=float).ravel()
    return M, F, A, g, gamma


@pytest.mark.parametrize("name", NAMES)
def test_transcription_matches_lagcodegens_derivation(name):
    """M, f from the bodies (lagcodegen's Lagrange equations) equal the published M, f; g, G and
    the second-derivative terms equal lagcodegen's constraint rows and gamma = -gdd."""
    pr = BP.PROBLEMS[name]()
    system = pr.system(f"tb_{name}")
    eom = derive(system.model)
    q, v, t = random_state(pr)
    M, F, A, g, gamma = numbers(system, eom, q, v, t)
    Mn, fn, gn, Gn, gdd = pr.numeric(q, v, t)
    assert np.max(np.abs(M - Mn)) <= 1e-12 * np.max(np.abs(Mn))
    assert np.max(np.abs(F - fn)) <= 1e-12 * np.max(np.abs(fn))
    assert np.max(np.abs(A - Gn)) <= 1e-12 * np.max(np.abs(Gn))
    assert np.max(np.abs(g - gn)) <= 1e-12 * max(1.0, np.max(np.abs(gn)))
    assert np.max(np.abs(gamma + gdd)) <= 1e-12 * np.max(np.abs(gdd))


@pytest.mark.parametrize("name", NAMES)
def test_second_derivative_terms_by_differences(name):
    """gdd = d^2 g(q + s v, t + s)/ds^2 at s = 0 (central differences), and G = dg/dq."""
    pr = BP.PROBLEMS[name]()
    q, v, t = random_state(pr, seed=3)
    h = 1e-4
    g = [pr.g(q + s * v, t + s) for s in (-h, 0.0, h)]
    assert np.allclose((g[0] - 2 * g[1] + g[2]) / h**2, pr.gdd(q, v, t), rtol=1e-5, atol=1e-5)
    G = np.array([(pr.g(q + h * e, t) - pr.g(q - h * e, t)) / (2 * h) for e in np.eye(pr.n)]).T
    assert np.allclose(G, pr.G(q, t), rtol=1e-6, atol=1e-8)


def test_initial_values_are_consistent_and_give_the_published_accelerations():
    """Andrews: g(q0) = 0, and [M -G^T; G 0] gives the description's q''(0) and lambda(0)."""
    pr = BP.andrews()
    assert np.max(np.abs(pr.g(pr.q0))) < 1e-15
    acc, lam = pr.kkt(pr.q0, pr.v0)
    assert np.allclose(acc, pr.extra["a0"], rtol=1e-12, atol=1e-9)
    assert np.allclose(lam, pr.extra["lambda0"], rtol=1e-12, atol=1e-12)
    car = BP.caraxis()
    assert np.max(np.abs(car.g(car.q0, 0.0))) == 0.0
    # d/dt g_1 = G v + dg_1/dt: xb' = 0, yb' = r w at t = 0
    gdot = car.G(car.q0, 0.0) @ car.v0 + np.array([car.params["r"] * car.params["w"] * car.q0[1], 0.0])
    assert np.max(np.abs(gdot)) < 1e-15


@pytest.fixture(scope="module", params=NAMES)
def compiled(request):
    pr = BP.PROBLEMS[request.param]()
    system = pr.system(f"tb_{request.param}")
    return pr, {form: compile_constrained(system, form) for form in ("index1", "ggl")}


def test_compiled_augmented_system_matches_the_transcription(compiled):
    """The generated solve (Schur complement of the positive definite M) against numpy's LU of
    the transcription's whole augmented matrix, at 20 random states."""
    pr, sims = compiled
    for seed in range(20):
        q, v, t = random_state(pr, seed=11 + seed)
        acc, lam = sims["index1"].kkt(t, np.concatenate([q, v]))
        acc_n, lam_n = pr.kkt(q, v, t)
        assert np.max(np.abs(acc - acc_n)) <= 1e-11 * np.max(np.abs(acc_n))
        assert np.max(np.abs(lam - lam_n)) <= 1e-11 * np.max(np.abs(lam_n))


CASES = [("index1", {}), ("index1", {"method": "bdf", "baumgarte": (1e3, 1e3)}), ("ggl", {})]


@pytest.mark.parametrize("form,opts", CASES, ids=["index1-default", "index1-bdf-baumgarte", "ggl"])
def test_end_point_matches_the_published_reference(compiled, form, opts):
    """At rtol 1e-10 every formulation lands on the published state at t1: positions to 1e-6,
    velocities to 1e-5 of the largest, multipliers to 1e-4 (relative, per
    component). (The published Andrews
    reference itself is good to ~3e-10, 5e-8 and 1e-6 in these: see bari_problems.)"""
    pr, sims = compiled
    res = sims[form].simulate(np.array([pr.t0, pr.t1]), q0=pr.q0, v0=pr.v0, rtol=1e-10, atol=1e-10, **opts)
    assert res.success and math.isclose(res.t[-1], pr.t1)
    q, v = res.y[-1, :pr.n], res.y[-1, pr.n:2 * pr.n]
    lam = np.array([res[f"lambda_{j}"][-1] for j in range(pr.nc)])
    assert pr.position_error(q) < 1e-6
    assert np.max(np.abs(v - pr.ref_v)) < 1e-5 * np.max(np.abs(pr.ref_v))
    assert pr.multiplier_error(lam) < 1e-4
    assert np.max(np.abs(pr.g(q, pr.t1))) < 1e-7


def test_benchmark_runs_on_a_tiny_configuration():
    """benchmarks/bari.py stays runnable: one problem, three contenders, one tolerance."""
    import bari
    settings = bari.Settings(rtols=[1e-6], rounds=1, budget=2.0, problems=("pendulum",),
                             contenders=r"^lcg index-1 Adams$|^lcg GGL IDA$|LSODA", quick=True)
    pr, contenders, rows, ref_lines = bari.measure_problem("pendulum", settings)
    assert {r["contender"] for r in rows} == {"lcg index-1 Adams", "lcg GGL IDA", "scipy LSODA index-1 ODE"}
    for r in rows:
        assert r["status"] == "ok" and r["err"] < 1e-2 and r["wall_ms"] > 0 and r["drift"] < 1e-2
    summ = bari.summarize(pr, contenders, rows)
    assert "lcg index-1 Adams" in bari.summary_table(summ)
