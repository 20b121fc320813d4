/* lcg_cvc.h -- lagcodegen's runtime: the native CVODE driver of the index-1
 * constrained equations of every constrained model.
 *
 * Model-independent: it integrates any constrained model through its function table
 * (lcg_dae_model.h), so it is compiled once per installation and SUNDIALS version, and a model
 * compiles only its own C. */
#ifndef LCG_CVC_H
#define LCG_CVC_H

#include <stddef.h>

#include "lcg_cvc_types.h" /* the structs, rendered from lagcodegen/codegen/signatures.py */

/* Integrate model m's y' = (q', q'') with q'' from the augmented system (m->crhs; difference-
 * quotient Jacobian) from tout[0], y(tout[0]) = y0; yout[k*ny + i] = y_i(tout[k]),
 * out[k*nout + j] = output j. ev (may be NULL when there are no root functions) receives the
 * events. Returns 0, a negative CVODE flag (-22: a table of another layout), -80 cancelled, -81
 * the wall-clock limit max_wall reached, or -100 - (model error code). */
int lcg_cvc_solve(const lcg_dae_model *m, const double *p, const double *y0, int nt, const double *tout,
                  double *yout, double *out, const lcg_cvc_options *opt, lcg_cvc_stats *st, lcg_events *ev);

/* The initial state of a run of model m in one call (no Python between the checks): y = (q0, v0)
 * taken as it is (mode 0), checked (mode 1: |f(q, t)| and |A q' + A0| within tol, the first nineq
 * root functions -- the inequalities -- at least -tol, the augmented matrix regular; then the
 * round-off removed by m->project with tol 1e-14, 50 steps) or projected (mode 2: m->project with
 * tol 1e-14, 50 steps, then the residuals within tol); in every mode the augmented system is then
 * solved at the resulting state (alpha = beta = 0). yy receives that state (ny values) or, with yp
 * not NULL, the GGL initial values: yy[ng] = (q, v, lambda, mu = 0), yp[ng] = (v, q'', 0, 0).
 * Returns 0, or 1 when a check or a model function fails (the caller then finds out why), -20 out
 * of memory, -22 a table of another layout. */
int lcg_dae_initial_state(const lcg_dae_model *m, double t, const double *y, const double *p, int mode, double tol,
                          int nineq, double *yy, double *yp);

/* Nonzero when m is a table this runtime reads (its version and sizes consistent); message
 * (size bytes, may be NULL) receives why not. */
int lcg_dae_check(const lcg_dae_model *m, char *message, size_t size);

/* The members of e (model e->model), each a run of lcg_cvc_solve with the options opt (root
 * finding with e->rootdir, e->terminal when opt->roots), over a pthread pool (ny values per state
 * row; a terminal event's state is the final one). Returns 0, -80 cancelled or -20 out of memory. */
int lcg_cvc_solve_many(lcg_cvc_ensemble *e, const lcg_cvc_options *opt);

#endif
