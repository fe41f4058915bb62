/*
 * A minimal FMI 2.0 co-simulation host for the tests: no Python anywhere in it.  Built for Linux (the
 * FMU's binaries/linux64/MODEL.so) and, with MinGW-w64, for Windows (binaries/win64/MODEL.dll; run here
 * under Wine).
 *
 *   fmi_host SPEC        (SPEC: a text file, one directive per line)
 *
 *   fmu DIR MODEL_IDENTIFIER GUID INSTANCE   load DIR's library (once per path) and add an instance of it;
 *                                            the lines below apply to it
 *   in VR C B A W PHI                        Real input VR = C + B t + A sin(W t + PHI), set at t = 0 inside
 *                                            initialisation mode and at t = k h before each step from k h
 *   table PATH                               the instance's Real inputs (its "in" lines, in their order) from
 *                                            PATH instead: little-endian doubles, row k (the inputs at k h)
 *                                            after row k - 1, as many rows as steps + 1 (exact on every
 *                                            platform: no libm, no text conversion)
 *   real VR / int VR / bool VR               an output, printed after initialisation and after every step
 *   steps N H                                (once, anywhere) N steps of H seconds for every instance
 *   parallel                                 (once, anywhere) call every fmi2Instantiate at the same time,
 *                                            one thread per instance
 *
 * Each instance: instantiate, setup experiment (start 0), enter initialisation, set inputs, exit
 * initialisation, then the instances step in turn (set inputs, do step); terminate, free.
 * Prints "OUT INSTANCE K v1 v2 ..." (%.17g) after initialisation (K = 0) and after step K; log messages as
 * "LOG INSTANCE STATUS CATEGORY MESSAGE".  Exit code 0 if every call returned fmi2OK, 3 if an
 * fmi2Instantiate returned NULL, 4 if another call failed, 2 on a bad spec or a library that will not load.
 *
 * The host itself does not link libm (sin comes from a private dlopen of it), so an FMU that needs libm
 * must declare it.  Compile: cc -ffp-contract=off -I<FMI 2.0 headers> fmi_host.c -ldl -lpthread; for
 * Windows: x86_64-w64-mingw32-gcc -ffp-contract=off -I<FMI 2.0 headers> fmi_host.c -static-libgcc
 * ("parallel" is Linux's alone).
 */
#ifdef _WIN32
#include <windows.h>
#define LIB_DIR "win64"
#define LIB_EXT "dll"
#else
#include <dlfcn.h>
#include <pthread.h>
#define LIB_DIR "linux64"
#define LIB_EXT "so"
#endif
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"

#define MAXI 8
#define MAXV 64

typedef struct {
    void *lib;
    char dir[1024];
    fmi2InstantiateTYPE *instantiate;
    fmi2FreeInstanceTYPE *freeInstance;
    fmi2SetupExperimentTYPE *setupExperiment;
    fmi2EnterInitializationModeTYPE *enterInit;
    fmi2ExitInitializationModeTYPE *exitInit;
    fmi2SetRealTYPE *setReal;
    fmi2GetRealTYPE *getReal;
    fmi2GetIntegerTYPE *getInteger;
    fmi2GetBooleanTYPE *getBoolean;
    fmi2DoStepTYPE *doStep;
    fmi2TerminateTYPE *terminate;
} Lib;

typedef struct {
    Lib *lib;
    char name[128], guid[128], model[128];
    fmi2Component c;
    int nin, nout;
    fmi2ValueReference in_vr[MAXV], out_vr[MAXV];
    double in_c[MAXV][5];
    int out_int[MAXV];
    FILE *table;                 /* the inputs row by row, or NULL: from in_c */
} Inst;

static double (*sin_fn)(double);
static fmi2CallbackFunctions cb;
#ifndef _WIN32
static pthread_barrier_t start_line;
#endif
static Lib libs[MAXI];
static int nlibs = 0;
static Inst insts[MAXI];
static int ninsts = 0;

static void logger(fmi2ComponentEnvironment env, fmi2String instance, fmi2Status status, fmi2String category,
                   fmi2String message, ...) {
    char buf[4096];
    va_list ap;
    va_start(ap, message);
    vsnprintf(buf, sizeof buf, message, ap);
    va_end(ap);
    (void)env;
    printf("LOG %s %d %s %s\n", instance ? instance : "?", (int)status, category ? category : "-", buf);
    fflush(stdout);
}

static void *sym(Lib *l, const char *name) {
#ifdef _WIN32
    void *p = (void *)GetProcAddress((HMODULE)l->lib, name);
#else
    void *p = dlsym(l->lib, name);
#endif
    if (!p) {
        printf("ERROR %s: no %s\n", l->dir, name);
        exit(2);
    }
    return p;
}

