/* FMI 3.0 co-simulation FMUs inside the container, and the connections that are not Float64 to Float64
 * (between inner FMUs of either version): included by container.c (so by both faces of the container; no
 * FMI 3.0 header is needed here: the FMI 3.0 functions of an inner FMU are called through the C types of
 * their prototypes, declared below under names of their own).
 *
 * An inner FMI 3.0 FMU is called as the master calls one (cosim/instances/in_process.py, Instance3):
 * fmi3InstantiateCoSimulation (no event mode, no early return, no intermediate update; its resource path
 * the native path of its resources folder with a separator at the end, as FMPy gives it),
 * fmi3EnterInitializationMode with the tolerance, start and stop time fmi2SetupExperiment would take,
 * fmi3Set/GetFloat64 with the count of values, fmi3DoStep with noSetFMUStatePriorToCurrentPoint true and
 * its four outputs (native_loop.c calls it directly: Inst.abi 3); a parameter or start value through the
 * setter of its FMI 3.0 type.  For the rest of the container, an inner FMI 3.0 FMU looks like an FMI 2.0
 * one: its Inner's functions are adapters of FMI 2.0 shape (Real as Float64, Integer as Int32, Boolean as
 * Boolean), its Inner.c the adapter's state.
 *
 * The other connections: each a get of the output and a set of the input per step (Inst.other, called by
 * the loop after the Float64 set, as the master's discrete_copier closures, cosim/plan/wiring.py), with the
 * master's conversion of each value (system.txt names it):
 *   c  the same C type on both sides: the values as they are;
 *   i  integers, enumerations and booleans of other C types: the value as a 64-bit integer, to the target
 *      type (a C bool: value != 0; an integer type: its low bytes, as ctypes stores a Python int);
 *   r  reals (Float32 / Float64): (double)x * factor + offset, to the target type;
 *   b  Boolean -> Real: (x != 0 ? 1.0 : 0.0) * factor + offset;
 *   t  Real -> Boolean: x > threshold.
 * native_loop.c calls an other connection with no argument: each is one of OTHER_MAX functions, the m-th
 * running connection m of the container whose loop runs in this thread (other_of). */
#include <stdbool.h>
#include <stdint.h>

#ifdef _WIN32
#define PLATFORM3 "x86_64-windows"
#define SEP3 "\\"
#else
#define PLATFORM3 "x86_64-linux"
#define SEP3 "/"
#endif

/* ------------------------------------------------------------------ the types of values */
/* an FMI type as a C type: its name in the FMI functions, its size, its kind: d double, f float, i signed
 * integer, u unsigned integer, b C bool, s a string (char *) */
typedef struct { int abi; const char *name; size_t size; char kind; } VType;

static const VType VTYPES[] = {
    {2, "Real", 8, 'd'}, {2, "Integer", 4, 'i'}, {2, "Boolean", 4, 'i'}, {2, "String", sizeof(char *), 's'},
    {3, "Float64", 8, 'd'}, {3, "Float32", 4, 'f'}, {3, "Int8", 1, 'i'}, {3, "UInt8", 1, 'u'},
    {3, "Int16", 2, 'i'}, {3, "UInt16", 2, 'u'}, {3, "Int32", 4, 'i'}, {3, "UInt32", 4, 'u'},
    {3, "Int64", 8, 'i'}, {3, "UInt64", 8, 'u'}, {3, "Boolean", 1, 'b'}, {3, "String", sizeof(char *), 's'},
};

static const VType *vtype(int abi, const char *name) {
    size_t j;
    for (j = 0; j < sizeof VTYPES / sizeof VTYPES[0]; j++)
        if (VTYPES[j].abi == abi && !strcmp(VTYPES[j].name, name)) return &VTYPES[j];
    return NULL;
}

static double get_d(const void *buf, size_t j, const VType *t) {
    return t->kind == 'f' ? (double)((const float *)buf)[j] : ((const double *)buf)[j];
}

static int64_t get_i(const void *buf, size_t j, const VType *t) {
    const unsigned char *b = (const unsigned char *)buf + j * t->size;
    if (t->kind == 'b') return *b != 0;
    switch (t->size) {
    case 1: return t->kind == 'u' ? (int64_t)*(const uint8_t *)b : (int64_t)*(const int8_t *)b;
    case 2: return t->kind == 'u' ? (int64_t)*(const uint16_t *)b : (int64_t)*(const int16_t *)b;
    case 4: return t->kind == 'u' ? (int64_t)*(const uint32_t *)b : (int64_t)*(const int32_t *)b;
    default: return *(const int64_t *)b;
    }
}

