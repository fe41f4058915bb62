/* The step slot of an isolated C FMU, both sides in C (cosim/instances/slot_c.py builds it, fills the
 * structures below and calls these functions through ctypes):
 *   - the child's side, wmr_slot_serve: in the child process (python -m cosim.instances.isolation), the
 *     FMU's own functions called on the slot's values (set, step, get, as the compiled loop calls them in
 *     process), request after request, with no Python between them, until the master sends a request on
 *     the control channel (then the child's Python answers it) or goes;
 *   - the master's side, wmr_slot_set / wmr_slot_step / wmr_slot_get: the FMI 2.0 signatures of an
 *     instance's fast path, so that the master's compiled loop calls them directly (c: a Parent).
 * A request is a number: the master writes the time, the step and the kind, then the count of requests
 * (req); the child answers with the status and the outputs, then the count answered (done).  C11 atomics
 * (sequentially consistent) order the values before the counts on both sides.  How each side waits for
 * the other is what the master's hand-off chooses (the slot's spin word, cosim/instances/handoff.py): poll
 * the count for a while (spin > 0: the core kept, about SPIN_S a poll; spin < 0: sched_yield between
 * polls), then block: the waiter says it sleeps (its asleep word), reads the count once more and waits in
 * poll() on its pipe; the other side, after writing a count, writes a byte on that pipe if the waiter says
 * it sleeps (the two words checked crosswise: no wake-up lost).  A child that dies closes its pipe's end:
 * the master's poll() returns at once (end of file); a child that takes longer than the timeout is found
 * hung.  Either is returned as a status of its own (LOST_*), which the master's Python reports. */
#include <errno.h>
#include <math.h>
#include <poll.h>
#include <sched.h>
#include <stdatomic.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

typedef int (*set2_t)(void *, const unsigned *, size_t, const double *);
typedef int (*get2_t)(void *, const unsigned *, size_t, double *);
typedef int (*step2_t)(void *, double, double, int);
typedef int (*set3_t)(void *, const unsigned *, size_t, const double *, size_t);
typedef int (*get3_t)(void *, const unsigned *, size_t, double *, size_t);
typedef int (*step3_t)(void *, double, double, _Bool, _Bool *, _Bool *, _Bool *, double *);
typedef int (*pre_t)(void);
typedef long (*tick_t)(long, long);
typedef int (*gil_ensure_t)(void);
typedef void (*gil_release_t)(int);
typedef int (*int_call_t)(void);
typedef void (*void_call_t)(void);

enum { REQ_STEP = 0, REQ_SET = 1, REQ_GET = 2 };
/* the child died (its process ended) or did not answer within the timeout; the master's wait interrupted
 * (Ctrl-C, its handler raised): not FMI statuses */
enum { LOST_DIED = 1001, LOST_HUNG = 1002, INTERRUPTED = 1003 };
/* a step after which an FMI 3.0 FMU ended the simulation (isolation.py SLOT_TERMINATED) */
enum { SLOT_TERMINATED = 100 };
#define SPIN_S 0.25e-6   /* [s] a poll of a spinning wait (200 polls: 50 us) */
#define MAX_BACKOFF 256   /* waits that block at once after spins that ran out, at most */

typedef struct {         /* the slot's header (isolation.py _HEAD), as the Python child reads it too */
    int64_t status; double t, h; int64_t spin;
} Head;

typedef struct {         /* the slot's own words, after its values; the master's and the child's apart */
    _Atomic uint64_t req;            /* requests the master has made */
    int64_t kind;                    /* the last one's kind: REQ_* */
    _Atomic int32_t master_asleep;   /* the master waits in poll(): the child writes a byte after answering */
    char pad[44];
    _Atomic uint64_t done;           /* requests the child has answered */
    _Atomic int32_t child_asleep;    /* the child waits in poll() or is in Python: the master writes a byte */
    char pad2[52];
} Words;

typedef struct {         /* a side's spins that ran out: the next `skip` waits block at once (doubled each
                            time, up to MAX_BACKOFF, until a spin is answered): where the other side has
                            no core of its own, polling for it only keeps it from running */
    int skip, backoff;
} Backoff;

