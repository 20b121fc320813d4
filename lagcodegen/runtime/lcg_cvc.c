/* lcg_cvc.c -- lagcodegen's runtime, compiled as it is.
 *
 * The native CVODE driver of the index-1 constrained equations of every constrained model
 * (notes, eq. 4.5), called through the model's function table (lcg_dae_model.h): the
 * accelerations come from the augmented system solved by the model's kkt at every
 * right-hand-side call (m->crhs), with optional Baumgarte stabilization and optional projection
 * onto the constraint manifold through CVODE's projection interface (CVodeSetProjFn; BDF only).
 * The Jacobian is CVODE's difference-quotient approximation. Root finding (CVodeRootInit)
 * reports events. The scratch arrays a run needs are allocated once per run, never per call. */
#include "lcg_control.h" /* first: POSIX */

#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "sundials_api.h"
#include "lcg_cvc.h"

#define LCG_STATS lcg_cvc_stats
#define LCG_ROOT_INFO CVodeGetRootInfo
#include "lcg_sundials.h"

/* The ensemble pool's row sizes (lcg_pool.h): the model of the ensemble e. */
#define NROW (e->model->ny)
#define NOUT (e->model->nout)
#define NOUTD (NOUT > 0 ? NOUT : 1)

typedef struct {
    int (*crhs)(double t, const double *y, const double *p, double alpha, double beta, double *ydot);
    const lcg_dae_model *m;
    const double *p;
    double alpha, beta, proj_tol;
    int proj_maxit;
    lcg_cvc_stats *st;
    watch w;      /* cancellation, poll callback, wall-clock limit */
    double *ynew; /* projection: the projected state (ny), or NULL */
    int *info;    /* root finding: the roots found (nroot), or NULL */
} user_data;

int lcg_dae_check(const lcg_dae_model *m, char *message, size_t size)
{
    const char *why = NULL;

    if (m == NULL)
        why = "no model table";
    else if (m->abi != LCG_DAE_MODEL_ABI)
        why = "a table of another version";
    else if (m->nq < 1 || m->nj < 0 || m->njh < 0 || m->njh > m->nj || m->ny < m->nq + 1
             || m->ng != m->ny + m->nj + m->njh || m->np < 0 || m->nout < 0 || m->nroot < 0)
        why = "inconsistent sizes";
    else if (m->kkt == NULL || m->crhs == NULL || m->natural_rate == NULL || m->residuals == NULL
             || m->project == NULL || m->coutputs == NULL || (m->nroot > 0 && m->roots == NULL) || (m->ggl_jac != NULL && m->ggl_res == NULL))
        why = "missing functions";
    if (why != NULL && message != NULL && size > 0)
        snprintf(message, size, "the constrained model table is unusable: %s (lcg_dae_model version %d, this "
                 "driver reads version %d)", why, m != NULL ? m->abi : -1, LCG_DAE_MODEL_ABI);
    return why == NULL;
}

static int fail(user_data *d, int rc, double t)
{
    if (rc == LCG_DAE_ERR_SINGULAR) {
        d->st->model_error = rc;
        d->st->t_reached = t;
        return -1; /* unrecoverable */
    }
    return 1; /* non-finite values: CVODE retries with a smaller step */
}

static int rhs(sunrealtype t, N_Vector y, N_Vector ydot, void *data)
{
    user_data *d = (user_data *)data;
    int rc;

    if (WATCH_TICK(&d->w))
        return -1; /* stop: cancelled or out of time */
    rc = d->crhs(t, N_VGetArrayPointer(y), d->p, d->alpha, d->beta, N_VGetArrayPointer(ydot));

    return rc == LCG_DAE_OK ? 0 : fail(d, rc, t);
}

/* CVProjFn: corr = P(ycur) - ycur for the projection P onto f(q, t) = 0, A q' + A0 = 0;
 * err (if not NULL) is replaced by its linearized projection. */
static int proj(sunrealtype t, N_Vector ycur, N_Vector corr, sunrealtype epsProj, N_Vector err, void *data)
{
    user_data *d = (user_data *)data;
    const double *y = N_VGetArrayPointer(ycur);
    double *c = N_VGetArrayPointer(corr), *ynew = d->ynew;
    int i, rc, ny = d->m->ny;
    (void)epsProj;

    rc = d->m->project(t, y, d->p, d->proj_tol, d->proj_maxit, ynew, err != NULL ? N_VGetArrayPointer(err) : NULL);
    if (rc != LCG_DAE_OK)
        return fail(d, rc, t);
    for (i = 0; i < ny; ++i)
        c[i] = ynew[i] - y[i];
    return 0;
}

