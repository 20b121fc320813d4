"""The dense linear algebra of the generated code, written once as procedures of the
language-neutral tree (:mod:`.procedure`) and printed by every backend (C: :mod:`.c_procedure`,
Fortran: :mod:`.fortran_procedure`): ``lu_factor(dim, K, piv)``, in-place LU with partial pivoting
of the dim x dim matrix K (row i, column j), a truth value (false when a pivot is below
dim * eps * max|K|, numerically singular); ``lu_solve(dim, K, piv, b)``, b overwritten by the
solution of K x = b from those factors, used by the augmented system of the constrained code
(eq. 4.5 of the notes), the impacts and the constrained sensitivities; the mass matrix's
factorization (:func:`mass_factor`: Cholesky, LU where M is not positive definite, or its diagonal;
a rigid-body tree's M = L^T L along the tree's parents) and solve (:func:`mass_solve`); the
augmented system by the Schur complement of M (:func:`schur_solve`), tried before the LU of the
whole system.
"""

from __future__ import annotations

from .ir import BinOp as Op
from .ir import Call, Compare, Integer, Logic, Neg, Not, Number
from .ir import Element as At
from .ir import Name as Ref
from .procedure import (Ancestors, Arg, Blank, Comment, EachElement, Exchange, Fail, Fallback, For, Identity, If, Local,
                        Procedure, Return, Set, Sized, ix)


def Fn(name, arg):  # noqa: N802 - a node's constructor
    return Call(name, (arg,))


def Cmp(op, left, right):  # noqa: N802
    return Compare(op, left, right)


def Or(left, right):  # noqa: N802
    return Logic("or", (left, right))


def Lit(value):  # noqa: N802
    return Number(value)


def _swap(a, b, temp: str) -> tuple:
    """Exchange the elements a and b through the scoped local ``temp``."""
    return Set(Ref(temp), a, declare=True), Set(a, b), Set(b, Ref(temp))


#: dim * eps: a pivot is below dim * eps * max|K| in a numerically singular matrix.
_dim_eps = Op("*", Call("real", (Ref("dim"),)), Call("epsilon", ()))


def lu_factor() -> Procedure:
    """In-place LU with partial pivoting (piv[k]: the row exchanged with row k)."""
    K = lambda i, j: At("K", (ix(i), ix(j)))  # noqa: E731
    body = (
        EachElement("K", "dim", ("i", "j"), (
            If(Cmp(">", Fn("abs", K("i", "j")), Ref("scale")), (Set(Ref("scale"), Fn("abs", K("i", "j"))),)),)),
        If(Or(Not(Cmp(">", Ref("scale"), Lit(0.0))), Not(Fn("isfinite", Ref("scale")))), (Return(False),)),
        For("k", ix(), ix("dim"), (
            Set(Ref("r"), ix("k"), declare=True),
            For("i", ix("k", const=1), ix("dim"), (
                If(Cmp(">", Fn("abs", K("i", "k")), Fn("abs", K("r", "k"))), (Set(Ref("r"), ix("i")),)),)),
            Set(At("piv", (ix("k"),)), ix("r")),
            If(Not(Cmp(">", Fn("abs", K("r", "k")), Op("*", _dim_eps, Ref("scale")))), (Return(False),)),
            If(Cmp("!=", ix("r"), ix("k")), (
                For("j", ix(), ix("dim"), _swap(K("k", "j"), K("r", "j"), "tmp")),)),
            For("i", ix("k", const=1), ix("dim"), (
                Set(Ref("f"), Op("/", K("i", "k"), K("k", "k")), declare=True),
                Set(K("i", "k"), Ref("f")),
                For("j", ix("k", const=1), ix("dim"), (
                    Set(K("i", "j"), Op("-", K("i", "j"), Op("*", Ref("f"), K("k", "j")))),)))),
        )),
        Return(True),
    )
    return Procedure(
        "lu_factor", (Arg("dim", "int"), Arg("K", "real", ("dim", "dim"), "inout"), Arg("piv", "int", ("dim",), "out")),
        (Local("scale", "real", init=0.0, alt="kmax"), Local("f", "real", scoped=True),
         Local("tmp", "real", scoped=True), Local("i", "int"), Local("j", "int"), Local("k", "int", alt="c"),
         Local("r", "int", scoped=True)),
        body, returns="truth", layouts={"K": "dim"})


