/* lcg_imp_fric.c -- lagcodegen's runtime, compiled as it is.
 *
 * The solver-independent core of Coulomb friction on contacts (see lcg_imp_fric.h), used by the
 * impact drivers lcg_imp.c (index 1, CVODE) and lcg_imp_ida.c (GGL, IDA). */
#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "lcg_imp_fric.h"

static void record(double *rec, int max_rec, int *n_rec, double t, int k, int kind, double P, double wm, double wp)
{
    lcg_imp_record(rec, max_rec, n_rec, t, k, kind, P, wm, wp);
}

/* Coulomb friction
 *
 * Contacts with a tangent row T_k and a friction coefficient mu_k >= 0 (the model's friction
 * table lcg_imp_friction, whose eval gives M, F, the rows R, s, h, gamma at a state): the driver
 * builds the contact problem of each mode itself. A contact in persistent contact sticks (fmode
 * 0: its tangential row held, u = T q' + T0 = 0, multiplier lambda_t free) or slips (fmode
 * +1 / -1 with u > 0 / u < 0: no tangential row, the normal row's force direction
 * G - fmode mu T, i.e. lambda_t = -fmode mu lambda_n). The system [M W^T; R 0] is not symmetric
 * while a contact slips (W: the force directions). Contacts with a tangent and no friction
 * (mu < 0 here) always stick; contacts without a tangent are frictionless.
 *
 * Modes change only at located roots (stick: mu lambda_n -+ lambda_t reaching 0; slip: the slip
 * velocity fmode u reaching 0; persistent contact: lambda_n reaching 0; the determinant of the
 * contact problem while a contact slips reaching 0: Painleve) and at impacts. There the modes of
 * all contacts in persistent contact are chosen together by enumeration (lcg_fr_modes): each contact
 * stick, slip +, slip - (the last two from rest only, |u| <= contact_speed; a sliding contact
 * keeps its direction) or release, the mode whose root fired excluded; a combination is
 * consistent when lambda_n >= 0, |lambda_t| <= mu lambda_n (stick), the tangential acceleration
 * has the slip's sign (slip from rest) and the normal acceleration >= 0 (release), to a relative
 * 1e-9. One consistent mode (or several with the same accelerations: the most constrained is
 * taken) is the motion; none (inconsistency) or several with different accelerations
 * (indeterminacy) is Painleve's paradox, reported by name (flag LCG_FLAG_CONTACT_MODE), never
 * integrated. Frictional impacts (lcg_fr_impact) are chosen the same way: each contact that takes
 * part in the impact with Newton's law on its normal and its tangential impulse sticking
 * (T dv = -u, |P_t| <= mu P_n) or sliding (P_t = -sigma mu P_n with sigma u+ >= 0), or left out
 * (P_n = 0, w+ >= 0).
 *
 * 3-D friction: a contact with two tangential rows T_1, T_2 (trow, trow2) has the exact circular
 * cone. It sticks (both rows held) while |lambda_t| <= mu lambda_n (root mu lambda_n - |lambda_t|)
 * and slips (fmode +1, "slip") with the force direction G - mu (d_1 T_1 + d_2 T_2), d = u / |u|
 * from the slip velocity at each state (lcg_fr_slip_directions); its root u . dref - |u| / 2 fires
 * where u stops or turns by 60 degrees from dref (d where the mode began; then only dref is
 * renewed). A slip from rest (|u| <= contact_speed) and a sliding impulse have no u to take d
 * from: fr_slip_fixed_point finds d = a_t / |a_t| (a_t: the tangential acceleration, or the slip
 * velocity after the impact), the force then opposing the slip it causes, by fixed-point
 * iteration and, where that does not converge (contacts coupled, sticking forces that have just
 * reached the cone: a_t small and turning fast with d), by Newton's method on the directions of
 * all such slips together (fr_slip_newton); the mode is consistent when a_t lies along d
 * (fr_aligned). When another contact's mode changes, a slip that has just begun (|u| <=
 * contact_speed) is offered slip (its direction found again from its own) and release, and
 * stick only where no mode is consistent without it. */

#define FR_STICK 0
#define FR_SLIP_POS 1
#define FR_SLIP_NEG 2
#define FR_FREE 3
#define FR_MAX_ENUM 4096 /* mode combinations enumerated at most */
#define FR_REL 1e-9      /* relative tolerance of the consistency conditions */
#define FR_SAME 1e-6     /* modes whose accelerations (velocity jumps) agree to this are one motion (as FR_DIR_REL:
                          * a slip whose tangential acceleration is negligible moves as the stick) */