static int roots(sunrealtype t, N_Vector y, sunrealtype *gout, void *data)
{
    user_data *d = (user_data *)data;
    int rc = d->m->roots(t, N_VGetArrayPointer(y), NULL, d->p, gout);

    if (rc != LCG_DAE_OK) {
        d->st->model_error = rc;
        d->st->t_reached = t;
        return -1;
    }
    return 0;
}

/* The checked (or projected) initial state and the GGL initial values; see lcg_cvc.h. */
int lcg_dae_initial_state(const lcg_dae_model *m, double t, const double *y, const double *p, int mode, double tol,
                          int nineq, double *yy, double *yp)
{
    double *buf, *g, *s, *acc, *lam, *gout;
    int i, r, nq, ny, nj, njh, rc = 1;

    if (!lcg_dae_check(m, NULL, 0))
        return LCG_FLAG_BAD_INPUT;
    nq = m->nq;
    ny = m->ny;
    nj = m->nj;
    njh = m->njh;
    /* g[max(njh, 1)], s[max(nj, 1)], acc[nv = ny - nq], lam[max(nj, 1)], gout[max(nroot, 1)] */
    buf = (double *)malloc(sizeof(double) * (size_t)((njh > 0 ? njh : 1) + 2 * (nj > 0 ? nj : 1) + (ny - nq)
                                                     + (m->nroot > 0 ? m->nroot : 1)));
    if (buf == NULL)
        return LCG_FLAG_NOMEM;
    g = buf;
    s = g + (njh > 0 ? njh : 1);
    acc = s + (nj > 0 ? nj : 1);
    lam = acc + (ny - nq);
    gout = lam + (nj > 0 ? nj : 1);
    if (mode == 1) {
        if (m->residuals(t, y, p, g, s) != LCG_DAE_OK)
            goto done;
        for (r = 0; r < njh; ++r)
            if (!(fabs(g[r]) <= tol))
                goto done;
        for (r = 0; r < nj; ++r)
            if (!(fabs(s[r]) <= tol))
                goto done;
        if (nineq > 0 && m->nroot > 0) {
            if (m->roots(t, y, NULL, p, gout) != LCG_DAE_OK)
                goto done;
            for (r = 0; r < nineq && r < m->nroot; ++r)
                if (!(gout[r] >= -tol))
                    goto done;
        }
        if (m->kkt(t, y, p, 0.0, 0.0, acc, lam) != LCG_DAE_OK)
            goto done;
        if (m->project(t, y, p, 1e-14, 50, yy, NULL) != LCG_DAE_OK)
            goto done;
    } else if (mode == 2) {
        if (m->project(t, y, p, 1e-14, 50, yy, NULL) != LCG_DAE_OK)
            goto done;
        if (m->residuals(t, yy, p, g, s) != LCG_DAE_OK)
            goto done;
        for (r = 0; r < njh; ++r)
            if (fabs(g[r]) > tol)
                goto done;
        for (r = 0; r < nj; ++r)
            if (fabs(s[r]) > tol)
                goto done;
    } else {
        for (i = 0; i < ny; ++i)
            yy[i] = y[i];
    }
    if (m->kkt(t, yy, p, 0.0, 0.0, acc, lam) != LCG_DAE_OK)
        goto done;
    if (yp != NULL) { /* GGL: yp = (q', v') of the index-1 right-hand side (q' = v, or k(q, v, t)) */
        if (m->crhs(t, yy, p, 0.0, 0.0, yp) != LCG_DAE_OK)
            goto done;
        for (r = 0; r < nj; ++r)
            yy[ny + r] = lam[r];
        for (i = ny + nj; i < m->ng; ++i)
            yy[i] = 0.0; /* mu */
        for (i = ny; i < m->ng; ++i)
            yp[i] = 0.0;
    }
    rc = 0;
done:
    free(buf);
    return rc;
}

