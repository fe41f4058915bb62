/*
 * What the FMI 2.0 loader (wmr_pyloader.c) and the FMI 3.0 loader (wmr_pyloader3.c) share: finding or
 * starting a Python interpreter, loading pythonfmu's (or pythonfmu3's) own binary shipped beside the loader, the two guards around that binary's defects, and the
 * instance wrapper.  Built for Linux (the binary beside it is libpythonfmu-export.so) and for 64-bit
 * Windows with MinGW-w64 (pythonfmu-export.dll).
 *
 * Included once by each loader; everything here is static (each FMU's loader is a separate copy with its
 * own statics).  Needs WMR_PY_LIBRARY, WMR_PY_HOME, WMR_PY_VERSION, WMR_PY_ENV and WMR_PY_MIN_MINOR (see
 * the loaders; on Windows WMR_PY_LIBRARY and WMR_PY_HOME are not used, WMR_PY_MIN_MINOR only there).
 *
 * Interpreter on Linux (wmr_ensure_python): on the first instantiation
 *   1. an interpreter already in the process (Py_IsInitialized in the global scope: a shared libpython or
 *      a statically linked python executable) is used, whatever its version, and nothing is loaded (never
 *      two interpreters in one process);
 *   2. otherwise the library named by the environment variable WMR_PY_ENV (if set) or the libpython
 *      recorded at build time (WMR_PY_LIBRARY) is loaded with RTLD_GLOBAL so that the C extension modules
 *      of the standard library (math, _struct, ...) resolve their symbols; its standard library is found
 *      (PYTHONHOME if set, else the first of the recorded home and the folders above the library that hold
 *      lib/pythonX.Y/os.py); it is initialised without signal handlers and the GIL is released, as
 *      pythonfmu expects of an embedding host.
 * Interpreter on Windows: pythonfmu's binary imports python3.dll (Python's stable ABI), which forwards to
 * the python3X.dll of its own folder; the loader makes sure the python3.dll in the process is the one
 * beside the interpreter in use, loading it by its full path before the binary.  The interpreter:
 *   1. a python3X.dll already loaded in the process (a Python host) that exports Py_IsInitialized;
 *   2. otherwise WMR_PY_ENV, if set: the path of a python3X.dll or of the folder holding it;
 *   3. otherwise the newest 64-bit Python 3.WMR_PY_MIN_MINOR or later registered under PEP 514
 *      (HKEY_CURRENT_USER, then HKEY_LOCAL_MACHINE: Software\Python\<company>\<tag>\InstallPath, the
 *      python.org installers' key being PythonCore), PythonCore preferred between equal versions.
 *   A Python it starts finds its standard library as Python itself decides when the DLL's folder holds a
 *   python3X._pth (the embeddable distribution) or PYTHONHOME is set; otherwise the DLL's folder must hold
 *   Lib\os.py (or Lib\os.pyc) and becomes the Python home.  Initialised without signal handlers, the GIL
 *   released, as on Linux.
 * Either platform: only the standard library is needed (pythonfmu's Python part is in the FMU's resources).
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
 * interpreter was not initialised before the call (then the PyState would own it).  The Windows binaries
 * keep the same global; the same rule applies there.
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

#ifdef _WIN32
#define WIN32_LEAN_AND_MEAN
#ifndef _WIN32_WINNT
#define _WIN32_WINNT 0x0601 /* Windows 7: SRW locks, GetModuleHandleEx */
#endif
#include <windows.h>
#else
#define _GNU_SOURCE
#include <dlfcn.h>
#include <fcntl.h>
#include <limits.h>
#include <pthread.h>
#include <semaphore.h>
#include <unistd.h>
#endif
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
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
#ifndef WMR_PY_MIN_MINOR
#define WMR_PY_MIN_MINOR 11 /* the oldest Python 3 the FMUs' code runs on (Windows: the registry's choice) */
#endif
#define WMR_STATUS_FATAL 4 /* fmi2Fatal and fmi3Fatal */
#define WMR_PATH_LEN 4096

