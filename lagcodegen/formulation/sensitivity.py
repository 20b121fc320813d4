"""The kernels of the forward sensitivity equations of M(q, p) q'' = F(q, q', t, p) (eq. 3.16).

For a run-time parameter p_k or an initial value, with s = dq/d(theta) and its rate s', the
tangent of the residual r(q, q', a, t, p) = M a - F (a = q'') gives

    M s'' = -(dr/dq) s - (dr/dq') s' - dr/dp_k,    dr/dy = dM a - dF,

the term dr/dp_k only for a parameter (an initial value has s(0) a unit vector and no forcing).
M is never inverted symbolically: the generated code solves with the factorization of M that
already gives q''. The quadrature rates z' = rate(q, q', t, p) give dz'/d(theta) = (drate/dy) s
+ drate/dp_k. Outputs: d out/d(theta) = (d out/dy) s + d out/dp_k.

Kernels (language-neutral :class:`~lagcodegen.formulation.kernels.Block` s, symbols ``y[i]``,
``p[k]``, ``t``, ``a[i]``):

* ``rhs``: M's upper triangle ("M", i, j), F ("F", i), the quadrature rates ("ydot", 2n + k) --
  the right-hand side kernel of :func:`~lagcodegen.formulation.kernels.model_blocks`;
* ``tangent``: ("G", i, j) = dr_i/dy_j (j < 2n), ("P", k, i) = dr_i/dp_k, ("Z", k, j) =
  drate_k/dy_j, ("Zp", k, m) = drate_k/dp_m (after the accelerations a are known);
* ``out``: ("Oy", k, i) = d out_k/dy_i, ("Op", k, m) = d out_k/dp_m.
"""

from __future__ import annotations

import dataclasses

import symengine as se

from ..errors import ModelError
from .kernels import Block, model_blocks, residual_derivatives, substituter
from .scene import Scene


def sensitivity_blocks(scene: Scene) -> dict[str, Block]:
    """The kernels ``rhs``, ``tangent`` and ``out`` of the sensitivity equations of ``scene``
    (module docstring). Rigid-body trees (whose M and F are programs, not expressions) raise
    ModelError."""
    eom = scene.eom
    model = eom.model
    if eom.tree is not None:
        raise ModelError(f"model {model.name!r}: sensitivities of a rigid-body tree model are not generated "
                         "(its M and F are programs, not expressions)")
    n = model.n
    c = substituter(scene)
    rhs = model_blocks(dataclasses.replace(scene, jacobian=False))["rhs"]
    y = [se.Symbol(s.name) for s in model.coords] + [se.Symbol(s.name) for s in model.speeds]
    params = [se.Symbol(name) for name in scene.runtime_parameters]
    a = [se.Symbol(f"a[{i}]") for i in range(n)]
    dr = residual_derivatives(eom)
    tangent = Block()
    for j in range(2 * n):
        for i in range(n):
            e = c(dr(i, j))
            if e != 0:
                tangent.add(("G", i, j), e)
    for k, par in enumerate(params):
        for i in range(n):
            r = sum((eom.M_se[i][j] * a[j] for j in range(n)), se.Integer(0)) - eom.F_se[i]
            e = c(se.diff(se.sympify(r), par))
            if e != 0:
                tangent.add(("P", k, i), e)
    for k, (_, rate) in enumerate(eom.quadratures):
        rate = se.sympify(rate)
        for j, var in enumerate(y):
            e = c(se.diff(rate, var))
            if e != 0:
                tangent.add(("Z", k, j), e)
        for m, par in enumerate(params):
            e = c(se.diff(rate, par))
            if e != 0:
                tangent.add(("Zp", k, m), e)
    states = y + [se.Symbol(name) for name, _ in eom.quadratures]
    out = Block()
    for k, o in enumerate(scene.output_list()):
        expr = se.sympify(o.expr)
        for i, var in enumerate(states):
            e = c(se.diff(expr, var))
            if e != 0:
                out.add(("Oy", k, i), e)
        for m, par in enumerate(params):
            e = c(se.diff(expr, par))
            if e != 0:
                out.add(("Op", k, m), e)
    for block in (tangent, out):
        bad = [e for e in block.exprs if e.atoms(se.Derivative, se.Subs)]
        if bad:
            raise ModelError(f"model {model.name!r}: sensitivities need derivatives of {bad[0]}, which symengine "
                             "cannot take in closed form")
    return {"rhs": rhs, "tangent": tangent, "out": out}
