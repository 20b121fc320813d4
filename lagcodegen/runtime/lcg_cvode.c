/* lcg_cvode.c -- the native CVODE driver of every model (lagcodegen's runtime, compiled as it is).
 *
 * The native CVODE driver of every model: integrates a model's right-hand side, called through
 * its function table (lcg_model.h), with SUNDIALS CVODE (dense or band linear solver, the
 * model's or a difference-quotient Jacobian) and writes the solution at the requested times
 * straight into the caller's arrays. No Python runs inside the solver loop; no model is
 * compiled into it.
 *
 * With the band solver CVODE integrates the interleaved state (q_1, q_1', q_2, q_2', ..., z),
 * which keeps the couplings of chain-like systems near the diagonal; the model functions
 * and the caller's arrays keep the order y = (q, q', z).
 *
 * Events (lcg_cvode_solve_events): CVODE's root finding (CVodeRootInit) on event functions
 * generated apart from the model (lcg_ode_roots), each with its direction and terminal flag
 * (lcg_events); a root found again within rounding of the run's start time (a run restarted
 * from the state of an event) is not reported. */
#include "lcg_control.h" /* first: POSIX */

#include <float.h>
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "sundials_api.h"
#include "lcg_cvode.h"

#define LCG_STATS lcg_cvode_stats
#define LCG_ROOT_INFO CVodeGetRootInfo
#include "lcg_sundials.h"

/* The ensemble pool's row sizes (lcg_pool.h): the model of the ensemble e. */
#define NROW (e->model->ny)
#define NOUT (e->model->nout)
#define NOUTD (NOUT > 0 ? NOUT : 1)

typedef struct {
    const lcg_model *m;
    const double *p;
    lcg_cvode_stats *st;
    watch w;            /* cancellation, poll callback, wall-clock limit */
    long mu, ml;        /* band solver: bandwidths in the interleaved order */
    double *yb;         /* band solver: state and derivative in the model's order (ny each) */
    double *fb;
    double *vals;       /* sparse Jacobian entries (jac_nnz), or NULL */
    double *jd;         /* band solver with a dense Jacobian: the Jacobian in the model's order */
    int nonfinite;      /* the last model call computed a non-finite value, at t_nonfinite */
    double t_nonfinite;
    const lcg_ode_roots *r; /* event functions, or NULL */
    int *info;          /* root finding: the roots found (r->nroot), or NULL */
    const lcg_inputs *in; /* input tables (lcg_inputs.h), or NULL */
    double *pin;        /* inputs: p with the inputs' slots set at the evaluation time */
    double key;         /* inputs: the time of the last restart (the run's start at first) */
    double tb;          /* inputs: the next restart time (HUGE_VAL: none) */
} user_data;

/* The run-time parameters at t: p, with the inputs' slots from their tables when there are any. */
static const double *params_at(user_data *d, double t)
{
    if (d->in == NULL)
        return d->p;
    lcg_inputs_apply(d->in, t, t >= d->tb, d->pin);
    return d->pin;
}

/* Position in the interleaved (band solver) order of model state i (n coordinates), and back. */
static int to_band(int n, int i)
{
    return band_place(n, i);
}

static int from_band(int n, int k)
{
    return k < 2 * n ? (k % 2 == 0 ? k / 2 : n + k / 2) : k;
}

static void gather(const lcg_model *m, const double *z, double *y)
{
    int k;
    for (k = 0; k < m->ny; ++k)
        y[from_band(m->nq, k)] = z[k];
}

static void scatter(const lcg_model *m, const double *y, double *z)
{
    int k;
    for (k = 0; k < m->ny; ++k)
        z[k] = y[from_band(m->nq, k)];
}

/* CVODE's return value for a model function's rc at t: 0; -1 (unrecoverable) for a singular mass
 * matrix; 1 (recoverable: CVODE retries with a smaller step) for a non-finite value, remembered
 * so that a run that fails right after names it and its t instead of CVODE's consequence. */
