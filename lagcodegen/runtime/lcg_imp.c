/* lcg_imp.c -- lagcodegen's runtime, compiled as it is.
 *
 * The native CVODE driver of constrained models with contacts: inequality constraints
 * g_k(q, t) >= 0 (notes, eq. 4.3) with a coefficient of restitution e_k, through the model's
 * contact table (lcg_imp_model.h) and its constrained table (lcg_dae_model.h). Each contact is
 * free (g_k > 0: root function g_k, decreasing) or in persistent contact (g_k = 0 held as a
 * holonomic constraint with its multiplier lambda_k, eq. 4.5: root function lambda_k,
 * decreasing). The right-hand side is the index-1 system of the equality constraints and the
 * contacts in persistent contact (m->crhs of the contact table).
 *
 * Where a free contact reaches g_k = 0 with a closing normal velocity w_k < 0, the run stops at
 * the located root, the velocities jump (im->impact: M dv = R^T P, Newton's law
 * w_k+ = -e_k w_k- on every contact that touches (g <= gap_tol) and closes, the equality rows and
 * the persistent contacts kept at zero velocity, all solved together), CVODE is reinitialized at
 * the new state and the run goes on in the same call. A contact whose impulse comes out negative
 * (it would pull) is left out and the impact solved again without it (the active set of the
 * linear complementarity problem, by elimination, at most nk + 1 solves). A contact whose rebound
 * speed e_k |w_k-| is at most contact_speed, or that hit again within min_flight of its last
 * impact (accumulating impacts, Zeno), gets e_k = 0 and turns into persistent contact; a
 * persistent contact is released where its multiplier becomes negative. The model's own events
 * (m->roots: monitored inequalities, user events) are recorded as by lcg_cvc.c. Contacts with
 * Coulomb friction (a friction table lcg_imp_friction) are solved here, mode by mode, from the
 * model's numbers by the friction core (lcg_imp_fric.c, "Coulomb friction"); without the table the
 * path above is unchanged. */
#include "lcg_control.h" /* first: POSIX */

#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sundials_api.h"
#include "lcg_imp.h"
#include "lcg_imp_fric.h" /* the friction core */

#define LCG_STATS lcg_cvc_stats
#include "lcg_sundials.h"

/* CVODE's reinitialization and interpolation (cvode.h; not among the declarations the other
 * drivers share). */
int CVodeReInit(void *cvode_mem, sunrealtype t0, N_Vector y0);
int CVodeGetDky(void *cvode_mem, sunrealtype t, int k, N_Vector dky);

/* Bisection steps locating a skipped contact on a step's interpolant. */
#define LCG_IMP_BISECT 60


typedef struct {
    const lcg_imp_model *im;
    const lcg_dae_model *m;
    const double *p;
    double alpha, beta;
    int *active;  /* nk: 1 in persistent contact */
    double *lam;  /* nj + nk multipliers (scratch) */
    double *gk, *wk; /* nk (scratch) */
    lcg_cvc_stats *st;
    watch w;
    lcg_fric *fr;  /* NULL: no friction table */
    lcg_fric_ctx fc; /* the friction core's view of this run (fc.fr = fr) */
    int nroot;     /* the model's events located */
} imp_data;

/* The right-hand side of the current modes: the generated crhs, or the friction driver's. */
static int crhs(imp_data *d, double t, const double *y, double *ydot, double *lam);

static int rhs(sunrealtype t, N_Vector y, N_Vector ydot, void *data)
{
    imp_data *d = (imp_data *)data;
    int rc;

    if (WATCH_TICK(&d->w))
        return -1;
    rc = crhs(d, t, N_VGetArrayPointer(y), N_VGetArrayPointer(ydot), d->lam);
    if (rc == LCG_DAE_ERR_SINGULAR) {
        d->st->model_error = rc;
        d->st->t_reached = t;
        return -1;
    }
    if (rc == LCG_DAE_OK && d->fr != NULL) { /* the integrals of the contact forces (see FR_WATCH) */
        double *z = N_VGetArrayPointer(ydot) + d->m->ny;
        int k, nk = d->im->nk, nj = d->im->nj;
        for (k = 0; k < nk; ++k) {
            z[2 * k] = d->lam[nj + k];
            z[2 * k + 1] = (d->fr->trow[k] >= 0 ? d->lam[d->fr->trow[k]] : 0.0)
                           + (d->fr->trow2[k] >= 0 ? d->lam[d->fr->trow2[k]] : 0.0);
        }
    }
    return rc == LCG_DAE_OK ? 0 : 1;
}

