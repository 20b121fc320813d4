"""Minimal coordinates: holonomic constraints solved symbolically and eliminated (formulation "minimal").

:func:`solve_constraints` solves f(q, t) = 0 (eq. 4.1) for some coordinates with sympy (every
branch), :func:`closest_branch` finds the branch a state lies on and :func:`reduced_model`
substitutes a branch into the model's positions and energies; :func:`lagcodegen.compile_constrained`
(formulation "minimal") compiles the unconstrained model of the branch the initial state lies
on. Symbolic only: nothing here compiles.
"""

from __future__ import annotations

import itertools
import math
from typing import Mapping, Sequence

import sympy as sp

from ..errors import ModelError
from ..model.model import Model, Particle, PlanarBody, RigidBody
from .constraints import ConstrainedSystem


def solve_constraints(system: ConstrainedSystem, eliminate: Sequence | None = None):
    """Solve the holonomic constraints symbolically for J coordinates (sympy).

    Returns (eliminated coordinate symbols, list of solution branches {q_e: expr in the
    remaining q, t}). Tries ``eliminate`` if given, else every subset of J coordinates, the
    last coordinates first. Raises ModelError when sympy solves none.
    """
    model = system.model
    if system.nonholonomic:
        raise ModelError("minimal coordinates need holonomic constraints only: nonholonomic constraints "
                         f"({system.n_nonholonomic}) cannot be eliminated; use formulation 'index1' or 'ggl'")
    J = system.n_holonomic
    if J == 0:
        raise ModelError("minimal coordinates: there are no holonomic constraints to eliminate")
    if eliminate is not None:
        subset = tuple(model.coords[model.index(q)] for q in eliminate)
        if len(subset) != J:
            raise ModelError(f"eliminate: {len(subset)} coordinate(s) given, but there are {J} holonomic constraints")
        candidates = [subset]
    else:
        candidates = list(itertools.combinations(list(reversed(model.coords)), J))
    tried = []
    for subset in candidates:
        tried.append("(" + ", ".join(q.name for q in subset) + ")")
        try:
            sols = sp.solve(list(system.holonomic), list(subset), dict=True)
        except (NotImplementedError, ValueError, TypeError):
            continue
        good = []
        for sol in sols:
            if set(sol) != set(subset):
                continue
            if any(expr.free_symbols & set(subset) for expr in sol.values()):
                continue
            good.append({q: sp.sympify(sol[q]) for q in subset})
        if good:
            return list(subset), good
    raise ModelError("minimal coordinates: sympy cannot solve the holonomic constraints "
                     f"{', '.join(f'{f} = 0' for f in system.holonomic)} for any set of {J} coordinate(s) "
                     f"(tried {', '.join(tried)}); use formulation 'index1' or 'ggl'")


def closest_branch(system: ConstrainedSystem, eliminated: Sequence, branches: Sequence[Mapping],
                   q: Sequence[float], t: float, values: Mapping[str, float]) -> tuple[int, float]:
    """(index, distance) of the solution branch nearest the coordinates ``q`` (all n of them) at
    time ``t`` with the parameter values ``values`` (by name): the distance is the largest
    difference between an eliminated coordinate of ``q`` and its branch expression. Branches
    that are not real there are skipped; (-1, inf) when none is. The caller decides whether the
    distance is small enough (a state on the constraints lies on its branch to rounding)."""
    model = system.model
    subs = {**{s: q[i] for i, s in enumerate(model.coords)}, model.t: t,
            **{s: values[s.name] for s in model.params}}
    best, err = -1, math.inf
    for b, sol in enumerate(branches):
        try:
            e = max(abs(complex(sp.sympify(sol[qe]).xreplace(subs).evalf()) - q[model.index(qe)])
                    for qe in eliminated)
        except (TypeError, ValueError):
            continue
        if e < err:
            best, err = b, e
    return best, err


