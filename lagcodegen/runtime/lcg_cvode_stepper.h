/* lcg_cvode_stepper.h -- lagcodegen's runtime: a CVODE integration that lives between calls (the
 * integrator object of lagcodegen.simulation.integrator).
 *
 * It works on the caller's time, state and parameters (one array, mem = (t, y[ny], p[np])) and
 * owns the CVODE memory, vectors and linear solver, made once; each call advances it: to a time
 * (CVODE's stop time there, so that it never evaluates the model past it), over a grid of output
 * times (as lcg_cvode_solve), or by one internal step. The caller may write t, y and p between
 * calls: the next call then restarts CVODE there (CVodeReInit), as a new run would. With event
 * functions (lcg_cvode_stepper_new_events), CVODE's root finding as lcg_cvode_solve_events: the
 * events found in a call go to the caller's record (reset per call); a terminal one stops the call
 * at the event, and the next call goes on from there without finding it again. */
#ifndef LCG_CVODE_STEPPER_H
#define LCG_CVODE_STEPPER_H

#include <stddef.h>

#include "lcg_cvode.h" /* lcg_cvode_types.h, lcg_ode_roots, lcg_events */

typedef struct lcg_cvode_stepper lcg_cvode_stepper;

/* A stepper of model m on the caller's mem (which must outlive it) with the options opt (copied,
 * with atol_vec; max_steps: the step budget of one call). NULL on failure, with the reason in
 * message. */
lcg_cvode_stepper *lcg_cvode_stepper_new(const lcg_model *m, const lcg_cvode_options *opt, double *mem,
                                         char *message, size_t size);

/* The same with the event functions r (NULL: none) located and recorded into ev (its rootdir and
 * terminal flags apply; it must outlive s; NULL: no root finding). */
lcg_cvode_stepper *lcg_cvode_stepper_new_events(const lcg_model *m, const lcg_ode_roots *r,
                                                const lcg_cvode_options *opt, double *mem, lcg_events *ev,
                                                char *message, size_t size);

/* Free s and everything it owns (NULL: nothing). */
void lcg_cvode_stepper_free(lcg_cvode_stepper *s);

/* The statistics of the last call (CVODE's counters since the last restart, flag, message). */
lcg_cvode_stats *lcg_cvode_stepper_stats(lcg_cvode_stepper *s);

/* Advance s to t_end (>= its time), stopping exactly there; with nt > 0 the state at the grid times
 * tout[0..nt-1] (increasing, in [t, t_end], t_end = tout[nt-1]) goes to the rows of yout. With
 * one_step, one internal step of CVODE (or to the next event), ending at t_end at the latest. A
 * terminal event stops the call there (the rows of yout before it are written). Returns 0, a negative CVODE
 * flag, -22 bad arguments, -80, -81, or -100 - (model error code); the state is the last one
 * reached. */
int lcg_cvode_stepper_advance(lcg_cvode_stepper *s, double t_end, int nt, const double *tout, double *yout,
                              int one_step);

/* The same, to t_end without a grid: the call of propagate_until. */
int lcg_cvode_stepper_until(lcg_cvode_stepper *s, double t_end);

/* The same over the grid tout[0..nt-1] (t_end = tout[nt-1]; nt >= 1): the call of propagate_grid. */
int lcg_cvode_stepper_grid(lcg_cvode_stepper *s, int nt, const double *tout, double *yout);

/* One step ending at t_limit at the latest (HUGE_VAL: no limit): the call of step. */
int lcg_cvode_stepper_step(lcg_cvode_stepper *s, double t_limit);

#endif
