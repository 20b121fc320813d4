"""A prepared native CVODE run with forward sensitivities (:class:`PreparedSensitivityRun`): the
run of :func:`.sensitivity.solve_sensitivities` (no events) with its directions parsed, the
sensitivity functions found and the driver's options struct made once, so that a call is the
driver's C call and a :class:`~lagcodegen.solvers.lazy_result.LazyResult` carrying the
sensitivities (the fast path of ``simulate(..., sensitivities=[...])``,
:mod:`lagcodegen.simulation.fastpath`). Bit-identical to :func:`.sensitivity.solve_sensitivities`
with the same values: the same driver, options and arrays.

Reentrant: each call has its own statistics struct and result arrays; the options struct is
never written once made."""

from __future__ import annotations

import time

import numpy as np

from ..control import CANCELLED, raise_pending
from ..lazy_result import ResultMaker, lazy_result
from ..request import StepControl
from .sensitivity import directions, functions, message, rotation_directions, sens_options, sens_stats


class SensitivityResultMaker(ResultMaker):
    """The members of a sensitivity run's LazyResult (``raw`` = (stats struct, outputs,
    parameters, wall time))."""

    def stats(self, raw) -> dict:
        st = raw[0]
        stats = sens_stats(st)
        stats["wall_time"] = raw[3]
        return stats


class PreparedSensitivityRun:
    """Runs of the ODE of ``cm`` with the sensitivities ``names`` on the native driver, with the
    step control ``control`` (that of :func:`.sensitivity.solve_sensitivities`; ``fixed`` the
    members every result shares), from the caller's checked
    arrays: ``run(t, t_ptr, y_ptr, p, p_ptr)`` as
    :class:`lagcodegen.solvers.cvode.prepared.PreparedCVODERun`'s."""

    def __init__(self, cm, names, control: StepControl, fixed: dict):
        method = control.method
        self.names, which, s0 = directions(cm, names, defer=True)
        # Rotations of a quaternion (general_directions): their s0 depends on each run's initial state.
        self.cm = cm
        self.rotations = rotation_directions(cm, self.names)
        self.fns = fns = functions(cm)
        self.ffi = ffi = fns.rt.ffi
        self.ns, self.ny, self.nout = len(self.names), cm.ny, cm.code.nout
        self.opt, self._atol = sens_options(ffi, fns.poll, control, cm.ny, self.ns)
        self._which = np.ascontiguousarray(which)
        self._s0 = np.ascontiguousarray(s0)
        self.which_ptr = ffi.from_buffer("int[]", self._which)
        self.s0_ptr = ffi.from_buffer("double[]", self._s0)
        self.values = list(cm.state_names) + list(cm.output_names)
        self.fixed = dict(fixed, backend="native", method=method)
        self.maker = SensitivityResultMaker(cm.state_names, cm.output_names, cm.param_names)

    def __call__(self, t: np.ndarray, t_ptr, y_ptr, p: np.ndarray, p_ptr):
        ffi, fns = self.ffi, self.fns
        fb = ffi.from_buffer
        nt, ns, ny, nout = t.shape[0], self.ns, self.ny, self.nout
        yout = np.empty((nt, ny))
        sout = np.empty((nt, ns, ny))
        out = np.empty((nt, max(nout, 1)))
        dout = np.empty((nt, ns, max(nout, 1)))
        st = ffi.new("lcg_cvsens_stats *")
        if self.rotations:  # the rotations' s0 at this run's initial state
            y0 = np.array(ffi.unpack(ffi.cast("double *", y_ptr), ny))
            self._s0[:] = directions(self.cm, self.names, y0, float(t[0]), p)[2]
        start = time.perf_counter()
        flag = fns.rt.lib.lcg_cvsens_solve(fns.table, fns.rhs, fns.out, p_ptr, ns, self.which_ptr, y_ptr,
                                           self.s0_ptr, nt, t_ptr, fb("double[]", yout), fb("double[]", sout),
                                           fb("double[]", out), fb("double[]", dout), self.opt, st)
        wall = time.perf_counter() - start
        if flag == CANCELLED:
            raise_pending()  # Ctrl-C during the run: KeyboardInterrupt
        done = st.nt_done
        if flag >= 0:
            text = "success"
        else:
            text = message(flag, st.model_error, ffi.string(st.message).decode(errors="replace"), t=st.t_reached)
        if done < nt:
            t, yout, out, sout, dout = t[:done].copy(), yout[:done], out[:done], sout[:done], dout[:done]
        res = lazy_result(self.maker, (st, out, p, wall), self.fixed, t, yout, int(flag), text)
        res.set_sensitivities(self.names, self.values, np.concatenate([sout, dout[:, :, :nout]], axis=2))
        return res
