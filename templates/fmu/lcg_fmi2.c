/* lcg_fmi2.c -- the FMI 2.0 functions of lagcodegen's FMUs (Model Exchange and Co-Simulation)
 * on the model-independent core (lcg_fmu.h). Only Real variables; no event indicators, no
 * FMU state, no directional derivatives (the modelDescription.xml says so). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"
#include "lcg_fmu.h"

typedef struct {
    lcg_fmu_instance *core;
    fmi2CallbackFunctions cb;
    fmi2Type type;
    fmi2Boolean logging;
    char name[128];
} lcg_fmi2;

static void say(const lcg_fmi2 *c, fmi2Status status, const char *category, const char *message)
{
    if (c->cb.logger != NULL && (c->logging || status >= fmi2Error))
        c->cb.logger(c->cb.componentEnvironment, c->name, status, category, "%s", message);
}

static fmi2Status fail(lcg_fmi2 *c)
{
    say(c, fmi2Error, "logStatusError", c->core->message);
    return fmi2Error;
}

static fmi2Status refuse(fmi2Component comp, const char *what)
{
    lcg_fmi2 *c = (lcg_fmi2 *)comp;
    if (c != NULL)
        say(c, fmi2Error, "logStatusError", what);
    return fmi2Error;
}

const char *fmi2GetTypesPlatform(void)
{
    return fmi2TypesPlatform;
}

const char *fmi2GetVersion(void)
{
    return fmi2Version;
}

fmi2Status fmi2SetDebugLogging(fmi2Component comp, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[])
{
    (void)nCategories;
    (void)categories;
    if (comp == NULL)
        return fmi2Error;
    ((lcg_fmi2 *)comp)->logging = loggingOn;
    return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn)
{
    const lcg_fmu_model *m = &lcg_fmu_this_model;
    lcg_fmi2 *c;

    (void)fmuResourceLocation;
    (void)visible;
    if (functions == NULL)
        return NULL;
    if (fmuGUID == NULL || strcmp(fmuGUID, m->token) != 0) {
        if (functions->logger != NULL)
            functions->logger(functions->componentEnvironment, instanceName, fmi2Error, "logStatusError",
                              "%s: the GUID %s is not this FMU's (%s)", m->identifier, fmuGUID ? fmuGUID : "(null)",
                              m->token);
        return NULL;
    }
    c = (lcg_fmi2 *)calloc(1, sizeof *c);
    if (c == NULL)
        return NULL;
    c->core = lcg_fmu_new(m);
    if (c->core == NULL) {
        free(c);
        return NULL;
    }
    c->cb = *functions;
    c->type = fmuType;
    c->logging = loggingOn;
    strncpy(c->name, instanceName ? instanceName : m->identifier, sizeof c->name - 1);
    return c;
}

void fmi2FreeInstance(fmi2Component comp)
{
    lcg_fmi2 *c = (lcg_fmi2 *)comp;
    if (c == NULL)
        return;
    lcg_fmu_free(c->core);
    free(c);
}

fmi2Status fmi2SetupExperiment(fmi2Component comp, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime)
{
    lcg_fmi2 *c = (lcg_fmi2 *)comp;
    (void)stopTimeDefined;
    (void)stopTime;
    if (c == NULL)
        return fmi2Error;
    lcg_fmu_experiment(c->core, toleranceDefined, tolerance, startTime);
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component comp)
{
    return comp == NULL ? fmi2Error : fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component comp)
{
    lcg_fmi2 *c = (lcg_fmi2 *)comp;
    if (c == NULL)
        return fmi2Error;
    return lcg_fmu_start(c->core) == 0 && lcg_fmu_eval(c->core) == 0 ? fmi2OK : fail(c);
}

fmi2Status fmi2Terminate(fmi2Component comp)
{
    return comp == NULL ? fmi2Error : fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component comp)
{
    lcg_fmi2 *c = (lcg_fmi2 *)comp;
    if (c == NULL)
        return fmi2Error;
    lcg_fmu_reset(c->core);
    return fmi2OK;
}

fmi2Status fmi2GetReal(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[])
{
    lcg_fmi2 *c = (lcg_fmi2 *)comp;
    size_t i;
    if (c == NULL || (nvr > 0 && (vr == NULL || value == NULL)))
        return fmi2Error;
    for (i = 0; i < nvr; ++i)
        if (lcg_fmu_get(c->core, vr[i], &value[i]) != 0)
            return fail(c);
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[])
{
    lcg_fmi2 *c = (lcg_fmi2 *)comp;
    size_t i;
    if (c == NULL || (nvr > 0 && (vr == NULL || value == NULL)))
        return fmi2Error;
    for (i = 0; i < nvr; ++i)
        if (lcg_fmu_set(c->core, vr[i], value[i]) != 0)
            return fail(c);
    return fmi2OK;
}

/* The FMU has Real variables only. */
#define NO_VARIABLES(fn, T)                                                                            \
    fmi2Status fn(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, T value[])            \
    {                                                                                                  \
        (void)vr;                                                                                      \
        (void)value;                                                                                   \
        return nvr == 0 ? fmi2OK : refuse(comp, #fn ": this FMU has Real variables only");             \
    }
NO_VARIABLES(fmi2GetInteger, fmi2Integer)
NO_VARIABLES(fmi2GetBoolean, fmi2Boolean)
NO_VARIABLES(fmi2GetString, fmi2String)
NO_VARIABLES(fmi2SetInteger, const fmi2Integer)
NO_VARIABLES(fmi2SetBoolean, const fmi2Boolean)
NO_VARIABLES(fmi2SetString, const fmi2String)

fmi2Status fmi2GetFMUstate(fmi2Component comp, fmi2FMUstate *FMUstate)
{
    (void)FMUstate;
    return refuse(comp, "fmi2GetFMUstate: not supported (canGetAndSetFMUstate is false)");
}

fmi2Status fmi2SetFMUstate(fmi2Component comp, fmi2FMUstate FMUstate)
{
    (void)FMUstate;
    return refuse(comp, "fmi2SetFMUstate: not supported (canGetAndSetFMUstate is false)");
}

fmi2Status fmi2FreeFMUstate(fmi2Component comp, fmi2FMUstate *FMUstate)
{
    (void)FMUstate;
    return refuse(comp, "fmi2FreeFMUstate: not supported (canGetAndSetFMUstate is false)");
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component comp, fmi2FMUstate FMUstate, size_t *size)
{
    (void)FMUstate;
    (void)size;
    return refuse(comp, "fmi2SerializedFMUstateSize: not supported (canSerializeFMUstate is false)");
}

fmi2Status fmi2SerializeFMUstate(fmi2Component comp, fmi2FMUstate FMUstate, fmi2Byte serializedState[], size_t size)
{
    (void)FMUstate;
    (void)serializedState;
    (void)size;
    return refuse(comp, "fmi2SerializeFMUstate: not supported (canSerializeFMUstate is false)");
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component comp, const fmi2Byte serializedState[], size_t size,
                                   fmi2FMUstate *FMUstate)
{
    (void)serializedState;
    (void)size;
    (void)FMUstate;
    return refuse(comp, "fmi2DeSerializeFMUstate: not supported (canSerializeFMUstate is false)");
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component comp, const fmi2ValueReference vUnknown_ref[], size_t nUnknown,
                                        const fmi2ValueReference vKnown_ref[], size_t nKnown,
                                        const fmi2Real dvKnown[], fmi2Real dvUnknown[])
{
    (void)vUnknown_ref;
    (void)nUnknown;
    (void)vKnown_ref;
    (void)nKnown;
    (void)dvKnown;
    (void)dvUnknown;
    return refuse(comp, "fmi2GetDirectionalDerivative: not supported (providesDirectionalDerivative is false)");
}

/* ---------------------------------------------------------------- Model Exchange */

fmi2Status fmi2EnterEventMode(fmi2Component comp)
{
    return comp == NULL ? fmi2Error : fmi2OK;
}

fmi2Status fmi2NewDiscreteStates(fmi2Component comp, fmi2EventInfo *eventInfo)
{
    if (comp == NULL || eventInfo == NULL)
        return fmi2Error;
    eventInfo->newDiscreteStatesNeeded = fmi2False;
    eventInfo->terminateSimulation = fmi2False;
    eventInfo->nominalsOfContinuousStatesChanged = fmi2False;
    eventInfo->valuesOfContinuousStatesChanged = fmi2False;
    eventInfo->nextEventTimeDefined = fmi2False;
    eventInfo->nextEventTime = 0.0;
    return fmi2OK;
}

fmi2Status fmi2EnterContinuousTimeMode(fmi2Component comp)
{
    return comp == NULL ? fmi2Error : fmi2OK;
}

fmi2Status fmi2CompletedIntegratorStep(fmi2Component comp, fmi2Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi2Boolean *enterEventMode, fmi2Boolean *terminateSimulation)
{
    (void)noSetFMUStatePriorToCurrentPoint;
    if (comp == NULL || enterEventMode == NULL || terminateSimulation == NULL)
        return fmi2Error;
    *enterEventMode = fmi2False;
    *terminateSimulation = fmi2False;
    return fmi2OK;
}

fmi2Status fmi2SetTime(fmi2Component comp, fmi2Real time)
{
    lcg_fmi2 *c = (lcg_fmi2 *)comp;
    if (c == NULL)
        return fmi2Error;
    lcg_fmu_set_time(c->core, time);
    return fmi2OK;
}

fmi2Status fmi2SetContinuousStates(fmi2Component comp, const fmi2Real x[], size_t nx)
{
    lcg_fmi2 *c = (lcg_fmi2 *)comp;
    if (c == NULL || nx != (size_t)c->core->m->nx || (nx > 0 && x == NULL))
        return refuse(comp, "fmi2SetContinuousStates: wrong number of states");
    lcg_fmu_set_states(c->core, x);
    return fmi2OK;
}

fmi2Status fmi2GetDerivatives(fmi2Component comp, fmi2Real derivatives[], size_t nx)
{
    lcg_fmi2 *c = (lcg_fmi2 *)comp;
    if (c == NULL || nx != (size_t)c->core->m->nx || (nx > 0 && derivatives == NULL))
        return refuse(comp, "fmi2GetDerivatives: wrong number of states");
    if (lcg_fmu_eval(c->core) != 0)
        return fail(c);
    if (nx > 0)
        memcpy(derivatives, c->core->dx, nx * sizeof(double));
    return fmi2OK;
}

fmi2Status fmi2GetEventIndicators(fmi2Component comp, fmi2Real eventIndicators[], size_t ni)
{
    (void)eventIndicators;
    return ni == 0 ? (comp == NULL ? fmi2Error : fmi2OK)
                   : refuse(comp, "fmi2GetEventIndicators: this FMU has no event indicators");
}

fmi2Status fmi2GetContinuousStates(fmi2Component comp, fmi2Real x[], size_t nx)
{
    lcg_fmi2 *c = (lcg_fmi2 *)comp;
    if (c == NULL || nx != (size_t)c->core->m->nx || (nx > 0 && x == NULL))
        return refuse(comp, "fmi2GetContinuousStates: wrong number of states");
    if (nx > 0)
        memcpy(x, c->core->x, nx * sizeof(double));
    return fmi2OK;
}

fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component comp, fmi2Real x_nominal[], size_t nx)
{
    lcg_fmi2 *c = (lcg_fmi2 *)comp;
    size_t i;
    if (c == NULL || nx != (size_t)c->core->m->nx || (nx > 0 && x_nominal == NULL))
        return refuse(comp, "fmi2GetNominalsOfContinuousStates: wrong number of states");
    for (i = 0; i < nx; ++i)
        x_nominal[i] = 1.0;
    return fmi2OK;
}

