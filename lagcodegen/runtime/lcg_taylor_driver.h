/* lcg_taylor_driver.h -- lagcodegen's Taylor runtime: the body of the model-independent Taylor
 * driver (included once, by lcg_taylor.c, after the macros NY, NE, NROW, P_MAX, PS and TL_* that
 * take every size and function from the model's table m).
 *
 * Step size, Horner evaluation (dense output), event location and the step itself (tl_run,
 * tl_step_plan, tl_step_take), shared by the run driver lcg_taylor_solve below and the integrator
 * object (lcg_taylor_stepper.c, one translation unit with lcg_taylor.c): both take the same steps
 * with the same arithmetic in the same order.
 *
 * A standalone integrator (<prefix>_taylor.c, templates/taylor/_driver.j2) prints the parts between
 * the lines "shared with <prefix>_taylor.c: NAME" and "end of NAME" from this file, its sizes
 * compiled in (lagcodegen.solvers.taylor.emit.driver_section): without the model argument m and
 * the lines between "#ifdef LCG_TAYLOR_RUNTIME" and its "#endif" (what only the runtime does:
 * the table check, relative tolerances by blocks), the options type and the jet's name its own. */

#include "lcg_taylor_roots.h" /* event location */

/* shared with <prefix>_taylor.c: rules */
/* y_i(tau) = sum_{k<=p} y_i,[k] tau^k for every state component: Horner in tau^2 over the orders
 * of the parity of p (a) and over the others (b), two independent chains of half the length
 * (a step of a small model waits for this evaluation's latency, not for its operations). */
static void tl_eval(const lcg_taylor_model *m, const double *X, int p, double tau, double *y)
{
    const double t2 = tau * tau;
    int i, k;

    for (i = 0; i < NY; ++i) {
        const double *x = X + (long)i * PS;
        double a = x[p], b = x[p - 1];
        for (k = p - 2; k >= 1; k -= 2) {
            a = a * t2 + x[k];
            b = b * t2 + x[k - 1];
        }
        y[i] = k == 0 ? (a * t2 + x[0]) + tau * b : b + tau * a;
    }
}

/* log2(x) within 0.09 for a finite x > 0 (x = m 2^e, m in [1/2, 1), log2 m ~ 2m - 2). */
static double tl_log2_rough(double x)
{
    int e;
    double m = frexp(x, &e);

    return e + 2.0 * m - 2.0;
}

/* The step size from the last two orders (see the top of this file); -1 if a coefficient is
 * not finite. sf[0], sf[1]: the safety factors of orders p and p - 1 as fac^-p, fac^-(p-1)
 * (tl_safety): h = min((sf_0 n_p)^(-1/p), (sf_1 n_(p-1))^(-1/(p-1))), the smaller one told
 * apart by rough logarithms (an error within ~1% of h, where the two limits are that close)
 * and computed by one pow. */
static double tl_step_size(const lcg_taylor_model *m,
                           const double *X, int p, const lcg_taylor_options *opt, const double sf[2])
{
    double np = 0.0, np1 = 0.0, check = 0.0;
    int i;
#ifdef LCG_TAYLOR_RUNTIME
    const int blk = opt->rel_block;
    double scale = 0.0;
#endif

    for (i = 0; i < NY; ++i) {
        const double *x = X + (long)i * PS;
        double w = (opt->atol_vec != NULL ? opt->atol_vec[i] : opt->atol) + opt->rtol * fabs(x[0]);
        double a, b;
#ifdef LCG_TAYLOR_RUNTIME
        if (blk > 0 && i >= blk) { /* a block's relative tolerance on its largest |y| */
            if (i % blk == 0) {
                int j;
                scale = 0.0;
                for (j = i; j < i + blk; ++j)
                    scale = fmax(scale, fabs(X[(long)j * PS]));
            }
            w = (opt->atol_vec != NULL ? opt->atol_vec[i] : opt->atol) + opt->rtol * scale;
        }
#endif
        if (!(w > DBL_MIN))
            w = DBL_MIN;
        w = 1.0 / w; /* one division per component, not two: the driver's costliest instruction */
        a = fabs(x[p]) * w;
        b = fabs(x[p - 1]) * w;
        check += a + b;
        if (a > np)
            np = a;
        if (b > np1)
            np1 = b;
    }
    if (!isfinite(check))
        return -1.0;
    np *= sf[0];
    np1 *= sf[1];
    if (np > 0.0 && (!(np1 > 0.0) || tl_log2_rough(np) * (p - 1) >= tl_log2_rough(np1) * p))
        return pow(np, -1.0 / p);
    if (np1 > 0.0)
        return pow(np1, -1.0 / (p - 1));
    return HUGE_VAL;
}

