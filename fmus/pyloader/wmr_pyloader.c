/*
 * The binary binaries/linux64/<model>.so of our pythonfmu FMUs: makes sure a Python interpreter is in the
 * process, then hands every FMI 2.0 call to pythonfmu's own binary, shipped beside it as
 * libpythonfmu-export.so.
 *
 * pythonfmu's binary takes the Python C API from the process that loads it.  A Python host (FMPy,
 * libcosimpy, ecospy, ...) has it; a C or C++ host has not.  On the first fmi2Instantiate this loader
 *   1. looks for an interpreter already in the process (Py_IsInitialized in the global scope: a shared
 *      libpython or a statically linked python executable); if there is one it is used, whatever its
 *      version, and nothing is loaded (never two interpreters in one process);
 *   2. otherwise loads the library named by the environment variable WMR_PY_ENV (if set) or the libpython
 *      recorded at build time (WMR_PY_LIBRARY), with RTLD_GLOBAL so that the C extension modules of the
 *      standard library (math, _struct, ...) resolve their symbols, finds its standard library (PYTHONHOME
 *      if set, else the first of the recorded home and the folders above the library that hold
 *      lib/pythonX.Y/os.py), initialises it without signal handlers and releases the GIL, as pythonfmu
 *      expects of an embedding host;
 *   3. loads libpythonfmu-export.so and resolves its FMI functions.
 * Steps 1 and 2 are serialised across all our FMUs in the process (see process_lock).
 * When no interpreter can be had, fmi2Instantiate returns NULL after one line through the host's logger
 * saying what was looked for and how to choose another Python.  The interpreter is never finalised.
 *
 * Built by fmus/build.py with the system C compiler:
 *   cc -shared -fPIC -O2 -I<FMI 2.0 headers> -DWMR_PY_LIBRARY=... -DWMR_PY_HOME=... -DWMR_PY_VERSION=...
 *      -DWMR_PY_ENV=... wmr_pyloader.c -ldl -lpthread
 */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <fcntl.h>
#include <limits.h>
#include <semaphore.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <wchar.h>

#include "fmi2Functions.h"

#ifndef WMR_PY_LIBRARY
#define WMR_PY_LIBRARY "" /* none recorded: the build interpreter had no shared libpython */
#endif
#ifndef WMR_PY_HOME
#define WMR_PY_HOME ""
#endif
#ifndef WMR_PY_VERSION
#define WMR_PY_VERSION "3"
#endif
#ifndef WMR_PY_ENV
#define WMR_PY_ENV "WMR_FMU_LIBPYTHON"
#endif
#define REAL_BINARY "libpythonfmu-export.so"

typedef int (*py_is_initialized_t)(void);
typedef void (*py_initialize_ex_t)(int);
typedef void *(*py_eval_save_thread_t)(void);
typedef const char *(*py_get_version_t)(void);
typedef wchar_t *(*py_decode_locale_t)(const char *, size_t *);
typedef void (*py_set_python_home_t)(const wchar_t *);

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

static pthread_mutex_t load_lock = PTHREAD_MUTEX_INITIALIZER;
static int loaded = 0;           /* 1 once Python and pythonfmu's binary are in place */
static char load_error[2048];    /* why loading failed (logged at every fmi2Instantiate) */

static void fail(const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(load_error, sizeof load_error, fmt, ap);
    va_end(ap);
}

/* The folder and file name (without .so) of this library. */
static void self_path(char *dir, size_t ndir, char *model, size_t nmodel) {
    Dl_info info;
    dir[0] = model[0] = '\0';
    if (dladdr((void *)&self_path, &info) == 0 || info.dli_fname == NULL) return;
    const char *slash = strrchr(info.dli_fname, '/');
    const char *base = slash ? slash + 1 : info.dli_fname;
    if (slash) snprintf(dir, ndir, "%.*s", (int)(slash - info.dli_fname), info.dli_fname);
    snprintf(model, nmodel, "%s", base);
    char *dot = strstr(model, ".so");
    if (dot) *dot = '\0';
}

static int is_file(const char *path) { return access(path, R_OK) == 0; }

/* 1 if home holds the standard library of Python `version` ("3.11"). */
static int has_stdlib(const char *home, const char *version) {
    char p[PATH_MAX], nodot[16];
    snprintf(p, sizeof p, "%s/lib/python%s/os.py", home, version);
    if (is_file(p)) return 1;
    size_t j = 0;
    for (const char *c = version; *c && j + 1 < sizeof nodot; ++c)
        if (*c != '.') nodot[j++] = *c;
    nodot[j] = '\0';
    snprintf(p, sizeof p, "%s/lib/python%s.zip", home, nodot);
    return is_file(p);
}

