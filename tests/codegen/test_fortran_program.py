"""Fortran in the forms the C backend had alone: the program-form right-hand side (pieces as module
subroutines), the tangent Jacobian and the sparse Jacobian, each against the C backend's functions
for the same scene (the same operation tree, so the same doubles), and strict gfortran."""

import subprocess

import numpy as np
import pytest

import lagcodegen as lcg
from lagcodegen import Scene, derive, generate_c, generate_fortran, systems
from lagcodegen.codegen import program

from helpers import STRICT_FFLAGS


def assert_same(a, b, what):
    """C and Fortran agree to the last bit, or (where a compiler contracts differently) to 1e-14."""
    a, b = np.asarray(a), np.asarray(b)
    if not np.array_equal(a, b):
        scale = max(np.max(np.abs(a)), 1e-300)
        np.testing.assert_allclose(b, a, rtol=1e-14, atol=1e-14 * scale, err_msg=what)


def strict(fc, code, folder):
    code.write(folder)
    for opt in ("-O0", "-O2"):
        proc = subprocess.run([fc, opt, *STRICT_FFLAGS, "-c", f"{code.prefix}.f90", "-o", f"{code.prefix}.o"],
                              cwd=folder, capture_output=True, text=True)
        assert proc.returncode == 0, f"{opt}:\n{proc.stderr}"
    assert max(map(len, code.files[f"{code.prefix}.f90"].splitlines())) <= 132


def sparse_as_dense(cm, t, y):
    """The sparse Jacobian's values placed by the pattern (column-major, rows increasing)."""
    ffi, p = cm.ffi, cm.parameter_vector()
    f = cm.rhs(t, y, p)
    pattern = cm.code.jac_pattern
    vals = np.empty(int(pattern.sum()))
    rc = cm.c_jac_sparse(t, ffi.from_buffer("double[]", np.ascontiguousarray(y)), ffi.from_buffer("double[]", f),
                         ffi.from_buffer("double[]", p), ffi.from_buffer("double[]", vals))
    assert rc == 0
    J = np.zeros(pattern.shape)
    cols, rows = np.nonzero(pattern.T)
    J[rows, cols] = vals
    return J


def test_program_form_rhs_of_an_18_link_chain_matches_c(fc):
    eom = derive(systems.n_link_pendulum(18, name="fp18"))
    scenes = {lang: Scene(eom, jacobian=False, outputs=["energy"], prefix=f"fp18_{lang}") for lang in ("c", "f")}
    fcode = generate_fortran(scenes["f"])
    src = fcode.files["fp18_f.f90"]
    assert "subroutine values0(" in src and "call values0(" in src  # the program form, in pieces
    assert fcode.files["fp18_f.h"] == generate_c(scenes["f"]).files["fp18_f.h"]  # the C backend's header
    cm, fm = lcg.build_code(generate_c(scenes["c"])), lcg.build_code(fcode)
    rng = np.random.default_rng(3)
    for _ in range(4):
        y = rng.uniform(-1.0, 1.0, cm.ny)
        assert_same(cm.rhs(0.4, y), fm.rhs(0.4, y), "rhs")
        assert_same(cm.outputs(0.4, y), fm.outputs(0.4, y), "outputs")
    # A physical check of the Fortran right-hand side alone: the energy of a free swing is conserved.
    res = fm.simulate([0.0, 1.0], q0=[0.3] * 18, rtol=1e-10, atol=1e-12)
    energy = res.outputs["energy"]
    assert abs(energy[-1] - energy[0]) < 1e-7 * abs(energy[0])


