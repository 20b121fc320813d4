/* lcg_taylor_imp.h -- lagcodegen's runtime: the Taylor driver of constrained models with contacts
 * (inequality constraints with a coefficient of restitution; impacts, persistent contact and
 * release), model-independent: it takes a model's Taylor contact jet (lcg_taylor_contact.h) and
 * its contact table (lcg_imp_model.h, for the impact law lcg_imp_law.c). */
#ifndef LCG_TAYLOR_IMP_H
#define LCG_TAYLOR_IMP_H

#include "lcg_taylor_types.h"  /* lcg_taylor_options, lcg_taylor_stats */
#include "lcg_dae_types.h"     /* lcg_events */
#include "lcg_taylor_contact.h"
#include "lcg_imp_law.h"       /* the impact law and the kinds of the contact records */

/* Coulomb friction on the Taylor contact driver: the jet's slipping modes (slip: the
 * generated <prefix>_taylor_contact_slip's tl_slip, after the table's hold: the tangential rows
 * r with slipping[r] not held, lambda_r = wc[r] lambda_n; slipping 2: a 3-D slip, wc = -mu and
 * lambda_r = -mu d_r lambda_n with d = u/|u| in the jet), the model's friction table fr
 * (lcg_imp_model.h) and the coefficients mu[nk] (< 0: none) of the friction core lcg_imp_fric.c. */
typedef struct lcg_taylor_friction {
    void (*slip)(void *work, const int *slipping, const double *wc);
    const lcg_imp_friction *fr;
    const double *mu;
} lcg_taylor_friction;

/* Integrate the system of the jet ct and the contact table im (y = (q, q'), the index-1 system of
 * the equality rows and the contacts in persistent contact; Baumgarte stab[0] = alpha,
 * stab[1] = beta, negative: the natural rate at y0, overwritten with the values used) from
 * tout[0], y(tout[0]) = y0, with the Taylor method (opt: tolerances, order, budgets, run control;
 * atol_vec and rel_block not used); the arguments from p to n_rec as lcg_imp_solve's (lcg_imp.h):
 * yout, out (the constrained table's outputs) and lamout[k*(nj + nk) + r] at the times tout,
 * restitution e, settings set (contact_speed, min_flight, gap_tol), the modes active (in: those
 * starting in persistent contact; out: the final ones), the records rec. ev: NULL, or the system's
 * events located on the steps' polynomials (ct->event_row of each, all >= 0; ev->rootdir: the
 * directions, ev->terminal: those that end the run), as lcg_imp_solve records them. fric: NULL, or
 * Coulomb friction (planar and 3-D; the modes of the friction core lcg_imp_fric.c, lamout then nrow
 * multipliers per time and active out as lcg_imp_solve's; -85 Painleve). Returns 0, -1
 * max_steps used up, -3 the step size fell below the resolution of t (or the contacts switch
 * without end at one time), -20 out of memory, -22 bad options or tables (or an event without its
 * row), -80 cancelled, -81 out of time, or -100 - (model error code). */
int lcg_taylor_imp_solve(const lcg_taylor_contact *ct, const lcg_imp_model *im, const double *p, const double *y0,
                         int nt, const double *tout, double *yout, double *out, double *lamout,
                         const lcg_taylor_options *opt, const double *e, const double *set, int *active,
                         int max_rec, double *rec, int *n_rec, lcg_taylor_stats *st, double *stab, lcg_events *ev,
                         const lcg_taylor_friction *fric);

#endif
