/* lcg_imp_model.h -- lagcodegen's runtime.
 *
 * The table of a constrained model's contact functions (<prefix>_impact.c, generated for systems
 * with inequality constraints g_k(q, t) >= 0 that have a coefficient of restitution): what the
 * model-independent impact driver (lcg_imp.c) needs besides the constrained table lcg_dae_model.
 * Rows r = 0..nj-1 are the equality constraints A q' + A0 = 0 (eq. 4.2, 4.3), rows nj + k the
 * contacts G_k q' + G0_k with G_k = dg_k/dq, G0_k = dg_k/dt, the rows after them (up to nrow)
 * the tangential rows of rough contacts (no slip, or Coulomb friction: lcg_imp_friction below),
 * held with their contact while it sticks. Models with generalized speeds v (q' = k(q, v, t),
 * dae->ny = nq + nv): the rows act on v (nv columns), ydot = (k, v'), the impact jumps v; so does
 * the friction table's. Pure C99; no other dependency. */
#ifndef LCG_IMP_MODEL_H
#define LCG_IMP_MODEL_H

#include "lcg_dae_model.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Layout version of lcg_imp_model: the driver refuses a table of another version. */
#define LCG_IMP_MODEL_ABI 1

typedef struct lcg_imp_model {
    int abi; /* LCG_IMP_MODEL_ABI */
    int nq;  /* coordinates */
    int nj;  /* equality constraints */
    int nk;  /* contacts */
    int nrow; /* rows: nj + nk + the tangential rows of no-slip contacts */
    /* g[nk] = g_k(q, t), w[nk] = G_k q' + G0_k (the normal velocities) */
    int (*gaps)(double t, const double *y, const double *p, double *g, double *w);
    /* ydot[2 nq] = (q', q'') and lam[nrow] from [M R^T; R 0] [q''; -lam] = [F; gamma - stab] with
     * the rows R of the equality constraints and of the contacts with active[k] != 0 (the others:
     * lam = 0); Baumgarte stab = 2 alpha s + beta^2 g (holonomic rows, contacts), alpha s
     * (nonholonomic and tangential rows) */
    int (*crhs)(double t, const double *y, const double *p, double alpha, double beta, const int *active,
                double *ydot, double *lam);
    /* the impact of the contacts with active[k] != 0: ynew[2 nq] = (q, q' + dv) with
     * M dv = R^T P, R_r dv = -s_r (equality rows: back onto A q' + A0 = 0), G_k dv = -(1 + e_k) w_k
     * (contacts: Newton's law w+ = -e w-; tangential rows: T dv = -T q'); P[nrow] the impulses
     * (0 for inactive contacts) */
    int (*impact)(double t, const double *y, const double *p, const int *active, const double *e, double *ynew,
                  double *P);
    /* the model's constrained table (its outputs and events) */
    const lcg_dae_model *dae;
} lcg_imp_model;

/* Layout version of lcg_imp_friction. */
#define LCG_IMP_FRICTION_ABI 2

/* What the impact driver needs besides lcg_imp_model for contacts with Coulomb friction
 * (generated only for systems with a friction coefficient): the numbers of the model at a state,
 * from which the driver (lcg_imp.c) builds and solves the contact problems of each mode itself.
 * With nv = dae->ny - nq speeds v (v = q' when ny = 2 nq), eval: M[nv*nv] (full, row-major),
 * F[nv], R[nrow*nv] (the rows as in lcg_imp_model, acting on v), s[nrow] = R v + R0, h[nrow]
 * (the holonomic values: f_j, g_k; 0 for the other rows), gam[nrow] = -d/dt (R v + R0) with v'
 * excluded, qd[nq] = q' = k(q, v, t). tangent_of[nt]: the contact (0..nk-1) of each tangential
 * row nj + nk + i; a contact has one tangential row (planar friction) or two, consecutive (3-D
 * friction with the exact circular cone |lambda_t| <= mu lambda_n, lcg_imp.c). */
typedef struct lcg_imp_friction {
    int abi; /* LCG_IMP_FRICTION_ABI */
    int njh; /* holonomic equality rows (the first njh) */
    int nt;  /* tangential rows */
    const int *tangent_of;
    int (*eval)(double t, const double *y, const double *p, double *M, double *F, double *R, double *s, double *h,
                double *gam, double *qd);
    const lcg_imp_model *imp;
} lcg_imp_friction;

#ifdef __cplusplus
}
#endif

#endif /* LCG_IMP_MODEL_H */
