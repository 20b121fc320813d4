/* lcg_stepper.h -- lagcodegen's runtime: what the steppers of the integrator object share
 * (lcg_cvode_stepper.c, lcg_cvsens_stepper.c, lcg_cvc_stepper.c, lcg_ida_stepper.c,
 * lcg_taylor_stepper.c): the caller's memory they work on and how a write to it is seen, the check
 * of a call's times, the start of a call, the grid rows at the current time, and the messages they
 * give, the end of a call and the calls on a stepper's advance; with SUNDIALS (included after
 * lcg_sundials.h, whose create_context, free_solver, set_step_limits and set_tolerances they use as
 * the drivers do) the lifecycle of a call, once: the caller's memory as a record
 * (lcg_stepper_memory: bind, keep, unbind), the start (lcg_stepper_begin), the advance to a time,
 * over a grid or by one step with the events recorded (lcg_stepper_drive over lcg_stepper_hooks),
 * the end (lcg_stepper_settle); the step limits with the budget of a call, the stop time of a
 * step, the counters. A stepper keeps only what is its own: its solver's setup and restart, how
 * its state moves between the caller's arrays and the solver's vectors, how it records roots.
 *
 * Each stepper is one translation unit with its run driver: include this file after the driver
 * (lcg_control.h first there, then math.h, stdio.h, stdlib.h). Every function here is static
 * inline, for the including stepper alone (one it does not use is no warning). The statement macros
 * work on any stepper's statistics or events record (the same field names in each). */
#ifndef LCG_STEPPER_H
#define LCG_STEPPER_H

#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>

#include "lcg_codes.h"

/* The stepper struct, zeroed, of the given bytes; NULL (with the message) if out of memory. */
static inline void *lcg_stepper_alloc(size_t bytes, char *message, size_t size)
{
    void *s = calloc(1, bytes);

    if (s == NULL)
        snprintf(message, size, "out of memory");
    return s;
}

/* A copy of the n values x (malloc; the caller's absolute tolerances, which the stepper keeps),
 * NULL if out of memory or x is NULL. */
static inline double *lcg_stepper_copy(const double *x, long n)
{
    double *c;
    long i;

    if (x == NULL || (c = (double *)malloc(sizeof(double) * (size_t)(n > 0 ? n : 1))) == NULL)
        return NULL;
    for (i = 0; i < n; ++i)
        c[i] = x[i];
    return c;
}

/* 1 if a[i] != b[i] for some i < n (a NaN differs from everything). */
static inline int lcg_stepper_differ(const double *a, const double *b, long n)
{
    long i;

    for (i = 0; i < n; ++i)
        if (a[i] != b[i])
            return 1;
    return 0;
}

/* The caller's memory as a call leaves it: seen = (mem[0..n-1], extra[0..n_extra-1]), with mem =
 * (t, y[ny], p[np]) (n = 1 + ny + np) and extra the stepper's further caller memory (the
 * sensitivities; NULL, 0: none). */
static inline void lcg_stepper_remember(double *seen, const double *mem, long n, const double *extra, long n_extra)
{
    long i;

    for (i = 0; i < n; ++i)
        seen[i] = mem[i];
    for (i = 0; i < n_extra; ++i)
        seen[n + i] = extra[i];
}

/* 1 if the caller wrote mem or extra since lcg_stepper_remember (the time, the state, the
 * parameters or the sensitivities): the next call restarts the solver there. */
static inline int lcg_stepper_written(const double *seen, const double *mem, long n, const double *extra,
                                      long n_extra)
{
    return lcg_stepper_differ(mem, seen, n) || lcg_stepper_differ(extra, seen + n, n_extra);
}

/* The caller's memory a SUNDIALS stepper works on, as every one of them keeps it: mem = (t, y[ny],
 * p[np]) and the further memory extra (n_extra values: the sensitivities; NULL, 0: none), which
 * the caller may write between calls; seen, the same as the last call left it; the copy of the
 * caller's absolute tolerances the stepper owns; whether the solver restarts from the caller's
 * values before the next step. */
typedef struct {
    double *tv, *y, *p;         /* the caller's time, state (ny) and parameters (np) */
    double *extra;              /* the caller's further memory, or NULL */
    long n, n_extra;            /* 1 + ny + np; the further memory's length */
    double *seen;               /* n + n_extra: as the last call left them */
    double *atol;               /* the copied tolerances, or NULL */
    int restart;                /* restart the solver at the caller's values before the next step */
} lcg_stepper_memory;

/* Bind b to the caller's mem = (t, y[ny], p[np]) and extra (n_extra) with a copy of the n_atol
 * tolerances atol (NULL: none): 0, or 1 out of memory (lcg_stepper_unbind frees what was made). */
