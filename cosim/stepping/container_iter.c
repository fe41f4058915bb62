/* The iterated coupling inside the container (algorithm = "iterated"): cosim/stepping/iterated.py ported to
 * C, operation for operation and call for call, so that the container's outputs equal the master's bit for bit.
 * container.c #includes it (after its reader of system.txt's tokens, before the instances are read); the
 * exporter (cosim/plan/container.py, iteration_text) writes what it reads: the settings and the components of
 * the plan's graph of copies in stepping order (FeedGraph.components), each a coupling loop with its unknowns
 * (the copies of its members that read an output of the loop, in the master's order) or a single instance.
 *
 * At each step k, component by component: a single instance steps as under Gauss-Seidel (native_loop.c's
 * inputs, step, outputs); a loop's coupling inputs u solve r(u) = G(y(t + h; u)) - u = 0, where every
 * evaluation after the first restores the loop's instances (fmi2SetFMUstate of the states fmi2GetFMUstate
 * saved at t) and the row, sets every member's inputs (the unknowns in place of their copies; with inputs
 * "linear", their value at t and fmi2SetRealInputDerivatives of order 1 towards u), then steps each member and
 * reads its outputs.  The iteration (LoopSolver.solve): accepted when max_i |r_i| / (1 + |G_i|) <= tolerance;
 * fixed point u + relaxation r; Newton u + du with J du = -r, J by forward differences (or the FMUs'
 * directional derivatives), kept while the residual halves, solved by iterated.py's solve_linear (Gaussian
 * elimination with partial pivoting, the same operations in the same order).  The first guess: the loop's
 * inputs extrapolated linearly from the last two steps.  At fmi2ExitInitializationMode, after the initial
 * exchange, each loop's algebraic part is solved with sets and gets only.  A loop that does not converge ends
 * the step (or the initialisation) with fmi2Error and the master's one line. */

typedef fmi2Status (*getstate_t)(fmi2Component, fmi2FMUstate *);
typedef fmi2Status (*setstate_t)(fmi2Component, fmi2FMUstate);
typedef fmi2Status (*freestate_t)(fmi2Component, fmi2FMUstate *);
typedef fmi2Status (*setder_t)(fmi2Component, const fmi2ValueReference *, size_t, const fmi2Integer *, const fmi2Real *);
typedef fmi2Status (*dirder_t)(fmi2Component, const fmi2ValueReference *, size_t, const fmi2ValueReference *, size_t,
                               const fmi2Real *, fmi2Real *);

/* beyond wmr_loop's OK, FAILED, PYTHON: COUPLING, a failure said already; NOT_CONVERGED, the iteration's own */
enum { COUPLING = 3, NOT_CONVERGED = 4 };

/* a coupling input: instance i's input at position pos (value reference vr) takes row[slot] * factor + offset,
 * the output src_vr of instance src_i */
typedef struct { int i, pos; unsigned vr; long slot; int src_i; unsigned src_vr; double factor, offset; } IterInput;

typedef struct {
    int loop, n, *members, n_unk;
    IterInput *unk;
    char *label;                        /* "one <-> two" */
    int have_end, have_prev;            /* what the loop keeps from step to step: */
    double *u_end, *u_prev, h_prev;     /* the inputs the last two steps ended with, the last step [s] */
    int have_jac; double *jac;          /* Newton's Jacobian dr/du (row major), kept while it serves */
    double *u, *g, *r, *g0, *start, *uj, *gj, *a, *b, *col; unsigned *vrs;   /* scratch */
    fmi2FMUstate *states; double *row_saved;
} IterComp;

typedef struct Iter {
    int newton; double tol; long max_it; double relax; int linear, directional;
    int n_comps; IterComp *comps;
    int **gix;   /* per instance, per copy: the index of the unknown that replaces it in its loop, or -1 */
    getstate_t *get_state; setstate_t *set_state; freestate_t *free_state; setder_t *set_der; dirder_t *dir_der;
} Iter;

#define ITER_ALLOC(n, type) ((type *)calloc((size_t)(n) + 1, sizeof(type)))

