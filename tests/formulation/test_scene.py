"""The scene drives generation: the structural Jacobian pattern, the sparse Jacobian it emits,
and CVODE's band solver on the interleaved state that the pattern makes banded."""

import subprocess

import numpy as np
import pytest

from lagcodegen import Scene, build_code, compile_reduction, derive, generate_c, systems
from lagcodegen.build import driver_sources, find_sundials
from lagcodegen.errors import LagcodegenError
from lagcodegen.formulation.scene import band_order, bandwidths

from helpers import STRICT_CFLAGS


def chain_initial(n: int) -> tuple[list[float], list[float]]:
    """The first dimer displaced rigidly by 0.1 (its stiff spring unstretched), all at rest."""
    q0 = [0.0] * n
    q0[0] = q0[1] = 0.1
    return q0, [0.0] * n


# --------------------------------------------------------------------------- sparse Jacobian, band solver
@pytest.fixture(scope="module")
def chain():
    eom = derive(systems.spring_chain(8, 1e4, name="tb_chain"))
    return build_code(generate_c(Scene(eom, sparse_jacobian=True, prefix="tb_chain")))


def sparse_as_dense(cm, t, y):
    ffi = cm.ffi
    p = cm.parameter_vector()
    f = cm.rhs(t, y, p)
    pattern = cm.code.jac_pattern
    vals = np.empty(int(pattern.sum()))
    rc = cm.c_jac_sparse(t, ffi.from_buffer("double[]", np.ascontiguousarray(y)),
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
        cm = build_code(generate_c(Scene(derive(systems.double_pendulum("tb_dbl")), sparse_jacobian=True,
                                    prefix="tb_dbl")))
    elif which == "routh":  # quadrature state
        from lagcodegen.theory.routhian import reduce
        red = reduce(systems.spherical_pendulum("tb_sph"))
        cm = build_code(generate_c(Scene(red.eom, sparse_jacobian=True, prefix="tb_sph_routh")))
    else:
        cm = build_code(generate_c(Scene(derive(systems.damped_pendulum("tb_damped")), sparse_jacobian=True,
                                    runtime_parameters=["g"], prefix="tb_damped")))
    rng = np.random.default_rng(1)
    for _ in range(3):
        y = 0.5 + 0.3 * rng.standard_normal(cm.ny)
        J = cm.jac(0.3, y)
        np.testing.assert_allclose(sparse_as_dense(cm, 0.3, y), J, rtol=1e-12, atol=1e-12)
        assert not np.any(J[~cm.code.jac_pattern])  # the pattern covers every nonzero


@pytest.mark.parametrize("jacobian,sparse", [(True, True), (False, True), (True, False), (False, False)])
def test_sparse_code_and_band_driver_compile_strictly(tmp_path, cc, jacobian, sparse):
    code = generate_c(Scene(derive(systems.spring_chain(4, name="tb_strict")), jacobian=jacobian, sparse_jacobian=sparse,
                            outputs=["energy"], prefix="tb_strict"))
    code.write(tmp_path)
    for name, text in driver_sources(code, find_sundials()).items():
        (tmp_path / name).write_text(text)
    for src in [n for n in code.files if n.endswith(".c")] + ["lcg_cvode.c", "lcg_inputs.c", "tb_strict_table.c"]:
        proc = subprocess.run([cc, *STRICT_CFLAGS, "-c", src, "-o", src + ".o"], cwd=tmp_path,
                              capture_output=True, text=True)
        assert proc.returncode == 0, proc.stderr


@pytest.mark.parametrize("scene", [dict(sparse_jacobian=True, jacobian=False), dict(jacobian=True),
                                   dict(jacobian=False)])
def test_band_solver_agrees_with_dense(scene):
    n = 8
    cm = build_code(generate_c(Scene(derive(systems.spring_chain(n, 1e4, name="tb_band")), outputs=["energy"],
                                prefix="tb_band_" + "_".join(f"{k}{int(v)}" for k, v in scene.items()), **scene)))
    q0, v0 = chain_initial(n)
    t = np.linspace(0.0, 5.0, 51)
    atol = np.full(cm.ny, 1e-12)
    atol[n:] = 1e-11  # a vector atol is permuted with the state
    dense = cm.simulate(t, q0=q0, v0=v0, method="bdf", rtol=1e-10, atol=atol, jacobian=False)
    band = cm.simulate(t, q0=q0, v0=v0, method="bdf", rtol=1e-10, atol=atol, linear_solver="band")
    assert band.success and band.stats["jac_evals"] > 0
    np.testing.assert_allclose(band.y, dense.y, atol=1e-7)
    np.testing.assert_allclose(band["energy"], dense["energy"], rtol=1e-7)


def test_band_solver_with_quadratures_and_explicit_bandwidths():
    from lagcodegen.theory.routhian import reduce
    red = reduce(systems.spherical_pendulum("tb_sph2"))
    cm = compile_reduction(red, outputs=("jacobi_h",), prefix="tb_sph2_routh")
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
    from lagcodegen.solvers.cvode import band_widths
    saved = chain.code.jac_pattern
    try:
        chain.code.jac_pattern = None
        assert band_widths(chain, None, np.full(chain.ny, 0.1), chain.parameter_vector()) == (2, 3)
    finally:
        chain.code.jac_pattern = saved


# --------------------------------------------------------------------------- shared harness