def reduced_model(system: ConstrainedSystem, solution: Mapping, name: str | None = None) -> Model:
    """A new Model in the remaining coordinates, with the solved ones substituted everywhere.
    The links of a rigid-body tree become rigid bodies (:meth:`Model.rigid_body`) at their
    world poses (:meth:`lagcodegen.model.bodies.Link.pose`): the joint coordinates no longer
    move a tree of their own once some are solved for.

    Eliminated velocities become d/dt of their solutions; a generalized force Q*_e on an
    eliminated coordinate is mapped by virtual work (Q*_r += Q*_e dq_e/dq_r). The eliminated
    coordinates and velocities are added as outputs ``<q_e>`` and ``<q_e>_dot``.
    """
    old = system.model
    new = Model(name or f"{old.name}_min")
    keep = [q for q in old.coords if q not in solution]
    new.coordinates([q.name for q in keep])
    for sym_, val in old.params.items():
        new.parameter(sym_.name, val)
    sub = dict(solution)
    for qe, expr in solution.items():
        vel = sp.diff(expr, old.t) + sum((sp.diff(expr, q) * old.dot(q) for q in keep), sp.Integer(0))
        sub[old.dot(qe)] = vel

    def S(e):
        return sp.sympify(e).xreplace(sub)

    def V(vec):
        return [S(c) for c in vec]

    body_points = set()
    for body in old.bodies:
        body_points.add(body.point.name)
        if isinstance(body, Particle):
            new.particle(body.name, S(body.mass), V(body.point.position))
        elif isinstance(body, PlanarBody):
            new.planar_body(body.name, S(body.mass), S(body.inertia), V(body.point.position), S(body.angle))
        elif isinstance(body, RigidBody):
            new.rigid_body(body.name, S(body.mass), body.inertia.applyfunc(S), V(body.point.position),
                           body.orientation.applyfunc(S))
    for link in old.links:  # a tree's links as rigid bodies in closed form (their world poses multiplied out)
        if link.mass != 0:
            body_points.add(link.name)
            new.rigid_body(link.name, S(link.mass), link.inertia.applyfunc(S), V(link.com_position()),
                           link.rotation().applyfunc(S))
    for pname, pt in old.points.items():
        if pname not in body_points:
            new.point(pname, V(pt.position))
    for label, T in old.kinetic_terms:
        new.kinetic_energy(S(T), label)
    for label, Vt in old.potential_terms:
        new.potential_energy(S(Vt), label)
    for label, U in old.generalized_potential_terms:
        new.generalized_potential(S(U), label)
    for label, D in old.dissipation_terms:
        new.dissipation(S(D), label)
    for label, pt, F in old.cartesian_forces:
        target = pt.name if pt.name in new.points else V(pt.position)
        new.force(target, V(F), label)
    for label, i, Q in old.generalized_forces:
        qi = old.coords[i]
        if qi in solution:
            for qr in keep:
                factor = sp.diff(solution[qi], qr)
                if factor != 0:
                    new.generalized_force(qr, S(Q) * factor, f"{label} (via {qi.name})")
        else:
            new.generalized_force(qi, S(Q), label)
    if old.gravity_spec is not None:
        g, up = old.gravity_spec
        new.gravity_spec = (S(g), up)
    for oname, expr in old.outputs.items():
        new.output(oname, S(expr))
    for qe, expr in solution.items():
        if qe.name not in new.outputs:
            new.output(qe.name, expr)
        if f"{qe.name}_dot" not in new.outputs:
            new.output(f"{qe.name}_dot", sub[old.dot(qe)])
    return new




def reduced_contacts(system: ConstrainedSystem, solution: Mapping, reduced: Model) -> ConstrainedSystem:
    """The contacts of ``system`` on its model reduced by ``solution`` (:func:`reduced_model`):
    a :class:`ConstrainedSystem` of ``reduced`` without equality constraints (they are
    eliminated) whose inequalities are those of ``system`` with the branch substituted, in the
    same order (so contact k and the event ``ineq_<k>`` keep their index), with their
    restitution, tangent and friction. The inequality g_k(q_r, q_e(q_r, t), t) >= 0 in the
    remaining coordinates is the same set; its gradient dg/dq_r = dg/dq (dq/dq_r) is the
    contact's row in minimal coordinates, so the impact law (sec. 4.3, eq. 4.5 over an impact)
    and a resting contact's multiplier lambda_k are those of the full system."""
    from .constraints import Inequality

    old = system.model
    sub = {old.coords[old.index(q)]: sp.sympify(e) for q, e in solution.items()}
    to_new = {old.coords[old.index(q)]: reduced.coords[reduced.index(q.name)] for q in old.coords
              if q not in sub}
    to_new.update({s: r for s in old.params for r in reduced.params if r.name == s.name})
    to_new[old.t] = reduced.t

    def S(e):
        return None if e is None else sp.sympify(e).xreplace(sub).xreplace(to_new)

    items = [Inequality(S(g), restitution=e, tangent=S(tan), friction=mu)
             for g, e, tan, mu in zip(system.inequalities, system.restitution, system.tangents, system.friction)]
    return ConstrainedSystem(reduced, inequalities=items)
