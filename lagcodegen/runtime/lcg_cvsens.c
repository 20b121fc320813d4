/* lcg_cvsens.c -- CVODE with forward sensitivities (lagcodegen's runtime, compiled as it is).
 *
 * The augmented ODE (y, s_1, ..., s_ns), s_j = dy/dtheta_j, of a model whose generated
 * <prefix>_sens_rhs evaluates the state's and every direction's right-hand side with one
 * factorization of the mass matrix. CVODE's Newton iteration solves (I - gamma J_aug) x = b with
 * the matrix of the states alone: J_aug is block lower triangular, J on its diagonal (J = df/dy
 * of the states) and d(J s_j + df/dp)/dy below; the correctors keep the diagonal only, factor
 * I - gamma J once (LU with partial pivoting) and solve each block with it. Two correctors:
 *  - staggered (the default; CVODES's CV_STAGGERED): a nonlinear solver of this file
 *    (SUNNonlinearSolver) iterates on the states alone with the model table's right-hand side
 *    until CVODE's convergence test passes, then corrects the sensitivities, linear in s, with
 *    the same matrix -- one <prefix>_sens_rhs per step when the matrix is fresh. Its matrix
 *    follows CVODE's rules for the plain run's dense solver (nls_solve).
 *  - simultaneous (CVODES's CV_SIMULTANEOUS): CVODE's Newton solver on the whole augmented
 *    system with a linear solver of this file (a matrix-embedded SUNLinearSolver): every
 *    direction at every iteration, the matrix refactored whenever gamma changes.
 * The cost of a setup is one Jacobian of the states and one n^3 factorization, whatever ns; a
 * solve costs (1 + ns) n^2.
 *
 * Input tables (lcg_cvsens_solve_inputs, lcg_inputs.h): every evaluation of the model's functions
 * sees p with the inputs' slots at their table values (a copy of p per run), and the run restarts
 * at the tables' restart times as the plain driver (lcg_cvode.c) does; a direction along an
 * input's slot is refused, the input being a given signal (du/dtheta = 0 for the others).
 *
 * SUNDIALS ships no struct of a custom solver that this runtime could take from a header
 * (scikit-sundae's libraries come without headers): the layouts of SUNDIALS 7.x's
 * _generic_SUNLinearSolver, _generic_SUNNonlinearSolver and their operations tables are declared
 * here, and checked at run time before use (the context's place in the struct, and that
 * SUNDIALS's dispatch reaches this file's operations); another layout ends the run with
 * LCG_FLAG_BAD_INPUT and a message, never a crash. */
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
    lcg_sens_proj_fn project;    /* projection after each step, or NULL */
    double *ynew;                /* its result (ny (1 + ns)) */
    int nonfinite;
    double t_nonfinite;
    watch w;            /* Ctrl-C (the poll callback), the wall-clock limit */
    lcg_cvsens_events *ev; /* the event functions and the events found, or NULL */
    int *info;          /* nroot: CVodeGetRootInfo's */
    /* the staggered corrector (nls_*): CVODE's Newton and dense solver rules for the states, then
     * the sensitivities with the same matrix */
    int staggered;      /* the corrector of this run: 1 staggered, 0 simultaneous (ls_*) */
    int bdf;            /* BDF: solves scaled by 2/(1 + gamma/gammap), as CVODE's dense solver */
    double rtol;
    const double *atol; /* ny (1 + ns) absolute tolerances of the error test (sens_ewt) */
    double wboost;      /* sqrt(1 + ns): the error weights' factor (sens_ewt) */
    int errcon;         /* the sensitivities in CVODE's error test (their absolute tolerances real) */
    int probe_hit;      /* set by the operations while the layout is checked */
    int have_A;         /* A holds the factors of I - gammap J */
    double gammap, crate, crate_s;
    long nstlp, netf_seen;
    int last_failed;    /* the previous solve ended in a convergence failure */
    long nls_iters, nls_fails, nsetups, nsens_iters, nrhs_states, nrhs_sens;
    double *ytmp, *wsens, *ftmp; /* scratch: ny (1 + ns) values */
    double *Ainv, *xtmp; /* (I - gammap J)^-1 column-major (from the factors), scratch of ny */
    const lcg_inputs *in; /* input tables (lcg_inputs.h), or NULL */
    double *pin;        /* inputs: p with the inputs' slots set at the evaluation time */
    double key;         /* inputs: the time of the last restart (the run's start at first) */
    double tb;          /* inputs: the next restart time (HUGE_VAL: none) */
    long nst_done;      /* inputs: the steps of the segments before the last restart */
} sens_data;

/* The run-time parameters at t: p, with the inputs' slots from their tables when there are any
 * (at the next restart time, the piece that ends there). */
static const double *params_at(sens_data *d, double t)
{
    if (d->in == NULL)
        return d->p;
    lcg_inputs_apply(d->in, t, t >= d->tb, d->pin);
    return d->pin;
}

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

/* CVODE's error weights of the augmented vector (CVodeWFtolerances, set by sens_tolerances):
 * the states' 1 / (rtol |y_i| + atol_i) as CVODE's own; a direction's sensitivities
 * 1 / (rtol max_j |s_j| + atol_i), on the largest of the direction (its components cross zero
 * where the others are large: on |s_j| alone such a component would ask for atol where the
 * direction's error is measured against its size); all times sqrt(1 + ns) (d->wboost). CVODE's
 * error test ||e||_WRMS <= 1 over the ny (1 + ns) values is then
 *     ||e_y||^2 + sum_k ||e_(s_k)||^2 <= 1
 * in the blocks' own WRMS norms: the states as strict as in the plain run and each direction
 * within its tolerance (CVODES's errconS takes the largest block norm; this sum is at most
 * sqrt(1 + ns) stricter). Without errcon the sensitivities' atol is 1e300: the test of the plain
 * run. Returns -1 (CVODE's error) where a weight is not positive. */
static int sens_ewt(N_Vector y, N_Vector ewt, void *data)
{
    sens_data *d = (sens_data *)data;
    const double *yv = N_VGetArrayPointer(y);
    double *w = N_VGetArrayPointer(ewt);
    const long ny = d->m->ny;
    long i, j;
    int k;

    for (i = 0; i < ny; ++i) {
        double den = d->rtol * fabs(yv[i]) + d->atol[i];
        if (!(den > 0.0))
            return -1;
        w[i] = d->wboost / den;
    }
    for (k = 0; k < d->ns; ++k) {
        const long b = ny * (1 + k);
        double scale = 0.0;
        for (j = 0; j < ny; ++j)
            scale = fmax(scale, fabs(yv[b + j]));
        for (j = 0; j < ny; ++j) {
            double den = d->rtol * scale + d->atol[b + j];
            if (!(den > 0.0))
                return -1;
            w[b + j] = d->wboost / den;
        }
    }
    return 0;
}