/* Integrate from tout[0] with y(tout[0]) = y0; see lcg_cvc.h. */
int lcg_cvc_solve(const lcg_dae_model *m, const double *p, const double *y0, int nt, const double *tout,
                  double *yout, double *out, const lcg_cvc_options *opt, lcg_cvc_stats *st, lcg_events *ev)
{
    SUNContext ctx = NULL;
    void *mem = NULL;
    N_Vector y = NULL, abstol = NULL;
    SUNMatrix A = NULL;
    SUNLinearSolver LS = NULL;
    user_data data;
    double *yv;
    long nst = 0;
    int k, i, flag = 0, rc, ny, nout, roots_on;

    memset(st, 0, sizeof *st);
    st->t_reached = tout[0];
    if (!lcg_dae_check(m, st->message, sizeof st->message))
        return st->flag = LCG_FLAG_BAD_INPUT;
    ny = m->ny;
    nout = m->nout;
    roots_on = opt->roots && ev != NULL && m->nroot > 0;
    data.crhs = m->crhs;
    data.m = m;
    data.p = p;
    data.alpha = opt->alpha;
    data.beta = opt->beta;
    if (opt->alpha < 0.0 || opt->beta < 0.0) { /* "auto": the rate of the fastest motion at y0 */
        double rate = 0.0;
        if (m->natural_rate(tout[0], y0, p, &rate) != LCG_DAE_OK)
            rate = 0.0; /* the run reports the model's error at its first step */
        if (opt->alpha < 0.0)
            data.alpha = rate;
        if (opt->beta < 0.0)
            data.beta = rate;
    }
    st->alpha = data.alpha;
    st->beta = data.beta;
    data.proj_tol = opt->proj_tol;
    data.proj_maxit = opt->proj_maxit > 0 ? opt->proj_maxit : 10;
    data.st = st;
    data.ynew = NULL;
    data.info = NULL;
    watch_init(&data.w, opt->cancel, opt->poll, opt->poll_data, opt->poll_every, opt->max_wall, nt, &st->nt_done);
    if (ev != NULL) {
        ev->n_events = 0;
        ev->terminated = 0;
    }
    LCG_CREATE_CONTEXT(LCG_FLAG_NOMEM);

    y = N_VNew_Serial(ny, ctx);
    mem = CVodeCreate(opt->method, ctx);
    A = SUNDenseMatrix(ny, ny, ctx);
    if (opt->projection && (data.ynew = (double *)malloc(sizeof(double) * (size_t)ny)) == NULL) {
        flag = LCG_FLAG_NOMEM;
        goto done;
    }
    if (roots_on && (data.info = (int *)malloc(sizeof(int) * (size_t)m->nroot)) == NULL) {
        flag = LCG_FLAG_NOMEM;
        goto done;
    }
    if (y == NULL || mem == NULL || A == NULL) {
        flag = LCG_FLAG_NOMEM;
        goto done;
    }
    LS = SUNLinSol_Dense(y, A, ctx);
    yv = N_VGetArrayPointer(y);
    for (i = 0; i < ny; ++i)
        yv[i] = y0[i];

    rc = m->coutputs(tout[0], y0, NULL, p, out);
    LCG_MODEL_ERROR(LCG_DAE_OK);
    for (i = 0; i < ny; ++i)
        yout[i] = y0[i];
    st->nt_done = 1;

    if ((flag = CVodeInit(mem, rhs, tout[0], y)) < 0)
        goto done;
    flag = set_tolerances(mem, 0, ctx, ny, opt->rtol, opt->atol, opt->atol_vec, -1, &abstol, LCG_FLAG_NOMEM);
    if (flag < 0)
        goto done;
    CVodeSetUserData(mem, &data);
    if ((flag = CVodeSetLinearSolver(mem, LS, A)) < 0)
        goto done;
    if (opt->projection) {
        if ((flag = CVodeSetProjFn(mem, proj)) < 0)
            goto done;
        if ((flag = CVodeSetProjErrEst(mem, opt->proj_err ? 1 : 0)) < 0)
            goto done;
    }
    if (roots_on) {
        if ((flag = CVodeRootInit(mem, m->nroot, roots)) < 0)
            goto done;
        if (ev->rootdir != NULL && (flag = CVodeSetRootDirection(mem, (int *)ev->rootdir)) < 0)
            goto done;
        CVodeSetNoInactiveRootWarn(mem);
    }
    if ((flag = set_step_limits(mem, 0, opt->max_order, opt->first_step, opt->max_step, opt->min_step)) < 0)
        goto done;
    if (nt > 1 && (flag = CVodeSetStopTime(mem, tout[nt - 1])) < 0)
        goto done;

    for (k = 1; k < nt; ++k) {
        double tret = tout[k - 1];
        if (WATCH_TICK(&data.w))
            goto done;
        for (;;) {
            LCG_STEP_BUDGET(CVode);
            flag = CVode(mem, tout[k], y, &tret, CV_NORMAL);
            st->t_reached = tret;
            if (flag == CV_ROOT_RETURN && roots_on) {
                if (record_events(mem, ev, tret, yv, m->nroot, ny, data.info)) {
                    ev->terminated = 1;
                    goto done;
                }
                continue;
            }
            break;
        }
        if (flag < 0)
            goto done;
        for (i = 0; i < ny; ++i)
            yout[(long)k * ny + i] = yv[i];
        rc = m->coutputs(tret, yv, NULL, p, out + (long)k * nout);
        LCG_MODEL_ERROR(LCG_DAE_OK);
        st->nt_done = k + 1;
    }

done:
    flag = watch_flag(&data.w, flag, st->message, sizeof st->message);
    if (mem != NULL) {
        CVodeGetNumSteps(mem, &st->nsteps);
        CVodeGetNumRhsEvals(mem, &st->nrhs);
        CVodeGetNumLinRhsEvals(mem, &st->nrhs_dq);
        CVodeGetNumJacEvals(mem, &st->njac);
        CVodeGetNumLinSolvSetups(mem, &st->nlinsetups);
        CVodeGetNumErrTestFails(mem, &st->netfails);
        CVodeGetNumNonlinSolvIters(mem, &st->nniters);
        CVodeGetNumNonlinSolvConvFails(mem, &st->nncfails);
        CVodeGetLastStep(mem, &st->h_last);
        if (opt->projection) {
            CVodeGetNumProjEvals(mem, &st->nproj);
            CVodeGetNumProjFails(mem, &st->nprojfails);
        }
        if (roots_on)
            CVodeGetNumGEvals(mem, &st->ngevals);
        if (flag < 0 && flag > LCG_FLAG_MODEL_ERROR && st->model_error == 0)
            CVodeGetCurrentTime(mem, &st->t_reached);
    }
    st->flag = flag;
    LCG_NOMEM_MESSAGE(LCG_FLAG_NOMEM, "CVODE");
    CVodeFree(&mem);
    free_solver(LS, NULL, A, (N_Vector[]){abstol, y}, 2, &ctx);
    free(data.ynew);
    free(data.info);
    return flag < 0 ? flag : 0;
}

