/* A small FMI 2.0 co-simulation FMU whose behaviour is chosen at compile time: it reproduces, one at a
 * time, what other tools' FMUs do (tests only).
 *
 * Variables: p (parameter, vr 0, start 1), u (Real input, vr 1), y (Real output, vr 2): y = p * u + c,
 * where c (vr 3, local state) counts the steps; b (Boolean input, vr 4), n (Integer output, vr 5) = steps.
 *
 * Behaviours (-D...):
 *   RESET_IN_SETUP   fmi2SetupExperiment resets p to 1 (as 20-sim FMUs do)
 *   FOREIGN_ENV      calls the logger with a componentEnvironment other than the one it was given
 *   VERBOSE          logs a message of status OK in category "logAll" at every step when that category
 *                    is enabled (FMUSDK with logging on)
 *   TERMINATE_AT=t   from t on, fmi2DoStep returns Discard with fmi2Terminated true
 *   ERROR_AT=t       from t on, fmi2DoStep logs an error and returns Error
 *   SEGFAULT_AT=t, ABORT_AT=t, EXIT_AT=t, HANG_AT=t, JUNK_AT=t   crash, abort, exit(3), loop forever, or
 *                    write junk to stdout, at the first step from t on
 *   BURN_US=n        every fmi2DoStep computes for about n microseconds of CPU time (a heavy FMU)
 */
#include <signal.h>
#include <stdio.h>
#include <time.h>
#include <stdlib.h>
#include <string.h>
#include "fmi2Functions.h"

typedef struct {
    fmi2CallbackFunctions cb;
    char name[256];
    double p, u, c, time, last_ok;
    int b, n, log_all, logging_on, terminated;
} Probe;

static void say(Probe *s, fmi2Status st, const char *cat, const char *msg) {
    void *env = s->cb.componentEnvironment;
#ifdef FOREIGN_ENV
    env = (void *)(size_t)0x5eed;
#endif
    if (s->cb.logger) s->cb.logger(env, s->name, st, cat, "%s", msg);
}

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String cats[]) {
    Probe *s = (Probe *)c;
    s->logging_on = on;
    s->log_all = (n == 0) ? on : 0;
    for (size_t i = 0; i < n; i++)
        if (!strcmp(cats[i], "logAll")) s->log_all = on;
    return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type t, fmi2String guid, fmi2String res,
                              const fmi2CallbackFunctions *cb, fmi2Boolean visible, fmi2Boolean on) {
    Probe *s = (Probe *)calloc(1, sizeof(Probe));
    if (!s) return NULL;
    s->cb = *cb;
    strncpy(s->name, name ? name : "", sizeof(s->name) - 1);
    s->p = 1.0;
    s->logging_on = s->log_all = on;
    say(s, fmi2OK, "logAll", "instantiated");
    return s;
}