/* The error weights (sens_ewt) on CVODE's memory mem of the run d with the options opt. */
static int sens_tolerances(sens_data *d, void *mem, const lcg_cvsens_options *opt)
{
    d->rtol = opt->rtol;
    d->atol = opt->atol;
    d->wboost = sqrt(1.0 + d->ns);
    return CVodeWFtolerances(mem, sens_ewt);
}

static int aug_rhs(sunrealtype t, N_Vector y, N_Vector ydot, void *data)
{
    sens_data *d = (sens_data *)data;
    const int ny = d->m->ny;
    double *yv = N_VGetArrayPointer(y), *fv = N_VGetArrayPointer(ydot);
    if (WATCH_TICK(&d->w))
        return -1; /* stop: cancelled or out of time */
    return model_status(d, d->sens_rhs(t, yv, params_at(d, t), d->ns, d->which, yv + ny, fv, fv + ny), t);
}

/* CVRootFn: the event functions at the state part of the augmented vector. */
static int sens_roots(sunrealtype t, N_Vector y, sunrealtype *gout, void *data)
{
    sens_data *d = (sens_data *)data;
    int rc = d->ev->roots(t, N_VGetArrayPointer(y), params_at(d, t), gout);

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

/* CVProjFn: corr = P(ycur) - ycur for the projection of the states and sensitivities; err (if
 * not NULL) replaced by its linearized projection. */
static int aug_proj(sunrealtype t, N_Vector ycur, N_Vector corr, sunrealtype epsProj, N_Vector err, void *data)
{
    sens_data *d = (sens_data *)data;
    const double *y = N_VGetArrayPointer(ycur);
    double *c = N_VGetArrayPointer(corr);
    long i, total = (long)d->m->ny * (1 + d->ns);
    int rc;
    (void)epsProj;

    rc = d->project(t, y, params_at(d, t), d->ns, d->which, d->ynew, err != NULL ? N_VGetArrayPointer(err) : NULL);
    if (rc != LCG_OK)
        return model_status(d, rc, t);
    for (i = 0; i < total; ++i)
        c[i] = d->ynew[i] - y[i];
    return 0;
}

/* J = df/dy at (t, y): the model's dense or sparse Jacobian, else forward differences. */
static int states_jacobian(sens_data *d, double t, const double *y)
{
    const lcg_model *m = d->m;
    const int ny = m->ny;
    const double *p = params_at(d, t);
    int rc, i, j, k;

    if ((rc = m->rhs(t, y, p, d->f0)) != LCG_OK)
        return rc;
    d->st->njac++;
    if (d->jacobian && m->jac != NULL)
        return m->jac(t, y, d->f0, p, d->J);
    if (d->jacobian && m->jac_sparse != NULL) {
        if ((rc = m->jac_sparse(t, y, d->f0, p, d->vals)) != LCG_OK)
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
        rc = m->rhs(t, d->y1, p, d->f1);
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

/* ---- The staggered corrector: a SUNNonlinearSolver of this file (CVODES's CV_STAGGERED). ----
 * Per step, the Newton iteration converges on the states alone (the model table's right-hand
 * side, with CVODE's convergence test on the states' weights), then the sensitivities, linear in
 * s, are corrected with the same matrix: one evaluation of <prefix>_sens_rhs at the converged
 * state, more only when the convergence test asks for it (a stale matrix). The matrix follows the
 * rules of CVODE's own Newton solver with its dense linear solver, as in the plain run: a new
 * factorization of I - gamma J when gamma moved by more than 30 % since the last one, every 20
 * steps and after a failure (crate, the convergence rate, kept across steps); a new Jacobian on
 * the first step, every 51 steps and after a convergence failure. The sensitivities' rate
 * (crate_s, in the same test with weights of the states' tolerances) is kept across new matrices
 * too: their iteration is linear, and a fresh matrix only makes it contract faster. CVODE's error
 * test still sees the whole augmented correction.
 *
 * SUNDIALS 7.x (sundials_nonlinearsolver.h, 7.9's operations table of 18 entries) declared here
 * as for the linear solver above, and checked before use: every operation CVODE calls is called
 * once through SUNDIALS's own dispatch and must land on this file's; another layout ends the run
 * with LCG_FLAG_BAD_INPUT and a message. */
#define LCG_NLS_ROOTFIND 0   /* SUNNONLINEARSOLVER_ROOTFIND */
#define LCG_NLS_CONTINUE 901 /* SUN_NLS_CONTINUE */
#define LCG_NLS_CONV_RECVR 902 /* SUN_NLS_CONV_RECVR */
#define LCG_CV_RHSFUNC_FAIL (-8)
#define LCG_CV_RHSFUNC_RECVR 10
#define LCG_NLS_MAXCOR 3
#define LCG_NLS_CRDOWN 0.3
#define LCG_NLS_RDIV 2.0
#define LCG_NLS_MSBP 20      /* steps between factorizations (CVODE's msbp) */
#define LCG_NLS_DGMAX 0.3    /* |gamma/gammap - 1| that asks for a factorization (dgmax_lsetup) */
#define LCG_NLS_DGMAX_JBAD 0.2
typedef int (*lcg_nls_fn)(void);
typedef struct lcg_nls_ops {
    int (*gettype)(SUNNonlinearSolver);
    int (*initialize)(SUNNonlinearSolver);
    int (*setup)(SUNNonlinearSolver, N_Vector, void *);
    int (*solve)(SUNNonlinearSolver, N_Vector, N_Vector, N_Vector, double, int, void *);
    int (*free)(SUNNonlinearSolver);
    int (*setsysfn)(SUNNonlinearSolver, lcg_nls_fn);
    int (*setsysfns)(SUNNonlinearSolver, lcg_nls_fn, lcg_nls_fn);
    int (*setlsetupfn)(SUNNonlinearSolver, lcg_nls_fn);
    int (*setlsolvefn)(SUNNonlinearSolver, lcg_nls_fn);
    int (*setctestfn)(SUNNonlinearSolver, lcg_nls_fn, void *);
    int (*setnormfn)(SUNNonlinearSolver, lcg_nls_fn);
    int (*setgetupdatenormfn)(SUNNonlinearSolver, lcg_nls_fn);
    int (*setgetconvratefn)(SUNNonlinearSolver, lcg_nls_fn);
    int (*setoptions)(SUNNonlinearSolver, const char *, const char *, int, char **);
    int (*setmaxiters)(SUNNonlinearSolver, int);
    int (*getnumiters)(SUNNonlinearSolver, long *);
    int (*getcuriter)(SUNNonlinearSolver, int *);
    int (*getnumconvfails)(SUNNonlinearSolver, long *);
} lcg_nls_ops;
typedef struct lcg_nls_object {
    void *content;
    void *reserved;
    lcg_nls_ops *ops;
    SUNContext sunctx;
} lcg_nls_object;

SUNNonlinearSolver SUNNonlinSolNewEmpty(SUNContext sunctx);
void SUNNonlinSolFreeEmpty(SUNNonlinearSolver NLS);
int SUNNonlinSolGetType(SUNNonlinearSolver NLS);
int SUNNonlinSolInitialize(SUNNonlinearSolver NLS);
int SUNNonlinSolSolve(SUNNonlinearSolver NLS, N_Vector y0, N_Vector y, N_Vector w, sunrealtype tol,
                      sunbooleantype callLSetup, void *mem);
int SUNNonlinSolSetSysFn(SUNNonlinearSolver NLS, lcg_nls_fn SysFn);
int SUNNonlinSolSetLSetupFn(SUNNonlinearSolver NLS, lcg_nls_fn SetupFn);
int SUNNonlinSolSetLSolveFn(SUNNonlinearSolver NLS, lcg_nls_fn SolveFn);
int SUNNonlinSolSetConvTestFn(SUNNonlinearSolver NLS, lcg_nls_fn CTestFn, void *ctest_data);
int SUNNonlinSolSetMaxIters(SUNNonlinearSolver NLS, int maxiters);
int SUNNonlinSolGetNumIters(SUNNonlinearSolver NLS, long *niters);
int SUNNonlinSolGetCurIter(SUNNonlinearSolver NLS, int *iter);
int SUNNonlinSolGetNumConvFails(SUNNonlinearSolver NLS, long *nconvfails);
int CVodeGetNumErrTestFails(void *cvode_mem, long int *netfails);

#define NLS_DATA(S) ((sens_data *)((lcg_nls_object *)(S))->content)
/* An operation of the table: while the layout is checked (d->probe), it records its place k. */
#define NLS_PROBE(S, k)                      \
    do {                                     \
        sens_data *d_ = NLS_DATA(S);         \
        if (d_ != NULL && d_->probe) {       \
            d_->probe_hit = (k);             \
            return 0;                        \
        }                                    \
    } while (0)

static int nls_type(SUNNonlinearSolver S)
{
    sens_data *d = NLS_DATA(S);
    if (d != NULL && d->probe) {
        d->probe_hit = 1;
        return 77; /* an answer the check recognizes */
    }
    return LCG_NLS_ROOTFIND;
}
static int nls_initialize(SUNNonlinearSolver S) { NLS_PROBE(S, 2); return 0; }
static int nls_free(SUNNonlinearSolver S) { NLS_PROBE(S, 5); return 0; }
/* CVODE's residual, linear solver and convergence test: this solver evaluates its own. */
static int nls_setsysfn(SUNNonlinearSolver S, lcg_nls_fn f) { (void)f; NLS_PROBE(S, 6); return 0; }
static int nls_setsysfns(SUNNonlinearSolver S, lcg_nls_fn f, lcg_nls_fn g) { (void)f; (void)g; NLS_PROBE(S, 7); return 0; }
static int nls_setlsetupfn(SUNNonlinearSolver S, lcg_nls_fn f) { (void)f; NLS_PROBE(S, 8); return 0; }
static int nls_setlsolvefn(SUNNonlinearSolver S, lcg_nls_fn f) { (void)f; NLS_PROBE(S, 9); return 0; }
static int nls_setctestfn(SUNNonlinearSolver S, lcg_nls_fn f, void *data) { (void)f; (void)data; NLS_PROBE(S, 10); return 0; }
static int nls_setnormfn(SUNNonlinearSolver S, lcg_nls_fn f) { (void)f; NLS_PROBE(S, 11); return 0; }
static int nls_setupdnormfn(SUNNonlinearSolver S, lcg_nls_fn f) { (void)f; NLS_PROBE(S, 12); return 0; }
static int nls_setconvratefn(SUNNonlinearSolver S, lcg_nls_fn f) { (void)f; NLS_PROBE(S, 13); return 0; }
static int nls_setoptions(SUNNonlinearSolver S, const char *id, const char *file, int argc, char **argv)
{
    (void)id; (void)file; (void)argc; (void)argv;
    NLS_PROBE(S, 14);
    return 0;
}
/* CVODE's NLS_MAXCOR (3) is this solver's own. */
static int nls_setmaxiters(SUNNonlinearSolver S, int maxiters) { (void)maxiters; NLS_PROBE(S, 15); return 0; }
/* The iterations and convergence failures of the last solve (CVODE adds them to its counters). */
static int nls_getnumiters(SUNNonlinearSolver S, long *n)
{
    NLS_PROBE(S, 16);
    *n = NLS_DATA(S)->nls_iters;
    return 0;
}
static int nls_getcuriter(SUNNonlinearSolver S, int *n)
{
    NLS_PROBE(S, 17);
    *n = 0;
    return 0;
}
static int nls_getnumconvfails(SUNNonlinearSolver S, long *n)
{
    NLS_PROBE(S, 18);
    *n = NLS_DATA(S)->nls_fails;
    return 0;
}

/* A CVODE flag of a model status (model_status: 0 ok, > 0 recoverable, < 0 stop). */
static int nls_flag(int status)
{
    return status == 0 ? 0 : status > 0 ? LCG_CV_RHSFUNC_RECVR : LCG_CV_RHSFUNC_FAIL;
}

/* f = the states' right-hand side at (t, y). */
static int nls_states_rhs(sens_data *d, double t, const double *y, double *f)
{
    if (WATCH_TICK(&d->w))
        return LCG_CV_RHSFUNC_FAIL; /* stop: cancelled or out of time */
    d->nrhs_states++;
    return nls_flag(model_status(d, d->m->rhs(t, y, params_at(d, t), f), t));
}

/* d->Ainv = (I - gamma J)^-1 from the factors in d->A, column by column: a block's solve is then
 * one matrix-vector product (the factorization is refreshed every few steps, the solves are made
 * 1 + ns times per iteration). */
static void inverse(sens_data *d)
{
    const int n = d->m->ny;
    int i, j;

    for (j = 0; j < n; ++j) {
        double *col = d->Ainv + (long)j * n;
        for (i = 0; i < n; ++i)
            col[i] = i == j ? 1.0 : 0.0;
        lu_solve(d, col);
    }
}

/* The matrix by CVODE's rules (cvLsSetup): the states' Jacobian at the predicted state y (anew
 * when jbad), I - gamma J factored. 0, or a CVODE flag (LCG_NLS_CONV_RECVR if singular). */
static int nls_setup(sens_data *d, double t, const double *y, double gamma, long nst, int jbad, int *jcur)
{
    int rc;

    *jcur = 0;
    if (jbad || !d->have_J) {
        rc = states_jacobian(d, t, y);
        if (rc != LCG_OK)
            return nls_flag(model_status(d, rc, t));
        d->have_J = 1;
        d->nst_J = nst;
        *jcur = 1;
    }
    d->nsetups++;
    d->gammap = gamma;
    d->crate = 1.0;
    d->nstlp = nst;
    d->have_A = factor(d, gamma) == 0;
    if (!d->have_A) {
        d->have_J = 0;
        return LCG_NLS_CONV_RECVR;
    }
    inverse(d);
    return 0;
}

/* b = A^-1 b for one block, scaled for the gamma of the step as CVODE's dense solver does (BDF). */
static void nls_lsolve(sens_data *d, double *b, double gamma)
{
    const int n = d->m->ny;
    const double gamrat = gamma / d->gammap, scale = d->bdf && gamrat != 1.0 ? 2.0 / (1.0 + gamrat) : 1.0;
    double *x = d->xtmp;
    int i, j;

    for (i = 0; i < n; ++i)
        x[i] = 0.0;
    for (j = 0; j < n; ++j) {
        const double bj = scale * b[j], *col = d->Ainv + (long)j * n;
        for (i = 0; i < n; ++i)
            x[i] += bj * col[i];
    }
    for (i = 0; i < n; ++i)
        b[i] = x[i];
    d->st->nblock_solves++;
}

static double nls_wrms(const double *x, const double *w, long n)
{
    double sum = 0.0;
    long i;

    for (i = 0; i < n; ++i)
        sum += (x[i] * w[i]) * (x[i] * w[i]);
    return sqrt(sum / (double)n);
}

/* One convergence test of CVODE's (cvNlsConvTest) on the correction of norm del at iteration m
 * (0 first) with the rate *crate and the last norm *delp: 0 converged, LCG_NLS_CONTINUE, or
 * LCG_NLS_CONV_RECVR (diverging). */
static int nls_test(double del, int m, double tol, double *crate, double *delp)
{
    if (m > 0)
        *crate = fmax(LCG_NLS_CRDOWN * *crate, del / *delp);
    if (del * fmin(1.0, *crate) / tol <= 1.0)
        return 0;
    if (m >= 1 && del > LCG_NLS_RDIV * *delp)
        return LCG_NLS_CONV_RECVR;
    *delp = del;
    return LCG_NLS_CONTINUE;
}

/* The states' Newton iteration from c = 0 (c: their correction to the predicted ypred). */
static int nls_states(sens_data *d, double t, const double *ypred, const double *zn1, const double *w, double *c,
                      double gamma, double rl1, double tol, int *setup, int *jbad, long nst, int *jcur)
{
    const int ny = d->m->ny;
    double *y = d->ytmp, *f = d->ftmp, *delta = d->f1, del, delp = 0.0;
    int i, m, flag;

    for (i = 0; i < ny; ++i) {
        c[i] = 0.0;
        y[i] = ypred[i];
    }
    if ((flag = nls_states_rhs(d, t, y, f)) != 0)
        return flag;
    if (*setup) {
        flag = nls_setup(d, t, y, gamma, nst, *jbad, jcur);
        *setup = 0;
        if (flag != 0)
            return flag;
    }
    for (m = 0;; ++m) {
        d->nls_iters++;
        for (i = 0; i < ny; ++i)
            delta[i] = -(rl1 * zn1[i] + c[i] - gamma * f[i]);
        nls_lsolve(d, delta, gamma);
        for (i = 0; i < ny; ++i)
            c[i] += delta[i];
        del = nls_wrms(delta, w, ny) / d->wboost;
        flag = nls_test(del, m, tol, &d->crate, &delp);
        if (flag != LCG_NLS_CONTINUE)
            return flag;
        if (m + 1 >= LCG_NLS_MAXCOR)
            return LCG_NLS_CONV_RECVR;
        for (i = 0; i < ny; ++i)
            y[i] = ypred[i] + c[i];
        if ((flag = nls_states_rhs(d, t, y, f)) != 0)
            return flag;
    }
}

/* The sensitivities' iteration from cs = 0 at the converged state ypred + c (cs: their
 * correction, ny ns values after the states'). Its weights: those of CVODE's error test (ewt,
 * after the states') when the sensitivities are in it (errcon, CVODES's ewtS), else from the
 * predicted sensitivities and the states' tolerances. */
static int nls_sens(sens_data *d, double t, const double *ypred, const double *zn1, const double *ewt,
                    const double *c, double *cs, double gamma, double rl1, double tol)
{
    const int ny = d->m->ny;
    const long nsy = (long)ny * d->ns;
    double *y = d->ytmp, *s = d->ytmp + ny, *delta = d->ftmp + ny, del, delp = 0.0;
    const double *w = d->errcon ? ewt + ny : d->wsens;
    const double wscale = d->errcon ? d->wboost : 1.0; /* the weights of sens_ewt without their factor */
    long i;
    int j, m, flag;

    for (i = 0; i < ny; ++i)
        y[i] = ypred[i] + c[i];
    for (i = 0; i < nsy; ++i)
        cs[i] = 0.0;
    if (!d->errcon)
        for (i = 0; i < nsy; ++i)
            d->wsens[i] = 1.0 / (d->rtol * fabs(ypred[ny + i]) + d->atol[i % ny]);
    for (m = 0;; ++m) {
        if (WATCH_TICK(&d->w))
            return LCG_CV_RHSFUNC_FAIL; /* stop: cancelled or out of time */
        for (i = 0; i < nsy; ++i)
            s[i] = ypred[ny + i] + cs[i];
        d->nrhs_sens++;
        d->nsens_iters++;
        flag = nls_flag(model_status(d, d->sens_rhs(t, y, params_at(d, t), d->ns, d->which, s, d->ftmp, delta), t));
        if (flag != 0)
            return flag;
        for (i = 0; i < nsy; ++i)
            delta[i] = -(rl1 * zn1[ny + i] + cs[i] - gamma * delta[i]);
        for (j = 0; j < d->ns; ++j)
            nls_lsolve(d, delta + (long)j * ny, gamma);
        for (i = 0; i < nsy; ++i)
            cs[i] += delta[i];
        del = nls_wrms(delta, w, nsy) / wscale;
        flag = nls_test(del, m, tol, &d->crate_s, &delp);
        if (flag != LCG_NLS_CONTINUE)
            return flag;
        if (m + 1 >= LCG_NLS_MAXCOR)
            return LCG_NLS_CONV_RECVR;
    }
}

/* SUNNonlinSolSolve: the correction c (= ycor, zero on entry) of the augmented state from the
 * prediction ypred, with CVODE's data of the step (CVodeGetNonlinearSystemData); the states
 * first, then the sensitivities. Decides on a new matrix as CVODE's cvNls and cvLsSetup do
 * (callLSetup is always false here: CVODE has no linear solver to set up). */
static int nls_solve(SUNNonlinearSolver S, N_Vector y0, N_Vector ycor, N_Vector wv, double tol, int callLSetup,
                     void *mem)
{
    sens_data *d = NLS_DATA(S);
    const int ny = d->m->ny;
    double t, gamma, rl1, *ypred, *c, *zn1, *w;
    N_Vector vpred, vyn, vfn, vzn1;
    void *ud;
    long nst = 0, netf = 0;
    int setup, jbad, jcur = 0, flag, other;
    (void)callLSetup;
    (void)mem;

    if (d->probe) {
        d->probe_hit = 4;
        return 0;
    }
    d->nls_iters = d->nls_fails = 0;
    if (CVodeGetNonlinearSystemData(d->mem, &t, &vpred, &vyn, &vfn, &gamma, &rl1, &vzn1, &ud) != 0)
        return LCG_CV_RHSFUNC_FAIL;
    ypred = N_VGetArrayPointer(y0);
    c = N_VGetArrayPointer(ycor);
    zn1 = N_VGetArrayPointer(vzn1);
    w = N_VGetArrayPointer(wv);
    CVodeGetNumSteps(d->mem, &nst);
    CVodeGetNumErrTestFails(d->mem, &netf);
    /* CVODE's cvNls: a new matrix after a failure of either kind, on the first step, every
     * LCG_NLS_MSBP steps and when gamma moved; the Jacobian (cvLsSetup) after a convergence
     * failure, on the first step and every LCG_CVSENS_MSBJ steps */
    other = d->last_failed;
    setup = !d->have_A || other || netf > d->netf_seen || nst == 0 || nst >= d->nstlp + LCG_NLS_MSBP
            || fabs(gamma / d->gammap - 1.0) > LCG_NLS_DGMAX;
    jbad = nst == 0 || nst >= d->nst_J + LCG_CVSENS_MSBJ || other;
    d->netf_seen = netf;
    for (;;) {
        flag = nls_states(d, t, ypred, zn1, w, c, gamma, rl1, tol, &setup, &jbad, nst, &jcur);
        if (flag == 0 && d->ns > 0)
            flag = nls_sens(d, t, ypred, zn1, w, c, c + ny, gamma, rl1, tol);
        if (flag == 0) {
            d->last_failed = 0;
            return 0;
        }
        d->nls_fails++;
        if (flag != LCG_NLS_CONV_RECVR || jcur || !d->have_A)
            break;
        /* not converged with an old Jacobian: a new one (CVODE's Newton solver retries so,
         * jbad when gamma is near the matrix's) and the whole correction again */
        setup = 1;
        jbad = nst == 0 || nst >= d->nst_J + LCG_CVSENS_MSBJ || fabs(gamma / d->gammap - 1.0) < LCG_NLS_DGMAX_JBAD;
    }
    d->last_failed = flag > 0;
    return flag;
}

/* The corrector's matrices and the step counts they were made at, for CVODE starting afresh
 * (CVodeReInit resets its step and failure counters; the inputs may have changed J): the next
 * solve evaluates J and factors anew. Its own counters go on. */
static void corrector_restart(sens_data *d)
{
    d->have_J = d->have_A = 0;
    d->gamma = d->gammap = 0.0;
    d->crate = d->crate_s = 1.0;
    d->nstlp = d->netf_seen = 0;
    d->last_failed = 0;
}

/* The corrector's state and counters for a new run (or a restart of the stepper). */
static void corrector_reset(sens_data *d)
{
    corrector_restart(d);
    d->nsetups = d->nsens_iters = d->nrhs_states = d->nrhs_sens = 0;
}

/* A function to hand to the setters while the layout is checked (never called). */
static int nls_dummy(void) { return 0; }

/* The staggered solver on the empty solver NLS of the context ctx, solving for d: its layout
 * checked (the context in its place; each operation CVODE uses reached through SUNDIALS's
 * dispatch). 0, or LCG_FLAG_BAD_INPUT with the reason in message. */
static int nls_attach(SUNNonlinearSolver NLS, SUNContext ctx, sens_data *d, char *message, size_t size)
{
    lcg_nls_object *obj = (lcg_nls_object *)NLS;
    lcg_nls_ops *ops;
    long n = 0;
    int k = 0, ok;

    if (obj->sunctx != ctx || obj->ops == NULL) {
        snprintf(message, size, "the SUNDIALS %s nonlinear solver object has another layout than "
                 "the sensitivity driver's (SUNDIALS 7.9)", LCG_SUNDIALS_VERSION);
        return LCG_FLAG_BAD_INPUT;
    }
    ops = obj->ops;
    obj->content = d;
    ops->gettype = nls_type;
    ops->initialize = nls_initialize;
    ops->setup = NULL; /* CVODE calls a setup only if there is one */
    ops->solve = nls_solve;
    ops->free = nls_free;
    ops->setsysfn = nls_setsysfn;
    ops->setsysfns = nls_setsysfns;
    ops->setlsetupfn = nls_setlsetupfn;
    ops->setlsolvefn = nls_setlsolvefn;
    ops->setctestfn = nls_setctestfn;
    ops->setnormfn = nls_setnormfn;
    ops->setgetupdatenormfn = nls_setupdnormfn;
    ops->setgetconvratefn = nls_setconvratefn;
    ops->setoptions = nls_setoptions;
    ops->setmaxiters = nls_setmaxiters;
    ops->getnumiters = nls_getnumiters;
    ops->getcuriter = nls_getcuriter;
    ops->getnumconvfails = nls_getnumconvfails;
    d->probe = 1;
    ok = SUNNonlinSolGetType(NLS) == 77 && d->probe_hit == 1;
#define NLS_CHECK(call, place) (d->probe_hit = 0, (void)(call), d->probe_hit == (place))
    ok = ok && NLS_CHECK(SUNNonlinSolInitialize(NLS), 2);
    ok = ok && NLS_CHECK(SUNNonlinSolSolve(NLS, NULL, NULL, NULL, 1.0, 0, NULL), 4);
    ok = ok && NLS_CHECK(SUNNonlinSolSetSysFn(NLS, nls_dummy), 6);
    ok = ok && NLS_CHECK(SUNNonlinSolSetLSetupFn(NLS, nls_dummy), 8);
    ok = ok && NLS_CHECK(SUNNonlinSolSetLSolveFn(NLS, nls_dummy), 9);
    ok = ok && NLS_CHECK(SUNNonlinSolSetConvTestFn(NLS, nls_dummy, d), 10);
    ok = ok && NLS_CHECK(SUNNonlinSolSetMaxIters(NLS, LCG_NLS_MAXCOR), 15);
    ok = ok && NLS_CHECK(SUNNonlinSolGetNumIters(NLS, &n), 16);
    ok = ok && NLS_CHECK(SUNNonlinSolGetCurIter(NLS, &k), 17);
    ok = ok && NLS_CHECK(SUNNonlinSolGetNumConvFails(NLS, &n), 18);
#undef NLS_CHECK
    d->probe = 0;
    if (!ok) {
        obj->content = NULL;
        snprintf(message, size, "the SUNDIALS %s nonlinear solver operations have another layout "
                 "than the sensitivity driver's (SUNDIALS 7.9)", LCG_SUNDIALS_VERSION);
        return LCG_FLAG_BAD_INPUT;
    }
    return 0;
}

/* The corrector that opt chooses (opt->corrector: LCG_CVSENS_STAGGERED, this file's nonlinear
 * solver; LCG_CVSENS_SIMULTANEOUS, CVODE's Newton solver with this file's block linear solver)
 * on d's CVODE memory, after CVodeInit: *LS or *NLS made in the context ctx (free them with
 * corrector_free after CVodeFree). 0, or a negative flag (LCG_FLAG_BAD_INPUT with the reason in
 * message, LCG_FLAG_NOMEM, or CVODE's). */
static int corrector_attach(sens_data *d, const lcg_cvsens_options *opt, SUNContext ctx, SUNLinearSolver *LS,
                            SUNNonlinearSolver *NLS, char *message, size_t size)
{
    const long total = (long)d->m->ny * (1 + d->ns);
    int flag;

    d->staggered = opt->corrector != LCG_CVSENS_SIMULTANEOUS;
    d->bdf = opt->method == CV_BDF;
    d->errcon = d->ns > 0 && opt->atol[d->m->ny] < 1e200; /* sens_options: 1e300 without errcon */
    corrector_reset(d);
    if (!d->staggered) {
        if ((*LS = SUNLinSolNewEmpty(ctx)) == NULL)
            return LCG_FLAG_NOMEM;
        if ((flag = ls_attach(*LS, ctx, d, message, size)) < 0)
            return flag;
        return CVodeSetLinearSolver(d->mem, *LS, NULL);
    }
    d->ytmp = (double *)malloc(sizeof(double) * (size_t)total);
    d->ftmp = (double *)malloc(sizeof(double) * (size_t)total);
    d->wsens = (double *)malloc(sizeof(double) * (size_t)(total - d->m->ny + 1));
    d->Ainv = (double *)malloc(sizeof(double) * (size_t)d->m->ny * (size_t)d->m->ny);
    d->xtmp = (double *)malloc(sizeof(double) * (size_t)d->m->ny);
    if (d->ytmp == NULL || d->ftmp == NULL || d->wsens == NULL || d->Ainv == NULL || d->xtmp == NULL
        || (*NLS = SUNNonlinSolNewEmpty(ctx)) == NULL)
        return LCG_FLAG_NOMEM;
    if ((flag = nls_attach(*NLS, ctx, d, message, size)) < 0)
        return flag;
    return CVodeSetNonlinearSolver(d->mem, *NLS);
}

/* The statistics of the corrector into st, after CVODE's own: the staggered one's setups, its
 * evaluations of the states' and the sensitivities' right-hand sides and its sensitivity iterations. */
static void corrector_stats(const sens_data *d, lcg_cvsens_stats *st)
{
    if (!d->staggered)
        return;
    st->nlinsetups = d->nsetups;
    st->nrhs += d->nrhs_sens;
    st->nrhs_states = d->nrhs_states;
    st->nsens_iters = d->nsens_iters;
}

/* Free what corrector_attach made (after CVodeFree). */
static void corrector_free(sens_data *d, SUNLinearSolver LS, SUNNonlinearSolver NLS)
{
    if (LS != NULL) {
        ((lcg_ls_object *)LS)->content = NULL;
        SUNLinSolFreeEmpty(LS);
    }
    if (NLS != NULL) {
        ((lcg_nls_object *)NLS)->content = NULL;
        SUNNonlinSolFreeEmpty(NLS);
    }
    free(d->ytmp);
    free(d->ftmp);
    free(d->wsens);
    free(d->Ainv);
    free(d->xtmp);
    d->ytmp = d->ftmp = d->wsens = d->Ainv = d->xtmp = NULL;
}

/* Add CVODE's counters since its last (re)initialization to st's. */
static void add_counts(void *mem, lcg_cvsens_stats *st)
{
    LCG_ADD_CVODE_COUNTS(mem, st);
}

/* b within rounding of a (a <= b): CVODE cannot step from a to b. */
static int too_close(double a, double b)
{
    return b - a <= 4.0 * DBL_EPSILON * (fabs(a) > fabs(b) ? fabs(a) : fabs(b));
}

/* CVode towards target, the root returns of the events on the way recorded into d->ev and stepped
 * over, within the step budget of the whole run (restarts included): a negative flag (-1: the
 * budget used up), ADVANCE_TERMINAL at a terminal event (its time in *tret), or 0. */
#define ADVANCE_TERMINAL 1
static int advance(sens_data *d, const lcg_cvsens_options *opt, double target, N_Vector y, double *tret,
                   long total)
{
    lcg_cvsens_stats *st = d->st;
    long nst = 0;
    int flag;

    for (;;) {
        CVodeGetNumSteps(d->mem, &nst);
        nst += d->nst_done;
        if (nst >= opt->max_steps) {
            snprintf(st->message, sizeof st->message, "the step budget max_steps = %ld is used up before t = %.17g",
                     opt->max_steps, target);
            return -1;
        }
        CVodeSetMaxNumSteps(d->mem, opt->max_steps - nst);
        flag = CVode(d->mem, target, y, tret, CV_NORMAL);
        st->t_reached = *tret;
        if (flag == CV_ROOT_RETURN && d->ev != NULL) {
            if (sens_record(d, *tret, d->key, N_VGetArrayPointer(y), total))
                return ADVANCE_TERMINAL;
            continue;
        }
        return flag < 0 ? flag : 0;
    }
}

/* At the restart time *tb the run has reached (augmented state y): start afresh there on the
 * inputs' next pieces (the history of the multistep method ends at a jump or kink of an input;
 * the sensitivities go on from their values), with the stop time at the next restart time or
 * tend. CVODE's counters so far go to st (CVodeReInit resets them). */
static int restart_at(sens_data *d, N_Vector y, double *tb, double tend)
{
    long nst = 0;
    int flag;

    CVodeGetNumSteps(d->mem, &nst);
    d->nst_done += nst;
    add_counts(d->mem, d->st);
    d->key = *tb;
    if ((flag = CVodeReInit(d->mem, *tb, y)) < 0)
        return flag;
    corrector_restart(d);
    *tb = d->tb = lcg_inputs_next_break(d->in, *tb);
    return CVodeSetStopTime(d->mem, *tb < tend ? *tb : tend);
}

/* The inputs of a run (NULL: none) checked against the model and the directions (none along an
 * input's slot: the input is a given signal), its copy of p made: 0, or a negative flag with the
 * reason in st->message. */
static int inputs_init(sens_data *d, const lcg_inputs *in, const double *p, lcg_cvsens_stats *st)
{
    const lcg_model *m = d->m;
    int a, j, i;

    d->in = in;
    d->tb = HUGE_VAL;
    if (in == NULL)
        return 0;
    if (lcg_inputs_check(in, m->np, st->message, sizeof st->message) != 0)
        return LCG_FLAG_BAD_INPUT;
    for (j = 0; j < d->ns; ++j)
        for (a = 0; a < in->count; ++a)
            if (d->which[j] == in->tables[a].slot) {
                snprintf(st->message, sizeof st->message, "sensitivity direction %d is along run-time parameter "
                         "%d, which input table %d sets (an input is a given signal)", j, d->which[j], a);
                return LCG_FLAG_BAD_INPUT;
            }
    if ((d->pin = (double *)malloc(sizeof(double) * (size_t)(m->np > 0 ? m->np : 1))) == NULL)
        return LCG_FLAG_NOMEM;
    for (i = 0; i < m->np; ++i)
        d->pin[i] = p[i];
    return 0;
}

/* The outputs and their sensitivities at (t, yv) into out and dout (nothing without outputs). */
static int outputs_at(sens_data *d, lcg_sens_out_fn sens_out, double t, const double *yv, double *out, double *dout)
{
    const lcg_model *m = d->m;
    const double *p;
    int rc;

    if (m->outputs == NULL)
        return LCG_OK;
    p = d->in == NULL ? d->p : (lcg_inputs_apply(d->in, t, 0, d->pin), d->pin); /* u at the output time */
    if ((rc = m->outputs(t, yv, p, out)) != LCG_OK)
        return rc;
    if (sens_out != NULL && m->nout > 0)
        return sens_out(t, yv, p, d->ns, d->which, yv + m->ny, dout);
    return LCG_OK;
}

/* The run of lcg_cvsens_solve_events with the input tables in (NULL: none); see lcg_cvsens.h. */
static int solve(const lcg_model *m, lcg_sens_rhs_fn sens_rhs, lcg_sens_out_fn sens_out, const double *p,
                 const lcg_inputs *in, int ns, const int *which, const double *y0, const double *s0, int nt,
                 const double *tout, double *yout, double *sout, double *out, double *dout,
                 const lcg_cvsens_options *opt, lcg_cvsens_stats *st, lcg_cvsens_events *ev)
{
    SUNContext ctx = NULL;
    void *mem = NULL;
    N_Vector y = NULL;
    SUNLinearSolver LS = NULL;
    SUNNonlinearSolver NLS = NULL;
    sens_data data;
    double *yv;
    double tb = HUGE_VAL; /* inputs: the next restart time */
    long total;
    int k, i, flag = 0, rc, ny, restart = in != NULL && in->nbreak > 0;

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
    data.key = tout[0];
    watch_init(&data.w, NULL, opt->poll, opt->poll_data, opt->poll_every, opt->max_wall, nt, &st->nt_done);
    LCG_CREATE_CONTEXT(LCG_FLAG_NOMEM);
    if ((flag = inputs_init(&data, in, p, st)) < 0)
        goto done;
    if (in != NULL)
        tb = lcg_inputs_next_break(in, tout[0]);

    data.J = (double *)malloc(sizeof(double) * (size_t)ny * (size_t)ny);
    data.A = (double *)malloc(sizeof(double) * (size_t)ny * (size_t)ny);
    data.piv = (int *)malloc(sizeof(int) * (size_t)ny);
    data.f0 = (double *)malloc(sizeof(double) * (size_t)ny);
    data.f1 = (double *)malloc(sizeof(double) * (size_t)ny);
    data.y1 = (double *)malloc(sizeof(double) * (size_t)ny);
    data.vals = (double *)malloc(sizeof(double) * (size_t)(m->jac_nnz > 0 ? m->jac_nnz : 1));
    data.project = opt->project;
    if (data.project != NULL && (data.ynew = (double *)malloc(sizeof(double) * (size_t)total)) == NULL) {
        flag = LCG_FLAG_NOMEM;
        goto done;
    }
    y = N_VNew_Serial((sunindextype)total, ctx);
    mem = CVodeCreate(opt->method, ctx);
    if (data.J == NULL || data.A == NULL || data.piv == NULL || data.f0 == NULL || data.f1 == NULL
        || data.y1 == NULL || data.vals == NULL || y == NULL || mem == NULL) {
        flag = LCG_FLAG_NOMEM;
        goto done;
    }
    data.mem = mem;

    yv = N_VGetArrayPointer(y);
    for (i = 0; i < ny; ++i)
        yv[i] = yout[i] = y0[i];
    for (i = 0; i < ny * ns; ++i)
        yv[ny + i] = sout[i] = s0[i];
    rc = outputs_at(&data, sens_out, tout[0], yv, out, dout);
    LCG_MODEL_ERROR(LCG_OK);
    st->nt_done = 1;

    if ((flag = CVodeInit(mem, aug_rhs, tout[0], y)) < 0)
        goto done;
    CVodeSetUserData(mem, &data);
    if ((flag = sens_tolerances(&data, mem, opt)) < 0)
        goto done;
    if ((flag = corrector_attach(&data, opt, ctx, &LS, &NLS, st->message, sizeof st->message)) < 0)
        goto done;
    CVodeSetMaxHnilWarns(mem, -1);
    if (data.project != NULL) {
        if ((flag = CVodeSetProjFn(mem, aug_proj)) < 0)
            goto done;
        if ((flag = CVodeSetProjErrEst(mem, 1)) < 0)
            goto done;
    }
    if (opt->max_order > 0 && (flag = CVodeSetMaxOrd(mem, opt->max_order)) < 0)
        goto done;
    if (opt->first_step > 0 && (flag = CVodeSetInitStep(mem, opt->first_step)) < 0)
        goto done;
    if (opt->max_step > 0 && (flag = CVodeSetMaxStep(mem, opt->max_step)) < 0)
        goto done;
    if (opt->min_step > 0 && (flag = CVodeSetMinStep(mem, opt->min_step)) < 0)
        goto done;
    data.tb = tb;
    if (nt > 1 && (flag = CVodeSetStopTime(mem, tb < tout[nt - 1] ? tb : tout[nt - 1])) < 0)
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
        while (tb < tout[k]) { /* inputs with restarts: a restart time before the next output time */
            if (!too_close(data.key, tb) && (flag = advance(&data, opt, tb, y, &tret, total)) != 0)
                goto stop;
            if ((flag = restart_at(&data, y, &tb, tout[nt - 1])) < 0)
                goto done;
        }
        if (restart && too_close(data.key, tout[k]))
            tret = tout[k]; /* an output time a rounding error after the restart: the restart's state */
        else if ((flag = advance(&data, opt, tout[k], y, &tret, total)) != 0)
            goto stop;
        for (i = 0; i < ny; ++i)
            yout[(long)k * ny + i] = yv[i];
        for (i = 0; i < ny * ns; ++i)
            sout[(long)k * ny * ns + i] = yv[ny + i];
        rc = outputs_at(&data, sens_out, tret, yv, out + (long)k * m->nout, dout + (long)k * ns * m->nout);
        LCG_MODEL_ERROR(LCG_OK);
        st->nt_done = k + 1;
        if (tb == tout[k] && k < nt - 1 && (flag = restart_at(&data, y, &tb, tout[nt - 1])) < 0)
            goto done;
    }

stop:
    if (flag == ADVANCE_TERMINAL) { /* a terminal event: the run ends with the rows before it */
        ev->terminated = 1;
        flag = 0;
    }
done:
    flag = watch_flag(&data.w, flag, st->message, sizeof st->message);
    if (mem != NULL) {
        add_counts(mem, st);
        CVodeGetLastStep(mem, &st->h_last);
        corrector_stats(&data, st);
        if (flag < 0 && flag > LCG_FLAG_MODEL_ERROR && st->model_error == 0)
            CVodeGetCurrentTime(mem, &st->t_reached);
    }
    flag = lcg_nonfinite_flag(flag, data.nonfinite, data.t_nonfinite, &st->model_error, &st->t_reached);
    st->flag = flag;
    LCG_NOMEM_MESSAGE(LCG_FLAG_NOMEM, "CVODE");
    CVodeFree(&mem);
    corrector_free(&data, LS, NLS);
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
    free(data.ynew);
    free(data.pin);
    SUNContext_Free(&ctx);
    return flag < 0 ? flag : 0;
}

int lcg_cvsens_solve(const lcg_model *m, lcg_sens_rhs_fn sens_rhs, lcg_sens_out_fn sens_out, const double *p,
                     int ns, const int *which, const double *y0, const double *s0, int nt, const double *tout,
                     double *yout, double *sout, double *out, double *dout, const lcg_cvsens_options *opt,
                     lcg_cvsens_stats *st)
{
    return solve(m, sens_rhs, sens_out, p, NULL, ns, which, y0, s0, nt, tout, yout, sout, out, dout, opt, st, NULL);
}

int lcg_cvsens_solve_events(const lcg_model *m, lcg_sens_rhs_fn sens_rhs, lcg_sens_out_fn sens_out,
                            const double *p, int ns, const int *which, const double *y0, const double *s0, int nt,
                            const double *tout, double *yout, double *sout, double *out, double *dout,
                            const lcg_cvsens_options *opt, lcg_cvsens_stats *st, lcg_cvsens_events *ev)
{
    return solve(m, sens_rhs, sens_out, p, NULL, ns, which, y0, s0, nt, tout, yout, sout, out, dout, opt, st, ev);
}

int lcg_cvsens_solve_inputs(const lcg_model *m, lcg_sens_rhs_fn sens_rhs, lcg_sens_out_fn sens_out,
                            const double *p, const lcg_inputs *in, int ns, const int *which, const double *y0,
                            const double *s0, int nt, const double *tout, double *yout, double *sout, double *out,
                            double *dout, const lcg_cvsens_options *opt, lcg_cvsens_stats *st)
{
    return solve(m, sens_rhs, sens_out, p, in, ns, which, y0, s0, nt, tout, yout, sout, out, dout, opt, st, NULL);
}