def lu_solve() -> Procedure:
    """K x = b with the factors of :func:`lu_factor`, b overwritten by x: the row exchanges, the
    forward substitution of L (unit diagonal), the back substitution of U."""
    K = lambda i, j: At("K", (ix(i), ix(j)))  # noqa: E731
    b = lambda i: At("b", (i if not isinstance(i, str) else ix(i),))  # noqa: E731
    body = (
        For("k", ix(), ix("dim"), (Exchange("b", ix("k"), At("piv", (ix("k"),))),)),
        For("i", ix(), ix("dim"), (
            For("k", ix(), ix("i"), (Set(b("i"), Op("-", b("i"), Op("*", K("i", "k"), b("k")))),)),)),
        For("i", ix(), ix("dim"), (
            For("k", ix("i", const=1), ix("dim"), (Set(b("i"), Op("-", b("i"), Op("*", K("i", "k"), b("k")))),)),
            Set(b("i"), Op("/", b("i"), K("i", "i")))), down=True),
    )
    return Procedure(
        "lu_solve", (Arg("dim", "int"), Arg("K", "real", ("dim", "dim")), Arg("piv", "int", ("dim",)),
                     Arg("b", "real", ("dim",), "inout")),
        (Local("tmp", "real", scoped=True), Local("i", "int"), Local("k", "int", alt="c")),
        body, layouts={"K": "dim"})


def mass_solve(*, name: str = "solve", diagonal: bool = False, parents: str | None = None) -> Procedure:
    """M x = b in place with the factors W, piv of the mass matrix's factorization (``kind``: its
    result; 1 Cholesky, W's lower triangle L: L L^T x = b; 2 LU with the row exchanges piv;
    with ``diagonal``, 3: W's diagonal alone), N coordinates (a constant of the source). With
    ``parents`` (the array of a tree's parents, as in :func:`mass_factor`) 4 replaces 1: M = L^T L,
    L^T z = b from the leaves, then L x = z from the root, along the tree."""
    W = lambda i, j: At("W", (ix(i), ix(j)))  # noqa: E731
    b = lambda i: At("b", (ix(i),))  # noqa: E731
    s = Ref("s")
    body: tuple = ()
    if parents:
        body += (If(Cmp("==", Ref("kind"), Integer(4)), (
            For("k", ix(), ix("N"), (
                Set(b("k"), Op("/", b("k"), W("k", "k"))),
                Ancestors("i", ix("k"), parents, (Set(b("i"), Op("-", b("i"), Op("*", W("k", "i"), b("k")))),))),
                down=True),
            For("k", ix(), ix("N"), (
                Ancestors("i", ix("k"), parents, (Set(b("k"), Op("-", b("k"), Op("*", W("k", "i"), b("i")))),)),
                Set(b("k"), Op("/", b("k"), W("k", "k"))))),
            Return()), note="M = L^T L: L^T z = b from the leaves, then L x = z from the root"), Blank())
    if diagonal:
        body += (If(Cmp("==", Ref("kind"), Integer(3)), (
            For("i", ix(), ix("N"), (Set(b("i"), Op("/", b("i"), W("i", "i"))),)), Return())),)
    if not parents:
        body += (If(Cmp("==", Ref("kind"), Integer(1)), (
            For("i", ix(), ix("N"), (
                Set(s, b("i"), declare=True),
                For("k", ix(), ix("i"), (Set(s, Op("-", s, Op("*", W("i", "k"), b("k")))),)),
                Set(b("i"), Op("/", s, W("i", "i"))))),
            For("i", ix(), ix("N"), (
                Set(s, b("i"), declare=True),
                For("k", ix("i", const=1), ix("N"), (Set(s, Op("-", s, Op("*", W("k", "i"), b("k")))),)),
                Set(b("i"), Op("/", s, W("i", "i")))), down=True),
            Return())),)
    body += (
        For("k", ix(), ix("N"), (Exchange("b", ix("k"), At("piv", (ix("k"),))),)),
        For("i", ix(), ix("N"), (
            For("k", ix(), ix("i"), (Set(b("i"), Op("-", b("i"), Op("*", W("i", "k"), b("k")))),)),)),
        For("i", ix(), ix("N"), (
            For("k", ix("i", const=1), ix("N"), (Set(b("i"), Op("-", b("i"), Op("*", W("i", "k"), b("k")))),)),
            Set(b("i"), Op("/", b("i"), W("i", "i")))), down=True),
    )
    return Procedure(
        name, (Arg("kind", "int", alt="ftype"), Arg("W", "real", ("N", "N")), Arg("piv", "int", ("N",)),
               Arg("b", "real", ("N",), "inout")),
        ((Local("s", "real", scoped=True),) if not parents else ())
        + (Local("tmp", "real", scoped=True), Local("i", "int"), Local("k", "int")),
        body, sizes=("N",))