void fmi2FreeInstance(fmi2Component c) { free(c); }

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean tolDef, fmi2Real tol, fmi2Real start,
                               fmi2Boolean stopDef, fmi2Real stop) {
    Probe *s = (Probe *)c;
    s->time = start;
#ifdef RESET_IN_SETUP
    s->p = 1.0;
#endif
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) { return fmi2OK; }
fmi2Status fmi2ExitInitializationMode(fmi2Component c) { return fmi2OK; }
fmi2Status fmi2Terminate(fmi2Component c) { return fmi2OK; }
fmi2Status fmi2Reset(fmi2Component c) { return fmi2OK; }

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real v[]) {
    Probe *s = (Probe *)c;
    for (size_t i = 0; i < n; i++) {
        switch (vr[i]) {
            case 0: v[i] = s->p; break;
            case 1: v[i] = s->u; break;
            case 2: v[i] = s->p * s->u + s->c; break;
            case 3: v[i] = s->c; break;
            default: return fmi2Error;
        }
    }
    return fmi2OK;
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Integer v[]) {
    Probe *s = (Probe *)c;
    for (size_t i = 0; i < n; i++) {
        if (vr[i] != 5) return fmi2Error;
        v[i] = s->n;
    }
    return fmi2OK;
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Boolean v[]) {
    Probe *s = (Probe *)c;
    for (size_t i = 0; i < n; i++) {
        if (vr[i] != 4) return fmi2Error;
        v[i] = s->b;
    }
    return fmi2OK;
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2String v[]) { return fmi2Error; }

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real v[]) {
    Probe *s = (Probe *)c;
    for (size_t i = 0; i < n; i++) {
        switch (vr[i]) {
            case 0: s->p = v[i]; break;
            case 1: s->u = v[i]; break;
            case 3: s->c = v[i]; break;
            default: return fmi2Error;
        }
    }
    return fmi2OK;
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer v[]) { return fmi2Error; }

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Boolean v[]) {
    Probe *s = (Probe *)c;
    for (size_t i = 0; i < n; i++) {
        if (vr[i] != 4) return fmi2Error;
        s->b = v[i];
    }
    return fmi2OK;
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2String v[]) { return fmi2Error; }
fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *st) { return fmi2Error; }
fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate st) { return fmi2Error; }
fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *st) { return fmi2Error; }
fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate st, size_t *n) { return fmi2Error; }
fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate st, fmi2Byte b[], size_t n) { return fmi2Error; }
fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte b[], size_t n, fmi2FMUstate *st) { return fmi2Error; }
fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference a[], size_t na,
                                        const fmi2ValueReference b[], size_t nb, const fmi2Real dv[], fmi2Real r[]) {
    return fmi2Error;
}
fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                       const fmi2Integer o[], const fmi2Real v[]) { return fmi2Error; }
fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                        const fmi2Integer o[], fmi2Real v[]) { return fmi2Error; }
fmi2Status fmi2CancelStep(fmi2Component c) { return fmi2Error; }

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean noSet) {
    Probe *s = (Probe *)c;
#ifdef BURN_US
    {   /* busy for BURN_US microseconds of this thread's CPU time */
        struct timespec a, b;
        clock_gettime(CLOCK_THREAD_CPUTIME_ID, &a);
        do {
            clock_gettime(CLOCK_THREAD_CPUTIME_ID, &b);
        } while ((b.tv_sec - a.tv_sec) * 1e6 + (b.tv_nsec - a.tv_nsec) * 1e-3 < BURN_US);
    }
#endif
#ifdef TERMINATE_AT
    if (t >= TERMINATE_AT - 1e-9) { s->terminated = 1; return fmi2Discard; }
#endif
#ifdef ERROR_AT
    if (t >= ERROR_AT - 1e-9) { say(s, fmi2Error, "logStatusError", "fmi2DoStep: the error asked for"); return fmi2Error; }
#endif
#ifdef SEGFAULT_AT
    if (t >= SEGFAULT_AT - 1e-9) raise(SIGSEGV);
#endif
#ifdef ABORT_AT
    if (t >= ABORT_AT - 1e-9) abort();
#endif
#ifdef EXIT_AT
    if (t >= EXIT_AT - 1e-9) exit(3);
#endif
#ifdef HANG_AT
    if (t >= HANG_AT - 1e-9) for (volatile int spin = 1; spin;) {}
#endif
#ifdef JUNK_AT
    if (t >= JUNK_AT - 1e-9) { printf("\x01\x02 junk from an FMU \xff\n"); fflush(stdout); }
#endif
#ifdef VERBOSE
    if (s->logging_on && s->log_all) say(s, fmi2OK, "logAll", "fmi2DoStep: a message at every step");
#endif
    s->c += 1.0;
    s->n += 1;
    s->time = t + h;
    s->last_ok = t + h;
    return fmi2OK;
}

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind k, fmi2Status *v) { return fmi2Error; }
fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind k, fmi2Real *v) {
    Probe *s = (Probe *)c;
    if (k != fmi2LastSuccessfulTime) return fmi2Error;
    *v = s->last_ok;
    return fmi2OK;
}
fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind k, fmi2Integer *v) { return fmi2Error; }
fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind k, fmi2Boolean *v) {
    Probe *s = (Probe *)c;
    if (k != fmi2Terminated) return fmi2Error;
    *v = s->terminated;
    return fmi2OK;
}
fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind k, fmi2String *v) { return fmi2Error; }
