/* lcg_imp_law.h -- lagcodegen's runtime: the impact law of frictionless and no-slip contacts,
 * shared by the impact drivers (lcg_imp.c: index 1 on CVODE; lcg_imp_ida.c: GGL on IDA) and the
 * RK4 example of the bundles of systems with contacts, which ship this file. Through
 * a model's contact table (lcg_imp_model.h): Newton's law on the contacts that touch and close,
 * solved jointly with the equality rows and the persistent contacts (im->impact), the contacts
 * that would pull left out (the active set of the impact's complementarity problem, by
 * elimination), plastic impacts into persistent contact, and the release of persistent contacts
 * whose multiplier pulls. Pure C99. */
#ifndef LCG_IMP_LAW_H
#define LCG_IMP_LAW_H

#include "lcg_imp_model.h"

/* The kinds of the contact records (rec[] rows: t, contact, kind, impulse P, w before, w after). */
#define LCG_IMP_BOUNCE 0           /* an impact after which the contact stays free */
#define LCG_IMP_STICK 1            /* an impact that ends in persistent contact (e = 0) */
#define LCG_IMP_RELEASE 2          /* persistent contact released (its multiplier turned negative) */
#define LCG_IMP_CONTACT_IMPULSE 3  /* the impulse a persistent contact took in another's impact */
#define LCG_IMP_SLIP 4             /* friction: a sticking contact begins to slip (impulse: lambda_t) */
#define LCG_IMP_GRIP 5             /* friction: a slipping contact begins to stick (impulse: lambda_t) */
#define LCG_IMP_REVERSE 6          /* friction: a slipping contact slips the other way from rest */
#define LCG_IMP_TANGENTIAL_IMPULSE 7 /* friction: the tangential impulse P_t of a contact in an impact */

/* What the law works on: the model's contact table and parameters, the contacts' modes active[nk]
 * (1: persistent contact), restitution e[nk], the settings set[3] (contact_speed, min_flight,
 * gap_tol; see lcg_imp.h), the time of each contact's last impact last[nk], scratch gk[nk],
 * wk[nk], scratch[2 nk + nrow + ny] and rows[2 nk], and the records rec (max_rec rows, *n_rec
 * their count, which may exceed max_rec). */
typedef struct lcg_imp_law {
    const lcg_imp_model *im;
    const double *p;
    int *active;
    const double *e;
    const double *set;
    double *last;
    double *gk, *wk, *scratch;
    int *rows;
    double *rec;
    int max_rec;
    int *n_rec;
} lcg_imp_law;

/* Append one record (counted past max_rec, not stored). */
void lcg_imp_record(double *rec, int max_rec, int *n_rec, double t, int k, int kind, double P, double wm, double wp);

/* The impact at (t, y) of the free contacts that touch (g <= gap_tol) and close (w < 0), and of
 * those with hit[k]: the velocities of y (y = (q, v), ny values) replaced by the jump, the modes
 * and records updated. Returns LCG_DAE_OK or a model error. */
int lcg_imp_jump(const lcg_imp_law *L, double t, double *y, const int *hit);

/* The persistent contacts at (t, y) chosen together: those whose multiplier (im->crhs with
 * Baumgarte alpha, beta) is negative are released (recorded), one at a time; with L->set,
 * L->scratch and L->rows given, also the free contacts that touch at rest (g <= gap_tol,
 * |w| <= contact_speed) are candidates, held in persistent contact (recorded as a stick with no
 * impulse) where their normal acceleration would be negative: the contacts' linear
 * complementarity problem (lambda >= 0 held, a >= 0 free) solved by Murty's least-index rule over
 * crhs solves (the normal accelerations by a difference of the normal velocities along the
 * motion), so that a release does not leave a coupled contact to sink and bounce back (chatter);
 * the velocities of y projected by a plastic impulse onto the rows of the contacts held. The last
 * solve's ydot[ny] and lam[nrow] left in place. Returns LCG_DAE_OK or a model error. */
int lcg_imp_release_pulling(const lcg_imp_law *L, double t, double *y, double alpha, double beta, double *ydot,
                            double *lam);

/* How far a free contact's gap may go below zero before it counts as skipped by a step: -gap_tol,
 * or gap_tol below where the segment began (g0) if that was deeper than -2 gap_tol (a contact
 * released with its gap drifted below zero). */
double lcg_imp_gap_floor(double g0, double gap_tol);

/* The free contact (active[k] == 0) deepest below its floor (lcg_imp_gap_floor of gprev[k]) and
 * still closing (wk < 0): its flight skipped by a step, the solver's sign test blind to it; or -1.
 * A contact below its floor that opens again (a released contact recovering) is not one. */
int lcg_imp_below_floor(const double *gk, const double *wk, const double *gprev, const int *active, int nk,
                        double gap_tol);

#endif
