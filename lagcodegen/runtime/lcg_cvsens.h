/* lcg_cvsens.h -- lagcodegen's runtime: CVODE with forward sensitivities.
 *
 * The state y (ny values) and ns sensitivity blocks s_j = dy/dtheta_j integrated together as one
 * ODE by CVODE, the right-hand side of both from the model's generated <prefix>_sens_rhs (one
 * factorization of the mass matrix per call), the Newton systems solved block by block with the
 * states' matrix I - gamma J (J = df/dy of the model's table: its Jacobian, or difference
 * quotients of its right-hand side), the off-diagonal blocks of the augmented Jacobian dropped
 * from the Newton matrix: CVODES's staggered corrector (the states converge first, then the
 * sensitivities) or its simultaneous one (options.corrector). Model-independent: compiled
 * once per installation and SUNDIALS version. */
#ifndef LCG_CVSENS_H
#define LCG_CVSENS_H

#include "lcg_model.h"
#include "lcg_inputs.h"

/* ydot = f(t, y, p), sdot[j*ny + i] = d ydot_i / d theta_j (which[j]: the run-time parameter
 * index of direction j, -1 for an initial value). Returns LCG_OK or a model error code. */
typedef int (*lcg_sens_rhs_fn)(double t, const double *y, const double *p, int ns, const int *which,
                               const double *s, double *ydot, double *sdot);
/* dout[j*nout + k] = d output_k / d theta_j at (t, y, s). */
typedef int (*lcg_sens_out_fn)(double t, const double *y, const double *p, int ns, const int *which,
                               const double *s, double *dout);

/* Projection onto a constraint manifold after each step (CVodeSetProjFn; BDF only): ynew (ny (1 +
 * ns)) the projected state and sensitivities of y (same layout), err (NULL, or the error estimate
 * of that layout) replaced by its linearized projection. Returns LCG_OK, LCG_ERR_SINGULAR_MASS
 * (unrecoverable) or another code (recoverable: CVODE retries with a smaller step). */
typedef int (*lcg_sens_proj_fn)(double t, const double *y, const double *p, int ns, const int *which,
                                double *ynew, double *err);

typedef struct lcg_cvsens_options {
    int method;            /* 1 Adams, 2 BDF */
    double rtol;
    const double *atol;    /* ny (1 + ns) absolute tolerances: states, then each sensitivity block */
    long max_steps;        /* steps over the whole run */
    int jacobian;          /* 1: the model's Jacobian in the Newton matrix, 0: difference quotients */
    int max_order;         /* 0: CVODE's default */
    double first_step, max_step, min_step; /* 0: CVODE's defaults */
    int (*poll)(void *data, long done, long total); /* called every poll_every s (nonzero: stop); NULL: none */
    void *poll_data;
    double poll_every;
    double max_wall;       /* wall-clock limit in seconds (0: none) */
    lcg_sens_proj_fn project; /* NULL: none; else the projection after each step (method BDF) */
    int corrector;         /* LCG_CVSENS_STAGGERED (0) or LCG_CVSENS_SIMULTANEOUS (1) */
} lcg_cvsens_options;

/* The corrector: staggered (CVODES's CV_STAGGERED: the Newton iteration on the states alone, then
 * the sensitivities, linear, with the same matrix, usually one evaluation per step) or
 * simultaneous (CVODES's CV_SIMULTANEOUS: every direction in every Newton iteration). */
#define LCG_CVSENS_STAGGERED 0
#define LCG_CVSENS_SIMULTANEOUS 1

typedef struct lcg_cvsens_stats {
    long nsteps, nrhs, nlinsetups, netfails, nniters, nncfails;
    long njac;             /* Jacobians of the states evaluated */
    long nfactor;          /* factorizations of I - gamma J */
    long nblock_solves;    /* block solves (one per block per linear solve) */
    long nrhs_states;      /* staggered: the states' right-hand sides of its Newton iterations */
    long nsens_iters;      /* staggered: its sensitivity iterations (one sens_rhs each, in nrhs) */
    double h_last, t_reached;
    int nt_done, model_error, flag;
    char message[256];
} lcg_cvsens_stats;

