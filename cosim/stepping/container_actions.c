/* The container's timed events and input tables (included by container.c; cosim/plan/container.py writes
 * them into system.txt after the variables).
 *
 * - holds: the row's slots after the outputs that the copies read where the master's wiring reads an array
 *   of its own (an event-driven input's held value, an override's), with their values before any event;
 * - tables: an instance's tabulated inputs, one row per step k: the Real columns written to their slots
 *   before the step (the copies read them there, as the master's table array), the other columns set on
 *   the FMU with one call per FMI type, in the master's order (cosim/plan/wiring.py table_feeder); at
 *   initialisation the row of step 0 before each pass of the initial exchange, as the master's feed(0);
 * - events: for each communication point where timed events act, before the step from it, what the master's
 *   actuator does there (cosim/runtime/manipulators.py), computed by the exporter: values set on an FMU,
 *   an instance's copies replaced (overrides and biases in force), held values written, a stop.
 * A stop ends fmi2DoStep with fmi2Discard at its time: fmi2GetBooleanStatus(fmi2Terminated) is then true and
 * fmi2GetRealStatus(fmi2LastSuccessfulTime) that time, as the master's run stopped by the event ends there. */

typedef struct { char type; int n; unsigned *vr; int *ival; char **sval; } Group;   /* n values per step */
typedef struct { int inst; long n_steps; int n_real; long *slots; double *real; int n_groups; Group *g; } Table;
/* what: 's' a value set on instance inst (p), 'c' instance inst's copies replaced (n of them), 'p' a held
 * value (slot, value), 'x' a stop (events[index]) */
typedef struct {
    char what; int inst; Param p;
    int n; int *pos; long *slot; double *factor, *offset;
    long put_slot; double put_value; int index;
} Item;
typedef struct { long k; int n; Item *items; } At;
typedef struct {
    int n_holds; long *hslot; double *hval;
    int n_tables; Table *tables;
    int n_at; At *at; int next;
    int stopped, stop_index; double stop_time;
} Actions;

static void *read_typed(Reader *r);   /* (container_inner3.c) */

/* "TYPE VR VALUE": a value a parameter line or an event sets (R, I, B, S; T an FMI 3.0 type's value or array,
 * read_typed); no container variable of its own (var -1) */
static int read_param(Reader *r, Param *a) {
    a->type = token(r)[0]; a->vr = (unsigned)num(r);
    if (a->type == 'R') a->r = real(r);
    else if (a->type == 'S') a->s = text(r);
    else if (a->type == 'T') a->typed = read_typed(r);
    else if (a->type == 'I' || a->type == 'B') a->i = (int)num(r);
    else r->bad = 1;
    a->var = -1;
    return !r->bad;
}

static int read_actions(Actions *A, Reader *r, long n_row, int n_inst) {
    long i, j, m;
    expect(r, "holds");
    A->n_holds = (int)num(r);
    if (r->bad || A->n_holds < 0) return 0;
    A->hslot = calloc((size_t)A->n_holds + 1, sizeof(long)); A->hval = calloc((size_t)A->n_holds + 1, sizeof(double));
    for (i = 0; i < A->n_holds; i++) {
        expect(r, "put"); A->hslot[i] = num(r); A->hval[i] = real(r);
        if (A->hslot[i] < 0 || A->hslot[i] >= n_row) r->bad = 1;
    }
    expect(r, "tables");
    A->n_tables = (int)num(r);
    if (r->bad || A->n_tables < 0) return 0;
    A->tables = calloc((size_t)A->n_tables + 1, sizeof(Table));
    for (i = 0; i < A->n_tables && !r->bad; i++) {
        Table *T = &A->tables[i];
        expect(r, "table");
        T->inst = (int)num(r); T->n_steps = num(r); T->n_real = (int)num(r); T->n_groups = (int)num(r);
        if (r->bad || T->inst < 0 || T->inst >= n_inst || T->n_steps < 1 || T->n_real < 0 || T->n_groups < 0) return 0;
        T->slots = calloc((size_t)T->n_real + 1, sizeof(long));
        T->real = calloc((size_t)(T->n_steps * T->n_real) + 1, sizeof(double));
        T->g = calloc((size_t)T->n_groups + 1, sizeof(Group));
        expect(r, "tslots");
        for (j = 0; j < T->n_real; j++) {
            T->slots[j] = num(r);
            if (T->slots[j] < 0 || T->slots[j] >= n_row) r->bad = 1;
        }
        for (j = 0; j < T->n_groups && !r->bad; j++) {
            Group *G = &T->g[j];
            expect(r, "tgroup");
            G->type = token(r)[0]; G->n = (int)num(r);
            if (r->bad || !strchr("IBS", G->type) || G->n < 1) return 0;
            G->vr = calloc((size_t)G->n, sizeof(unsigned));
            for (m = 0; m < G->n; m++) G->vr[m] = (unsigned)num(r);
            if (G->type == 'S') G->sval = calloc((size_t)(T->n_steps * G->n), sizeof(char *));
            else G->ival = calloc((size_t)(T->n_steps * G->n), sizeof(int));
        }
        for (m = 0; m < T->n_steps && !r->bad; m++) {
            expect(r, "trow");
            for (j = 0; j < T->n_real; j++) T->real[m * T->n_real + j] = real(r);
            for (j = 0; j < T->n_groups; j++) {
                Group *G = &T->g[j];
                int e;
                for (e = 0; e < G->n; e++) {
                    if (G->type == 'S') G->sval[m * G->n + e] = text(r);
                    else G->ival[m * G->n + e] = (int)num(r);
                }
            }
        }
    }
    expect(r, "events");
    A->n_at = (int)num(r);
    if (r->bad || A->n_at < 0) return 0;
    A->at = calloc((size_t)A->n_at + 1, sizeof(At));
    for (i = 0; i < A->n_at && !r->bad; i++) {
        At *a = &A->at[i];
        expect(r, "at");
        a->k = num(r); a->n = (int)num(r);
        if (r->bad || a->k < 0 || a->n < 0 || (i && a->k <= A->at[i - 1].k)) return 0;
        a->items = calloc((size_t)a->n + 1, sizeof(Item));
        for (j = 0; j < a->n && !r->bad; j++) {
            Item *it = &a->items[j];
            char *w = token(r);
            if (!strcmp(w, "set")) {
                it->what = 's'; it->inst = (int)num(r);
                read_param(r, &it->p);
                if (it->inst < 0 || it->inst >= n_inst) r->bad = 1;
            } else if (!strcmp(w, "copies")) {
                it->what = 'c'; it->inst = (int)num(r); it->n = (int)num(r);
                if (r->bad || it->inst < 0 || it->inst >= n_inst || it->n < 0) return 0;
                it->pos = calloc((size_t)it->n + 1, sizeof(int)); it->slot = calloc((size_t)it->n + 1, sizeof(long));
                it->factor = calloc((size_t)it->n + 1, sizeof(double)); it->offset = calloc((size_t)it->n + 1, sizeof(double));
                for (m = 0; m < it->n; m++) {
                    expect(r, "copy");
                    it->pos[m] = (int)num(r); it->slot[m] = num(r); it->factor[m] = real(r); it->offset[m] = real(r);
                    if (it->pos[m] < 0 || it->slot[m] < 0 || it->slot[m] >= n_row) r->bad = 1;
                }
            } else if (!strcmp(w, "put")) {
                it->what = 'p'; it->put_slot = num(r); it->put_value = real(r);
                if (it->put_slot < 0 || it->put_slot >= n_row) r->bad = 1;
            } else if (!strcmp(w, "stop")) {
                it->what = 'x'; it->index = (int)num(r);
            } else r->bad = 1;
        }
    }
    return !r->bad;
}

