/* A system of FMUs as one FMI 2.0 co-simulation FMU (cosim/plan/container.py writes it): the runtime of the
 * container, the master's own compiled loop (native_loop.c, included below, the same source the master
 * runs) given the system as data.  The exporter writes that data into resources/system.txt: each inner
 * FMU's folder (unpacked under resources/), its parameters and start values, the values it sets and reads
 * each step, the copies with their factor and offset (the unit conversion folded in, as the master's
 * wiring gives them), and the container's variables (recorded outputs read from the row, open inputs and
 * parameters passed to their inner FMU).
 *
 * Life cycle, as the master's start-up: every inner FMU instantiated at fmi2Instantiate; at
 * fmi2EnterInitializationMode, each one set up (fmi2SetupExperiment), given its parameters and start values
 * (a value the host set replacing the scenario's), then each one in initialisation mode; at
 * fmi2ExitInitializationMode, outputs copied to inputs in the plan's order pass after pass until nothing
 * changes, each one out of initialisation mode, their outputs read; fmi2DoStep(t, n h) = wmr_loop over the
 * n steps of the grid from k = (t - t0) / h (the time of step k is t0 + k h, as the master's).
 * Inner FMI 3.0 FMUs and the connections that are not Float64 to Float64: container_inner3.c, included below.
 * A Model Exchange instance is integrated by the master's integrators with its event handling
 * (container_me.c, included below).
 * Numbers in system.txt are C99 hexadecimal floats (exact); strings are "x" followed by their bytes in hex. */
#ifdef _WIN32
/* win64 (MinGW-w64): the inner FMUs' DLLs by LoadLibrary; the loop's wall clock by the performance counter
 * (native_loop.c's clock_gettime is in winpthreads, which a DLL of KERNEL32 and msvcrt alone does not have) */
#include <windows.h>
#include <time.h>
static int wmr_clock_gettime(struct timespec *ts) {
    LARGE_INTEGER n, f;
    QueryPerformanceCounter(&n); QueryPerformanceFrequency(&f);
    ts->tv_sec = (time_t)(n.QuadPart / f.QuadPart);
    ts->tv_nsec = (long)((n.QuadPart % f.QuadPart) * 1000000000LL / f.QuadPart);
    return 0;
}
#define clock_gettime(id, ts) wmr_clock_gettime(ts)
#define PLATFORM "win64"
#define LIB_EXT "dll"
#else
#include <dlfcn.h>
#define PLATFORM "linux64"
#define LIB_EXT "so"
#endif
#include "native_loop.c"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>

typedef void *fmi2Component;
typedef void *fmi2ComponentEnvironment;
typedef void *fmi2FMUstate;
typedef unsigned int fmi2ValueReference;
typedef double fmi2Real;
typedef int fmi2Integer;
typedef int fmi2Boolean;
typedef char fmi2Char;
typedef const fmi2Char *fmi2String;
typedef char fmi2Byte;
typedef enum { fmi2OK, fmi2Warning, fmi2Discard, fmi2Error, fmi2Fatal, fmi2Pending } fmi2Status;
typedef enum { fmi2ModelExchange, fmi2CoSimulation } fmi2Type;
typedef enum { fmi2DoStepStatus, fmi2PendingStatus, fmi2LastSuccessfulTime, fmi2Terminated } fmi2StatusKind;
typedef struct {
    void (*logger)(fmi2ComponentEnvironment, fmi2String, fmi2Status, fmi2String, fmi2String, ...);
    void *(*allocateMemory)(size_t, size_t);
    void (*freeMemory)(void *);
    void (*stepFinished)(fmi2ComponentEnvironment, fmi2Status);
    fmi2ComponentEnvironment componentEnvironment;
} fmi2CallbackFunctions;

typedef fmi2Component (*inst_t)(fmi2String, fmi2Type, fmi2String, fmi2String, const fmi2CallbackFunctions *,
                                fmi2Boolean, fmi2Boolean);
typedef void (*free_t)(fmi2Component);
typedef fmi2Status (*setup_t)(fmi2Component, fmi2Boolean, fmi2Real, fmi2Real, fmi2Boolean, fmi2Real);
typedef fmi2Status (*mode_t_)(fmi2Component);
typedef fmi2Status (*seti_t)(fmi2Component, const fmi2ValueReference *, size_t, const fmi2Integer *);
typedef fmi2Status (*geti_t)(fmi2Component, const fmi2ValueReference *, size_t, fmi2Integer *);
typedef fmi2Status (*sets_t)(fmi2Component, const fmi2ValueReference *, size_t, const fmi2String *);

#define VERSION_TAG "wmr-container 7"

/* (type T: a value of another FMI 3.0 type, typed: container_inner3.c) */
typedef struct { char type; unsigned vr; double r; int i; char *s; int var; void *typed; } Param;

typedef struct {
    char *name, *dir, *mi, *guid;
    int tol_defined; double tol;
    void *dll; fmi2Component c;
    inst_t instantiate; free_t free_instance; setup_t setup; mode_t_ enter, exit_, terminate;
    set2_t set_real; seti_t set_integer, set_boolean; sets_t set_string; geti_t get_integer, get_boolean;
    int n_params; Param *params;
    size_t n_out;   /* its Real outputs (Inst.n_out is 0 in the loop where they are read lazily) */
    int lazy;       /* its outputs feed no copy: read when the host asks for them, not after every step */
    struct MeInst *me;   /* run as Model Exchange: its integrator and events (container_me.c); else NULL */
} Inner;

