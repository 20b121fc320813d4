"""Steady motions (section 3.5 of the notes): the non-ignorable coordinates at rest, the ignorable ones turning uniformly.

With q_r' = q_r'' = 0 the reduced equations (3.10) become

    dR/dq_r = 0                                                  (eq. 3.13)

for given values of the integrals C_i and the parameters, and the ignorable coordinates move
at the constant rates v_i = dR/dC_i (eq. 3.11). More generally (dissipation, forces, an
explicit time dependence) the condition is F_R(q_r, 0, t) = 0 for the reduced system's
M q'' = F, which is -dR/dq_r for a conservative one. Without ignorable coordinates the
steady motions are the equilibria of the full system (R = -L).

Roots are found by sympy (lexicographic Groebner basis, then numeric back-substitution) when
the equations are polynomial in the coordinates, or in sin q and cos q of angle-like
coordinates (q -> (sin q, cos q) with sin^2 + cos^2 = 1), for at most two coordinates; and
always numerically (``scipy.optimize.root``) from a grid of starting points. Every real root,
polished by Newton's method and de-duplicated, is reported with its linear stability
(:mod:`lagcodegen.theory.linearize`). A root must have a small residual and a small Newton
correction (so that F -> 0 at infinity, as for the Kepler problem, is no root), and a
regular mass matrix.

A :class:`~lagcodegen.theory.constraints.ConstrainedSystem` with holonomic constraints is
searched for its equilibria on the constraints (:func:`constrained_equilibria`: F + A^T lambda = 0
with f = 0, eqs. 4.1 and 4.5, then :func:`~lagcodegen.theory.linearize.linearize` on the
constraints); one with nonholonomic constraints is refused (its equilibria come in families;
:func:`~lagcodegen.theory.linearize.linearize` checks and linearizes a given steady motion).
"""

from __future__ import annotations

import itertools
import math
import warnings
from dataclasses import dataclass
from typing import Mapping

import numpy as np
import symengine as se
import sympy as sp

from ..derivation import EquationsOfMotion, derive, require_lagrange
from ..errors import ModelError
from ..model.model import Model
from ..util import check_finite
from .constraints import ConstrainedSystem
from .linearize import Linearization, exact_number, linearize
from .routhian import RouthReduction, ignorable_coordinates, reduce

__all__ = ["SteadyMotion", "constrained_equilibria", "steady_motions"]

#: Most coordinates for which sympy is tried (numeric roots are always searched).
SYMBOLIC_MAX_COORDINATES = 2
#: Largest total degree of a polynomial of the system handed to sympy's groebner.
SYMBOLIC_MAX_DEGREE = 12
#: Most starting points of the numeric search.
MAX_STARTS = 400


@dataclass
class SteadyMotion:
    """One steady motion (eq. 3.13) and its linear stability.

    ``coordinates``: the constant non-ignorable coordinates (angles wrapped into (-pi, pi]);
    ``velocities``: the constant ignorable velocities v_i = dR/dC_i (eq. 3.11);
    ``integrals``: the C_i it was found for; ``linearization``: the reduced equations
    linearized about it; ``eigenvalues``, ``frequencies`` (small-oscillation angular
    frequencies) and ``stable`` (linear sense) come from it. ``residual``: max |F_R| there.
    """

    coordinates: dict[str, float]
    velocities: dict[str, float]
    integrals: dict[str, float]
    parameters: dict[str, float]
    linearization: Linearization
    residual: float

    @property
    def eigenvalues(self) -> np.ndarray:
        return self.linearization.eigenvalues

    @property
    def frequencies(self) -> np.ndarray:
        return self.linearization.frequencies

    @property
    def stable(self) -> bool:
        return self.linearization.stable()

    def __repr__(self) -> str:
        q = ", ".join(f"{k}={v:.10g}" for k, v in self.coordinates.items())
        v = ", ".join(f"{k}'={x:.10g}" for k, x in self.velocities.items())
        w = ", ".join(f"{x:.6g}" for x in self.frequencies)
        return (f"SteadyMotion({q}{'; ' + v if v else ''}; {'stable' if self.stable else 'unstable'}"
                f"{'; omega=' + w if w else ''})")


