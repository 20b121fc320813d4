/* lcg_cvsens_stepper.c -- lagcodegen's runtime: the CVODE integration with forward sensitivities
 * that lives between calls (see lcg_cvsens_stepper.h).
 *
 * One translation unit with the sensitivity driver lcg_cvsens.c, included here, so that CVODE
 * calls the driver's own augmented right-hand side, corrector (corrector_attach: the staggered
 * nonlinear solver or the block linear solver, the states' matrix I - gamma J for every block)
 * and root function with the same options; a grid
 * from a fresh stepper gives the numbers of lcg_cvsens_solve on the same times. Events: the
 * driver's root finding (sens_roots_init, sens_record), recorded per call; a root within rounding
 * of the time CVODE (re)started from is not reported, as in lcg_cvsens_solve_events. The module
 * built from this file replaces lcg_cvsens.c's own. */
#include "lcg_cvsens.c"

#include "lcg_cvsens_stepper.h"
#include "lcg_stepper.h"

struct lcg_cvsens_stepper {
    const lcg_model *m;
    lcg_cvsens_options opt;     /* the caller's, atol pointing at the copy b.atol */
    lcg_cvsens_stats st;        /* of the last call */
    sens_data data;             /* what the callbacks see (lcg_cvsens.c) */
    int ns;
    int *which;                 /* ns: the directions (copied) */
    lcg_stepper_memory b;       /* the caller's time, state, parameters and sensitivities (b.extra, ns*ny) */
    double *yout, *sout;        /* the grid rows of the current call */
    long total;                 /* ny (1 + ns): the augmented state */
    double t_start;             /* the time of the last CVodeInit / CVodeReInit */
    lcg_cvsens_events *ev;      /* the caller's event functions and record, or NULL */
    int roots_on;
    SUNContext ctx;
    void *mem;
    N_Vector yv;
    SUNLinearSolver LS;
    SUNNonlinearSolver NLS;
};

void lcg_cvsens_stepper_free(lcg_cvsens_stepper *x)
{
    if (x == NULL)
        return;
    if (x->mem != NULL)
        CVodeFree(&x->mem);
    corrector_free(&x->data, x->LS, x->NLS);
    free_solver(NULL, NULL, NULL, (N_Vector[]){x->yv}, 1, &x->ctx);
    free(x->data.J);
    free(x->data.A);
    free(x->data.piv);
    free(x->data.f0);
    free(x->data.f1);
    free(x->data.y1);
    free(x->data.vals);
    free(x->data.info);
    free(x->which);
    lcg_stepper_unbind(&x->b);
    free(x);
}

lcg_cvsens_stats *lcg_cvsens_stepper_stats(lcg_cvsens_stepper *x)
{
    return &x->st;
}

/* The caller's state and sensitivities into CVODE's vector. */
static void xs_load(lcg_cvsens_stepper *x)
{
    double *yv = N_VGetArrayPointer(x->yv);
    long i, ny = x->m->ny;

    for (i = 0; i < ny; ++i)
        yv[i] = x->b.y[i];
    for (i = 0; i < ny * x->ns; ++i)
        yv[ny + i] = x->b.extra[i];
}

/* CVODE's vector into y (ny values) and s (ns*ny). */
static void xs_store(lcg_cvsens_stepper *x, double *y, double *s)
{
    const double *yv = N_VGetArrayPointer(x->yv);
    long i, ny = x->m->ny;

    for (i = 0; i < ny; ++i)
        y[i] = yv[i];
    for (i = 0; i < ny * x->ns; ++i)
        s[i] = yv[ny + i];
}

/* CVODE's vector into the grid row k of the call (lcg_stepper_hooks). */
static void xs_row(void *p, int k)
{
    lcg_cvsens_stepper *x = (lcg_cvsens_stepper *)p;

    xs_store(x, x->yout + (long)k * x->m->ny, x->sout + (long)k * x->m->ny * x->ns);
}

