/* lcg_sundials.h -- the SUNDIALS plumbing shared by the native drivers (lcg_cvode.c, lcg_cvc.c,
 * lcg_ida.c, ...) and steppers: how SUNDIALS errors reach the caller's stats (record_error, the
 * context and its error handler), the solvers' shared setup (tolerances, step limits, IDA's
 * objects and options: ida_create, ida_init, ida_roots) and the drivers' flag conventions
 * (lcg_codes.h: LCG_FLAG_NOMEM out of memory, -1 step budget used up, LCG_MODEL_ERROR_FLAG(rc) a
 * model error).
 *
 * Included by a driver source after sundials_api.h, with LCG_STATS defined (its statistics type,
 * with a char message[]), and, for root finding, LCG_ROOT_INFO (CVodeGetRootInfo or
 * IDAGetRootInfo) and the events type lcg_events. The statement macros assume the drivers' local
 * names: st (the stats), flag, rc, mem, nst, opt, tout, k, ctx, and the label done. */
#ifndef LCG_SUNDIALS_H
#define LCG_SUNDIALS_H

#include <stdio.h>

#include "lcg_codes.h"

/* The SUNErrHandlerFn: the last SUNDIALS error message, into stats->message. */
static void record_error(int line, const char *func, const char *file, const char *msg,
                         SUNErrCode err_code, void *err_user_data, SUNContext sunctx)
{
    LCG_STATS *st = (LCG_STATS *)err_user_data;
    (void)line;
    (void)file;
    (void)sunctx;
    snprintf(st->message, sizeof st->message, "%s (code %d): %s", func ? func : "SUNDIALS",
             err_code, msg ? msg : "");
}

/* Create the SUNContext *ctx with record_error (into the statistics st) as its only error
 * handler: 0, or nonzero (with st's message) when it cannot be made. Static inline, as
 * free_solver: a driver or stepper that does not call it gets no warning. */
static inline int create_context(SUNContext *ctx, LCG_STATS *st)
{
    if (SUNContext_Create(0, ctx) != 0) {
        snprintf(st->message, sizeof st->message, "SUNContext_Create failed");
        return 1;
    }
    SUNContext_ClearErrHandlers(*ctx);
    SUNContext_PushErrHandler(*ctx, record_error, st);
    return 0;
}

/* Create the SUNContext ctx (create_context); nomem: the driver's out-of-memory flag, returned
 * (and stored in st->flag) when the context cannot be made. */
#define LCG_CREATE_CONTEXT(nomem)                                                    \
    do {                                                                             \
        if (create_context(&ctx, st) != 0)                                           \
            return st->flag = (nomem);                                               \
    } while (0)

/* The step limits of the options on the solver's memory mem (ida: IDA's, else CVODE's): the
 * maximum order, the first, largest and smallest step (each 0: the solver's own). 0, or the first
 * negative flag. */
static inline int set_step_limits(void *mem, int ida, int max_order, double first_step, double max_step,
                                  double min_step)
{
    int flag;

    if (max_order > 0 && (flag = ida ? IDASetMaxOrd(mem, max_order) : CVodeSetMaxOrd(mem, max_order)) < 0)
        return flag;
    if (first_step > 0 && (flag = ida ? IDASetInitStep(mem, first_step) : CVodeSetInitStep(mem, first_step)) < 0)
        return flag;
    if (max_step > 0 && (flag = ida ? IDASetMaxStep(mem, max_step) : CVodeSetMaxStep(mem, max_step)) < 0)
        return flag;
    if (min_step > 0 && (flag = ida ? IDASetMinStep(mem, min_step) : CVodeSetMinStep(mem, min_step)) < 0)
        return flag;
    return 0;
}

/* The place of model state i (nq coordinates) in CVODE's band solver order: q_i, v_i interleaved
 * (the others after them); nq < 0: i itself. */
static inline int band_place(int nq, int i)
{
    return nq < 0 ? i : i < nq ? 2 * i : (i < 2 * nq ? 2 * (i - nq) + 1 : i);
}

/* The run's tolerances on the solver's memory mem (ida: IDA's, else CVODE's): rtol with the n
 * absolute tolerances atol_vec, copied into a new vector *abstol of the context ctx (the caller
 * frees it) at their band places (band_place; band_nq < 0: in order), or with the scalar atol
 * when atol_vec is NULL. 0, a negative flag, or nomem when the vector cannot be made. */