static inline int lcg_stepper_bind(lcg_stepper_memory *b, double *mem, long ny, long np, double *extra,
                                   long n_extra, const double *atol, long n_atol)
{
    b->tv = mem;
    b->y = mem + 1;
    b->p = b->y + ny;
    b->extra = extra;
    b->n = 1 + ny + np;
    b->n_extra = n_extra;
    b->seen = (double *)malloc(sizeof(double) * (size_t)(b->n + n_extra));
    b->atol = lcg_stepper_copy(atol, n_atol);
    return b->seen == NULL || (atol != NULL && b->atol == NULL);
}

/* Free what lcg_stepper_bind made (the caller's memory stays). */
static inline void lcg_stepper_unbind(lcg_stepper_memory *b)
{
    free(b->seen);
    free(b->atol);
}

/* The caller's memory as a call leaves it (lcg_stepper_remember). */
static inline void lcg_stepper_keep(lcg_stepper_memory *b)
{
    lcg_stepper_remember(b->seen, b->tv, b->n, b->extra, b->n_extra);
}

/* 1 if the grid of a call at time t to t_end is good: nt >= 0, and with nt > 0 the times tout
 * given (and, outs, the output arrays), finite and not decreasing from t, the last one t_end
 * (exact_end) or not after it. (t_end >= t is the caller's test: its time may be more than a
 * double.) */
static inline int lcg_stepper_grid_ok(double t, double t_end, int nt, const double *tout, int outs, int exact_end)
{
    int k;

    if (nt < 0)
        return 0;
    if (nt == 0)
        return 1;
    if (tout == NULL || !outs || tout[0] < t || (exact_end ? tout[nt - 1] != t_end : tout[nt - 1] > t_end))
        return 0;
    for (k = 0; k < nt; ++k)
        if (!isfinite(tout[k]) || (k > 0 && tout[k] < tout[k - 1]))
            return 0;
    return 1;
}

/* The message of a call whose times go backward (lcg_stepper_grid_ok failed, or t_end < t):
 * LCG_FLAG_BAD_INPUT. */
static inline int lcg_stepper_backward(char *message, size_t size, double t_end, double t)
{
    snprintf(message, size,
             "time going backward: the end time %.17g lies before the integrator's time %.17g, or the "
             "grid's times are not finite and increasing from there", t_end, t);
    return LCG_FLAG_BAD_INPUT;
}

/* The end time of a grid call over tout[0..nt-1] (-HUGE_VAL, refused, without a grid). */
static inline double lcg_stepper_grid_end(int nt, const double *tout)
{
    return nt > 0 && tout != NULL ? tout[nt - 1] : -HUGE_VAL;
}

/* Where a one-step call at time t aims (only a hint of the first step's size after a (re)start;
 * the stop time t_end bounds the step): t_end, or without an end a little past t. */
static inline double lcg_stepper_one_step_tout(double t, double t_end)
{
    return isfinite(t_end) ? t_end : t + fmax(1.0, 1e-3 * fabs(t));
}

/* The grid times tout[k..] at the current time t: the current values v (n) into their rows of out
 * (row length n); returns the index of the first grid time after t. */
static inline int lcg_stepper_rows_now(int k, int nt, const double *tout, double t, const double *v, long n,
                                       double *out)
{
    long i;

    for (; k < nt && tout[k] <= t; ++k)
        for (i = 0; i < n; ++i)
            out[(long)k * n + i] = v[i];
    return k;
}

/* The start of a call on b at time t to t_end (the grid tout[0..nt-1], outs: its output arrays
 * given; the last grid time t_end): 0, or LCG_FLAG_BAD_INPUT with the message of times going
 * backward. A write of the caller's memory since the last call marks a restart. */
static inline int lcg_stepper_begin(lcg_stepper_memory *b, double t_end, int nt, const double *tout, int outs,
                                    char *message, size_t size)
{
    double t = b->tv[0];

    if (!(t_end >= t) || !lcg_stepper_grid_ok(t, t_end, nt, tout, outs, 1))
        return lcg_stepper_backward(message, size, t_end, t);
    if (!b->restart && lcg_stepper_written(b->seen, b->tv, b->n, b->extra, b->n_extra))
        b->restart = 1; /* the caller set the time, the state, the parameters or the further memory */
    return 0;
}

/* A solver's failure while a model function had failed (model_error set): the model's flag
 * LCG_MODEL_ERROR_FLAG(model_error) instead. */
static inline int lcg_stepper_model_flag(int flag, int model_error)
{
    return model_error != 0 && flag < 0 && flag > LCG_FLAG_MODEL_ERROR ? LCG_MODEL_ERROR_FLAG(model_error) : flag;
}

