/* lcg_ida.c -- lagcodegen's runtime, compiled as it is.
 *
 * The native IDA driver of the constrained equations in the stabilized index-2 form of Gear,
 * Gupta and Leimkuhler (GGL), for every constrained model, called through the model's function
 * table (lcg_dae_model.h): unknowns yy = (q, v, lambda, mu) and the residual (m->ggl_res)
 *   q' - v - A_h^T mu,  M v' - F - A^T lambda  (eq. 4.5),  f(q, t) (eq. 4.1),  A v + A0 (eqs. 4.2, 4.3).
 * lambda and mu are algebraic (IDASetId) and, by default, excluded from the error test
 * (IDASetSuppressAlg). Consistent lambda, mu and yp come from IDACalcIC(IDA_YA_YDP_INIT). The
 * scratch arrays a run needs are allocated once per run, never per call. */
#include "lcg_control.h" /* first: POSIX */

#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "sundials_api.h"
#include "lcg_cvc.h" /* lcg_dae_check */
#include "lcg_ida.h"

#define LCG_STATS lcg_ida_stats
#define LCG_ROOT_INFO IDAGetRootInfo
#include "lcg_sundials.h"

/* The ensemble pool's row sizes (lcg_pool.h): the model of the ensemble e. */
#define NROW (e->model->ng)
#define NOUT (e->model->nout)
#define NOUTD (NOUT > 0 ? NOUT : 1)

typedef struct {
    int (*res)(double t, const double *yy, const double *yp, const double *p, double *rr);
    const lcg_dae_model *m;
    const double *p;
    lcg_ida_stats *st;
    watch w;   /* cancellation, poll callback, wall-clock limit */
    int *info; /* root finding: the roots found (nroot), or NULL */
} user_data;

static int res(sunrealtype t, N_Vector yy, N_Vector yp, N_Vector rr, void *data)
{
    user_data *d = (user_data *)data;
    int rc;

    if (WATCH_TICK(&d->w))
        return -1; /* stop: cancelled or out of time */
    rc = d->res(t, N_VGetArrayPointer(yy), N_VGetArrayPointer(yp), d->p, N_VGetArrayPointer(rr));

    return rc == LCG_DAE_OK ? 0 : 1; /* non-finite: IDA retries with a smaller step */
}

static int jac(sunrealtype t, sunrealtype cj, N_Vector yy, N_Vector yp, N_Vector r, SUNMatrix J, void *data,
               N_Vector tmp1, N_Vector tmp2, N_Vector tmp3)
{
    user_data *d = (user_data *)data;
    int rc = d->m->ggl_jac(t, cj, N_VGetArrayPointer(yy), N_VGetArrayPointer(yp), d->p, SUNDenseMatrix_Data(J));
    (void)r;
    (void)tmp1;
    (void)tmp2;
    (void)tmp3;
    return rc == LCG_DAE_OK ? 0 : 1;
}

static int roots(sunrealtype t, N_Vector yy, N_Vector yp, sunrealtype *gout, void *data)
{
    user_data *d = (user_data *)data;
    const double *y = N_VGetArrayPointer(yy);
    int rc = d->m->roots(t, y, y + d->m->ny, d->p, gout);
    (void)yp;

    if (rc != LCG_DAE_OK) {
        d->st->model_error = rc;
        d->st->t_reached = t;
        return -1;
    }
    return 0;
}

/* Outputs of a GGL row yy = (q, v, lambda, mu): the multipliers from the row. */
static int row_outputs(const lcg_dae_model *m, double t, const double *yy, const double *p, double *out)
{
    return m->coutputs(t, yy, yy + m->ny, p, out);
}

