/* lcg_taylor.h -- lagcodegen's Taylor runtime: the Taylor-series driver of every model.
 *
 * Model-independent: it integrates any model through the table of its Taylor jet
 * (lcg_taylor_model.h), so it is compiled once per installation, and a model compiles only its
 * jet. Each step computes the normalized Taylor coefficients y_[k] = y^(k)(t)/k!, k <= order,
 * chooses the step h from the last two coefficients (Jorba & Zou) and advances y by the
 * polynomial; output times inside a step are evaluations of that polynomial, events roots of
 * the event functions' polynomials. Plain C99 + libm + pthreads (ensembles). */
#ifndef LCG_TAYLOR_H
#define LCG_TAYLOR_H

#include "lcg_taylor_model.h"

typedef struct {
    double rtol;            /* relative tolerance of one step */
    double atol;            /* absolute tolerance of one step, used when atol_vec is NULL */
    const double *atol_vec; /* NULL, or ny absolute tolerances */
    long max_steps;         /* step budget over the whole run */
    double max_step;        /* 0: unbounded */
    int order;              /* 0: from the tolerances, else 2..LCG_TAYLOR_ORDER_MAX */
    /* run control (all zero: none) */
    int *cancel;            /* NULL, or a flag another thread may set: the run stops with flag -80 */
    int (*poll)(void *data, long done, long total); /* NULL, or called from the calling thread about
                               every poll_every s with the output rows done; nonzero cancels (-80) */
    void *poll_data;
    double poll_every;      /* seconds between poll calls (0: 0.05) */
    double max_wall;        /* wall-clock limit of the run in seconds (0: none): flag -81 */
} lcg_taylor_options;

typedef struct {
    long nsteps;       /* steps taken */
    long njet;         /* Taylor jets computed (one per step, each worth order+1 right-hand sides) */
    long nroot;        /* steps whose event polynomials needed a root search */
    int order;         /* Taylor order used */
    double t_reached;  /* time of the last state reached */
    double h_last, h_min, h_max;
    int flag;          /* 0 success, < 0 failure (see lcg_taylor_solve) */
    int model_error;   /* 1 singular mass matrix, 2 non-finite value, or 0 */
    int nt_done;       /* rows of yout filled */
    char message[512];
} lcg_taylor_stats;

/* Events found by root finding on the step polynomials: event k at t[k] with state
 * y[k*ny ...], event function which[k], direction[k] (+1 increasing, -1 decreasing). Only
 * the first max_events are stored; n_events counts them all. */
typedef struct {
    int max_events;
    int n_events;
    double *t;
    double *y;
    int *which;
    int *direction;
    int terminated; /* 1 if a terminal event ended the run */
} lcg_taylor_events;

/* Integrate model m from tout[0] with y(tout[0]) = y0 to tout[nt-1]; yout[k*ny + i] = y_i(tout[k]),
 * out[k*nout + j] = output j at tout[k] (out may be NULL when nout = 0; ev may be NULL).
 * Returns 0; -1 max_steps used up; -3 the step size fell below the resolution of t;
 * -20 out of memory; -22 bad options or a table of another layout; -80 cancelled; -81 the
 * wall-clock limit max_wall reached; -100 - e for model error e (1 singular mass matrix,
 * 2 non-finite value). st->message explains failures. */
int lcg_taylor_solve(const lcg_taylor_model *m, const double *p, const double *y0, int nt, const double *tout,
                     double *yout, double *out, const lcg_taylor_options *opt, lcg_taylor_stats *st,
                     lcg_taylor_events *ev);

/* Normalized Taylor coefficients of model m at (t, y) up to order (<= LCG_TAYLOR_ORDER_MAX):
 * jet[i*(order+1) + k] = y_i^(k)(t)/k!. Returns 0, a model error code (1, 2), -20 out of memory
 * or -22 a bad order or table. */
int lcg_taylor_jet(const lcg_taylor_model *m, double t, const double *y, const double *p, int order, double *jet);
/* An ensemble of nmem runs that differ in p and the initial state, spread over nthreads threads
 * (members taken in turn from a shared counter; each member is a run of the single-run solver
 * with its own SUNDIALS context, so its numbers are those of the same run alone). Arrays are by
 * member; NULL where not wanted. The caller presets flag[i] (e.g. -82: never started). */
typedef struct {
    const lcg_taylor_model *model; /* the model every member integrates */
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
} lcg_taylor_ensemble;

/* The members of e (model e->model), each a run of lcg_taylor_solve (no events) with the options
 * opt, over a pthread pool (NROW = ny state values per row). Returns 0, -80 cancelled or -20 out
 * of memory. */
int lcg_taylor_solve_many(lcg_taylor_ensemble *e, const lcg_taylor_options *opt);

#endif
