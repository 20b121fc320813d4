"""The inverse-dynamics regressor kernel of a model with a rigid-body tree: Y(q, q', q'') with
tau_tree = Y pi (:mod:`lagcodegen.model.regressor`), and the bodies' dynamic parameters pi as
the model holds them (in its run-time parameters)."""

from __future__ import annotations

import symengine as se

from ..errors import ModelError
from ..model.regressor import recorded_regressor
from .dynamics import tree_kernel_symbols
from .kernels import Block, substitute_all
from .scene import Scene


def regressor_blocks(scene: Scene) -> tuple[Block, Block, list[str]]:
    """(the block of targets ("Y", i * ncol + j), row-major n x ncol, in ``y[i]``, ``a[i]``,
    ``p[k]`` with the tree's program as its temporaries; the block of targets ("pi", k) in
    ``p[k]``; the bodies' link names, 10 columns each). Entries that are zero are not targets."""
    model, sub, q, qd, a = tree_kernel_symbols(scene, "inverse-dynamics regressor")
    defs, Y, pi, names = recorded_regressor(model, q, qd, a)
    if not names:
        raise ModelError(f"model {model.name!r}: its tree has no moving link, so no inverse-dynamics regressor")
    block = Block(defs=list(zip([sym for sym, _ in defs], substitute_all(sub, [e for _, e in defs]))))
    ncol = 10 * len(names)
    for i, row in enumerate(Y):
        for j, e in enumerate(row):
            if e != 0:
                block.add(("Y", i * ncol + j), se.sympify(e).xreplace(sub))
    params = Block()
    for k, e in enumerate(substitute_all(sub, pi)):
        if e != 0:
            params.add(("pi", k), e)
    return block, params, names
