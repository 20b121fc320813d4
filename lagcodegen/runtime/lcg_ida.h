/* lcg_ida.h -- lagcodegen's runtime: the native IDA driver of the GGL (stabilized
 * index-2) constrained equations of every constrained model compiled for them.
 *
 * Model-independent: it integrates any constrained model through its function table
 * (lcg_dae_model.h, with ggl_res), so it is compiled once per installation and SUNDIALS version,
 * and a model compiles only its own C. */
#ifndef LCG_IDA_H
#define LCG_IDA_H

#include "lcg_ida_types.h" /* the structs, rendered from lagcodegen/codegen/signatures.py */

/* Integrate model m's GGL residual (m->ggl_res) from tout[0] with yy(tout[0]) = yy0,
 * yp(tout[0]) = yp0 (guesses for lambda, mu and yp when calc_ic is set); yout[k*ng + i] =
 * yy_i(tout[k]) (row 0: the consistent initial values), out[k*nout + j] = output j (lambda from
 * the state). ev (may be NULL) receives the events, with ev->y rows of ng values.
 * Returns 0, a negative IDA flag (-22: a table of another layout or without the GGL residual),
 * -80 cancelled, -81 the wall-clock limit max_wall reached, or -100 - (model error code). */
int lcg_ida_solve(const lcg_dae_model *m, const double *p, const double *yy0, const double *yp0, int nt,
                  const double *tout, double *yout, double *out, const lcg_ida_options *opt, lcg_ida_stats *st,
                  lcg_events *ev);

/* The members of e (model e->model), each a run of lcg_ida_solve with the options opt (root
 * finding with e->rootdir, e->terminal when opt->roots), over a pthread pool (ng values per state
 * row; a terminal event's state is the final one). Returns 0, -80 cancelled or -20 out of memory. */
int lcg_ida_solve_many(lcg_ida_ensemble *e, const lcg_ida_options *opt);

#endif