/* ---- the platform layer: libraries, locks, paths ------------------------------------------------- */
#ifdef _WIN32
typedef HMODULE wmr_lib;
typedef wchar_t wmr_char; /* paths: UTF-16, so that any user name or folder works */
typedef SRWLOCK wmr_mutex;
#define WMR_MUTEX_INITIALIZER SRWLOCK_INIT
#define WMR_REAL_BINARY L"pythonfmu-export.dll"
#define WMR_PLATFORM2 "win64"
#define WMR_PLATFORM3 "x86_64-windows"
static void wmr_lock(wmr_mutex *m) { AcquireSRWLockExclusive(m); }
static void wmr_unlock(wmr_mutex *m) { ReleaseSRWLockExclusive(m); }
static void *wmr_sym(wmr_lib h, const char *name) { return (void *)GetProcAddress(h, name); }
#else
typedef void *wmr_lib;
typedef char wmr_char;
typedef pthread_mutex_t wmr_mutex;
#define WMR_MUTEX_INITIALIZER PTHREAD_MUTEX_INITIALIZER
#define WMR_REAL_BINARY "libpythonfmu-export.so"
#define WMR_PLATFORM2 "linux64"
#define WMR_PLATFORM3 "x86_64-linux"
static void wmr_lock(wmr_mutex *m) { pthread_mutex_lock(m); }
static void wmr_unlock(wmr_mutex *m) { pthread_mutex_unlock(m); }
static void *wmr_sym(wmr_lib h, const char *name) { return dlsym(h, name); }
#endif

typedef int (*py_is_initialized_t)(void);
typedef void (*py_initialize_ex_t)(int);
typedef void *(*py_eval_save_thread_t)(void);
typedef const char *(*py_get_version_t)(void);
typedef wchar_t *(*py_decode_locale_t)(const char *, size_t *);
typedef void (*py_set_python_home_t)(const wchar_t *);
typedef void (*finalize_python_interpreter_t)(void);

static wmr_mutex wmr_load_lock = WMR_MUTEX_INITIALIZER;
static int wmr_loaded = 0;            /* 1 once Python and the binary are in place */
static char wmr_load_error[2048];     /* why loading failed (logged at every instantiation) */
static py_is_initialized_t wmr_py_is_initialized; /* of the interpreter in use */

static void wmr_fail(const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(wmr_load_error, sizeof wmr_load_error, fmt, ap);
    va_end(ap);
}

/* Start the interpreter whose C API is reachable through `h`, if it is not running: `home` (NULL: Python
 * finds its own) becomes its home.  Returns 0 after wmr_fail. */
static int wmr_initialize(wmr_lib h, const char *where, const char *how, const wchar_t *home) {
    py_initialize_ex_t init_ex = (py_initialize_ex_t)wmr_sym(h, "Py_InitializeEx");
    py_eval_save_thread_t save_thread = (py_eval_save_thread_t)wmr_sym(h, "PyEval_SaveThread");
    py_set_python_home_t set_home = (py_set_python_home_t)wmr_sym(h, "Py_SetPythonHome");
    if (!init_ex || !save_thread) {
        wmr_fail("%s (%s) is not a Python 3 library (Py_InitializeEx not found)", where, how);
        return 0;
    }
    if (home && set_home) set_home(home); /* kept by the caller: Python reads it during and after start-up */
    init_ex(0);     /* no signal handlers: the host owns them */
    save_thread();  /* release the GIL; pythonfmu takes it with PyGILState_Ensure on every call */
    return 1;
}

#ifdef _WIN32
/* ---- Windows: finding Python ----------------------------------------------------------------------- */

static void wmr_utf8(const wchar_t *w, char *out, size_t n) {
    if (WideCharToMultiByte(CP_UTF8, 0, w, -1, out, (int)n, NULL, NULL) == 0) snprintf(out, n, "?");
}

static int wmr_is_file(const wchar_t *path) {
    DWORD a = GetFileAttributesW(path);
    return a != INVALID_FILE_ATTRIBUTES && !(a & FILE_ATTRIBUTE_DIRECTORY);
}

static int wmr_is_dir(const wchar_t *path) {
    DWORD a = GetFileAttributesW(path);
    return a != INVALID_FILE_ATTRIBUTES && (a & FILE_ATTRIBUTE_DIRECTORY);
}

