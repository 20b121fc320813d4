/* lcg_cvsens.c -- CVODE with forward sensitivities (lagcodegen's runtime, compiled as it is).
 *
 * The augmented ODE (y, s_1, ..., s_ns), s_j = dy/dtheta_j, of a model whose generated
 * <prefix>_sens_rhs evaluates the state's and every direction's right-hand side with one
 * factorization of the mass matrix. CVODE's Newton iteration solves (I - gamma J_aug) x = b with
 * a linear solver of this file (a matrix-embedded SUNLinearSolver): J_aug is block lower
 * triangular, J on its diagonal (J = df/dy of the states) and d(J s_j + df/dp)/dy below; the
 * solver keeps the diagonal only, factors I - gamma J once (LU with partial pivoting) and solves
 * each block with it -- CVODES's simultaneous corrector. The cost of a setup is one Jacobian of
 * the states and one n^3 factorization, whatever ns; a solve costs (1 + ns) n^2.
 *
 * SUNDIALS ships no struct of a custom linear solver that this runtime could take from a header
 * (scikit-sundae's libraries come without headers): the layout of SUNDIALS 7.x's
 * _generic_SUNLinearSolver and its operations table is declared here, and checked at run time
 * before use (the context's place in the struct, and that SUNLinSolSetup calls this file's
 * setup); another layout ends the run with LCG_FLAG_BAD_INPUT and a message, never a crash. */
#include "lcg_control.h" /* first: POSIX */

#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sundials_api.h"
#include "lcg_cvsens.h"

#define LCG_STATS lcg_cvsens_stats
#include "lcg_sundials.h"

/* SUNDIALS 7.x (sundials_linearsolver.h): the solver object and its operations. */
#define LCG_LS_MATRIX_EMBEDDED 3 /* SUNLINEARSOLVER_MATRIX_EMBEDDED */
#define LCG_LS_CUSTOM 17         /* SUNLINEARSOLVER_CUSTOM */
typedef struct lcg_ls_ops {
    int (*gettype)(SUNLinearSolver);
    int (*getid)(SUNLinearSolver);
    int (*setatimes)(SUNLinearSolver, void *, void (*)(void));
    int (*setpreconditioner)(SUNLinearSolver, void *, void (*)(void), void (*)(void));
    int (*setscalingvectors)(SUNLinearSolver, N_Vector, N_Vector);
    int (*setoptions)(SUNLinearSolver, const char *, const char *, int, char **);
    int (*setzeroguess)(SUNLinearSolver, int);
    int (*initialize)(SUNLinearSolver);
    int (*setup)(SUNLinearSolver, SUNMatrix);
    int (*solve)(SUNLinearSolver, SUNMatrix, N_Vector, N_Vector, double);
    int (*numiters)(SUNLinearSolver);
    double (*resnorm)(SUNLinearSolver);
    sunindextype (*lastflag)(SUNLinearSolver);
    int (*space)(SUNLinearSolver, long *, long *);
    N_Vector (*resid)(SUNLinearSolver);
    int (*free)(SUNLinearSolver);
} lcg_ls_ops;
typedef struct lcg_ls_object {
    void *content;
    void *reserved;
    lcg_ls_ops *ops;
    SUNContext sunctx;
} lcg_ls_object;

SUNLinearSolver SUNLinSolNewEmpty(SUNContext sunctx);
void SUNLinSolFreeEmpty(SUNLinearSolver S);
int SUNLinSolSetup(SUNLinearSolver S, SUNMatrix A);
int CVodeGetNonlinearSystemData(void *cvode_mem, sunrealtype *tcur, N_Vector *ypred, N_Vector *yn, N_Vector *fn,
                                sunrealtype *gamma, sunrealtype *rl1, N_Vector *zn1, void **user_data);
int CVodeGetCurrentGamma(void *cvode_mem, sunrealtype *gamma);

