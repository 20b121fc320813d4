/* lcg_taylor_imp.c -- lagcodegen's runtime, compiled as it is.
 *
 * The Taylor driver of constrained models with contacts (see lcg_taylor_imp.h): the steps of the
 * Taylor runtime's driver (lcg_taylor_driver.h: step size, Horner evaluation, root isolation,
 * the step) on the model's contact jet (lcg_taylor_contact.h: the index-1 system of the rows
 * held, the equality rows and the contacts in persistent contact), and the impact law shared
 * with the CVODE and IDA impact drivers (lcg_imp_law.c).
 *
 * Each step's polynomials are searched on (0, h] for the first switch of a contact: a free
 * contact's gap g_k decreasing through 0 (an impact; a gap that begins below zero, drifted, also
 * through the floor lcg_imp_gap_floor), a persistent contact's multiplier lambda_k decreasing
 * through 0 (a release). Every root of the polynomial on the step is isolated (Descartes' rule
 * and bisection, lcg_taylor_roots.h), so a flight shorter than a step is not skipped. The step
 * ends at the first such root; there the contacts hit (and those that touch and close) take the
 * impact law (lcg_imp_jump), the contacts that pull are released (lcg_imp_release_pulling), the
 * rows held are set for the new modes and the integration restarts from the new state. Output
 * times inside a step are evaluations of its polynomial; the multipliers there are the index-1
 * solve at that state (im->crhs, as the CVODE impact driver reports them).
 *
 * Coulomb friction (fric != NULL): the modes are the friction core's (lcg_imp_fric.c: lcg_fr_start,
 * then lcg_fr_impact and lcg_fr_modes at every switch with the core's ending[], as lcg_imp.c); the
 * jet holds a sticking contact's tangential rows and gives a slipping one the force direction
 * G - sigma mu T (3-D: G - mu d.T, d = u/|u| in the jet; ti_hold). The transitions (lcg_fr_roots
 * at the states of the step's polynomial, with their multipliers from lcg_fr_crhs) are sampled at
 * TI_FR_SAMPLES points of each step and bisected; the determinant's root is Painleve's paradox
 * (LCG_FLAG_CONTACT_MODE), as are the core's inconsistent or indeterminate mode choices. */
#include "lcg_control.h" /* first: POSIX */

#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "lcg_taylor_imp.h"
#include "lcg_imp_fric.h" /* the friction core of the CVODE and IDA impact drivers */

#include "lcg_taylor_adapter.h" /* the driver on the table m, tl_table_ok */
#include "lcg_taylor_driver.h"

/* The first root in (0, h] of the polynomial x (degree d) minus level where it decreases: tau, or
 * -1 if none. A polynomial that is exactly 0 at tau = 0 (a gap right after its impact) is divided
 * by tau first: the isolation takes the intervals' end values, and one that is 0 at the start
 * would hide the interval's other root; if it decreases from there (a contact that touches at rest
 * and is pulled down, a multiplier at 0 that turns negative), the root is at 0: the switch now. */
static double ti_first_down(const double *x, int d, double level, double h)
{
    double c[P_MAX + 2], tau[P_MAX + 1];
    int dir[P_MAX + 1], n, i, zero = 0;

    for (i = 0; i < P_MAX + 2; ++i)
        c[i] = i <= d ? x[i] : 0.0;
    c[0] -= level;
    while (d > 0 && c[0] == 0.0) {
        for (i = 0; i < d; ++i)
            c[i] = c[i + 1];
        --d;
        zero = 1;
    }
    if (zero && c[0] < 0.0)
        return 0.0;
    if (d == 0)
        return -1.0;
    n = tl_roots(c, d, h, tau, dir, P_MAX + 1);
    for (i = 0; i < n; ++i)
        if (dir[i] < 0)
            return tau[i];
    return -1.0;
}

/* Output row kout at (t, yk): the constrained table's outputs and the multipliers of the rows
 * held (the first nlam of im->crhs's). Returns LCG_DAE_OK or a model error. */
