/* lcg_ida.h -- lagcodegen's runtime: the native IDA driver of the GGL (stabilized
 * index-2) constrained equations of every constrained model compiled for them.
 *
 * Model-independent: it integrates any constrained model through its function table
 * (lcg_dae_model.h, with ggl_res), so it is compiled once per installation and SUNDIALS version,
 * and a model compiles only its own C. */
#ifndef LCG_IDA_H
#define LCG_IDA_H

#include "lcg_dae_model.h"

typedef struct {
    double rtol;
    double atol;
    const double *atol_vec; /* NULL, or ng absolute tolerances */
    long max_steps;         /* over the whole run */
    double first_step;      /* 0: IDA's estimate */
    double max_step;        /* 0: unbounded */
    double min_step;
    int max_order;          /* 0: 5 */
    int suppress_alg;       /* 1: lambda, mu excluded from the error test (IDASetSuppressAlg) */
    int jacobian;           /* 1: the model's dF/dyy + cj dF/dyp (ggl_jac), 0: difference quotients */
    int calc_ic;            /* 1: IDACalcIC(IDA_YA_YDP_INIT) for lambda, mu and yp */
    double ic_alg_atol;     /* absolute tolerance of lambda, mu during IDACalcIC only (e.g. 1e8) */
    int roots;              /* 1: root finding on the model's nroot event functions */
    int stop_at_outputs;    /* 1: step exactly to every output time (IDASetStopTime), no interpolation */
    /* run control (all zero: none) */
    int *cancel;            /* NULL, or a flag another thread may set: the run stops with flag -80 */
    int (*poll)(void *data, long done, long total); /* NULL, or called from the calling thread about
                               every poll_every s with the output rows done; nonzero cancels (-80) */
    void *poll_data;
    double poll_every;      /* seconds between poll calls (0: 0.05) */
    double max_wall;        /* wall-clock limit of the run in seconds (0: none): flag -81 */
} lcg_ida_options;

typedef struct {
    long nsteps, nres, nres_dq, njac, nlinsetups, netfails, nniters, nncfails, nbacktracks, ngevals;
    double t_reached;
    double h_last;
    int flag;        /* last IDA return flag (>= 0: success) */
    int ic_flag;     /* IDACalcIC's return flag */
    int model_error; /* LCG_DAE_ERR_* from the model functions, or 0 */
    int nt_done;     /* rows of yout filled */
    char message[512];
} lcg_ida_stats;

/* Integrate model m's GGL residual (m->ggl_res) from tout[0] with yy(tout[0]) = yy0,
 * yp(tout[0]) = yp0 (guesses for lambda, mu and yp when calc_ic is set); yout[k*ng + i] =
 * yy_i(tout[k]) (row 0: the consistent initial values), out[k*nout + j] = output j (lambda from
 * the state). ev (may be NULL) receives the events, with ev->y rows of ng values.
 * Returns 0, a negative IDA flag (-22: a table of another layout or without the GGL residual),
 * -80 cancelled, -81 the wall-clock limit max_wall reached, or -100 - (model error code). */
int lcg_ida_solve(const lcg_dae_model *m, const double *p, const double *yy0, const double *yp0, int nt,
                  const double *tout, double *yout, double *out, const lcg_ida_options *opt, lcg_ida_stats *st,
                  lcg_events *ev);

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
    const double *yp0;        /* member i: yp0 + i*yp0_stride */
    long yp0_stride;
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
} lcg_ida_ensemble;

/* The members of e (model e->model), each a run of lcg_ida_solve with the options opt (root
 * finding with e->rootdir, e->terminal when opt->roots), over a pthread pool (ng values per state
 * row; a terminal event's state is the final one). Returns 0, -80 cancelled or -20 out of memory. */
int lcg_ida_solve_many(lcg_ida_ensemble *e, const lcg_ida_options *opt);

#endif
