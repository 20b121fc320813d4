"""Ignorable coordinates and Routh's reduction (sec. 3.4 of the notes).

A coordinate q_i that does not appear in L (dL/dq_i = 0), in the dissipation D nor in the
generalized forces, and on which no non-potential force acts, has a conserved momentum:
dL/dq_i' = C_i (eq. 3.8). Solving these m relations for the ignorable velocities and
forming the Routhian

    R = -L + sum_i C_i q_i'                                     (eq. 3.9, ignorable i)

leaves a system in the n - m other coordinates with the C_i as parameters:

    d/dt (dR/dq_r') - dR/dq_r = 0                               (eq. 3.10)

The ignorable coordinates follow by quadrature, q_i' = dR/dC_i (eq. 3.11), and the Jacobi
function of the reduced system, h = R - sum_r q_r' dR/dq_r' (eq. 3.12), equals the full h.

:func:`reduce` builds a :class:`RouthReduction`, which holds the symbolic results and a
reduced :class:`~lagcodegen.model.Model` with Lagrangian L_R = -R. Its derived equations
carry the ignorable coordinates as quadrature states, so that the generated code integrates
(q_r, q_r', q_i) and a simulation returns the whole configuration.
"""

from __future__ import annotations

import random
from dataclasses import dataclass
from functools import cached_property
from typing import Mapping, Sequence

import numpy as np
import sympy as sp

from ..derivation import EquationsOfMotion, derive, require_lagrange, to_se
from ..errors import DerivationError, LagcodegenError, ModelError
from ..model.model import Model
from ..result import Result
from ..util import check_finite, state_vector

__all__ = ["RouthReduction", "ignorable_coordinates", "reduce", "is_zero", "tidy"]


# ---------------------------------------------------------------------- expression helpers
def tidy(expr, max_ops: int = 400) -> sp.Expr:
    """Simplify ``expr`` with sympy when it is small enough for that to be quick."""
    expr = sp.sympify(expr)
    if expr.is_number or sp.count_ops(expr) > max_ops:
        return expr
    return sp.simplify(expr)


def is_zero(expr, trials: int = 4) -> bool:
    """Whether ``expr`` vanishes identically.

    Evaluated with 30 significant digits at random points of its free symbols (in
    [0.2, 1.3], away from the usual singularities); an expression that is not zero there is
    not identically zero. When every trial is zero it is taken as identically zero; when
    evaluation fails (complex values, poles) sympy's simplify decides.
    """
    expr = sp.sympify(expr)
    if expr == 0:
        return True
    syms = sorted(expr.free_symbols, key=lambda s: s.name)
    rng = random.Random(20240611)
    conclusive = 0
    for _ in range(trials):
        vals = {s: sp.Float(rng.uniform(0.2, 1.3), 30) for s in syms}
        try:
            v = complex(expr.xreplace(vals).evalf(30))
        except (TypeError, ValueError, ZeroDivisionError):
            continue
        if not np.isfinite(v.real) or not np.isfinite(v.imag):
            continue
        if abs(v) > 1e-18:
            return False
        conclusive += 1
    if conclusive:
        return True
    return sp.simplify(expr) == 0


def _names(symbols) -> str:
    return ", ".join(s.name for s in symbols)


# ---------------------------------------------------------------------- ignorable coordinates
def _non_ignorable_reason(eom: EquationsOfMotion, i: int) -> str | None:
    """Where coordinate i shows up so that p_i is not conserved (None: it is ignorable)."""
    q, v = eom.q[i], eom.qd[i]
    if q in eom.L.free_symbols and not is_zero(sp.diff(eom.L, q)):
        return "it appears in L"
    if q in eom.D.free_symbols and not is_zero(sp.diff(eom.D, q)):
        return "it appears in D"
    for j, Qj in enumerate(eom.Q):
        if q in Qj.free_symbols and not is_zero(sp.diff(Qj, q)):
            return f"it appears in the generalized force on {eom.q[j].name}"
    if not is_zero(eom.Q[i]):
        return "a generalized force acts on it"
    if v in eom.D.free_symbols and not is_zero(sp.diff(eom.D, v)):
        return f"D depends on {v.name} (a dissipative force acts on it)"
    return None