/* Integrate from tout[0]; see lcg_ida.h. */
int lcg_ida_solve(const lcg_dae_model *m, const double *p, const double *yy0, const double *yp0, int nt,
                  const double *tout, double *yout, double *out, const lcg_ida_options *opt, lcg_ida_stats *st,
                  lcg_events *ev)
{
    SUNContext ctx = NULL;
    void *mem = NULL;
    N_Vector yy = NULL, yp = NULL, id = NULL, abstol = NULL, ictol = NULL;
    SUNMatrix A = NULL;
    SUNLinearSolver LS = NULL;
    user_data data;
    double *yv, *ypv;
    long nst = 0;
    int k, i, flag = 0, rc, ny, ng, nout, roots_on;

    memset(st, 0, sizeof *st);
    st->t_reached = tout[0];
    if (!lcg_dae_check(m, st->message, sizeof st->message))
        return st->flag = LCG_FLAG_BAD_INPUT;
    if (m->ggl_res == NULL) {
        snprintf(st->message, sizeof st->message, "the model was compiled without the GGL residual");
        return st->flag = LCG_FLAG_BAD_INPUT;
    }
    ny = m->ny;
    ng = m->ng;
    nout = m->nout;
    roots_on = opt->roots && ev != NULL && m->nroot > 0;
    data.res = m->ggl_res;
    data.m = m;
    data.p = p;
    data.st = st;
    data.info = NULL;
    watch_init(&data.w, opt->cancel, opt->poll, opt->poll_data, opt->poll_every, opt->max_wall, nt, &st->nt_done);
    if (ev != NULL) {
        ev->n_events = 0;
        ev->terminated = 0;
    }
    LCG_CREATE_CONTEXT(LCG_FLAG_NOMEM_IDA);

    if ((flag = ida_create(ctx, ng, ny, &yy, &yp, &id, &mem, &A, &LS, LCG_FLAG_NOMEM_IDA)) != 0)
        goto done;
    if (roots_on && (data.info = (int *)malloc(sizeof(int) * (size_t)m->nroot)) == NULL) {
        flag = LCG_FLAG_NOMEM_IDA;
        goto done;
    }
    yv = N_VGetArrayPointer(yy);
    ypv = N_VGetArrayPointer(yp);
    for (i = 0; i < ng; ++i) {
        yv[i] = yy0[i];
        ypv[i] = yp0[i];
    }

    if ((flag = ida_init(mem, res, tout[0], yy, yp, id, &data, opt->suppress_alg, LS, A)) < 0)
        goto done;
    flag = set_tolerances(mem, 1, ctx, ng, opt->rtol, opt->atol, opt->atol_vec, -1, &abstol, LCG_FLAG_NOMEM_IDA);
    if (flag < 0)
        goto done;
    if (opt->jacobian && m->ggl_jac != NULL && (flag = IDASetJacFn(mem, jac)) < 0)
        goto done;
    if ((flag = ida_roots(mem, roots_on ? m->nroot : 0, roots, roots_on ? ev->rootdir : NULL)) < 0)
        goto done;
    if ((flag = set_step_limits(mem, 1, opt->max_order, opt->first_step, opt->max_step, opt->min_step)) < 0)
        goto done;
    if (nt > 1 && (flag = IDASetStopTime(mem, tout[nt - 1])) < 0)
        goto done;

    if (opt->calc_ic && nt > 1) {
        /* IDACalcIC's convergence test weighs every component, and in the index-2 GGL system
         * round-off in q is amplified by cj^2 in lambda: loose absolute tolerances on lambda, mu
         * (ic_alg_atol) for the initial-condition solve only, the run's own afterwards. */
        ictol = N_VNew_Serial(ng, ctx);
        if (ictol == NULL) {
            flag = LCG_FLAG_NOMEM_IDA;
            goto done;
        }
        for (i = 0; i < ng; ++i)
            N_VGetArrayPointer(ictol)[i] = i >= ny ? opt->ic_alg_atol
                                           : (opt->atol_vec != NULL ? opt->atol_vec[i] : opt->atol);
        if ((flag = IDASVtolerances(mem, opt->rtol, ictol)) < 0)
            goto done;
        flag = IDACalcIC(mem, IDA_YA_YDP_INIT, tout[1]);
        st->ic_flag = flag;
        if (flag < 0)
            goto done;
        if ((flag = IDAGetConsistentIC(mem, yy, yp)) < 0)
            goto done;
        flag = abstol != NULL ? IDASVtolerances(mem, opt->rtol, abstol) : IDASStolerances(mem, opt->rtol, opt->atol);
        if (flag < 0)
            goto done;
        /* New tolerances after IDACalcIC's setup: restart from the consistent values so that
         * IDASolve runs its initial setup again (error weights from the run's tolerances). */
        if ((flag = IDAReInit(mem, tout[0], yy, yp)) < 0)
            goto done;
    }
    rc = row_outputs(m, tout[0], yv, p, out);
    LCG_MODEL_ERROR(LCG_DAE_OK);
    for (i = 0; i < ng; ++i)
        yout[i] = yv[i];
    st->nt_done = 1;

    for (k = 1; k < nt; ++k) {
        double tret = tout[k - 1];
        if (WATCH_TICK(&data.w))
            goto done;
        for (;;) {
            LCG_STEP_BUDGET(IDA);
            /* Stop exactly at the output times: values there are step values, which satisfy the
             * constraints to the Newton tolerance (interpolated ones only to the interpolation error). */
            if (opt->stop_at_outputs && (flag = IDASetStopTime(mem, tout[k])) < 0)
                goto done;
            flag = IDASolve(mem, tout[k], &tret, yy, yp, IDA_NORMAL);
            st->t_reached = tret;
            if (flag == IDA_ROOT_RETURN && roots_on) {
                if (record_events(mem, ev, tret, yv, m->nroot, ng, data.info)) {
                    ev->terminated = 1;
                    goto done;
                }
                continue;
            }
            break;
        }
        if (flag < 0)
            goto done;
        for (i = 0; i < ng; ++i)
            yout[(long)k * ng + i] = yv[i];
        rc = row_outputs(m, tret, yv, p, out + (long)k * nout);
        LCG_MODEL_ERROR(LCG_DAE_OK);
        st->nt_done = k + 1;
    }

done:
    flag = watch_flag(&data.w, flag, st->message, sizeof st->message);
    if (mem != NULL) {
        IDAGetNumSteps(mem, &st->nsteps);
        IDAGetNumResEvals(mem, &st->nres);
        IDAGetNumLinResEvals(mem, &st->nres_dq);
        IDAGetNumJacEvals(mem, &st->njac);
        IDAGetNumLinSolvSetups(mem, &st->nlinsetups);
        IDAGetNumErrTestFails(mem, &st->netfails);
        IDAGetNumNonlinSolvIters(mem, &st->nniters);
        IDAGetNumNonlinSolvConvFails(mem, &st->nncfails);
        IDAGetNumBacktrackOps(mem, &st->nbacktracks);
        IDAGetLastStep(mem, &st->h_last);
        if (roots_on)
            IDAGetNumGEvals(mem, &st->ngevals);
        if (flag < 0 && flag > LCG_FLAG_MODEL_ERROR && st->model_error == 0)
            IDAGetCurrentTime(mem, &st->t_reached);
    }
    st->flag = flag;
    LCG_NOMEM_MESSAGE(LCG_FLAG_NOMEM_IDA, "IDA");
    IDAFree(&mem);
    free_solver(LS, NULL, A, (N_Vector[]){abstol, ictol, id, yp, yy}, 5, &ctx);
    free(data.info);
    return flag < 0 ? flag : 0;
}

