"""The part of a constrained bundle (:func:`lagcodegen.codegen.bundle.render_constrained_bundle`)
that systems with contacts (:class:`~lagcodegen.theory.constraints.Inequality` with a
restitution, notes sec. 4.3) add: the contact functions ``<prefix>_impact.c`` with their table
(lcg_imp_model.h: the gaps, the index-1 right-hand side with the persistent contacts held, the
impact law M dv = R^T P with Newton's law), the tables they point to (``<prefix>_dae_table.c``,
``<prefix>_table.c`` with the unconstrained model ``<prefix>.c``), all compiled into the bundle's
library, and ``rk4_example.c`` that drives them: fixed-step RK4 with every impact located by
bisection within its step and the jump applied there, persistent contact and release. The impact
law is the runtime's own file ``lcg_imp_law.c`` (with ``lcg_imp_law.h``), which the impact drivers
(lcg_imp.c, lcg_imp_ida.c) use: the bundle ships it as it is, in its library.

Systems with Coulomb friction (``Inequality(..., tangent=..., friction=mu)``, planar or 3-D) get
the friction table of ``<prefix>_impact.c`` (lcg_imp_friction: the model's numbers at a state)
and the runtime's friction core ``lcg_imp_fric.c`` (with ``lcg_imp_fric.h``), the file the impact
drivers solve stick/slip/release modes, frictional impacts and Painleve's paradox with, shipped as
it is; their example (``templates/bundle/rk4_friction.c.j2``) keeps the modes fixed within a step
and locates each transition (the roots the CVODE driver watches) by bisection as it locates
impacts, and stops with exit status 3 and the core's message on Painleve's paradox."""

from __future__ import annotations

from ..codes import c_header as codes_header
from ..errors import ModelError
from ..runtime import sources as runtime_files
from .record import GeneratedCode
from .tables import dae_table, model_table


def check_contact_bundle(system, c_sources: bool, ggl: bool) -> None:
    """Refusals by name: what the contact bundle does not carry (``c_sources``: whether the
    bundle's language is printed as C, the backend's answer)."""
    if not c_sources:
        raise ModelError("bundles of systems with contacts are made in C only (their library and RK4 example "
                         "are written for the C contact functions <prefix>_impact.c; compile_constrained runs "
                         "Fortran contact code): lang='c'")
    if ggl:
        raise ModelError("bundles of systems with contacts are made for the index-1 formulation, not GGL")
    if system.model.general:
        raise ModelError(f"bundles of systems with contacts and generalized speeds (model {system.model.name!r}) "
                         "are not made")


#: The runtime files the example of a system with Coulomb friction adds to the library: the
#: friction core of the impact drivers, as it is.
FRICTION_RUNTIME = ("lcg_imp_fric.h", "lcg_imp_fric.c")


def tangent_columns(system) -> list[str]:
    """The names of the tangential multipliers (rows nj + nk + i of the contact table, in order),
    as the impact driver's results name them: ``lambda_t_ineq_<k>`` for a contact with one
    tangent, ``lambda_t0_ineq_<k>``, ``lambda_t1_ineq_<k>`` for one with two (3-D)."""
    names = []
    for k in system.contacts:
        tangent = system.tangents[k]
        if tangent is None:
            continue
        if isinstance(tangent, tuple) and len(tangent) > 1:
            names += [f"lambda_t{d}_ineq_{k}" for d in range(len(tangent))]
        else:
            names.append(f"lambda_t_ineq_{k}")
    return names


def contact_columns(system, output_names) -> list[str]:
    """The columns the contact bundle's example prints after the state: the outputs, then the
    contacts' multipliers ``lambda_ineq_<k>``, then (systems with Coulomb friction) the
    tangential multipliers (:func:`tangent_columns`)."""
    extra = tangent_columns(system) if system.has_friction else []
    return [*output_names, *(f"lambda_ineq_{k}" for k in system.contacts), *extra]


