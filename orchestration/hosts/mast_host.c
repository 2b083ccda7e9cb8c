/* A small FMI 2.0 co-simulation host in C: runs native MAST FMUs without Python, on Linux and, compiled by
 * zig for x86_64-windows-gnu, on Windows (tested under Wine: hosts/c_host.py, tests/test_portability.py).
 *
 *     mast_host PLAN RESULT
 *
 * PLAN (written by hosts/c_host.py from a run of the project's master) names the FMUs' libraries, their
 * parameters and the master's exchange schedule. The host
 *
 * 1. runs CYCLES instantiate / (doStep before initialization: fmi2Error expected) / setupExperiment /
 *    enterInitializationMode / parameters / exitInitializationMode / doStep / getReal / terminate /
 *    freeInstance cycles per FMU, counting the statuses that differ from the expected ones;
 * 2. runs the system on the master's own exchange loop, mast_ticks (mast.core.exchange.SOURCE, compiled into
 *    this program as mast_exchange.c): the same FMI calls in the same order as the project's master, so a
 *    change of the communication pattern there changes this host too. Initialisation: every FMU gets its
 *    parameters and, in initialization mode, the inputs the master set last there (after its fixed-point
 *    passes over the initial values); their outputs after exitInitializationMode start the loop.
 *
 * Prints one line per FMU "cycles NAME DONE UNEXPECTED" and "run TICKS STATUS"; RESULT receives the flat
 * vector's outputs at every recorded tick (rows of N_OUT doubles, little-endian, as the machine stores them).
 *
 * PLAN: lines of whitespace-separated fields; a double is written as the 16 hexadecimal digits of its
 * IEEE 754 bits (exact on every C library); a string (name, library, GUID, resource URI, String parameter)
 * is the rest of its line.
 */
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifdef _WIN32
#include <windows.h>
#define LOAD(path) ((void *)LoadLibraryA(path))
#define SYMBOL(lib, name) ((void *)GetProcAddress((HMODULE)(lib), name))
#define UNLOAD(lib) FreeLibrary((HMODULE)(lib))
#else
#include <dlfcn.h>
#define LOAD(path) dlopen(path, RTLD_NOW | RTLD_LOCAL)
#define SYMBOL(lib, name) dlsym(lib, name)
#define UNLOAD(lib) dlclose(lib)
#endif

#include "fmi2Functions.h"
#include "mast_exchange.c"

#define LINE 4096

typedef struct {
    char name[LINE], library[LINE], guid[LINE], resources[LINE];
    void *lib;
    fmi2InstantiateTYPE *instantiate;
    fmi2FreeInstanceTYPE *free_instance;
    fmi2SetupExperimentTYPE *setup;
    fmi2EnterInitializationModeTYPE *enter_init;
    fmi2ExitInitializationModeTYPE *exit_init;
    fmi2TerminateTYPE *terminate;
    fmi2SetRealTYPE *set_real;
    fmi2GetRealTYPE *get_real;
    fmi2SetIntegerTYPE *set_integer;
    fmi2SetStringTYPE *set_string;
    fmi2DoStepTYPE *do_step;
    int n_real, n_int, n_str;
    unsigned int *real_vr, *int_vr, *str_vr;
    double *real_value;
    int *int_value;
    char **str_value;
} fmu;

static FILE *plan;
static int quiet;   /* the life cycles' expected errors are not printed */
static char line[LINE];

static void fail(const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    fprintf(stderr, "mast_host: ");
    vfprintf(stderr, fmt, ap);
    fprintf(stderr, "\n");
    va_end(ap);
    exit(2);
}

static char *next_line(const char *key)
{
    size_t n = strlen(key);
    if (!fgets(line, sizeof line, plan)) fail("plan: expected '%s', found the end of the file", key);
    line[strcspn(line, "\r\n")] = '\0';
    if (strncmp(line, key, n) != 0 || (line[n] != ' ' && line[n] != '\0'))
        fail("plan: expected '%s', found '%.60s'", key, line);
    return line[n] ? line + n + 1 : line + n;
}

static char *cursor;

static char *field(void)
{
    char *start = cursor + strspn(cursor, " ");
    if (!*start) fail("plan: a line ends too early: '%.60s'", line);
    char *end = start + strcspn(start, " ");
    cursor = *end ? end + 1 : end;
    *end = '\0';
    return start;
}

static long integer(void) { return strtol(field(), NULL, 10); }

static double real(void)
{
    unsigned long long bits = strtoull(field(), NULL, 16);
    double value;
    memcpy(&value, &bits, sizeof value);
    return value;
}

static void *table(size_t n, size_t size)
{
    void *p = calloc(n ? n : 1, size);
    if (!p) fail("out of memory");
    return p;
}

static void *symbol(fmu *f, const char *name)
{
    void *p = SYMBOL(f->lib, name);
    if (!p) fail("%s: %s has no function %s", f->name, f->library, name);
    return p;
}

