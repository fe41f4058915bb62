/* WmrCPlant: the wheeled mobile robot plant of wmr-cosim, written in C as an FMI 2.0 FMU "from another
 * toolchain", for co-simulation and Model Exchange (one library, both interfaces in one archive).  The same
 * physics as components/plant.py (Maggi dynamics (34)-(36) of the two drive wheels and the pose of point A
 * (23)-(24), the friction 2 a tanh(cF w / 2) of (36) or its printed exp form, the foam: a5, a6 rise by
 * foam_rise_* times a level ramping linearly over foam_ramp_time once the foam is reached, by time or by
 * region).
 *
 * Co-simulation: RK4 in `rk4_substeps` substeps per communication step with the inputs held, in the same
 * operation order as components/plant.py, so that with the same inputs the states are bit-identical; the
 * foam region is checked at each step's start.
 *
 * Model Exchange: the 7 states alpha1, alpha2 [rad], w1, w2 [rad/s], xA, yA [m], beta [rad] (the local
 * variables state_* in SI units, their derivatives der_*), advanced by the master's integrator; the
 * derivatives are one stage of the RK4 above (the same function) at the time of fmi2SetTime and the inputs
 * as set.  Foam by time: time events at its kinks t_foam and t_foam + foam_ramp_time.  Foam by region: a
 * state event (the one event indicator, see region_indicator) at the entry of A into the rectangle, which
 * sets t_foam to the event's time.  rk4_substeps is ignored.
 *
 * Deliberately not the Python plant's interface: other variable names, wheel angles and heading in
 * degrees, wheel speeds in rpm (declared in the model description's UnitDefinitions).
 *
 * Built from this source by fmus/cplant_build.py with FMPy's CMake project and FMI headers.
 */
#include <float.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"

#define GUID "{5b0f3c1e-7d4a-4c55-9a57-3f0c2e8a6b11}"
#define PI_ 3.14159265358979323846
#define RAD2DEG (180.0 / PI_)
#define DEG2RAD (PI_ / 180.0)
#define RADS2RPM (30.0 / PI_)
#define STEP_RTOL 1e-9
#define EVENT_RTOL 1e-12   /* Model Exchange: a time within this (relative, at least 1 s) of a kink is at it */
#define NX 7               /* continuous states (Model Exchange) */
#define NZ 1               /* event indicators (Model Exchange) */

/* Real value references: parameters, inputs, outputs, then (34-47) the states and their derivatives */
enum {
    R_A1, R_A2, R_A3, R_A4, R_A5, R_A6, R_CF, R_R, R_L1, R_X0, R_Y0, R_HEAD0,
    R_DA1, R_DA2, R_RAMP, R_TON, R_XLO, R_XHI, R_YLO, R_YHI,
    R_U1, R_U2, R_D1, R_D2,
    R_PHI1, R_PHI2, R_OM1, R_OM2, R_X, R_Y, R_HEAD, R_DF1, R_DF2, R_LAMBDA,
    R_STATE, R_DER = R_STATE + NX,
    N_REAL = R_DER + NX
};
enum { I_SUBSTEPS, N_INT };
enum { B_EXP, B_ON_TIME, B_ON_REGION, N_BOOL };
#define FIRST_INPUT R_U1
#define FIRST_OUTPUT R_PHI1

static const char *REAL_NAMES[N_REAL] = {
    "inertia_a1", "inertia_a2", "inertia_a3", "coriolis_a4", "roll_res_right", "roll_res_left", "slope_cF",
    "wheel_radius", "half_track", "start_x", "start_y", "start_heading", "foam_rise_right", "foam_rise_left",
    "foam_ramp_time", "foam_time", "foam_x_lo", "foam_x_hi", "foam_y_lo", "foam_y_hi",
    "torque_right", "torque_left", "dist_right", "dist_left",
    "phi_right", "phi_left", "omega_right", "omega_left", "pos_x", "pos_y", "heading",
    "dist_total_right", "dist_total_left", "foam_lambda",
    "state_phi_right", "state_phi_left", "state_omega_right", "state_omega_left", "state_pos_x", "state_pos_y",
    "state_heading", "der_phi_right", "der_phi_left", "der_omega_right", "der_omega_left", "der_pos_x",
    "der_pos_y", "der_heading"};