typedef struct {
    const lcg_model *m;
    lcg_sens_rhs_fn sens_rhs;
    const double *p;
    int ns;
    const int *which;
    int jacobian;
    lcg_cvsens_stats *st;
    void *mem;
    int probe;          /* set by setup while the layout is checked */
    double *J;          /* ny x ny, column-major: df/dy of the states */
    double *A;          /* LU factors of I - gamma J, row-major */
    int *piv;
    double gamma;       /* gamma of the factors (0: none) */
    int have_J;         /* J holds a Jacobian, evaluated at step nst_J after ncf_J convergence failures */
    long nst_J, ncf_J;
    double *f0, *f1, *y1, *vals; /* scratch */
    int nonfinite;
    double t_nonfinite;
    watch w;            /* Ctrl-C (the poll callback), the wall-clock limit */
    lcg_cvsens_events *ev; /* the event functions and the events found, or NULL */
    int *info;          /* nroot: CVodeGetRootInfo's */
} sens_data;

static int model_status(sens_data *d, int rc, double t)
{
    d->nonfinite = rc == LCG_ERR_NONFINITE;
    if (d->nonfinite)
        d->t_nonfinite = t;
    if (rc == LCG_ERR_SINGULAR_MASS) {
        d->st->model_error = rc;
        d->st->t_reached = t;
        return -1;
    }
    return rc == LCG_OK ? 0 : 1;
}

static int aug_rhs(sunrealtype t, N_Vector y, N_Vector ydot, void *data)
{
    sens_data *d = (sens_data *)data;
    const int ny = d->m->ny;
    double *yv = N_VGetArrayPointer(y), *fv = N_VGetArrayPointer(ydot);
    if (WATCH_TICK(&d->w))
        return -1; /* stop: cancelled or out of time */
    return model_status(d, d->sens_rhs(t, yv, d->p, d->ns, d->which, yv + ny, fv, fv + ny), t);
}

/* CVRootFn: the event functions at the state part of the augmented vector. */
static int sens_roots(sunrealtype t, N_Vector y, sunrealtype *gout, void *data)
{
    sens_data *d = (sens_data *)data;
    int rc = d->ev->roots(t, N_VGetArrayPointer(y), d->p, gout);

    if (rc != LCG_OK) {
        d->st->model_error = rc;
        d->st->t_reached = t;
        return -1;
    }
    return 0;
}

/* Root finding on d's CVODE memory with the event functions and directions of d->ev: 0 or a
 * negative CVODE flag (LCG_FLAG_NOMEM without memory for the root information). */
static int sens_roots_init(sens_data *d)
{
    int flag;

    if ((d->info = (int *)malloc(sizeof(int) * (size_t)d->ev->nroot)) == NULL)
        return LCG_FLAG_NOMEM;
    if ((flag = CVodeRootInit(d->mem, d->ev->nroot, sens_roots)) < 0)
        return flag;
    if (d->ev->rootdir != NULL && (flag = CVodeSetRootDirection(d->mem, (int *)d->ev->rootdir)) < 0)
        return flag;
    CVodeSetNoInactiveRootWarn(d->mem);
    return 0;
}

/* The roots CVODE returned at t with the augmented vector yv (total values) into d->ev, except
 * those within rounding of t0, the time CVODE started from; returns 1 if one of them is terminal. */
static int sens_record(sens_data *d, double t, double t0, const double *yv, long total)
{
    lcg_cvsens_events *ev = d->ev;
    double h = 0.0;
    long k;
    int i, stop = 0;

    if (CVodeGetRootInfo(d->mem, d->info) < 0)
        return 1;
    CVodeGetLastStep(d->mem, &h);
    if (t - t0 <= 100.0 * DBL_EPSILON * (fabs(t0) + fabs(h)))
        return 0;
    for (i = 0; i < ev->nroot; ++i) {
        if (d->info[i] == 0)
            continue;
        if (ev->n_events < ev->max_events) {
            ev->t[ev->n_events] = t;
            for (k = 0; k < total; ++k)
                ev->y[(long)ev->n_events * total + k] = yv[k];
            ev->which[ev->n_events] = i;
            ev->direction[ev->n_events] = d->info[i];
        }
        ev->n_events++;
        if (ev->terminal == NULL || ev->terminal[i])
            stop = 1;
    }
    return stop;
}

