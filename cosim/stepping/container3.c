/* The container's FMI 3.0 face (cosim/plan/container.py builds this file for an export with --fmi 3): the
 * FMI 2.0 container of container.c (included below, unchanged: the same loop, system.txt and inner FMUs)
 * behind the FMI 3.0 co-simulation API.  An fmi3 instance holds the container and the host's logger;
 * the inner FMUs get FMI 2.0 callbacks whose logger passes their messages (and the container's) on to it.
 * The container's variables: Real as Float64, Integer as Int32, Boolean as Boolean, their value references
 * those of the FMI 2.0 description.  The instantiation token is the container's GUID.  What the container
 * does not do (Model Exchange, Scheduled Execution, event mode, clocks, states, derivatives, other types) is
 * an error, said through the logger.  The prototypes are the standard's (fmi3Functions.h). */
#include "container.c"

#include <stdbool.h>
#include <stdint.h>
#include "fmi3Functions.h"

typedef struct {
    Container *s;
    fmi3InstanceEnvironment env;
    fmi3LogMessageCallback log;
    fmi2CallbackFunctions cb;   /* what the FMI 2.0 container and the inner FMUs are given */
    double time;                /* the independent variable (value reference 0), s */
    int early_return_allowed;   /* a stop event inside a step of the host may return early */
} Host3;

/* the FMI 2.0 logger the container and the inner FMUs call: the message formatted, then to the host's */
static void log3(fmi2ComponentEnvironment env, fmi2String name, fmi2Status st, fmi2String category,
                 fmi2String fmt, ...) {
    Host3 *h = env;
    char msg[2048];
    va_list ap;
    (void)name;
    if (!h || !h->log) return;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    h->log(h->env, (fmi3Status)(st > fmi2Fatal ? fmi2Error : st), category ? category : "", msg);
}

static void *alloc3(size_t n, size_t size) { return calloc(n, size); }

static fmi3Status status3(fmi2Status st) { return st > fmi2Fatal ? fmi3Error : (fmi3Status)st; }

static fmi3Status unsupported3(fmi3Instance instance, const char *what) {
    Host3 *h = instance;
    char msg[256];
    snprintf(msg, sizeof msg, "%s is not supported by this container", what);
    if (h && h->log) h->log(h->env, fmi3Error, "logStatusError", msg);
    return fmi3Error;
}

static fmi3Instance refuse_instance(fmi3InstanceEnvironment env, fmi3LogMessageCallback log, const char *what) {
    char msg[256];
    snprintf(msg, sizeof msg, "%s: this FMU is co-simulation only", what);
    if (log) log(env, fmi3Error, "logStatusError", msg);
    return NULL;
}

const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn, size_t nCategories,
                               const fmi3String categories[]) {
    (void)instance; (void)loggingOn; (void)nCategories; (void)categories;
    return fmi3OK;
}

fmi3Instance fmi3InstantiateCoSimulation(fmi3String instanceName, fmi3String instantiationToken,
                                         fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                         fmi3Boolean eventModeUsed, fmi3Boolean earlyReturnAllowed,
                                         const fmi3ValueReference requiredIntermediateVariables[],
                                         size_t nRequiredIntermediateVariables,
                                         fmi3InstanceEnvironment instanceEnvironment,
                                         fmi3LogMessageCallback logMessage,
                                         fmi3IntermediateUpdateCallback intermediateUpdate) {
    Host3 *h = calloc(1, sizeof(Host3));
    char *uri;
    (void)eventModeUsed; (void)requiredIntermediateVariables;
    (void)nRequiredIntermediateVariables; (void)intermediateUpdate;
    if (!h) return NULL;
    h->env = instanceEnvironment; h->log = logMessage; h->early_return_allowed = earlyReturnAllowed;
    h->cb.logger = log3; h->cb.allocateMemory = alloc3; h->cb.freeMemory = free; h->cb.componentEnvironment = h;
    if (!resourcePath) {
        if (logMessage) logMessage(instanceEnvironment, fmi3Error, "logStatusError", "no resource path");
        free(h);
        return NULL;
    }
    uri = encode_uri(resourcePath);   /* (an absolute path: the FMI 2.0 container takes it as a file URI) */
    h->s = fmi2Instantiate(instanceName, fmi2CoSimulation, instantiationToken, uri, &h->cb, visible, loggingOn);
    free(uri);
    if (!h->s) { free(h); return NULL; }
    return h;
}