/* M_STEP: co-simulation's step mode; M_EVENT, M_CONT: Model Exchange's event and continuous-time modes */
typedef enum { M_INSTANTIATED, M_INIT, M_STEP, M_TERMINATED, M_FAILED, M_EVENT, M_CONT } Mode;
#define IN(m) (1u << (m))

typedef struct {
    fmi2CallbackFunctions cb;
    char *name;
    int logging;
    int me;               /* instantiated for Model Exchange */
    Mode mode;
    double r[N_REAL];
    int i[N_INT];
    int b[N_BOOL];
    /* state */
    double x[NX];         /* alpha1, alpha2, w1, w2, xA, yA, beta [rad, rad/s, m] */
    double t;             /* time of the state (Model Exchange: of fmi2SetTime) */
    double t_foam;        /* time the foam is reached (INFINITY before) */
    int region_hit;
    double i11, i12, h;
} Plant;

static void logf_(Plant *p, fmi2Status st, const char *cat, const char *fmt, ...) {
    char buf[512];
    va_list ap;
    if (!p->logging && st == fmi2OK) return;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    if (p->cb.logger) p->cb.logger(p->cb.componentEnvironment, p->name, st, cat, "%s", buf);
}

static double g_shape(const Plant *p, double x) {
    if (p->b[B_EXP]) { double e = exp(-2.0 * x); return (1.0 - e) / (1.0 + e); }
    return tanh(x);
}

static double foam_level(const Plant *p, double t) {
    double tf = p->t_foam, ramp = p->r[R_RAMP];
    if (t < tf) return 0.0;
    if (ramp <= 0.0 || t >= tf + ramp) return 1.0;
    return (t - tf) / ramp;
}

static void check_region(Plant *p) {
    if (p->b[B_ON_REGION] && !p->region_hit) {
        double xa = p->x[4], ya = p->x[5];
        if (p->r[R_XLO] <= xa && xa <= p->r[R_XHI] && p->r[R_YLO] <= ya && ya <= p->r[R_YHI]) {
            p->region_hit = 1;
            if (p->t < p->t_foam) p->t_foam = p->t;
        }
    }
}

/* the coefficients of the right-hand side, from the parameters and the inputs as set */
typedef struct { double u1, u2, tau1, tau2, i11, i12, k, a4x2, hr, hrl; } Coef;

static void coef(const Plant *p, Coef *q) {
    const double *r = p->r;
    q->u1 = r[R_U1]; q->u2 = r[R_U2]; q->tau1 = r[R_D1]; q->tau2 = r[R_D2];
    q->i11 = p->i11; q->i12 = p->i12; q->k = 0.5 * r[R_CF]; q->a4x2 = 2.0 * r[R_A4];
    q->hr = 0.5 * r[R_R]; q->hrl = q->hr / r[R_L1];
}

/* one evaluation of the right-hand side (one RK4 stage of plant_step, the derivatives of Model Exchange):
 * the wheel accelerations of (34), M^-1 (u - C(w) w - F(w) - tau_d) with C of (35) and the friction F of (36),
 * f5, f6 = 2 (a5 + lambda da1), 2 (a6 + lambda da2); the velocity of point A and the heading rate (23)-(24) */
static void stage(const Plant *p, const Coef *q, double f5, double f6, double w1, double w2, double be,
                  double *kw1, double *kw2, double *kx, double *ky, double *kb) {
    double c, r1, r2, v;
    c = q->a4x2 * (w2 - w1);
    r1 = q->u1 - c * w2 - f5 * g_shape(p, q->k * w1) - q->tau1;
    r2 = q->u2 + c * w1 - f6 * g_shape(p, q->k * w2) - q->tau2;
    *kw1 = q->i11 * r1 + q->i12 * r2; *kw2 = q->i12 * r1 + q->i11 * r2;
    v = q->hr * (w1 + w2);
    *kx = v * cos(be); *ky = v * sin(be); *kb = q->hrl * (w1 - w2);
}

/* Model Exchange: the derivatives of the states at the time set, the foam level lambda(t) of foam_level */
static void derivatives(const Plant *p, double *dx) {
    const double *r = p->r, *x = p->x;
    double lam = foam_level(p, p->t);
    Coef q;
    coef(p, &q);
    dx[0] = x[2];
    dx[1] = x[3];
    stage(p, &q, 2.0 * (r[R_A5] + lam * r[R_DA1]), 2.0 * (r[R_A6] + lam * r[R_DA2]), x[2], x[3], x[6],
          dx + 2, dx + 3, dx + 4, dx + 5, dx + 6);
}

