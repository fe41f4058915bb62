/* Two FMI 2.0 co-simulation FMUs of one mechanical system, for tests of coupling algorithms: one C source,
 * the model chosen at compile time (tests/coupling_fmus.py builds both).
 *
 * The system: two bodies on a line, each tied to the wall by a spring-damper, tied to each other by a
 * coupling spring-damper and, optionally, a stiff one-sided contact.  Positions are measured from each
 * body's own rest position, positive to the right; body 1 sits to the LEFT of body 2, with a clearance
 * `gap` [m] between them at rest, so the bodies touch when x1 - x2 reaches gap.
 *
 * MassForce (default build): body 1.   m1 x1'' = -k1 x1 - d1 x1' + F
 *   vr 0 x [m] output, vr 1 v [m/s] output (no direct feedthrough), vr 2 F [N] input (the force on body 1);
 *   parameters vr 10 m1 [kg] (1), 11 k1 [N/m] (10), 12 d1 [N.s/m] (0.1), 13 x0 [m] (1), 14 v0 [m/s] (0),
 *   15 h_int [s] (1e-5).
 * MassCoupler (-DCOUPLER): body 2 and the coupling.   m2 x2'' = -k2 x2 - d2 x2' - F
 *   vr 0 x [m] output, vr 1 v [m/s] output, vr 2 x_in [m] input, vr 3 v_in [m/s] input (body 1's position and
 *   velocity), vr 4 F [N] output (the force ON BODY 1, direct feedthrough from x_in and v_in):
 *       F = kc (x - x_in) + dc (v - v_in) + Fc,   Fc = -kk (x_in - x - gap) if x_in - x > gap, else 0:
 *   the contact pushes body 1 to the left (Fc < 0) and, by the reaction -F, body 2 to the right: a stiff
 *   repulsion;
 *   parameters vr 10 m2 [kg] (1), 11 k2 [N/m] (10), 12 d2 [N.s/m] (0.1), 13 x0 [m] (0), 14 v0 [m/s] (0),
 *   15 h_int [s] (1e-5), 16 kc [N/m] (100), 17 dc [N.s/m] (0.5), 18 kk [N/m] (0: no contact), 19 gap [m] (0.1).
 *
 * Inputs: each Real input has a value u and a first derivative du [unit/s] (fmi2SetRealInputDerivatives,
 * order 1 only).  fmi2SetReal of an input sets u and resets du to 0.  Over a step from t to t + h the input
 * at time s is u + du (s - t); at the end of fmi2DoStep the input becomes u + du h and du is reset to 0.
 * Outputs read after a step are those of the state and the inputs at t + h; after fmi2SetReal (no step)
 * they reflect the new inputs at once.
 *
 * Integration: classic RK4 with n = ceil(h / h_int) equal substeps per communication step h (a ratio within
 * 1e-9 of a whole number counts as that number).  fmi2DoStep: time = currentCommunicationPoint + h; h <= 0
 * is an error.  The whole instance is its state (fmi2GetFMUstate copies it; serialization is not supported).
 * Parameters are fixed: settable before fmi2ExitInitializationMode only.
 */
#include <math.h>

typedef struct Mass Mass;
#define MODEL Mass
#include "cs_common.h"

#ifdef COUPLER
#define NPAR 10
#define NIN 2
static const double DEFAULTS[NPAR] = {1.0, 10.0, 0.1, 0.0, 0.0, 1e-5, 100.0, 0.5, 0.0, 0.1};
static const char *PAR_NAMES[NPAR] = {"m2", "k2", "d2", "x0", "v0", "h_int", "kc", "dc", "kk", "gap"};
#define VR_F_OUT 4
#else
#define NPAR 6
#define NIN 1
static const double DEFAULTS[NPAR] = {1.0, 10.0, 0.1, 1.0, 0.0, 1e-5};
static const char *PAR_NAMES[NPAR] = {"m1", "k1", "d1", "x0", "v0", "h_int"};
#endif

/* parameters: p[vr - VR_PAR]; inputs: u[vr - VR_IN] */
#define VR_X 0
#define VR_V 1
#define VR_IN 2
#define VR_PAR 10
enum { P_M, P_K, P_D, P_X0, P_V0, P_HINT, P_KC, P_DC, P_KK, P_GAP };

struct Mass {
    Base b;                   /* the name, the logger, the time [s], initialised */
    double p[NPAR];
    double x, v;              /* [m], [m/s] */
    double u[NIN], du[NIN];   /* inputs and their derivatives [unit], [unit/s] */
};

static size_t model_size(void) { return sizeof(Mass); }

static void model_reset(Mass *s) {
    memcpy(s->p, DEFAULTS, sizeof s->p);
    s->b.time = 0.0;
    s->b.initialized = 0;
    s->x = s->p[P_X0];
    s->v = s->p[P_V0];
    memset(s->u, 0, sizeof s->u);
    memset(s->du, 0, sizeof s->du);
}

