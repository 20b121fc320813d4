/* lcg_cvsens_stepper.h -- lagcodegen's runtime: a CVODE integration with forward sensitivities
 * that lives between calls (the integrator object of lagcodegen.simulation.integrator made with
 * sensitivities).
 *
 * It works on the caller's time, state and parameters (one array, mem = (t, y[ny], p[np])) and
 * the caller's sensitivities s[j*ny + i] = dy_i/dtheta_j (ns directions), and owns the CVODE
 * memory of the augmented ODE and its block Newton solver (lcg_cvsens.c), made once; each call
 * advances it: to a time (CVODE's stop time there), over a grid of output times (the states and
 * sensitivities there, as lcg_cvsens_solve gives them), or by one internal step. The caller may
 * write t, y, p and s between calls: the next call then restarts CVODE there (CVodeReInit, the
 * states' Jacobian evaluated anew), as a new run would -- e.g. s set to zero restarts the
 * sensitivities from the current time. With event functions (ev not NULL), CVODE's root finding as
 * lcg_cvsens_solve_events: the events found in a call go to ev (reset per call); a terminal one
 * stops the call at the event, and the next call goes on from there without finding it again. */
#ifndef LCG_CVSENS_STEPPER_H
#define LCG_CVSENS_STEPPER_H

#include <stddef.h>

#include "lcg_cvsens.h"

typedef struct lcg_cvsens_stepper lcg_cvsens_stepper;

/* A stepper of model m with the sensitivity functions sens_rhs, ns directions which[ns] (copied),
 * on the caller's mem and s (ns*ny; both must outlive it), with the options opt (copied, with its
 * ny (1 + ns) absolute tolerances; max_steps: the step budget of one call) and the events ev (NULL:
 * none; it must outlive s). NULL on failure, with the reason in message. */
lcg_cvsens_stepper *lcg_cvsens_stepper_new(const lcg_model *m, lcg_sens_rhs_fn sens_rhs, int ns, const int *which,
                                           const lcg_cvsens_options *opt, double *mem, double *s,
                                           lcg_cvsens_events *ev, char *message, size_t size);

/* Free st and everything it owns (NULL: nothing). */
void lcg_cvsens_stepper_free(lcg_cvsens_stepper *st);

/* The statistics of the last call (CVODE's counters since the last restart, flag, message). */
lcg_cvsens_stats *lcg_cvsens_stepper_stats(lcg_cvsens_stepper *st);

/* Advance to t_end (>= its time), stopping exactly there; with nt > 0 the state and sensitivities
 * at the grid times tout[0..nt-1] (increasing, in [t, t_end], t_end = tout[nt-1]) go to
 * yout[k*ny + i] and sout[(k*ns + j)*ny + i]. With one_step, one internal step of CVODE (or to the
 * next event), ending at t_end at the latest. Returns 0, a negative CVODE flag, -22 bad arguments,
 * -80, -81, or -100 - (model error code); the state is the last one reached. */
int lcg_cvsens_stepper_advance(lcg_cvsens_stepper *st, double t_end, int nt, const double *tout, double *yout,
                               double *sout, int one_step);

/* The same, to t_end without a grid: the call of propagate_until. */
int lcg_cvsens_stepper_until(lcg_cvsens_stepper *st, double t_end);

/* The same over the grid tout[0..nt-1] (nt >= 1): the call of propagate_grid. */
int lcg_cvsens_stepper_grid(lcg_cvsens_stepper *st, int nt, const double *tout, double *yout, double *sout);

/* One step ending at t_limit at the latest (HUGE_VAL: no limit): the call of step. */
int lcg_cvsens_stepper_step(lcg_cvsens_stepper *st, double t_limit);

#endif