static inline int set_tolerances(void *mem, int ida, SUNContext ctx, int n, double rtol, double atol,
                                 const double *atol_vec, int band_nq, N_Vector *abstol, int nomem)
{
    int i;

    if (atol_vec == NULL)
        return ida ? IDASStolerances(mem, rtol, atol) : CVodeSStolerances(mem, rtol, atol);
    if ((*abstol = N_VNew_Serial(n, ctx)) == NULL)
        return nomem;
    for (i = 0; i < n; ++i)
        N_VGetArrayPointer(*abstol)[band_place(band_nq, i)] = atol_vec[i];
    return ida ? IDASVtolerances(mem, rtol, *abstol) : CVodeSVtolerances(mem, rtol, *abstol);
}

/* The objects of an IDA run of ng unknowns (lcg_ida.c, lcg_ida_stepper.c, lcg_imp_ida.c), of the
 * context ctx: the vectors *yy, *yp, the vector *id of the differential components (the first ny:
 * q, v; the others, lambda and mu, algebraic), IDA's memory *mem, the dense matrix *A and its
 * linear solver *LS. 0, or nomem when one of them cannot be made (those made are the caller's to
 * free, free_solver). */
static inline int ida_create(SUNContext ctx, int ng, int ny, N_Vector *yy, N_Vector *yp, N_Vector *id, void **mem,
                             SUNMatrix *A, SUNLinearSolver *LS, int nomem)
{
    int i;

    *yy = N_VNew_Serial(ng, ctx);
    *yp = N_VNew_Serial(ng, ctx);
    *id = N_VNew_Serial(ng, ctx);
    *mem = IDACreate(ctx);
    *A = SUNDenseMatrix(ng, ng, ctx);
    if (*yy == NULL || *yp == NULL || *id == NULL || *mem == NULL || *A == NULL
        || (*LS = SUNLinSol_Dense(*yy, *A, ctx)) == NULL)
        return nomem;
    for (i = 0; i < ng; ++i)
        N_VGetArrayPointer(*id)[i] = i < ny ? 1.0 : 0.0;
    return 0;
}

/* IDA's setup on the objects of ida_create, as every IDA driver makes it: IDAInit (the residual
 * res from t0, yy, yp), the user data, the differential components id, the algebraic ones
 * excluded from the error test (suppress_alg), the linear solver LS on A. The tolerances are the
 * caller's to set next. 0, or the first negative flag. */
static inline int ida_init(void *mem, IDAResFn res, double t0, N_Vector yy, N_Vector yp, N_Vector id, void *user_data,
                           int suppress_alg, SUNLinearSolver LS, SUNMatrix A)
{
    int flag;

    if ((flag = IDAInit(mem, res, t0, yy, yp)) < 0)
        return flag;
    IDASetUserData(mem, user_data);
    if ((flag = IDASetId(mem, id)) < 0)
        return flag;
    if (suppress_alg && (flag = IDASetSuppressAlg(mem, 1)) < 0)
        return flag;
    return IDASetLinearSolver(mem, LS, A);
}

/* IDA's root finding of nroot functions g (nroot 0: none), with the directions dirs (NULL: both),
 * no warning for roots that are zero at the start. 0, or the first negative flag. */
static inline int ida_roots(void *mem, int nroot, IDARootFn g, const int *dirs)
{
    int flag;

    if (nroot <= 0)
        return 0;
    if ((flag = IDARootInit(mem, nroot, g)) < 0)
        return flag;
    if (dirs != NULL && (flag = IDASetRootDirection(mem, (int *)dirs)) < 0)
        return flag;
    IDASetNoInactiveRootWarn(mem);
    return 0;
}

/* After CVodeFree / IDAFree: the solver's objects freed in this order, the linear and nonlinear
 * solvers, the matrix, the nv vectors v (e.g. a compound literal), the context *ctx (each NULL:
 * nothing). */
static inline void free_solver(SUNLinearSolver LS, SUNNonlinearSolver NLS, SUNMatrix A, const N_Vector *v, int nv,
                               SUNContext *ctx)
{
    int i;

    if (LS != NULL)
        SUNLinSolFree(LS);
    if (NLS != NULL)
        SUNNonlinSolFree(NLS);
    if (A != NULL)
        SUNMatDestroy(A);
    for (i = 0; i < nv; ++i)
        if (v[i] != NULL)
            N_VDestroy(v[i]);
    if (*ctx != NULL)
        SUNContext_Free(ctx);
}

