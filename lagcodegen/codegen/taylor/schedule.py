"""The order of the tangent operations in the C code of the variational jet (:mod:`.variational`,
printed by :mod:`.sensitivity`): levels of mutually independent operations, the convolutions of
each level fused into loops over the orders with one accumulator per product.

At order k a product's coefficient sum_j x_[j] y_[k-j] is a chain of dependent additions;
separate loops run these chains one after the other, each bound by the latency of an addition.
The tangent operations of a jet are mostly such sums (the tangent of a product is two products,
of sin x the product cos x dx), and many are independent of one another (the tangents of
different operations, and of the same operation along different directions): one loop holding
the sums of up to :data:`GROUP` products runs their chains side by side. Each sum is added in the
same order as in its own loop, so the numbers are the same.
"""

from __future__ import annotations

from dataclasses import dataclass

from .decompose import Op

#: Most products summed in one fused loop (one accumulator register each).
GROUP = 8


@dataclass(frozen=True)
class Fused:
    """``dot`` operations of one level computed in one loop over the orders."""

    ops: tuple

    @property
    def pairs(self) -> list:
        """The products (x, y) of the group's operations, in their order (accumulator i: the
        i-th)."""
        return [pr for op in self.ops for pr in op.pairs if pr is not None]


def _npairs(op: Op) -> int:
    return sum(1 for pr in op.pairs if pr is not None)


def _reads(op: Op) -> set:
    rows = set(op.args)
    rows.update(r for pr in op.pairs if pr is not None for r in pr)
    return rows


def levels(ops: list) -> list[list]:
    """``ops`` (in an order where each reads only rows written before it or elsewhere) as levels:
    an operation's level is one more than the highest level of the operations among ``ops``
    whose rows it reads at the same order. Within a level, the operations keep their order."""
    level_of: dict[int, int] = {}
    out: list[list] = []
    for op in ops:
        lev = max((level_of[r] + 1 for r in _reads(op) if r in level_of), default=0)
        for o in op.out:
            level_of[o] = lev
        while len(out) <= lev:
            out.append([])
        out[lev].append(op)
    return out


def schedule(ops: list, tangent_rows=frozenset(), group: int = GROUP) -> list:
    """``ops`` as items for the C code: :class:`Fused` groups of the ``dot`` operations of each
    level (up to ``group`` products a loop; a dot with more stays alone) then the level's other
    operations, level by level. The dots of a level are grouped by their first factor that is
    not a tangent (a row neither in ``tangent_rows`` nor written by ``ops``): the tangents of one
    operation along several directions share it, and one loop loads it once."""
    written = {o for op in ops for o in op.out}

    def shared(op):
        rows = [r for pr in op.pairs if pr is not None for r in pr if r not in written and r not in tangent_rows]
        return min(rows, default=-1)

    items: list = []
    for level in levels(ops):
        dots = sorted((op for op in level if op.kind == "dot" and 0 < _npairs(op) <= group), key=shared)
        current: list = []
        for op in dots:
            if current and sum(map(_npairs, current)) + _npairs(op) > group:
                items.append(Fused(tuple(current)))
                current = []
            current.append(op)
        if current:
            items.append(Fused(tuple(current)))
        items += [op for op in level if not (op.kind == "dot" and 0 < _npairs(op) <= group)]
    return items


def item_count(item) -> int:
    """The operations of an item (for splitting the code into functions of bounded size)."""
    return len(item.ops) if isinstance(item, Fused) else 1
