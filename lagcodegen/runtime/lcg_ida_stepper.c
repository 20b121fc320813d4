/* lcg_ida_stepper.c -- lagcodegen's runtime: the GGL integration of a constrained system on IDA
 * that lives between calls (see lcg_ida_stepper.h).
 *
 * One translation unit with the run driver lcg_ida.c, included here, so that IDA calls the
 * driver's own residual, Jacobian and root functions with the same options and the same
 * IDACalcIC start; a grid from a fresh stepper gives the numbers of lcg_ida_solve on the same
 * times. The module built from this file (with lcg_cvc.c, which lcg_ida.c calls) replaces
 * lcg_ida.c's own. */
#include "lcg_ida.c"

#include "lcg_ida_stepper.h"
#include "lcg_stepper.h"

struct lcg_ida_stepper {
    const lcg_dae_model *m;
    lcg_ida_options opt;        /* the caller's, atol_vec pointing at the copy b.atol */
    lcg_ida_stats st;           /* of the last call */
    user_data data;             /* what the callbacks see (lcg_ida.c) */
    lcg_events *ev;             /* the caller's record, or NULL */
    int roots_on;
    lcg_stepper_memory b;       /* the caller's time, state and parameters, as the last call left them;
                                   b.atol: ng values, or NULL; b.restart: new initial values before
                                   the next step (a write, a failure) */
    double *yout;               /* the grid rows of the current call */
    int need_ic;                /* IDACalcIC before the next step */
    SUNContext ctx;
    void *mem;
    N_Vector yy, yp, id, abstol, ictol;
    SUNMatrix A;
    SUNLinearSolver LS;
};

void lcg_ida_stepper_free(lcg_ida_stepper *s)
{
    if (s == NULL)
        return;
    if (s->mem != NULL)
        IDAFree(&s->mem);
    free_solver(s->LS, NULL, s->A, (N_Vector[]){s->abstol, s->ictol, s->id, s->yp, s->yy}, 5, &s->ctx);
    free(s->data.info);
    lcg_stepper_unbind(&s->b);
    free(s);
}

lcg_ida_stats *lcg_ida_stepper_stats(lcg_ida_stepper *s)
{
    return &s->st;
}

const double *lcg_ida_stepper_unknowns(lcg_ida_stepper *s)
{
    return N_VGetArrayPointer(s->yy);
}

/* The state (q, v) of IDA's unknowns into y (ny values). */
static void is_store(lcg_ida_stepper *s, double *y)
{
    const double *yy = N_VGetArrayPointer(s->yy);
    int i;

    for (i = 0; i < s->m->ny; ++i)
        y[i] = yy[i];
}

/* The state of IDA's unknowns into the grid row k of the call (lcg_stepper_hooks). */
static void is_row(void *x, int k)
{
    lcg_ida_stepper *s = (lcg_ida_stepper *)x;

    is_store(s, s->yout + (long)k * s->m->ny);
}

/* The run's tolerances (after IDACalcIC's own): 0 or a negative flag. */
static int is_tolerances(lcg_ida_stepper *s)
{
    return s->abstol != NULL ? IDASVtolerances(s->mem, s->opt.rtol, s->abstol)
                             : IDASStolerances(s->mem, s->opt.rtol, s->opt.atol);
}