static void logger(fmi2ComponentEnvironment env, fmi2String instance, fmi2Status status, fmi2String category,
                   fmi2String message, ...)
{
    (void)env;
    if (status >= fmi2Warning && !quiet)
        fprintf(stderr, "[%s] %s: %s\n", category ? category : "", instance ? instance : "", message ? message : "");
}

static fmi2CallbackFunctions callbacks;   /* filled in main: a DLL's function address is no constant */

static fmi2Component instantiate(fmu *f)
{
    return f->instantiate(f->name, fmi2CoSimulation, f->guid, f->resources, &callbacks, fmi2False, fmi2False);
}

static int set_parameters(fmu *f, fmi2Component c)
{
    int bad = 0;
    if (f->n_real) bad += f->set_real(c, f->real_vr, (size_t)f->n_real, f->real_value) != fmi2OK;
    if (f->n_int) bad += f->set_integer(c, f->int_vr, (size_t)f->n_int, f->int_value) != fmi2OK;
    if (f->n_str) bad += f->set_string(c, f->str_vr, (size_t)f->n_str, (const fmi2String *)f->str_value) != fmi2OK;
    return bad;
}

/* One life cycle of an instance; the number of calls whose status (or result) was not the expected one. */
static int cycle(fmu *f, const mast_unit *u, double t0)
{
    int bad = 0;
    fmi2Component c = instantiate(f);
    if (!c) return 1;
    bad += f->do_step(c, t0, u->h, fmi2True) != fmi2Error;          /* not allowed before initialization */
    bad += f->setup(c, fmi2False, 0.0, t0, fmi2False, 0.0) != fmi2OK;
    bad += f->enter_init(c) != fmi2OK;
    bad += set_parameters(f, c);
    bad += f->exit_init(c) != fmi2OK;
    bad += f->do_step(c, t0, u->h, fmi2True) != fmi2OK;
    bad += f->get_real(c, u->vr_out, (size_t)u->n_out, u->pending) != fmi2OK;
    bad += f->terminate(c) != fmi2OK;
    f->free_instance(c);
    return bad;
}

