"""The dense LU solve written once as procedures of the language-neutral tree (codegen/linalg.py)
and printed by each backend (c_procedure.py, fortran_procedure.py): both printed solves compile
with the project's warnings as errors and give numpy's solution, including systems that need row
exchanges, and both refuse singular and non-finite matrices."""

from __future__ import annotations

import ctypes
import subprocess

import numpy as np
import pytest

from lagcodegen.codegen import ir, linalg
from lagcodegen.codegen import procedure as pr
from lagcodegen.codegen.c_procedure import CProcedurePrinter
from lagcodegen.codegen.fortran_procedure import FortranProcedurePrinter

C_MAIN = """#include <float.h>
#include <math.h>

{factor}

{solve}

int solve_c(int dim, double *K, double *b, int *piv)
{{
    if (!lu_factor(dim, K, piv))
        return 0;
    lu_solve(dim, K, piv, b);
    return 1;
}}
"""

F_MAIN = """module lt
  use, intrinsic :: iso_c_binding, only: c_double, c_int
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  implicit none
contains

{factor}

{solve}

  integer(c_int) function solve_f(dim, K, b, piv) bind(C, name="solve_f")
    integer(c_int), value :: dim
    real(c_double), intent(inout) :: K(dim, dim), b(dim)
    integer(c_int), intent(out) :: piv(dim)
    solve_f = 0
    if (.not. lu_factor(dim, K, piv)) return
    call lu_solve(dim, K, piv, b)
    solve_f = 1
  end function solve_f
end module lt
"""


def _texts(printer) -> dict:
    return {name: printer().text(make()) for name, make in linalg.PROCEDURES.items()}


@pytest.fixture(scope="module")
def solvers(tmp_path_factory, cc, fc):
    """(C solve, Fortran solve, C pivots): each takes (K, b) and returns (ok, x, piv)."""
    tmp = tmp_path_factory.mktemp("lu")
    c, f = _texts(CProcedurePrinter), _texts(FortranProcedurePrinter)
    (tmp / "lu.c").write_text(C_MAIN.format(factor=c["lu_factor"], solve=c["lu_solve"]))
    (tmp / "lu.f90").write_text(F_MAIN.format(factor=f["lu_factor"], solve=f["lu_solve"]))
    subprocess.run([cc, "-shared", "-fPIC", "-O2", "-Wall", "-Wextra", "-Werror", "-std=c99", "-pedantic",
                    "lu.c", "-o", "liblu_c.so", "-lm"], cwd=tmp, check=True, capture_output=True)
    subprocess.run([fc, "-shared", "-fPIC", "-O2", "-Wall", "-Werror", "-std=f2008", "lu.f90", "-o", "liblu_f.so"],
                   cwd=tmp, check=True, capture_output=True)
    libs = ctypes.CDLL(str(tmp / "liblu_c.so")).solve_c, ctypes.CDLL(str(tmp / "liblu_f.so")).solve_f
    dbl, it = np.ctypeslib.ndpointer(np.float64), np.ctypeslib.ndpointer(np.int32)
    for fn in libs:
        fn.argtypes, fn.restype = [ctypes.c_int, dbl, dbl, it], ctypes.c_int

    def run(fn, order):
        def solve(K, b):
            K = np.array(K, dtype=np.float64, order=order)  # Fortran: K(i, j) row i, column j, by columns
            x, piv = np.array(b, dtype=np.float64), np.zeros(len(b), dtype=np.int32)
            ok = fn(len(b), K.ravel(order="K") if order == "C" else K.T.ravel(), x, piv)
            return ok, x, piv
        return solve
    return run(libs[0], "C"), run(libs[1], "F")


def test_printed_solves_agree_with_numpy(solvers):
    rng = np.random.default_rng(7)
    K = rng.normal(size=(6, 6))
    K[0, 0] = 0.0  # the first pivot must come from another row
    b = rng.normal(size=6)
    expected = np.linalg.solve(K, b)
    results = [solve(K, b) for solve in solvers]
    for ok, x, _ in results:
        assert ok == 1
        assert np.allclose(x, expected, rtol=1e-12, atol=1e-12)
    # the same pivots (1-based in Fortran) and the same doubles: one tree, the same operations
    (_, xc, pc), (_, xf, pf) = results
    assert pc[0] != 0 and np.array_equal(pc + 1, pf)
    assert np.array_equal(xc, xf)


@pytest.mark.parametrize("case", ["rank", "zero", "nan"])
def test_printed_solves_refuse_singular_and_non_finite(solvers, case):
    K = np.arange(16.0).reshape(4, 4) + 1.0  # rank 2
    if case == "zero":
        K = np.zeros((4, 4))
    elif case == "nan":
        K = np.eye(4)
        K[2, 1] = np.nan
    for solve in solvers:
        assert solve(K, np.ones(4))[0] == 0


MASS_C = """#include <float.h>
#include <math.h>
#define N 5

{factor}

{solve}

int mass_c(int kind, double *W, int *piv, double *b)
{{
    if (kind == 2 && !lu_factor(N, W, piv))
        return 0;
    ms(kind, (const double (*)[N])W, piv, b);
    return 1;
}}
"""

