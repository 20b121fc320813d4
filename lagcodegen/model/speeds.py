"""A model's generalized speeds v != q' and equations given directly (notes eq. 2.1 with q' a
function of the speeds; Kane's form): the checks of the speeds and their kinematic equations
(:meth:`Model.generalized_speeds <lagcodegen.model.model.Model.generalized_speeds>`), a
quaternion joint's speeds and kinematics, and the checks of M v' = F given directly
(:meth:`Model.equations_of_motion <lagcodegen.model.model.Model.equations_of_motion>`). Nothing
is derived here."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import sympy as sp

from ..errors import ModelError
from ..util import excerpt
from .bodies import Joint, quaternion_rates, quaternion_rotation
from .names import as_expr, check_name


@dataclass(frozen=True)
class GivenEquations:
    """Equations of motion M(q, v, t) v' = F(q, v, t) given directly (:meth:`Model.equations_of_motion`),
    with the energies of the system they describe when known (None: not known)."""

    label: str
    M: sp.Matrix  # nv x nv
    F: sp.Matrix  # nv x 1
    kinetic_energy: sp.Expr | None
    potential_energy: sp.Expr | None
    symmetric: bool
    missing: tuple = ()  # ("T" or "V", why it is not known) for the error messages


#: :meth:`Model.equations_of_motion` proves M symmetric by expanding M_ij - M_ji only for entries of
#: at most this many operations (else M counts as not symmetric: solved by LU, still right).
SYMMETRY_CHECK_MAX_OPS = 400


def provably_symmetric(M: sp.Matrix) -> bool:
    """True if M_ij - M_ji is zero for every i < j, structurally or once expanded (entries of
    at most SYMMETRY_CHECK_MAX_OPS operations)."""
    n = M.shape[0]
    for i in range(n):
        for j in range(i + 1, n):
            a, b = M[i, j], M[j, i]
            if a == b:
                continue
            if sp.count_ops(a) + sp.count_ops(b) > SYMMETRY_CHECK_MAX_OPS or sp.expand(a - b) != 0:
                return False
    return True


def declared_speeds(model, names: Sequence[str] | str, kinematics, excess: bool) -> tuple[list, list]:
    """(the speeds' symbols, q' per coordinate as sympy expressions) of
    :meth:`Model.generalized_speeds`, every name and expression checked."""
    if model.velocities:
        raise ModelError(f"model {model.name!r} has generalized speeds already")
    if isinstance(names, str):
        names = names.replace(",", " ").split()
    syms = []
    rates = {s.name for s in model.speeds}
    for name in names:
        check_name(name, "generalized speed")
        if name not in rates:  # a coordinate's own rate may be one of the speeds
            model._check_free(name)
        syms.append(sp.Symbol(name))
    if len(set(syms)) != len(syms):
        raise ModelError("generalized speeds: a name is given twice")
    if len(syms) > model.n and not excess:
        raise ModelError(f"{len(syms)} generalized speeds for {model.n} coordinates: at most one per coordinate")
    if isinstance(kinematics, dict):
        rows = {model.index(k): v for k, v in kinematics.items()}
        missing = [model.coords[i].name for i in range(model.n) if i not in rows]
        if missing:
            raise ModelError(f"kinematic equations: no q' given for coordinate(s) {', '.join(missing)}")
        kinematics = [rows[i] for i in range(model.n)]
    kinematics = list(kinematics)
    if len(kinematics) != model.n:
        raise ModelError(f"kinematic equations: {len(kinematics)} given for {model.n} coordinates")
    exprs = [as_expr(e, f"kinematic equation of {q.name!r}") for e, q in zip(kinematics, model.coords)]
    allowed = set(model.coords) | set(syms) | set(model.params) | {model.t}
    for e, q in zip(exprs, model.coords):
        bad = e.free_symbols - allowed
        if bad:
            raise ModelError(f"kinematic equation of {q.name!r} ({excerpt(e)}) uses "
                             f"{', '.join(sorted(s.name for s in bad))}: only coordinates, the speeds "
                             f"{', '.join(names)}, parameters and t")
    return syms, exprs


def quaternion_kinematics(joint: Joint, coords: Sequence) -> tuple[list, list]:
    """(the speeds, q' of each coordinate) of a quaternion joint with coordinates ``coords``: a
    free joint's (x, y, z)' = R(q) v and the quaternion's q' = 1/2 q (x) (0, w)."""
    w = [sp.Symbol(name) for name in joint.speed_names]
    quat = coords[-4:]
    qdot = []
    if joint.kind == "free":
        R = quaternion_rotation(*quat)
        qdot = [sum((R[i][j] * w[j] for j in range(3)), sp.Integer(0)) for i in range(3)]
    return w, qdot + quaternion_rates(quat, w[-3:])


def check_given(model, expr, what: str) -> None:
    """``model.check_symbols`` for a term in (q, v, t): with generalized speeds, the coordinates'
    rates q' that are not speeds are refused (they are no state: write them by the kinematic
    equations)."""
    model.check_symbols(expr, what)
    if model.general:
        rates = sorted(s.name for s in sp.sympify(expr).free_symbols if s in set(model.speeds) - set(model.velocities))
        if rates:
            raise ModelError(f"{what} uses the coordinates' rate(s) {', '.join(rates)}, which are not speeds of "
                             f"model {model.name!r}: write them by the kinematic equations (the speeds are "
                             f"{', '.join(s.name for s in model.velocities)})")


def given_equations(model, M, F, energies: tuple, symmetric: bool | None, label: str,
                    missing: dict | None) -> GivenEquations:
    """The :class:`GivenEquations` of :meth:`Model.equations_of_motion`, checked: M nv x nv and F
    of nv rows in the model's symbols (``energies``: (T, V), each None when not given)."""
    what = f"mass matrix of {label!r}"
    try:
        Mm = sp.Matrix(M)
    except (TypeError, ValueError, sp.SympifyError):
        raise ModelError(f"{what} is not a matrix: {excerpt(M)}") from None
    nv = model.nv
    if Mm.shape != (nv, nv):
        raise ModelError(f"{what} is {Mm.shape[0]} x {Mm.shape[1]}, the model has {nv} speeds "
                         f"({', '.join(s.name for s in model.v)})")
    try:
        Fm = sp.Matrix(F)
    except (TypeError, ValueError, sp.SympifyError):
        raise ModelError(f"forces of {label!r} are not a vector: {excerpt(F)}") from None
    if Fm.shape == (1, nv) and nv > 1:
        Fm = Fm.T
    if Fm.shape != (nv, 1):
        raise ModelError(f"forces of {label!r} have {Fm.shape[0]} x {Fm.shape[1]} entries, the model has {nv} speeds")
    Mm = Mm.applyfunc(lambda e: as_expr(e, what))
    Fm = Fm.applyfunc(lambda e: as_expr(e, f"forces of {label!r}"))
    kinetic_energy, potential_energy = energies
    T = None if kinetic_energy is None else as_expr(kinetic_energy, f"kinetic energy of {label!r}")
    V = None if potential_energy is None else as_expr(potential_energy, f"potential energy of {label!r}")
    for expr, part in ((Mm, what), (Fm, f"forces of {label!r}"), (T, f"kinetic energy of {label!r}")):
        if expr is not None:
            check_given(model, expr, part)
    if V is not None:
        model.check_symbols(V, f"potential energy of {label!r}", allow_speeds=False)
    if symmetric is None:
        symmetric = provably_symmetric(Mm)
    return GivenEquations(label, Mm, Fm, T, V, bool(symmetric),
                          tuple((k, str(v)) for k, v in (missing or {}).items() if v))
