/* An FMI 2.0 co-simulation FMU that is one affine map with direct feedthrough, for tests of algebraic loops
 * (tests/coupling_fmus.py builds it):
 *
 *     y(t) = a u(t) + b0 + b1 t + bw sin(w t)
 *
 *   vr 0 u [1] input, vr 1 y [1] output (depends directly on u); parameters vr 10 a [1] (1), 11 b0 [1] (0),
 *   12 b1 [1/s] (0), 13 bw [1] (0), 14 w [rad/s] (1).
 *
 * The output is always that of the current input at the current time: after fmi2SetReal at once, after
 * fmi2DoStep at the end of the step (time = currentCommunicationPoint + h).  The instance (time, input,
 * parameters) is its state: fmi2GetFMUstate copies it (serialization is not supported).  The input may be
 * given a first derivative (fmi2SetRealInputDerivatives, order 1): over a step the input then moves
 * linearly, and the output at the end of the step is that of the input u + du h.  Parameters are fixed:
 * settable before fmi2ExitInitializationMode only.
 */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "fmi2Functions.h"

#define NPAR 5
static const double DEFAULTS[NPAR] = {1.0, 0.0, 0.0, 0.0, 1.0};
static const char *PAR_NAMES[NPAR] = {"a", "b0", "b1", "bw", "w"};
#define VR_U 0
#define VR_Y 1
#define VR_PAR 10
enum { P_A, P_B0, P_B1, P_BW, P_W };

typedef struct {
    fmi2CallbackFunctions cb;
    char name[256];
    double time;        /* [s] */
    double p[NPAR];
    double u, du;       /* the input [1] and its derivative [1/s] */
    int initialized;    /* after fmi2ExitInitializationMode */
} Affine;

static void say(Affine *s, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void say(Affine *s, const char *fmt, ...) {
    char msg[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    if (s->cb.logger) s->cb.logger(s->cb.componentEnvironment, s->name, fmi2Error, "logStatusError", "%s", msg);
}

static double output(const Affine *s) {
    const double *p = s->p;
    return p[P_A] * s->u + p[P_B0] + p[P_B1] * s->time + p[P_BW] * sin(p[P_W] * s->time);
}

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String cats[]) {
    (void)c; (void)on; (void)n; (void)cats;
    return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type t, fmi2String guid, fmi2String res,
                              const fmi2CallbackFunctions *cb, fmi2Boolean visible, fmi2Boolean on) {
    (void)guid; (void)res; (void)visible; (void)on;
    Affine *s = (Affine *)calloc(1, sizeof(Affine));
    if (!s) return NULL;
    s->cb = *cb;
    strncpy(s->name, name ? name : "", sizeof(s->name) - 1);
    if (t != fmi2CoSimulation) {
        say(s, "fmi2Instantiate: only co-simulation is supported");
        free(s);
        return NULL;
    }
    memcpy(s->p, DEFAULTS, sizeof s->p);
    return s;
}

void fmi2FreeInstance(fmi2Component c) { free(c); }

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean tolDef, fmi2Real tol, fmi2Real start,
                               fmi2Boolean stopDef, fmi2Real stop) {
    (void)tolDef; (void)tol; (void)stopDef; (void)stop;
    ((Affine *)c)->time = start;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) { (void)c; return fmi2OK; }
fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    ((Affine *)c)->initialized = 1;
    return fmi2OK;
}
fmi2Status fmi2Terminate(fmi2Component c) { (void)c; return fmi2OK; }
fmi2Status fmi2Reset(fmi2Component c) {
    Affine *s = (Affine *)c;
    memcpy(s->p, DEFAULTS, sizeof s->p);
    s->time = s->u = s->du = 0.0;
    s->initialized = 0;
    return fmi2OK;
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real v[]) {
    Affine *s = (Affine *)c;
    for (size_t i = 0; i < n; i++) {
        if (vr[i] == VR_U) v[i] = s->u;
        else if (vr[i] == VR_Y) v[i] = output(s);
        else if (vr[i] >= VR_PAR && vr[i] < VR_PAR + NPAR) v[i] = s->p[vr[i] - VR_PAR];
        else {
            say(s, "fmi2GetReal: unknown value reference %u", (unsigned)vr[i]);
            return fmi2Error;
        }
    }
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real v[]) {
    Affine *s = (Affine *)c;
    for (size_t i = 0; i < n; i++) {
        if (vr[i] == VR_U) {
            s->u = v[i];
            s->du = 0.0;
        } else if (vr[i] >= VR_PAR && vr[i] < VR_PAR + NPAR) {
            if (s->initialized) {
                say(s, "fmi2SetReal: %s is a fixed parameter: it cannot be set after initialisation",
                    PAR_NAMES[vr[i] - VR_PAR]);
                return fmi2Error;
            }
            s->p[vr[i] - VR_PAR] = v[i];
        } else {
            say(s, "fmi2SetReal: value reference %u is not an input or a parameter", (unsigned)vr[i]);
            return fmi2Error;
        }
    }
    return fmi2OK;
}

