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

#include "lcg_taylor_adapter.h" /* the driver on the table m, tl_table_ok */
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
