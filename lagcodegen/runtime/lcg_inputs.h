/* lcg_inputs.h -- lagcodegen's runtime: input signals u(t) read from tables.
 *
 * An input of a model is one of its run-time parameters, p[slot], whose value varies in time. A
 * table gives it as a piecewise cubic polynomial over its n breakpoints t_0 < ... < t_{n-1}
 * (zero-order hold, linear interpolation and cubic splines are all of this form; the
 * coefficients are computed once by the caller): piece 0 before t_0 and piece n from t_{n-1} on
 * hold the end values, piece k (0 < k < n) covers [t_{k-1}, t_k) and is expanded about t_{k-1}:
 *     u(t) = c[4k] + c[4k+1] s + c[4k+2] s^2 + c[4k+3] s^3,   s = t - t_{k-1}
 * (about t_0 for piece 0, t_{n-1} for piece n). A piece is right-continuous at its start.
 *
 * The drivers set p[slot] from the table at each evaluation time. They stop at each of the
 * run's restart times (in->breaks: the breakpoints where an input jumps or kinks) and start afresh
 * there (CVodeReInit), and evaluate an input at the end of a segment on the piece before the
 * restart time, so a jump or a kink of u falls on a step boundary and costs no rejected steps. Pure C99 + libm. */
#ifndef LCG_INPUTS_H
#define LCG_INPUTS_H

#include <stddef.h>

#include "lcg_inputs_types.h" /* the structs, rendered from lagcodegen/codegen/signatures.py */

/* 0 if the inputs in can drive a model of np run-time parameters (slots in range and distinct,
 * n >= 1, times finite and increasing, coefficients finite); else -22 with the reason in message. */
int lcg_inputs_check(const lcg_inputs *in, int np, char *message, size_t size);

/* Fill tab (slot, n breakpoints t[], coefficients into c[4 (n + 1)], which tab keeps pointing
 * to, as it does to t) with the zero-order hold (kind 0) or the linear interpolation (kind 1) of
 * the values v[] at t[]. Returns 0, or -22 for n < 1, times not increasing or an unknown kind. */
int lcg_input_table_fill(lcg_input_table *tab, int slot, int n, const double *t, const double *v, int kind,
                         double *c);

/* The piece of tab that holds t: the number of breakpoints <= t (0 .. n). */
int lcg_input_piece(const lcg_input_table *tab, double t);

/* The value at t of piece k of tab (its polynomial, also outside the piece's interval). */
double lcg_input_value(const lcg_input_table *tab, int k, double t);

/* p[slot] = u(t) for each table of in; left: at a breakpoint, the piece that ends there (the
 * end of a segment before a restart) rather than the one that starts there. */
void lcg_inputs_apply(const lcg_inputs *in, double t, int left, double *p);

/* The first restart time of in after t, or HUGE_VAL. */
double lcg_inputs_next_break(const lcg_inputs *in, double t);

#endif /* LCG_INPUTS_H */
