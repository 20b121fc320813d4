/* lcg_model.h -- lagcodegen's runtime.
 *
 * The table of a compiled model's functions: what the model-independent native drivers
 * (lcg_cvode.c, compiled once per installation) need to know of a model. Each model library
 * defines one table, <prefix>_model (file <prefix>_table.c), and <prefix>_model_table() returning
 * its address. Pure C99; no other dependency than lcg_codes.h (the result codes, generated from
 * lagcodegen/codes.py). */
#ifndef LCG_MODEL_H
#define LCG_MODEL_H

#ifdef __cplusplus
extern "C" {
#endif

/* Layout version of lcg_model: a driver refuses a table of another version. */
#define LCG_MODEL_ABI 1

/* The model functions' return codes (every model, every language): LCG_OK, LCG_ERR_SINGULAR_MASS,
 * LCG_ERR_NONFINITE of lcg_codes.h (rendered from lagcodegen/codes.py). */
#include "lcg_codes.h"

typedef struct lcg_model {
    int abi;      /* LCG_MODEL_ABI */
    int nq;       /* coordinates (a model with generalized speeds, y = (q, v, z): the speeds nv) */
    int nz;       /* quadrature states after (q, q') (generalized speeds: ny - 2 nv) */
    int ny;       /* state size 2 nq + nz */
    int np;       /* run-time parameters */
    int nout;     /* outputs */
    /* ydot[ny] = f(t, y, p) */
    int (*rhs)(double t, const double *y, const double *p, double *ydot);
    /* jac[j*ny + i] = d ydot[i] / d y[j] (ydot = f(t, y, p)); NULL: no dense Jacobian */
    int (*jac)(double t, const double *y, const double *ydot, const double *p, double *jac);
    /* out[nout] = outputs at (t, y); NULL when nout = 0 */
    int (*outputs)(double t, const double *y, const double *p, double *out);
    /* the jac_nnz structurally nonzero entries of df/dy in compressed-column order
       (rows jac_rowind[jac_colptr[j] .. jac_colptr[j + 1] - 1] of column j); NULL: none */
    int (*jac_sparse)(double t, const double *y, const double *ydot, const double *p, double *vals);
    int jac_nnz;
    const int *jac_colptr;
    const int *jac_rowind;
} lcg_model;

#ifdef __cplusplus
}
#endif

#endif /* LCG_MODEL_H */
