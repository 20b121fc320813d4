"""The native IDA family: the stabilized index-2 GGL form of a constrained system (eq. 4.5;
unknowns q, v, lambda, mu) integrated by the generated driver ``<prefix>_ida_solve``, one call
over all output times; lambda and mu are algebraic (IDASetId) and left out of the error test
(IDASetSuppressAlg); IDACalcIC polishes the consistent initial values."""

from __future__ import annotations

import time

import numpy as np

from ..result import Result
from .base import SINGULAR_AUGMENTED, NativeEvents, message, native_options, native_stats
from .control import CANCELLED, POLL_EVERY, raise_pending
from .cvode import append_event_row

#: Default absolute tolerance of the algebraic GGL unknowns lambda, mu. scikit-sundae never
#: calls IDASetSuppressAlg, so there a huge atol is what keeps them out of the error test. The
#: native driver excludes them from the error test with IDASetSuppressAlg, but IDA's Newton
#: convergence test (and IDACalcIC's) still weighs every component, and in the index-2 system
#: round-off in q reaches lambda amplified by cj^2 = O(1/h^2): with a tight atol on lambda the
#: corrector fails to converge (observed for atol <= 1e-4 at rtol = 1e-10), so the native
#: driver uses the same loose value for lambda, mu by default (``alg_atol``).
ALGEBRAIC_ATOL = 1e8


def solve_ggl(sim, t, yy0, yp0, p, rtol, atol, suppress_alg, jacobian, roots, max_events, max_steps,
              first_step, max_step, min_step, max_order, stop_at_outputs, max_wall=0.0) -> Result:
    ffi, pre = sim.ffi, sim.info.prefix
    ng, nt, nout, n = sim.info.ng, t.size, len(sim.info.output_names), sim.n
    yout = np.full((nt, ng), np.nan)
    out = np.full((nt, max(nout, 1)), np.nan)
    keep: list = []
    opt = native_options(ffi, f"{pre}_ida_options", atol, keep, rtol=rtol, max_steps=int(max_steps),
                         first_step=first_step, max_step=max_step, min_step=min_step, max_order=max_order,
                         suppress_alg=int(suppress_alg), jacobian=int(jacobian), calc_ic=1,
                         ic_alg_atol=ALGEBRAIC_ATOL, roots=int(roots), stop_at_outputs=int(stop_at_outputs),
                         poll=sim.compiled.poll, poll_every=POLL_EVERY, max_wall=max_wall)
    st = ffi.new(f"{pre}_ida_stats *")
    events = NativeEvents(ffi, pre, sim.info.events, ng, max_events) if roots else None
    start = time.perf_counter()
    flag = getattr(sim.lib, f"{pre}_ida_solve")(sim.c_params(p), ffi.from_buffer("double[]", yy0),
                                                ffi.from_buffer("double[]", yp0), nt, ffi.from_buffer("double[]", t),
                                                ffi.from_buffer("double[]", yout), ffi.from_buffer("double[]", out),
                                                opt, st, events.struct if events else ffi.NULL)
    wall = time.perf_counter() - start
    if flag == CANCELLED:
        raise_pending()
    recs = events.records(sim.state_names, 2 * n) if events else []
    done = st.nt_done
    tt, yy, oo = t[:done].copy(), yout[:done].copy(), out[:done].copy()
    if events and events.terminated and recs:
        row = events.y[events.count - 1]
        tt, yy, oo = append_event_row(sim, tt, yy, oo, recs[-1].t, row, p, lam=row[2 * n: 2 * n + sim.info.J])
    stats = native_stats(ffi, st)
    stats.update(suppress_alg=suppress_alg, wall_time=wall)
    detail = ffi.string(st.message).decode(errors="replace")
    outputs = {k: oo[:, i].copy() for i, k in enumerate(sim.info.output_names)}
    outputs.update(sim.ggl_multiplier_outputs(yy))
    res = Result(t=tt, y=yy[:, : 2 * n].copy(), state_names=list(sim.state_names), outputs=outputs,
                 stats=stats, status=int(flag), backend="native", method="bdf",
                 message=("IDACalcIC found no consistent lambda, y': " if st.ic_flag < 0 else "")
                 + message(flag, st.model_error, detail, "IDA", SINGULAR_AUGMENTED))
    res.events = recs
    return res
