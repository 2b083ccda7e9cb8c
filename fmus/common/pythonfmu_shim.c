/* The binary of every Python FMU (FMI 2.0, Linux): a thin front to pythonfmu's export library.
 *
 * pythonfmu 0.7.0's C++ layer answers every Python exception with fmi2Fatal; FMI 2.0 (section
 * 2.1.3, 4.3) asks for fmi2Error when a call is not allowed in the instance's state or names a
 * variable the call cannot take, and the instance stays usable. `mast build` ships pythonfmu's
 * library beside this one as `<modelIdentifier>.pythonfmu.so` and this file, compiled, as
 * `<modelIdentifier>.so`. Every fmi2 call is forwarded; the inner instance logs through the relay
 * below, and when a call ends in fmi2Fatal its status is settled by what the model logged:
 *
 * - the Python glue (fmus/common/slave.py, `fmi_call`) logs an illegal call with status Error
 *   just before raising, a failure it did not foresee (and every call after one) with status
 *   Fatal; pythonfmu then logs its own report of the exception (no category) and says fmi2Fatal;
 * - after a model message with status Error, the call returns fmi2Error; otherwise fmi2Fatal stays
 *   fmi2Fatal. pythonfmu's report is passed on only when the model logged nothing itself (after a
 *   model message it repeats it, or says "unknown error").
 *
 * The inner instance is created with logging on, so the relay sees every message; the host's
 * logger gets errors and warnings always and the other messages while logging is on (the host's
 * loggingOn and fmi2SetDebugLogging), as the native FMUs do (native/fmi2_wrapper.c).
 * Nothing else changes: values, states and the other statuses pass through untouched.
 */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"

#define INNER_SUFFIX ".pythonfmu"   /* <modelIdentifier>.so -> <modelIdentifier>.pythonfmu.so */

/* the functions pythonfmu's library exports (Co-Simulation), resolved per instance */
#define FORWARDED(X) X(Instantiate) X(FreeInstance) X(SetupExperiment) X(EnterInitializationMode) \
    X(ExitInitializationMode) X(Terminate) X(Reset) X(GetReal) X(GetInteger) X(GetBoolean) X(GetString) \
    X(SetReal) X(SetInteger) X(SetBoolean) X(SetString) X(GetFMUstate) X(SetFMUstate) X(FreeFMUstate) \
    X(SerializedFMUstateSize) X(SerializeFMUstate) X(DeSerializeFMUstate) X(GetDirectionalDerivative) \
    X(SetRealInputDerivatives) X(GetRealOutputDerivatives) X(DoStep) X(CancelStep) X(GetStatus) \
    X(GetRealStatus) X(GetIntegerStatus) X(GetBooleanStatus) X(GetStringStatus)

typedef struct {
#define MEMBER(name) fmi2##name##TYPE *name;
    FORWARDED(MEMBER)
#undef MEMBER
} Api;

typedef struct {
    void *library;                    /* pythonfmu's export library (dlopen handle) */
    Api api;
    fmi2Component inner;
    fmi2CallbackFunctions host;       /* the host's callbacks, as given to fmi2Instantiate */
    fmi2CallbackFunctions relayed;    /* what the inner instance gets: the relay as its logger */
    int logging_on;
    int model_status;                 /* status of the model's last message in the current call, -1: none */
} Shim;

static void relay(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status, fmi2String category,
                  fmi2String message, ...)
{
    Shim *s = env;
    int from_model = category && *category;  /* pythonfmu's own messages carry no category */
    if (from_model) {
        s->model_status = status;
    } else if (status == fmi2Fatal && s->model_status >= fmi2Error) {
        return;  /* pythonfmu's report of an exception the model has logged already */
    }
    if (!s->host.logger || (status == fmi2OK && !s->logging_on)) return;
    if (from_model || !message || !strchr(message, '%')) {  /* the model's messages have '%' written '%%' */
        s->host.logger(s->host.componentEnvironment, name, status, category, message);
        return;
    }
    /* pythonfmu's text, used as a format by hosts that expand it and as it is by the others: '%' -> '%%' */
    char *escaped = malloc(2 * strlen(message) + 1), *out = escaped;
    if (!escaped) return;
    for (const char *in = message; *in; in++) {
        if (*in == '%') *out++ = '%';
        *out++ = *in;
    }
    *out = '\0';
    s->host.logger(s->host.componentEnvironment, name, status, category, escaped);
    free(escaped);
}

static void report(const fmi2CallbackFunctions *functions, fmi2String name, const char *what, const char *detail)
{
    if (functions && functions->logger)
        functions->logger(functions->componentEnvironment, name, fmi2Error, "logStatusError",
                          "fmi2Instantiate: %s: %s", what, detail ? detail : "unknown reason");
}

/* the path of pythonfmu's library: this library's own path with INNER_SUFFIX before the extension */
static char *inner_path(void)
{
    Dl_info self;
    if (!dladdr((void *)&inner_path, &self) || !self.dli_fname) return NULL;
    const char *own = self.dli_fname, *slash = strrchr(own, '/'), *dot = strrchr(own, '.');
    size_t stem = dot && (!slash || dot > slash) ? (size_t)(dot - own) : strlen(own);
    char *path = malloc(strlen(own) + sizeof INNER_SUFFIX);
    if (!path) return NULL;
    memcpy(path, own, stem);
    strcpy(path + stem, INNER_SUFFIX);
    strcat(path, own + stem);
    return path;
}