def _times_eps(size: str, scale: str):
    """size * eps * scale: a pivot below it is numerically zero."""
    return Op("*", Op("*", Call("real", (Ref(size),)), Call("epsilon", ())), Ref(scale))


def _cholesky(L: str, M: str, size: str, scale: str, j: str, d: str, s: str, below, note=None) -> For:
    """The Cholesky factor of ``M`` (lower triangle) into ``L``, column by column; ``below``: the
    statement taken where a pivot d is not above ``size`` * eps * ``scale``."""
    At2 = lambda a, i, k: At(a, (ix(i), ix(k)))  # noqa: E731
    return For(j, ix(), ix(size), (
        Set(Ref(d), At2(M, j, j), declare=True),
        For("k", ix(), ix(j), (Set(Ref(d), Op("-", Ref(d), Op("*", At2(L, j, "k"), At2(L, j, "k")))),)),
        If(Not(Cmp(">", Ref(d), _times_eps(size, scale))), (below,)),
        Set(At2(L, j, j), Fn("sqrt", Ref(d))),
        For("i", ix(j, const=1), ix(size), (
            Set(Ref(s), At2(M, "i", j), declare=True),
            For("k", ix(), ix(j), (Set(Ref(s), Op("-", Ref(s), Op("*", At2(L, "i", "k"), At2(L, j, "k")))),)),
            Set(At2(L, "i", j), Op("/", Ref(s), At2(L, j, j))))),
    ), note=note)


def _tree_factor(parents: str) -> tuple:
    """M = L^T L into W (L lower triangular) from the leaves (the last rows) to the root along the
    tree ``parents``: W's rows from M's entries on each row's ancestors, then for each row k from
    the last, the square root of its pivot, its ancestors' entries divided by it, and the update
    of the entries (i, j) with i an ancestor of k and j i or an ancestor of i; a pivot not above
    N * eps * scale gives up (:class:`~.procedure.Fail`)."""
    W = lambda i, j: At("W", (ix(i), ix(j)))  # noqa: E731
    M = lambda i, j: At("M", (ix(i), ix(j)))  # noqa: E731
    return (
        For("k", ix(), ix("N"), (
            Set(W("k", "k"), M("k", "k")),
            Ancestors("i", ix("k"), parents, (Set(W("k", "i"), M("k", "i")),))), down=True),
        For("k", ix(), ix("N"), (
            If(Not(Cmp(">", W("k", "k"), _times_eps("N", "scale"))), (Fail(),)),
            Set(W("k", "k"), Fn("sqrt", W("k", "k"))),
            Ancestors("i", ix("k"), parents, (Set(W("k", "i"), Op("/", W("k", "i"), W("k", "k"))),)),
            Ancestors("i", ix("k"), parents, (Ancestors("j", ix("i"), parents, (
                Set(W("i", "j"), Op("-", W("i", "j"), Op("*", W("k", "i"), W("k", "j")))),), inclusive=True),))),
            down=True),
    )


