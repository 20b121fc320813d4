"""The dense linear algebra written once as procedures of the language-neutral tree
(codegen/linalg.py) and printed by each backend (c_procedure.py, fortran_procedure.py): the LU
solve, the mass matrix's factorization of every kind with its solve, and the Schur complement
solve of [M A^T; A 0] compile with the project's warnings as errors and give numpy's solution
(including systems that need row exchanges, and the same doubles in both languages), refuse
singular and non-finite matrices, and read in each language's idiom."""

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


def _compile(tmp, name: str, c: str, f: str, cc, fc):
    """C and Fortran sources compiled with the project's warnings as errors: (C library, Fortran library)."""
    (tmp / f"{name}.c").write_text(c)
    (tmp / f"{name}.f90").write_text(f)
    subprocess.run([cc, "-shared", "-fPIC", "-O2", "-Wall", "-Wextra", "-Werror", "-std=c99", "-pedantic",
                    f"{name}.c", "-o", f"lib{name}_c.so", "-lm"], cwd=tmp, check=True, capture_output=True)
    subprocess.run([fc, "-shared", "-fPIC", "-O2", "-Wall", "-Werror", "-std=f2008", f"{name}.f90", "-o",
                    f"lib{name}_f.so", "-J", str(tmp)], cwd=tmp, check=True, capture_output=True)
    return ctypes.CDLL(str(tmp / f"lib{name}_c.so")), ctypes.CDLL(str(tmp / f"lib{name}_f.so"))


FACTOR_C = """#include <float.h>
#include <math.h>
#define N 5

{full}

{diag}

{lu}

{solve}

int factor_c(int which, double *M, double *W, int *piv, double *b)
{{
    int kind = which == 0 ? full((const double (*)[N])M, (double (*)[N])W, piv)
             : which == 1 ? diag((const double (*)[N])M, (double (*)[N])W, piv)
             : lu((const double (*)[N])M, (double (*)[N])W, piv);
    if (kind)
        ms(kind, (const double (*)[N])W, piv, b);
    return kind;
}}
"""

FACTOR_F = """module ft
  use, intrinsic :: iso_c_binding, only: c_double, c_int
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  implicit none
  integer, parameter :: n = 5
contains

{full}

{diag}

{solve}

  integer(c_int) function factor_f(which, M, W, piv, b) bind(C, name="factor_f")
    integer(c_int), value :: which
    real(c_double), intent(in) :: M(n, n)
    real(c_double), intent(out) :: W(n, n)
    real(c_double), intent(inout) :: b(n)
    integer(c_int), intent(out) :: piv(n)
    if (which == 0) then
      factor_f = factor(M, W, piv)
    else
      factor_f = factor_d(M, W, piv)
    end if
    if (factor_f /= 0) call solve(factor_f, W, piv, b)
  end function factor_f
end module ft
"""


@pytest.fixture(scope="module")
def factors(tmp_path_factory, cc, fc):
    """The printed mass_factor (general: Cholesky with the LU fallback; diagonal; C also LU alone)
    followed by mass_solve, in C and Fortran: each (which, M, b) -> (kind, x, piv); which 0:
    general, 1: diagonal, 2: LU alone (C)."""
    C, F = CProcedurePrinter, FortranProcedurePrinter
    c = FACTOR_C.format(full=C().text(linalg.mass_factor(name="full")),
                        diag=C().text(linalg.mass_factor(name="diag", diagonal=True, pivot="q",
                                                         cholesky_comment=False)),
                        lu=C().text(linalg.mass_factor(name="lu", lu_only=True)),
                        solve=C().text(linalg.mass_solve(name="ms", diagonal=True)))
    f = FACTOR_F.format(full=F().text(linalg.mass_factor(pivot="r")),
                        diag=F().text(linalg.mass_factor(name="factor_d", diagonal=True, pivot="r")),
                        solve=F().text(linalg.mass_solve(diagonal=True)))
    libs = _compile(tmp_path_factory.mktemp("factor"), "factor", c, f, cc, fc)
    dbl, it = np.ctypeslib.ndpointer(np.float64), np.ctypeslib.ndpointer(np.int32)
    fns = libs[0].factor_c, libs[1].factor_f
    for fn in fns:
        fn.argtypes, fn.restype = [ctypes.c_int, dbl, dbl, it, dbl], ctypes.c_int

    def run(fn, fortran):
        def factor(which, M, b):
            M = np.array(M.T if fortran else M, dtype=np.float64).ravel()  # Fortran: M(i, j) by columns
            W, x, piv = np.zeros(25), np.array(b, dtype=np.float64), np.zeros(5, dtype=np.int32)
            kind = fn(which, M, W, piv, x)
            return kind, x, piv
        return factor
    return run(fns[0], False), run(fns[1], True)