/* ------------------------------------------------------------------ reading system.txt */
typedef struct { char *text, *at; int bad; } Reader;

static char *token(Reader *r) {
    char *p = r->at, *t;
    while (*p == ' ' || *p == '\n' || *p == '\t' || *p == '\r') p++;
    if (!*p) { r->bad = 1; return ""; }
    t = p;
    while (*p && *p != ' ' && *p != '\n' && *p != '\t' && *p != '\r') p++;
    if (*p) *p++ = 0;
    r->at = p;
    return t;
}
static long num(Reader *r) { char *e, *t = token(r); long v = strtol(t, &e, 10); if (*e) r->bad = 1; return v; }
static double real(Reader *r) { char *e, *t = token(r); double v = strtod(t, &e); if (*e) r->bad = 1; return v; }
static char *text(Reader *r) {
    char *t = token(r), *out;
    size_t n, j;
    if (t[0] != 'x') { r->bad = 1; return NULL; }
    n = (strlen(t) - 1) / 2;
    out = calloc(n + 1, 1);
    for (j = 0; out && j < n; j++) { unsigned v; sscanf(t + 1 + 2 * j, "%2x", &v); out[j] = (char)v; }
    return out;
}
static void expect(Reader *r, const char *word) { if (strcmp(token(r), word)) r->bad = 1; }

#include "container_actions.c"

/* a variable of the container: kind 'o' (a recorded output), 'i' (an open input) or 'p' (a parameter); type
 * 'R', 'I' or 'B' (Real, Integer, Boolean); an Integer's or a Boolean's value held exactly as a double */
typedef struct { char kind, type; int inst; unsigned ref; double value; int tunable; int set; } Var;

typedef struct {
    const fmi2CallbackFunctions *cb;
    char *name;
    int n; Inner *inner; Inst *insts; Loop L;
    double *row; long n_row;
    int n_vars; Var *vars;
    int n_others; struct Other *others;   /* the connections that are not Float64 to Float64 */
    double step; int mode;   /* 0 instantiated, 1 initialisation mode, 2 stepping, 3 terminated */
    double t0; int stop_defined; double stop;
    int stale;      /* the lazy instances' outputs in the row are older than their last step */
    Actions act;    /* timed events and input tables (container_actions.c) */
    struct Iter *iter;       /* the iterated coupling (container_iter.c); NULL under Gauss-Seidel and Jacobi */
    int terminated; double last_successful;   /* an inner FMU ended the simulation: the time of the last row [s] */
} Container;

static void say(Container *s, fmi2Status st, const char *fmt, ...) {
    char msg[1024];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    if (s && s->cb && s->cb->logger)
        s->cb->logger(s->cb->componentEnvironment, s->name, st, st == fmi2OK ? "logEvents" : "logStatusError", "%s", msg);
}

#ifdef _WIN32
#define LOOKUP(dll, sym) GetProcAddress((HMODULE)(dll), sym)
#define UNLOAD(dll) FreeLibrary((HMODULE)(dll))
#else
#define LOOKUP(dll, sym) dlsym(dll, sym)
#define UNLOAD(dll) dlclose(dll)
#endif
#include "container_inner3.c"   /* inner FMI 3.0 FMUs, the other connections */

static int me_read(Container *s, Reader *r, int i);   /* (container_me.c) */
#include "container_iter.c"

static int read_instance(Container *s, Reader *r, int i) {
    Inner *q = &s->inner[i];
    Inst *p = &s->insts[i];
    long j, off, nc, no, me;
    expect(r, "inst");
    q->name = text(r); q->dir = text(r); q->mi = text(r); q->guid = text(r);
    q->tol_defined = (int)num(r); q->tol = real(r);
    p->raw_set = p->raw_step = p->raw_get = 1; p->no_set_prior = 1;
    p->n_in = (size_t)num(r); p->n_out = (size_t)num(r); off = num(r); nc = num(r); q->n_params = (int)num(r);
    p->dec = num(r);   /* its decimation: it steps every dec base steps (Loop.multirate), as native.py sets it */
    /* its FMI version, its count of Float64 values set and got (an FMI 3.0 array's elements each), its other
     * connections, whether it runs as Model Exchange (its "me" line follows its other connections) */
    p->abi = (int)num(r); p->n_in_values = (size_t)num(r); p->n_out_values = (size_t)num(r); no = num(r); me = num(r);
    if (r->bad || p->dec < 1 || off < 0 || off + (long)p->n_out_values > s->n_row || nc < 0 || q->n_params < 0 ||
        (p->abi != 2 && p->abi != 3) || p->n_in_values < p->n_in || p->n_out_values < p->n_out || no < 0 ||
        (me && p->abi != 2)) return 0;
    p->in_vr = calloc(p->n_in + 1, sizeof(unsigned)); p->in_val = calloc(p->n_in_values + 1, sizeof(double));
    p->out_vr = calloc(p->n_out + 1, sizeof(unsigned)); p->out_val = s->row + off;
    for (j = 0; j < (long)p->n_in; j++) p->in_vr[j] = (unsigned)num(r);
    for (j = 0; j < (long)p->n_out; j++) p->out_vr[j] = (unsigned)num(r);
    p->n_copies = (int)nc;
    p->pos = calloc((size_t)nc + 1, sizeof(int)); p->src = calloc((size_t)nc + 1, sizeof(double *));
    p->slot = calloc((size_t)nc + 1, sizeof(long)); p->factor = calloc((size_t)nc + 1, sizeof(double));
    p->offset = calloc((size_t)nc + 1, sizeof(double)); p->plain = calloc((size_t)nc + 1, sizeof(int));
    for (j = 0; j < nc; j++) {
        expect(r, "copy");
        p->pos[j] = (int)num(r); p->src[j] = s->row; p->slot[j] = num(r);
        p->factor[j] = real(r); p->offset[j] = real(r);
        p->plain[j] = p->factor[j] == 1.0 && p->offset[j] == 0.0;
        if (p->pos[j] < 0 || (size_t)p->pos[j] >= p->n_in_values || p->slot[j] < 0 || p->slot[j] >= s->n_row) r->bad = 1;
    }
    q->params = calloc((size_t)q->n_params + 1, sizeof(Param));
    for (j = 0; j < q->n_params; j++) {
        Param *a = &q->params[j];
        expect(r, "param");
        read_param(r, a);
        a->var = (int)num(r);   /* (the container's variable of that name, -1: none) */
    }
    p->other = &OTHERS[s->n_others]; p->n_other = (int)no;   /* (the loop calls them after the set) */
    for (j = 0; j < no && !r->bad; j++) if (!read_other(s, r, i)) r->bad = 1;
    if (me && !r->bad && !me_read(s, r, i)) return 0;
    return !r->bad;
}

