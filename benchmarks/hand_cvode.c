/* hand_cvode.c -- a hand-written CVODE program on a lagcodegen-generated right-hand side.
 *
 * The baseline of benchmarks/native_overhead.py: what a C programmer would write by hand to
 * integrate the generated <prefix>_rhs (and <prefix>_jac) with SUNDIALS CVODE -- dense linear
 * solver, the same options as lagcodegen's native driver (tolerances, output times, Adams or
 * BDF, generated or difference-quotient Jacobian, step budget) -- and nothing else. It is
 * compiled against one generated model through "model_alias.h", which native_overhead.py
 * writes:
 *
 *     #include "<prefix>.h"
 *     #define MODEL_NY  <PREFIX>_NY
 *     #define MODEL_NQ  <PREFIX>_NQ
 *     #define MODEL_HAS_JAC 1            (or 0)
 *     #define model_rhs <prefix>_rhs
 *     #define model_jac <prefix>_jac
 *     static const double model_p[] = {...};
 *
 * and linked with the SUNDIALS libraries bundled in the scikit-sundae wheel, declared by
 * lagcodegen's sundials_api.h.
 *
 * Usage: hand_cvode METHOD(1 adams, 2 bdf) JAC(0/1) RTOL ATOL T_END NT Q0 REPEATS
 * Prints: "median_s <s> steps <n> rhs <n> y_end <y[0]> ... <y[NY-1]>". Each repeat is one
 * complete solve (context, vectors, solver created and freed), like one driver call. */
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "sundials_api.h"
#include "model_alias.h"

static double now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static int rhs(sunrealtype t, N_Vector y, N_Vector ydot, void *data)
{
    int rc = model_rhs(t, N_VGetArrayPointer(y), (const double *)data, N_VGetArrayPointer(ydot));
    return rc == 0 ? 0 : (rc == 1 ? -1 : 1);
}

#if MODEL_HAS_JAC
static int jac(sunrealtype t, N_Vector y, N_Vector fy, SUNMatrix J, void *data, N_Vector tmp1, N_Vector tmp2,
               N_Vector tmp3)
{
    int rc = model_jac(t, N_VGetArrayPointer(y), N_VGetArrayPointer(fy), (const double *)data,
                       SUNDenseMatrix_Data(J));
    (void)tmp1;
    (void)tmp2;
    (void)tmp3;
    return rc == 0 ? 0 : (rc == 1 ? -1 : 1);
}
#endif

/* One solve: y(0) = (q0, ..., 0, ...), outputs at nt equally spaced times in [0, t_end]. */
static int solve(int method, int use_jac, double rtol, double atol, const double *tout, int nt, double q0,
                 double *yout, long *nsteps, long *nrhs)
{
    SUNContext ctx = NULL;
    void *mem = NULL;
    N_Vector y = NULL;
    SUNMatrix A = NULL;
    SUNLinearSolver LS = NULL;
    double *yv, tret;
    int i, k, flag;

    if (SUNContext_Create(0, &ctx) != 0)
        return -20;
    y = N_VNew_Serial(MODEL_NY, ctx);
    yv = N_VGetArrayPointer(y);
    for (i = 0; i < MODEL_NY; ++i)
        yv[i] = i < MODEL_NQ ? q0 : 0.0;
    for (i = 0; i < MODEL_NY; ++i)
        yout[i] = yv[i];
    mem = CVodeCreate(method, ctx);
    A = SUNDenseMatrix(MODEL_NY, MODEL_NY, ctx);
    LS = SUNLinSol_Dense(y, A, ctx);
    flag = CVodeInit(mem, rhs, tout[0], y);
    if (flag >= 0)
        flag = CVodeSStolerances(mem, rtol, atol);
    if (flag >= 0)
        flag = CVodeSetUserData(mem, (void *)model_p);
    if (flag >= 0)
        flag = CVodeSetLinearSolver(mem, LS, A);
#if MODEL_HAS_JAC
    if (flag >= 0 && use_jac)
        flag = CVodeSetJacFn(mem, jac);
#else
    (void)use_jac;
#endif
    if (flag >= 0)
        flag = CVodeSetMaxNumSteps(mem, 1000000);
    if (flag >= 0)
        flag = CVodeSetStopTime(mem, tout[nt - 1]);
    for (k = 1; k < nt && flag >= 0; ++k) {
        flag = CVode(mem, tout[k], y, &tret, CV_NORMAL);
        for (i = 0; i < MODEL_NY; ++i)
            yout[k * MODEL_NY + i] = yv[i];
    }
    CVodeGetNumSteps(mem, nsteps);
    CVodeGetNumRhsEvals(mem, nrhs);
    CVodeFree(&mem);
    SUNLinSolFree(LS);
    SUNMatDestroy(A);
    N_VDestroy(y);
    SUNContext_Free(&ctx);
    return flag < 0 ? flag : 0;
}

static int cmp(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

int main(int argc, char **argv)
{
    int method, use_jac, nt, repeats, r, i, flag = 0;
    double rtol, atol, t_end, q0, *tout, *yout, *times;
    long nsteps = 0, nrhs = 0;

    if (argc != 9) {
        fprintf(stderr, "usage: %s METHOD JAC RTOL ATOL T_END NT Q0 REPEATS\n", argv[0]);
        return 2;
    }
    method = atoi(argv[1]);
    use_jac = atoi(argv[2]);
    rtol = atof(argv[3]);
    atol = atof(argv[4]);
    t_end = atof(argv[5]);
    nt = atoi(argv[6]);
    q0 = atof(argv[7]);
    repeats = atoi(argv[8]);
    if (nt < 2 || repeats < 1)
        return 2;
    tout = malloc(sizeof(double) * (size_t)nt);
    yout = malloc(sizeof(double) * (size_t)nt * MODEL_NY);
    times = malloc(sizeof(double) * (size_t)repeats);
    if (tout == NULL || yout == NULL || times == NULL)
        return 3;
    for (i = 0; i < nt; ++i)
        tout[i] = t_end * (double)i / (double)(nt - 1);
    for (r = 0; r < repeats; ++r) {
        double start = now();
        flag = solve(method, use_jac, rtol, atol, tout, nt, q0, yout, &nsteps, &nrhs);
        times[r] = now() - start;
        if (flag < 0) {
            fprintf(stderr, "CVODE failed with flag %d\n", flag);
            return 1;
        }
    }
    qsort(times, (size_t)repeats, sizeof(double), cmp);
    printf("median_s %.9e steps %ld rhs %ld y_end", repeats % 2 ? times[repeats / 2]
           : 0.5 * (times[repeats / 2 - 1] + times[repeats / 2]), nsteps, nrhs);
    for (i = 0; i < MODEL_NY; ++i)
        printf(" %.17g", yout[(nt - 1) * MODEL_NY + i]);
    printf("\n");
    free(tout);
    free(yout);
    free(times);
    return 0;
}
