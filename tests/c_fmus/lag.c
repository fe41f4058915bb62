/* Two small FMI 2.0 FMUs, each with a Model Exchange and a Co-Simulation interface, for tests of
 * linearisation (state-space models of FMUs, loops closed across FMUs, stability margins): one C source,
 * the model chosen at compile time (tests/linear_fmus.py builds them and writes their model descriptions).
 *
 * Lag (default build): a first-order lag with the state x [1],
 *
 *     x' = (k u - x) / tau,   y = x        (no direct feedthrough),   x(start) = x0
 *
 *   vr 0 u [1] input (start 0), vr 1 y [1] output, vr 2 x [1] the continuous state (local), vr 3 der(x)
 *   [1/s] its derivative (local); parameters vr 10 k [1] (1), vr 11 tau [s] (1, must be > 0: a tau <= 0 is
 *   an error at fmi2ExitInitializationMode), vr 12 x0 [1] (0, the initial state).
 *
 * Gain (-DGAIN): memoryless, no state,
 *
 *     y = kp u + y0                        (direct feedthrough)
 *
 *   vr 0 u [1] input (start 0), vr 1 y [1] output; parameters vr 10 kp [1] (1), vr 11 y0 [1] (0).
 *
 * Model Exchange: the usual calls on one continuous state (Lag) or none (Gain), no event indicators, no
 * time events (fmi2NewDiscreteStates has nothing to do) and no step events (fmi2CompletedIntegratorStep,
 * which the model description says is not needed, asks for none).
 * Co-Simulation: fmi2DoStep advances the Lag by the exact solution with u held over the step,
 *
 *     x(t + h) = k u + (x(t) - k u) exp(-h / tau),
 *
 * so a co-simulation with a piecewise-constant input has no error of integration; the Gain has nothing to
 * advance but the time.  Outputs are computed when read: after fmi2SetReal of u they reflect the new input
 * at once, in both interfaces (the Gain's y; the Lag's der(x)).
 *
 * Other defines:
 *   DIRECTIONAL   fmi2GetDirectionalDerivative gives exact partial derivatives (without it: fmi2Error).
 *                 Model Exchange: knowns among {x, u}, unknowns among {der(x), y}:
 *                     Lag:  d der(x)/dx = -1/tau, d der(x)/du = k/tau, dy/dx = 1, dy/du = 0;
 *                     Gain: dy/du = kp (the Gain has no x or der(x)).
 *                 Co-Simulation: the partial of the output by the input only (known u, unknown y):
 *                     Lag 0, Gain kp.
 *   NO_FMU_STATE  fmi2GetFMUstate, fmi2SetFMUstate and fmi2FreeFMUstate return fmi2Error (without it an
 *                 FMU state is a copy of the mode, the time, the parameters, u and x: `Values` below;
 *                 serialization is never supported).
 *
 * The calls are checked against the FMI 2.0 state machine (each function's allowed modes, as the Reference
 * FMUs check them): a call out of order is an error, logged.  Parameters are fixed: settable before
 * fmi2ExitInitializationMode only; u may be set in every mode but Terminated (in Model Exchange in
 * event and continuous-time mode both); x follows x0 until then, and after it only fmi2SetContinuousStates
 * (Model Exchange) sets it, never fmi2SetReal.  Errors are always logged (category logStatusError, unless
 * switched off by fmi2SetDebugLogging); the one debug message (category logEvents, at the end of the
 * initialisation) only when logging is on, which it is not by default.  Memory comes from the
 * environment's allocateMemory / freeMemory.
 */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "fmi2Functions.h"

#define VR_U 0
#define VR_Y 1
#define VR_PAR 10   /* parameters: p[vr - VR_PAR] */

#ifdef GAIN
#define NX 0
#define NPAR 2
enum { P_KP, P_Y0 };
static const double DEFAULTS[NPAR] = {1.0, 0.0};
static const char *PAR_NAMES[NPAR] = {"kp", "y0"};
#else
#define NX 1
#define NPAR 3
#define VR_X 2
#define VR_DER 3
enum { P_K, P_TAU, P_X0 };
static const double DEFAULTS[NPAR] = {1.0, 1.0, 0.0};
static const char *PAR_NAMES[NPAR] = {"k", "tau", "x0"};
#endif

