/* A careless FMI 2.0 host in C (tests/test_careless_host.py): one instance run, freed twice, then called again.
 *
 *   cc -I<FMI 2.0 headers> -o careless_host careless_host.c -ldl
 *   ./careless_host BINARY.so GUID RESOURCES_URI STEP_SIZE
 * prints "bad=<calls that did not answer as expected> logged_after_free=<messages after the first free>" and exits
 * with the number of bad answers (a crash: the signal's exit status).
 */
#include <dlfcn.h>
#include <stdio.h>
#include <stdlib.h>

#include "fmi2FunctionTypes.h"

static int logged = 0;
static void logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status, fmi2String category,
                   fmi2String message, ...)
{
    (void)env; (void)name; (void)status; (void)category; (void)message;
    logged++;
}

/* the FMI functions this host calls, each loaded as a local of its own name */
#define CALLS(X) X(fmi2Instantiate) X(fmi2FreeInstance) X(fmi2SetupExperiment) X(fmi2EnterInitializationMode) \
    X(fmi2ExitInitializationMode) X(fmi2Terminate) X(fmi2DoStep) X(fmi2GetReal) X(fmi2SetReal)
#define LOAD(name) name##TYPE *name = (name##TYPE *)dlsym(lib, #name); \
    if (!name) { fprintf(stderr, "missing %s\n", #name); return 100; }

int main(int argc, char **argv)
{
    if (argc != 5) { fprintf(stderr, "usage: %s BINARY.so GUID RESOURCES_URI STEP\n", argv[0]); return 100; }
    void *lib = dlopen(argv[1], RTLD_NOW | RTLD_LOCAL);
    if (!lib) { fprintf(stderr, "%s\n", dlerror()); return 100; }
    double h = atof(argv[4]);
    CALLS(LOAD)
    fmi2CallbackFunctions cb = {logger, calloc, free, NULL, NULL};
    fmi2Component c = fmi2Instantiate("careless", fmi2CoSimulation, argv[2], argv[3], &cb, 0, 0);
    if (!c) { fprintf(stderr, "instantiate failed\n"); return 100; }
    fmi2ValueReference vr0 = 0;
    double v = 0.0;
    int bad = 0;
    bad += fmi2SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0) != fmi2OK;
    bad += fmi2EnterInitializationMode(c) != fmi2OK;
    bad += fmi2ExitInitializationMode(c) != fmi2OK;
    bad += fmi2DoStep(c, 0.0, h, 1) != fmi2OK;
    bad += fmi2Terminate(c) != fmi2OK;
    fmi2FreeInstance(c);
    int before = logged;
    fmi2FreeInstance(c);                                         /* a second free: refused, nothing touched */
    bad += fmi2DoStep(c, h, h, 1) != fmi2Error;                  /* every call on the freed instance: Error */
    bad += fmi2GetReal(c, &vr0, 1, &v) != fmi2Error;
    bad += fmi2SetReal(c, &vr0, 1, &v) != fmi2Error;
    bad += fmi2Terminate(c) != fmi2Error;
    fmi2FreeInstance(c);
    /* the process goes on: a new instance works */
    fmi2Component d = fmi2Instantiate("after", fmi2CoSimulation, argv[2], argv[3], &cb, 0, 0);
    int after = logged;
    bad += !d || fmi2SetupExperiment(d, 0, 0.0, 0.0, 0, 0.0) != fmi2OK || fmi2EnterInitializationMode(d) != fmi2OK ||
           fmi2ExitInitializationMode(d) != fmi2OK || fmi2DoStep(d, 0.0, h, 1) != fmi2OK;
    if (d) fmi2FreeInstance(d);
    printf("bad=%d logged_after_free=%d\n", bad, after - before);
    return bad;
}