def contact_context(system, info) -> dict:
    """What the example's template takes besides the constrained bundle's context."""
    contacts = list(system.contacts)
    n_tangent = len(tangent_columns(system))  # tangential rows: one per tangent, two for a 3-D contact
    lambda_columns = [(i, int(name[len("lambda_"):])) for i, name in enumerate(info.output_names)
                      if name.startswith("lambda_") and name[len("lambda_"):].isdigit()]
    ctx = dict(nk=len(contacts), nrow=info.J + len(contacts) + n_tangent, contacts=contacts,
               restitution=[repr(float(system.restitution[k])) for k in contacts],
               contact_text=[f"g_{k} = {system.inequalities[k]} >= 0, e = {system.restitution[k]:g}"
                             for k in contacts],
               lambda_columns=lambda_columns, friction=system.has_friction)
    if system.has_friction:
        ctx["contact_text"] = [text + _friction_text(system, k) for k, text in zip(contacts, ctx["contact_text"])]
        ctx.update(mu=[repr(-1.0 if system.friction[k] is None else float(system.friction[k])) for k in contacts],
                   tangent_columns=tangent_columns(system))
    return ctx


def _friction_text(system, k) -> str:
    """How contact k's tangent acts, for the example's comment."""
    tangent = system.tangents[k]
    if tangent is None:
        return ", frictionless"
    if system.friction[k] is None:
        return f", no slip along {tangent}"
    cone = " (3-D, circular cone)" if isinstance(tangent, tuple) and len(tangent) > 1 else ""
    return f", Coulomb friction mu = {system.friction[k]:g} along {tangent}{cone}"


def contact_files(code: GeneratedCode, friction: bool = False) -> dict[str, str]:
    """The C files and headers the contact functions need in the bundle (their library sources
    are :func:`library_sources`); with ``friction`` the runtime's friction core too."""
    pre = code.prefix
    return {f"{pre}_impact.c": code.files[f"{pre}_impact.c"], "lcg_imp_model.h": code.files["lcg_imp_model.h"],
            f"{pre}.c": code.files[f"{pre}.c"], f"{pre}.h": code.files[f"{pre}.h"],
            f"{pre}_table.c": model_table(code), f"{pre}_dae_table.c": dae_table(code),
            **runtime_files(("lcg_model.h", "lcg_dae_model.h", "lcg_imp_law.h", "lcg_imp_law.c")),
            **(runtime_files(FRICTION_RUNTIME) if friction else {}),
            "lcg_codes.h": codes_header()}


def library_sources(code: GeneratedCode, friction: bool = False) -> list[str]:
    """The C files the contact bundle adds to its library (``friction``: also the friction core)."""
    pre = code.prefix
    return [f"{pre}_impact.c", f"{pre}.c", f"{pre}_table.c", f"{pre}_dae_table.c", "lcg_imp_law.c",
            *(name for name in FRICTION_RUNTIME if name.endswith(".c") and friction)]


def contact_table(code: GeneratedCode, table: list, friction: bool = False) -> None:
    """The README's file table ``table`` (name, what) with the contact bundle's files (``friction``:
    a system with Coulomb friction)."""
    pre = code.prefix
    for i, (name, _) in enumerate(table):
        if name == "rk4_example.c" and friction:
            table[i] = (name, "fixed-step RK4 of the index-1 equations with the contacts' impacts and Coulomb "
                              "friction (stick, slip, release and impacts located by bisection within a step, "
                              "the modes chosen by lcg_imp_fric.c; Painleve's paradox: exit status 3); CSV on "
                              "stdout, the contact events on stderr; needs only a C compiler")
        elif name == "rk4_example.c":
            table[i] = (name, "fixed-step RK4 of the index-1 equations with the contacts' impacts (located by "
                              "bisection within a step), persistent contact and release; CSV on stdout, the "
                              "contact events on stderr; needs only a C compiler")
    table[-1:-1] = [(f"{pre}_impact.c", "the contact functions (gaps, index-1 right-hand side with the persistent "
                                        "contacts, the impact law) and their table (lcg_imp_model.h)"),
                    (f"{pre}.c", f"the unconstrained model ({pre}.h), which the tables point to"),
                    (f"{pre}_table.c", "the unconstrained model's function table (lcg_model.h)"),
                    (f"{pre}_dae_table.c", "the constrained model's function table (lcg_dae_model.h)"),
                    ("lcg_imp_law.c", "the impact law (Newton's law on the contacts jointly, persistent contact, "
                                      "release), lagcodegen's runtime file as its impact drivers use it; "
                                      "lcg_imp_law.h its declarations")]
    if friction:
        table[-1:-1] = [("lcg_imp_fric.c", "the friction core (the contact problem of each stick/slip/release "
                                           "mode, their enumeration, frictional impacts, Painleve's paradox), "
                                           "lagcodegen's runtime file as its impact drivers use it; "
                                           "lcg_imp_fric.h its declarations")]