/* the lines after the container's variables: "iteration 0", or the settings and the components */
static int iter_read(Container *s, Reader *r) {
    Iter *it;
    int c, m, x;
    expect(r, "iteration");
    if (!num(r)) return !r->bad;
    it = s->iter = ITER_ALLOC(1, Iter);
    it->newton = (int)num(r); it->tol = real(r); it->max_it = num(r); it->relax = real(r);
    it->linear = (int)num(r); it->directional = (int)num(r); it->n_comps = (int)num(r);
    if (r->bad || it->max_it < 1 || it->n_comps < 1 || it->n_comps > s->n) return 0;
    it->comps = ITER_ALLOC(it->n_comps, IterComp);
    for (c = 0; c < it->n_comps; c++) {
        IterComp *C = &it->comps[c];
        size_t len = 1;
        expect(r, "comp");
        C->loop = (int)num(r); C->n = (int)num(r);
        if (r->bad || C->n < 1 || C->n > s->n) return 0;
        C->members = ITER_ALLOC(C->n, int);
        for (m = 0; m < C->n; m++) {
            C->members[m] = (int)num(r);
            if (C->members[m] < 0 || C->members[m] >= s->n) return 0;
            len += strlen(s->inner[C->members[m]].name ? s->inner[C->members[m]].name : "") + 5;
        }
        C->n_unk = (int)num(r);
        if (r->bad || C->n_unk < 0 || (C->loop && C->n_unk < 1)) return 0;
        C->unk = ITER_ALLOC(C->n_unk, IterInput);
        for (x = 0; x < C->n_unk; x++) {
            IterInput *u = &C->unk[x];
            expect(r, "unknown");
            u->i = (int)num(r); u->pos = (int)num(r); u->vr = (unsigned)num(r); u->slot = num(r);
            u->src_i = (int)num(r); u->src_vr = (unsigned)num(r); u->factor = real(r); u->offset = real(r);
            if (u->i < 0 || u->i >= s->n || u->src_i < 0 || u->src_i >= s->n || u->slot < 0 || u->slot >= s->n_row)
                return 0;
        }
        C->label = calloc(len, 1);
        for (m = 0; m < C->n; m++) {
            if (m) strcat(C->label, " <-> ");
            strcat(C->label, s->inner[C->members[m]].name ? s->inner[C->members[m]].name : "");
        }
#define SCRATCH(f) C->f = ITER_ALLOC(C->n_unk, double);
        SCRATCH(u_end) SCRATCH(u_prev) SCRATCH(u) SCRATCH(g) SCRATCH(r) SCRATCH(g0) SCRATCH(start) SCRATCH(uj)
        SCRATCH(gj) SCRATCH(b) SCRATCH(col)
#undef SCRATCH
        C->jac = ITER_ALLOC((long)C->n_unk * C->n_unk, double); C->a = ITER_ALLOC((long)C->n_unk * C->n_unk, double);
        C->vrs = ITER_ALLOC(C->n_unk, unsigned);
        C->states = ITER_ALLOC(C->n, fmi2FMUstate); C->row_saved = ITER_ALLOC(s->n_row, double);
    }
    return !r->bad;
}

/* after the instances are read: which copy each unknown replaces */
static int iter_link(Container *s) {
    Iter *it = s->iter;
    int c, x, i, j, found;
    if (!it) return 1;
    it->gix = ITER_ALLOC(s->n, int *);
    for (i = 0; i < s->n; i++) {
        it->gix[i] = ITER_ALLOC(s->insts[i].n_copies, int);
        for (j = 0; j < s->insts[i].n_copies; j++) it->gix[i][j] = -1;
    }
    for (c = 0; c < it->n_comps; c++)
        for (x = 0; x < it->comps[c].n_unk; x++) {
            IterInput *u = &it->comps[c].unk[x];
            Inst *p = &s->insts[u->i];
            for (found = 0, j = 0; j < p->n_copies; j++)
                if (p->pos[j] == u->pos) { it->gix[u->i][j] = x; found = 1; }
            if (!found || (size_t)u->pos >= p->n_in || p->in_vr[u->pos] != u->vr) return 0;
        }
    return 1;
}

#ifdef _WIN32
#define ITER_LOOKUP(dll, sym) ((void *)GetProcAddress((HMODULE)(dll), sym))
#else
#define ITER_LOOKUP(dll, sym) dlsym(dll, sym)
#endif

/* after the inner FMUs are loaded: the functions of rollback (and of the options) of every loop's members,
 * their steps with noSetFMUStatePriorToCurrentPoint false (the master's allow_rollback) */
