"""C (or Fortran) files of a constrained system (eq. 4.5): the augmented index-1 system and the
GGL residual, from the kernels of :mod:`lagcodegen.formulation.constrained`.

:func:`generate_constrained` renders templates/c/dae.c.j2 (accelerations and multipliers from
[M A^T; A 0][q''; -lambda] = [F; gamma], constraint residuals, projection, outputs, events) and,
for the GGL formulation, the DAE residual F(t, y, y') and its Jacobian dF/dy + cj dF/dy' for
IDA; with ``lang="fortran"`` the same functions come from templates/fortran/dae.f90.j2 (bound
to the same C names, evaluating the same operations). The native drivers are not part of a
model's code: they are model-independent (lagcodegen/runtime/lcg_cvc.c, lcg_ida.c), compiled once
into the runtime (:func:`lagcodegen.build.runtime`), and call a model through its function table
``<prefix>_dae_table.c`` (lcg_dae_model.h), which the build adds (:func:`lagcodegen.build.dae_table_source`).
"""

from __future__ import annotations

from typing import Iterable, Sequence

from ..derivation import derive
from ..errors import ModelError
from ..formulation.constrained import (DEFAULT_OUTPUTS, ConstrainedBlocks, ConstrainedCodeInfo, constrained_blocks,
                                       impact_blocks)
from ..formulation.scene import Scene
from ..theory.constraints import ConstrainedSystem
from ..runtime import source as runtime_source
from ..version import __version__
from .c import mass_force_text, print_block
from .ir import deep_recursion
from .languages import backend, generate_code
from .record import DaeLayout
from .templates import environment


def generate_constrained(system: ConstrainedSystem, *, ggl: bool = False, ggl_jacobian: bool = True,
                           outputs: Sequence[str] = DEFAULT_OUTPUTS, events: Iterable = (),
                           runtime_parameters=None, values=None, prefix: str | None = None, lang: str = "c"):
    """Generated code of a constrained system: the model's own files plus ``<prefix>_dae.h`` and
    its implementation (augmented-system solve, projection, outputs, roots, GGL residual and
    Jacobian), with its layout in ``code.dae`` (:class:`~.record.DaeLayout`). The native drivers
    that integrate it (index 1 on CVODE, GGL on IDA) are the runtime's, model-independent.

    ``lang``: ``"c"`` (``<prefix>.c``, ``<prefix>_dae.c``, C99) or ``"fortran"`` (``<prefix>.f90``
    and ``<prefix>_dae.f90``, Fortran 2008 modules whose functions are bound to the same C
    names and signatures, see :func:`lagcodegen.codegen.fortran.FortranBackend.constrained_source`);
    the headers are the same C files in both cases.

    Returns (GeneratedCode ready for :func:`lagcodegen.build.build`, ConstrainedCodeInfo).
    """
    language = backend(lang)
    model = system.model
    eom = derive(model)
    if eom.quadratures:
        raise ModelError("constrained systems with quadrature states are not supported")
    scene = Scene(eom, jacobian=False, outputs=(), runtime_parameters=runtime_parameters,
                  values=dict(values or {}), prefix=prefix)
    language.check_prefix(scene.prefix, suffix="_dae_err_projection")
    code = generate_code(scene, lang)
    cb = constrained_blocks(system, scene, ggl=ggl, ggl_jacobian=ggl_jacobian, outputs=outputs, events=events)
    n, J, JH, ng = cb.n, cb.J, cb.JH, cb.ng
    outs, evs = cb.outputs, cb.events

    pre = code.prefix
    ctx = dict(prefix=pre, PREFIX=pre.upper(), version=__version__, model_name=model.name, n=n, nj=J, njh=JH,
               ng=ng, np=len(scene.runtime_parameters), nout=len(outs), nroot=len(evs),
               state_names=code.state_names, param_names=list(scene.runtime_parameters),
               outputs=[name for name, _ in outs], roots=[f"{ev.name}: {ev.expr}" for ev in evs],
               ggl=ggl, ggl_jac=bool(ggl and ggl_jacobian), outputs_use_lam=cb.outputs_use_lam,
               roots_use_lam=cb.roots_use_lam, general=model.general, nv=model.nv)
    if model.general:  # n is the speeds' count nv there; the coordinates' count and rates q' = k(q, v, t)
        quaternions = [model.index(lk.coordinates[-4]) for lk in model.links if lk.joint.quaternion]
        ctx.update(n=model.nq, kin=print_block(cb.blocks["kin"]), conq=print_block(cb.blocks["conq"]),
                   quaternions=quaternions)
    env = environment()
    files = {f"{pre}_dae.h": env.get_template("c/dae.h.j2").render(**ctx)}
    with deep_recursion():
        files.update(language.constrained_source(cb, ctx))
    if system.contacts:
        if lang != "c":
            raise ModelError(f"inequality constraints with a restitution (contacts) are generated in C only, "
                             f"not lang={lang!r}")
        files[f"{pre}_impact.c"] = _impact_source(system, scene, ctx, cb, ggl)
        files["lcg_imp_model.h"] = runtime_source("lcg_imp_model.h")
    code.files.update(files)
    code.dae = DaeLayout(nq=model.nq, nj=J, njh=JH, ng=ng, np=len(scene.runtime_parameters), nout=len(outs),
                         nroot=len(evs), ggl=bool(ggl), ggl_jac=bool(ggl and ggl_jacobian),
                         nv=model.nv if model.general else None)
    info = ConstrainedCodeInfo(pre, model.nq, J, JH, ng, [name for name, _ in outs], evs, ggl, bool(ggl and ggl_jacobian),
                               dict(scene.folded), lang, tuple(system.contacts))
    return code, info


def _impact_source(system: ConstrainedSystem, scene: Scene, ctx: dict, cb: ConstrainedBlocks,
                   ggl: bool = False) -> str:
    """``<prefix>_impact.c`` (templates/c/impact.c.j2): the contact functions and their table
    ``lcg_imp_model`` (lagcodegen/runtime/lcg_imp_model.h) for the impact driver; with friction or
    ``ggl`` also the model's numbers at a state (``lcg_imp_friction``), from which the friction
    driver (lcg_imp.c) solves its modes and the GGL impact driver (lcg_imp_ida.c) builds its
    residual. M and F are those of ``cb`` (:func:`constrained_blocks` of the same system; a
    tree's program printed once for both files, :func:`lagcodegen.codegen.c.mass_force_text`)."""
    blocks = impact_blocks(system, scene, mass_force=False)
    mfp = mass_force_text(cb)
    contacts = ", ".join(f"{system.inequalities[k]} >= 0, e = {system.restitution[k]:g}"
                         + (f", no slip along {system.tangents[k]}" if system.tangents[k] is not None
                            and system.friction[k] is None else "")
                         + (f", Coulomb friction along {system.tangents[k]}" if system.friction[k] is not None
                            else "")
                         for k in system.contacts)
    return environment().get_template("c/impact.c.j2").render(
        **ctx, nk=len(system.contacts), contacts=contacts, mf_program=mfp,
        mf="" if mfp else print_block(cb.blocks["mf"]),
        rows=print_block(blocks["rows"]), tangent_of=blocks["tangent_of"], friction=system.has_friction,
        numbers=ggl)


def generate_constrained_c(system: ConstrainedSystem, **options):
    """:func:`generate_constrained` (the name of earlier versions; ``lang`` chooses the language)."""
    return generate_constrained(system, **options)


def generate_constrained_fortran(system: ConstrainedSystem, **options):
    """:func:`generate_constrained` with ``lang="fortran"``."""
    return generate_constrained(system, lang="fortran", **options)