/* Integrate model m with ns sensitivity directions from tout[0]: y(tout[0]) = y0, s(tout[0]) = s0
 * (ns*ny). Writes yout[k*ny + i], sout[(k*ns + j)*ny + i], out[k*nout + c] and
 * dout[(k*ns + j)*nout + c] at the nt output times. Returns 0, a negative CVODE flag,
 * LCG_FLAG_BAD_INPUT, LCG_FLAG_NOMEM, LCG_FLAG_CANCELLED (poll), LCG_FLAG_TIMED_OUT (max_wall) or
 * LCG_MODEL_ERROR_FLAG(rc). */
int lcg_cvsens_solve(const lcg_model *m, lcg_sens_rhs_fn sens_rhs, lcg_sens_out_fn sens_out, const double *p,
                     int ns, const int *which, const double *y0, const double *s0, int nt, const double *tout,
                     double *yout, double *sout, double *out, double *dout, const lcg_cvsens_options *opt,
                     lcg_cvsens_stats *st);

/* Events of a run with sensitivities: the event functions (gout[nroot] at (t, y, p); 0 or a model
 * error code) located by CVODE's root finding on the state part of the augmented vector, and the
 * events found: event k at t[k] with the augmented vector y[k*ny*(1 + ns) ..] there (the state,
 * then the ns sensitivity blocks), event function which[k], crossing direction[k]. The events
 * reset nothing: the sensitivities go on continuously through a non-terminal one; a terminal one
 * ends the run (terminated = 1). Only the first max_events are stored; n_events counts them all. */
typedef struct lcg_cvsens_events {
    int nroot;
    int (*roots)(double t, const double *y, const double *p, double *gout);
    const int *rootdir;    /* nroot directions to watch (0 both, +1, -1), or NULL: both */
    const int *terminal;   /* nroot flags: stop at this event, or NULL: every event stops */
    int max_events;
    int n_events;
    double *t;
    double *y;             /* max_events rows of ny (1 + ns) values */
    int *which;
    int *direction;
    int terminated;
} lcg_cvsens_events;

/* lcg_cvsens_solve with the events of ev (NULL: none, as lcg_cvsens_solve). A terminal event ends
 * the run: the rows of yout, sout, out, dout are those of the output times before it. A root
 * within rounding of tout[0] is not reported (a run restarted from the state of an event). */
int lcg_cvsens_solve_events(const lcg_model *m, lcg_sens_rhs_fn sens_rhs, lcg_sens_out_fn sens_out,
                            const double *p, int ns, const int *which, const double *y0, const double *s0, int nt,
                            const double *tout, double *yout, double *sout, double *out, double *dout,
                            const lcg_cvsens_options *opt, lcg_cvsens_stats *st, lcg_cvsens_events *ev);

/* lcg_cvsens_solve driven by the input tables in (NULL: none, as lcg_cvsens_solve; see
 * lcg_inputs.h): p[slot] of each table follows its table in every right-hand side, sensitivity
 * right-hand side, Jacobian and output evaluation (a copy of p per run: the call is reentrant),
 * and the run stops at each of in's restart times and starts afresh there (CVodeReInit of the
 * augmented state: the sensitivities go on continuously, as u does not depend on the directions).
 * A direction along an input's slot (which[j] == slot) is refused: LCG_FLAG_BAD_INPUT with the
 * reason in st->message, as for tables that do not fit the model. */
int lcg_cvsens_solve_inputs(const lcg_model *m, lcg_sens_rhs_fn sens_rhs, lcg_sens_out_fn sens_out,
                            const double *p, const lcg_inputs *in, int ns, const int *which, const double *y0,
                            const double *s0, int nt, const double *tout, double *yout, double *sout, double *out,
                            double *dout, const lcg_cvsens_options *opt, lcg_cvsens_stats *st);

#endif