static int iter_load(Container *s) {
    Iter *it = s->iter;
    int c, m;
    if (!it) return 1;
    it->get_state = ITER_ALLOC(s->n, getstate_t); it->set_state = ITER_ALLOC(s->n, setstate_t);
    it->free_state = ITER_ALLOC(s->n, freestate_t); it->set_der = ITER_ALLOC(s->n, setder_t);
    it->dir_der = ITER_ALLOC(s->n, dirder_t);
    for (c = 0; c < it->n_comps; c++) {
        IterComp *C = &it->comps[c];
        if (!C->loop) continue;
        for (m = 0; m < C->n; m++) {
            int i = C->members[m];
            Inner *q = &s->inner[i];
            const char *missing = NULL;
            if (!(it->get_state[i] = (getstate_t)ITER_LOOKUP(q->dll, "fmi2GetFMUstate"))) missing = "fmi2GetFMUstate";
            if (!(it->set_state[i] = (setstate_t)ITER_LOOKUP(q->dll, "fmi2SetFMUstate"))) missing = "fmi2SetFMUstate";
            if (!(it->free_state[i] = (freestate_t)ITER_LOOKUP(q->dll, "fmi2FreeFMUstate"))) missing = "fmi2FreeFMUstate";
            if (it->linear && !(it->set_der[i] = (setder_t)ITER_LOOKUP(q->dll, "fmi2SetRealInputDerivatives")))
                missing = "fmi2SetRealInputDerivatives";
            if (it->directional && !(it->dir_der[i] = (dirder_t)ITER_LOOKUP(q->dll, "fmi2GetDirectionalDerivative")))
                missing = "fmi2GetDirectionalDerivative";
            if (missing) { say(s, fmi2Error, "%s: %s not found", q->name, missing); return 0; }
            s->insts[i].no_set_prior = 0;
        }
    }
    return 1;
}

static void iter_free(Container *s) {
    Iter *it = s->iter;
    int c, i;
    if (!it) return;
    for (c = 0; it->comps && c < it->n_comps; c++) {
        IterComp *C = &it->comps[c];
        free(C->members); free(C->unk); free(C->label); free(C->u_end); free(C->u_prev); free(C->jac);
        free(C->u); free(C->g); free(C->r); free(C->g0); free(C->start); free(C->uj); free(C->gj); free(C->a);
        free(C->b); free(C->col); free(C->vrs); free(C->states); free(C->row_saved);
    }
    for (i = 0; it->gix && i < s->n; i++) free(it->gix[i]);
    free(it->gix); free(it->comps);
    free(it->get_state); free(it->set_state); free(it->free_state); free(it->set_der); free(it->dir_der);
    free(it);
    s->iter = NULL;
}

/* G of the output now in the row (iterated.py: Unknown.g) */
static double iter_g(const Container *s, const IterInput *u) {
    double v = s->row[u->slot];
    return u->factor == 1.0 && u->offset == 0.0 ? v : v * u->factor + u->offset;
}

/* instance i's inputs of step k, as native_loop.c's inputs (the generated loop's), the values of its loop's
 * unknowns in place of their copies where vals is given (Stepper.set_inputs with ``given``) */
static int iter_inputs(Container *s, int i, long k, const double *vals) {
    Loop *L = &s->L;
    Inst *p = &L->inst[i];
    const int *gix = s->iter->gix[i];
    int j, st;
    double x = 0.0, v[p->n_copies + 1];
    if (!p->n_copies) return OK;
    for (j = 0; j < p->n_copies; j++)
        v[j] = p->plain[j] ? p->src[j][p->slot[j]] : p->src[j][p->slot[j]] * p->factor[j] + p->offset[j];
    if (vals)
        for (j = 0; j < p->n_copies; j++) if (gix[j] >= 0) v[j] = vals[gix[j]];
    for (j = 0; j < p->n_copies; j++) x = j ? x + v[j] : v[j];
    if (L->check_inputs && x - x != 0.0) return fail(L, k, i, C_NONFINITE, x);
    for (j = 0; j < p->n_copies; j++) p->in_val[p->pos[j]] = v[j];
    st = ((set2_t)p->set)(p->c, p->in_vr, p->n_in, p->in_val);
    if (st) return fail(L, k, i, C_SET, st);
    return OK;
}