/* Model Exchange, foam by region: the one event indicator z = min(xA - x_lo, x_hi - xA, yA - y_lo, y_hi - yA),
 * >= 0 exactly when A is in the closed rectangle of check_region (x - y >= 0 iff x >= y in IEEE arithmetic),
 * so that its sign change from - to + is the entry.  A min() rather than one indicator per edge: an edge
 * crossed beside the rectangle is no event.  A constant 1 when the foam is not by region or already reached. */
static double region_indicator(const Plant *p) {
    const double *r = p->r;
    double xa = p->x[4], ya = p->x[5], z, d;
    if (!p->b[B_ON_REGION] || p->region_hit) return 1.0;
    z = xa - r[R_XLO];
    d = r[R_XHI] - xa; if (d < z) z = d;
    d = ya - r[R_YLO]; if (d < z) z = d;
    d = r[R_YHI] - ya; if (d < z) z = d;
    return z;
}

/* Model Exchange: the next time event after p->t, the next kink of the foam level (t_foam, then
 * t_foam + foam_ramp_time); 0 if none */
static int next_time_event(const Plant *p, double *te) {
    double tf = p->t_foam, tol = EVENT_RTOL * fmax(1.0, fabs(p->t));
    if (!isfinite(tf)) return 0;
    if (tf > p->t + tol) { *te = tf; return 1; }
    if (tf + p->r[R_RAMP] > p->t + tol) { *te = tf + p->r[R_RAMP]; return 1; }
    return 0;
}

/* 0 (with a message) if an input is not finite */
static int inputs_finite(Plant *p, const char *what, double t) {
    const double *r = p->r;
    double s = r[R_U1] + r[R_U2] + r[R_D1] + r[R_D2];
    if (isfinite(s)) return 1;
    logf_(p, fmi2Error, "logStatusError", "%s at t = %.17g s: non-finite input (torque_right = %g, torque_left = %g, "
          "dist_right = %g, dist_left = %g N.m)", what, t, r[R_U1], r[R_U2], r[R_D1], r[R_D2]);
    return 0;
}

static void outputs(Plant *p) {
    double *r = p->r, *x = p->x;
    r[R_PHI1] = x[0] * RAD2DEG;
    r[R_PHI2] = x[1] * RAD2DEG;
    r[R_OM1] = x[2] * RADS2RPM;
    r[R_OM2] = x[3] * RADS2RPM;
    r[R_X] = x[4];
    r[R_Y] = x[5];
    r[R_HEAD] = x[6] * RAD2DEG;
    if (p->t < p->t_foam) {
        r[R_DF1] = r[R_D1]; r[R_DF2] = r[R_D2]; r[R_LAMBDA] = 0.0;
    } else {
        double lam = foam_level(p, p->t), k = 0.5 * r[R_CF];
        r[R_DF1] = 2.0 * lam * r[R_DA1] * g_shape(p, k * x[2]) + r[R_D1];
        r[R_DF2] = 2.0 * lam * r[R_DA2] * g_shape(p, k * x[3]) + r[R_D2];
        r[R_LAMBDA] = lam;
    }
}

