/* lcg_imp_ida.c -- lagcodegen's runtime, compiled as it is.
 *
 * The native IDA driver of constrained models with contacts in the GGL form (see lcg_imp_ida.h):
 * the equality rows and the contacts in persistent contact (with the tangential rows of no-slip
 * contacts) are rows of the stabilized index-2 DAE of Gear, Gupta and Leimkuhler, unknowns
 * yy = (q, v, lambda[nrow], mu[njh + nk]); the rows of free contacts are lambda_r = 0, mu_r = 0.
 * The residual is built here from the model's numbers at a state (nums->eval: M, F, R, s, h), its
 * Jacobian by IDA's difference quotients. IDA steps one step at a time: a free contact reaching
 * g = 0 is a root (decreasing), a persistent contact's multiplier reaching 0 (decreasing) its
 * release; a step that skipped a free contact's flight (its gap below the floor and closing at
 * the step's end, lcg_imp_below_floor) is located on IDA's interpolant by bisection. There the
 * impact law shared with the index-1 driver applies (lcg_imp_law.c: Newton's law jointly with
 * the active set, plastic impacts into persistent contact, the release of pulling contacts) and
 * IDA restarts from consistent values: lambda and v' from the index-1 system of the active rows
 * (im->crhs, no stabilization), mu = 0, q' = k(q, v, t). Outputs come from IDA's interpolant. */
#include "lcg_control.h" /* first: POSIX */

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sundials_api.h"
#include "lcg_imp_ida.h"
#include "lcg_imp_fric.h" /* the friction core */

#define LCG_STATS lcg_ida_stats
#include "lcg_sundials.h"

#ifndef IDA_ONE_STEP
#define IDA_ONE_STEP 2
#endif
/* IDA's interpolation (ida.h; not among the declarations the other drivers share). */
int IDAGetDky(void *ida_mem, sunrealtype t, int k, N_Vector dky);

/* Bisection steps locating a skipped contact on a step's interpolant. */
#define LCG_IMP_IDA_BISECT 60

/* Friction: where the determinant of a slipping contact problem has fallen to this fraction of its
 * value where the modes began, the run stops with Painleve's paradox (the problem turning
 * singular). The index-1 driver stops at the determinant's zero; IDA cannot step up to it, since
 * lambda, one of its unknowns, grows without bound there (its steps shrink to nothing within
 * about 1e-6 of it). */
#define LCG_IMP_IDA_SINGULAR 1e-4

typedef struct {
    const lcg_imp_friction *nf;
    const lcg_imp_model *im;
    const lcg_dae_model *m;
    const double *p;
    int n, nq, ny, nj, nk, nrow, nmu, nroot; /* n: the speeds v, nq: the coordinates, ny = nq + n */
    int speeds;  /* 1: generalized speeds (q' = k(q, v, t)); 0: v = q' (nq = n) */
    int *active; /* nk: 1 in persistent contact */
    int *hrow;   /* nmu: the row of each mu (the holonomic equality rows, then the contacts) */
    double *M, *F, *R, *s, *h, *gam, *qd, *gk, *wk;
    /* generalized speeds: the state (q, v + R_h^T mu) and the numbers there (only its q' used) */
    double *y2, *M2, *F2, *R2, *s2, *h2, *gam2, *qd2;
    lcg_ida_stats *st;
    watch w;
    lcg_fric *fr;    /* NULL: no Coulomb friction (mu not given) */
    lcg_fric_ctx fc; /* the friction core's view of this run (fc.fr = fr; no Baumgarte) */
    double *ydot;    /* ny scratch */
    double *lamr;    /* nrow scratch: the index-1 multipliers of the roots while a contact slips */
} imp_ida;

/* Whether row r is held: equality rows always, a contact's rows while it is in persistent contact
 * (with Coulomb friction: its tangential rows while it sticks). */
static int row_on(const imp_ida *d, int r)
{
    int k;

    if (r < d->nj)
        return 1;
    if (r < d->nj + d->nk)
        return d->active[r - d->nj] != 0;
    k = d->nf->tangent_of[r - d->nj - d->nk];
    return d->active[k] != 0 && (d->fr == NULL || d->fr->mu[k] < 0.0 || d->fr->fmode[k] == 0);
}

/* Whether row r is a tangential row of a slipping contact k (*k), its multiplier then set by
 * Coulomb's law: lambda_r = *c lambda_n with *c = -fmode mu (3-D: -mu d_1, -mu d_2 of the slip
 * direction d, d->fr->dir at the state). */