# ---------------------------------------------------------------------- setup
def _resolve(system) -> tuple[EquationsOfMotion, RouthReduction | None]:
    """The equations to solve, and the reduction they come from (a full system with
    ignorable coordinates is reduced over all of them)."""
    if isinstance(system, RouthReduction):
        return system.eom, system
    eom = derive(system) if isinstance(system, Model) else system
    if getattr(eom, "general", False):
        model = eom.model
        raise ModelError(f"steady_motions: model {model.name!r} has generalized speeds (nq = {model.nq}, nv = "
                         f"{model.nv}; quaternion joints or Model.generalized_speeds), whose steady motions are not "
                         "searched: a quaternion's equilibria and spins come in families (every rotation about the "
                         "vertical, every rate of a spin). Give one to linearize(eom, q0=..., v0=...), which "
                         "checks that it is steady in these speeds and linearizes it in tangent coordinates, or "
                         "search on Euler angles (rotation='ZYX'), where Routh's reduction applies")
    require_lagrange(eom, "steady_motions")
    if not isinstance(eom, EquationsOfMotion):
        raise ModelError("steady_motions needs a RouthReduction, EquationsOfMotion or Model, "
                         f"got {type(system).__name__}")
    if ignorable_coordinates(eom):
        red = reduce(eom)
        return red.eom, red
    return eom, None


def _values(eom: EquationsOfMotion, red: RouthReduction | None, integrals, params) -> tuple[dict, dict]:
    values = {s.name: float(v) for s, v in eom.model.params.items()}
    names_C = [C.name for C in red.integrals] if red else []
    for k, v in (params or {}).items():
        if k not in values or k in names_C:
            raise ModelError(f"{k!r} is not a parameter of model {eom.model.name!r}"
                             + (" (give integrals in `integrals`)" if k in names_C else ""))
        values[k] = check_finite(v, f"parameter {k!r}")
    C = {k: 0.0 for k in names_C}
    if integrals:
        if red is None:
            raise ModelError("integrals given, but the system has no ignorable coordinate")
        for k, v in integrals.items():
            key = k if k in C else f"C_{k}"
            if key not in C:
                raise ModelError(f"{k!r} is not an integral of the reduction (integrals: {', '.join(C)})")
            C[key] = check_finite(v, f"integral {k!r}")
    values.update(C)
    return values, C


def _is_periodic(fun, n: int, k: int, rng: np.random.Generator) -> bool:
    """Whether the steady-motion residual is 2 pi-periodic in coordinate k (angle-like)."""
    shift = np.zeros(n)
    shift[k] = 2 * math.pi
    agree = 0
    for _ in range(6):
        x = rng.uniform(-2.0, 2.0, n)
        a, b = fun(x), fun(x + shift)
        if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
            continue
        if np.max(np.abs(a - b)) > 1e-9 * max(1.0, float(np.max(np.abs(a)))):
            return False
        agree += 1
    return agree >= 3


# ---------------------------------------------------------------------- symbolic roots
def _symbolic_roots(G: list[sp.Expr], qs: list[sp.Symbol], periodic: list[bool]) -> list[np.ndarray]:
    """Real roots from sympy for small polynomial (or polynomial-in-sin/cos) systems, else []."""
    if len(qs) > SYMBOLIC_MAX_COORDINATES:
        return []
    sub, unknowns, extra, back = {}, [], [], []
    for q, per in zip(qs, periodic):
        if per:
            s, c = sp.Dummy(f"s_{q.name}"), sp.Dummy(f"c_{q.name}")
            sub.update({sp.sin(q): s, sp.cos(q): c, sp.tan(q): s / c})
            unknowns += [s, c]
            extra.append(s**2 + c**2 - 1)
            back.append(("angle", s, c))
        else:
            unknowns.append(q)
            back.append(("plain", q, None))
    eqs, dens = [], []
    for g in G:
        g = sp.nsimplify(sp.expand_trig(g), rational=True)
        g = g.xreplace(sub) if sub else g
        if g.free_symbols & {q for q, per in zip(qs, periodic) if per}:
            return []  # an angle left outside sin/cos
        num, den = sp.fraction(sp.together(g))
        try:
            poly = sp.Poly(num, *unknowns)
        except sp.PolynomialError:
            return []
        if poly.total_degree() > SYMBOLIC_MAX_DEGREE:
            return []
        if not poly.is_zero:
            eqs.append(num)
        dens.append(den)
    if not eqs:
        return []
    sols = _solve_polynomial_system(eqs + extra, unknowns)
    out = []
    for sol in sols:
        if set(sol) != set(unknowns):
            continue  # a family of solutions: leave it to the numeric search
        vals = sol
        try:
            if any(abs(complex(sp.N(d.xreplace({u: sp.Float(x, 30) for u, x in vals.items()}), 20))) < 1e-14
                   for d in dens):
                continue
        except (ValueError, TypeError):
            continue
        x = [math.atan2(vals[a], vals[b]) if kind == "angle" else vals[a] for kind, a, b in back]
        out.append(np.array(x, dtype=float))
    return out


