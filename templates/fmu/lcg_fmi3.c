/* lcg_fmi3.c -- the FMI 3.0 functions of lagcodegen's FMUs (Model Exchange and Co-Simulation)
 * on the model-independent core (lcg_fmu.h). Only Float64 variables; no event indicators, no
 * clocks, no FMU state, no directional derivatives (the modelDescription.xml says so);
 * Scheduled Execution is not provided. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "fmi3Functions.h"
#include "lcg_fmu.h"

typedef struct {
    lcg_fmu_instance *core;
    fmi3InstanceEnvironment env;
    fmi3LogMessageCallback log;
    fmi3Boolean logging;
} lcg_fmi3;

static void say(const lcg_fmi3 *c, fmi3Status status, const char *category, const char *message)
{
    if (c->log != NULL && (c->logging || status >= fmi3Error))
        c->log(c->env, status, category, message);
}

static fmi3Status fail(lcg_fmi3 *c)
{
    say(c, fmi3Error, "logStatusError", c->core->message);
    return fmi3Error;
}

static fmi3Status refuse(fmi3Instance instance, const char *what)
{
    lcg_fmi3 *c = (lcg_fmi3 *)instance;
    if (c != NULL)
        say(c, fmi3Error, "logStatusError", what);
    return fmi3Error;
}

static fmi3Instance instantiate(fmi3String token, fmi3Boolean loggingOn, fmi3InstanceEnvironment env,
                                fmi3LogMessageCallback logMessage)
{
    const lcg_fmu_model *m = &lcg_fmu_this_model;
    lcg_fmi3 *c;

    if (token == NULL || strcmp(token, m->token) != 0) {
        if (logMessage != NULL)
            logMessage(env, fmi3Error, "logStatusError", "the instantiationToken is not this FMU's");
        return NULL;
    }
    c = (lcg_fmi3 *)calloc(1, sizeof *c);
    if (c == NULL)
        return NULL;
    c->core = lcg_fmu_new(m);
    if (c->core == NULL) {
        free(c);
        return NULL;
    }
    c->env = env;
    c->log = logMessage;
    c->logging = loggingOn;
    return c;
}

const char *fmi3GetVersion(void)
{
    return fmi3Version;
}

fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn, size_t nCategories,
                               const fmi3String categories[])
{
    (void)nCategories;
    (void)categories;
    if (instance == NULL)
        return fmi3Error;
    ((lcg_fmi3 *)instance)->logging = loggingOn;
    return fmi3OK;
}

fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName, fmi3String instantiationToken,
                                          fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                          fmi3InstanceEnvironment instanceEnvironment,
                                          fmi3LogMessageCallback logMessage)
{
    (void)instanceName;
    (void)resourcePath;
    (void)visible;
    return instantiate(instantiationToken, loggingOn, instanceEnvironment, logMessage);
}

fmi3Instance fmi3InstantiateCoSimulation(fmi3String instanceName, fmi3String instantiationToken,
                                         fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                         fmi3Boolean eventModeUsed, fmi3Boolean earlyReturnAllowed,
                                         const fmi3ValueReference requiredIntermediateVariables[],
                                         size_t nRequiredIntermediateVariables,
                                         fmi3InstanceEnvironment instanceEnvironment,
                                         fmi3LogMessageCallback logMessage,
                                         fmi3IntermediateUpdateCallback intermediateUpdate)
{
    (void)instanceName;
    (void)resourcePath;
    (void)visible;
    (void)eventModeUsed;
    (void)earlyReturnAllowed;
    (void)requiredIntermediateVariables;
    (void)nRequiredIntermediateVariables;
    (void)intermediateUpdate;
    return instantiate(instantiationToken, loggingOn, instanceEnvironment, logMessage);
}

fmi3Instance fmi3InstantiateScheduledExecution(fmi3String instanceName, fmi3String instantiationToken,
                                               fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                               fmi3InstanceEnvironment instanceEnvironment,
                                               fmi3LogMessageCallback logMessage, fmi3ClockUpdateCallback clockUpdate,
                                               fmi3LockPreemptionCallback lockPreemption,
                                               fmi3UnlockPreemptionCallback unlockPreemption)
{
    (void)instanceName;
    (void)instantiationToken;
    (void)resourcePath;
    (void)visible;
    (void)loggingOn;
    (void)clockUpdate;
    (void)lockPreemption;
    (void)unlockPreemption;
    if (logMessage != NULL)
        logMessage(instanceEnvironment, fmi3Error, "logStatusError", "Scheduled Execution is not provided");
    return NULL;
}

void fmi3FreeInstance(fmi3Instance instance)
{
    lcg_fmi3 *c = (lcg_fmi3 *)instance;
    if (c == NULL)
        return;
    lcg_fmu_free(c->core);
    free(c);
}

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined, fmi3Float64 tolerance,
                                       fmi3Float64 startTime, fmi3Boolean stopTimeDefined, fmi3Float64 stopTime)
{
    lcg_fmi3 *c = (lcg_fmi3 *)instance;
    (void)stopTimeDefined;
    (void)stopTime;
    if (c == NULL)
        return fmi3Error;
    lcg_fmu_experiment(c->core, toleranceDefined, tolerance, startTime);
    return fmi3OK;
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance)
{
    lcg_fmi3 *c = (lcg_fmi3 *)instance;
    if (c == NULL)
        return fmi3Error;
    return lcg_fmu_start(c->core) == 0 && lcg_fmu_eval(c->core) == 0 ? fmi3OK : fail(c);
}

fmi3Status fmi3EnterEventMode(fmi3Instance instance)
{
    return instance == NULL ? fmi3Error : fmi3OK;
}

fmi3Status fmi3Terminate(fmi3Instance instance)
{
    return instance == NULL ? fmi3Error : fmi3OK;
}

fmi3Status fmi3Reset(fmi3Instance instance)
{
    lcg_fmi3 *c = (lcg_fmi3 *)instance;
    if (c == NULL)
        return fmi3Error;
    lcg_fmu_reset(c->core);
    return fmi3OK;
}

fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                          fmi3Float64 values[], size_t nValues)
{
    lcg_fmi3 *c = (lcg_fmi3 *)instance;
    size_t i;
    if (c == NULL)
        return fmi3Error;
    if (nValues != nValueReferences || (nValues > 0 && (valueReferences == NULL || values == NULL)))
        return refuse(instance, "fmi3GetFloat64: nValues differs from nValueReferences (scalar variables only)");
    for (i = 0; i < nValueReferences; ++i)
        if (lcg_fmu_get(c->core, valueReferences[i], &values[i]) != 0)
            return fail(c);
    return fmi3OK;
}

fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                          const fmi3Float64 values[], size_t nValues)
{
    lcg_fmi3 *c = (lcg_fmi3 *)instance;
    size_t i;
    if (c == NULL)
        return fmi3Error;
    if (nValues != nValueReferences || (nValues > 0 && (valueReferences == NULL || values == NULL)))
        return refuse(instance, "fmi3SetFloat64: nValues differs from nValueReferences (scalar variables only)");
    for (i = 0; i < nValueReferences; ++i)
        if (lcg_fmu_set(c->core, valueReferences[i], values[i]) != 0)
            return fail(c);
    return fmi3OK;
}

/* The FMU has Float64 variables only. */
#define NO_VARIABLES(fn, T)                                                                              \
    fmi3Status fn(fmi3Instance instance, const fmi3ValueReference valueReferences[],                     \
                  size_t nValueReferences, T values[], size_t nValues)                                   \
    {                                                                                                    \
        (void)valueReferences;                                                                           \
        (void)values;                                                                                    \
        (void)nValues;                                                                                   \
        return nValueReferences == 0 ? fmi3OK : refuse(instance, #fn ": this FMU has Float64 variables only"); \
    }
NO_VARIABLES(fmi3GetFloat32, fmi3Float32)
NO_VARIABLES(fmi3GetInt8, fmi3Int8)
NO_VARIABLES(fmi3GetUInt8, fmi3UInt8)
NO_VARIABLES(fmi3GetInt16, fmi3Int16)
NO_VARIABLES(fmi3GetUInt16, fmi3UInt16)
NO_VARIABLES(fmi3GetInt32, fmi3Int32)
NO_VARIABLES(fmi3GetUInt32, fmi3UInt32)
NO_VARIABLES(fmi3GetInt64, fmi3Int64)
NO_VARIABLES(fmi3GetUInt64, fmi3UInt64)
NO_VARIABLES(fmi3GetBoolean, fmi3Boolean)
NO_VARIABLES(fmi3GetString, fmi3String)
NO_VARIABLES(fmi3SetFloat32, const fmi3Float32)
NO_VARIABLES(fmi3SetInt8, const fmi3Int8)
NO_VARIABLES(fmi3SetUInt8, const fmi3UInt8)
NO_VARIABLES(fmi3SetInt16, const fmi3Int16)
NO_VARIABLES(fmi3SetUInt16, const fmi3UInt16)
NO_VARIABLES(fmi3SetInt32, const fmi3Int32)
NO_VARIABLES(fmi3SetUInt32, const fmi3UInt32)
NO_VARIABLES(fmi3SetInt64, const fmi3Int64)
NO_VARIABLES(fmi3SetUInt64, const fmi3UInt64)
NO_VARIABLES(fmi3SetBoolean, const fmi3Boolean)
NO_VARIABLES(fmi3SetString, const fmi3String)

fmi3Status fmi3GetBinary(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                         size_t valueSizes[], fmi3Binary values[], size_t nValues)
{
    (void)valueReferences;
    (void)valueSizes;
    (void)values;
    (void)nValues;
    return nValueReferences == 0 ? fmi3OK : refuse(instance, "fmi3GetBinary: this FMU has Float64 variables only");
}

fmi3Status fmi3SetBinary(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                         const size_t valueSizes[], const fmi3Binary values[], size_t nValues)
{
    (void)valueReferences;
    (void)valueSizes;
    (void)values;
    (void)nValues;
    return nValueReferences == 0 ? fmi3OK : refuse(instance, "fmi3SetBinary: this FMU has Float64 variables only");
}

fmi3Status fmi3GetClock(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                        fmi3Clock values[])
{
    (void)valueReferences;
    (void)values;
    return nValueReferences == 0 ? fmi3OK : refuse(instance, "fmi3GetClock: this FMU has no clocks");
}

fmi3Status fmi3SetClock(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                        const fmi3Clock values[])
{
    (void)valueReferences;
    (void)values;
    return nValueReferences == 0 ? fmi3OK : refuse(instance, "fmi3SetClock: this FMU has no clocks");
}

fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance instance, fmi3ValueReference valueReference,
                                               size_t *nDependencies)
{
    (void)valueReference;
    (void)nDependencies;
    return refuse(instance, "fmi3GetNumberOfVariableDependencies: the dependencies are in modelDescription.xml");
}

