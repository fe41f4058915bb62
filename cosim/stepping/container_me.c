/* A Model Exchange FMU (FMI 2.0) inside the container (container.c includes this file): the FMU's equations
 * advanced between communication points by the master's fixed-step integrators, explicit Euler or
 * classical RK4 (cosim/instances/integrators.py, FixedStep), with the master's handling of events
 * (cosim/instances/model_exchange.py), ported call for call and operation for operation so that the
 * container's results equal the master's bit for bit (the build passes -ffp-contract=off: no fused
 * multiply-add, each expression evaluated in the order the Python writes it).
 *
 * To the loop (native_loop.c) such an instance is an ordinary FMI 2.0 instance: its Inst's c is the MeInst
 * below and its set, step and get are the wrappers me_set, me_step and me_get, with the signatures of
 * fmi2SetReal, fmi2DoStep and fmi2GetReal (no change to the loop).
 *
 *   - me_set: the inputs of the step.  A discrete Real input among them enters event mode first (in
 *     continuous-time mode); the values are compared with the last ones set: a change restarts the
 *     integration at the step's start ("dirty").
 *   - me_step(t, h): the FMU from t to the step's end (the master's grid point start + (k + 1) h where t
 *     is start + k h, else t + h).  At t: the event iteration if the FMU is in event mode (a value was set),
 *     else, with new inputs, the integrator restarted (an event indicator the inputs moved across zero is an
 *     event at t).  Then, until the step's end: integrate to the next time event or the end, stopping at a
 *     state event (located by bisection to the event tolerance, the integration stopped just after the
 *     crossing) or where fmi2CompletedIntegratorStep asks for event mode; each event: event mode, the event
 *     iteration (fmi2NewDiscreteStates until no new discrete states are needed), continuous-time mode, the
 *     integrator restarted.  The FMU ending the simulation (terminateSimulation) ends the step there
 *     (Inst.terminated, Inst.last_time: the loop ends the segment, as the master's run ends).
 *   - me_get: fmi2GetReal of the FMU.
 *
 * Each communication step of span s is split into n = max(1, ceil(s / max_step - 1e-9)) equal steps (one
 * without max_step), the i-th from t + s i / n, the last ending on the step's end exactly.
 * CVODE is not here: the exporter refuses an instance with solver = "cvode" (docs/export-fmu.md). */

#define ME_MAX_EVENTS_AT_ONE_TIME 1000   /* model_exchange.py MAX_EVENTS_AT_ONE_TIME */
#define ME_TOO_SHORT 1e-13               /* model_exchange.py TOO_SHORT [s per s of time] */

enum { ME_EULER = 1, ME_RK4 = 2, ME_CVODE = 3 };
static const char *ME_METHODS[] = {"", "euler", "rk4", "cvode"};
enum { ME_INSTANTIATED, ME_EVENT, ME_CONTINUOUS };

typedef struct {
    fmi2Boolean newDiscreteStatesNeeded, terminateSimulation, nominalsOfContinuousStatesChanged,
        valuesOfContinuousStatesChanged, nextEventTimeDefined;
    fmi2Real nextEventTime;
} me_event_info_t;

typedef fmi2Status (*me_time_t)(fmi2Component, fmi2Real);
typedef fmi2Status (*me_setx_t)(fmi2Component, const fmi2Real *, size_t);
typedef fmi2Status (*me_getv_t)(fmi2Component, fmi2Real *, size_t);
typedef fmi2Status (*me_new_t)(fmi2Component, me_event_info_t *);
typedef fmi2Status (*me_completed_t)(fmi2Component, fmi2Boolean, fmi2Boolean *, fmi2Boolean *);

/* the calls of the continuous-time equations, as integrators.py's Equations.names */
static const char *ME_EQ_NAMES[] = {"fmi2SetTime", "fmi2SetContinuousStates", "fmi2GetContinuousStates",
                                    "fmi2GetDerivatives", "fmi2GetNominalsOfContinuousStates",
                                    "fmi2GetEventIndicators"};

typedef struct MeInst {
    Container *s; const char *name; fmi2Component c;
    /* its settings (system.txt "me" line) */
    int method; int has_max_step; double max_step; double event_tol; double rtol;
    int nx, nz; int needs_completed; int discrete_inputs;
    /* the FMU's functions */
    set2_t set_real, get_real;
    me_time_t set_time; me_setx_t set_x; me_getv_t get_x, get_dx, get_z, get_nominals;
    mode_t_ enter_event, enter_continuous; me_new_t new_discrete; me_completed_t completed;
    /* the instance (ModelExchange): its mode, time [s], start [s], next time event, indicators at the end of
     * the last step, last inputs set, whether they changed since the integrator started, a step event */
    int mode; double t, start;
    int has_next_event; double next_event;
    double *z;
    double *inputs; size_t n_inputs; int has_inputs; int dirty;
    int step_event;
    _Bool terminated; double last_time;
    /* the integrator (FixedStep): its states and indicators, and work arrays */
    double *x, *zx; int has_x;
    double *buf, *xt, *k1, *k2, *k3, *k4, *xn, *zn, *xm, *zm, *xh, *zh, *x0, *z0;
    struct MeCvode *cv;   /* CVODE (NULL for Euler and RK4) */
} MeInst;