static void free_actions(Actions *A) {
    int i, j;
    for (i = 0; A->tables && i < A->n_tables; i++) {
        Table *T = &A->tables[i];
        for (j = 0; T->g && j < T->n_groups; j++) {
            Group *G = &T->g[j];
            if (G->sval) for (long m = 0; m < T->n_steps * G->n; m++) free(G->sval[m]);
            free(G->vr); free(G->ival); free(G->sval);
        }
        free(T->slots); free(T->real); free(T->g);
    }
    for (i = 0; A->at && i < A->n_at; i++) {
        for (j = 0; A->at[i].items && j < A->at[i].n; j++) {
            Item *it = &A->at[i].items[j];
            free(it->p.s); free(it->pos); free(it->slot); free(it->factor); free(it->offset);
        }
        free(A->at[i].items);
    }
    free(A->hslot); free(A->hval); free(A->tables); free(A->at);
}

/* the held values before any event, into the row */
static void write_holds(Actions *A, double *row) {
    int i;
    for (i = 0; i < A->n_holds; i++) row[A->hslot[i]] = A->hval[i];
}

/* instance i's tabulated inputs of step k (all instances' where i < 0): the Real columns into the row, the
 * others set on the FMU; the status of the first set that fails (0: none) */
static int feed_tables(Actions *A, Inner *inner, double *row, int i, long k, const char **who) {
    int t, j, st;
    for (t = 0; t < A->n_tables; t++) {
        Table *T = &A->tables[t];
        Inner *q = &inner[T->inst];
        long m = k < T->n_steps ? k : T->n_steps - 1;
        if (i >= 0 && T->inst != i) continue;
        for (j = 0; j < T->n_real; j++) row[T->slots[j]] = T->real[m * T->n_real + j];
        for (j = 0; j < T->n_groups; j++) {
            Group *G = &T->g[j];
            if (G->type == 'S') st = q->set_string(q->c, G->vr, (size_t)G->n, (fmi2String *)&G->sval[m * G->n]);
            else st = (G->type == 'B' ? q->set_boolean : q->set_integer)(q->c, G->vr, (size_t)G->n, &G->ival[m * G->n]);
            if (st) { *who = q->name; return st; }
        }
    }
    return 0;
}

/* instance p's copies replaced by the item's (the arrays the loop reads, grown where needed) */
static void replace_copies(Inst *p, Item *it, double *row) {
    int j;
    size_t n = (size_t)it->n + 1;
    p->pos = realloc(p->pos, n * sizeof(int)); p->src = realloc(p->src, n * sizeof(double *));
    p->slot = realloc(p->slot, n * sizeof(long)); p->factor = realloc(p->factor, n * sizeof(double));
    p->offset = realloc(p->offset, n * sizeof(double)); p->plain = realloc(p->plain, n * sizeof(int));
    for (j = 0; j < it->n; j++) {
        p->pos[j] = it->pos[j]; p->src[j] = row; p->slot[j] = it->slot[j];
        p->factor[j] = it->factor[j]; p->offset[j] = it->offset[j];
        p->plain[j] = p->factor[j] == 1.0 && p->offset[j] == 0.0;
    }
    p->n_copies = it->n;
}
