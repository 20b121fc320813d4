"""The dense LU solve of the generated code, written once as procedures of the language-neutral
tree (:mod:`.procedure`) and printed by every backend (C: :mod:`.c_procedure`, Fortran:
:mod:`.fortran_procedure`): ``lu_factor(dim, K, piv)``, in-place LU with partial pivoting of the
dim x dim matrix K (row i, column j), a truth value (false when a pivot is below
dim * eps * max|K|, numerically singular); ``lu_solve(dim, K, piv, b)``, b overwritten by the
solution of K x = b from those factors. Used by the augmented system of the constrained code
(eq. 4.5 of the notes), the impacts and the constrained sensitivities.
"""

from __future__ import annotations

from .ir import BinOp as Op
from .ir import Call, Compare, Integer, Logic, Not, Number
from .ir import Element as At
from .ir import Name as Ref
from .procedure import Arg, EachElement, Exchange, For, If, Local, Procedure, Return, Set, ix


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


def mass_solve(*, name: str = "solve", diagonal: bool = False) -> Procedure:
    """M x = b in place with the factors W, piv of the mass matrix's factorization (``kind``: its
    result; 1 Cholesky, W's lower triangle L: L L^T x = b; 2 LU with the row exchanges piv;
    with ``diagonal``, 3: W's diagonal alone), N coordinates (a constant of the source)."""
    W = lambda i, j: At("W", (ix(i), ix(j)))  # noqa: E731
    b = lambda i: At("b", (ix(i),))  # noqa: E731
    s = Ref("s")
    body: tuple = ()
    if diagonal:
        body += (If(Cmp("==", Ref("kind"), Integer(3)), (
            For("i", ix(), ix("N"), (Set(b("i"), Op("/", b("i"), W("i", "i"))),)), Return())),)
    body += (
        If(Cmp("==", Ref("kind"), Integer(1)), (
            For("i", ix(), ix("N"), (
                Set(s, b("i"), declare=True),
                For("k", ix(), ix("i"), (Set(s, Op("-", s, Op("*", W("i", "k"), b("k")))),)),
                Set(b("i"), Op("/", s, W("i", "i"))))),
            For("i", ix(), ix("N"), (
                Set(s, b("i"), declare=True),
                For("k", ix("i", const=1), ix("N"), (Set(s, Op("-", s, Op("*", W("k", "i"), b("k")))),)),
                Set(b("i"), Op("/", s, W("i", "i")))), down=True),
            Return())),
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
        (Local("s", "real", scoped=True), Local("tmp", "real", scoped=True), Local("i", "int"), Local("k", "int")),
        body, sizes=("N",))


#: The procedures by name.
PROCEDURES = {"lu_factor": lu_factor, "lu_solve": lu_solve, "mass_solve": mass_solve}
