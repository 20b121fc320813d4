/* lcg_ida_stepper.h -- lagcodegen's runtime: the GGL integration of a constrained system on IDA
 * (lcg_ida.c's equations, eq. 4.5 in the stabilized index-2 form) that lives between calls (the
 * integrator object of lagcodegen.simulation.integrator).
 *
 * On the caller's mem = (t, y[ny], p[np]) with y = (q, v): the IDA memory, the unknowns
 * yy = (q, v, lambda, mu) and yy' made once; each call advances it to a time, over a grid (rows
 * of y), or by one internal step. A write of t, y or p restarts IDA there: y projected onto the
 * constraints, lambda and yy' from the augmented system (lcg_dae_initial_state), polished by
 * IDACalcIC before the next step, as a new run starts. Events as lcg_cvc_stepper.h. */
#ifndef LCG_IDA_STEPPER_H
#define LCG_IDA_STEPPER_H

#include <stddef.h>

#include "lcg_ida.h"

typedef struct lcg_ida_stepper lcg_ida_stepper;

/* A stepper of the constrained model m on the caller's mem (which must outlive it, as must ev)
 * from the initial values yy0, yp0 (ng each: consistent, or guesses of lambda, mu and yy' that
 * IDACalcIC polishes when opt->calc_ic) with the options opt (copied, with atol_vec of ng values;
 * max_steps: the budget of one call). NULL on failure, with the reason in message. */
lcg_ida_stepper *lcg_ida_stepper_new(const lcg_dae_model *m, const lcg_ida_options *opt, double *mem,
                                     const double *yy0, const double *yp0, lcg_events *ev, char *message,
                                     size_t size);

/* Free s and everything it owns (NULL: nothing). */
void lcg_ida_stepper_free(lcg_ida_stepper *s);

/* The statistics of the last call (IDA's counters since the last restart, flag, message). */
lcg_ida_stats *lcg_ida_stepper_stats(lcg_ida_stepper *s);

/* The current unknowns yy = (q, v, lambda, mu) (ng values; lambda, mu as the last step left them). */
const double *lcg_ida_stepper_unknowns(lcg_ida_stepper *s);

/* Advance s to t_end (>= its time), stopping exactly there; with nt > 0 the state y at the grid
 * times tout[0..nt-1] (increasing, t_end = tout[nt-1]) goes to the rows of yout (ny each); with
 * one_step, one internal step (or to the next event) ending at t_end at the latest. Returns 0, a
 * negative IDA flag, -22 bad arguments (or a written state off the constraints), -80, -81, or
 * -100 - (model error code). */
int lcg_ida_stepper_advance(lcg_ida_stepper *s, double t_end, int nt, const double *tout, double *yout,
                            int one_step);
int lcg_ida_stepper_until(lcg_ida_stepper *s, double t_end);
int lcg_ida_stepper_grid(lcg_ida_stepper *s, int nt, const double *tout, double *yout);
int lcg_ida_stepper_step(lcg_ida_stepper *s, double t_limit);

#endif