/* The options of lcg_cvsens_solve on the stepper's CVODE memory: 0 or a negative flag. */
static int xs_setup(lcg_cvsens_stepper *x, char *message, size_t size)
{
    const lcg_model *m = x->m;
    const lcg_cvsens_options *opt = &x->opt;
    sens_data *d = &x->data;
    const size_t ny = (size_t)m->ny;
    int flag;

    d->J = (double *)malloc(sizeof(double) * ny * ny);
    d->A = (double *)malloc(sizeof(double) * ny * ny);
    d->piv = (int *)malloc(sizeof(int) * ny);
    d->f0 = (double *)malloc(sizeof(double) * ny);
    d->f1 = (double *)malloc(sizeof(double) * ny);
    d->y1 = (double *)malloc(sizeof(double) * ny);
    d->vals = (double *)malloc(sizeof(double) * (size_t)(m->jac_nnz > 0 ? m->jac_nnz : 1));
    x->yv = N_VNew_Serial((sunindextype)x->total, x->ctx);
    x->mem = CVodeCreate(opt->method, x->ctx);
    if (d->J == NULL || d->A == NULL || d->piv == NULL || d->f0 == NULL || d->f1 == NULL || d->y1 == NULL
        || d->vals == NULL || x->yv == NULL || x->mem == NULL)
        return LCG_FLAG_NOMEM;
    d->mem = x->mem;
    xs_load(x);
    if ((flag = CVodeInit(x->mem, aug_rhs, x->b.tv[0], x->yv)) < 0)
        return flag;
    CVodeSetUserData(x->mem, d);
    if ((flag = sens_tolerances(d, x->mem, opt)) < 0)
        return flag;
    if ((flag = corrector_attach(d, opt, x->ctx, &x->LS, &x->NLS, message, size)) < 0)
        return flag;
    CVodeSetMaxHnilWarns(x->mem, -1);
    if (x->roots_on) {
        d->ev = x->ev;
        if ((flag = sens_roots_init(d)) < 0)
            return flag;
    }
    return lcg_stepper_limits(x->mem, 0, opt->max_order, opt->first_step, opt->max_step, opt->min_step,
                              opt->max_steps);
}

lcg_cvsens_stepper *lcg_cvsens_stepper_new(const lcg_model *m, lcg_sens_rhs_fn sens_rhs, int ns, const int *which,
                                           const lcg_cvsens_options *opt, double *mem, double *s,
                                           lcg_cvsens_events *ev, char *message, size_t size)
{
    lcg_cvsens_stepper *x;
    long i;
    int flag;

    if (m == NULL || m->abi != LCG_MODEL_ABI || m->rhs == NULL || m->ny != 2 * m->nq + m->nz || sens_rhs == NULL) {
        snprintf(message, size, "the model table is missing or of another layout");
        return NULL;
    }
    if (opt == NULL || opt->atol == NULL || mem == NULL || ns < 1 || which == NULL || s == NULL
        || opt->max_steps < 1 || !isfinite(mem[0])) {
        snprintf(message, size, "bad options (max_steps >= 1, at least one direction) or a non-finite time");
        return NULL;
    }
    if ((x = (lcg_cvsens_stepper *)lcg_stepper_alloc(sizeof *x, message, size)) == NULL)
        return NULL;
    x->m = m;
    x->opt = *opt;
    x->ns = ns;
    x->total = (long)m->ny * (1 + ns);
    x->which = (int *)malloc(sizeof(int) * (size_t)ns);
    if (lcg_stepper_bind(&x->b, mem, m->ny, m->np, s, (long)m->ny * ns, opt->atol, x->total) != 0
        || x->which == NULL || create_context(&x->ctx, &x->st) != 0) {
        snprintf(message, size, "out of memory");
        lcg_cvsens_stepper_free(x);
        return NULL;
    }
    for (i = 0; i < ns; ++i)
        x->which[i] = which[i];
    x->opt.atol = x->b.atol;
    x->data.m = m;
    x->data.sens_rhs = sens_rhs;
    x->data.p = x->b.p;
    x->data.ns = ns;
    x->data.which = x->which;
    x->data.jacobian = opt->jacobian;
    x->data.st = &x->st;
    x->ev = ev;
    x->roots_on = ev != NULL && ev->nroot > 0 && ev->roots != NULL;
    x->t_start = mem[0];
    message[0] = '\0';
    flag = xs_setup(x, message, size);
    if (flag < 0) {
        if (message[0] == '\0' || flag == LCG_FLAG_NOMEM)
            lcg_stepper_setup_failed(message, size, flag, LCG_FLAG_NOMEM, "CVODE", x->st.message);
        lcg_cvsens_stepper_free(x);
        return NULL;
    }
    lcg_stepper_keep(&x->b);
    return x;
}