/* components/plant.py Plant.step, operation for operation */
static void plant_step(Plant *p, double t, double h) {
    const double *r = p->r;
    int n = p->i[I_SUBSTEPS], s;
    double dt = h / n, hdt = 0.5 * dt;
    double a5 = r[R_A5], a6 = r[R_A6], da1 = r[R_DA1], da2 = r[R_DA2];
    double lam = 0.0, f5 = 0.0, f6 = 0.0, ts;
    double x1, x2, w1, w2, xa, ya, be;
    int stat;
    Coef q;
    coef(p, &q);
    p->t = t;
    if (p->b[B_ON_REGION] && !p->region_hit) check_region(p);
    stat = t + h < p->t_foam || t >= p->t_foam + r[R_RAMP];
    if (stat) {
        lam = foam_level(p, t);
        f5 = 2.0 * (a5 + lam * da1);
        f6 = 2.0 * (a6 + lam * da2);
    }
    x1 = p->x[0]; x2 = p->x[1]; w1 = p->x[2]; w2 = p->x[3]; xa = p->x[4]; ya = p->x[5]; be = p->x[6];
    ts = t;
    for (s = 0; s < n; s++) {
        double kw1a, kw2a, kxa, kya, kba, kw1b, kw2b, kxb, kyb, kbb, kw1c, kw2c, kxc, kyc, kbc;
        double kw1d, kw2d, kxd, kyd, kbd, wb1, wb2, bb, wc1, wc2, bc, wd1, wd2, bd, s6;
        if (!stat) { lam = foam_level(p, ts); f5 = 2.0 * (a5 + lam * da1); f6 = 2.0 * (a6 + lam * da2); }
        stage(p, &q, f5, f6, w1, w2, be, &kw1a, &kw2a, &kxa, &kya, &kba);
        if (!stat) { lam = foam_level(p, ts + hdt); f5 = 2.0 * (a5 + lam * da1); f6 = 2.0 * (a6 + lam * da2); }
        wb1 = w1 + hdt * kw1a; wb2 = w2 + hdt * kw2a; bb = be + hdt * kba;
        stage(p, &q, f5, f6, wb1, wb2, bb, &kw1b, &kw2b, &kxb, &kyb, &kbb);
        wc1 = w1 + hdt * kw1b; wc2 = w2 + hdt * kw2b; bc = be + hdt * kbb;
        stage(p, &q, f5, f6, wc1, wc2, bc, &kw1c, &kw2c, &kxc, &kyc, &kbc);
        if (!stat) { lam = foam_level(p, ts + dt); f5 = 2.0 * (a5 + lam * da1); f6 = 2.0 * (a6 + lam * da2); }
        wd1 = w1 + dt * kw1c; wd2 = w2 + dt * kw2c; bd = be + dt * kbc;
        stage(p, &q, f5, f6, wd1, wd2, bd, &kw1d, &kw2d, &kxd, &kyd, &kbd);
        s6 = dt / 6.0;
        x1 += s6 * (w1 + 2.0 * (wb1 + wc1) + wd1);
        x2 += s6 * (w2 + 2.0 * (wb2 + wc2) + wd2);
        w1 += s6 * (kw1a + 2.0 * (kw1b + kw1c) + kw1d);
        w2 += s6 * (kw2a + 2.0 * (kw2b + kw2c) + kw2d);
        xa += s6 * (kxa + 2.0 * (kxb + kxc) + kxd);
        ya += s6 * (kya + 2.0 * (kyb + kyc) + kyd);
        be += s6 * (kba + 2.0 * (kbb + kbc) + kbd);
        ts += dt;
    }
    p->x[0] = x1; p->x[1] = x2; p->x[2] = w1; p->x[3] = w2; p->x[4] = xa; p->x[5] = ya; p->x[6] = be;
    p->t = t + h;
}

/* the states and their derivatives at the time of the state, as the local variables state_*, der_* */
static void locals_(Plant *p) {
    int k;
    for (k = 0; k < NX; k++) p->r[R_STATE + k] = p->x[k];
    derivatives(p, p->r + R_DER);
}