/* J = df/dy at (t, y): the model's dense or sparse Jacobian, else forward differences. */
static int states_jacobian(sens_data *d, double t, const double *y)
{
    const lcg_model *m = d->m;
    const int ny = m->ny;
    int rc, i, j, k;

    if ((rc = m->rhs(t, y, d->p, d->f0)) != LCG_OK)
        return rc;
    d->st->njac++;
    if (d->jacobian && m->jac != NULL)
        return m->jac(t, y, d->f0, d->p, d->J);
    if (d->jacobian && m->jac_sparse != NULL) {
        if ((rc = m->jac_sparse(t, y, d->f0, d->p, d->vals)) != LCG_OK)
            return rc;
        memset(d->J, 0, sizeof(double) * (size_t)ny * (size_t)ny);
        for (j = 0; j < ny; ++j)
            for (k = m->jac_colptr[j]; k < m->jac_colptr[j + 1]; ++k)
                d->J[(long)j * ny + m->jac_rowind[k]] = d->vals[k];
        return LCG_OK;
    }
    for (i = 0; i < ny; ++i)
        d->y1[i] = y[i];
    for (j = 0; j < ny; ++j) {
        double h = 1.4901161193847656e-08 * (fabs(y[j]) > 1.0 ? fabs(y[j]) : 1.0);
        d->y1[j] = y[j] + h;
        h = d->y1[j] - y[j];
        rc = m->rhs(t, d->y1, d->p, d->f1);
        d->y1[j] = y[j];
        if (rc != LCG_OK)
            return rc;
        for (i = 0; i < ny; ++i)
            d->J[(long)j * ny + i] = (d->f1[i] - d->f0[i]) / h;
    }
    return LCG_OK;
}

/* A = LU of I - gamma J (partial pivoting); returns 0, or 1 if singular (recoverable: CVODE
 * retries with a smaller step). */
static int factor(sens_data *d, double gamma)
{
    const int n = d->m->ny;
    double *A = d->A;
    int i, j, k;

    for (i = 0; i < n; ++i)
        for (j = 0; j < n; ++j)
            A[(long)i * n + j] = (i == j ? 1.0 : 0.0) - gamma * d->J[(long)j * n + i];
    d->gamma = gamma;
    d->st->nfactor++;
    for (k = 0; k < n; ++k) {
        int r = k;
        for (i = k + 1; i < n; ++i)
            if (fabs(A[(long)i * n + k]) > fabs(A[(long)r * n + k]))
                r = i;
        d->piv[k] = r;
        if (!(fabs(A[(long)r * n + k]) > 0.0) || !isfinite(A[(long)r * n + k]))
            return 1;
        if (r != k)
            for (j = 0; j < n; ++j) {
                double tmp = A[(long)k * n + j];
                A[(long)k * n + j] = A[(long)r * n + j];
                A[(long)r * n + j] = tmp;
            }
        for (i = k + 1; i < n; ++i) {
            double f = A[(long)i * n + k] / A[(long)k * n + k];
            A[(long)i * n + k] = f;
            for (j = k + 1; j < n; ++j)
                A[(long)i * n + j] -= f * A[(long)k * n + j];
        }
    }
    return 0;
}

static void lu_solve(const sens_data *d, double *b)
{
    const int n = d->m->ny;
    const double *A = d->A;
    int i, k;

    for (k = 0; k < n; ++k)
        if (d->piv[k] != k) {
            double tmp = b[k];
            b[k] = b[d->piv[k]];
            b[d->piv[k]] = tmp;
        }
    for (i = 0; i < n; ++i)
        for (k = 0; k < i; ++k)
            b[i] -= A[(long)i * n + k] * b[k];
    for (i = n - 1; i >= 0; --i) {
        for (k = i + 1; k < n; ++k)
            b[i] -= A[(long)i * n + k] * b[k];
        b[i] /= A[(long)i * n + i];
    }
}

static int ls_type(SUNLinearSolver S)
{
    (void)S;
    return LCG_LS_MATRIX_EMBEDDED;
}

static int ls_id(SUNLinearSolver S)
{
    (void)S;
    return LCG_LS_CUSTOM;
}

/* CVODE calls no setup of a matrix-embedded solver (it leaves the Newton matrix to the solver):
 * the solver's setup only answers the layout check. */