fmi3Status fmi3GetVariableDependencies(fmi3Instance instance, fmi3ValueReference dependent,
                                       size_t elementIndicesOfDependent[], fmi3ValueReference independents[],
                                       size_t elementIndicesOfIndependents[], fmi3DependencyKind dependencyKinds[],
                                       size_t nDependencies)
{
    (void)dependent;
    (void)elementIndicesOfDependent;
    (void)independents;
    (void)elementIndicesOfIndependents;
    (void)dependencyKinds;
    (void)nDependencies;
    return refuse(instance, "fmi3GetVariableDependencies: the dependencies are in modelDescription.xml");
}

fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState *FMUState)
{
    (void)FMUState;
    return refuse(instance, "fmi3GetFMUState: not supported (canGetAndSetFMUState is false)");
}

fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState FMUState)
{
    (void)FMUState;
    return refuse(instance, "fmi3SetFMUState: not supported (canGetAndSetFMUState is false)");
}

fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState *FMUState)
{
    (void)FMUState;
    return refuse(instance, "fmi3FreeFMUState: not supported (canGetAndSetFMUState is false)");
}

fmi3Status fmi3SerializedFMUStateSize(fmi3Instance instance, fmi3FMUState FMUState, size_t *size)
{
    (void)FMUState;
    (void)size;
    return refuse(instance, "fmi3SerializedFMUStateSize: not supported (canSerializeFMUState is false)");
}

