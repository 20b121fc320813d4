/* lcg_fmu_core.c -- one instance of an FMU's model (see lcg_fmu.h). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "lcg_fmu.h"

/* The model functions' error codes (<prefix>.h). */
static const char *model_error(int code)
{
    switch (code) {
    case 1:
        return "the mass matrix M(q, t) (constrained: the augmented matrix [M A^T; A 0]) is singular at this state";
    case 2:
        return "a computed value is not finite (overflow, division by zero, domain error)";
    case 3:
        return "the projection onto the constraints did not converge";
    default:
        return "the model function failed";
    }
}

lcg_fmu_instance *lcg_fmu_new(const lcg_fmu_model *m)
{
    lcg_fmu_instance *inst = (lcg_fmu_instance *)calloc(1, sizeof *inst);
    const size_t nx = (size_t)m->nx, np = (size_t)m->np, nout = (size_t)m->nout;

    if (inst == NULL)
        return NULL;
    inst->m = m;
    /* one block: x, dx, p, out, the integrator's work (at least one double each) */
    inst->x = (double *)calloc(2 * nx + np + (size_t)m->nwork + nout + (size_t)LCG_DOPRI_WORK(m->nx) + 4,
                               sizeof(double));
    if (inst->x == NULL) {
        free(inst);
        return NULL;
    }
    inst->dx = inst->x + nx;
    inst->p = inst->dx + nx + 1;
    inst->out = inst->p + np + (size_t)m->nwork + 1;
    inst->work = inst->out + nout + 1;
    lcg_fmu_reset(inst);
    return inst;
}

void lcg_fmu_free(lcg_fmu_instance *inst)
{
    if (inst == NULL)
        return;
    free(inst->x);
    free(inst);
}

void lcg_fmu_reset(lcg_fmu_instance *inst)
{
    const lcg_fmu_model *m = inst->m;

    inst->t = 0.0;
    if (m->nx)
        memcpy(inst->x, m->x_start, (size_t)m->nx * sizeof(double));
    if (m->np)
        memcpy(inst->p, m->p_start, (size_t)m->np * sizeof(double));
    if (m->nwork)
        memset(inst->p + m->np, 0, (size_t)m->nwork * sizeof(double));
    inst->valid = 0;
    inst->started = 0;
    inst->message[0] = '\0';
    lcg_fmu_set_tolerance(inst, m->tolerance);
}

void lcg_fmu_set_tolerance(lcg_fmu_instance *inst, double rtol)
{
    if (!(rtol > 0.0) || !isfinite(rtol))
        rtol = inst->m->tolerance;
    inst->rtol = rtol;
    inst->atol = rtol * 1e-3;
    lcg_dopri_init(&inst->ode, inst->m->nx, inst->work, inst->rtol, inst->atol);
}

int lcg_fmu_kind(const lcg_fmu_instance *inst, unsigned int vr, int *index)
{
    const lcg_fmu_model *m = inst->m;
    unsigned long k = vr;

    *index = 0;
    if (k == 0)
        return LCG_FMU_TIME;
    k -= 1;
    if (k < (unsigned long)m->nx) {
        *index = (int)k;
        return LCG_FMU_STATE;
    }
    k -= (unsigned long)m->nx;
    if (k < (unsigned long)m->nx) {
        *index = (int)k;
        return LCG_FMU_DERIVATIVE;
    }
    k -= (unsigned long)m->nx;
    if (k < (unsigned long)m->np) {
        *index = (int)k;
        return LCG_FMU_PARAMETER;
    }
    k -= (unsigned long)m->np;
    if (k < (unsigned long)m->nout) {
        *index = (int)k;
        return LCG_FMU_OUTPUT;
    }
    return LCG_FMU_UNKNOWN;
}

int lcg_fmu_start(lcg_fmu_instance *inst)
{
    const lcg_fmu_model *m = inst->m;
    int code = m->start != NULL ? m->start(inst->t, inst->x, inst->p) : 0;

    inst->valid = 0;
    if (code != 0) {
        snprintf(inst->message, sizeof inst->message, "%s: at the initial state (t = %.17g) %s (code %d)",
                 m->identifier, inst->t, model_error(code), code);
        return -1;
    }
    inst->started = 1;
    return 0;
}