def ignorable_coordinates(eom: EquationsOfMotion) -> list[sp.Symbol]:
    """Coordinates whose momentum p_i = dL/dq_i' is an integral of motion (eq. 3.8).

    q_i is ignorable when dL/dq_i = 0 (it does not appear in L = T - V), it does not appear
    in D nor in any generalized force, and neither a generalized force (Q_i = 0) nor a
    dissipative one (dD/dq_i' = 0) acts on it: then d/dt(dL/dq_i') = 0 by eq. 3.16.
    The test is for identical vanishing, so L may contain q_i in cancelling terms (as
    derivation leaves cos(phi)^2 + sin(phi)^2).
    """
    return [q for i, q in enumerate(eom.q) if _non_ignorable_reason(eom, i) is None]


# ---------------------------------------------------------------------- the reduction
@dataclass
class RouthReduction:
    """Routh's reduction of a model over its ignorable coordinates (sec. 3.4).

    Symbolic fields are sympy objects in the full model's symbols plus the integrals C_i:

    ``ignorable``          the ignorable coordinates q_i
    ``coordinates``        the remaining coordinates q_r (and ``velocities`` q_r')
    ``integrals``          symbols C_i (named ``C_<q_i>``), the constant momenta (eq. 3.8)
    ``momenta``            dL/dq_i' as functions of (q, q', t): what C_i equals
    ``velocity_solution``  q_i' -> expression in (q_r, q_r', C, t), from dL/dq_i' = C_i
    ``R``                  the Routhian -L + sum C_i q_i' with q_i' eliminated (eq. 3.9)
    ``reconstruction``     q_i' = dR/dC_i (eq. 3.11), one per ignorable coordinate
    ``h_R``                R - sum_r q_r' dR/dq_r' (eq. 3.12), equal to the full h
    ``model``              the reduced Model: coordinates q_r, parameters + C_i, L_R = -R
    """

    full: EquationsOfMotion
    ignorable: list[sp.Symbol]
    coordinates: list[sp.Symbol]
    velocities: list[sp.Symbol]
    integrals: list[sp.Symbol]
    momenta: list[sp.Expr]
    velocity_solution: dict
    R: sp.Expr
    reconstruction: list[sp.Expr]
    h_R: sp.Expr
    model: Model

    # ------------------------------------------------------------ symbolic views
    @property
    def t(self) -> sp.Symbol:
        return self.full.t

    @property
    def rates(self) -> dict[sp.Symbol, sp.Expr]:
        """q_i -> dR/dC_i (eq. 3.11)."""
        return dict(zip(self.ignorable, self.reconstruction))

    def accelerations(self) -> sp.Matrix:
        """Symbols q_r'' used by :meth:`equations`."""
        return sp.Matrix([sp.Symbol(f"{q.name}_ddot") for q in self.coordinates])

    def equations(self) -> sp.Matrix:
        """The reduced equations (eq. 3.10) as residuals (each = 0) in q_r, q_r', q_r''.

        d/dt(dR/dq_r') - dR/dq_r - dD/dq_r' + Q_r: with L_R = -R, this is eq. 3.16 of the
        reduced system multiplied by -1; for a conservative system it is eq. 3.10 as printed.
        """
        a = list(self.accelerations())
        D = self.model_dissipation
        Q = self.model_forces
        rows = []
        for k, v in enumerate(self.velocities):
            dRdv = sp.diff(self.R, v)
            ddt = sp.diff(dRdv, self.t)
            for q, w, acc in zip(self.coordinates, self.velocities, a):
                ddt += sp.diff(dRdv, q) * w + sp.diff(dRdv, w) * acc
            rows.append(ddt - sp.diff(self.R, self.coordinates[k]) - sp.diff(D, v) + Q[k])
        return sp.Matrix(rows)

    @property
    def model_dissipation(self) -> sp.Expr:
        """D carried over to the reduced model (it depends on no ignorable coordinate or velocity)."""
        return sum((e for _, e in self.model.dissipation_terms), sp.Integer(0))

    @property
    def model_forces(self) -> list[sp.Expr]:
        """Generalized forces on q_r, with the ignorable velocities eliminated."""
        Q = [sp.Integer(0)] * len(self.coordinates)
        for _, i, e in self.model.generalized_forces:
            Q[i] += e
        return Q

    @cached_property
    def eom(self) -> EquationsOfMotion:
        """Derived equations of the reduced model, with quadratures q_i' = dR/dC_i (eq. 3.11).

        The generated code integrates y = (q_r, q_r', q_i).
        """
        eom = derive(self.model)
        eom.quadratures = [(q.name, to_se(rate, f"reconstruction rate of {q.name!r}"))
                           for q, rate in zip(self.ignorable, self.reconstruction)]
        return eom

    # ------------------------------------------------------------ numbers
    def parameter_values(self, params: Mapping[str, float] | None = None) -> dict[str, float]:
        """Full-model parameter values: defaults overridden by ``params`` (by name)."""
        values = {s.name: float(v) for s, v in self.full.model.params.items()}
        for k, v in (params or {}).items():
            if k not in values:
                raise ModelError(f"{k!r} is not a parameter of model {self.full.model.name!r} "
                                 f"(parameters: {', '.join(values) or 'none'})")
            values[k] = check_finite(v, f"parameter {k!r}")
        return values

    def integrals_at(self, q0, v0=None, t0: float = 0.0,
                     params: Mapping[str, float] | None = None) -> dict[str, float]:
        """Values of the integrals C_i = dL/dq_i' (eq. 3.8) at a state of the full model.

        ``q0``, ``v0``: arrays in the full model's coordinate order, or dicts by name.
        """
        qv = state_vector(q0, [q.name for q in self.full.q], "q0")
        vv = state_vector(v0, [q.name for q in self.full.q], "v0")
        values = self.parameter_values(params)
        sub = {q: sp.Float(x, 20) for q, x in zip(self.full.q, qv)}
        sub.update({v: sp.Float(x, 20) for v, x in zip(self.full.qd, vv)})
        sub.update({s: sp.Float(values[s.name], 20) for s in self.full.model.params})
        sub[self.t] = sp.Float(t0, 20)
        out = {}
        for C, p in zip(self.integrals, self.momenta):
            val = complex(p.xreplace(sub).evalf(20))
            if not np.isfinite(val.real) or abs(val.imag) > 1e-12 * max(1.0, abs(val.real)):
                raise ModelError(f"the momentum {C.name} = {p} is not a finite real number at the initial state")
            out[C.name] = val.real
        return out

    # ------------------------------------------------------------ simulate (compiled by lagcodegen.compile_reduction)
    def initial_state(self, cm, q0, v0=None, t0: float = 0.0,
                      params: Mapping[str, float] | None = None) -> tuple[np.ndarray, dict[str, float]]:
        """Reduced state y0 = (q_r, q_r', q_i) and run-time parameters (with the C_i) from a full state."""
        integral_names = {C.name for C in self.integrals}
        user = dict(params or {})
        given = integral_names & set(user)
        if given:
            raise LagcodegenError(f"{', '.join(sorted(given))}: the integrals are computed from the initial "
                                  "state, do not pass them")
        unknown = set(user) - set(cm.param_names)
        if unknown:
            raise LagcodegenError(f"{', '.join(sorted(unknown))}: not a run-time parameter of this scene "
                                  f"(run-time parameters: {', '.join(cm.param_names)})")
        values = self.parameter_values()
        values.update(cm.code.folded)
        values.update({k: v for k, v in zip(cm.param_names, cm.code.param_defaults) if k not in integral_names})
        values.update({k: check_finite(v, f"parameter {k!r}") for k, v in user.items()})
        full_values = {k: v for k, v in values.items() if k not in integral_names}
        C = self.integrals_at(q0, v0, t0, full_values)
        run = {k: values[k] for k in cm.param_names if k not in integral_names}
        run.update(C)
        qv = state_vector(q0, [q.name for q in self.full.q], "q0")
        vv = state_vector(v0, [q.name for q in self.full.q], "v0")
        index = {q: i for i, q in enumerate(self.full.q)}
        red = [index[q] for q in self.coordinates]
        ign = [index[q] for q in self.ignorable]
        y0 = np.concatenate([qv[red], vv[red], qv[ign]])
        return y0, run

    def simulate(self, cm, t, q0, v0=None, params: Mapping[str, float] | None = None,
                 **options) -> Result:
        """Integrate the reduced system from a state of the FULL model.

        ``q0``, ``v0`` are in the full model's coordinate order (or dicts by name). The
        integrals C_i are computed from them (eq. 3.8) and passed as run-time parameters;
        the state is y0 = (q_r, q_r', q_i). The Result's ``q`` holds every coordinate
        (ignorable ones as quadrature states, eq. 3.11) and its ``parameters`` the C_i.
        ``options`` go to :meth:`CompiledModel.simulate <lagcodegen.simulation.ode.CompiledModel.simulate>`.
        """
        times = np.asarray(t, dtype=float).ravel()
        y0, run = self.initial_state(cm, q0, v0, float(times[0]) if times.size else 0.0, params)
        return cm.simulate(t, y0=y0, params=run, **options)


