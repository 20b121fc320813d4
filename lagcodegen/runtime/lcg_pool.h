/* lcg_pool.h -- the ensemble pool of lagcodegen's native drivers: many runs of one driver over a
 * pthread pool, members taken in turn from a shared counter (each member a run of the driver's
 * single-run solver with its own solver context, so its numbers are those of the same run alone).
 *
 * Included once, at the end of a driver source (after lcg_control.h), with these macros defined:
 *   LCG_POOL_ENSEMBLE   the ensemble type (lcg_<driver>_ensemble)
 *   LCG_POOL_OPTIONS    the options type
 *   LCG_POOL_STATS      the statistics type (nt_done, t_reached, model_error, message)
 *   LCG_POOL_SOLVE_MANY the public function's name
 *   NROW, NOUT, NOUTD   the state row size, the outputs and max(NOUT, 1) of the ensemble e
 *   COUNTS(c, st)       fills c[0..4] (steps, rhs evals, jac evals, error test fails, nonlinear
 *                       convergence fails) from st
 * and optionally
 *   LCG_POOL_EVENTS     the events type of the driver's root finding (lcg_events): each member's
 *                       first max_events events go to its slots of e->ev_t, ev_y, ev_which,
 *                       ev_direction (those not NULL), their count to counts[6]
 *   LCG_POOL_YP0        defined: every member has an initial yp0 too (IDA)
 * The driver defines pool_member (declared here): one member's run, returning its flag. */
#ifndef LCG_POOL_H
#define LCG_POOL_H

#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

/* A worker's scratch for one member (filled by pool_member). */
typedef struct {
#ifdef LCG_POOL_EVENTS
    LCG_POOL_EVENTS evs;  /* the member's events record (arrays of maxev events, once per worker) */
    int maxev;
#endif
    double *olast;        /* NOUTD outputs at ylast */
    const double *ylast;  /* the state row of a terminal event that ended the run, or NULL */
    double tlast;         /* its time */
    long ev_n;            /* events found */
    int ev_term;          /* a terminal event ended the run */
} pool_scratch;

/* The run of member i (parameters pi, initial state y0i, yp0i or NULL) with the options o into
 * st, yout (nt x NROW), out (nt x NOUTD); returns the run's flag. */
static int pool_member(LCG_POOL_ENSEMBLE *e, const double *pi, const double *y0i, const double *yp0i,
                       const LCG_POOL_OPTIONS *o, LCG_POOL_STATS *st, double *yout, double *out, pool_scratch *s);

typedef struct {
    LCG_POOL_ENSEMBLE *e;
    const LCG_POOL_OPTIONS *opt;
    pthread_mutex_t mu;
    pthread_cond_t cv;
    int running;
    int failed;  /* a worker could not allocate its scratch */
} pool_t;

#ifdef LCG_POOL_EVENTS
/* The first events of member i (at most maxev of the s->ev_n found) copied from the worker's record
 * to the member's slots of e->ev_t, ev_y (NROW values each), ev_which, ev_direction (those not NULL). */
static void member_events(LCG_POOL_ENSEMBLE *e, long i, const pool_scratch *s)
{
    long k, kept = s->ev_n < (long)s->maxev ? s->ev_n : (long)s->maxev, base = (long)s->maxev * i;

    for (k = 0; k < kept; ++k) {
        if (e->ev_t != NULL)
            e->ev_t[base + k] = s->evs.t[k];
        if (e->ev_which != NULL)
            e->ev_which[base + k] = s->evs.which[k];
        if (e->ev_direction != NULL)
            e->ev_direction[base + k] = s->evs.direction[k];
        if (e->ev_y != NULL)
            memcpy(e->ev_y + (base + k) * NROW, s->evs.y + k * NROW, sizeof(double) * NROW);
    }
}
#endif

/* The member i's results into the ensemble's arrays: its run's statistics st and flag rc, its rows
 * yout, out, and from the worker's scratch s the terminal event's row, the events and their counts. */