/* a failing call: said with the instance, the call and the time; its status (Error at least) returned */
static int me_failed(MeInst *m, const char *what, int st, double t) {
    say(m->s, fmi2Error, "%s: %s returned status %d at t = %.9g s (the integration: %s)", m->name, what, st, t,
        ME_METHODS[m->method]);
    return st > 1 ? st : fmi2Error;
}
#define ME_EQ(m, call, which, t) do { int st_ = (call); if (st_ > 1) return me_failed(m, ME_EQ_NAMES[which], st_, t); } while (0)
#define ME_OK(x) do { int st_ = (x); if (st_) return st_; } while (0)

/* integrators.py crossed: whether an indicator changed domain (z > 0 against z <= 0) */
static int me_crossed(const double *before, const double *after, int n) {
    int i;
    for (i = 0; i < n; i++) if ((before[i] > 0.0) != (after[i] > 0.0)) return 1;
    return 0;
}

/* ------------------------------------------------------------------ the fixed-step integrator */
/* _slope: dx/dt at (t, x) from the FMU, into k */
static int me_slope(MeInst *m, const double *x, double t, double *k) {
    ME_EQ(m, m->set_time(m->c, t), 0, t);
    if (m->nx) {
        memcpy(m->buf, x, sizeof(double) * (size_t)m->nx);
        ME_EQ(m, m->set_x(m->c, m->buf, (size_t)m->nx), 1, t);
        ME_EQ(m, m->get_dx(m->c, k, (size_t)m->nx), 3, t);
    }
    return 0;
}

/* one step of dt [s] from x at t into out (_euler, _rk4) */
static int me_method(MeInst *m, const double *x, double t, double dt, double *out) {
    int i, nx = m->nx;
    if (m->method == ME_EULER) {
        ME_OK(me_slope(m, x, t, m->k1));
        for (i = 0; i < nx; i++) out[i] = x[i] + dt * m->k1[i];
        return 0;
    }
    {
        double h2 = 0.5 * dt, s6;
        double *tmp = m->xt;
        ME_OK(me_slope(m, x, t, m->k1));
        for (i = 0; i < nx; i++) tmp[i] = x[i] + h2 * m->k1[i];
        ME_OK(me_slope(m, tmp, t + h2, m->k2));
        for (i = 0; i < nx; i++) tmp[i] = x[i] + h2 * m->k2[i];
        ME_OK(me_slope(m, tmp, t + h2, m->k3));
        for (i = 0; i < nx; i++) tmp[i] = x[i] + dt * m->k3[i];
        ME_OK(me_slope(m, tmp, t + dt, m->k4));
        s6 = dt / 6.0;
        for (i = 0; i < nx; i++) out[i] = x[i] + s6 * (m->k1[i] + 2.0 * (m->k2[i] + m->k3[i]) + m->k4[i]);
    }
    return 0;
}

/* FixedStep._indicators: the indicators at (t, x) into z (the FMU left at them) */
static int me_indicators_at(MeInst *m, double t, const double *x, double *z) {
    ME_EQ(m, m->set_time(m->c, t), 0, t);
    if (m->nx) {
        memcpy(m->buf, x, sizeof(double) * (size_t)m->nx);
        ME_EQ(m, m->set_x(m->c, m->buf, (size_t)m->nx), 1, t);
    }
    if (m->nz) ME_EQ(m, m->get_z(m->c, z, (size_t)m->nz), 5, t);
    return 0;
}

static int me_cv_reset(MeInst *m, double t);
static int me_cv_advance(MeInst *m, double t_out, double *t_now, int *state);

/* Integrator.reset: start again from the FMU's states at t (FixedStep.reset, or Cvode.reset) */
static int me_reset(MeInst *m, double t) {
    if (m->cv) return me_cv_reset(m, t);
    if (m->nx) ME_EQ(m, m->get_x(m->c, m->x, (size_t)m->nx), 2, t);
    m->has_x = 1;
    return me_indicators_at(m, t, m->x, m->zx);
}