static Lib *load(const char *dir, const char *model) {
    for (int i = 0; i < nlibs; ++i)
        if (strcmp(libs[i].dir, dir) == 0) return &libs[i];
    Lib *l = &libs[nlibs++];
    char path[2048];
    snprintf(l->dir, sizeof l->dir, "%s", dir);
    snprintf(path, sizeof path, "%s/binaries/" LIB_DIR "/%s." LIB_EXT, dir, model);
#ifdef _WIN32
    l->lib = (void *)LoadLibraryA(path);
    if (!l->lib) {
        printf("ERROR LoadLibrary %s: error %lu\n", path, (unsigned long)GetLastError());
        exit(2);
    }
#else
    l->lib = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!l->lib) {
        printf("ERROR dlopen %s\n", dlerror());
        exit(2);
    }
#endif
    *(void **)&l->instantiate = sym(l, "fmi2Instantiate");
    *(void **)&l->freeInstance = sym(l, "fmi2FreeInstance");
    *(void **)&l->setupExperiment = sym(l, "fmi2SetupExperiment");
    *(void **)&l->enterInit = sym(l, "fmi2EnterInitializationMode");
    *(void **)&l->exitInit = sym(l, "fmi2ExitInitializationMode");
    *(void **)&l->setReal = sym(l, "fmi2SetReal");
    *(void **)&l->getReal = sym(l, "fmi2GetReal");
    *(void **)&l->getInteger = sym(l, "fmi2GetInteger");
    *(void **)&l->getBoolean = sym(l, "fmi2GetBoolean");
    *(void **)&l->doStep = sym(l, "fmi2DoStep");
    *(void **)&l->terminate = sym(l, "fmi2Terminate");
    return l;
}

static int check(fmi2Status s, const char *what, Inst *in) {
    if (s != fmi2OK) {
        printf("FAILED %s %s status %d\n", in->name, what, (int)s);
        return 0;
    }
    return 1;
}

static int set_inputs(Inst *in, double t) {
    if (in->nin == 0) return 1;
    double v[MAXV];
    if (in->table) {
        if (fread(v, sizeof(double), (size_t)in->nin, in->table) != (size_t)in->nin) {
            printf("FAILED %s table: no row for t = %.17g\n", in->name, t);
            return 0;
        }
    } else {
        for (int i = 0; i < in->nin; ++i) {
            const double *k = in->in_c[i];
            v[i] = k[0] + k[1] * t + k[2] * sin_fn(k[3] * t + k[4]);
        }
    }
    return check(in->lib->setReal(in->c, in->in_vr, in->nin, v), "fmi2SetReal", in);
}

static int print_outputs(Inst *in, int k) {
    printf("OUT %s %d", in->name, k);
    for (int i = 0; i < in->nout; ++i) {
        if (in->out_int[i] == 2) {
            fmi2Boolean x;
            if (!check(in->lib->getBoolean(in->c, &in->out_vr[i], 1, &x), "fmi2GetBoolean", in)) return 0;
            printf(" %d", x ? 1 : 0);
        } else if (in->out_int[i]) {
            fmi2Integer x;
            if (!check(in->lib->getInteger(in->c, &in->out_vr[i], 1, &x), "fmi2GetInteger", in)) return 0;
            printf(" %d", (int)x);
        } else {
            fmi2Real x;
            if (!check(in->lib->getReal(in->c, &in->out_vr[i], 1, &x), "fmi2GetReal", in)) return 0;
            printf(" %.17g", x);
        }
    }
    printf("\n");
    return 1;
}

static void instantiate(Inst *in) {
    char uri[2100];
#ifdef _WIN32
    char full[1024];   /* file:///C:/path/resources (under Wine, a Linux path is on drive Z:) */
    DWORD n = GetFullPathNameA(in->lib->dir, sizeof full, full, NULL);
    if (n == 0 || n >= sizeof full) snprintf(full, sizeof full, "%s", in->lib->dir);
    for (char *p = full; *p; ++p)
        if (*p == '\\') *p = '/';
    snprintf(uri, sizeof uri, "file:///%s/resources", full);
#else
    snprintf(uri, sizeof uri, "file://%s/resources", in->lib->dir);
#endif
    in->c = in->lib->instantiate(in->name, fmi2CoSimulation, in->guid, uri, &cb, fmi2False, fmi2True);
}

#ifndef _WIN32
static void *instantiate_thread(void *arg) {
    pthread_barrier_wait(&start_line);
    instantiate((Inst *)arg);
    return NULL;
}
#endif

