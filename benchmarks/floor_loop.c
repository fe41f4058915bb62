/* The floor of a stepping loop (benchmarks/bench.py generic, key c_floor): a chain of FMI 2.0
 * co-simulation FMUs stepped by hand in C, making the calls our master makes in the order it makes them
 * under Gauss-Seidel (instantiate with logging on and the error category, set up, the first FMU's
 * parameter, initialise; then per step and FMU: set the input from its predecessor's output (not for the
 * first), do the step, get the output) and storing each output of each step in an array: no recording
 * file, no checks, no interpreter.  What is left is the FMUs' own cost and the calls.
 *
 * Usage: floor_loop CONFIG OUT.bin; CONFIG lines (whitespace-separated):
 *   steps h
 *   param_vr param_value                      (set on the first FMU before initialisation)
 *   then per FMU: library guid resource_uri name in_vr factor out_vr  (in_vr -1 for the first; its input
 *   is factor times its predecessor's output)
 * Writes the outputs (steps x FMUs doubles) to OUT.bin and prints {"loop_s": ...} (the stepping alone). */
#include <dlfcn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include "fmi2Functions.h"

#define MAX_FMUS 16

typedef struct {
    void *lib;
    fmi2Component c;
    fmi2SetRealTYPE *setReal;
    fmi2GetRealTYPE *getReal;
    fmi2DoStepTYPE *doStep;
    fmi2ValueReference in_vr, out_vr;
    int has_in;
    double factor;
} Fmu;

static void logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status, fmi2String category,
                   fmi2String message, ...) {
    (void)env; (void)name; (void)status; (void)category; (void)message;
}

static void *sym(void *lib, const char *name) {
    void *p = dlsym(lib, name);
    if (!p) { fprintf(stderr, "no %s\n", name); exit(2); }
    return p;
}

int main(int argc, char **argv) {
    FILE *cfg;
    long steps, k;
    double h, pval;
    unsigned pvr;
    Fmu f[MAX_FMUS];
    int n = 0, i;
    char lib[4096], guid[512], uri[4096], name[256];
    long in_vr, out_vr;
    double factor;
    fmi2CallbackFunctions cb = {logger, calloc, free, NULL, NULL};
    fmi2String cats[] = {"logStatusError"};
    double *out, prev = 0.0, v;
    struct timespec a, b;
    if (argc != 3 || !(cfg = fopen(argv[1], "r"))) { fprintf(stderr, "usage: floor_loop CONFIG OUT.bin\n"); return 2; }
    if (fscanf(cfg, "%ld %lf %u %lf", &steps, &h, &pvr, &pval) != 4) return 2;
    while (n < MAX_FMUS && fscanf(cfg, "%4095s %511s %4095s %255s %ld %lf %ld", lib, guid, uri, name, &in_vr, &factor,
                                  &out_vr) == 7) {
        Fmu *p = &f[n];
        fmi2InstantiateTYPE *inst;
        p->lib = dlopen(lib, RTLD_NOW | RTLD_LOCAL);
        if (!p->lib) { fprintf(stderr, "%s\n", dlerror()); return 2; }
        inst = (fmi2InstantiateTYPE *)sym(p->lib, "fmi2Instantiate");
        p->setReal = (fmi2SetRealTYPE *)sym(p->lib, "fmi2SetReal");
        p->getReal = (fmi2GetRealTYPE *)sym(p->lib, "fmi2GetReal");
        p->doStep = (fmi2DoStepTYPE *)sym(p->lib, "fmi2DoStep");
        p->c = inst(name, fmi2CoSimulation, guid, uri, &cb, fmi2False, fmi2True);
        if (!p->c) { fprintf(stderr, "%s: fmi2Instantiate failed\n", name); return 2; }
        ((fmi2SetDebugLoggingTYPE *)sym(p->lib, "fmi2SetDebugLogging"))(p->c, fmi2True, 1, cats);
        ((fmi2SetupExperimentTYPE *)sym(p->lib, "fmi2SetupExperiment"))(p->c, fmi2False, 0.0, 0.0, fmi2False, 0.0);
        if (n == 0) p->setReal(p->c, &pvr, 1, &pval);
        ((fmi2EnterInitializationModeTYPE *)sym(p->lib, "fmi2EnterInitializationMode"))(p->c);
        p->has_in = in_vr >= 0;
        p->in_vr = (fmi2ValueReference)(in_vr < 0 ? 0 : in_vr);
        p->out_vr = (fmi2ValueReference)out_vr;
        p->factor = factor;
        n++;
    }
    fclose(cfg);
    for (i = 0; i < n; i++)
        ((fmi2ExitInitializationModeTYPE *)sym(f[i].lib, "fmi2ExitInitializationMode"))(f[i].c);
    out = malloc(sizeof(double) * (size_t)steps * (size_t)n);
    clock_gettime(CLOCK_MONOTONIC, &a);
    for (k = 0; k < steps; k++) {
        double t = (double)k * h;
        for (i = 0; i < n; i++) {
            Fmu *p = &f[i];
            if (p->has_in) {
                v = p->factor == 1.0 ? prev : prev * p->factor;
                if (p->setReal(p->c, &p->in_vr, 1, &v)) return 1;
            }
            if (p->doStep(p->c, t, h, fmi2True)) return 1;
            if (p->getReal(p->c, &p->out_vr, 1, &prev)) return 1;
            out[k * n + i] = prev;
        }
    }
    clock_gettime(CLOCK_MONOTONIC, &b);
    {
        FILE *o = fopen(argv[2], "wb");
        if (!o || fwrite(out, sizeof(double), (size_t)steps * (size_t)n, o) != (size_t)steps * (size_t)n) return 2;
        fclose(o);
    }
    printf("{\"loop_s\": %.9f}\n", (double)(b.tv_sec - a.tv_sec) + 1e-9 * (double)(b.tv_nsec - a.tv_nsec));
    return 0;
}
