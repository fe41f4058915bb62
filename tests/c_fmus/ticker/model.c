/* Ticker (tests only): an input clock r (periodic, its interval in the model description) whose ticks n
 * counts (n clocked by r); a triggered input clock s with its clocked input u and output y = 2 u (at s's
 * ticks); an output clock o raised at every `every`-th tick of r, and at the time t_o (a time event: none
 * when t_o < 0), whose rises m counts (m clocked by o).
 * The clocked outputs take their values at the tick (when the clock is set, before the discrete states
 * are updated); the clocks are deactivated by fmi3UpdateDiscreteStates. */
#include <math.h>
#include "config.h"
#include "model.h"

Status setStartValues(ModelInstance *comp) {
    M(n) = 0;
    M(u) = 0;
    M(y) = 0;
    M(m) = 0;
    M(every) = 3;
    M(t_o) = -1;
    M(r_active) = M(s_active) = M(o_active) = M(o_done) = 0;
    return OK;
}

static void schedule(ModelInstance *comp) {
    comp->nextEventTimeDefined = M(t_o) >= 0 && !M(o_done);
    comp->nextEventTime = M(t_o);
}

Status calculateValues(ModelInstance *comp) {
    if (comp->state == Instantiated || comp->state == InitializationMode) {
        schedule(comp);
    }
    return OK;
}

Status getFloat64(ModelInstance *comp, ValueReference vr, double values[], size_t nValues, size_t *index) {
    ASSERT_NVALUES(1);
    switch (vr) {
        case vr_time: values[(*index)++] = comp->time; return OK;
        case vr_n: values[(*index)++] = M(n); return OK;
        case vr_u: values[(*index)++] = M(u); return OK;
        case vr_y: values[(*index)++] = M(s_active) ? 2 * M(u) : M(y); return OK;
        case vr_m: values[(*index)++] = M(m); return OK;
        case vr_every: values[(*index)++] = M(every); return OK;
        case vr_t_o: values[(*index)++] = M(t_o); return OK;
        default:
            logError(comp, "Get Float64 is not allowed for value reference %u.", vr);
            return Error;
    }
}

Status setFloat64(ModelInstance *comp, ValueReference vr, const double values[], size_t nValues, size_t *index) {
    ASSERT_NVALUES(1);
    const double v = values[(*index)++];
    switch (vr) {
        case vr_u: M(u) = v; return OK;
        case vr_every: M(every) = v; return OK;
        case vr_t_o: M(t_o) = v; schedule(comp); return OK;
        default:
            logError(comp, "Set Float64 is not allowed for value reference %u.", vr);
            return Error;
    }
}

Status activateClock(ModelInstance *comp, ValueReference vr) {
    switch (vr) {
        case vr_r:
            M(r_active) = 1;
            M(n) += 1;
            if (M(every) > 0 && fmod(M(n), M(every)) == 0) {
                M(o_active) = 1;
                M(m) += 1;
            }
            return OK;
        case vr_s:
            M(s_active) = 1;
            return OK;
        default:
            logError(comp, "Clock %u is not an input clock.", vr);
            return Error;
    }
}

Status getClock(ModelInstance *comp, ValueReference vr, bool *value) {
    if (vr != vr_o) {
        logError(comp, "Clock %u is not an output clock.", vr);
        return Error;
    }
    if (M(t_o) >= 0 && !M(o_done) && (comp->time >= M(t_o) || isClose(comp->time, M(t_o)))) {
        M(o_done) = 1;
        M(o_active) = 1;
        M(m) += 1;
    }
    *value = M(o_active);
    M(o_active) = 0;   /* (an output clock reads active once per tick) */
    return OK;
}

Status eventUpdate(ModelInstance *comp) {
    if (M(s_active)) {
        M(y) = 2 * M(u);
    }
    M(r_active) = M(s_active) = 0;
    comp->valuesOfContinuousStatesChanged = false;
    comp->nominalsOfContinuousStatesChanged = false;
    comp->newDiscreteStatesNeeded = false;
    comp->terminateSimulation = false;
    schedule(comp);
    return OK;
}
