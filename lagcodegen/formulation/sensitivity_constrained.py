"""The kernels of the forward sensitivity equations of a constrained system in the index-1 form (eq. 4.5).

The index-1 right-hand side solves, at every call, the augmented (KKT) system

    [M  A^T] [a]   [F          ]
    [A  0  ] [x] = [gamma - b  ],    lambda = -x,   b_r = 2 alpha s_r + beta^2 f_r (holonomic rows),
                                                    b_r = alpha s_r (nonholonomic rows),

with a = q'', s = A q' + A0 (eq. 4.3), f(q, t) the holonomic residuals (eq. 4.1) and the Baumgarte
rates alpha, beta of the run. As residuals, R1 = M a - A^T lambda - F, R2 = A a - gamma + b. For a
direction theta (a run-time parameter p_k, or an initial value) with S = dy/dtheta, y = (q, q'),
the tangent of R = 0 at fixed (a, lambda) gives

    [M  A^T] [da]     [(dR1/dy) S + dR1/dp_k]
    [A  0  ] [dx] = - [(dR2/dy) S + dR2/dp_k],    dlambda = -dx,

the same KKT matrix as the accelerations' (factored once, never inverted symbolically), the
dR/dp_k terms only for a parameter. alpha and beta are constants of a run: on solutions s = f =
0, so their own derivatives (the "auto" rates depend on the initial state and the parameters)
drop out. Outputs: d out/dtheta = (d out/dy) S + (d out/dlambda) dlambda + d out/dp_k.

The initial sensitivities are those of the initial projection onto the constraints that
simulate() applies (Gauss-Newton on the positions, then the velocities, eqs. 4.1-4.3),
linearized at the consistent initial state: with G = df/dq,

    S_q = (I - G^T (G G^T)^-1 G) S_q0 - G^T (G G^T)^-1 df/dp_k,
    S_v = (I - A^T (A A^T)^-1 A) S_v0 - A^T (A A^T)^-1 ((ds/dq) S_q + ds/dp_k).

Kernels (language-neutral :class:`~lagcodegen.formulation.kernels.Block` s, symbols ``y[i]``,
``p[k]``, ``t``, ``a[i]``, ``lam[r]``):

* ``mf``, ``con``, ``gam``, ``out``: those of :func:`~lagcodegen.formulation.constrained.constrained_blocks`
  (M, F; A, s, f; gamma; the outputs);
* ``tangent``: ("Ry", i, j) = dR_i/dy_j (rows R1 then R2), ("Rp", k, i) = dR_i/dp_k (after a and
  lambda are known);
* ``con_tangent``: ("Sy", r, j) = ds_r/dy_j, ("Sp", k, r) = ds_r/dp_k, ("Gy", r, j) = df_r/dq_j,
  ("Gp", k, r) = df_r/dp_k;
* ``dout``: ("Oy", k, i) = d out_k/dy_i, ("Ol", k, r) = d out_k/dlambda_r, ("Op", k, m) = d out_k/dp_m.
"""

from __future__ import annotations

from typing import Sequence

import symengine as se

from ..errors import ModelError
from ..theory.constraints import ConstrainedSystem
from .constrained import ConstrainedSymbols, _constrained_outputs, constrained_blocks
from .kernels import Block, symbol_map
from .scene import Scene


def constrained_sensitivity_blocks(system: ConstrainedSystem, scene: Scene, outputs: Sequence[str]) -> dict:
    """The kernels of the index-1 sensitivity equations of ``system`` (module docstring), the
    symbols renamed as in ``scene``; ``outputs`` the output names of the compiled system."""
    eom = scene.eom
    model = system.model
    if eom.tree is not None:
        raise ModelError(f"model {model.name!r}: sensitivities of a rigid-body tree model are not generated "
                         "(its M and F are programs, not expressions)")
    if system.contacts:
        raise ModelError(f"system {model.name!r}: sensitivities of systems with contacts (impacts) are not "
                         "generated")
    base = constrained_blocks(system, scene, outputs=outputs)
    sym = ConstrainedSymbols(system, eom)
    n, J, JH = sym.n, sym.J, sym.JH
    sub = dict(symbol_map(scene))
    lam_arr = [se.Symbol(f"lam[{r}]") for r in range(J)]
    sub.update(dict(zip(sym.lam, lam_arr)))

    def c(e):
        return se.sympify(e).xreplace(sub)

    y = sym.q + sym.v
    params = [se.Symbol(name) for name in scene.runtime_parameters]
    a = [se.Symbol(f"a[{i}]") for i in range(n)]
    R = []
    for i in range(n):
        R.append(sum((sym.M[i][j] * a[j] for j in range(n)), se.Integer(0)) - sym.F[i]
                 - sum((sym.A[r][i] * sym.lam[r] for r in range(J)), se.Integer(0)))
    for r in range(J):
        R.append(sum((sym.A[r][i] * a[i] for i in range(n)), se.Integer(0)) - sym.gamma[r])
    tangent = Block()
    for i, res in enumerate(R):
        tangent.add_partials(res, y, c, lambda j, i=i: ("Ry", i, j))
        tangent.add_partials(res, params, c, lambda k, i=i: ("Rp", k, i))
    con_tangent = Block()
    for r in range(J):
        con_tangent.add_partials(sym.s[r], y, c, lambda j, r=r: ("Sy", r, j))
        con_tangent.add_partials(sym.s[r], params, c, lambda k, r=r: ("Sp", k, r))
    for r in range(JH):
        con_tangent.add_partials(sym.f[r], sym.q, c, lambda j, r=r: ("Gy", r, j))
        con_tangent.add_partials(sym.f[r], params, c, lambda k, r=r: ("Gp", k, r))
    dout = Block()
    for k, (_, expr) in enumerate(_constrained_outputs(system, sym, scene, list(outputs))):
        dout.add_partials(expr, y, c, lambda i, k=k: ("Oy", k, i))
        dout.add_partials(expr, sym.lam, c, lambda r, k=k: ("Ol", k, r))
        dout.add_partials(expr, params, c, lambda m, k=k: ("Op", k, m))
    for block in (tangent, con_tangent, dout):
        bad = [e for e in block.exprs if e.atoms(se.Derivative, se.Subs)]
        if bad:
            raise ModelError(f"system {model.name!r}: sensitivities need derivatives of {bad[0]}, which symengine "
                             "cannot take in closed form")
    blocks = {k: base.blocks[k] for k in ("mf", "con", "gam", "out")}
    blocks.update(tangent=tangent, con_tangent=con_tangent, dout=dout)
    return {"blocks": blocks, "n": n, "J": J, "JH": JH, "nout": len(base.outputs),
            "outputs_use_lam": base.outputs_use_lam}