int main(int argc, char **argv) {
    if (argc != 2) {
        fprintf(stderr, "usage: fmi_host SPEC\n");
        return 2;
    }
#ifdef _WIN32
    HMODULE libm = LoadLibraryA("msvcrt.dll");
    if (!libm || !(*(void **)&sin_fn = (void *)GetProcAddress(libm, "sin"))) {
        fprintf(stderr, "cannot load sin from msvcrt.dll\n");
        return 2;
    }
#else
    void *libm = dlopen("libm.so.6", RTLD_NOW | RTLD_LOCAL);
    if (!libm || !(*(void **)&sin_fn = dlsym(libm, "sin"))) {
        fprintf(stderr, "cannot load sin from libm.so.6\n");
        return 2;
    }
#endif
    FILE *f = fopen(argv[1], "r");
    if (!f) {
        fprintf(stderr, "cannot open %s\n", argv[1]);
        return 2;
    }
    char line[4096], dir[1024], model[128], guid[128], name[128], table[1024];
    long nsteps = 0;
    int parallel = 0;
    double h = 0.0;
    Inst *cur = NULL;
    while (fgets(line, sizeof line, f)) {
        unsigned vr;
        double k[5];
        if (sscanf(line, "fmu %1023s %127s %127s %127s", dir, model, guid, name) == 4) {
            if (ninsts == MAXI) return 2;
            cur = &insts[ninsts++];
            cur->lib = load(dir, model);
            snprintf(cur->name, sizeof cur->name, "%s", name);
            snprintf(cur->guid, sizeof cur->guid, "%s", guid);
            snprintf(cur->model, sizeof cur->model, "%s", model);
        } else if (cur && sscanf(line, "in %u %lf %lf %lf %lf %lf", &vr, &k[0], &k[1], &k[2], &k[3], &k[4]) == 6) {
            cur->in_vr[cur->nin] = vr;
            memcpy(cur->in_c[cur->nin++], k, sizeof k);
        } else if (cur && sscanf(line, "real %u", &vr) == 1) {
            cur->out_vr[cur->nout] = vr;
            cur->out_int[cur->nout++] = 0;
        } else if (cur && sscanf(line, "int %u", &vr) == 1) {
            cur->out_vr[cur->nout] = vr;
            cur->out_int[cur->nout++] = 1;
        } else if (cur && sscanf(line, "bool %u", &vr) == 1) {
            cur->out_vr[cur->nout] = vr;
            cur->out_int[cur->nout++] = 2;
        } else if (cur && sscanf(line, "table %1023s", table) == 1) {
            cur->table = fopen(table, "rb");
            if (!cur->table) {
                fprintf(stderr, "cannot open %s\n", table);
                return 2;
            }
        } else if (strncmp(line, "parallel", 8) == 0) {
            parallel = 1;
        } else if (sscanf(line, "steps %ld %lf", &nsteps, &h) == 2) {
        } else if (line[0] != '\n' && line[0] != '#') {
            fprintf(stderr, "bad spec line: %s", line);
            return 2;
        }
    }
    fclose(f);
    cb.logger = logger;
    cb.allocateMemory = calloc;
    cb.freeMemory = free;
    if (parallel) {
#ifdef _WIN32
        fprintf(stderr, "parallel: not in the Windows build\n");
        return 2;
#else
        pthread_t th[MAXI];
        pthread_barrier_init(&start_line, NULL, (unsigned)ninsts);
        for (int i = 0; i < ninsts; ++i) pthread_create(&th[i], NULL, instantiate_thread, &insts[i]);
        for (int i = 0; i < ninsts; ++i) pthread_join(th[i], NULL);
#endif
    } else {
        for (int i = 0; i < ninsts; ++i) instantiate(&insts[i]);
    }
    for (int i = 0; i < ninsts; ++i) {
        Inst *in = &insts[i];
        if (!in->c) {
            printf("INSTANTIATE_FAILED %s\n", in->name);
            return 3;
        }
        if (!check(in->lib->setupExperiment(in->c, fmi2False, 0.0, 0.0, fmi2False, 0.0), "setup", in) ||
            !check(in->lib->enterInit(in->c), "enterInit", in) || !set_inputs(in, 0.0) ||
            !check(in->lib->exitInit(in->c), "exitInit", in) || !print_outputs(in, 0))
            return 4;
    }
    for (long s = 0; s < nsteps; ++s) {
        double t = (double)s * h;
        for (int i = 0; i < ninsts; ++i) {
            Inst *in = &insts[i];
            if (!set_inputs(in, t) || !check(in->lib->doStep(in->c, t, h, fmi2True), "doStep", in) ||
                !print_outputs(in, (int)s + 1))
                return 4;
        }
    }
    for (int i = 0; i < ninsts; ++i) {
        if (!check(insts[i].lib->terminate(insts[i].c), "terminate", &insts[i])) return 4;
        insts[i].lib->freeInstance(insts[i].c);
        if (insts[i].table) fclose(insts[i].table);
    }
    printf("DONE\n");
    return 0;
}