/* The message of a failed setup of the solver named solver: flag nomem is out of memory, any other
 * a failure with the solver's last message detail. */
static inline void lcg_stepper_setup_failed(char *message, size_t size, int flag, int nomem, const char *solver,
                                            const char *detail)
{
    if (flag == nomem)
        snprintf(message, size, "out of memory creating the %s solver", solver);
    else
        snprintf(message, size, "%s setup failed (flag %d): %s", solver, flag, detail);
}

/* The start of a call: the statistics st cleared of the last call's flag, model error, rows done
 * and message, the events record ev (NULL: none) emptied. */
#define LCG_STEPPER_NEW_CALL(st, ev)                                                 \
    do {                                                                             \
        (st)->flag = (st)->model_error = (st)->nt_done = 0;                          \
        (st)->message[0] = '\0';                                                     \
        if ((ev) != NULL) {                                                          \
            (ev)->n_events = 0;                                                      \
            (ev)->terminated = 0;                                                    \
        }                                                                            \
    } while (0)

/* The end of a call that reached the time t: the statistics st keep it (unless a model error set
 * the time of the failure) and the call's flag flag (0, or negative). */
#define LCG_STEPPER_END_CALL(st, flag, t)                                            \
    do {                                                                             \
        if ((st)->model_error == 0)                                                  \
            (st)->t_reached = (t);                                                   \
        (st)->flag = (flag) < 0 ? (flag) : 0;                                        \
    } while (0)

/* The calls of the integrator object on lcg_<kind>_stepper_advance(s, t_end, nt, tout, yout,
 * one_step), defined at file scope (no semicolon after it): lcg_<kind>_stepper_until (to t_end, no
 * grid: propagate_until), lcg_<kind>_stepper_grid (over the grid tout[0..nt-1], to its last time:
 * propagate_grid), lcg_<kind>_stepper_step (one step ending at t_limit at the latest: step). */
#define LCG_STEPPER_CALLS(kind)                                                                        \
    int lcg_##kind##_stepper_until(lcg_##kind##_stepper *s, double t_end)                               \
    {                                                                                                  \
        return lcg_##kind##_stepper_advance(s, t_end, 0, NULL, NULL, 0);                                \
    }                                                                                                  \
    int lcg_##kind##_stepper_grid(lcg_##kind##_stepper *s, int nt, const double *tout, double *yout)    \
    {                                                                                                  \
        return lcg_##kind##_stepper_advance(s, lcg_stepper_grid_end(nt, tout), nt, tout, yout, 0);      \
    }                                                                                                  \
    int lcg_##kind##_stepper_step(lcg_##kind##_stepper *s, double t_limit)                              \
    {                                                                                                  \
        return lcg_##kind##_stepper_advance(s, t_limit, 0, NULL, NULL, 1);                              \
    }

#ifdef LCG_SUNDIALS_H
/* SUNDIALS 7 declarations beyond sundials_api.h's (the run drivers do not need them). */
#ifndef CV_ONE_STEP
#define CV_ONE_STEP 2
#endif
#ifndef IDA_ONE_STEP
#define IDA_ONE_STEP 2
#endif
int CVodeClearStopTime(void *cvode_mem);
int IDAClearStopTime(void *ida_mem);

/* The step limits of the options on the solver's memory (set_step_limits; ida: IDA's, else
 * CVODE's), then the step budget of one call max_steps: 0 or a negative flag. */
static inline int lcg_stepper_limits(void *mem, int ida, int max_order, double first_step, double max_step,
                                     double min_step, long max_steps)
{
    int flag = set_step_limits(mem, ida, max_order, first_step, max_step, min_step);

    if (flag < 0)
        return flag;
    return ida ? IDASetMaxNumSteps(mem, max_steps) : CVodeSetMaxNumSteps(mem, max_steps);
}

/* The stop time of a one-step call (ida: on IDA's memory, else CVODE's): t_end, or none without an
 * end. */
static inline int lcg_stepper_stop(void *mem, int ida, double t_end)
{
    if (isfinite(t_end))
        return ida ? IDASetStopTime(mem, t_end) : CVodeSetStopTime(mem, t_end);
    return ida ? IDAClearStopTime(mem) : CVodeClearStopTime(mem);
}

/* The stop time t of the solver's memory (ida: IDA's, else CVODE's). */
static inline int lcg_stepper_stop_at(void *mem, int ida, double t)
{
    return ida ? IDASetStopTime(mem, t) : CVodeSetStopTime(mem, t);
}