#define COUNTS(c, st) (c[0] = (st)->nsteps, c[1] = (st)->nrhs + (st)->nrhs_dq, c[2] = (st)->njac, \
                       c[3] = (st)->netfails, c[4] = (st)->nncfails)

#define LCG_POOL_ENSEMBLE lcg_cvc_ensemble
#define LCG_POOL_OPTIONS lcg_cvc_options
#define LCG_POOL_STATS lcg_cvc_stats
#define LCG_POOL_SOLVE_MANY lcg_cvc_solve_many
#define LCG_POOL_EVENTS lcg_events
#include "lcg_pool.h"

static int pool_member(lcg_cvc_ensemble *e, const double *pi, const double *y0i, const double *yp0i,
                       const lcg_cvc_options *o, lcg_cvc_stats *st, double *yout, double *out, pool_scratch *s)
{
    int rc = lcg_cvc_solve(e->model, pi, y0i, e->nt, e->tout, yout, out, o, st, &s->evs);

    (void)yp0i;
    s->ev_n = s->evs.n_events;
    s->ev_term = s->evs.terminated;
    if (s->evs.terminated && s->evs.n_events > 0 && s->evs.n_events <= s->maxev) {
        int j;
        s->ylast = s->evs.y + (long)(s->evs.n_events - 1) * NROW;
        s->tlast = s->evs.t[s->evs.n_events - 1];
        if (e->model->coutputs(s->tlast, s->ylast, NULL, pi, s->olast) != LCG_DAE_OK)
            for (j = 0; j < NOUTD; ++j)
                s->olast[j] = NAN;
    }
    return rc;
}