def mass_factor(*, name: str = "factor", diagonal: bool = False, pivot: str = "p", cholesky_comment: bool = True,
                lu_only: bool = False, parents: str | None = None) -> Procedure:
    """Factor the symmetric N x N mass matrix M into W: Cholesky (result 1, W's lower triangle),
    LU with partial pivoting (2, the row exchanges in piv) where M is not numerically positive
    definite, 0 where it is singular or not finite; with ``diagonal`` (M structurally diagonal),
    3: W holds M's diagonal. ``lu_only`` (M not symmetric): LU alone. ``pivot``: the name of the
    LU pivot row; ``cholesky_comment``: a comment before the Cholesky factorization. With
    ``parents`` (the name of an array of a tree's parents, :class:`~.procedure.Ancestors`; M[i][j]
    nonzero only for j an ancestor of i, or i of j) M = L^T L from the leaves to the root along
    the tree in place of Cholesky, without fill-in (Featherstone 2008, sec. 6.5): result 4."""
    W = lambda i, j: At("W", (ix(i), ix(j)))  # noqa: E731
    M = lambda i, j: At("M", (ix(i), ix(j)))  # noqa: E731
    scale = Ref("scale")
    body: tuple = (
        For("i", ix(), ix("N"), (If(Cmp(">", Fn("abs", M("i", "i")), scale), (Set(scale, Fn("abs", M("i", "i"))),)),)),
        If(Or(Not(Cmp(">", scale, Lit(0.0))), Not(Fn("isfinite", scale))), (Return(0),)),
    )
    if diagonal:
        body += (Blank(), For("i", ix(), ix("N"), (
            If(Not(Cmp(">", Fn("abs", M("i", "i")), _times_eps("N", "scale"))), (Return(0),)),
            Set(W("i", "i"), M("i", "i")),
            Identity("piv", ix("i")))), Return(3))
    if lu_only:
        body += (Blank(), Comment("M is not symmetric (every entry written): LU with partial pivoting."), Fail())
    if parents:
        body += (Blank(), Comment(
            "M = L^T L (L lower triangular in W) from the leaves to the root, along the tree's parents\n"
            f"{parents} (M[i][j] != 0 only for j an ancestor of i: no fill-in; Featherstone 2008,\nsec. 6.5)."))
    elif cholesky_comment:
        body += (Blank(), Comment("Cholesky, lower triangle of W."))
    p = Ref(pivot)
    lu = (
        Set(scale, Lit(0.0)),
        For("i", ix(), ix("N"), (For("j", ix(), ix("N"), (
            Set(W("i", "j"), M("i", "j")),
            If(Cmp(">", Fn("abs", M("i", "j")), scale), (Set(scale, Fn("abs", M("i", "j"))),)))),)),
        For("k", ix(), ix("N"), (
            Set(p, ix("k"), declare=True),
            For("i", ix("k", const=1), ix("N"), (
                If(Cmp(">", Fn("abs", W("i", "k")), Fn("abs", W(pivot, "k"))), (Set(p, ix("i")),)),)),
            Set(At("piv", (ix("k"),)), ix(pivot)),
            If(Not(Cmp(">", Fn("abs", W(pivot, "k")), _times_eps("N", "scale"))), (Return(0),)),
            If(Cmp("!=", ix(pivot), ix("k")), (For("j", ix(), ix("N"), _swap(W("k", "j"), W(pivot, "j"), "tmp")),)),
            For("i", ix("k", const=1), ix("N"), (
                Set(W("i", "k"), Op("/", W("i", "k"), W("k", "k"))),
                For("j", ix("k", const=1), ix("N"), (
                    Set(W("i", "j"), Op("-", W("i", "j"), Op("*", W("i", "k"), W("k", "j")))),)))))),
        Return(2),
    )
    first = _tree_factor(parents) if parents else (_cholesky("W", "M", "N", "scale", "j", "d", "s", Fail()),)
    body += (Fallback(first, lu, kinds=(4 if parents else 1, 2), label="lu",
                      note="LU with partial pivoting (rows of W swapped in place, piv(k) = row swapped with k)."),)
    return Procedure(
        name, (Arg("M", "real", ("N", "N")), Arg("W", "real", ("N", "N"), "out"), Arg("piv", "int", ("N",), "out")),
        (Local("scale", "real", init=0.0, alt="smax"),)
        + ((Local("d", "real", scoped=True), Local("s", "real", scoped=True)) if not parents else ())
        + (Local("tmp", "real", scoped=True), Local("i", "int"), Local("j", "int"), Local("k", "int"),
           Local(pivot, "int", scoped=True)),
        body, returns="kind", result="ftype", sizes=("N",), identity=(("piv", "N"),))


def _substitution(size: str, factor, rhs: str, out: str, diagonal: str, note=None, back: bool = False) -> For:
    """out = T^-1 rhs for the triangular T whose element (i, k) is ``factor`` (an element of the
    matrix ``diagonal``, whose diagonal divides): forward (k < i), or ``back`` (k > i)."""
    s = Ref("s")
    return For("i", ix(), ix(size), (
        Set(s, At(rhs, (ix("i"),)), declare=True),
        For("k", ix("i", const=1) if back else ix(), ix(size) if back else ix("i"), (
            Set(s, Op("-", s, Op("*", factor, At(out, (ix("k"),))))),)),
        Set(At(out, (ix("i"),)), Op("/", s, At(diagonal, (ix("i"), ix("i")))))), note=note, down=back)