/* The Python home of the interpreter in `lib` (a path to libpython or to a python executable). */
static int find_home(const char *lib, const char *version, int recorded, char *home, size_t nhome) {
    if (recorded && WMR_PY_HOME[0] && has_stdlib(WMR_PY_HOME, version)) {
        snprintf(home, nhome, "%s", WMR_PY_HOME);
        return 1;
    }
    char d[PATH_MAX];
    if (realpath(lib, d) == NULL) snprintf(d, sizeof d, "%s", lib);
    for (int up = 0; up < 4; ++up) {
        char *slash = strrchr(d, '/');
        if (slash == NULL || slash == d) break;
        *slash = '\0';
        if (has_stdlib(d, version)) {
            snprintf(home, nhome, "%s", d);
            return 1;
        }
    }
    return 0;
}

/* Start the interpreter whose C API is reachable through `h` (a dlopen handle or RTLD_DEFAULT). */
static int start_python(void *h, const char *lib, int recorded, const char *how) {
    py_is_initialized_t is_init = (py_is_initialized_t)dlsym(h, "Py_IsInitialized");
    py_initialize_ex_t init_ex = (py_initialize_ex_t)dlsym(h, "Py_InitializeEx");
    py_eval_save_thread_t save_thread = (py_eval_save_thread_t)dlsym(h, "PyEval_SaveThread");
    py_get_version_t get_version = (py_get_version_t)dlsym(h, "Py_GetVersion");
    py_decode_locale_t decode = (py_decode_locale_t)dlsym(h, "Py_DecodeLocale");
    py_set_python_home_t set_home = (py_set_python_home_t)dlsym(h, "Py_SetPythonHome");
    if (!is_init || !init_ex || !save_thread || !get_version) {
        fail("%s (%s) is not a Python 3 library (Py_InitializeEx not found)", lib, how);
        return 0;
    }
    if (is_init()) return 1;
    char version[16]; /* "3.11" from "3.11.7 (main, ...)" */
    const char *v = get_version();
    size_t n = strspn(v, "0123456789");
    if (v[n] == '.') n += 1 + strspn(v + n + 1, "0123456789");
    snprintf(version, sizeof version, "%.*s", (int)(n < 15 ? n : 15), v);
    const char *env_home = getenv("PYTHONHOME");
    char home[PATH_MAX];
    if (env_home && env_home[0]) {
        snprintf(home, sizeof home, "%.*s", (int)strcspn(env_home, ":"), env_home);
        if (!has_stdlib(home, version)) {
            fail("PYTHONHOME=%s holds no standard library of Python %s (lib/python%s/os.py) for %s (%s); "
                 "unset PYTHONHOME or point it at that Python's prefix", env_home, version, version, lib, how);
            return 0;
        }
    } else {
        if (!find_home(lib, version, recorded, home, sizeof home)) {
            fail("found no standard library of Python %s (lib/python%s/os.py) near %s (%s); "
                 "set PYTHONHOME to that Python's prefix", version, version, lib, how);
            return 0;
        }
        if (set_home && decode) {
            wchar_t *w = decode(home, NULL); /* kept: Python reads it during and after initialisation */
            if (w) set_home(w);
        }
    }
    init_ex(0);     /* no signal handlers: the host owns them */
    save_thread();  /* release the GIL; pythonfmu takes it with PyGILState_Ensure on every call */
    return 1;
}

/* Several of our FMUs (each a separate copy of this loader, with its own statics) may be instantiated at
 * once on several threads: a named semaphore private to the process serialises starting the interpreter
 * across all of them.  It is unlinked after the first attempt: a loader that comes later creates a fresh
 * one and finds the interpreter started (or fails the same way). */
static sem_t *process_lock(char *name, size_t n) {
    snprintf(name, n, "/wmr-pyloader-%ld", (long)getpid());
    sem_t *sem = sem_open(name, O_CREAT, 0600, 1);
    if (sem == SEM_FAILED) return NULL; /* no /dev/shm: the per-FMU mutex alone */
    while (sem_wait(sem) != 0) {
    }
    return sem;
}

static int ensure_python_locked(void);

static int ensure_python(void) {
    char name[64];
    sem_t *sem = process_lock(name, sizeof name);
    int ok = ensure_python_locked();
    if (sem) {
        sem_unlink(name); /* nothing left in /dev/shm; later loaders find the outcome, not the lock */
        sem_post(sem);
        sem_close(sem);
    }
    return ok;
}

