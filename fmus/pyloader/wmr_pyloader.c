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
 * The direct path (Linux): fmi2SetReal, fmi2DoStep and fmi2GetReal, the three calls a master makes at
 * every step, reach the slave's Python methods from here instead of through pythonfmu's binary, which
 * spends about 1 us of each call building its arguments, formatting and looking up the method by name and
 * creating three strings to empty the log queue (measured on G1: docs/benchmarks.md), and the three calls
 * of a step cross into Python once.  The slave (our fmus/fmi_base.py WmrSlave) hands itself to the loader
 * while pythonfmu's binary constructs it (in fmi2Instantiate, and in fmi2Reset, which constructs a new
 * one): the loader puts this thread's key, with None, in the dict sys._wmr_pyloader_slaves, the slave's
 * __init__ replaces None by itself, and the loader takes it out again.  A slave that does not (pythonfmu's
 * own slaves) keeps every call on pythonfmu's binary.  With the slave in hand:
 *   - fmi2SetReal of inputs only (slave._loader_held(): the Real inputs, which set_real takes in every
 *     mode without a message) returns fmi2OK at once and holds the values, each input once with its last
 *     value; any other fmi2SetReal calls slave._loader_set_real(vrs, values): True when set_real set them,
 *     False when it would refuse them (nothing changed): then pythonfmu's fmi2SetReal, whose failure and
 *     messages are pythonfmu's own;
 *   - fmi2DoStep calls slave._loader_step(t, h, held vrs, held values, get vrs): set_real of the held
 *     values, then do_step(t, h) as pythonfmu calls it (true: fmi2OK, false: fmi2Discard), then, after a
 *     step that succeeded, the values of the value references of the last fmi2GetReal, which the loader
 *     keeps as the step's outputs;
 *   - fmi2GetReal of those value references, with no call since the step, copies the step's outputs;
 *     any other calls slave._loader_get_real(vrs): the values, or None (initialization mode, or a value
 *     reference that is not a Real): then pythonfmu's fmi2GetReal.
 * Every other call (and fmi2SetReal and fmi2GetReal not served as above) first makes the held sets
 * (slave._loader_set_real) and forgets the step's outputs, so the slave sees every call in the order the
 * host made it, as through pythonfmu: a get before or after a step, a set between, the FMU state, reset.
 * The Python calls are made as pythonfmu makes them: value references and values as Python lists of int
 * and float, the method looked up on the slave at every call, the GIL taken with PyGILState_Ensure; the
 * log messages a call queued go to the host through pythonfmu's binary (an fmi2GetReal of no variables
 * empties the queue, through its logger and the categories the host enabled), in the order they were
 * queued.  An exception out of a Python call is Fatal as in pythonfmu: the one line pythonfmu writes
 * ("Fatal py exception encountered: [doStep] PyObject_CallMethod" and the exception's repr, or "unknown
 * error" where messages were queued before it, as pythonfmu's binary loses the exception then) is queued
 * after the slave's own messages and sent the same way, and the instance gets no further call.  The
 * step's outcome also sets what fmi2GetRealStatus (fmi2LastSuccessfulTime) and fmi2GetBooleanStatus
 * (fmi2Terminated) report: the loader keeps both, for the steps of either path, as pythonfmu does.  What
 * the loader keeps is per instance (FMI calls on one instance never overlap; instances on several threads
 * each take the GIL).  Windows keeps pythonfmu's path.
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
#include <math.h>

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


/* ---- the direct path (see above) ------------------------------------------------------------------- */
#ifndef _WIN32
typedef struct _object PyObject; /* opaque: only the C API's functions touch it */
typedef long wmr_ssize;          /* Py_ssize_t */
static struct {
    int state;                   /* 0: not resolved yet, 1: resolved, -1: not available */
    int (*gil_ensure)(void);
    void (*gil_release)(int);
    PyObject *(*sys_get)(const char *);
    int (*sys_set)(const char *, PyObject *);
    PyObject *(*dict_new)(void);
    PyObject *(*dict_get)(PyObject *, PyObject *);
    int (*dict_set)(PyObject *, PyObject *, PyObject *);
    int (*dict_del)(PyObject *, PyObject *);
    unsigned long (*thread_ident)(void);
    PyObject *(*long_from_ulong)(unsigned long);
    PyObject *(*list_new)(wmr_ssize);
    int (*list_set)(PyObject *, wmr_ssize, PyObject *);
    PyObject *(*list_get)(PyObject *, wmr_ssize);
    wmr_ssize (*list_size)(PyObject *);
    PyObject *(*float_from)(double);
    double (*float_as)(PyObject *);
    PyObject *(*intern)(const char *);
    PyObject *(*unicode_from)(const char *);
    PyObject *(*vcall_method)(PyObject *, PyObject *const *, size_t, PyObject *);
    int (*is_true)(PyObject *);
    void (*incref)(PyObject *);
    void (*decref)(PyObject *);
    void (*err_fetch)(PyObject **, PyObject **, PyObject **);
    void (*err_clear)(void);
    PyObject *(*repr)(PyObject *);
    const char *(*utf8)(PyObject *);
    unsigned long (*ulong_as)(PyObject *);
    PyObject *none, *true_, *false_;
    PyObject *s_set, *s_get, *s_step, *s_fatal, *s_queue, *s_held;
} P;

#define PY_SYM(field, name)                                        \
    do {                                                           \
        *(void **)(&P.field) = dlsym(RTLD_DEFAULT, name);          \
        if (P.field == NULL) return 0;                             \
    } while (0)

/* Resolve the C API of the interpreter in the process (wmr_ready has made sure there is one). */
static int py_resolve(void) {
    PY_SYM(gil_ensure, "PyGILState_Ensure");
    PY_SYM(gil_release, "PyGILState_Release");
    PY_SYM(sys_get, "PySys_GetObject");
    PY_SYM(sys_set, "PySys_SetObject");
    PY_SYM(dict_new, "PyDict_New");
    PY_SYM(dict_get, "PyDict_GetItem");
    PY_SYM(dict_set, "PyDict_SetItem");
    PY_SYM(dict_del, "PyDict_DelItem");
    PY_SYM(thread_ident, "PyThread_get_thread_ident");
    PY_SYM(long_from_ulong, "PyLong_FromUnsignedLong");
    PY_SYM(list_new, "PyList_New");
    PY_SYM(list_set, "PyList_SetItem");
    PY_SYM(list_get, "PyList_GetItem");
    PY_SYM(list_size, "PyList_Size");
    PY_SYM(float_from, "PyFloat_FromDouble");
    PY_SYM(float_as, "PyFloat_AsDouble");
    PY_SYM(intern, "PyUnicode_InternFromString");
    PY_SYM(unicode_from, "PyUnicode_FromString");
    PY_SYM(vcall_method, "PyObject_VectorcallMethod");
    PY_SYM(is_true, "PyObject_IsTrue");
    PY_SYM(incref, "Py_IncRef");
    PY_SYM(decref, "Py_DecRef");
    PY_SYM(err_fetch, "PyErr_Fetch");
    PY_SYM(err_clear, "PyErr_Clear");
    PY_SYM(repr, "PyObject_Repr");
    PY_SYM(utf8, "PyUnicode_AsUTF8");
    PY_SYM(ulong_as, "PyLong_AsUnsignedLong");
    PY_SYM(none, "_Py_NoneStruct");
    PY_SYM(true_, "_Py_TrueStruct");
    PY_SYM(false_, "_Py_FalseStruct");
    int g = P.gil_ensure();
    P.s_set = P.intern("_loader_set_real");
    P.s_get = P.intern("_loader_get_real");
    P.s_step = P.intern("_loader_step");
    P.s_held = P.intern("_loader_held");
    P.s_fatal = P.intern("_loader_fatal");
    P.s_queue = P.intern("_get_log_queue");
    P.gil_release(g);
    return P.s_set && P.s_get && P.s_step && P.s_fatal && P.s_queue && P.s_held;
}

static wmr_mutex py_resolve_lock = WMR_MUTEX_INITIALIZER;

static int py_available(void) {
    if (P.state == 0) {
        wmr_lock(&py_resolve_lock);
        if (P.state == 0) P.state = py_resolve() ? 1 : -1;
        wmr_unlock(&py_resolve_lock);
    }
    return P.state == 1;
}

#define SLOTS "_wmr_pyloader_slaves"

/* Before pythonfmu's binary constructs a slave on this thread: the slot the slave fills (see above). */
static void slot_open(void) {
    if (!py_available()) return;
    int g = P.gil_ensure();
    PyObject *slots = P.sys_get(SLOTS); /* borrowed */
    if (slots == NULL) {
        PyObject *d = P.dict_new();
        if (d && P.sys_set(SLOTS, d) == 0) slots = d;
        if (d) P.decref(d); /* sys holds it */
    }
    PyObject *key = P.long_from_ulong(P.thread_ident());
    if (slots && key && P.dict_set(slots, key, P.none) != 0) P.err_clear();
    if (key) P.decref(key);
    P.gil_release(g);
}

/* After: the slave constructed on this thread (a new reference), or NULL. */
static PyObject *slot_close(void) {
    if (!py_available()) return NULL;
    int g = P.gil_ensure();
    PyObject *slave = NULL, *slots = P.sys_get(SLOTS), *key = P.long_from_ulong(P.thread_ident());
    if (slots && key) {
        PyObject *v = P.dict_get(slots, key); /* borrowed */
        if (v && v != P.none) {
            slave = v;
            P.incref(slave);
        }
        if (v && P.dict_del(slots, key) != 0) P.err_clear();
    }
    if (key) P.decref(key);
    P.gil_release(g);
    return slave;
}
#endif

/* What the host holds (wmr_pyfinder.h's wmr_instance first) and what the direct path keeps. */
typedef struct {
    wmr_instance w;
    double last_time;   /* fmi2LastSuccessfulTime: as pythonfmu's binary keeps it */
    int terminated;     /* fmi2Terminated: a step returned Discard */
#ifndef _WIN32
    PyObject *slave;    /* the slave (a reference of ours), or NULL: every call to pythonfmu's binary */
    PyObject *queue;    /* its log queue (a reference of ours) */
    PyObject *set_key;  /* the value references of the last set, as a list (reused while unchanged) */
    PyObject *get_key;  /* of the last fmi2GetReal on the direct path: the outputs each step returns */
    size_t set_n, get_n;
    fmi2ValueReference *set_vr, *get_vr;
    unsigned char *held; /* [vr] 1 for a Real input: its fmi2SetReal waits for the next call (see above) */
    size_t n_held;       /* the size of held */
    size_t pend_n;       /* the held inputs waiting: each once, in the order first set, its last value */
    fmi2ValueReference *pend_vr; /* (n_held of each) */
    double *pend_val;
    size_t *pend_at;     /* [vr] its position in pend_vr + 1, or 0 */
    int cached;          /* 1: cache holds get_key's values after the last step, and nothing was called since */
    double *cache;       /* get_n values */
    size_t cache_cap;
#endif
} instance;

#ifndef _WIN32
/* Drop the slave and what goes with it (the GIL held). */
static void slave_drop(instance *x) {
    PyObject **refs[] = {&x->slave, &x->queue, &x->set_key, &x->get_key};
    for (size_t k = 0; k < sizeof refs / sizeof refs[0]; ++k)
        if (*refs[k]) {
            P.decref(*refs[k]);
            *refs[k] = NULL;
        }
    free(x->set_vr);
    free(x->get_vr);
    free(x->held);
    free(x->pend_vr);
    free(x->pend_val);
    free(x->pend_at);
    free(x->cache);
    x->set_vr = x->get_vr = x->pend_vr = NULL;
    x->held = NULL;
    x->pend_val = x->cache = NULL;
    x->pend_at = NULL;
    x->set_n = x->get_n = x->n_held = x->pend_n = x->cache_cap = 0;
    x->cached = 0;
}

/* The map of the value references whose sets may wait: slave._loader_held() (the GIL held; 0: none). */
static int held_map(instance *x, PyObject *slave) {
    PyObject *list = P.vcall_method(P.s_held, &slave, 1, NULL);
    wmr_ssize n = list ? P.list_size(list) : -1;
    unsigned long top = 0;
    for (wmr_ssize i = 0; i < n; ++i) {
        unsigned long vr = P.ulong_as(P.list_get(list, i));
        if (vr > top) top = vr;
    }
    if (n > 0) {
        x->held = (unsigned char *)calloc(top + 1, 1);
        x->pend_vr = (fmi2ValueReference *)calloc(top + 1, sizeof x->pend_vr[0]);
        x->pend_val = (double *)calloc(top + 1, sizeof x->pend_val[0]);
        x->pend_at = (size_t *)calloc(top + 1, sizeof x->pend_at[0]);
        if (x->held && x->pend_vr && x->pend_val && x->pend_at) { /* else none held */
            x->n_held = top + 1;
            for (wmr_ssize i = 0; i < n; ++i) x->held[P.ulong_as(P.list_get(list, i))] = 1;
        }
    }
    if (list) P.decref(list);
    if (n < 0) P.err_clear();
    return 1;
}

/* Take the slave constructed on this thread (slot_close), replacing the one held. */
static void slave_take(instance *x, PyObject *slave) {
    if (x->slave == NULL && slave == NULL) return;
    int g = P.gil_ensure();
    slave_drop(x);
    if (slave) {
        PyObject *queue = P.vcall_method(P.s_queue, &slave, 1, NULL);
        if (queue) {
            x->slave = slave;
            x->queue = queue;
            held_map(x, slave);
        } else {
            P.err_clear();
            P.decref(slave);
        }
    }
    P.gil_release(g);
}

/* The value references as a Python list: `*key` while they are the same as last time (the GIL held); a
 * list that is not `*key` is the caller's to release. */
static PyObject *vr_list(PyObject **key, fmi2ValueReference **kept, size_t *kept_n, const fmi2ValueReference vr[],
                         size_t n) {
    if (*key && *kept_n == n && (n == 0 || memcmp(*kept, vr, n * sizeof vr[0]) == 0)) return *key;
    PyObject *list = P.list_new((wmr_ssize)n);
    if (list == NULL) return NULL;
    for (size_t i = 0; i < n; ++i) {
        PyObject *v = P.long_from_ulong(vr[i]);
        if (v == NULL || P.list_set(list, (wmr_ssize)i, v) != 0) {
            P.decref(list);
            return NULL;
        }
    }
    fmi2ValueReference *copy = (fmi2ValueReference *)malloc(n ? n * sizeof vr[0] : 1);
    if (copy == NULL) return list;
    memcpy(copy, vr, n * sizeof vr[0]);
    if (*key) P.decref(*key);
    free(*kept);
    *key = list, *kept = copy, *kept_n = n;
    return list;
}

/* A Python list of floats (the GIL held), or NULL. */
static PyObject *float_list(const double v[], size_t n) {
    PyObject *list = P.list_new((wmr_ssize)n);
    for (size_t i = 0; list && i < n; ++i) {
        PyObject *f = P.float_from(v[i]);
        if (f == NULL || P.list_set(list, (wmr_ssize)i, f) != 0) {
            P.decref(list);
            list = NULL;
        }
    }
    return list;
}

/* Send the messages the slave queued to the host through pythonfmu's binary (its logger and categories). */
static void flush_log(instance *x) {
    wmr_ssize n = P.list_size(x->queue);
    if (n < 0) P.err_clear();
    if (n > 0) F.getReal(x->w.real, NULL, 0, NULL);
}

/* An exception out of a Python call (the GIL held): Fatal, logged as pythonfmu logs it (see above). */
static fmi2Status fatal(instance *x, const char *what) {
    PyObject *type = NULL, *value = NULL, *tb = NULL;
    P.err_fetch(&type, &value, &tb);
    char text[4096];
    const char *r = NULL;
    wmr_ssize queued = P.list_size(x->queue);
    if (queued < 0) P.err_clear();
    /* pythonfmu's binary empties the queue before it reads the exception, and loses it when there were
     * messages to send ("unknown error"): the same words here */
    PyObject *rep = value && queued == 0 ? P.repr(value) : NULL;
    if (rep) r = P.utf8(rep);
    if (r == NULL) P.err_clear();
    snprintf(text, sizeof text, "Fatal py exception encountered: %s\n%s", what, r ? r : "unknown error");
    PyObject *msg = P.unicode_from(text);
    PyObject *args[2] = {x->slave, msg};
    PyObject *done = msg ? P.vcall_method(P.s_fatal, args, 2, NULL) : NULL;
    if (done) P.decref(done);
    else P.err_clear();
    PyObject *garbage[] = {msg, rep, type, value, tb};
    for (size_t k = 0; k < sizeof garbage / sizeof garbage[0]; ++k)
        if (garbage[k]) P.decref(garbage[k]);
    flush_log(x);
    x->w.fatal = 1;
    return fmi2Fatal;
}

/* slave._loader_set_real(vrs, values) (the GIL held): the status, or -1 for pythonfmu's binary. */
static int set_now(instance *x, const fmi2ValueReference vr[], size_t n, const fmi2Real v[]) {
    int s = -1;
    PyObject *vrs = vr_list(&x->set_key, &x->set_vr, &x->set_n, vr, n);
    PyObject *vals = vrs ? float_list(v, n) : NULL;
    if (vals) {
        PyObject *args[3] = {x->slave, vrs, vals};
        PyObject *r = P.vcall_method(P.s_set, args, 3, NULL);
        int done = r ? P.is_true(r) : -1;
        if (r) P.decref(r);
        if (done < 0) {
            s = fatal(x, "[setReal] PyObject_CallMethod");
        } else {
            if (done) s = fmi2OK;
            flush_log(x);
        }
        P.decref(vals);
    } else {
        P.err_clear();
    }
    if (vrs && vrs != x->set_key) P.decref(vrs);
    return s;
}

/* No held set waits any more. */
static void pend_clear(instance *x) {
    for (size_t i = 0; i < x->pend_n; ++i) x->pend_at[x->pend_vr[i]] = 0;
    x->pend_n = 0;
}

/* Before any call but a held set, a step and a cached get: the cache is stale, and the sets held are made
 * (the slave's next call comes after them, as through pythonfmu).  fmi2OK, or fmi2Fatal. */
static fmi2Status settle(instance *x) {
    x->cached = 0;
    if (x->pend_n == 0 || x->slave == NULL || x->w.fatal) return fmi2OK;
    int g = P.gil_ensure();
    int s = set_now(x, x->pend_vr, x->pend_n, x->pend_val);
    pend_clear(x);
    P.gil_release(g);
    return s == fmi2Fatal ? fmi2Fatal : fmi2OK; /* (held sets are always taken: _loader_held) */
}

/* fmi2SetReal on the direct path: held when every value reference may wait, else made now (after the
 * held ones).  The status, or -1 for pythonfmu's binary. */
static int direct_set(instance *x, const fmi2ValueReference vr[], size_t n, const fmi2Real v[]) {
    size_t i = 0;
    while (i < n && vr[i] < x->n_held && x->held[vr[i]]) ++i;
    if (i == n) { /* each input once, its last value (set_real assigns each in turn: the same outcome) */
        x->cached = 0;
        for (i = 0; i < n; ++i) {
            size_t at = x->pend_at[vr[i]];
            if (at == 0) {
                x->pend_vr[x->pend_n] = vr[i];
                at = x->pend_at[vr[i]] = ++x->pend_n;
            }
            x->pend_val[at - 1] = v[i];
        }
        return fmi2OK;
    }
    if (settle(x) != fmi2OK) return fmi2Fatal;
    int g = P.gil_ensure();
    int s = set_now(x, vr, n, v);
    P.gil_release(g);
    return s;
}

/* fmi2GetReal on the direct path: from the cache when these are the outputs the last step returned and
 * nothing was called since, else slave._loader_get_real(vrs).  The status, or -1 for pythonfmu's binary. */
static int direct_get(instance *x, const fmi2ValueReference vr[], size_t n, fmi2Real v[]) {
    if (x->cached && n == x->get_n && (n == 0 || memcmp(vr, x->get_vr, n * sizeof vr[0]) == 0)) {
        memcpy(v, x->cache, n * sizeof v[0]);
        return fmi2OK;
    }
    if (settle(x) != fmi2OK) return fmi2Fatal;
    int g = P.gil_ensure();
    int s = -1;
    PyObject *vrs = vr_list(&x->get_key, &x->get_vr, &x->get_n, vr, n);
    if (vrs) {
        PyObject *args[2] = {x->slave, vrs};
        PyObject *r = P.vcall_method(P.s_get, args, 2, NULL);
        if (r == NULL) {
            s = fatal(x, "[getReal] PyObject_CallMethod");
        } else {
            if (r != P.none) {
                for (size_t i = 0; i < n; ++i) v[i] = P.float_as(P.list_get(r, (wmr_ssize)i));
                s = fmi2OK;
            }
            P.decref(r);
            flush_log(x);
        }
        if (vrs != x->get_key) P.decref(vrs);
    } else {
        P.err_clear();
    }
    P.gil_release(g);
    return s;
}

/* fmi2DoStep on the direct path: slave._loader_step(t, h, held vrs, held values, get_key): the held sets,
 * then pythonfmu's Step (do_step(t, h), its truth value), then, after a step that succeeded, the values
 * of get_key into the cache. */
static fmi2Status direct_step(instance *x, fmi2Real t, fmi2Real h) {
    int g = P.gil_ensure();
    fmi2Status s;
    PyObject *pv = NULL, *pf = NULL, *r = NULL;
    if (x->pend_n) {
        pv = vr_list(&x->set_key, &x->set_vr, &x->set_n, x->pend_vr, x->pend_n);
        pf = pv ? float_list(x->pend_val, x->pend_n) : NULL;
    }
    pend_clear(x);
    x->cached = 0;
    PyObject *ft = P.float_from(t), *fh = P.float_from(h);
    if (ft && fh && (pf || !pv)) {
        PyObject *args[6] = {x->slave, ft, fh, pv ? pv : P.none, pf ? pf : P.none,
                             x->get_key && x->get_n ? x->get_key : P.none};
        r = P.vcall_method(P.s_step, args, 6, NULL);
    }
    PyObject *garbage[] = {ft, fh, pf, pv != x->set_key ? pv : NULL};
    for (size_t k = 0; k < sizeof garbage / sizeof garbage[0]; ++k)
        if (garbage[k]) P.decref(garbage[k]);
    int ok = -1;
    if (r == P.true_ || r == P.false_) {
        ok = r == P.true_;
    } else if (r) {
        wmr_ssize n = P.list_size(r);   /* the values of get_key: the step succeeded */
        if (n >= 0 && (size_t)n == x->get_n && x->cache_cap < x->get_n) {
            double *c = (double *)realloc(x->cache, x->get_n * sizeof c[0]);
            if (c) x->cache = c, x->cache_cap = x->get_n;
        }
        if (n >= 0 && (size_t)n == x->get_n && x->cache_cap >= x->get_n) {
            for (wmr_ssize i = 0; i < n; ++i) x->cache[i] = P.float_as(P.list_get(r, i));
            x->cached = 1;
        }
        if (n < 0) P.err_clear();
        ok = P.is_true(r);
    }
    if (r) P.decref(r);
    if (ok < 0) {
        x->cached = 0;
        s = fatal(x, "[doStep] PyObject_CallMethod");
    } else {
        flush_log(x);
        s = ok ? fmi2OK : fmi2Discard;
    }
    P.gil_release(g);
    return s;
}
#else
static fmi2Status settle(instance *x) {
    (void)x;
    return fmi2OK;
}
#endif

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
#ifndef _WIN32
    slot_open();
#endif
    fmi2Component c = F.instantiate(instanceName, fmuType, fmuGUID, fmuResourceLocation, functions, visible, loggingOn);
#ifndef _WIN32
    PyObject *slave = slot_close();
#endif
    wmr_instantiate_end();
    instance *x = c ? (instance *)calloc(1, sizeof *x) : NULL;
#ifndef _WIN32
    if (x == NULL && slave) { /* out of memory: the slave is leaked, the host sees a failed instantiation */
        int g = P.gil_ensure();
        P.decref(slave);
        P.gil_release(g);
    }
#endif
    if (x == NULL) return NULL;
    x->w.real = c;
    x->last_time = NAN; /* pythonfmu's binary: NaN before the first step */
#ifndef _WIN32
    slave_take(x, slave);
#endif
    return (fmi2Component)x;
}