static int row_slips(const imp_ida *d, int r, int *k, double *c)
{
    const lcg_fric *f = d->fr;

    if (f == NULL || r < d->nj + d->nk)
        return 0;
    *k = d->nf->tangent_of[r - d->nj - d->nk];
    if (!d->active[*k] || f->mu[*k] < 0.0 || f->fmode[*k] == 0)
        return 0;
    if (f->trow2[*k] >= 0)
        *c = -f->mu[*k] * f->dir[2 * *k + (r == f->trow2[*k])];
    else
        *c = -f->fmode[*k] * f->mu[*k];
    return 1;
}

/* The GGL residual (see lcg_imp_ida.h). With generalized speeds the coordinate rows are
 * q' - k(q, v + R_h^T mu, t): the correction of the positions moves along the speeds' images
 * (k is affine in v), so that h' = s + R_h R_h^T mu; mu = 0 on the solution, as in GGL's form
 * q' - v - R_h^T mu for v = q'. */
static int res(sunrealtype t, N_Vector yyv, N_Vector ypv, N_Vector rrv, void *data)
{
    imp_ida *d = (imp_ida *)data;
    const double *yy = N_VGetArrayPointer(yyv), *yp = N_VGetArrayPointer(ypv);
    double *rr = N_VGetArrayPointer(rrv);
    int n = d->n, nq = d->nq, ny = d->ny, i, j, r, rc, moved = 0;
    const double *lam = yy + ny, *mu = lam + d->nrow;

    if (WATCH_TICK(&d->w))
        return -1;
    rc = d->nf->eval(t, yy, d->p, d->M, d->F, d->R, d->s, d->h, d->gam, d->qd);
    if (rc != LCG_DAE_OK)
        return 1; /* non-finite: IDA retries with a smaller step */
    if (d->fr != NULL) /* 3-D slips: the direction of the force from the slip velocity here */
        lcg_fr_slip_directions(d->fr, d->nk);
    if (d->speeds) { /* q' - k(q, v + R_h^T mu, t) */
        for (i = 0; i < ny; ++i)
            d->y2[i] = yy[i];
        for (j = 0; j < d->nmu; ++j) {
            r = d->hrow[j];
            if (!row_on(d, r) || mu[j] == 0.0)
                continue;
            moved = 1;
            for (i = 0; i < n; ++i)
                d->y2[nq + i] += d->R[(long)r * n + i] * mu[j];
        }
        if (moved) {
            rc = d->nf->eval(t, d->y2, d->p, d->M2, d->F2, d->R2, d->s2, d->h2, d->gam2, d->qd2);
            if (rc != LCG_DAE_OK)
                return 1;
        }
        for (i = 0; i < nq; ++i)
            rr[i] = yp[i] - (moved ? d->qd2[i] : d->qd[i]);
    } else {
        for (i = 0; i < n; ++i)
            rr[i] = yp[i] - yy[n + i];
    }
    for (i = 0; i < n; ++i) {
        double acc = -d->F[i];
        for (j = 0; j < n; ++j)
            acc += d->M[i * n + j] * yp[nq + j];
        rr[nq + i] = acc;
    }
    for (r = 0; r < d->nrow; ++r) {
        int k;
        double c;
        if (row_on(d, r)) {
            for (i = 0; i < n; ++i)
                rr[nq + i] -= d->R[(long)r * n + i] * lam[r];
            rr[ny + r] = d->s[r];
        } else if (row_slips(d, r, &k, &c)) { /* the friction force along T_r, by Coulomb's law */
            for (i = 0; i < n; ++i)
                rr[nq + i] -= d->R[(long)r * n + i] * lam[r];
            rr[ny + r] = lam[r] - c * lam[d->nj + k];
        } else {
            rr[ny + r] = lam[r];
        }
    }
    for (j = 0; j < d->nmu; ++j) {
        r = d->hrow[j];
        if (row_on(d, r)) {
            if (!d->speeds)
                for (i = 0; i < n; ++i)
                    rr[i] -= d->R[(long)r * n + i] * mu[j];
            rr[ny + d->nrow + j] = d->h[r];
        } else {
            rr[ny + d->nrow + j] = mu[j];
        }
    }
    return 0;
}

