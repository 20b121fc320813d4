/* lcg_dopri.h -- an explicit Runge-Kutta integrator with error control: the embedded pair of
 * Dormand and Prince, orders 5(4), with the PI step size controller of Hairer, Norsett and
 * Wanner (Solving Ordinary Differential Equations I, sec. II.4 and II.5, the DOPRI5 code).
 * C99 + libm; part of lagcodegen's FMUs (their Co-Simulation steps), independent of any model.
 */
#ifndef LCG_DOPRI_H
#define LCG_DOPRI_H

#ifdef __cplusplus
extern "C" {
#endif

/* ydot[n] = f(t, y); returns 0, or a nonzero code of the caller's (the step is then retried
 * with half the step size, and the call fails when f fails at its starting point). */
typedef int (*lcg_dopri_rhs)(void *data, double t, const double *y, double *ydot);

#define LCG_DOPRI_OK 0
#define LCG_DOPRI_ERR_RHS 1             /* f failed at the starting point (code in rhs_code) */
#define LCG_DOPRI_ERR_TOO_MANY_STEPS 2  /* max_steps steps did not reach t_end */
#define LCG_DOPRI_ERR_STEP_TOO_SMALL 3  /* the step size fell below the resolution of t */

typedef struct {
    int n;
    double rtol, atol;   /* error test: |err_i| <= atol + rtol max(|y_i|, |y1_i|) (RMS norm) */
    double h;            /* step size for the next step; 0: chosen by the starting-step heuristic */
    double hmax;         /* largest step (0: unlimited) */
    double facold;       /* the controller's error of the last accepted step */
    long max_steps;      /* steps per call of lcg_dopri_advance */
    long steps, rejected, evaluations;  /* counters, summed over calls */
    int rhs_code;        /* the code f returned when the call failed with LCG_DOPRI_ERR_RHS */
    double *k[7], *y1, *ysti;
} lcg_dopri;

/* Number of doubles of the work array for n equations. */
#define LCG_DOPRI_WORK(n) (9 * (n))

/* Set up for n equations with the caller's work array (LCG_DOPRI_WORK(n) doubles). */
void lcg_dopri_init(lcg_dopri *s, int n, double *work, double rtol, double atol);

/* Integrate y' = f(t, y) from *t to t_end (> *t), stepping exactly onto t_end; *t and y[n] are
 * updated to the last accepted step (t_end on success). Returns LCG_DOPRI_OK or an error code. */
int lcg_dopri_advance(lcg_dopri *s, lcg_dopri_rhs f, void *data, double *t, double *y, double t_end);

#ifdef __cplusplus
}
#endif

#endif /* LCG_DOPRI_H */