/* one evaluation of a loop: u -> G(y(u)) into g (a step's, or at initialisation sets and gets only) */
typedef struct { Container *s; IterComp *C; long k; double t, h; int first, init; } IterEval;

static int iter_evaluate(IterEval *e, const double *u, double *g) {
    Container *s = e->s;
    Iter *it = s->iter;
    IterComp *C = e->C;
    Loop *L = &s->L;
    int m, x, st, ended = -1;
    double ended_at = 0.0;
    if (e->init) {   /* (Iterated.initialize: each member set, then read) */
        for (m = 0; m < C->n; m++) {
            if ((st = iter_inputs(s, C->members[m], 0, u))) return st;
            if ((st = outputs(L, C->members[m], -1))) return st;
        }
    } else {
        const double *vals = it->linear ? C->start : u;
        if (!e->first) {   /* back to the state at t */
            for (m = 0; m < C->n; m++) {
                Inner *q = &s->inner[C->members[m]];
                if ((st = it->set_state[C->members[m]](q->c, C->states[m]))) {
                    say(s, fmi2Error, "%s: fmi2SetFMUstate returned %d at t = %.9g s", q->name, st, e->t);
                    return COUPLING;
                }
            }
            memcpy(s->row, C->row_saved, sizeof(double) * (size_t)s->n_row);
        }
        e->first = 0;
        for (m = 0; m < C->n; m++) {
            int i = C->members[m], n = 0;
            if ((st = iter_inputs(s, i, e->k, vals))) return st;
            if (!it->linear) continue;
            /* its coupling inputs linear from their value at t to u at t + h (IteratedStep.derivatives) */
            for (x = 0; x < C->n_unk; x++)
                if (C->unk[x].i == i) { C->vrs[n] = C->unk[x].vr; C->col[n] = (u[x] - C->start[x]) / e->h; n++; }
            if (n) {
                fmi2Integer order[n];
                for (x = 0; x < n; x++) order[x] = 1;
                if ((st = it->set_der[i](s->inner[i].c, C->vrs, (size_t)n, order, C->col))) {
                    say(s, fmi2Error, "%s: fmi2SetRealInputDerivatives returned %d at t = %.9g s", s->inner[i].name,
                        st, e->t);
                    return COUPLING;
                }
            }
        }
        for (m = 0; m < C->n; m++) {
            if ((st = step(L, C->members[m], e->k, e->t, e->h, &ended, &ended_at))) return st;
            if ((st = outputs(L, C->members[m], e->k))) return st;
        }
    }
    for (x = 0; x < C->n_unk; x++) g[x] = iter_g(s, &C->unk[x]);
    return OK;
}

/* iterated.py's solve_linear: x with a x = b (a n by n, row major; both overwritten, x in b); 0 where a
 * pivot is zero */
static int iter_solve_linear(double *a, double *b, int n) {
    int c, i, j, p;
    for (c = 0; c < n; c++) {
        p = c;
        for (i = c + 1; i < n; i++) if (fabs(a[i * n + c]) > fabs(a[p * n + c])) p = i;
        if (a[p * n + c] == 0.0) return 0;
        if (p != c) {
            double w;
            for (j = 0; j < n; j++) { w = a[c * n + j]; a[c * n + j] = a[p * n + j]; a[p * n + j] = w; }
            w = b[c]; b[c] = b[p]; b[p] = w;
        }
        for (i = c + 1; i < n; i++) {
            double l = a[i * n + c] / a[c * n + c];
            for (j = c + 1; j < n; j++) a[i * n + j] = a[i * n + j] - l * a[c * n + j];
            b[i] = b[i] - l * b[c];
        }
    }
    for (i = n - 1; i >= 0; i--) {
        double v = b[i];
        for (j = i + 1; j < n; j++) v = v - a[i * n + j] * b[j];
        b[i] = v / a[i * n + i];
    }
    return 1;
}

