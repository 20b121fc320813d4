/* lcg_cvode_stepper.c -- lagcodegen's runtime: the CVODE integration that lives between calls
 * (see lcg_cvode_stepper.h).
 *
 * One translation unit with the run driver lcg_cvode.c, included here, so that CVODE calls the
 * driver's own right-hand side and Jacobian callbacks (dense, band in the interleaved order,
 * sparse into dense, run control, non-finite values reported as recoverable) with the same
 * options; a grid from a fresh stepper gives the numbers of lcg_cvode_solve on the same times.
 * Events: the driver's root finding (roots_init, roots_found), recorded per call; a root within
 * rounding of the time CVODE (re)started from is not reported, as in lcg_cvode_solve_events.
 * The module built from this file replaces lcg_cvode.c's own. */
#include "lcg_cvode.c"

#include "lcg_cvode_stepper.h"
#include "lcg_stepper.h"

struct lcg_cvode_stepper {
    const lcg_model *m;
    lcg_cvode_options opt;      /* the caller's, atol_vec pointing at the copy b.atol */
    lcg_cvode_stats st;         /* of the last call */
    user_data data;             /* what the callbacks see (lcg_cvode.c) */
    lcg_stepper_memory b;       /* the caller's time, state and parameters, as the last call left them */
    double *yout;               /* the grid rows of the current call */
    double t_start;             /* the time of the last CVodeInit / CVodeReInit */
    lcg_events *ev;             /* the caller's record of the events found, or NULL */
    int roots_on;               /* root finding on the event functions data.r */
    SUNContext ctx;
    void *mem;
    N_Vector yv, abstol;
    SUNMatrix A;
    SUNLinearSolver LS;
    SUNNonlinearSolver NLS;
};

void lcg_cvode_stepper_free(lcg_cvode_stepper *s)
{
    if (s == NULL)
        return;
    if (s->mem != NULL)
        CVodeFree(&s->mem);
    free_solver(s->LS, s->NLS, s->A, (N_Vector[]){s->abstol, s->yv}, 2, &s->ctx);
    free(s->data.yb);
    free(s->data.fb);
    free(s->data.vals);
    free(s->data.jd);
    free(s->data.info);
    lcg_stepper_unbind(&s->b);
    free(s);
}

lcg_cvode_stats *lcg_cvode_stepper_stats(lcg_cvode_stepper *s)
{
    return &s->st;
}

/* The caller's state into CVODE's vector (interleaved for the band solver). */
static void cs_load(lcg_cvode_stepper *s)
{
    double *yv = N_VGetArrayPointer(s->yv);
    int i;

    if (s->opt.linear_solver == 1)
        scatter(s->m, s->b.y, yv);
    else
        for (i = 0; i < s->m->ny; ++i)
            yv[i] = s->b.y[i];
}

/* CVODE's vector into the caller's state. */
static void cs_store(lcg_cvode_stepper *s, double *y)
{
    double *yv = N_VGetArrayPointer(s->yv);
    int i;

    if (s->opt.linear_solver == 1)
        gather(s->m, yv, y);
    else
        for (i = 0; i < s->m->ny; ++i)
            y[i] = yv[i];
}

/* CVODE's vector into the grid row k of the call (lcg_stepper_hooks). */
static void cs_row(void *x, int k)
{
    lcg_cvode_stepper *s = (lcg_cvode_stepper *)x;

    cs_store(s, s->yout + (long)k * s->m->ny);
}

