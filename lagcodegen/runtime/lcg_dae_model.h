/* lcg_dae_model.h -- lagcodegen's runtime.
 *
 * The table of a compiled constrained model's functions (<prefix>_dae.h): what the
 * model-independent native drivers of the constrained formulations (lcg_cvc.c: index 1 on
 * CVODE; lcg_ida.c: GGL on IDA; compiled once per installation) need to know of a model. Each
 * constrained model library defines one table, <prefix>_dae_model (file <prefix>_dae_table.c),
 * and <prefix>_dae_model_table() returning its address. Pure C99; no other dependency. */
#ifndef LCG_DAE_MODEL_H
#define LCG_DAE_MODEL_H

#include "lcg_model.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Layout version of lcg_dae_model (and of lcg_events, lcg_dae_types.h): a driver refuses a table of another version. */
#define LCG_DAE_MODEL_ABI 1

/* The constrained model functions' return codes (<PREFIX>_DAE_OK, ... of every <prefix>_dae.h):
 * LCG_DAE_OK, LCG_DAE_ERR_SINGULAR, LCG_DAE_ERR_NONFINITE, LCG_DAE_ERR_PROJECTION of lcg_codes.h
 * (included by lcg_model.h). */

typedef struct lcg_dae_model {
    int abi;    /* LCG_DAE_MODEL_ABI */
    int nq;     /* coordinates */
    int ny;     /* index-1 state size nq + nv: y = (q, v), nv = ny - nq the generalized speeds (the size of
                 * M, of the rows A in v and of kkt's acc); 2 nq when v = q' (crhs writes q' = k(q, v, t)) */
    int nj;     /* equality constraints (rows of A) */
    int njh;    /* holonomic ones among them (the first njh rows) */
    int ng;     /* GGL unknowns ny + nj + njh: yy = (q, q', lambda, mu) (GGL: ny = 2 nq only) */
    int np;     /* run-time parameters */
    int nout;   /* outputs */
    int nroot;  /* root (event) functions */
    /* the functions of <prefix>_dae.h (see there) */
    int (*kkt)(double t, const double *y, const double *p, double alpha, double beta, double *acc, double *lam);
    int (*crhs)(double t, const double *y, const double *p, double alpha, double beta, double *ydot);
    int (*natural_rate)(double t, const double *y, const double *p, double *rate);
    int (*residuals)(double t, const double *y, const double *p, double *g, double *s);
    int (*project)(double t, const double *y, const double *p, double tol, int maxit, double *ynew, double *err);
    int (*coutputs)(double t, const double *y, const double *lam, const double *p, double *out);
    /* NULL when nroot = 0 */
    int (*roots)(double t, const double *y, const double *lam, const double *p, double *gout);
    /* NULL unless compiled for the GGL formulation (ggl_jac: with its Jacobian) */
    int (*ggl_res)(double t, const double *yy, const double *yp, const double *p, double *rr);
    int (*ggl_jac)(double t, double cj, const double *yy, const double *yp, const double *p, double *jac);
    /* the unconstrained model's own table (<prefix>_table.c: M q'' = F without the constraints) */
    const lcg_model *model;
} lcg_dae_model;

#ifdef __cplusplus
}
#endif

#endif /* LCG_DAE_MODEL_H */
