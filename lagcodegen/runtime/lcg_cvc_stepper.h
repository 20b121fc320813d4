/* lcg_cvc_stepper.h -- lagcodegen's runtime: the index-1 integration of a constrained system
 * (lcg_cvc.c's equations, eq. 4.5 at the acceleration level) that lives between calls (the
 * integrator object of lagcodegen.simulation.integrator).
 *
 * As lcg_cvode_stepper.h, on the caller's mem = (t, y[ny], p[np]) with y = (q, q'): CVODE memory
 * made once (Baumgarte stabilization, projection, root finding as lcg_cvc_solve), each call
 * advancing it to a time, over a grid, or by one internal step; a write of t, y or p restarts
 * CVODE there. Events found in a call go to the caller's record ev (reset per call); a terminal
 * one stops the call at the event. */
#ifndef LCG_CVC_STEPPER_H
#define LCG_CVC_STEPPER_H

#include <stddef.h>

#include "lcg_cvc.h"

typedef struct lcg_cvc_stepper lcg_cvc_stepper;

/* A stepper of the constrained model m on the caller's mem (which must outlive it, as must ev)
 * with the options opt (copied, with atol_vec; alpha or beta < 0: the natural rate at the initial
 * state; max_steps: the budget of one call). NULL on failure, with the reason in message. */
lcg_cvc_stepper *lcg_cvc_stepper_new(const lcg_dae_model *m, const lcg_cvc_options *opt, double *mem,
                                     lcg_events *ev, char *message, size_t size);

/* Free s and everything it owns (NULL: nothing). */
void lcg_cvc_stepper_free(lcg_cvc_stepper *s);

/* The statistics of the last call (CVODE's counters since the last restart, alpha, beta, flag,
 * message). */
lcg_cvc_stats *lcg_cvc_stepper_stats(lcg_cvc_stepper *s);

/* Advance s to t_end (>= its time), stopping exactly there; with nt > 0 the state at the grid times
 * tout[0..nt-1] (increasing, t_end = tout[nt-1]) goes to the rows of yout; with one_step, one
 * internal step (or to the next event) ending at t_end at the latest. Returns 0, a negative CVODE
 * flag, -22 bad arguments, -80, -81, or -100 - (model error code). */
int lcg_cvc_stepper_advance(lcg_cvc_stepper *s, double t_end, int nt, const double *tout, double *yout,
                            int one_step);
int lcg_cvc_stepper_until(lcg_cvc_stepper *s, double t_end);
int lcg_cvc_stepper_grid(lcg_cvc_stepper *s, int nt, const double *tout, double *yout);
int lcg_cvc_stepper_step(lcg_cvc_stepper *s, double t_limit);

#endif
