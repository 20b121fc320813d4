"""Every wrapper that hands memory to C checks lengths and dtypes first (issue 13): a wrong
array is a LagcodegenError naming the expected length and the entries, never a read past a
buffer; integer arrays are converted, never reinterpreted as doubles' bits."""

import numpy as np
import pytest

import lagcodegen as lcg
from lagcodegen import LagcodegenError
from lagcodegen.api import compile_constrained

from helpers import cartesian_pendulum, pendulum_q0


@pytest.fixture(scope="module")
def dp():
    return lcg.compile_model(lcg.systems.double_pendulum(), outputs=["energy"])


@pytest.fixture(scope="module")
def cp():
    return compile_constrained(cartesian_pendulum("cp_wrap"), "ggl")


BAD = [np.zeros(0), np.zeros(3), np.zeros(5), None, "abc", np.zeros((2, 3)), [1.0, 2.0 + 1j, 0.0, 0.0]]


@pytest.mark.parametrize("bad", BAD, ids=["empty", "short", "long", "none", "text", "matrix", "complex"])
@pytest.mark.parametrize("fn", ["rhs", "jac", "outputs"])
def test_model_wrappers_refuse_wrong_state_arrays(dp, fn, bad):
    with pytest.raises(LagcodegenError, match=r"y (has \d+ values, expected 4|must be an array of 4)"):
        getattr(dp, fn)(0.0, bad)


@pytest.mark.parametrize("fn", ["rhs", "jac", "outputs"])
def test_model_wrappers_refuse_wrong_parameter_arrays_and_convert_integers(dp, fn):
    y = [0.3, -0.2, 0.1, 0.0]
    with pytest.raises(LagcodegenError, match=r"p has 1 values, expected %d \(" % dp.code.np):
        getattr(dp, fn)(0.0, y, [1.0])
    as_float = getattr(dp, fn)(0.0, y, dp.parameter_vector())
    as_int = getattr(dp, fn)(0.0, np.array(y), dp.parameter_vector().round().astype(int))
    rounded = getattr(dp, fn)(0.0, y, dp.parameter_vector().round())
    np.testing.assert_array_equal(as_int, rounded)  # read as values, not as the bits of int64
    assert np.all(np.isfinite(as_float))


def test_constrained_wrappers_check_every_array(cp):
    y = np.concatenate([pendulum_q0(), [0.0, 0.0]])
    for call in (lambda v: cp.kkt(0.0, v), lambda v: cp.residuals(0.0, v), lambda v: cp.project(0.0, v),
                 lambda v: cp.outputs(0.0, v), lambda v: cp.roots(0.0, v)):
        for bad in (np.zeros(0), np.zeros(3), None):
            with pytest.raises(LagcodegenError, match="y"):
                call(bad)
    with pytest.raises(LagcodegenError, match="lam has 2 values, expected 1"):
        cp.outputs(0.0, y, lam=[1.0, 2.0])
    ng = cp.info.ng
    yy, yp = np.zeros(ng), np.zeros(ng)
    with pytest.raises(LagcodegenError, match=f"yy has 2 values, expected {ng}"):
        cp.ggl_residual(0.0, np.zeros(2), yp)
    with pytest.raises(LagcodegenError, match=f"yp has 1 values, expected {ng}"):
        cp.ggl_jacobian(0.0, 1.0, yy, np.zeros(1))
    with pytest.raises(LagcodegenError, match="params has 1 values"):
        cp.kkt(0.0, y, np.array([1.0]))
    acc, lam = cp.kkt(0.0, y)
    assert np.all(np.isfinite(acc)) and lam.shape == (1,)