/* An instance whose Real outputs feed no copy, at one rate (every instance steps every base step), has its
 * outputs read when the host asks for them (or before a value the host sets reaches an inner FMU) rather than
 * after each of its steps: the same values, since nothing is set or stepped in that instance between the
 * end of its last step and that read, and a get does not change an FMU; the calls of the steps the host does
 * not see are saved.  Multi-rate: every output is read as the master reads it (an instance's outputs hold
 * between its points while its inputs change). */
static void lazy_outputs(Container *s) {
    int i, j, m;
    for (i = 0; i < s->n; i++) {
        Inst *p = &s->insts[i];
        long lo = p->out_val - s->row, hi = lo + (long)p->n_out_values;
        int fed = 0;
        for (m = 0; m < s->n && !fed; m++)
            for (j = 0; j < s->insts[m].n_copies; j++)
                if (s->insts[m].slot[j] >= lo && s->insts[m].slot[j] < hi) { fed = 1; break; }
        s->inner[i].n_out = p->n_out;
        s->inner[i].lazy = !fed && !s->L.multirate && p->n_out > 0;
    }
}

static int read_system(Container *s, const char *path) {
    FILE *f = fopen(path, "rb");
    long size, i;
    Reader r = {0};
    int ok = 0;
    if (!f) return 0;
    fseek(f, 0, SEEK_END); size = ftell(f); fseek(f, 0, SEEK_SET);
    r.text = r.at = calloc((size_t)size + 1, 1);
    if (fread(r.text, 1, (size_t)size, f) != (size_t)size) r.bad = 1;
    fclose(f);
    if (strncmp(r.text, VERSION_TAG "\n", strlen(VERSION_TAG) + 1)) goto done;
    r.at += strlen(VERSION_TAG) + 1;
    expect(&r, "system");
    s->n = (int)num(&r); s->n_row = num(&r); s->L.simultaneous = (int)num(&r); s->L.check_inputs = (int)num(&r);
    s->step = real(&r); s->n_vars = (int)num(&r);
    s->L.multirate = (int)num(&r);   /* some instance at its own rate: the multi-rate passes, as native.py */
    if (r.bad || s->n < 1 || s->n_row < 1 || s->n_vars < 0 || !(s->step > 0)) goto done;
    s->row = calloc((size_t)s->n_row, sizeof(double));
    s->inner = calloc((size_t)s->n, sizeof(Inner)); s->insts = calloc((size_t)s->n, sizeof(Inst));
    s->vars = calloc((size_t)s->n_vars + 1, sizeof(Var));
    for (i = 0; i < s->n; i++) if (!read_instance(s, &r, (int)i)) goto done;
    for (i = 0; i < s->n_vars; i++) {
        Var *v = &s->vars[i];
        expect(&r, "var");
        v->kind = token(&r)[0]; v->type = token(&r)[0]; v->inst = (int)num(&r); v->ref = (unsigned)num(&r);
        v->value = real(&r); v->tunable = (int)num(&r);
        if (!strchr("oip", v->kind) || !strchr("RIB", v->type)) r.bad = 1;
        /* a Real output is a slot of the row; the others are read from their instance */
        if (v->kind == 'o' && v->type == 'R' ? v->ref >= (unsigned)s->n_row : (v->inst < 0 || v->inst >= s->n))
            r.bad = 1;
    }
    if (!r.bad && (!iter_read(s, &r) || !iter_link(s))) r.bad = 1;
    if (!r.bad && !read_actions(&s->act, &r, s->n_row, s->n)) r.bad = 1;
    expect(&r, "end");
    ok = !r.bad;
    if (ok) { lazy_outputs(s); write_holds(&s->act, s->row); }
done:
    free(r.text);
    return ok;
}