/* The options of lcg_cvode_solve, on the stepper's CVODE memory: 0 or a negative flag. */
static int cs_setup(lcg_cvode_stepper *s, char *message, size_t size)
{
    const lcg_model *m = s->m;
    const lcg_cvode_options *opt = &s->opt;
    int flag, ny = m->ny, band = opt->linear_solver == 1, fixedpoint = opt->linear_solver == 2;
    int use_jac = opt->jacobian && (m->jac != NULL || m->jac_sparse != NULL);

    if (band && (opt->mupper < 0 || opt->mlower < 0 || opt->mupper >= ny || opt->mlower >= ny)) {
        snprintf(message, size, "band solver: bandwidths mu = %ld, ml = %ld out of range", opt->mupper,
                 opt->mlower);
        return LCG_FLAG_BAD_INPUT;
    }
    s->yv = N_VNew_Serial(ny, s->ctx);
    s->mem = CVodeCreate(opt->method, s->ctx);
    if (!fixedpoint)
        s->A = band ? SUNBandMatrix(ny, opt->mupper, opt->mlower, s->ctx) : SUNDenseMatrix(ny, ny, s->ctx);
    if (band && ((s->data.yb = (double *)malloc(sizeof(double) * (size_t)ny)) == NULL
                 || (s->data.fb = (double *)malloc(sizeof(double) * (size_t)ny)) == NULL))
        return LCG_FLAG_NOMEM;
    if (use_jac && m->jac_sparse != NULL && (band || m->jac == NULL)
        && (s->data.vals = (double *)malloc(sizeof(double) * (size_t)(m->jac_nnz > 0 ? m->jac_nnz : 1))) == NULL)
        return LCG_FLAG_NOMEM;
    if (use_jac && band && m->jac_sparse == NULL
        && (s->data.jd = (double *)malloc(sizeof(double) * (size_t)ny * (size_t)ny)) == NULL)
        return LCG_FLAG_NOMEM;
    if (s->roots_on && (s->data.info = (int *)malloc(sizeof(int) * (size_t)s->data.r->nroot)) == NULL)
        return LCG_FLAG_NOMEM;
    if (s->yv == NULL || s->mem == NULL || (s->A == NULL && !fixedpoint))
        return LCG_FLAG_NOMEM;
    if (!fixedpoint && (s->LS = band ? SUNLinSol_Band(s->yv, s->A, s->ctx) : SUNLinSol_Dense(s->yv, s->A, s->ctx))
        == NULL)
        return LCG_FLAG_NOMEM;
    cs_load(s);
    if ((flag = CVodeInit(s->mem, band ? rhs_band : rhs, s->b.tv[0], s->yv)) < 0)
        return flag;
    flag = set_tolerances(s->mem, 0, s->ctx, ny, opt->rtol, opt->atol, opt->atol_vec, band ? m->nq : -1,
                          &s->abstol, LCG_FLAG_NOMEM);
    if (flag < 0)
        return flag;
    CVodeSetUserData(s->mem, &s->data);
    if (fixedpoint) {
        if ((s->NLS = SUNNonlinSol_FixedPoint(s->yv, 0, s->ctx)) == NULL)
            return LCG_FLAG_NOMEM;
        if ((flag = CVodeSetNonlinearSolver(s->mem, s->NLS)) < 0)
            return flag;
    } else {
        if ((flag = CVodeSetLinearSolver(s->mem, s->LS, s->A)) < 0)
            return flag;
        if (use_jac && (flag = CVodeSetJacFn(s->mem, band ? jac_band : jac)) < 0)
            return flag;
    }
    CVodeSetMaxHnilWarns(s->mem, -1);
    if (s->roots_on && (flag = roots_init(s->mem, &s->data, s->ev)) < 0)
        return flag;
    return lcg_stepper_limits(s->mem, 0, opt->max_order, opt->first_step, opt->max_step, opt->min_step,
                              opt->max_steps);
}

lcg_cvode_stepper *lcg_cvode_stepper_new(const lcg_model *m, const lcg_cvode_options *opt, double *mem,
                                         char *message, size_t size)
{
    return lcg_cvode_stepper_new_events(m, NULL, opt, mem, NULL, message, size);
}

