"""The inverse-dynamics kernel of a model with a rigid-body tree: tau = M(q) q'' - F(q, q', t)
(eq. 3.16 solved for the generalized forces that produce given accelerations), with the tree's
share by recursive Newton-Euler (:func:`lagcodegen.model.treedynamics.recorded_inverse_dynamics`:
O(n), no mass matrix) and the closed-form terms of the model's other elements added. With
q' = 0 and q'' = 0 it is the static (gravity) load -F(q, 0, t)."""

from __future__ import annotations

import symengine as se

from ..errors import ModelError
from ..model.treedynamics import recorded_inverse_dynamics
from .kernels import Block, substitute_all, symbol_map
from .scene import Scene


def tree_kernel_symbols(scene: Scene, what: str) -> tuple:
    """(the model, the symbol map, q, v, the accelerations ``a[i]``) of a kernel along the
    scene's rigid-body tree (inverse dynamics, its regressor); ModelError naming ``what`` if the
    model has no tree."""
    eom = scene.eom
    if eom.tree is None:
        raise ModelError(f"model {eom.model.name!r} has no rigid-body tree (Model.link): no {what}")
    model = eom.model
    q = [se.Symbol(s.name) for s in model.coords]
    qd = [se.Symbol(s.name) for s in model.v]
    return model, symbol_map(scene), q, qd, [se.Symbol(f"a[{i}]") for i in range(model.nv)]


def inverse_dynamics_block(scene: Scene) -> Block:
    """Targets ("tau", i) in the array symbols ``y[i]``, ``a[i]`` (the accelerations q''),
    ``p[k]``, ``t``; the tree's program as the block's temporaries (:attr:`Block.defs`)."""
    model, sub, q, qd, a = tree_kernel_symbols(scene, "inverse dynamics kernel")
    n = model.nv
    eom = scene.eom
    defs, tau = recorded_inverse_dynamics(model, q, qd, a)
    M_rest, F_rest = eom.tree.rest
    block = Block(defs=list(zip([sym for sym, _ in defs], substitute_all(sub, [e for _, e in defs]))))
    for i in range(n):
        rest = se.Add(*(se.sympify(M_rest[i][j]) * a[j] for j in range(n) if M_rest[i][j] != 0))
        block.add(("tau", i), se.sympify(rest - se.sympify(F_rest[i]) + tau[i]).xreplace(sub))
    return block