/* The tolerance that sets the order: rtol, or the smallest atol if rtol = 0. */
static double tl_tolerance(const lcg_taylor_model *m, const lcg_taylor_options *opt)
{
    double tol = opt->rtol;
    int i;

    if (!(tol > 0.0)) {
        tol = opt->atol;
        if (opt->atol_vec != NULL)
            for (i = 0; i < NY; ++i)
                if (opt->atol_vec[i] > 0.0 && (!(tol > 0.0) || opt->atol_vec[i] < tol))
                    tol = opt->atol_vec[i];
    }
    return tol > DBL_EPSILON ? tol : DBL_EPSILON;
}

/* The cap c of the step, h <= rho e^-c (tl_safety). 1.7 was chosen at equal achieved error on the
 * n-link pendulum (n = 1..3, errors 1e-4..1e-12; benchmarks/taylor_order.py --caps): a looser cap
 * (1.0-1.3) reaches errors of 1e-4..1e-5 in up to 29% less time (median 11%), ties or loses up to
 * 14% elsewhere, and lets the final error pass the tolerance (err/tol up to 3.3, against 0.77 at
 * 1.7); a tighter one (2.0) takes up to 31% more time (11% less at a few tight errors from n = 3),
 * its errors 1e-3 of the tolerance. An embedder may compile with -DLCG_TAYLOR_CAP=<c> to choose
 * otherwise. */
#ifndef LCG_TAYLOR_CAP
#define LCG_TAYLOR_CAP 1.7
#endif

/* The safety factors of the step of order p (k = p, p - 1) as fac^-k (tl_step_size): fac =
 * exp(-0.7/(p-1)), and at most tol^(-1/k) e^-c (c = LCG_TAYLOR_CAP), which keeps h below
 * rho e^-c (rho: the radius of convergence estimated from the same coefficients), so that the
 * last term bounds the series' tail also when the order is higher than the tolerance asks for. */
static void tl_safety(double tol, int p, double sf[2])
{
    int j;

    for (j = 0; j < 2; ++j) {
        double cap = pow(tol, -1.0 / (p - j)) * exp(-(LCG_TAYLOR_CAP));
        sf[j] = pow(fmin(exp(-0.7 / (p - 1)), cap), -(double)(p - j));
    }
}

/* The order of a run: opt_order if given, else ceil(-ln(tol)/2 + 3), within 2..P_MAX. Two orders
 * above Jorba & Zou's -ln(tol)/2 + 1: tuned at equal achieved error on the n-link pendulum
 * (n = 1..5, errors 1e-4..1e-12; steps x measured cost per step of each order), where the
 * higher order reaches the same error in ~10% less time (a higher order's steps cost more
 * but are longer, and the step's fixed cost (libm, Horner, bookkeeping) is shared by more
 * orders), and the achieved error stays further below tol (median err/tol 0.01-0.06, max
 * 0.8, against 0.2-0.3 and 1.7 at -ln(tol)/2 + 1). */
static int tl_order(double tol, int opt_order)
{
    int order = opt_order > 0 ? opt_order : (int)ceil(-0.5 * log(tol) + 3.0);

    return order < 2 ? 2 : order > P_MAX ? P_MAX : order;
}

