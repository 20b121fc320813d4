/* lcg_control.h -- run control of lagcodegen's native drivers (one translation unit each):
 * cancellation, a poll callback (progress, Ctrl-C) and a wall-clock limit, the "watch" of one run.
 *
 * Include it first in a driver source, before any system header: it asks for POSIX 2008
 * (clock_gettime, pthreads). Every function here is static, for the including driver alone.
 *
 * Flags (lcg_codes.h): LCG_FLAG_CANCELLED (-80) the cancel flag was set or the poll callback
 * returned nonzero, LCG_FLAG_TIMED_OUT (-81) the wall-clock limit max_wall was reached. The watch
 * is checked every 64 ticks (right-hand-side calls and output times): the clock is read only then,
 * and only when a poll callback or a wall-clock limit is set. */
#ifndef LCG_CONTROL_H
#define LCG_CONTROL_H

#if !defined(_POSIX_C_SOURCE) || _POSIX_C_SOURCE < 200809L
#undef _POSIX_C_SOURCE
#define _POSIX_C_SOURCE 200809L
#endif

#include <stddef.h>
#include <stdio.h>
#include <time.h>

#include "lcg_codes.h"

#if defined(__GNUC__) || defined(__clang__)
#define LCG_LOAD(p) __atomic_load_n((p), __ATOMIC_RELAXED)
#define LCG_STORE(p, v) __atomic_store_n((p), (v), __ATOMIC_RELAXED)
#define LCG_FETCH_ADD(p, v) __atomic_fetch_add((p), (v), __ATOMIC_RELAXED)
#else
#error "the native drivers need the GNU atomic builtins (gcc, clang)"
#endif

static double now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

typedef struct {
    int *cancel;
    int (*poll)(void *, long, long);
    void *poll_data;
    double every, limit, start, next;
    long total;
    const int *done;  /* output rows done (passed to poll) */
    unsigned count;
    int active;       /* anything to watch */
    int stop;         /* 0, or the flag that stops the run: -80 cancelled, -81 wall-clock limit */
} watch;


static void watch_init(watch *w, int *cancel, int (*poll)(void *, long, long), void *poll_data, double every,
                       double limit, long total, const int *done)
{
    w->cancel = cancel;
    w->poll = poll;
    w->poll_data = poll_data;
    w->every = every > 0 ? every : 0.05;
    w->limit = limit > 0 ? limit : 0;
    w->total = total;
    w->done = done;
    w->count = 0;
    w->stop = 0;
    w->active = cancel != NULL || poll != NULL || w->limit > 0;
    w->start = poll != NULL || w->limit > 0 ? now() : 0.0;
    w->next = w->start + w->every;
}

/* The stop flag (0: go on): the cancel flag, the wall-clock limit, the poll callback when due. */
static int watch_check(watch *w)
{
    double t;

    if (w->stop)
        return w->stop;
    if (w->cancel != NULL && LCG_LOAD(w->cancel))
        return w->stop = LCG_FLAG_CANCELLED;
    if (w->poll == NULL && w->limit <= 0)
        return 0;
    t = now();
    if (w->limit > 0 && t - w->start > w->limit)
        return w->stop = LCG_FLAG_TIMED_OUT;
    if (w->poll != NULL && t >= w->next) {
        w->next = t + w->every;
        if (w->poll(w->poll_data, (long)*w->done, w->total))
            return w->stop = LCG_FLAG_CANCELLED;
    }
    return 0;
}

/* Nonzero if the run must stop; checks the watch every 64 ticks. */
#define WATCH_TICK(w) ((w)->active && (++(w)->count & 63u) == 0 && watch_check(w) != 0)

/* After done: a stop of the watch replaces the solver's flag (its right-hand side failed on purpose). */
static int watch_flag(const watch *w, int flag, char *message, size_t size)
{
    if (w->stop == 0)
        return flag;
    if (w->stop == LCG_FLAG_CANCELLED)
        snprintf(message, size, "cancelled");
    else
        snprintf(message, size, "the wall-clock limit max_wall = %g s was reached", w->limit);
    return w->stop;
}


#endif /* LCG_CONTROL_H */