def _mass_cases():
    rng = np.random.default_rng(11)
    A = rng.normal(size=(5, 5))
    Q = np.linalg.qr(A)[0]
    indefinite = Q @ np.diag([3.0, -1.0, 2.0, 0.5, -4.0]) @ Q.T  # symmetric, not positive definite
    return {"cholesky": (A @ A.T + 5 * np.eye(5), 0, 1), "lu fallback": ((indefinite + indefinite.T) / 2, 0, 2),
            "diagonal": (np.diag(rng.uniform(1.0, 2.0, size=5)), 1, 3)}


@pytest.mark.parametrize("case", ["cholesky", "lu fallback", "diagonal"])
def test_printed_mass_factor_agrees_with_numpy(factors, case):
    """mass_factor of every kind (1: Cholesky, 2: LU after the Cholesky gave up on an indefinite
    matrix, 3: the diagonal) in both languages: the kind, numpy's solution, the same doubles and
    the same pivots (the identity of the diagonal kind: set at entry in Fortran, in the loop in C)."""
    M, which, kind = _mass_cases()[case]
    b = np.random.default_rng(5).normal(size=5)
    (kc, xc, pc), (kf, xf, pf) = (factor(which, M, b) for factor in factors)
    assert kc == kf == kind
    for x in (xc, xf):
        assert np.allclose(x, np.linalg.solve(M, b), rtol=1e-12, atol=1e-12)
    assert np.array_equal(xc, xf)
    if kind != 1:  # Cholesky leaves piv alone in C
        assert np.array_equal(pc + 1, pf)
    if kind == 3:
        assert np.array_equal(pf, np.arange(1, 6))


def test_printed_mass_factor_lu_alone_and_refusals(factors):
    """C's LU alone (a matrix not symmetric) solves by LU; a zero, singular or non-finite matrix is
    refused (0) in both languages; Fortran has no LU alone (a fallback taken before any loop)."""
    solve_c, solve_f = factors
    rng = np.random.default_rng(2)
    M = rng.normal(size=(5, 5)) + 5 * np.eye(5)
    b = rng.normal(size=5)
    kind, x, _ = solve_c(2, M, b)
    assert kind == 2 and np.allclose(x, np.linalg.solve(M, b), rtol=1e-12, atol=1e-12)
    singular = np.ones((5, 5))
    nan = np.eye(5)
    nan[1, 1] = np.nan
    for M in (np.zeros((5, 5)), singular, nan):
        for solve in factors:
            assert solve(0, M, b)[0] == 0
    with pytest.raises(NotImplementedError, match="fallback"):
        FortranProcedurePrinter().text(linalg.mass_factor(lu_only=True))


SCHUR_C = """#include <float.h>
#include <math.h>
#define N 4
#define J {J}
#define JD {JD}

{schur}

int schur_c(double *M, const double *F, double *A, const double *b, double *acc, double *x)
{{
    return schur_solve((double (*)[N])M, F, (double (*)[N])A, b, acc, x);
}}
"""