/* dst = a + b (b may be empty); 0 if it does not fit. */
static int wmr_join(wchar_t *dst, size_t n, const wchar_t *a, const wchar_t *b) {
    size_t la = wcslen(a), lb = wcslen(b);
    int sep = la > 0 && lb > 0 && a[la - 1] != L'\\' && a[la - 1] != L'/';
    if (la + (size_t)sep + lb + 1 > n) return 0;
    memcpy(dst, a, la * sizeof(wchar_t));
    if (sep) dst[la++] = L'\\';
    memcpy(dst + la, b, (lb + 1) * sizeof(wchar_t));
    return 1;
}

/* The folder part of `path` (no trailing backslash), in place. */
static void wmr_strip_file(wchar_t *path) {
    wchar_t *s = wcsrchr(path, L'\\'), *f = wcsrchr(path, L'/');
    if (f > s) s = f;
    if (s) *s = L'\0';
}

/* The message text of a Windows error code. */
static void wmr_win_error(DWORD code, char *out, size_t n) {
    wchar_t w[512];
    if (FormatMessageW(FORMAT_MESSAGE_FROM_SYSTEM | FORMAT_MESSAGE_IGNORE_INSERTS, NULL, code, 0, w, 512, NULL) == 0)
        _snwprintf(w, 512, L"error %lu", (unsigned long)code);
    w[511] = L'\0';
    for (size_t k = wcslen(w); k > 0 && (w[k - 1] == L'\n' || w[k - 1] == L'\r' || w[k - 1] == L'.'); --k) w[k - 1] = 0;
    wmr_utf8(w, out, n);
}

/* The folder and file name (without .dll) of this library. */
static void wmr_self_path(wchar_t *dir, size_t ndir, char *model, size_t nmodel) {
    HMODULE self = NULL;
    dir[0] = L'\0';
    model[0] = '\0';
    if (!GetModuleHandleExW(GET_MODULE_HANDLE_EX_FLAG_FROM_ADDRESS | GET_MODULE_HANDLE_EX_FLAG_UNCHANGED_REFCOUNT,
                            (LPCWSTR)(void *)&wmr_self_path, &self))
        return;
    wchar_t path[WMR_PATH_LEN];
    DWORD len = GetModuleFileNameW(self, path, WMR_PATH_LEN);
    if (len == 0 || len >= WMR_PATH_LEN) return;
    wchar_t *base = wcsrchr(path, L'\\');
    base = base ? base + 1 : path;
    wmr_utf8(base, model, nmodel);
    char *dot = strrchr(model, '.');
    if (dot) *dot = '\0';
    if (base > path) {
        base[-1] = L'\0';
        wmr_join(dir, ndir, path, L"");
    }
}

/* Load the library at `path` (a full path); its own dependencies are searched in its folder first. */
static HMODULE wmr_load_full(const wchar_t *path) { return LoadLibraryExW(path, NULL, LOAD_WITH_ALTERED_SEARCH_PATH); }

/* python3X.dll of Python 3.`minor` in `dir` (0 if absent). */
static int wmr_python_dll(const wchar_t *dir, int minor, wchar_t *dll, size_t n) {
    wchar_t name[32];
    _snwprintf(name, 32, L"python3%d.dll", minor);
    name[31] = 0;
    return wmr_join(dll, n, dir, name) && wmr_is_file(dll);
}

/* The newest python3X.dll (X >= WMR_PY_MIN_MINOR) in `dir`: its minor version, or -1. */
static int wmr_newest_in(const wchar_t *dir, wchar_t *dll, size_t n) {
    for (int minor = 40; minor >= WMR_PY_MIN_MINOR; --minor)
        if (wmr_python_dll(dir, minor, dll, n)) return minor;
    return -1;
}

/* A registry string value as UTF-16 (0 if absent). */
static int wmr_reg_string(HKEY key, const wchar_t *sub, const wchar_t *name, wchar_t *out, DWORD n) {
    DWORD bytes = n * sizeof(wchar_t);
    if (RegGetValueW(key, sub, name, RRF_RT_REG_SZ, NULL, out, &bytes) != ERROR_SUCCESS) return 0;
    out[n - 1] = L'\0';
    return 1;
}

/* The newest 64-bit Python 3 registered under PEP 514 with its python3X.dll present: the DLL's path and
 * its minor version (-1 if none).  `seen` lists what was found (for the message when nothing fits). */