/* Normalized Taylor coefficients at (t, y) up to order (<= P_MAX):
 * jet[i*(order+1) + k] = y_i^(k)(t)/k!. Returns 0, a model error code (1, 2), -20 out of memory
 * or -22 a bad order. */
int lcg_taylor_jet(const lcg_taylor_model *m, double t, const double *y, const double *p, int order, double *jet)
{
    double *X;
    void *work;
    int rc, i, k;

#ifdef LCG_TAYLOR_RUNTIME
    if (!tl_table_ok(m))
        return -22; /* a table of another layout */
#endif
    if (order < 1 || order > P_MAX)
        return -22;
    X = (double *)calloc((size_t)NROW * PS, sizeof(double));
    work = calloc(1, TL_WORK_SIZE);
    rc = X == NULL || work == NULL ? -20 : TL_START(work, p);
    if (rc == 0)
        rc = TL_JET(work, X, t, y, order);
    if (rc == 0)
        for (i = 0; i < NY; ++i)
            for (k = 0; k <= order; ++k) {
                jet[i * (order + 1) + k] = X[i * PS + k];
                if (!isfinite(jet[i * (order + 1) + k]))
                    rc = 2;
            }
    free(X);
    free(work);
    return rc;
}
/* end of rules */

/* A Taylor integration between its steps: the jet and the model's workspace, the order and the
 * step rule's safety factors of the run's tolerance, the last whole step, the events' scratch. */
typedef struct {
    double *X;                  /* the jet, NROW x PS */
    void *work;                 /* the model's workspace (TL_WORK_SIZE bytes) */
    int order, kmax;            /* kmax: order, one more with events (for g_[order]) */
    double fac[2];              /* the safety factors as fac^-k (tl_safety) */
    double hprev;               /* the last whole step (0: none yet), bounds the next one's growth */
    double *last, *tau;         /* events: the last root of each (NE), the roots of one step */
    int *which, *dir;           /* the event and direction of each root of a step */
} tl_run;

/* The storage of r for model m (zeroed jet and workspace): 0, or -20 out of memory (free what
 * was made with tl_run_free). */
static int tl_run_alloc(const lcg_taylor_model *m, tl_run *r)
{
    r->X = (double *)calloc((size_t)NROW * PS, sizeof(double));
    r->work = calloc(1, TL_WORK_SIZE > 0 ? TL_WORK_SIZE : 1);
    r->last = (double *)malloc(sizeof(double) * (size_t)(NE + NE * (P_MAX + 1) + 1));
    r->which = (int *)malloc(sizeof(int) * (size_t)(2 * NE * (P_MAX + 1) + 1));
    if (r->X == NULL || r->work == NULL || r->last == NULL || r->which == NULL)
        return -20;
    r->tau = r->last + NE;
    r->dir = r->which + NE * (P_MAX + 1);
    return 0;
}

static void tl_run_free(tl_run *r)
{
    free(r->X);
    free(r->work);
    free(r->last);
    free(r->which);
}

/* The order and safety factors of the options opt (also into st->order). */
static void tl_run_order(const lcg_taylor_model *m, tl_run *r, const lcg_taylor_options *opt, lcg_taylor_stats *st)
{
    double tol = tl_tolerance(m, opt);

    r->order = tl_order(tol, opt->order);
    st->order = r->order;
    tl_safety(tol, r->order, r->fac);
    r->kmax = r->order + (NE > 0); /* events: one order more of the operations, for g_[order] */
}

/* A new start: no step taken, no root reported yet. */
static void tl_run_restart(const lcg_taylor_model *m, tl_run *r)
{
    int i;

    r->hprev = 0.0;
    for (i = 0; i < NE; ++i)
        r->last[i] = -HUGE_VAL;
}

/* The next step from the state y at the time thi + tlo (double-double) towards t_end: the jet,
 * the step size *h by the rule (at most max_step, 100 times the last step, and to t_end: *end = 1
 * there), the events in (0, *h] recorded into ev (NULL: not recorded), a terminal one ending the
 * step at it (*end = 2). 0, or a negative flag (st's message and model error set). */
