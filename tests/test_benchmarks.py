"""The benchmark instruments stay runnable: one tiny configuration of each script's main pieces
(a few seconds each; the --quick modes run in CI separately), and the band solver and sparse
Jacobian the benchmarks measure."""

import math
import sys
from pathlib import Path
from types import SimpleNamespace

import pytest

from lagcodegen import systems


BENCH = Path(__file__).resolve().parent.parent / "benchmarks"
sys.path.insert(0, str(BENCH))

import _harness as H  # noqa: E402


def finite(value) -> bool:
    return isinstance(value, (int, float)) and math.isfinite(value)


def test_c_harness_times_every_function(tmp_path):
    from lagcodegen import Scene, build_code, derive, generate_c
    chain = build_code(generate_c(Scene(derive(systems.spring_chain(8, 1e4, name="tb_chain")), sparse_jacobian=True,
                                   prefix="tb_chain")))
    costs = H.c_call_costs(chain.code, tmp_path, SimpleNamespace(repeats=1, c_target=0.005))
    assert set(costs) == {"rhs", "jac", "jac_sparse"} and all(finite(v) and v > 0 for v in costs.values())


def test_time_at_interpolates_and_bounds():
    pts = [(1e-3, 1.0), (1e-7, 3.0)]
    assert H.time_at(pts, 1e-5)[0] == pytest.approx(math.sqrt(3.0))
    assert H.time_at([(1e-9, 2.0)], 1e-6) == (2.0, "bound")
    assert H.time_at([(1e-3, 2.0)], 1e-6) == (None, "")


# --------------------------------------------------------------------------- scripts
def test_work_precision_tiny():
    import work_precision as wp
    settings = wp.Settings(rtols=[1e-4, 1e-7], repeats=1, budget=2.0, ref_rtol=1e-10, check_rtol=1e-9,
                           scenes=("pendulum",), contenders=r"CVODE Adams jac \(native\)|scipy DOP853 \(cm|lambdify")
    scene, rows = wp.run_scene("pendulum", settings)
    assert {r["contender"] for r in rows} == {"CVODE Adams jac (native)", "scipy DOP853 (cm.rhs)",
                                              "scipy DOP853 (lambdify)"}
    for r in rows:
        assert r["status"] == "ok"
        assert all(finite(r[k]) for k in ("wall_ms", "err_final", "err_max", "evals"))
    native = [r["err_max"] for r in rows if r["contender"].startswith("CVODE")]
    assert native[1] < native[0]  # tighter rtol, smaller error
    text = wp.report(settings, ("0", "0"), [(scene, rows)])
    assert "WINNERS" in text and "ms @ 1e-04" in text


def test_work_precision_constrained_and_chain_scenes_build():
    import work_precision as wp
    settings = wp.Settings(rtols=[1e-5], repeats=1, budget=2.0, ref_rtol=1e-9, check_rtol=1e-8,
                           contenders=r"GGL \(native|band sparse jac")
    for key in ("constrained", "chain"):
        scene, rows = wp.run_scene(key, settings)
        assert rows and all(r["status"] == "ok" and finite(r["err_max"]) for r in rows), rows


def test_stress_sections_tiny():
    import stress
    limits = []
    rows = stress.section_c(True, limits) + stress.section_d(True, limits)[0]
    assert {r["section"] for r in rows} == {"C", "D"}
    for r in rows:
        if r["section"] == "C":
            assert r["status"] == "ok" and all(finite(r[k]) for k in ("wall_s", "steps", "rhs_evals"))
    text = stress.report(rows, limits, {"lyapunov": 1.0}, ("0", "0"))
    assert "LIMITS" in text and "Adams/BDF steps" in text
    assert stress.turning_theta(0.5, 1e-6) == pytest.approx(1e-6 / math.sqrt(2 * 9.81 * (1 - math.cos(0.5))),
                                                            rel=1e-3)