SCHUR_F = """module {module}
  use, intrinsic :: iso_c_binding, only: c_double, c_int
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  implicit none
  integer, parameter :: nq = 4, nj = {J}
contains

{schur}

  integer(c_int) function schur_f(M, F, A, b, acc, x) bind(C, name="schur_f")
    real(c_double), intent(in) :: M(nq, nq), F(nq), A(nj, nq), b(nj)
    real(c_double), intent(out) :: acc(nq), x(nj)
    schur_f = 0
    if (schur_solve(M, F, A, b, acc, x)) schur_f = 1
  end function schur_f
end module {module}
"""


@pytest.mark.parametrize("J", [2, 0])
def test_printed_schur_solve_agrees_with_numpy(tmp_path, cc, fc, J):
    """schur_solve in C (J and its array size JD as the dae code defines them) and Fortran (sizes
    nq, nj; nj = 0 leaves out the constraints' work, its arrays and the loops, with the arguments
    that leaves unused named): the solution of [M A^T; A 0] [a; x] = [F; b], the same doubles in
    both, and false where M is not positive definite."""
    schur = linalg.schur_solve()
    c = SCHUR_C.format(J=J, JD=max(J, 1), schur=CProcedurePrinter(
        dims={"J": "JD"}, vector_pointers=True, const_matrices=False).text(schur))
    f = SCHUR_F.format(J=J, module=f"st{J}", schur=FortranProcedurePrinter(
        sizes={"N": "nq", "J": "nj"}, zero=() if J else ("J",), spaced=False).text(schur))
    assert ("associate (unused_A => A, unused_b => b, unused_x => x)" in f) == (J == 0)
    lib_c, lib_f = _compile(tmp_path, "schur", c, f, cc, fc)
    dbl = np.ctypeslib.ndpointer(np.float64)
    rng = np.random.default_rng(J)
    B = rng.normal(size=(4, 4))
    M = B @ B.T + 4 * np.eye(4)
    A = rng.normal(size=(max(J, 1), 4))[:J]
    F, b = rng.normal(size=4), rng.normal(size=J)
    K = np.block([[M, A.T], [A, np.zeros((J, J))]])
    expected = np.linalg.solve(K, np.concatenate([F, b]))
    results = []
    for fn, fortran in ((lib_c.schur_c, False), (lib_f.schur_f, True)):
        fn.argtypes, fn.restype = [dbl] * 6, ctypes.c_int
        order = "F" if fortran else "C"  # Fortran: A(r, i) by columns
        acc, x = np.zeros(4), np.zeros(max(J, 1))
        assert fn(M.ravel(order=order).copy(), F, A.ravel(order=order).copy() if J else np.zeros(1),
                  b if J else np.zeros(1), acc, x) == 1
        assert np.allclose(np.concatenate([acc, x[:J]]), expected, rtol=1e-12, atol=1e-12), fn
        results.append((acc, x[:J]))
        indefinite = M - 20 * np.eye(4)
        assert fn(indefinite.ravel(order=order).copy(), F, A.ravel(order=order).copy() if J else np.zeros(1),
                  b if J else np.zeros(1), np.zeros(4), np.zeros(max(J, 1))) == 0
    (ac, xc), (af, xf) = results
    assert np.array_equal(ac, af) and np.array_equal(xc, xf)