/* ---------------------------------------------------------------- Co-Simulation */

fmi2Status fmi2SetRealInputDerivatives(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[])
{
    (void)vr;
    (void)nvr;
    (void)order;
    (void)value;
    return refuse(comp, "fmi2SetRealInputDerivatives: not supported (canInterpolateInputs is false)");
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[])
{
    (void)vr;
    (void)nvr;
    (void)order;
    (void)value;
    return refuse(comp, "fmi2GetRealOutputDerivatives: not supported (maxOutputDerivativeOrder is 0)");
}

fmi2Status fmi2DoStep(fmi2Component comp, fmi2Real currentCommunicationPoint, fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentPoint)
{
    lcg_fmi2 *c = (lcg_fmi2 *)comp;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (c == NULL)
        return fmi2Error;
    if (isnan(communicationStepSize))
        return refuse(comp, "fmi2DoStep: the communication step size is not a number (NaN)");
    if (!isfinite(currentCommunicationPoint))
        return refuse(comp, "fmi2DoStep: the communication point is not a finite number");
    if (communicationStepSize < 0.0)
        return refuse(comp, "fmi2DoStep: the communication step size is negative");
    if (!isfinite(communicationStepSize))
        return refuse(comp, "fmi2DoStep: the communication step size is infinite");
    return lcg_fmu_step(c->core, currentCommunicationPoint, currentCommunicationPoint + communicationStepSize) == 0
               ? fmi2OK : fail(c);
}