static void member_record(LCG_POOL_ENSEMBLE *e, long i, const LCG_POOL_STATS *st, int rc, const double *yout,
                          const double *out, const pool_scratch *s, double wall)
{
    int k, j, rows = st->nt_done;
    const double *ylast = s->ylast, *olast = s->olast;
    double tlast = s->tlast;
    long *c;

    if (e->flag != NULL)
        e->flag[i] = rc;
    if (e->nt_done != NULL)
        e->nt_done[i] = rows;
    if (e->t_reached != NULL)
        e->t_reached[i] = ylast != NULL ? tlast : st->t_reached;
    if (e->wall != NULL)
        e->wall[i] = wall;
    if (e->counts != NULL) {
        c = e->counts + 8 * i;
        COUNTS(c, st);
        c[5] = st->model_error;
        c[6] = s->ev_n;
        c[7] = s->ev_term;
    }
#ifdef LCG_POOL_EVENTS
    member_events(e, i, s);
#endif
    if (e->final != NULL) {
        double *f = e->final + (long)(NROW + NOUT) * i;
        const double *ys = ylast != NULL ? ylast : (rows > 0 ? yout + (long)(rows - 1) * NROW : NULL);
        const double *os = ylast != NULL ? olast : (rows > 0 ? out + (long)(rows - 1) * NOUTD : NULL);
        for (k = 0; k < NROW; ++k)
            f[k] = ys != NULL ? ys[k] : NAN;
        for (k = 0; k < NOUT; ++k)
            f[NROW + k] = os != NULL ? os[k] : NAN;
    }
    if (e->traj != NULL) {
        double *tr = e->traj + (long)e->nt * e->ncol * i;
        for (k = 0; k < e->nt; ++k)
            for (j = 0; j < e->ncol; ++j) {
                int cj = e->col[j];
                tr[(long)k * e->ncol + j] = k >= rows ? NAN
                    : cj < NROW ? yout[(long)k * NROW + cj] : out[(long)k * NOUTD + cj - NROW];
            }
    }
    if (rc < 0 && e->messages != NULL) {
        long m = LCG_FETCH_ADD(&e->n_messages, 1);
        if (m < e->max_messages) {
            char *dst = e->messages + 256 * m;
            strncpy(dst, st->message, 255);
            dst[255] = '\0';
            e->message_member[m] = i;
        }
    }
}

static void *pool_worker(void *arg)
{
    pool_t *pool = (pool_t *)arg;
    LCG_POOL_ENSEMBLE *e = pool->e;
    LCG_POOL_OPTIONS o = *pool->opt;
    LCG_POOL_STATS st;
    pool_scratch s;
    double *yout = (double *)malloc(sizeof(double) * (size_t)e->nt * NROW);
    double *out = (double *)malloc(sizeof(double) * (size_t)e->nt * NOUTD);
#ifdef LCG_POOL_EVENTS
    int maxev = e->max_events > 0 ? e->max_events : 64;
    double *ev_t = (double *)malloc(sizeof(double) * (size_t)maxev);
    double *ev_y = (double *)malloc(sizeof(double) * (size_t)maxev * NROW);
    int *ev_which = (int *)malloc(sizeof(int) * (size_t)maxev);
    int *ev_dir = (int *)malloc(sizeof(int) * (size_t)maxev);
    int ok = ev_t != NULL && ev_y != NULL && ev_which != NULL && ev_dir != NULL;
#else
    int ok = 1;
#endif
    double *olast = (double *)malloc(sizeof(double) * NOUTD);

    o.cancel = &e->cancel;
    o.poll = NULL;
    o.poll_data = NULL;
    memset(&s, 0, sizeof s);
    s.olast = olast;
#ifdef LCG_POOL_EVENTS
    s.maxev = maxev;
    s.evs.max_events = maxev;
    s.evs.t = ev_t;
    s.evs.y = ev_y;
    s.evs.which = ev_which;
    s.evs.direction = ev_dir;
    s.evs.rootdir = e->rootdir;
    s.evs.terminal = e->terminal;
#endif
    if (yout == NULL || out == NULL || olast == NULL || !ok) {
        pthread_mutex_lock(&pool->mu);
        pool->failed = 1;
        pthread_mutex_unlock(&pool->mu);
        LCG_STORE(&e->cancel, 1);
    } else {
        for (;;) {
            long i = LCG_FETCH_ADD(&e->next, 1);
            const double *pi, *y0i, *yp0i = NULL;
            double t0;
            int rc;

            if (i >= e->nmem || LCG_LOAD(&e->cancel))
                break;
            pi = e->p != NULL ? e->p + e->p_stride * i : NULL;
            y0i = e->y0 + e->y0_stride * i;
#ifdef LCG_POOL_YP0
            yp0i = e->yp0 + e->yp0_stride * i;
#endif
            s.ylast = NULL;
            s.tlast = 0.0;
            s.ev_n = 0;
            s.ev_term = 0;
            t0 = now();
            rc = pool_member(e, pi, y0i, yp0i, &o, &st, yout, out, &s);
            member_record(e, i, &st, rc, yout, out, &s, now() - t0);
            LCG_FETCH_ADD(&e->done, 1);
        }
    }
    free(yout);
    free(out);
    free(olast);
#ifdef LCG_POOL_EVENTS
    free(ev_t);
    free(ev_y);
    free(ev_which);
    free(ev_dir);
#endif
    pthread_mutex_lock(&pool->mu);
    pool->running--;
    pthread_cond_signal(&pool->cv);
    pthread_mutex_unlock(&pool->mu);
    return NULL;
}