/* ModelExchange._completed: fmi2CompletedIntegratorStep at t; *stop 1 if the integration must stop there */
static int me_completed(MeInst *m, double t, int *stop) {
    fmi2Boolean enter = 0, terminate = 0;
    int st;
    *stop = 0;
    if (!m->needs_completed) return 0;
    /* (noSetFMUStatePriorToCurrentPoint: the container saves no state) */
    if ((st = m->completed(m->c, 1, &enter, &terminate)) > 1) return me_failed(m, "fmi2CompletedIntegratorStep", st, t);
    if (terminate) { m->terminated = 1; m->last_time = t; *stop = 1; return 0; }
    m->step_event = enter != 0;
    *stop = m->step_event;
    return 0;
}

/* FixedStep._locate: the crossing inside [ti, tn] by bisection on the length of a step from ti, to the event
 * tolerance; into *t_hit, xn, zn (the FMU left at its end) */
static int me_locate(MeInst *m, double ti, double tn, double *t_hit) {
    size_t bx = sizeof(double) * (size_t)m->nx;
    double lo = ti, hi = tn;
    int have_hi = 0;
    memcpy(m->x0, m->x, bx); memcpy(m->z0, m->zx, sizeof(double) * (size_t)m->nz);
    while (hi - lo > m->event_tol) {
        double mid = 0.5 * (lo + hi);
        if (mid <= lo || mid >= hi) break;
        ME_OK(me_method(m, m->x0, ti, mid - ti, m->xm));
        ME_OK(me_indicators_at(m, mid, m->xm, m->zm));
        if (me_crossed(m->z0, m->zm, m->nz)) { hi = mid; memcpy(m->xh, m->xm, bx); have_hi = 1; }
        else lo = mid;
    }
    if (!have_hi) ME_OK(me_method(m, m->x0, ti, tn - ti, m->xh));   /* the full step is the shortest found */
    ME_OK(me_indicators_at(m, hi, m->xh, m->zh));
    memcpy(m->xn, m->xh, bx); memcpy(m->zn, m->zh, sizeof(double) * (size_t)m->nz);
    *t_hit = hi;
    return 0;
}

/* Integrator.advance (FixedStep.advance; Cvode.advance): from t towards t_out; *t_now the time reached, *state 1 if a state event stopped it */
static int me_integrate(MeInst *m, double t, double t_out, double *t_now, int *state) {
    size_t bx = sizeof(double) * (size_t)m->nx, bz = sizeof(double) * (size_t)m->nz;
    double span, q;
    long n, i;
    int stop;
    *state = 0;
    if (m->cv) return me_cv_advance(m, t_out, t_now, state);
    if (!m->has_x && m->nx) ME_OK(me_reset(m, t));
    span = t_out - t;
    if (!m->has_max_step) n = 1;
    else { q = ceil(span / m->max_step - 1e-9); n = q > 1.0 ? (long)q : 1; }
    for (i = 0; i < n; i++) {
        double ti = t + span * (double)i / (double)n;
        double tn = i + 1 < n ? t + span * (double)(i + 1) / (double)n : t_out;
        ME_OK(me_method(m, m->x, ti, tn - ti, m->xn));
        ME_OK(me_indicators_at(m, tn, m->xn, m->zn));
        if (m->nz && me_crossed(m->zx, m->zn, m->nz)) {
            ME_OK(me_locate(m, ti, tn, &tn));
            memcpy(m->x, m->xn, bx); memcpy(m->zx, m->zn, bz);
            ME_OK(me_completed(m, tn, &stop));
            *t_now = tn; *state = 1;
            return 0;
        }
        memcpy(m->x, m->xn, bx); memcpy(m->zx, m->zn, bz);
        ME_OK(me_completed(m, tn, &stop));
        if (stop) { *t_now = tn; return 0; }
    }
    *t_now = t_out;
    return 0;
}

/* ------------------------------------------------------------------ CVODE (integrators.py Cvode) */
/* FMPy's SUNDIALS libraries (7.x), shipped in the container's resources/sundials/ and loaded here, each with
 * its own symbols first (RTLD_DEEPBIND: a host that links another SUNDIALS, as fmusim does, does not meet
 * them); the calls and settings of the master's Cvode: BDF, a dense linear solver, relative tolerance rtol,
 * absolute tolerance rtol times each state's nominal, the largest step, root finding on every indicator
 * (an indicator at 0 given as the negative number nearest to it), normal mode. */
#define ME_CV_BDF 2
#define ME_CV_NORMAL 1
#define ME_CV_ROOT_RETURN 2
#define ME_CV_MAX_NUM_STEPS 100000L   /* Cvode.MAX_NUM_STEPS */
static const char *ME_CV_LIBS[] = {"sundials_core", "sundials_nvecserial", "sundials_sunmatrixdense",
                                   "sundials_sunlinsoldense", "sundials_cvode"};
