/*
 * The binary binaries/linux64/<model>.so of our pythonfmu FMUs: makes sure a Python interpreter is in the
 * process, then hands every FMI 2.0 call to pythonfmu's own binary, shipped beside it as
 * libpythonfmu-export.so.
 *
 * pythonfmu's binary takes the Python C API from the process that loads it.  A Python host (FMPy,
 * libcosimpy, ecospy, ...) has it; a C or C++ host has not.  On the first fmi2Instantiate this loader
 * finds or starts an interpreter (wmr_pyfinder.h: the one in the process, else WMR_PY_ENV's library or the
 * libpython recorded at build time), then loads libpythonfmu-export.so and resolves its FMI functions.
 * When no interpreter can be had, fmi2Instantiate returns NULL after one line through the host's logger
 * saying what was looked for and how to choose another Python.  The interpreter is never finalised.
 *
 * Around pythonfmu 0.7's defects (wmr_pyfinder.h): after each instantiation the binary's empty PyState is
 * released (no use-after-free at exit), and an instance that returned fmi2Fatal gets no further call (not
 * even fmi2FreeInstance, which would release its Python objects a second time).
 *
 * On Windows (binaries/win64/<model>.dll) the same, in front of pythonfmu's pythonfmu-export.dll; the
 * interpreter is found as wmr_pyfinder.h says for Windows.
 *
 * Built by fmus/build.py with the system C compiler:
 *   cc -shared -fPIC -O2 -I<FMI 2.0 headers> -DWMR_PY_LIBRARY=... -DWMR_PY_HOME=... -DWMR_PY_VERSION=...
 *      -DWMR_PY_ENV=... -DWMR_PY_MIN_MINOR=... wmr_pyloader.c -ldl -lpthread
 * and, where MinGW-w64 is installed, for Windows:
 *   x86_64-w64-mingw32-gcc -shared -O2 -static-libgcc -s -I<FMI 2.0 headers> -DWMR_PY_VERSION=...
 *      -DWMR_PY_ENV=... -DWMR_PY_MIN_MINOR=... wmr_pyloader.c -ladvapi32
 */
#include "wmr_pyfinder.h"
#include "fmi2Functions.h"

/* pythonfmu's FMI functions */
static struct {
    fmi2InstantiateTYPE *instantiate;
    fmi2FreeInstanceTYPE *freeInstance;
    fmi2SetDebugLoggingTYPE *setDebugLogging;
    fmi2SetupExperimentTYPE *setupExperiment;
    fmi2EnterInitializationModeTYPE *enterInitializationMode;
    fmi2ExitInitializationModeTYPE *exitInitializationMode;
    fmi2TerminateTYPE *terminate;
    fmi2ResetTYPE *reset;
    fmi2GetRealTYPE *getReal;
    fmi2GetIntegerTYPE *getInteger;
    fmi2GetBooleanTYPE *getBoolean;
    fmi2GetStringTYPE *getString;
    fmi2SetRealTYPE *setReal;
    fmi2SetIntegerTYPE *setInteger;
    fmi2SetBooleanTYPE *setBoolean;
    fmi2SetStringTYPE *setString;
    fmi2GetFMUstateTYPE *getFMUstate;
    fmi2SetFMUstateTYPE *setFMUstate;
    fmi2FreeFMUstateTYPE *freeFMUstate;
    fmi2SerializedFMUstateSizeTYPE *serializedFMUstateSize;
    fmi2SerializeFMUstateTYPE *serializeFMUstate;
    fmi2DeSerializeFMUstateTYPE *deSerializeFMUstate;
    fmi2GetDirectionalDerivativeTYPE *getDirectionalDerivative;
    fmi2SetRealInputDerivativesTYPE *setRealInputDerivatives;
    fmi2GetRealOutputDerivativesTYPE *getRealOutputDerivatives;
    fmi2DoStepTYPE *doStep;
    fmi2CancelStepTYPE *cancelStep;
    fmi2GetStatusTYPE *getStatus;
    fmi2GetRealStatusTYPE *getRealStatus;
    fmi2GetIntegerStatusTYPE *getIntegerStatus;
    fmi2GetBooleanStatusTYPE *getBooleanStatus;
    fmi2GetStringStatusTYPE *getStringStatus;
} F;

