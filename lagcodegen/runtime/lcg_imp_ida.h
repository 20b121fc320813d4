/* lcg_imp_ida.h -- lagcodegen's runtime: the native IDA driver of constrained models with
 * contacts in the GGL (stabilized index-2) form, model-independent: it takes a model's contact
 * table (lcg_imp_model.h) and the table of its numbers at a state (lcg_imp_friction, whose eval
 * gives M, F, the rows R, s, h). */
#ifndef LCG_IMP_IDA_H
#define LCG_IMP_IDA_H

#include "lcg_imp.h"       /* the index-1 impact driver, the impact law (lcg_imp_law.h) */
#include "lcg_ida_types.h" /* lcg_ida_options, lcg_ida_stats, lcg_events */

/* Integrate the model of nums (nums->imp its contact table; y = (q, v), ny = nq + nv; speeds: 1
 * for a model with generalized speeds, q' = k(q, v, t), 0 for v = q', ny = 2 nq) from tout[0],
 * y(tout[0]) = y0, as the GGL residual of the equality rows and of the contacts in persistent
 * contact with their tangential rows (no slip, or sticking):
 *   q' - v - R_h^T mu (speeds: q' - k(q, v + R_h^T mu, t)),  M v' - F - R^T lambda,
 *   s_r = R_r v + R0_r (rows held),  h_r (holonomic rows held),
 * lambda_r = 0 and mu_r = 0 for the rows of free contacts; lambda, mu algebraic. Impacts
 * (lcg_imp_jump: Newton's law), persistent contact (a plastic impact) and release (the contact's
 * multiplier, an unknown of the DAE, reaching 0) as the index-1 driver lcg_imp.c applies them; at
 * each switch IDA restarts from consistent values (lambda and v' from the index-1 system of the
 * active rows, mu = 0). yout[k*ny + i], out[k*nout + j] (the constrained table's outputs) and
 * lamout[k*nrow + r] (the multipliers of every row, 0 for free ones) at the times tout. Options:
 * rtol and atol (q, v), ic_alg_atol the absolute tolerance of lambda, mu, suppress_alg,
 * max_steps (over all segments), step limits, max_order, roots (the model's events, ev), the run
 * control; jacobian, calc_ic, stop_at_outputs and atol_vec are not used (difference-quotient
 * Jacobian; outputs interpolated). e, set, active, max_rec, rec, n_rec as lcg_imp_solve
 * (lcg_imp.h). extra[2]: the segments whose flight a step skipped (located on IDA's interpolant)
 * and the deepest gap then. mu[nk]: the contacts' Coulomb coefficients (< 0: none; NULL: no
 * friction, every tangential row held with its contact). With friction (the friction core,
 * lcg_imp_fric.h) a sticking contact holds its tangential rows as GGL rows; a slipping one holds
 * its normal row only, its tangential multipliers set by Coulomb's law in the residual
 * (lambda_t = -sigma mu lambda_n; 3-D: -mu lambda_n d, d the slip direction), so that the force
 * is (G - sigma mu T)^T lambda_n; the transitions are roots (lcg_fr_roots, on the unknowns
 * lambda and the slip velocities), where the modes of all contacts are chosen together as on the
 * index-1 driver (lcg_fr_impact, lcg_fr_modes) and IDA restarts from consistent values; active
 * returns the modes as lcg_imp_solve does. Returns 0, a negative IDA flag, -22 a table of another
 * layout, -80 cancelled, -81 out of time, -85 (LCG_FLAG_CONTACT_MODE) no unique stick/slip/release
 * mode (Painleve's paradox; st->message names it), or -100 - (model error code). */
int lcg_imp_ida_solve(const lcg_imp_friction *nums, const double *p, const double *y0, int nt, const double *tout,
                      double *yout, double *out, double *lamout, const lcg_ida_options *opt, const double *e,
                      const double *set, int *active, int max_rec, double *rec, int *n_rec, lcg_ida_stats *st,
                      lcg_events *ev, double *extra, const double *mu, int speeds);

#endif