def _numeric_poly(p: sp.Expr, var: sp.Symbol, known: dict) -> np.ndarray:
    """Coefficients (highest first) of p as a polynomial in ``var`` once ``known`` values are in.

    Coefficients that cancel to rounding level (relative to the sum of their terms' sizes)
    are zero, so that the degree seen is the true one at that point.
    """
    sub = {u: sp.Float(x, 30) for u, x in known.items()}
    out = []
    for c in sp.Poly(p, var).all_coeffs():
        terms = sp.Add.make_args(sp.expand(c))
        vals = [complex(t.xreplace(sub).evalf(30)) for t in terms]
        total = sum(vals)
        size = sum(abs(v) for v in vals)
        out.append(0.0 if abs(total) <= 1e-12 * size else total.real)
    coeffs = np.array(out, dtype=float)
    nz = np.flatnonzero(coeffs)
    return coeffs[nz[0]:] if nz.size else np.zeros(1)


def _solve_polynomial_system(eqs: list[sp.Expr], unknowns: list[sp.Symbol]) -> list[dict]:
    """Real solutions (approximate floats) of a zero-dimensional polynomial system.

    A lexicographic Groebner basis (exact, rational coefficients) makes the system
    triangular; its real roots then follow variable by variable (``numpy.roots``, polished later).
    Returns [] when the system has infinitely many solutions or sympy gives up.
    """
    try:
        basis = sp.groebner(eqs, *unknowns, order="lex")
        if list(basis.exprs) == [1]:
            return []
        if not basis.is_zero_dimensional:
            return []
    except (NotImplementedError, sp.PolynomialError, ValueError, TypeError, ZeroDivisionError):
        return []
    polys = list(basis.exprs)
    partial: list[dict] = [{}]
    for var in reversed(unknowns):
        grown = []
        for sol in partial:
            known = set(sol) | {var}
            rel = [_numeric_poly(p, var, sol) for p in polys if var in p.free_symbols and p.free_symbols <= known]
            rel = [c for c in rel if len(c) > 1]
            if not rel:
                continue
            lead = min(rel, key=len)
            try:
                roots = np.roots(lead)
            except np.linalg.LinAlgError:
                return []
            for z in roots:
                if abs(z.imag) > 1e-7 * max(1.0, abs(z.real)):
                    continue
                x = float(z.real)
                ok = True
                for cf in rel:
                    size = float(np.sum(np.abs(cf) * np.abs(x) ** np.arange(len(cf) - 1, -1, -1)))
                    if abs(np.polyval(cf, x)) > 1e-6 * max(size, 1e-300):
                        ok = False
                        break
                if ok:
                    grown.append({**sol, var: x})
        partial = grown
    return partial