static void release(Shim *s)
{
    if (s->library) dlclose(s->library);
    free(s);
}

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String resources,
                              const fmi2CallbackFunctions *functions, fmi2Boolean visible, fmi2Boolean loggingOn)
{
    Shim *s = calloc(1, sizeof *s);
    char *path = inner_path();
    if (!s || !path) {
        report(functions, name, "out of memory, or this library cannot find its own path", NULL);
        free(path);
        free(s);
        return NULL;
    }
    s->library = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!s->library) {
        report(functions, name, "cannot load the model's library", dlerror());
        free(path);
        release(s);
        return NULL;
    }
#define RESOLVE(fn) s->api.fn = (fmi2##fn##TYPE *)dlsym(s->library, "fmi2" #fn); \
    if (!s->api.fn) { report(functions, name, path, "fmi2" #fn " is missing"); free(path); release(s); return NULL; }
    FORWARDED(RESOLVE)
#undef RESOLVE
    free(path);
    if (functions) s->host = *functions;
    s->relayed = s->host;
    s->relayed.logger = relay;
    s->relayed.componentEnvironment = s;
    s->logging_on = loggingOn;
    s->model_status = -1;
    s->inner = s->api.Instantiate(name, type, guid, resources, &s->relayed, visible, fmi2True);
    if (!s->inner) {
        release(s);
        return NULL;
    }
    return s;
}

void fmi2FreeInstance(fmi2Component c)
{
    Shim *s = c;
    if (!s) return;
    s->api.FreeInstance(s->inner);
    release(s);
}

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t n, const fmi2String categories[])
{
    Shim *s = c;
    (void)n; (void)categories;
    if (!s) return fmi2Error;
    s->logging_on = loggingOn;  /* the inner instance keeps logging on: the relay filters */
    return fmi2OK;
}

/* the status a forwarded call returns (see the top of this file) */
static fmi2Status settled(const Shim *s, fmi2Status status)
{
    return status == fmi2Fatal && s->model_status == fmi2Error ? fmi2Error : status;
}

#define FORWARD(fn, ...) { Shim *s = c; if (!s) return fmi2Error; s->model_status = -1; \
    return settled(s, s->api.fn(s->inner, __VA_ARGS__)); }
#define FORWARD0(fn) { Shim *s = c; if (!s) return fmi2Error; s->model_status = -1; \
    return settled(s, s->api.fn(s->inner)); }

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime)
    FORWARD(SetupExperiment, toleranceDefined, tolerance, startTime, stopTimeDefined, stopTime)
fmi2Status fmi2EnterInitializationMode(fmi2Component c) FORWARD0(EnterInitializationMode)
fmi2Status fmi2ExitInitializationMode(fmi2Component c) FORWARD0(ExitInitializationMode)
fmi2Status fmi2Terminate(fmi2Component c) FORWARD0(Terminate)
fmi2Status fmi2Reset(fmi2Component c) FORWARD0(Reset)
fmi2Status fmi2CancelStep(fmi2Component c) FORWARD0(CancelStep)

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[])
    FORWARD(GetReal, vr, nvr, value)
fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Integer value[])
    FORWARD(GetInteger, vr, nvr, value)
fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Boolean value[])
    FORWARD(GetBoolean, vr, nvr, value)
fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2String value[])
    FORWARD(GetString, vr, nvr, value)
fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[])
    FORWARD(SetReal, vr, nvr, value)
fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Integer value[])
    FORWARD(SetInteger, vr, nvr, value)
fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Boolean value[])
    FORWARD(SetBoolean, vr, nvr, value)
fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2String value[])
    FORWARD(SetString, vr, nvr, value)

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *state) FORWARD(GetFMUstate, state)
fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate state) FORWARD(SetFMUstate, state)
fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *state) FORWARD(FreeFMUstate, state)
fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate state, size_t *size)
    FORWARD(SerializedFMUstateSize, state, size)
fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate state, fmi2Byte bytes[], size_t size)
    FORWARD(SerializeFMUstate, state, bytes, size)
fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte bytes[], size_t size, fmi2FMUstate *state)
    FORWARD(DeSerializeFMUstate, bytes, size, state)

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown[], size_t nUnknown,
                                        const fmi2ValueReference vKnown[], size_t nKnown,
                                        const fmi2Real dvKnown[], fmi2Real dvUnknown[])
    FORWARD(GetDirectionalDerivative, vUnknown, nUnknown, vKnown, nKnown, dvKnown, dvUnknown)
fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[])
    FORWARD(SetRealInputDerivatives, vr, nvr, order, value)
fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[])
    FORWARD(GetRealOutputDerivatives, vr, nvr, order, value)

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean noSetFMUStatePriorToCurrentPoint)
    FORWARD(DoStep, t, h, noSetFMUStatePriorToCurrentPoint)

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind kind, fmi2Status *value)
    FORWARD(GetStatus, kind, value)
fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind kind, fmi2Real *value)
    FORWARD(GetRealStatus, kind, value)
fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind kind, fmi2Integer *value)
    FORWARD(GetIntegerStatus, kind, value)
fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind kind, fmi2Boolean *value)
    FORWARD(GetBooleanStatus, kind, value)
fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind kind, fmi2String *value)
    FORWARD(GetStringStatus, kind, value)