static int model_status(user_data *d, int rc, double t)
{
    d->nonfinite = rc == LCG_ERR_NONFINITE;
    if (d->nonfinite)
        d->t_nonfinite = t;
    if (rc == LCG_ERR_SINGULAR_MASS) {
        d->st->model_error = rc;
        d->st->t_reached = t;
        return -1;
    }
    return rc == LCG_OK ? 0 : 1;
}

static int rhs(sunrealtype t, N_Vector y, N_Vector ydot, void *data)
{
    user_data *d = (user_data *)data;

    if (WATCH_TICK(&d->w))
        return -1; /* stop: cancelled or out of time */
    return model_status(d, d->m->rhs(t, N_VGetArrayPointer(y), params_at(d, t), N_VGetArrayPointer(ydot)), t);
}

static int rhs_band(sunrealtype t, N_Vector y, N_Vector ydot, void *data)
{
    user_data *d = (user_data *)data;
    int rc;

    if (WATCH_TICK(&d->w))
        return -1;
    gather(d->m, N_VGetArrayPointer(y), d->yb);
    rc = d->m->rhs(t, d->yb, params_at(d, t), d->fb);
    scatter(d->m, d->fb, N_VGetArrayPointer(ydot));
    return model_status(d, rc, t);
}

/* Dense matrix from the model's dense Jacobian, else from its sparse one. */
static int jac(sunrealtype t, N_Vector y, N_Vector fy, SUNMatrix J, void *data, N_Vector tmp1,
               N_Vector tmp2, N_Vector tmp3)
{
    user_data *d = (user_data *)data;
    const lcg_model *m = d->m;
    double *Jd = SUNDenseMatrix_Data(J);
    int rc, j, k;
    (void)tmp1;
    (void)tmp2;
    (void)tmp3;
    if (m->jac != NULL)
        return model_status(d, m->jac(t, N_VGetArrayPointer(y), N_VGetArrayPointer(fy), params_at(d, t), Jd), t);
    rc = m->jac_sparse(t, N_VGetArrayPointer(y), N_VGetArrayPointer(fy), params_at(d, t), d->vals);
    if (rc != LCG_OK)
        return model_status(d, rc, t);
    for (j = 0; j < m->ny; ++j)
        for (k = m->jac_colptr[j]; k < m->jac_colptr[j + 1]; ++k)
            Jd[(long)j * m->ny + m->jac_rowind[k]] = d->vals[k];
    return 0;
}

/* Band matrix (interleaved order) from the model's sparse Jacobian, else from its dense one;
 * CVODE zeroes it first. */
static int jac_band(sunrealtype t, N_Vector y, N_Vector fy, SUNMatrix J, void *data, N_Vector tmp1,
                    N_Vector tmp2, N_Vector tmp3)
{
    user_data *d = (user_data *)data;
    const lcg_model *m = d->m;
    int rc, i, j, k;
    (void)tmp1;
    (void)tmp2;
    (void)tmp3;
    gather(m, N_VGetArrayPointer(y), d->yb);
    gather(m, N_VGetArrayPointer(fy), d->fb);
    if (m->jac_sparse != NULL) {
        rc = m->jac_sparse(t, d->yb, d->fb, params_at(d, t), d->vals);
        if (rc != LCG_OK)
            return model_status(d, rc, t);
        for (j = 0; j < m->ny; ++j) {
            int jj = to_band(m->nq, j);
            double *col = SUNBandMatrix_Column(J, jj);
            for (k = m->jac_colptr[j]; k < m->jac_colptr[j + 1]; ++k) {
                i = to_band(m->nq, m->jac_rowind[k]);
                if (i - jj <= d->ml && jj - i <= d->mu)
                    col[i - jj] = d->vals[k];
            }
        }
        return 0;
    }
    rc = m->jac(t, d->yb, d->fb, params_at(d, t), d->jd);
    if (rc != LCG_OK)
        return model_status(d, rc, t);
    for (j = 0; j < m->ny; ++j) {
        int jj = to_band(m->nq, j);
        double *col = SUNBandMatrix_Column(J, jj);
        for (i = 0; i < m->ny; ++i) {
            int ii = to_band(m->nq, i);
            if (ii - jj <= d->ml && jj - ii <= d->mu)
                col[ii - jj] = d->jd[(long)j * m->ny + i];
        }
    }
    return 0;
}

