"""The benchmark instruments stay runnable: one tiny configuration of each script's main pieces
(a few seconds each; the --quick modes run in CI separately), and the band solver and sparse
Jacobian the benchmarks measure."""

import math
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

import lagcodegen as lcg
from lagcodegen import Scene, build, derive, generate_c, systems
from lagcodegen.build import driver_sources, find_sundials
from lagcodegen.errors import LagcodegenError
from lagcodegen.scene import band_order, bandwidths

from conftest import STRICT_CFLAGS

BENCH = Path(__file__).resolve().parent.parent / "benchmarks"
sys.path.insert(0, str(BENCH))

import _harness as H  # noqa: E402


def finite(value) -> bool:
    return isinstance(value, (int, float)) and math.isfinite(value)


# --------------------------------------------------------------------------- sparse Jacobian, band solver
@pytest.fixture(scope="module")
def chain():
    eom = derive(H.spring_chain(8, 1e4, name="tb_chain"))
    return build(generate_c(Scene(eom, sparse_jacobian=True, prefix="tb_chain")))


def sparse_as_dense(cm, t, y):
    ffi, pre = cm.ffi, cm.code.prefix
    p = cm.parameter_vector()
    f = cm.rhs(t, y, p)
    pattern = cm.code.jac_pattern
    vals = np.empty(int(pattern.sum()))
    rc = getattr(cm.lib, f"{pre}_jac_sparse")(t, ffi.from_buffer("double[]", np.ascontiguousarray(y)),
                                             ffi.from_buffer("double[]", f), ffi.from_buffer("double[]", p),
                                             ffi.from_buffer("double[]", vals))
    assert rc == 0
    J = np.zeros(pattern.shape)
    cols, rows = np.nonzero(pattern.T)  # column-major order, rows increasing
    J[rows, cols] = vals
    return J


def test_chain_pattern_is_banded_when_interleaved(chain):
    pattern = chain.code.jac_pattern
    assert bandwidths(pattern, band_order(8)) == (2, 3)
    assert bandwidths(pattern) == (8, 9)  # (q, q') order: the identity block alone is 8 above
    dense = generate_c(Scene(derive(systems.n_link_pendulum(3)), jacobian=False)).jac_pattern
    assert dense[3:, :].all() and dense[:3, 3:].diagonal().all() and not dense[:3, :3].any()


@pytest.mark.parametrize("which", ["chain", "double", "routh", "damped"])
def test_sparse_jacobian_matches_dense(which, chain):
    if which == "chain":
        cm = chain
    elif which == "double":  # full M: factor once, solve the nonzero columns
        cm = build(generate_c(Scene(derive(systems.double_pendulum("tb_dbl")), sparse_jacobian=True,
                                    prefix="tb_dbl")))
    elif which == "routh":  # quadrature state
        from lagcodegen.routhian import reduce
        red = reduce(systems.spherical_pendulum("tb_sph"))
        cm = build(generate_c(Scene(red.eom, sparse_jacobian=True, prefix="tb_sph_routh")))
    else:
        cm = build(generate_c(Scene(derive(systems.damped_pendulum("tb_damped")), sparse_jacobian=True,
                                    runtime_parameters=["g"], prefix="tb_damped")))
    rng = np.random.default_rng(1)
    for _ in range(3):
        y = 0.5 + 0.3 * rng.standard_normal(cm.ny)
        J = cm.jac(0.3, y)
        np.testing.assert_allclose(sparse_as_dense(cm, 0.3, y), J, rtol=1e-12, atol=1e-12)
        assert not np.any(J[~cm.code.jac_pattern])  # the pattern covers every nonzero


@pytest.mark.parametrize("jacobian,sparse", [(True, True), (False, True), (True, False), (False, False)])
def test_sparse_code_and_band_driver_compile_strictly(tmp_path, cc, jacobian, sparse):
    code = generate_c(Scene(derive(H.spring_chain(4, name="tb_strict")), jacobian=jacobian, sparse_jacobian=sparse,
                            outputs=["energy"], prefix="tb_strict"))
    code.write(tmp_path)
    for name, text in driver_sources(code, find_sundials()).items():
        (tmp_path / name).write_text(text)
    for src in [n for n in code.files if n.endswith(".c")] + ["tb_strict_cvode.c"]:
        proc = subprocess.run([cc, *STRICT_CFLAGS, "-c", src, "-o", src + ".o"], cwd=tmp_path,
                              capture_output=True, text=True)
        assert proc.returncode == 0, proc.stderr


@pytest.mark.parametrize("scene", [dict(sparse_jacobian=True, jacobian=False), dict(jacobian=True),
                                   dict(jacobian=False)])
def test_band_solver_agrees_with_dense(scene):
    n = 8
    cm = build(generate_c(Scene(derive(H.spring_chain(n, 1e4, name="tb_band")), outputs=["energy"],
                                prefix="tb_band_" + "_".join(f"{k}{int(v)}" for k, v in scene.items()), **scene)))
    q0, v0 = H.chain_initial(n)
    t = np.linspace(0.0, 5.0, 51)
    atol = np.full(cm.ny, 1e-12)
    atol[n:] = 1e-11  # a vector atol is permuted with the state
    dense = cm.simulate(t, q0=q0, v0=v0, method="bdf", rtol=1e-10, atol=atol, jacobian=False)
    band = cm.simulate(t, q0=q0, v0=v0, method="bdf", rtol=1e-10, atol=atol, linear_solver="band")
    assert band.success and band.stats["jac_evals"] > 0
    np.testing.assert_allclose(band.y, dense.y, atol=1e-7)
    np.testing.assert_allclose(band["energy"], dense["energy"], rtol=1e-7)


def test_band_solver_with_quadratures_and_explicit_bandwidths():
    from lagcodegen.routhian import reduce
    red = reduce(systems.spherical_pendulum("tb_sph2"))
    cm = red.compile(outputs=("jacobi_h",), prefix="tb_sph2_routh")
    kw = dict(q0=[0.8, 0.0], v0=[0.3, 2.0], rtol=1e-10, atol=1e-12)
    dense = red.simulate(cm, [0, 5], **kw)
    band = red.simulate(cm, [0, 5], linear_solver="band", **kw)
    full = red.simulate(cm, [0, 5], linear_solver="band", bandwidths=(2, 2), **kw)
    np.testing.assert_allclose(band.y, dense.y, atol=1e-7)
    np.testing.assert_allclose(full.y, dense.y, atol=1e-7)
    with pytest.raises(LagcodegenError):
        red.simulate(cm, [0, 5], linear_solver="band", backend="sksundae", **kw)
    with pytest.raises(LagcodegenError):
        red.simulate(cm, [0, 5], linear_solver="banded", **kw)
    with pytest.raises(LagcodegenError):
        red.simulate(cm, [0, 5], linear_solver="band", bandwidths=(9, 0), **kw)


def test_band_probe_without_recorded_pattern(chain):
    from lagcodegen.solve import band_widths
    saved = chain.code.jac_pattern
    try:
        chain.code.jac_pattern = None
        assert band_widths(chain, None, np.full(chain.ny, 0.1), chain.parameter_vector()) == (2, 3)
    finally:
        chain.code.jac_pattern = saved


# --------------------------------------------------------------------------- shared harness
def test_c_harness_times_every_function(tmp_path, chain):
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
