/* lcg_taylor_stepper.c -- lagcodegen's Taylor runtime: the Taylor integrator that lives between
 * calls (see lcg_taylor_stepper.h).
 *
 * One translation unit with the run driver lcg_taylor.c, included here, so that a step is the
 * driver's own: the same order and step-size rule (tl_order, tl_step_size, tl_safety,
 * tl_tolerance), the same Horner evaluation (tl_eval), the same event location (tl_roots), the
 * same double-double time. A grid
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
    double hprev;               /* last whole step (0: none yet), bounds the next one's growth */
    double fac[2];              /* the step rule's safety factors as fac^-k (tl_safety) */
    int order, kmax;
    double *p_start;            /* np: the parameters the workspace's run constants are of */
    double *atol;               /* ny, or NULL */
    double *X;                  /* the jet, nrows x PS */
    void *work;                 /* the model's workspace (work_size bytes) */
    double *last, *tau;         /* events: the last root of each, the roots of one step */
    int *which, *dir;
};

void lcg_taylor_stepper_free(lcg_taylor_stepper *s)
{
    if (s == NULL)
        return;
    free(s->p_start);
    free(s->atol);
    free(s->X);
    free(s->work);
    free(s->last);
    free(s->which);
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

    memset(s->work, 0, TL_WORK_SIZE > 0 ? TL_WORK_SIZE : 1);
    for (i = 0; i < m->np; ++i)
        s->p_start[i] = s->p[i];
    return TL_START(s->work, s->p);
}

lcg_taylor_stepper *lcg_taylor_stepper_new(const lcg_taylor_model *m, const lcg_taylor_options *opt, double *mem,
                                           lcg_taylor_events *ev, char *message, size_t size)
{
    lcg_taylor_stepper *s;
    double tol;
    int i, rc;

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
    s->X = (double *)calloc((size_t)NROW * PS, sizeof(double));
    s->work = calloc(1, TL_WORK_SIZE > 0 ? TL_WORK_SIZE : 1);
    s->last = (double *)malloc(sizeof(double) * (size_t)(NE + NE * (P_MAX + 1) + 1));
    s->which = (int *)malloc(sizeof(int) * (size_t)(2 * NE * (P_MAX + 1) + 1));
    s->atol = lcg_stepper_copy(opt->atol_vec, NY);
    if (s->p_start == NULL || s->X == NULL || s->work == NULL || s->last == NULL || s->which == NULL
        || (opt->atol_vec != NULL && s->atol == NULL)) {
        snprintf(message, size, "out of memory");
        lcg_taylor_stepper_free(s);
        return NULL;
    }
    s->tau = s->last + NE;
    s->dir = s->which + NE * (P_MAX + 1);
    s->opt.atol_vec = s->atol;
    s->opt.cancel = NULL; /* run control per call: poll and max_wall stay */
    for (i = 0; i < NE; ++i)
        s->last[i] = -HUGE_VAL;
    s->t_seen = mem[0];
    tol = tl_tolerance(m, &s->opt);
    s->order = tl_order(tol, opt->order);
    tl_safety(tol, s->order, s->fac);
    s->kmax = s->order + (NE > 0);
    s->st.order = s->order;
    rc = ts_start(s);
    if (rc != 0) {
        snprintf(message, size, "the model's run constants failed (model error %d: %s)", rc,
                 rc == 1 ? "singular mass matrix" : "a non-finite value");
        lcg_taylor_stepper_free(s);
        return NULL;
    }
    return s;
}

/* The step loop of lcg_taylor_solve (lagcodegen/templates/taylor/_driver.j2) on the stepper's
 * state, with the same arithmetic in the same order. */