/* CVRootFn: the event functions at (t, y) (the model's order). */
static int roots(sunrealtype t, N_Vector y, sunrealtype *gout, void *data)
{
    user_data *d = (user_data *)data;
    const double *ym = N_VGetArrayPointer(y);
    int rc;

    if (d->yb != NULL) { /* band solver: the interleaved order back to the model's */
        gather(d->m, ym, d->yb);
        ym = d->yb;
    }
    rc = d->r->roots(t, ym, params_at(d, t), gout);
    if (rc != LCG_OK) {
        d->st->model_error = rc;
        d->st->t_reached = t;
        return -1;
    }
    return 0;
}

/* The roots CVODE returned at t (state y, model's order) into ev, except those within rounding of
 * the start time t0 (found again where a run restarts from an event's state); returns 1 if one of
 * the recorded roots is terminal. */
static int record_roots(void *mem, lcg_events *ev, double t, double t0, double h, const double *y, int nroot,
                        int ny, int *info)
{
    if (t - t0 <= 100.0 * DBL_EPSILON * (fabs(t0) + fabs(h)))
        return CVodeGetRootInfo(mem, info) < 0;
    return record_events(mem, ev, t, y, nroot, ny, info);
}

/* Root finding on CVODE's memory: the event functions of d->r with ev's directions. 0 or a negative
 * CVODE flag. (The run driver and the stepper, lcg_cvode_stepper.c, set it up here.) */
static int roots_init(void *mem, const user_data *d, const lcg_events *ev)
{
    int flag;

    if ((flag = CVodeRootInit(mem, d->r->nroot, roots)) < 0)
        return flag;
    if (ev->rootdir != NULL && (flag = CVodeSetRootDirection(mem, (int *)ev->rootdir)) < 0)
        return flag;
    CVodeSetNoInactiveRootWarn(mem);
    return 0;
}

/* At CVODE's root return at t with its vector yv (interleaved for the band solver): the roots into
 * ev (record_roots, t0 the time CVODE started from); returns 1 if one of them is terminal. */
static int roots_found(void *mem, user_data *d, lcg_events *ev, double t, double t0, const double *yv)
{
    double h = 0.0;

    if (d->yb != NULL) { /* band solver: the interleaved order back to the model's */
        gather(d->m, yv, d->yb);
        yv = d->yb;
    }
    CVodeGetLastStep(mem, &h);
    return record_roots(mem, ev, t, t0, h, yv, d->r->nroot, d->m->ny, d->info);
}

/* Add CVODE's counters since its last (re)initialization to st's (with the driver's own: the
 * difference-quotient right-hand sides and the Jacobians). */
static void add_counts(void *mem, lcg_cvode_stats *st)
{
    long dq = 0, jac = 0;

    LCG_ADD_CVODE_COUNTS(mem, st);
    CVodeGetNumLinRhsEvals(mem, &dq);
    CVodeGetNumJacEvals(mem, &jac);
    st->nrhs_dq += dq;
    st->njac += jac;
}

/* The steps of the whole run (for the step budget, advance): those of the segments before the last
 * restart are in st->nsteps (0 without inputs until the run ends). */
#define CVodeTotalGetNumSteps(mem, n) (CVodeGetNumSteps(mem, n), *(n) += st->nsteps)

/* b within rounding of a (a <= b): CVODE cannot step from a to b. */
static int too_close(double a, double b)
{
    return b - a <= 4.0 * DBL_EPSILON * (fabs(a) > fabs(b) ? fabs(a) : fabs(b));
}

/* At the breakpoint *tb the run has reached (state y): start afresh there (the history of the
 * multistep method ends at a jump or kink of an input), on the next segment's pieces, with the stop
 * time at the next breakpoint or tend. The counters so far go to st (CVodeReInit resets them). */
