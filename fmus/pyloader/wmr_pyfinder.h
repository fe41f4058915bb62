/*
 * What the FMI 2.0 loader (wmr_pyloader.c) and the FMI 3.0 loader (wmr_pyloader3.c) share: finding or
 * starting a Python interpreter, loading pythonfmu's (or pythonfmu3's) own binary shipped beside the
 * loader as libpythonfmu-export.so, the two guards around that binary's defects, and the instance wrapper.
 *
 * Included once by each loader; everything here is static (each FMU's loader is a separate copy with its
 * own statics).  Needs WMR_PY_LIBRARY, WMR_PY_HOME, WMR_PY_VERSION and WMR_PY_ENV (see the loaders).
 *
 * Interpreter (wmr_ensure_python): on the first instantiation
 *   1. an interpreter already in the process (Py_IsInitialized in the global scope: a shared libpython or
 *      a statically linked python executable) is used, whatever its version, and nothing is loaded (never
 *      two interpreters in one process);
 *   2. otherwise the library named by the environment variable WMR_PY_ENV (if set) or the libpython
 *      recorded at build time (WMR_PY_LIBRARY) is loaded with RTLD_GLOBAL so that the C extension modules
 *      of the standard library (math, _struct, ...) resolve their symbols; its standard library is found
 *      (PYTHONHOME if set, else the first of the recorded home and the folders above the library that hold
 *      lib/pythonX.Y/os.py); it is initialised without signal handlers and the GIL is released, as
 *      pythonfmu expects of an embedding host.
 * Serialised across all our FMUs in the process (wmr_process_lock).  The interpreter is never finalised.
 *
 * Exit (wmr_instantiate_begin / wmr_instantiate_end): pythonfmu 0.7 and pythonfmu3 0.3.4 keep their
 * interpreter state in a global std::shared_ptr<PyState> that exit()'s static destructors destroy; the
 * library's __attribute__((destructor)), run later from _dl_fini for every copy still loaded, resets that
 * destroyed pointer again and decrements a counter inside the freed block (a use-after-free that breaks
 * glibc's free lists: "corrupted double-linked list", exit 134, at some normal exits).  The copies are
 * still loaded at exit: this loader never closes the binary, and pythonfmu3's is NODELETE.  Since the
 * interpreter is always initialised before the binary's first instantiation (step 1 or 2 above), that
 * PyState owns nothing (its worker thread sees Py_IsInitialized() and returns at once): after every
 * instantiation the loader calls the binary's exported finalizePythonInterpreter(), which empties the
 * global pointer, so that neither the static destructor nor the library destructor has anything to free.
 * The next instantiation creates a fresh, empty PyState.  Never called while another instantiation of the
 * same copy is in progress (the binary resets the pointer without its own lock), never when the
 * interpreter was not initialised before the call (then the PyState would own it).
 *
 * Fatal (wmr_instance): after a Fatal status pythonfmu and pythonfmu3 have already released the slave's
 * Python objects without clearing their pointers, so freeing the instance releases them a second time
 * (heap corruption, a crash at the next garbage collection).  The FMI standard allows no further call
 * after Fatal; the loader enforces it: the host gets a wrapper, every call on an instance that returned
 * Fatal returns Fatal without reaching the binary, and freeing it frees only the wrapper (the slave is
 * leaked, as the standard's rule implies).
 */
#ifndef WMR_PYFINDER_H
#define WMR_PYFINDER_H

#define _GNU_SOURCE
#include <dlfcn.h>
#include <fcntl.h>
#include <limits.h>
#include <pthread.h>
#include <semaphore.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <wchar.h>

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
#define WMR_REAL_BINARY "libpythonfmu-export.so"
#define WMR_STATUS_FATAL 4 /* fmi2Fatal and fmi3Fatal */

typedef int (*py_is_initialized_t)(void);
typedef void (*py_initialize_ex_t)(int);
typedef void *(*py_eval_save_thread_t)(void);
typedef const char *(*py_get_version_t)(void);
typedef wchar_t *(*py_decode_locale_t)(const char *, size_t *);
typedef void (*py_set_python_home_t)(const wchar_t *);
typedef void (*finalize_python_interpreter_t)(void);

static pthread_mutex_t wmr_load_lock = PTHREAD_MUTEX_INITIALIZER;
static int wmr_loaded = 0;            /* 1 once Python and the binary are in place */
static char wmr_load_error[2048];     /* why loading failed (logged at every instantiation) */
static py_is_initialized_t wmr_py_is_initialized; /* of the interpreter in use */

static void wmr_fail(const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(wmr_load_error, sizeof wmr_load_error, fmt, ap);
    va_end(ap);
}