static int wmr_registered_python(wchar_t *dll, size_t n, char *seen, size_t nseen) {
    static const HKEY roots[] = {HKEY_CURRENT_USER, HKEY_LOCAL_MACHINE};
    int best = -1, best_core = 0;
    seen[0] = '\0';
    for (size_t r = 0; r < sizeof roots / sizeof roots[0]; ++r) {
        HKEY python;
        if (RegOpenKeyExW(roots[r], L"Software\\Python", 0, KEY_READ | KEY_WOW64_64KEY, &python) != ERROR_SUCCESS)
            continue;
        wchar_t company[256];
        for (DWORD c = 0;; ++c) {
            DWORD nc = 256;
            if (RegEnumKeyExW(python, c, company, &nc, NULL, NULL, NULL, NULL) != ERROR_SUCCESS) break;
            if (_wcsicmp(company, L"PyLauncher") == 0) continue;
            int core = _wcsicmp(company, L"PythonCore") == 0;
            HKEY ck;
            if (RegOpenKeyExW(python, company, 0, KEY_READ | KEY_WOW64_64KEY, &ck) != ERROR_SUCCESS) continue;
            wchar_t tag[256];
            for (DWORD t = 0;; ++t) {
                DWORD nt = 256;
                if (RegEnumKeyExW(ck, t, tag, &nt, NULL, NULL, NULL, NULL) != ERROR_SUCCESS) break;
                wchar_t version[64], arch[64], install[WMR_PATH_LEN], sub[300];
                if (!wmr_reg_string(ck, tag, L"SysVersion", version, 64)) {
                    if (!core) continue; /* PEP 514: only PythonCore's tags are versions */
                    wmr_join(version, 64, tag, L"");
                }
                if (wmr_reg_string(ck, tag, L"SysArchitecture", arch, 64) && wcscmp(arch, L"64bit") != 0) continue;
                if (core && (wcsstr(tag, L"-32") || wcsstr(tag, L"-arm"))) continue;
                _snwprintf(sub, 300, L"%ls\\InstallPath", tag);
                sub[299] = 0;
                if (!wmr_reg_string(ck, sub, NULL, install, WMR_PATH_LEN)) continue;
                int major = 0, minor = -1;
                if (swscanf(version, L"%d.%d", &major, &minor) != 2 || major != 3) continue;
                if (wcslen(version) > 0 && version[wcslen(version) - 1] == L't') continue; /* free-threaded build */
                char u8[300], line[400];
                wmr_utf8(install, u8, sizeof u8);
                snprintf(line, sizeof line, "%s3.%d at %s", seen[0] ? "; " : "", minor, u8);
                strncat(seen, line, nseen - strlen(seen) - 1);
                wchar_t candidate[WMR_PATH_LEN];
                if (minor < WMR_PY_MIN_MINOR || !wmr_python_dll(install, minor, candidate, WMR_PATH_LEN)) continue;
                if (minor > best || (minor == best && core && !best_core)) {
                    best = minor;
                    best_core = core;
                    wmr_join(dll, n, candidate, L"");
                }
            }
            RegCloseKey(ck);
        }
        RegCloseKey(python);
    }
    return best;
}

/* Make python3.dll in the process the one in `dir` (pythonfmu's binary imports it by name). */
static int wmr_stable_abi(const wchar_t *dir, const char *where, const char *how) {
    wchar_t want[WMR_PATH_LEN];
    if (!wmr_join(want, WMR_PATH_LEN, dir, L"python3.dll") || !wmr_is_file(want)) {
        wmr_fail("%s (%s) has no python3.dll beside it (Python's stable ABI, which pythonfmu's binary imports)",
                 where, how);
        return 0;
    }
    HMODULE loaded = GetModuleHandleW(L"python3.dll");
    if (loaded) {
        wchar_t have[WMR_PATH_LEN];
        DWORD len = GetModuleFileNameW(loaded, have, WMR_PATH_LEN);
        if (len > 0 && len < WMR_PATH_LEN && _wcsicmp(have, want) != 0) {
            char a[WMR_PATH_LEN], b[WMR_PATH_LEN];
            wmr_utf8(have, a, sizeof a);
            wmr_utf8(want, b, sizeof b);
            wmr_fail("the process already has %s loaded, not %s of the Python in use (%s, %s): two Pythons in "
                     "one process", a, b, where, how);
            return 0;
        }
        return 1;
    }
    if (wmr_load_full(want) == NULL) {
        char a[WMR_PATH_LEN], e[512];
        wmr_utf8(want, a, sizeof a);
        wmr_win_error(GetLastError(), e, sizeof e);
        wmr_fail("cannot load %s (%s): %s", a, how, e);
        return 0;
    }
    return 1;
}