#define RESOLVE(field, name)                                            \
    do {                                                                \
        *(void **)(&F.field) = wmr_sym(real, name);                         \
        if (F.field == NULL) {                                          \
            wmr_fail("pythonfmu's binary has no function %s", name);    \
            return 0;                                                   \
        }                                                               \
    } while (0)

static int load_real(const wmr_char *dir, const char *resourceLocation) {
    wmr_lib real = wmr_load_binary(dir, resourceLocation, 1, WMR_PLATFORM2);
    if (real == NULL) return 0;
    RESOLVE(instantiate, "fmi2Instantiate");
    RESOLVE(freeInstance, "fmi2FreeInstance");
    RESOLVE(setDebugLogging, "fmi2SetDebugLogging");
    RESOLVE(setupExperiment, "fmi2SetupExperiment");
    RESOLVE(enterInitializationMode, "fmi2EnterInitializationMode");
    RESOLVE(exitInitializationMode, "fmi2ExitInitializationMode");
    RESOLVE(terminate, "fmi2Terminate");
    RESOLVE(reset, "fmi2Reset");
    RESOLVE(getReal, "fmi2GetReal");
    RESOLVE(getInteger, "fmi2GetInteger");
    RESOLVE(getBoolean, "fmi2GetBoolean");
    RESOLVE(getString, "fmi2GetString");
    RESOLVE(setReal, "fmi2SetReal");
    RESOLVE(setInteger, "fmi2SetInteger");
    RESOLVE(setBoolean, "fmi2SetBoolean");
    RESOLVE(setString, "fmi2SetString");
    RESOLVE(getFMUstate, "fmi2GetFMUstate");
    RESOLVE(setFMUstate, "fmi2SetFMUstate");
    RESOLVE(freeFMUstate, "fmi2FreeFMUstate");
    RESOLVE(serializedFMUstateSize, "fmi2SerializedFMUstateSize");
    RESOLVE(serializeFMUstate, "fmi2SerializeFMUstate");
    RESOLVE(deSerializeFMUstate, "fmi2DeSerializeFMUstate");
    RESOLVE(getDirectionalDerivative, "fmi2GetDirectionalDerivative");
    RESOLVE(setRealInputDerivatives, "fmi2SetRealInputDerivatives");
    RESOLVE(getRealOutputDerivatives, "fmi2GetRealOutputDerivatives");
    RESOLVE(doStep, "fmi2DoStep");
    RESOLVE(cancelStep, "fmi2CancelStep");
    RESOLVE(getStatus, "fmi2GetStatus");
    RESOLVE(getRealStatus, "fmi2GetRealStatus");
    RESOLVE(getIntegerStatus, "fmi2GetIntegerStatus");
    RESOLVE(getBooleanStatus, "fmi2GetBooleanStatus");
    RESOLVE(getStringStatus, "fmi2GetStringStatus");
    return 1;
}

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn) {
    char model[256];
    if (!wmr_ready(load_real, fmuResourceLocation, model, sizeof model)) {
        if (functions && functions->logger)
            functions->logger(functions->componentEnvironment, instanceName, fmi2Error, "logStatusError",
                              "%s: no Python interpreter for this FMU: %s", model[0] ? model : "FMU", wmr_load_error);
        else
            fprintf(stderr, "%s: no Python interpreter for this FMU: %s\n", model[0] ? model : "FMU", wmr_load_error);
        return NULL;
    }
    wmr_instantiate_begin();
    fmi2Component c = F.instantiate(instanceName, fmuType, fmuGUID, fmuResourceLocation, functions, visible, loggingOn);
    wmr_instantiate_end();
    return (fmi2Component)wmr_wrap(c);
}

/* Every other function is called only with a component fmi2Instantiate returned (our wrapper), so
 * pythonfmu's binary is loaded; the NULL checks guard hosts that call out of order.  An instance that
 * returned fmi2Fatal gets no further call (see wmr_pyfinder.h). */