static int restart_at(void *mem, user_data *d, N_Vector y, double *tb, double tend)
{
    int flag;

    add_counts(mem, d->st);
    d->key = *tb;
    if ((flag = CVodeReInit(mem, *tb, y)) < 0)
        return flag;
    *tb = d->tb = lcg_inputs_next_break(d->in, *tb);
    return CVodeSetStopTime(mem, *tb < tend ? *tb : tend);
}

static int fill_outputs(const lcg_model *m, double t, const double *y, const double *p, double *out)
{
    return m->outputs != NULL ? m->outputs(t, y, p, out) : LCG_OK;
}

/* out[k*nout + j] = output j at (t[k], y[k*ny ...]) for k < nt; stops at the first error. */
int lcg_outputs_batch(const lcg_model *m, int nt, const double *t, const double *y, const double *p, double *out)
{
    int k, rc;

    if (m->outputs == NULL)
        return LCG_OK;
    for (k = 0; k < nt; ++k)
        if ((rc = m->outputs(t[k], y + (long)k * m->ny, p, out + (long)k * m->nout)) != LCG_OK)
            return rc;
    return LCG_OK;
}

int lcg_rhs_call(const lcg_model *m, double t, const void *y, const void *p, void *ydot)
{
    return m->rhs(t, (const double *)y, (const double *)p, (double *)ydot);
}

int lcg_rhs_batch(const lcg_model *m, int nt, double t, const double *y, const double *p, int pstride, double *ydot,
                  int *failed)
{
    int k, rc;

    for (k = 0; k < nt; ++k)
        if ((rc = m->rhs(t, y + (long)k * m->ny, p == NULL ? NULL : p + (long)k * pstride,
                         ydot + (long)k * m->ny)) != LCG_OK) {
            *failed = k;
            return rc;
        }
    return LCG_OK;
}

/* CVode towards target (the root returns of the events on the way recorded into ev and stepped
 * over): a negative CVODE flag, ADVANCE_TERMINAL at a terminal event (its time in *tret), or 0. */
#define ADVANCE_TERMINAL 1
static int advance(void *mem, user_data *d, const lcg_cvode_options *opt, lcg_events *ev, int roots_on,
                   double target, N_Vector y, double *tret, const double *yv)
{
    lcg_cvode_stats *st = d->st;
    long nst = 0;
    int flag;

    for (;;) { /* the step budget (max_steps) over the whole run, restarts included */
        CVodeTotalGetNumSteps(mem, &nst);
        if (nst >= opt->max_steps) {
            snprintf(st->message, sizeof st->message, "the step budget max_steps = %ld is used up before t = %.17g",
                     opt->max_steps, target);
            return -1;
        }
        CVodeSetMaxNumSteps(mem, opt->max_steps - nst);
        flag = CVode(mem, target, y, tret, CV_NORMAL);
        st->t_reached = *tret;
        if (flag == CV_ROOT_RETURN && roots_on) {
            if (roots_found(mem, d, ev, *tret, d->key, yv)) {
                ev->terminated = 1;
                return ADVANCE_TERMINAL;
            }
            continue;
        }
        return flag < 0 ? flag : 0;
    }
}

/* Integrate model m from tout[0] with y(tout[0]) = y0; yout[k*ny + i] = y_i(tout[k]),
 * out[k*nout + j] = output j at tout[k]; r: event functions (NULL: none) located and recorded into
 * ev; in: input tables (NULL: none). Returns 0, or a negative CVODE flag / -100 - model error. */