def _resolve_ignorable(eom: EquationsOfMotion, ignorable: Sequence[str] | None) -> list[sp.Symbol]:
    if ignorable is None:
        found = ignorable_coordinates(eom)
        if not found:
            reasons = "; ".join(f"{q.name} ({_non_ignorable_reason(eom, i)})" for i, q in enumerate(eom.q))
            raise ModelError(f"no ignorable coordinate: every coordinate appears in L (or in D or a force): "
                             f"{reasons}", location="routhian.reduce")
        return found
    if isinstance(ignorable, str):
        ignorable = ignorable.replace(",", " ").split()
    if not ignorable:
        raise ModelError("no ignorable coordinate given", location="routhian.reduce")
    out = []
    for name in ignorable:
        name = getattr(name, "name", name)
        i = eom.model.index(name)  # ModelError when not a coordinate
        reason = _non_ignorable_reason(eom, i)
        if reason is not None:
            raise ModelError(f"coordinate {name!r} is not ignorable: {reason}", location="routhian.reduce")
        if eom.q[i] in out:
            raise ModelError(f"coordinate {name!r} is listed twice", location="routhian.reduce")
        out.append(eom.q[i])
    return out


def reduce(system: EquationsOfMotion | Model, ignorable: Sequence[str] | None = None) -> RouthReduction:
    """Routh's reduction of ``system`` (a Model is derived first) over ``ignorable``.

    ``ignorable=None`` takes every ignorable coordinate (:func:`ignorable_coordinates`).
    Raises :class:`~lagcodegen.errors.ModelError` when there is none, when a named
    coordinate is not ignorable (appears in L, D or a force) or is not a coordinate, and
    when dL/dq_i' = C_i cannot be solved for the ignorable velocities.
    """
    require_lagrange(system, "Routh's reduction")
    underived: DerivationError | None = None
    if isinstance(system, Model):
        try:
            eom = derive(system)
        except DerivationError as exc:  # e.g. L linear in an ignorable velocity: say why below
            eom, underived = derive(system, check=False), exc
    else:
        eom = system
    model = eom.model
    ign = _resolve_ignorable(eom, ignorable)
    idx = [model.index(q) for q in ign]
    rest = [i for i in range(eom.n) if i not in idx]
    if not rest:
        raise ModelError("every coordinate is ignorable: nothing would be left to integrate "
                         "(the motion is q_i' = const)", location="routhian.reduce")
    qI = [eom.q[i] for i in idx]
    vI = [eom.qd[i] for i in idx]
    qr = [eom.q[i] for i in rest]
    vr = [eom.qd[i] for i in rest]
    zero_ign = {q: sp.Integer(0) for q in qI}  # L, D, Q do not depend on q_i: any value will do

    taken = {s.name for s in model.params} | {q.name for q in model.coords} | {v.name for v in model.speeds}
    integrals = []
    for q in qI:
        name = f"C_{q.name}"
        if name in taken:
            raise ModelError(f"cannot name the integral of {q.name!r} {name!r}: the model already uses that name",
                             location="routhian.reduce")
        integrals.append(sp.Symbol(name))

    # Integrals of motion dL/dq_i' = C_i (eq. 3.8), linear in the ignorable velocities.
    L = tidy(eom.L.xreplace(zero_ign))
    momenta = [tidy(sp.diff(L, v)) for v in vI]
    m = len(qI)
    A = sp.Matrix(m, m, lambda a, b: tidy(sp.diff(momenta[a], vI[b])))
    if A.free_symbols & set(vI):
        raise ModelError(f"the momenta of {_names(qI)} are not linear in {_names(vI)}: T must be "
                         "quadratic in the velocities", location="routhian.reduce")
    rhs = sp.Matrix([C - p.xreplace({v: 0 for v in vI}) for C, p in zip(integrals, momenta)])
    if is_zero(A.det()):
        raise ModelError(f"velocity elimination is singular: dL/dq_i' = C_i cannot be solved for "
                         f"{_names(vI)} (the ignorable block of M, {A.tolist()}, has zero determinant; "
                         f"is L linear in {_names(vI)}?)", location="routhian.reduce")
    if underived is not None:
        raise underived
    sol = A.LUsolve(rhs)
    velocity_solution = {v: tidy(s) for v, s in zip(vI, sol)}

    # Routhian (eq. 3.9), its C-derivatives (eq. 3.11) and Jacobi function (eq. 3.12).
    R = tidy((-L + sum(C * v for C, v in zip(integrals, vI))).xreplace(velocity_solution))
    leftover = R.free_symbols & set(vI + qI)
    if leftover:  # pragma: no cover - guarded by the checks above
        raise ModelError(f"the Routhian still depends on {_names(leftover)}", location="routhian.reduce")
    reconstruction = [tidy(sp.diff(R, C)) for C in integrals]
    h_R = tidy(R - sum(v * sp.diff(R, v) for v in vr))

    reduced = _reduced_model(eom, qr, vr, qI, integrals, R, reconstruction, velocity_solution, zero_ign)
    return RouthReduction(full=eom, ignorable=qI, coordinates=qr, velocities=vr, integrals=integrals,
                          momenta=momenta, velocity_solution=velocity_solution, R=R,
                          reconstruction=reconstruction, h_R=h_R, model=reduced)