#define ME_CV_NLIBS 5

typedef int (*me_rhs_t)(double, void *, void *, void *);
typedef int (*me_root_t)(double, void *, double *, void *);

typedef struct MeCvode {
    void *lib[ME_CV_NLIBS];
    int (*context_create)(int, void **); int (*context_free)(void **);
    void *(*new_serial)(int64_t, void *); void (*destroy)(void *); double *(*data)(void *);
    void *(*create)(int, void *); int (*init)(void *, me_rhs_t, double, void *);
    int (*sv_tolerances)(void *, double, void *); int (*root_init)(void *, int, me_root_t);
    void *(*dense_matrix)(int64_t, int64_t, void *); void *(*lin_sol_dense)(void *, void *, void *);
    int (*set_linear_solver)(void *, void *, void *); int (*set_max_step)(void *, double);
    int (*set_max_num_steps)(void *, long); int (*set_no_inactive_root_warn)(void *);
    int (*set_user_data)(void *, void *); int (*reinit)(void *, double, void *);
    int (*cvode)(void *, double, void *, double *, int); void (*cvode_free)(void **);
    int (*lin_sol_free)(void *); void (*mat_destroy)(void *);
    /* the run: context, states, absolute tolerances, CVODE, matrix, linear solver */
    int discrete, n; void *ctx, *x, *abstol, *mem, *A, *LS;
    int failure;   /* the status of a failing FMU call in a right-hand side (0: none) */
} MeCvode;

/* the SUNDIALS libraries from res/sundials and their functions; 0 (said) if they cannot be */
static int me_cv_load(MeInst *m, const char *res) {
    MeCvode *cv = m->cv = calloc(1, sizeof(MeCvode));
    char *path;
    int j;
    if (!cv || !(path = malloc(strlen(res) + 64))) return 0;
    for (j = 0; j < ME_CV_NLIBS; j++) {
        sprintf(path, "%s/sundials/%s." LIB_EXT, res, ME_CV_LIBS[j]);
#ifdef _WIN32
        cv->lib[j] = (void *)LoadLibraryExA(path, NULL, LOAD_WITH_ALTERED_SEARCH_PATH);
        if (!cv->lib[j]) { say(m->s, fmi2Error, "%s: LoadLibrary %s failed", m->name, path); free(path); return 0; }
#else
        cv->lib[j] = dlopen(path, RTLD_NOW | RTLD_LOCAL | RTLD_DEEPBIND);
        if (!cv->lib[j]) { say(m->s, fmi2Error, "%s: %s", m->name, dlerror()); free(path); return 0; }
#endif
    }
    free(path);
#define ME_CV_SYM(field, sym) \
    for (j = ME_CV_NLIBS - 1; j >= 0 && !(*(void **)&cv->field = (void *)LOOKUP(cv->lib[j], sym)); j--) {} \
    if (!cv->field) { say(m->s, fmi2Error, "%s: SUNDIALS' %s not found", m->name, sym); return 0; }
    ME_CV_SYM(context_create, "SUNContext_Create") ME_CV_SYM(context_free, "SUNContext_Free")
    ME_CV_SYM(new_serial, "N_VNew_Serial") ME_CV_SYM(destroy, "N_VDestroy") ME_CV_SYM(data, "N_VGetArrayPointer")
    ME_CV_SYM(create, "CVodeCreate") ME_CV_SYM(init, "CVodeInit") ME_CV_SYM(sv_tolerances, "CVodeSVtolerances")
    ME_CV_SYM(root_init, "CVodeRootInit") ME_CV_SYM(dense_matrix, "SUNDenseMatrix")
    ME_CV_SYM(lin_sol_dense, "SUNLinSol_Dense") ME_CV_SYM(set_linear_solver, "CVodeSetLinearSolver")
    ME_CV_SYM(set_max_step, "CVodeSetMaxStep") ME_CV_SYM(set_max_num_steps, "CVodeSetMaxNumSteps")
    ME_CV_SYM(set_no_inactive_root_warn, "CVodeSetNoInactiveRootWarn") ME_CV_SYM(set_user_data, "CVodeSetUserData")
    ME_CV_SYM(reinit, "CVodeReInit") ME_CV_SYM(cvode, "CVode") ME_CV_SYM(cvode_free, "CVodeFree")
    ME_CV_SYM(lin_sol_free, "SUNLinSolFree") ME_CV_SYM(mat_destroy, "SUNMatDestroy")
#undef ME_CV_SYM
    return 1;
}

static int me_cv_ok(MeInst *m, int flag, const char *what) {
    if (!flag) return 0;
    say(m->s, fmi2Error, "%s: CVODE: %s returned %d", m->name, what, flag);
    return fmi2Error;
}