static int solve(const lcg_model *m, const lcg_ode_roots *r, const double *p, const lcg_inputs *in,
                 const double *y0, int nt, const double *tout, double *yout, double *out,
                 const lcg_cvode_options *opt, lcg_cvode_stats *st, lcg_events *ev)
{
    SUNContext ctx = NULL;
    void *mem = NULL;
    N_Vector y = NULL, abstol = NULL;
    SUNMatrix A = NULL;
    SUNLinearSolver LS = NULL;
    SUNNonlinearSolver NLS = NULL;
    user_data data;
    double *yv, *ym;
    int k, i, flag = 0, rc, ny, nout, band = opt->linear_solver == 1, fixedpoint = opt->linear_solver == 2;
    int use_jac, roots_on = r != NULL && ev != NULL && r->nroot > 0 && r->roots != NULL;
    int restart = in != NULL && in->nbreak > 0;
    double tb = HUGE_VAL; /* inputs: the next restart time */
    const double *pk;     /* the parameters of an output row */

    memset(st, 0, sizeof *st);
    st->t_reached = tout[0];
    if (m == NULL || m->abi != LCG_MODEL_ABI || m->rhs == NULL || m->ny != 2 * m->nq + m->nz) {
        snprintf(st->message, sizeof st->message, "the model table is missing or of another layout "
                 "(lcg_model version %d, this driver reads version %d)", m != NULL ? m->abi : -1, LCG_MODEL_ABI);
        return st->flag = LCG_FLAG_BAD_INPUT;
    }
    ny = m->ny;
    nout = m->nout;
    use_jac = opt->jacobian && (m->jac != NULL || m->jac_sparse != NULL);
    data.m = m;
    data.p = p;
    data.st = st;
    data.nonfinite = 0;
    data.t_nonfinite = 0.0;
    data.yb = data.fb = data.vals = data.jd = NULL;
    data.r = r;
    data.info = NULL;
    if (ev != NULL) {
        ev->n_events = 0;
        ev->terminated = 0;
    }
    data.in = in;
    data.pin = NULL;
    data.key = tout[0];
    data.tb = HUGE_VAL;
    if (in != NULL) {
        if (lcg_inputs_check(in, m->np, st->message, sizeof st->message) != 0)
            return st->flag = LCG_FLAG_BAD_INPUT;
        if ((data.pin = (double *)malloc(sizeof(double) * (size_t)(m->np > 0 ? m->np : 1))) == NULL)
            return st->flag = LCG_FLAG_NOMEM;
        for (i = 0; i < m->np; ++i)
            data.pin[i] = p[i];
        tb = lcg_inputs_next_break(in, tout[0]);
    }
    watch_init(&data.w, opt->cancel, opt->poll, opt->poll_data, opt->poll_every, opt->max_wall, nt, &st->nt_done);
    data.mu = opt->mupper;
    data.ml = opt->mlower;
    LCG_CREATE_CONTEXT(LCG_FLAG_NOMEM);

    y = N_VNew_Serial(ny, ctx);
    mem = CVodeCreate(opt->method, ctx);
    if (band && (opt->mupper < 0 || opt->mlower < 0 || opt->mupper >= ny || opt->mlower >= ny)) {
        snprintf(st->message, sizeof st->message, "band solver: bandwidths mu = %ld, ml = %ld out of range",
                 opt->mupper, opt->mlower);
        flag = LCG_FLAG_BAD_INPUT;
        goto done;
    }
    if (!fixedpoint)
        A = band ? SUNBandMatrix(ny, opt->mupper, opt->mlower, ctx) : SUNDenseMatrix(ny, ny, ctx);
    if (band && ((data.yb = (double *)malloc(sizeof(double) * (size_t)ny)) == NULL
                 || (data.fb = (double *)malloc(sizeof(double) * (size_t)ny)) == NULL)) {
        flag = LCG_FLAG_NOMEM;
        goto done;
    }
    if (roots_on && (data.info = (int *)malloc(sizeof(int) * (size_t)r->nroot)) == NULL) {
        flag = LCG_FLAG_NOMEM;
        goto done;
    }
    if (use_jac && m->jac_sparse != NULL && (band || m->jac == NULL)
        && (data.vals = (double *)malloc(sizeof(double) * (size_t)(m->jac_nnz > 0 ? m->jac_nnz : 1))) == NULL) {
        flag = LCG_FLAG_NOMEM;
        goto done;
    }
    if (use_jac && band && m->jac_sparse == NULL
        && (data.jd = (double *)malloc(sizeof(double) * (size_t)ny * (size_t)ny)) == NULL) {
        flag = LCG_FLAG_NOMEM;
        goto done;
    }
    if (y == NULL || mem == NULL || (A == NULL && !fixedpoint)) {
        flag = LCG_FLAG_NOMEM;
        goto done;
    }
    if (!fixedpoint)
        LS = band ? SUNLinSol_Band(y, A, ctx) : SUNLinSol_Dense(y, A, ctx);
    yv = N_VGetArrayPointer(y);
    ym = band ? data.yb : yv; /* the state in the model's order */
    if (band)
        scatter(m, y0, yv);
    else
        for (i = 0; i < ny; ++i)
            yv[i] = y0[i];

    pk = p;
    if (in != NULL) {
        lcg_inputs_apply(in, tout[0], 0, data.pin);
        pk = data.pin;
    }
    rc = fill_outputs(m, tout[0], y0, pk, out);
    LCG_MODEL_ERROR(LCG_OK);
    for (i = 0; i < ny; ++i)
        yout[i] = y0[i];
    st->nt_done = 1;

    if ((flag = CVodeInit(mem, band ? rhs_band : rhs, tout[0], y)) < 0)
        goto done;
    flag = set_tolerances(mem, 0, ctx, ny, opt->rtol, opt->atol, opt->atol_vec, band ? m->nq : -1, &abstol,
                          LCG_FLAG_NOMEM);
    if (flag < 0)
        goto done;
    CVodeSetUserData(mem, &data);
    if (fixedpoint) {
        /* Functional iteration: no Jacobian, no linear solves (nonstiff problems, Adams). */
        NLS = SUNNonlinSol_FixedPoint(y, 0, ctx);
        if (NLS == NULL) {
            flag = LCG_FLAG_NOMEM;
            goto done;
        }
        if ((flag = CVodeSetNonlinearSolver(mem, NLS)) < 0)
            goto done;
    } else {
        if ((flag = CVodeSetLinearSolver(mem, LS, A)) < 0)
            goto done;
        if (use_jac && (flag = CVodeSetJacFn(mem, band ? jac_band : jac)) < 0)
            goto done;
    }
    CVodeSetMaxHnilWarns(mem, -1); /* no "t + h = t" warnings on stdout: failures are reported */
    if (roots_on && (flag = roots_init(mem, &data, ev)) < 0)
        goto done;
    if ((flag = set_step_limits(mem, 0, opt->max_order, opt->first_step, opt->max_step, opt->min_step)) < 0)
        goto done;
    data.tb = tb;
    if (nt > 1 && (flag = CVodeSetStopTime(mem, tb < tout[nt - 1] ? tb : tout[nt - 1])) < 0)
        goto done;

    for (k = 1; k < nt; ++k) {
        double tret = tout[k - 1];
        if (WATCH_TICK(&data.w))
            goto done;
        while (tb < tout[k]) { /* inputs with restart: a breakpoint before the next output time */
            if (!too_close(data.key, tb)) {
                if ((flag = advance(mem, &data, opt, ev, roots_on, tb, y, &tret, yv)) < 0 || flag == ADVANCE_TERMINAL)
                    goto done;
            }
            if ((flag = restart_at(mem, &data, y, &tb, tout[nt - 1])) < 0)
                goto done;
        }
        if (restart && too_close(data.key, tout[k])) {
            tret = tout[k]; /* an output time a rounding error after the restart: the restart's state */
        } else if ((flag = advance(mem, &data, opt, ev, roots_on, tout[k], y, &tret, yv)) < 0 || flag == ADVANCE_TERMINAL) {
            goto done;
        }
        if (band)
            gather(m, yv, data.yb);
        for (i = 0; i < ny; ++i)
            yout[(long)k * ny + i] = ym[i];
        if (in != NULL)
            lcg_inputs_apply(in, tret, 0, data.pin); /* the signal's value at the output time */
        rc = fill_outputs(m, tret, ym, pk, out + (long)k * nout);
        LCG_MODEL_ERROR(LCG_OK);
        st->nt_done = k + 1;
        if (tb == tout[k] && k < nt - 1 && (flag = restart_at(mem, &data, y, &tb, tout[nt - 1])) < 0)
            goto done;
    }

done:
    flag = watch_flag(&data.w, flag, st->message, sizeof st->message);
    if (mem != NULL) {
        add_counts(mem, st);
        CVodeGetLastStep(mem, &st->h_last);
        if (flag < 0 && flag > LCG_FLAG_MODEL_ERROR && st->model_error == 0)
            CVodeGetCurrentTime(mem, &st->t_reached);
    }
    flag = lcg_nonfinite_flag(flag, data.nonfinite, data.t_nonfinite, &st->model_error, &st->t_reached);
    st->flag = flag;
    LCG_NOMEM_MESSAGE(LCG_FLAG_NOMEM, "CVODE");
    CVodeFree(&mem);
    free_solver(LS, NLS, A, (N_Vector[]){abstol, y}, 2, &ctx);
    free(data.yb);
    free(data.fb);
    free(data.vals);
    free(data.jd);
    free(data.info);
    free(data.pin);
    return flag < 0 ? flag : 0;
}

