/* An FMI 2.0 co-simulation FMU that is one affine map with direct feedthrough, for tests of algebraic loops
 * (tests/coupling_fmus.py builds it):
 *
 *     y(t) = a u(t) + b0 + b1 t + bw sin(w t)
 *
 *   vr 0 u [1] input, vr 1 y [1] output (depends directly on u); parameters vr 10 a [1] (1), 11 b0 [1] (0),
 *   12 b1 [1/s] (0), 13 bw [1] (0), 14 w [rad/s] (1).
 *
 * The output is always that of the current input at the current time: after fmi2SetReal at once, after
 * fmi2DoStep at the end of the step (time = currentCommunicationPoint + h).  The instance (time, input,
 * parameters) is its state: fmi2GetFMUstate copies it (serialization is not supported).  The input may be
 * given a first derivative (fmi2SetRealInputDerivatives, order 1): over a step the input then moves
 * linearly, and the output at the end of the step is that of the input u + du h.  Parameters are fixed:
 * settable before fmi2ExitInitializationMode only.  fmi2GetDirectionalDerivative gives dy/du = a.
 */
#include <math.h>

typedef struct Affine Affine;
#define MODEL Affine
#define MODEL_DIRECTIONAL_DERIVATIVE
#include "cs_common.h"

#define NPAR 5
static const double DEFAULTS[NPAR] = {1.0, 0.0, 0.0, 0.0, 1.0};
static const char *PAR_NAMES[NPAR] = {"a", "b0", "b1", "bw", "w"};
#define VR_U 0
#define VR_Y 1
#define VR_PAR 10
enum { P_A, P_B0, P_B1, P_BW, P_W };

struct Affine {
    Base b;             /* the name, the logger, the time [s], initialised */
    double p[NPAR];
    double u, du;       /* the input [1] and its derivative [1/s] */
};

static size_t model_size(void) { return sizeof(Affine); }

static void model_reset(Affine *s) {
    memcpy(s->p, DEFAULTS, sizeof s->p);
    s->b.time = 0.0;
    s->b.initialized = 0;
    s->u = s->du = 0.0;
}

static double output(const Affine *s) {
    const double *p = s->p;
    return p[P_A] * s->u + p[P_B0] + p[P_B1] * s->b.time + p[P_BW] * sin(p[P_W] * s->b.time);
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real v[]) {
    Affine *s = (Affine *)c;
    for (size_t i = 0; i < n; i++) {
        if (vr[i] == VR_U) v[i] = s->u;
        else if (vr[i] == VR_Y) v[i] = output(s);
        else if (vr[i] >= VR_PAR && vr[i] < VR_PAR + NPAR) v[i] = s->p[vr[i] - VR_PAR];
        else {
            say(s, "fmi2GetReal: unknown value reference %u", (unsigned)vr[i]);
            return fmi2Error;
        }
    }
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real v[]) {
    Affine *s = (Affine *)c;
    for (size_t i = 0; i < n; i++) {
        if (vr[i] == VR_U) {
            s->u = v[i];
            s->du = 0.0;
        } else if (vr[i] >= VR_PAR && vr[i] < VR_PAR + NPAR) {
            if (!parameter_settable(s, "fmi2SetReal", PAR_NAMES[vr[i] - VR_PAR])) return fmi2Error;
            s->p[vr[i] - VR_PAR] = v[i];
        } else {
            say(s, "fmi2SetReal: value reference %u is not an input or a parameter", (unsigned)vr[i]);
            return fmi2Error;
        }
    }
    return fmi2OK;
}

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                       const fmi2Integer o[], const fmi2Real v[]) {
    Affine *s = (Affine *)c;
    for (size_t i = 0; i < n; i++) {
        if (o[i] != 1 || vr[i] != VR_U) {
            say(s, "fmi2SetRealInputDerivatives: only the first derivative of u (value reference 0)");
            return fmi2Error;
        }
        s->du = v[i];
    }
    return fmi2OK;
}

/* The output's derivative by the input: a (the only unknown y, the only known u). */
fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference unknowns[], size_t nu,
                                        const fmi2ValueReference knowns[], size_t nk, const fmi2Real seed[],
                                        fmi2Real out[]) {
    Affine *s = (Affine *)c;
    for (size_t i = 0; i < nu; i++) {
        if (unknowns[i] != VR_Y) {
            say(s, "fmi2GetDirectionalDerivative: unknown %u is not the output y", (unsigned)unknowns[i]);
            return fmi2Error;
        }
        out[i] = 0.0;
        for (size_t j = 0; j < nk; j++) {
            if (knowns[j] != VR_U) {
                say(s, "fmi2GetDirectionalDerivative: known %u is not the input u", (unsigned)knowns[j]);
                return fmi2Error;
            }
            out[i] += s->p[P_A] * seed[j];
        }
    }
    return fmi2OK;
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean noSet) {
    Affine *s = (Affine *)c;
    (void)noSet;
    if (!do_step_checks(s, h)) return fmi2Error;
    s->u += s->du * h;
    s->du = 0.0;
    s->b.time = t + h;
    return fmi2OK;
}