typedef struct {         /* the master's side of one child */
    Head *head; Words *w; double *out; size_t out_bytes;
    int step_w, done_r;
    double timeout;      /* [s] the longest wait for an answer; < 0: none */
    int stepping;        /* the step loop has begun: the child sets the inputs with each step */
    int fresh;           /* the last step left the outputs in the slot */
    _Bool *terminated; double *last_time;   /* FMI 3.0: the FMU ended the simulation, and when */
    double t;            /* [s] the time of the last step requested */
    int lost;            /* LOST_* once the child is lost (every call then returns it) */
    uint64_t seq;        /* requests made */
    tick_t tick;         /* the hand-off's measure, called before a step's request when left is 0 */
    long left, skipped, ran_out;
    Backoff backoff;
    /* Python's PyGILState_Ensure, PyGILState_Release, PyErr_CheckSignals, PyErr_Clear (NULL: none), so
     * that a signal whose handler raises (a second Ctrl-C) ends a wait as it ends the Python child's */
    void *gil_ensure, *gil_release, *check_signals, *err_clear;
} Parent;

typedef struct {         /* the child's side: the FMU's functions on the slot */
    Head *head; Words *w; double *in, *out;
    int s_r, d_w, ctl_r;
    int abi; void *c; void *set, *step, *get;
    unsigned *in_vr; size_t n_in, n_in_values;
    unsigned *out_vr; size_t n_out, n_out_values;
    int no_set_prior;
    pre_t pre;           /* before the next step's DoStep, after its inputs, once (the inputs' derivatives) */
    uint64_t last;       /* the last request answered */
    _Bool flags[3]; double last_success;   /* fmi3DoStep's outputs */
    Backoff backoff;
} Served;