/* Contact roots first (g_k free, lambda_k in persistent contact), then the model's events, then
 * (with friction) the friction core's (lcg_fr_roots: two per contact, and the determinant of the
 * contact problem while a contact slips). */
static int roots(sunrealtype t, N_Vector yv, sunrealtype *gout, void *data)
{
    imp_data *d = (imp_data *)data;
    const double *y = N_VGetArrayPointer(yv);
    double *ydot = NULL;
    int k, rc, nk = d->im->nk, nj = d->im->nj, any = 0;

    rc = d->im->gaps(t, y, d->p, d->gk, d->wk);
    for (k = 0; k < nk; ++k)
        any |= d->active[k];
    if (rc == LCG_DAE_OK && any) {
        ydot = d->gk + 2 * nk; /* scratch of ny values after gk, wk */
        rc = crhs(d, t, y, ydot, d->lam);
    }
    if (rc == LCG_DAE_OK && d->nroot > 0)
        rc = d->m->roots(t, y, NULL, d->p, gout + nk);
    if (rc != LCG_DAE_OK) {
        d->st->model_error = rc;
        d->st->t_reached = t;
        return -1;
    }
    for (k = 0; k < nk; ++k)
        gout[k] = d->active[k] ? d->lam[nj + k] : d->gk[k];
    if (d->fr != NULL)
        lcg_fr_roots(&d->fc, d->lam, gout + nk + d->nroot);
    return 0;
}

/* Add CVODE's counters (reset by CVodeReInit) to c: steps, rhs, rhs of difference quotients,
 * Jacobians, linear setups, error test failures, nonlinear iterations, their failures. */
static void add_counts(void *mem, long *c)
{
    long v;

    CVodeGetNumSteps(mem, &v);
    c[0] += v;
    CVodeGetNumRhsEvals(mem, &v);
    c[1] += v;
    CVodeGetNumLinRhsEvals(mem, &v);
    c[2] += v;
    CVodeGetNumJacEvals(mem, &v);
    c[3] += v;
    CVodeGetNumLinSolvSetups(mem, &v);
    c[4] += v;
    CVodeGetNumErrTestFails(mem, &v);
    c[5] += v;
    CVodeGetNumNonlinSolvIters(mem, &v);
    c[6] += v;
    CVodeGetNumNonlinSolvConvFails(mem, &v);
    c[7] += v;
}

static void record(double *rec, int max_rec, int *n_rec, double t, int k, int kind, double P, double wm, double wp)
{
    lcg_imp_record(rec, max_rec, n_rec, t, k, kind, P, wm, wp);
}

static int crhs(imp_data *d, double t, const double *y, double *ydot, double *lam)
{
    if (d->fr != NULL)
        return lcg_fr_crhs(&d->fc, t, y, ydot, lam);
    return d->im->crhs(t, y, d->p, d->alpha, d->beta, d->active, ydot, lam);
}

/* The law of lcg_imp_law.c on this run's data (d, e, set, last, the scratch s and rows). */
static lcg_imp_law law_of(imp_data *d, const double *e, const double *set, double *last, double *s, int *rows,
                          double *rec, int max_rec, int *n_rec)
{
    lcg_imp_law L;

    L.im = d->im;
    L.p = d->p;
    L.active = d->active;
    L.e = e;
    L.set = set;
    L.last = last;
    L.gk = d->gk;
    L.wk = d->wk;
    L.scratch = s;
    L.rows = rows;
    L.rec = rec;
    L.max_rec = max_rec;
    L.n_rec = n_rec;
    return L;
}

/* The impact at (t, y) of the free contacts that touch and close (and those that hit[]): the
 * velocities of y replaced (lcg_imp_jump). s: scratch (see lcg_imp_solve). Returns LCG_DAE_OK or
 * a model error. */