/* The modes of FMI 2.0's state machines (bits, so that each function names the modes it is allowed in). */
enum {
    INSTANTIATED = 1 << 0,
    INITIALIZATION = 1 << 1,
    EVENT = 1 << 2,         /* Model Exchange */
    CONTINUOUS = 1 << 3,    /* Model Exchange */
    STEP_COMPLETE = 1 << 4, /* Co-Simulation */
    TERMINATED = 1 << 5
};
#define ANY_MODE (INSTANTIATED | INITIALIZATION | EVENT | CONTINUOUS | STEP_COMPLETE | TERMINATED)
#define RUNNING (EVENT | CONTINUOUS | STEP_COMPLETE)

/* What an FMU state holds: everything that fmi2Reset sets back. */
typedef struct {
    int mode;
    double time;        /* [s] */
    double p[NPAR];
    double u;           /* [1] */
#if NX
    double x;           /* [1] */
#endif
} Values;

typedef struct {
    fmi2CallbackFunctions cb;
    fmi2Type type;
    char name[256];
    int log_events, log_errors;
    int logging_on;     /* loggingOn of fmi2Instantiate, which fmi2Reset restores */
    Values v;
} Instance;

/* ------------------------------------------------------------------------------------------ logging */

static void say(Instance *s, fmi2Status st, const char *category, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));
static void say(Instance *s, fmi2Status st, const char *category, const char *fmt, ...) {
    if (!s->cb.logger || !(st == fmi2OK ? s->log_events : s->log_errors)) return;
    char msg[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    s->cb.logger(s->cb.componentEnvironment, s->name, st, category, "%s", msg);
}

#define FAIL(s, ...) (say((s), fmi2Error, "logStatusError", __VA_ARGS__), fmi2Error)

/* The interfaces a function belongs to. */
#define BOTH (-1)
#define ME_ONLY ((int)fmi2ModelExchange)
#define CS_ONLY ((int)fmi2CoSimulation)

/* Whether `fn` may be called now: in one of `modes`, on an instance of `interface` (or either: BOTH). */
static int allowed(Instance *s, const char *fn, int modes, int interface) {
    if (interface != BOTH && interface != (int)s->type) {
        say(s, fmi2Error, "logStatusError", "%s: a %s function, called on a %s instance", fn,
            interface == ME_ONLY ? "Model Exchange" : "Co-Simulation",
            s->type == fmi2ModelExchange ? "model-exchange" : "co-simulation");
        return 0;
    }
    if (!(s->v.mode & modes)) {
        say(s, fmi2Error, "logStatusError", "%s: not allowed in the current mode (%d)", fn, s->v.mode);
        return 0;
    }
    return 1;
}

/* ------------------------------------------------------------------------------------------- model */

static void reset_values(Values *v) {
    memset(v, 0, sizeof *v);
    v->mode = INSTANTIATED;
    memcpy(v->p, DEFAULTS, sizeof v->p);
#if NX
    v->x = v->p[P_X0];
#endif
}

static double output(const Values *v) {
#ifdef GAIN
    return v->p[P_KP] * v->u + v->p[P_Y0];
#else
    return v->x;
#endif
}

#if NX
static double derivative(const Values *v) {   /* [1/s] */
    return (v->p[P_K] * v->u - v->x) / v->p[P_TAU];
}
#endif

/* -------------------------------------------------------------------------- common to both interfaces */

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String cats[]) {
    Instance *s = (Instance *)c;
    if (n == 0) {
        s->log_events = s->log_errors = on;
        return fmi2OK;
    }
    for (size_t i = 0; i < n; i++) {
        if (!strcmp(cats[i], "logEvents")) s->log_events = on;
        else if (!strcmp(cats[i], "logStatusError")) s->log_errors = on;
        else return FAIL(s, "fmi2SetDebugLogging: unknown log category \"%s\"", cats[i]);
    }
    return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String resources,
                              const fmi2CallbackFunctions *cb, fmi2Boolean visible, fmi2Boolean loggingOn) {
    (void)guid; (void)resources; (void)visible;
    if (!cb) return NULL;
    Instance *s = cb->allocateMemory ? (Instance *)cb->allocateMemory(1, sizeof(Instance))
                                     : (Instance *)calloc(1, sizeof(Instance));
    if (!s) return NULL;
    s->cb = *cb;
    strncpy(s->name, name ? name : "", sizeof(s->name) - 1);
    s->logging_on = loggingOn;
    s->log_events = loggingOn;
    s->log_errors = 1;   /* errors are reported unless switched off */
    if (type != fmi2ModelExchange && type != fmi2CoSimulation) {
        say(s, fmi2Error, "logStatusError", "fmi2Instantiate: unknown interface type %d", (int)type);
        if (cb->freeMemory) cb->freeMemory(s);
        else free(s);
        return NULL;
    }
    s->type = type;
    reset_values(&s->v);
    return s;
}

