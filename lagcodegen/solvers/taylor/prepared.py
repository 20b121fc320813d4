"""A prepared Taylor run (:class:`PreparedTaylorRun`): the run of :meth:`.runner.TaylorModule.simulate`
with its options fixed once (its own options struct, made when prepared), so that a call is the
driver's C call on the caller's arrays and a :class:`~lagcodegen.solvers.lazy_result.LazyResult`
(the fast path of ``simulate()``, :mod:`lagcodegen.simulation.fastpath`). Bit-identical to
:meth:`~.runner.TaylorModule.simulate` with the same values: the same driver, options and arrays.

Reentrant: each call has its own statistics struct and result arrays; the options struct is
never written once made."""

from __future__ import annotations

import numpy as np

from ..control import CANCELLED, raise_pending
from ..lazy_result import ResultMaker, lazy_result
from .runner import TaylorModule, message, run_stats

_empty = np.empty


class TaylorResultMaker(ResultMaker):
    """The members of a Taylor run's LazyResult (``raw`` = (stats struct, outputs, parameters))."""

    def stats(self, raw) -> dict:
        return run_stats(raw[0])


class PreparedTaylorRun:
    """Runs of ``module`` with the options given, from the caller's checked arrays:
    ``run(t, t_ptr, y_ptr, p, p_ptr)`` with ``t`` contiguous increasing float64 times, ``y_ptr``
    the cdata of ny finite initial values, ``p`` the parameters, and ``*_ptr`` the cdata of each
    (``p_ptr`` NULL without parameters).
    ``fixed``: the members every result shares (backend, method, n_coordinates, model_name,
    drawing). A module with events records them as its own runs do (at most ``max_events``, an
    events struct of its pool per run)."""

    def __init__(self, module: TaylorModule, *, rtol: float, atol, max_step: float, max_steps: int,
                 order: int | None, max_wall: float, fixed: dict, max_events: int = 10_000):
        self.module = module
        self.events, self.max_events = bool(module.events), max_events
        self.opt, self._atol = module.options_struct(rtol=rtol, atol=atol, max_step=max_step, max_steps=max_steps,
                                                     order=order, max_wall=max_wall)
        self.fixed = dict(fixed, backend="native", method="taylor")
        self.maker = TaylorResultMaker(module.state_names, module.output_names, module.param_names)
        self.ffi = ffi = module.ffi
        self.null = ffi.NULL
        self.fb, self.new = ffi.from_buffer, ffi.new  # bound once (a call uses each)
        self.solve = module._solve
        self.ny, self.nout, self.stats_type = module.ny, module.nout, module.types[1]
        self.no_out = module._no_out  # the outputs placeholder of a model without outputs (never written)

    def _arrays(self, nt: int):
        """The run's rows, outputs (and their cdata) and statistics struct."""
        yout = _empty((nt, self.ny))
        if self.nout:
            out = _empty((nt, self.nout))
            out_ptr = self.fb("double[]", out)
        else:
            out, out_ptr = self.no_out
        return yout, out, out_ptr, self.new(self.stats_type)

    def _finish(self, flag: int, st, t: np.ndarray, yout: np.ndarray, out: np.ndarray, p: np.ndarray):
        """The result of a run that stopped early or failed (Ctrl-C raised here)."""
        if flag == CANCELLED:
            raise_pending()  # Ctrl-C during the run: KeyboardInterrupt
        done = st.nt_done
        if done < t.shape[0]:
            t, yout, out = t[:done].copy(), yout[:done], out[:done]
        text = "success" if flag == 0 else message(flag, st.model_error,
                                                   self.ffi.string(st.message).decode(errors="replace"))
        return lazy_result(self.maker, (st, out, p), self.fixed, t, yout, flag, text)

    def __call__(self, t: np.ndarray, t_ptr, y_ptr, p: np.ndarray, p_ptr):
        if self.events:
            return self._with_events(t, t_ptr, y_ptr, p, p_ptr)
        nt = t.shape[0]
        yout, out, out_ptr, st = self._arrays(nt)
        flag = self.solve(p_ptr, y_ptr, nt, t_ptr, self.fb("double[]", yout), out_ptr, self.opt, st, self.null)
        if flag == 0 and st.nt_done >= nt:
            return lazy_result(self.maker, (st, out, p), self.fixed, t, yout, 0, "success")
        return self._finish(flag, st, t, yout, out, p)

    def _with_events(self, t: np.ndarray, t_ptr, y_ptr, p: np.ndarray, p_ptr):
        """A run with the module's events: the events struct from its pool, the records into the
        result and the struct back (:meth:`.runner.TaylorModule.simulate`'s way)."""
        module = self.module
        nt = t.shape[0]
        yout, out, out_ptr, st = self._arrays(nt)
        ev, keep = module._events_struct(self.max_events)
        flag = self.solve(p_ptr, y_ptr, nt, t_ptr, self.fb("double[]", yout), out_ptr, self.opt, st, ev)
        res = self._finish(flag, st, t, yout, out, p)
        module._events_into(res, ev, keep, p)
        module._ev_pool.append((ev, keep))  # read out: the next run may fill it
        return res
