"""The kernels' own symbols (accelerations, temporaries) never meet the model's symbols."""

import numpy as np
import pytest
import sympy as sp

import lagcodegen as lcg
from lagcodegen import Model, ModelError, derive
from lagcodegen.derivation import to_sp
from lagcodegen.formulation.kernels import residual_derivatives
from lagcodegen.model.model import RESERVED_PREFIX


def test_coordinates_named_like_the_jacobian_temporaries_are_refused():
    """Coordinates __acc0, __acc1 once gave an analytic Jacobian wrong by 34: the residual's
    acceleration temporaries are named with the prefix no model name may start with."""
    assert RESERVED_PREFIX == "__"
    m = Model("acc")
    with pytest.raises(ModelError, match="'__acc0' starts with '__', which is reserved"):
        m.coordinates("__acc0 __acc1")


def test_residual_derivatives_with_names_an_array_or_temporary_might_use():
    m = Model("names")
    a, acc0, y = m.coordinates("a acc0 y")
    k, = m.parameters(k=3.0)
    m.kinetic_energy((1 + a**2) * m.dot(a) ** 2 / 2 + m.dot(acc0) ** 2 / 2 + m.dot(y) ** 2 / 2 + a * m.dot(y))
    m.potential_energy(k * (a**2 + acc0**2 + y**2) / 2 + a * acc0 * y)
    eom = derive(m)
    d = residual_derivatives(eom)
    accs = sp.symbols("A0:3")
    r = eom.M * sp.Matrix(accs) - eom.F
    ys = list(m.coords) + list(m.speeds)
    sub = {sp.Symbol(f"a[{i}]"): accs[i] for i in range(3)}
    for i in range(3):
        for j in range(6):
            assert sp.simplify(to_sp(d(i, j)).xreplace(sub) - sp.diff(r[i], ys[j])) == 0, (i, j)


def test_compiled_jacobian_of_such_names_matches_differences():
    m = Model("jacnames")
    a, acc0 = m.coordinates("a acc0")
    m.kinetic_energy((2 + sp.cos(a)) * m.dot(a) ** 2 / 2 + m.dot(acc0) ** 2 / 2 + sp.sin(a) * m.dot(a) * m.dot(acc0))
    m.potential_energy(a**2 / 2 + acc0**4 / 4 + a * acc0)
    cm = lcg.compile_model(m, jacobian=True, native=False)
    y = np.array([0.3, -0.7, 0.2, 0.5])
    J = cm.jac(0.0, y)
    h = 1e-6
    num = np.column_stack([(cm.rhs(0.0, y + h * e) - cm.rhs(0.0, y - h * e)) / (2 * h) for e in np.eye(4)])
    assert np.allclose(J, num, rtol=1e-6, atol=1e-6)