/* ------------------------------------------------------------------ the inner FMUs */
static char *decode_uri(const char *uri) {   /* file:///a%20b/ -> /a b/ */
    const char *p = uri;
    char *out = calloc(strlen(uri) + 1, 1), *o = out;
    if (!strncmp(p, "file://localhost/", 17)) p += 16;
    else if (!strncmp(p, "file:///", 8)) p += 7;
    else if (!strncmp(p, "file:/", 6)) p += 5;
    else { free(out); return NULL; }
#ifdef _WIN32
    if (p[0] == '/' && p[1] && p[2] == ':') p++;   /* file:///C:/a -> C:/a */
#endif
    for (; *p; p++) {
        unsigned v;
        if (*p == '%' && sscanf(p + 1, "%2x", &v) == 1) { *o++ = (char)v; p += 2; }
        else *o++ = *p;
    }
    while (o > out && o[-1] == '/') *--o = 0;
    return out;
}

static char *encode_uri(const char *path) {
    char *out = calloc(strlen(path) * 3 + 16, 1), *o = out;
    const char *p;
#ifdef _WIN32
    o += sprintf(o, "file:///");   /* file:///C:/a (a drive's colon kept, backslashes as slashes) */
#else
    o += sprintf(o, "file://");
#endif
    for (p = path; *p; p++) {
        unsigned char ch = (unsigned char)*p;
#ifdef _WIN32
        if (ch == '\\') ch = '/';
        if (ch == ':' && p == path + 1) { *o++ = ':'; continue; }
#endif
        if ((ch >= 'a' && ch <= 'z') || (ch >= 'A' && ch <= 'Z') || (ch >= '0' && ch <= '9') || strchr("/-._~", ch))
            *o++ = (char)ch;
        else o += sprintf(o, "%%%02X", ch);
    }
    return out;
}

#include "container_me.c"

#define SYM(q, field, sym) \
    if (!((q)->field = (void *)LOOKUP(dll, sym))) { say(s, fmi2Error, "%s: %s not found", who, sym); return 0; }

static int load_inner(Container *s, Inner *q, Inst *p, const char *res, fmi2Boolean visible, fmi2Boolean logging) {
    char *lib = malloc(strlen(res) + strlen(q->dir) + strlen(q->mi) + 40), *where, *uri;
    sprintf(lib, "%s/%s/binaries/%s/%s." LIB_EXT, res, q->dir, p->abi == 3 ? PLATFORM3 : PLATFORM, q->mi);
#ifdef _WIN32
    /* (a full path with backslashes: the DLLs beside it are found first) */
    for (where = lib; *where; where++) if (*where == '/') *where = '\\';
    void *dll = q->dll = (void *)LoadLibraryExA(lib, NULL, LOAD_WITH_ALTERED_SEARCH_PATH);
    const char *who = q->name;
    if (!q->dll) { say(s, fmi2Error, "%s: LoadLibrary %s failed (error %lu)", q->name, lib, (unsigned long)GetLastError()); free(lib); return 0; }
#else
    /* (RTLD_DEEPBIND: FMUs exporting the same FMI names do not meet) */
    void *dll = q->dll = dlopen(lib, RTLD_NOW | RTLD_LOCAL | RTLD_DEEPBIND);
    const char *who = q->name;
    if (!q->dll) { say(s, fmi2Error, "%s: %s", q->name, dlerror()); free(lib); return 0; }
#endif
    free(lib);
    if (p->abi == 3) return load_inner3(s, q, p, res, dll, visible, logging);
    SYM(q, instantiate, "fmi2Instantiate") SYM(q, free_instance, "fmi2FreeInstance")
    SYM(q, setup, "fmi2SetupExperiment") SYM(q, enter, "fmi2EnterInitializationMode")
    SYM(q, exit_, "fmi2ExitInitializationMode") SYM(q, terminate, "fmi2Terminate")
    SYM(q, set_real, "fmi2SetReal") SYM(q, set_integer, "fmi2SetInteger") SYM(q, set_boolean, "fmi2SetBoolean")
    SYM(q, set_string, "fmi2SetString") SYM(q, get_integer, "fmi2GetInteger") SYM(q, get_boolean, "fmi2GetBoolean")
    if (!q->me) { SYM(p, step, "fmi2DoStep") SYM(p, get, "fmi2GetReal") }
    p->set = (void *)q->set_real;
    if (q->me && !me_load(s, q, p, res)) return 0;
    where = malloc(strlen(res) + strlen(q->dir) + 16);
    sprintf(where, "%s/%s/resources", res, q->dir);
    uri = encode_uri(where);
    q->c = q->instantiate(q->name, q->me ? fmi2ModelExchange : fmi2CoSimulation, q->guid, uri, s->cb, visible, logging);
    free(where); free(uri);
    if (!q->c) { say(s, fmi2Error, "%s: fmi2Instantiate failed", q->name); return 0; }
    p->c = q->c;
    if (q->me) q->me->c = q->c, p->c = q->me;   /* (the loop calls its wrappers: container_me.c) */
    return 1;
}

static void free_container(Container *s) {
    int i;
    if (!s) return;
    for (i = 0; s->inner && i < s->n; i++) {
        Inner *q = &s->inner[i];
        Inst *p = &s->insts[i];
        if (q->c && q->free_instance) q->free_instance(q->c);
        me_free(q->me);
        if (q->dll) UNLOAD(q->dll);
        free(q->name); free(q->dir); free(q->mi); free(q->guid);
        for (int j = 0; q->params && j < q->n_params; j++) { free(q->params[j].s); free_typed(q->params[j].typed); }
        free(q->params);
        free(p->in_vr); free(p->in_val); free(p->out_vr);
        free(p->pos); free(p->src); free(p->slot); free(p->factor); free(p->offset); free(p->plain);
    }
    free_actions(&s->act);
    free_others(s);
    iter_free(s);
    free(s->inner); free(s->insts); free(s->vars); free(s->row); free(s->name);
    free(s);
}

