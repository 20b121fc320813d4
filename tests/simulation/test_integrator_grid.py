"""Integrator.propagate_grid with the caller's preallocated arrays: the cdata of the times and out
arrays are kept while the same arrays come back, so values written into them in place between
calls must be what the C code reads and writes."""

import numpy as np
import pytest

import lagcodegen as lcg
from lagcodegen import LagcodegenError, systems


@pytest.fixture(scope="module")
def pendulum():
    return lcg.compile_model(systems.pendulum())


@pytest.mark.parametrize("method", ["taylor", "adams"])
def test_reused_arrays_give_the_rows_of_new_arrays(pendulum, method):
    opts = dict(q0=[1.2], method=method, rtol=1e-10, atol=1e-10)
    offsets = np.linspace(0.05, 0.5, 10)
    times, rows = np.empty(10), np.empty((10, 2))
    with pendulum.integrator(**opts) as a, pendulum.integrator(**opts) as b:
        for _ in range(6):
            np.add(a.time, offsets, out=times)
            got = a.propagate_grid(times, out=rows)
            assert got is rows
            np.testing.assert_array_equal(rows, b.propagate_grid(b.time + offsets))
        assert a.time == b.time == pytest.approx(3.0)
        # the same run by simulate(): the grid's last row is its state at t = 3
        ref = pendulum.simulate(np.array([0.0, 3.0]), **opts)
        np.testing.assert_allclose(rows[-1], ref.y[-1], rtol=0, atol=1e-8)
        # the pendulum's energy (1 - cos q) g/l + v^2/2 is conserved along the reused rows
        g = 9.81
        energy = g * (1 - np.cos(rows[:, 0])) + rows[:, 1] ** 2 / 2
        assert np.ptp(energy) < 1e-7


def test_out_of_another_shape_or_layout_is_refused(pendulum):
    with pendulum.integrator(q0=[0.3], method="taylor") as integ, \
            pendulum.integrator(q0=[0.3], method="taylor") as ref:
        times = np.array([0.1, 0.2])
        out = np.empty((2, 2))
        integ.propagate_grid(times, out=out)
        ref.propagate_grid([0.1, 0.2])
        with pytest.raises(LagcodegenError, match="shape"):
            integ.propagate_grid(times + 0.2, out=np.empty((3, 2)))
        with pytest.raises(LagcodegenError, match="C-contiguous"):
            integ.propagate_grid(times + 0.2, out=np.empty((2, 2), order="F"))
        with pytest.raises(LagcodegenError, match="float64"):
            integ.propagate_grid(times + 0.2, out=np.empty((2, 2), dtype=np.float32))
        strided = np.array([0.3, 0.0, 0.4])[::2]  # not contiguous: converted
        assert integ.propagate_grid(strided, out=out) is out
        np.testing.assert_array_equal(out, ref.propagate_grid([0.3, 0.4]))
        assert integ.time == ref.time == 0.4