/* Before each call of the solver (CVode or IDA): stop with flag -1 once opt->max_steps steps are
 * taken, else allow the steps that are left. */
#define LCG_STEP_BUDGET(solver)                                                      \
    do {                                                                             \
        solver##GetNumSteps(mem, &nst);                                              \
        if (nst >= opt->max_steps) {                                                 \
            flag = -1;                                                               \
            snprintf(st->message, sizeof st->message,                                \
                     "the step budget max_steps = %ld is used up before t = %.17g",  \
                     opt->max_steps, tout[k]);                                       \
            goto done;                                                               \
        }                                                                            \
        solver##SetMaxNumSteps(mem, opt->max_steps - nst);                           \
    } while (0)

/* After a model function returned rc: unless rc is ok, stop with flag LCG_MODEL_ERROR_FLAG(rc). */
#define LCG_MODEL_ERROR(ok)                                                          \
    do {                                                                             \
        if (rc != (ok)) {                                                            \
            st->model_error = rc;                                                    \
            flag = LCG_MODEL_ERROR_FLAG(rc);                                         \
            goto done;                                                               \
        }                                                                            \
    } while (0)

/* A CVODE failure (error test, convergence or right-hand-side failures) right after a callback
 * reported a non-finite value (nonfinite, at t_nonfinite) has that value as its cause: the model
 * error LCG_ERR_NONFINITE into *model_error, its time into *t_reached, and its flag; else flag. */
static inline int lcg_nonfinite_flag(int flag, int nonfinite, double t_nonfinite, int *model_error,
                                     double *t_reached)
{
    if (nonfinite && *model_error == 0 && LCG_CVODE_NONFINITE_CAUSE(flag)) {
        *model_error = LCG_ERR_NONFINITE;
        *t_reached = t_nonfinite;
        return LCG_MODEL_ERROR_FLAG(*model_error);
    }
    return flag;
}

/* Add CVODE's counters since its last (re)initialization that the statistics st of every CVODE
 * driver keep (steps, right-hand sides, linear solver setups, error test failures, nonlinear
 * iterations and their convergence failures) to st's. */
#define LCG_ADD_CVODE_COUNTS(mem, st)                                                \
    do {                                                                             \
        long c_[6] = {0, 0, 0, 0, 0, 0};                                             \
        CVodeGetNumSteps((mem), &c_[0]);                                             \
        CVodeGetNumRhsEvals((mem), &c_[1]);                                          \
        CVodeGetNumLinSolvSetups((mem), &c_[2]);                                     \
        CVodeGetNumErrTestFails((mem), &c_[3]);                                      \
        CVodeGetNumNonlinSolvIters((mem), &c_[4]);                                   \
        CVodeGetNumNonlinSolvConvFails((mem), &c_[5]);                               \
        (st)->nsteps += c_[0];                                                       \
        (st)->nrhs += c_[1];                                                         \
        (st)->nlinsetups += c_[2];                                                   \
        (st)->netfails += c_[3];                                                     \
        (st)->nniters += c_[4];                                                      \
        (st)->nncfails += c_[5];                                                     \
    } while (0)

/* After done: the message of the out-of-memory flag nomem when nothing more precise was recorded. */
#define LCG_NOMEM_MESSAGE(nomem, solver)                                             \
    do {                                                                             \
        if (flag == (nomem) && st->message[0] == '\0')                               \
            snprintf(st->message, sizeof st->message,                                \
                     "out of memory creating the " solver " solver");                \
    } while (0)

#ifdef LCG_ROOT_INFO
/* Record the roots the solver found at t, with the state y of ny values, into the events record
 * ev; info: scratch of nroot ints (allocated with the run); returns 1 if one of them is terminal. */
static int record_events(void *mem, lcg_events *ev, double t, const double *y, int nroot, int ny, int *info)
{
    int i, k, stop = 0;

    if (LCG_ROOT_INFO(mem, info) < 0)
        return 1;
    for (i = 0; i < nroot; ++i) {
        if (info[i] == 0)
            continue;
        if (ev->n_events < ev->max_events) {
            ev->t[ev->n_events] = t;
            for (k = 0; k < ny; ++k)
                ev->y[(long)ev->n_events * ny + k] = y[k];
            ev->which[ev->n_events] = i;
            ev->direction[ev->n_events] = info[i];
        }
        ev->n_events++;
        if (ev->terminal == NULL || ev->terminal[i])
            stop = 1;
    }
    return stop;
}
#endif

#endif /* LCG_SUNDIALS_H */