int lcg_cvode_solve(const lcg_model *m, const double *p, const double *y0, int nt, const double *tout,
                    double *yout, double *out, const lcg_cvode_options *opt, lcg_cvode_stats *st)
{
    return solve(m, NULL, p, NULL, y0, nt, tout, yout, out, opt, st, NULL);
}

/* lcg_cvode_solve with the events r (NULL: none) located and recorded into ev; see lcg_cvode.h. */
int lcg_cvode_solve_events(const lcg_model *m, const lcg_ode_roots *r, const double *p, const double *y0, int nt,
                           const double *tout, double *yout, double *out, const lcg_cvode_options *opt,
                           lcg_cvode_stats *st, lcg_events *ev)
{
    return solve(m, r, p, NULL, y0, nt, tout, yout, out, opt, st, ev);
}

/* lcg_cvode_solve with the input tables in (NULL: none); see lcg_cvode.h. */
int lcg_cvode_solve_inputs(const lcg_model *m, const double *p, const lcg_inputs *in, const double *y0, int nt,
                           const double *tout, double *yout, double *out, const lcg_cvode_options *opt,
                           lcg_cvode_stats *st)
{
    return solve(m, NULL, p, in, y0, nt, tout, yout, out, opt, st, NULL);
}

#define COUNTS(c, st) (c[0] = (st)->nsteps, c[1] = (st)->nrhs + (st)->nrhs_dq, c[2] = (st)->njac, \
                       c[3] = (st)->netfails, c[4] = (st)->nncfails)