/* ------------------------------------------------------------------ the FMI 2.0 interface */
const char *fmi2GetTypesPlatform(void) { return "default"; }
const char *fmi2GetVersion(void) { return "2.0"; }
fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String cats[]) {
    (void)c; (void)on; (void)n; (void)cats;
    return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String location,
                              const fmi2CallbackFunctions *cb, fmi2Boolean visible, fmi2Boolean logging) {
    Container *s = calloc(1, sizeof(Container));
    char *res, *sys;
    int i;
    if (!s) return NULL;
    s->cb = cb; s->name = strdup(name ? name : "container");
    if (type != fmi2CoSimulation) { say(s, fmi2Error, "this FMU is co-simulation only"); free_container(s); return NULL; }
    if (!guid || strcmp(guid, CONTAINER_GUID)) { say(s, fmi2Error, "wrong GUID %s", guid ? guid : "(none)"); free_container(s); return NULL; }
    res = location ? decode_uri(location) : NULL;
    if (!res) { say(s, fmi2Error, "the resource location %s is not a file URI", location ? location : "(none)"); free_container(s); return NULL; }
    sys = malloc(strlen(res) + 16);
    sprintf(sys, "%s/system.txt", res);
    if (!read_system(s, sys)) { say(s, fmi2Error, "%s cannot be read", sys); free(sys); free(res); free_container(s); return NULL; }
    free(sys);
    for (i = 0; i < s->n; i++)
        if (!load_inner(s, &s->inner[i], &s->insts[i], res, visible, logging)) { free(res); free_container(s); return NULL; }
    free(res);
    if (!link_others(s)) { free_container(s); return NULL; }
    if (!iter_load(s)) { free_container(s); return NULL; }
    s->L.n = s->n; s->L.inst = s->insts; s->L.h = s->step; s->L.h_last = s->step; s->L.k_last = -1;
    s->L.decimation = 1; s->L.n_steps = -1;
    return s;
}

void fmi2FreeInstance(fmi2Component c) { free_container((Container *)c); }

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean tol_defined, fmi2Real tol, fmi2Real start,
                               fmi2Boolean stop_defined, fmi2Real stop) {
    Container *s = c;
    (void)tol_defined; (void)tol;
    s->t0 = start; s->stop_defined = stop_defined; s->stop = stop;
    return fmi2OK;
}

/* a value of type 'R', 'I' or 'B' (held as a double) to value reference vr of the inner FMU q */
static int set_value(Inner *q, char type, unsigned vr, double value) {
    fmi2Integer i = (fmi2Integer)value;
    if (type == 'R') return q->set_real(q->c, &vr, 1, &value);
    if (type == 'B') return q->set_boolean(q->c, &vr, 1, &i);
    return q->set_integer(q->c, &vr, 1, &i);
}

/* a parameter or start value the scenario sets (the host's value where it set that variable) */
static int set_param(Container *s, Inner *q, Param *a) {
    if (a->type == 'S') { fmi2String v = a->s; return q->set_string(q->c, &a->vr, 1, &v); }
    if (a->type == 'T') return set_typed(s, q, a->vr, a->typed);
    if (a->var >= 0 && s->vars[a->var].set) return set_value(q, a->type, a->vr, s->vars[a->var].value);
    return set_value(q, a->type, a->vr, a->type == 'R' ? a->r : (double)a->i);
}

/* the timed events of the communication points up to step k, in order (container_actions.c) */
static int apply_at(Container *s, long k) {
    Actions *A = &s->act;
    int j, st;
    while (A->next < A->n_at && A->at[A->next].k <= k) {
        At *a = &A->at[A->next++];
        for (j = 0; j < a->n; j++) {
            Item *it = &a->items[j];
            if (it->what == 's') {
                Inner *q = &s->inner[it->inst];
                Param *p = &it->p;
                if ((st = set_param(s, q, p))) { say(s, fmi2Error, "%s: an event's value to value reference %u returned %d at t = %.17g s",
                              q->name, p->vr, st, s->L.t0 + (double)a->k * s->L.h); return 1; }
            } else if (it->what == 'c') replace_copies(&s->insts[it->inst], it, s->row);
            else if (it->what == 'p') s->row[it->put_slot] = it->put_value;
            else { A->stopped = 1; A->stop_index = it->index; A->stop_time = s->L.t0 + (double)a->k * s->L.h; return 0; }
        }
    }
    return 0;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    Container *s = c;
    int i, j, st;
    s->L.t0 = s->t0;
    for (i = 0; i < s->n; i++) {
        Inner *q = &s->inner[i];
        /* the tolerance the master gives it (its instance's, else the experiment's; else none) */
        if ((st = q->setup(q->c, q->tol_defined, q->tol, s->t0, s->stop_defined, s->stop)))
            { say(s, fmi2Error, "%s: fmi2SetupExperiment returned %d", q->name, st); return fmi2Error; }
        for (j = 0; j < q->n_params; j++)
            if ((st = set_param(s, q, &q->params[j])))
                { say(s, fmi2Error, "%s: setting value reference %u returned %d", q->name, q->params[j].vr, st); return fmi2Error; }
        for (j = 0; j < s->n_vars; j++) {   /* what the host set that the scenario does not */
            Var *v = &s->vars[j];
            int k, listed = 0;
            if (v->kind == 'o' || v->inst != i || !v->set) continue;
            for (k = 0; k < q->n_params; k++) listed |= q->params[k].var == j;
            if (!listed && (st = set_value(q, v->type, v->ref, v->value)))
                { say(s, fmi2Error, "%s: setting value reference %u returned %d", q->name, v->ref, st); return fmi2Error; }
        }
    }
    for (i = 0; i < s->n; i++)
        if ((st = s->inner[i].enter(s->inner[i].c)))
            { say(s, fmi2Error, "%s: fmi2EnterInitializationMode returned %d", s->inner[i].name, st); return fmi2Error; }
    s->mode = 1;
    return fmi2OK;
}