/* Start the interpreter of the python3X.dll `h` at `dll`: its home as the rules above say. */
static int wmr_start_python(HMODULE h, const wchar_t *dll, const char *where, const char *how) {
    py_is_initialized_t is_init = (py_is_initialized_t)wmr_sym(h, "Py_IsInitialized");
    if (is_init == NULL) {
        wmr_fail("%s (%s) is not a Python 3 library (Py_IsInitialized not found)", where, how);
        return 0;
    }
    wmr_py_is_initialized = is_init;
    if (is_init()) return 1;
    static wchar_t home[WMR_PATH_LEN]; /* kept: Python reads its home during and after start-up */
    wchar_t pth[WMR_PATH_LEN], probe[WMR_PATH_LEN];
    wmr_join(home, WMR_PATH_LEN, dll, L"");
    wmr_strip_file(home);
    wmr_join(pth, WMR_PATH_LEN, dll, L"");
    wchar_t *dot = wcsrchr(pth, L'.');
    if (dot) *dot = L'\0';
    size_t lp = wcslen(pth);
    if (lp + 6 < WMR_PATH_LEN) wcscpy(pth + lp, L"._pth");
    wchar_t env[8];
    if (wmr_is_file(pth) || GetEnvironmentVariableW(L"PYTHONHOME", env, 8) > 0)
        return wmr_initialize(h, where, how, NULL); /* the ._pth file, or PYTHONHOME, says where */
    if (!(wmr_join(probe, WMR_PATH_LEN, home, L"Lib\\os.py") && wmr_is_file(probe)) &&
        !(wmr_join(probe, WMR_PATH_LEN, home, L"Lib\\os.pyc") && wmr_is_file(probe))) {
        wmr_fail("found no standard library (Lib\\os.py) beside %s (%s); set PYTHONHOME to that Python's folder",
                 where, how);
        return 0;
    }
    return wmr_initialize(h, where, how, home);
}

/* A named mutex private to the process serialises starting the interpreter across all our FMUs. */
static HANDLE wmr_process_lock(void) {
    wchar_t name[64];
    _snwprintf(name, 64, L"Local\\wmr-pyloader-%lu", (unsigned long)GetCurrentProcessId());
    name[63] = 0;
    HANDLE m = CreateMutexW(NULL, FALSE, name);
    if (m) WaitForSingleObject(m, INFINITE);
    return m; /* NULL: the per-FMU lock alone */
}

static int wmr_use_python(HMODULE h, const wchar_t *dll, const char *how) {
    char where[WMR_PATH_LEN];
    wchar_t dir[WMR_PATH_LEN];
    wmr_utf8(dll, where, sizeof where);
    wmr_join(dir, WMR_PATH_LEN, dll, L"");
    wmr_strip_file(dir);
    return wmr_stable_abi(dir, where, how) && wmr_start_python(h, dll, where, how);
}