fmi2Status fmi2CancelStep(fmi2Component comp)
{
    return refuse(comp, "fmi2CancelStep: the steps are not asynchronous");
}

fmi2Status fmi2GetStatus(fmi2Component comp, const fmi2StatusKind s, fmi2Status *value)
{
    (void)s;
    (void)value;
    return refuse(comp, "fmi2GetStatus: the steps are not asynchronous");
}

fmi2Status fmi2GetRealStatus(fmi2Component comp, const fmi2StatusKind s, fmi2Real *value)
{
    lcg_fmi2 *c = (lcg_fmi2 *)comp;
    if (c == NULL || value == NULL)
        return fmi2Error;
    if (s != fmi2LastSuccessfulTime)
        return refuse(comp, "fmi2GetRealStatus: only fmi2LastSuccessfulTime is known");
    *value = c->core->t;
    return fmi2OK;
}

fmi2Status fmi2GetIntegerStatus(fmi2Component comp, const fmi2StatusKind s, fmi2Integer *value)
{
    (void)s;
    (void)value;
    return refuse(comp, "fmi2GetIntegerStatus: no integer status");
}

fmi2Status fmi2GetBooleanStatus(fmi2Component comp, const fmi2StatusKind s, fmi2Boolean *value)
{
    if (comp == NULL || value == NULL)
        return fmi2Error;
    if (s != fmi2Terminated)
        return refuse(comp, "fmi2GetBooleanStatus: only fmi2Terminated is known");
    *value = fmi2False;
    return fmi2OK;
}

fmi2Status fmi2GetStringStatus(fmi2Component comp, const fmi2StatusKind s, fmi2String *value)
{
    (void)s;
    (void)value;
    return refuse(comp, "fmi2GetStringStatus: no string status");
}
