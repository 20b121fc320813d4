"""cffi declarations of the generated functions and drivers (API mode: struct layouts come
from the headers through ``...;``), one function per kind of generated code."""

from __future__ import annotations

from .record import GeneratedCode
from .signatures import c_signature

#: The run-control fields at the end of every native driver's options struct
#: (templates/c/_control.j2, option_fields).
CONTROL_FIELDS = ("int *cancel; int (*poll)(void *data, long done, long total); void *poll_data; "
                  "double poll_every; double max_wall;")
#: The Python function the drivers call back while a run is long (progress, Ctrl-C): one per module.
POLL_CDEF = 'extern "Python" int lcg_poll(void *data, long done, long total);'


def ensemble_cdef(name: str, options: str, fn: str, yp0: bool = False, events: bool = False,
                  model: bool | str = False) -> str:
    """The ensemble struct ``name`` of a driver and its solve-many function ``fn``
    (templates/c/_control.j2, ensemble_struct and pool; ``model``: the model-independent driver's
    field with the model's function table, of type ``model`` if a string, else ``lcg_model``)."""
    extra = "const double *yp0; long yp0_stride;" if yp0 else ""
    ev = "int max_events; const int *rootdir; const int *terminal;" if events else ""
    table = f"const {model if isinstance(model, str) else 'lcg_model'} *model;" if model else ""
    return f"""
typedef struct {{
    {table} long nmem; int nthreads; const double *p; long p_stride; const double *y0; long y0_stride; {extra}
    int nt; const double *tout; double *final; double *traj; int ncol; const int *col; int *flag; int *nt_done;
    double *t_reached; double *wall; long *counts; char *messages; long max_messages; long *message_member;
    long n_messages; {ev} int (*poll)(void *data, long done, long total); void *poll_data; double poll_every;
    int cancel; long done; long next; ...;
}} {name};
int {fn}({name} *e, const {options} *opt);"""


#: The function table of a compiled model (templates/c/lcg_model.h.j2).
MODEL_TABLE_CDEF = """
typedef struct lcg_model {
    int abi; int nq; int nz; int ny; int np; int nout;
    int (*rhs)(double t, const double *y, const double *p, double *ydot);
    int (*jac)(double t, const double *y, const double *ydot, const double *p, double *jac);
    int (*outputs)(double t, const double *y, const double *p, double *out);
    int (*jac_sparse)(double t, const double *y, const double *ydot, const double *p, double *vals);
    int jac_nnz; const int *jac_colptr; const int *jac_rowind;
    ...;
} lcg_model;"""


#: The function table of a compiled constrained model and the events record of its drivers
#: (templates/c/lcg_dae_model.h.j2).
DAE_TABLE_CDEF = """
typedef struct lcg_dae_model {
    int abi; int nq; int ny; int nj; int njh; int ng; int np; int nout; int nroot;
    int (*kkt)(double t, const double *y, const double *p, double alpha, double beta, double *acc, double *lam);
    int (*crhs)(double t, const double *y, const double *p, double alpha, double beta, double *ydot);
    int (*natural_rate)(double t, const double *y, const double *p, double *rate);
    int (*residuals)(double t, const double *y, const double *p, double *g, double *s);
    int (*project)(double t, const double *y, const double *p, double tol, int maxit, double *ynew, double *err);
    int (*coutputs)(double t, const double *y, const double *lam, const double *p, double *out);
    int (*roots)(double t, const double *y, const double *lam, const double *p, double *gout);
    int (*ggl_res)(double t, const double *yy, const double *yp, const double *p, double *rr);
    int (*ggl_jac)(double t, double cj, const double *yy, const double *yp, const double *p, double *jac);
    const lcg_model *model;
    ...;
} lcg_dae_model;
typedef struct {
    int max_events; int n_events; double *t; double *y; int *which; int *direction;
    const int *rootdir; const int *terminal; int terminated; ...;
} lcg_events;"""