/* The options of lcg_ida_solve, on the stepper's IDA memory: 0 or a negative flag. */
static int is_setup(lcg_ida_stepper *s, const double *yy0, const double *yp0)
{
    const lcg_dae_model *m = s->m;
    const lcg_ida_options *opt = &s->opt;
    int i, flag, ny = m->ny, ng = m->ng;

    flag = ida_create(s->ctx, ng, ny, &s->yy, &s->yp, &s->id, &s->mem, &s->A, &s->LS, LCG_FLAG_NOMEM_IDA);
    if (flag != 0)
        return flag;
    s->ictol = N_VNew_Serial(ng, s->ctx);
    if (s->roots_on && (s->data.info = (int *)malloc(sizeof(int) * (size_t)m->nroot)) == NULL)
        return LCG_FLAG_NOMEM_IDA;
    if (s->ictol == NULL)
        return LCG_FLAG_NOMEM_IDA;
    for (i = 0; i < ng; ++i) {
        N_VGetArrayPointer(s->yy)[i] = yy0[i];
        N_VGetArrayPointer(s->yp)[i] = yp0[i];
        N_VGetArrayPointer(s->ictol)[i] = i >= ny ? opt->ic_alg_atol
                                          : (opt->atol_vec != NULL ? opt->atol_vec[i] : opt->atol);
    }
    flag = ida_init(s->mem, res, s->b.tv[0], s->yy, s->yp, s->id, &s->data, opt->suppress_alg, s->LS, s->A);
    if (flag < 0)
        return flag;
    flag = set_tolerances(s->mem, 1, s->ctx, ng, opt->rtol, opt->atol, opt->atol_vec, -1, &s->abstol,
                          LCG_FLAG_NOMEM_IDA);
    if (flag < 0)
        return flag;
    if (opt->jacobian && m->ggl_jac != NULL && (flag = IDASetJacFn(s->mem, jac)) < 0)
        return flag;
    if ((flag = ida_roots(s->mem, s->roots_on ? m->nroot : 0, roots, s->roots_on ? s->ev->rootdir : NULL)) < 0)
        return flag;
    return lcg_stepper_limits(s->mem, 1, opt->max_order, opt->first_step, opt->max_step, opt->min_step,
                              opt->max_steps);
}

lcg_ida_stepper *lcg_ida_stepper_new(const lcg_dae_model *m, const lcg_ida_options *opt, double *mem,
                                     const double *yy0, const double *yp0, lcg_events *ev, char *message,
                                     size_t size)
{
    lcg_ida_stepper *s;
    int i, flag;

    if (!lcg_dae_check(m, message, size))
        return NULL;
    if (m->ggl_res == NULL) {
        snprintf(message, size, "the model was compiled without the GGL residual");
        return NULL;
    }
    if (opt == NULL || mem == NULL || yy0 == NULL || yp0 == NULL || opt->max_steps < 1 || !isfinite(mem[0])) {
        snprintf(message, size, "bad options (max_steps >= 1) or a non-finite time");
        return NULL;
    }
    if ((s = (lcg_ida_stepper *)lcg_stepper_alloc(sizeof *s, message, size)) == NULL)
        return NULL;
    s->m = m;
    s->opt = *opt;
    s->opt.cancel = NULL;
    s->ev = ev;
    s->roots_on = opt->roots && ev != NULL && m->nroot > 0;
    s->need_ic = opt->calc_ic;
    if (lcg_stepper_bind(&s->b, mem, m->ny, m->np, NULL, 0, opt->atol_vec, m->ng) != 0
        || create_context(&s->ctx, &s->st) != 0) {
        snprintf(message, size, "out of memory");
        lcg_ida_stepper_free(s);
        return NULL;
    }
    s->opt.atol_vec = s->b.atol;
    s->data.res = m->ggl_res;
    s->data.m = m;
    s->data.p = s->b.p;
    s->data.st = &s->st;
    flag = is_setup(s, yy0, yp0);
    if (flag < 0) {
        lcg_stepper_setup_failed(message, size, flag, LCG_FLAG_NOMEM_IDA, "IDA", s->st.message);
        lcg_ida_stepper_free(s);
        return NULL;
    }
    for (i = 0; i < m->ny; ++i)
        s->b.y[i] = yy0[i];
    lcg_stepper_keep(&s->b);
    return s;
}

/* The roots IDA returned at tret (lcg_stepper_hooks; each one ends a step). */
static int is_record(void *x, double tret)
{
    lcg_ida_stepper *s = (lcg_ida_stepper *)x;

    if (record_events(s->mem, s->ev, tret, N_VGetArrayPointer(s->yy), s->m->nroot, s->m->ng, s->data.info)) {
        s->ev->terminated = 1;
        return 1;
    }
    return 0;
}

/* Restart at the caller's (t, y, p): y projected onto the constraints, lambda, mu and yy' from the
 * augmented system, IDACalcIC before the next step. 0, -22 (no consistent state there) or an IDA flag. */
