/* lcg_imp_law.c -- lagcodegen's runtime, compiled as it is: the impact law shared by the impact
 * drivers (see lcg_imp_law.h; lcg_imp.c, lcg_imp_ida.c). */
#include <math.h>

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
    int nk = im->nk, nj = im->nj, ny = im->dae->ny, k, rc, iter, changed = 0;
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
    for (iter = 0; iter <= nk; ++iter) {
        int worst = -1;
        rc = im->impact(t, y, L->p, rows, eff, ynew, P);
        if (rc != LCG_DAE_OK)
            return rc;
        for (k = 0; k < nk; ++k)
            if (rows[k] && P[nj + k] < 0.0 && (worst < 0 || P[nj + k] < P[nj + worst]))
                worst = k;
        if (worst < 0)
            break;
        rows[worst] = 0; /* it would pull: not part of the impact (a persistent contact is released) */
        if (active[worst]) {
            active[worst] = 0;
            lcg_imp_record(L->rec, L->max_rec, L->n_rec, t, worst, LCG_IMP_RELEASE, 0.0, wm[worst], wm[worst]);
        }
    }
    rc = im->gaps(t, ynew, L->p, gk, wk);
    if (rc != LCG_DAE_OK)
        return rc;
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

int lcg_imp_release_pulling(const lcg_imp_law *L, double t, const double *y, double alpha, double beta,
                            double *ydot, double *lam)
{
    const lcg_imp_model *im = L->im;
    int k, rc, again = 1, nk = im->nk, nj = im->nj;

    while (again) {
        again = 0;
        rc = im->crhs(t, y, L->p, alpha, beta, L->active, ydot, lam);
        if (rc != LCG_DAE_OK)
            return rc;
        for (k = 0; k < nk; ++k)
            if (L->active[k] && lam[nj + k] < 0.0) {
                L->active[k] = 0;
                lcg_imp_record(L->rec, L->max_rec, L->n_rec, t, k, LCG_IMP_RELEASE, 0.0, 0.0, 0.0);
                again = 1;
                break;
            }
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