/* dr/du = D - I from the directional derivatives of the instance owning both ends (IteratedStep.directional) */
static int iter_directional(IterEval *e, double t) {
    Container *s = e->s;
    IterComp *C = e->C;
    int n = C->n_unk, j, m, rows;
    for (m = 0; m < n; m++) for (j = 0; j < n; j++) C->jac[m * n + j] = m == j ? -1.0 : -0.0;   /* (-np.eye) */
    for (j = 0; j < n; j++) {
        const IterInput *xj = &C->unk[j];
        double seed = 1.0;
        int st;
        for (rows = 0, m = 0; m < n; m++) if (C->unk[m].src_i == xj->i) C->vrs[rows++] = C->unk[m].src_vr;
        if (!rows) continue;
        st = s->iter->dir_der[xj->i](s->inner[xj->i].c, C->vrs, (size_t)rows, &xj->vr, 1, &seed, C->col);
        if (st) {
            say(s, fmi2Error, "%s: the directional derivative returned status %d at t = %.9g s", s->inner[xj->i].name,
                st, t);
            return COUPLING;
        }
        for (rows = 0, m = 0; m < n; m++)
            if (C->unk[m].src_i == xj->i) { C->jac[m * n + j] = C->jac[m * n + j] + C->unk[m].factor * C->col[rows]; rows++; }
    }
    return OK;
}

static const char *iter_plural(long n) { return n == 1 ? "" : "s"; }

/* LoopSolver.solve: u (the guess in, the inputs accepted out), the last evaluation's outputs in the row;
 * NOT_CONVERGED with the reason in why */
static int iter_solve(IterEval *e, char *why, size_t n_why) {
    Container *s = e->s;
    Iter *it = s->iter;
    IterComp *C = e->C;
    int n = C->n_unk, x, j, st;
    long itn;
    const char *method = it->newton ? "newton" : "fixed-point";
    double err, err_prev = INFINITY;
    for (itn = 1; itn <= it->max_it; itn++) {
        if ((st = iter_evaluate(e, C->u, C->g))) return st;
        for (x = 0; x < n; x++) C->r[x] = C->g[x] - C->u[x];
        err = 0.0;
        for (x = 0; x < n; x++) {
            double ex = fabs(C->r[x]) / (1.0 + fabs(C->g[x]));
            if (x == 0 || ex > err) err = ex;   /* (Python's max: the first, then each larger one) */
        }
        if (err <= it->tol) return OK;
        if (!isfinite(err)) {
            snprintf(why, n_why, "the iterate is no longer finite after %ld iteration%s (%s)", itn, iter_plural(itn), method);
            return NOT_CONVERGED;
        }
        if (itn == it->max_it) {
            snprintf(why, n_why, "residual %.3g after %ld iteration%s (%s, tolerance %g)", err, itn, iter_plural(itn),
                     method, it->tol);
            return NOT_CONVERGED;
        }
        if (!it->newton) {
            for (x = 0; x < n; x++) C->u[x] = C->u[x] + it->relax * C->r[x];
        } else {
            if (!C->have_jac || err > 0.5 * err_prev) {
                if (it->directional) {
                    if ((st = iter_directional(e, e->init ? e->t : e->t + e->h))) return st;
                } else {   /* forward differences at u (LoopSolver.jacobian) */
                    for (j = 0; j < n; j++) {
                        double au = fabs(C->u[j]);
                        double d = 1.4901161193847656e-08 * (au > 1.0 ? au : 1.0);
                        memcpy(C->uj, C->u, sizeof(double) * (size_t)n);
                        C->uj[j] = C->uj[j] + d;
                        if ((st = iter_evaluate(e, C->uj, C->gj))) return st;
                        for (x = 0; x < n; x++) C->jac[x * n + j] = ((C->gj[x] - C->uj[x]) - C->r[x]) / d;
                    }
                }
                C->have_jac = 1;
            }
            memcpy(C->a, C->jac, sizeof(double) * (size_t)n * (size_t)n);
            for (x = 0; x < n; x++) C->b[x] = -C->r[x];
            if (!iter_solve_linear(C->a, C->b, n)) {
                snprintf(why, n_why, "the Jacobian is singular after %ld iteration%s (newton)", itn, iter_plural(itn));
                return NOT_CONVERGED;
            }
            for (x = 0; x < n; x++) C->u[x] = C->u[x] + C->b[x];
        }
        for (x = 0; x < n; x++)
            if (!isfinite(C->u[x])) {
                snprintf(why, n_why, "the iterate is no longer finite after %ld iteration%s (%s)", itn, iter_plural(itn),
                         method);
                return NOT_CONVERGED;
            }
        err_prev = err;
    }
    return NOT_CONVERGED;   /* (unreachable: the last iteration returns) */
}