void fmi3FreeInstance(fmi3Instance instance) {
    Host3 *h = instance;
    if (!h) return;
    fmi2FreeInstance(h->s);
    free(h);
}

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined, fmi3Float64 tolerance,
                                       fmi3Float64 startTime, fmi3Boolean stopTimeDefined, fmi3Float64 stopTime) {
    Host3 *h = instance;
    fmi2Status st = fmi2SetupExperiment(h->s, toleranceDefined, tolerance, startTime, stopTimeDefined, stopTime);
    h->time = startTime;
    return status3(st ? st : fmi2EnterInitializationMode(h->s));
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance) {
    return status3(fmi2ExitInitializationMode(((Host3 *)instance)->s));
}

fmi3Status fmi3Terminate(fmi3Instance instance) { return status3(fmi2Terminate(((Host3 *)instance)->s)); }

fmi3Status fmi3Reset(fmi3Instance instance) { return unsupported3(instance, "fmi3Reset"); }

fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
                      fmi3Float64 communicationStepSize, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                      fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation, fmi3Boolean *earlyReturn,
                      fmi3Float64 *lastSuccessfulTime) {
    Host3 *h = instance;
    fmi2Status st = fmi2DoStep(h->s, currentCommunicationPoint, communicationStepSize,
                               noSetFMUStatePriorToCurrentPoint);
    if (eventHandlingNeeded) *eventHandlingNeeded = false;
    if (terminateSimulation) *terminateSimulation = false;
    if (earlyReturn) *earlyReturn = false;
    if (st == fmi2Discard && (h->s->terminated || h->s->act.stopped)) {
        /* the simulation ended inside the step: an inner FMU ended it, or a stop event (container.c); without
         * early return the host's step ends where it asked, the outputs those of the end's time */
        double at = h->s->act.stopped ? h->s->act.stop_time : h->s->last_successful;
        if (terminateSimulation) *terminateSimulation = true;
        if (h->early_return_allowed) {
            if (earlyReturn) *earlyReturn = at < currentCommunicationPoint + communicationStepSize;
            if (lastSuccessfulTime) *lastSuccessfulTime = at;
            h->time = at;
        } else {
            if (lastSuccessfulTime) *lastSuccessfulTime = currentCommunicationPoint + communicationStepSize;
            h->time = currentCommunicationPoint + communicationStepSize;
        }
        return fmi3OK;
    }
    if (st == fmi2OK) h->time = currentCommunicationPoint + communicationStepSize;
    if (lastSuccessfulTime)
        *lastSuccessfulTime = st == fmi2OK ? currentCommunicationPoint + communicationStepSize
                                           : currentCommunicationPoint;
    return status3(st);
}

/* the container's variables: Float64 (its Real; time at value reference 0), Int32 (its Integer), Boolean (its
 * Boolean, 0 or 1 inside) */
fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, fmi3Float64 values[], size_t nValues) {
    Host3 *h = instance;
    size_t j;
    (void)nValues;
    for (j = 0; j < nValueReferences; j++) {
        fmi2Status st;
        if (valueReferences[j] == 0) { values[j] = h->time; continue; }
        if ((st = fmi2GetReal(h->s, &valueReferences[j], 1, &values[j]))) return status3(st);
    }
    return fmi3OK;
}

fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, const fmi3Float64 values[], size_t nValues) {
    (void)nValues;
    return status3(fmi2SetReal(((Host3 *)instance)->s, valueReferences, nValueReferences, values));
}

fmi3Status fmi3GetInt32(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                        size_t nValueReferences, fmi3Int32 values[], size_t nValues) {
    (void)nValues;
    return status3(fmi2GetInteger(((Host3 *)instance)->s, valueReferences, nValueReferences, (fmi2Integer *)values));
}

fmi3Status fmi3SetInt32(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                        size_t nValueReferences, const fmi3Int32 values[], size_t nValues) {
    (void)nValues;
    return status3(fmi2SetInteger(((Host3 *)instance)->s, valueReferences, nValueReferences,
                                  (const fmi2Integer *)values));
}

