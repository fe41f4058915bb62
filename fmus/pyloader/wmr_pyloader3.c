/*
 * The binary binaries/x86_64-linux/<model>.so of our pythonfmu3 FMUs (FMI 3.0): makes sure a Python
 * interpreter is in the process, then hands every FMI 3.0 call to pythonfmu3's own binary, shipped beside
 * it as libpythonfmu-export.so.  The FMI 2.0 loader (wmr_pyloader.c) does the same for pythonfmu.
 *
 * pythonfmu3's binary takes the Python C API from the process that loads it: alone it runs only in a
 * Python host.  On the first instantiation this loader finds or starts an interpreter (wmr_pyfinder.h: the
 * one in the process, else WMR_PY_ENV's library or the libpython recorded at build time), then loads
 * libpythonfmu-export.so and resolves its FMI 3.0 functions (all of fmi3FunctionTypes.h: the binary
 * exports all of them).  When no interpreter can be had, the instantiation returns NULL after one line
 * through the host's logMessage callback.  The interpreter is never finalised.
 *
 * Clocks (the sampled-data FMUs' periodic input clock): pythonfmu3 0.3's binary tells the slave nothing of
 * eventModeUsed and has no fmi3SetClock/GetClock (it throws "not implemented").  This loader sets the
 * Boolean value reference WMR_EVENT_MODE_VR of the slave true after an instantiation with eventModeUsed
 * (and again after fmi3Reset, which makes a new slave), forwards fmi3SetClock and fmi3GetClock as
 * fmi3SetBoolean and fmi3GetBoolean of the clock's value reference (fmi3Clock and fmi3Boolean are both
 * bool), and returns fmi3Error from fmi3UpdateDiscreteStates when the slave reports a failed sample (it sets
 * nominalsOfContinuousStatesChanged, which means nothing in co-simulation; the importer gets false).  The
 * slave's side is fmus/fmi3_base.py (EVENT_MODE_VR, update_discrete_states).
 *
 * Around pythonfmu3 0.3's defects (wmr_pyfinder.h): after each instantiation the binary's global, empty
 * PyState is released (no use-after-free at exit), and an instance that returned fmi3Fatal gets no
 * further call (not even fmi3FreeInstance, which would release its Python objects a second time).
 *
 * Built by fmus/build.py with the system C compiler:
 *   cc -shared -fPIC -O2 -I<FMI 3.0 headers> -DWMR_PY_LIBRARY=... -DWMR_PY_HOME=... -DWMR_PY_VERSION=...
 *      -DWMR_PY_ENV=... -DWMR_PY_MIN_MINOR=... wmr_pyloader3.c -ldl -lpthread
 * (it builds for Windows too, as wmr_pyloader.c does; no FMU ships that build: it is not tested).
 */
#include "wmr_pyfinder.h"
#include "fmi3Functions.h"

/* Every FMI 3.0 function that takes an instance and returns a status: X(name, parameters, arguments of
 * the forwarded call, REAL standing for the binary's instance).  From fmi3FunctionTypes.h. */