static int ls_setup(SUNLinearSolver S, SUNMatrix Amat)
{
    sens_data *d = (sens_data *)((lcg_ls_object *)S)->content;
    (void)Amat;
    if (d->probe)
        d->probe = 2;
    return 0;
}

/* x = (I - gamma J)^-1 b block by block. J is evaluated anew at CVODE's current iterate at the
 * first solve, after a convergence failure of the Newton iteration, and LCG_CVSENS_MSBJ steps
 * after the last one (CVODE's own rules for its matrix-based solvers); I - gamma J is refactored
 * whenever J or gamma changed. */
#define LCG_CVSENS_MSBJ 51
static int ls_solve(SUNLinearSolver S, SUNMatrix Amat, N_Vector x, N_Vector b, double tol)
{
    sens_data *d = (sens_data *)((lcg_ls_object *)S)->content;
    const int ny = d->m->ny;
    double gamma, t, rl1, *xv = N_VGetArrayPointer(x), *bv = N_VGetArrayPointer(b);
    N_Vector ypred, yn, fn, zn1;
    void *ud;
    long i, total = (long)ny * (1 + d->ns), nst = 0, ncf = 0;
    int j, rc;
    (void)Amat;
    (void)tol;

    if (CVodeGetNonlinearSystemData(d->mem, &t, &ypred, &yn, &fn, &gamma, &rl1, &zn1, &ud) != 0)
        return -1;
    CVodeGetNumSteps(d->mem, &nst);
    CVodeGetNumNonlinSolvConvFails(d->mem, &ncf);
    if (!d->have_J || ncf > d->ncf_J || nst >= d->nst_J + LCG_CVSENS_MSBJ) {
        rc = states_jacobian(d, t, N_VGetArrayPointer(yn));
        if (rc != LCG_OK)
            return model_status(d, rc, t) < 0 ? -1 : 1;
        d->have_J = 1;
        d->nst_J = nst;
        d->ncf_J = ncf;
        d->gamma = 0.0; /* refactor */
    }
    if (gamma != d->gamma && factor(d, gamma) != 0) {
        d->have_J = 0;
        return 1;
    }
    for (i = 0; i < total; ++i)
        xv[i] = bv[i];
    for (j = 0; j <= d->ns; ++j)
        lu_solve(d, xv + (long)j * ny);
    d->st->nblock_solves += 1 + d->ns;
    return 0;
}

/* The block solver of this file on the empty solver LS of the context ctx, solving for d: its
 * layout checked (the context in its place, SUNLinSolSetup calling ours). 0, or LCG_FLAG_BAD_INPUT
 * with the reason in message. */
static int ls_attach(SUNLinearSolver LS, SUNContext ctx, sens_data *d, char *message, size_t size)
{
    lcg_ls_object *obj = (lcg_ls_object *)LS;

    if (obj->sunctx != ctx || obj->ops == NULL) {
        snprintf(message, size, "the SUNDIALS %s linear solver object has another layout than "
                 "the sensitivity driver's (SUNDIALS 7.x)", LCG_SUNDIALS_VERSION);
        return LCG_FLAG_BAD_INPUT;
    }
    obj->content = d;
    obj->ops->gettype = ls_type;
    obj->ops->getid = ls_id;
    obj->ops->setup = ls_setup;
    obj->ops->solve = ls_solve;
    d->probe = 1;
    SUNLinSolSetup(LS, NULL);
    if (d->probe != 2) {
        snprintf(message, size, "the SUNDIALS %s linear solver operations have another layout "
                 "than the sensitivity driver's (SUNDIALS 7.x)", LCG_SUNDIALS_VERSION);
        return LCG_FLAG_BAD_INPUT;
    }
    d->probe = 0;
    return 0;
}

int lcg_cvsens_solve(const lcg_model *m, lcg_sens_rhs_fn sens_rhs, lcg_sens_out_fn sens_out, const double *p,
                     int ns, const int *which, const double *y0, const double *s0, int nt, const double *tout,
                     double *yout, double *sout, double *out, double *dout, const lcg_cvsens_options *opt,
                     lcg_cvsens_stats *st)
{
    return lcg_cvsens_solve_events(m, sens_rhs, sens_out, p, ns, which, y0, s0, nt, tout, yout, sout, out, dout, opt,
                                   st, NULL);
}