#define FORWARD(field, c, ...)                                               \
    do {                                                                     \
        wmr_instance *w_ = (wmr_instance *)(c);                              \
        if (w_ == NULL || F.field == NULL) return fmi2Error;                 \
        if (w_->fatal) return fmi2Fatal;                                     \
        fmi2Status s_ = F.field(w_->real, ##__VA_ARGS__);                    \
        if (s_ == fmi2Fatal) w_->fatal = 1;                                  \
        return s_;                                                           \
    } while (0)

void fmi2FreeInstance(fmi2Component c) {
    wmr_instance *w = (wmr_instance *)c;
    if (w == NULL) return;
    if (!w->fatal && F.freeInstance) F.freeInstance(w->real); /* after Fatal: leaked (see wmr_pyfinder.h) */
    free(w);
}
fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String cat[]) {
    FORWARD(setDebugLogging, c, on, n, cat);
}
fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean tolDef, fmi2Real tol, fmi2Real start,
                               fmi2Boolean stopDef, fmi2Real stop) {
    FORWARD(setupExperiment, c, tolDef, tol, start, stopDef, stop);
}
fmi2Status fmi2EnterInitializationMode(fmi2Component c) { FORWARD(enterInitializationMode, c); }
fmi2Status fmi2ExitInitializationMode(fmi2Component c) { FORWARD(exitInitializationMode, c); }
fmi2Status fmi2Terminate(fmi2Component c) { FORWARD(terminate, c); }
fmi2Status fmi2Reset(fmi2Component c) { FORWARD(reset, c); }
fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real v[]) {
    FORWARD(getReal, c, vr, n, v);
}
fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Integer v[]) {
    FORWARD(getInteger, c, vr, n, v);
}
fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Boolean v[]) {
    FORWARD(getBoolean, c, vr, n, v);
}
fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2String v[]) {
    FORWARD(getString, c, vr, n, v);
}
fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real v[]) {
    FORWARD(setReal, c, vr, n, v);
}
fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer v[]) {
    FORWARD(setInteger, c, vr, n, v);
}
fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Boolean v[]) {
    FORWARD(setBoolean, c, vr, n, v);
}
fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2String v[]) {
    FORWARD(setString, c, vr, n, v);
}
fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *s) { FORWARD(getFMUstate, c, s); }
fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate s) { FORWARD(setFMUstate, c, s); }
fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *s) { FORWARD(freeFMUstate, c, s); }
fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate s, size_t *size) {
    FORWARD(serializedFMUstateSize, c, s, size);
}
fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate s, fmi2Byte b[], size_t size) {
    FORWARD(serializeFMUstate, c, s, b, size);
}
fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte b[], size_t size, fmi2FMUstate *s) {
    FORWARD(deSerializeFMUstate, c, b, size, s);
}
fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference u[], size_t nu,
                                        const fmi2ValueReference z[], size_t nz, const fmi2Real dv[],
                                        fmi2Real dz[]) {
    FORWARD(getDirectionalDerivative, c, u, nu, z, nz, dv, dz);
}
fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                       const fmi2Integer order[], const fmi2Real v[]) {
    FORWARD(setRealInputDerivatives, c, vr, n, order, v);
}
fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                        const fmi2Integer order[], fmi2Real v[]) {
    FORWARD(getRealOutputDerivatives, c, vr, n, order, v);
}
fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean noSetPrior) {
    FORWARD(doStep, c, t, h, noSetPrior);
}
fmi2Status fmi2CancelStep(fmi2Component c) { FORWARD(cancelStep, c); }
fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind k, fmi2Status *v) { FORWARD(getStatus, c, k, v); }
fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind k, fmi2Real *v) {
    FORWARD(getRealStatus, c, k, v);
}
fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind k, fmi2Integer *v) {
    FORWARD(getIntegerStatus, c, k, v);
}
fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind k, fmi2Boolean *v) {
    FORWARD(getBooleanStatus, c, k, v);
}
fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind k, fmi2String *v) {
    FORWARD(getStringStatus, c, k, v);
}
