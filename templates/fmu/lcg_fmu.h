/* lcg_fmu.h -- the model-independent core of lagcodegen's FMUs: one instance of a model
 * y' = f(t, y, p) (states, run-time parameters and inputs, outputs) behind the value references
 * of its modelDescription.xml, and its Co-Simulation step (lcg_dopri.h). The FMI 2.0 and 3.0
 * functions (lcg_fmi2.c, lcg_fmi3.c) call it; the generated lcg_fmu_model.c states the model.
 * C99 + libm.
 *
 * Value references (one Float64/Real variable each):
 *   0                          time (the independent variable)
 *   1 .. nx                    the continuous states y
 *   nx+1 .. 2 nx               their derivatives der(y)
 *   2 nx+1 .. 2 nx+np          the model's run-time parameters and inputs, in p order
 *   2 nx+np+1 .. 2 nx+np+nout  the outputs
 */
#ifndef LCG_FMU_H
#define LCG_FMU_H

#include <stddef.h>

#include "lcg_dopri.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The generated model functions (see <prefix>.h): 0 on success, else an error code. */
typedef int (*lcg_fmu_rhs_fn)(double t, const double *y, const double *p, double *ydot);
typedef int (*lcg_fmu_outputs_fn)(double t, const double *y, const double *p, double *out);

/* What lcg_fmu_model.c states about the model. */
typedef struct {
    const char *identifier;    /* modelIdentifier */
    const char *token;         /* guid (FMI 2.0) / instantiationToken (FMI 3.0) */
    int nx, np, nout;
    const double *x_start;     /* nx start values of the states */
    const double *p_start;     /* np start values of the parameters and inputs */
    double tolerance;          /* default relative tolerance of the Co-Simulation integrator */
    lcg_fmu_rhs_fn rhs;
    lcg_fmu_outputs_fn outputs;  /* NULL when nout is 0 */
    int nwork;                 /* doubles after p[np] that no value reference names (start's results) */
    /* Called when initialization ends, with the initial state and p (of np + nwork doubles), or NULL:
     * e.g. the Baumgarte rates of a constrained model's "auto" stabilization. 0 or an error code. */
    int (*start)(double t, const double *x, double *p);
} lcg_fmu_model;

extern const lcg_fmu_model lcg_fmu_this_model;

/* The kinds of variable a value reference names. */
enum { LCG_FMU_TIME, LCG_FMU_STATE, LCG_FMU_DERIVATIVE, LCG_FMU_PARAMETER, LCG_FMU_OUTPUT, LCG_FMU_UNKNOWN };

typedef struct {
    const lcg_fmu_model *m;
    double t;
    double *x, *p, *dx, *out, *work;
    int valid;                 /* dx and out hold the values at (t, x, p) */
    int started;               /* m->start has run since the last reset or initialization */
    double rtol, atol;         /* Co-Simulation tolerances */
    lcg_dopri ode;
    char message[256];         /* what went wrong, for the importer's log */
} lcg_fmu_instance;

/* A new instance at the start values (NULL when out of memory); lcg_fmu_free releases it. */
lcg_fmu_instance *lcg_fmu_new(const lcg_fmu_model *m);
void lcg_fmu_free(lcg_fmu_instance *inst);
/* Back to the start values (time 0, the default tolerance). */
void lcg_fmu_reset(lcg_fmu_instance *inst);
/* The Co-Simulation tolerance: relative rtol (> 0), absolute rtol * 1e-3. */
void lcg_fmu_set_tolerance(lcg_fmu_instance *inst, double rtol);

/* The kind of value reference vr, and its index within that kind in *index. */
int lcg_fmu_kind(const lcg_fmu_instance *inst, unsigned int vr, int *index);
/* Read one variable (derivatives and outputs are evaluated when needed): 0, or -1 with
 * inst->message set. */
int lcg_fmu_get(lcg_fmu_instance *inst, unsigned int vr, double *value);
/* Write one variable (time, states, parameters and inputs): 0, or -1 with inst->message set. */
int lcg_fmu_set(lcg_fmu_instance *inst, unsigned int vr, double value);
/* Initialization ends: run m->start at (t, x, p). 0 or -1. */
int lcg_fmu_start(lcg_fmu_instance *inst);
/* Evaluate the derivatives and outputs at (t, x, p) unless they are current: 0 or -1. */
int lcg_fmu_eval(lcg_fmu_instance *inst);
/* Integrate from t_start to t_end with the inputs held (Co-Simulation): 0 or -1. */
int lcg_fmu_step(lcg_fmu_instance *inst, double t_start, double t_end);
/* The experiment: the start time and, when tolerance_defined, the tolerance (lcg_fmu_set_tolerance). */
void lcg_fmu_experiment(lcg_fmu_instance *inst, int tolerance_defined, double rtol, double t_start);
/* The time (Model Exchange): derivatives and outputs are evaluated again when read. */
void lcg_fmu_set_time(lcg_fmu_instance *inst, double t);
/* The continuous states x (m->nx values; Model Exchange). */
void lcg_fmu_set_states(lcg_fmu_instance *inst, const double *x);

#ifdef __cplusplus
}
#endif

#endif /* LCG_FMU_H */
