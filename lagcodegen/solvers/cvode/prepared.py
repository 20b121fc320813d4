"""A prepared native CVODE run of the ODE of a scene (:class:`PreparedCVODERun`): the run of
:func:`.native.solve_native` (no events, no input tables, no sensitivities) with its options
struct made once, so that a call is the driver's C call on the caller's arrays and a
:class:`~lagcodegen.solvers.lazy_result.LazyResult` (the fast path of ``simulate()``,
:mod:`lagcodegen.simulation.fastpath`). Bit-identical to :func:`.native.solve_native` with the
same values: the same driver, options struct and arrays.

Reentrant: each call has its own statistics struct and result arrays; the options struct (from
:func:`.native.ode_options`) is never written."""

from __future__ import annotations

import numpy as np

from ..base import native_stats
from ..control import CANCELLED, raise_pending
from ..lazy_result import ResultMaker, lazy_result
from ..request import StepControl
from .native import ode_struct, run_message


class CVODEResultMaker(ResultMaker):
    """The members of a CVODE run's LazyResult (``raw`` = (stats struct, outputs, parameters))."""

    def __init__(self, ffi, state_names, output_names, param_names):
        super().__init__(state_names, output_names, param_names)
        self.ffi = ffi

    def stats(self, raw) -> dict:
        return native_stats(self.ffi, raw[0])


class PreparedCVODERun:
    """Runs of the ODE of ``cm`` on the native driver with the step control ``control`` (that of
    :func:`.native.solve_native`; ``fixed`` the members every result shares), from the caller's
    checked arrays: ``run(t, t_ptr, y_ptr, p, p_ptr)`` as
    :class:`lagcodegen.solvers.taylor.prepared.PreparedTaylorRun`'s."""

    def __init__(self, cm, control: StepControl, fixed: dict):
        self.opt = ode_struct(cm, control)
        method = control.method
        self.solve = cm.native_solve
        self.ffi = cm.ffi
        self.stats_type = cm.stats_type
        self.ny = cm.ny
        self.nout = cm.code.nout
        empty = np.zeros(1)  # the outputs array of a model without outputs (the driver writes none)
        self.no_out = (empty, cm.ffi.from_buffer("double[]", empty))
        self.fixed = dict(fixed, backend="native", method=method)
        self.maker = CVODEResultMaker(cm.ffi, cm.state_names, cm.output_names, cm.param_names)

    def __call__(self, t: np.ndarray, t_ptr, y_ptr, p: np.ndarray, p_ptr):
        ffi = self.ffi
        fb = ffi.from_buffer
        nt = t.shape[0]
        yout = np.empty((nt, self.ny))
        if self.nout:
            out = np.empty((nt, self.nout))
            out_ptr = fb("double[]", out)
        else:
            out, out_ptr = self.no_out
        st = ffi.new(self.stats_type)
        flag = self.solve(p_ptr, y_ptr, nt, t_ptr, fb("double[]", yout), out_ptr, self.opt, st)
        if flag >= 0 and st.nt_done >= nt:
            return lazy_result(self.maker, (st, out, p), self.fixed, t, yout, flag, "success")
        if flag == CANCELLED:
            raise_pending()  # Ctrl-C during the run: KeyboardInterrupt
        done = st.nt_done
        if done < nt:
            t, yout, out = t[:done].copy(), yout[:done].copy(), out[:done].copy()
        return lazy_result(self.maker, (st, out, p), self.fixed, t, yout, int(flag), run_message(ffi, flag, st))