def schur_solve() -> Procedure:
    """The augmented system [M A^T; A 0] [a; x] = [F; b] (N coordinates, J constraints) by the
    Schur complement of M: M = L L^T (Cholesky), V = L^-1 A^T, u = L^-1 F, S = V^T V =
    A M^-1 A^T = G G^T (Cholesky), S x = V^T u - b, a = L^-T (u - V x): about half the operations
    of the LU of the whole system, without pivoting. True, or false where it does not apply (M not
    numerically positive definite, or a pivot of S below 1e-8 max S_rr): the caller then solves
    the whole system by LU, which decides whether it is singular."""
    A2 = lambda a, i, k: At(a, (ix(i), ix(k)))  # noqa: E731
    A1 = lambda a, i: At(a, (ix(i),))  # noqa: E731
    s, d, scale = Ref("s"), Ref("d"), Ref("scale")
    minus = lambda x, y: Set(x, Op("-", x, y))  # noqa: E731
    constraints = (
        For("r", ix(), ix("J"), (For("i", ix(), ix("N"), (
            Set(s, A2("A", "r", "i"), declare=True),
            For("k", ix(), ix("i"), (minus(s, Op("*", A2("L", "i", "k"), A2("V", "r", "k"))),)),
            Set(A2("V", "r", "i"), Op("/", s, A2("L", "i", "i"))))),), note="row r of V^T: L^-1 A_r^T"),
        Set(scale, Lit(0.0)),
        For("r", ix(), ix("J"), (
            Set(s, Neg(A1("b", "r")), declare=True),
            For("k", ix(), ix("N"), (Set(s, Op("+", s, Op("*", A2("V", "r", "k"), A1("u", "k")))),)),
            Set(A1("x", "r"), s),
            For("c", ix(), ix("r", const=1), (
                Set(s, Lit(0.0)),
                For("k", ix(), ix("N"), (Set(s, Op("+", s, Op("*", A2("V", "r", "k"), A2("V", "c", "k")))),)),
                Set(A2("S", "r", "c"), s))),
            If(Cmp(">", A2("S", "r", "r"), scale), (Set(scale, A2("S", "r", "r")),))),
            note="lower triangle of S, and x = V^T u - b"),
        For("c", ix(), ix("J"), (
            Set(d, A2("S", "c", "c"), declare=True),
            For("k", ix(), ix("c"), (minus(d, Op("*", A2("S", "c", "k"), A2("S", "c", "k"))),)),
            If(Not(Cmp(">", d, Op("*", Lit(1e-8), scale))), (Return(False),)),
            Set(A2("S", "c", "c"), Fn("sqrt", d)),
            For("i", ix("c", const=1), ix("J"), (
                Set(s, A2("S", "i", "c"), declare=True),
                For("k", ix(), ix("c"), (minus(s, Op("*", A2("S", "i", "k"), A2("S", "c", "k"))),)),
                Set(A2("S", "i", "c"), Op("/", s, A2("S", "c", "c"))))),
        ), note="S = G G^T, G over S's lower triangle"),
        _substitution("J", A2("S", "i", "k"), "x", "x", "S", note="x = S^-1 x"),
        _substitution("J", A2("S", "k", "i"), "x", "x", "S", back=True),
    )
    body = (
        For("i", ix(), ix("N"), (If(Cmp(">", A2("M", "i", "i"), scale), (Set(scale, A2("M", "i", "i")),)),)),
        If(Or(Not(Cmp(">", scale, Lit(0.0))), Not(Fn("isfinite", scale))), (Return(False),)),
        _cholesky("L", "M", "N", "scale", "c", "d", "s", Return(False), note="M = L L^T"),
        _substitution("N", A2("L", "i", "k"), "F", "u", "L", note="u = L^-1 F"),
        Sized("J", constraints, none="no constraints"),
        For("i", ix(), ix("N"), (
            Set(s, A1("u", "i"), declare=True),
            Sized("J", (For("r", ix(), ix("J"), (minus(s, Op("*", A2("V", "r", "i"), A1("x", "r"))),)),)),
            For("k", ix("i", const=1), ix("N"), (minus(s, Op("*", A2("L", "k", "i"), A1("acc", "k"))),)),
            Set(A1("acc", "i"), Op("/", s, A2("L", "i", "i")))), down=True, note="a = L^-T (u - V x)"),
        Return(True),
    )
    return Procedure(
        "schur_solve", (Arg("M", "real", ("N", "N")), Arg("F", "real", ("N",)), Arg("A", "real", ("J", "N")),
                        Arg("b", "real", ("J",)), Arg("acc", "real", ("N",), "out"), Arg("x", "real", ("J",), "out")),
        (Local("L", "real", shape=("N", "N")), Local("V", "real", shape=("J", "N")), Local("S", "real", shape=("J", "J")),
         Local("u", "real", shape=("N",)), Local("scale", "real", init=0.0, alt="smax"),
         Local("d", "real", scoped=True), Local("s", "real", scoped=True, alt="w"),
         Local("i", "int"), Local("k", "int"), Local("r", "int", needs="J"), Local("c", "int")),
        body, returns="truth", sizes=("N", "J"))


#: The procedures by name.
PROCEDURES = {"lu_factor": lu_factor, "lu_solve": lu_solve, "mass_solve": mass_solve, "mass_factor": mass_factor,
              "schur_solve": schur_solve}
