/* lcg_imp.h -- lagcodegen's runtime: the native CVODE driver of constrained models with
 * contacts (inequality constraints with a coefficient of restitution; impacts and persistent
 * contact), model-independent: it takes a model's contact table (lcg_imp_model.h). */
#ifndef LCG_IMP_H
#define LCG_IMP_H

#include "lcg_imp_model.h"
#include "lcg_imp_law.h" /* the impact law and the kinds of the contact records (LCG_IMP_BOUNCE, ...) */
#include "lcg_cvc_types.h" /* lcg_cvc_options, lcg_cvc_stats, lcg_events */

/* Integrate model im (y = (q, q'), index-1 with the equality constraints and the contacts in
 * persistent contact; Baumgarte opt->alpha, opt->beta, negative: the natural rate at y0) from
 * tout[0], y(tout[0]) = y0; yout[k*ny + i], out[k*nout + j] (the constrained table's outputs) and
 * lamout[k*(nj + nk) + r] (the multipliers of the equality rows and of the contacts, 0 for free
 * ones) at the times tout. e[nk]: the coefficients of restitution; set: [0] contact_speed (a
 * rebound at most this fast, or a resting start, is persistent contact), [1] min_flight (an
 * impact within this time of the contact's last one is persistent contact: accumulation), [2]
 * gap_tol (contacts with g <= gap_tol take part in an impact). active[nk]: in, the contacts that
 * start in persistent contact (those touching at rest are added); out, the final modes (contacts
 * with Coulomb friction in contact: 1 sticking, 2 slipping with u > 0, 3 with u < 0). rec:
 * max_rec records of 6 values (t, contact, kind, impulse P, w before, w after), *n_rec their
 * number (may exceed max_rec; the friction records 4..7 carry the slip velocity u = T q' + T0
 * before and after in place of w). ev: the model's events (opt->roots), may be NULL. fr: the
 * model's friction table (NULL: none; then the generated crhs and impact are used as they are),
 * mu[nk] the contacts' Coulomb coefficients (< 0: none); with fr, lamout has nrow values per time
 * (the tangential multipliers after the contacts'). Returns 0, a negative CVODE flag, -22 a table
 * of another layout, -80 cancelled, -81 out of time, -85 (LCG_FLAG_CONTACT_MODE) no unique
 * stick/slip/release mode (Painleve's paradox; st->message names it), or -100 - (model error
 * code). Projection (opt->projection) and atol_vec are not used. */
int lcg_imp_solve(const lcg_imp_model *im, const double *p, const double *y0, int nt, const double *tout,
                  double *yout, double *out, double *lamout, const lcg_cvc_options *opt, const double *e,
                  const double *set, int *active, int max_rec, double *rec, int *n_rec, lcg_cvc_stats *st,
                  lcg_events *ev, const lcg_imp_friction *fr, const double *mu);

#endif