static void set_defaults(Plant *p) {
    static const double def[N_REAL] = {
        0.0691, 0.0511, 0.0291, 0.0014, 4.3001, 4.3001, 0.226, 0.0825, 0.16, 0.0, 0.0, 0.0,
        0.0, 0.0, 0.1, 0.0, 0.0, 0.0, 0.0, 0.0,
        0.0, 0.0, 0.0, 0.0,
        0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
    memcpy(p->r, def, sizeof def);
    p->i[I_SUBSTEPS] = 2;
    p->b[B_EXP] = 0; p->b[B_ON_TIME] = 0; p->b[B_ON_REGION] = 0;
}

/* the initial state from the parameters (PlantParams checks + Plant.reset); 0 if a parameter is bad
 * (rk4_substeps only in co-simulation: Model Exchange ignores it) */
static int reset_state(Plant *p) {
    double *r = p->r, m11, m12, det;
    int k;
    for (k = 0; k < FIRST_INPUT; k++)
        if (!isfinite(r[k])) { logf_(p, fmi2Error, "logStatusError", "parameter %s = %g: must be finite", REAL_NAMES[k], r[k]); return 0; }
    if (!(r[R_CF] > 0.0) || !(r[R_R] > 0.0) || !(r[R_L1] > 0.0)) {
        logf_(p, fmi2Error, "logStatusError", "slope_cF, wheel_radius and half_track must be > 0"); return 0; }
    if (r[R_A4] < 0.0 || r[R_A5] < 0.0 || r[R_A6] < 0.0 || r[R_RAMP] < 0.0) {
        logf_(p, fmi2Error, "logStatusError", "coriolis_a4, roll_res_*, foam_ramp_time must be >= 0"); return 0; }
    if (!p->me && p->i[I_SUBSTEPS] < 1) {
        logf_(p, fmi2Error, "logStatusError", "rk4_substeps = %d: must be >= 1", p->i[I_SUBSTEPS]); return 0; }
    m11 = r[R_A1] + r[R_A2] + r[R_A3];
    m12 = r[R_A1] - r[R_A2];
    if (!(m11 > fabs(m12))) {
        logf_(p, fmi2Error, "logStatusError", "inertia_a1..a3 = %g, %g, %g: M of (35) is not positive definite",
              r[R_A1], r[R_A2], r[R_A3]); return 0; }
    if (p->b[B_ON_REGION] && !(r[R_XLO] < r[R_XHI] && r[R_YLO] < r[R_YHI])) {
        logf_(p, fmi2Error, "logStatusError", "foam region: empty rectangle"); return 0; }
    det = m11 * m11 - m12 * m12;
    p->i11 = m11 / det;
    p->i12 = -m12 / det;
    p->x[0] = p->x[1] = p->x[2] = p->x[3] = 0.0;
    p->x[4] = r[R_X0]; p->x[5] = r[R_Y0]; p->x[6] = r[R_HEAD0] * DEG2RAD;
    p->t_foam = p->b[B_ON_TIME] ? r[R_TON] : INFINITY;
    p->region_hit = 0;
    check_region(p);
    outputs(p);
    return 1;
}

/* ------------------------------------------------------------------------------------------ FMI 2.0 */
const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String cats[]) {
    (void)n; (void)cats;
    ((Plant *)c)->logging = on;
    return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String resources,
                              const fmi2CallbackFunctions *cb, fmi2Boolean visible, fmi2Boolean loggingOn) {
    Plant *p;
    (void)resources; (void)visible;
    if (!cb || !cb->allocateMemory || !cb->freeMemory) return NULL;
    if ((type != fmi2CoSimulation && type != fmi2ModelExchange) || !guid || strcmp(guid, GUID) != 0) {
        if (cb->logger) cb->logger(cb->componentEnvironment, name, fmi2Error, "logStatusError",
                                   "WmrCPlant: co-simulation or Model Exchange, GUID %s", GUID);
        return NULL;
    }
    p = (Plant *)cb->allocateMemory(1, sizeof(Plant));
    if (!p) return NULL;
    p->cb = *cb;
    p->name = (char *)cb->allocateMemory(strlen(name ? name : "") + 1, 1);
    if (p->name) strcpy(p->name, name ? name : "");
    p->logging = loggingOn;
    p->me = type == fmi2ModelExchange;
    p->mode = M_INSTANTIATED;
    set_defaults(p);
    p->h = NAN;
    p->t = 0.0;
    reset_state(p);
    return p;
}

void fmi2FreeInstance(fmi2Component c) {
    Plant *p = (Plant *)c;
    fmi2CallbackFreeMemory fr;
    if (!p) return;
    fr = p->cb.freeMemory;
    fr(p->name);
    fr(p);
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean tolDef, fmi2Real tol, fmi2Real t0, fmi2Boolean stopDef,
                               fmi2Real tStop) {
    (void)tolDef; (void)tol; (void)stopDef; (void)tStop;
    ((Plant *)c)->t = t0;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    ((Plant *)c)->mode = M_INIT;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    Plant *p = (Plant *)c;
    double t0 = p->t;
    if (!reset_state(p)) { p->mode = M_FAILED; return fmi2Error; }
    p->t = t0;
    outputs(p);
    p->mode = p->me ? M_EVENT : M_STEP;
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c) { ((Plant *)c)->mode = M_TERMINATED; return fmi2OK; }

fmi2Status fmi2Reset(fmi2Component c) {
    Plant *p = (Plant *)c;
    set_defaults(p);
    p->h = NAN; p->t = 0.0;
    reset_state(p);
    p->mode = M_INSTANTIATED;
    return fmi2OK;
}