static int tl_step_plan(const lcg_taylor_model *m, tl_run *r, const lcg_taylor_options *opt, lcg_taylor_stats *st,
                        lcg_taylor_events *ev, double thi, double tlo, const double *y, double t_end,
                        double *h_out, int *end_out)
{
    double *X = r->X, *last = r->last, *tau = r->tau;
    int *which = r->which, *dir = r->dir, order = r->order;
    double h, rem;
    int rc, end = 0, nroot = 0, e, j;

    rc = TL_JET(r->work, X, thi + tlo, y, r->kmax);
    st->njet++;
    if (rc != 0) {
        st->model_error = rc;
        return -100 - rc;
    }
    h = tl_step_size(m, X, order, opt, r->fac);
    if (h < 0.0) {
        snprintf(st->message, sizeof st->message, "non-finite Taylor coefficients at t = %.17g", thi + tlo);
        st->model_error = 2;
        return -102;
    }
    if (opt->max_step > 0.0 && h > opt->max_step)
        h = opt->max_step;
    if (r->hprev > 0.0 && h > 100.0 * r->hprev)
        h = 100.0 * r->hprev;
    rem = (t_end - thi) - tlo;
    if (h >= rem) {
        h = rem;
        end = 1;
    }
    if (!(h > 4.0 * DBL_EPSILON * fabs(thi)) || !(h > 0.0) || !isfinite(h)) {
        snprintf(st->message, sizeof st->message, "the step size %.3g fell below the resolution of t = %.17g%s", h,
                 thi + tlo, isfinite(h) ? "" : " (or is unbounded: give max_step or an end time)");
        return -3;
    }

    /* shared with <prefix>_taylor.c: events */
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
    /* end of events */
    *h_out = h;
    *end_out = end;
    return 0;
}

/* Take the planned step h (end as tl_step_plan gave it): y(t_n + h) from the jet, the time
 * *thi + *tlo advanced in double-double, the statistics. 0, or -102 (a non-finite state: y back at
 * the step's start, the time where it was). */
static int tl_step_take(const lcg_taylor_model *m, tl_run *r, lcg_taylor_stats *st, double *thi, double *tlo,
                        double *y, double h, int end)
{
    double s, bb;
    int i, j;

    tl_eval(m, r->X, r->order, h, y);
    for (i = 0; i < NY; ++i)
        if (!isfinite(y[i])) {
            snprintf(st->message, sizeof st->message, "non-finite state at t = %.17g", *thi + *tlo + h);
            st->model_error = 2;
            for (j = 0; j < NY; ++j) /* back to the step's start */
                y[j] = r->X[(long)j * PS];
            return -102;
        }
    s = *thi + h;
    bb = s - *thi;
    *tlo += (*thi - (s - bb)) + (h - bb);
    *thi = s + *tlo;
    *tlo -= *thi - s;
    st->nsteps++;
    st->h_last = h;
    if (h > st->h_max)
        st->h_max = h;
    if (h < st->h_min && end == 0)
        st->h_min = h;
    if (end == 0)
        r->hprev = h;
    return 0;
}

/* The outputs at the time t of the state y into out (NOUT values): 0, or the model error's flag
 * (st's model error set). */
static int tl_outputs(const lcg_taylor_model *m, lcg_taylor_stats *st, double t, const double *y, const double *p,
                      double *out)
{
    int rc = TL_OUTPUTS(t, y, p, out);

    if (rc != 0)
        st->model_error = rc;
    return rc != 0 ? -100 - rc : 0;
}

