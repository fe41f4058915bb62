/* The fixed-step stepping loop in C: Gauss-Seidel or Jacobi over the instances (at one rate, or each at its
 * own: the multi-rate passes of cosim/stepping/multirate.py), a segment of steps k0 .. k1 - 1 without
 * returning to Python (cosim/stepping/native.py builds it, fills the structures below and
 * calls wmr_loop through a view of the library that keeps the GIL: an FMU's own Python code (pythonfmu)
 * and the callbacks take it recursively).
 *
 * It does what the generated Python loop (cosim/stepping/generated.py) does, call for call and operation
 * for operation, so that a run is bit for bit the same through either:
 *   - the time of step k is t0 + (double)k * h; the last step's length h_last where the run's stop time
 *     is not on the grid;
 *   - an input copy is src[slot] where factor is 1 and offset 0, else src[slot] * factor + offset (no
 *     fused multiply-add: the build passes -ffp-contract=off);
 *   - with check_inputs, the copies' values summed left to right: a sum x with x - x != 0 is a non-finite
 *     input, reported with that sum;
 *   - a call that returns a status other than 0 (fmi2OK, fmi3OK) ends the segment with that status;
 *   - the row is taken (the recording) after every step where it is due: every decimation-th point, the
 *     last point, and where an FMU ended the simulation; copied whole, or written as the record of
 *     signals.npy (its columns converted in C) into the recording's buffer.
 * Each of an instance's set, step and get is either an FMI function called directly (FMI 2.0 or 3.0
 * signatures, as its fast path's tails give the extra arguments) or a callback into Python (a Model
 * Exchange instance's integration, an isolated instance, a timed call). */
#include <stddef.h>
#include <stdint.h>
#include <string.h>
#include <time.h>

typedef int (*set2_t)(void *, const unsigned *, size_t, const double *);
typedef int (*step2_t)(void *, double, double, int);
typedef int (*set3_t)(void *, const unsigned *, size_t, const double *, size_t);
typedef int (*step3_t)(void *, double, double, _Bool, _Bool *, _Bool *, _Bool *, double *);
typedef int (*cb_io_t)(void);
typedef int (*cb_step_t)(double, double);
typedef int (*cb_feed_t)(long);
typedef int (*cb_take_t)(long, int);

/* what ended a segment: wmr_loop's return value and Loop.f_call */
enum { OK = 0, FAILED = 1, PYTHON = 2 };   /* PYTHON: a callback raised, or made the failure itself */
enum { C_TABLE = 1, C_NONFINITE, C_SET, C_CONNECTION, C_STEP, C_GET, C_RECORDED, C_TERMINATED };

typedef struct {
    int abi;                  /* 2 or 3: the FMI version of the direct calls */
    void *c;                  /* the instance's handle */
    void *set, *step, *get;   /* FMI functions, or callbacks where raw_* is 0 */
    int raw_set, raw_step, raw_get;
    unsigned *in_vr; size_t n_in; double *in_val; size_t n_in_values;
    unsigned *out_vr; size_t n_out; double *out_val; size_t n_out_values;
    int no_set_prior;         /* DoStep's noSetFMUStatePriorToCurrentPoint */
    _Bool *flags[3];          /* fmi3DoStep: eventHandlingNeeded, terminateSimulation, earlyReturn */
    double *last_success;     /* fmi3DoStep: lastSuccessfulTime */
    _Bool *terminated;        /* set by a step after which the FMU ended the simulation (NULL: never) */
    double *last_time;        /* ... and its last successful time */
    int n_copies;
    int *pos; double **src; long *slot; double *factor; double *offset; int *plain;
    cb_feed_t feed;           /* the tabulated inputs of step k (NULL: none) */
    int n_other; cb_io_t *other;   /* the other connections (NULL: none) */
    long dec;                 /* multi-rate: it steps every dec base steps, over dec h */
    long taken; double spent; /* multi-rate: its steps taken, and their wall time [s] */
} Inst;

typedef struct {
    int n; Inst *inst;
    int simultaneous;         /* 0: Gauss-Seidel, 1: Jacobi (every instance sees the previous step's outputs) */
    int check_inputs;
    double t0, h, h_last; long k_last;   /* k_last < 0: every step is h */
    /* the recording: the row (doubles first: row[0] the time), copied to rec after every recorded step */
    double *row; size_t row_bytes;
    long decimation, n_steps; int has_stop; double stop;
    cb_take_t getters;        /* reads the recorded outputs of other types into the row (NULL: none); or,
                                 where the recording is not a row to copy, takes the point itself */
    char *rec; long rec_cap, rec_n;   /* rec NULL: no row copied */
    /* the failure: at step f_step, instance f_inst, call f_call (C_*), FMI status or value f_value, at
     * the time f_time [s] (multi-rate: its failures carry their time, as the stepper's) */
    long f_step; int f_inst; int f_call; double f_value; double f_time;
    int multirate;            /* the instances at their rates (Inst.dec), as cosim/stepping/multirate.py */
    /* the recording's rows as records (n_cols > 0): in place of the row, each recorded column converted
     * from the row (bytes col_src[j], a double or a 64-bit integer) to its type in signals.npy (col_kind[j],
     * REC_*) at byte col_dst[j] of a record of rec_bytes, written at rec; the first non-finite value of a
     * column taken from a double noted (bad_row: the record's index from rec, -1: none; bad_col: the
     * column), the segment going on as the Python flush would */
    int n_cols; int *col_src; int *col_kind; int *col_dst; size_t rec_bytes;
    long bad_row; int bad_col;
} Loop;