/* Contact roots first (g_k free, lambda_k, an unknown, in persistent contact), then the model's
 * events (with the equality multipliers, the first nj of lambda), then (with friction) the
 * friction core's (lcg_fr_roots). With friction, while a contact is in persistent contact the
 * contact problem of the current modes is solved at the state (lcg_fr_crhs: the slip velocities,
 * the determinant) and its multipliers, not the unknowns lambda, serve the contacts' and the
 * friction roots, as on the index-1 driver: the unknowns of an index-2 row carry the error of its
 * velocity constraint divided by the step (a sticking force off by far more than the friction
 * bound in the first tiny step after a restart), and where the problem turns singular the normal
 * force passes through infinity, its sign change to be located with the determinant's root. */
static int roots(sunrealtype t, N_Vector yyv, N_Vector ypv, sunrealtype *gout, void *data)
{
    imp_ida *d = (imp_ida *)data;
    const double *y = N_VGetArrayPointer(yyv), *lam = y + d->ny;
    int k, rc, slipping = 0;
    (void)ypv;

    rc = d->im->gaps(t, y, d->p, d->gk, d->wk);
    if (rc == LCG_DAE_OK && d->fr != NULL) {
        int any = 0;
        for (k = 0; k < d->nk; ++k) {
            any |= d->active[k];
            slipping |= d->active[k] && d->fr->trow[k] >= 0 && d->fr->mu[k] >= 0.0 && d->fr->fmode[k] != 0;
        }
        if (any) {
            rc = lcg_fr_crhs(&d->fc, t, y, d->ydot, d->lamr);
            lam = d->lamr;
        }
    }
    if (rc == LCG_DAE_OK && d->nroot > 0)
        rc = d->m->roots(t, y, y + d->ny, d->p, gout + d->nk);
    if (rc != LCG_DAE_OK) {
        d->st->model_error = rc;
        d->st->t_reached = t;
        return -1;
    }
    for (k = 0; k < d->nk; ++k)
        gout[k] = d->active[k] ? lam[d->nj + k] : d->gk[k];
    if (d->fr != NULL) {
        lcg_fr_roots(&d->fc, lam, gout + d->nk + d->nroot);
        if (slipping) /* det / det0 reaching LCG_IMP_IDA_SINGULAR */
            gout[d->nk + d->nroot + 2 * d->nk] -= LCG_IMP_IDA_SINGULAR;
    }
    return 0;
}

/* yy, yp consistent with the state y = (q, v) at t and the current modes: lambda and v' from the
 * index-1 system of the active rows (no stabilization: the hidden constraints of the DAE; with
 * friction the friction core's contact problem of the current modes, the tangential multipliers
 * of slipping contacts by Coulomb's law), q' = k(q, v, t), mu = 0. */
static int consistent(imp_ida *d, double t, const double *y, double *yy, double *yp, int ng)
{
    int i, rc;

    if (d->fr != NULL)
        rc = lcg_fr_crhs(&d->fc, t, y, yp, yy + d->ny);
    else
        rc = d->im->crhs(t, y, d->p, 0.0, 0.0, d->active, yp, yy + d->ny);
    if (rc != LCG_DAE_OK)
        return rc;
    for (i = 0; i < d->ny; ++i)
        yy[i] = y[i];
    for (i = d->ny + d->nrow; i < ng; ++i)
        yy[i] = 0.0;
    for (i = d->ny; i < ng; ++i)
        yp[i] = 0.0;
    return LCG_DAE_OK;
}

/* Add IDA's counters (reset by IDAReInit) to st's. */
static void add_counts(void *mem, lcg_ida_stats *st, int roots_on)
{
    long v;

    IDAGetNumSteps(mem, &v);
    st->nsteps += v;
    IDAGetNumResEvals(mem, &v);
    st->nres += v;
    IDAGetNumLinResEvals(mem, &v);
    st->nres_dq += v;
    IDAGetNumJacEvals(mem, &v);
    st->njac += v;
    IDAGetNumLinSolvSetups(mem, &v);
    st->nlinsetups += v;
    IDAGetNumErrTestFails(mem, &v);
    st->netfails += v;
    IDAGetNumNonlinSolvIters(mem, &v);
    st->nniters += v;
    IDAGetNumNonlinSolvConvFails(mem, &v);
    st->nncfails += v;
    if (roots_on) {
        IDAGetNumGEvals(mem, &v);
        st->ngevals += v;
    }
}

/* One output row at t from IDA's interpolant (tmp: ng values): the state, the multipliers, the
 * outputs. */