/* Cvode._load_states: x and the absolute tolerances from the FMU's states and nominals */
static int me_cv_load_states(MeInst *m, double t) {
    MeCvode *cv = m->cv;
    double *px = cv->data(cv->x), *pabs = cv->data(cv->abstol);
    int i;
    if (cv->discrete) { px[0] = 1.0; pabs[0] = m->rtol; return 0; }
    ME_EQ(m, m->get_x(m->c, px, (size_t)m->nx), 2, t);
    ME_EQ(m, m->get_nominals(m->c, pabs, (size_t)m->nx), 4, t);
    for (i = 0; i < m->nx; i++) pabs[i] = fabs(pabs[i]) * m->rtol;
    return 0;
}

/* Cvode._fail: a failing FMU call as CVODE's recoverable (Discard) or unrecoverable error */
static int me_cv_fail(MeInst *m, int st) {
    m->cv->failure = st;
    return st == fmi2Discard ? 1 : -1;
}

/* Cvode._f, the right-hand side */
static int me_cv_f(double t, void *y, void *ydot, void *user_data) {
    MeInst *m = user_data;
    MeCvode *cv = m->cv;
    int st;
    if ((st = m->set_time(m->c, t)) > 1) return me_cv_fail(m, st);
    if (cv->discrete) cv->data(ydot)[0] = 0.0;
    else {
        if ((st = m->set_x(m->c, cv->data(y), (size_t)m->nx)) > 1) return me_cv_fail(m, st);
        if ((st = m->get_dx(m->c, cv->data(ydot), (size_t)m->nx)) > 1) return me_cv_fail(m, st);
    }
    return 0;
}

/* Cvode._g, the root function: the event indicators, a zero as the negative number nearest to it */
static int me_cv_g(double t, void *y, double *gout, void *user_data) {
    MeInst *m = user_data;
    int st, i;
    if ((st = m->set_time(m->c, t)) > 1) return me_cv_fail(m, st);
    if (!m->cv->discrete && (st = m->set_x(m->c, m->cv->data(y), (size_t)m->nx)) > 1) return me_cv_fail(m, st);
    if ((st = m->get_z(m->c, gout, (size_t)m->nz)) > 1) return me_cv_fail(m, st);
    for (i = 0; i < m->nz; i++) if (gout[i] == 0.0) gout[i] = -0x1p-1074;   /* ZERO_SIDE = -ulp(0.0) */
    return 0;
}

/* Cvode.__init__: CVODE started at t0 from the FMU's states */
static int me_cv_create(MeInst *m, double t0) {
    MeCvode *cv = m->cv;
    cv->discrete = m->nx == 0;
    cv->n = m->nx > 1 ? m->nx : 1;
    ME_OK(me_cv_ok(m, cv->context_create(0, &cv->ctx), "SUNContext_Create"));   /* (SUN_COMM_NULL) */
    cv->x = cv->new_serial(cv->n, cv->ctx);
    cv->abstol = cv->new_serial(cv->n, cv->ctx);
    if (!cv->x || !cv->abstol) return me_cv_ok(m, -1, "N_VNew_Serial");
    ME_OK(me_cv_load_states(m, t0));
    if (!(cv->mem = cv->create(ME_CV_BDF, cv->ctx))) return me_cv_ok(m, -1, "CVodeCreate");
    ME_OK(me_cv_ok(m, cv->set_user_data(cv->mem, m), "CVodeSetUserData"));
    ME_OK(me_cv_ok(m, cv->init(cv->mem, me_cv_f, t0, cv->x), "CVodeInit"));
    ME_OK(me_cv_ok(m, cv->sv_tolerances(cv->mem, m->rtol, cv->abstol), "CVodeSVtolerances"));
    ME_OK(me_cv_ok(m, cv->root_init(cv->mem, m->nz, me_cv_g), "CVodeRootInit"));
    if (!(cv->A = cv->dense_matrix(cv->n, cv->n, cv->ctx))) return me_cv_ok(m, -1, "SUNDenseMatrix");
    if (!(cv->LS = cv->lin_sol_dense(cv->x, cv->A, cv->ctx))) return me_cv_ok(m, -1, "SUNLinSol_Dense");
    ME_OK(me_cv_ok(m, cv->set_linear_solver(cv->mem, cv->LS, cv->A), "CVodeSetLinearSolver"));
    ME_OK(me_cv_ok(m, cv->set_max_step(cv->mem, m->max_step), "CVodeSetMaxStep"));
    ME_OK(me_cv_ok(m, cv->set_max_num_steps(cv->mem, ME_CV_MAX_NUM_STEPS), "CVodeSetMaxNumSteps"));
    return me_cv_ok(m, cv->set_no_inactive_root_warn(cv->mem), "CVodeSetNoInactiveRootWarn");
}

