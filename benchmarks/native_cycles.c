/* A C host with no Python: N instantiate / initialise / step / get-set FMU state / free cycles of one
 * native MAST FMU, plus calls out of order, then the resident memory growth (benchmarks/native_cycles.py
 * runs it under valgrind; tests/test_native.py too).
 *
 *   cc -O2 -I<FMI 2.0 headers, e.g. fmpy/c-code> -o native_cycles native_cycles.c -ldl
 *   ./native_cycles BINARY.so GUID N_CYCLES STEP_SIZE
 * prints "rss_kib_after_10 rss_kib_after_N statuses_ok" and exits 0 when every status was the expected one.
 */
#include <dlfcn.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2FunctionTypes.h"

static int logged = 0;
static void logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status, fmi2String category,
                   fmi2String fmt, ...)
{
    (void)env; (void)name; (void)status; (void)category; (void)fmt;
    logged++;
}

static long rss_kib(void)
{
    FILE *f = fopen("/proc/self/statm", "r");
    long pages = 0, resident = 0;
    if (f) {
        if (fscanf(f, "%ld %ld", &pages, &resident) != 2) resident = 0;
        fclose(f);
    }
    return resident * 4;
}

#define LOAD(name) name##TYPE *name = (name##TYPE *)dlsym(lib, #name); \
    if (!name) { fprintf(stderr, "missing %s\n", #name); return 2; }

int main(int argc, char **argv)
{
    if (argc != 5) { fprintf(stderr, "usage: %s BINARY.so GUID N STEP\n", argv[0]); return 2; }
    void *lib = dlopen(argv[1], RTLD_NOW | RTLD_LOCAL);
    if (!lib) { fprintf(stderr, "%s\n", dlerror()); return 2; }
    const char *guid = argv[2];
    int n = atoi(argv[3]);
    double h = atof(argv[4]);
    LOAD(fmi2Instantiate)
    LOAD(fmi2FreeInstance)
    LOAD(fmi2SetupExperiment)
    LOAD(fmi2EnterInitializationMode)
    LOAD(fmi2ExitInitializationMode)
    LOAD(fmi2Terminate)
    LOAD(fmi2DoStep)
    LOAD(fmi2GetReal)
    LOAD(fmi2SetReal)
    LOAD(fmi2GetFMUstate)
    LOAD(fmi2SetFMUstate)
    LOAD(fmi2FreeFMUstate)
    fmi2CallbackFunctions cb = {logger, calloc, free, NULL, NULL};
    int bad = 0;
    long rss10 = 0;
    for (int k = 0; k < n; k++) {
        fmi2Component c = fmi2Instantiate("cycle", fmi2CoSimulation, guid, "file:///nowhere", &cb, 0, 0);
        if (!c) { fprintf(stderr, "instantiate failed\n"); return 1; }
        fmi2ValueReference vr0 = 0, unknown = 100000;
        double v = 0.0, out[4];
        bad += fmi2DoStep(c, 0.0, h, 1) != 3;                     /* before initialization: fmi2Error */
        bad += fmi2GetReal(c, &unknown, 1, out) != 3;              /* unknown value reference: fmi2Error */
        bad += fmi2SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0) != 0;
        bad += fmi2EnterInitializationMode(c) != 0;
        bad += fmi2ExitInitializationMode(c) != 0;
        fmi2FMUstate state = NULL;
        for (int s = 0; s < 5; s++) {
            int st = fmi2DoStep(c, s * h, h, 1);
            bad += st != 0 && st != 2;                           /* OK, or Discard (a model refusing) */
            if (s == 2) bad += fmi2GetFMUstate(c, &state) != 0;
        }
        bad += fmi2SetFMUstate(c, state) != 0;
        bad += fmi2FreeFMUstate(c, &state) != 0;
        bad += fmi2GetReal(c, &vr0, 1, &v) != 0;
        bad += fmi2SetReal(c, &unknown, 1, &v) != 3;
        bad += fmi2Terminate(c) != 0;
        fmi2FreeInstance(c);
        if (k == 9) rss10 = rss_kib();
    }
    printf("%ld %ld %d %d\n", rss10, rss_kib(), bad == 0, logged);
    dlclose(lib);
    return bad != 0;
}
