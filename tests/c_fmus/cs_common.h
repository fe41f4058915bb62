/* The FMI 2.0 co-simulation functions that do not depend on the model, for the small test FMUs of the
 * coupling algorithms (mass.c, affine.c), included once by each before its own functions.
 *
 * The including file defines MODEL, the name of its instance struct, whose first member is a `Base`
 * (declared here), and, before including this header, declares
 *
 *     static void model_reset(MODEL *s);   -- the parameters' defaults and the initial state
 *     static size_t model_size(void);      -- sizeof(MODEL), the struct being complete only there
 *
 * and defines MODEL_DIRECTIONAL_DERIVATIVE if it gives fmi2GetDirectionalDerivative itself.
 *
 * What is here: the logger (say), instantiation (co-simulation only), set-up (the start time), the modes,
 * reset, the FMU state as a copy of the instance struct (no serialization), the types the models have
 * none of (Integer, Boolean, String: an error if asked for any), the statuses (fmi2LastSuccessfulTime, not
 * terminated), and the checks every fmi2DoStep starts with (do_step_checks).  The model's own: fmi2GetReal,
 * fmi2SetReal, fmi2SetRealInputDerivatives, fmi2DoStep.
 */
#ifndef CS_COMMON_H
#define CS_COMMON_H

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "fmi2Functions.h"

typedef struct {
    fmi2CallbackFunctions cb;
    char name[256];
    double time;        /* [s] */
    int initialized;    /* after fmi2ExitInitializationMode */
} Base;

static void say(void *c, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void say(void *c, const char *fmt, ...) {
    Base *b = (Base *)c;
    char msg[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    if (b->cb.logger) b->cb.logger(b->cb.componentEnvironment, b->name, fmi2Error, "logStatusError", "%s", msg);
}

static void model_reset(MODEL *s);
static size_t model_size(void);

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String cats[]) {
    (void)c; (void)on; (void)n; (void)cats;
    return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type t, fmi2String guid, fmi2String res,
                              const fmi2CallbackFunctions *cb, fmi2Boolean visible, fmi2Boolean on) {
    (void)guid; (void)res; (void)visible; (void)on;
    MODEL *s = (MODEL *)calloc(1, model_size());
    if (!s) return NULL;
    Base *b = (Base *)s;
    b->cb = *cb;
    strncpy(b->name, name ? name : "", sizeof(b->name) - 1);
    if (t != fmi2CoSimulation) {
        say(s, "fmi2Instantiate: only co-simulation is supported");
        free(s);
        return NULL;
    }
    model_reset(s);
    return s;
}

void fmi2FreeInstance(fmi2Component c) { free(c); }

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean tolDef, fmi2Real tol, fmi2Real start,
                               fmi2Boolean stopDef, fmi2Real stop) {
    (void)tolDef; (void)tol; (void)stopDef; (void)stop;
    ((Base *)c)->time = start;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) { (void)c; return fmi2OK; }
fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    ((Base *)c)->initialized = 1;
    return fmi2OK;
}
fmi2Status fmi2Terminate(fmi2Component c) { (void)c; return fmi2OK; }
fmi2Status fmi2Reset(fmi2Component c) {
    model_reset((MODEL *)c);
    return fmi2OK;
}

/* A parameter may be set before fmi2ExitInitializationMode only. */
static int parameter_settable(void *c, const char *fn, const char *param) {
    if (((Base *)c)->initialized) {
        say(c, "%s: %s is a fixed parameter: it cannot be set after initialisation", fn, param);
        return 0;
    }
    return 1;
}