#define FR_PI 3.14159265358979323846
#define FR_DIR_ITER 30   /* fixed-point iterations of a 3-D slip's direction at most */
#define FR_DIR_REL 1e-6  /* a 3-D slip's tangential acceleration (velocity after an impact) below this,
                          * relative to the largest, develops no slip: its direction d is kept and it
                          * is consistent (at the limit of sticking the force is the sticking one, and
                          * the tangential acceleration is the constraints' stabilization residue) */

static int coulomb(const lcg_fric *f, int k)
{
    return f->trow[k] >= 0 && f->mu[k] >= 0.0;
}

/* Whether contact k has 3-D Coulomb friction (two tangential rows, the exact circular cone). */
static int cone3(const lcg_fric *f, int k)
{
    return coulomb(f, k) && f->trow2[k] >= 0;
}

/* The model's numbers at (t, y) into f. */
int lcg_fr_eval(lcg_fric_ctx *d, double t, const double *y)
{
    lcg_fric *f = d->fr;
    return f->tab->eval(t, y, d->p, f->M, f->F, f->R, f->s, f->h, f->gam, f->qd);
}

/* b: the right-hand sides of the rows. accel: Baumgarte-stabilized accelerations (as the
 * generated crhs); otherwise the impact with the contacts' effective restitution eff[]. */
static void fr_rhs(lcg_fric_ctx *d, int accel, const double *eff)
{
    lcg_fric *f = d->fr;
    int r, nj = d->im->nj, nk = d->im->nk;

    for (r = 0; r < f->nrow; ++r) {
        if (!accel)
            f->b[r] = (r >= nj && r < nj + nk) ? -(1.0 + eff[r - nj]) * f->s[r] : -f->s[r];
        else if (r < f->tab->njh || (r >= nj && r < nj + nk))
            f->b[r] = f->gam[r] - 2.0 * d->alpha * f->s[r] - d->beta * d->beta * f->h[r];
        else
            f->b[r] = f->gam[r] - d->alpha * f->s[r];
    }
}

/* LU with partial pivoting of the dim x dim row-major A; *det its determinant. Returns 1, or 0
 * when a pivot is negligible (singular). */
static int fr_lu(int dim, double *A, int *piv, double *det)
{
    double scale = 0.0, dt = 1.0;
    int i, j, k;

    for (i = 0; i < dim * dim; ++i)
        if (fabs(A[i]) > scale)
            scale = fabs(A[i]);
    for (k = 0; k < dim; ++k) {
        int pr = k;
        for (i = k + 1; i < dim; ++i)
            if (fabs(A[i * dim + k]) > fabs(A[pr * dim + k]))
                pr = i;
        piv[k] = pr;
        if (!(fabs(A[pr * dim + k]) > dim * DBL_EPSILON * scale)) {
            *det = 0.0;
            return 0;
        }
        if (pr != k) {
            for (j = 0; j < dim; ++j) {
                double tmp = A[k * dim + j];
                A[k * dim + j] = A[pr * dim + j];
                A[pr * dim + j] = tmp;
            }
            dt = -dt;
        }
        dt *= A[k * dim + k];
        for (i = k + 1; i < dim; ++i) {
            double l = A[i * dim + k] / A[k * dim + k];
            A[i * dim + k] = l;
            for (j = k + 1; j < dim; ++j)
                A[i * dim + j] -= l * A[k * dim + j];
        }
    }
    *det = dt;
    return 1;
}

static void fr_lu_solve(int dim, const double *A, const int *piv, double *x)
{
    int i, j;

    for (i = 0; i < dim; ++i) {
        double tmp = x[piv[i]];
        x[piv[i]] = x[i];
        x[i] = tmp;
        for (j = 0; j < i; ++j)
            x[i] -= A[i * dim + j] * x[j];
    }
    for (i = dim - 1; i >= 0; --i) {
        for (j = i + 1; j < dim; ++j)
            x[i] -= A[i * dim + j] * x[j];
        x[i] /= A[i * dim + i];
    }
}

/* The contact problem of the mode (act[k]: in contact; mode[k]: 0 stick, +-1 slip) with the
 * numbers and right-hand sides in f: [M W^T; R 0] [x; z] = [F or 0; b], x into f->x, the
 * multipliers (impulses) lam = -z into f->lam (all rows; 0 off the mode; the tangential one of a
 * slipping contact -mode mu lambda_n), the determinant (0: singular) into f->det. Rows that are
 * dependent are solved with -eps on the multipliers' diagonal as the generated solve_active. */
static int fr_solve(lcg_fric_ctx *d, const int *act, const int *mode, const double *dir, int accel)
{
    lcg_fric *f = d->fr;
    int n = f->n, nj = d->im->nj, nk = d->im->nk, m = 0, r, i, j, k, dim, attempt;
    double mscale = 0.0, rscale = 0.0, eps = 0.0, det = 0.0;
    double *K = f->K, *rhs = f->rhs;

    for (r = 0; r < nj; ++r)
        f->sel[m++] = r;
    for (k = 0; k < nk; ++k)
        if (act[k]) {
            f->sel[m++] = nj + k;
            if (f->trow[k] >= 0 && (f->mu[k] < 0.0 || mode[k] == 0))
                f->sel[m++] = f->trow[k];
            if (f->trow2[k] >= 0 && (f->mu[k] < 0.0 || mode[k] == 0))
                f->sel[m++] = f->trow2[k];
        }
    dim = n + m;
    for (i = 0; i < n; ++i)
        if (fabs(f->M[i * n + i]) > mscale)
            mscale = fabs(f->M[i * n + i]);
    f->det = 0.0;
    for (attempt = 0; attempt < 2; ++attempt) {
        for (i = 0; i < n; ++i) {
            for (j = 0; j < n; ++j)
                K[i * dim + j] = f->M[i * n + j];
            rhs[i] = accel ? f->F[i] : 0.0;
        }
        for (j = 0; j < m; ++j) {
            const double *Rr = f->R + (long)f->sel[j] * n, *Tr = NULL, *Tr2 = NULL;
            double norm = 0.0, sm = 0.0, sm2 = 0.0;
            r = f->sel[j];
            if (r >= nj && r < nj + nk && coulomb(f, r - nj) && mode[r - nj] != 0) {
                k = r - nj;
                Tr = f->R + (long)f->trow[k] * n;
                sm = mode[k] * f->mu[k];
                if (cone3(f, k)) { /* the force -mu lambda_n (d_1 T_1 + d_2 T_2) */
                    Tr2 = f->R + (long)f->trow2[k] * n;
                    sm = f->mu[k] * dir[2 * k];
                    sm2 = f->mu[k] * dir[2 * k + 1];
                }
            }
            for (i = 0; i < n; ++i) {
                K[i * dim + n + j] = Tr != NULL ? Rr[i] - sm * Tr[i] - (Tr2 != NULL ? sm2 * Tr2[i] : 0.0) : Rr[i];
                K[(n + j) * dim + i] = Rr[i];
                norm += Rr[i] * Rr[i];
            }
            for (i = 0; i < m; ++i)
                K[(n + j) * dim + n + i] = 0.0;
            K[(n + j) * dim + n + j] = -eps;
            rhs[n + j] = f->b[r];
            if (norm > rscale)
                rscale = norm;
        }
        if (fr_lu(dim, K, f->piv, &det))
            break;
        if (attempt == 1 || m == 0 || !(rscale > 0.0))
            return LCG_DAE_ERR_SINGULAR;
        eps = 1e-12 * mscale / rscale;
    }
    if (attempt == 0)
        f->det = det;
    fr_lu_solve(dim, K, f->piv, rhs);
    for (i = 0; i < dim; ++i)
        if (!isfinite(rhs[i]))
            return LCG_DAE_ERR_NONFINITE;
    for (i = 0; i < n; ++i)
        f->x[i] = rhs[i];
    for (r = 0; r < f->nrow; ++r)
        f->lam[r] = 0.0;
    for (j = 0; j < m; ++j)
        f->lam[f->sel[j]] = -rhs[n + j];
    for (k = 0; k < nk; ++k)
        if (act[k] && cone3(f, k) && mode[k] != 0) {
            f->lam[f->trow[k]] = -dir[2 * k] * f->mu[k] * f->lam[nj + k];
            f->lam[f->trow2[k]] = -dir[2 * k + 1] * f->mu[k] * f->lam[nj + k];
        } else if (act[k] && coulomb(f, k) && mode[k] != 0) {
            f->lam[f->trow[k]] = -mode[k] * f->mu[k] * f->lam[nj + k];
        }
    return LCG_DAE_OK;
}

/* R_r x - gamma_r (accelerations x: the row's second derivative) or s_r + R_r x (impacts,
 * x = dv: the row's velocity after). */
static double fr_row(const lcg_fric *f, int r, const double *x, int accel)
{
    double v = accel ? -f->gam[r] : f->s[r];
    int i;

    for (i = 0; i < f->n; ++i)
        v += f->R[(long)r * f->n + i] * x[i];
    return v;
}

/* The slip velocity of contact k along its tangents (u2: 0 for a planar contact). */
void lcg_fr_slip(const lcg_fric *f, int k, double *u, double *u2)
{
    *u = f->trow[k] >= 0 ? f->s[f->trow[k]] : 0.0;
    *u2 = f->trow2[k] >= 0 ? f->s[f->trow2[k]] : 0.0;
}

/* 3-D friction: the force of a slipping contact opposes its slip velocity u, d = u / |u| (the
 * numbers in f at a state), where the slip's root u . dref - |u| / 2 is positive (u within 60
 * degrees of dref) and |u| above 1e-3 contact_speed; elsewhere d = dref: a slip that begins from
 * rest (the direction chosen with its mode), and past the root, so that the motion stays smooth
 * through u = 0 along dref and CVODE's interpolant locates the root as in the planar case (the
 * direction u / |u| would flip there). */
void lcg_fr_slip_directions(lcg_fric *f, int nk)
{
    int k;

    for (k = 0; k < nk; ++k) {
        double u, u2, norm;
        if (!cone3(f, k) || f->fmode[k] == 0)
            continue;
        lcg_fr_slip(f, k, &u, &u2);
        norm = hypot(u, u2);
        if (norm > 1e-3 * f->vtol && u * f->dref[2 * k] + u2 * f->dref[2 * k + 1] > 0.5 * norm) {
            f->dir[2 * k] = u / norm;
            f->dir[2 * k + 1] = u2 / norm;
        } else {
            f->dir[2 * k] = f->dref[2 * k];
            f->dir[2 * k + 1] = f->dref[2 * k + 1];
        }
    }
}

/* The friction roots of the current modes at a state (gf[2 nk + 1]; see lcg_imp_fric.h) from the
 * multipliers lam[nrow] there and the numbers in d->fr evaluated there (s; det while a contact slips). */
void lcg_fr_roots(const lcg_fric_ctx *d, const double *lam, double *gf)
{
    const lcg_fric *f = d->fr;
    int k, nk = d->im->nk, nj = d->im->nj, slipping = 0;

    for (k = 0; k < nk; ++k) {
        gf[2 * k] = gf[2 * k + 1] = 1.0;
        if (!d->active[k] || f->trow[k] < 0 || f->mu[k] < 0.0)
            continue;
        if (f->trow2[k] >= 0 && f->fmode[k] == 0) { /* 3-D: the cone's bound widened by the tolerance
                                                      * with which sticking was found admissible */
            int r;
            double big = 0.0;
            for (r = 0; r < f->nrow; ++r)
                if (fabs(lam[r]) > big)
                    big = fabs(lam[r]);
            gf[2 * k] = f->mu[k] * lam[nj + k] - hypot(lam[f->trow[k]], lam[f->trow2[k]])
                        + FR_REL * (1.0 + big);
        } else if (f->trow2[k] >= 0) { /* 3-D: u . dref - |u| / 2: u stops (or turns by 60 degrees) */
            double u, u2;
            lcg_fr_slip(f, k, &u, &u2);
            gf[2 * k] = u * f->dref[2 * k] + u2 * f->dref[2 * k + 1] - 0.5 * hypot(u, u2);
            slipping = 1;
        } else if (f->fmode[k] == 0) {
            gf[2 * k] = f->mu[k] * lam[nj + k] - lam[f->trow[k]];
            gf[2 * k + 1] = f->mu[k] * lam[nj + k] + lam[f->trow[k]];
        } else {
            gf[2 * k] = f->fmode[k] * f->s[f->trow[k]];
            slipping = 1;
        }
    }
    gf[2 * nk] = slipping && f->det0 != 0.0 ? f->det / f->det0 : 1.0;
}

/* The right-hand side of the current mode at (t, y): ydot = (q', v'), lam[nrow] (NULL: not
 * wanted). */
int lcg_fr_crhs(lcg_fric_ctx *d, double t, const double *y, double *ydot, double *lam)
{
    lcg_fric *f = d->fr;
    int i, rc, n = f->n;

    rc = lcg_fr_eval(d, t, y);
    if (rc != LCG_DAE_OK)
        return rc;
    fr_rhs(d, 1, NULL);
    lcg_fr_slip_directions(f, d->im->nk);
    rc = fr_solve(d, d->active, f->fmode, f->dir, 1);
    if (rc != LCG_DAE_OK)
        return rc;
    for (i = 0; i < f->nq; ++i)
        ydot[i] = f->qd[i];
    for (i = 0; i < n; ++i)
        ydot[f->nq + i] = f->x[i];
    if (lam != NULL)
        for (i = 0; i < f->nrow; ++i)
            lam[i] = f->lam[i];
    return LCG_DAE_OK;
}

static const char *fr_mode_name(int act, int mode, int three)
{
    return !act ? "free" : mode != 0 && three ? "slip" : mode > 0 ? "slip+" : mode < 0 ? "slip-" : "stick";
}

/* "k:mode, ..." of the contacts that are or were in contact (was[k]) into buf. */
static void fr_describe(const lcg_fric_ctx *d, const int *was, const int *act, const int *mode, char *buf,
                        size_t size)
{
    size_t used = 0;
    int k;

    buf[0] = '\0';
    for (k = 0; k < d->im->nk && used + 1 < size; ++k) {
        int len;
        if (!was[k])
            continue;
        len = snprintf(buf + used, size - used, "%s%d:%s", used ? " " : "", k,
                       fr_mode_name(act[k], mode[k], cone3(d->fr, k)));
        if (len < 0)
            break;
        used += (size_t)len;
    }
}

/* The trial mode solved (f->tact, f->tmode, f->tdir), the directions of its 3-D slips whose
 * direction is not given by the slip velocity (a slip from rest, |u| <= contact_speed, and every
 * slip in an impact) found by fixed-point iteration; but a slip that begins where the sticking
 * force reached the cone's bound (its root fired: ending FR_END_STICK) keeps that force's
 * direction, d = -lambda_t / |lambda_t| (the friction force continuous; the tangential
 * acceleration there is ~0, its direction the root's residue and round-off): d = a_t / |a_t| with a_t the tangential
 * acceleration (impact: the slip velocity after), so that the force -mu lambda_n d opposes the slip
 * that results (maximal dissipation on the circular cone); at most FR_DIR_ITER + 1 solves. */
static int fr_slip_given(const lcg_fric *f, int k);
static int fr_slip_newton(lcg_fric_ctx *d, int accel, const double *start);

static int fr_slip_fixed_point(lcg_fric_ctx *d, int accel)
{
    lcg_fric *f = d->fr;
    int it, k, rc, nk = d->im->nk;
    double *start = f->nw + nk * nk + 4 * nk; /* the first guesses, 2 nk */
    double *last = start + 2 * nk;            /* the fixed point's last directions, 2 nk */

    for (k = 0; k < 2 * nk; ++k)
        start[k] = f->tdir[k];

    for (it = 0; it < FR_DIR_ITER; ++it) {
        int moved = 0, i;
        double tol = 0.0;
        rc = fr_solve(d, f->tact, f->tmode, f->tdir, accel);
        if (rc != LCG_DAE_OK)
            return rc;
        for (i = 0; i < f->n; ++i)
            if (fabs(f->x[i]) > tol)
                tol = fabs(f->x[i]);
        tol = FR_DIR_REL * (1.0 + tol);
        for (k = 0; k < nk; ++k) {
            double a, a2, na;
            if (!f->tact[k] || !cone3(f, k) || f->tmode[k] == 0 || (accel && fr_slip_given(f, k)))
                continue;
            a = fr_row(f, f->trow[k], f->x, accel);
            a2 = fr_row(f, f->trow2[k], f->x, accel);
            na = hypot(a, a2);
            if (!(na > tol)) /* no slip develops along d (the limit of sticking, where the force is the
                              * sticking one): d is kept, not turned to the direction of round-off */
                continue;
            if (hypot(a / na - f->tdir[2 * k], a2 / na - f->tdir[2 * k + 1]) > 1e-13)
                moved = 1;
            f->tdir[2 * k] = a / na;
            f->tdir[2 * k + 1] = a2 / na;
        }
        if (!moved)
            return LCG_DAE_OK;
    }
    /* not converged: the directions solved together by Newton's method from the first guesses
     * (fr_slip_newton); failing that (e.g. a_t against d whatever d: no slip from rest), the last
     * directions solved, for the caller's check of a_t along d */
    for (k = 0; k < 2 * nk; ++k)
        last[k] = f->tdir[k];
    if (!fr_slip_newton(d, accel, start))
        for (k = 0; k < 2 * nk; ++k)
            f->tdir[k] = last[k];
    return fr_solve(d, f->tact, f->tmode, f->tdir, accel);
}

/* The angular residuals of the unknown 3-D slips idx[0..nu-1] at the directions th (angles in the
 * tangents' plane): r_i = th_i - angle(a_t) wrapped to (-pi, pi] (0 where a_t is negligible: no
 * slip develops, d kept); the mode solved with those directions; *done: whether every a_t lies
 * along its d to the accuracy a_t has, |a_t x d| <= 1e-3 FR_REL (1 + max |x|) + 1e-10 |a_t| (a_t
 * of a slip that has just reached the cone is small: its angle is known to round-off over |a_t|).
 * Returns LCG_DAE_OK or an error. */
static int fr_newton_residual(lcg_fric_ctx *d, int accel, const int *idx, int nu, const double *th, double *r,
                              int *done)
{
    lcg_fric *f = d->fr;
    int i, rc;
    double tol = 0.0, across;

    for (i = 0; i < nu; ++i) {
        f->tdir[2 * idx[i]] = cos(th[i]);
        f->tdir[2 * idx[i] + 1] = sin(th[i]);
    }
    rc = fr_solve(d, f->tact, f->tmode, f->tdir, accel);
    if (rc != LCG_DAE_OK)
        return rc;
    for (i = 0; i < f->n; ++i)
        if (fabs(f->x[i]) > tol)
            tol = fabs(f->x[i]);
    across = 1e-3 * FR_REL * (1.0 + tol);
    tol = FR_DIR_REL * (1.0 + tol);
    *done = 1;
    for (i = 0; i < nu; ++i) {
        int k = idx[i];
        double a = fr_row(f, f->trow[k], f->x, accel), a2 = fr_row(f, f->trow2[k], f->x, accel), e;
        if (!(hypot(a, a2) > tol)) {
            r[i] = 0.0;
            continue;
        }
        e = th[i] - atan2(a2, a);
        r[i] = e - 2.0 * FR_PI * floor((e + FR_PI) / (2.0 * FR_PI));
        if (!(fabs(r[i]) < 0.5 * FR_PI && hypot(a, a2) * fabs(sin(r[i])) <= across + 1e-10 * hypot(a, a2)))
            *done = 0;
    }
    return LCG_DAE_OK;
}

/* The slip directions d_k of the trial mode's 3-D slips that are to be found (as in
 * fr_slip_fixed_point), solved together: Newton's method on their angles th_k for
 * th_k = angle(a_t,k(th)) (each force opposing the slip it causes), the Jacobian by forward
 * differences (one solve of the contact problem per unknown), steps halved while the largest
 * residual does not decrease; from the first guesses start[2 nk]. Where contacts are coupled and
 * the sticking forces have just reached the cone (a_t small, turning fast with d) the fixed point
 * diverges; Newton converges. Returns 1 with f->tdir set when converged (see fr_newton_residual),
 * 0 when not (or a trial's contact problem was singular). */
static int fr_slip_newton(lcg_fric_ctx *d, int accel, const double *start)
{
    lcg_fric *f = d->fr;
    int nk = d->im->nk, nu = 0, i, j, k, it, rc, done = 0, probe;
    int *idx = f->nidx, *piv = f->nidx + nk;
    double *J = f->nw, *th = J + nk * nk, *r = th + nk, *r2 = r + nk, *dth = r2 + nk;
    double best, det;

    for (k = 0; k < nk; ++k)
        if (f->tact[k] && cone3(f, k) && f->tmode[k] != 0 && !(accel && fr_slip_given(f, k))) {
            idx[nu] = k;
            th[nu++] = atan2(start[2 * k + 1], start[2 * k]);
        }
    if (nu == 0)
        return 0;
    rc = fr_newton_residual(d, accel, idx, nu, th, r, &done);
    if (rc != LCG_DAE_OK)
        return 0;
    for (it = 0; it < FR_DIR_ITER; ++it) {
        double step = 1.0;
        best = 0.0;
        for (i = 0; i < nu; ++i)
            if (fabs(r[i]) > best)
                best = fabs(r[i]);
        if (done)
            return 1;
        for (j = 0; j < nu; ++j) { /* J[i][j] = d r_i / d th_j */
            double h = 1e-7;
            th[j] += h;
            rc = fr_newton_residual(d, accel, idx, nu, th, r2, &probe);
            th[j] -= h;
            if (rc != LCG_DAE_OK)
                return 0;
            for (i = 0; i < nu; ++i) {
                double e = r2[i] - r[i];
                e -= 2.0 * FR_PI * floor((e + FR_PI) / (2.0 * FR_PI));
                J[i * nu + j] = e / h;
            }
        }
        if (!fr_lu(nu, J, piv, &det))
            break;
        for (i = 0; i < nu; ++i)
            dth[i] = -r[i];
        fr_lu_solve(nu, J, piv, dth);
        for (; step > 1e-4; step *= 0.5) { /* the step, halved until the largest residual decreases */
            double now = 0.0;
            for (i = 0; i < nu; ++i)
                th[i] += step * dth[i];
            rc = fr_newton_residual(d, accel, idx, nu, th, r2, &done);
            if (rc != LCG_DAE_OK)
                return 0;
            for (i = 0; i < nu; ++i)
                if (fabs(r2[i]) > now)
                    now = fabs(r2[i]);
            if (now < best || done)
                break;
            for (i = 0; i < nu; ++i)
                th[i] -= step * dth[i];
        }
        if (!(step > 1e-4))
            break;
        for (i = 0; i < nu; ++i)
            r[i] = r2[i];
        if (done)
            return 1;
    }
    return 0;
}

/* Whether a 3-D slip of contact k (in lcg_fr_modes, at the current state) has its direction given,
 * not to be found: it slips at more than contact_speed (d = u / |u|), or it slips already and its
 * slip root has not fired (a slip that has just begun: d its own), or it begins where its
 * sticking force reached the cone's bound (d against that force, continuous). */
static int fr_slip_given(const lcg_fric *f, int k)
{
    return hypot(f->u[k], f->u2[k]) > f->vtol || (f->fmode[k] != 0 && f->ending[k] == 0)
           || f->ending[k] == FR_END_STICK;
}

/* Whether the 3-D slip of contact k in the trial mode has its tangential acceleration (impact:
 * velocity after) a along its direction d: a . d >= -tol and |a x d| <= tol + 1e-6 |a|, or a
 * negligible (FR_DIR_REL). */
static int fr_aligned(const lcg_fric *f, int k, int accel, double tol)
{
    double a = fr_row(f, f->trow[k], f->x, accel), a2 = fr_row(f, f->trow2[k], f->x, accel);
    double along = a * f->tdir[2 * k] + a2 * f->tdir[2 * k + 1];
    double across = a * f->tdir[2 * k + 1] - a2 * f->tdir[2 * k];
    double small = 0.0;
    int i;

    for (i = 0; i < f->n; ++i)
        if (fabs(f->x[i]) > small)
            small = fabs(f->x[i]);
    if (hypot(a, a2) <= FR_DIR_REL * (1.0 + small)) /* no slip develops (see FR_DIR_REL) */
        return 1;
    return along >= -tol && fabs(across) <= tol + 1e-6 * hypot(a, a2);
}

/* Choose the modes of the contacts in persistent contact at (t, y) by enumeration (see above);
 * ending[k] (NULL: none) excludes the mode whose root fired. The transitions are recorded (rec,
 * max_rec, n_rec); a contact that begins to stick gets its slip velocity projected to zero
 * (y's velocities changed). Returns LCG_DAE_OK, a model error, or -1 with the Painleve message in
 * d->message (the caller stops with LCG_FLAG_CONTACT_MODE). */
/* Mode c of the enumeration (a mixed-radix number over the contacts' options f->opts, f->nopt)
 * into f->tact, f->tmode, and its problem solved (accel: 1 the accelerations, 0 the impulses of an
 * impact). Returns LCG_DAE_OK with *lscale = FR_REL (1 + max |multiplier|), LCG_DAE_ERR_SINGULAR
 * (a mode to pass over) or another error. */
static int fr_try_mode(lcg_fric_ctx *d, int c, int accel, double *lscale)
{
    lcg_fric *f = d->fr;
    int idx = c, k, i, rc;
    double m = 0.0;

    for (k = 0; k < d->im->nk; ++k) {
        int ch = f->opts[4 * k + idx % f->nopt[k]];
        idx /= f->nopt[k];
        f->tact[k] = ch != FR_FREE;
        f->tmode[k] = ch == FR_SLIP_POS ? 1 : ch == FR_SLIP_NEG ? -1 : 0;
        if (cone3(f, k)) { /* the first guess of a 3-D slip's direction (lcg_fr_modes, lcg_fr_impact) */
            f->tdir[2 * k] = f->gdir[2 * k];
            f->tdir[2 * k + 1] = f->gdir[2 * k + 1];
        }
    }
    rc = fr_slip_fixed_point(d, accel);
    if (rc != LCG_DAE_OK)
        return rc;
    for (i = 0; i < f->nrow; ++i)
        if (fabs(f->lam[i]) > m)
            m = fabs(f->lam[i]);
    *lscale = FR_REL * (1.0 + m);
    return LCG_DAE_OK;
}

/* The mode just solved (f->x, f->lam, modes f->tact, f->tmode) against the first consistent one:
 * the first is kept (f->bact, f->bmode, f->bestx, f->bestlam; *found set) and 0 returned; a later
 * one returns 1 if its accelerations (velocity jumps) differ from the first's beyond FR_SAME. */
static int fr_another_motion(lcg_fric *f, int nk, int n, int *found, double *xscale)
{
    int i, k;

    if (!*found) {
        *found = 1;
        for (k = 0; k < nk; ++k) {
            f->bact[k] = f->tact[k];
            f->bmode[k] = f->tmode[k];
            f->bdir[2 * k] = f->tdir[2 * k];
            f->bdir[2 * k + 1] = f->tdir[2 * k + 1];
        }
        for (i = 0; i < n; ++i) {
            f->bestx[i] = f->x[i];
            if (fabs(f->x[i]) > *xscale)
                *xscale = fabs(f->x[i]);
        }
        for (i = 0; i < f->nrow; ++i)
            f->bestlam[i] = f->lam[i];
        return 0;
    }
    for (i = 0; i < n; ++i)
        if (fabs(f->x[i] - f->bestx[i]) > FR_SAME * (1.0 + *xscale))
            return 1;
    return 0;
}

int lcg_fr_modes(lcg_fric_ctx *d, double t, double *y, const int *ending, double vtol, double *rec, int max_rec,
                 int *n_rec)
{
    lcg_fric *f = d->fr;
    int nk = d->im->nk, nj = d->im->nj, n = f->n, k, i, c, rc, total = 1, found = 0, grip = 0, pass;
    double xscale = 0.0;
    char a[120], b[120];

    rc = lcg_fr_eval(d, t, y);
    if (rc != LCG_DAE_OK)
        return rc;
    fr_rhs(d, 1, NULL);
    lcg_fr_slip_directions(f, nk);
    if (fr_solve(d, d->active, f->fmode, f->dir, 1) != LCG_DAE_OK) /* the current modes' forces (guesses below) */
        for (i = 0; i < f->nrow; ++i)
            f->lam[i] = 0.0;
    /* pass 0: a slip just begun goes on (or releases); pass 1, only if pass 0 finds no consistent
     * mode: it may also stick (a slip just begun and a stick are both consistent at the limit of
     * sticking, with accelerations that differ by the force's excess over the cone) */
    for (pass = 0; pass < 2 && !found; ++pass) {
        int begun = 0;
        total = 1;
        for (k = 0; k < nk; ++k) {
            int *o = f->opts + 4 * k, no = 0, end = ending != NULL ? ending[k] : 0;
            double u, u2;
            lcg_fr_slip(f, k, &u, &u2);
            f->u[k] = u;
            f->u2[k] = u2;
            if (cone3(f, k)) { /* the guess of a 3-D slip's direction: along u, or against the sticking force */
                double nu = hypot(u, u2), lt = f->lam[f->trow[k]], lt2 = f->lam[f->trow2[k]], nl = hypot(lt, lt2);
                int keep = f->fmode[k] != 0 && end == 0 && nu <= vtol; /* a slip just begun: its own direction */
                f->gdir[2 * k] = keep ? f->dir[2 * k] : nu > vtol ? u / nu : nl > 0.0 ? -lt / nl : f->dir[2 * k];
                f->gdir[2 * k + 1] = keep ? f->dir[2 * k + 1] : nu > vtol ? u2 / nu : nl > 0.0 ? -lt2 / nl
                                                                                        : f->dir[2 * k + 1];
            }
            if (!d->active[k] || end == FR_END_RELEASE) {
                o[no++] = FR_FREE;
            } else if (cone3(f, k) && f->fmode[k] != 0 && end == 0 && hypot(u, u2) <= vtol) { /* 3-D, a slip just
                                                                                               * begun: on */
                o[no++] = FR_SLIP_POS;
                if (pass == 1) /* when another contact's change turns its acceleration against d */
                    o[no++] = FR_STICK;
                o[no++] = FR_FREE;
                begun = 1;
            } else if (cone3(f, k) && hypot(u, u2) <= vtol) { /* 3-D from rest: stick, slip, release */
                int cur = f->fmode[k] == 0 ? FR_STICK : FR_SLIP_POS;
                for (i = 0; i < 4; ++i)
                    if (i != FR_SLIP_NEG && !(end != 0 && i == cur && cur == FR_STICK))
                        o[no++] = i;
            } else if (cone3(f, k)) { /* 3-D slipping: on, d = u / |u| */
                o[no++] = FR_SLIP_POS;
                o[no++] = FR_FREE;
            } else if (!coulomb(f, k)) {
                o[no++] = FR_STICK;
                o[no++] = FR_FREE;
            } else if (fabs(u) <= vtol) {
                int cur = f->fmode[k] == 0 ? FR_STICK : f->fmode[k] > 0 ? FR_SLIP_POS : FR_SLIP_NEG;
                for (i = 0; i < 4; ++i)
                    if (!(end != 0 && i == cur))
                        o[no++] = i;
            } else {
                o[no++] = u > 0.0 ? FR_SLIP_POS : FR_SLIP_NEG;
                o[no++] = FR_FREE;
            }
            f->nopt[k] = no;
            if (total > FR_MAX_ENUM / no) {
                snprintf(d->message, d->message_size, "more than %d stick/slip/release modes of the "
                         "contacts in persistent contact at t = %.17g to enumerate", FR_MAX_ENUM, t);
                return -1;
            }
            total *= no;
        }
        for (c = 0; c < total; ++c) {
            int ok = 1;
            double lscale, ascale = 0.0;
            rc = fr_try_mode(d, c, 1, &lscale);
            if (rc == LCG_DAE_ERR_SINGULAR)
                continue;
            if (rc != LCG_DAE_OK)
                return rc;
            for (i = 0; i < n; ++i)
                if (fabs(f->x[i]) > ascale)
                    ascale = fabs(f->x[i]);
            ascale = FR_REL * (1.0 + ascale);
            for (k = 0; k < nk && ok; ++k) {
                if (f->tact[k]) {
                    double ln = f->lam[nj + k];
                    ok = ln >= -lscale;
                    if (ok && cone3(f, k) && f->tmode[k] == 0)
                        ok = hypot(f->lam[f->trow[k]], f->lam[f->trow2[k]]) <= f->mu[k] * ln + lscale;
                    else if (ok && cone3(f, k) && !fr_slip_given(f, k))
                        ok = fr_aligned(f, k, 1, ascale);
                    else if (ok && cone3(f, k))
                        ok = 1;
                    else if (ok && coulomb(f, k) && f->tmode[k] == 0)
                        ok = fabs(f->lam[f->trow[k]]) <= f->mu[k] * ln + lscale;
                    else if (ok && coulomb(f, k) && fabs(f->u[k]) <= vtol)
                        ok = f->tmode[k] * fr_row(f, f->trow[k], f->x, 1) >= -ascale;
                } else if (d->active[k]) {
                    ok = fr_row(f, nj + k, f->x, 1) >= -ascale;
                }
            }
            if (!ok)
                continue;
            if (fr_another_motion(f, nk, n, &found, &xscale)) {
                fr_describe(d, d->active, f->bact, f->bmode, a, sizeof a);
                fr_describe(d, d->active, f->tact, f->tmode, b, sizeof b);
                snprintf(d->message, d->message_size, "Painleve's paradox (indeterminacy) at t = %.17g: the "
                         "contact modes [%s] and [%s] are both consistent with Coulomb friction and give different "
                         "accelerations (friction too large for this configuration)", t, a, b);
                return -1;
            }
        }
        if (!begun)
            break;
    }
    if (!found) {
        fr_describe(d, d->active, d->active, f->fmode, a, sizeof a);
        snprintf(d->message, d->message_size, "Painleve's paradox (inconsistency) at t = %.17g: no "
                 "stick/slip/release mode of the contacts [%s] has admissible contact forces (lambda_n >= 0, "
                 "|lambda_t| <= mu lambda_n) with Coulomb friction (friction too large for this configuration)",
                 t, a);
        return -1;
    }
    for (k = 0; k < nk; ++k) {
        int was = d->active[k], old = f->fmode[k], now = f->bmode[k];
        double lt = f->trow[k] >= 0 ? f->bestlam[f->trow[k]] : 0.0;
        if (!was)
            continue;
        if (cone3(f, k)) { /* 3-D: |lambda_t| and |u| recorded; the slip direction and the root's reference */
            lt = hypot(lt, f->bestlam[f->trow2[k]]);
            f->u[k] = hypot(f->u[k], f->u2[k]);
            f->dir[2 * k] = f->dref[2 * k] = f->bdir[2 * k];
            f->dir[2 * k + 1] = f->dref[2 * k + 1] = f->bdir[2 * k + 1];
        }
        if (!f->bact[k]) {
            d->active[k] = 0;
            f->fmode[k] = 0;
            record(rec, max_rec, n_rec, t, k, LCG_IMP_RELEASE, 0.0, 0.0, 0.0);
            continue;
        }
        if (coulomb(f, k) && old != now) {
            int kind = old == 0 ? LCG_IMP_SLIP : now == 0 ? LCG_IMP_GRIP : LCG_IMP_REVERSE;
            record(rec, max_rec, n_rec, t, k, kind, lt, f->u[k], now == 0 ? 0.0 : f->u[k]);
            grip |= now == 0;
        }
        f->fmode[k] = now;
    }
    if (grip) { /* the contacts that begin to stick: their slip velocity (and the normal ones) to 0 */
        for (k = 0; k < nk; ++k)
            f->eff[k] = 0.0;
        fr_rhs(d, 0, f->eff);
        rc = fr_solve(d, d->active, f->fmode, f->dir, 0);
        if (rc != LCG_DAE_OK)
            return rc;
        for (i = 0; i < n; ++i)
            y[f->nq + i] += f->x[i];
    }
    rc = lcg_fr_crhs(d, t, y, d->ydot, d->lam);
    if (rc != LCG_DAE_OK)
        return rc;
    f->det0 = f->det;
    return LCG_DAE_OK;
}

/* The frictional impact at (t, y) of the free contacts that touch and close (and those that
 * hit[]) with the contacts in persistent contact (see above and impact()). Returns as lcg_fr_modes. */
int lcg_fr_impact(lcg_fric_ctx *d, double t, double *y, const int *hit, const double *e, const double *set,
                  double *last, double *rec, int max_rec, int *n_rec)
{
    lcg_fric *f = d->fr;
    int nk = d->im->nk, nj = d->im->nj, n = f->n, k, i, c, rc, total = 1, found = 0, changed = 0;
    double gap_tol = set[2], vscale = 0.0, xscale = 0.0;
    char a[120], b[120];

    rc = lcg_fr_eval(d, t, y);
    if (rc != LCG_DAE_OK)
        return rc;
    for (k = 0; k < nk; ++k) {
        int *o = f->opts + 4 * k, no = 0;
        double g = f->h[nj + k], w = f->s[nj + k];
        f->wm[k] = w;
        lcg_fr_slip(f, k, &f->u[k], &f->u2[k]);
        if (cone3(f, k)) { /* the guess of a 3-D sliding impulse's direction: along u before */
            double nu = hypot(f->u[k], f->u2[k]);
            f->gdir[2 * k] = nu > 0.0 ? f->u[k] / nu : f->dir[2 * k];
            f->gdir[2 * k + 1] = nu > 0.0 ? f->u2[k] / nu : f->dir[2 * k + 1];
        }
        f->part[k] = d->active[k] || ((hit[k] || g <= gap_tol) && w < 0.0);
        f->plastic[k] = d->active[k] || e[k] * fabs(w) <= set[0] || t - last[k] < set[1];
        f->eff[k] = f->plastic[k] ? 0.0 : e[k];
        changed |= f->part[k] && !d->active[k];
        if (f->part[k]) {
            o[no++] = FR_STICK;
            if (coulomb(f, k)) {
                o[no++] = FR_SLIP_POS;
                if (!cone3(f, k))
                    o[no++] = FR_SLIP_NEG;
            }
            if (fabs(w) > vscale)
                vscale = fabs(w);
            if (hypot(f->u[k], f->u2[k]) > vscale)
                vscale = hypot(f->u[k], f->u2[k]);
        }
        o[no++] = FR_FREE;
        f->nopt[k] = no;
        if (total > FR_MAX_ENUM / no) {
            snprintf(d->message, d->message_size, "more than %d modes of the contacts in the impact at "
                     "t = %.17g to enumerate", FR_MAX_ENUM, t);
            return -1;
        }
        total *= no;
    }
    if (!changed)
        return LCG_DAE_OK;
    fr_rhs(d, 0, f->eff);
    vscale = FR_REL * (1.0 + vscale);
    for (c = 0; c < total; ++c) {
        int ok = 1;
        double pscale;
        rc = fr_try_mode(d, c, 0, &pscale);
        if (rc == LCG_DAE_ERR_SINGULAR)
            continue;
        if (rc != LCG_DAE_OK)
            return rc;
        for (k = 0; k < nk && ok; ++k) {
            if (!f->part[k])
                continue;
            if (!f->tact[k]) {
                ok = fr_row(f, nj + k, f->x, 0) >= -vscale;
                continue;
            }
            ok = f->lam[nj + k] >= -pscale;
            if (ok && cone3(f, k) && f->tmode[k] == 0)
                ok = hypot(f->lam[f->trow[k]], f->lam[f->trow2[k]]) <= f->mu[k] * f->lam[nj + k] + pscale;
            else if (ok && cone3(f, k))
                ok = fr_aligned(f, k, 0, vscale);
            else if (ok && coulomb(f, k) && f->tmode[k] == 0)
                ok = fabs(f->lam[f->trow[k]]) <= f->mu[k] * f->lam[nj + k] + pscale;
            else if (ok && coulomb(f, k))
                ok = f->tmode[k] * fr_row(f, f->trow[k], f->x, 0) >= -vscale;
        }
        if (!ok)
            continue;
        if (fr_another_motion(f, nk, n, &found, &xscale)) {
            fr_describe(d, f->part, f->bact, f->bmode, a, sizeof a);
            fr_describe(d, f->part, f->tact, f->tmode, b, sizeof b);
            snprintf(d->message, d->message_size, "Painleve's paradox (indeterminate frictional impact) "
                     "at t = %.17g: the impact modes [%s] and [%s] are both consistent with Newton's law and Coulomb "
                     "friction and give different velocities", t, a, b);
            return -1;
        }
    }
    if (!found) {
        fr_describe(d, f->part, f->part, f->fmode, a, sizeof a);
        snprintf(d->message, d->message_size, "Painleve's paradox (inconsistent frictional impact) at "
                 "t = %.17g: no stick/slide/leave mode of the contacts [%s] in the impact has admissible "
                 "impulses (P_n >= 0, |P_t| <= mu P_n) with Newton's law", t, a);
        return -1;
    }
    for (i = 0; i < n; ++i)
        y[f->nq + i] += f->bestx[i];
    for (k = 0; k < nk; ++k) {
        double wp, up;
        if (!f->part[k])
            continue;
        if (!f->bact[k]) {
            if (d->active[k]) {
                d->active[k] = 0;
                record(rec, max_rec, n_rec, t, k, LCG_IMP_RELEASE, 0.0, f->wm[k], f->wm[k]);
            }
            continue;
        }
        wp = fr_row(f, nj + k, f->bestx, 0);
        if (d->active[k]) {
            if (f->bestlam[nj + k] != 0.0)
                record(rec, max_rec, n_rec, t, k, LCG_IMP_CONTACT_IMPULSE, f->bestlam[nj + k], f->wm[k], wp);
        } else {
            last[k] = t;
            d->active[k] = f->plastic[k];
            record(rec, max_rec, n_rec, t, k, f->plastic[k] ? LCG_IMP_STICK : LCG_IMP_BOUNCE, f->bestlam[nj + k],
                   f->wm[k], wp);
        }
        f->fmode[k] = f->bmode[k];
        if (cone3(f, k)) { /* 3-D: |P_t| and |u| before and after recorded; the direction kept */
            double pt = hypot(f->bestlam[f->trow[k]], f->bestlam[f->trow2[k]]);
            f->dir[2 * k] = f->dref[2 * k] = f->bdir[2 * k];
            f->dir[2 * k + 1] = f->dref[2 * k + 1] = f->bdir[2 * k + 1];
            up = hypot(fr_row(f, f->trow[k], f->bestx, 0), fr_row(f, f->trow2[k], f->bestx, 0));
            if (pt != 0.0)
                record(rec, max_rec, n_rec, t, k, LCG_IMP_TANGENTIAL_IMPULSE, pt, hypot(f->u[k], f->u2[k]), up);
        } else if (f->trow[k] >= 0 && f->bestlam[f->trow[k]] != 0.0) {
            up = fr_row(f, f->trow[k], f->bestx, 0);
            record(rec, max_rec, n_rec, t, k, LCG_IMP_TANGENTIAL_IMPULSE, f->bestlam[f->trow[k]], f->u[k], up);
        }
    }
    return LCG_DAE_OK;
}


/* The friction state of the table fr with the coefficients mu[nk] in one block of memory
 * (*mem, freed by the caller); the table checked against im. Returns 0, or -1 (out of memory, or
 * a table of another layout: message in message). */
int lcg_fr_setup(lcg_fric *f, const lcg_imp_friction *fr, const lcg_imp_model *im, const double *mu, double vtol,
                 void **mem, char *message, size_t message_size)
{
    int tangents_ok = 1;
    int nq = im->nq, n = im->dae->ny - nq, nrow = im->nrow, nk = im->nk, dim = n + nrow, k, i;
    size_t nd = (size_t)(n * n + n + nrow * n + 4 * nrow + nq + dim * dim + dim + n + nrow + n + nrow + 3 * nk
                         + nk + 10 * nk + nk * nk + 8 * nk);
    size_t ni = (size_t)(3 * nk + dim + nrow + 4 * nk + 10 * nk + 2 * nk);
    double *db;
    int *ib;

    if (fr->abi != LCG_IMP_FRICTION_ABI || fr->imp != im || fr->nt != nrow - im->nj - nk || fr->njh < 0
        || n < 1 || im->dae->nq != nq
        || fr->njh > im->nj || (fr->nt > 0 && fr->tangent_of == NULL) || fr->eval == NULL) {
        snprintf(message, message_size, "the friction table is unusable (lcg_imp_friction version %d, "
                 "this driver reads version %d)", fr->abi, LCG_IMP_FRICTION_ABI);
        return -1;
    }
    *mem = malloc(sizeof(double) * nd + sizeof(int) * ni);
    if (*mem == NULL) {
        snprintf(message, message_size, "out of memory");
        return -1;
    }
    db = (double *)*mem;
    ib = (int *)(db + nd);
    f->tab = fr;
    f->mu = mu;
    f->n = n;
    f->nq = nq;
    f->nrow = nrow;
    f->M = db;
    f->F = f->M + n * n;
    f->R = f->F + n;
    f->s = f->R + nrow * n;
    f->h = f->s + nrow;
    f->gam = f->h + nrow;
    f->qd = f->gam + nrow;
    f->b = f->qd + nq;
    f->K = f->b + nrow;
    f->rhs = f->K + dim * dim;
    f->x = f->rhs + dim;
    f->lam = f->x + n;
    f->bestx = f->lam + nrow;
    f->bestlam = f->bestx + n;
    f->u = f->bestlam + nrow;
    f->wm = f->u + nk;
    f->eff = f->wm + nk;
    f->u2 = f->eff + nk;
    f->dir = f->u2 + nk;
    f->tdir = f->dir + 2 * nk;
    f->bdir = f->tdir + 2 * nk;
    f->dref = f->bdir + 2 * nk;
    f->gdir = f->dref + 2 * nk;
    f->nw = f->gdir + 2 * nk;
    f->trow = ib;
    f->trow2 = f->trow + nk;
    f->fmode = f->trow2 + nk;
    f->piv = f->fmode + nk;
    f->sel = f->piv + dim;
    f->opts = f->sel + nrow;
    f->nopt = f->opts + 4 * nk;
    f->tact = f->nopt + nk;
    f->tmode = f->tact + nk;
    f->bact = f->tmode + nk;
    f->bmode = f->bact + nk;
    f->part = f->bmode + nk;
    f->plastic = f->part + nk;
    f->ending = f->plastic + nk;
    f->nidx = f->ending + nk;
    for (k = 0; k < nk; ++k) {
        f->trow[k] = f->trow2[k] = -1;
        f->fmode[k] = 0;
        f->ending[k] = 0;
        f->u2[k] = 0.0;
        f->dir[2 * k] = f->tdir[2 * k] = f->bdir[2 * k] = f->dref[2 * k] = f->gdir[2 * k] = 1.0;
        f->dir[2 * k + 1] = f->tdir[2 * k + 1] = f->bdir[2 * k + 1] = f->dref[2 * k + 1] = f->gdir[2 * k + 1] = 0.0;
    }
    for (i = 0; i < fr->nt; ++i) { /* a contact's rows: one (planar) or two consecutive (3-D) */
        k = fr->tangent_of[i];
        if (k < 0 || k >= nk)
            continue;
        if (f->trow[k] < 0)
            f->trow[k] = im->nj + nk + i;
        else if (f->trow2[k] < 0 && f->trow[k] == im->nj + nk + i - 1)
            f->trow2[k] = im->nj + nk + i;
        else
            tangents_ok = 0;
    }
    if (!tangents_ok) {
        snprintf(message, message_size, "the friction table is unusable: a contact has more than two "
                 "tangential rows, or two that are not consecutive");
        free(*mem);
        *mem = NULL;
        return -1;
    }
    f->vtol = vtol;
    f->det = f->det0 = 0.0;
    return 0;
}