/* What lcg_stepper_drive works on: the solver's memory mem (ida: IDA's, else CVODE's) and the
 * vectors it solves into (y; IDA: y, yp); on the stepper s, the record of the roots the solver
 * returned at tret (NULL: no root finding; returns 1 at a terminal event, the events record
 * marked terminated; 0 when an event was recorded; -1 when none was, a root found again at the
 * start) and the store of the solver's state into row k of the call's grid arrays; the call's
 * run control, and (IDA) a stop time at each grid time. */
typedef struct {
    void *mem;
    int ida;
    N_Vector y, yp;
    void *s;
    int (*record)(void *s, double tret);
    void (*store)(void *s, int k);
    watch *w;
    int stop_at_outputs;
} lcg_stepper_hooks;

/* The solver towards tout (one_step: one internal step), recording the events met on the way
 * (hooks' record): *stop set at a terminal one; in one-step mode the step ends at an event
 * recorded. 0, or the solver's flag. */
static inline int lcg_stepper_solve(const lcg_stepper_hooks *h, double tout, int one_step, double *tret, int *stop)
{
    int flag, recorded;

    for (;;) {
        flag = h->ida ? IDASolve(h->mem, tout, tret, h->y, h->yp, one_step ? IDA_ONE_STEP : IDA_NORMAL)
                      : CVode(h->mem, tout, h->y, tret, one_step ? CV_ONE_STEP : CV_NORMAL);
        if (flag != CV_ROOT_RETURN || h->record == NULL) /* IDA_ROOT_RETURN: the same 2 */
            return flag;
        recorded = h->record(h->s, *tret);
        if (recorded > 0) {
            *stop = 1;
            return 0;
        }
        if (one_step && recorded == 0)
            return 0;
    }
}

/* The advance of every SUNDIALS stepper from the time t (the grid rows before k written):
 * one_step, one internal step ending at t_end at the latest; without a grid (nt = 0) to t_end,
 * stopping exactly there; else over the grid tout[k..nt-1] (t_end its last time), each row
 * stored and counted in *nt_done. *tret: the time the solver reached. 0 or a negative flag. */
static inline int lcg_stepper_drive(const lcg_stepper_hooks *h, double t, double t_end, int nt, const double *tout,
                                    int k, int one_step, double *tret, int *nt_done)
{
    int flag = 0, stop = 0;

    if (one_step) {
        flag = lcg_stepper_stop(h->mem, h->ida, t_end);
        if (flag >= 0 && t_end > t)
            flag = lcg_stepper_solve(h, lcg_stepper_one_step_tout(t, t_end), 1, tret, &stop);
    } else if (nt == 0) {
        if (t_end > t && (flag = lcg_stepper_stop_at(h->mem, h->ida, t_end)) >= 0)
            flag = lcg_stepper_solve(h, t_end, 0, tret, &stop);
    } else if (k < nt) {
        if ((flag = lcg_stepper_stop_at(h->mem, h->ida, t_end)) < 0)
            return flag;
        for (; k < nt; ++k) {
            if (WATCH_TICK(h->w))
                break;
            if (h->stop_at_outputs && (flag = lcg_stepper_stop_at(h->mem, h->ida, tout[k])) < 0)
                break;
            flag = lcg_stepper_solve(h, tout[k], 0, tret, &stop);
            if (flag < 0 || stop)
                break;
            h->store(h->s, k);
            *nt_done = k + 1;
        }
    }
    return flag;
}

/* The flag of a call that ended with flag (after the run control's, watch_flag): a solver's failure
 * while a model function had failed is the model's (lcg_stepper_model_flag); a failure restarts
 * the solver at the last state reached before the next step (keep_bad_input: not after
 * LCG_FLAG_BAD_INPUT, which changed nothing). */
static inline int lcg_stepper_settle(lcg_stepper_memory *b, int flag, int model_error, int keep_bad_input)
{
    flag = lcg_stepper_model_flag(flag, model_error);
    if (flag < 0 && !(keep_bad_input && flag == LCG_FLAG_BAD_INPUT))
        b->restart = 1;
    return flag;
}

/* CVODE's counters since the last (re)start that every CVODE stepper's statistics st keep: steps,
 * right-hand sides, error test and nonlinear convergence failures, the last step. */
#define LCG_STEPPER_CVODE_COUNTS(mem, st)                                            \
    do {                                                                             \
        CVodeGetNumSteps((mem), &(st)->nsteps);                                      \
        CVodeGetNumRhsEvals((mem), &(st)->nrhs);                                     \
        CVodeGetNumErrTestFails((mem), &(st)->netfails);                             \
        CVodeGetNumNonlinSolvConvFails((mem), &(st)->nncfails);                      \
        CVodeGetLastStep((mem), &(st)->h_last);                                      \
    } while (0)
#endif /* LCG_SUNDIALS_H */

#endif /* LCG_STEPPER_H */
