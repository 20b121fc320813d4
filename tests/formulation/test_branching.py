"""The branch-induced sparsity of a tree's mass matrix (lagcodegen.formulation.branching) and the
generated C's L^T L factorization along it: the parents of hand-made patterns, the choice
against the dense Cholesky, and a branched tree's accelerations and Jacobian against Pinocchio's
ABA and central differences."""

import numpy as np
import pytest

import lagcodegen as lcg
from lagcodegen.formulation.branching import factor_cost, parents_of_pattern, tree_parents


def pattern_of(parent):
    """The symmetric pattern of a tree with ``parent``: (i, j) where one is the other's ancestor."""
    n = len(parent)
    nz = [[i == j for j in range(n)] for i in range(n)]
    for i in range(n):
        j = parent[i]
        while j >= 0:
            nz[i][j] = nz[j][i] = True
            j = parent[j]
    return nz


def test_parents_of_tree_chain_and_other_patterns():
    star = [-1, 0, 1, 2, 0, 4, 5, 0, 7, 8, 9, 9]  # a root with three branches, one forked
    assert parents_of_pattern(pattern_of(star)) == star
    chain = list(range(-1, 11))
    assert parents_of_pattern(pattern_of(chain)) == chain
    coupled = pattern_of(star)
    coupled[3][6] = coupled[6][3] = True  # two branches coupled (e.g. a closed loop): not a tree's
    assert parents_of_pattern(coupled) is None
    # cost: a chain costs sum over k of k(k+1)/2 updates plus the roots, about N^3 / 6
    assert factor_cost(chain) == sum(k * (k + 1) // 2 for k in range(12)) + 12


def test_choice_against_dense():
    """The tree's factorization is chosen only where it saves: branched and large enough."""
    def targets(parent):
        nz = pattern_of(parent)
        n = len(parent)
        pairs = [("M", i, j) for i in range(n) for j in range(i, n)]
        return pairs, [1 if nz[i][j] else 0 for _, i, j in pairs]
    legs = [-1, 0, 1, 2, 3, 4] + [5, 6, 7, 5, 9, 10, 5, 12, 13, 5, 15, 16]  # a free flyer and four legs
    assert tree_parents(*targets(legs), len(legs)) == legs
    assert tree_parents(*targets(list(range(-1, 17))), 18) is None  # a chain: no saving
    assert tree_parents(*targets(legs[:8]), 8) is None  # too small to matter


def branched_tree():
    """A fixed base with three branches (4, 4 and 2 + 2 forked) of revolute joints about mixed
    axes, random placements and inertias: 12 speeds, as a lagcodegen Model and a Pinocchio model."""
    pin = pytest.importorskip("pinocchio")
    rng = np.random.default_rng(3)
    m = lcg.Model("branched12")
    g, = m.parameters(g=9.81)
    m.gravity(g)
    pm = pin.Model()
    pm.gravity = pin.Motion(np.array([0, 0, -9.81, 0, 0, 0]))
    parent = [-1, 0, 1, 2, -1, 4, 5, 6, -1, 8, 9, 9]
    names, ids = [], []
    for i, par in enumerate(parent):
        R, t = pin.rpy.rpyToMatrix(*rng.uniform(-3, 3, 3)), rng.uniform(-0.3, 0.3, 3)
        ax = np.array([(0, 0, 1), (1, 0, 0), (0, 1, 0)][i % 3], dtype=float)
        A = rng.normal(size=(3, 3))
        mass, c, inertia = rng.uniform(0.5, 2), rng.uniform(-0.2, 0.2, 3), A @ A.T + 0.1 * np.eye(3)
        names.append(m.link(f"l{i}", parent=None if par < 0 else names[par], joint=lcg.Joint.revolute(f"j{i}", tuple(ax)),
                            origin=lcg.Placement(tuple(t), rotation=R.tolist()), mass=mass, com=tuple(c),
                            inertia=(inertia[0, 0], inertia[1, 1], inertia[2, 2], inertia[0, 1], inertia[0, 2],
                                     inertia[1, 2])).name)
        jid = pm.addJoint(0 if par < 0 else ids[par], pin.JointModelRevoluteUnaligned(ax), pin.SE3(R, t), f"j{i}")
        pm.appendBodyToJoint(jid, pin.Inertia(mass, c, inertia), pin.SE3.Identity())
        ids.append(jid)
    return m, pm


def test_branched_tree_factors_along_the_tree_and_agrees_with_pinocchio():
    """The generated C of a branched 12-joint tree factors M along the tree (the parents array in
    the source), and its accelerations agree with Pinocchio's ABA to 1e-12 at random states; its
    Jacobian (every column solved with the same factors) with central differences of rhs."""
    pin = pytest.importorskip("pinocchio")
    m, pm = branched_tree()
    cm = lcg.compile_model(m, jacobian=True)
    src = cm.code.files[cm.code.source_name]
    assert "static const int branched12_parent[N] = {" in src and "-1, 0, 1, 2, -1, 4, 5, 6, -1, 8, 9, 9" in src
    data = pm.createData()
    rng = np.random.default_rng(4)
    for _ in range(5):
        q, v = rng.uniform(-3, 3, 12), rng.normal(size=12)
        ref = pin.aba(pm, data, q, v, np.zeros(12))
        np.testing.assert_allclose(cm.rhs(0.0, np.r_[q, v])[12:], ref, rtol=0, atol=1e-12 * np.abs(ref).max())
    y = np.r_[q, v]
    J = cm.jac(0.0, y)
    h = 1e-6
    fd = np.column_stack([(cm.rhs(0.0, y + h * e) - cm.rhs(0.0, y - h * e)) / (2 * h) for e in np.eye(24)])
    np.testing.assert_allclose(J, fd, rtol=0, atol=1e-6 * np.abs(fd).max())
