"""cffi declarations of the generated functions and drivers, one function per kind of generated
code. The structs come from their one declaration (:mod:`.signatures`: every field, so that cffi
checks each layout against the compiled header); the functions are the headers' prototypes."""

from __future__ import annotations

from .record import GeneratedCode
from .signatures import (DAE_TABLE, DRIVERS, MODEL_TABLE, TAYLOR_TABLE, c_signature, cffi_struct)

#: The Python function the drivers call back while a run is long (progress, Ctrl-C): one per module.
POLL_CDEF = 'extern "Python" int lcg_poll(void *data, long done, long total);'


def driver_cdef(name: str) -> str:
    """The structs of the driver ``name`` (:data:`~.signatures.DRIVERS`), as cffi declarations."""
    return "\n".join(cffi_struct(s) for s in DRIVERS[name].structs)


def _solve_many(driver: str) -> str:
    return f"int lcg_{driver}_solve_many(lcg_{driver}_ensemble *e, const lcg_{driver}_options *opt);"


#: The function table of a compiled model (lcg_model.h).
MODEL_TABLE_CDEF = cffi_struct(MODEL_TABLE)
#: The function table of a compiled constrained model (lcg_dae_model.h) and the events record of
#: its drivers.
DAE_TABLE_CDEF = cffi_struct(DAE_TABLE) + "\n" + driver_cdef("dae")


def constrained_runtime_cdef() -> str:
    """The constrained drivers of the runtime: the index-1 CVODE driver (lcg_cvc.h) with the
    initial state in one call, the GGL IDA driver (lcg_ida.h), their ensembles."""
    return "\n".join([DAE_TABLE_CDEF, driver_cdef("cvc"), """
int lcg_cvc_solve(const lcg_dae_model *m, const double *p, const double *y0, int nt, const double *tout,
                  double *yout, double *out, const lcg_cvc_options *opt, lcg_cvc_stats *st, lcg_events *ev);
int lcg_dae_initial_state(const lcg_dae_model *m, double t, const double *y, const double *p, int mode, double tol,
                          int nineq, double *yy, double *yp);
int lcg_dae_check(const lcg_dae_model *m, char *message, size_t size);""", _solve_many("cvc"),
                      driver_cdef("ida"), """
int lcg_ida_solve(const lcg_dae_model *m, const double *p, const double *yy0, const double *yp0, int nt,
                  const double *tout, double *yout, double *out, const lcg_ida_options *opt, lcg_ida_stats *st,
                  lcg_events *ev);""", _solve_many("ida")])


def runtime_cdef() -> str:
    """The model-independent runtime module: the model table, the CVODE driver taking it
    (lcg_cvode.h), its ensembles, the batch of outputs, the constrained drivers
    (:func:`constrained_runtime_cdef`) and the poll callback."""
    return "\n".join([MODEL_TABLE_CDEF, driver_cdef("inputs"), driver_cdef("cvode"), """
int lcg_cvode_solve(const lcg_model *m, const double *p, const double *y0, int nt, const double *tout,
                    double *yout, double *out, const lcg_cvode_options *opt, lcg_cvode_stats *st);
int lcg_outputs_batch(const lcg_model *m, int nt, const double *t, const double *y, const double *p,
                      double *out);""", _solve_many("cvode"), constrained_runtime_cdef(), """
int lcg_cvode_solve_events(const lcg_model *m, const lcg_ode_roots *r, const double *p, const double *y0, int nt,
                           const double *tout, double *yout, double *out, const lcg_cvode_options *opt,
                           lcg_cvode_stats *st, lcg_events *ev);
int lcg_cvode_solve_inputs(const lcg_model *m, const double *p, const lcg_inputs *in, const double *y0, int nt,
                           const double *tout, double *yout, double *out, const lcg_cvode_options *opt,
                           lcg_cvode_stats *st);""", POLL_CDEF])


def model_cdef(code: GeneratedCode, native: bool) -> str:
    """The model functions of ``code`` (:data:`~.signatures.MODEL_FUNCTIONS`, the header's own
    signatures) for a module of its own (code with further drivers, or built without SUNDIALS);
    with ``native``, the poll callback of its drivers."""
    p = code.prefix
    names = ["rhs"] + ["jac"] * code.jacobian + ["outputs"] * bool(code.nout)
    names += ["jac_sparse"] * bool(getattr(code, "sparse_jacobian", False))
    lines = [c_signature(name, p) + ";" for name in names]
    if native:
        lines.append(POLL_CDEF)
    return "\n".join(lines)


#: The table of a model's Taylor jet (lcg_taylor_model.h, templates/taylor/lcg_taylor_model.h.j2).
TAYLOR_TABLE_CDEF = "#define LCG_TAYLOR_ABI ...\n#define LCG_TAYLOR_ORDER_MAX ...\n" + cffi_struct(TAYLOR_TABLE)


def taylor_runtime_cdef() -> str:
    """The model-independent Taylor runtime module: the jet table, the Taylor driver taking it
    (lcg_taylor.h), its ensembles and the poll callback."""
    return "\n".join([TAYLOR_TABLE_CDEF, driver_cdef("taylor"), """
int lcg_taylor_solve(const lcg_taylor_model *m, const double *p, const double *y0, int nt, const double *tout,
                     double *yout, double *out, const lcg_taylor_options *opt, lcg_taylor_stats *st,
                     lcg_taylor_events *ev);
int lcg_taylor_jet(const lcg_taylor_model *m, double t, const double *y, const double *p, int order,
                   double *jet);""", _solve_many("taylor"), POLL_CDEF])
