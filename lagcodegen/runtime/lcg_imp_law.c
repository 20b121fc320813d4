/* lcg_imp_law.c -- lagcodegen's runtime, compiled as it is: the impact law shared by the impact
 * drivers (see lcg_imp_law.h; lcg_imp.c, lcg_imp_ida.c). */
#include <math.h>
#include <stddef.h>

#include "lcg_imp_law.h"

#define REC 6

void lcg_imp_record(double *rec, int max_rec, int *n_rec, double t, int k, int kind, double P, double wm, double wp)
{
    if (*n_rec < max_rec) {
        double *r = rec + (long)(*n_rec) * REC;
        r[0] = t;
        r[1] = k;
        r[2] = kind;
        r[3] = P;
        r[4] = wm;
        r[5] = wp;
    }
    (*n_rec)++;
}

int lcg_imp_jump(const lcg_imp_law *L, double t, double *y, const int *hit)
{
    const lcg_imp_model *im = L->im;
    int nk = im->nk, nj = im->nj, ny = im->dae->ny, k, rc, iter, changed = 0, settled = 0;
    double *eff = L->scratch, *wm = eff + nk, *P = wm + nk, *ynew = P + im->nrow, *gk = L->gk, *wk = L->wk;
    const double *e = L->e, *set = L->set;
    double gap_tol = set[2];
    int *rows = L->rows, *plastic = rows + nk, *active = L->active;

    rc = im->gaps(t, y, L->p, gk, wk);
    if (rc != LCG_DAE_OK)
        return rc;
    for (k = 0; k < nk; ++k) {
        wm[k] = wk[k];
        rows[k] = active[k] || ((hit[k] || gk[k] <= gap_tol) && wk[k] < 0.0);
        plastic[k] = active[k] || e[k] * fabs(wk[k]) <= set[0] || t - L->last[k] < set[1];
        eff[k] = plastic[k] ? 0.0 : e[k];
        changed |= rows[k] && !active[k];
    }
    if (!changed)
        return LCG_DAE_OK;
    for (iter = 0; iter <= 4 * nk + 8; ++iter) {
        int worst = -1, sinks = -1;
        rc = im->impact(t, y, L->p, rows, eff, ynew, P);
        if (rc != LCG_DAE_OK)
            return rc;
        for (k = 0; k < nk; ++k)
            if (rows[k] && P[nj + k] < 0.0 && (worst < 0 || P[nj + k] < P[nj + worst]))
                worst = k;
        if (worst >= 0) {
            rows[worst] = 0; /* it would pull: not part of the impact (a persistent contact is released) */
            if (active[worst]) {
                active[worst] = 0;
                lcg_imp_record(L->rec, L->max_rec, L->n_rec, t, worst, LCG_IMP_RELEASE, 0.0, wm[worst], wm[worst]);
            }
            continue;
        }
        /* a free contact that touches and would close after the jump (pushed by the others'
         * impulses) takes part, plastically: the impact's complementarity problem over the
         * touching contacts, so that no second impact follows at once */
        rc = im->gaps(t, ynew, L->p, gk, wk);
        if (rc != LCG_DAE_OK)
            return rc;
        for (k = 0; k < nk && sinks < 0; ++k)
            if (!rows[k] && gk[k] <= gap_tol && wk[k] < -set[0])
                sinks = k;
        if (sinks < 0) {
            settled = 1; /* gk, wk: the gaps after the jump */
            break;
        }
        rows[sinks] = plastic[sinks] = 1;
        eff[sinks] = 0.0;
    }
    if (!settled) {
        rc = im->gaps(t, ynew, L->p, gk, wk);
        if (rc != LCG_DAE_OK)
            return rc;
    }
    for (k = 0; k < nk; ++k) {
        if (!rows[k])
            continue;
        if (active[k]) {
            if (P[nj + k] != 0.0)
                lcg_imp_record(L->rec, L->max_rec, L->n_rec, t, k, LCG_IMP_CONTACT_IMPULSE, P[nj + k], wm[k], wk[k]);
            continue;
        }
        L->last[k] = t;
        active[k] = plastic[k];
        lcg_imp_record(L->rec, L->max_rec, L->n_rec, t, k, plastic[k] ? LCG_IMP_STICK : LCG_IMP_BOUNCE, P[nj + k],
                       wm[k], wk[k]);
    }
    for (k = 0; k < ny; ++k)
        y[k] = ynew[k];
    return LCG_DAE_OK;
}

/* The normal accelerations a[nk] of the contacts at (t, y) under ydot (the last solve's), by a
 * forward difference of their normal velocities along the motion: (w(t + h, y + h ydot) - w) / h,
 * w = L->wk (at (t, y), left as it is); scratch yh[ny], gh[nk], wh[nk]. */