fmi3Status fmi3SerializeFMUState(fmi3Instance instance, fmi3FMUState FMUState, fmi3Byte serializedState[],
                                 size_t size)
{
    (void)FMUState;
    (void)serializedState;
    (void)size;
    return refuse(instance, "fmi3SerializeFMUState: not supported (canSerializeFMUState is false)");
}

fmi3Status fmi3DeserializeFMUState(fmi3Instance instance, const fmi3Byte serializedState[], size_t size,
                                   fmi3FMUState *FMUState)
{
    (void)serializedState;
    (void)size;
    (void)FMUState;
    return refuse(instance, "fmi3DeserializeFMUState: not supported (canSerializeFMUState is false)");
}

fmi3Status fmi3GetDirectionalDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns,
                                        const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
                                        size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity)
{
    (void)unknowns;
    (void)nUnknowns;
    (void)knowns;
    (void)nKnowns;
    (void)seed;
    (void)nSeed;
    (void)sensitivity;
    (void)nSensitivity;
    return refuse(instance, "fmi3GetDirectionalDerivative: not supported (providesDirectionalDerivatives is false)");
}

fmi3Status fmi3GetAdjointDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns,
                                    const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
                                    size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity)
{
    (void)unknowns;
    (void)nUnknowns;
    (void)knowns;
    (void)nKnowns;
    (void)seed;
    (void)nSeed;
    (void)sensitivity;
    (void)nSensitivity;
    return refuse(instance, "fmi3GetAdjointDerivative: not supported (providesAdjointDerivatives is false)");
}

