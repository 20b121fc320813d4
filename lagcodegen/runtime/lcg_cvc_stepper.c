/* lcg_cvc_stepper.c -- lagcodegen's runtime: the index-1 integration of a constrained system that
 * lives between calls (see lcg_cvc_stepper.h).
 *
 * One translation unit with the run driver lcg_cvc.c, included here, so that CVODE calls the
 * driver's own right-hand side (the augmented system with Baumgarte terms), projection and root
 * functions with the same options; a grid from a fresh stepper gives the numbers of
 * lcg_cvc_solve on the same times. The module built from this file replaces lcg_cvc.c's own. */
#include "lcg_cvc.c"

#include "lcg_cvc_stepper.h"
#include "lcg_stepper.h"

struct lcg_cvc_stepper {
    const lcg_dae_model *m;
    lcg_cvc_options opt;        /* the caller's, atol_vec pointing at the copy b.atol */
    lcg_cvc_stats st;           /* of the last call */
    user_data data;             /* what the callbacks see (lcg_cvc.c) */
    lcg_events *ev;             /* the caller's record, or NULL */
    int roots_on;
    lcg_stepper_memory b;       /* the caller's time, state and parameters, as the last call left them */
    double *yout;               /* the grid rows of the current call */
    SUNContext ctx;
    void *mem;
    N_Vector yv, abstol;
    SUNMatrix A;
    SUNLinearSolver LS;
};

void lcg_cvc_stepper_free(lcg_cvc_stepper *s)
{
    if (s == NULL)
        return;
    if (s->mem != NULL)
        CVodeFree(&s->mem);
    free_solver(s->LS, NULL, s->A, (N_Vector[]){s->abstol, s->yv}, 2, &s->ctx);
    free(s->data.ynew);
    free(s->data.info);
    lcg_stepper_unbind(&s->b);
    free(s);
}

lcg_cvc_stats *lcg_cvc_stepper_stats(lcg_cvc_stepper *s)
{
    return &s->st;
}

/* CVODE's vector into y (ny values). */
static void cc_store(lcg_cvc_stepper *s, double *y)
{
    const double *yv = N_VGetArrayPointer(s->yv);
    int i;

    for (i = 0; i < s->m->ny; ++i)
        y[i] = yv[i];
}

/* CVODE's vector into the grid row k of the call (lcg_stepper_hooks). */
static void cc_row(void *x, int k)
{
    lcg_cvc_stepper *s = (lcg_cvc_stepper *)x;

    cc_store(s, s->yout + (long)k * s->m->ny);
}

/* The options of lcg_cvc_solve, on the stepper's CVODE memory: 0 or a negative flag. */
static int cc_setup(lcg_cvc_stepper *s)
{
    const lcg_dae_model *m = s->m;
    const lcg_cvc_options *opt = &s->opt;
    int i, flag, ny = m->ny;

    s->yv = N_VNew_Serial(ny, s->ctx);
    s->mem = CVodeCreate(opt->method, s->ctx);
    s->A = SUNDenseMatrix(ny, ny, s->ctx);
    if (opt->projection && (s->data.ynew = (double *)malloc(sizeof(double) * (size_t)ny)) == NULL)
        return LCG_FLAG_NOMEM;
    if (s->roots_on && (s->data.info = (int *)malloc(sizeof(int) * (size_t)m->nroot)) == NULL)
        return LCG_FLAG_NOMEM;
    if (s->yv == NULL || s->mem == NULL || s->A == NULL || (s->LS = SUNLinSol_Dense(s->yv, s->A, s->ctx)) == NULL)
        return LCG_FLAG_NOMEM;
    for (i = 0; i < ny; ++i)
        N_VGetArrayPointer(s->yv)[i] = s->b.y[i];
    if ((flag = CVodeInit(s->mem, rhs, s->b.tv[0], s->yv)) < 0)
        return flag;
    flag = set_tolerances(s->mem, 0, s->ctx, ny, opt->rtol, opt->atol, opt->atol_vec, -1, &s->abstol,
                          LCG_FLAG_NOMEM);
    if (flag < 0)
        return flag;
    CVodeSetUserData(s->mem, &s->data);
    if ((flag = CVodeSetLinearSolver(s->mem, s->LS, s->A)) < 0)
        return flag;
    if (opt->projection) {
        if ((flag = CVodeSetProjFn(s->mem, proj)) < 0)
            return flag;
        if ((flag = CVodeSetProjErrEst(s->mem, opt->proj_err ? 1 : 0)) < 0)
            return flag;
    }
    if (s->roots_on) {
        if ((flag = CVodeRootInit(s->mem, m->nroot, roots)) < 0)
            return flag;
        if (s->ev->rootdir != NULL && (flag = CVodeSetRootDirection(s->mem, (int *)s->ev->rootdir)) < 0)
            return flag;
        CVodeSetNoInactiveRootWarn(s->mem);
    }
    return lcg_stepper_limits(s->mem, 0, opt->max_order, opt->first_step, opt->max_step, opt->min_step,
                              opt->max_steps);
}