def test_pruning_one_variant(tmp_path):
    import pruning
    v = pruning.Variant("jacobian", "double pendulum", systems.double_pendulum("tb_pr"), dict(jacobian=True),
                        dict(method="adams", rtol=1e-6, atol=1e-8), [0.5, 0.5], [0, 0], T=1.0)
    row = pruning.measure(v, 0, SimpleNamespace(repeats=1, c_target=0.005), tmp_path, sim_repeats=1)
    for key in ("bytes", "lines", "gen_s", "compile_s", "rhs_ns", "jac_ns", "sim_ms", "steps"):
        assert finite(row[key]), key
    assert "RHS [ns]" in H.format_table(pruning.COLUMNS, [row])


def test_native_overhead_double_pendulum(tmp_path):
    import native_overhead as no
    rows = no.measure("double pendulum", systems.double_pendulum("tb_ovh"), 1, tmp_path)
    assert len(rows) == len(no.CONFIGS)
    for r in rows:
        assert r["steps"] == r["hand_steps"] and r["max_dy"] == 0.0
        assert all(finite(r[k]) and r[k] > 0 for k in ("hand_ms", "driver_ms", "simulate_ms", "driver_ratio"))


@pytest.mark.parametrize("peer", ["lagcodegen", "sympy", "casadi", "pydy"])
def test_peers_one_link(tmp_path, peer):
    import peers
    if peers.available().get(peer):
        pytest.skip(peers.available()[peer])
    ctx = peers.context(1, [1e-5, 1e-8], SimpleNamespace(repeats=1, c_target=0.005), 5.0)
    res = peers.RUNNERS[peer](1, ctx, tmp_path)
    assert finite(res["derive_s"]) and finite(res["codegen_s"])
    assert finite(res.get("rhs_c_ns") or res.get("rhs_py_ns"))
    errs = [e for e, _ in res["points"]]
    assert all(finite(e) for e in errs) and errs[1] < errs[0]


def test_taylor_contacts_tiny():
    """benchmarks/taylor_contacts.py: both impact drivers run the ball; errors against the closed form."""
    import taylor_contacts as tc
    methods = {"CVODE Adams": "adams", "Taylor": "taylor"}
    rows = tc.measure(tc.ball(), methods, [1e-6], 1)
    assert [r["method"] for r in rows] == list(methods)
    assert all(finite(r["error"]) and r["error"] < 1e-2 and r["s"] > 0 for r in rows)
    eq = tc.equal_error(rows, methods, [1e-2])
    assert eq[0]["Taylor how"] == "bound"


def test_taylor_runtime_one_link():
    """benchmarks/taylor_runtime.py: both Taylor builds run (bit-identical, else it exits) and build."""
    import taylor_runtime as tr
    rows = tr.run_times(1, [1e-6], rounds=1, batch=0.001)
    assert rows[0]["identical"] and rows[0]["steps"] > 10
    assert finite(rows[0]["per_model_us"]) and finite(rows[0]["runtime_us"]) and rows[0]["ratio"] > 0
    cold = tr.build_times(1, 1)
    assert [r["kind"] for r in cold] == ["per-model", "runtime"] and all(finite(r["total"]) for r in cold)


def test_taylor_order_cap_study_one_link():
    """benchmarks/taylor_order.py --caps: the cap 1.7 is its own base (every ratio 1), a looser cap's
    sweep ends further from the exact state than 1.7's (its longer steps), and its ratios are finite.
    Its reference is heyoka's (the [bench] extra; .ci/run's second step runs it)."""
    pytest.importorskip("heyoka")
    import taylor_order as to
    label, rows, overall = to.study([1], caps=[1.2], tols=[10.0 ** (-k / 2) for k in range(4, 21)], seconds=0.02,
                                    rounds=1)
    assert label == "cap" and {r["cap"] for r in rows} == {1.2, 1.7} and len(rows) == 4
    base = [r for r in rows if r["cap"] == 1.7]
    assert all(r[f"{t:.0e}"] in (None, 1.0) for r in base for t in to.TARGETS)
    by = {o["cap"]: o for o in overall}
    assert by[1.7]["geo"] == 1.0 and finite(by[1.2]["geo"]) and by[1.2]["cells"] >= 8
    assert by[1.2]["med"] > by[1.7]["med"] and by[1.2]["max"] > by[1.7]["max"]