static double now_s(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static inline void relax(void) {
#if defined(__x86_64__) || defined(__i386__)
    __builtin_ia32_pause();
#elif defined(__aarch64__)
    __asm__ __volatile__("yield");
#endif
}

/* poll *word until it is no longer old: 1 when it changed, 0 when the polls ran out */
static int spin_wait(_Atomic uint64_t *word, uint64_t old, int64_t spin) {
    long i;
    double end;
    if (spin < 0) {
        for (i = 0; i < -spin; i++) {
            if (atomic_load(word) != old) return 1;
            sched_yield();
        }
        return atomic_load(word) != old;
    }
    if (spin == 0) return 0;
    end = now_s() + (double)spin * SPIN_S;
    for (i = 0;; i++) {
        if (atomic_load(word) != old) return 1;
        if ((i & 63) == 63 && now_s() > end) return 0;
        relax();
    }
}

/* the polls of the next wait: none while the spins back off */
static int64_t spin_budget(Backoff *b, int64_t spin) {
    if (!spin) return 0;
    if (b->skip > 0) {
        b->skip--;
        return 0;
    }
    return spin;
}

/* a wait's spin was answered (ok) or ran out */
static void spin_result(Backoff *b, int ok) {
    if (ok) {
        b->backoff = 0;
        return;
    }
    b->backoff = b->backoff ? (2 * b->backoff < MAX_BACKOFF ? 2 * b->backoff : MAX_BACKOFF) : 1;
    b->skip = b->backoff;
}

/* read what is on a non-blocking pipe: 0 at its end (the other side gone), else 1 */
static int drain(int fd) {
    char buf[64];
    for (;;) {
        ssize_t n = read(fd, buf, sizeof buf);
        if (n > 0) continue;
        if (n == 0) return 0;
        if (errno == EINTR) continue;
        return 1;   /* EAGAIN: nothing more */
    }
}

/* a signal interrupted the master's wait: whether its Python handler raised (the exception cleared: the
 * master's Python raises KeyboardInterrupt on INTERRUPTED) */
static int raised(const Parent *p) {
    int g, r;
    if (!p || !p->check_signals) return 0;
    g = ((gil_ensure_t)p->gil_ensure)();
    r = ((int_call_t)p->check_signals)();
    if (r < 0) ((void_call_t)p->err_clear)();
    ((gil_release_t)p->gil_release)(g);
    return r < 0;
}

/* block until *word is no longer old: 0 it changed, 1 the pipe fd ended, 2 timed out, 3 the pipe other
 * (the child's control channel; -1: none) has a request (asleep then stays set), 4 a signal's handler
 * raised (the master's, p) */
static int block_wait(_Atomic uint64_t *word, uint64_t old, _Atomic int32_t *asleep, int fd, int other,
                      double timeout, const Parent *p) {
    struct pollfd fds[2] = {{fd, POLLIN, 0}, {other, POLLIN, 0}};
    double end = timeout >= 0 ? now_s() + timeout : 0.0;
    int r, ms = -1;
    atomic_store(asleep, 1);
    for (;;) {
        if (atomic_load(word) != old) { r = 0; break; }
        if (timeout >= 0) {
            double left = end - now_s();
            if (left <= 0) { r = 2; break; }
            ms = (int)ceil(left * 1e3);
        }
        r = poll(fds, other >= 0 ? 2 : 1, ms);
        if (r < 0 && errno == EINTR && raised(p)) { r = 4; break; }
        if (r < 0 && errno != EINTR) { r = 1; break; }
        if (r <= 0) continue;
        if (fds[0].revents && !drain(fd)) { r = atomic_load(word) != old ? 0 : 1; break; }
        if (other >= 0 && fds[1].revents && atomic_load(word) == old) return 3;
    }
    atomic_store(asleep, 0);
    return r;
}

/* ---------------------------------------------------------------------------------- the child's side */
static int set_in(Served *s) {
    if (!s->n_in) return 0;
    if (s->abi == 2) return ((set2_t)s->set)(s->c, s->in_vr, s->n_in, s->in);
    return ((set3_t)s->set)(s->c, s->in_vr, s->n_in, s->in, s->n_in_values);
}

static int get_out(Served *s) {
    if (!s->n_out) return 0;
    if (s->abi == 2) return ((get2_t)s->get)(s->c, s->out_vr, s->n_out, s->out);
    return ((get3_t)s->get)(s->c, s->out_vr, s->n_out, s->out, s->n_out_values);
}

/* set the inputs (and the derivatives given for this step), step, get the outputs: as the Python child's
 * step (isolation.py _Server.step), status for status */
static int step_once(Served *s) {
    double t = s->head->t, h = s->head->h;
    int st = set_in(s);
    if (st) return st;
    if (s->pre) {
        pre_t pre = s->pre;
        s->pre = NULL;
        if ((st = pre())) return st;
    }
    if (s->abi == 2) {
        st = ((step2_t)s->step)(s->c, t, h, s->no_set_prior);
    } else {
        st = ((step3_t)s->step)(s->c, t, h, (_Bool)s->no_set_prior, &s->flags[0], &s->flags[1], &s->flags[2],
                                &s->last_success);
        if (!st && s->flags[1]) {   /* its last successful time in the slot's time; outputs not read */
            s->head->t = isfinite(s->last_success) ? s->last_success : t + h;
            return SLOT_TERMINATED;
        }
    }
    if (st) return st;
    return get_out(s);
}

static void answer(Served *s, uint64_t r) {
    int64_t kind = s->w->kind;
    int st = kind == REQ_STEP ? step_once(s) : kind == REQ_SET ? set_in(s) : get_out(s);
    ssize_t n;
    s->head->status = st;
    s->last = r;
    atomic_store(&s->w->done, r);
    if (atomic_load(&s->w->master_asleep))
        do n = write(s->d_w, "d", 1); while (n < 0 && errno == EINTR);   /* (the master gone: EPIPE) */
}

/* answer the master's requests until it sends one on the control channel (1) or goes (0) */
int wmr_slot_serve(Served *s) {
    Words *w = s->w;
    if (!drain(s->s_r)) return 0;
    atomic_store(&w->child_asleep, 0);
    for (;;) {
        uint64_t r = atomic_load(&w->req);
        int64_t polls;
        if (r != s->last) { answer(s, r); continue; }
        if ((polls = spin_budget(&s->backoff, s->head->spin))) {
            int ok = spin_wait(&w->req, s->last, polls);
            spin_result(&s->backoff, ok);
            if (ok) continue;
        }
        switch (block_wait(&w->req, s->last, &w->child_asleep, s->s_r, s->ctl_r, -1.0, NULL)) {
        case 0: continue;
        case 3: return 1;
        default: return 0;
        }
    }
}

/* --------------------------------------------------------------------------------- the master's side */
static int request(Parent *p, int kind) {
    Words *w = p->w;
    ssize_t n;
    if (p->lost) return p->lost;
    w->kind = kind;
    atomic_store(&w->req, ++p->seq);
    if (atomic_load(&w->child_asleep)) {
        do n = write(p->step_w, "s", 1); while (n < 0 && errno == EINTR);
        if (n < 0 && errno != EAGAIN) return p->lost = LOST_DIED;   /* EPIPE: nobody reads */
    }
    return 0;
}

/* the answer to the last request: its status (or LOST_*); spin 0: block at once */
static int await_answer(Parent *p, int spin) {
    Words *w = p->w;
    int64_t polls = spin ? spin_budget(&p->backoff, p->head->spin) : 0;
    int r;
    if (p->lost) return p->lost;
    if (polls) {
        int ok = spin_wait(&w->done, p->seq - 1, polls);
        spin_result(&p->backoff, ok);
        if (ok) return (int)p->head->status;
        p->ran_out++;
    }
    r = block_wait(&w->done, p->seq - 1, &w->master_asleep, p->done_r, -1, p->timeout, p);
    if (r == 1) return p->lost = LOST_DIED;
    if (r == 2) return p->lost = LOST_HUNG;
    if (r == 4) return INTERRUPTED;   /* (the run ends: the child's answer is not awaited) */
    return (int)p->head->status;
}

/* a step's request (the hand-off measured first, as isolation.py Child.start): 0, or LOST_*, or -1 when
 * the measure raised */
int wmr_slot_start(Parent *p, double t, double h) {
    p->head->t = t;
    p->head->h = h;
    p->t = t;
    p->stepping = 1;
    if (p->tick) {
        if (p->left > 0) {
            p->left--;
            p->skipped++;
        } else {
            long n = p->tick(p->skipped, p->ran_out);
            p->skipped = p->ran_out = 0;
            if (n < 0) return -1;
            p->left = n;
        }
    }
    return request(p, REQ_STEP);
}

/* the answer to the step started: its status (an FMI 3.0 FMU that ended the simulation: 0, *terminated
 * set, *last_time its last successful time) */
int wmr_slot_finish(Parent *p, int spin) {
    int s = await_answer(p, spin);
    if (s == LOST_DIED || s == LOST_HUNG || s == INTERRUPTED) return s;
    p->fresh = s == 0;
    if (s == SLOT_TERMINATED && p->terminated) {
        *p->terminated = 1;
        *p->last_time = p->head->t;
        return 0;
    }
    return s;
}

int wmr_slot_step(Parent *p, double t, double h, int no_set_prior) {
    int s = wmr_slot_start(p, t, h);
    (void)no_set_prior;   /* (the child's instance steps as it was told: allow_rollback) */
    return s ? s : wmr_slot_finish(p, 1);
}

/* the inputs are in the slot already: the child sets them with the step; before the first step, now */
int wmr_slot_set(Parent *p, const unsigned *vr, size_t n, const double *values) {
    int s;
    (void)vr; (void)n; (void)values;
    if (p->stepping) return 0;
    if ((s = request(p, REQ_SET))) return s;
    return await_answer(p, 1);
}

/* the outputs the last step left in the slot; before the first step, or after a step that did not read
 * them, read now */
int wmr_slot_get(Parent *p, const unsigned *vr, size_t n, double *out) {
    int s;
    (void)vr; (void)n;
    if (!p->fresh) {
        if ((s = request(p, REQ_GET))) return s;
        if ((s = await_answer(p, 1))) return s;
    }
    if (p->out_bytes) memcpy(out, p->out, p->out_bytes);
    return 0;
}

/* the layout check: the size of the structures as this build sees them */
size_t wmr_slot_sizes(int which) {
    return which == 0 ? sizeof(Words) : which == 1 ? sizeof(Parent) : sizeof(Served);
}