int main(int argc, char **argv)
{
    if (argc != 3) fail("usage: mast_host PLAN RESULT");
    callbacks.logger = logger;
    callbacks.allocateMemory = calloc;
    callbacks.freeMemory = free;
    plan = fopen(argv[1], "r");
    if (!plan) fail("%s: cannot open the plan", argv[1]);
    cursor = next_line("mast-host-plan");
    if (integer() != 1) fail("plan: version 1 expected");
    cursor = next_line("cycles");
    long cycles = integer();
    cursor = next_line("run");
    double t0 = real(), h = real();
    long n_ticks = integer(), record_every = integer();
    cursor = next_line("flat");
    int n_out = (int)integer();
    double *flat = table((size_t)n_out, sizeof(double));
    cursor = next_line("units");
    int n_units = (int)integer();
    fmu *fmus = table((size_t)n_units, sizeof(fmu));
    mast_unit *units = table((size_t)n_units, sizeof(mast_unit));

    for (int k = 0; k < n_units; k++) {
        fmu *f = fmus + k;
        mast_unit *u = units + k;
        strcpy(f->name, next_line("unit"));
        strcpy(f->library, next_line("library"));
        strcpy(f->guid, next_line("guid"));
        strcpy(f->resources, next_line("resources"));
        cursor = next_line("schedule");
        u->multiple = integer();
        u->h = real();
        u->feedthrough = (int)integer();
        cursor = next_line("reals");
        f->n_real = (int)integer();
        f->real_vr = table((size_t)f->n_real, sizeof(unsigned int));
        f->real_value = table((size_t)f->n_real, sizeof(double));
        for (int i = 0; i < f->n_real; i++) { f->real_vr[i] = (unsigned int)integer(); f->real_value[i] = real(); }
        cursor = next_line("integers");
        f->n_int = (int)integer();
        f->int_vr = table((size_t)f->n_int, sizeof(unsigned int));
        f->int_value = table((size_t)f->n_int, sizeof(int));
        for (int i = 0; i < f->n_int; i++) { f->int_vr[i] = (unsigned int)integer(); f->int_value[i] = (int)integer(); }
        cursor = next_line("strings");
        f->n_str = (int)integer();
        f->str_vr = table((size_t)f->n_str, sizeof(unsigned int));
        f->str_value = table((size_t)f->n_str, sizeof(char *));
        for (int i = 0; i < f->n_str; i++) {
            cursor = next_line("string");
            f->str_vr[i] = (unsigned int)integer();
            f->str_value[i] = strcpy(table(strlen(cursor) + 1, 1), cursor);
        }
        cursor = next_line("inputs");
        u->n_in = (int)integer();
        unsigned int *vr_in = table((size_t)u->n_in, sizeof(unsigned int));
        int *src = table((size_t)u->n_in, sizeof(int));
        for (int i = 0; i < u->n_in; i++) vr_in[i] = (unsigned int)integer();
        for (int i = 0; i < u->n_in; i++) src[i] = (int)integer();
        u->vr_in = vr_in;
        u->src = src;
        u->in_buf = table((size_t)u->n_in, sizeof(double));
        cursor = next_line("initial");
        for (int i = 0; i < u->n_in; i++) u->in_buf[i] = real();
        cursor = next_line("outputs");
        u->n_out = (int)integer();
        unsigned int *vr_out = table((size_t)u->n_out, sizeof(unsigned int));
        for (int i = 0; i < u->n_out; i++) vr_out[i] = (unsigned int)integer();
        u->vr_out = vr_out;
        u->offset = (int)integer();
        if (u->offset < 0 || u->offset + u->n_out > n_out) fail("%s: outputs outside the flat vector", f->name);
        for (int i = 0; i < u->n_in; i++)
            if (src[i] < 0 || src[i] >= n_out) fail("%s: input %d from outside the flat vector", f->name, i);
        u->pending = table((size_t)u->n_out, sizeof(double));

        f->lib = LOAD(f->library);
        if (!f->lib) fail("%s: cannot load %s", f->name, f->library);
        f->instantiate = symbol(f, "fmi2Instantiate");
        f->free_instance = symbol(f, "fmi2FreeInstance");
        f->setup = symbol(f, "fmi2SetupExperiment");
        f->enter_init = symbol(f, "fmi2EnterInitializationMode");
        f->exit_init = symbol(f, "fmi2ExitInitializationMode");
        f->terminate = symbol(f, "fmi2Terminate");
        f->set_real = symbol(f, "fmi2SetReal");
        f->get_real = symbol(f, "fmi2GetReal");
        f->set_integer = symbol(f, "fmi2SetInteger");
        f->set_string = symbol(f, "fmi2SetString");
        f->do_step = symbol(f, "fmi2DoStep");
        u->set = (set_fn)f->set_real;
        u->get = (get_fn)f->get_real;
        u->step = (step_fn)f->do_step;
    }
    fclose(plan);

    /* 1. life cycles */
    quiet = 1;
    for (int k = 0; k < n_units; k++) {
        int unexpected = 0;
        for (long i = 0; i < cycles; i++) unexpected += cycle(fmus + k, units + k, t0);
        printf("cycles %s %ld %d\n", fmus[k].name, cycles, unexpected);
    }

    /* 2. the system on the master's exchange loop */
    quiet = 0;
    for (int k = 0; k < n_units; k++) {
        fmu *f = fmus + k;
        mast_unit *u = units + k;
        u->comp = instantiate(f);
        if (!u->comp) fail("%s: fmi2Instantiate failed", f->name);
        if (f->setup(u->comp, fmi2False, 0.0, t0, fmi2False, 0.0) != fmi2OK || f->enter_init(u->comp) != fmi2OK
            || set_parameters(f, u->comp))
            fail("%s: initialization failed", f->name);
        if (u->n_in && f->set_real(u->comp, u->vr_in, (size_t)u->n_in, u->in_buf) != fmi2OK)
            fail("%s: setting the initial inputs failed", f->name);
    }
    for (int k = 0; k < n_units; k++)
        if (fmus[k].exit_init(units[k].comp) != fmi2OK) fail("%s: fmi2ExitInitializationMode failed", fmus[k].name);
    for (int k = 0; k < n_units; k++) {
        mast_unit *u = units + k;
        if (fmus[k].get_real(u->comp, u->vr_out, (size_t)u->n_out, flat + u->offset) != fmi2OK)
            fail("%s: reading the initial outputs failed", fmus[k].name);
        memcpy(u->pending, flat + u->offset, sizeof(double) * (size_t)u->n_out);
    }
    FILE *out = fopen(argv[2], "wb");
    if (!out) fail("%s: cannot write the result", argv[2]);
    double none = 0.0;
    long at = 0;
    int which = 0, call = 0, status = 0;
    for (long n = 0;; n += record_every) {
        fwrite(flat, sizeof(double), (size_t)n_out, out);
        if (n >= n_ticks) break;
        long n1 = n + record_every < n_ticks ? n + record_every : n_ticks;
        status = mast_ticks(units, n_units, flat, n_out, &none, 0, n, n1, t0, h, &at, &which, &call);
        if (status) {
            fprintf(stderr, "mast_host: %s: call %d failed at tick %ld\n", fmus[which].name, call, at);
            break;
        }
    }
    fclose(out);
    printf("run %ld %d\n", n_ticks, status);
    for (int k = 0; k < n_units; k++) {
        fmus[k].terminate(units[k].comp);
        fmus[k].free_instance(units[k].comp);
    }
    return status;
}
