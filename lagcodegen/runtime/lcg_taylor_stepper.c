/* lcg_taylor_stepper.c -- lagcodegen's Taylor runtime: the Taylor integrator that lives between
 * calls (see lcg_taylor_stepper.h).
 *
 * One translation unit with the run driver lcg_taylor.c, included here, so that a step is the
 * driver's own (lcg_taylor_driver.h): the same run state (tl_run: order, step rule, jet), the same
 * step (tl_step_plan: the jet, the step size, the events; tl_step_take: the Horner evaluation, the
 * double-double time). A grid
 * from a fresh stepper therefore takes the steps of lcg_taylor_solve on the same times and gives
 * the same numbers, bit for bit. The module built from this file replaces lcg_taylor.c's own. */
#include "lcg_taylor.c"

#include "lcg_taylor_stepper.h"
#include "lcg_stepper.h"

/* The model m's sizes again (lcg_taylor.c ends with the ensemble pool's). */
#undef NROW
#undef NOUT
#undef NOUTD
#define NROW (m->nrows)

struct lcg_taylor_stepper {
    const lcg_taylor_model *m;
    lcg_taylor_options opt;     /* the caller's, atol_vec pointing at atol below */
    lcg_taylor_events *ev;      /* the caller's record, or NULL */
    lcg_taylor_stats st;        /* of the last call */
    double *tv;                 /* the caller's: the time (tv[0]), the state y, the parameters p */
    double *y;                  /* ny: the state */
    double *p;                  /* np: the parameters */
    double t_lo, t_seen;        /* the time's low part (double-double tv[0] + t_lo); tv[0] as the last
                                   call left it */
    tl_run run;                 /* the jet, workspace, order, last step and events' scratch (the driver's) */
    double *p_start;            /* np: the parameters the workspace's run constants are of */
    double *atol;               /* ny, or NULL */
};

void lcg_taylor_stepper_free(lcg_taylor_stepper *s)
{
    if (s == NULL)
        return;
    tl_run_free(&s->run);
    free(s->p_start);
    free(s->atol);
    free(s);
}

lcg_taylor_stats *lcg_taylor_stepper_stats(lcg_taylor_stepper *s)
{
    return &s->st;
}

/* The model's run constants of the parameters p (into a zeroed workspace): 0 or a model error. */
static int ts_start(lcg_taylor_stepper *s)
{
    const lcg_taylor_model *m = s->m;
    int i;

    memset(s->run.work, 0, TL_WORK_SIZE > 0 ? TL_WORK_SIZE : 1);
    for (i = 0; i < m->np; ++i)
        s->p_start[i] = s->p[i];
    return TL_START(s->run.work, s->p);
}

lcg_taylor_stepper *lcg_taylor_stepper_new(const lcg_taylor_model *m, const lcg_taylor_options *opt, double *mem,
                                           lcg_taylor_events *ev, char *message, size_t size)
{
    lcg_taylor_stepper *s;
    int rc;

    if (!tl_table_ok(m)) {
        snprintf(message, size, "the Taylor model table is missing or of another layout");
        return NULL;
    }
    if (opt == NULL || opt->max_steps < 1 || opt->max_step < 0.0 || opt->order < 0 || opt->order > P_MAX
        || (opt->order > 0 && opt->order < 2) || mem == NULL || !isfinite(mem[0])) {
        snprintf(message, size, "bad options (order must be 0 or 2..%d, max_steps >= 1, max_step >= 0)", P_MAX);
        return NULL;
    }
    if ((s = (lcg_taylor_stepper *)lcg_stepper_alloc(sizeof *s, message, size)) == NULL)
        return NULL;
    s->m = m;
    s->opt = *opt;
    s->ev = ev;
    s->tv = mem;
    s->y = mem + 1;
    s->p = s->y + NY;
    s->p_start = (double *)calloc((size_t)(m->np + 1), sizeof(double));
    s->atol = lcg_stepper_copy(opt->atol_vec, NY);
    if (tl_run_alloc(m, &s->run) != 0 || s->p_start == NULL || (opt->atol_vec != NULL && s->atol == NULL)) {
        snprintf(message, size, "out of memory");
        lcg_taylor_stepper_free(s);
        return NULL;
    }
    s->opt.atol_vec = s->atol;
    s->opt.cancel = NULL; /* run control per call: poll and max_wall stay */
    tl_run_restart(m, &s->run);
    s->t_seen = mem[0];
    tl_run_order(m, &s->run, &s->opt, &s->st);
    rc = ts_start(s);
    if (rc != 0) {
        snprintf(message, size, "the model's run constants failed (model error %d: %s)", rc,
                 rc == 1 ? "singular mass matrix" : "a non-finite value");
        lcg_taylor_stepper_free(s);
        return NULL;
    }
    return s;
}