/* The force on the body this FMU integrates [N], at position x, velocity v and inputs in[]. */
static double force(const Mass *s, double x, double v, const double in[]) {
#ifdef COUPLER
    const double *p = s->p;
    double F = p[P_KC] * (x - in[0]) + p[P_DC] * (v - in[1]);   /* on body 1 */
    double closing = in[0] - x;
    if (p[P_KK] != 0.0 && closing > p[P_GAP]) F += -p[P_KK] * (closing - p[P_GAP]);
    return -F;                                                   /* the reaction on body 2 */
#else
    (void)s; (void)x; (void)v;
    return in[0];
#endif
}

static void deriv(const Mass *s, double x, double v, const double in[], double *dx, double *dv) {
    *dx = v;
    *dv = (-s->p[P_K] * x - s->p[P_D] * v + force(s, x, v, in)) / s->p[P_M];
}

static void inputs_at(const Mass *s, double tau, double in[]) {
    for (int i = 0; i < NIN; i++) in[i] = s->u[i] + s->du[i] * tau;
}

static void rk4(Mass *s, double h) {
    double r = h / s->p[P_HINT];
    double n = ceil(r - 1e-9 * r);
    if (n < 1.0) n = 1.0;
    double dt = h / n, tau = 0.0;
    for (long i = 0; i < (long)n; i++) {
        double in[NIN], k1x, k1v, k2x, k2v, k3x, k3v, k4x, k4v;
        double x = s->x, v = s->v;
        inputs_at(s, tau, in);
        deriv(s, x, v, in, &k1x, &k1v);
        inputs_at(s, tau + 0.5 * dt, in);
        deriv(s, x + 0.5 * dt * k1x, v + 0.5 * dt * k1v, in, &k2x, &k2v);
        deriv(s, x + 0.5 * dt * k2x, v + 0.5 * dt * k2v, in, &k3x, &k3v);
        inputs_at(s, tau + dt, in);
        deriv(s, x + dt * k3x, v + dt * k3v, in, &k4x, &k4v);
        s->x = x + dt / 6.0 * (k1x + 2.0 * k2x + 2.0 * k3x + k4x);
        s->v = v + dt / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v);
        tau = (double)(i + 1) * dt;
    }
}

#ifdef COUPLER
static double coupling_force(const Mass *s) { return -force(s, s->x, s->v, s->u); }
#endif

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real v[]) {
    Mass *s = (Mass *)c;
    for (size_t i = 0; i < n; i++) {
        fmi2ValueReference r = vr[i];
        if (r == VR_X) v[i] = s->x;
        else if (r == VR_V) v[i] = s->v;
        else if (r >= VR_IN && r < VR_IN + NIN) v[i] = s->u[r - VR_IN];
#ifdef COUPLER
        else if (r == VR_F_OUT) v[i] = coupling_force(s);
#endif
        else if (r >= VR_PAR && r < VR_PAR + NPAR) v[i] = s->p[r - VR_PAR];
        else {
            say(s, "fmi2GetReal: unknown value reference %u", (unsigned)r);
            return fmi2Error;
        }
    }
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real v[]) {
    Mass *s = (Mass *)c;
    for (size_t i = 0; i < n; i++) {
        fmi2ValueReference r = vr[i];
        if (r >= VR_IN && r < VR_IN + NIN) {
            s->u[r - VR_IN] = v[i];
            s->du[r - VR_IN] = 0.0;
        } else if (r >= VR_PAR && r < VR_PAR + NPAR) {
            int k = (int)(r - VR_PAR);
            if (!parameter_settable(s, "fmi2SetReal", PAR_NAMES[k])) return fmi2Error;
            if ((k == P_M || k == P_HINT) && !(v[i] > 0.0)) {
                say(s, "fmi2SetReal: %s = %g: must be > 0", PAR_NAMES[k], v[i]);
                return fmi2Error;
            }
            s->p[k] = v[i];
            if (k == P_X0) s->x = v[i];
            if (k == P_V0) s->v = v[i];
        } else {
            say(s, "fmi2SetReal: value reference %u is not an input or a parameter", (unsigned)r);
            return fmi2Error;
        }
    }
    return fmi2OK;
}

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                       const fmi2Integer o[], const fmi2Real v[]) {
    Mass *s = (Mass *)c;
    for (size_t i = 0; i < n; i++) {
        if (o[i] != 1) {
            say(s, "fmi2SetRealInputDerivatives: order %d: only order 1 is supported", (int)o[i]);
            return fmi2Error;
        }
        if (vr[i] < VR_IN || vr[i] >= VR_IN + NIN) {
            say(s, "fmi2SetRealInputDerivatives: value reference %u is not a Real input", (unsigned)vr[i]);
            return fmi2Error;
        }
    }
    for (size_t i = 0; i < n; i++) s->du[vr[i] - VR_IN] = v[i];
    return fmi2OK;
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean noSet) {
    Mass *s = (Mass *)c;
    (void)noSet;
    if (!do_step_checks(s, h)) return fmi2Error;
    rk4(s, h);
    for (int i = 0; i < NIN; i++) {
        s->u[i] += s->du[i] * h;
        s->du[i] = 0.0;
    }
    s->b.time = t + h;
    return fmi2OK;
}