lcg_cvode_stepper *lcg_cvode_stepper_new_events(const lcg_model *m, const lcg_ode_roots *r,
                                                const lcg_cvode_options *opt, double *mem, lcg_events *ev,
                                                char *message, size_t size)
{
    lcg_cvode_stepper *s;
    int flag;

    if (m == NULL || m->abi != LCG_MODEL_ABI || m->rhs == NULL || m->ny != 2 * m->nq + m->nz) {
        snprintf(message, size, "the model table is missing or of another layout");
        return NULL;
    }
    if (opt == NULL || mem == NULL || opt->max_steps < 1 || !isfinite(mem[0])) {
        snprintf(message, size, "bad options (max_steps >= 1) or a non-finite time");
        return NULL;
    }
    if ((s = (lcg_cvode_stepper *)lcg_stepper_alloc(sizeof *s, message, size)) == NULL)
        return NULL;
    s->m = m;
    s->opt = *opt;
    s->opt.cancel = NULL;
    if (lcg_stepper_bind(&s->b, mem, m->ny, m->np, NULL, 0, opt->atol_vec, m->ny) != 0
        || create_context(&s->ctx, &s->st) != 0) {
        snprintf(message, size, "out of memory");
        lcg_cvode_stepper_free(s);
        return NULL;
    }
    s->opt.atol_vec = s->b.atol;
    s->data.m = m;
    s->data.p = s->b.p;
    s->data.st = &s->st;
    s->data.mu = opt->mupper; /* band solver: the bandwidths the Jacobian is copied within */
    s->data.ml = opt->mlower;
    s->data.r = r;
    s->ev = ev;
    s->roots_on = r != NULL && ev != NULL && r->nroot > 0 && r->roots != NULL;
    s->t_start = mem[0];
    flag = cs_setup(s, message, size);
    if (flag < 0) {
        if (message[0] == '\0' || flag == LCG_FLAG_NOMEM)
            lcg_stepper_setup_failed(message, size, flag, LCG_FLAG_NOMEM, "CVODE", s->st.message);
        lcg_cvode_stepper_free(s);
        return NULL;
    }
    lcg_stepper_keep(&s->b);
    return s;
}

/* The roots CVODE returned at tret (lcg_stepper_hooks): a root within rounding of the time CVODE
 * (re)started from is not reported. */
static int cs_record(void *x, double tret)
{
    lcg_cvode_stepper *s = (lcg_cvode_stepper *)x;
    int before = s->ev->n_events;

    if (roots_found(s->mem, &s->data, s->ev, tret, s->t_start, N_VGetArrayPointer(s->yv))) {
        s->ev->terminated = 1;
        return 1;
    }
    return s->ev->n_events > before ? 0 : -1;
}

int lcg_cvode_stepper_advance(lcg_cvode_stepper *s, double t_end, int nt, const double *tout, double *yout,
                              int one_step)
{
    lcg_cvode_stats *st = &s->st;
    const lcg_cvode_options *opt = &s->opt;
    user_data *d = &s->data;
    const lcg_stepper_hooks hooks = {s->mem, 0, s->yv, NULL, s, s->roots_on ? cs_record : NULL, cs_row, &d->w, 0};
    double t = s->b.tv[0], tret = t;
    int k, flag;

    LCG_STEPPER_NEW_CALL(st, s->ev);
    d->nonfinite = 0;
    watch_init(&d->w, opt->cancel, opt->poll, opt->poll_data, opt->poll_every, opt->max_wall, nt, &st->nt_done);
    if ((flag = lcg_stepper_begin(&s->b, t_end, nt, tout, yout != NULL, st->message, sizeof st->message)) < 0)
        goto out;
    if (s->b.restart) {
        cs_load(s);
        if ((flag = CVodeReInit(s->mem, t, s->yv)) < 0)
            goto out;
        s->b.restart = 0;
        s->t_start = t;
    }
    s->yout = yout;
    st->nt_done = k = lcg_stepper_rows_now(0, nt, tout, t, s->b.y, s->m->ny, yout);
    flag = lcg_stepper_drive(&hooks, t, t_end, nt, tout, k, one_step, &tret, &st->nt_done);
    if (tret > t || flag < 0) {
        cs_store(s, s->b.y);
        s->b.tv[0] = tret;
    }

out:
    flag = watch_flag(&d->w, flag, st->message, sizeof st->message);
    flag = lcg_nonfinite_flag(flag, d->nonfinite, d->t_nonfinite, &st->model_error, &st->t_reached);
    flag = lcg_stepper_settle(&s->b, flag, st->model_error, 0);
    LCG_STEPPER_CVODE_COUNTS(s->mem, st);
    CVodeGetNumLinRhsEvals(s->mem, &st->nrhs_dq);
    CVodeGetNumJacEvals(s->mem, &st->njac);
    LCG_STEPPER_END_CALL(st, flag, s->b.tv[0]);
    lcg_stepper_keep(&s->b);
    return st->flag;
}

/* lcg_cvode_stepper_until, lcg_cvode_stepper_grid, lcg_cvode_stepper_step */
LCG_STEPPER_CALLS(cvode)