/* IteratedStep.loop_step: the loop C from t over h */
static int iter_loop_step(Container *s, IterComp *C, long k, double t, double h) {
    Iter *it = s->iter;
    int n = C->n_unk, m, x, st;
    char why[256];
    IterEval e = {s, C, k, t, h, 1, 0};
    for (x = 0; x < n; x++) C->g0[x] = iter_g(s, &C->unk[x]);
    memcpy(C->start, C->have_end ? C->u_end : C->g0, sizeof(double) * (size_t)n);
    if (C->have_end && C->have_prev && C->h_prev > 0.0) {
        double sc = h / C->h_prev;
        for (x = 0; x < n; x++) C->u[x] = C->u_end[x] + (C->u_end[x] - C->u_prev[x]) * sc;
    } else {
        memcpy(C->u, C->g0, sizeof(double) * (size_t)n);
    }
    for (m = 0; m < C->n; m++) {   /* (Stepper.save: the states, then the row) */
        Inner *q = &s->inner[C->members[m]];
        C->states[m] = NULL;
        if ((st = it->get_state[C->members[m]](q->c, &C->states[m]))) {
            say(s, fmi2Error, "%s: fmi2GetFMUstate returned %d at t = %.9g s", q->name, st, t);
            while (m-- > 0) it->free_state[C->members[m]](s->inner[C->members[m]].c, &C->states[m]);
            return COUPLING;
        }
    }
    memcpy(C->row_saved, s->row, sizeof(double) * (size_t)s->n_row);
    st = iter_solve(&e, why, sizeof why);
    for (m = 0; m < C->n; m++) it->free_state[C->members[m]](s->inner[C->members[m]].c, &C->states[m]);
    if (st == NOT_CONVERGED) {
        say(s, fmi2Error, "the coupling loop %s did not converge at step %ld (t = %.9g s, h = %.6g s): %s", C->label, k,
            t, h, why);
        return COUPLING;
    }
    if (st) return st;
    memcpy(C->u_prev, C->start, sizeof(double) * (size_t)n);
    memcpy(C->u_end, C->u, sizeof(double) * (size_t)n);
    C->h_prev = h; C->have_prev = C->have_end = 1;
    return OK;
}

/* the steps k0 .. k1 - 1 (IteratedStep.step): each component in turn, a loop iterated, an instance alone
 * set, stepped and read */
static int iter_loop(Container *s, long k0, long k1) {
    Loop *L = &s->L;
    Iter *it = s->iter;
    long k;
    int c, st, ended = -1;
    double ended_at = 0.0;
    for (k = k0; k < k1; k++) {
        double t = L->t0 + (double)k * L->h, h = L->h;
        for (c = 0; c < it->n_comps; c++) {
            IterComp *C = &it->comps[c];
            if (C->loop) {
                if ((st = iter_loop_step(s, C, k, t, h))) return st;
                continue;
            }
            if ((st = inputs(L, C->members[0], k))) return st;
            if ((st = step(L, C->members[0], k, t, h, &ended, &ended_at))) return st;
            if ((st = outputs(L, C->members[0], k))) return st;
        }
    }
    return OK;
}

/* Iterated.initialize: in initialisation mode, after the initial exchange, each loop's algebraic part at t0
 * (sets and gets, no step, no state); 0, said, where one fails */
static int iter_initialize(Container *s) {
    Iter *it = s->iter;
    int c, st;
    char why[256];
    if (!it) return 1;
    for (c = 0; c < it->n_comps; c++) {
        IterComp *C = &it->comps[c];
        IterEval e = {s, C, 0, s->t0, 0.0, 1, 1};
        int x;
        if (!C->loop) continue;
        for (x = 0; x < C->n_unk; x++) C->u[x] = iter_g(s, &C->unk[x]);
        st = iter_solve(&e, why, sizeof why);
        C->have_jac = 0;   /* (the Jacobian of the algebraic part alone is not the step's) */
        if (st == NOT_CONVERGED) {
            say(s, fmi2Error, "the coupling loop %s did not converge at initialisation (t = %.9g s): %s", C->label,
                s->t0, why);
            return 0;
        }
        if (st == FAILED) {
            say(s, fmi2Error, "%s: the initialisation of the coupling loop %s failed (call %d, status or value %g)",
                s->inner[s->L.f_inst].name, C->label, s->L.f_call, s->L.f_value);
            return 0;
        }
        if (st) return 0;
    }
    return 1;
}
