/* lcg_taylor_stepper.h -- lagcodegen's Taylor runtime: a Taylor integrator that lives between
 * calls (the integrator object of lagcodegen.simulation.integrator).
 *
 * It works on the caller's time, state and parameters (one array) and owns the jet's storage and
 * the model's workspace, allocated once; each call advances it: to a time (stopping exactly there), over a
 * grid of output times (dense output, as lcg_taylor_solve), or by one step. The caller may write
 * y, p and t between calls: a change of p recomputes the model's run
 * constants, a change of t restarts the double-double time. Plain C99 + libm. */
#ifndef LCG_TAYLOR_STEPPER_H
#define LCG_TAYLOR_STEPPER_H

#include <stddef.h>

#include "lcg_taylor_types.h"

typedef struct lcg_taylor_stepper lcg_taylor_stepper;

/* A stepper of model m on the caller's memory mem = (t, y[ny], p[np]) (the time, the state and the
 * parameters, which the caller may read and write between calls and which must outlive the
 * stepper), with the options opt (copied, with atol_vec) and the events record ev (NULL: events
 * are not recorded; else its arrays must outlive the stepper). NULL on failure, with the reason
 * in message. */
lcg_taylor_stepper *lcg_taylor_stepper_new(const lcg_taylor_model *m, const lcg_taylor_options *opt, double *mem,
                                           lcg_taylor_events *ev, char *message, size_t size);

/* Free s and everything it owns (NULL: nothing). */
void lcg_taylor_stepper_free(lcg_taylor_stepper *s);

/* The statistics of the last call (steps, jets, flag, message, ...). */
lcg_taylor_stats *lcg_taylor_stepper_stats(lcg_taylor_stepper *s);

/* Advance s to t_end (>= its time), the last step cut to end exactly there; with nt > 0 the state at
 * the grid times tout[0..nt-1] (increasing, in [t, t_end]) goes to the rows of yout (ny each). With
 * one_step, a single step instead, ending at t_end at the latest. A terminal event stops it at the
 * event (ev->terminated). Returns 0, or the flags of lcg_taylor_solve (-1 the step budget
 * opt->max_steps of one call used up, -3, -22 bad arguments, -80, -81, -100 - e); the state stays
 * the last one reached. */
int lcg_taylor_stepper_advance(lcg_taylor_stepper *s, double t_end, int nt, const double *tout, double *yout,
                               int one_step);

/* The same, to t_end without a grid: the call of propagate_until. */
int lcg_taylor_stepper_until(lcg_taylor_stepper *s, double t_end);

/* The same over the grid tout[0..nt-1] (t_end = tout[nt-1]; nt >= 1): the call of propagate_grid. */
int lcg_taylor_stepper_grid(lcg_taylor_stepper *s, int nt, const double *tout, double *yout);

/* One step ending at t_limit at the latest (HUGE_VAL: no limit): the call of step. */
int lcg_taylor_stepper_step(lcg_taylor_stepper *s, double t_limit);

#endif