int lcg_taylor_stepper_advance(lcg_taylor_stepper *s, double t_end, int nt, const double *tout, double *yout,
                               int one_step)
{
    const lcg_taylor_model *m = s->m;
    const lcg_taylor_options *opt = &s->opt;
    lcg_taylor_stats *st = &s->st;
    lcg_taylor_events *ev = s->ev;
    double *X = s->X, *y = s->y, *last = s->last, *tau = s->tau;
    int *which = s->which, *dir = s->dir;
    double thi, tlo;
    int order = s->order, kmax = s->kmax, kout = 0, flag = 0, rc, i;
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
        s->hprev = 0.0;
        for (i = 0; i < NE; ++i)
            last[i] = -HUGE_VAL;
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
        double h, rem, sum, bb;
        int end = 0, nroot = 0, e, j;

        /* Grid and end times within rounding of the current time (a step ended there): its state,
         * as the run driver (templates/taylor/_driver.j2) does; no step below the resolution of t. */
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
        rc = TL_JET(s->work, X, thi + tlo, y, kmax);
        st->njet++;
        if (rc != 0) {
            st->model_error = rc;
            flag = -100 - rc;
            break;
        }
        h = tl_step_size(m, X, order, opt, s->fac);
        if (h < 0.0) {
            snprintf(st->message, sizeof st->message, "non-finite Taylor coefficients at t = %.17g", thi + tlo);
            st->model_error = 2;
            flag = -102;
            break;
        }
        if (opt->max_step > 0.0 && h > opt->max_step)
            h = opt->max_step;
        if (s->hprev > 0.0 && h > 100.0 * s->hprev)
            h = 100.0 * s->hprev;
        rem = (t_end - thi) - tlo;
        if (h >= rem) {
            h = rem;
            end = 1;
        }
        if (!(h > 4.0 * DBL_EPSILON * fabs(thi)) || !(h > 0.0) || !isfinite(h)) {
            snprintf(st->message, sizeof st->message,
                     "the step size %.3g fell below the resolution of t = %.17g (or is unbounded: give "
                     "max_step or an end time)", h, thi + tlo);
            flag = -3;
            break;
        }

        /* Events: roots of each event polynomial in (0, h], in time order. */
        for (e = 0; e < NE; ++e) {
            double *g = X + (long)TL_EVENT_ROW(e) * PS;
            int found = tl_roots(g, order, h, tau + nroot, dir + nroot, P_MAX + 1);
            for (j = 0; j < found; ++j)
                which[nroot + j] = e;
            nroot += found;
        }
        if (nroot > 0) {
            int a, b2;
            st->nroot++;
            for (a = 1; a < nroot; ++a) /* merge the events' lists by time */
                for (b2 = a; b2 > 0 && tau[b2 - 1] > tau[b2]; --b2) {
                    double tt = tau[b2];
                    int ww = which[b2], dd = dir[b2];
                    tau[b2] = tau[b2 - 1];
                    which[b2] = which[b2 - 1];
                    dir[b2] = dir[b2 - 1];
                    tau[b2 - 1] = tt;
                    which[b2 - 1] = ww;
                    dir[b2 - 1] = dd;
                }
        }
        for (j = 0; j < nroot; ++j) {
            double te = thi + (tlo + tau[j]);
            e = which[j];
            if (te - last[e] <= 1e-9 * h + 4.0 * DBL_EPSILON * fabs(te))
                continue; /* the root reported at the end of the previous step, found again */
            last[e] = te;
            if (TL_EVENT_DIRECTION(e) != 0 && dir[j] != TL_EVENT_DIRECTION(e))
                continue;
            if (ev != NULL) {
                if (ev->n_events < ev->max_events) {
                    ev->t[ev->n_events] = te;
                    tl_eval(m, X, order, tau[j], ev->y + (long)ev->n_events * NY);
                    ev->which[ev->n_events] = e;
                    ev->direction[ev->n_events] = dir[j];
                }
                ev->n_events++;
            }
            if (TL_EVENT_TERMINAL(e)) {
                h = tau[j];
                end = 2;
                break;
            }
        }

        /* Dense output: the step polynomial at the grid times in (t_n, t_n + h]. */
        while (kout < nt) {
            double dt = (tout[kout] - thi) - tlo;
            if (dt > h)
                break;
            tl_eval(m, X, order, dt, yout + (long)kout * NY);
            st->nt_done = ++kout;
        }

        /* Advance: y(t_n + h) and t in double-double (t_hi + t_lo). */
        tl_eval(m, X, order, h, y);
        for (i = 0; i < NY; ++i)
            if (!isfinite(y[i])) {
                snprintf(st->message, sizeof st->message, "non-finite state at t = %.17g", thi + tlo + h);
                st->model_error = 2;
                flag = -102;
                for (j = 0; j < NY; ++j) /* back to the step's start */
                    y[j] = X[(long)j * PS];
                goto done;
            }
        sum = thi + h;
        bb = sum - thi;
        tlo += (thi - (sum - bb)) + (h - bb);
        thi = sum + tlo;
        tlo -= thi - sum;
        st->nsteps++;
        taken++;
        st->h_last = h;
        if (h > st->h_max)
            st->h_max = h;
        if (h < st->h_min && end == 0)
            st->h_min = h;
        if (end == 0)
            s->hprev = h;
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