static void put_d(void *buf, size_t j, const VType *t, double x) {
    if (t->kind == 'f') ((float *)buf)[j] = (float)x;
    else ((double *)buf)[j] = x;
}

static void put_i(void *buf, size_t j, const VType *t, int64_t v) {
    unsigned char *b = (unsigned char *)buf + j * t->size;
    if (t->kind == 'b') { *(bool *)b = v != 0; return; }
    switch (t->size) {   /* (the low bytes: what ctypes keeps of a Python int) */
    case 1: *(uint8_t *)b = (uint8_t)(uint64_t)v; break;
    case 2: *(uint16_t *)b = (uint16_t)(uint64_t)v; break;
    case 4: *(uint32_t *)b = (uint32_t)(uint64_t)v; break;
    default: *(int64_t *)b = v;
    }
}

/* the FMI getter or setter of a type: fmi2 (instance, vr, nvr, values) or fmi3 (..., nValues) */
typedef int (*acc2_t)(void *, const unsigned *, size_t, void *);
typedef int (*acc3_t)(void *, const unsigned *, size_t, void *, size_t);

static int access_values(int abi, void *fn, void *c, const unsigned *vr, void *buf, size_t n) {
    return abi == 2 ? ((acc2_t)fn)(c, vr, 1, buf) : ((acc3_t)fn)(c, vr, 1, buf, n);
}

static void *accessor(Container *s, Inner *q, int abi, const char *op, const char *type) {
    char name[64];
    void *fn;
    snprintf(name, sizeof name, "fmi%d%s%s", abi, op, type);
    fn = (void *)LOOKUP(q->dll, name);
    if (!fn) say(s, fmi2Error, "%s: %s not found", q->name, name);
    return fn;
}

/* ------------------------------------------------------------------ an inner FMI 3.0 FMU */
typedef int (*enter3_t)(void *, bool, double, double, bool, double);
typedef void (*log3_t)(void *, int, const char *, const char *);
typedef void *(*inst3_t)(const char *, const char *, const char *, bool, bool, bool, bool, const unsigned *, size_t,
                         void *, log3_t, void *);
typedef int (*f64_t)(void *, const unsigned *, size_t, const double *, size_t);
typedef int (*i32_t)(void *, const unsigned *, size_t, int32_t *, size_t);
typedef int (*b3_t)(void *, const unsigned *, size_t, bool *, size_t);
typedef int (*s3_t)(void *, const unsigned *, size_t, const char *const *, size_t);

/* what an Inner's c points at for an FMI 3.0 FMU */
typedef struct Inner3 {
    void *c;
    Container *s; const char *name;
    int tol_defined, stop_defined; double tol, start, stop;   /* (fmi2SetupExperiment's, for the enter) */
    bool flags[3]; double last;   /* fmi3DoStep's eventHandlingNeeded, terminateSimulation, earlyReturn, lastSuccessfulTime */
    void (*free_)(void *);
    enter3_t enter; int (*exit_)(void *), (*terminate)(void *);
    f64_t set_f64; i32_t set_i32, get_i32; b3_t set_b, get_b; s3_t set_s;
} Inner3;

static void log_inner3(void *env, int status, const char *category, const char *message) {
    Inner3 *w = env;
    Container *s = w->s;
    if (s && s->cb && s->cb->logger)
        s->cb->logger(s->cb->componentEnvironment, w->name, (fmi2Status)status, category ? category : "", "%s",
                      message ? message : "");
}