def test_integrator_overhead_pendulum():
    """benchmarks/integrator_overhead.py: every call measured on both families, overheads computed."""
    import integrator_overhead as io
    sim = io.lcg.compile_model(io.systems.n_link_pendulum(1, name="ovh_test"))
    rows = []
    for method in ("taylor", "adams"):
        rows += io.rows_of("pendulum", 1, method, 1e-3, io.measure(sim, method, 1e-3, rounds=1, batch=0.002))
    assert {r["call"] for r in rows} == {"propagate_for", "closed loop", "propagate_grid", "propagate_grid, out=",
                                         "step", "simulate", "simulate, full path", "module run"}
    assert {r["method"] for r in rows if r["call"] == "module run"} == {"taylor"}  # the Taylor family's layer
    assert all(finite(r["call_us"]) and r["call_us"] > 0 and finite(r["overhead_us"]) for r in rows)


def test_events_every_contender_finds_the_crossings():
    import events
    import lagcodegen as lcg
    sim = lcg.compile_model(systems.pendulum("tb_events"))
    exact = events.exact_crossings()
    for name, run in events.contenders(sim).items():
        found = run(1e-8)
        if found is not None:  # the run without events finds nothing
            assert len(found) == len(exact) == 15, name
            assert max(abs(found - exact) / exact) < 1e-5, name


def test_taylor_benchmark_heyoka_forms_agree_with_lagcodegen():
    """benchmarks/taylor.py: the explicit system q'' = M^-1 F eliminated by hand and heyoka's own
    Lagrangian form are the same dynamics (final states agree), and so is lagcodegen's Taylor
    integrator of its own derivation; the operation counts are read."""
    pytest.importorskip("heyoka")
    import numpy as np
    import lagcodegen as lcg
    import taylor as tb
    n, q0, t_end = 3, 1.0, 2.0
    states = []
    for form in tb.HEYOKA_FORMS:
        ta, perm = tb.heyoka_integrator(form, n, 1e-14, q0)
        ta.propagate_until(t_end)
        states.append(np.array(ta.state)[perm])
    sim = lcg.compile_model(lcg.systems.n_link_pendulum(n, name="tbq3"))
    res = sim.simulate(np.array([0.0, t_end]), y0=np.r_[np.full(n, q0), np.zeros(n)], method="taylor",
                       rtol=1e-13, atol=1e-13)
    assert np.abs(states[0] - states[1]).max() < 1e-10
    assert np.abs(res.y[-1] - states[0]).max() < 1e-9
    assert np.abs(states[0]).max() > 0.5  # it moved
    ops = tb.our_operations(sim)
    assert ops["conv"] == n * (n - 1) and ops["ops"] > 0 and "sincos" in ops["kinds"]


def test_sensitivities_tiny():
    """benchmarks/sensitivities.py: accuracy against central differences, cost ratios and the fit
    comparison run on the double pendulum (p = 1) and the damped pendulum."""
    import sensitivities as sb
    import lagcodegen as lcg
    model = systems.double_pendulum(name="tb_sens_dp")
    sim = lcg.compile_model(model)
    acc = sb.accuracy_rows("dp", model, sim, [1], quick=True)
    assert acc[0]["vs_central"] < 1e-5
    assert acc[0]["vs_casadi"] is None or acc[0]["vs_casadi"] < 1e-5
    rows, _ = sb.cost_rows("dp", model, sim, [1], rounds=1)
    assert all(finite(rows[0][k]) and rows[0][k] > 0 for k in ("plain_ms", "sens_ms", "ratio", "ratio_errcon_off"))
    fits = sb.fit_rows(1)
    assert abs(fits[0]["l"] - 1.0) < 0.01 and abs(fits[1]["c"] - 0.3) < 0.01 and fits[0]["speedup"] > 0