/* co-simulation: the outputs of the last step; Model Exchange: the outputs at the time, states and inputs
 * as set; both: the states and their derivatives (state_*, der_*) at the time of the state */
fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real v[]) {
    Plant *p = (Plant *)c;
    size_t k;
    int fresh = 0;
    for (k = 0; k < n; k++) {
        if (vr[k] >= N_REAL) { logf_(p, fmi2Error, "logStatusError", "no Real with value reference %u", vr[k]); return fmi2Error; }
        if (!fresh && (p->me || vr[k] >= R_STATE)) {
            if (p->me) outputs(p);
            locals_(p);
            fresh = 1;
        }
        v[k] = p->r[vr[k]];
    }
    return fmi2OK;
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Integer v[]) {
    Plant *p = (Plant *)c;
    size_t k;
    for (k = 0; k < n; k++) {
        if (vr[k] >= N_INT) return fmi2Error;
        v[k] = p->i[vr[k]];
    }
    return fmi2OK;
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Boolean v[]) {
    Plant *p = (Plant *)c;
    size_t k;
    for (k = 0; k < n; k++) {
        if (vr[k] >= N_BOOL) return fmi2Error;
        v[k] = p->b[vr[k]];
    }
    return fmi2OK;
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2String v[]) {
    (void)c; (void)vr; (void)v;
    return n ? fmi2Error : fmi2OK;
}

/* parameters before initialisation; foam_rise_* (tunable) and the inputs at any time */
static int settable_real(const Plant *p, fmi2ValueReference vr) {
    if (vr >= FIRST_OUTPUT) return 0;
    if (vr >= FIRST_INPUT || vr == R_DA1 || vr == R_DA2) return 1;
    return p->mode == M_INSTANTIATED || p->mode == M_INIT;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real v[]) {
    Plant *p = (Plant *)c;
    size_t k;
    for (k = 0; k < n; k++) {
        if (vr[k] >= N_REAL || !settable_real(p, vr[k])) {
            logf_(p, fmi2Error, "logStatusError", "%s cannot be set now",
                  vr[k] < N_REAL ? REAL_NAMES[vr[k]] : "(unknown value reference)");
            return fmi2Error;
        }
        p->r[vr[k]] = v[k];
    }
    return fmi2OK;
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer v[]) {
    Plant *p = (Plant *)c;
    size_t k;
    for (k = 0; k < n; k++) {
        if (vr[k] >= N_INT || !(p->mode == M_INSTANTIATED || p->mode == M_INIT)) return fmi2Error;
        p->i[vr[k]] = v[k];
    }
    return fmi2OK;
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Boolean v[]) {
    Plant *p = (Plant *)c;
    size_t k;
    for (k = 0; k < n; k++) {
        if (vr[k] >= N_BOOL || !(p->mode == M_INSTANTIATED || p->mode == M_INIT)) return fmi2Error;
        p->b[vr[k]] = v[k] ? 1 : 0;
    }
    return fmi2OK;
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2String v[]) {
    (void)c; (void)vr; (void)v;
    return n ? fmi2Error : fmi2OK;
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean noSetPrior) {
    Plant *p = (Plant *)c;
    double tn;
    (void)noSetPrior;
    if (p->me) {
        logf_(p, fmi2Error, "logStatusError", "fmi2DoStep: a Model Exchange instance is advanced by its master");
        return fmi2Error;
    }
    if (p->mode != M_STEP) {
        logf_(p, fmi2Error, "logStatusError", "fmi2DoStep at t = %.17g s refused: %s", t,
              p->mode == M_FAILED ? "an earlier step failed" : "not initialised");
        return fmi2Error;
    }
    if (!(h > 0.0) || !isfinite(h)) {
        logf_(p, fmi2Error, "logStatusError", "step size h = %g s: must be finite and > 0", h);
        return fmi2Error;
    }
    /* a step within STEP_RTOL of the previous one, and a time within STEP_RTOL of a whole multiple of the
     * step, are snapped to them (the Python slaves do the same), so that accumulating masters see k h */
    if (h != p->h) {
        if (isfinite(p->h) && fabs(h - p->h) <= STEP_RTOL * p->h) h = p->h; else p->h = h;
    }
    tn = nearbyint(t / h) * h;
    if (tn != t && fabs(tn - t) <= STEP_RTOL * fabs(t)) t = tn;
    if (!inputs_finite(p, "step", t)) {
        p->mode = M_FAILED;
        return fmi2Error;
    }
    plant_step(p, t, h);
    outputs(p);
    return fmi2OK;
}