void fmi2FreeInstance(fmi2Component c) {
    Instance *s = (Instance *)c;
    if (!s) return;
    if (s->cb.freeMemory) s->cb.freeMemory(s);
    else free(s);
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean tolDef, fmi2Real tol, fmi2Real start,
                               fmi2Boolean stopDef, fmi2Real stop) {
    Instance *s = (Instance *)c;
    (void)tolDef; (void)tol; (void)stopDef; (void)stop;
    if (!allowed(s, "fmi2SetupExperiment", INSTANTIATED, BOTH)) return fmi2Error;
    s->v.time = start;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    Instance *s = (Instance *)c;
    if (!allowed(s, "fmi2EnterInitializationMode", INSTANTIATED, BOTH)) return fmi2Error;
    s->v.mode = INITIALIZATION;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    Instance *s = (Instance *)c;
    if (!allowed(s, "fmi2ExitInitializationMode", INITIALIZATION, BOTH)) return fmi2Error;
#if NX
    /* tau divides x' and is the time constant of the exact step: only a positive one makes a lag */
    if (!(s->v.p[P_TAU] > 0.0))
        return FAIL(s, "fmi2ExitInitializationMode: tau = %g s: must be > 0", s->v.p[P_TAU]);
    say(s, fmi2OK, "logEvents", "initialised at t = %g s: x = %g", s->v.time, s->v.x);
#else
    say(s, fmi2OK, "logEvents", "initialised at t = %g s: y = %g", s->v.time, output(&s->v));
#endif
    /* Model Exchange starts in event mode (the initial event iteration), co-simulation ready to step */
    s->v.mode = s->type == fmi2ModelExchange ? EVENT : STEP_COMPLETE;
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c) {
    Instance *s = (Instance *)c;
    if (!allowed(s, "fmi2Terminate", RUNNING, BOTH)) return fmi2Error;
    s->v.mode = TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component c) {
    Instance *s = (Instance *)c;
    reset_values(&s->v);
    s->log_events = s->logging_on;
    s->log_errors = 1;
    return fmi2OK;
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real value[]) {
    Instance *s = (Instance *)c;
    if (!allowed(s, "fmi2GetReal", ANY_MODE & ~INSTANTIATED, BOTH)) return fmi2Error;
    for (size_t i = 0; i < n; i++) {
        if (vr[i] == VR_U) value[i] = s->v.u;
        else if (vr[i] == VR_Y) value[i] = output(&s->v);
#if NX
        else if (vr[i] == VR_X) value[i] = s->v.x;
        else if (vr[i] == VR_DER) value[i] = derivative(&s->v);
#endif
        else if (vr[i] >= VR_PAR && vr[i] < VR_PAR + NPAR) value[i] = s->v.p[vr[i] - VR_PAR];
        else return FAIL(s, "fmi2GetReal: unknown value reference %u", (unsigned)vr[i]);
    }
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real value[]) {
    Instance *s = (Instance *)c;
    if (!allowed(s, "fmi2SetReal", ANY_MODE & ~TERMINATED, BOTH)) return fmi2Error;
    for (size_t i = 0; i < n; i++) {
        if (vr[i] == VR_U) {
            s->v.u = value[i];
        } else if (vr[i] >= VR_PAR && vr[i] < VR_PAR + NPAR) {
            if (!(s->v.mode & (INSTANTIATED | INITIALIZATION)))
                return FAIL(s, "fmi2SetReal: %s is a fixed parameter: it cannot be set after initialisation",
                             PAR_NAMES[vr[i] - VR_PAR]);
            s->v.p[vr[i] - VR_PAR] = value[i];
#if NX
            /* until the end of the initialisation the state is its start value, an initial unknown */
            if (vr[i] - VR_PAR == P_X0) s->v.x = value[i];
#endif
        } else {
            return FAIL(s, "fmi2SetReal: value reference %u is not an input or a parameter", (unsigned)vr[i]);
        }
    }
    return fmi2OK;
}