static fmi2Status none(fmi2Component c, size_t n, const char *fn) {
    if (!n) return fmi2OK;
    say((Affine *)c, "%s: this FMU has no variables of that type", fn);
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

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *st) {
    Affine *s = (Affine *)c;
    Affine *copy = *st ? (Affine *)*st : (Affine *)malloc(sizeof(Affine));
    if (!copy) {
        say(s, "fmi2GetFMUstate: out of memory");
        return fmi2Error;
    }
    *copy = *s;
    *st = copy;
    return fmi2OK;
}
fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate st) {
    if (!st) {
        say((Affine *)c, "fmi2SetFMUstate: no state");
        return fmi2Error;
    }
    *(Affine *)c = *(const Affine *)st;
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
fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate st, size_t *n) {
    (void)st; (void)n;
    say((Affine *)c, "fmi2SerializedFMUstateSize: serialization is not supported");
    return fmi2Error;
}
fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate st, fmi2Byte b[], size_t n) {
    (void)st; (void)b; (void)n;
    say((Affine *)c, "fmi2SerializeFMUstate: serialization is not supported");
    return fmi2Error;
}
fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte b[], size_t n, fmi2FMUstate *st) {
    (void)b; (void)n; (void)st;
    say((Affine *)c, "fmi2DeSerializeFMUstate: serialization is not supported");
    return fmi2Error;
}
fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference a[], size_t na,
                                        const fmi2ValueReference b[], size_t nb, const fmi2Real dv[], fmi2Real r[]) {
    (void)a; (void)na; (void)b; (void)nb; (void)dv; (void)r;
    say((Affine *)c, "fmi2GetDirectionalDerivative: not supported");
    return fmi2Error;
}

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                       const fmi2Integer o[], const fmi2Real v[]) {
    Affine *s = (Affine *)c;
    for (size_t i = 0; i < n; i++) {
        if (o[i] != 1 || vr[i] != VR_U) {
            say(s, "fmi2SetRealInputDerivatives: only the first derivative of u (value reference 0)");
            return fmi2Error;
        }
        s->du = v[i];
    }
    return fmi2OK;
}
fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                        const fmi2Integer o[], fmi2Real v[]) {
    (void)vr; (void)n; (void)o; (void)v;
    say((Affine *)c, "fmi2GetRealOutputDerivatives: not supported (maxOutputDerivativeOrder 0)");
    return fmi2Error;
}
fmi2Status fmi2CancelStep(fmi2Component c) {
    say((Affine *)c, "fmi2CancelStep: steps are not asynchronous");
    return fmi2Error;
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean noSet) {
    Affine *s = (Affine *)c;
    (void)noSet;
    if (!s->initialized) {
        say(s, "fmi2DoStep: called before fmi2ExitInitializationMode");
        return fmi2Error;
    }
    if (!(h > 0.0)) {
        say(s, "fmi2DoStep: communication step size %g s: must be > 0", h);
        return fmi2Error;
    }
    s->u += s->du * h;
    s->du = 0.0;
    s->time = t + h;
    return fmi2OK;
}

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind k, fmi2Status *v) {
    (void)k; (void)v;
    say((Affine *)c, "fmi2GetStatus: steps are not asynchronous");
    return fmi2Error;
}
fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind k, fmi2Real *v) {
    Affine *s = (Affine *)c;
    if (k != fmi2LastSuccessfulTime) {
        say(s, "fmi2GetRealStatus: only fmi2LastSuccessfulTime");
        return fmi2Error;
    }
    *v = s->time;
    return fmi2OK;
}
fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind k, fmi2Integer *v) {
    (void)k; (void)v;
    say((Affine *)c, "fmi2GetIntegerStatus: not supported");
    return fmi2Error;
}
fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind k, fmi2Boolean *v) {
    Affine *s = (Affine *)c;
    if (k != fmi2Terminated) {
        say(s, "fmi2GetBooleanStatus: only fmi2Terminated");
        return fmi2Error;
    }
    *v = fmi2False;
    return fmi2OK;
}
fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind k, fmi2String *v) {
    (void)k; (void)v;
    say((Affine *)c, "fmi2GetStringStatus: not supported");
    return fmi2Error;
}