/* The roots CVODE returned at tret (lcg_stepper_hooks): a root within rounding of the time CVODE
 * (re)started from is not reported. */
static int xs_record(void *p, double tret)
{
    lcg_cvsens_stepper *x = (lcg_cvsens_stepper *)p;
    int before = x->ev->n_events;

    if (sens_record(&x->data, tret, x->t_start, N_VGetArrayPointer(x->yv), x->total)) {
        x->ev->terminated = 1;
        return 1;
    }
    return x->ev->n_events > before ? 0 : -1;
}

int lcg_cvsens_stepper_advance(lcg_cvsens_stepper *x, double t_end, int nt, const double *tout, double *yout,
                               double *sout, int one_step)
{
    lcg_cvsens_stats *st = &x->st;
    const lcg_cvsens_options *opt = &x->opt;
    sens_data *d = &x->data;
    const lcg_stepper_hooks hooks = {x->mem, 0, x->yv, NULL, x, x->roots_on ? xs_record : NULL, xs_row, &d->w, 0};
    double t = x->b.tv[0], tret = t;
    int k, flag;

    LCG_STEPPER_NEW_CALL(st, x->ev);
    d->nonfinite = 0;
    watch_init(&d->w, NULL, opt->poll, opt->poll_data, opt->poll_every, opt->max_wall, nt, &st->nt_done);
    flag = lcg_stepper_begin(&x->b, t_end, nt, tout, yout != NULL && sout != NULL, st->message,
                             sizeof st->message);
    if (flag < 0)
        goto out;
    if (x->b.restart) {
        xs_load(x);
        if ((flag = CVodeReInit(x->mem, t, x->yv)) < 0)
            goto out;
        corrector_reset(d); /* as a new run: the states' Jacobian evaluated at the first solve */
        x->b.restart = 0;
        x->t_start = t;
    }
    x->yout = yout;
    x->sout = sout;
    /* grid times at the current time: the current state and sensitivities */
    lcg_stepper_rows_now(0, nt, tout, t, x->b.extra, x->b.n_extra, sout);
    st->nt_done = k = lcg_stepper_rows_now(0, nt, tout, t, x->b.y, x->m->ny, yout);
    flag = lcg_stepper_drive(&hooks, t, t_end, nt, tout, k, one_step, &tret, &st->nt_done);
    if (tret > t || flag < 0) {
        xs_store(x, x->b.y, x->b.extra);
        x->b.tv[0] = tret;
    }

out:
    flag = watch_flag(&d->w, flag, st->message, sizeof st->message);
    flag = lcg_nonfinite_flag(flag, d->nonfinite, d->t_nonfinite, &st->model_error, &st->t_reached);
    flag = lcg_stepper_settle(&x->b, flag, st->model_error, 0);
    LCG_STEPPER_CVODE_COUNTS(x->mem, st);
    CVodeGetNumLinSolvSetups(x->mem, &st->nlinsetups);
    CVodeGetNumNonlinSolvIters(x->mem, &st->nniters);
    corrector_stats(&x->data, st);
    LCG_STEPPER_END_CALL(st, flag, x->b.tv[0]);
    lcg_stepper_keep(&x->b);
    return st->flag;
}

int lcg_cvsens_stepper_until(lcg_cvsens_stepper *x, double t_end)
{
    return lcg_cvsens_stepper_advance(x, t_end, 0, NULL, NULL, NULL, 0);
}

int lcg_cvsens_stepper_grid(lcg_cvsens_stepper *x, int nt, const double *tout, double *yout, double *sout)
{
    return lcg_cvsens_stepper_advance(x, lcg_stepper_grid_end(nt, tout), nt, tout, yout, sout, 0);
}

int lcg_cvsens_stepper_step(lcg_cvsens_stepper *x, double t_limit)
{
    return lcg_cvsens_stepper_advance(x, t_limit, 0, NULL, NULL, NULL, 1);
}
