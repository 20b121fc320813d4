"""The branch-induced sparsity of a rigid-body tree's mass matrix (Featherstone, Rigid Body
Dynamics Algorithms, 2008, sec. 6.5): M[i][j] != 0 only where speed j is an ancestor of speed i
(or i of j) in the tree, so that the factorization M = L^T L, run from the leaves to the root,
fills nothing in and costs about the sum of the squared depths instead of N^3 / 6. It is written
once in the procedure tree (:func:`lagcodegen.codegen.linalg.mass_factor` and ``mass_solve`` with
``parents``, loops up the tree as :class:`lagcodegen.codegen.procedure.Ancestors`); the generated C
uses it (templates/c/_linalg.j2, ``parents``) where :func:`tree_parents` finds such a pattern and
the saving is large."""

from __future__ import annotations

#: The factorization of the tree's pattern is used when it costs at most this share of the
#: dense Cholesky's N^3 / 6 multiply-adds (chains: about the same cost, never taken).
MAX_COST_SHARE = 0.5
#: ... and M has at least this many rows (smaller ones factor in a few hundred operations).
MIN_SIZE = 12


def parents_of_pattern(nonzero: list[list[bool]]) -> list[int] | None:
    """The parent of each row (-1: a root) of the symmetric pattern ``nonzero`` (N x N, the
    structurally nonzero entries of M), the nearest earlier row i has an entry in, if every
    entry below the diagonal lies on the row's chain of ancestors; else None (not a tree's
    pattern in this order)."""
    n = len(nonzero)
    parent = []
    for i in range(n):
        below = [j for j in range(i) if nonzero[i][j] or nonzero[j][i]]
        parent.append(below[-1] if below else -1)
        chain, j = set(), parent[i]
        while j >= 0:
            chain.add(j)
            j = parent[j]
        if any(j not in chain for j in below):
            return None
    return parent


def factor_cost(parent: list[int]) -> int:
    """Multiply-adds of the L^T L factorization along ``parent`` (each row's update of its
    ancestors' rows: the sum over ancestors i of row k of i's depth)."""
    depth = []
    for j in parent:
        depth.append(0 if j < 0 else depth[j] + 1)
    cost = 0
    for k, j in enumerate(parent):
        i = j
        while i >= 0:
            cost += depth[i] + 1
            i = parent[i]
    return cost + len(parent)


def tree_parents(targets: list, exprs: list, n: int) -> list[int] | None:
    """The parents for the sparse factorization of the N x N mass matrix whose entries are the
    kernel targets ("M", i, j) (``exprs``: their expressions, a structural zero is the number
    0), or None: M's pattern is not a tree's in this order, N < :data:`MIN_SIZE`, or the
    factorization would cost more than :data:`MAX_COST_SHARE` of the dense one."""
    if n < MIN_SIZE:
        return None
    nonzero = [[False] * n for _ in range(n)]
    for target, e in zip(targets, exprs):
        if target[0] == "M" and e != 0:
            nonzero[target[1]][target[2]] = True
    parent = parents_of_pattern(nonzero)
    if parent is None or factor_cost(parent) > MAX_COST_SHARE * n ** 3 / 6:
        return None
    return parent