#define LCG_POOL_ENSEMBLE lcg_cvode_ensemble
#define LCG_POOL_OPTIONS lcg_cvode_options
#define LCG_POOL_STATS lcg_cvode_stats
#define LCG_POOL_SOLVE_MANY lcg_cvode_solve_many
#define LCG_POOL_EVENTS lcg_events
#include "lcg_pool.h"

static int pool_member(lcg_cvode_ensemble *e, const double *pi, const double *y0i, const double *yp0i,
                       const lcg_cvode_options *o, lcg_cvode_stats *st, double *yout, double *out, pool_scratch *s)
{
    const lcg_inputs *in = NULL;
    int rc;

    (void)yp0i;
    if (e->inputs != NULL) /* the member's own tables: its row of p (lcg_cvode_ensemble) */
        in = e->inputs + (e->p_stride > 0 ? (pi - e->p) / e->p_stride : 0);
    if (e->roots == NULL)
        return solve(e->model, NULL, pi, in, y0i, e->nt, e->tout, yout, out, o, st, NULL);
    rc = solve(e->model, e->roots, pi, in, y0i, e->nt, e->tout, yout, out, o, st, &s->evs);
    s->ev_n = s->evs.n_events;
    s->ev_term = s->evs.terminated;
    if (s->evs.terminated && s->evs.n_events > 0 && s->evs.n_events <= s->maxev) {
        int j;
        s->ylast = s->evs.y + (long)(s->evs.n_events - 1) * NROW;
        s->tlast = s->evs.t[s->evs.n_events - 1];
        if (fill_outputs(e->model, s->tlast, s->ylast, pi, s->olast) != LCG_OK)
            for (j = 0; j < NOUTD; ++j)
                s->olast[j] = NAN;
    }
    return rc;
}
