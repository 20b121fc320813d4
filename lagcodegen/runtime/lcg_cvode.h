/* lcg_cvode.h -- lagcodegen's runtime: the native CVODE driver of every model.
 *
 * Model-independent: it integrates any model through its function table (lcg_model.h), so it
 * is compiled once per installation and SUNDIALS version, and a model compiles only its own C. */
#ifndef LCG_CVODE_H
#define LCG_CVODE_H

#include "lcg_cvode_types.h" /* the structs, rendered from lagcodegen/codegen/signatures.py */
#include "lcg_dae_types.h"   /* lcg_events: the events found */
#include "lcg_inputs.h"

/* Integrate model m from tout[0] with y(tout[0]) = y0 and write yout[k*ny + i] = y_i(tout[k]),
 * out[k*nout + j] = output j at tout[k] (nt output times, increasing).
 * Returns 0, a negative CVODE flag (-22: bad bandwidths or a table of another layout), -80
 * cancelled, -81 the wall-clock limit max_wall reached, or -100 - (model error code). */
int lcg_cvode_solve(const lcg_model *m, const double *p, const double *y0, int nt, const double *tout,
                    double *yout, double *out, const lcg_cvode_options *opt, lcg_cvode_stats *st);

/* lcg_cvode_solve with root finding on the event functions r (NULL: none): the events found, in time
 * order, into ev (its rootdir and terminal flags apply; NULL: none recorded); a terminal event ends
 * the run (ev->terminated = 1; the rows of yout are those of the output times before it). A root
 * within rounding of tout[0] is not reported (a run restarted from the state of an event). */
int lcg_cvode_solve_events(const lcg_model *m, const lcg_ode_roots *r, const double *p, const double *y0, int nt,
                           const double *tout, double *yout, double *out, const lcg_cvode_options *opt,
                           lcg_cvode_stats *st, lcg_events *ev);

/* lcg_cvode_solve with the input tables in (NULL: none; see lcg_inputs.h): p[slot] of each table
 * follows its table; with in->restart the run stops at every breakpoint and restarts there
 * (CVodeReInit). -22 for tables that do not fit the model (st->message says why). */
int lcg_cvode_solve_inputs(const lcg_model *m, const double *p, const lcg_inputs *in, const double *y0, int nt,
                           const double *tout, double *yout, double *out, const lcg_cvode_options *opt,
                           lcg_cvode_stats *st);

/* The members of e (model e->model), each a run of lcg_cvode_solve (with the events e->roots unless
 * NULL, the member's input tables e->inputs unless NULL) with the options opt, over a pthread pool
 * (NROW = ny state values per row). Returns 0, -80 cancelled or -20 out of memory. */
int lcg_cvode_solve_many(lcg_cvode_ensemble *e, const lcg_cvode_options *opt);

/* out[k*nout + j] = output j of model m at (t[k], y[k*ny ...]) for k < nt. */
int lcg_outputs_batch(const lcg_model *m, int nt, const double *t, const double *y, const double *p, double *out);

/* ydot[ny] = f(t, y, p) of model m (y, p, ydot: arrays of double): m->rhs called once, for the
 * Python binding's rhs. cffi calls a function of the runtime directly, at less cost than through
 * the table's function pointer, and the untyped pointers take its cheapest buffers (char[]). */
int lcg_rhs_call(const lcg_model *m, double t, const void *y, const void *p, void *ydot);

/* ydot[k*ny ...] = f(t, y[k*ny ...], p[k*pstride ...]) of model m for k < nt (pstride 0: one p for
 * all; p may be NULL without run-time parameters). Returns LCG_OK, or the code of the first state
 * that fails, its index in *failed. */
int lcg_rhs_batch(const lcg_model *m, int nt, double t, const double *y, const double *p, int pstride, double *ydot,
                  int *failed);

#endif