static int ensure_python_locked(void) {
    /* 1. an interpreter already in the process (a Python host, or one loaded by another FMU) */
    if (dlsym(RTLD_DEFAULT, "Py_IsInitialized") != NULL) {
        Dl_info info;
        const char *where = "the host process";
        if (dladdr(dlsym(RTLD_DEFAULT, "Py_IsInitialized"), &info) && info.dli_fname) where = info.dli_fname;
        return start_python(RTLD_DEFAULT, where, 0, "already loaded in the process");
    }
    /* 2. the library chosen by the user, else the one recorded at build time */
    const char *env = getenv(WMR_PY_ENV);
    int recorded = !(env && env[0]);
    const char *lib = recorded ? WMR_PY_LIBRARY : env;
    char how[256];
    if (recorded)
        snprintf(how, sizeof how, "the Python %s this FMU was built with", WMR_PY_VERSION);
    else
        snprintf(how, sizeof how, "given by %s", WMR_PY_ENV);
    if (lib[0] == '\0') {
        fail("no Python in the process and none recorded (the FMU was built by a Python without a shared "
             "libpython); set %s to the path of a libpython3.X.so", WMR_PY_ENV);
        return 0;
    }
    void *h = dlopen(lib, RTLD_NOW | RTLD_GLOBAL);
    if (h == NULL) {
        const char *e = dlerror();
        fail("cannot load %s (%s): %s; install Python %s with its shared library, or set %s to the path of "
             "another libpython3.X.so", lib, how, e ? e : "unknown error", WMR_PY_VERSION, WMR_PY_ENV);
        return 0;
    }
    return start_python(h, lib, recorded, how);
}

#define RESOLVE(field, name)                                            \
    do {                                                                \
        *(void **)(&F.field) = dlsym(real, name);                       \
        if (F.field == NULL) {                                          \
            fail("%s has no function %s", path, name);                  \
            return 0;                                                   \
        }                                                               \
    } while (0)

static int load_real(const char *dir, fmi2String resourceLocation) {
    char path[PATH_MAX];
    if (snprintf(path, sizeof path, "%s/" REAL_BINARY, dir) >= (int)sizeof path) path[0] = '\0';
    if (!is_file(path) && resourceLocation) {
        /* the host copied this library elsewhere: try <fmu>/binaries/linux64 through the resources' URI */
        const char *p = resourceLocation;
        if (strncmp(p, "file://", 7) == 0) p += 7;
        if (strncmp(p, "localhost/", 10) == 0) p += 9;
        char res[PATH_MAX];
        size_t j = 0;
        for (; *p && j + 1 < sizeof res; ++p) { /* undo %XX escapes */
            if (p[0] == '%' && p[1] && p[2]) {
                char hex[3] = {p[1], p[2], 0};
                res[j++] = (char)strtol(hex, NULL, 16);
                p += 2;
            } else {
                res[j++] = *p;
            }
        }
        res[j] = '\0';
        while (j > 1 && res[j - 1] == '/') res[--j] = '\0';
        snprintf(path, sizeof path, "%s/../binaries/linux64/%s", res, REAL_BINARY);
    }
    void *real = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (real == NULL) {
        const char *e = dlerror();
        fail("cannot load pythonfmu's binary %s: %s", path, e ? e : "unknown error");
        return 0;
    }
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
    char dir[PATH_MAX], model[256];
    self_path(dir, sizeof dir, model, sizeof model);
    pthread_mutex_lock(&load_lock);
    if (!loaded && load_error[0] == '\0') {
        if (ensure_python() && load_real(dir, fmuResourceLocation)) loaded = 1;
    }
    pthread_mutex_unlock(&load_lock);
    if (!loaded) {
        if (functions && functions->logger)
            functions->logger(functions->componentEnvironment, instanceName, fmi2Error, "logStatusError",
                              "%s: no Python interpreter for this FMU: %s", model[0] ? model : "FMU", load_error);
        else
            fprintf(stderr, "%s: no Python interpreter for this FMU: %s\n", model[0] ? model : "FMU", load_error);
        return NULL;
    }
    return F.instantiate(instanceName, fmuType, fmuGUID, fmuResourceLocation, functions, visible, loggingOn);
}

/* Every other function is called only with a component fmi2Instantiate returned, so pythonfmu's binary is
 * loaded; the NULL checks guard hosts that call out of order. */
#define FORWARD(field, ...) return F.field ? F.field(__VA_ARGS__) : fmi2Error

void fmi2FreeInstance(fmi2Component c) {
    if (F.freeInstance) F.freeInstance(c);
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