/* Every other function is called only with a component fmi2Instantiate returned (our wrapper), so
 * pythonfmu's binary is loaded; the NULL checks guard hosts that call out of order.  An instance that
 * returned fmi2Fatal gets no further call (see wmr_pyfinder.h).  The held sets are made first (settle). */
#define FORWARD(field, c, ...)                                               \
    do {                                                                     \
        instance *x_ = (instance *)(c);                                      \
        if (x_ == NULL || F.field == NULL) return fmi2Error;                 \
        if (x_->w.fatal) return fmi2Fatal;                                   \
        if (settle(x_) != fmi2OK) return fmi2Fatal;                          \
        fmi2Status s_ = F.field(x_->w.real, ##__VA_ARGS__);                  \
        if (s_ == fmi2Fatal) x_->w.fatal = 1;                                \
        return s_;                                                           \
    } while (0)

void fmi2FreeInstance(fmi2Component c) {
    instance *x = (instance *)c;
    if (x == NULL) return;
    if (!x->w.fatal) { /* after Fatal: leaked, and the slave with it (see wmr_pyfinder.h) */
#ifndef _WIN32
        slave_take(x, NULL); /* pythonfmu's binary then releases the slave's last reference, as before */
#endif
        if (F.freeInstance) F.freeInstance(x->w.real);
    }
    free(x);
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
/* pythonfmu's binary constructs a new slave: the direct path takes it (see above). */
static fmi2Status reset(fmi2Component c) { FORWARD(reset, c); }
fmi2Status fmi2Reset(fmi2Component c) {
#ifndef _WIN32
    instance *x = (instance *)c;
    if (x && !x->w.fatal && x->slave) {
        slot_open();
        fmi2Status s = reset(c);
        PyObject *slave = slot_close();
        if (!x->w.fatal) slave_take(x, slave);
        else if (slave) { /* Fatal: pythonfmu released what it held; the new slave is leaked as the old one */
            int g = P.gil_ensure();
            P.decref(slave);
            P.gil_release(g);
        }
        return s;
    }
#endif
    return reset(c);
}
fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real v[]) {
#ifndef _WIN32
    instance *x = (instance *)c;
    if (x && x->slave && !x->w.fatal) {
        int s = direct_get(x, vr, n, v);
        if (s >= 0) return (fmi2Status)s;
    }
#endif
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
#ifndef _WIN32
    instance *x = (instance *)c;
    if (x && x->slave && !x->w.fatal) {
        int s = direct_set(x, vr, n, v);
        if (s >= 0) return (fmi2Status)s;
    }
#endif
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
static fmi2Status do_step(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean noSetPrior) {
#ifndef _WIN32
    instance *x = (instance *)c;
    if (x && x->slave && !x->w.fatal) return direct_step(x, t, h);
#endif
    FORWARD(doStep, c, t, h, noSetPrior);
}
fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean noSetPrior) {
    fmi2Status s = do_step(c, t, h, noSetPrior);
    instance *x = (instance *)c;
    if (x && s == fmi2OK) x->last_time = t + h; /* as pythonfmu's fmi2DoStep */
    if (x && s == fmi2Discard) x->last_time = t, x->terminated = 1;
    return s;
}
fmi2Status fmi2CancelStep(fmi2Component c) { FORWARD(cancelStep, c); }
fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind k, fmi2Status *v) { FORWARD(getStatus, c, k, v); }
fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind k, fmi2Real *v) {
    instance *x = (instance *)c;
    if (x && !x->w.fatal && F.getRealStatus && k == fmi2LastSuccessfulTime) { /* the loader keeps it */
        *v = x->last_time;
        return fmi2OK;
    }
    FORWARD(getRealStatus, c, k, v);
}
fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind k, fmi2Integer *v) {
    FORWARD(getIntegerStatus, c, k, v);
}
fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind k, fmi2Boolean *v) {
    instance *x = (instance *)c;
    if (x && !x->w.fatal && F.getBooleanStatus && k == fmi2Terminated) { /* the loader keeps it */
        *v = x->terminated ? fmi2True : fmi2False;
        return fmi2OK;
    }
    FORWARD(getBooleanStatus, c, k, v);
}
fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind k, fmi2String *v) {
    FORWARD(getStringStatus, c, k, v);
}