/* the adapters: FMI 2.0 shapes over the FMI 3.0 calls */
static void free3(fmi2Component c) { Inner3 *w = c; if (w->c) w->free_(w->c); free(w); }
static fmi2Status setup3(fmi2Component c, fmi2Boolean tol_defined, fmi2Real tol, fmi2Real start, fmi2Boolean stop_defined,
                         fmi2Real stop) {
    Inner3 *w = c;
    w->tol_defined = tol_defined; w->tol = tol; w->start = start; w->stop_defined = stop_defined; w->stop = stop;
    return fmi2OK;
}
static fmi2Status enter3(fmi2Component c) {
    Inner3 *w = c;   /* (FMPy: a tolerance or stop time not defined is passed as 0.0) */
    return (fmi2Status)w->enter(w->c, w->tol_defined != 0, w->tol_defined ? w->tol : 0.0, w->start,
                                w->stop_defined != 0, w->stop_defined ? w->stop : 0.0);
}
static fmi2Status exit3(fmi2Component c) { Inner3 *w = c; return (fmi2Status)w->exit_(w->c); }
static fmi2Status terminate3(fmi2Component c) { Inner3 *w = c; return (fmi2Status)w->terminate(w->c); }
static int set_real3(void *c, const unsigned *vr, size_t n, const double *v) {
    Inner3 *w = c;
    return w->set_f64(w->c, vr, n, v, n);
}
static fmi2Status set_int3(fmi2Component c, const fmi2ValueReference *vr, size_t n, const fmi2Integer *v) {
    Inner3 *w = c;
    return (fmi2Status)w->set_i32(w->c, vr, n, (int32_t *)v, n);
}
static fmi2Status get_int3(fmi2Component c, const fmi2ValueReference *vr, size_t n, fmi2Integer *v) {
    Inner3 *w = c;
    return (fmi2Status)w->get_i32(w->c, vr, n, (int32_t *)v, n);
}
static fmi2Status set_bool3(fmi2Component c, const fmi2ValueReference *vr, size_t n, const fmi2Integer *v) {
    Inner3 *w = c;
    bool b[n + 1];
    size_t j;
    for (j = 0; j < n; j++) b[j] = v[j] != 0;
    return (fmi2Status)w->set_b(w->c, vr, n, b, n);
}
static fmi2Status get_bool3(fmi2Component c, const fmi2ValueReference *vr, size_t n, fmi2Integer *v) {
    Inner3 *w = c;
    bool b[n + 1];
    size_t j;
    int st = w->get_b(w->c, vr, n, b, n);
    for (j = 0; j < n; j++) v[j] = b[j] ? 1 : 0;
    return (fmi2Status)st;
}
static fmi2Status set_string3(fmi2Component c, const fmi2ValueReference *vr, size_t n, const fmi2String *v) {
    Inner3 *w = c;
    return (fmi2Status)w->set_s(w->c, vr, n, v, n);
}

#define SYM3(field, sym) \
    if (!(*(void **)&(field) = (void *)LOOKUP(dll, sym))) { say(s, fmi2Error, "%s: %s not found", q->name, sym); return 0; }

/* an FMI 3.0 FMU's library loaded (dll): its functions found, instantiated as the master instantiates one */
static int load_inner3(Container *s, Inner *q, Inst *p, const char *res, void *dll, fmi2Boolean visible,
                       fmi2Boolean logging) {
    Inner3 *w = calloc(1, sizeof(Inner3));
    inst3_t instantiate;
    char *where;
    if (!w) return 0;
    w->s = s; w->name = q->name;
    q->c = w;   /* (freed with the container from here on) */
    q->free_instance = free3; q->setup = setup3; q->enter = enter3; q->exit_ = exit3; q->terminate = terminate3;
    q->set_real = set_real3; q->set_integer = set_int3; q->set_boolean = set_bool3; q->set_string = set_string3;
    q->get_integer = get_int3; q->get_boolean = get_bool3;
    SYM3(instantiate, "fmi3InstantiateCoSimulation") SYM3(w->free_, "fmi3FreeInstance")
    SYM3(w->enter, "fmi3EnterInitializationMode") SYM3(w->exit_, "fmi3ExitInitializationMode")
    SYM3(w->terminate, "fmi3Terminate") SYM3(w->set_f64, "fmi3SetFloat64") SYM3(w->set_i32, "fmi3SetInt32")
    SYM3(w->get_i32, "fmi3GetInt32") SYM3(w->set_b, "fmi3SetBoolean") SYM3(w->get_b, "fmi3GetBoolean")
    SYM3(w->set_s, "fmi3SetString") SYM3(p->step, "fmi3DoStep") SYM3(p->get, "fmi3GetFloat64")
    p->set = (void *)w->set_f64;
    where = malloc(strlen(res) + strlen(q->dir) + 16);
    sprintf(where, "%s" SEP3 "%s" SEP3 "resources" SEP3, res, q->dir);
#ifdef _WIN32
    { char *x; for (x = where; *x; x++) if (*x == '/') *x = '\\'; }
#endif
    w->c = instantiate(q->name, q->guid, where, visible != 0, logging != 0, false, false, NULL, 0, w, log_inner3, NULL);
    free(where);
    if (!w->c) { say(s, fmi2Error, "%s: fmi3InstantiateCoSimulation failed", q->name); return 0; }
    p->c = w->c;
    p->flags[0] = &w->flags[0]; p->flags[1] = &w->flags[1]; p->flags[2] = &w->flags[2];
    p->last_success = &w->last;
    p->terminated = &w->flags[1]; p->last_time = &w->last;   /* (terminateSimulation ends the loop, as the master's) */
    return 1;
}