/* Cvode.reset */
static int me_cv_reset(MeInst *m, double t) {
    ME_OK(me_cv_load_states(m, t));
    return me_cv_ok(m, m->cv->reinit(m->cv->mem, t, m->cv->x), "CVodeReInit");
}

/* Cvode.advance */
static int me_cv_advance(MeInst *m, double t_out, double *t_now, int *state) {
    MeCvode *cv = m->cv;
    double tret = 0.0;
    int flag, stop;
    cv->failure = 0;
    flag = cv->cvode(cv->mem, t_out, cv->x, &tret, ME_CV_NORMAL);
    if (flag < 0) {
        if (cv->failure) return me_failed(m, "a call in CVODE's right-hand side or root function", cv->failure, tret);
        say(m->s, fmi2Error, "%s: CVODE failed at t = %.9g s (flag %d)", m->name, tret, flag);
        return fmi2Error;
    }
    *t_now = flag == 0 ? t_out : tret;
    ME_EQ(m, m->set_time(m->c, *t_now), 0, *t_now);
    if (!cv->discrete) ME_EQ(m, m->set_x(m->c, cv->data(cv->x), (size_t)m->nx), 1, *t_now);
    *state = flag == ME_CV_ROOT_RETURN;
    return me_completed(m, *t_now, &stop);
}

static void me_cv_free(MeCvode *cv) {
    int j;
    if (!cv) return;
    if (cv->mem) cv->cvode_free(&cv->mem);
    if (cv->LS) cv->lin_sol_free(cv->LS);
    if (cv->A) cv->mat_destroy(cv->A);
    if (cv->x) cv->destroy(cv->x);
    if (cv->abstol) cv->destroy(cv->abstol);
    if (cv->ctx) cv->context_free(&cv->ctx);
    for (j = ME_CV_NLIBS - 1; j >= 0; j--) if (cv->lib[j]) UNLOAD(cv->lib[j]);
    free(cv);
}

/* ------------------------------------------------------------------ the instance's events */
/* ModelExchange._indicators: the indicators now into the instance's z */
static int me_indicators(MeInst *m, double *z) {
    if (m->nz) ME_EQ(m, m->get_z(m->c, z, (size_t)m->nz), 5, m->t);
    return 0;
}

/* ModelExchange._event_iteration: *ended 1 if the FMU ended the simulation */
static int me_event_iteration(MeInst *m, double t, int *ended) {
    me_event_info_t info;
    int j, st;
    *ended = 0;
    for (j = 0; j < ME_MAX_EVENTS_AT_ONE_TIME; j++) {
        memset(&info, 0, sizeof info);
        if ((st = m->new_discrete(m->c, &info)) > 1) return me_failed(m, "fmi2NewDiscreteStates", st, t);
        if (info.terminateSimulation) { m->terminated = 1; m->last_time = t; *ended = 1; return 0; }
        if (!info.newDiscreteStatesNeeded) break;
    }
    if (j == ME_MAX_EVENTS_AT_ONE_TIME) {
        say(m->s, fmi2Error, "%s: the event iteration at t = %.9g s did not end after %d updates of the discrete "
            "states", m->name, t, ME_MAX_EVENTS_AT_ONE_TIME);
        return fmi2Error;
    }
    m->has_next_event = info.nextEventTimeDefined != 0;
    m->next_event = info.nextEventTime;
    if ((st = m->enter_continuous(m->c)) > 1) return me_failed(m, "fmi2EnterContinuousTimeMode", st, t);
    m->mode = ME_CONTINUOUS;
    return 0;
}

/* ModelExchange.enter_event_mode: event mode now, if in continuous-time mode */
static int me_enter_event_mode(MeInst *m) {
    int st;
    if (m->mode != ME_CONTINUOUS) return 0;
    if ((st = m->enter_event(m->c)) > 1) return me_failed(m, "fmi2EnterEventMode", st, m->t);
    m->mode = ME_EVENT;
    return 0;
}

/* ModelExchange._event_at: event mode (unless in it), the event iteration, continuous-time mode, the
 * integrator restarted */
static int me_event_at(MeInst *m, double t) {
    int st, ended;
    if (m->mode != ME_EVENT) {
        if ((st = m->enter_event(m->c)) > 1) return me_failed(m, "fmi2EnterEventMode", st, t);
        m->mode = ME_EVENT;
    }
    m->step_event = 0;
    ME_OK(me_event_iteration(m, t, &ended));
    if (ended) return 0;
    m->dirty = 0;
    ME_OK(me_reset(m, t));
    return me_indicators(m, m->z);
}