/* a recorded column's type in signals.npy, from a double (F8, F4) or from a 64-bit integer (the rest) */
enum { REC_F8, REC_F4, REC_I1, REC_I2, REC_I4, REC_I8, REC_U1, REC_U2, REC_U4, REC_U8, REC_BOOL };

static double now_s(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static int fail(Loop *L, long k, int i, int call, double value) {
    L->f_step = k; L->f_inst = i; L->f_call = call; L->f_value = value;
    return FAILED;
}

static int fail_at(int s, Loop *L, double t) {   /* a failure of the multi-rate passes: its time */
    if (s == FAILED) L->f_time = t;
    return s;
}

/* instance i's inputs of step k: tables, copies (checked), the set, the other connections */
static int inputs(Loop *L, int i, long k) {
    Inst *p = &L->inst[i];
    int s, j;
    if (p->feed) {
        s = p->feed(k);
        if (s < 0) return PYTHON;
        if (s) return fail(L, k, i, C_TABLE, s);
    }
    if (p->n_copies) {
        /* (each value written where the set reads it; on a non-finite sum the segment ends before the set) */
        double x = 0.0, v;
        for (j = 0; j < p->n_copies; j++) {
            v = p->plain[j] ? p->src[j][p->slot[j]] : p->src[j][p->slot[j]] * p->factor[j] + p->offset[j];
            p->in_val[p->pos[j]] = v;
            x = j ? x + v : v;
        }
        if (L->check_inputs && x - x != 0.0) return fail(L, k, i, C_NONFINITE, x);
        if (!p->raw_set) s = ((cb_io_t)p->set)();
        else if (p->abi == 2) s = ((set2_t)p->set)(p->c, p->in_vr, p->n_in, p->in_val);
        else s = ((set3_t)p->set)(p->c, p->in_vr, p->n_in, p->in_val, p->n_in_values);
        if (s < 0) return PYTHON;
        if (s) return fail(L, k, i, C_SET, s);
    }
    for (j = 0; j < p->n_other; j++) {
        s = p->other[j]();
        if (s < 0) return PYTHON;
        if (s) return fail(L, k, i, C_CONNECTION, s);
    }
    return OK;
}

static int step(Loop *L, int i, long k, double t, double h, int *ended, double *ended_at) {
    Inst *p = &L->inst[i];
    int s;
    if (!p->raw_step) s = ((cb_step_t)p->step)(t, h);
    else if (p->abi == 2) s = ((step2_t)p->step)(p->c, t, h, p->no_set_prior);
    else s = ((step3_t)p->step)(p->c, t, h, (_Bool)p->no_set_prior, p->flags[0], p->flags[1], p->flags[2],
                                 p->last_success);
    if (s < 0) return PYTHON;
    if (s) return fail(L, k, i, C_STEP, s);
    if (p->terminated && *p->terminated) { *ended = i; *ended_at = *p->last_time; }
    return OK;
}

static int outputs(Loop *L, int i, long k) {
    Inst *p = &L->inst[i];
    int s;
    if (!p->n_out) return OK;
    if (!p->raw_get) s = ((cb_io_t)p->get)();
    else if (p->abi == 2) s = ((set2_t)p->get)(p->c, p->out_vr, p->n_out, p->out_val);
    else s = ((set3_t)p->get)(p->c, p->out_vr, p->n_out, p->out_val, p->n_out_values);
    if (s < 0) return PYTHON;
    if (s) return fail(L, k + 1, i, C_GET, s);
    return OK;
}

/* the row as the record rec_n: each column converted as numpy converts it (C casts: an integer truncated to
 * its width, a double rounded to a float, a Boolean any non-zero value), memcpy for the packed layout */
static void record(Loop *L) {
    char *rec = L->rec + (size_t)L->rec_n * L->rec_bytes, *row = (char *)L->row;
    int j;
    for (j = 0; j < L->n_cols; j++) {
        char *src = row + L->col_src[j], *dst = rec + L->col_dst[j];
        double x; int64_t v;
        if (L->col_kind[j] <= REC_F4) {
            memcpy(&x, src, sizeof x);
            if (L->bad_row < 0 && x - x != 0.0) { L->bad_row = L->rec_n; L->bad_col = j; }
            if (L->col_kind[j] == REC_F8) memcpy(dst, &x, 8);
            else { float f = (float)x; memcpy(dst, &f, 4); }
            continue;
        }
        memcpy(&v, src, sizeof v);
        switch (L->col_kind[j]) {
        case REC_I1: { int8_t w = (int8_t)v; memcpy(dst, &w, 1); break; }
        case REC_I2: { int16_t w = (int16_t)v; memcpy(dst, &w, 2); break; }
        case REC_I4: { int32_t w = (int32_t)v; memcpy(dst, &w, 4); break; }
        case REC_I8: memcpy(dst, &v, 8); break;
        case REC_U1: { uint8_t w = (uint8_t)v; memcpy(dst, &w, 1); break; }
        case REC_U2: { uint16_t w = (uint16_t)v; memcpy(dst, &w, 2); break; }
        case REC_U4: { uint32_t w = (uint32_t)v; memcpy(dst, &w, 4); break; }
        case REC_U8: { uint64_t w = (uint64_t)v; memcpy(dst, &w, 8); break; }
        default: { _Bool w = v != 0; memcpy(dst, &w, 1); break; }
        }
    }
}

/* the recording's take of the point k (the row copied when it is due) */
static int take(Loop *L, long k, int ended) {
    if (L->decimation != 1 && k % L->decimation && k != L->n_steps && !ended) return OK;
    if (L->row) L->row[0] = (k == L->n_steps && L->has_stop) ? L->stop : L->t0 + (double)k * L->h;
    if (L->getters && L->getters(k, ended)) return PYTHON;   /* (Python made the failure, or raised) */
    if (L->rec) {
        if (L->rec_n >= L->rec_cap) return PYTHON;   /* (cannot happen: the buffer is sized for the segment) */
        if (L->n_cols) record(L);
        else memcpy(L->rec + (size_t)L->rec_n * L->row_bytes, L->row, L->row_bytes);
        L->rec_n++;
    }
    return OK;
}

/* multi-rate, Gauss-Seidel: in the plan's order, an instance takes its step from t_{k+1-d} in the base
 * step k that ends it, its inputs as they are then; Jacobi: the instances whose step starts at t_k take
 * their inputs, then step, then those whose step ends at t_{k+1} give their outputs */
static int pass_rates(Loop *L, long k, double t, double h) {
    int i, s, dummy = -1;
    double dummy_at = 0.0, w;
    for (i = 0; i < L->n; i++) {
        Inst *p = &L->inst[i];
        long d = p->dec, k0 = k + 1 - d;
        double t0;
        if (L->simultaneous) {
            if (k % d) continue;
            if ((s = fail_at(inputs(L, i, k), L, t))) return s;
            continue;
        }
        if ((k + 1) % d) continue;
        t0 = d == 1 ? t : L->t0 + (double)k0 * L->h;
        if ((s = fail_at(inputs(L, i, k0), L, t0))) return s;
        w = now_s();
        s = step(L, i, k0, t0, (double)d * h, &dummy, &dummy_at);
        p->spent += now_s() - w;
        if ((s = fail_at(s, L, t0))) return s;
        if ((s = fail_at(outputs(L, i, k), L, t + h))) return s;
        p->taken++;
    }
    if (!L->simultaneous) return OK;
    for (i = 0; i < L->n; i++) {
        Inst *p = &L->inst[i];
        if (k % p->dec) continue;
        w = now_s();
        s = step(L, i, k, t, (double)p->dec * h, &dummy, &dummy_at);
        p->spent += now_s() - w;
        if ((s = fail_at(s, L, t))) return s;
        p->taken++;
    }
    for (i = 0; i < L->n; i++)
        if ((k + 1) % L->inst[i].dec == 0 && (s = fail_at(outputs(L, i, k), L, t + h))) return s;
    return OK;
}

/* multi-rate: after the pass, the first instance (in the plan's order) that has ended the simulation */
static int first_ended(Loop *L, double *at) {
    int i;
    for (i = 0; i < L->n; i++)
        if (L->inst[i].terminated && *L->inst[i].terminated) { *at = *L->inst[i].last_time; return i; }
    return -1;
}

int wmr_loop(Loop *L, long k0, long k1) {
    long k;
    int i, s;
    for (k = k0; k < k1; k++) {
        double t = L->t0 + (double)k * L->h;
        double h = (k == L->k_last) ? L->h_last : L->h;
        int ended = -1;
        double ended_at = 0.0;
        if (L->multirate) {
            if ((s = pass_rates(L, k, t, h))) return s;
            ended = first_ended(L, &ended_at);
        } else if (L->simultaneous) {
            for (i = 0; i < L->n; i++) if ((s = inputs(L, i, k))) return s;
            for (i = 0; i < L->n; i++) if ((s = step(L, i, k, t, h, &ended, &ended_at))) return s;
            for (i = 0; i < L->n; i++) if ((s = outputs(L, i, k))) return s;
        } else {
            for (i = 0; i < L->n; i++) {
                if ((s = inputs(L, i, k))) return s;
                if ((s = step(L, i, k, t, h, &ended, &ended_at))) return s;
                if ((s = outputs(L, i, k))) return s;
            }
        }
        if ((s = take(L, k + 1, ended >= 0))) { L->f_step = k + 1; return s; }
        if (ended >= 0) return fail(L, k + 1, ended, C_TERMINATED, ended_at);
    }
    return OK;
}

/* the layout check: the size of the structures as this build sees them */
size_t wmr_loop_sizes(int which) { return which == 0 ? sizeof(Inst) : sizeof(Loop); }