static int normal_accelerations(const lcg_imp_law *L, double t, const double *y, const double *ydot, double *yh,
                                double *gh, double *wh, double *a)
{
    const lcg_imp_model *im = L->im;
    int k, rc, ny = im->dae->ny, nk = im->nk;
    double scale = 0.0, h;

    for (k = 0; k < ny; ++k)
        if (fabs(ydot[k]) > scale)
            scale = fabs(ydot[k]);
    h = 1e-7 / (1.0 + scale);
    for (k = 0; k < ny; ++k)
        yh[k] = y[k] + h * ydot[k];
    rc = im->gaps(t + h, yh, L->p, gh, wh);
    if (rc != LCG_DAE_OK)
        return rc;
    for (k = 0; k < nk; ++k)
        a[k] = (wh[k] - L->wk[k]) / h;
    return LCG_DAE_OK;
}

int lcg_imp_release_pulling(const lcg_imp_law *L, double t, double *y, double alpha, double beta, double *ydot,
                            double *lam)
{
    const lcg_imp_model *im = L->im;
    int k, rc, again = 1, nk = im->nk, nj = im->nj, ny = im->dae->ny, iter = 0, touching = 0, held = 0;
    int joint = L->set != NULL && L->scratch != NULL && L->rows != NULL;
    int *cand = joint ? L->rows : NULL;
    /* scratch: a[nk], wh[nk], then P[nrow] (its first nk the gaps along the motion), yh[ny] */
    double *a = joint ? L->scratch : NULL, *wh = joint ? L->scratch + nk : NULL;
    double *P = joint ? L->scratch + 2 * nk : NULL, *yh = joint ? L->scratch + 2 * nk + im->nrow : NULL;

    if (joint) { /* the free contacts that touch at rest: candidates for persistent contact */
        rc = im->gaps(t, y, L->p, L->gk, L->wk);
        if (rc != LCG_DAE_OK)
            return rc;
        for (k = 0; k < nk; ++k) {
            cand[k] = !L->active[k] && L->gk[k] <= L->set[2] && fabs(L->wk[k]) <= L->set[0];
            touching |= cand[k];
        }
    }
    while (again) {
        int lcp = touching && iter < 4 * nk + 8; /* the contacts' LCP, by Murty's least-index rule */
        double big = 0.0;
        again = 0;
        rc = im->crhs(t, y, L->p, alpha, beta, L->active, ydot, lam);
        if (rc != LCG_DAE_OK)
            return rc;
        if (lcp) {
            ++iter;
            rc = normal_accelerations(L, t, y, ydot, yh, P, wh, a);
            if (rc != LCG_DAE_OK)
                return rc;
            for (k = im->nq; k < ny; ++k)
                if (fabs(ydot[k]) > big)
                    big = fabs(ydot[k]);
        }
        for (k = 0; k < nk && !again; ++k) {
            if (L->active[k] && lam[nj + k] < 0.0) { /* it pulls: released */
                L->active[k] = 0;
                if (cand != NULL && cand[k] == 2) /* held in this call: not recorded as held and released */
                    --held;
                else
                    lcg_imp_record(L->rec, L->max_rec, L->n_rec, t, k, LCG_IMP_RELEASE, 0.0, 0.0, 0.0);
                if (cand != NULL)
                    cand[k] = 1;
                again = 1;
            } else if (lcp && cand[k] && !L->active[k] && a[k] < -1e-6 * (1.0 + big)) { /* it would sink: held */
                L->active[k] = 1;
                cand[k] = 2;
                ++held;
                again = 1;
            }
        }
    }
    if (held > 0) { /* the contacts held: their normal velocities (|w| <= contact_speed) to 0 by a
                     * plastic impulse with the persistent contacts, recorded as sticks */
        double *eff = a, *ynew = yh;
        for (k = 0; k < nk; ++k)
            eff[k] = 0.0;
        rc = im->impact(t, y, L->p, L->active, eff, ynew, P);
        if (rc != LCG_DAE_OK)
            return rc;
        for (k = 0; k < nk; ++k)
            if (cand[k] == 2 && L->active[k]) {
                lcg_imp_record(L->rec, L->max_rec, L->n_rec, t, k, LCG_IMP_STICK, P[nj + k], L->wk[k], 0.0);
                if (L->last != NULL)
                    L->last[k] = t;
            }
        for (k = 0; k < ny; ++k)
            y[k] = ynew[k];
        rc = im->crhs(t, y, L->p, alpha, beta, L->active, ydot, lam);
        if (rc != LCG_DAE_OK)
            return rc;
    }
    return LCG_DAE_OK;
}

double lcg_imp_gap_floor(double g0, double gap_tol)
{
    return g0 < -2.0 * gap_tol ? g0 - gap_tol : -gap_tol;
}

int lcg_imp_below_floor(const double *gk, const double *wk, const double *gprev, const int *active, int nk,
                        double gap_tol)
{
    int k, worst = -1;

    for (k = 0; k < nk; ++k)
        if (!active[k] && gk[k] < lcg_imp_gap_floor(gprev[k], gap_tol) && wk[k] < 0.0
            && (worst < 0 || gk[k] < gk[worst]))
            worst = k;
    return worst;
}