static int read_all(Container *s) {
    int i;
    for (i = 0; i < s->n; i++) if (outputs(&s->L, i, 0)) return 0;
    return 1;
}

/* the master's initial exchange (cosim/runtime/startup.py exchange_initial): outputs to inputs in the
 * plan's order, pass after pass (at most n + 1), until no input changes */
static int exchange(Container *s) {
    long total = 0, m, i, j;
    double *last, *now;
    int have_last = 0, pass;
    for (i = 0; i < s->n; i++) total += s->insts[i].n_copies;
    last = calloc((size_t)total + 1, sizeof(double)); now = calloc((size_t)total + 1, sizeof(double));
    other_of = s;
    if (!read_all(s)) goto failed;
    for (pass = 0; pass <= s->n; pass++) {
        m = 0;
        for (i = 0; i < s->n; i++) {
            Inst *p = &s->insts[i];
            const char *who = NULL;
            int st = feed_tables(&s->act, s->inner, s->row, (int)i, 0, &who);   /* (the master's feed(0)) */
            if (st) { say(s, fmi2Error, "%s: setting its tabulated inputs returned %d", who, st); goto failed; }
            for (j = 0; j < p->n_copies; j++) {
                double v = p->plain[j] ? p->src[j][p->slot[j]] : p->src[j][p->slot[j]] * p->factor[j] + p->offset[j];
                p->in_val[p->pos[j]] = v;
                now[m++] = v;
            }
            if (s->L.check_inputs)
                for (j = 0; j < (long)p->n_in_values; j++)
                    if (p->in_val[j] - p->in_val[j] != 0.0) {
                        say(s, fmi2Error, "%s: a non-finite input at initialisation (value reference %u)",
                            s->inner[i].name, p->in_vr[j]);
                        goto failed;
                    }
            if (p->n_in && set_inputs(p)) goto failed;
            for (j = 0; j < p->n_other; j++) if (p->other[j]()) goto failed;   /* (as the master: after the set) */
            if (outputs(&s->L, (int)i, 0)) goto failed;
        }
        if (have_last) {   /* (as Python's list ==: value by value) */
            for (j = 0; j < total && now[j] == last[j]; j++) {}
            if (j == total) break;
        }
        memcpy(last, now, sizeof(double) * (size_t)total);
        have_last = 1;
    }
    free(last); free(now);
    return 1;
failed:
    free(last); free(now);
    return 0;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    Container *s = c;
    int i, st;
    if (!exchange(s)) { say(s, fmi2Error, "the initial exchange of outputs to inputs failed"); return fmi2Error; }
    if (!iter_initialize(s)) return fmi2Error;
    for (i = 0; i < s->n; i++) {
        if ((st = s->inner[i].exit_(s->inner[i].c)))
            { say(s, fmi2Error, "%s: fmi2ExitInitializationMode returned %d", s->inner[i].name, st); return fmi2Error; }
        if (s->inner[i].me && !me_start(s->inner[i].me, s->t0)) return fmi2Error;
    }
    if (!read_all(s)) { say(s, fmi2Error, "reading the outputs after initialisation failed"); return fmi2Error; }
    for (i = 0; i < s->n; i++) if (s->inner[i].lazy) s->insts[i].n_out = 0;   /* (read by fetch_lazy) */
    s->mode = 2;
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c) {
    Container *s = c;
    int i;
    fmi2Status worst = fmi2OK;
    for (i = 0; i < s->n; i++) {
        int st = s->inner[i].terminate(s->inner[i].c);
        if (st > (int)worst) worst = (fmi2Status)st;
    }
    s->mode = 3;
    return worst;
}

fmi2Status fmi2Reset(fmi2Component c) {
    say(c, fmi2Error, "fmi2Reset is not supported");
    return fmi2Error;
}

/* the lazy instances' outputs into the row, where a step has passed since they were read */
static fmi2Status fetch_lazy(Container *s) {
    int i, st;
    if (!s->stale) return fmi2OK;
    for (i = 0; i < s->n; i++) {
        Inner *q = &s->inner[i];
        Inst *p = &s->insts[i];
        if (!q->lazy) continue;
        p->n_out = q->n_out;   /* (the loop's own read of its outputs, FMI 2.0 or 3.0) */
        st = outputs(&s->L, i, 0);
        p->n_out = 0;
        if (st) {
            say(s, fmi2Error, "%s: reading its outputs returned %g", q->name, s->L.f_value);
            return fmi2Error;
        }
    }
    s->stale = 0;
    return fmi2OK;
}