static int impact(imp_data *d, double t, double *y, const int *hit, const double *e, const double *set,
                  double *last, double *s, int *rows, double *rec, int max_rec, int *n_rec)
{
    lcg_imp_law L = law_of(d, e, set, last, s, rows, rec, max_rec, n_rec);
    return lcg_imp_jump(&L, t, y, hit);
}

/* The persistent contacts at (t, y) chosen (recorded; lcg_imp_release_pulling, without friction):
 * those whose multiplier pulls released, free contacts touching at rest that would sink held. */
static int release_pulling(imp_data *d, double t, double *y, double *ydot, const double *set, double *s,
                           int *rows, double *rec, int max_rec, int *n_rec)
{
    lcg_imp_law L = law_of(d, NULL, set, NULL, s, rows, rec, max_rec, n_rec);
    return lcg_imp_release_pulling(&L, t, y, d->alpha, d->beta, ydot, d->lam);
}

/* The impact of the contacts hit[] (and those touching and closing) at (t, y of CVODE), the
 * contacts that pull released (with friction: the modes chosen, the roots that fired in
 * d->fr->ending excluded), CVODE restarted there. *flag: CVODE's flag (< 0: failed).
 * Returns LCG_DAE_OK, a model error, or -1: Painleve (*flag = LCG_FLAG_CONTACT_MODE). */
static int restart(imp_data *d, void *mem, N_Vector y, double t, int *hit, const double *e, const double *set,
                   double *last, double *s, int *rows, double *ydot, double *rec, int max_rec, int *n_rec, long *base,
                   double t_stop, int *flag)
{
    double *yv = N_VGetArrayPointer(y);
    int k, rc;

    if (d->fr != NULL) {
        rc = lcg_fr_impact(&d->fc, t, yv, hit, e, set, last, rec, max_rec, n_rec);
        if (rc == LCG_DAE_OK)
            rc = lcg_fr_modes(&d->fc, t, yv, d->fr->ending, set[0], rec, max_rec, n_rec);
        for (k = 0; k < d->im->nk; ++k)
            d->fr->ending[k] = 0;
        if (rc == -1) {
            *flag = LCG_FLAG_CONTACT_MODE;
            d->st->t_reached = t;
            return LCG_DAE_OK;
        }
    } else {
        rc = impact(d, t, yv, hit, e, set, last, s, rows, rec, max_rec, n_rec);
        if (rc == LCG_DAE_OK)
            rc = release_pulling(d, t, yv, ydot, set, s, rows, rec, max_rec, n_rec);
    }
    if (rc != LCG_DAE_OK)
        return rc;
    for (k = 0; k < d->im->nk; ++k)
        hit[k] = 0;
    add_counts(mem, base);
    if ((*flag = CVodeReInit(mem, t, y)) >= 0 && t_stop > t)
        *flag = CVodeSetStopTime(mem, t_stop);
    return LCG_DAE_OK;
}

/* The first time in [ta, tb] (gap of contact k above its floor at ta, below at tb) where the gap,
 * on CVODE's interpolant of the last step, is below the floor: *tstar, y the state there. */
static int bisect(imp_data *d, void *mem, N_Vector y, int k, double ta, double tb, const double *gprev,
                  double gap_tol, double *tstar)
{
    double *yv = N_VGetArrayPointer(y), floor = lcg_imp_gap_floor(gprev[k], gap_tol);
    int it, rc;

    for (it = 0; it < LCG_IMP_BISECT; ++it) {
        double tm = 0.5 * (ta + tb);
        if (!(tm > ta && tm < tb))
            break;
        if (CVodeGetDky(mem, tm, 0, y) < 0)
            break;
        rc = d->im->gaps(tm, yv, d->p, d->gk, d->wk);
        if (rc != LCG_DAE_OK)
            return rc;
        if (d->gk[k] < floor)
            tb = tm;
        else
            ta = tm;
    }
    *tstar = tb;
    CVodeGetDky(mem, tb, 0, y);
    return LCG_DAE_OK;
}

/* A segment of the run begins at (t, y): kept as where a rerun would start (tprev, yprev), with
 * the contacts' gaps there (gprev). Returns LCG_DAE_OK or a model error. */
