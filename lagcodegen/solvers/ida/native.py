"""The native IDA family: the stabilized index-2 GGL form of a constrained system (eq. 4.5;
unknowns q, v, lambda, mu) integrated by the runtime's model-independent driver ``lcg_ida_solve`` on
the model's function table, one call over all output times; lambda and mu are algebraic (IDASetId) and left out of the error test
(IDASetSuppressAlg); IDACalcIC polishes the consistent initial values."""

from __future__ import annotations

import time

import numpy as np

from ...codegen.signatures import IDA_OPTIONS as IDA_STRUCT
from ...codegen.signatures import pack_format
from ...result import Result
from ..base import SINGULAR_AUGMENTED, message, native_stats, pooled_stats, reached_rows
from ..control import CANCELLED, raise_pending
from ..cvode.native import append_event_row
from ..request import GGLForm, Recording, StepControl, option_values

#: Default absolute tolerance of the algebraic GGL unknowns lambda, mu. scikit-sundae never
#: calls IDASetSuppressAlg, so there a huge atol is what keeps them out of the error test. The
#: native driver excludes them from the error test with IDASetSuppressAlg, but IDA's Newton
#: convergence test (and IDACalcIC's) still weighs every component, and in the index-2 system
#: round-off in q reaches lambda amplified by cj^2 = O(1/h^2): with a tight atol on lambda the
#: corrector fails to converge (observed for atol <= 1e-4 at rtol = 1e-10), so the native
#: driver uses the same loose value for lambda, mu by default (``alg_atol``).
ALGEBRAIC_ATOL = 1e8


#: The fields of the IDA driver's options that vary between runs and their pack format
#: (PreparedOptions; the format from the struct's declaration, lagcodegen.codegen.signatures).
_IDA_VARYING = ("rtol", "max_steps", "first_step", "max_step", "min_step", "max_order", "suppress_alg", "jacobian",
                "roots", "stop_at_outputs", "max_wall")
IDA_OPTIONS = (_IDA_VARYING, pack_format(IDA_STRUCT, _IDA_VARYING))


def solve_ggl(sim, t, yy0, yp0, p, control: StepControl, form: GGLForm, recording: Recording) -> Result:
    """A GGL run with the step control ``control`` in the GGL form ``form``: one call of
    ``lcg_ida_solve`` (``sim.c_ida_solve``; ``t``, ``yy0``, ``yp0`` contiguous float64 arrays,
    ``control.atol`` a float or an array of NG values); ``recording.roots``: locate the compiled
    events (at most ``recording.max_events`` kept)."""
    c, roots, suppress_alg = control, recording.roots, form.suppress_alg
    ffi = sim.ffi
    ng, nt = sim.info.ng, t.size
    yout = np.empty((nt, ng))  # rows past st.nt_done are cut off below
    out = np.empty((nt, sim.n_out_columns))
    opt = sim.ida_options.get(c.atol, *option_values(IDA_STRUCT, _IDA_VARYING, c, form, recording))
    pool = sim.ida_stats_pool
    st = pooled_stats(ffi, pool, sim.ida_stats_type)
    events = sim.native_events(recording.max_events) if roots else None
    fb, darr = ffi.from_buffer, sim._double_array
    try:
        start = time.perf_counter()
        flag = sim.c_ida_solve(sim.c_params(p), fb(darr, yy0), fb(darr, yp0), nt, fb(darr, t),
                               fb(darr, yout), fb(darr, out), opt, st,
                               events.struct if events else ffi.NULL)
        wall = time.perf_counter() - start
        if flag == CANCELLED:
            raise_pending()
        recs = events.records(sim.state_names, sim.ny) if events else []
        tt, yy, oo = reached_rows(t, yout, out, st.nt_done)
        if events and events.terminated and recs:
            row = events.y[events.count - 1]
            tt, yy, oo = append_event_row(sim, tt, yy, oo, recs[-1].t, row, p, lam=row[sim.ny: sim.ny + sim.info.J])
    finally:
        if events:
            sim.release_events(events)
    stats = native_stats(ffi, st)
    stats["suppress_alg"] = suppress_alg
    stats["wall_time"] = wall
    text = "success" if flag >= 0 else message(flag, st.model_error, ffi.string(st.message).decode(errors="replace"),
                                               "IDA", SINGULAR_AUGMENTED)
    if st.ic_flag < 0:
        text = "IDACalcIC found no consistent lambda, y': " + text
    pool.append(st)
    outputs = dict(zip(sim.info.output_names, oo.T))  # column views
    outputs.update(sim.ggl_multiplier_outputs(yy, copy=False))
    return Result(t=tt, y=yy[:, : sim.ny], state_names=sim.state_names, outputs=outputs, stats=stats,
                  status=int(flag), backend="native", method="bdf", message=text, events=recs)