/* the container's variable vr of the type the host asks for (NULL, said, where it has none) */
static Var *variable(Container *s, fmi2ValueReference vr, char type) {
    static const char *names[] = {"Real", "Integer", "Boolean"};
    if (vr < 1 || vr > (unsigned)s->n_vars || s->vars[vr - 1].type != type) {
        say(s, fmi2Error, "no %s variable %u", names[type == 'R' ? 0 : type == 'I' ? 1 : 2], vr);
        return NULL;
    }
    return &s->vars[vr - 1];
}

/* an Integer or Boolean output, read from its instance when the host asks (as the master's recording reads
 * them after the step) */
static fmi2Status get_from_inner(Container *s, Var *v, fmi2Integer *out) {
    Inner *q = &s->inner[v->inst];
    int st = (v->type == 'I' ? q->get_integer : q->get_boolean)(q->c, &v->ref, 1, out);
    if (st) say(s, fmi2Error, "%s: fmi2Get%s of value reference %u returned %d", q->name,
                v->type == 'I' ? "Integer" : "Boolean", v->ref, st);
    return (fmi2Status)st;
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real value[]) {
    Container *s = c;
    size_t j;
    fmi2Status st = fetch_lazy(s);
    if (st) return st;
    for (j = 0; j < n; j++) {
        Var *v = variable(s, vr[j], 'R');
        if (!v) return fmi2Error;
        value[j] = v->kind == 'o' ? s->row[v->ref] : v->value;
    }
    return fmi2OK;
}

static fmi2Status get_ints(Container *s, const fmi2ValueReference vr[], size_t n, fmi2Integer value[], char type) {
    size_t j;
    for (j = 0; j < n; j++) {
        Var *v = variable(s, vr[j], type);
        fmi2Status st;
        if (!v) return fmi2Error;
        if (v->kind != 'o') value[j] = (fmi2Integer)v->value;
        else if ((st = get_from_inner(s, v, &value[j]))) return st;
    }
    return fmi2OK;
}

/* n values of a type to the container's variables: kept for the set-up, passed at once to the inner FMU
 * once it is in initialisation mode or after */
static fmi2Status set_values(Container *s, const fmi2ValueReference vr[], size_t n, const double value[], char type) {
    size_t j;
    for (j = 0; j < n; j++) {
        Var *v = variable(s, vr[j], type);
        if (!v) return fmi2Error;
        if (v->kind == 'o') { say(s, fmi2Error, "variable %u is an output: it cannot be set", vr[j]); return fmi2Error; }
        if (s->mode == 2 && v->kind == 'p' && !v->tunable)
            { say(s, fmi2Error, "variable %u is a fixed parameter: set it before initialisation", vr[j]); return fmi2Error; }
        v->value = value[j]; v->set = 1;
        if (s->mode == 2 && fetch_lazy(s)) return fmi2Error;   /* (the outputs of the step, before the value) */
        if (s->mode >= 1) {
            Inner *q = &s->inner[v->inst];
            int st = s->mode == 2 ? me_before_set(q->me) : 0;
            if (!st) st = set_value(q, v->type, v->ref, v->value);
            if (st) { say(s, fmi2Error, "%s: setting value reference %u returned %d", q->name, v->ref, st); return (fmi2Status)st; }
        }
    }
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real value[]) {
    return set_values(c, vr, n, value, 'R');
}

static fmi2Status set_ints(Container *s, const fmi2ValueReference vr[], size_t n, const fmi2Integer value[], char type) {
    size_t j;
    fmi2Status st = fmi2OK;
    for (j = 0; j < n && st == fmi2OK; j++) {
        double x = type == 'B' ? (double)(value[j] != 0) : (double)value[j];
        st = set_values(s, &vr[j], 1, &x, type);
    }
    return st;
}

static fmi2Status none(fmi2Component c, size_t n, const char *what) {
    if (!n) return fmi2OK;
    say(c, fmi2Error, "this container has no %s variables", what);
    return fmi2Error;
}
fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Integer v[]) { return get_ints(c, vr, n, v, 'I'); }
fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Boolean v[]) { return get_ints(c, vr, n, v, 'B'); }
fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2String v[]) { (void)vr; (void)v; return none(c, n, "String"); }
fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer v[]) { return set_ints(c, vr, n, v, 'I'); }
fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Boolean v[]) { return set_ints(c, vr, n, v, 'B'); }
fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2String v[]) { (void)vr; (void)v; return none(c, n, "String"); }

static fmi2Status unsupported(fmi2Component c, const char *what) {
    say(c, fmi2Error, "%s is not supported by this container", what);
    return fmi2Error;
}
fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *st) { (void)st; return unsupported(c, "fmi2GetFMUstate"); }
fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate st) { (void)st; return unsupported(c, "fmi2SetFMUstate"); }
fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *st) { (void)st; return unsupported(c, "fmi2FreeFMUstate"); }
fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate st, size_t *n) { (void)st; (void)n; return unsupported(c, "fmi2SerializedFMUstateSize"); }
fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate st, fmi2Byte b[], size_t n) { (void)st; (void)b; (void)n; return unsupported(c, "fmi2SerializeFMUstate"); }
fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte b[], size_t n, fmi2FMUstate *st) { (void)st; (void)b; (void)n; return unsupported(c, "fmi2DeSerializeFMUstate"); }
fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference u[], size_t nu, const fmi2ValueReference z[],
                                        size_t nz, const fmi2Real dv[], fmi2Real dz[]) {
    (void)u; (void)nu; (void)z; (void)nz; (void)dv; (void)dz;
    return unsupported(c, "fmi2GetDirectionalDerivative");
}
fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer o[], const fmi2Real v[]) {
    (void)vr; (void)n; (void)o; (void)v;
    return unsupported(c, "fmi2SetRealInputDerivatives");
}
fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer o[], fmi2Real v[]) {
    (void)vr; (void)n; (void)o; (void)v;
    return unsupported(c, "fmi2GetRealOutputDerivatives");
}
fmi2Status fmi2CancelStep(fmi2Component c) { return unsupported(c, "fmi2CancelStep"); }