/* The models have no Integer, Boolean or String variables: asking for any is an error. */
static fmi2Status none(Instance *s, size_t n, const char *fn) {
    if (!n) return fmi2OK;
    return FAIL(s, "%s: this FMU has no variables of that type", fn);
}
fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Integer v[]) {
    (void)vr; (void)v;
    return none((Instance *)c, n, "fmi2GetInteger");
}
fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Boolean v[]) {
    (void)vr; (void)v;
    return none((Instance *)c, n, "fmi2GetBoolean");
}
fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2String v[]) {
    (void)vr; (void)v;
    return none((Instance *)c, n, "fmi2GetString");
}
fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer v[]) {
    (void)vr; (void)v;
    return none((Instance *)c, n, "fmi2SetInteger");
}
fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Boolean v[]) {
    (void)vr; (void)v;
    return none((Instance *)c, n, "fmi2SetBoolean");
}
fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2String v[]) {
    (void)vr; (void)v;
    return none((Instance *)c, n, "fmi2SetString");
}

/* ------------------------------------------------------------------------------------------ FMU state */

#ifdef NO_FMU_STATE
fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *st) {
    (void)st;
    return FAIL((Instance *)c, "fmi2GetFMUstate: not supported (canGetAndSetFMUstate is false)");
}
fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate st) {
    (void)st;
    return FAIL((Instance *)c, "fmi2SetFMUstate: not supported (canGetAndSetFMUstate is false)");
}
fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *st) {
    (void)st;
    return FAIL((Instance *)c, "fmi2FreeFMUstate: not supported (canGetAndSetFMUstate is false)");
}
#else
/* A state is a copy of the instance's Values; one given back (*st not NULL) is overwritten. */
fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *st) {
    Instance *s = (Instance *)c;
    if (!st) return FAIL(s, "fmi2GetFMUstate: no place for the state");
    Values *copy = (Values *)*st;
    if (!copy) {
        copy = s->cb.allocateMemory ? (Values *)s->cb.allocateMemory(1, sizeof(Values))
                                    : (Values *)calloc(1, sizeof(Values));
        if (!copy) return FAIL(s, "fmi2GetFMUstate: out of memory");
    }
    *copy = s->v;
    *st = copy;
    return fmi2OK;
}
fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate st) {
    Instance *s = (Instance *)c;
    if (!st) return FAIL(s, "fmi2SetFMUstate: no state");
    s->v = *(const Values *)st;
    return fmi2OK;
}
fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *st) {
    Instance *s = (Instance *)c;
    if (st && *st) {
        if (s->cb.freeMemory) s->cb.freeMemory(*st);
        else free(*st);
        *st = NULL;
    }
    return fmi2OK;
}
#endif

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate st, size_t *n) {
    (void)st; (void)n;
    return FAIL((Instance *)c, "fmi2SerializedFMUstateSize: serialization is not supported");
}
fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate st, fmi2Byte b[], size_t n) {
    (void)st; (void)b; (void)n;
    return FAIL((Instance *)c, "fmi2SerializeFMUstate: serialization is not supported");
}
fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte b[], size_t n, fmi2FMUstate *st) {
    (void)b; (void)n; (void)st;
    return FAIL((Instance *)c, "fmi2DeSerializeFMUstate: serialization is not supported");
}

/* ------------------------------------------------------------------------------ partial derivatives */

#ifdef DIRECTIONAL
/* The partial derivative of `unknown` by `known` into *d; 0 if that pair is not offered in this interface
 * (Model Exchange: states and inputs by derivatives and outputs; Co-Simulation: the output by the input). */