int lcg_cvsens_solve_events(const lcg_model *m, lcg_sens_rhs_fn sens_rhs, lcg_sens_out_fn sens_out,
                            const double *p, int ns, const int *which, const double *y0, const double *s0, int nt,
                            const double *tout, double *yout, double *sout, double *out, double *dout,
                            const lcg_cvsens_options *opt, lcg_cvsens_stats *st, lcg_cvsens_events *ev)
{
    SUNContext ctx = NULL;
    void *mem = NULL;
    N_Vector y = NULL, abstol = NULL;
    SUNLinearSolver LS = NULL;
    sens_data data;
    double *yv;
    long nst = 0, total;
    int k, i, flag = 0, rc, ny;

    memset(st, 0, sizeof *st);
    memset(&data, 0, sizeof data);
    st->t_reached = tout[0];
    if (m == NULL || m->abi != LCG_MODEL_ABI || m->rhs == NULL || m->ny != 2 * m->nq + m->nz || sens_rhs == NULL
        || ns < 0) {
        snprintf(st->message, sizeof st->message, "the model table is missing or of another layout");
        return st->flag = LCG_FLAG_BAD_INPUT;
    }
    ny = m->ny;
    total = (long)ny * (1 + ns);
    data.m = m;
    data.sens_rhs = sens_rhs;
    data.p = p;
    data.ns = ns;
    data.which = which;
    data.jacobian = opt->jacobian;
    data.st = st;
    data.gamma = 0.0;
    watch_init(&data.w, NULL, opt->poll, opt->poll_data, opt->poll_every, opt->max_wall, nt, &st->nt_done);
    LCG_CREATE_CONTEXT(LCG_FLAG_NOMEM);

    data.J = (double *)malloc(sizeof(double) * (size_t)ny * (size_t)ny);
    data.A = (double *)malloc(sizeof(double) * (size_t)ny * (size_t)ny);
    data.piv = (int *)malloc(sizeof(int) * (size_t)ny);
    data.f0 = (double *)malloc(sizeof(double) * (size_t)ny);
    data.f1 = (double *)malloc(sizeof(double) * (size_t)ny);
    data.y1 = (double *)malloc(sizeof(double) * (size_t)ny);
    data.vals = (double *)malloc(sizeof(double) * (size_t)(m->jac_nnz > 0 ? m->jac_nnz : 1));
    y = N_VNew_Serial((sunindextype)total, ctx);
    abstol = N_VNew_Serial((sunindextype)total, ctx);
    mem = CVodeCreate(opt->method, ctx);
    LS = SUNLinSolNewEmpty(ctx);
    if (data.J == NULL || data.A == NULL || data.piv == NULL || data.f0 == NULL || data.f1 == NULL
        || data.y1 == NULL || data.vals == NULL || y == NULL || abstol == NULL || mem == NULL || LS == NULL) {
        flag = LCG_FLAG_NOMEM;
        goto done;
    }
    data.mem = mem;
    if ((flag = ls_attach(LS, ctx, &data, st->message, sizeof st->message)) < 0)
        goto done;

    yv = N_VGetArrayPointer(y);
    for (i = 0; i < ny; ++i)
        yv[i] = yout[i] = y0[i];
    for (i = 0; i < ny * ns; ++i)
        yv[ny + i] = sout[i] = s0[i];
    for (i = 0; i < total; ++i)
        N_VGetArrayPointer(abstol)[i] = opt->atol[i];
    if (m->outputs != NULL) {
        rc = m->outputs(tout[0], yv, p, out);
        LCG_MODEL_ERROR(LCG_OK);
        if (sens_out != NULL && m->nout > 0) {
            rc = sens_out(tout[0], yv, p, ns, which, yv + ny, dout);
            LCG_MODEL_ERROR(LCG_OK);
        }
    }
    st->nt_done = 1;

    if ((flag = CVodeInit(mem, aug_rhs, tout[0], y)) < 0)
        goto done;
    if ((flag = CVodeSVtolerances(mem, opt->rtol, abstol)) < 0)
        goto done;
    CVodeSetUserData(mem, &data);
    if ((flag = CVodeSetLinearSolver(mem, LS, NULL)) < 0)
        goto done;
    CVodeSetMaxHnilWarns(mem, -1);
    if (opt->max_order > 0 && (flag = CVodeSetMaxOrd(mem, opt->max_order)) < 0)
        goto done;
    if (opt->first_step > 0 && (flag = CVodeSetInitStep(mem, opt->first_step)) < 0)
        goto done;
    if (opt->max_step > 0 && (flag = CVodeSetMaxStep(mem, opt->max_step)) < 0)
        goto done;
    if (opt->min_step > 0 && (flag = CVodeSetMinStep(mem, opt->min_step)) < 0)
        goto done;
    if (nt > 1 && (flag = CVodeSetStopTime(mem, tout[nt - 1])) < 0)
        goto done;
    if (ev != NULL && ev->nroot > 0 && ev->roots != NULL) {
        ev->n_events = ev->terminated = 0;
        data.ev = ev;
        if ((flag = sens_roots_init(&data)) < 0)
            goto done;
    }

    for (k = 1; k < nt; ++k) {
        double tret = tout[k - 1];
        if (WATCH_TICK(&data.w))
            goto done;
        LCG_STEP_BUDGET(CVode);
        flag = CVode(mem, tout[k], y, &tret, CV_NORMAL);
        st->t_reached = tret;
        while (flag == CV_ROOT_RETURN && data.ev != NULL) {
            if (sens_record(&data, tret, tout[0], yv, total)) {
                ev->terminated = 1;
                flag = 0;
                goto done;
            }
            LCG_STEP_BUDGET(CVode);
            flag = CVode(mem, tout[k], y, &tret, CV_NORMAL);
            st->t_reached = tret;
        }
        if (flag < 0)
            goto done;
        for (i = 0; i < ny; ++i)
            yout[(long)k * ny + i] = yv[i];
        for (i = 0; i < ny * ns; ++i)
            sout[(long)k * ny * ns + i] = yv[ny + i];
        if (m->outputs != NULL) {
            rc = m->outputs(tret, yv, p, out + (long)k * m->nout);
            LCG_MODEL_ERROR(LCG_OK);
            if (sens_out != NULL && m->nout > 0) {
                rc = sens_out(tret, yv, p, ns, which, yv + ny, dout + (long)k * ns * m->nout);
                LCG_MODEL_ERROR(LCG_OK);
            }
        }
        st->nt_done = k + 1;
    }

done:
    flag = watch_flag(&data.w, flag, st->message, sizeof st->message);
    if (mem != NULL) {
        CVodeGetNumSteps(mem, &st->nsteps);
        CVodeGetNumRhsEvals(mem, &st->nrhs);
        CVodeGetNumLinSolvSetups(mem, &st->nlinsetups);
        CVodeGetNumErrTestFails(mem, &st->netfails);
        CVodeGetNumNonlinSolvIters(mem, &st->nniters);
        CVodeGetNumNonlinSolvConvFails(mem, &st->nncfails);
        CVodeGetLastStep(mem, &st->h_last);
        if (flag < 0 && flag > LCG_FLAG_MODEL_ERROR && st->model_error == 0)
            CVodeGetCurrentTime(mem, &st->t_reached);
    }
    if (data.nonfinite && st->model_error == 0 && LCG_CVODE_NONFINITE_CAUSE(flag)) {
        st->model_error = LCG_ERR_NONFINITE;
        st->t_reached = data.t_nonfinite;
        flag = LCG_MODEL_ERROR_FLAG(st->model_error);
    }
    st->flag = flag;
    LCG_NOMEM_MESSAGE(LCG_FLAG_NOMEM, "CVODE");
    CVodeFree(&mem);
    if (LS != NULL) {
        ((lcg_ls_object *)LS)->content = NULL;
        SUNLinSolFreeEmpty(LS);
    }
    if (abstol != NULL)
        N_VDestroy(abstol);
    if (y != NULL)
        N_VDestroy(y);
    free(data.J);
    free(data.A);
    free(data.piv);
    free(data.f0);
    free(data.f1);
    free(data.y1);
    free(data.vals);
    free(data.info);
    SUNContext_Free(&ctx);
    return flag < 0 ? flag : 0;
}