/* ModelExchange._inputs_changed: new inputs at t */
static int me_inputs_changed(MeInst *m, double t) {
    m->dirty = 0;
    ME_OK(me_indicators(m, m->zn));
    if (m->nz && me_crossed(m->z, m->zn, m->nz)) return me_event_at(m, t);
    ME_OK(me_reset(m, t));
    memcpy(m->z, m->zn, sizeof(double) * (size_t)m->nz);
    return 0;
}

/* ModelExchange._advance: the FMU from t to t_end [s] with its events */
static int me_advance(MeInst *m, double t, double t_end) {
    int at_once = 0;
    m->t = t;
    if (m->mode == ME_EVENT) ME_OK(me_event_at(m, t));
    else if (m->dirty) ME_OK(me_inputs_changed(m, t));
    while (!m->terminated) {
        double a = fabs(t_end), eps = ME_TOO_SHORT * (a > 1.0 ? a : 1.0), target, t_before, lowest;
        int timed, state;
        if (m->t >= t_end - eps) break;
        timed = m->has_next_event && m->next_event <= t_end + eps;
        if (timed) {   /* max(self.t, min(te, t_end)), as Python's min and max pick */
            lowest = t_end < m->next_event ? t_end : m->next_event;
            target = lowest > m->t ? lowest : m->t;
        } else target = t_end;
        t_before = m->t;
        if (target - m->t > eps) ME_OK(me_integrate(m, m->t, target, &m->t, &state));
        else {   /* (what is left is shorter than CVODE can start over) */
            m->t = target; state = 0;
            ME_EQ(m, m->set_time(m->c, target), 0, target);
        }
        if (state || m->step_event) ME_OK(me_event_at(m, m->t));
        else if (timed && m->t >= target) ME_OK(me_event_at(m, m->t));
        else continue;
        at_once = m->t == t_before ? at_once + 1 : 0;
        if (at_once > ME_MAX_EVENTS_AT_ONE_TIME) {
            say(m->s, fmi2Error, "%s: more than %d events at t = %.9g s", m->name, ME_MAX_EVENTS_AT_ONE_TIME, m->t);
            return fmi2Error;
        }
    }
    if (m->t < t_end && !m->terminated) {   /* (within TOO_SHORT of it: the step's end) */
        m->t = t_end;
        ME_EQ(m, m->set_time(m->c, t_end), 0, t_end);
    }
    return me_indicators(m, m->z);
}

/* ------------------------------------------------------------------ what the loop calls */
/* the fast path's set_real: the step's inputs (see the top) */
static int me_set(void *c, const unsigned *vr, size_t n, const double *v) {
    MeInst *m = c;
    size_t j;
    int s;
    if (m->discrete_inputs && m->mode == ME_CONTINUOUS && me_enter_event_mode(m)) return fmi2Error;
    s = m->set_real(m->c, vr, n, v);
    if (s <= 1) {
        int changed = !m->has_inputs || m->n_inputs != n;
        for (j = 0; !changed && j < n; j++) changed = v[j] != m->inputs[j];
        if (changed) {
            free(m->inputs);
            m->inputs = malloc(sizeof(double) * (n + 1));
            if (!m->inputs) return fmi2Error;
            memcpy(m->inputs, v, sizeof(double) * n);
            m->n_inputs = n; m->has_inputs = 1; m->dirty = 1;
        }
    }
    return s;
}

/* ModelExchange.step_end: the end of the step of h from t [s] */
static double me_step_end(MeInst *m, double t, double h) {
    double k = nearbyint((t - m->start) / h);   /* (Python's round: halves to even) */
    if (m->start + k * h == t) return m->start + (k + 1.0) * h;
    return t + h;
}

/* the fast path's do_step */
static int me_step(void *c, double t, double h, int no_set_prior) {
    MeInst *m = c;
    (void)no_set_prior;
    return me_advance(m, t, me_step_end(m, t, h));
}

static int me_get(void *c, const unsigned *vr, size_t n, double *v) {
    MeInst *m = c;
    return m->get_real(m->c, vr, n, v);
}

/* ------------------------------------------------------------------ life cycle (from container.c) */
/* system.txt's "me" line of an instance: method, max_step (0x0p+0 with flag 0: none), event tolerance,
 * number of states and of event indicators, whether it needs fmi2CompletedIntegratorStep, whether a Real
 * input it is set each step is discrete */
static int me_read(Container *s, Reader *r, int i) {
    MeInst *m = calloc(1, sizeof(MeInst));
    char *method;
    s->inner[i].me = m;
    if (!m) return 0;
    expect(r, "me");
    method = token(r);
    m->method = !strcmp(method, "euler") ? ME_EULER : !strcmp(method, "rk4") ? ME_RK4 : !strcmp(method, "cvode") ? ME_CVODE : 0;
    m->has_max_step = (int)num(r); m->max_step = real(r); m->event_tol = real(r); m->rtol = real(r);
    m->nx = (int)num(r); m->nz = (int)num(r); m->needs_completed = (int)num(r); m->discrete_inputs = (int)num(r);
    if (!m->method || m->nx < 0 || m->nz < 0 || (m->has_max_step && !(m->max_step > 0))) r->bad = 1;
    return !r->bad;
}