static int ti_output(const lcg_imp_model *im, const double *p, double t, const double *yk, const int *active,
                     const double ab[2], double *ydot, double *lam, double *lamrow, double *outrow, lcg_fric_ctx *fc)
{
    int rc = fc != NULL ? lcg_fr_crhs(fc, t, yk, ydot, lam) : im->crhs(t, yk, p, ab[0], ab[1], active, ydot, lam), i;

    if (rc != LCG_DAE_OK)
        return rc;
    for (i = 0; i < (fc != NULL ? im->nrow : im->nj + im->nk); ++i) /* with friction: all rows */
        lamrow[i] = lam[i];
    return im->dae->coutputs(t, yk, NULL, p, outrow);
}

/* The first switch of a contact on the step (0, h] of the jet X: *tau and the contact, or -1. */
static int ti_first_switch(const lcg_taylor_contact *ct, const double *X, int order, const int *active, double h,
                           double gap_tol, double *tau)
{
    int k, which = -1;

    for (k = 0; k < ct->nk; ++k) {
        double tk;
        if (active[k]) {
            tk = ti_first_down(X + (long)(ct->lam_row + ct->nj + k) * PS, order, 0.0, h);
        } else {
            const double *g = X + (long)ct->gap_row[k] * PS;
            tk = ti_first_down(g, order, 0.0, h);
            if (g[0] < 0.0) { /* drifted below zero: also through the floor (lcg_imp_gap_floor) */
                double t2 = ti_first_down(g, order, lcg_imp_gap_floor(g[0], gap_tol), h);
                if (t2 >= 0.0 && (tk < 0.0 || t2 < tk))
                    tk = t2;
            }
        }
        if (tk >= 0.0 && (which < 0 || tk < *tau)) {
            *tau = tk;
            which = k;
        }
    }
    return which;
}

/* The free contacts that touch (g <= gap_tol) at rest (|w| <= contact_speed) at (t, y) held from
 * now on (recorded as "stick" without impulse), as a start at rest holds them; those whose
 * multiplier pulls are released after (lcg_imp_release_pulling). Returns LCG_DAE_OK or a model
 * error. */
static int ti_settle(const lcg_imp_model *im, const double *p, double t, const double *y, int *active,
                     const double *set, double *gk, double *wk, double *rec, int max_rec, int *n_rec)
{
    int k, rc = im->gaps(t, y, p, gk, wk);

    if (rc != LCG_DAE_OK)
        return rc;
    for (k = 0; k < im->nk; ++k)
        if (!active[k] && gk[k] <= set[2] && fabs(wk[k]) <= set[0]) {
            active[k] = 1;
            lcg_imp_record(rec, max_rec, n_rec, t, k, LCG_IMP_STICK, 0.0, wk[k], wk[k]);
        }
    return LCG_DAE_OK;
}

#define TI_FR_SLOW 100.0 /* a 3-D slip at most this times contact_speed: d fixed within a step */
#define TI_FR_CAP0 1e-9  /* the first such step at most this, each next one at most twice the last */

/* Coulomb friction: the rows held of the current modes at (t, y) (the table's hold, then the jet's
 * tl_slip: a slipping contact's tangential row not held, lambda_t = -sigma mu lambda_n; 3-D:
 * lambda_t = -mu lambda_n d with d = u/|u| in the jet (slipping 2), or, while |u| is at most
 * TI_FR_SLOW contact_speed (a slip from rest or about to stop: u/|u| has no useful series), the
 * core's d fixed within the step). Returns 1 when a 3-D slip has its d fixed (the step capped),
 * 0, or a model error (< 0 ... as lcg_fr_eval). */