def _reduced_model(eom: EquationsOfMotion, qr, vr, qI, integrals, R, reconstruction, velocity_solution,
                   zero_ign) -> Model:
    """The Model in q_r with L_R = -R (so Lagrange's equations of it are eq. 3.10).

    L_R is split into T_R = L_R - L_R|_{q_r'=0} (the velocity terms) and the amended
    potential V_R = -L_R|_{q_r'=0}; T_R + V_R is the Jacobi h (eq. 3.12) when L_R has no
    terms linear in q_r'. Dissipation and generalized forces on q_r carry over.
    """
    full = eom.model
    red = Model(f"{full.name}_routh")
    red.coordinates([q.name for q in qr])
    for s, v in full.params.items():
        red.parameter(s.name, v)
    for C in integrals:
        red.parameter(C.name, 0.0)
    LR = -R
    VR = tidy(-LR.xreplace({v: 0 for v in vr}))
    TR = tidy(LR + VR)
    red.kinetic_energy(TR, label="-R, velocity terms")
    if VR != 0:
        red.potential_energy(VR, label="amended potential -R(q_r' = 0)")
    D = tidy(eom.D.xreplace(zero_ign))
    if D != 0:
        red.dissipation(D, label="D")
    for i, q in enumerate(qr):
        Q = tidy(eom.Q[full.index(q)].xreplace(zero_ign).xreplace(velocity_solution))
        if Q != 0:
            red.generalized_force(q.name, Q, label=f"Q[{q.name}]")
    for q, rate in zip(qI, reconstruction):
        red.output(f"{q.name}_dot", rate)
    return red