#define FMI3_FORWARDED(X) \
    X(fmi3SetDebugLogging, (fmi3Instance instance, fmi3Boolean loggingOn, size_t nCategories, const fmi3String categories[]), (REAL, loggingOn, nCategories, categories)) \
    X(fmi3EnterInitializationMode, (fmi3Instance instance, fmi3Boolean toleranceDefined, fmi3Float64 tolerance, fmi3Float64 startTime, fmi3Boolean stopTimeDefined, fmi3Float64 stopTime), (REAL, toleranceDefined, tolerance, startTime, stopTimeDefined, stopTime)) \
    X(fmi3ExitInitializationMode, (fmi3Instance instance), (REAL)) \
    X(fmi3EnterEventMode, (fmi3Instance instance), (REAL)) \
    X(fmi3Terminate, (fmi3Instance instance), (REAL)) \
    X(fmi3GetFloat32, (fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3Float32 values[], size_t nValues), (REAL, valueReferences, nValueReferences, values, nValues)) \
    X(fmi3GetFloat64, (fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3Float64 values[], size_t nValues), (REAL, valueReferences, nValueReferences, values, nValues)) \
    X(fmi3GetInt8, (fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3Int8 values[], size_t nValues), (REAL, valueReferences, nValueReferences, values, nValues)) \
    X(fmi3GetUInt8, (fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3UInt8 values[], size_t nValues), (REAL, valueReferences, nValueReferences, values, nValues)) \
    X(fmi3GetInt16, (fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3Int16 values[], size_t nValues), (REAL, valueReferences, nValueReferences, values, nValues)) \
    X(fmi3GetUInt16, (fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3UInt16 values[], size_t nValues), (REAL, valueReferences, nValueReferences, values, nValues)) \
    X(fmi3GetInt32, (fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3Int32 values[], size_t nValues), (REAL, valueReferences, nValueReferences, values, nValues)) \
    X(fmi3GetUInt32, (fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3UInt32 values[], size_t nValues), (REAL, valueReferences, nValueReferences, values, nValues)) \
    X(fmi3GetInt64, (fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3Int64 values[], size_t nValues), (REAL, valueReferences, nValueReferences, values, nValues)) \
    X(fmi3GetUInt64, (fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3UInt64 values[], size_t nValues), (REAL, valueReferences, nValueReferences, values, nValues)) \
    X(fmi3GetBoolean, (fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3Boolean values[], size_t nValues), (REAL, valueReferences, nValueReferences, values, nValues)) \
    X(fmi3GetString, (fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3String values[], size_t nValues), (REAL, valueReferences, nValueReferences, values, nValues)) \
    X(fmi3GetBinary, (fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, size_t valueSizes[], fmi3Binary values[], size_t nValues), (REAL, valueReferences, nValueReferences, valueSizes, values, nValues)) \
    X(fmi3SetFloat32, (fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3Float32 values[], size_t nValues), (REAL, valueReferences, nValueReferences, values, nValues)) \
    X(fmi3SetFloat64, (fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3Float64 values[], size_t nValues), (REAL, valueReferences, nValueReferences, values, nValues)) \
    X(fmi3SetInt8, (fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3Int8 values[], size_t nValues), (REAL, valueReferences, nValueReferences, values, nValues)) \
    X(fmi3SetUInt8, (fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3UInt8 values[], size_t nValues), (REAL, valueReferences, nValueReferences, values, nValues)) \
    X(fmi3SetInt16, (fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3Int16 values[], size_t nValues), (REAL, valueReferences, nValueReferences, values, nValues)) \
    X(fmi3SetUInt16, (fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3UInt16 values[], size_t nValues), (REAL, valueReferences, nValueReferences, values, nValues)) \
    X(fmi3SetInt32, (fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3Int32 values[], size_t nValues), (REAL, valueReferences, nValueReferences, values, nValues)) \
    X(fmi3SetUInt32, (fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3UInt32 values[], size_t nValues), (REAL, valueReferences, nValueReferences, values, nValues)) \
    X(fmi3SetInt64, (fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3Int64 values[], size_t nValues), (REAL, valueReferences, nValueReferences, values, nValues)) \
    X(fmi3SetUInt64, (fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3UInt64 values[], size_t nValues), (REAL, valueReferences, nValueReferences, values, nValues)) \
    X(fmi3SetBoolean, (fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3Boolean values[], size_t nValues), (REAL, valueReferences, nValueReferences, values, nValues)) \
    X(fmi3SetString, (fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3String values[], size_t nValues), (REAL, valueReferences, nValueReferences, values, nValues)) \
    X(fmi3SetBinary, (fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const size_t valueSizes[], const fmi3Binary values[], size_t nValues), (REAL, valueReferences, nValueReferences, valueSizes, values, nValues)) \
    X(fmi3GetNumberOfVariableDependencies, (fmi3Instance instance, fmi3ValueReference valueReference, size_t* nDependencies), (REAL, valueReference, nDependencies)) \
    X(fmi3GetVariableDependencies, (fmi3Instance instance, fmi3ValueReference dependent, size_t elementIndicesOfDependent[], fmi3ValueReference independents[], size_t elementIndicesOfIndependents[], fmi3DependencyKind dependencyKinds[], size_t nDependencies), (REAL, dependent, elementIndicesOfDependent, independents, elementIndicesOfIndependents, dependencyKinds, nDependencies)) \
    X(fmi3GetFMUState, (fmi3Instance instance, fmi3FMUState* FMUState), (REAL, FMUState)) \
    X(fmi3SetFMUState, (fmi3Instance instance, fmi3FMUState FMUState), (REAL, FMUState)) \
    X(fmi3FreeFMUState, (fmi3Instance instance, fmi3FMUState* FMUState), (REAL, FMUState)) \
    X(fmi3SerializedFMUStateSize, (fmi3Instance instance, fmi3FMUState FMUState, size_t* size), (REAL, FMUState, size)) \
    X(fmi3SerializeFMUState, (fmi3Instance instance, fmi3FMUState FMUState, fmi3Byte serializedState[], size_t size), (REAL, FMUState, serializedState, size)) \
    X(fmi3DeserializeFMUState, (fmi3Instance instance, const fmi3Byte serializedState[], size_t size, fmi3FMUState* FMUState), (REAL, serializedState, size, FMUState)) \
    X(fmi3GetDirectionalDerivative, (fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns, const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[], size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity), (REAL, unknowns, nUnknowns, knowns, nKnowns, seed, nSeed, sensitivity, nSensitivity)) \
    X(fmi3GetAdjointDerivative, (fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns, const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[], size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity), (REAL, unknowns, nUnknowns, knowns, nKnowns, seed, nSeed, sensitivity, nSensitivity)) \
    X(fmi3EnterConfigurationMode, (fmi3Instance instance), (REAL)) \
    X(fmi3ExitConfigurationMode, (fmi3Instance instance), (REAL)) \
    X(fmi3GetIntervalDecimal, (fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3Float64 intervals[], fmi3IntervalQualifier qualifiers[]), (REAL, valueReferences, nValueReferences, intervals, qualifiers)) \
    X(fmi3GetIntervalFraction, (fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3UInt64 counters[], fmi3UInt64 resolutions[], fmi3IntervalQualifier qualifiers[]), (REAL, valueReferences, nValueReferences, counters, resolutions, qualifiers)) \
    X(fmi3GetShiftDecimal, (fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3Float64 shifts[]), (REAL, valueReferences, nValueReferences, shifts)) \
    X(fmi3GetShiftFraction, (fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3UInt64 counters[], fmi3UInt64 resolutions[]), (REAL, valueReferences, nValueReferences, counters, resolutions)) \
    X(fmi3SetIntervalDecimal, (fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3Float64 intervals[]), (REAL, valueReferences, nValueReferences, intervals)) \
    X(fmi3SetIntervalFraction, (fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3UInt64 counters[], const fmi3UInt64 resolutions[]), (REAL, valueReferences, nValueReferences, counters, resolutions)) \
    X(fmi3SetShiftDecimal, (fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3Float64 shifts[]), (REAL, valueReferences, nValueReferences, shifts)) \
    X(fmi3SetShiftFraction, (fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3UInt64 counters[], const fmi3UInt64 resolutions[]), (REAL, valueReferences, nValueReferences, counters, resolutions)) \
    X(fmi3EvaluateDiscreteStates, (fmi3Instance instance), (REAL)) \
    X(fmi3EnterContinuousTimeMode, (fmi3Instance instance), (REAL)) \
    X(fmi3CompletedIntegratorStep, (fmi3Instance instance, fmi3Boolean noSetFMUStatePriorToCurrentPoint, fmi3Boolean* enterEventMode, fmi3Boolean* terminateSimulation), (REAL, noSetFMUStatePriorToCurrentPoint, enterEventMode, terminateSimulation)) \
    X(fmi3SetTime, (fmi3Instance instance, fmi3Float64 time), (REAL, time)) \
    X(fmi3SetContinuousStates, (fmi3Instance instance, const fmi3Float64 continuousStates[], size_t nContinuousStates), (REAL, continuousStates, nContinuousStates)) \
    X(fmi3GetContinuousStateDerivatives, (fmi3Instance instance, fmi3Float64 derivatives[], size_t nContinuousStates), (REAL, derivatives, nContinuousStates)) \
    X(fmi3GetEventIndicators, (fmi3Instance instance, fmi3Float64 eventIndicators[], size_t nEventIndicators), (REAL, eventIndicators, nEventIndicators)) \
    X(fmi3GetContinuousStates, (fmi3Instance instance, fmi3Float64 continuousStates[], size_t nContinuousStates), (REAL, continuousStates, nContinuousStates)) \
    X(fmi3GetNominalsOfContinuousStates, (fmi3Instance instance, fmi3Float64 nominals[], size_t nContinuousStates), (REAL, nominals, nContinuousStates)) \
    X(fmi3GetNumberOfEventIndicators, (fmi3Instance instance, size_t* nEventIndicators), (REAL, nEventIndicators)) \
    X(fmi3GetNumberOfContinuousStates, (fmi3Instance instance, size_t* nContinuousStates), (REAL, nContinuousStates)) \
    X(fmi3EnterStepMode, (fmi3Instance instance), (REAL)) \
    X(fmi3GetOutputDerivatives, (fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3Int32 orders[], fmi3Float64 values[], size_t nValues), (REAL, valueReferences, nValueReferences, orders, values, nValues)) \
    X(fmi3DoStep, (fmi3Instance instance, fmi3Float64 currentCommunicationPoint, fmi3Float64 communicationStepSize, fmi3Boolean noSetFMUStatePriorToCurrentPoint, fmi3Boolean* eventHandlingNeeded, fmi3Boolean* terminateSimulation, fmi3Boolean* earlyReturn, fmi3Float64* lastSuccessfulTime), (REAL, currentCommunicationPoint, communicationStepSize, noSetFMUStatePriorToCurrentPoint, eventHandlingNeeded, terminateSimulation, earlyReturn, lastSuccessfulTime)) \
    X(fmi3ActivateModelPartition, (fmi3Instance instance, fmi3ValueReference clockReference, fmi3Float64 activationTime), (REAL, clockReference, activationTime))