#define ME_SYM(field, sym) \
    if (!(*(void **)&m->field = (void *)LOOKUP(q->dll, sym))) { say(s, fmi2Error, "%s: %s not found", q->name, sym); return 0; }

/* the Model Exchange functions of the loaded FMU; the instance's Inst given the wrappers */
static int me_load(Container *s, Inner *q, Inst *p, const char *res) {
    MeInst *m = q->me;
    size_t nx = (size_t)m->nx + 1, nz = (size_t)m->nz + 1;
    m->s = s; m->name = q->name;
    ME_SYM(set_time, "fmi2SetTime") ME_SYM(set_x, "fmi2SetContinuousStates")
    ME_SYM(get_x, "fmi2GetContinuousStates") ME_SYM(get_dx, "fmi2GetDerivatives")
    ME_SYM(get_z, "fmi2GetEventIndicators") ME_SYM(enter_event, "fmi2EnterEventMode")
    ME_SYM(enter_continuous, "fmi2EnterContinuousTimeMode") ME_SYM(new_discrete, "fmi2NewDiscreteStates")
    ME_SYM(completed, "fmi2CompletedIntegratorStep") ME_SYM(get_real, "fmi2GetReal")
    ME_SYM(get_nominals, "fmi2GetNominalsOfContinuousStates")
    if (m->method == ME_CVODE && !me_cv_load(m, res)) return 0;
    m->set_real = q->set_real;
    m->x = calloc(nx, sizeof(double)); m->buf = calloc(nx, sizeof(double)); m->xt = calloc(nx, sizeof(double));
    m->k1 = calloc(nx, sizeof(double)); m->k2 = calloc(nx, sizeof(double)); m->k3 = calloc(nx, sizeof(double));
    m->k4 = calloc(nx, sizeof(double)); m->xn = calloc(nx, sizeof(double)); m->xm = calloc(nx, sizeof(double));
    m->xh = calloc(nx, sizeof(double)); m->x0 = calloc(nx, sizeof(double));
    m->z = calloc(nz, sizeof(double)); m->zx = calloc(nz, sizeof(double)); m->zn = calloc(nz, sizeof(double));
    m->zm = calloc(nz, sizeof(double)); m->zh = calloc(nz, sizeof(double)); m->z0 = calloc(nz, sizeof(double));
    if (!m->x || !m->buf || !m->xt || !m->k1 || !m->k2 || !m->k3 || !m->k4 || !m->xn || !m->xm || !m->xh || !m->x0 ||
        !m->z || !m->zx || !m->zn || !m->zm || !m->zh || !m->z0) return 0;
    p->c = m;
    p->set = (void *)me_set; p->step = (void *)me_step; p->get = (void *)me_get;
    p->terminated = &m->terminated; p->last_time = &m->last_time;
    return 1;
}

/* ModelExchange.exit_initialization, after fmi2ExitInitializationMode: the event iteration at the start
 * time, continuous-time mode, the integrator started (t0 the experiment's start [s]) */
static int me_start(MeInst *m, double t0) {
    int ended;
    m->t = m->start = t0;
    m->mode = ME_EVENT;
    if (me_event_iteration(m, m->t, &ended)) return 0;
    if (ended) {
        say(m->s, fmi2Error, "%s: the FMU ended the simulation in its initial event iteration at t = %.6g s",
            m->name, m->t);
        return 0;
    }
    if (m->cv && me_cv_create(m, m->t)) return 0;   /* (make_integrator: CVODE started, then reset as the others) */
    if (me_reset(m, m->t) || me_indicators(m, m->z)) return 0;
    m->dirty = 0;
    return 1;
}

/* a value the host sets while the container steps: the FMU in event mode first, as the master sets a value
 * between steps (the next step begins with the event iteration) */
static int me_before_set(MeInst *m) { return m ? me_enter_event_mode(m) : 0; }

static void me_free(MeInst *m) {
    if (!m) return;
    me_cv_free(m->cv);
    free(m->inputs); free(m->x); free(m->buf); free(m->xt); free(m->k1); free(m->k2); free(m->k3); free(m->k4);
    free(m->xn); free(m->xm); free(m->xh); free(m->x0);
    free(m->z); free(m->zx); free(m->zn); free(m->zm); free(m->zh); free(m->z0);
    free(m);
}