fmi3Status fmi3EnterConfigurationMode(fmi3Instance instance)
{
    return refuse(instance, "fmi3EnterConfigurationMode: this FMU has no structural parameters");
}

fmi3Status fmi3ExitConfigurationMode(fmi3Instance instance)
{
    return refuse(instance, "fmi3ExitConfigurationMode: this FMU has no structural parameters");
}

fmi3Status fmi3GetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                  size_t nValueReferences, fmi3Float64 intervals[], fmi3IntervalQualifier qualifiers[])
{
    (void)valueReferences;
    (void)nValueReferences;
    (void)intervals;
    (void)qualifiers;
    return refuse(instance, "fmi3GetIntervalDecimal: this FMU has no clocks");
}

fmi3Status fmi3GetIntervalFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                   size_t nValueReferences, fmi3UInt64 counters[], fmi3UInt64 resolutions[],
                                   fmi3IntervalQualifier qualifiers[])
{
    (void)valueReferences;
    (void)nValueReferences;
    (void)counters;
    (void)resolutions;
    (void)qualifiers;
    return refuse(instance, "fmi3GetIntervalFraction: this FMU has no clocks");
}

fmi3Status fmi3GetShiftDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                               size_t nValueReferences, fmi3Float64 shifts[])
{
    (void)valueReferences;
    (void)nValueReferences;
    (void)shifts;
    return refuse(instance, "fmi3GetShiftDecimal: this FMU has no clocks");
}

fmi3Status fmi3GetShiftFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                size_t nValueReferences, fmi3UInt64 counters[], fmi3UInt64 resolutions[])
{
    (void)valueReferences;
    (void)nValueReferences;
    (void)counters;
    (void)resolutions;
    return refuse(instance, "fmi3GetShiftFraction: this FMU has no clocks");
}

fmi3Status fmi3SetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                  size_t nValueReferences, const fmi3Float64 intervals[])
{
    (void)valueReferences;
    (void)nValueReferences;
    (void)intervals;
    return refuse(instance, "fmi3SetIntervalDecimal: this FMU has no clocks");
}

fmi3Status fmi3SetIntervalFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                   size_t nValueReferences, const fmi3UInt64 counters[],
                                   const fmi3UInt64 resolutions[])
{
    (void)valueReferences;
    (void)nValueReferences;
    (void)counters;
    (void)resolutions;
    return refuse(instance, "fmi3SetIntervalFraction: this FMU has no clocks");
}