# ---------------------------------------------------------------------- numeric roots
def _starts(n: int, periodic: list[bool], bounds: list[tuple[float, float] | None], per_axis: int,
            rng: np.random.Generator) -> np.ndarray:
    axes = []
    for per, b in zip(periodic, bounds):
        if b is not None:
            axes.append(np.linspace(b[0], b[1], per_axis))
        elif per:
            axes.append(np.linspace(-math.pi, math.pi, per_axis, endpoint=False) + 0.5 * math.pi / per_axis)
        else:
            mags = np.logspace(-2, 2, max(2, per_axis // 2))
            axes.append(np.concatenate([-mags[::-1], [0.0], mags]))
    total = math.prod(len(a) for a in axes)
    if total <= MAX_STARTS:
        return np.array(list(itertools.product(*axes)), dtype=float).reshape(-1, n)
    return np.column_stack([rng.choice(a, MAX_STARTS) for a in axes])


def _polish(fun, jac, x0: np.ndarray) -> np.ndarray | None:
    """Newton-type refinement (MINPACK hybrd via scipy) of a starting point; None if it fails."""
    import scipy.optimize  # scipy: needed for steady motions only
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore")
        try:
            sol = scipy.optimize.root(fun, x0, jac=jac, method="hybr", options={"xtol": 1e-14})
        except (ValueError, ArithmeticError, np.linalg.LinAlgError):
            return None
    x = np.asarray(sol.x, dtype=float)
    return x if np.all(np.isfinite(x)) else None


def _is_root(fun, jac, x: np.ndarray, atol: float) -> bool:
    """A small residual, and a Newton correction small against x (rejects G -> 0 at infinity)."""
    r = fun(x)
    if not np.all(np.isfinite(r)) or np.max(np.abs(r)) > atol:
        return False
    J = jac(x)
    if not np.all(np.isfinite(J)):
        return False
    step = np.linalg.lstsq(J, r, rcond=None)[0]
    return bool(np.max(np.abs(step), initial=0.0) <= 1e-6 * max(1.0, float(np.max(np.abs(x)))))


def _wrap(x: np.ndarray, periodic: list[bool]) -> np.ndarray:
    x = x.copy()
    for k, per in enumerate(periodic):
        if per:
            w = math.remainder(x[k], 2 * math.pi)  # in [-pi, pi]
            x[k] = math.pi if w <= -math.pi + 1e-12 else w
    return x


def _evaluate(expr: sp.Expr, values: Mapping[str, float], at: Mapping[sp.Symbol, float], tsym: sp.Symbol,
              t: float, what: str = "expression") -> float:
    """expr with parameters (integral values exact) substituted first, then the coordinates (``at``:
    the non-ignorable coordinates and, at 0, their velocities). A symbol left over (an input, a
    symbol of no parameter) is a ModelError naming it, not sympy's "Cannot convert expression to
    float"."""
    def number(v: float):
        return sp.Integer(int(v)) if float(v).is_integer() and abs(v) < 2**53 else sp.Float(v, 20)
    e = expr.xreplace({sp.Symbol(k): number(v) for k, v in values.items()}).xreplace({tsym: number(t)})
    e = e.xreplace({q: (sp.Float(x, 20) if x else sp.Integer(0)) for q, x in at.items()})
    if e.free_symbols:
        raise ModelError(f"{what} depends on {', '.join(sorted(s.name for s in e.free_symbols))}, "
                         "which has no value at a steady motion (not a coordinate, velocity or parameter)",
                         location="steady_motions")
    z = complex(e.evalf(20))
    return z.real if math.isfinite(z.real) and abs(z.imag) <= 1e-12 * max(1.0, abs(z.real)) else math.nan


# ---------------------------------------------------------------------- main
def _numeric_functions(variables: list, G: list, J: list):
    """(fun, jac): the residuals G and their Jacobian J (row-major, len(G) x len(variables)) as
    numpy functions of the variables (floating-point warnings silenced: a failed point is NaN)."""
    f_G = se.Lambdify(variables, G, real=True)
    f_J = se.Lambdify(variables, J, real=True)
    shape = (len(G), len(variables))

    def fun(x):
        with np.errstate(all="ignore"):
            return np.asarray(f_G(np.asarray(x, dtype=float)), dtype=float).ravel()

    def jac(x):
        with np.errstate(all="ignore"):
            return np.asarray(f_J(np.asarray(x, dtype=float)), dtype=float).reshape(shape)
    return fun, jac


def _keep_new(x: np.ndarray, found: list, bnds: list, periodic: list) -> None:
    """Append the root ``x`` to ``found`` unless it lies outside the bounds or is one found
    already (to 1e-7 relative, angles modulo 2 pi)."""
    if any(b is not None and not (b[0] - 1e-9 <= xi <= b[1] + 1e-9) for xi, b in zip(x, bnds)):
        return
    if any(np.max(np.abs(_wrap(x - y, periodic))) <= 1e-7 * max(1.0, float(np.max(np.abs(y)))) for y in found):
        return
    found.append(x)


def _bounds(bounds, names: list[str]) -> dict:
    """The user's search bounds by coordinate name, each name checked."""
    user_bounds = dict(bounds or {})
    for k in user_bounds:
        if k not in names:
            raise ModelError(f"bounds given for {k!r}, which is not a coordinate ({', '.join(names)})")
    return user_bounds


def _at_rest(eom: EquationsOfMotion, values: Mapping[str, float], t: float) -> dict:
    """symengine substitution: the parameters' values, every velocity 0, the time ``t``."""
    sub = {se.Symbol(k): exact_number(v) for k, v in values.items()}
    sub.update({se.Symbol(v.name): se.Integer(0) for v in eom.qd})
    sub[se.Symbol(eom.t.name)] = exact_number(float(t))
    return sub


def steady_motions(system, integrals: Mapping[str, float] | None = None, params: Mapping[str, float] | None = None,
                   *, t: float = 0.0, bounds: Mapping[str, tuple[float, float]] | None = None,
                   starts: int = 24, tol: float = 1e-9, symbolic: bool = True) -> list[SteadyMotion]:
    """Every real steady motion (eq. 3.13) of ``system``, with its linear stability.

    Parameters
    ----------
    system:
        A :class:`~lagcodegen.theory.routhian.RouthReduction`, or equations (or a Model) of a full
        system: with ignorable coordinates it is reduced first, without any its steady
        motions are its equilibria. Or a
        :class:`~lagcodegen.theory.constraints.ConstrainedSystem` with holonomic constraints
        only: its equilibria on the constraints (see :func:`constrained_equilibria`).
    integrals:
        Values of the integrals, by name ``C_<q>`` or by the ignorable coordinate's name
        (default 0: equilibria).
    params:
        Parameter values by name (default: the model's).
    t:
        Time at which the equations are evaluated (only matters for rheonomic systems).
    bounds:
        Search ranges ``name -> (lo, hi)``; roots outside are dropped. Default: (-pi, pi]
        for angle-like coordinates (residual 2 pi-periodic), +-[0.01, 100] and 0 otherwise.
    starts:
        Starting points per coordinate of the numeric search (the grid is capped at
        MAX_STARTS points).
    tol:
        Residual tolerance, relative to the size of the residual over the starting grid.
    symbolic:
        Also solve with sympy (a Groebner basis; small polynomial systems only).

    Raises :class:`~lagcodegen.errors.ModelError` ("no real steady motion") when none is found.
    """
    if isinstance(system, ConstrainedSystem):
        if integrals:
            raise ModelError("integrals are for Routh's reduction (eq. 3.9); a ConstrainedSystem is "
                             "searched for its equilibria only", location="steady_motions")
        return constrained_equilibria(system, params=params, t=t, bounds=bounds, starts=starts, tol=tol)
    eom, red = _resolve(system)
    values, C = _values(eom, red, integrals, params)
    qs = list(eom.q)
    names = [q.name for q in qs]
    n = len(qs)
    user_bounds = _bounds(bounds, names)

    # Residual F_R(q, 0, t) with the numbers substituted (symengine), and its Jacobian.
    sub = _at_rest(eom, values, t)
    qse = [se.Symbol(q) for q in names]
    G = [se.sympify(f).xreplace(sub) for f in eom.F_se]
    stray = set().union(*(g.free_symbols for g in G)) - set(qse)
    if stray:
        raise ModelError(f"F depends on {', '.join(sorted(str(s) for s in stray))}, which has no value "
                         "(not a coordinate or parameter; an input?): give it as a parameter", location="steady_motions")
    J = [[se.diff(g, q) for q in qse] for g in G]
    fun, jac = _numeric_functions(qse, G, [e for row in J for e in row])

    rng = np.random.default_rng(1234)
    periodic = [_is_periodic(fun, n, k, rng) for k in range(n)]
    bnds = [tuple(map(float, user_bounds[k])) if k in user_bounds else None for k in names]
    grid = _starts(n, periodic, bnds, starts, rng)
    with np.errstate(all="ignore"):
        sizes = np.array([np.max(np.abs(fun(x))) for x in grid])
    finite = sizes[np.isfinite(sizes)]
    scale = max(1.0, float(np.median(finite))) if finite.size else 1.0

    candidates = []
    if symbolic:
        candidates += _symbolic_roots([sp.sympify(g) for g in G], qs, periodic)
    candidates += list(grid)

    found: list[np.ndarray] = []
    for x0 in candidates:
        x = _polish(fun, jac, np.asarray(x0, dtype=float))
        if x is None:
            continue
        if not _is_root(fun, jac, x, tol * scale):
            continue
        _keep_new(_wrap(x, periodic), found, bnds, periodic)
    found.sort(key=lambda x: tuple(np.round(x, 9)))

    motions = []
    other = [k for k in values if k not in C]
    for x in found:
        try:
            lin = linearize(eom, q0=x, v0=np.zeros(n), t=t, params=values)
        except ModelError:  # singular mass matrix or a pole there: not a regular steady motion
            continue
        # q_i' = dR/dC_i (eq. 3.11) may hold the non-ignorable velocities (cross terms of T): 0 here
        at = {**dict(zip(red.coordinates, x)), **{v: 0.0 for v in eom.qd}} if red is not None else {}
        vel = {q.name: _evaluate(rate, values, at, eom.t, t, f"the rate of {q.name} (eq. 3.11)")
               for q, rate in zip(red.ignorable, red.reconstruction)} if red is not None else {}
        motions.append(SteadyMotion(coordinates=dict(zip(names, map(float, x))), velocities=vel,
                                    integrals=dict(C), parameters={k: values[k] for k in other},
                                    linearization=lin, residual=float(np.max(np.abs(fun(x))))))
    if not motions:
        where = f" for {', '.join(f'{k} = {v:g}' for k, v in C.items())}" if C else ""
        raise ModelError(f"no real steady motion{where}: F(q, q' = 0) = 0 has no real root with a regular "
                         f"mass matrix (searched from {len(candidates)} starting points)", location="steady_motions")
    return motions


# ---------------------------------------------------------------------- constrained systems
def constrained_equilibria(system: ConstrainedSystem, *, params: Mapping[str, float] | None = None, t: float = 0.0,
                           bounds: Mapping[str, tuple[float, float]] | None = None, starts: int = 24,
                           tol: float = 1e-9) -> list[SteadyMotion]:
    """Every equilibrium of a system with holonomic constraints, with its linear stability.

    At rest (q' = q'' = 0) eq. 4.5 is F(q, 0, t) + A(q)^T lambda = 0 with f(q, t) = 0 (eq. 4.1):
    n + J equations in (q, lambda), solved numerically (``scipy.optimize.root``) from a grid
    of coordinates, the multipliers starting from the least-squares fit of A^T lambda = -F
    there. Each root is linearized on the constraints (:func:`~lagcodegen.theory.linearize.linearize`
    of the ConstrainedSystem: independent coordinates by pivoting) for its stability; its
    ``coordinates`` are all n coordinates, its ``velocities`` and ``integrals`` empty.

    Scope: equilibria only (Routh's reduction, eq. 3.9, of a constrained system is not
    done), and holonomic constraints only: with nonholonomic constraints the equilibria come in
    families (F in the span of more rows of A than there are equations to fix q), and a steady
    motion has to be given: :func:`~lagcodegen.theory.linearize.linearize` checks and linearizes one.
    Arguments as for :func:`steady_motions`.
    """
    if not isinstance(system, ConstrainedSystem):
        raise ModelError(f"constrained_equilibria needs a ConstrainedSystem, got {type(system).__name__}")
    if system.n_nonholonomic:
        raise ModelError(
            f"the steady motions of a system with nonholonomic constraints ({system.n_nonholonomic}) are not searched: "
            "its equilibria come in families (F(q, 0) + A^T lambda = 0 has fewer equations than unknowns) and its "
            "steady motions are not those of a Routhian; give the motion to linearize(system, q0=..., v0=...), "
            "which checks that it is steady and linearizes it", location="steady_motions")
    if system.J == 0:  # inequalities only
        return steady_motions(system.derived(), params=params, t=t, bounds=bounds, starts=starts, tol=tol)
    eom = system.derived()
    values, _ = _values(eom, None, None, params)
    names = [q.name for q in eom.q]
    n, JH = system.n, system.n_holonomic
    user_bounds = _bounds(bounds, names)
    from ..derivation import to_se  # a lower stage: the constraints as symengine expressions
    sub = _at_rest(eom, values, t)
    qse = [se.Symbol(k) for k in names]
    lam = [se.Symbol(f"__lambda{j}") for j in range(JH)]
    F = [se.sympify(f).xreplace(sub) for f in eom.F_se]
    A = [[to_se(a, f"holonomic constraint {r.index}").xreplace(sub) for a in r.A] for r in system.rows()]
    f = [to_se(e, f"holonomic constraint {j}").xreplace(sub) for j, e in enumerate(system.holonomic)]
    G = [F[i] + se.Add(*(A[j][i] * lam[j] for j in range(JH))) for i in range(n)] + f
    stray = set().union(*(g.free_symbols for g in G)) - set(qse) - set(lam)
    if stray:
        raise ModelError(f"the equations depend on {', '.join(sorted(str(s) for s in stray))}, which "
                         "has no value (not a coordinate or parameter; an input?)", location="steady_motions")
    x = qse + lam
    fun, jac = _numeric_functions(x, G, [se.diff(g, y) for g in G for y in x])
    f_FA = se.Lambdify(qse, F + [a for row in A for a in row], real=True)

    def with_multipliers(q):
        with np.errstate(all="ignore"):
            vals = np.asarray(f_FA(np.asarray(q, dtype=float)), dtype=float).ravel()
        Fq, Aq = vals[:n], vals[n:].reshape(JH, n)
        if not (np.all(np.isfinite(Fq)) and np.all(np.isfinite(Aq))):
            return None
        return np.concatenate([q, np.linalg.lstsq(Aq.T, -Fq, rcond=None)[0]])

    rng = np.random.default_rng(1234)
    periodic = [_is_periodic(lambda q: fun(np.concatenate([q, np.zeros(JH)])), n, k, rng) for k in range(n)]
    bnds = [tuple(map(float, user_bounds[k])) if k in user_bounds else None for k in names]
    grid = [y for y in (with_multipliers(q) for q in _starts(n, periodic, bnds, starts, rng)) if y is not None]
    with np.errstate(all="ignore"):
        sizes = np.array([np.max(np.abs(fun(y))) for y in grid]) if grid else np.zeros(0)
    finite = sizes[np.isfinite(sizes)]
    scale = max(1.0, float(np.median(finite))) if finite.size else 1.0
    found: list[np.ndarray] = []
    for y0 in grid:
        y = _polish(fun, jac, y0)
        if y is None or not _is_root(fun, jac, y, tol * scale):
            continue
        _keep_new(_wrap(y[:n], periodic), found, bnds, periodic)
    found.sort(key=lambda q: tuple(np.round(q, 9)))
    motions = []
    for q in found:
        try:
            lin = linearize(system, q0=q, v0=np.zeros(n), t=t, params=values, tol=max(tol, 1e-8))
        except ModelError:  # a singular constraint Jacobian or mass matrix there: not a regular equilibrium
            continue
        motions.append(SteadyMotion(coordinates=dict(zip(names, map(float, q))), velocities={}, integrals={},
                                    parameters=dict(values), linearization=lin,
                                    residual=float(np.max(np.abs(fun(np.concatenate([q, lin.multipliers])))))))
    if not motions:
        raise ModelError(f"no real equilibrium on the constraints: F(q, 0) + A^T lambda = 0, f(q) = 0 has no regular "
                         f"real root (searched from {len(grid)} starting points)", location="steady_motions")
    return motions
