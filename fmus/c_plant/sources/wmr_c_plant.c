/* WmrCPlant: the wheeled mobile robot plant of wmr-cosim, written in C as an FMI 2.0 co-simulation FMU
 * "from another toolchain".  The same physics as components/plant.py (Maggi dynamics (34)-(36) of the two
 * drive wheels and the pose of point A (23)-(24), RK4 in `rk4_substeps` substeps per communication step
 * with the inputs held, the friction 2 a tanh(cF w / 2) of (36) or its printed exp form, the foam: a5, a6
 * rise by foam_rise_* times a level ramping linearly over foam_ramp_time once the foam is reached, by time
 * or by region), in the same operation order, so that with the same inputs the states are bit-identical.
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

/* Real value references */
enum {
    R_A1, R_A2, R_A3, R_A4, R_A5, R_A6, R_CF, R_R, R_L1, R_X0, R_Y0, R_HEAD0,
    R_DA1, R_DA2, R_RAMP, R_TON, R_XLO, R_XHI, R_YLO, R_YHI,
    R_U1, R_U2, R_D1, R_D2,
    R_PHI1, R_PHI2, R_OM1, R_OM2, R_X, R_Y, R_HEAD, R_DF1, R_DF2, R_LAMBDA,
    N_REAL
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
    "dist_total_right", "dist_total_left", "foam_lambda"};

typedef enum { M_INSTANTIATED, M_INIT, M_STEP, M_TERMINATED, M_FAILED } Mode;