static int is_restart(lcg_ida_stepper *s)
{
    const lcg_dae_model *m = s->m;
    double *yy = N_VGetArrayPointer(s->yy);
    int i, rc;

    rc = lcg_dae_initial_state(m, s->b.tv[0], s->b.y, s->b.p, 2, 1e-8, 0, yy, N_VGetArrayPointer(s->yp));
    if (rc != 0) {
        snprintf(s->st.message, sizeof s->st.message,
                 "no consistent state at the written time, state and parameters (the projection onto the "
                 "constraints failed or the augmented matrix is singular)");
        return LCG_FLAG_BAD_INPUT;
    }
    for (i = 0; i < m->ny; ++i)
        s->b.y[i] = yy[i];
    s->need_ic = s->opt.calc_ic;
    return IDAReInit(s->mem, s->b.tv[0], s->yy, s->yp);
}

/* IDACalcIC towards tout1 with loose tolerances on lambda, mu, then the run's (as lcg_ida_solve). */
static int is_calc_ic(lcg_ida_stepper *s, double tout1)
{
    int flag;

    if ((flag = IDASVtolerances(s->mem, s->opt.rtol, s->ictol)) < 0)
        return flag;
    flag = IDACalcIC(s->mem, IDA_YA_YDP_INIT, tout1);
    s->st.ic_flag = flag;
    if (flag < 0)
        return flag;
    if ((flag = IDAGetConsistentIC(s->mem, s->yy, s->yp)) < 0)
        return flag;
    if ((flag = is_tolerances(s)) < 0)
        return flag;
    s->need_ic = 0;
    return IDAReInit(s->mem, s->b.tv[0], s->yy, s->yp);
}

int lcg_ida_stepper_advance(lcg_ida_stepper *s, double t_end, int nt, const double *tout, double *yout,
                            int one_step)
{
    lcg_ida_stats *st = &s->st;
    const lcg_ida_options *opt = &s->opt;
    user_data *d = &s->data;
    const lcg_stepper_hooks hooks = {s->mem, 1, s->yy, s->yp, s, s->roots_on ? is_record : NULL, is_row, &d->w,
                                     opt->stop_at_outputs};
    double t = s->b.tv[0], tret = t, tout1;
    int k = 0, flag;

    LCG_STEPPER_NEW_CALL(st, s->ev);
    watch_init(&d->w, opt->cancel, opt->poll, opt->poll_data, opt->poll_every, opt->max_wall, nt, &st->nt_done);
    if ((flag = lcg_stepper_begin(&s->b, t_end, nt, tout, yout != NULL, st->message, sizeof st->message)) < 0)
        goto out;
    if (s->b.restart) {
        if ((flag = is_restart(s)) < 0)
            goto out;
        s->b.restart = 0;
    }
    while (k < nt && tout[k] <= t)
        ++k;
    tout1 = k < nt ? tout[k] : lcg_stepper_one_step_tout(t, t_end);
    if (s->need_ic && tout1 > t && (flag = is_calc_ic(s, tout1)) < 0)
        goto out;
    is_store(s, s->b.y);
    s->yout = yout;
    st->nt_done = k = lcg_stepper_rows_now(0, nt, tout, t, s->b.y, s->m->ny, yout);
    flag = lcg_stepper_drive(&hooks, t, t_end, nt, tout, k, one_step, &tret, &st->nt_done);
    if (tret > t || flag < 0) {
        is_store(s, s->b.y);
        s->b.tv[0] = tret;
    }

out:
    flag = watch_flag(&d->w, flag, st->message, sizeof st->message);
    flag = lcg_stepper_settle(&s->b, flag, st->model_error, 1);
    IDAGetNumSteps(s->mem, &st->nsteps);
    IDAGetNumResEvals(s->mem, &st->nres);
    IDAGetNumLinResEvals(s->mem, &st->nres_dq);
    IDAGetNumJacEvals(s->mem, &st->njac);
    IDAGetNumErrTestFails(s->mem, &st->netfails);
    IDAGetNumNonlinSolvConvFails(s->mem, &st->nncfails);
    IDAGetLastStep(s->mem, &st->h_last);
    if (s->roots_on)
        IDAGetNumGEvals(s->mem, &st->ngevals);
    LCG_STEPPER_END_CALL(st, flag, s->b.tv[0]);
    lcg_stepper_keep(&s->b);
    return st->flag;
}

/* lcg_ida_stepper_until, lcg_ida_stepper_grid, lcg_ida_stepper_step */
LCG_STEPPER_CALLS(ida)