fmi3Status fmi3SetShiftDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                               size_t nValueReferences, const fmi3Float64 shifts[])
{
    (void)valueReferences;
    (void)nValueReferences;
    (void)shifts;
    return refuse(instance, "fmi3SetShiftDecimal: this FMU has no clocks");
}

fmi3Status fmi3SetShiftFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                size_t nValueReferences, const fmi3UInt64 counters[], const fmi3UInt64 resolutions[])
{
    (void)valueReferences;
    (void)nValueReferences;
    (void)counters;
    (void)resolutions;
    return refuse(instance, "fmi3SetShiftFraction: this FMU has no clocks");
}

fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance instance)
{
    return instance == NULL ? fmi3Error : fmi3OK;
}

fmi3Status fmi3UpdateDiscreteStates(fmi3Instance instance, fmi3Boolean *discreteStatesNeedUpdate,
                                    fmi3Boolean *terminateSimulation, fmi3Boolean *nominalsOfContinuousStatesChanged,
                                    fmi3Boolean *valuesOfContinuousStatesChanged, fmi3Boolean *nextEventTimeDefined,
                                    fmi3Float64 *nextEventTime)
{
    if (instance == NULL)
        return fmi3Error;
    if (discreteStatesNeedUpdate != NULL)
        *discreteStatesNeedUpdate = fmi3False;
    if (terminateSimulation != NULL)
        *terminateSimulation = fmi3False;
    if (nominalsOfContinuousStatesChanged != NULL)
        *nominalsOfContinuousStatesChanged = fmi3False;
    if (valuesOfContinuousStatesChanged != NULL)
        *valuesOfContinuousStatesChanged = fmi3False;
    if (nextEventTimeDefined != NULL)
        *nextEventTimeDefined = fmi3False;
    if (nextEventTime != NULL)
        *nextEventTime = 0.0;
    return fmi3OK;
}

/* ---------------------------------------------------------------- Model Exchange */

fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance instance)
{
    return instance == NULL ? fmi3Error : fmi3OK;
}

fmi3Status fmi3CompletedIntegratorStep(fmi3Instance instance, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi3Boolean *enterEventMode, fmi3Boolean *terminateSimulation)
{
    (void)noSetFMUStatePriorToCurrentPoint;
    if (instance == NULL || enterEventMode == NULL || terminateSimulation == NULL)
        return fmi3Error;
    *enterEventMode = fmi3False;
    *terminateSimulation = fmi3False;
    return fmi3OK;
}

fmi3Status fmi3SetTime(fmi3Instance instance, fmi3Float64 time)
{
    lcg_fmi3 *c = (lcg_fmi3 *)instance;
    if (c == NULL)
        return fmi3Error;
    lcg_fmu_set_time(c->core, time);
    return fmi3OK;
}

fmi3Status fmi3SetContinuousStates(fmi3Instance instance, const fmi3Float64 continuousStates[],
                                   size_t nContinuousStates)
{
    lcg_fmi3 *c = (lcg_fmi3 *)instance;
    if (c == NULL || nContinuousStates != (size_t)c->core->m->nx || (nContinuousStates > 0 && !continuousStates))
        return refuse(instance, "fmi3SetContinuousStates: wrong number of states");
    lcg_fmu_set_states(c->core, continuousStates);
    return fmi3OK;
}

fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance instance, fmi3Float64 derivatives[],
                                             size_t nContinuousStates)
{
    lcg_fmi3 *c = (lcg_fmi3 *)instance;
    if (c == NULL || nContinuousStates != (size_t)c->core->m->nx || (nContinuousStates > 0 && !derivatives))
        return refuse(instance, "fmi3GetContinuousStateDerivatives: wrong number of states");
    if (lcg_fmu_eval(c->core) != 0)
        return fail(c);
    if (nContinuousStates > 0)
        memcpy(derivatives, c->core->dx, nContinuousStates * sizeof(double));
    return fmi3OK;
}