int lcg_fmu_eval(lcg_fmu_instance *inst)
{
    const lcg_fmu_model *m = inst->m;
    int code;

    if (!inst->started && lcg_fmu_start(inst) != 0)
        return -1;
    if (inst->valid)
        return 0;
    code = m->rhs(inst->t, inst->x, inst->p, inst->dx);
    if (code == 0 && m->nout > 0 && m->outputs != NULL)
        code = m->outputs(inst->t, inst->x, inst->p, inst->out);
    if (code != 0) {
        snprintf(inst->message, sizeof inst->message, "%s: at t = %.17g %s (code %d)", m->identifier, inst->t,
                 model_error(code), code);
        return -1;
    }
    inst->valid = 1;
    return 0;
}

int lcg_fmu_get(lcg_fmu_instance *inst, unsigned int vr, double *value)
{
    int i;

    switch (lcg_fmu_kind(inst, vr, &i)) {
    case LCG_FMU_TIME:
        *value = inst->t;
        return 0;
    case LCG_FMU_STATE:
        *value = inst->x[i];
        return 0;
    case LCG_FMU_PARAMETER:
        *value = inst->p[i];
        return 0;
    case LCG_FMU_DERIVATIVE:
        if (lcg_fmu_eval(inst) != 0)
            return -1;
        *value = inst->dx[i];
        return 0;
    case LCG_FMU_OUTPUT:
        if (lcg_fmu_eval(inst) != 0)
            return -1;
        *value = inst->out[i];
        return 0;
    default:
        snprintf(inst->message, sizeof inst->message, "%s: no Float64 variable has value reference %u",
                 inst->m->identifier, vr);
        return -1;
    }
}

int lcg_fmu_set(lcg_fmu_instance *inst, unsigned int vr, double value)
{
    int i;

    switch (lcg_fmu_kind(inst, vr, &i)) {
    case LCG_FMU_TIME:
        inst->t = value;
        break;
    case LCG_FMU_STATE:
        inst->x[i] = value;
        break;
    case LCG_FMU_PARAMETER:
        inst->p[i] = value;
        break;
    case LCG_FMU_DERIVATIVE:
    case LCG_FMU_OUTPUT:
        snprintf(inst->message, sizeof inst->message, "%s: the variable of value reference %u is computed by "
                 "the model and cannot be set", inst->m->identifier, vr);
        return -1;
    default:
        snprintf(inst->message, sizeof inst->message, "%s: no Float64 variable has value reference %u",
                 inst->m->identifier, vr);
        return -1;
    }
    inst->valid = 0;
    return 0;
}

static int ode_rhs(void *data, double t, const double *y, double *ydot)
{
    const lcg_fmu_instance *inst = (const lcg_fmu_instance *)data;
    return inst->m->rhs(t, y, inst->p, ydot);
}

void lcg_fmu_experiment(lcg_fmu_instance *inst, int tolerance_defined, double rtol, double t_start)
{
    if (tolerance_defined)
        lcg_fmu_set_tolerance(inst, rtol);
    lcg_fmu_set_time(inst, t_start);
}

void lcg_fmu_set_time(lcg_fmu_instance *inst, double t)
{
    inst->t = t;
    inst->valid = 0;
}

void lcg_fmu_set_states(lcg_fmu_instance *inst, const double *x)
{
    if (inst->m->nx > 0)
        memcpy(inst->x, x, (size_t)inst->m->nx * sizeof(double));
    inst->valid = 0;
}

int lcg_fmu_step(lcg_fmu_instance *inst, double t_start, double t_end)
{
    const lcg_fmu_model *m = inst->m;
    int code;

    inst->t = t_start;
    if (!inst->started && lcg_fmu_start(inst) != 0)
        return -1;
    inst->valid = 0;
    if (m->nx == 0) {
        inst->t = t_end;
        return 0;
    }
    code = lcg_dopri_advance(&inst->ode, ode_rhs, inst, &inst->t, inst->x, t_end);
    switch (code) {
    case LCG_DOPRI_OK:
        return 0;
    case LCG_DOPRI_ERR_RHS:
        snprintf(inst->message, sizeof inst->message, "%s: at t = %.17g %s (code %d)", m->identifier, inst->t,
                 model_error(inst->ode.rhs_code), inst->ode.rhs_code);
        return -1;
    case LCG_DOPRI_ERR_TOO_MANY_STEPS:
        snprintf(inst->message, sizeof inst->message, "%s: %ld Runge-Kutta steps did not reach t = %.17g from "
                 "t = %.17g (tolerance %g)", m->identifier, inst->ode.max_steps, t_end, inst->t, inst->rtol);
        return -1;
    default:
        snprintf(inst->message, sizeof inst->message, "%s: the step size fell below the resolution of t at "
                 "t = %.17g (tolerance %g): the solution is not smooth there", m->identifier, inst->t, inst->rtol);
        return -1;
    }
}