typedef struct {
    fmi2CallbackFunctions cb;
    char *name;
    int logging;
    Mode mode;
    double r[N_REAL];
    int i[N_INT];
    int b[N_BOOL];
    /* state */
    double x[7];          /* alpha1, alpha2, w1, w2, xA, yA, beta [rad, rad/s, m] */
    double t;             /* time of the state */
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
    double u1 = r[R_U1], u2 = r[R_U2], tau1 = r[R_D1], tau2 = r[R_D2];
    int n = p->i[I_SUBSTEPS], s;
    double dt = h / n, hdt = 0.5 * dt, i11 = p->i11, i12 = p->i12, k = 0.5 * r[R_CF], a4x2 = 2.0 * r[R_A4];
    double a5 = r[R_A5], a6 = r[R_A6], da1 = r[R_DA1], da2 = r[R_DA2], hr = 0.5 * r[R_R], hrl = hr / r[R_L1];
    double lam = 0.0, f5 = 0.0, f6 = 0.0, ts;
    double x1, x2, w1, w2, xa, ya, be;
    int stat;
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
        double c, r1, r2, v, kw1a, kw2a, kxa, kya, kba, kw1b, kw2b, kxb, kyb, kbb, kw1c, kw2c, kxc, kyc, kbc;
        double kw1d, kw2d, kxd, kyd, kbd, wb1, wb2, bb, wc1, wc2, bc, wd1, wd2, bd, s6;
        if (!stat) { lam = foam_level(p, ts); f5 = 2.0 * (a5 + lam * da1); f6 = 2.0 * (a6 + lam * da2); }
        c = a4x2 * (w2 - w1);
        r1 = u1 - c * w2 - f5 * g_shape(p, k * w1) - tau1;
        r2 = u2 + c * w1 - f6 * g_shape(p, k * w2) - tau2;
        kw1a = i11 * r1 + i12 * r2; kw2a = i12 * r1 + i11 * r2;
        v = hr * (w1 + w2);
        kxa = v * cos(be); kya = v * sin(be); kba = hrl * (w1 - w2);
        if (!stat) { lam = foam_level(p, ts + hdt); f5 = 2.0 * (a5 + lam * da1); f6 = 2.0 * (a6 + lam * da2); }
        wb1 = w1 + hdt * kw1a; wb2 = w2 + hdt * kw2a; bb = be + hdt * kba;
        c = a4x2 * (wb2 - wb1);
        r1 = u1 - c * wb2 - f5 * g_shape(p, k * wb1) - tau1;
        r2 = u2 + c * wb1 - f6 * g_shape(p, k * wb2) - tau2;
        kw1b = i11 * r1 + i12 * r2; kw2b = i12 * r1 + i11 * r2;
        v = hr * (wb1 + wb2);
        kxb = v * cos(bb); kyb = v * sin(bb); kbb = hrl * (wb1 - wb2);
        wc1 = w1 + hdt * kw1b; wc2 = w2 + hdt * kw2b; bc = be + hdt * kbb;
        c = a4x2 * (wc2 - wc1);
        r1 = u1 - c * wc2 - f5 * g_shape(p, k * wc1) - tau1;
        r2 = u2 + c * wc1 - f6 * g_shape(p, k * wc2) - tau2;
        kw1c = i11 * r1 + i12 * r2; kw2c = i12 * r1 + i11 * r2;
        v = hr * (wc1 + wc2);
        kxc = v * cos(bc); kyc = v * sin(bc); kbc = hrl * (wc1 - wc2);
        if (!stat) { lam = foam_level(p, ts + dt); f5 = 2.0 * (a5 + lam * da1); f6 = 2.0 * (a6 + lam * da2); }
        wd1 = w1 + dt * kw1c; wd2 = w2 + dt * kw2c; bd = be + dt * kbc;
        c = a4x2 * (wd2 - wd1);
        r1 = u1 - c * wd2 - f5 * g_shape(p, k * wd1) - tau1;
        r2 = u2 + c * wd1 - f6 * g_shape(p, k * wd2) - tau2;
        kw1d = i11 * r1 + i12 * r2; kw2d = i12 * r1 + i11 * r2;
        v = hr * (wd1 + wd2);
        kxd = v * cos(bd); kyd = v * sin(bd); kbd = hrl * (wd1 - wd2);
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

/* the initial state from the parameters (PlantParams checks + Plant.reset); 0 if a parameter is bad */
static int reset_state(Plant *p) {
    double *r = p->r, m11, m12, det;
    int k;
    for (k = 0; k < FIRST_INPUT; k++)
        if (!isfinite(r[k])) { logf_(p, fmi2Error, "logStatusError", "parameter %s = %g: must be finite", REAL_NAMES[k], r[k]); return 0; }
    if (!(r[R_CF] > 0.0) || !(r[R_R] > 0.0) || !(r[R_L1] > 0.0)) {
        logf_(p, fmi2Error, "logStatusError", "slope_cF, wheel_radius and half_track must be > 0"); return 0; }
    if (r[R_A4] < 0.0 || r[R_A5] < 0.0 || r[R_A6] < 0.0 || r[R_RAMP] < 0.0) {
        logf_(p, fmi2Error, "logStatusError", "coriolis_a4, roll_res_*, foam_ramp_time must be >= 0"); return 0; }
    if (p->i[I_SUBSTEPS] < 1) {
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
    if (type != fmi2CoSimulation || !guid || strcmp(guid, GUID) != 0) {
        if (cb->logger) cb->logger(cb->componentEnvironment, name, fmi2Error, "logStatusError",
                                   "WmrCPlant: only co-simulation, GUID %s", GUID);
        return NULL;
    }
    p = (Plant *)cb->allocateMemory(1, sizeof(Plant));
    if (!p) return NULL;
    p->cb = *cb;
    p->name = (char *)cb->allocateMemory(strlen(name ? name : "") + 1, 1);
    if (p->name) strcpy(p->name, name ? name : "");
    p->logging = loggingOn;
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
    p->mode = M_STEP;
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

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real v[]) {
    Plant *p = (Plant *)c;
    size_t k;
    for (k = 0; k < n; k++) {
        if (vr[k] >= N_REAL) { logf_(p, fmi2Error, "logStatusError", "no Real with value reference %u", vr[k]); return fmi2Error; }
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
    double tn, s;
    (void)noSetPrior;
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
    s = p->r[R_U1] + p->r[R_U2] + p->r[R_D1] + p->r[R_D2];
    if (!isfinite(s)) {
        logf_(p, fmi2Error, "logStatusError", "step at t = %.17g s: non-finite input (torque_right = %g, torque_left = %g, "
              "dist_right = %g, dist_left = %g N.m)", t, p->r[R_U1], p->r[R_U2], p->r[R_D1], p->r[R_D2]);
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

/* not supported (declared so in the model description) */
fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *s) { (void)c; (void)s; return fmi2Error; }
fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate s) { (void)c; (void)s; return fmi2Error; }
fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *s) { (void)c; (void)s; return fmi2Error; }
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