/* The step loop of lcg_taylor_solve (lcg_taylor_driver.h: the same tl_step_plan and tl_step_take)
 * on the stepper's state, to t_end, over a grid or by one step. */
int lcg_taylor_stepper_advance(lcg_taylor_stepper *s, double t_end, int nt, const double *tout, double *yout,
                               int one_step)
{
    const lcg_taylor_model *m = s->m;
    const lcg_taylor_options *opt = &s->opt;
    lcg_taylor_stats *st = &s->st;
    lcg_taylor_events *ev = s->ev;
    tl_run *r = &s->run;
    double *y = s->y;
    double thi, tlo;
    int kout = 0, flag = 0, rc, i;
    long taken = 0;
    watch wt;

    LCG_STEPPER_NEW_CALL(st, ev);
    st->nsteps = st->njet = st->nroot = 0;
    st->h_last = 0.0;
    st->h_min = HUGE_VAL;
    st->h_max = 0.0;
    watch_init(&wt, opt->cancel, opt->poll, opt->poll_data, opt->poll_every, opt->max_wall, nt, &st->nt_done);
    if (s->tv[0] != s->t_seen) { /* the caller set the time: a new start */
        s->t_lo = 0.0;
        tl_run_restart(m, r);
    }
    if (lcg_stepper_differ(s->p, s->p_start, m->np)) {
        rc = ts_start(s); /* the caller set the parameters: their run constants */
        if (rc != 0) {
            st->model_error = rc;
            flag = -100 - rc;
            goto done;
        }
    }
    thi = s->tv[0];
    tlo = s->t_lo;
    if (!(t_end >= thi + tlo) || !lcg_stepper_grid_ok(thi, t_end, nt, tout, yout != NULL, 0)) {
        flag = lcg_stepper_backward(st->message, sizeof st->message, t_end, thi);
        goto done;
    }
    /* grid times at the current time: the current state */
    st->nt_done = kout = lcg_stepper_rows_now(0, nt, tout, thi + tlo, y, NY, yout);

    while (kout < nt || (nt == 0 && (!one_step || taken == 0) && thi + tlo < t_end)) {
        double h = 0.0;
        int end = 0;

        /* Grid and end times within rounding of the current time (a step ended there): its state,
         * as the run driver does; no step below the resolution of t. */
        while (kout < nt && (tout[kout] - thi) - tlo <= 4.0 * DBL_EPSILON * fabs(thi)) {
            for (i = 0; i < NY; ++i)
                yout[(long)kout * NY + i] = y[i];
            st->nt_done = ++kout;
        }
        if (nt > 0 ? kout == nt : (t_end - thi) - tlo <= 4.0 * DBL_EPSILON * fabs(thi))
            break;

        if (taken >= opt->max_steps) {
            snprintf(st->message, sizeof st->message,
                     "the step budget max_steps = %ld of one call is used up before t = %.17g", opt->max_steps,
                     nt > 0 ? tout[kout] : t_end);
            flag = -1;
            break;
        }
        if (WATCH_TICK(&wt))
            break;
        if ((flag = tl_step_plan(m, r, opt, st, ev, thi, tlo, y, t_end, &h, &end)) != 0)
            break;

        /* Dense output: the step polynomial at the grid times in (t_n, t_n + h]. */
        while (kout < nt) {
            double dt = (tout[kout] - thi) - tlo;
            if (dt > h)
                break;
            tl_eval(m, r->X, r->order, dt, yout + (long)kout * NY);
            st->nt_done = ++kout;
        }

        if ((flag = tl_step_take(m, r, st, &thi, &tlo, y, h, end)) != 0)
            goto done;
        taken++;
        if (end == 2) {
            if (ev != NULL)
                ev->terminated = 1;
            break;
        }
        if (end == 1) {
            thi = t_end; /* exactly there */
            tlo = 0.0;
        }
    }

    s->tv[0] = thi;
    s->t_lo = tlo;
done:
    flag = watch_flag(&wt, flag, st->message, sizeof st->message);
    s->t_seen = s->tv[0];
    st->t_reached = s->tv[0] + s->t_lo;
    if (st->h_min == HUGE_VAL)
        st->h_min = st->h_last;
    st->flag = flag;
    return flag;
}

/* lcg_taylor_stepper_until, lcg_taylor_stepper_grid, lcg_taylor_stepper_step */
LCG_STEPPER_CALLS(taylor)