static int output_row(const imp_ida *d, void *mem, double t, N_Vector tmp, double *yrow, double *lrow, double *orow)
{
    const double *v = N_VGetArrayPointer(tmp);
    int i, ny = d->ny;

    if (IDAGetDky(mem, t, 0, tmp) < 0)
        return LCG_DAE_ERR_NONFINITE;
    for (i = 0; i < ny; ++i)
        yrow[i] = v[i];
    for (i = 0; i < d->nrow; ++i)
        lrow[i] = v[ny + i];
    return d->m->coutputs(t, v, v + ny, d->p, orow);
}

/* Integrate with impacts on IDA; see lcg_imp_ida.h. */
int lcg_imp_ida_solve(const lcg_imp_friction *nums, const double *p, const double *y0, int nt, const double *tout,
                      double *yout, double *out, double *lamout, const lcg_ida_options *opt, const double *e,
                      const double *set, int *active, int max_rec, double *rec, int *n_rec, lcg_ida_stats *st,
                      lcg_events *ev, double *extra, const double *mu, int speeds)
{
    SUNContext ctx = NULL;
    void *mem = NULL;
    N_Vector yy = NULL, yp = NULL, id = NULL, atolv = NULL, tmp = NULL;
    SUNMatrix A = NULL;
    SUNLinearSolver LS = NULL;
    imp_ida d;
    lcg_fric fdata;
    void *fmem = NULL;
    char painleve[sizeof st->message];
    lcg_imp_law L, Lq;
    const lcg_imp_model *im;
    const lcg_dae_model *m;
    double *buf = NULL, *ys, *ydot, *lamtmp, *last, *scratch, *gprev, *wa, *yyv, *ypv;
    double tprev, tret = tout[0];
    int *ibuf = NULL, *hit, *rows, *info, *dirs;
    long nst = 0;
    int n, nq, ny, nj, nk, nrow, nmu, ng, nroot, nall, i, j, k, kout, flag = 0, rc, quiet = 0;

    memset(st, 0, sizeof *st);
    st->t_reached = tout[0];
    *n_rec = 0;
    extra[0] = extra[1] = 0.0;
    im = nums != NULL ? nums->imp : NULL;
    if (nums == NULL || nums->abi != LCG_IMP_FRICTION_ABI || im == NULL || im->abi != LCG_IMP_MODEL_ABI
        || im->dae == NULL || im->dae->abi != LCG_DAE_MODEL_ABI || im->nk < 1 || im->nq != im->dae->nq
        || im->nj != im->dae->nj || im->dae->ny <= im->nq || (!speeds && im->dae->ny != 2 * im->nq)
        || im->nrow != im->nj + im->nk + nums->nt) {
        snprintf(st->message, sizeof st->message, "the contact tables are unusable (lcg_imp_model version %d, "
                 "this driver reads version %d)", im != NULL ? im->abi : -1, LCG_IMP_MODEL_ABI);
        return st->flag = LCG_FLAG_BAD_INPUT;
    }
    m = im->dae;
    nq = im->nq;
    ny = m->ny;
    n = ny - nq; /* the speeds */
    nj = im->nj;
    nk = im->nk;
    nrow = im->nrow;
    nmu = nums->njh + nk;
    ng = ny + nrow + nmu;
    nroot = (opt->roots && ev != NULL) ? m->nroot : 0;
    nall = nk + nroot + (mu != NULL ? 2 * nk + 1 : 0);
    d.fr = NULL;
    if (mu != NULL) { /* Coulomb friction: the friction core's state (its numbers serve the residual) */
        if (lcg_fr_setup(&fdata, nums, im, mu, set[0], &fmem, st->message, sizeof st->message) != 0)
            return st->flag = LCG_FLAG_BAD_INPUT;
        d.fr = &fdata;
    }
    if (ev != NULL) {
        ev->n_events = 0;
        ev->terminated = 0;
    }
    /* doubles: M[n n], F[n], R[nrow n], s, h, gam[nrow], qd[nq], gk, wk[nk], ys[ny], ydot[ny], lamtmp[nrow],
     * last[nk], scratch[2 nk + nrow + ny], gprev[nk], wa[nk], and with generalized speeds y2[ny] and the
     * numbers there (M2 ... qd2); ints: hrow[nmu], hit[nk], rows[2 nk], info[nall], dirs[nall] */
    buf = (double *)malloc(sizeof(double) * (size_t)(n * n + n + nrow * n + 3 * nrow + 2 * nk + 2 * ny + nrow + nk
                                                     + 2 * nk + nrow + ny + 2 * nk + nq
                                                     + (speeds ? ny + n * n + n + nrow * n + 3 * nrow + nq : 0)));
    ibuf = (int *)malloc(sizeof(int) * (size_t)(nmu + 3 * nk + 2 * nall));
    if (buf == NULL || ibuf == NULL) {
        free(buf);
        free(ibuf);
        free(fmem);
        snprintf(st->message, sizeof st->message, "out of memory");
        return st->flag = LCG_FLAG_NOMEM_IDA;
    }
    d.M = buf;
    d.F = d.M + n * n;
    d.R = d.F + n;
    d.s = d.R + nrow * n;
    d.h = d.s + nrow;
    d.gam = d.h + nrow;
    d.qd = d.gam + nrow; /* q' = k(q, v, t) of the numbers' table */
    d.gk = d.qd + nq;
    d.wk = d.gk + nk;
    ys = d.wk + nk;
    ydot = ys + ny;
    lamtmp = ydot + ny;
    last = lamtmp + nrow;
    scratch = last + nk;
    gprev = scratch + 2 * nk + nrow + ny;
    wa = gprev + nk;
    d.y2 = d.M2 = d.F2 = d.R2 = d.s2 = d.h2 = d.gam2 = d.qd2 = NULL;
    if (speeds) {
        d.y2 = wa + nk;
        d.M2 = d.y2 + ny;
        d.F2 = d.M2 + n * n;
        d.R2 = d.F2 + n;
        d.s2 = d.R2 + nrow * n;
        d.h2 = d.s2 + nrow;
        d.gam2 = d.h2 + nrow;
        d.qd2 = d.gam2 + nrow;
    }
    d.hrow = ibuf;
    hit = d.hrow + nmu;
    rows = hit + nk;
    info = rows + 2 * nk;
    dirs = info + nall;
    for (j = 0; j < nums->njh; ++j)
        d.hrow[j] = j;
    for (k = 0; k < nk; ++k) {
        d.hrow[nums->njh + k] = nj + k;
        last[k] = -HUGE_VAL;
        hit[k] = 0;
        active[k] = active[k] != 0;
    }
    for (i = 0; i < nall; ++i) /* contacts and friction: decreasing; the model's events: as asked */
        dirs[i] = (i < nk || i >= nk + nroot) ? -1 : (ev->rootdir != NULL ? ev->rootdir[i - nk] : 0);
    if (d.fr != NULL) { /* the residual on the friction core's numbers */
        d.M = fdata.M;
        d.F = fdata.F;
        d.R = fdata.R;
        d.s = fdata.s;
        d.h = fdata.h;
        d.gam = fdata.gam;
        d.qd = fdata.qd;
    }
    d.ydot = ydot;
    d.lamr = lamtmp;
    d.fc.im = im;
    d.fc.p = p;
    d.fc.alpha = d.fc.beta = 0.0;
    d.fc.active = active;
    d.fc.fr = d.fr;
    d.fc.lam = lamtmp;
    d.fc.ydot = ydot;
    d.fc.message = st->message;
    d.fc.message_size = sizeof st->message;
    d.nf = nums;
    d.im = im;
    d.m = m;
    d.p = p;
    d.n = n;
    d.nq = nq;
    d.ny = ny;
    d.speeds = speeds != 0;
    d.nj = nj;
    d.nk = nk;
    d.nrow = nrow;
    d.nmu = nmu;
    d.nroot = nroot;
    d.active = active;
    d.st = st;
    L.im = im;
    L.p = p;
    L.active = active;
    L.e = e;
    L.set = set;
    L.last = last;
    L.gk = d.gk;
    L.wk = d.wk;
    L.scratch = scratch;
    L.rows = rows;
    L.rec = rec;
    L.max_rec = max_rec;
    L.n_rec = n_rec;
    Lq = L; /* the initial modes, not recorded */
    Lq.max_rec = 0;
    Lq.n_rec = &quiet;
    watch_init(&d.w, opt->cancel, opt->poll, opt->poll_data, opt->poll_every, opt->max_wall, nt, &st->nt_done);
    if (create_context(&ctx, st) != 0) {
        free(buf);
        free(ibuf);
        free(fmem);
        return st->flag = LCG_FLAG_NOMEM_IDA;
    }
    if ((flag = ida_create(ctx, ng, ny, &yy, &yp, &id, &mem, &A, &LS, LCG_FLAG_NOMEM_IDA)) != 0)
        goto done;
    atolv = N_VNew_Serial(ng, ctx);
    tmp = N_VNew_Serial(ng, ctx);
    if (atolv == NULL || tmp == NULL) {
        flag = LCG_FLAG_NOMEM_IDA;
        goto done;
    }
    yyv = N_VGetArrayPointer(yy);
    ypv = N_VGetArrayPointer(yp);
    for (i = 0; i < ng; ++i) /* q, v: atol; lambda, mu: ic_alg_atol */
        N_VGetArrayPointer(atolv)[i] = i < ny ? opt->atol : opt->ic_alg_atol;
    for (i = 0; i < ny; ++i)
        ys[i] = y0[i];
    /* the contacts the initial state rests on (touching, at rest, pushing) start in persistent contact */
    rc = im->gaps(tout[0], ys, p, d.gk, d.wk);
    LCG_MODEL_ERROR(LCG_DAE_OK);
    for (k = 0; k < nk; ++k)
        if (!active[k] && d.gk[k] <= set[2] && fabs(d.wk[k]) <= set[0])
            active[k] = 1;
    if (d.fr != NULL) { /* the initial modes: sticking where the slip velocity is at most contact_speed */
        rc = lcg_fr_eval(&d.fc, tout[0], ys);
        LCG_MODEL_ERROR(LCG_DAE_OK);
        for (k = 0; k < nk; ++k)
            if (active[k] && fdata.trow[k] >= 0 && fdata.mu[k] >= 0.0) {
                double u, u2;
                lcg_fr_slip(&fdata, k, &u, &u2);
                fdata.fmode[k] = hypot(u, u2) <= set[0] ? 0 : fdata.trow2[k] >= 0 || u > 0.0 ? 1 : -1;
            }
        rc = lcg_fr_modes(&d.fc, tout[0], ys, NULL, set[0], rec, 0, &quiet);
        if (rc == -1) {
            flag = LCG_FLAG_CONTACT_MODE;
            goto done;
        }
    } else {
        rc = lcg_imp_release_pulling(&Lq, tout[0], ys, 0.0, 0.0, ydot, lamtmp);
    }
    LCG_MODEL_ERROR(LCG_DAE_OK);
    rc = consistent(&d, tout[0], ys, yyv, ypv, ng);
    LCG_MODEL_ERROR(LCG_DAE_OK);
    rc = m->coutputs(tout[0], yyv, yyv + ny, p, out);
    LCG_MODEL_ERROR(LCG_DAE_OK);
    for (i = 0; i < ny; ++i)
        yout[i] = yyv[i];
    for (i = 0; i < nrow; ++i)
        lamout[i] = yyv[ny + i];
    st->nt_done = 1;

    if ((flag = ida_init(mem, res, tout[0], yy, yp, id, &d, opt->suppress_alg, LS, A)) < 0)
        goto done;
    if ((flag = IDASVtolerances(mem, opt->rtol, atolv)) < 0)
        goto done;
    if ((flag = ida_roots(mem, nall, roots, dirs)) < 0)
        goto done;
    if ((flag = set_step_limits(mem, 1, opt->max_order, opt->first_step, opt->max_step, opt->min_step)) < 0)
        goto done;
    if (nt > 1 && (flag = IDASetStopTime(mem, tout[nt - 1])) < 0)
        goto done;

    tprev = tout[0];
    rc = im->gaps(tout[0], ys, p, gprev, wa);
    LCG_MODEL_ERROR(LCG_DAE_OK);
    kout = 1;
    while (kout < nt) {
        double teff;
        int missed = -1, apex = 0, any = 0;
        if (WATCH_TICK(&d.w))
            goto done;
        IDAGetNumSteps(mem, &nst);
        if (st->nsteps + nst >= opt->max_steps) {
            flag = -1;
            snprintf(st->message, sizeof st->message, "the step budget max_steps = %ld is used up before t = %.17g",
                     opt->max_steps, tout[nt - 1]);
            goto done;
        }
        IDASetMaxNumSteps(mem, opt->max_steps - st->nsteps - nst);
        flag = IDASolve(mem, tout[nt - 1], &tret, yy, yp, IDA_ONE_STEP);
        st->t_reached = tret;
        if (flag < 0)
            goto done;
        teff = tret;
        if (flag != IDA_ROOT_RETURN) { /* a free contact deeper than its floor: a flight skipped by the step */
            rc = im->gaps(tret, yyv, p, d.gk, d.wk);
            LCG_MODEL_ERROR(LCG_DAE_OK);
            missed = lcg_imp_below_floor(d.gk, d.wk, gprev, active, nk, set[2]);
        }
        if (missed >= 0) {
            extra[0] += 1.0;
            apex = wa[missed] > 0.0; /* rising at the step's start: the whole flight within one step */
            if (!apex) { /* the first time below the floor on the step's interpolant */
                double ta = tprev, tb = tret, floor = lcg_imp_gap_floor(gprev[missed], set[2]);
                int it;
                for (it = 0; it < LCG_IMP_IDA_BISECT; ++it) {
                    double tm = 0.5 * (ta + tb);
                    if (!(tm > ta && tm < tb) || IDAGetDky(mem, tm, 0, tmp) < 0)
                        break;
                    rc = im->gaps(tm, N_VGetArrayPointer(tmp), p, d.gk, d.wk);
                    LCG_MODEL_ERROR(LCG_DAE_OK);
                    if (d.gk[missed] < floor)
                        tb = tm;
                    else
                        ta = tm;
                }
                teff = tb;
                if (IDAGetDky(mem, teff, 0, tmp) < 0)
                    goto done;
                rc = im->gaps(teff, N_VGetArrayPointer(tmp), p, d.gk, d.wk);
                LCG_MODEL_ERROR(LCG_DAE_OK);
                if (!(d.wk[missed] < 0.0)) { /* not closing there on the interpolant: as a flight within the step */
                    apex = 1;
                    teff = tret;
                }
            }
        }
        /* the output times up to here, from the interpolant */
        while (kout < nt && tout[kout] <= teff) {
            rc = output_row(&d, mem, tout[kout], tmp, yout + (long)kout * ny, lamout + (long)kout * nrow,
                            out + (long)kout * m->nout);
            LCG_MODEL_ERROR(LCG_DAE_OK);
            st->nt_done = ++kout;
        }
        if (flag == IDA_ROOT_RETURN) {
            if (IDAGetRootInfo(mem, info) < 0)
                goto done;
            for (j = nk; j < nk + nroot; ++j) { /* the model's events */
                if (info[j] == 0)
                    continue;
                if (ev->n_events < ev->max_events) {
                    ev->t[ev->n_events] = tret;
                    for (i = 0; i < ny; ++i)
                        ev->y[(long)ev->n_events * ny + i] = yyv[i];
                    ev->which[ev->n_events] = j - nk;
                    ev->direction[ev->n_events] = info[j];
                }
                ev->n_events++;
                if (ev->terminal == NULL || ev->terminal[j - nk])
                    ev->terminated = 1;
            }
            if (ev != NULL && ev->terminated) {
                flag = IDA_ROOT_RETURN;
                goto done;
            }
            for (k = 0; k < nk; ++k) {
                hit[k] = info[k] != 0 && !active[k];
                if (info[k] != 0 && active[k] && d.fr != NULL) { /* released by lcg_fr_modes */
                    fdata.ending[k] = FR_END_RELEASE;
                    any = 1;
                } else if (info[k] != 0 && active[k]) { /* the multiplier reaches zero: release */
                    active[k] = 0;
                    lcg_imp_record(rec, max_rec, n_rec, tret, k, LCG_IMP_RELEASE, 0.0, 0.0, 0.0);
                    any = 1;
                }
                any |= hit[k];
            }
            if (d.fr != NULL) { /* friction: the modes whose roots fired end; Painleve: a singular problem */
                const int *fi = info + nk + nroot;
                for (k = 0; k < nk; ++k)
                    if ((fi[2 * k] != 0 || fi[2 * k + 1] != 0) && active[k] && fdata.ending[k] == 0) {
                        fdata.ending[k] = fdata.fmode[k] == 0 ? FR_END_STICK : FR_END_SLIP;
                        any = 1;
                    }
                if (fi[2 * nk] != 0) {
                    flag = LCG_FLAG_CONTACT_MODE;
                    snprintf(st->message, sizeof st->message, "Painleve's paradox at t = %.17g: the contact "
                             "problem of the slipping contact(s) became singular (its determinant fell to %g of "
                             "its value where the modes began: the normal's effective mass with friction, "
                             "G M^-1 (G - sigma mu T)^T, tends to 0 and the normal force grows without bound)",
                             tret, LCG_IMP_IDA_SINGULAR);
                    goto done;
                }
            }
            for (i = 0; i < ny; ++i)
                ys[i] = yyv[i];
        } else if (missed >= 0) {
            if (apex) {
                for (i = 0; i < ny; ++i)
                    ys[i] = yyv[i];
                last[missed] = teff; /* a flight shorter than a step (accumulation): plastic */
            } else {
                if (IDAGetDky(mem, teff, 0, tmp) < 0)
                    goto done;
                for (i = 0; i < ny; ++i)
                    ys[i] = N_VGetArrayPointer(tmp)[i];
            }
            rc = im->gaps(teff, ys, p, d.gk, d.wk);
            LCG_MODEL_ERROR(LCG_DAE_OK);
            if (-d.gk[missed] > extra[1])
                extra[1] = -d.gk[missed];
            for (k = 0; k < nk; ++k)
                hit[k] = k == missed;
            any = 1;
        }
        if (!any) { /* an ordinary step: its end is where the next step's floor and rise are taken */
            rc = im->gaps(tret, yyv, p, gprev, wa);
            LCG_MODEL_ERROR(LCG_DAE_OK);
            tprev = tret;
            continue;
        }
        /* the switch at teff: the impact law, the contacts that pull released (with friction: the
         * frictional impact and the modes of all contacts chosen together, the modes whose roots
         * fired excluded), IDA restarted */
        if (d.fr != NULL) {
            rc = lcg_fr_impact(&d.fc, teff, ys, hit, e, set, last, rec, max_rec, n_rec);
            if (rc == LCG_DAE_OK)
                rc = lcg_fr_modes(&d.fc, teff, ys, fdata.ending, set[0], rec, max_rec, n_rec);
            for (k = 0; k < nk; ++k)
                fdata.ending[k] = 0;
            if (rc == -1) {
                flag = LCG_FLAG_CONTACT_MODE;
                st->t_reached = teff;
                goto done;
            }
        } else {
            rc = lcg_imp_jump(&L, teff, ys, hit);
            LCG_MODEL_ERROR(LCG_DAE_OK);
            rc = lcg_imp_release_pulling(&L, teff, ys, 0.0, 0.0, ydot, lamtmp);
        }
        LCG_MODEL_ERROR(LCG_DAE_OK);
        for (k = 0; k < nk; ++k)
            hit[k] = 0;
        rc = consistent(&d, teff, ys, yyv, ypv, ng);
        LCG_MODEL_ERROR(LCG_DAE_OK);
        add_counts(mem, st, 1);
        if ((flag = IDAReInit(mem, teff, yy, yp)) < 0)
            goto done;
        if (nt > 1 && teff < tout[nt - 1] && (flag = IDASetStopTime(mem, tout[nt - 1])) < 0)
            goto done;
        rc = im->gaps(teff, ys, p, gprev, wa);
        LCG_MODEL_ERROR(LCG_DAE_OK);
        tprev = teff;
    }

done:
    if (d.fr != NULL) /* the final friction modes of the Coulomb contacts: 1 stick, 2 slip+, 3 slip-, 4 slip (3-D) */
        for (k = 0; k < nk; ++k)
            if (active[k] && fdata.trow[k] >= 0 && fdata.mu[k] >= 0.0)
                active[k] = fdata.fmode[k] != 0 && fdata.trow2[k] >= 0 ? 4 : fdata.fmode[k] > 0 ? 2
                            : fdata.fmode[k] < 0 ? 3 : 1;
    flag = watch_flag(&d.w, flag, st->message, sizeof st->message);
    if (flag == LCG_FLAG_CONTACT_MODE) /* kept from IDA's error handler (the counters below) */
        memcpy(painleve, st->message, sizeof painleve);
    if (mem != NULL) {
        add_counts(mem, st, 1);
        IDAGetLastStep(mem, &st->h_last);
        if (flag < 0 && flag > LCG_FLAG_MODEL_ERROR && st->model_error == 0 && flag != LCG_FLAG_CONTACT_MODE)
            IDAGetCurrentTime(mem, &st->t_reached);
    }
    st->flag = flag;
    if (flag == LCG_FLAG_CONTACT_MODE)
        memcpy(st->message, painleve, sizeof painleve);
    LCG_NOMEM_MESSAGE(LCG_FLAG_NOMEM_IDA, "IDA");
    IDAFree(&mem);
    free_solver(LS, NULL, A, (N_Vector[]){tmp, atolv, id, yp, yy}, 5, &ctx);
    free(buf);
    free(ibuf);
    free(fmem);
    return flag < 0 ? flag : 0;
}
