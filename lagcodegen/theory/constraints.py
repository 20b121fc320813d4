"""Constrained systems: holonomic, nonholonomic (Pfaffian) and inequality constraints (notes, sec. 4).

A :class:`ConstrainedSystem` adds constraints to a :class:`~lagcodegen.model.Model`:

* holonomic constraints f_j(q, t) = 0 (eq. 4.1), used in their differential form
  df_j = sum_i (df_j/dq_i) dq_i + (df_j/dt) dt = 0 (eq. 4.2), i.e. the row A_j = df_j/dq and
  A0_j = df_j/dt;
* nonholonomic (Pfaffian) constraints A_j . q' + A0_j = 0, the nonintegrable differential form
  of eq. 4.3 divided by dt;
* inequality constraints g_k(q, t) >= 0 (eq. 4.3, left): a plain expression is *monitored* (its
  crossing of zero is a root-finding event, see :mod:`lagcodegen.model.events`), not enforced;
  an :class:`Inequality` with a coefficient of restitution is a contact that is enforced by
  impacts (velocity jumps, Newton's law) and, in persistent contact, as the holonomic
  constraint g_k = 0 with its multiplier (:mod:`lagcodegen.simulation.constrained_impacts`).

Every equality constraint j contributes a constraint force R_j = lambda_j A_j (sec. 4.3) and
the equations of motion become (eq. 4.5)

    M q'' = F + A^T lambda,        A q'' = gamma,

where gamma = -(d/dt)(A q' + A0) with q'' excluded: gamma_j = -(sum_i d(A_j q' + A0_j)/dq_i q_i'
+ d(A_j q' + A0_j)/dt). Sign convention: lambda_j A_j is the generalized force the constraint
exerts; for a pendulum written as f = x^2 + y^2 - l^2 (A = (2x, 2y), pointing away from the
pivot) the rod tension is T = -2 l lambda = -lambda |A|.

The system is only described here; :func:`lagcodegen.compile_constrained` generates, compiles
and integrates its code.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Iterable, Mapping, Sequence

import numpy as np
import sympy as sp

from ..derivation import derive
from ..errors import ModelError
from ..model.model import Model
from ..util import check_finite, excerpt, state_vector
from .tangents import check_tangent, scalar_expression
from .integrability import IntegrabilityReport, frobenius_terms, integrability  # noqa: F401 (re-exported)

#: What to do with a "nonholonomic" constraint that the Frobenius test finds integrable.
INTEGRABLE_POLICIES = ("error", "allow")


#: Formulations of constrained dynamics lagcodegen integrates (eqs. 4.1-4.5): augmented index 1
#: on CVODE, stabilized index 2 (Gear-Gupta-Leimkuhler) on IDA, minimal coordinates.
FORMULATIONS = ("index1", "ggl", "minimal")


def _expr(value, what: str) -> sp.Expr:
    if isinstance(value, sp.Equality):
        value = value.lhs - value.rhs
    return scalar_expression(value, what)


@dataclass(frozen=True)
class Inequality:
    """An inequality constraint g(q, t) >= 0 (eq. 4.3) that is a contact with impacts.

    ``restitution`` e (0 <= e <= 1): when g reaches 0 with a closing normal velocity
    w = A q' + A0 < 0 (A = dg/dq, A0 = dg/dt), the velocities jump by the impulse of the
    constraint force lambda A (sec. 4.3, eq. 4.5 integrated over the impact):
    q'+ = q'- + M^-1 A^T P with A q'+ + A0 = -e (A q'- + A0) (Newton's law), P >= 0 the impulse
    (the notes' Lambda = -P in q'+ = q'- - M^-1 A^T Lambda). ``restitution=None`` keeps the
    meaning of a plain expression: the terminal event ``ineq_<k>`` where g reaches 0.

    ``tangent`` (optional, with a restitution): a rough contact. ``tangent(q, t)`` is a *position*
    expression whose time derivative is the slip velocity u = T q' + T0 (T = d tangent/dq,
    T0 = d tangent/dt) of the touching points, e.g. the horizontal position of the touching
    point, or x - R phi for a disc rolling on a line. Without ``friction`` the contact does not
    slip: while it touches (in an impact and in persistent contact) u is held at zero by a second
    row T with its own impulse and multiplier (unbounded friction; the contact is released by its
    normal multiplier only). Without a tangent contacts are frictionless. The tangent may instead be
    the slip velocity u itself, an expression linear in the speeds (q', or the generalized speeds v
    of quaternion joints), for contacts whose slip is no position's rate (a sphere on a free joint:
    x' - R w_y). A pair ``(t1, t2)`` is a 3-D contact: two tangential rows (meant orthonormal in
    the contact plane) and Coulomb's exact circular cone |lambda_t| <= mu lambda_n.

    ``friction`` mu (keyword, >= 0, with a tangent): Coulomb friction instead of no slip. In
    persistent contact it sticks (u = 0) while |lambda_t| <= mu lambda_n, else slips with
    lambda_t = -mu lambda_n sign(u); impacts likewise with the impulses (notes, sec. 4.3;
    :mod:`lagcodegen.simulation.constrained_impacts`). The law acts on the multipliers: the
    physical one when g and tangent are lengths (gap and position of the touching point).
    """

    expr: object
    restitution: float | None = None
    tangent: object = None
    friction: float | None = field(default=None, kw_only=True)

    def __post_init__(self):
        e = self.restitution
        mu = self.friction
        if mu is not None:
            if isinstance(mu, bool) or not isinstance(mu, (int, float, np.floating, np.integer)) \
                    or not (0.0 <= float(mu) < math.inf):
                raise ModelError(f"Inequality({excerpt(self.expr)}): friction must be a finite number >= 0 (the "
                                 f"Coulomb coefficient mu), got {excerpt(mu)}")
            if self.tangent is None:
                raise ModelError(f"Inequality({excerpt(self.expr)}): friction needs a tangent (the position "
                                 "expression whose time derivative is the slip velocity)")
            object.__setattr__(self, "friction", float(mu))
        if self.tangent is not None and e is None:
            raise ModelError(f"Inequality({excerpt(self.expr)}): a tangent (rough contact) needs a restitution")
        if e is None:
            return
        if isinstance(e, bool) or not isinstance(e, (int, float, np.floating, np.integer)):
            raise ModelError(f"Inequality({excerpt(self.expr)}): restitution must be a number in [0, 1], "
                             f"got {excerpt(e)}")
        if not (0.0 <= float(e) <= 1.0):
            raise ModelError(f"Inequality({excerpt(self.expr)}): restitution must be in [0, 1] (Newton's law "
                             f"A q'+ = -e A q'-), got {e!r}")
        object.__setattr__(self, "restitution", float(e))


@dataclass(frozen=True)
class PfaffianRow:
    """One equality constraint in Pfaffian form A . q' + A0 = 0 (eq. 4.2 / eq. 4.3).

    ``f`` is the holonomic constraint f(q, t) = 0 the row comes from (eq. 4.2), or None for a
    nonholonomic constraint.
    """

    index: int
    A: tuple
    A0: sp.Expr
    f: sp.Expr | None = None

    @property
    def holonomic(self) -> bool:
        return self.f is not None


class ConstrainedSystem:
    """A model plus constraints (notes, sec. 4).

    Parameters
    ----------
    model:
        The unconstrained :class:`~lagcodegen.model.Model` (coordinates q_1..q_n).
    holonomic:
        Expressions f_j(q, t) meaning f_j = 0 (eq. 4.1); sympy ``Eq(lhs, rhs)`` is accepted.
    nonholonomic:
        Pfaffian constraints A . q' + A0 = 0 (eq. 4.3): each item a pair ``(A, A0)`` with ``A``
        a list/Matrix of n coefficients (or a dict coordinate -> coefficient) in (q, t), or
        just ``A`` (then A0 = 0).
    inequalities:
        Expressions g_k(q, t) meaning g_k >= 0 (eq. 4.3). They are monitored through
        root-finding events (event ``ineq_<k>``, terminal, direction -1), not enforced. An
        :class:`Inequality` with a ``restitution`` is a contact instead: enforced by impacts
        and persistent contact (index-1 formulation; see
        :mod:`lagcodegen.simulation.constrained_impacts`), no event. An inequality that cannot
        act is a ModelError: one in no coordinate, or with a repeated factor in the coordinates
        (:func:`_check_inequality`).
    integrable:
        ``"error"`` (default): a nonholonomic constraint that passes the Frobenius test is
        rejected ("integrable: it is holonomic"); ``"allow"``: keep it as a Pfaffian
        constraint (the equations are still correct, the constraint is just not
        nonholonomic).
    check_integrability:
        Run the Frobenius test on every nonholonomic constraint (default). It costs
        O(n^3) symbolic terms per constraint (about 7 s for the Whipple bicycle's four rolling
        constraints in 8 coordinates); ``False`` skips it for constraints known to be
        nonholonomic: :attr:`integrability_reports` then starts empty, :meth:`is_integrable`
        runs the test on demand, and ``integrable`` is not enforced.

    Notes
    -----
    Constraint j (holonomic ones first, then the nonholonomic ones) has the multiplier
    ``lambda_<j>`` (symbols in :attr:`multipliers`).
    """

    def __init__(self, model: Model, holonomic: Iterable = (), nonholonomic: Iterable = (),
                 inequalities: Iterable = (), *, integrable: str = "error", check_integrability: bool = True):
        if not isinstance(model, Model):
            raise ModelError(f"ConstrainedSystem needs a lagcodegen Model, got {type(model).__name__}")
        if integrable not in INTEGRABLE_POLICIES:
            raise ModelError(f"integrable must be one of {', '.join(INTEGRABLE_POLICIES)}, got {integrable!r}")
        self.model = model
        n = model.n
        if n == 0:
            raise ModelError(f"model {model.name!r} has no coordinates")
        t = model.t

        self.holonomic: list[sp.Expr] = []
        for j, f in enumerate(holonomic):
            what = f"holonomic constraint {j}"
            f = _expr(f, what)
            model.check_symbols(f, what, allow_speeds=False)
            if not (f.free_symbols & set(model.coords)):
                raise ModelError(f"{what} ({excerpt(f)} = 0) involves no coordinate of model {model.name!r}")
            self.holonomic.append(f)

        self.nonholonomic: list[tuple[tuple, sp.Expr]] = []
        for j, item in enumerate(nonholonomic):
            what = f"nonholonomic constraint {j}"
            A, A0 = self._split_pfaffian(item, what)
            for i, a in enumerate(A):
                model.check_symbols(a, f"{what}, coefficient of {model.coords[i].name}'", allow_speeds=False)
            model.check_symbols(A0, f"{what}, A0", allow_speeds=False)
            if all(a == 0 for a in A):
                raise ModelError(f"{what}: every coefficient A_i is zero (A0 = {A0}): not a constraint on the "
                                 "velocities")
            self.nonholonomic.append((A, A0))

        self.inequalities: list[sp.Expr] = []
        #: per inequality: its coefficient of restitution, or None (a monitored inequality)
        self.restitution: list[float | None] = []
        #: per inequality: the tangent expression of a rough contact, or None
        self.tangents: list[sp.Expr | None] = []
        #: per inequality: its Coulomb friction coefficient mu, or None (no slip with a tangent,
        #: frictionless without)
        self.friction: list[float | None] = []
        for k, g in enumerate(inequalities):
            what = f"inequality constraint {k}"
            e = tangent = mu = None
            if isinstance(g, Inequality):
                g, e, tangent, mu = g.expr, g.restitution, g.tangent, g.friction
            self.restitution.append(e)
            self.friction.append(mu)
            if tangent is not None:
                tangent = check_tangent(model, tangent, what)
            self.tangents.append(tangent)
            g = _expr(g, what)
            model.check_symbols(g, what, allow_speeds=False)
            _check_inequality(g, what, model)
            self.inequalities.append(g)

        J = len(self.holonomic) + len(self.nonholonomic)
        if J > model.nv:
            what = "coordinates" if not model.general else "generalized speeds"
            names = model.coords if not model.general else model.v
            raise ModelError(f"{J} equality constraints ({len(self.holonomic)} holonomic, "
                             f"{len(self.nonholonomic)} nonholonomic) but only {model.nv} {what} "
                             f"({', '.join(q.name for q in names)}): at most {model.nv} are possible")
        if J == 0 and not self.inequalities:
            raise ModelError("no constraints given")

        taken = {s.name for s in model.known_symbols()}
        self.multipliers = [sp.Symbol(f"lambda_{j}") for j in range(J)]
        clash = [s.name for s in self.multipliers if s.name in taken]
        if clash:
            raise ModelError(f"the model declares {', '.join(clash)}, names reserved for Lagrange multipliers")

        if not isinstance(check_integrability, bool):
            raise ModelError(f"check_integrability must be True or False, got {check_integrability!r}")
        self.integrability_checked = check_integrability
        self.integrability_reports: dict[int, IntegrabilityReport] = {}
        for j, (A, A0) in enumerate(self.nonholonomic if check_integrability else ()):
            rep = integrability(A, A0, model.coords, t)
            self.integrability_reports[j] = rep
            if rep.integrable and integrable == "error":
                form = " + ".join(f"({a})*d{q.name}" for a, q in zip(A, model.coords) if a != 0)
                if A0 != 0:
                    form += f" + ({A0})*dt"
                how = "" if rep.proven else " (numerically, at random points)"
                raise ModelError(
                    f"nonholonomic constraint {j} ({excerpt(form, quote=False)} = 0) is integrable: it is holonomic "
                    "(the Frobenius "
                    f"condition w ^ dw = 0 holds{how}); give it as a holonomic constraint f(q, t) = 0, or pass "
                    "integrable='allow' to keep the Pfaffian form")

    # ------------------------------------------------------------------ input
    def _split_pfaffian(self, item, what: str) -> tuple[tuple, sp.Expr]:
        model = self.model
        n = model.n
        if isinstance(item, tuple) and len(item) == 2 and _is_row(item[0]):
            A, A0 = item
        else:
            A, A0 = item, 0
        if isinstance(A, Mapping):
            coeffs = [sp.Integer(0)] * n
            for key, val in A.items():
                coeffs[model.index(key)] = _expr(val, f"{what}, coefficient of {key}")
            A = coeffs
        elif isinstance(A, sp.MatrixBase):
            A = list(A)
        else:
            try:
                A = list(A)
            except TypeError:
                raise ModelError(f"{what}: A must be a row of {n} coefficients, got {A!r}") from None
        if len(A) != n:
            raise ModelError(f"{what}: A has {len(A)} coefficients, the model has {n} coordinates "
                             f"({', '.join(q.name for q in model.coords)})")
        A = tuple(_expr(a, f"{what}, coefficient {i}") for i, a in enumerate(A))
        return A, _expr(A0, f"{what}, A0")

    # ------------------------------------------------------------------ sizes
    @property
    def n(self) -> int:
        """Number of coordinates."""
        return self.model.n

    @property
    def n_holonomic(self) -> int:
        return len(self.holonomic)

    @property
    def n_nonholonomic(self) -> int:
        return len(self.nonholonomic)

    @property
    def J(self) -> int:
        """Number of equality constraints (holonomic + nonholonomic)."""
        return self.n_holonomic + self.n_nonholonomic

    @property
    def contacts(self) -> list[int]:
        """Indices k of the inequalities that are contacts (an :class:`Inequality` with a
        restitution): enforced by impacts, not events."""
        return [k for k, e in enumerate(self.restitution) if e is not None]

    @property
    def has_friction(self) -> bool:
        """Whether a contact has Coulomb friction (an :class:`Inequality` with ``friction``)."""
        return any(mu is not None for mu in self.friction)

    @property
    def dof(self) -> int:
        """Degrees of freedom n - J (sec. 4.1)."""
        return self.n - self.J

    # ------------------------------------------------------------------ forms
    def rows(self) -> list[PfaffianRow]:
        """Every equality constraint in Pfaffian form; holonomic rows from eq. 4.2."""
        model = self.model
        out = []
        for j, f in enumerate(self.holonomic):
            out.append(PfaffianRow(j, tuple(sp.diff(f, q) for q in model.coords), sp.diff(f, model.t), f))
        for k, (A, A0) in enumerate(self.nonholonomic):
            out.append(PfaffianRow(self.n_holonomic + k, A, A0, None))
        return out

    @property
    def A(self) -> sp.Matrix:
        """Constraint matrix (J x n): rows df_j/dq (eq. 4.2) then the Pfaffian rows (eq. 4.3)."""
        return sp.Matrix([list(r.A) for r in self.rows()]) if self.J else sp.zeros(0, self.n)

    @property
    def A0(self) -> sp.Matrix:
        """The dt coefficients (J): df_j/dt, then A0 of the Pfaffian rows."""
        return sp.Matrix([r.A0 for r in self.rows()]) if self.J else sp.zeros(0, 1)

    def velocity_residuals(self) -> sp.Matrix:
        """A q' + A0 (= 0 on the constraint manifold), in (q, q', t)."""
        v = sp.Matrix(self.model.speeds)
        return self.A * v + self.A0

    def acceleration_rhs(self) -> sp.Matrix:
        """gamma with A q'' = gamma: gamma = -d/dt (A q' + A0) with the q'' terms excluded."""
        model = self.model
        s = self.velocity_residuals()
        out = []
        for sj in s:
            d = sp.diff(sj, model.t) + sum((sp.diff(sj, q) * v for q, v in zip(model.coords, model.speeds)),
                                           sp.Integer(0))
            out.append(-d)
        return sp.Matrix(out)

    def equations(self, eom=None) -> tuple[sp.Matrix, sp.Matrix]:
        """Residuals of eq. 4.5 with the multipliers: (M q'' - F - A^T lambda, A q'' - gamma).

        Symbols of q'' are those of :meth:`EquationsOfMotion.accelerations`.
        """
        eom = eom or derive(self.model)
        a = eom.accelerations()
        lam = sp.Matrix(self.multipliers)
        dyn = eom.M * a - eom.F - self.A.T * lam
        return dyn, self.A * a - self.acceleration_rhs()

    def constraint_forces(self) -> list[sp.Matrix]:
        """R_j = lambda_j A_j (sec. 4.3), one generalized-force vector per constraint."""
        return [self.multipliers[r.index] * sp.Matrix(r.A) for r in self.rows()]

    def derived(self):
        """Lagrange's equations of :attr:`model` (eq. 3.16, :func:`lagcodegen.derive`), derived on
        the first call and kept (the model must not change afterwards)."""
        eom = self.__dict__.get("_derived")
        if eom is None:
            eom = self.__dict__["_derived"] = derive(self.model)
        return eom

    def is_integrable(self, j: int) -> IntegrabilityReport:
        """Frobenius test of nonholonomic constraint ``j`` (index among the nonholonomic ones)."""
        if not isinstance(j, int) or not 0 <= j < self.n_nonholonomic:
            raise ModelError(f"no nonholonomic constraint {j!r} (there are {self.n_nonholonomic})")
        if j not in self.integrability_reports:  # built with check_integrability=False: test now
            A, A0 = self.nonholonomic[j]
            self.integrability_reports[j] = integrability(A, A0, self.model.coords, self.model.t)
        return self.integrability_reports[j]

    # ------------------------------------------------------------------ numbers
    def _numeric_values(self, q0, v0, params, t0):
        model = self.model
        q = state_vector(q0, [s.name for s in model.coords], "q0")
        v = np.zeros(model.nv) if v0 is None else state_vector(v0, [s.name for s in model.v], "v0")
        pvals = {s: float(val) for s, val in model.params.items()}
        names = {s.name: s for s in model.params}
        for key, val in (params or {}).items():
            if key not in names:
                raise ModelError(f"{key!r} is not a parameter of model {model.name!r}")
            pvals[names[key]] = check_finite(val, f"parameter {key!r}")
        subs = {**dict(zip(model.coords, q)), **dict(zip(model.v, v)), **pvals,
                model.t: check_finite(t0, "t0")}
        subs = {k: sp.Float(float(val), 17) for k, val in subs.items()}
        if model.general:  # the coordinates' rates q' = k(q, v, t) at this state
            rates = [sp.sympify(k).xreplace(subs).evalf() for k in model.qdot]
            subs.update({qd: sp.Float(float(r), 17) for qd, r in zip(model.speeds, rates) if qd not in subs})
        return q, v, subs

    def evaluate(self, q0, v0=None, params: Mapping | None = None, t0: float = 0.0) -> dict:
        """Numbers at a state: A (J x n), A0, g = f(q, t) (holonomic), gdot = A q' + A0."""
        _, _, subs = self._numeric_values(q0, v0, params, t0)

        def num(e, what):
            val = sp.sympify(e).xreplace(subs).evalf()
            try:
                x = float(val)
            except TypeError:
                raise ModelError(f"{what} is not a real number at this state: {excerpt(val)}") from None
            return x

        rows = self.rows()
        A = np.array([[num(a, f"constraint {r.index}, A") for a in r.A] for r in rows]).reshape(self.J, self.n)
        A0 = np.array([num(r.A0, f"constraint {r.index}, A0") for r in rows])
        g = np.array([num(f, f"holonomic constraint {j}") for j, f in enumerate(self.holonomic)])
        v = np.array([float(subs[s]) for s in self.model.speeds], dtype=float)
        gdot = A @ v + A0 if self.J else np.zeros(0)
        if self.model.general and self.J:  # the rows in the generalized speeds: A G, G = dk/dv
            model = self.model
            G = np.array([[num(sp.diff(k, w), "kinematic equation") for w in model.v] for k in model.qdot])
            A = A @ G
        ineq = np.array([num(gk, f"inequality constraint {k}") for k, gk in enumerate(self.inequalities)])
        return {"A": A, "A0": A0, "g": g, "gdot": gdot, "inequalities": ineq}

    def check_initial(self, q0, v0=None, params: Mapping | None = None, t0: float = 0.0,
                      tol: float = 1e-8) -> dict:
        """Check an initial state against the constraints; raise ModelError naming what is wrong.

        * the constraint Jacobian A (J x n) must have full rank J at q0 (otherwise constraints
          are redundant, or inconsistent, there);
        * every holonomic constraint must hold: |f_j(q0, t0)| <= tol (eq. 4.1);
        * every velocity constraint must hold: |A_j q0' + A0_j| <= tol (eqs. 4.2, 4.3);
        * inequality constraints must hold: g_k(q0, t0) >= -tol.

        Returns the numbers of :meth:`evaluate` plus ``rank``.
        """
        vals = self.evaluate(q0, v0, params, t0)
        A = vals["A"]
        J = self.J
        rank = J
        if J:
            if not np.all(np.isfinite(A)):
                raise ModelError("the constraint Jacobian A is not finite at the initial state")
            rank = int(np.linalg.matrix_rank(A, tol=rank_tolerance(A)))
            if rank < J:
                detail = dependent_rows(A)
                raise ModelError(f"singular constraint Jacobian at the initial state: A ({J}x{A.shape[1]}) has rank "
                                 f"{rank} < {J} constraints; {detail} (redundant or inconsistent constraints, "
                                 "or a singular configuration)")
        bad = [f"holonomic constraint {j} (g_{j} = {excerpt(f)}) has residual {vals['g'][j]:.3g}"
               for j, f in enumerate(self.holonomic) if not abs(vals["g"][j]) <= tol]
        bad += [f"velocity constraint {j} (gdot_{j} = A_{j} q' + A0_{j}) has residual {vals['gdot'][j]:.3g}"
                for j in range(J) if not abs(vals["gdot"][j]) <= tol]
        bad += [f"inequality constraint {k} ({excerpt(g)} >= 0) is violated: {vals['inequalities'][k]:.3g}"
                for k, g in enumerate(self.inequalities) if not vals["inequalities"][k] >= -tol]
        if bad:
            raise ModelError("inconsistent initial conditions (tolerance %.3g): %s; project them with "
                             "initial='project' (CLI: --project-initial) or fix q0/v0" % (tol, "; ".join(bad)))
        vals["rank"] = rank
        return vals

    def __repr__(self) -> str:
        return (f"ConstrainedSystem({self.model.name!r}, {self.n_holonomic} holonomic, {self.n_nonholonomic} "
                f"nonholonomic, {len(self.inequalities)} inequalities)")


#: Operations of an inequality at most that :func:`_check_inequality` factors (factoring a large
#: expression in several variables can take long; a larger one is not searched for repeated factors).
FACTOR_OPS = 200


def _check_inequality(g: sp.Expr, what: str, model: Model) -> None:
    """Refuse an inequality g(q, t) >= 0 that cannot act as one: g involves no coordinate (``0*y``,
    ``5 - t``: the motion never changes it), or has a repeated factor in the coordinates (``y**2``,
    ``(x - 1)**2*y``: on that factor's zero set g and its gradient dg/dq vanish together, so g
    touches zero without crossing it and, as a contact, has no normal direction)."""
    shown = excerpt(str(g))
    if not (g.free_symbols & set(model.coords)):
        raise ModelError(f"{what} ({shown} >= 0) involves no coordinate of model {model.name!r}: the motion never "
                         "changes it, so it constrains nothing (a condition on time alone is an event)")
    if sp.count_ops(g) > FACTOR_OPS:
        return
    try:
        _, factors = sp.factor_list(g)
    except (sp.PolynomialError, NotImplementedError, ValueError, TypeError, RecursionError):
        return
    coords = set(model.coords)
    for factor, power in factors:
        if power >= 2 and factor.free_symbols & coords:
            raise ModelError(f"{what} ({shown} >= 0) has the factor {excerpt(str(factor))} to the power {power}: "
                             "where that factor is zero, g and its gradient dg/dq vanish together (an even power "
                             "never crosses zero; a contact there has no normal direction); write the factor once, "
                             f"e.g. {excerpt(str(factor))} >= 0 or its negative")


def _is_row(x) -> bool:
    return isinstance(x, (list, tuple, sp.MatrixBase, Mapping, np.ndarray))


def rank_tolerance(A: np.ndarray) -> float:
    if A.size == 0:
        return 0.0
    s = np.linalg.svd(A, compute_uv=False)
    return max(A.shape) * np.finfo(float).eps * 1e3 * (s[0] if s.size else 0.0)


def dependent_rows(A: np.ndarray) -> str:
    """Name the rows of A that add nothing to the rank of the rows before them."""
    tol = rank_tolerance(A)
    parts = []
    kept: list[int] = []
    for j in range(A.shape[0]):
        if not np.any(np.abs(A[j]) > tol):
            parts.append(f"constraint {j} has a zero gradient A_{j} there")
            continue
        trial = kept + [j]
        if np.linalg.matrix_rank(A[trial], tol=tol) < len(trial):
            others = ", ".join(str(k) for k in kept)
            parts.append(f"constraint {j} is linearly dependent on constraint(s) {others}")
        else:
            kept.append(j)
    return "; ".join(parts) or "rank deficient"


def ground_contact(model: Model, link, point: Sequence = (0, 0, 0), *, restitution: float, ground: float = 0.0,
                   tangent: str | None = None, friction: float | None = None, name: str | None = None) -> Inequality:
    """A ground contact of the point ``point`` of ``link`` (a link of ``model`` or its name; the
    point in the link frame): the inequality g = z - ground >= 0 on the point's world height (the
    plane z = ``ground``, normal +z), an :class:`Inequality` with the coefficient of
    ``restitution``, for :class:`ConstrainedSystem`'s ``inequalities``; the point is declared on
    the model as ``name`` (default ``<link>_contact_<k>``). Without ``tangent`` the contact is
    frictionless; ``tangent="x"`` or ``"y"``: a rough contact along that world axis only (no slip,
    or Coulomb ``friction`` mu, planar); ``tangent="xy"``: both world axes, 3-D friction with the
    exact circular cone |lambda_t| <= mu lambda_n (the point's world x and y as the two tangents).
    Works on floating-base models (quaternion free joints: ``urdf.load(path, floating=True)``)."""
    if not isinstance(model, Model):
        raise ModelError(f"ground_contact needs a lagcodegen Model, got {type(model).__name__}")
    link = getattr(link, "name", link)
    if not isinstance(link, str):
        raise ModelError(f"ground_contact: link must be a link or its name, got {link!r}")
    if tangent not in (None, "x", "y", "xy"):
        raise ModelError(f"ground_contact: tangent must be None, 'x', 'y' (one world axis: planar friction) or 'xy' "
                         f"(3-D friction), got {tangent!r}")
    if friction is not None and tangent is None:
        raise ModelError("ground_contact: friction needs a tangent direction ('x', 'y' or 'xy')")
    if name is None:
        k = sum(1 for nme in model.points if nme.startswith(f"{link}_contact_"))
        name = f"{link}_contact_{k}"
    pt = model.point_on(link, point, name)
    if pt.dim != 3:
        raise ModelError(f"ground_contact: the point of link {link!r} is not 3-D")
    g = pt.position[2] - _expr(ground, "ground_contact: ground height")
    tan = None if tangent is None else tuple(pt.position["xy".index(a)] for a in tangent)
    tan = tan[0] if tan is not None and len(tan) == 1 else tan
    return Inequality(g, restitution=restitution, tangent=tan, friction=friction)