def test_printers_choose_their_idioms():
    """One tree, each language's idiom: the fallback from Cholesky to LU is a goto in C and the
    result as a flag with exit in Fortran; the identity permutation is set in the diagonal loop in
    C and at entry in Fortran; sizes are named per language (J declared as JD in C, nj in
    Fortran) and a compile-time zero size leaves the Fortran loops and locals out."""
    factor = linalg.mass_factor(diagonal=True)
    c, f = CProcedurePrinter().text(factor), FortranProcedurePrinter().text(factor)
    assert "            goto lu;\n" in c and "\nlu:\n" in c and "    return 1;\n" in c
    assert "        ftype = 2\n        exit\n" in f and "    if (ftype == 1) return\n" in f
    assert "        piv[i] = i;\n    }\n    return 3;" in c
    assert f.index("piv(i) = i") < f.index("smax = 0.0_c_double") and "piv(i) = i" not in f.split("smax")[-1]
    schur = linalg.schur_solve()
    c = CProcedurePrinter(dims={"J": "JD"}).text(schur)
    assert "double L[N][N], V[JD][N], S[JD][JD], u[N], scale = 0.0;" in c and "for (r = 0; r < J; ++r)" in c
    full = FortranProcedurePrinter(sizes={"N": "nq", "J": "nj"}).text(schur)
    empty = FortranProcedurePrinter(sizes={"N": "nq", "J": "nj"}, zero=("J",)).text(schur)
    assert "V(nj, nq), S(nj, nj)" in full and "do r = 1, nj" in full
    assert "nj" not in empty.replace("A(nj, nq), b(nj)", "").replace("x(nj)", "") and "integer :: i, k, c\n" in empty
    assert "real(c_double) :: L(nq, nq), u(nq), smax, d, w\n" in empty  # s is w: S differs only by case
    with pytest.raises(ValueError, match="Fallback"):
        CProcedurePrinter().text(pr.Procedure("p", (), (), (pr.Fail(),)))


TREE = [-1, 0, 1, 0, 3, 3, -1, 6]  # two roots; the first forks at 0 and at 3

TREE_C = """#include <float.h>
#include <math.h>
#define N 8

static const int par[N] = {{{parents}}};

{factor}

{solve}

int tree_c(const double *M, double *W, int *piv, double *b)
{{
    int kind = tf((const double (*)[N])M, (double (*)[N])W, piv);
    if (kind)
        ts(kind, (const double (*)[N])W, piv, b);
    return kind;
}}
"""

TREE_F = """module tt
  use, intrinsic :: iso_c_binding, only: c_double, c_int
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  implicit none
  integer, parameter :: n = 8
  integer, parameter :: par(n) = [{parents}]
contains

{factor}

{solve}

  integer(c_int) function tree_f(M, W, piv, b) bind(C, name="tree_f")
    real(c_double), intent(in) :: M(n, n)
    real(c_double), intent(out) :: W(n, n)
    real(c_double), intent(inout) :: b(n)
    integer(c_int), intent(out) :: piv(n)
    tree_f = factor(M, W, piv)
    if (tree_f /= 0) call solve(tree_f, W, piv, b)
  end function tree_f
end module tt
"""


def _tree_pattern(parent) -> np.ndarray:
    """(i, j) where i is j or an ancestor of j, or j of i."""
    nz = np.eye(len(parent), dtype=bool)
    for i in range(len(parent)):
        j = parent[i]
        while j >= 0:
            nz[i, j] = nz[j, i] = True
            j = parent[j]
    return nz


@pytest.fixture(scope="module")
def tree_solvers(tmp_path_factory, cc, fc):
    """mass_factor and mass_solve along the tree TREE (``parents``, the tree's Ancestors loops) in
    C (the parents as the tree keeps them, -1 at a root) and Fortran (plus one, 0 at a root): each
    M, b -> (kind, x, piv)."""
    C, F = CProcedurePrinter, FortranProcedurePrinter
    c = TREE_C.format(parents=", ".join(map(str, TREE)),
                      factor=C().text(linalg.mass_factor(name="tf", parents="par")),
                      solve=C().text(linalg.mass_solve(name="ts", parents="par")))
    f = TREE_F.format(parents=", ".join(str(p + 1) for p in TREE),
                      factor=F().text(linalg.mass_factor(pivot="r", parents="par")),
                      solve=F().text(linalg.mass_solve(parents="par")))
    libs = _compile(tmp_path_factory.mktemp("tree"), "tree", c, f, cc, fc)
    dbl, it = np.ctypeslib.ndpointer(np.float64), np.ctypeslib.ndpointer(np.int32)
    fns = libs[0].tree_c, libs[1].tree_f
    for fn in fns:
        fn.argtypes, fn.restype = [dbl, dbl, it, dbl], ctypes.c_int

    def run(fn, fortran):
        def solve(M, b):
            M = np.array(M.T if fortran else M, dtype=np.float64).ravel()  # Fortran: M(i, j) by columns
            W, x, piv = np.zeros(64), np.array(b, dtype=np.float64), np.zeros(8, dtype=np.int32)
            return fn(M, W, piv, x), x, piv
        return solve
    return run(fns[0], False), run(fns[1], True)