/* The FMI 3.0 functions this loader wraps rather than forwards (the clock, below): the same form. */
#define FMI3_WRAPPED(X) \
    X(fmi3Reset, (fmi3Instance instance), (REAL)) \
    X(fmi3GetClock, (fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3Clock values[]), (REAL, valueReferences, nValueReferences, values)) \
    X(fmi3SetClock, (fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3Clock values[]), (REAL, valueReferences, nValueReferences, values)) \
    X(fmi3UpdateDiscreteStates, (fmi3Instance instance, fmi3Boolean* discreteStatesNeedUpdate, fmi3Boolean* terminateSimulation, fmi3Boolean* nominalsOfContinuousStatesChanged, fmi3Boolean* valuesOfContinuousStatesChanged, fmi3Boolean* nextEventTimeDefined, fmi3Float64* nextEventTime), (REAL, discreteStatesNeedUpdate, terminateSimulation, nominalsOfContinuousStatesChanged, valuesOfContinuousStatesChanged, nextEventTimeDefined, nextEventTime))

/* pythonfmu3's FMI functions */
static struct {
    fmi3InstantiateModelExchangeTYPE *fmi3InstantiateModelExchange;
    fmi3InstantiateCoSimulationTYPE *fmi3InstantiateCoSimulation;
    fmi3InstantiateScheduledExecutionTYPE *fmi3InstantiateScheduledExecution;
    fmi3FreeInstanceTYPE *fmi3FreeInstance;
#define X(name, params, args) name##TYPE *name;
    FMI3_FORWARDED(X)
    FMI3_WRAPPED(X)
#undef X
} F;