static fmi2Status none(fmi2Component c, size_t n, const char *fn) {
    if (!n) return fmi2OK;
    say(c, "%s: this FMU has no variables of that type", fn);
    return fmi2Error;
}
fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Integer v[]) {
    (void)vr; (void)v;
    return none(c, n, "fmi2GetInteger");
}
fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Boolean v[]) {
    (void)vr; (void)v;
    return none(c, n, "fmi2GetBoolean");
}
fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2String v[]) {
    (void)vr; (void)v;
    return none(c, n, "fmi2GetString");
}
fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer v[]) {
    (void)vr; (void)v;
    return none(c, n, "fmi2SetInteger");
}
fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Boolean v[]) {
    (void)vr; (void)v;
    return none(c, n, "fmi2SetBoolean");
}
fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2String v[]) {
    (void)vr; (void)v;
    return none(c, n, "fmi2SetString");
}

/* The state: a copy of the whole instance struct. */
fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *st) {
    void *copy = *st ? *st : malloc(model_size());
    if (!copy) {
        say(c, "fmi2GetFMUstate: out of memory");
        return fmi2Error;
    }
    memcpy(copy, c, model_size());
    *st = copy;
    return fmi2OK;
}
fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate st) {
    if (!st) {
        say(c, "fmi2SetFMUstate: no state");
        return fmi2Error;
    }
    memcpy(c, st, model_size());
    return fmi2OK;
}
fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *st) {
    (void)c;
    if (st) {
        free(*st);
        *st = NULL;
    }
    return fmi2OK;
}

static fmi2Status unsupported(fmi2Component c, const char *what) {
    say(c, "%s", what);
    return fmi2Error;
}
fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate st, size_t *n) {
    (void)st; (void)n;
    return unsupported(c, "fmi2SerializedFMUstateSize: serialization is not supported");
}
fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate st, fmi2Byte b[], size_t n) {
    (void)st; (void)b; (void)n;
    return unsupported(c, "fmi2SerializeFMUstate: serialization is not supported");
}
fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte b[], size_t n, fmi2FMUstate *st) {
    (void)b; (void)n; (void)st;
    return unsupported(c, "fmi2DeSerializeFMUstate: serialization is not supported");
}
#ifndef MODEL_DIRECTIONAL_DERIVATIVE
fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference a[], size_t na,
                                        const fmi2ValueReference b[], size_t nb, const fmi2Real dv[], fmi2Real r[]) {
    (void)a; (void)na; (void)b; (void)nb; (void)dv; (void)r;
    return unsupported(c, "fmi2GetDirectionalDerivative: not supported");
}
#endif
fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                        const fmi2Integer o[], fmi2Real v[]) {
    (void)vr; (void)n; (void)o; (void)v;
    return unsupported(c, "fmi2GetRealOutputDerivatives: not supported (maxOutputDerivativeOrder 0)");
}
fmi2Status fmi2CancelStep(fmi2Component c) {
    return unsupported(c, "fmi2CancelStep: steps are not asynchronous");
}

/* What every fmi2DoStep checks first: initialised, a step > 0 [s]. */
static int do_step_checks(void *c, double h) {
    if (!((Base *)c)->initialized) {
        say(c, "fmi2DoStep: called before fmi2ExitInitializationMode");
        return 0;
    }
    if (!(h > 0.0)) {
        say(c, "fmi2DoStep: communication step size %g s: must be > 0", h);
        return 0;
    }
    return 1;
}

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind k, fmi2Status *v) {
    (void)k; (void)v;
    return unsupported(c, "fmi2GetStatus: steps are not asynchronous");
}
fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind k, fmi2Real *v) {
    if (k != fmi2LastSuccessfulTime) return unsupported(c, "fmi2GetRealStatus: only fmi2LastSuccessfulTime");
    *v = ((Base *)c)->time;
    return fmi2OK;
}
fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind k, fmi2Integer *v) {
    (void)k; (void)v;
    return unsupported(c, "fmi2GetIntegerStatus: not supported");
}
fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind k, fmi2Boolean *v) {
    if (k != fmi2Terminated) return unsupported(c, "fmi2GetBooleanStatus: only fmi2Terminated");
    *v = fmi2False;
    return fmi2OK;
}
fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind k, fmi2String *v) {
    (void)k; (void)v;
    return unsupported(c, "fmi2GetStringStatus: not supported");
}

#endif