fmi3Status fmi3GetBoolean(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, fmi3Boolean values[], size_t nValues) {
    size_t j;
    (void)nValues;
    for (j = 0; j < nValueReferences; j++) {
        fmi2Boolean b = 0;
        fmi2Status st = fmi2GetBoolean(((Host3 *)instance)->s, &valueReferences[j], 1, &b);
        if (st) return status3(st);
        values[j] = b != 0;
    }
    return fmi3OK;
}

fmi3Status fmi3SetBoolean(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, const fmi3Boolean values[], size_t nValues) {
    size_t j;
    (void)nValues;
    for (j = 0; j < nValueReferences; j++) {
        fmi2Boolean b = values[j] ? 1 : 0;
        fmi2Status st = fmi2SetBoolean(((Host3 *)instance)->s, &valueReferences[j], 1, &b);
        if (st) return status3(st);
    }
    return fmi3OK;
}

/* ------------------------------------------------------------------ what this container does not do */
fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn, fmi3InstanceEnvironment instanceEnvironment, fmi3LogMessageCallback logMessage) { return refuse_instance(instanceEnvironment, logMessage, "fmi3InstantiateModelExchange"); }
fmi3Instance fmi3InstantiateScheduledExecution(fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn, fmi3InstanceEnvironment instanceEnvironment, fmi3LogMessageCallback logMessage, fmi3ClockUpdateCallback clockUpdate, fmi3LockPreemptionCallback lockPreemption, fmi3UnlockPreemptionCallback unlockPreemption) { return refuse_instance(instanceEnvironment, logMessage, "fmi3InstantiateScheduledExecution"); }
fmi3Status fmi3EnterEventMode(fmi3Instance instance) { return unsupported3(instance, "fmi3EnterEventMode"); }
fmi3Status fmi3GetFloat32(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3Float32 values[], size_t nValues) { return nValueReferences == 0 ? fmi3OK : unsupported3(instance, "fmi3GetFloat32"); }
fmi3Status fmi3GetInt8(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3Int8 values[], size_t nValues) { return nValueReferences == 0 ? fmi3OK : unsupported3(instance, "fmi3GetInt8"); }
fmi3Status fmi3GetUInt8(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3UInt8 values[], size_t nValues) { return nValueReferences == 0 ? fmi3OK : unsupported3(instance, "fmi3GetUInt8"); }
fmi3Status fmi3GetInt16(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3Int16 values[], size_t nValues) { return nValueReferences == 0 ? fmi3OK : unsupported3(instance, "fmi3GetInt16"); }
fmi3Status fmi3GetUInt16(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3UInt16 values[], size_t nValues) { return nValueReferences == 0 ? fmi3OK : unsupported3(instance, "fmi3GetUInt16"); }
fmi3Status fmi3GetUInt32(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3UInt32 values[], size_t nValues) { return nValueReferences == 0 ? fmi3OK : unsupported3(instance, "fmi3GetUInt32"); }
fmi3Status fmi3GetInt64(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3Int64 values[], size_t nValues) { return nValueReferences == 0 ? fmi3OK : unsupported3(instance, "fmi3GetInt64"); }
fmi3Status fmi3GetUInt64(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3UInt64 values[], size_t nValues) { return nValueReferences == 0 ? fmi3OK : unsupported3(instance, "fmi3GetUInt64"); }
fmi3Status fmi3GetString(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3String values[], size_t nValues) { return nValueReferences == 0 ? fmi3OK : unsupported3(instance, "fmi3GetString"); }
fmi3Status fmi3GetBinary(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, size_t valueSizes[], fmi3Binary values[], size_t nValues) { return nValueReferences == 0 ? fmi3OK : unsupported3(instance, "fmi3GetBinary"); }
fmi3Status fmi3GetClock(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3Clock values[]) { return nValueReferences == 0 ? fmi3OK : unsupported3(instance, "fmi3GetClock"); }
fmi3Status fmi3SetFloat32(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3Float32 values[], size_t nValues) { return nValueReferences == 0 ? fmi3OK : unsupported3(instance, "fmi3SetFloat32"); }
fmi3Status fmi3SetInt8(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3Int8 values[], size_t nValues) { return nValueReferences == 0 ? fmi3OK : unsupported3(instance, "fmi3SetInt8"); }
fmi3Status fmi3SetUInt8(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3UInt8 values[], size_t nValues) { return nValueReferences == 0 ? fmi3OK : unsupported3(instance, "fmi3SetUInt8"); }
fmi3Status fmi3SetInt16(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3Int16 values[], size_t nValues) { return nValueReferences == 0 ? fmi3OK : unsupported3(instance, "fmi3SetInt16"); }
fmi3Status fmi3SetUInt16(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3UInt16 values[], size_t nValues) { return nValueReferences == 0 ? fmi3OK : unsupported3(instance, "fmi3SetUInt16"); }
fmi3Status fmi3SetUInt32(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3UInt32 values[], size_t nValues) { return nValueReferences == 0 ? fmi3OK : unsupported3(instance, "fmi3SetUInt32"); }
fmi3Status fmi3SetInt64(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3Int64 values[], size_t nValues) { return nValueReferences == 0 ? fmi3OK : unsupported3(instance, "fmi3SetInt64"); }
fmi3Status fmi3SetUInt64(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3UInt64 values[], size_t nValues) { return nValueReferences == 0 ? fmi3OK : unsupported3(instance, "fmi3SetUInt64"); }
fmi3Status fmi3SetString(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3String values[], size_t nValues) { return nValueReferences == 0 ? fmi3OK : unsupported3(instance, "fmi3SetString"); }
fmi3Status fmi3SetBinary(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const size_t valueSizes[], const fmi3Binary values[], size_t nValues) { return nValueReferences == 0 ? fmi3OK : unsupported3(instance, "fmi3SetBinary"); }
fmi3Status fmi3SetClock(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3Clock values[]) { return nValueReferences == 0 ? fmi3OK : unsupported3(instance, "fmi3SetClock"); }
fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance instance, fmi3ValueReference valueReference, size_t* nDependencies) { return unsupported3(instance, "fmi3GetNumberOfVariableDependencies"); }
fmi3Status fmi3GetVariableDependencies(fmi3Instance instance, fmi3ValueReference dependent, size_t elementIndicesOfDependent[], fmi3ValueReference independents[], size_t elementIndicesOfIndependents[], fmi3DependencyKind dependencyKinds[], size_t nDependencies) { return unsupported3(instance, "fmi3GetVariableDependencies"); }
fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState* FMUState) { return unsupported3(instance, "fmi3GetFMUState"); }
fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState FMUState) { return unsupported3(instance, "fmi3SetFMUState"); }
fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState* FMUState) { return unsupported3(instance, "fmi3FreeFMUState"); }
fmi3Status fmi3SerializedFMUStateSize(fmi3Instance instance, fmi3FMUState FMUState, size_t* size) { return unsupported3(instance, "fmi3SerializedFMUStateSize"); }
fmi3Status fmi3SerializeFMUState(fmi3Instance instance, fmi3FMUState FMUState, fmi3Byte serializedState[], size_t size) { return unsupported3(instance, "fmi3SerializeFMUState"); }
fmi3Status fmi3DeserializeFMUState(fmi3Instance instance, const fmi3Byte serializedState[], size_t size, fmi3FMUState* FMUState) { return unsupported3(instance, "fmi3DeserializeFMUState"); }
fmi3Status fmi3GetDirectionalDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns, const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[], size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity) { return unsupported3(instance, "fmi3GetDirectionalDerivative"); }
fmi3Status fmi3GetAdjointDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns, const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[], size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity) { return unsupported3(instance, "fmi3GetAdjointDerivative"); }
fmi3Status fmi3EnterConfigurationMode(fmi3Instance instance) { return unsupported3(instance, "fmi3EnterConfigurationMode"); }
fmi3Status fmi3ExitConfigurationMode(fmi3Instance instance) { return unsupported3(instance, "fmi3ExitConfigurationMode"); }
fmi3Status fmi3GetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3Float64 intervals[], fmi3IntervalQualifier qualifiers[]) { return nValueReferences == 0 ? fmi3OK : unsupported3(instance, "fmi3GetIntervalDecimal"); }
fmi3Status fmi3GetIntervalFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3UInt64 counters[], fmi3UInt64 resolutions[], fmi3IntervalQualifier qualifiers[]) { return nValueReferences == 0 ? fmi3OK : unsupported3(instance, "fmi3GetIntervalFraction"); }
fmi3Status fmi3GetShiftDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3Float64 shifts[]) { return nValueReferences == 0 ? fmi3OK : unsupported3(instance, "fmi3GetShiftDecimal"); }
fmi3Status fmi3GetShiftFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3UInt64 counters[], fmi3UInt64 resolutions[]) { return nValueReferences == 0 ? fmi3OK : unsupported3(instance, "fmi3GetShiftFraction"); }
fmi3Status fmi3SetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3Float64 intervals[]) { return nValueReferences == 0 ? fmi3OK : unsupported3(instance, "fmi3SetIntervalDecimal"); }
fmi3Status fmi3SetIntervalFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3UInt64 counters[], const fmi3UInt64 resolutions[]) { return nValueReferences == 0 ? fmi3OK : unsupported3(instance, "fmi3SetIntervalFraction"); }
fmi3Status fmi3SetShiftDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3Float64 shifts[]) { return nValueReferences == 0 ? fmi3OK : unsupported3(instance, "fmi3SetShiftDecimal"); }
fmi3Status fmi3SetShiftFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3UInt64 counters[], const fmi3UInt64 resolutions[]) { return nValueReferences == 0 ? fmi3OK : unsupported3(instance, "fmi3SetShiftFraction"); }
fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance instance) { return unsupported3(instance, "fmi3EvaluateDiscreteStates"); }
fmi3Status fmi3UpdateDiscreteStates(fmi3Instance instance, fmi3Boolean* discreteStatesNeedUpdate, fmi3Boolean* terminateSimulation, fmi3Boolean* nominalsOfContinuousStatesChanged, fmi3Boolean* valuesOfContinuousStatesChanged, fmi3Boolean* nextEventTimeDefined, fmi3Float64* nextEventTime) { return unsupported3(instance, "fmi3UpdateDiscreteStates"); }
fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance instance) { return unsupported3(instance, "fmi3EnterContinuousTimeMode"); }
fmi3Status fmi3CompletedIntegratorStep(fmi3Instance instance, fmi3Boolean noSetFMUStatePriorToCurrentPoint, fmi3Boolean* enterEventMode, fmi3Boolean* terminateSimulation) { return unsupported3(instance, "fmi3CompletedIntegratorStep"); }
fmi3Status fmi3SetTime(fmi3Instance instance, fmi3Float64 time) { return unsupported3(instance, "fmi3SetTime"); }
fmi3Status fmi3SetContinuousStates(fmi3Instance instance, const fmi3Float64 continuousStates[], size_t nContinuousStates) { return unsupported3(instance, "fmi3SetContinuousStates"); }
fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance instance, fmi3Float64 derivatives[], size_t nContinuousStates) { return unsupported3(instance, "fmi3GetContinuousStateDerivatives"); }
fmi3Status fmi3GetEventIndicators(fmi3Instance instance, fmi3Float64 eventIndicators[], size_t nEventIndicators) { return unsupported3(instance, "fmi3GetEventIndicators"); }
fmi3Status fmi3GetContinuousStates(fmi3Instance instance, fmi3Float64 continuousStates[], size_t nContinuousStates) { return unsupported3(instance, "fmi3GetContinuousStates"); }
fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance instance, fmi3Float64 nominals[], size_t nContinuousStates) { return unsupported3(instance, "fmi3GetNominalsOfContinuousStates"); }
fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance instance, size_t* nEventIndicators) { return unsupported3(instance, "fmi3GetNumberOfEventIndicators"); }
fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance instance, size_t* nContinuousStates) { return unsupported3(instance, "fmi3GetNumberOfContinuousStates"); }
fmi3Status fmi3EnterStepMode(fmi3Instance instance) { return unsupported3(instance, "fmi3EnterStepMode"); }
fmi3Status fmi3GetOutputDerivatives(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3Int32 orders[], fmi3Float64 values[], size_t nValues) { return nValueReferences == 0 ? fmi3OK : unsupported3(instance, "fmi3GetOutputDerivatives"); }
fmi3Status fmi3ActivateModelPartition(fmi3Instance instance, fmi3ValueReference clockReference, fmi3Float64 activationTime) { return unsupported3(instance, "fmi3ActivateModelPartition"); }