static int segment_start(imp_data *d, double t, const double *y, int ny, double *tprev, double *yprev, double *gprev)
{
    int i;

    *tprev = t;
    for (i = 0; i < ny; ++i)
        yprev[i] = y[i];
    return d->im->gaps(t, yprev, d->p, gprev, d->wk);
}

/* Integrate with impacts; see lcg_imp.h. */
int lcg_imp_solve(const lcg_imp_model *im, const double *p, const double *y0, int nt, const double *tout,
                  double *yout, double *out, double *lamout, const lcg_cvc_options *opt, const double *e,
                  const double *set, int *active, int max_rec, double *rec, int *n_rec, lcg_cvc_stats *st,
                  lcg_events *ev, const lcg_imp_friction *fr, const double *mu)
{
    SUNContext ctx = NULL;
    void *mem = NULL;
    N_Vector y = NULL;
    SUNMatrix A = NULL;
    SUNLinearSolver LS = NULL;
    imp_data data;
    lcg_fric fdata;
    void *fmem = NULL;
    char painleve[sizeof st->message];
    const lcg_dae_model *m;
    double *yv, *buf = NULL, *last, *scratch, *ydot, *yprev, *gprev, *wa;
    double tprev;
    int *ibuf = NULL, *info, *hit, *dirs, *rows;
    int j;
    long nst = 0;
    long base[8] = {0, 0, 0, 0, 0, 0, 0, 0}; /* the counters of the segments before the last CVodeReInit */
    int k, i, flag = 0, rc, ny, nk, nj, nr, nroot, nall, nlam, nvec, quiet = 0;

    memset(st, 0, sizeof *st);
    st->t_reached = tout[0];
    *n_rec = 0;
    if (im == NULL || im->abi != LCG_IMP_MODEL_ABI || im->dae == NULL || im->nk < 1 || im->nrow < im->nj + im->nk
        || im->dae->abi != LCG_DAE_MODEL_ABI || im->nq != im->dae->nq || im->nj != im->dae->nj) {
        snprintf(st->message, sizeof st->message, "the contact table is unusable (lcg_imp_model version %d, "
                     "this driver reads version %d)", im != NULL ? im->abi : -1, LCG_IMP_MODEL_ABI);
        return st->flag = LCG_FLAG_BAD_INPUT;
    }
    m = im->dae;
    ny = m->ny;
    nk = im->nk;
    nj = im->nj;
    nr = nj + nk;
    nroot = (opt->roots && ev != NULL) ? m->nroot : 0;
    nall = nk + nroot + (fr != NULL ? 2 * nk + 1 : 0);
    nlam = fr != NULL ? im->nrow : nr; /* the multipliers reported per output time */
    data.fr = NULL;
    if (fr != NULL) {
        if (lcg_fr_setup(&fdata, fr, im, mu, set[0], &fmem, st->message, sizeof st->message) != 0)
            return st->flag = LCG_FLAG_BAD_INPUT;
        data.fr = &fdata;
    }
    if (ev != NULL) {
        ev->n_events = 0;
        ev->terminated = 0;
    }
    /* doubles: lam[nrow], gk[nk], wk[nk], ydot scratch[ny], last[nk], impact scratch
     * (eff[nk], wm[nk], P[nrow], ynew[ny]), the segment's start yprev[ny], gprev[nk], wa[nk];
     * ints: info[nall], hit[nk], dirs[nall], rows[2 nk] */
    buf = (double *)malloc(sizeof(double) * (size_t)(im->nrow + 3 * nk + ny + 2 * nk + im->nrow + ny + nk + ny + 2 * nk));
    ibuf = (int *)malloc(sizeof(int) * (size_t)(2 * nall + 3 * nk));
    if (buf == NULL || ibuf == NULL) {
        free(buf);
        free(ibuf);
        free(fmem);
        snprintf(st->message, sizeof st->message, "out of memory");
        return st->flag = LCG_FLAG_NOMEM;
    }
    data.lam = buf; /* nrow multipliers; the first nr (equality rows, contacts) are reported */
    data.gk = data.lam + im->nrow;
    data.wk = data.gk + nk;
    ydot = data.wk + nk; /* = gk + 2 nk, as roots() expects */
    last = ydot + ny;
    scratch = last + nk;
    yprev = scratch + 2 * nk + im->nrow + ny;
    gprev = yprev + ny;
    wa = gprev + nk;
    info = ibuf;
    hit = info + nall;
    dirs = hit + nk;
    rows = dirs + nall;
    for (k = 0; k < nk; ++k) {
        last[k] = -HUGE_VAL;
        hit[k] = 0;
        active[k] = active[k] != 0;
    }
    for (i = 0; i < nall; ++i)
        dirs[i] = (i < nk || i >= nk + nroot) ? -1 : (ev->rootdir != NULL ? ev->rootdir[i - nk] : 0);

    data.im = im;
    data.m = m;
    data.p = p;
    data.active = active;
    data.st = st;
    data.nroot = nroot;
    data.alpha = opt->alpha;
    data.beta = opt->beta;
    if (opt->alpha < 0.0 || opt->beta < 0.0) { /* "auto": the rate of the fastest motion at y0 */
        double rate = 0.0;
        if (m->natural_rate(tout[0], y0, p, &rate) != LCG_DAE_OK)
            rate = 0.0;
        if (opt->alpha < 0.0)
            data.alpha = rate;
        if (opt->beta < 0.0)
            data.beta = rate;
    }
    st->alpha = data.alpha;
    st->beta = data.beta;
    data.fc.im = im;
    data.fc.p = p;
    data.fc.alpha = data.alpha;
    data.fc.beta = data.beta;
    data.fc.active = active;
    data.fc.fr = data.fr;
    data.fc.lam = data.lam;
    data.fc.ydot = ydot;
    data.fc.message = st->message;
    data.fc.message_size = sizeof st->message;
    watch_init(&data.w, opt->cancel, opt->poll, opt->poll_data, opt->poll_every, opt->max_wall, nt, &st->nt_done);
    if (create_context(&ctx, st) != 0) {
        free(buf);
        free(ibuf);
        free(fmem);
        return st->flag = LCG_FLAG_NOMEM;
    }

    /* FR_WATCH: with friction, CVODE's state carries the integrals of the contacts' multipliers
     * (2 nk values after y, z' = (lambda_n, lambda_t) per contact), so that its error control
     * resolves how the contact forces vary: while contacts stick under forcing that depends on time
     * alone the state is constant and the steps would otherwise grow past the forcing's period,
     * over which a friction limit is crossed and recrossed unseen by the sign test of the roots. */
    nvec = ny + (data.fr != NULL ? 2 * nk : 0);
    y = N_VNew_Serial(nvec, ctx);
    mem = CVodeCreate(opt->method, ctx);
    A = SUNDenseMatrix(nvec, nvec, ctx);
    if (y == NULL || mem == NULL || A == NULL) {
        flag = LCG_FLAG_NOMEM;
        goto done;
    }
    LS = SUNLinSol_Dense(y, A, ctx);
    yv = N_VGetArrayPointer(y);
    for (i = 0; i < ny; ++i)
        yv[i] = y0[i];
    for (i = ny; i < nvec; ++i)
        yv[i] = 0.0;
    /* the contacts the initial state rests on (touching, at rest, pushing) start in persistent contact */
    rc = im->gaps(tout[0], yv, p, data.gk, data.wk);
    LCG_MODEL_ERROR(LCG_DAE_OK);
    for (k = 0; k < nk; ++k)
        if (!active[k] && data.gk[k] <= set[2] && fabs(data.wk[k]) <= set[0])
            active[k] = 1;
    if (data.fr != NULL) { /* the initial modes: sticking where the slip velocity is at most contact_speed */
        rc = lcg_fr_eval(&data.fc, tout[0], yv);
        LCG_MODEL_ERROR(LCG_DAE_OK);
        for (k = 0; k < nk; ++k)
            if (active[k] && fdata.trow[k] >= 0 && fdata.mu[k] >= 0.0) {
                double u, u2;
                lcg_fr_slip(&fdata, k, &u, &u2);
                fdata.fmode[k] = hypot(u, u2) <= set[0] ? 0 : fdata.trow2[k] >= 0 || u > 0.0 ? 1 : -1;
            }
        rc = lcg_fr_modes(&data.fc, tout[0], yv, NULL, set[0], rec, 0, &quiet);
        if (rc == -1) {
            flag = LCG_FLAG_CONTACT_MODE;
            goto done;
        }
    } else {
        rc = release_pulling(&data, tout[0], yv, ydot, set, scratch, rows, rec, 0, &quiet);
    }
    LCG_MODEL_ERROR(LCG_DAE_OK);

    rc = m->coutputs(tout[0], yv, NULL, p, out);
    LCG_MODEL_ERROR(LCG_DAE_OK);
    for (i = 0; i < ny; ++i)
        yout[i] = yv[i];
    for (i = 0; i < nlam; ++i)
        lamout[i] = data.lam[i];
    st->nt_done = 1;

    if ((flag = CVodeInit(mem, rhs, tout[0], y)) < 0)
        goto done;
    if ((flag = CVodeSStolerances(mem, opt->rtol, opt->atol)) < 0)
        goto done;
    CVodeSetUserData(mem, &data);
    if ((flag = CVodeSetLinearSolver(mem, LS, A)) < 0)
        goto done;
    if ((flag = CVodeRootInit(mem, nall, roots)) < 0)
        goto done;
    if ((flag = CVodeSetRootDirection(mem, dirs)) < 0)
        goto done;
    CVodeSetNoInactiveRootWarn(mem);
    if ((flag = set_step_limits(mem, 0, opt->max_order, opt->first_step, opt->max_step, opt->min_step)) < 0)
        goto done;
    if (nt > 1 && (flag = CVodeSetStopTime(mem, tout[nt - 1])) < 0)
        goto done;

    rc = segment_start(&data, tout[0], yv, ny, &tprev, yprev, gprev);
    LCG_MODEL_ERROR(LCG_DAE_OK);
    for (k = 1; k < nt; ++k) {
        double tret = tout[k - 1];
        if (WATCH_TICK(&data.w))
            goto done;
        for (;;) {
            int missed = -1, rflag = 0;
            CVodeGetNumSteps(mem, &nst);
            if (base[0] + nst >= opt->max_steps) {
                flag = -1;
                snprintf(st->message, sizeof st->message,
                         "the step budget max_steps = %ld is used up before t = %.17g", opt->max_steps, tout[k]);
                goto done;
            }
            CVodeSetMaxNumSteps(mem, opt->max_steps - base[0] - nst);
            flag = CVode(mem, tout[k], y, &tret, CV_NORMAL);
            st->t_reached = tret;
            if (flag >= 0) { /* a free contact deeper than where the segment began: a flight skipped by a step */
                rc = im->gaps(tret, yv, p, data.gk, data.wk);
                LCG_MODEL_ERROR(LCG_DAE_OK);
                missed = lcg_imp_below_floor(data.gk, data.wk, gprev, active, nk, set[2]);
            }
            if (missed >= 0) {
                /* A step skipped a free contact's flight (or its gap began negative): the segment
                 * again from its start in single steps up to this return, each step's end checked,
                 * the crossing located by bisection on the step's interpolant, the impact there. */
                double t_miss = tret, ta = tprev, tstar = -HUGE_VAL;
                int apex = 0;
                st->nretries++;
                for (i = 0; i < ny; ++i)
                    yv[i] = yprev[i];
                rc = im->gaps(tprev, yv, p, data.gk, wa);
                LCG_MODEL_ERROR(LCG_DAE_OK);
                add_counts(mem, base);
                if ((flag = CVodeReInit(mem, tprev, y)) < 0 || (flag = CVodeSetStopTime(mem, t_miss)) < 0)
                    goto done;
                for (;;) {
                    CVodeGetNumSteps(mem, &nst);
                    if (base[0] + nst >= opt->max_steps) {
                        flag = -1;
                        snprintf(st->message, sizeof st->message, "the step budget max_steps = %ld is used up "
                                 "before t = %.17g", opt->max_steps, tout[k]);
                        goto done;
                    }
                    flag = CVode(mem, t_miss, y, &tret, CV_ONE_STEP);
                    st->t_reached = tret;
                    if (flag < 0 || flag == CV_ROOT_RETURN)
                        break; /* failed, or CVODE's root finding saw it this time */
                    rc = im->gaps(tret, yv, p, data.gk, data.wk);
                    LCG_MODEL_ERROR(LCG_DAE_OK);
                    missed = lcg_imp_below_floor(data.gk, data.wk, gprev, active, nk, set[2]);
                    if (missed >= 0) {
                        apex = wa[missed] > 0.0;
                        if (apex) /* rising at the step's start: the whole flight within one step */
                            tstar = tret;
                        else
                            rc = bisect(&data, mem, y, missed, ta, tret, gprev, set[2], &tstar);
                        LCG_MODEL_ERROR(LCG_DAE_OK);
                        break;
                    }
                    if (tret >= t_miss)
                        break; /* these steps saw no crossing: the segment as it is */
                    ta = tret;
                    for (j = 0; j < nk; ++j)
                        wa[j] = data.wk[j];
                }
                if (flag < 0)
                    goto done;
                if (nt > 1 && (rflag = CVodeSetStopTime(mem, tout[nt - 1])) < 0) {
                    flag = rflag;
                    goto done;
                }
                if (missed >= 0) { /* the state at the crossing: the impact there, then on to tout[k] */
                    tret = tstar;
                    rc = im->gaps(tret, yv, p, data.gk, data.wk);
                    LCG_MODEL_ERROR(LCG_DAE_OK);
                    if (-data.gk[missed] > st->max_penetration)
                        st->max_penetration = -data.gk[missed];
                    for (j = 0; j < nk; ++j)
                        hit[j] = j == missed;
                    if (apex)
                        last[missed] = tret; /* a flight shorter than a step (accumulation): plastic */
                    rc = restart(&data, mem, y, tret, hit, e, set, last, scratch, rows, ydot, rec, max_rec, n_rec,
                                 base, nt > 1 ? tout[nt - 1] : tret, &rflag);
                    LCG_MODEL_ERROR(LCG_DAE_OK);
                    if (rflag < 0) {
                        flag = rflag;
                        goto done;
                    }
                    rc = segment_start(&data, tret, yv, ny, &tprev, yprev, gprev);
                    LCG_MODEL_ERROR(LCG_DAE_OK);
                    continue;
                }
                if (flag != CV_ROOT_RETURN && tret < tout[k]) { /* no crossing up to an earlier return */
                    rc = segment_start(&data, tret, yv, ny, &tprev, yprev, gprev);
                    LCG_MODEL_ERROR(LCG_DAE_OK);
                    continue;
                }
            }
            if (flag == CV_ROOT_RETURN) {
                int j, stop = 0, any = 0;
                if (CVodeGetRootInfo(mem, info) < 0)
                    goto done;
                for (j = nk; j < nk + nroot; ++j) { /* the model's events */
                    if (info[j] == 0)
                        continue;
                    if (ev->n_events < ev->max_events) {
                        ev->t[ev->n_events] = tret;
                        for (i = 0; i < ny; ++i)
                            ev->y[(long)ev->n_events * ny + i] = yv[i];
                        ev->which[ev->n_events] = j - nk;
                        ev->direction[ev->n_events] = info[j];
                    }
                    ev->n_events++;
                    if (ev->terminal == NULL || ev->terminal[j - nk])
                        stop = 1;
                }
                if (stop) {
                    ev->terminated = 1;
                    flag = CV_ROOT_RETURN;
                    goto done;
                }
                for (j = 0; j < nk; ++j) {
                    hit[j] = info[j] != 0 && !active[j];
                    if (info[j] != 0 && active[j] && data.fr != NULL) { /* released by lcg_fr_modes */
                        fdata.ending[j] = FR_END_RELEASE;
                        any = 1;
                    } else if (info[j] != 0 && active[j]) { /* the multiplier crosses zero: release */
                        active[j] = 0;
                        record(rec, max_rec, n_rec, tret, j, LCG_IMP_RELEASE, 0.0, 0.0, 0.0);
                        any = 1;
                    }
                    any |= hit[j];
                }
                if (data.fr != NULL) {
                    const int *fi = info + nk + nroot;
                    for (j = 0; j < nk; ++j)
                        if ((fi[2 * j] != 0 || fi[2 * j + 1] != 0) && active[j] && fdata.ending[j] == 0) {
                            fdata.ending[j] = fdata.fmode[j] == 0 ? FR_END_STICK : FR_END_SLIP;
                            any = 1;
                        }
                    if (fi[2 * nk] != 0) {
                        flag = LCG_FLAG_CONTACT_MODE;
                        st->t_reached = tret;
                        snprintf(st->message, sizeof st->message, "Painleve's paradox at t = %.17g: the contact "
                                 "problem of the slipping contact(s) became singular (the normal's effective mass "
                                 "with friction, G M^-1 (G - sigma mu T)^T, reached 0: the normal force grows "
                                 "without bound)", tret);
                        goto done;
                    }
                }
                if (any) {
                    rc = restart(&data, mem, y, tret, hit, e, set, last, scratch, rows, ydot, rec, max_rec, n_rec,
                                 base, nt > 1 ? tout[nt - 1] : tret, &flag);
                    LCG_MODEL_ERROR(LCG_DAE_OK);
                    if (flag < 0)
                        goto done;
                }
                rc = segment_start(&data, tret, yv, ny, &tprev, yprev, gprev);
                LCG_MODEL_ERROR(LCG_DAE_OK);
                if (tret >= tout[k])
                    break;
                continue;
            }
            break;
        }
        if (flag >= 0) {
            rc = segment_start(&data, tret, yv, ny, &tprev, yprev, gprev);
            LCG_MODEL_ERROR(LCG_DAE_OK);
        }
        if (flag < 0)
            goto done;
        for (i = 0; i < ny; ++i)
            yout[(long)k * ny + i] = yv[i];
        rc = crhs(&data, tret, yv, ydot, data.lam);
        LCG_MODEL_ERROR(LCG_DAE_OK);
        for (i = 0; i < nlam; ++i)
            lamout[(long)k * nlam + i] = data.lam[i];
        rc = m->coutputs(tret, yv, NULL, p, out + (long)k * m->nout);
        LCG_MODEL_ERROR(LCG_DAE_OK);
        st->nt_done = k + 1;
    }

done:
    if (data.fr != NULL) /* the final friction modes of the Coulomb contacts: 1 stick, 2 slip+, 3 slip-, 4 slip (3-D) */
        for (k = 0; k < nk; ++k)
            if (active[k] && fdata.trow[k] >= 0 && fdata.mu[k] >= 0.0)
                active[k] = fdata.fmode[k] != 0 && fdata.trow2[k] >= 0 ? 4 : fdata.fmode[k] > 0 ? 2
                            : fdata.fmode[k] < 0 ? 3 : 1;
    flag = watch_flag(&data.w, flag, st->message, sizeof st->message);
    if (flag == LCG_FLAG_CONTACT_MODE) /* kept from CVODE's error handler (the counters below) */
        memcpy(painleve, st->message, sizeof painleve);
    if (mem != NULL) {
        add_counts(mem, base);
        st->nsteps = base[0];
        st->nrhs = base[1];
        st->nrhs_dq = base[2];
        st->njac = base[3];
        st->nlinsetups = base[4];
        st->netfails = base[5];
        st->nniters = base[6];
        st->nncfails = base[7];
        CVodeGetLastStep(mem, &st->h_last);
        CVodeGetNumGEvals(mem, &st->ngevals);
        if (flag < 0 && flag > LCG_FLAG_MODEL_ERROR && st->model_error == 0 && flag != LCG_FLAG_CONTACT_MODE)
            CVodeGetCurrentTime(mem, &st->t_reached);
    }
    st->flag = flag;
    if (flag == LCG_FLAG_CONTACT_MODE)
        memcpy(st->message, painleve, sizeof painleve);
    LCG_NOMEM_MESSAGE(LCG_FLAG_NOMEM, "CVODE");
    CVodeFree(&mem);
    free_solver(LS, NULL, A, &y, 1, &ctx);
    free(buf);
    free(ibuf);
    free(fmem);
    return flag < 0 ? flag : 0;
}
