"""A prepared Taylor run with forward sensitivities (:class:`PreparedTaylorSensitivityRun`): the
run of :meth:`.sensitivity.VariationalModule.simulate` with its variational jet found and its
own options struct made once, so that a call is the Taylor driver's C call on the augmented
system and a :class:`~lagcodegen.solvers.lazy_result.LazyResult` carrying the sensitivities (the
fast path of ``simulate(method="taylor", sensitivities=[...])``,
:mod:`lagcodegen.simulation.fastpath`). Bit-identical to
:meth:`~.sensitivity.VariationalModule.simulate` with the same values: the same driver, table,
options and arrays.

Reentrant: each call has its own statistics struct, initial vector and result arrays; the
options struct is never written once made."""

from __future__ import annotations

import time

import numpy as np

from ..control import CANCELLED, POLL_EVERY, install, raise_pending
from ..lazy_result import ResultMaker, lazy_result
from .runner import message
from .sensitivity import VariationalModule, sens_stats


class TaylorSensitivityResultMaker(ResultMaker):
    """The members of a Taylor sensitivity run's LazyResult (``raw`` = (stats struct, outputs,
    parameters, wall time)): the statistics as :meth:`VariationalModule.simulate` reports them."""

    def stats(self, raw) -> dict:
        return sens_stats(raw[0], raw[3])


class PreparedTaylorSensitivityRun:
    """Runs of the variational jet ``module`` with the options given, from the caller's checked
    arrays: ``run(t, t_ptr, y_ptr, p, p_ptr)`` as
    :class:`lagcodegen.solvers.taylor.prepared.PreparedTaylorRun`'s (the cdata of the caller's
    model, read here for the initial state of the augmented system). ``atol``: a scalar or ny
    values."""

    def __init__(self, module: VariationalModule, *, rtol: float, atol, errcon: bool, max_step: float,
                 max_steps: int, order: int | None, max_wall: float, fixed: dict, model_ffi, param_names):
        rt = module.rt
        self.module, self.ffi, self.model_ffi = module, rt.ffi, model_ffi
        self.ny, self.ns, self.nout = module.ny, module.ns, module.nout
        self._atol = module.tolerances(atol, errcon)
        opt = self.opt = rt.ffi.new("lcg_taylor_options *")
        opt.poll = install(rt)
        opt.poll_every = POLL_EVERY
        opt.rtol = rtol
        opt.atol = float(self._atol[:module.ny].min())
        opt.atol_vec = rt.ffi.from_buffer("double[]", self._atol)
        opt.max_steps = int(max_steps)
        opt.max_step = float(max_step)
        opt.order = int(order or 0)
        opt.rel_block = module.ny  # each direction's sensitivities: one block of the step-size rule
        opt.max_wall = float(max_wall)
        self._s0 = np.ascontiguousarray(np.concatenate([np.zeros(module.ny), module.s0.ravel()]))
        self.values = module.state_names + module.output_names
        self.fixed = dict(fixed, backend="native", method="taylor")
        self.maker = TaylorSensitivityResultMaker(module.state_names, module.output_names, param_names)

    def __call__(self, t: np.ndarray, t_ptr, y_ptr, p: np.ndarray, p_ptr):
        ffi, module = self.ffi, self.module
        fb = ffi.from_buffer
        ny, ns, nout = self.ny, self.ns, self.nout
        nt = t.shape[0]
        y0v = self._s0.copy()
        y0v[:ny] = self.model_ffi.unpack(y_ptr, ny)
        if module.rotations:  # a rotation of a quaternion joint: its s0 at this run's initial state
            y0v[ny:] = module.initial_sensitivities(y0v[:ny], t[0], p).ravel()
        yout = np.empty((nt, ny * (1 + ns)))
        out = np.empty((nt, max(nout * (1 + ns), 1)))
        st = ffi.new("lcg_taylor_stats *")
        start = time.perf_counter()
        flag = module.rt.lib.lcg_taylor_solve(module.table, fb("double[]", p) if p.size else ffi.NULL,
                                              fb("double[]", y0v), nt, t_ptr, fb("double[]", yout),
                                              fb("double[]", out), self.opt, st, ffi.NULL)
        wall = time.perf_counter() - start
        if flag == CANCELLED:
            raise_pending()  # Ctrl-C during the run: KeyboardInterrupt
        done = min(int(st.nt_done), nt)
        text = "success" if flag == 0 else message(flag, st.model_error,
                                                   ffi.string(st.message).decode(errors="replace"))
        if done < nt:
            t, yout, out = t[:done].copy(), yout[:done], out[:done]
        res = lazy_result(self.maker, (st, out[:, :nout], p, wall), self.fixed, t, yout[:, :ny].copy(), flag, text)
        s = yout[:, ny:].reshape(done, ns, ny)
        ds = out[:, nout:nout * (1 + ns)].reshape(done, ns, nout)
        res.set_sensitivities(module.names, self.values, np.concatenate([s, ds], axis=2))
        return res