def constrained_runtime_cdef() -> str:
    """The constrained drivers of the runtime: the index-1 CVODE driver (templates/c/lcg_cvc.h.j2)
    with the initial state in one call, the GGL IDA driver (lcg_ida.h.j2), their ensembles."""
    return "\n".join([DAE_TABLE_CDEF, f"""
typedef struct {{
    int method; double rtol; double atol; const double *atol_vec; long max_steps; double first_step;
    double max_step; double min_step; int max_order; double alpha; double beta; int projection;
    double proj_tol; int proj_maxit; int proj_err; int roots; {CONTROL_FIELDS} ...;
}} lcg_cvc_options;
typedef struct {{
    long nsteps, nrhs, nrhs_dq, njac, nlinsetups, netfails, nniters, nncfails, nproj, nprojfails, ngevals;
    double t_reached; double h_last; double alpha; double beta; int flag; int model_error; int nt_done;
    char message[512]; ...;
}} lcg_cvc_stats;
int lcg_cvc_solve(const lcg_dae_model *m, const double *p, const double *y0, int nt, const double *tout,
                  double *yout, double *out, const lcg_cvc_options *opt, lcg_cvc_stats *st, lcg_events *ev);
int lcg_dae_initial_state(const lcg_dae_model *m, double t, const double *y, const double *p, int mode, double tol,
                          int nineq, double *yy, double *yp);
int lcg_dae_check(const lcg_dae_model *m, char *message, size_t size);""",
                      ensemble_cdef("lcg_cvc_ensemble", "lcg_cvc_options", "lcg_cvc_solve_many", events=True,
                                    model="lcg_dae_model"), f"""
typedef struct {{
    double rtol; double atol; const double *atol_vec; long max_steps; double first_step; double max_step;
    double min_step; int max_order; int suppress_alg; int jacobian; int calc_ic; double ic_alg_atol; int roots;
    int stop_at_outputs; {CONTROL_FIELDS} ...;
}} lcg_ida_options;
typedef struct {{
    long nsteps, nres, nres_dq, njac, nlinsetups, netfails, nniters, nncfails, nbacktracks, ngevals;
    double t_reached; double h_last; int flag; int ic_flag; int model_error; int nt_done; char message[512]; ...;
}} lcg_ida_stats;
int lcg_ida_solve(const lcg_dae_model *m, const double *p, const double *yy0, const double *yp0, int nt,
                  const double *tout, double *yout, double *out, const lcg_ida_options *opt, lcg_ida_stats *st,
                  lcg_events *ev);""", ensemble_cdef("lcg_ida_ensemble", "lcg_ida_options", "lcg_ida_solve_many",
                                                   yp0=True, events=True, model="lcg_dae_model")])


def runtime_cdef() -> str:
    """The model-independent runtime module: the model table, the CVODE driver taking it
    (templates/c/lcg_cvode.h.j2), its ensembles, the batch of outputs, the constrained drivers
    (:func:`constrained_runtime_cdef`) and the poll callback."""
    return "\n".join([MODEL_TABLE_CDEF, f"""
typedef struct {{
    int method; int jacobian; double rtol; double atol; const double *atol_vec;
    long max_steps; double first_step; double max_step; double min_step; int max_order;
    int linear_solver; long mupper; long mlower; {CONTROL_FIELDS}
}} lcg_cvode_options;
typedef struct {{
    long nsteps, nrhs, nrhs_dq, njac, nlinsetups, netfails, nniters, nncfails;
    double t_reached; double h_last; int flag; int model_error; int nt_done; char message[512];
}} lcg_cvode_stats;
int lcg_cvode_solve(const lcg_model *m, const double *p, const double *y0, int nt, const double *tout,
                    double *yout, double *out, const lcg_cvode_options *opt, lcg_cvode_stats *st);
int lcg_outputs_batch(const lcg_model *m, int nt, const double *t, const double *y, const double *p,
                      double *out);""", ensemble_cdef("lcg_cvode_ensemble", "lcg_cvode_options", "lcg_cvode_solve_many",
                                      model=True), constrained_runtime_cdef(), POLL_CDEF])


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


#: The table of a model's Taylor jet (templates/taylor/lcg_taylor_model.h.j2).
TAYLOR_TABLE_CDEF = """
#define LCG_TAYLOR_ABI ...
#define LCG_TAYLOR_ORDER_MAX ...
typedef struct lcg_taylor_model {
    int abi; int nq; int nz; int ny; int np; int nout; int ne; int nrows; int order_max; size_t work_size;
    int (*start)(void *work, const double *p);
    int (*jet)(void *work, double *X, double t, const double *y, int kmax);
    int (*outputs)(double t, const double *y, const double *p, double *out);
    const int *event_row; const int *event_direction; const int *event_terminal;
    ...;
} lcg_taylor_model;"""


def taylor_runtime_cdef() -> str:
    """The model-independent Taylor runtime module: the jet table, the Taylor driver taking it
    (templates/taylor/lcg_taylor.h.j2), its ensembles and the poll callback."""
    return "\n".join([TAYLOR_TABLE_CDEF, f"""
typedef struct {{
    double rtol; double atol; const double *atol_vec; long max_steps; double max_step; int order; {CONTROL_FIELDS}
}} lcg_taylor_options;
typedef struct {{
    long nsteps; long njet; long nroot; int order; double t_reached; double h_last; double h_min;
    double h_max; int flag; int model_error; int nt_done; char message[512];
}} lcg_taylor_stats;
typedef struct {{
    int max_events; int n_events; double *t; double *y; int *which; int *direction; int terminated;
}} lcg_taylor_events;
int lcg_taylor_solve(const lcg_taylor_model *m, const double *p, const double *y0, int nt, const double *tout,
                     double *yout, double *out, const lcg_taylor_options *opt, lcg_taylor_stats *st,
                     lcg_taylor_events *ev);
int lcg_taylor_jet(const lcg_taylor_model *m, double t, const double *y, const double *p, int order,
                   double *jet);""", ensemble_cdef("lcg_taylor_ensemble", "lcg_taylor_options", "lcg_taylor_solve_many",
                                   model="lcg_taylor_model"), POLL_CDEF])