def test_sensitivity_correctors_tiny():
    """benchmarks/sensitivity_correctors.py: the counts and the cost of both correctors on the
    double pendulum (p = 1)."""
    import sensitivity_correctors as sc
    rows = sc.rows_of("dp", systems.double_pendulum(name="tb_sens_dp"), (1,), rounds=1)
    assert [r["corrector"] for r in rows] == ["plain", "staggered", "simultaneous", "staggered", "simultaneous"]
    assert all(r["steps"] > 10 and finite(r["ratio"]) and r["ratio"] > 0 for r in rows)
    stag, simu = rows[1], rows[2]
    assert stag["states_rhs"] >= 1.0 and simu["states_rhs"] is None
    assert 1.0 <= stag["sens_rhs"] < simu["sens_rhs"]  # the staggered one evaluates the directions less often


def test_sensitivities_taylor_tiny():
    """benchmarks/sensitivities.py --taylor: the Taylor cost ratio and the comparison with CVODE
    at equal error on the double pendulum (p = 1, two tolerances)."""
    import sensitivities as sb
    import lagcodegen as lcg
    sim = lcg.compile_model(systems.double_pendulum(name="tb_sens_dp"))
    rows = sb.taylor_cost_rows("dp", sim, [1], rounds=1)
    assert all(finite(rows[0][k]) and rows[0][k] > 0 for k in ("plain_ms", "sens_ms", "ratio", "ratio_errcon_off"))
    assert rows[0]["steps"] >= rows[0]["steps_plain"] > 0
    equal, points = sb.taylor_vs_cvode_rows("dp", sim, 1, 1, tolerances=(1e-6, 1e-9))
    assert len(equal) == 2 and all(0 < e < 1e-3 for e, _ in points["taylor"] + points["adams"])
    assert points["taylor"][1][0] < points["taylor"][0][0]  # tighter tolerance, smaller error
    assert sb.taylor_lines(rows, equal, 1)


def test_sensitivities_heyoka_variational_context():
    """benchmarks/sensitivities.py --taylor's heyoka column: its explicit system q'' = M^-1 F of the
    double pendulum has our sensitivities (var_ode_sys along l1 and theta2(0), to 1e-6 at t = 2),
    and its cost ratio with p sensitivities is measured."""
    pytest.importorskip("heyoka")
    import numpy as np
    import sensitivities as sb
    import lagcodegen as lcg
    model = systems.double_pendulum(name="tb_sens_dp")
    sim = lcg.compile_model(model)
    sys_, hq, hy = sb.heyoka_explicit(model, sim)
    ta = hy.taylor_adaptive(hy.var_ode_sys(sys_, [hy.par[sim.param_names.index("l1")], hq[1]], order=1),
                            [sb.Q0] * 2 + [0.0] * 2, pars=list(sim.parameter_vector()), tol=1e-13)
    ta.propagate_until(2.0)
    ref = np.array(ta.state[4:]).reshape(4, 2).T
    ours = sim.simulate(np.array([0.0, 2.0]), q0=[sb.Q0] * 2, rtol=1e-10, atol=1e-12, method="taylor",
                        sensitivities=["l1", "theta2(0)"]).sensitivities[-1, :, :4]
    assert np.max(np.abs(ours - ref)) < 1e-6 * np.max(np.abs(ref))
    ratios = sb.heyoka_var_ratios(model, sim, [1], rounds=1)
    ratio, steps = ratios[1]
    plain, var = map(int, steps.split("/"))
    assert finite(ratio) and ratio > 0 and var >= plain > 0