static int ti_hold(const lcg_taylor_contact *ct, void *work, const int *active, const double ab[2],
                   const lcg_taylor_friction *fric, lcg_fric_ctx *fc, double t, const double *y, int *slipping,
                   double *wc)
{
    const lcg_fric *f = fc != NULL ? fc->fr : NULL;
    int r, k, fixed = 0, evaluated = 0;

    ct->hold(work, active, ab[0], ab[1]);
    if (fric == NULL)
        return 0;
    for (r = 0; r < ct->nr; ++r) {
        slipping[r] = 0;
        wc[r] = 0.0;
    }
    for (k = 0; k < ct->nk; ++k)
        if (active[k] && f->trow[k] >= 0 && f->mu[k] >= 0.0 && f->fmode[k] != 0) {
            slipping[f->trow[k]] = 1;
            if (f->trow2[k] >= 0) { /* 3-D: G - mu (d1 T1 + d2 T2) */
                double u, u2;
                if (!evaluated) { /* the core's numbers and slip directions at (t, y) */
                    int rc = lcg_fr_crhs(fc, t, y, fc->ydot, fc->lam);
                    if (rc != LCG_DAE_OK)
                        return rc < 0 ? rc : -rc;
                    evaluated = 1;
                }
                lcg_fr_slip(f, k, &u, &u2);
                slipping[f->trow2[k]] = 1;
                if (hypot(u, u2) > TI_FR_SLOW * f->vtol) {
                    slipping[f->trow[k]] = slipping[f->trow2[k]] = 2;
                    wc[f->trow[k]] = wc[f->trow2[k]] = -f->mu[k];
                } else {
                    wc[f->trow[k]] = -f->mu[k] * f->dir[2 * k];
                    wc[f->trow2[k]] = -f->mu[k] * f->dir[2 * k + 1];
                    fixed = 1;
                }
            } else {
                wc[f->trow[k]] = -(double)f->fmode[k] * f->mu[k];
            }
        }
    fric->slip(work, slipping, wc);
    return fixed;
}

/* The friction core's transition functions (lcg_fr_roots, 2 nk + 1) at tau on the step's
 * polynomial X of the current modes: the state there (ys), its multipliers (lcg_fr_crhs). */
static int ti_fr_gf(const lcg_taylor_model *m, const double *X, int order, double t, double tau, lcg_fric_ctx *fc,
                    double *ys, double *gf)
{
    int rc;

    tl_eval(m, X, order, tau, ys);
    rc = lcg_fr_crhs(fc, t + tau, ys, fc->ydot, fc->lam);
    if (rc != LCG_DAE_OK)
        return rc;
    lcg_fr_roots(fc, fc->lam, gf);
    return LCG_DAE_OK;
}

#define TI_FR_SAMPLES 8 /* the friction functions sampled at 8 points of each step, their roots bisected */

/* The first root in (0, h] of the friction functions on the step (decreasing through 0, from > 0
 * to <= 0 between samples of the step's polynomial, then bisected to the resolution of t): *tau
 * and the function's index (2 k, 2 k + 1: contact k's mode ends; 2 nk: the determinant, Painleve),
 * or -1 (*rc a model error, else LCG_DAE_OK). ga, gb, gm: scratch of 2 nk + 1, ys of ny. */
static int ti_fr_first(const lcg_taylor_model *m, const double *X, int order, double t, double h, lcg_fric_ctx *fc,
                       int ng, double *ys, double *ga, double *gb, double *gm, double *tau, int *rc)
{
    double a = 0.0;
    int j, i, which = -1;

    if ((*rc = ti_fr_gf(m, X, order, t, 0.0, fc, ys, ga)) != LCG_DAE_OK)
        return -1;
    for (j = 1; j <= TI_FR_SAMPLES; ++j) {
        double b = h * j / TI_FR_SAMPLES;
        if ((*rc = ti_fr_gf(m, X, order, t, b, fc, ys, gb)) != LCG_DAE_OK)
            return -1;
        for (i = 0; i < ng; ++i)
            if (ga[i] > 0.0 && gb[i] <= 0.0) { /* bisected on (a, b] */
                double lo = a, hi = b;
                while (hi - lo > 4.0 * DBL_EPSILON * (fabs(t) + hi)) {
                    double mid = 0.5 * (lo + hi);
                    if (!(mid > lo && mid < hi))
                        break;
                    if ((*rc = ti_fr_gf(m, X, order, t, mid, fc, ys, gm)) != LCG_DAE_OK)
                        return -1;
                    if (gm[i] > 0.0)
                        lo = mid;
                    else
                        hi = mid;
                }
                if (which < 0 || hi < *tau) {
                    *tau = hi;
                    which = i;
                }
            }
        if (which >= 0)
            return which;
        for (i = 0; i < ng; ++i)
            ga[i] = gb[i];
        a = b;
    }
    return -1;
}

#define TI_MODEL_ERROR(rc)                          \
    do {                                            \
        if ((rc) != LCG_DAE_OK) {                   \
            st->model_error = (rc);                 \
            flag = LCG_MODEL_ERROR_FLAG(rc);        \
            goto done;                              \
        }                                           \
    } while (0)