/* ------------------------------------------------------------------ a parameter of another FMI 3.0 type */
/* "param T TYPE N v1 .. vN var": an FMI 3.0 value (or array) that is not a scalar Float64, Int32, Boolean
 * or String, set through its own setter as FMPy's set<TYPE> sets it (the values as the C type takes them) */
typedef struct { const VType *t; size_t n; void *buf; } Typed;

static void *read_typed(Reader *r) {
    Typed *v = calloc(1, sizeof(Typed));
    long n;
    size_t j;
    if (!v) { r->bad = 1; return NULL; }
    v->t = vtype(3, token(r));
    n = num(r);
    if (!v->t || v->t->kind == 's' || n < 1) { r->bad = 1; return v; }
    v->n = (size_t)n;
    v->buf = calloc(v->n, v->t->size);
    for (j = 0; v->buf && j < v->n; j++) {
        if (v->t->kind == 'd' || v->t->kind == 'f') put_d(v->buf, j, v->t, real(r));
        else {
            char *e, *t = token(r);
            int64_t x = t[0] == '-' ? (int64_t)strtoll(t, &e, 10) : (int64_t)strtoull(t, &e, 10);
            if (*e) r->bad = 1;
            put_i(v->buf, j, v->t, x);
        }
    }
    return v;
}

static int set_typed(Container *s, Inner *q, unsigned vr, void *typed) {
    Typed *v = typed;
    void *fn = accessor(s, q, 3, "Set", v->t->name);
    Inner3 *w = q->c;
    return fn ? ((acc3_t)fn)(w->c, &vr, 1, v->buf, v->n) : fmi2Error;
}

static void free_typed(void *typed) {
    Typed *v = typed;
    if (v) free(v->buf);
    free(v);
}

/* the Float64 inputs of instance p to its FMU (the initial exchange's set; the loop makes its own) */
static int set_inputs(Inst *p) {
    if (p->abi == 2) return ((set2_t)p->set)(p->c, p->in_vr, p->n_in, p->in_val);
    return ((set3_t)p->set)(p->c, p->in_vr, p->n_in, p->in_val, p->n_in_values);
}

/* ------------------------------------------------------------------ the other connections */
#define OTHER_MAX 256

typedef struct Other {
    int src, dst;                 /* instances (indices) */
    const VType *st, *dt;         /* the C types of the output and the input */
    unsigned svr, dvr; size_t n;  /* value references and the count of values (an array's) */
    char mode; double factor, offset, threshold;
    void *get, *set, *sbuf, *dbuf;
} Other;

/* "other SRC SRC_ABI SRC_TYPE SRC_VR DST_TYPE DST_VR N MODE FACTOR OFFSET THRESHOLD": a connection to
 * instance i (its abi p->abi) */
static int read_other(Container *s, Reader *r, int i) {
    Other *o, *grown;
    int sabi;
    if (s->n_others >= OTHER_MAX) return 0;
    grown = realloc(s->others, (size_t)(s->n_others + 1) * sizeof(Other));
    if (!grown) return 0;
    s->others = grown;
    o = &s->others[s->n_others++];
    memset(o, 0, sizeof *o);
    expect(r, "other");
    o->dst = i; o->src = (int)num(r); sabi = (int)num(r);
    o->st = vtype(sabi, token(r)); o->svr = (unsigned)num(r);
    o->dt = vtype(s->insts[i].abi, token(r)); o->dvr = (unsigned)num(r);
    o->n = (size_t)num(r); o->mode = token(r)[0];
    o->factor = real(r); o->offset = real(r); o->threshold = real(r);
    if (r->bad || !o->st || !o->dt || o->src < 0 || o->src >= s->n || sabi != s->insts[o->src].abi || o->n < 1 ||
        !strchr("cirbt", o->mode) || o->st->kind == 's' || o->dt->kind == 's') return 0;
    o->sbuf = calloc(o->n, o->st->size); o->dbuf = calloc(o->n, o->dt->size);
    return o->sbuf && o->dbuf;
}

