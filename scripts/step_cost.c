/* Nanoseconds per fmi2DoStep (with one fmi2SetReal of the inputs before it) of one FMU binary,
 * best of 7 runs of N steps: the cost of a model's step plus the shared layer, no Python.
 *   step_cost LIB.so GUID PORT_MODE_VR MODE N INPUT_VR...   (used by scripts/ph_step_cost.py) */
#define _POSIX_C_SOURCE 200809L
#include <dlfcn.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "fmi2Functions.h"

static void logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status s, fmi2String cat,
                   fmi2String msg, ...) {
    (void)env; (void)s; (void)cat;
    fprintf(stderr, "%s: %s\n", name, msg);
}

static void *need(void *lib, const char *name) {
    void *f = dlsym(lib, name);
    if (!f) { fprintf(stderr, "missing %s\n", name); exit(2); }
    return f;
}

static double now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

int main(int argc, char **argv) {
    if (argc < 7) { fprintf(stderr, "usage: step_cost LIB GUID PORT_MODE_VR MODE N INPUT_VR...\n"); return 2; }
    void *lib = dlopen(argv[1], RTLD_NOW);
    if (!lib) { fprintf(stderr, "%s\n", dlerror()); return 2; }
    fmi2InstantiateTYPE *inst = need(lib, "fmi2Instantiate");
    fmi2SetupExperimentTYPE *setup = need(lib, "fmi2SetupExperiment");
    fmi2EnterInitializationModeTYPE *enter = need(lib, "fmi2EnterInitializationMode");
    fmi2ExitInitializationModeTYPE *leave = need(lib, "fmi2ExitInitializationMode");
    fmi2SetIntegerTYPE *set_int = need(lib, "fmi2SetInteger");
    fmi2SetRealTYPE *set_real = need(lib, "fmi2SetReal");
    fmi2DoStepTYPE *do_step = need(lib, "fmi2DoStep");
    fmi2CallbackFunctions cb = {logger, calloc, free, NULL, NULL};
    fmi2Component c = inst("bench", fmi2CoSimulation, argv[2], "", &cb, fmi2False, fmi2False);
    fmi2ValueReference mode_vr = (fmi2ValueReference)atoi(argv[3]);
    fmi2Integer mode = atoi(argv[4]);
    long n = atol(argv[5]);
    size_t m = (size_t)(argc - 6);
    fmi2ValueReference vr[16];
    double u[16];
    for (size_t j = 0; j < m && j < 16; j++) vr[j] = (fmi2ValueReference)atoi(argv[6 + j]);
    if (!c || setup(c, fmi2False, 0.0, 0.0, fmi2False, 0.0) || enter(c) || set_int(c, &mode_vr, 1, &mode) ||
        leave(c)) return 1;
    double best = INFINITY, t = 0.0, h = 0.01;
    for (int rep = 0; rep < 7; rep++) {
        double start = now();
        for (long k = 0; k < n; k++) {
            for (size_t j = 0; j < m; j++) u[j] = 0.1 * sin(0.01 * (double)k + (double)j);
            if (set_real(c, vr, m, u) || do_step(c, t, h, fmi2True)) return 1;
            t += h;
        }
        best = fmin(best, (now() - start) / (double)n);
    }
    printf("%.1f\n", best * 1e9);
    return 0;
}
