"""The C of the forward sensitivity equations of a constrained system in the index-1 form:
``<prefix>_csens.c`` with ``<prefix>_csens_rhs`` (the state's right-hand side and the
sensitivities' of ns directions, one factorization of the augmented matrix), ``<prefix>_csens_outputs``
(the outputs' sensitivities, the multipliers' included), ``<prefix>_csens_initial`` (the
initial sensitivities through the linearized projection onto the constraints) and
``<prefix>_csens_model_table`` (an ``lcg_model`` table of the index-1 right-hand side with its
exact Jacobian, for the runtime's sensitivity driver), printed from the kernels of
:func:`lagcodegen.formulation.sensitivity_constrained.constrained_sensitivity_blocks` by
:class:`~lagcodegen.codegen.c.CPrinter`. A file of its own, compiled on first use of
sensitivities: the system's other generated files do not change. The rhs and outputs functions
have the signatures of the ODE's (:data:`lagcodegen.codegen.sensitivity.SENS_RHS`); their
parameter array holds the run-time parameters followed by the Baumgarte rates alpha, beta."""

from __future__ import annotations

from typing import Sequence

from ..formulation.scene import Scene
from ..formulation.sensitivity_constrained import constrained_sensitivity_blocks
from ..theory.constraints import ConstrainedSystem
from ..version import __version__
from .c import print_block
from .templates import environment

#: The C prototypes of the generated functions (``{prefix}`` to fill in).
CSENS_RHS = ("int {prefix}_csens_rhs(double t, const double *y, const double *p, int ns, const int *which, "
             "const double *s, double *ydot, double *sdot)")
CSENS_OUTPUTS = ("int {prefix}_csens_outputs(double t, const double *y, const double *p, int ns, const int *which, "
                 "const double *s, double *dout)")
CSENS_INITIAL = ("int {prefix}_csens_initial(double t, const double *y, const double *p, int ns, const int *which, "
                 "double *s)")


def constrained_sensitivity_source(system: ConstrainedSystem, scene: Scene, outputs: Sequence[str],
                                   prefix: str) -> dict[str, str]:
    """``{<prefix>_csens.c: text}``: the index-1 sensitivity functions of ``system`` (module
    docstring); ``scene`` the scene of its compiled code, ``outputs`` its output names."""
    kb = constrained_sensitivity_blocks(system, scene, outputs)
    blocks = kb["blocks"]
    text = environment().get_template("c/csens.c.j2").render(
        prefix=prefix, version=__version__, model_name=system.model.name, n=kb["n"], nj=kb["J"], njh=kb["JH"],
        np=len(scene.runtime_parameters), nout=kb["nout"],
        **{k: print_block(blocks[k]) for k in ("mf", "con", "gam", "out", "tangent", "con_tangent", "dout")})
    return {f"{prefix}_csens.c": text}