#define RESOLVE(name)                                                    \
    do {                                                                 \
        *(void **)(&F.name) = wmr_sym(real, #name);                          \
        if (F.name == NULL) {                                            \
            wmr_fail("pythonfmu3's binary has no function %s", #name);   \
            return 0;                                                    \
        }                                                                \
    } while (0)

static int load_real(const wmr_char *dir, const char *resourcePath) {
    wmr_lib real = wmr_load_binary(dir, resourcePath, 0, WMR_PLATFORM3);
    if (real == NULL) return 0;
    RESOLVE(fmi3InstantiateModelExchange);
    RESOLVE(fmi3InstantiateCoSimulation);
    RESOLVE(fmi3InstantiateScheduledExecution);
    RESOLVE(fmi3FreeInstance);
#define X(name, params, args) RESOLVE(name);
    FMI3_FORWARDED(X)
    FMI3_WRAPPED(X)
#undef X
    return 1;
}

/* 1 when the binary is loaded; otherwise logs why through logMessage (or stderr) and returns 0. */
static int ready(fmi3String resourcePath, fmi3InstanceEnvironment env, fmi3LogMessageCallback logMessage) {
    char model[256];
    if (wmr_ready(load_real, resourcePath, model, sizeof model)) return 1;
    char msg[sizeof wmr_load_error + 300];
    snprintf(msg, sizeof msg, "%s: no Python interpreter for this FMU: %s", model[0] ? model : "FMU", wmr_load_error);
    if (logMessage)
        logMessage(env, fmi3Error, "logStatusError", msg);
    else
        fprintf(stderr, "%s\n", msg);
    return 0;
}

const char *fmi3GetVersion(void) { return fmi3Version; }

/* The Boolean value reference that tells the slave eventModeUsed (fmus/fmi3_base.py, EVENT_MODE_VR): no
 * variable has it.  pythonfmu3 hands value references to Python as C ints, so it is the largest one. */
#define WMR_EVENT_MODE_VR 0x7FFFFFFFu

/* Tell the slave of `w` that the importer uses event mode; 0 on failure (then the slave logged why). */
static int tell_event_mode(wmr_instance *w) {
    const fmi3ValueReference vr = WMR_EVENT_MODE_VR;
    const fmi3Boolean on = fmi3True;
    fmi3Status s = F.fmi3SetBoolean(w->real, &vr, 1, &on, 1);
    if (s == fmi3Fatal) w->fatal = 1;
    return s <= fmi3Warning;
}

fmi3Instance fmi3InstantiateCoSimulation(fmi3String instanceName, fmi3String instantiationToken,
                                         fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                         fmi3Boolean eventModeUsed, fmi3Boolean earlyReturnAllowed,
                                         const fmi3ValueReference requiredIntermediateVariables[],
                                         size_t nRequiredIntermediateVariables,
                                         fmi3InstanceEnvironment instanceEnvironment,
                                         fmi3LogMessageCallback logMessage,
                                         fmi3IntermediateUpdateCallback intermediateUpdate) {
    if (!ready(resourcePath, instanceEnvironment, logMessage)) return NULL;
    wmr_instantiate_begin();
    fmi3Instance c = F.fmi3InstantiateCoSimulation(instanceName, instantiationToken, resourcePath, visible,
                                                   loggingOn, eventModeUsed, earlyReturnAllowed,
                                                   requiredIntermediateVariables, nRequiredIntermediateVariables,
                                                   instanceEnvironment, logMessage, intermediateUpdate);
    wmr_instantiate_end();
    wmr_instance *w = wmr_wrap(c);
    if (w != NULL && eventModeUsed) {
        w->event_mode = 1;
        if (!tell_event_mode(w)) {
            fmi3FreeInstance((fmi3Instance)w);
            return NULL;
        }
    }
    return (fmi3Instance)w;
}

fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName, fmi3String instantiationToken,
                                          fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                          fmi3InstanceEnvironment instanceEnvironment,
                                          fmi3LogMessageCallback logMessage) {
    if (!ready(resourcePath, instanceEnvironment, logMessage)) return NULL;
    wmr_instantiate_begin();
    fmi3Instance c = F.fmi3InstantiateModelExchange(instanceName, instantiationToken, resourcePath, visible,
                                                    loggingOn, instanceEnvironment, logMessage);
    wmr_instantiate_end();
    return (fmi3Instance)wmr_wrap(c);
}

fmi3Instance fmi3InstantiateScheduledExecution(fmi3String instanceName, fmi3String instantiationToken,
                                               fmi3String resourcePath, fmi3Boolean visible,
                                               fmi3Boolean loggingOn, fmi3InstanceEnvironment instanceEnvironment,
                                               fmi3LogMessageCallback logMessage, fmi3ClockUpdateCallback clockUpdate,
                                               fmi3LockPreemptionCallback lockPreemption,
                                               fmi3UnlockPreemptionCallback unlockPreemption) {
    if (!ready(resourcePath, instanceEnvironment, logMessage)) return NULL;
    wmr_instantiate_begin();
    fmi3Instance c = F.fmi3InstantiateScheduledExecution(instanceName, instantiationToken, resourcePath, visible,
                                                         loggingOn, instanceEnvironment, logMessage, clockUpdate,
                                                         lockPreemption, unlockPreemption);
    wmr_instantiate_end();
    return (fmi3Instance)wmr_wrap(c);
}

void fmi3FreeInstance(fmi3Instance instance) {
    wmr_instance *w = (wmr_instance *)instance;
    if (w == NULL) return;
    if (!w->fatal && F.fmi3FreeInstance) F.fmi3FreeInstance(w->real); /* after Fatal: leaked (wmr_pyfinder.h) */
    free(w);
}

/* Every other function is called only with an instance an instantiation returned (our wrapper), so the
 * binary is loaded; the NULL checks guard hosts that call out of order.  An instance that returned
 * fmi3Fatal gets no further call (see wmr_pyfinder.h). */
#define REAL w_->real
#define X(name, params, args)                                             \
    fmi3Status name params {                                              \
        wmr_instance *w_ = (wmr_instance *)instance;                      \
        if (w_ == NULL || F.name == NULL) return fmi3Error;               \
        if (w_->fatal) return fmi3Fatal;                                  \
        fmi3Status s_ = F.name args;                                      \
        if (s_ == fmi3Fatal) w_->fatal = 1;                               \
        return s_;                                                        \
    }
FMI3_FORWARDED(X)
#undef X
#undef REAL

/* fmi3Reset makes a new slave: it is told eventModeUsed again. */
fmi3Status fmi3Reset(fmi3Instance instance) {
    wmr_instance *w = (wmr_instance *)instance;
    if (w == NULL || F.fmi3Reset == NULL) return fmi3Error;
    if (w->fatal) return fmi3Fatal;
    fmi3Status s = F.fmi3Reset(w->real);
    if (s == fmi3Fatal) w->fatal = 1;
    if (s <= fmi3Warning && w->event_mode && !tell_event_mode(w)) return w->fatal ? fmi3Fatal : fmi3Error;
    return s;
}

/* The clock calls as fmi3SetBoolean/GetBoolean of the clock's value reference (the slave routes them). */
fmi3Status fmi3SetClock(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                        const fmi3Clock values[]) {
    wmr_instance *w = (wmr_instance *)instance;
    if (w == NULL || F.fmi3SetBoolean == NULL) return fmi3Error;
    if (w->fatal) return fmi3Fatal;
    fmi3Status s = F.fmi3SetBoolean(w->real, valueReferences, nValueReferences, (const fmi3Boolean *)values,
                                    nValueReferences);
    if (s == fmi3Fatal) w->fatal = 1;
    return s;
}

fmi3Status fmi3GetClock(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                        fmi3Clock values[]) {
    wmr_instance *w = (wmr_instance *)instance;
    if (w == NULL || F.fmi3GetBoolean == NULL) return fmi3Error;
    if (w->fatal) return fmi3Fatal;
    fmi3Status s = F.fmi3GetBoolean(w->real, valueReferences, nValueReferences, (fmi3Boolean *)values,
                                    nValueReferences);
    if (s == fmi3Fatal) w->fatal = 1;
    return s;
}

/* The slave's answer into the importer's (non-NULL) outputs; a failed sample (the slave sets
 * nominalsOfContinuousStatesChanged) is fmi3Error. */
fmi3Status fmi3UpdateDiscreteStates(fmi3Instance instance, fmi3Boolean *discreteStatesNeedUpdate,
                                    fmi3Boolean *terminateSimulation, fmi3Boolean *nominalsOfContinuousStatesChanged,
                                    fmi3Boolean *valuesOfContinuousStatesChanged, fmi3Boolean *nextEventTimeDefined,
                                    fmi3Float64 *nextEventTime) {
    wmr_instance *w = (wmr_instance *)instance;
    if (w == NULL || F.fmi3UpdateDiscreteStates == NULL) return fmi3Error;
    if (w->fatal) return fmi3Fatal;
    fmi3Boolean need = fmi3False, term = fmi3False, failed = fmi3False, values = fmi3False, defined = fmi3False;
    fmi3Float64 next = 0.0;
    fmi3Status s = F.fmi3UpdateDiscreteStates(w->real, &need, &term, &failed, &values, &defined, &next);
    if (s == fmi3Fatal) w->fatal = 1;
    if (discreteStatesNeedUpdate) *discreteStatesNeedUpdate = need;
    if (terminateSimulation) *terminateSimulation = term;
    if (nominalsOfContinuousStatesChanged) *nominalsOfContinuousStatesChanged = fmi3False;
    if (valuesOfContinuousStatesChanged) *valuesOfContinuousStatesChanged = values;
    if (nextEventTimeDefined) *nextEventTimeDefined = defined;
    if (nextEventTime && defined) *nextEventTime = next;
    if (s <= fmi3Warning && failed) return fmi3Error;
    return s;
}