/* The events on the step (0, *h] of the jet X, in time order (ev->rootdir: the directions taken),
 * each recorded with the state there; a root within rounding of the event's last one (at the end
 * of the previous step) is not reported again. A terminal one ends the step there: *h set to it,
 * returns 1; else 0. last[e]: the time of event e's last root; tau, which, dir: scratch of
 * ne (P_MAX + 1) entries. */
static int ti_events(const lcg_taylor_model *m, const lcg_taylor_contact *ct, const double *X, int order, double thi,
                     double tlo, double *h, lcg_events *ev, double *last, double *tau, int *which, int *dir)
{
    int e, j, a, n = 0, ny = m->ny;

    for (e = 0; e < ct->ne; ++e) {
        int found = tl_roots(X + (long)ct->event_row[e] * PS, order, *h, tau + n, dir + n, P_MAX + 1);
        for (j = 0; j < found; ++j)
            which[n + j] = e;
        n += found;
    }
    for (a = 1; a < n; ++a) /* merge the events' lists by time */
        for (j = a; j > 0 && tau[j - 1] > tau[j]; --j) {
            double tt = tau[j];
            int ww = which[j], dd = dir[j];
            tau[j] = tau[j - 1];
            which[j] = which[j - 1];
            dir[j] = dir[j - 1];
            tau[j - 1] = tt;
            which[j - 1] = ww;
            dir[j - 1] = dd;
        }
    for (j = 0; j < n; ++j) {
        double te = thi + (tlo + tau[j]);
        e = which[j];
        if (te - last[e] <= 1e-9 * *h + 4.0 * DBL_EPSILON * fabs(te))
            continue;
        last[e] = te;
        if (ev->rootdir != NULL && ev->rootdir[e] != 0 && dir[j] != ev->rootdir[e])
            continue;
        if (ev->n_events < ev->max_events) {
            ev->t[ev->n_events] = te;
            tl_eval(m, X, order, tau[j], ev->y + (long)ev->n_events * ny);
            ev->which[ev->n_events] = e;
            ev->direction[ev->n_events] = dir[j];
        }
        ev->n_events++;
        if (ev->terminal == NULL || ev->terminal[e]) {
            *h = tau[j];
            return 1;
        }
    }
    return 0;
}