static int partial(const Instance *s, fmi2ValueReference unknown, fmi2ValueReference known, double *d) {
    const double *p = s->v.p;
    int me = s->type == fmi2ModelExchange;
#ifdef GAIN
    (void)me;
    if (unknown == VR_Y && known == VR_U) *d = p[P_KP];
    else return 0;
#else
    if (!me && !(unknown == VR_Y && known == VR_U)) return 0;
    if (unknown == VR_DER && known == VR_X) *d = -1.0 / p[P_TAU];
    else if (unknown == VR_DER && known == VR_U) *d = p[P_K] / p[P_TAU];
    else if (unknown == VR_Y && known == VR_X) *d = 1.0;
    else if (unknown == VR_Y && known == VR_U) *d = 0.0;
    else return 0;
#endif
    return 1;
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference unknowns[], size_t nu,
                                        const fmi2ValueReference knowns[], size_t nk, const fmi2Real seed[],
                                        fmi2Real out[]) {
    Instance *s = (Instance *)c;
    if (!allowed(s, "fmi2GetDirectionalDerivative", ANY_MODE & ~INSTANTIATED, BOTH)) return fmi2Error;
    for (size_t i = 0; i < nu; i++) {
        double sum = 0.0;
        for (size_t j = 0; j < nk; j++) {
            double d;
            if (!partial(s, unknowns[i], knowns[j], &d))
                return FAIL(s, "fmi2GetDirectionalDerivative: no partial derivative of value reference %u "
                             "by value reference %u in this interface", (unsigned)unknowns[i], (unsigned)knowns[j]);
            sum += d * seed[j];
        }
        out[i] = sum;
    }
    return fmi2OK;
}
#else
fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference unknowns[], size_t nu,
                                        const fmi2ValueReference knowns[], size_t nk, const fmi2Real seed[],
                                        fmi2Real out[]) {
    (void)unknowns; (void)nu; (void)knowns; (void)nk; (void)seed; (void)out;
    return FAIL((Instance *)c, "fmi2GetDirectionalDerivative: not supported (built without DIRECTIONAL)");
}
#endif

/* ---------------------------------------------------------------------------------- Model Exchange */

fmi2Status fmi2EnterEventMode(fmi2Component c) {
    Instance *s = (Instance *)c;
    if (!allowed(s, "fmi2EnterEventMode", EVENT | CONTINUOUS, ME_ONLY)) return fmi2Error;
    s->v.mode = EVENT;
    return fmi2OK;
}

/* No discrete states, no time events: one call ends the event iteration. */
fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo *info) {
    Instance *s = (Instance *)c;
    if (!allowed(s, "fmi2NewDiscreteStates", EVENT, ME_ONLY)) return fmi2Error;
    info->newDiscreteStatesNeeded = fmi2False;
    info->terminateSimulation = fmi2False;
    info->nominalsOfContinuousStatesChanged = fmi2False;
    info->valuesOfContinuousStatesChanged = fmi2False;
    info->nextEventTimeDefined = fmi2False;
    info->nextEventTime = 0.0;
    return fmi2OK;
}

fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c) {
    Instance *s = (Instance *)c;
    if (!allowed(s, "fmi2EnterContinuousTimeMode", EVENT, ME_ONLY)) return fmi2Error;
    s->v.mode = CONTINUOUS;
    return fmi2OK;
}

fmi2Status fmi2CompletedIntegratorStep(fmi2Component c, fmi2Boolean noSetPrior, fmi2Boolean *enterEventMode,
                                       fmi2Boolean *terminateSimulation) {
    Instance *s = (Instance *)c;
    (void)noSetPrior;
    if (!allowed(s, "fmi2CompletedIntegratorStep", CONTINUOUS, ME_ONLY)) return fmi2Error;
    *enterEventMode = fmi2False;
    *terminateSimulation = fmi2False;
    return fmi2OK;
}

fmi2Status fmi2SetTime(fmi2Component c, fmi2Real time) {
    Instance *s = (Instance *)c;
    if (!allowed(s, "fmi2SetTime", EVENT | CONTINUOUS, ME_ONLY)) return fmi2Error;
    s->v.time = time;
    return fmi2OK;
}

/* The number of continuous states the caller gives must be the model's own (0 or 1). */
static int check_nx(Instance *s, const char *fn, size_t nx) {
    if (nx == NX) return 1;
    say(s, fmi2Error, "logStatusError", "%s: %zu continuous states asked for, the model has %d", fn, nx, NX);
    return 0;
}

fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t nx) {
    Instance *s = (Instance *)c;
    if (!allowed(s, "fmi2SetContinuousStates", CONTINUOUS, ME_ONLY)) return fmi2Error;
    if (!check_nx(s, "fmi2SetContinuousStates", nx)) return fmi2Error;
#if NX
    s->v.x = x[0];
#else
    (void)x;
#endif
    return fmi2OK;
}

