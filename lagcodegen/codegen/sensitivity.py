"""The C of the forward sensitivity equations: ``<prefix>_sens.c`` with ``<prefix>_sens_rhs``
(the state's right-hand side and the sensitivities' of ns directions, one factorization of M)
and ``<prefix>_sens_outputs`` (the outputs' sensitivities), printed from the kernels of
:mod:`lagcodegen.formulation.sensitivity` through the common operation tree (:mod:`.lowering`)
and :class:`~lagcodegen.codegen.c.CPrinter`: the expanded tangent (``c/sens.c.j2``) or the
per-direction sweep of the right-hand side's program (``c/sens_direction.c.j2``), as
:func:`lagcodegen.formulation.sensitivity.sensitivity_form` chooses. A file of its own, compiled
on first use of sensitivities: the model's other generated files do not change."""

from __future__ import annotations

from ..formulation.scene import Scene
from ..formulation.sensitivity import (SENSITIVITY_FORMS, direction_tangent, output_block, sensitivity_blocks,
                                       sensitivity_form)
from ..errors import ModelError
from ..version import __version__
from . import ir, lowering, program
from .c import CPrinter, c_statement, print_block
from .templates import environment

#: The C prototypes of the generated functions (``{prefix}`` to fill in).
SENS_RHS = ("int {prefix}_sens_rhs(double t, const double *y, const double *p, int ns, const int *which, "
            "const double *s, double *ydot, double *sdot)")
SENS_OUTPUTS = ("int {prefix}_sens_outputs(double t, const double *y, const double *p, int ns, const int *which, "
                "const double *s, double *dout)")

_PAD = "    "


def sensitivity_source(scene: Scene, prefix: str, form: str = "auto") -> dict[str, str]:
    """``{<prefix>_sens.c: text}``: the sensitivity functions of ``scene`` (module docstring).
    ``form``: "expanded", "direction" or "auto" (:func:`~lagcodegen.formulation.sensitivity.sensitivity_form`)."""
    if form not in SENSITIVITY_FORMS:
        raise ModelError(f"sensitivity form {form!r}: choose one of {', '.join(SENSITIVITY_FORMS)}")
    if form == "auto":
        form = sensitivity_form(scene)
    eom = scene.eom
    n, nz = eom.model.n, len(eom.quadratures)
    ctx = dict(prefix=prefix, version=__version__, model_name=eom.model.name, n=n, nz=nz, ny=2 * n + nz,
               np=len(scene.runtime_parameters), nout=len(scene.output_list()), nq=None)
    if eom.general:  # y = (q, v, z): N the speeds, NQ the coordinates
        nv = eom.model.nv
        ctx.update(n=nv, nq=n, ny=n + nv + nz)
    if form == "direction":
        ctx.update(_direction_context(scene))
        text = environment().get_template("c/sens_direction.c.j2").render(**ctx)
    else:
        blocks = sensitivity_blocks(scene)
        text = environment().get_template("c/sens.c.j2").render(
            **ctx, rhs=print_block(blocks["rhs"]), tangent=print_block(blocks["tangent"]),
            out=print_block(blocks["out"]))
    return {f"{prefix}_sens.c": text}


def _direction_context(scene: Scene) -> dict:
    """The template fields of the per-direction form: the program's values (a value read once
    written into its reader, the others locals or, where the targets or the sweep read them,
    elements of ``v``), the targets, the sweep of one direction, the outputs' kernel."""
    dt = direction_tangent(scene)
    prog = dt.program
    printer = CPrinter()
    outside = {prog.index(a) for _, a in dt.targets} - {None}
    sweeps = [dt.state_ops] + dt.param_ops
    trees = [[lowering.expression(e) for _, _, e in ops] for ops in sweeps]
    for tree in (t for ts in trees for t in ts):
        outside |= ir.elements(tree, "v")
    whole = program.Measure(statement=lambda st: 0, value=lambda k, tree: 0, statements=1 << 60, chars=1 << 60)
    pieces = program._value_pieces(prog, [(0, len(prog))], outside, whole)[0]
    values = [st for piece in pieces for st in piece]
    targets = [ir.Assign(program.rhs_target(t), lowering.expression(a)) for t, a in dt.targets]

    def statements(ops, ts, pad):
        out = []
        for (kind, k, _), tree in zip(ops, ts):
            if kind == "d":
                st = ir.Assign((ir.Name(f"d{k}"),), tree, local=True)
            elif kind == "g":
                st = ir.Assign((ir.Element("g", k),), tree, accumulate=True)
            else:
                zero = 2 * dt.n if dt.nv is None else 0  # generalized speeds: k is ydot's row
                st = ir.Assign((ir.Element("dk", zero + k),), tree, accumulate=True)
            out.append(c_statement(printer, st, pad))
        return "\n".join(out)
    cases = [(m, statements(ops, ts, _PAD * 4)) for m, (ops, ts) in enumerate(zip(dt.param_ops, trees[1:])) if ops]
    return dict(nv=max(1, len(prog)),
                values="\n".join(c_statement(printer, st, _PAD * 2) for st in values),
                targets="\n".join(c_statement(printer, st) for st in targets),
                sweep=statements(dt.state_ops, trees[0], _PAD * 3), cases=cases,
                out=print_block(output_block(scene)))