int lcg_taylor_imp_solve(const lcg_taylor_contact *ct, const lcg_imp_model *im, const double *p, const double *y0,
                         int nt, const double *tout, double *yout, double *out, double *lamout,
                         const lcg_taylor_options *opt, const double *e, const double *set, int *active,
                         int max_rec, double *rec, int *n_rec, lcg_taylor_stats *st, double *stab, lcg_events *ev,
                         const lcg_taylor_friction *fric)
{
    const lcg_taylor_model *m = ct != NULL ? ct->jet : NULL;
    tl_run r;
    lcg_imp_law L, Lq;
    double *buf = NULL, *y, *ydot, *lam, *gk, *wk, *last, *scratch, *elast = NULL, *etau = NULL;
    double thi, tlo, tend, ab[2], tsame = -HUGE_VAL;
    int *ibuf = NULL, *hit, *rows, *ewhich = NULL, *edir = NULL;
    int kout = 1, flag = 0, rc, i, k, ny = 0, nk = 0, nlam = 0, nout = 0, same = 0, quiet = 0, ne = 0;
    watch wt;
    /* Coulomb friction: the core's state and view of the run, the jet's slipping rows */
    lcg_fric fdata;
    lcg_fric_ctx fc, *fcp = NULL;
    void *fmem = NULL;
    double *fbuf = NULL, *wc = NULL, *ys = NULL, *ga = NULL, *gb = NULL, *gm = NULL;
    int *slipping = NULL, ng = 0, cone = 0, frozen = 0;
    double fcap = TI_FR_CAP0;

    memset(&r, 0, sizeof r);
    memset(st, 0, sizeof *st);
    *n_rec = 0;
    thi = nt > 0 ? tout[0] : 0.0;
    tlo = 0.0;
    watch_init(&wt, opt->cancel, opt->poll, opt->poll_data, opt->poll_every, opt->max_wall, nt, &st->nt_done);
    if (ct == NULL || ct->abi != LCG_TAYLOR_CONTACT_ABI || !tl_table_ok(m) || m->ne != 0 || im == NULL
        || im->abi != LCG_IMP_MODEL_ABI || im->dae == NULL || im->nk < 1 || im->nk != ct->nk || im->nj != ct->nj
        || ct->nr > im->nrow || im->dae->ny != m->ny || ct->lam_row < m->ny || ct->lam_row + ct->nr > m->nrows
        || ct->hold == NULL || ct->gap_row == NULL) {
        snprintf(st->message, sizeof st->message, "the Taylor contact tables are missing or of another layout "
                 "(lcg_taylor_contact version %d, this driver reads version %d)", ct != NULL ? ct->abi : -1,
                 LCG_TAYLOR_CONTACT_ABI);
        flag = LCG_FLAG_BAD_INPUT;
        goto done;
    }
    if (ev != NULL) {
        ev->n_events = 0;
        ev->terminated = 0;
        ne = ct->ne;
        for (i = 0; i < ne; ++i)
            if (ct->event_row == NULL || ct->event_row[i] < 0 || ct->event_row[i] >= m->nrows) {
                snprintf(st->message, sizeof st->message, "event %d is not a row of the Taylor contact jet (it "
                         "uses a multiplier)", i);
                flag = LCG_FLAG_BAD_INPUT;
                goto done;
            }
    }
    if (nt < 1 || opt->max_steps < 0 || opt->max_step < 0.0 || opt->order < 0 || opt->order > P_MAX
        || (opt->order > 0 && opt->order < 2)) {
        snprintf(st->message, sizeof st->message, "bad options (order must be 0 or 2..%d)", P_MAX);
        flag = LCG_FLAG_BAD_INPUT;
        goto done;
    }
    ny = m->ny;
    nk = im->nk;
    nlam = im->nj + nk;
    if (fric != NULL) {
        if (fric->slip == NULL || fric->fr == NULL || fric->mu == NULL) {
            snprintf(st->message, sizeof st->message, "Coulomb friction needs the jet's tl_slip, the friction "
                     "table and the coefficients");
            flag = LCG_FLAG_BAD_INPUT;
            goto done;
        }
        if (lcg_fr_setup(&fdata, fric->fr, im, fric->mu, set[0], &fmem, st->message, sizeof st->message) != 0) {
            flag = LCG_FLAG_BAD_INPUT;
            goto done;
        }
        for (k = 0; k < nk; ++k)
            cone |= fdata.trow2[k] >= 0 && fdata.mu[k] >= 0.0;
        ng = 2 * nk + 1;
        nlam = im->nrow;
        /* doubles: wc[nr], ys[ny], ga, gb, gm[ng]; ints: slipping[nr] */
        fbuf = (double *)malloc(sizeof(double) * (size_t)(ct->nr + ny + 3 * ng));
        slipping = (int *)malloc(sizeof(int) * (size_t)(ct->nr > 0 ? ct->nr : 1));
        if (fbuf == NULL || slipping == NULL) {
            snprintf(st->message, sizeof st->message, "out of memory");
            flag = LCG_FLAG_NOMEM;
            goto done;
        }
        wc = fbuf;
        ys = wc + ct->nr;
        ga = ys + ny;
        gb = ga + ng;
        gm = gb + ng;
    }
    nout = im->dae->nout;
    tl_run_order(m, &r, opt, st);
    r.kmax = r.order + 1; /* the gaps' and multipliers' polynomials to the step's order */
    /* doubles: y[ny], ydot[ny], lam[nrow], gk[nk], wk[nk], last[nk], the law's scratch
     * (eff[nk], wm[nk], P[nrow], ynew[ny]); ints: hit[nk], rows[2 nk] */
    buf = (double *)malloc(sizeof(double) * (size_t)(3 * ny + 2 * im->nrow + 5 * nk));
    ibuf = (int *)malloc(sizeof(int) * (size_t)(3 * nk));
    if (ne > 0) { /* the events' last roots, and the roots of one step */
        elast = (double *)malloc(sizeof(double) * (size_t)(ne + ne * (P_MAX + 1)));
        ewhich = (int *)malloc(sizeof(int) * (size_t)(2 * ne * (P_MAX + 1)));
    }
    if (tl_run_alloc(m, &r) != 0 || buf == NULL || ibuf == NULL || (ne > 0 && (elast == NULL || ewhich == NULL))) {
        snprintf(st->message, sizeof st->message, "out of memory");
        flag = LCG_FLAG_NOMEM;
        goto done;
    }
    y = buf;
    ydot = y + ny;
    lam = ydot + ny;
    gk = lam + im->nrow;
    wk = gk + nk;
    last = wk + nk;
    scratch = last + nk;
    hit = ibuf;
    rows = hit + nk;
    if (ne > 0) {
        etau = elast + ne;
        edir = ewhich + ne * (P_MAX + 1);
        for (i = 0; i < ne; ++i)
            elast[i] = -HUGE_VAL;
    }
    L.im = im;
    L.p = p;
    L.active = active;
    L.e = e;
    L.set = set;
    L.last = last;
    L.gk = gk;
    L.wk = wk;
    L.scratch = scratch;
    L.rows = rows;
    L.rec = rec;
    L.max_rec = max_rec;
    L.n_rec = n_rec;
    Lq = L; /* the releases of the initial state are not recorded */
    Lq.max_rec = 0;
    Lq.n_rec = &quiet;

    ab[0] = stab[0];
    ab[1] = stab[1];
    if (ab[0] < 0.0 || ab[1] < 0.0) { /* "auto": the rate of the fastest motion at y0 */
        double rate = 0.0;
        if (im->dae->natural_rate(tout[0], y0, p, &rate) != LCG_DAE_OK)
            rate = 0.0;
        if (ab[0] < 0.0)
            ab[0] = rate;
        if (ab[1] < 0.0)
            ab[1] = rate;
    }
    stab[0] = ab[0];
    stab[1] = ab[1];
    if (fric != NULL) {
        fc.im = im;
        fc.p = p;
        fc.alpha = ab[0];
        fc.beta = ab[1];
        fc.active = active;
        fc.fr = &fdata;
        fc.lam = lam;
        fc.ydot = ydot;
        fc.message = st->message;
        fc.message_size = sizeof st->message;
        fcp = &fc;
    }
    rc = TL_START(r.work, p);
    TI_MODEL_ERROR(rc);
    for (k = 0; k < nk; ++k) {
        last[k] = -HUGE_VAL;
        hit[k] = 0;
        active[k] = active[k] != 0;
    }
    for (i = 0; i < ny; ++i)
        y[i] = y0[i];
    /* the contacts the initial state rests on (touching, at rest) start in persistent contact; one
     * that touches and closes takes its impact at once; those that pull are released */
    rc = im->gaps(thi, y, p, gk, wk);
    TI_MODEL_ERROR(rc);
    for (k = 0; k < nk; ++k)
        if (!active[k] && gk[k] <= set[2] && fabs(wk[k]) <= set[0])
            active[k] = 1;
    if (fcp != NULL) { /* the initial modes (as the CVODE driver): sticking where the slip velocity is small */
        rc = lcg_fr_start(fcp, thi, y, set[0]);
        if (rc == -1) {
            flag = LCG_FLAG_CONTACT_MODE;
            goto done;
        }
        TI_MODEL_ERROR(rc);
    } else {
        rc = lcg_imp_jump(&L, thi, y, hit);
        TI_MODEL_ERROR(rc);
        rc = lcg_imp_release_pulling(&Lq, thi, y, ab[0], ab[1], ydot, lam);
        TI_MODEL_ERROR(rc);
    }
    for (i = 0; i < ny; ++i)
        yout[i] = y[i];
    rc = ti_output(im, p, thi, y, active, ab, ydot, lam, lamout, out, fcp);
    TI_MODEL_ERROR(rc);
    st->nt_done = 1;
    frozen = ti_hold(ct, r.work, active, ab, fric, fcp, thi, y, slipping, wc);
    TI_MODEL_ERROR(frozen < 0 ? -frozen : LCG_DAE_OK);
    tl_run_restart(m, &r);
    tend = tout[nt - 1];
    st->h_min = HUGE_VAL;

    while (kout < nt) {
        double h, rem, tau = 0.0, ftau = 0.0;
        int end = 0, which, fw = -1;

        /* Output times within rounding of the current time (a step ended there): its state. */
        while (kout < nt && (tout[kout] - thi) - tlo <= 4.0 * DBL_EPSILON * fabs(thi)) {
            for (i = 0; i < ny; ++i)
                yout[(long)kout * ny + i] = y[i];
            rc = ti_output(im, p, tout[kout], y, active, ab, ydot, lam, lamout + (long)kout * nlam,
                           out + (long)kout * nout, fcp);
            TI_MODEL_ERROR(rc);
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
        if (cone) { /* 3-D slips: d fixed (slow) or u/|u| in the jet (fast), chosen at each step's start */
            frozen = ti_hold(ct, r.work, active, ab, fric, fcp, thi + tlo, y, slipping, wc);
            TI_MODEL_ERROR(frozen < 0 ? -frozen : LCG_DAE_OK);
        }
        rc = TL_JET(r.work, r.X, thi + tlo, y, r.kmax);
        st->njet++;
        if (rc == 1)
            snprintf(st->message, sizeof st->message, "the augmented matrix [M R^T; R 0] of the rows held is "
                     "singular at t = %.17g", thi + tlo);
        TI_MODEL_ERROR(rc);
        h = tl_step_size(m, r.X, r.order, opt, r.fac);
        if (h < 0.0) {
            snprintf(st->message, sizeof st->message, "non-finite Taylor coefficients at t = %.17g", thi + tlo);
            st->model_error = 2;
            flag = LCG_MODEL_ERROR_FLAG(2);
            break;
        }
        if (opt->max_step > 0.0 && h > opt->max_step)
            h = opt->max_step;
        if (r.hprev > 0.0 && h > 100.0 * r.hprev)
            h = 100.0 * r.hprev;
        if (frozen) { /* a 3-D slip's d fixed within the step: short steps, doubling */
            if (h > fcap)
                h = fcap;
            fcap *= 2.0;
        } else {
            fcap = TI_FR_CAP0;
        }
        rem = (tend - thi) - tlo;
        if (h >= rem) {
            h = rem;
            end = 1;
        }
        if (!(h > 4.0 * DBL_EPSILON * fabs(thi)) || !(h > 0.0) || !isfinite(h)) {
            snprintf(st->message, sizeof st->message, "the step size %.3g fell below the resolution of t = %.17g%s",
                     h, thi + tlo, isfinite(h) ? "" : " (or is unbounded: give max_step or an end time)");
            flag = -3;
            break;
        }
        which = ti_first_switch(ct, r.X, r.order, active, h, set[2], &tau);
        if (which >= 0) {
            st->nroot++;
            h = tau;
            end = 2;
        }
        if (fcp != NULL) { /* the friction transitions, on the step's polynomial */
            fw = ti_fr_first(m, r.X, r.order, thi + tlo, h, fcp, ng, ys, ga, gb, gm, &ftau, &rc);
            TI_MODEL_ERROR(rc);
            if (fw >= 0 && (which < 0 || ftau < h)) {
                if (which < 0)
                    st->nroot++;
                h = ftau;
                which = -1;
                end = 2;
            } else {
                fw = -1;
            }
        }
        if (ne > 0 && h > 0.0 && ti_events(m, ct, r.X, r.order, thi, tlo, &h, ev, elast, etau, ewhich, edir)) {
            which = -1; /* a terminal event at or before the contact's switch ends the run there */
            fw = -1;
            end = 3;
        }

        /* Dense output: the step polynomial at the output times in (t_n, t_n + h]. */
        while (kout < nt) {
            double dt = (tout[kout] - thi) - tlo, *yk = yout + (long)kout * ny;
            if (dt > h)
                break;
            tl_eval(m, r.X, r.order, dt, yk);
            rc = ti_output(im, p, tout[kout], yk, active, ab, ydot, lam, lamout + (long)kout * nlam,
                           out + (long)kout * nout, fcp);
            TI_MODEL_ERROR(rc);
            st->nt_done = ++kout;
        }
        if ((flag = tl_step_take(m, &r, st, &thi, &tlo, y, h, end)) != 0)
            break;
        if (end == 3) {
            ev->terminated = 1;
            break;
        }
        if (which >= 0 || fw >= 0) { /* the switch: an impact (or a release), the contacts that pull released */
            double t = thi + tlo;
            if (t == tsame) {
                if (++same > 4 * nk + 8) {
                    snprintf(st->message, sizeof st->message, "the contacts switch without end at t = %.17g "
                             "(contact %d)", t, which >= 0 ? which : fw / 2);
                    flag = -3;
                    break;
                }
            } else {
                tsame = t;
                same = 0;
            }
            if (fcp != NULL) { /* Coulomb friction: the core chooses the modes, as the CVODE driver */
                if (fw == ng - 1) {
                    snprintf(st->message, sizeof st->message, "Painleve's paradox at t = %.17g: the contact problem "
                             "of the slipping contact(s) became singular (the normal's effective mass with friction, "
                             "G M^-1 (G - sigma mu T)^T, reached 0: the normal force grows without bound)", t);
                    flag = LCG_FLAG_CONTACT_MODE;
                    break;
                }
                if (fw >= 0)
                    fdata.ending[fw / 2] = fdata.fmode[fw / 2] == 0 ? FR_END_STICK : FR_END_SLIP;
                else if (active[which])
                    fdata.ending[which] = FR_END_RELEASE;
                else
                    hit[which] = 1;
                rc = lcg_fr_impact(fcp, t, y, hit, e, set, last, rec, max_rec, n_rec);
                if (rc == LCG_DAE_OK)
                    rc = lcg_fr_modes(fcp, t, y, fdata.ending, set[0], rec, max_rec, n_rec);
                for (k = 0; k < nk; ++k) {
                    fdata.ending[k] = 0;
                    hit[k] = 0;
                }
                if (rc == -1) {
                    flag = LCG_FLAG_CONTACT_MODE;
                    break;
                }
                TI_MODEL_ERROR(rc);
                frozen = ti_hold(ct, r.work, active, ab, fric, fcp, t, y, slipping, wc);
                TI_MODEL_ERROR(frozen < 0 ? -frozen : LCG_DAE_OK);
                fcap = TI_FR_CAP0;
                r.hprev = 0.0;
                continue;
            }
            if (active[which]) { /* a release: the contact leaves with w = 0 (not an impact) */
                active[which] = 0;
                lcg_imp_record(rec, max_rec, n_rec, t, which, LCG_IMP_RELEASE, 0.0, 0.0, 0.0);
            } else {
                hit[which] = 1;
                rc = lcg_imp_jump(&L, t, y, hit);
                TI_MODEL_ERROR(rc);
                hit[which] = 0;
            }
            if (same > 0) { /* switches without flight between them (impacts accumulating within the
                              * resolution of t): the contacts that touch at rest are held */
                rc = ti_settle(im, p, t, y, active, set, gk, wk, rec, max_rec, n_rec);
                TI_MODEL_ERROR(rc);
            }
            rc = lcg_imp_release_pulling(&L, t, y, ab[0], ab[1], ydot, lam);
            TI_MODEL_ERROR(rc);
            ct->hold(r.work, active, ab[0], ab[1]);
            r.hprev = 0.0; /* a new series from the jump (the events' last roots kept) */
            continue;
        }
        if (end == 1)
            break;
    }

done:
    if (fcp != NULL) /* the final friction modes of the Coulomb contacts: 1 stick, 2 slip+, 3 slip- */
        for (k = 0; k < nk; ++k)
            if (active[k] && fdata.trow[k] >= 0 && fdata.mu[k] >= 0.0)
                active[k] = fdata.fmode[k] != 0 && fdata.trow2[k] >= 0 ? 4 : fdata.fmode[k] > 0 ? 2
                            : fdata.fmode[k] < 0 ? 3 : 1;
    flag = watch_flag(&wt, flag, st->message, sizeof st->message);
    st->t_reached = thi + tlo;
    if (st->h_min == HUGE_VAL)
        st->h_min = st->h_last;
    st->flag = flag;
    tl_run_free(&r);
    free(buf);
    free(ibuf);
    free(elast);
    free(ewhich);
    free(fmem);
    free(fbuf);
    free(slipping);
    return flag;
}