#define COUNTS(c, st) (c[0] = (st)->nsteps, c[1] = (st)->nres + (st)->nres_dq, c[2] = (st)->njac, \
                       c[3] = (st)->netfails, c[4] = (st)->nncfails)

#define LCG_POOL_ENSEMBLE lcg_ida_ensemble
#define LCG_POOL_OPTIONS lcg_ida_options
#define LCG_POOL_STATS lcg_ida_stats
#define LCG_POOL_SOLVE_MANY lcg_ida_solve_many
#define LCG_POOL_EVENTS lcg_events
#define LCG_POOL_YP0
#include "lcg_pool.h"

static int pool_member(lcg_ida_ensemble *e, const double *pi, const double *y0i, const double *yp0i,
                       const lcg_ida_options *o, lcg_ida_stats *st, double *yout, double *out, pool_scratch *s)
{
    int rc = lcg_ida_solve(e->model, pi, y0i, yp0i, e->nt, e->tout, yout, out, o, st, &s->evs);

    s->ev_n = s->evs.n_events;
    s->ev_term = s->evs.terminated;
    if (s->evs.terminated && s->evs.n_events > 0 && s->evs.n_events <= s->maxev) {
        int j;
        s->ylast = s->evs.y + (long)(s->evs.n_events - 1) * NROW;
        s->tlast = s->evs.t[s->evs.n_events - 1];
        if (row_outputs(e->model, s->tlast, s->ylast, pi, s->olast) != LCG_DAE_OK)
            for (j = 0; j < NOUTD; ++j)
                s->olast[j] = NAN;
    }
    return rc;
}