/* The folder and file name (without .so) of this library. */
static void wmr_self_path(char *dir, size_t ndir, char *model, size_t nmodel) {
    Dl_info info;
    dir[0] = model[0] = '\0';
    if (dladdr((void *)&wmr_self_path, &info) == 0 || info.dli_fname == NULL) return;
    const char *slash = strrchr(info.dli_fname, '/');
    const char *base = slash ? slash + 1 : info.dli_fname;
    if (slash) snprintf(dir, ndir, "%.*s", (int)(slash - info.dli_fname), info.dli_fname);
    snprintf(model, nmodel, "%s", base);
    char *dot = strstr(model, ".so");
    if (dot) *dot = '\0';
}

static int wmr_is_file(const char *path) { return access(path, R_OK) == 0; }

/* 1 if home holds the standard library of Python `version` ("3.11"). */
static int wmr_has_stdlib(const char *home, const char *version) {
    char p[PATH_MAX], nodot[16];
    snprintf(p, sizeof p, "%s/lib/python%s/os.py", home, version);
    if (wmr_is_file(p)) return 1;
    size_t j = 0;
    for (const char *c = version; *c && j + 1 < sizeof nodot; ++c)
        if (*c != '.') nodot[j++] = *c;
    nodot[j] = '\0';
    snprintf(p, sizeof p, "%s/lib/python%s.zip", home, nodot);
    return wmr_is_file(p);
}

/* The Python home of the interpreter in `lib` (a path to libpython or to a python executable). */
static int wmr_find_home(const char *lib, const char *version, int recorded, char *home, size_t nhome) {
    if (recorded && WMR_PY_HOME[0] && wmr_has_stdlib(WMR_PY_HOME, version)) {
        snprintf(home, nhome, "%s", WMR_PY_HOME);
        return 1;
    }
    char d[PATH_MAX];
    if (realpath(lib, d) == NULL) snprintf(d, sizeof d, "%s", lib);
    for (int up = 0; up < 4; ++up) {
        char *slash = strrchr(d, '/');
        if (slash == NULL || slash == d) break;
        *slash = '\0';
        if (wmr_has_stdlib(d, version)) {
            snprintf(home, nhome, "%s", d);
            return 1;
        }
    }
    return 0;
}