static int wmr_ensure_python_locked(void) {
    wchar_t dll[WMR_PATH_LEN];
    /* 1. a Python already in the process (a Python host, or one started by another FMU) */
    for (int minor = 40; minor >= 0; --minor) {
        wchar_t name[32];
        _snwprintf(name, 32, L"python3%d.dll", minor);
        name[31] = 0;
        HMODULE h = GetModuleHandleW(name);
        if (h && GetProcAddress(h, "Py_IsInitialized")) {
            DWORD len = GetModuleFileNameW(h, dll, WMR_PATH_LEN);
            if (len == 0 || len >= WMR_PATH_LEN) continue;
            return wmr_use_python(h, dll, "already loaded in the process");
        }
    }
    /* 2. the Python the user chose */
    wchar_t env[WMR_PATH_LEN], how_w[64];
    char how[WMR_PATH_LEN + 64];
    MultiByteToWideChar(CP_UTF8, 0, WMR_PY_ENV, -1, how_w, 64);
    DWORD ne = GetEnvironmentVariableW(how_w, env, WMR_PATH_LEN);
    if (ne > 0 && ne < WMR_PATH_LEN) {
        char u8[WMR_PATH_LEN];
        wmr_utf8(env, u8, sizeof u8);
        snprintf(how, sizeof how, "given by %s", WMR_PY_ENV);
        if (wmr_is_dir(env)) {
            if (wmr_newest_in(env, dll, WMR_PATH_LEN) < 0) {
                wmr_fail("%s=%s: that folder holds no python3X.dll of Python 3.%d or later", WMR_PY_ENV, u8,
                         WMR_PY_MIN_MINOR);
                return 0;
            }
        } else if (!wmr_is_file(env)) {
            wmr_fail("%s=%s: no such file or folder (give the path of a python3X.dll or of its folder)", WMR_PY_ENV, u8);
            return 0;
        } else {
            wmr_join(dll, WMR_PATH_LEN, env, L"");
        }
    } else {
        /* 3. the newest one registered */
        char seen[1024];
        if (wmr_registered_python(dll, WMR_PATH_LEN, seen, sizeof seen) < 0) {
            wmr_fail("no Python in the process, %s not set, and no 64-bit Python 3.%d or later registered "
                     "(Software\\Python in HKEY_CURRENT_USER or HKEY_LOCAL_MACHINE%s%s%s): install one from "
                     "python.org, or set %s to the path of a python3X.dll", WMR_PY_ENV, WMR_PY_MIN_MINOR,
                     seen[0] ? "; found " : "", seen, seen[0] ? "" : ": none", WMR_PY_ENV);
            return 0;
        }
        snprintf(how, sizeof how, "the newest 64-bit Python 3 registered");
    }
    HMODULE h = wmr_load_full(dll);
    if (h == NULL) {
        char u8[WMR_PATH_LEN], e[512];
        wmr_utf8(dll, u8, sizeof u8);
        wmr_win_error(GetLastError(), e, sizeof e);
        wmr_fail("cannot load %s (%s): %s", u8, how, e);
        return 0;
    }
    return wmr_use_python(h, dll, how);
}

static int wmr_ensure_python(void) {
    HANDLE m = wmr_process_lock();
    int ok = wmr_ensure_python_locked();
    if (m) {
        ReleaseMutex(m);
        CloseHandle(m);
    }
    return ok;
}

/* What pythonfmu's binary imports besides python3.dll and Windows itself: the Visual C++ runtime (FMI 2.0;
 * pythonfmu3's binary links it statically).  Named in the message when one of them is missing. */
static void wmr_missing_runtime(char *out, size_t n) {
    static const wchar_t *names[] = {L"MSVCP140.dll", L"VCRUNTIME140.dll", L"VCRUNTIME140_1.dll"};
    out[0] = '\0';
    for (size_t k = 0; k < sizeof names / sizeof names[0]; ++k) {
        HMODULE m = LoadLibraryExW(names[k], NULL, 0);
        if (m) {
            FreeLibrary(m);
            continue;
        }
        char u8[64];
        wmr_utf8(names[k], u8, sizeof u8);
        strncat(out, out[0] ? ", " : "", n - strlen(out) - 1);
        strncat(out, u8, n - strlen(out) - 1);
    }
}
#else
/* ---- Linux: finding Python ------------------------------------------------------------------------- */

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