@pytest.mark.parametrize("links,chunk", [(4, 3), (6, None)])
def test_tangent_jacobian_matches_c(fc, tmp_path, monkeypatch, links, chunk):
    # chunk 3: the columns' code in several pieces, its local tangents in the scratch array s.
    if chunk is not None:
        import lagcodegen.codegen.c as cmod
        monkeypatch.setattr(program, "CHUNK_STATEMENTS", chunk)
        monkeypatch.setattr(cmod, "CHUNK_STATEMENTS", chunk)
    eom = derive(systems.n_link_pendulum(links, name=f"ft{links}"))
    fcode = generate_fortran(Scene(eom, jacobian_form="tangent", prefix=f"ft{links}_f"))
    src = fcode.files[f"ft{links}_f.f90"]
    assert "subroutine run_piece(" in src
    assert ("intent(inout) :: s(*)" in src) == (chunk is not None)
    strict(fc, fcode, tmp_path)
    cm = lcg.build_code(generate_c(Scene(eom, jacobian_form="tangent", prefix=f"ft{links}_c")), native=False)
    fm = lcg.build_code(fcode, native=False)
    expanded = lcg.build_code(generate_c(Scene(eom, jacobian_form="expanded", prefix=f"ft{links}_e")), native=False)
    rng = np.random.default_rng(links)
    for _ in range(4):
        y = rng.uniform(-1.0, 1.0, cm.ny)
        assert_same(cm.rhs(0.2, y), fm.rhs(0.2, y), "rhs")
        assert_same(cm.jac(0.2, y), fm.jac(0.2, y), "tangent jac")
        # A second method: the symbolically differentiated (expanded) Jacobian.
        np.testing.assert_allclose(fm.jac(0.2, y), expanded.jac(0.2, y), rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("which", ["chain", "double", "routh"])
def test_sparse_jacobian_matches_c(fc, tmp_path, which):
    if which == "chain":  # M structurally diagonal: one expression per entry
        eom = derive(systems.spring_chain(5, 1e3, name="fs_chain"))
    elif which == "double":  # full M: factor once, solve the nonzero columns
        eom = derive(systems.double_pendulum("fs_dbl"))
    else:  # a quadrature state
        from lagcodegen.theory.routhian import reduce
        eom = reduce(systems.spherical_pendulum("fs_sph")).eom
    fcode = generate_fortran(Scene(eom, sparse_jacobian=True, prefix=f"fs_{which}_f"))
    assert fcode.sparse_jacobian and f"fs_{which}_f_sparse.h" in fcode.files
    strict(fc, fcode, tmp_path)
    cm = lcg.build_code(generate_c(Scene(eom, sparse_jacobian=True, prefix=f"fs_{which}_c")), native=False)
    fm = lcg.build_code(fcode, native=False)
    assert np.array_equal(cm.code.jac_pattern, fm.code.jac_pattern)
    symbols = subprocess.run(["nm", f"fs_{which}_f.o"], cwd=tmp_path, capture_output=True, text=True).stdout
    assert f"D fs_{which}_f_jac_colptr" in symbols and f"D fs_{which}_f_jac_rowind" in symbols  # the header's
    rng = np.random.default_rng(5)
    for _ in range(3):
        y = 0.5 + 0.3 * rng.standard_normal(cm.ny)
        Jf = sparse_as_dense(fm, 0.3, y)
        assert_same(sparse_as_dense(cm, 0.3, y), Jf, "sparse jac")
        np.testing.assert_allclose(Jf, fm.jac(0.3, y), rtol=1e-12, atol=1e-12)  # against the dense Jacobian


@pytest.mark.parametrize("hashed", [False, True])
def test_expanded_jacobian_in_pieces_matches_c(fc, tmp_path, monkeypatch, hashed):
    # A program-form model with the expanded Jacobian: its block in pieces (the temporaries in an
    # allocated array), or hash-consed into a program of its own (hashed).
    import lagcodegen.codegen.c as cmod
    for module in (program, cmod):
        monkeypatch.setattr(module, "PROGRAM_MIN_OPS", 0)
        monkeypatch.setattr(module, "CHUNK_STATEMENTS", 7)
        if hashed:
            monkeypatch.setattr(module, "BLOCK_CSE_MAX_OPS", 0)
    eom = derive(systems.n_link_pendulum(3, name="fe3"))
    fcode = generate_fortran(Scene(eom, jacobian_form="expanded", prefix="fe3_f"))
    src = fcode.files["fe3_f.f90"]
    jac_body = src.split("function fe3_f_jac(")[1]
    assert "subroutine jacobian1(" in src and "call jacobian0(" in jac_body
    assert ("allocate (v(" in jac_body) == hashed and ("allocate (x(" in jac_body) != hashed
    strict(fc, fcode, tmp_path)
    cm = lcg.build_code(generate_c(Scene(eom, jacobian_form="expanded", prefix="fe3_c")), native=False)
    fm = lcg.build_code(fcode, native=False)
    rng = np.random.default_rng(11)
    for _ in range(3):
        y = rng.uniform(-1.0, 1.0, cm.ny)
        assert_same(cm.rhs(0.1, y), fm.rhs(0.1, y), "rhs")
        assert_same(cm.jac(0.1, y), fm.jac(0.1, y), "expanded jac in pieces")
