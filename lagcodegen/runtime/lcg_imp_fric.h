/* lcg_imp_fric.h -- lagcodegen's runtime: the solver-independent core of Coulomb friction on
 * contacts, shared by the impact drivers (lcg_imp.c: index 1 on CVODE; lcg_imp_ida.c: GGL on IDA).
 * From the model's numbers at a state (the table lcg_imp_friction of lcg_imp_model.h: M, F, the
 * rows R, s, h, gamma) it builds and solves the contact problem of each stick/slip/release mode,
 * chooses the modes of all contacts in persistent contact together by enumeration (lcg_fr_modes),
 * solves frictional impacts (lcg_fr_impact) and reports Painleve's paradox by name; see "Coulomb
 * friction" in lcg_imp_fric.c. Pure C99; no solver dependency. */
#ifndef LCG_IMP_FRIC_H
#define LCG_IMP_FRIC_H

#include <stddef.h>

#include "lcg_imp_model.h"
#include "lcg_imp_law.h" /* lcg_imp_record and the kinds of the contact records */

/* Why a contact's mode is reconsidered (lcg_fric.ending[k], lcg_fr_modes' ending): its root fired. */
#define FR_END_RELEASE 1 /* the root of lambda_n fired */
#define FR_END_STICK 2   /* the root of mu lambda_n -+ lambda_t fired */
#define FR_END_SLIP 3    /* the root of the slip velocity fired */

/* The state of Coulomb friction of one run (lcg_fr_setup): the table, the coefficients, the
 * contacts' tangential rows and modes, the model's numbers at the last state evaluated, scratch. */
typedef struct lcg_fric {
    const lcg_imp_friction *tab;
    const double *mu; /* nk: Coulomb coefficient, < 0: none (a tangent without friction sticks) */
    int n, nq, nrow; /* n: the speeds v (y = (q, v), q' = qd = k(q, v, t)); nq: the coordinates */
    int *trow;        /* nk: the tangential row of contact k, or -1 */
    int *trow2;       /* nk: its second tangential row (3-D friction, the row after trow), or -1 */
    int *fmode;       /* nk: 0 stick, +1 / -1 slipping with u > 0 / u < 0 (3-D: +1 slipping) */
    double *M, *F, *R, *s, *h, *gam, *qd, *b, *K, *rhs, *x, *lam, *bestx, *bestlam, *u, *wm, *eff;
    double *u2;       /* nk: the slip velocity along the second tangent (3-D) */
    /* 3-D friction, 2 per contact: the slip direction d (unit, in the tangents' components) of the
     * force -mu lambda_n d while slipping (dir: the current modes'; tdir: the trial mode's; bdir:
     * the chosen one's) and the reference of the slip root (dref: d where the mode began) */
    double *dir, *tdir, *bdir, *dref, *gdir; /* gdir: the first guess of a trial's d */
    double *nw;       /* fr_slip_newton's workspace: nk * nk + 8 nk */
    int *nidx;        /* nk: fr_slip_newton's unknown contacts, then its pivots (nk) */
    double vtol;      /* contact_speed: a slip velocity at most this is at rest */
    int *piv, *sel, *opts, *nopt, *tact, *tmode, *bact, *bmode, *part, *plastic, *ending;
    double det, det0; /* the determinant of the current mode's contact problem, and at its start */
} lcg_fric;

/* What the friction core works on besides its state fr: the model's contact table and
 * parameters, the Baumgarte rates of the accelerations (0, 0: none), the contacts' modes
 * active[nk] (1: persistent contact), the multipliers lam[nrow] of the chosen modes (left there
 * by lcg_fr_modes), scratch ydot[ny], and the buffer of the Painleve and error messages. */
typedef struct lcg_fric_ctx {
    const lcg_imp_model *im;
    const double *p;
    double alpha, beta;
    int *active;
    lcg_fric *fr;
    double *lam;
    double *ydot;
    char *message;
    size_t message_size;
} lcg_fric_ctx;

/* The friction state f of the table fr with the coefficients mu[nk] (< 0: none) and contact_speed
 * vtol, in one block of memory (*mem, freed by the caller); the table checked against im.
 * Returns 0, or -1 (out of memory, or a table of another layout: message in message). */
int lcg_fr_setup(lcg_fric *f, const lcg_imp_friction *fr, const lcg_imp_model *im, const double *mu, double vtol,
                 void **mem, char *message, size_t message_size);

/* The model's numbers at (t, y) into d->fr. */
int lcg_fr_eval(lcg_fric_ctx *d, double t, const double *y);

/* The slip velocity of contact k along its tangents, from the numbers in f (u2: 0 for a planar contact). */
void lcg_fr_slip(const lcg_fric *f, int k, double *u, double *u2);

/* 3-D friction: the slip directions d of the slipping contacts from the numbers in f. */
void lcg_fr_slip_directions(lcg_fric *f, int nk);

/* The right-hand side of the current modes at (t, y): ydot = (q', v'), lam[nrow] (NULL: not
 * wanted); d->fr->det the determinant of the contact problem. */
int lcg_fr_crhs(lcg_fric_ctx *d, double t, const double *y, double *ydot, double *lam);

/* The friction roots of the current modes at a state, gf[2 nk + 1]: two per contact (sticking:
 * mu lambda_n - lambda_t, mu lambda_n + lambda_t; slipping: fmode u, 1; 3-D: mu lambda_n -
 * |lambda_t| widened by FR_REL, 1 sticking and u . dref - |u| / 2, 1 slipping; 1, 1 for the
 * others), then det / det0 of the contact problem while a contact slips (else 1); all decreasing
 * through 0 where a mode ends. lam[nrow]: the multipliers at the state; d->fr's numbers (s, det)
 * evaluated there (lcg_fr_crhs) when a contact slips. */
void lcg_fr_roots(const lcg_fric_ctx *d, const double *lam, double *gf);

/* Choose the modes of the contacts in persistent contact at (t, y) by enumeration; ending[k]
 * (NULL: none) excludes the mode whose root fired. Transitions recorded; a contact that begins to
 * stick has its slip velocity projected to 0 (y's velocities changed); d->lam, d->ydot the chosen
 * modes' multipliers and right-hand side. Returns LCG_DAE_OK, a model error, or -1 with the
 * Painleve message in d->message (the caller stops with LCG_FLAG_CONTACT_MODE). */
int lcg_fr_modes(lcg_fric_ctx *d, double t, double *y, const int *ending, double vtol, double *rec, int max_rec,
                 int *n_rec);

/* The frictional impact at (t, y) of the free contacts that touch (g <= set[2]) and close (and
 * those that hit[]) with the contacts in persistent contact: y's velocities jump, modes, last[nk]
 * and records updated. Returns as lcg_fr_modes. */
int lcg_fr_impact(lcg_fric_ctx *d, double t, double *y, const int *hit, const double *e, const double *set,
                  double *last, double *rec, int max_rec, int *n_rec);

#endif