int lcg_taylor_solve(const lcg_taylor_model *m, const double *p, const double *y0, int nt, const double *tout,
                     double *yout, double *out, const lcg_taylor_options *opt, lcg_taylor_stats *st,
                     lcg_taylor_events *ev)
{
    tl_run r = {0};
    double *y = NULL;
    double thi, tlo, tend;
    int kout = 1, flag = 0, i;
    watch wt;

    memset(st, 0, sizeof *st);
    thi = nt > 0 ? tout[0] : 0.0;
    tlo = 0.0;
    if (ev != NULL) {
        ev->n_events = 0;
        ev->terminated = 0;
    }
    watch_init(&wt, opt->cancel, opt->poll, opt->poll_data, opt->poll_every, opt->max_wall, nt, &st->nt_done);
    if (!tl_table_ok(m)) {
        snprintf(st->message, sizeof st->message, "the Taylor model table is missing or of another layout "
                 "(lcg_taylor_model version %d, this driver reads version %d)", m != NULL ? m->abi : -1,
                 LCG_TAYLOR_ABI);
        flag = -22;
        goto done;
    }
    if (nt < 1 || opt->max_steps < 0 || opt->max_step < 0.0 || opt->order < 0 || opt->order > P_MAX
        || (opt->order > 0 && opt->order < 2) || opt->rel_block < 0
        || (opt->rel_block > 0 && NY % opt->rel_block != 0)) {
        snprintf(st->message, sizeof st->message, "bad options (order must be 0 or 2..%d)", P_MAX);
        flag = -22;
        goto done;
    }
    tl_run_order(m, &r, opt, st);
    y = (double *)malloc(sizeof(double) * (size_t)NY);
    if (tl_run_alloc(m, &r) != 0 || y == NULL) {
        snprintf(st->message, sizeof st->message, "out of memory");
        flag = -20;
        goto done;
    }
    flag = TL_START(r.work, p);
    if (flag != 0) {
        st->model_error = flag;
        flag = -100 - flag;
        goto done;
    }
    for (i = 0; i < NY; ++i)
        y[i] = yout[i] = y0[i];
    if ((flag = tl_outputs(m, st, tout[0], y0, p, out)) != 0)
        goto done;
    st->nt_done = 1;
    tl_run_restart(m, &r);
    tend = tout[nt - 1];
    st->h_min = HUGE_VAL;

    while (kout < nt) {
        double h = 0.0;
        int end = 0;

        /* Output times within rounding of the current time (a step ended there): its state. */
        while (kout < nt && (tout[kout] - thi) - tlo <= 4.0 * DBL_EPSILON * fabs(thi)) {
            for (i = 0; i < NY; ++i)
                yout[(long)kout * NY + i] = y[i];
            if ((flag = tl_outputs(m, st, tout[kout], y, p, out + (long)kout * NOUT)) != 0)
                goto done;
            st->nt_done = ++kout;
        }
        if (kout == nt)
            break;

        if (st->nsteps >= opt->max_steps) {
            snprintf(st->message, sizeof st->message,
                     "the step budget max_steps = %ld is used up before t = %.17g", opt->max_steps, tout[kout]);
            flag = -1;
            break;
        }
        if (WATCH_TICK(&wt))
            break;
        if ((flag = tl_step_plan(m, &r, opt, st, ev, thi, tlo, y, tend, &h, &end)) != 0)
            break;

        /* Dense output: the step polynomial at the output times in (t_n, t_n + h]. */
        while (kout < nt) {
            double dt = (tout[kout] - thi) - tlo;
            if (dt > h)
                break;
            tl_eval(m, r.X, r.order, dt, yout + (long)kout * NY);
            if ((flag = tl_outputs(m, st, tout[kout], yout + (long)kout * NY, p, out + (long)kout * NOUT)) != 0)
                goto done;
            st->nt_done = ++kout;
        }

        if ((flag = tl_step_take(m, &r, st, &thi, &tlo, y, h, end)) != 0)
            break;
        if (end == 2) {
            if (ev != NULL)
                ev->terminated = 1;
            break;
        }
        if (end == 1)
            break;
    }

done:
    flag = watch_flag(&wt, flag, st->message, sizeof st->message);
    st->t_reached = thi + tlo;
    if (st->h_min == HUGE_VAL)
        st->h_min = st->h_last;
    st->flag = flag;
    tl_run_free(&r);
    free(y);
    return flag;
}