lcg_cvc_stepper *lcg_cvc_stepper_new(const lcg_dae_model *m, const lcg_cvc_options *opt, double *mem,
                                     lcg_events *ev, char *message, size_t size)
{
    lcg_cvc_stepper *s;
    int flag;

    if (!lcg_dae_check(m, message, size))
        return NULL;
    if (opt == NULL || mem == NULL || opt->max_steps < 1 || !isfinite(mem[0])) {
        snprintf(message, size, "bad options (max_steps >= 1) or a non-finite time");
        return NULL;
    }
    if ((s = (lcg_cvc_stepper *)lcg_stepper_alloc(sizeof *s, message, size)) == NULL)
        return NULL;
    s->m = m;
    s->opt = *opt;
    s->opt.cancel = NULL;
    s->ev = ev;
    s->roots_on = opt->roots && ev != NULL && m->nroot > 0;
    if (lcg_stepper_bind(&s->b, mem, m->ny, m->np, NULL, 0, opt->atol_vec, m->ny) != 0
        || create_context(&s->ctx, &s->st) != 0) {
        snprintf(message, size, "out of memory");
        lcg_cvc_stepper_free(s);
        return NULL;
    }
    s->opt.atol_vec = s->b.atol;
    s->data.crhs = m->crhs;
    s->data.m = m;
    s->data.p = s->b.p;
    s->data.alpha = opt->alpha;
    s->data.beta = opt->beta;
    if (opt->alpha < 0.0 || opt->beta < 0.0) { /* "auto": the rate of the fastest motion at the start */
        double rate = 0.0;
        if (m->natural_rate(mem[0], s->b.y, s->b.p, &rate) != LCG_DAE_OK)
            rate = 0.0;
        if (opt->alpha < 0.0)
            s->data.alpha = rate;
        if (opt->beta < 0.0)
            s->data.beta = rate;
    }
    s->data.proj_tol = opt->proj_tol;
    s->data.proj_maxit = opt->proj_maxit > 0 ? opt->proj_maxit : 10;
    s->data.st = &s->st;
    flag = cc_setup(s);
    if (flag < 0) {
        lcg_stepper_setup_failed(message, size, flag, LCG_FLAG_NOMEM, "CVODE", s->st.message);
        lcg_cvc_stepper_free(s);
        return NULL;
    }
    s->st.alpha = s->data.alpha;
    s->st.beta = s->data.beta;
    lcg_stepper_keep(&s->b);
    return s;
}

/* The roots CVODE returned at tret (lcg_stepper_hooks; each one ends a step). */
static int cc_record(void *x, double tret)
{
    lcg_cvc_stepper *s = (lcg_cvc_stepper *)x;

    if (record_events(s->mem, s->ev, tret, N_VGetArrayPointer(s->yv), s->m->nroot, s->m->ny, s->data.info)) {
        s->ev->terminated = 1;
        return 1;
    }
    return 0;
}

int lcg_cvc_stepper_advance(lcg_cvc_stepper *s, double t_end, int nt, const double *tout, double *yout,
                            int one_step)
{
    lcg_cvc_stats *st = &s->st;
    const lcg_cvc_options *opt = &s->opt;
    user_data *d = &s->data;
    const lcg_stepper_hooks hooks = {s->mem, 0, s->yv, NULL, s, s->roots_on ? cc_record : NULL, cc_row, &d->w, 0};
    double t = s->b.tv[0], tret = t, *yv = N_VGetArrayPointer(s->yv);
    int i, k, flag, ny = s->m->ny;

    LCG_STEPPER_NEW_CALL(st, s->ev);
    watch_init(&d->w, opt->cancel, opt->poll, opt->poll_data, opt->poll_every, opt->max_wall, nt, &st->nt_done);
    if ((flag = lcg_stepper_begin(&s->b, t_end, nt, tout, yout != NULL, st->message, sizeof st->message)) < 0)
        goto out;
    if (s->b.restart) {
        for (i = 0; i < ny; ++i)
            yv[i] = s->b.y[i];
        if ((flag = CVodeReInit(s->mem, t, s->yv)) < 0)
            goto out;
        s->b.restart = 0;
    }
    s->yout = yout;
    st->nt_done = k = lcg_stepper_rows_now(0, nt, tout, t, s->b.y, ny, yout);
    flag = lcg_stepper_drive(&hooks, t, t_end, nt, tout, k, one_step, &tret, &st->nt_done);
    if (tret > t || flag < 0) {
        cc_store(s, s->b.y);
        s->b.tv[0] = tret;
    }

out:
    flag = watch_flag(&d->w, flag, st->message, sizeof st->message);
    flag = lcg_stepper_settle(&s->b, flag, st->model_error, 0);
    LCG_STEPPER_CVODE_COUNTS(s->mem, st);
    CVodeGetNumLinRhsEvals(s->mem, &st->nrhs_dq);
    if (opt->projection)
        CVodeGetNumProjEvals(s->mem, &st->nproj);
    if (s->roots_on)
        CVodeGetNumGEvals(s->mem, &st->ngevals);
    LCG_STEPPER_END_CALL(st, flag, s->b.tv[0]);
    lcg_stepper_keep(&s->b);
    return st->flag;
}

/* lcg_cvc_stepper_until, lcg_cvc_stepper_grid, lcg_cvc_stepper_step */
LCG_STEPPER_CALLS(cvc)