/* each other connection's getter and setter (after every inner FMU is loaded) */
static int link_others(Container *s) {
    int m;
    for (m = 0; m < s->n_others; m++) {
        Other *o = &s->others[m];
        o->get = accessor(s, &s->inner[o->src], s->insts[o->src].abi, "Get", o->st->name);
        o->set = accessor(s, &s->inner[o->dst], s->insts[o->dst].abi, "Set", o->dt->name);
        if (!o->get || !o->set) return 0;
    }
    return 1;
}

static void free_others(Container *s) {
    int m;
    for (m = 0; m < s->n_others; m++) { free(s->others[m].sbuf); free(s->others[m].dbuf); }
    free(s->others);
}

/* one other connection: the output's values got, converted, set (the first status other than OK returned) */
static int run_other(Container *s, Other *o) {
    Inst *ps = &s->insts[o->src], *pd = &s->insts[o->dst];
    void *out = o->mode == 'c' ? o->sbuf : o->dbuf;
    size_t j;
    int st = access_values(ps->abi, o->get, ps->c, &o->svr, o->sbuf, o->n);
    if (st) return st;
    for (j = 0; o->mode != 'c' && j < o->n; j++) {
        if (o->mode == 'r') put_d(o->dbuf, j, o->dt, get_d(o->sbuf, j, o->st) * o->factor + o->offset);
        else if (o->mode == 'b') put_d(o->dbuf, j, o->dt, (get_i(o->sbuf, j, o->st) ? 1.0 : 0.0) * o->factor + o->offset);
        else if (o->mode == 't') put_i(o->dbuf, j, o->dt, get_d(o->sbuf, j, o->st) > o->threshold);
        else put_i(o->dbuf, j, o->dt, get_i(o->sbuf, j, o->st));
    }
    return access_values(pd->abi, o->set, pd->c, &o->dvr, out, o->n);
}

/* the container whose loop (or initial exchange) runs in this thread: set before each */
static __thread Container *other_of;

#define OTHER1(m) static int other_##m(void) { return run_other(other_of, &other_of->others[m]); }
#define OTHER16(h) OTHER1(0x##h##0) OTHER1(0x##h##1) OTHER1(0x##h##2) OTHER1(0x##h##3) OTHER1(0x##h##4) \
    OTHER1(0x##h##5) OTHER1(0x##h##6) OTHER1(0x##h##7) OTHER1(0x##h##8) OTHER1(0x##h##9) OTHER1(0x##h##a) \
    OTHER1(0x##h##b) OTHER1(0x##h##c) OTHER1(0x##h##d) OTHER1(0x##h##e) OTHER1(0x##h##f)
OTHER16(0) OTHER16(1) OTHER16(2) OTHER16(3) OTHER16(4) OTHER16(5) OTHER16(6) OTHER16(7)
OTHER16(8) OTHER16(9) OTHER16(a) OTHER16(b) OTHER16(c) OTHER16(d) OTHER16(e) OTHER16(f)
#define ROW16(h) other_0x##h##0, other_0x##h##1, other_0x##h##2, other_0x##h##3, other_0x##h##4, other_0x##h##5, \
    other_0x##h##6, other_0x##h##7, other_0x##h##8, other_0x##h##9, other_0x##h##a, other_0x##h##b, other_0x##h##c, \
    other_0x##h##d, other_0x##h##e, other_0x##h##f
static cb_io_t OTHERS[OTHER_MAX] = {ROW16(0), ROW16(1), ROW16(2), ROW16(3), ROW16(4), ROW16(5), ROW16(6), ROW16(7),
                                    ROW16(8), ROW16(9), ROW16(a), ROW16(b), ROW16(c), ROW16(d), ROW16(e), ROW16(f)};