fmi2Status fmi2GetContinuousStates(fmi2Component c, fmi2Real x[], size_t nx) {
    Instance *s = (Instance *)c;
    if (!allowed(s, "fmi2GetContinuousStates", INITIALIZATION | EVENT | CONTINUOUS | TERMINATED, ME_ONLY))
        return fmi2Error;
    if (!check_nx(s, "fmi2GetContinuousStates", nx)) return fmi2Error;
#if NX
    x[0] = s->v.x;
#else
    (void)x;
#endif
    return fmi2OK;
}

fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real dx[], size_t nx) {
    Instance *s = (Instance *)c;
    if (!allowed(s, "fmi2GetDerivatives", EVENT | CONTINUOUS | TERMINATED, ME_ONLY)) return fmi2Error;
    if (!check_nx(s, "fmi2GetDerivatives", nx)) return fmi2Error;
#if NX
    dx[0] = derivative(&s->v);
#else
    (void)dx;
#endif
    return fmi2OK;
}

fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real nominal[], size_t nx) {
    Instance *s = (Instance *)c;
    if (!allowed(s, "fmi2GetNominalsOfContinuousStates", INSTANTIATED | EVENT | CONTINUOUS | TERMINATED, ME_ONLY))
        return fmi2Error;
    if (!check_nx(s, "fmi2GetNominalsOfContinuousStates", nx)) return fmi2Error;
#if NX
    nominal[0] = 1.0;
#else
    (void)nominal;
#endif
    return fmi2OK;
}

fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real z[], size_t nz) {
    Instance *s = (Instance *)c;
    (void)z;
    if (!allowed(s, "fmi2GetEventIndicators", INITIALIZATION | EVENT | CONTINUOUS | TERMINATED, ME_ONLY))
        return fmi2Error;
    if (nz) return FAIL(s, "fmi2GetEventIndicators: %zu event indicators asked for, the model has none", nz);
    return fmi2OK;
}

/* ----------------------------------------------------------------------------------- Co-Simulation */

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean noSetPrior) {
    Instance *s = (Instance *)c;
    (void)noSetPrior;
    if (!allowed(s, "fmi2DoStep", STEP_COMPLETE, CS_ONLY)) return fmi2Error;
    if (!(h > 0.0)) return FAIL(s, "fmi2DoStep: communication step size %g s: must be > 0", h);
#if NX
    {   /* exact for u constant over the step: the lag relaxes towards k u with the time constant tau */
        const double target = s->v.p[P_K] * s->v.u;
        s->v.x = target + (s->v.x - target) * exp(-h / s->v.p[P_TAU]);
    }
#endif
    s->v.time = t + h;
    return fmi2OK;
}

/* The input is held over a step (canInterpolateInputs false) and outputs have no derivatives
 * (maxOutputDerivativeOrder 0); steps are never asynchronous. */
fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                       const fmi2Integer order[], const fmi2Real v[]) {
    (void)vr; (void)n; (void)order; (void)v;
    return FAIL((Instance *)c, "fmi2SetRealInputDerivatives: not supported (canInterpolateInputs is false)");
}
fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                        const fmi2Integer order[], fmi2Real v[]) {
    (void)vr; (void)n; (void)order; (void)v;
    return FAIL((Instance *)c, "fmi2GetRealOutputDerivatives: not supported (maxOutputDerivativeOrder 0)");
}
fmi2Status fmi2CancelStep(fmi2Component c) {
    return FAIL((Instance *)c, "fmi2CancelStep: steps are not asynchronous");
}

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind k, fmi2Status *v) {
    (void)k; (void)v;
    return FAIL((Instance *)c, "fmi2GetStatus: steps are not asynchronous");
}
fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind k, fmi2Real *v) {
    Instance *s = (Instance *)c;
    if (k != fmi2LastSuccessfulTime) return FAIL(s, "fmi2GetRealStatus: only fmi2LastSuccessfulTime");
    *v = s->v.time;
    return fmi2OK;
}
fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind k, fmi2Integer *v) {
    (void)k; (void)v;
    return FAIL((Instance *)c, "fmi2GetIntegerStatus: not supported");
}
fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind k, fmi2Boolean *v) {
    Instance *s = (Instance *)c;
    if (k != fmi2Terminated) return FAIL(s, "fmi2GetBooleanStatus: only fmi2Terminated");
    *v = fmi2False;   /* the models never ask to end the simulation */
    return fmi2OK;
}
fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind k, fmi2String *v) {
    (void)k; (void)v;
    return FAIL((Instance *)c, "fmi2GetStringStatus: not supported");
}
