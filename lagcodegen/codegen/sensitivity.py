"""The C of the forward sensitivity equations: ``<prefix>_sens.c`` with ``<prefix>_sens_rhs``
(the state's right-hand side and the sensitivities' of ns directions, one factorization of M)
and ``<prefix>_sens_outputs`` (the outputs' sensitivities), printed from the kernels of
:func:`lagcodegen.formulation.sensitivity.sensitivity_blocks` through the common operation tree
(:mod:`.lowering`) and :class:`~lagcodegen.codegen.c.CPrinter`. A file of its own, compiled on
first use of sensitivities: the model's other generated files do not change."""

from __future__ import annotations

from ..formulation.scene import Scene
from ..formulation.sensitivity import sensitivity_blocks
from ..version import __version__
from .c import print_block
from .templates import environment

#: The C prototypes of the generated functions (``{prefix}`` to fill in).
SENS_RHS = ("int {prefix}_sens_rhs(double t, const double *y, const double *p, int ns, const int *which, "
            "const double *s, double *ydot, double *sdot)")
SENS_OUTPUTS = ("int {prefix}_sens_outputs(double t, const double *y, const double *p, int ns, const int *which, "
                "const double *s, double *dout)")


def sensitivity_source(scene: Scene, prefix: str) -> dict[str, str]:
    """``{<prefix>_sens.c: text}``: the sensitivity functions of ``scene`` (module docstring)."""
    blocks = sensitivity_blocks(scene)
    eom = scene.eom
    n, nz = eom.model.n, len(eom.quadratures)
    text = environment().get_template("c/sens.c.j2").render(
        prefix=prefix, version=__version__, model_name=eom.model.name, n=n, nz=nz, ny=2 * n + nz,
        np=len(scene.runtime_parameters), nout=len(scene.output_list()),
        rhs=print_block(blocks["rhs"]), tangent=print_block(blocks["tangent"]), out=print_block(blocks["out"]))
    return {f"{prefix}_sens.c": text}