fmi3Status fmi3GetEventIndicators(fmi3Instance instance, fmi3Float64 eventIndicators[], size_t nEventIndicators)
{
    (void)eventIndicators;
    if (nEventIndicators != 0)
        return refuse(instance, "fmi3GetEventIndicators: this FMU has no event indicators");
    return instance == NULL ? fmi3Error : fmi3OK;
}

fmi3Status fmi3GetContinuousStates(fmi3Instance instance, fmi3Float64 continuousStates[], size_t nContinuousStates)
{
    lcg_fmi3 *c = (lcg_fmi3 *)instance;
    if (c == NULL || nContinuousStates != (size_t)c->core->m->nx || (nContinuousStates > 0 && !continuousStates))
        return refuse(instance, "fmi3GetContinuousStates: wrong number of states");
    if (nContinuousStates > 0)
        memcpy(continuousStates, c->core->x, nContinuousStates * sizeof(double));
    return fmi3OK;
}

fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance instance, fmi3Float64 nominals[], size_t nContinuousStates)
{
    lcg_fmi3 *c = (lcg_fmi3 *)instance;
    size_t i;
    if (c == NULL || nContinuousStates != (size_t)c->core->m->nx || (nContinuousStates > 0 && !nominals))
        return refuse(instance, "fmi3GetNominalsOfContinuousStates: wrong number of states");
    for (i = 0; i < nContinuousStates; ++i)
        nominals[i] = 1.0;
    return fmi3OK;
}

fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance instance, size_t *nEventIndicators)
{
    if (instance == NULL || nEventIndicators == NULL)
        return fmi3Error;
    *nEventIndicators = 0;
    return fmi3OK;
}

fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance instance, size_t *nContinuousStates)
{
    lcg_fmi3 *c = (lcg_fmi3 *)instance;
    if (c == NULL || nContinuousStates == NULL)
        return fmi3Error;
    *nContinuousStates = (size_t)c->core->m->nx;
    return fmi3OK;
}

/* ---------------------------------------------------------------- Co-Simulation */

fmi3Status fmi3EnterStepMode(fmi3Instance instance)
{
    return instance == NULL ? fmi3Error : fmi3OK;
}

fmi3Status fmi3GetOutputDerivatives(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                    size_t nValueReferences, const fmi3Int32 orders[], fmi3Float64 values[],
                                    size_t nValues)
{
    (void)valueReferences;
    (void)nValueReferences;
    (void)orders;
    (void)values;
    (void)nValues;
    return refuse(instance, "fmi3GetOutputDerivatives: not supported (maxOutputDerivativeOrder is 0)");
}

fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
                      fmi3Float64 communicationStepSize, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                      fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation, fmi3Boolean *earlyReturn,
                      fmi3Float64 *lastSuccessfulTime)
{
    lcg_fmi3 *c = (lcg_fmi3 *)instance;
    int code;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (c == NULL)
        return fmi3Error;
    if (isnan(communicationStepSize))
        return refuse(instance, "fmi3DoStep: the communication step size is not a number (NaN)");
    if (!isfinite(currentCommunicationPoint))
        return refuse(instance, "fmi3DoStep: the communication point is not a finite number");
    if (communicationStepSize < 0.0)
        return refuse(instance, "fmi3DoStep: the communication step size is negative");
    if (!isfinite(communicationStepSize))
        return refuse(instance, "fmi3DoStep: the communication step size is infinite");
    code = lcg_fmu_step(c->core, currentCommunicationPoint, currentCommunicationPoint + communicationStepSize);
    if (eventHandlingNeeded != NULL)
        *eventHandlingNeeded = fmi3False;
    if (terminateSimulation != NULL)
        *terminateSimulation = fmi3False;
    if (earlyReturn != NULL)
        *earlyReturn = fmi3False;
    if (lastSuccessfulTime != NULL)
        *lastSuccessfulTime = c->core->t;
    return code == 0 ? fmi3OK : fail(c);
}

fmi3Status fmi3ActivateModelPartition(fmi3Instance instance, fmi3ValueReference clockReference,
                                      fmi3Float64 activationTime)
{
    (void)clockReference;
    (void)activationTime;
    return refuse(instance, "fmi3ActivateModelPartition: Scheduled Execution is not provided");
}