/* Start the interpreter whose C API is reachable through `h` (a dlopen handle or RTLD_DEFAULT). */
static int wmr_start_python(void *h, const char *lib, int recorded, const char *how) {
    py_is_initialized_t is_init = (py_is_initialized_t)dlsym(h, "Py_IsInitialized");
    py_initialize_ex_t init_ex = (py_initialize_ex_t)dlsym(h, "Py_InitializeEx");
    py_eval_save_thread_t save_thread = (py_eval_save_thread_t)dlsym(h, "PyEval_SaveThread");
    py_get_version_t get_version = (py_get_version_t)dlsym(h, "Py_GetVersion");
    py_decode_locale_t decode = (py_decode_locale_t)dlsym(h, "Py_DecodeLocale");
    py_set_python_home_t set_home = (py_set_python_home_t)dlsym(h, "Py_SetPythonHome");
    if (!is_init || !init_ex || !save_thread || !get_version) {
        wmr_fail("%s (%s) is not a Python 3 library (Py_InitializeEx not found)", lib, how);
        return 0;
    }
    wmr_py_is_initialized = is_init;
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
        if (!wmr_has_stdlib(home, version)) {
            wmr_fail("PYTHONHOME=%s holds no standard library of Python %s (lib/python%s/os.py) for %s (%s); "
                     "unset PYTHONHOME or point it at that Python's prefix", env_home, version, version, lib, how);
            return 0;
        }
    } else {
        if (!wmr_find_home(lib, version, recorded, home, sizeof home)) {
            wmr_fail("found no standard library of Python %s (lib/python%s/os.py) near %s (%s); "
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
static sem_t *wmr_process_lock(char *name, size_t n) {
    snprintf(name, n, "/wmr-pyloader-%ld", (long)getpid());
    sem_t *sem = sem_open(name, O_CREAT, 0600, 1);
    if (sem == SEM_FAILED) return NULL; /* no /dev/shm: the per-FMU mutex alone */
    while (sem_wait(sem) != 0) {
    }
    return sem;
}

static int wmr_ensure_python_locked(void) {
    /* 1. an interpreter already in the process (a Python host, or one loaded by another FMU) */
    if (dlsym(RTLD_DEFAULT, "Py_IsInitialized") != NULL) {
        Dl_info info;
        const char *where = "the host process";
        if (dladdr(dlsym(RTLD_DEFAULT, "Py_IsInitialized"), &info) && info.dli_fname) where = info.dli_fname;
        return wmr_start_python(RTLD_DEFAULT, where, 0, "already loaded in the process");
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
        wmr_fail("no Python in the process and none recorded (the FMU was built by a Python without a shared "
                 "libpython); set %s to the path of a libpython3.X.so", WMR_PY_ENV);
        return 0;
    }
    void *h = dlopen(lib, RTLD_NOW | RTLD_GLOBAL);
    if (h == NULL) {
        const char *e = dlerror();
        wmr_fail("cannot load %s (%s): %s; install Python %s with its shared library, or set %s to the path of "
                 "another libpython3.X.so", lib, how, e ? e : "unknown error", WMR_PY_VERSION, WMR_PY_ENV);
        return 0;
    }
    return wmr_start_python(h, lib, recorded, how);
}

static int wmr_ensure_python(void) {
    char name[64];
    sem_t *sem = wmr_process_lock(name, sizeof name);
    int ok = wmr_ensure_python_locked();
    if (sem) {
        sem_unlink(name); /* nothing left in /dev/shm; later loaders find the outcome, not the lock */
        sem_post(sem);
        sem_close(sem);
    }
    return ok;
}

/* The binary's finalizePythonInterpreter (see "Exit" above). */
static finalize_python_interpreter_t wmr_finalize_binary;

/* Load the binary: beside this library (`dir`), else, when the host copied this library elsewhere, in
 * <fmu>/binaries/<platform> found from the resources folder (`resources`: a file:// URI for FMI 2.0,
 * is_uri 1; a path for FMI 3.0, is_uri 0).  Returns its handle, or NULL after wmr_fail. */
static void *wmr_load_binary(const char *dir, const char *resources, int is_uri, const char *platform) {
    char path[PATH_MAX];
    if (snprintf(path, sizeof path, "%s/" WMR_REAL_BINARY, dir) >= (int)sizeof path) path[0] = '\0';
    if (!wmr_is_file(path) && resources) {
        const char *p = resources;
        if (is_uri && strncmp(p, "file://", 7) == 0) p += 7;
        if (is_uri && strncmp(p, "localhost/", 10) == 0) p += 9;
        char res[PATH_MAX];
        size_t j = 0;
        for (; *p && j + 1 < sizeof res; ++p) { /* undo a URI's %XX escapes */
            if (is_uri && p[0] == '%' && p[1] && p[2]) {
                char hex[3] = {p[1], p[2], 0};
                res[j++] = (char)strtol(hex, NULL, 16);
                p += 2;
            } else {
                res[j++] = *p;
            }
        }
        res[j] = '\0';
        while (j > 1 && res[j - 1] == '/') res[--j] = '\0';
        snprintf(path, sizeof path, "%s/../binaries/%s/%s", res, platform, WMR_REAL_BINARY);
    }
    void *real = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (real == NULL) {
        const char *e = dlerror();
        wmr_fail("cannot load pythonfmu's binary %s: %s", path, e ? e : "unknown error");
        return NULL;
    }
    *(void **)(&wmr_finalize_binary) = dlsym(real, "finalizePythonInterpreter");
    if (wmr_finalize_binary == NULL) {
        wmr_fail("%s has no function finalizePythonInterpreter (not pythonfmu 0.7 or pythonfmu3 0.3's binary)", path);
        return NULL;
    }
    return real;
}

/* Instantiations of this copy of the binary in progress, and whether the interpreter was initialised
 * before each began (see "Exit" above). */
static pthread_mutex_t wmr_instantiate_lock = PTHREAD_MUTEX_INITIALIZER;
static int wmr_instantiating = 0;
static int wmr_owned_elsewhere = 1; /* 0 once an instantiation began without an initialised interpreter */

static void wmr_instantiate_begin(void) {
    pthread_mutex_lock(&wmr_instantiate_lock);
    ++wmr_instantiating;
    if (!(wmr_py_is_initialized && wmr_py_is_initialized())) wmr_owned_elsewhere = 0;
    pthread_mutex_unlock(&wmr_instantiate_lock);
}

static void wmr_instantiate_end(void) {
    pthread_mutex_lock(&wmr_instantiate_lock);
    if (--wmr_instantiating == 0 && wmr_owned_elsewhere) wmr_finalize_binary(); /* an empty PyState: nothing to finalise */
    pthread_mutex_unlock(&wmr_instantiate_lock);
}

/* What the host holds: the binary's instance and whether it returned Fatal (see "Fatal" above). */
typedef struct {
    void *real;
    int fatal;
} wmr_instance;

static wmr_instance *wmr_wrap(void *real) {
    if (real == NULL) return NULL;
    wmr_instance *w = (wmr_instance *)calloc(1, sizeof *w);
    if (w) w->real = real;
    return w; /* NULL (out of memory): the slave is leaked, the host sees a failed instantiation */
}

#endif /* WMR_PYFINDER_H */
