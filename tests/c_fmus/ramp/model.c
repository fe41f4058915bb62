/* Ramp (tests only): x' = s from x = 0, x its one event indicator (so that it starts at exactly 0), an
 * output y = x.  Parameters: s, the slope; T_reset, a time event at which x is set back to 0 and the slope
 * becomes s_after (none when T_reset < 0); T_stop, a time event at which the FMU ends the simulation
 * (terminateSimulation; FMI 2.0 co-simulation: Discard with fmi2Terminated).  Output crossings counts the
 * events at which x is in the other FMI domain (x > 0 against x <= 0) than at the event before. */
#include "config.h"
#include "model.h"

static void schedule(ModelInstance *comp) {
    comp->nextEventTimeDefined = true;
    comp->nextEventTime = (!M(reset_done) && M(T_reset) >= 0 && M(T_reset) < M(T_stop)) ? M(T_reset) : M(T_stop);
}

Status setStartValues(ModelInstance *comp) {
    M(x) = 0;
    M(s) = 1;
    M(T_reset) = -1;
    M(s_after) = 1;
    M(T_stop) = 1e300;
    M(crossings) = 0;
    M(x_last) = 0;
    M(reset_done) = 0;
    comp->isDirtyValues = true;
    return OK;
}

Status calculateValues(ModelInstance *comp) {
    if (comp->state == Instantiated || comp->state == InitializationMode) {
        schedule(comp);
    }
    comp->isDirtyValues = false;
    return OK;
}

Status getFloat64(ModelInstance *comp, ValueReference vr, double values[], size_t nValues, size_t *index) {
    ASSERT_NVALUES(1);
    switch (vr) {
        case vr_time: values[(*index)++] = comp->time; return OK;
        case vr_x: values[(*index)++] = M(x); return OK;
        case vr_der_x: values[(*index)++] = M(s); return OK;
        case vr_s: values[(*index)++] = M(s); return OK;
        case vr_T_reset: values[(*index)++] = M(T_reset); return OK;
        case vr_s_after: values[(*index)++] = M(s_after); return OK;
        case vr_T_stop: values[(*index)++] = M(T_stop); return OK;
        case vr_crossings: values[(*index)++] = M(crossings); return OK;
        default:
            logError(comp, "Get Float64 is not allowed for value reference %u.", vr);
            return Error;
    }
}

Status setFloat64(ModelInstance *comp, ValueReference vr, const double values[], size_t nValues, size_t *index) {
    ASSERT_NVALUES(1);
    const double v = values[(*index)++];
    switch (vr) {
        case vr_x: M(x) = v; M(x_last) = v; break;
        case vr_s: M(s) = v; break;
        case vr_T_reset: M(T_reset) = v; break;
        case vr_s_after: M(s_after) = v; break;
        case vr_T_stop: M(T_stop) = v; break;
        default:
            logError(comp, "Set Float64 is not allowed for value reference %u.", vr);
            return Error;
    }
    comp->isDirtyValues = true;
    return OK;
}

Status eventUpdate(ModelInstance *comp) {
    const bool timed = comp->nextEventTimeDefined
        && (comp->time >= comp->nextEventTime || isClose(comp->time, comp->nextEventTime));
    if ((M(x_last) > 0) != (M(x) > 0)) {
        M(crossings) += 1;
    }
    comp->valuesOfContinuousStatesChanged = false;
    if (timed && !M(reset_done) && M(T_reset) >= 0 && comp->nextEventTime == M(T_reset)) {
        M(x) = 0;
        M(s) = M(s_after);
        M(reset_done) = 1;
        comp->valuesOfContinuousStatesChanged = true;
    }
    M(x_last) = M(x);
    comp->terminateSimulation = timed && comp->nextEventTime == M(T_stop);
    comp->nominalsOfContinuousStatesChanged = false;
    comp->newDiscreteStatesNeeded = false;
    schedule(comp);
    return OK;
}

size_t getNumberOfEventIndicators(ModelInstance *comp) {
    UNUSED(comp);
    return 1;
}

size_t getNumberOfContinuousStates(ModelInstance *comp) {
    UNUSED(comp);
    return 1;
}

Status getContinuousStates(ModelInstance *comp, double x[], size_t nx) {
    UNUSED(nx);
    x[0] = M(x);
    return OK;
}

Status getNominalsOfContinuousStates(ModelInstance *comp, double nominals[], size_t nx) {
    UNUSED(comp);
    UNUSED(nx);
    nominals[0] = 1.0;
    return OK;
}

Status setContinuousStates(ModelInstance *comp, const double x[], size_t nx) {
    UNUSED(nx);
    M(x) = x[0];
    return OK;
}

Status getDerivatives(ModelInstance *comp, double dx[], size_t nx) {
    UNUSED(nx);
    dx[0] = M(s);
    return OK;
}

Status getEventIndicators(ModelInstance *comp, double z[], size_t nz) {
    UNUSED(nz);
    z[0] = M(x);
    return OK;
}