static const char *CALL_NAMES[] = {"", "tabulated inputs", "a non-finite input", "fmi2SetReal", "a connection",
                                   "fmi2DoStep", "fmi2GetReal", "a recorded output", "the end of the simulation"};

/* one step of the host = the loop over the steps of the grid it spans */
fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean no_set_prior) {
    Container *s = c;
    double n = h / s->step, k = (t - s->t0) / s->step;
    long nk = lround(n), k0 = lround(k);
    int st;
    (void)no_set_prior;
    if (s->mode != 2) { say(s, fmi2Error, "fmi2DoStep before fmi2ExitInitializationMode"); return fmi2Error; }
    if (s->terminated) { say(s, fmi2Error, "fmi2DoStep after the simulation ended"); return fmi2Error; }
    if (nk < 1 || fabs(n - (double)nk) > 1e-6 || k0 < 0 || fabs(k - (double)k0) > 1e-6) {
        say(s, fmi2Error, "fmi2DoStep(%.17g, %.17g): the container steps on the grid of its step %.17g s from %.17g s: "
            "take steps that are whole multiples of it", t, h, s->step, s->t0);
        return fmi2Error;
    }
    other_of = s;   /* (the connections that are not Float64: their container, for this thread) */
    if (s->act.stopped) { say(s, fmi2Error, "fmi2DoStep after the stop of events[%d]", s->act.stop_index); return fmi2Error; }
    {
        long k = k0, end = k0 + nk;
        st = OK;
        while (k < end && st == OK) {
            long next = end;
            if (apply_at(s, k)) return fmi2Error;
            if (s->act.stopped) {
                for (int i = 0; i < s->n; i++) s->stale |= s->inner[i].lazy;
                say(s, fmi2OK, "stopped by events[%d] at t = %.17g s", s->act.stop_index, s->act.stop_time);
                return fmi2Discard;
            }
            if (s->act.next < s->act.n_at && s->act.at[s->act.next].k < end) next = s->act.at[s->act.next].k;
            if (!s->act.n_tables) { st = s->iter ? iter_loop(s, k, next) : wmr_loop(&s->L, k, next); k = next; continue; }
            for (; k < next && st == OK; k++) {   /* (the tables' row of each step before it) */
                const char *who = NULL;
                int fs = feed_tables(&s->act, s->inner, s->row, -1, k, &who);
                if (fs) { say(s, fmi2Error, "%s: setting its tabulated inputs of step %ld returned %d", who, k, fs); return fmi2Error; }
                st = wmr_loop(&s->L, k, k + 1);
            }
        }
    }
    for (int i = 0; i < s->n; i++) s->stale |= s->inner[i].lazy;
    if (st == OK) return fmi2OK;
    if (st == COUPLING) return fmi2Error;   /* (said) */
    if (st == FAILED && s->L.f_call == C_TERMINATED) {
        /* an inner FMU (a Model Exchange one's event) ended the simulation: the master records the row of the
         * step it ended in and stops; the host is told so (fmi2Discard, fmi2Terminated, the row's time as
         * fmi2LastSuccessfulTime) */
        s->terminated = 1;
        s->last_successful = s->L.t0 + (double)s->L.f_step * s->L.h;
        say(s, fmi2OK, "%s ended the simulation at t = %.17g s", s->inner[s->L.f_inst].name, s->L.f_value);
        return fmi2Discard;
    }
    {
        int call = s->L.f_call >= 0 && s->L.f_call <= C_TERMINATED ? s->L.f_call : 0;
        say(s, fmi2Error, "%s: %s failed at step %ld (status or value %g)", s->inner[s->L.f_inst].name,
            CALL_NAMES[call], s->L.f_step, s->L.f_value);
    }
    return fmi2Error;
}

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind k, fmi2Status *v) { (void)k; (void)v; return unsupported(c, "fmi2GetStatus"); }
fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind k, fmi2Real *v) {
    Container *s = c;
    if (k == fmi2LastSuccessfulTime && s->act.stopped) { *v = s->act.stop_time; return fmi2OK; }
    if (k == fmi2LastSuccessfulTime && s->terminated) { *v = s->last_successful; return fmi2OK; }
    return unsupported(c, "fmi2GetRealStatus");
}
fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind k, fmi2Integer *v) { (void)k; (void)v; return unsupported(c, "fmi2GetIntegerStatus"); }
fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind k, fmi2String *v) { (void)k; (void)v; return unsupported(c, "fmi2GetStringStatus"); }
fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind k, fmi2Boolean *v) {
    if (k == fmi2Terminated) { *v = ((Container *)c)->terminated || ((Container *)c)->act.stopped; return fmi2OK; }
    return fmi2Discard;
}
