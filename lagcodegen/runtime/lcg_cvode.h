/* lcg_cvode.h -- lagcodegen's runtime: the native CVODE driver of every model.
 *
 * Model-independent: it integrates any model through its function table (lcg_model.h), so it
 * is compiled once per installation and SUNDIALS version, and a model compiles only its own C. */
#ifndef LCG_CVODE_H
#define LCG_CVODE_H

#include "lcg_model.h"

typedef struct {
    int method;             /* CV_ADAMS (1) or CV_BDF (2) */
    int jacobian;           /* 1: the model's Jacobian (dense, else sparse), 0: difference quotients */
    double rtol;
    double atol;
    const double *atol_vec; /* NULL, or ny absolute tolerances */
    long max_steps;         /* over the whole run */
    double first_step;      /* 0: CVODE's estimate */
    double max_step;        /* 0: unbounded */
    double min_step;
    int max_order;          /* 0: the method's maximum */
    int linear_solver;      /* 0: dense, 1: band (state interleaved as (q_1, q_1', q_2, ...)),
                               2: none, fixed-point nonlinear iteration (nonstiff problems) */
    long mupper, mlower;    /* band: upper and lower bandwidth in the interleaved order */
    /* run control (all zero: none) */
    int *cancel;            /* NULL, or a flag another thread may set: the run stops with flag -80 */
    int (*poll)(void *data, long done, long total); /* NULL, or called from the calling thread about
                               every poll_every s with the output rows done; nonzero cancels (-80) */
    void *poll_data;
    double poll_every;      /* seconds between poll calls (0: 0.05) */
    double max_wall;        /* wall-clock limit of the run in seconds (0: none): flag -81 */
} lcg_cvode_options;

typedef struct {
    long nsteps, nrhs, nrhs_dq, njac, nlinsetups, netfails, nniters, nncfails;
    double t_reached;
    double h_last;
    int flag;        /* last CVODE return flag (>= 0: success) */
    int model_error; /* LCG_ERR_* from the model functions, or 0 */
    int nt_done;     /* rows of yout filled */
    char message[512];
} lcg_cvode_stats;

/* Integrate model m from tout[0] with y(tout[0]) = y0 and write yout[k*ny + i] = y_i(tout[k]),
 * out[k*nout + j] = output j at tout[k] (nt output times, increasing).
 * Returns 0, a negative CVODE flag (-22: bad bandwidths or a table of another layout), -80
 * cancelled, -81 the wall-clock limit max_wall reached, or -100 - (model error code). */
int lcg_cvode_solve(const lcg_model *m, const double *p, const double *y0, int nt, const double *tout,
                    double *yout, double *out, const lcg_cvode_options *opt, lcg_cvode_stats *st);
/* An ensemble of nmem runs that differ in p and the initial state, spread over nthreads threads
 * (members taken in turn from a shared counter; each member is a run of the single-run solver
 * with its own SUNDIALS context, so its numbers are those of the same run alone). Arrays are by
 * member; NULL where not wanted. The caller presets flag[i] (e.g. -82: never started). */
typedef struct {
    const lcg_model *model; /* the model every member integrates */
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
    int (*poll)(void *data, long done, long total); /* NULL, or called from the calling thread about
                                 every poll_every s with the members done; nonzero cancels */
    void *poll_data;
    double poll_every;        /* seconds (0: 0.05) */
    int cancel;               /* set (by anyone) to stop: running members end with -80 */
    long done;                /* members finished (the progress counter) */
    long next;                /* members started */
} lcg_cvode_ensemble;

/* The members of e (model e->model), each a run of lcg_cvode_solve with the options opt, over a
 * pthread pool (NROW = ny state values per row). Returns 0, -80 cancelled or -20 out of memory. */
int lcg_cvode_solve_many(lcg_cvode_ensemble *e, const lcg_cvode_options *opt);

/* out[k*nout + j] = output j of model m at (t[k], y[k*ny ...]) for k < nt. */
int lcg_outputs_batch(const lcg_model *m, int nt, const double *t, const double *y, const double *p, double *out);

#endif