/* "3.11" from Py_GetVersion's "3.11.7 (main, ...)". */
static void wmr_short_version(const char *v, char *out, size_t n) {
    size_t k = strspn(v, "0123456789");
    if (v[k] == '.') k += 1 + strspn(v + k + 1, "0123456789");
    snprintf(out, n, "%.*s", (int)(k < n - 1 ? k : n - 1), v);
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
    py_get_version_t get_version = (py_get_version_t)dlsym(h, "Py_GetVersion");
    py_decode_locale_t decode = (py_decode_locale_t)dlsym(h, "Py_DecodeLocale");
    if (!is_init || !get_version || !dlsym(h, "Py_InitializeEx")) {
        wmr_fail("%s (%s) is not a Python 3 library (Py_InitializeEx not found)", lib, how);
        return 0;
    }
    wmr_py_is_initialized = is_init;
    if (is_init()) return 1;
    char version[16];
    wmr_short_version(get_version(), version, sizeof version);
    const char *env_home = getenv("PYTHONHOME");
    char home[PATH_MAX];
    if (env_home && env_home[0]) {
        snprintf(home, sizeof home, "%.*s", (int)strcspn(env_home, ":"), env_home);
        if (!wmr_has_stdlib(home, version)) {
            wmr_fail("PYTHONHOME=%s holds no standard library of Python %s (lib/python%s/os.py) for %s (%s); "
                     "unset PYTHONHOME or point it at that Python's prefix", env_home, version, version, lib, how);
            return 0;
        }
        return wmr_initialize(h, lib, how, NULL);
    }
    if (!wmr_find_home(lib, version, recorded, home, sizeof home)) {
        wmr_fail("found no standard library of Python %s (lib/python%s/os.py) near %s (%s); "
                 "set PYTHONHOME to that Python's prefix", version, version, lib, how);
        return 0;
    }
    wchar_t *w = decode ? decode(home, NULL) : NULL; /* kept: Python reads it during and after start-up */
    return wmr_initialize(h, lib, how, w);
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

#endif

/* ---- both platforms: the binary, the exit and Fatal guards ----------------------------------------- */

/* The folder of a resource location (FMI 2.0: a file:// URI, is_uri 1, with %XX escapes; FMI 3.0: a
 * path) into `res` (UTF-8), with the platform's separator and no trailing one; file:///C:/... gives C:\... */
static void wmr_resource_dir(const char *resources, int is_uri, char *res, size_t n) {
#ifdef _WIN32
    const char sep = '\\';
#else
    const char sep = '/';
#endif
    const char *p = resources;
    if (is_uri && strncmp(p, "file://", 7) == 0) p += 7;
    if (is_uri && strncmp(p, "localhost/", 10) == 0) p += 9;
#ifdef _WIN32
    if (is_uri && p[0] == '/' && p[1] && p[2] == ':') ++p; /* file:///C:/... */
#endif
    size_t j = 0;
    for (; *p && j + 1 < n; ++p) { /* undo a URI's %XX escapes */
        if (is_uri && p[0] == '%' && p[1] && p[2]) {
            char hex[3] = {p[1], p[2], 0};
            res[j++] = (char)strtol(hex, NULL, 16);
            p += 2;
        } else {
            res[j++] = *p == '/' ? sep : *p;
        }
    }
    res[j] = '\0';
    while (j > 1 && res[j - 1] == sep) res[--j] = '\0';
}

/* The binary's finalizePythonInterpreter (see "Exit" above). */
static finalize_python_interpreter_t wmr_finalize_binary;

/* Load the binary: beside this library (`dir`), else, when the host copied this library elsewhere, in
 * <fmu>/binaries/<platform> found from the resources folder (`resources`: a file:// URI for FMI 2.0,
 * is_uri 1; a path for FMI 3.0, is_uri 0).  Returns its handle, or NULL after wmr_fail. */
static wmr_lib wmr_load_binary(const wmr_char *dir, const char *resources, int is_uri, const char *platform) {
#ifdef _WIN32
    wchar_t path[WMR_PATH_LEN], res[WMR_PATH_LEN], plat[64], rel[128];
    char res8[WMR_PATH_LEN];
    if (!wmr_join(path, WMR_PATH_LEN, dir, WMR_REAL_BINARY)) path[0] = L'\0';
    if (!wmr_is_file(path) && resources) {
        wmr_resource_dir(resources, is_uri, res8, sizeof res8);
        MultiByteToWideChar(CP_UTF8, 0, res8, -1, res, WMR_PATH_LEN);
        MultiByteToWideChar(CP_UTF8, 0, platform, -1, plat, 64);
        _snwprintf(rel, 128, L"..\\binaries\\%ls\\%ls", plat, WMR_REAL_BINARY);
        rel[127] = 0;
        wmr_join(path, WMR_PATH_LEN, res, rel);
    }
    HMODULE real = wmr_load_full(path);
    if (real == NULL) {
        DWORD code = GetLastError();
        char u8[WMR_PATH_LEN], e[512], missing[128];
        wmr_utf8(path, u8, sizeof u8);
        wmr_win_error(code, e, sizeof e);
        wmr_missing_runtime(missing, sizeof missing);
        if (missing[0])
            wmr_fail("cannot load pythonfmu's binary %s: %s; it needs Microsoft's Visual C++ runtime, of which %s "
                     "is not found: install the Visual C++ Redistributable for Visual Studio 2015-2022 (x64)",
                     u8, e, missing);
        else
            wmr_fail("cannot load pythonfmu's binary %s: %s", u8, e);
        return NULL;
    }
    char where[WMR_PATH_LEN];
    wmr_utf8(path, where, sizeof where);
#else
    char path[PATH_MAX];
    if (snprintf(path, sizeof path, "%s/" WMR_REAL_BINARY, dir) >= (int)sizeof path) path[0] = '\0';
    char res[PATH_MAX];
    if (!wmr_is_file(path) && resources) {
        wmr_resource_dir(resources, is_uri, res, sizeof res);
        snprintf(path, sizeof path, "%s/../binaries/%s/%s", res, platform, WMR_REAL_BINARY);
    }
    void *real = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (real == NULL) {
        const char *e = dlerror();
        wmr_fail("cannot load pythonfmu's binary %s: %s", path, e ? e : "unknown error");
        return NULL;
    }
    const char *where = path;
#endif
    *(void **)(&wmr_finalize_binary) = wmr_sym(real, "finalizePythonInterpreter");
    if (wmr_finalize_binary == NULL) {
        wmr_fail("%s has no function finalizePythonInterpreter (not pythonfmu 0.7 or pythonfmu3 0.3's binary)", where);
        return NULL;
    }
    return real;
}

/* Instantiations of this copy of the binary in progress, and whether the interpreter was initialised
 * before each began (see "Exit" above). */
static wmr_mutex wmr_instantiate_lock = WMR_MUTEX_INITIALIZER;
static int wmr_instantiating = 0;
static int wmr_owned_elsewhere = 1; /* 0 once an instantiation began without an initialised interpreter */

static void wmr_instantiate_begin(void) {
    wmr_lock(&wmr_instantiate_lock);
    ++wmr_instantiating;
    if (!(wmr_py_is_initialized && wmr_py_is_initialized())) wmr_owned_elsewhere = 0;
    wmr_unlock(&wmr_instantiate_lock);
}

static void wmr_instantiate_end(void) {
    wmr_lock(&wmr_instantiate_lock);
    if (--wmr_instantiating == 0 && wmr_owned_elsewhere) wmr_finalize_binary(); /* an empty PyState: nothing to finalise */
    wmr_unlock(&wmr_instantiate_lock);
}

/* What the host holds: the binary's instance, whether it returned Fatal (see "Fatal" above), and (FMI 3.0
 * co-simulation, wmr_pyloader3.c) whether it was instantiated with eventModeUsed. */
typedef struct {
    void *real;
    int fatal;
    int event_mode;
} wmr_instance;

static inline wmr_instance *wmr_wrap(void *real) { /* (the FMI 2.0 loader wraps in a larger struct of its own) */
    if (real == NULL) return NULL;
    wmr_instance *w = (wmr_instance *)calloc(1, sizeof *w);
    if (w) w->real = real;
    return w; /* NULL (out of memory): the slave is leaked, the host sees a failed instantiation */
}

/* Find Python and load the binary once per copy (`load_real`: the loader's own resolver of the binary's
 * FMI functions); 1 when both are in place.  Otherwise `model` and wmr_load_error say why. */
static int wmr_ready(int (*load_real)(const wmr_char *, const char *), const char *resources, char *model,
                     size_t nmodel) {
    wmr_char dir[WMR_PATH_LEN];
    wmr_self_path(dir, WMR_PATH_LEN, model, nmodel);
    wmr_lock(&wmr_load_lock);
    if (!wmr_loaded && wmr_load_error[0] == '\0') {
        if (wmr_ensure_python() && load_real(dir, resources)) wmr_loaded = 1;
    }
    wmr_unlock(&wmr_load_lock);
    return wmr_loaded;
}

#endif /* WMR_PYFINDER_H */