fmi2Status fmi2CancelStep(fmi2Component c) { (void)c; return fmi2Error; }

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *v) { (void)c; (void)s; (void)v; return fmi2Discard; }
fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *v) {
    Plant *p = (Plant *)c;
    if (s == fmi2LastSuccessfulTime) { *v = p->t; return fmi2OK; }
    return fmi2Discard;
}
fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *v) { (void)c; (void)s; (void)v; return fmi2Discard; }
fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *v) {
    (void)c;
    if (s == fmi2Terminated) { *v = fmi2False; return fmi2OK; }
    return fmi2Discard;
}
fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *v) { (void)c; (void)s; (void)v; return fmi2Discard; }

/* the FMU state: a copy of the Plant (the instance's own name, callbacks, logging flag and interface stay) */
fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *s) {
    Plant *p = (Plant *)c, *q;
    if (!s) return fmi2Error;
    q = *s ? (Plant *)*s : (Plant *)p->cb.allocateMemory(1, sizeof(Plant));
    if (!q) { logf_(p, fmi2Error, "logStatusError", "fmi2GetFMUstate: out of memory"); return fmi2Error; }
    *q = *p;
    q->name = NULL;
    *s = q;
    return fmi2OK;
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate s) {
    Plant *p = (Plant *)c;
    char *name = p->name;
    fmi2CallbackFunctions cb = p->cb;
    int logging = p->logging, me = p->me;
    if (!s) { logf_(p, fmi2Error, "logStatusError", "fmi2SetFMUstate: no state"); return fmi2Error; }
    *p = *(const Plant *)s;
    p->name = name; p->cb = cb; p->logging = logging; p->me = me;
    return fmi2OK;
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *s) {
    Plant *p = (Plant *)c;
    if (s && *s) { p->cb.freeMemory(*s); *s = NULL; }
    return fmi2OK;
}

/* not supported (declared so in the model description) */
fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate s, size_t *n) { (void)c; (void)s; (void)n; return fmi2Error; }
fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate s, fmi2Byte b[], size_t n) { (void)c; (void)s; (void)b; (void)n; return fmi2Error; }
fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte b[], size_t n, fmi2FMUstate *s) { (void)c; (void)b; (void)n; (void)s; return fmi2Error; }
fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference u[], size_t nu, const fmi2ValueReference z[],
                                        size_t nz, const fmi2Real dv[], fmi2Real dz[]) {
    (void)c; (void)u; (void)nu; (void)z; (void)nz; (void)dv; (void)dz; return fmi2Error; }
fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer o[],
                                       const fmi2Real v[]) { (void)c; (void)vr; (void)n; (void)o; (void)v; return fmi2Error; }
fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer o[],
                                        fmi2Real v[]) { (void)c; (void)vr; (void)n; (void)o; (void)v; return fmi2Error; }

/* ---------------------------------------------------------------------------- FMI 2.0 Model Exchange */
/* 1 if the call is allowed: a Model Exchange instance in one of the modes */
static int me_call(Plant *p, const char *fn, unsigned modes) {
    if (!p->me) {
        logf_(p, fmi2Error, "logStatusError", "%s: not a Model Exchange instance", fn);
        return 0;
    }
    if (!(IN(p->mode) & modes)) {
        logf_(p, fmi2Error, "logStatusError", "%s at t = %.17g s refused: %s", fn, p->t,
              p->mode == M_FAILED ? "an earlier call failed" : "not in the mode for it");
        return 0;
    }
    return 1;
}

fmi2Status fmi2EnterEventMode(fmi2Component c) {
    Plant *p = (Plant *)c;
    if (!me_call(p, "fmi2EnterEventMode", IN(M_EVENT) | IN(M_CONT))) return fmi2Error;
    p->mode = M_EVENT;
    return fmi2OK;
}

/* at every event: the foam region is checked (the state event of region_indicator: the foam is reached at
 * the event's time), and the next time event is the next kink of the foam level */
fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo *ev) {
    Plant *p = (Plant *)c;
    double te = 0.0;
    if (!me_call(p, "fmi2NewDiscreteStates", IN(M_EVENT))) return fmi2Error;
    check_region(p);
    ev->newDiscreteStatesNeeded = fmi2False;
    ev->terminateSimulation = fmi2False;
    ev->nominalsOfContinuousStatesChanged = fmi2False;
    ev->valuesOfContinuousStatesChanged = fmi2False;
    ev->nextEventTimeDefined = next_time_event(p, &te) ? fmi2True : fmi2False;
    ev->nextEventTime = te;
    return fmi2OK;
}

fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c) {
    Plant *p = (Plant *)c;
    if (!me_call(p, "fmi2EnterContinuousTimeMode", IN(M_EVENT) | IN(M_CONT))) return fmi2Error;
    p->mode = M_CONT;
    return fmi2OK;
}

/* completedIntegratorStepNotNeeded="true": nothing to do after a step */
fmi2Status fmi2CompletedIntegratorStep(fmi2Component c, fmi2Boolean noSetPrior, fmi2Boolean *enterEventMode,
                                       fmi2Boolean *terminateSimulation) {
    Plant *p = (Plant *)c;
    (void)noSetPrior;
    if (!me_call(p, "fmi2CompletedIntegratorStep", IN(M_CONT))) return fmi2Error;
    *enterEventMode = fmi2False;
    *terminateSimulation = fmi2False;
    return fmi2OK;
}

fmi2Status fmi2SetTime(fmi2Component c, fmi2Real t) {
    Plant *p = (Plant *)c;
    if (!me_call(p, "fmi2SetTime", IN(M_EVENT) | IN(M_CONT))) return fmi2Error;
    p->t = t;
    return fmi2OK;
}

fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t nx) {
    Plant *p = (Plant *)c;
    if (!me_call(p, "fmi2SetContinuousStates", IN(M_EVENT) | IN(M_CONT))) return fmi2Error;
    if (nx != NX) { logf_(p, fmi2Error, "logStatusError", "fmi2SetContinuousStates: %u states, not %d", (unsigned)nx, NX); return fmi2Error; }
    memcpy(p->x, x, sizeof p->x);
    return fmi2OK;
}

fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real dx[], size_t nx) {
    Plant *p = (Plant *)c;
    if (!me_call(p, "fmi2GetDerivatives", IN(M_EVENT) | IN(M_CONT))) return fmi2Error;
    if (nx != NX) { logf_(p, fmi2Error, "logStatusError", "fmi2GetDerivatives: %u states, not %d", (unsigned)nx, NX); return fmi2Error; }
    if (!inputs_finite(p, "derivatives", p->t)) {
        p->mode = M_FAILED;
        return fmi2Error;
    }
    derivatives(p, dx);
    return fmi2OK;
}

fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real z[], size_t nz) {
    Plant *p = (Plant *)c;
    if (!me_call(p, "fmi2GetEventIndicators", IN(M_EVENT) | IN(M_CONT))) return fmi2Error;
    if (nz != NZ) { logf_(p, fmi2Error, "logStatusError", "fmi2GetEventIndicators: %u indicators, not %d", (unsigned)nz, NZ); return fmi2Error; }
    z[0] = region_indicator(p);
    return fmi2OK;
}

fmi2Status fmi2GetContinuousStates(fmi2Component c, fmi2Real x[], size_t nx) {
    Plant *p = (Plant *)c;
    if (!me_call(p, "fmi2GetContinuousStates", IN(M_EVENT) | IN(M_CONT))) return fmi2Error;
    if (nx != NX) { logf_(p, fmi2Error, "logStatusError", "fmi2GetContinuousStates: %u states, not %d", (unsigned)nx, NX); return fmi2Error; }
    memcpy(x, p->x, sizeof p->x);
    return fmi2OK;
}

fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real x[], size_t nx) {
    Plant *p = (Plant *)c;
    size_t k;
    if (!me_call(p, "fmi2GetNominalsOfContinuousStates", ~0u)) return fmi2Error;
    if (nx != NX) { logf_(p, fmi2Error, "logStatusError", "fmi2GetNominalsOfContinuousStates: %u states, not %d", (unsigned)nx, NX); return fmi2Error; }
    for (k = 0; k < nx; k++) x[k] = 1.0;
    return fmi2OK;
}
