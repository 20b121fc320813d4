"""``lagcodegen info``: the derived equations of a model file, printed as text or LaTeX.

One job: printing what the derivation (:meth:`lagcodegen.modelfile.ModelFile.derive`) and the
constraints (:class:`lagcodegen.theory.constraints.ConstrainedSystem`) give; nothing compiles.
"""

from __future__ import annotations

import argparse

import sympy as sp

from .common import EXIT_OK, MODEL_HELP, load

HELP = "print a model file's energies, momenta and equations of motion"

DESCRIPTION = """Print what lagcodegen derives from the model: its coordinates and parameters, the
kinetic energy T (eq. 2.2 of the notes), the potential energy V (eq. 2.7), the Rayleigh
dissipation function D (eq. 3.15) if any, the generalized momenta p = dL/dq' (eq. 2.3), and
Lagrange's equations as the mass matrix M and force vector F of M q'' = F (eq. 3.16).
Model files with [constraints] also show each constraint (eqs. 4.1, 4.3), their differential
form A dq + A0 dt = 0 (eq. 4.2), Lagrange's equations with multipliers (eq. 4.5) and the
constraints at acceleration level; then the events.

    lagcodegen info examples/double_pendulum.toml --latex"""


def add_parser(sub) -> None:
    i = sub.add_parser("info", help=HELP, description=DESCRIPTION,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    i.add_argument("model", help=MODEL_HELP)
    i.add_argument("--latex", action="store_true", help="LaTeX instead of pretty text")
    i.add_argument("--simplify", action=argparse.BooleanOptionalAction, default=None,
                   help="simplify before printing (default: only for up to 3 coordinates)")
    i.set_defaults(func=run)


def run(args) -> int:
    mf = load(args.model, True, getattr(args, "urdf", None)).model_file
    eom = mf.derive()
    model = mf.model
    show = sp.latex if args.latex else (lambda e: sp.pretty(e, use_unicode=False))
    print(f"model {model.name}: {model.n} coordinates")
    print("coordinates: " + ", ".join(q.name for q in model.coords))
    print("parameters:  " + ", ".join(f"{k.name} = {v:g}" for k, v in model.params.items()))
    sections = [("kinetic energy T (eq. 2.2)", eom.T), ("potential energy V (eq. 2.7)", eom.V)]
    if eom.D != 0:
        sections.append(("Rayleigh dissipation D (eq. 3.15)", eom.D))
    sections += [("generalized momenta p = dL/dq' (eq. 2.3)", eom.momenta),
                 ("mass matrix M (eq. 3.16: M q'' = F)", eom.M),
                 ("force vector F", eom.F)]
    simplify = args.simplify if args.simplify is not None else model.n <= 3
    for title, expr in sections:
        print(f"\n{title}:")
        print(show(sp.simplify(expr) if simplify else expr))
    if mf.constrained is not None:
        _info_constrained(mf, eom, show, simplify)
    _info_events(mf, show)
    return EXIT_OK


def _info_constrained(mf, eom, show, simplify: bool) -> None:
    """The constraints, their differential form (eq. 4.2) and the equations with multipliers (eq. 4.5)."""
    system = mf.constrained
    model = system.model
    simp = sp.simplify if simplify else (lambda e: e)
    sim = mf.simulation
    lam = ", ".join(m.name for m in system.multipliers) or "none"
    print(f"\nconstraints: {system.n_holonomic} holonomic, {system.n_nonholonomic} nonholonomic, "
          f"{len(system.inequalities)} inequalities; degrees of freedom n - J = {system.dof}; multipliers: {lam}; "
          f"formulation {sim.formulation}")
    for j, f in enumerate(system.holonomic):
        print(f"\nholonomic constraint {j} (eq. 4.1): f_{j}(q, t) = 0 (output g_{j}) with f_{j} =")
        print(show(simp(f)))
    for k, row in enumerate(r for r in system.rows() if not r.holonomic):
        rep = system.is_integrable(k)
        kind = "integrable (kept as a Pfaffian row)" if rep.integrable else "not integrable (Frobenius)"
        print(f"\nnonholonomic constraint {k} (eq. 4.3; row {row.index}), {kind}: A . q' + A0 = 0 with "
              "A . q' + A0 =")
        expr = sum((a * v for a, v in zip(row.A, model.speeds)), sp.Integer(0)) + row.A0
        print(show(simp(expr)))
    for k, g in enumerate(system.inequalities):
        e = system.restitution[k]
        what = (f"terminal event ineq_{k}, decreasing" if e is None else
                f"contact: impacts with restitution {e:g}, persistent contact with multiplier lambda_ineq_{k}"
                + ("" if system.tangents[k] is None else f", no slip along {system.tangents[k]}"
                   if system.friction[k] is None else
                   f", Coulomb friction mu = {system.friction[k]:g} along {system.tangents[k]}"))
        print(f"\ninequality constraint {k} (eq. 4.3): ineq_{k}(q, t) >= 0 ({what}) with ineq_{k} =")
        print(show(simp(g)))
    if system.J:
        coords = ", ".join(q.name for q in model.coords)
        print(f"\ndifferential form (eq. 4.2): A dq + A0 dt = 0, A = (df/dq; Pfaffian rows) over ({coords}):")
        print(show(system.A.applyfunc(simp)))
        print("\nA0 (df/dt; Pfaffian A0):")
        print(show(system.A0.applyfunc(simp)))
        dyn, acc = system.equations(eom)
        print("\nequations with multipliers (eq. 4.5): M q'' - F - A^T lambda = 0:")
        print(show(dyn.applyfunc(simp)))
        print("\nand the constraints at acceleration level, A q'' - gamma = 0 (gamma = -(d/dt)(A q' + A0) "
              "without q''):")
        print(show(acc.applyfunc(simp)))


def _info_events(mf, show) -> None:
    """The file's [[events]] (every kind of model)."""
    for ev in mf.events:
        direction = {-1: "decreasing", 0: "either direction", 1: "increasing"}[ev.direction]
        print(f"\nevent {ev.name} ({direction}{', terminal' if ev.terminal else ''}): zero of")
        print(show(ev.expr))