/* Run the ensemble e, every member with the options opt (its max_wall applies to each member;
 * e->cancel stops running members too); the calling thread waits for the workers and calls e->poll
 * with the members done. Returns 0, LCG_FLAG_CANCELLED or LCG_FLAG_NOMEM (threads or scratch). */
int LCG_POOL_SOLVE_MANY(LCG_POOL_ENSEMBLE *e, const LCG_POOL_OPTIONS *opt)
{
    pool_t pool;
    pthread_t *tid;
    int k, started = 0, nthreads = e->nthreads > 0 ? e->nthreads : 1;
    double every = e->poll_every > 0 ? e->poll_every : 0.05, next;

    if ((long)nthreads > e->nmem)
        nthreads = e->nmem > 0 ? (int)e->nmem : 1;
    e->next = 0;
    e->done = 0;
    e->n_messages = 0;
    if (e->nmem <= 0)
        return 0;
    tid = (pthread_t *)malloc(sizeof(pthread_t) * (size_t)nthreads);
    if (tid == NULL)
        return LCG_FLAG_NOMEM;
    pool.e = e;
    pool.opt = opt;
    pool.running = 0;
    pool.failed = 0;
    pthread_mutex_init(&pool.mu, NULL);
    pthread_cond_init(&pool.cv, NULL);
    pthread_mutex_lock(&pool.mu);
    for (k = 0; k < nthreads; ++k) {
        if (pthread_create(&tid[k], NULL, pool_worker, &pool) != 0)
            break;
        pool.running++;
        started++;
    }
    if (started == 0)
        pool.failed = 1;
    next = now() + every;
    while (pool.running > 0) {
        struct timespec ts;
        double t;
        clock_gettime(CLOCK_REALTIME, &ts); /* pthread_cond_timedwait's clock */
        t = (double)ts.tv_nsec * 1e-9 + (e->poll != NULL ? 0.02 : 0.2);
        ts.tv_sec += (time_t)t;
        ts.tv_nsec = (long)((t - (double)(time_t)t) * 1e9);
        pthread_cond_timedwait(&pool.cv, &pool.mu, &ts);
        if (e->poll != NULL && pool.running > 0 && (t = now()) >= next) {
            long done = LCG_LOAD(&e->done);
            int stop;
            next = t + every;
            pthread_mutex_unlock(&pool.mu);
            stop = e->poll(e->poll_data, done, e->nmem);
            pthread_mutex_lock(&pool.mu);
            if (stop)
                LCG_STORE(&e->cancel, 1);
        }
    }
    pthread_mutex_unlock(&pool.mu);
    for (k = 0; k < started; ++k)
        pthread_join(tid[k], NULL);
    free(tid);
    pthread_mutex_destroy(&pool.mu);
    pthread_cond_destroy(&pool.cv);
    if (pool.failed)
        return LCG_FLAG_NOMEM;
    return LCG_LOAD(&e->cancel) ? LCG_FLAG_CANCELLED : 0;
}

#endif /* LCG_POOL_H */
