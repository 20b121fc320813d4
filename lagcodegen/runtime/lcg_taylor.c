/* lcg_taylor.c -- lagcodegen's Taylor runtime, compiled as it is.
 *
 * The Taylor-series driver of every model (see lcg_taylor.h): step size, dense output, event
 * location, run control and ensembles, calling the model's jet through its table
 * (lcg_taylor_model.h). No model is compiled into it.
 *
 * Step size (Jorba & Zou): with w_i = atol_i + rtol |y_i(t_n)|,
 *   h = s min( min_i (w_i / |y_i,[p]|)^(1/p), min_i (w_i / |y_i,[p-1]|)^(1/(p-1)) ),
 * where with options.rel_block = b > 0 the components from b on take the largest |y_j(t_n)| of
 * their block of b (a run's sensitivities along one direction: a component crossing zero while
 * the others are large is measured against the direction's size, not asked for atol),
 * s = exp(-0.7 / (p - 1)) (see tl_safety for a cap at high order), at most 100 times the
 * previous step and max_step; orders whose coefficients all vanish (polynomial solutions) do
 * not limit it. Order p = ceil(-ln(tol)/2 + 3) (tl_order), tol = rtol (the smallest atol if
 * rtol = 0).
 */
#include "lcg_control.h" /* first: POSIX */

#include <float.h>
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "lcg_taylor.h"

/* The driver's runtime-only parts (lcg_taylor_driver.h): the table check, tolerances by blocks. */
#define LCG_TAYLOR_RUNTIME 1

/* The sizes and functions of the model m (the driver's argument) for the driver (lcg_taylor_driver.h). */
#define NY (m->ny)
#define NE (m->ne)
#define NOUT (m->nout)
#define NROW (m->nrows)
#define P_MAX LCG_TAYLOR_ORDER_MAX
#define PS (P_MAX + 2)
#define TL_WORK_SIZE (m->work_size)
#define TL_START(work, p) m->start(work, p)
#define TL_JET(work, X, t, y, kmax) m->jet(work, X, t, y, kmax)
#define TL_OUTPUTS(t, y, p, out) (m->outputs != NULL ? m->outputs(t, y, p, out) : 0)
#define TL_EVENT_ROW(e) (m->event_row[e])
#define TL_EVENT_DIRECTION(e) (m->event_direction[e])
#define TL_EVENT_TERMINAL(e) (m->event_terminal[e])

/* A table this driver can use: its version and order limit, consistent sizes. */
static int tl_table_ok(const lcg_taylor_model *m)
{
    return m != NULL && m->abi == LCG_TAYLOR_ABI && m->order_max == LCG_TAYLOR_ORDER_MAX && m->nq >= 0
        && m->nz >= 0 && m->ny == 2 * m->nq + m->nz && m->ny > 0 && m->nrows >= m->ny + m->nq && m->nout >= 0
        && m->ne >= 0 && m->start != NULL && m->jet != NULL && (m->nout == 0 || m->outputs != NULL)
        && (m->ne == 0 || (m->event_row != NULL && m->event_direction != NULL && m->event_terminal != NULL));
}

/* Step size, dense output, event location, the step, the run loop and the jet entry point (a file
 * of lagcodegen/runtime/, shared with the stepper lcg_taylor_stepper.c, which includes this file). */
#include "lcg_taylor_driver.h"

#undef NROW
#undef NOUT
/* The ensemble pool's row sizes (lcg_pool.h): the model of the ensemble e. */
#define NROW (e->model->ny)
#define NOUT (e->model->nout)
#define NOUTD (NOUT > 0 ? NOUT : 1)

#define COUNTS(c, st) (c[0] = (st)->nsteps, c[1] = (st)->njet, c[2] = 0, c[3] = 0, c[4] = 0)

#define LCG_POOL_ENSEMBLE lcg_taylor_ensemble
#define LCG_POOL_OPTIONS lcg_taylor_options
#define LCG_POOL_STATS lcg_taylor_stats
#define LCG_POOL_SOLVE_MANY lcg_taylor_solve_many
#include "lcg_pool.h"

static int pool_member(lcg_taylor_ensemble *e, const double *pi, const double *y0i, const double *yp0i,
                       const lcg_taylor_options *o, lcg_taylor_stats *st, double *yout, double *out, pool_scratch *s)
{
    (void)yp0i;
    (void)s;
    return lcg_taylor_solve(e->model, pi, y0i, e->nt, e->tout, yout, out, o, st, NULL);
}