MASS_F = """module mt
  use, intrinsic :: iso_c_binding, only: c_double, c_int
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  implicit none
  integer, parameter :: n = 5
contains

{factor}

{solve}

  integer(c_int) function mass_f(kind, W, piv, b) bind(C, name="mass_f")
    integer(c_int), value :: kind
    real(c_double), intent(inout) :: W(n, n), b(n)
    integer(c_int), intent(inout) :: piv(n)
    mass_f = 0
    if (kind == 2) then
      if (.not. lu_factor(n, W, piv)) return
    end if
    call solve(kind, W, piv, b)
    mass_f = 1
  end function mass_f
end module mt
"""


def test_printed_mass_solves_agree_with_numpy(tmp_path, cc, fc):
    """The mass-matrix solve from the factors of each kind (1: Cholesky L, 2: LU with row
    exchanges, 3: the diagonal) in both languages, against numpy, bit for bit between them."""
    lu = linalg.lu_factor()
    c = MASS_C.format(factor=CProcedurePrinter().text(lu),
                               solve=CProcedurePrinter().text(linalg.mass_solve(name="ms", diagonal=True)))
    f = MASS_F.format(factor=FortranProcedurePrinter().text(lu),
                      solve=FortranProcedurePrinter().text(linalg.mass_solve(diagonal=True)))
    (tmp_path / "m.c").write_text(c)
    (tmp_path / "m.f90").write_text(f)
    subprocess.run([cc, "-shared", "-fPIC", "-O2", "-Wall", "-Wextra", "-Werror", "-std=c99", "-pedantic",
                    "m.c", "-o", "libm_c.so", "-lm"], cwd=tmp_path, check=True, capture_output=True)
    subprocess.run([fc, "-shared", "-fPIC", "-O2", "-Wall", "-Werror", "-std=f2008", "m.f90", "-o", "libm_f.so"],
                   cwd=tmp_path, check=True, capture_output=True)
    rng = np.random.default_rng(3)
    A = rng.normal(size=(5, 5))
    spd = A @ A.T + 5 * np.eye(5)
    general = A.copy()
    general[0, 0] = 0.0
    diag = np.diag(rng.uniform(1.0, 2.0, size=5))
    b = rng.normal(size=5)
    cases = {1: (spd, np.linalg.cholesky(spd)), 2: (general, general), 3: (diag, diag)}
    dbl, it = np.ctypeslib.ndpointer(np.float64), np.ctypeslib.ndpointer(np.int32)
    results = {}
    for lib, fn, transpose in (("libm_c.so", "mass_c", False), ("libm_f.so", "mass_f", True)):
        solve = getattr(ctypes.CDLL(str(tmp_path / lib)), fn)
        solve.argtypes, solve.restype = [ctypes.c_int, dbl, it, dbl], ctypes.c_int
        for kind, (M, W) in cases.items():
            W = np.array(W.T if transpose else W, dtype=np.float64).ravel()  # Fortran: W(i, j) by columns
            x, piv = b.copy(), np.zeros(5, dtype=np.int32)
            assert solve(kind, W, piv, x) == 1
            assert np.allclose(x, np.linalg.solve(M, b), rtol=1e-12, atol=1e-12), (fn, kind)
            results[fn, kind] = x
    for kind in cases:
        assert np.array_equal(results["mass_c", kind], results["mass_f", kind])


def test_fortran_index_and_name_rules():
    """Every index value prints one more in Fortran (loop bounds, pivots), a local whose name
    equals an argument's but for case takes its other name, and one that does not keeps its own."""
    body = (pr.For("k", pr.ix("i", const=1), pr.ix("i"), (
        pr.Set(ir.Element("b", (pr.ix("k"),)), ir.Element("b", (ir.Element("piv", (pr.ix("k"),)),))),)),)
    proc = pr.Procedure("p", (pr.Arg("i", "int"), pr.Arg("b", "real", ("i",), "inout"),
                              pr.Arg("piv", "int", ("i",))),
                        (pr.Local("k", "int", alt="c"),), body)
    f = FortranProcedurePrinter().text(proc)
    # k from i + 1 to i - 1 counted from 0 is k from i + 2 to i counted from 1 (i is a size: not shifted)
    assert "    do k = i + 2, i\n      b(k) = b(piv(k))\n    end do" in f
    c = CProcedurePrinter().text(proc)
    assert "    for (k = i + 1; k < i; ++k)\n        b[k] = b[piv[k]];" in c
    clash = pr.Procedure("p", proc.args + (pr.Arg("K", "real", ("i",)),), proc.locals, body)
    assert "do c = i + 2, i\n      b(c) = b(piv(c))" in FortranProcedurePrinter().text(clash)
    with pytest.raises(TypeError, match="no function 'exp'"):
        CProcedurePrinter().expr(ir.Call("exp", (ir.Name("x"),)))
