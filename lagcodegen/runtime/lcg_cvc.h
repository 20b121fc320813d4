/* lcg_cvc.h -- lagcodegen's runtime: the native CVODE driver of the index-1
 * constrained equations of every constrained model.
 *
 * Model-independent: it integrates any constrained model through its function table
 * (lcg_dae_model.h), so it is compiled once per installation and SUNDIALS version, and a model
 * compiles only its own C. */
#ifndef LCG_CVC_H
#define LCG_CVC_H

#include <stddef.h>

#include "lcg_dae_model.h"

typedef struct {
    int method;             /* CV_ADAMS (1) or CV_BDF (2); projection needs CV_BDF */
    double rtol;
    double atol;
    const double *atol_vec; /* NULL, or ny absolute tolerances */
    long max_steps;         /* over the whole run */
    double first_step;      /* 0: CVODE's estimate */
    double max_step;        /* 0: unbounded */
    double min_step;
    int max_order;          /* 0: the method's maximum */
    double alpha;           /* Baumgarte stabilization (0: none; negative: m->natural_rate at y0, */
    double beta;            /* "auto") */
    int projection;         /* 1: project onto the constraints after each step (CVodeSetProjFn) */
    double proj_tol;        /* Gauss-Newton step tolerance of the projection */
    int proj_maxit;         /* Gauss-Newton steps at most */
    int proj_err;           /* 1: project the error estimate too (CVODE's default) */
    int roots;              /* 1: root finding on the model's nroot event functions */
    /* run control (all zero: none) */
    int *cancel;            /* NULL, or a flag another thread may set: the run stops with flag -80 */
    int (*poll)(void *data, long done, long total); /* NULL, or called from the calling thread about
                               every poll_every s with the output rows done; nonzero cancels (-80) */
    void *poll_data;
    double poll_every;      /* seconds between poll calls (0: 0.05) */
    double max_wall;        /* wall-clock limit of the run in seconds (0: none): flag -81 */
} lcg_cvc_options;

typedef struct {
    long nsteps, nrhs, nrhs_dq, njac, nlinsetups, netfails, nniters, nncfails, nproj, nprojfails, ngevals;
    double t_reached;
    double h_last;
    double alpha, beta; /* the Baumgarte parameters used */
    int flag;        /* last CVODE return flag (>= 0: success) */
    int model_error; /* LCG_DAE_ERR_* from the model functions, or 0 */
    int nt_done;     /* rows of yout filled */
    char message[512];
} lcg_cvc_stats;

/* Integrate model m's y' = (q', q'') with q'' from the augmented system (m->crhs; difference-
 * quotient Jacobian) from tout[0], y(tout[0]) = y0; yout[k*ny + i] = y_i(tout[k]),
 * out[k*nout + j] = output j. ev (may be NULL when there are no root functions) receives the
 * events. Returns 0, a negative CVODE flag (-22: a table of another layout), -80 cancelled, -81
 * the wall-clock limit max_wall reached, or -100 - (model error code). */
int lcg_cvc_solve(const lcg_dae_model *m, const double *p, const double *y0, int nt, const double *tout,
                  double *yout, double *out, const lcg_cvc_options *opt, lcg_cvc_stats *st, lcg_events *ev);

/* The initial state of a run of model m in one call (no Python between the checks): y = (q0, v0)
 * taken as it is (mode 0), checked (mode 1: |f(q, t)| and |A q' + A0| within tol, the first nineq
 * root functions -- the inequalities -- at least -tol, the augmented matrix regular; then the
 * round-off removed by m->project with tol 1e-14, 50 steps) or projected (mode 2: m->project with
 * tol 1e-14, 50 steps, then the residuals within tol); in every mode the augmented system is then
 * solved at the resulting state (alpha = beta = 0). yy receives that state (ny values) or, with yp
 * not NULL, the GGL initial values: yy[ng] = (q, v, lambda, mu = 0), yp[ng] = (v, q'', 0, 0).
 * Returns 0, or 1 when a check or a model function fails (the caller then finds out why), -20 out
 * of memory, -22 a table of another layout. */
int lcg_dae_initial_state(const lcg_dae_model *m, double t, const double *y, const double *p, int mode, double tol,
                          int nineq, double *yy, double *yp);

/* Nonzero when m is a table this runtime reads (its version and sizes consistent); message
 * (size bytes, may be NULL) receives why not. */
int lcg_dae_check(const lcg_dae_model *m, char *message, size_t size);

/* An ensemble of nmem runs that differ in p and the initial state, spread over nthreads threads
 * (members taken in turn from a shared counter; each member is a run of the single-run solver
 * with its own SUNDIALS context, so its numbers are those of the same run alone). Arrays are by
 * member; NULL where not wanted. The caller presets flag[i] (e.g. -82: never started). */
typedef struct {
    const lcg_dae_model *model; /* the model every member integrates */
    long nmem;
    int nthreads;
    const double *p;          /* member i: p + i*p_stride (p_stride 0: shared; NULL: no parameters) */
    long p_stride;
    const double *y0;         /* member i: y0 + i*y0_stride */
    long y0_stride;
    int nt;
    const double *tout;
    double *final;            /* nmem x (NROW + NOUT): state and outputs at the last time reached */
    double *traj;             /* nmem x nt x ncol: columns col[] of (state | outputs); NaN past the end */
    int ncol;
    const int *col;
    int *flag;                /* return flag of each member (0 success) */
    int *nt_done;             /* output rows reached */
    double *t_reached;
    double *wall;             /* seconds */
    long *counts;             /* nmem x 8: steps, rhs evals, jac evals, error test fails, nonlinear
                                 convergence fails, model error, events, terminated */
    char *messages;           /* max_messages x 256: solver messages of failed members (truncated) */
    long max_messages;
    long *message_member;     /* the member of each message */
    long n_messages;          /* failed members with a message (may exceed max_messages) */
    int max_events;           /* events kept per member run (root finding; 0: 64) */
    const int *rootdir;       /* NROOT directions of the event functions (0: both), or NULL */
    const int *terminal;      /* NROOT flags: the event ends the run, or NULL (all terminal) */
    int (*poll)(void *data, long done, long total); /* NULL, or called from the calling thread about
                                 every poll_every s with the members done; nonzero cancels */
    void *poll_data;
    double poll_every;        /* seconds (0: 0.05) */
    int cancel;               /* set (by anyone) to stop: running members end with -80 */
    long done;                /* members finished (the progress counter) */
    long next;                /* members started */
} lcg_cvc_ensemble;

/* The members of e (model e->model), each a run of lcg_cvc_solve with the options opt (root
 * finding with e->rootdir, e->terminal when opt->roots), over a pthread pool (ny values per state
 * row; a terminal event's state is the final one). Returns 0, -80 cancelled or -20 out of memory. */
int lcg_cvc_solve_many(lcg_cvc_ensemble *e, const lcg_cvc_options *opt);

#endif
