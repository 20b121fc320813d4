/* lcg_taylor.h -- lagcodegen's Taylor runtime: the Taylor-series driver of every model.
 *
 * Model-independent: it integrates any model through the table of its Taylor jet
 * (lcg_taylor_model.h), so it is compiled once per installation, and a model compiles only its
 * jet. Each step computes the normalized Taylor coefficients y_[k] = y^(k)(t)/k!, k <= order,
 * chooses the step h from the last two coefficients (Jorba & Zou) and advances y by the
 * polynomial; output times inside a step are evaluations of that polynomial, events roots of
 * the event functions' polynomials. Plain C99 + libm + pthreads (ensembles). */
#ifndef LCG_TAYLOR_H
#define LCG_TAYLOR_H

#include "lcg_taylor_types.h" /* the structs, rendered from lagcodegen/codegen/signatures.py */

/* Integrate model m from tout[0] with y(tout[0]) = y0 to tout[nt-1]; yout[k*ny + i] = y_i(tout[k]),
 * out[k*nout + j] = output j at tout[k] (out may be NULL when nout = 0; ev may be NULL).
 * Returns 0; -1 max_steps used up; -3 the step size fell below the resolution of t;
 * -20 out of memory; -22 bad options or a table of another layout; -80 cancelled; -81 the
 * wall-clock limit max_wall reached; -100 - e for model error e (1 singular mass matrix,
 * 2 non-finite value). st->message explains failures. */
int lcg_taylor_solve(const lcg_taylor_model *m, const double *p, const double *y0, int nt, const double *tout,
                     double *yout, double *out, const lcg_taylor_options *opt, lcg_taylor_stats *st,
                     lcg_taylor_events *ev);

/* Normalized Taylor coefficients of model m at (t, y) up to order (<= LCG_TAYLOR_ORDER_MAX):
 * jet[i*(order+1) + k] = y_i^(k)(t)/k!. Returns 0, a model error code (1, 2), -20 out of memory
 * or -22 a bad order or table. */
int lcg_taylor_jet(const lcg_taylor_model *m, double t, const double *y, const double *p, int order, double *jet);

/* The members of e (model e->model), each a run of lcg_taylor_solve (no events) with the options
 * opt, over a pthread pool (NROW = ny state values per row). Returns 0, -80 cancelled or -20 out
 * of memory. */
int lcg_taylor_solve_many(lcg_taylor_ensemble *e, const lcg_taylor_options *opt);

#endif