@pytest.mark.parametrize("case", ["positive definite", "indefinite"])
def test_printed_tree_factor_agrees_with_numpy(tree_solvers, case):
    """The factorization M = L^T L along a tree (kind 4) of a random symmetric positive definite
    matrix with the tree's pattern, and the LU it falls back to (kind 2) for an indefinite one
    with that pattern: numpy's solution in both languages, the same doubles and pivots."""
    rng = np.random.default_rng(17)
    nz = _tree_pattern(TREE)
    L = np.tril(rng.normal(size=(8, 8))) * nz + 3 * np.eye(8)  # row k: k and its ancestors
    M = L.T @ L
    assert not M[~nz].any()  # no fill-in: the tree's pattern
    kind = 4
    if case == "indefinite":
        M = M - 20 * np.eye(8) * (np.arange(8) % 2)  # symmetric, some negative pivots
        assert np.linalg.eigvalsh(M).min() < 0
        kind = 2
    b = rng.normal(size=8)
    (kc, xc, pc), (kf, xf, pf) = (solve(M, b) for solve in tree_solvers)
    assert kc == kf == kind
    for x in (xc, xf):
        assert np.allclose(x, np.linalg.solve(M, b), rtol=1e-12, atol=1e-12)
    assert np.array_equal(xc, xf)
    if kind == 2:
        assert np.array_equal(pc + 1, pf)


def test_ancestors_read_in_each_language():
    """The loop up a tree: C's for along the parents (from the parent, or from the node itself),
    Fortran's do while over the parents held plus one (a root's parent 0), its step closing the body."""
    c = CProcedurePrinter().text(linalg.mass_factor(parents="par"))
    assert "        for (i = par[k]; i >= 0; i = par[i])\n            for (j = i; j >= 0; j = par[j])\n" in c
    assert "\n     * par (M[i][j] != 0 only for j an ancestor of i: no fill-in; Featherstone 2008,\n" in c
    f = FortranProcedurePrinter().text(linalg.mass_solve(parents="par"))
    assert ("        i = par(k)\n        do while (i >= 1)\n          b(i) = b(i) - W(k, i) * b(k)\n"
            "          i = par(i)\n        end do\n") in f
    assert "if (ftype == 4) then ! M = L^T L" in f and "real(c_double) :: tmp\n" in f  # no s: the tree has none
    factor = FortranProcedurePrinter().text(linalg.mass_factor(parents="par"))
    assert "        j = i\n        do while (j >= 1)\n" in factor and "ftype = 4\n" in factor
    # Fortran's exit would leave the do while, not the first way's loop: there a Fail up a tree is refused
    up = pr.Ancestors("i", pr.ix("k"), "par", (pr.Fail(),))
    proc = pr.Procedure("p", (), (pr.Local("i", "int"), pr.Local("k", "int")), (pr.Fallback(
        (pr.For("k", pr.ix(), pr.ix("N"), (up,)),), (pr.Return(2),)),), returns="kind", sizes=("N",))
    c = CProcedurePrinter().text(proc)
    assert "        for (i = par[k]; i >= 0; i = par[i])\n            goto fallback;\n" in c
    with pytest.raises(NotImplementedError, match="fallback"):
        FortranProcedurePrinter().text(proc)
