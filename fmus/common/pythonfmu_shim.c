/* The binary of every Python FMU (Linux), FMI 2.0 and FMI 3.0: a thin front to pythonfmu's export library.
 *
 * One source for both versions: `mast build` compiles it with FMI_VERSION defined as 2 (pythonfmu 0.7.0,
 * the FMI 2.0 FMUs) or 3 (pythonfmu3 0.3.4, the FMI 3.0 variants). Both libraries answer every Python
 * exception with Fatal; FMI (2.0 sections 2.1.3 and 4.3, 3.0 sections 2.2.3 and 4.2) asks for Error when a
 * call is not allowed in the instance's state or names a variable the call cannot take, and the instance
 * stays usable. `mast build` ships pythonfmu's library beside this one as `<modelIdentifier>.pythonfmu.so`
 * and this file, compiled, as `<modelIdentifier>.so`. Every call is forwarded; the inner instance logs
 * through the relay below, and when a call ends in Fatal its status is settled by what the model logged:
 *
 * - the Python glue (fmus/common/slave.py, `fmi_call`) logs an illegal call with status Error
 *   just before raising, a failure it did not foresee (and every call after one) with status
 *   Fatal; pythonfmu then logs its own report of the exception (no category) and says Fatal;
 * - after a model message with status Error, the call returns Error; otherwise Fatal stays
 *   Fatal. pythonfmu's report is passed on only when the model logged nothing itself (after a
 *   model message it repeats it, or says "unknown error").
 *
 * The inner instance is created with logging on, so the relay sees every message; the host's
 * logger gets errors and warnings always and the other messages while logging is on (the host's
 * loggingOn and SetDebugLogging), as the native FMUs do (native/fmi2_wrapper.c).
 * Nothing else changes: values, states and the other statuses pass through untouched. Before any of it, a call's
 * instance is checked against the instances this front made and has not freed (mast_guard.h): a second free
 * does nothing and any other call on a freed instance returns Error unread; FMI 3.0's start and stop time are
 * checked here too (pythonfmu3 does not pass the stop time on; the glue checks doStep's times, slave.py).
 */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "mast_guard.h"

#define INNER_SUFFIX ".pythonfmu"   /* <modelIdentifier>.so -> <modelIdentifier>.pythonfmu.so */
#define UNPAREN(...) __VA_ARGS__
#define TEXT_(x) #x
#define TEXT(x) TEXT_(x)

#if FMI_VERSION == 2
#include "fmi2Functions.h"
#define FMI(name) fmi2##name
typedef fmi2Status Status;
typedef fmi2Component Instance;
/* the functions forwarded as they are (Co-Simulation): X(name, (parameters after the instance), (their names)) */
#define FORWARDED0(X) X(EnterInitializationMode) X(ExitInitializationMode) X(Terminate) X(Reset) X(CancelStep)
#define FORWARDED(X) \
    X(SetupExperiment, (fmi2Boolean toleranceDefined, fmi2Real tolerance, fmi2Real startTime, \
                        fmi2Boolean stopTimeDefined, fmi2Real stopTime), \
      (toleranceDefined, tolerance, startTime, stopTimeDefined, stopTime)) \
    X(GetInteger, (const fmi2ValueReference vr[], size_t nvr, fmi2Integer value[]), (vr, nvr, value)) \
    X(GetBoolean, (const fmi2ValueReference vr[], size_t nvr, fmi2Boolean value[]), (vr, nvr, value)) \
    X(GetString, (const fmi2ValueReference vr[], size_t nvr, fmi2String value[]), (vr, nvr, value)) \
    X(SetInteger, (const fmi2ValueReference vr[], size_t nvr, const fmi2Integer value[]), (vr, nvr, value)) \
    X(SetBoolean, (const fmi2ValueReference vr[], size_t nvr, const fmi2Boolean value[]), (vr, nvr, value)) \
    X(SetString, (const fmi2ValueReference vr[], size_t nvr, const fmi2String value[]), (vr, nvr, value)) \
    X(GetFMUstate, (fmi2FMUstate *state), (state)) \
    X(SetFMUstate, (fmi2FMUstate state), (state)) \
    X(FreeFMUstate, (fmi2FMUstate *state), (state)) \
    X(SerializedFMUstateSize, (fmi2FMUstate state, size_t *size), (state, size)) \
    X(SerializeFMUstate, (fmi2FMUstate state, fmi2Byte bytes[], size_t size), (state, bytes, size)) \
    X(DeSerializeFMUstate, (const fmi2Byte bytes[], size_t size, fmi2FMUstate *state), (bytes, size, state)) \
    X(GetDirectionalDerivative, (const fmi2ValueReference vUnknown[], size_t nUnknown, \
                                 const fmi2ValueReference vKnown[], size_t nKnown, const fmi2Real dvKnown[], \
                                 fmi2Real dvUnknown[]), (vUnknown, nUnknown, vKnown, nKnown, dvKnown, dvUnknown)) \
    X(SetRealInputDerivatives, (const fmi2ValueReference vr[], size_t nvr, const fmi2Integer order[], \
                                const fmi2Real value[]), (vr, nvr, order, value)) \
    X(GetRealOutputDerivatives, (const fmi2ValueReference vr[], size_t nvr, const fmi2Integer order[], \
                                 fmi2Real value[]), (vr, nvr, order, value)) \
    X(GetStatus, (const fmi2StatusKind kind, fmi2Status *value), (kind, value)) \
    X(GetRealStatus, (const fmi2StatusKind kind, fmi2Real *value), (kind, value)) \
    X(GetIntegerStatus, (const fmi2StatusKind kind, fmi2Integer *value), (kind, value)) \
    X(GetStringStatus, (const fmi2StatusKind kind, fmi2String *value), (kind, value))
/* the functions of pythonfmu's library this front calls from functions written by hand, below */
#define HANDWRITTEN(X) X(Instantiate) X(FreeInstance) X(GetReal) X(SetReal) X(DoStep) X(GetBooleanStatus)
#define STATUS_OK fmi2OK
#define STATUS_ERROR fmi2Error
#define STATUS_FATAL fmi2Fatal

#elif FMI_VERSION == 3
#include "fmi3Functions.h"
#define FMI(name) fmi3##name
typedef fmi3Status Status;
typedef fmi3Instance Instance;
#define FORWARDED0(X) X(ExitInitializationMode) X(EnterEventMode) X(Terminate) X(Reset) \
    X(EnterConfigurationMode) X(ExitConfigurationMode) X(EvaluateDiscreteStates) X(EnterContinuousTimeMode) \
    X(EnterStepMode)
#define VALUES(X, T) \
    X(Get##T, (const fmi3ValueReference vr[], size_t nvr, fmi3##T values[], size_t n), (vr, nvr, values, n)) \
    X(Set##T, (const fmi3ValueReference vr[], size_t nvr, const fmi3##T values[], size_t n), (vr, nvr, values, n))
#define DERIVATIVE(X, name) \
    X(name, (const fmi3ValueReference unknowns[], size_t nUnknowns, const fmi3ValueReference knowns[], \
             size_t nKnowns, const fmi3Float64 seed[], size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity), \
      (unknowns, nUnknowns, knowns, nKnowns, seed, nSeed, sensitivity, nSensitivity))
#define FORWARDED(X) \
    VALUES(X, Float32) VALUES(X, Float64) VALUES(X, Int8) VALUES(X, UInt8) VALUES(X, Int16) VALUES(X, UInt16) \
    VALUES(X, Int32) VALUES(X, UInt32) VALUES(X, Int64) VALUES(X, UInt64) VALUES(X, Boolean) VALUES(X, String) \
    X(GetBinary, (const fmi3ValueReference vr[], size_t nvr, size_t sizes[], fmi3Binary values[], size_t n), \
      (vr, nvr, sizes, values, n)) \
    X(SetBinary, (const fmi3ValueReference vr[], size_t nvr, const size_t sizes[], const fmi3Binary values[], \
                  size_t n), (vr, nvr, sizes, values, n)) \
    X(GetClock, (const fmi3ValueReference vr[], size_t nvr, fmi3Clock values[]), (vr, nvr, values)) \
    X(SetClock, (const fmi3ValueReference vr[], size_t nvr, const fmi3Clock values[]), (vr, nvr, values)) \
    X(GetNumberOfVariableDependencies, (fmi3ValueReference vr, size_t *n), (vr, n)) \
    X(GetVariableDependencies, (fmi3ValueReference dependent, size_t elementsOfDependent[], \
                                fmi3ValueReference independents[], size_t elementsOfIndependents[], \
                                fmi3DependencyKind kinds[], size_t n), \
      (dependent, elementsOfDependent, independents, elementsOfIndependents, kinds, n)) \
    X(GetFMUState, (fmi3FMUState *state), (state)) \
    X(SetFMUState, (fmi3FMUState state), (state)) \
    X(FreeFMUState, (fmi3FMUState *state), (state)) \
    X(SerializedFMUStateSize, (fmi3FMUState state, size_t *size), (state, size)) \
    X(SerializeFMUState, (fmi3FMUState state, fmi3Byte bytes[], size_t size), (state, bytes, size)) \
    X(DeserializeFMUState, (const fmi3Byte bytes[], size_t size, fmi3FMUState *state), (bytes, size, state)) \
    DERIVATIVE(X, GetDirectionalDerivative) DERIVATIVE(X, GetAdjointDerivative) \
    X(GetIntervalDecimal, (const fmi3ValueReference vr[], size_t nvr, fmi3Float64 intervals[], \
                           fmi3IntervalQualifier qualifiers[]), (vr, nvr, intervals, qualifiers)) \
    X(GetIntervalFraction, (const fmi3ValueReference vr[], size_t nvr, fmi3UInt64 counters[], \
                            fmi3UInt64 resolutions[], fmi3IntervalQualifier qualifiers[]), \
      (vr, nvr, counters, resolutions, qualifiers)) \
    X(GetShiftDecimal, (const fmi3ValueReference vr[], size_t nvr, fmi3Float64 shifts[]), (vr, nvr, shifts)) \
    X(GetShiftFraction, (const fmi3ValueReference vr[], size_t nvr, fmi3UInt64 counters[], \
                         fmi3UInt64 resolutions[]), (vr, nvr, counters, resolutions)) \
    X(SetIntervalDecimal, (const fmi3ValueReference vr[], size_t nvr, const fmi3Float64 intervals[]), \
      (vr, nvr, intervals)) \
    X(SetIntervalFraction, (const fmi3ValueReference vr[], size_t nvr, const fmi3UInt64 counters[], \
                            const fmi3UInt64 resolutions[]), (vr, nvr, counters, resolutions)) \
    X(SetShiftDecimal, (const fmi3ValueReference vr[], size_t nvr, const fmi3Float64 shifts[]), (vr, nvr, shifts)) \
    X(SetShiftFraction, (const fmi3ValueReference vr[], size_t nvr, const fmi3UInt64 counters[], \
                         const fmi3UInt64 resolutions[]), (vr, nvr, counters, resolutions)) \
    X(UpdateDiscreteStates, (fmi3Boolean *discreteStatesNeedUpdate, fmi3Boolean *terminateSimulation, \
                             fmi3Boolean *nominalsChanged, fmi3Boolean *valuesChanged, \
                             fmi3Boolean *nextEventTimeDefined, fmi3Float64 *nextEventTime), \
      (discreteStatesNeedUpdate, terminateSimulation, nominalsChanged, valuesChanged, nextEventTimeDefined, \
       nextEventTime)) \
    X(CompletedIntegratorStep, (fmi3Boolean noSetFMUStatePriorToCurrentPoint, fmi3Boolean *enterEventMode, \
                                fmi3Boolean *terminateSimulation), \
      (noSetFMUStatePriorToCurrentPoint, enterEventMode, terminateSimulation)) \
    X(SetTime, (fmi3Float64 time), (time)) \
    X(SetContinuousStates, (const fmi3Float64 x[], size_t n), (x, n)) \
    X(GetContinuousStateDerivatives, (fmi3Float64 dx[], size_t n), (dx, n)) \
    X(GetEventIndicators, (fmi3Float64 z[], size_t n), (z, n)) \
    X(GetContinuousStates, (fmi3Float64 x[], size_t n), (x, n)) \
    X(GetNominalsOfContinuousStates, (fmi3Float64 nominals[], size_t n), (nominals, n)) \
    X(GetNumberOfEventIndicators, (size_t *n), (n)) \
    X(GetNumberOfContinuousStates, (size_t *n), (n)) \
    X(GetOutputDerivatives, (const fmi3ValueReference vr[], size_t nvr, const fmi3Int32 orders[], \
                             fmi3Float64 values[], size_t n), (vr, nvr, orders, values, n)) \
    X(DoStep, (fmi3Float64 t, fmi3Float64 h, fmi3Boolean noSetFMUStatePriorToCurrentPoint, \
               fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation, fmi3Boolean *earlyReturn, \
               fmi3Float64 *lastSuccessfulTime), \
      (t, h, noSetFMUStatePriorToCurrentPoint, eventHandlingNeeded, terminateSimulation, earlyReturn, \
       lastSuccessfulTime)) \
    X(ActivateModelPartition, (fmi3ValueReference clock, fmi3Float64 activationTime), (clock, activationTime))
#define HANDWRITTEN(X) X(InstantiateCoSimulation) X(FreeInstance) X(EnterInitializationMode)
#define STATUS_OK fmi3OK
#define STATUS_ERROR fmi3Error
#define STATUS_FATAL fmi3Fatal

#else
#error "compile with FMI_VERSION defined as 2 or 3 (mast build does)"
#endif

/* the functions of pythonfmu's library this front calls, resolved per instance */
typedef struct {
#define MEMBER0(name) FMI(name##TYPE) *name;
#define MEMBER(name, params, args) FMI(name##TYPE) *name;
    FORWARDED0(MEMBER0)
    FORWARDED(MEMBER)
    HANDWRITTEN(MEMBER0)
#undef MEMBER
#undef MEMBER0
} Api;

typedef struct {
    void *library;                    /* pythonfmu's export library (dlopen handle) */
    Api api;
    Instance inner;
#if FMI_VERSION == 2
    fmi2CallbackFunctions host;       /* the host's callbacks, as given to fmi2Instantiate */
    fmi2CallbackFunctions relayed;    /* what the inner instance gets: the relay as its logger */
#else
    fmi3LogMessageCallback host_logger;
    fmi3InstanceEnvironment host_environment;
#endif
    int logging_on;
    int model_status;                 /* status of the model's last message in the current call, -1: none */
#if FMI_VERSION == 2
    double *io;                       /* the exchange buffer (below): the inputs, then the outputs; NULL: none */
    size_t n_in, n_io;                /* value references 0 .. n_in - 1 are the inputs, n_in .. n_io - 1 the outputs */
    int stepping;                     /* step mode, no failure since: the buffer answers */
    int dirty;                        /* inputs set in the buffer the Python side has not read yet */
    void *py_step;                    /* the glue's step for the fast path (a Python callable), or NULL */
    int refused;                      /* the fast path's last step was refused: fmi2Terminated is true */
#endif
} Shim;

#if FMI_VERSION == 2
static fmi2ValueReference io_refs[1024];   /* 0, 1, 2, ...: the value references of the exchange buffer */
#endif

#if FMI_VERSION == 2
/* FMI 2.0's logger expands the message as a printf format: pythonfmu's text (not the model's, which has
 * '%' written '%%') gets its '%' doubled, so hosts that expand it and hosts that do not both show it */
static void pass_on(Shim *s, const char *name, int status, const char *category, const char *message, int escape)
{
    if (!escape || !message || !strchr(message, '%')) {
        s->host.logger(s->host.componentEnvironment, name, (fmi2Status)status, category, message);
        return;
    }
    char *escaped = malloc(2 * strlen(message) + 1), *out = escaped;
    if (!escaped) return;
    for (const char *in = message; *in; in++) {
        if (*in == '%') *out++ = '%';
        *out++ = *in;
    }
    *out = '\0';
    s->host.logger(s->host.componentEnvironment, name, (fmi2Status)status, category, escaped);
    free(escaped);
}
#define HOST_LOGGER(s) ((s)->host.logger)
#else
/* FMI 3.0's logger takes the message as it is */
static void pass_on(Shim *s, const char *name, int status, const char *category, const char *message, int escape)
{
    (void)name; (void)escape;
    s->host_logger(s->host_environment, (fmi3Status)status, category, message);
}
#define HOST_LOGGER(s) ((s)->host_logger)
#endif

/* every message of the inner instance: the model's status is noted, pythonfmu's repeat of it dropped */
static void relay_message(Shim *s, const char *name, int status, const char *category, const char *message)
{
    int from_model = category && *category;  /* pythonfmu's own messages carry no category */
    if (from_model) {
        s->model_status = status;
    } else if (status == STATUS_FATAL && s->model_status >= STATUS_ERROR) {
        return;  /* pythonfmu's report of an exception the model has logged already */
    }
    if (!HOST_LOGGER(s) || (status == STATUS_OK && !s->logging_on)) return;
    pass_on(s, name, status, category, message, !from_model);
}

#if FMI_VERSION == 2
static void relay(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status, fmi2String category,
                  fmi2String message, ...)
{
    relay_message(env, name, status, category, message);
}
#else
static void relay(fmi3InstanceEnvironment env, fmi3Status status, fmi3String category, fmi3String message)
{
    relay_message(env, NULL, status, category, message);
}
#endif

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

/* pythonfmu's library keeps its interpreter guard in a static std::shared_ptr, which the C++ exit handlers
 * destroy, and resets it again from its destructor function finalizePythonInterpreter (run later, by
 * _dl_fini): a second release through freed memory that now and then aborts a C/C++ host at exit ("corrupted
 * double-linked list", SIGABRT; docs/using-the-fmus.md). An exit handler registered after the library was
 * loaded runs before those: it resets the guard first (the interpreter is finalized there when pythonfmu
 * started it, as the destructor would), and both later releases find it empty. In a Python host the
 * interpreter has been finalized and the guard released already (fmus/common/slave.py): nothing is left to
 * do. This library stays loaded until exit (NODELETE): the handler of a library unloaded earlier would run at
 * its dlclose, with the interpreter still in use. */
static void (*reset_guard)(void);

static void reset_guard_at_exit(void)
{
    if (reset_guard) reset_guard();
}

static void defuse_teardown(void *library, const char *path)
{
    static int registered;
    Dl_info self;
    if (registered) return;
    registered = 1;
    reset_guard = (void (*)(void))dlsym(library, "finalizePythonInterpreter");
    if (!reset_guard || !dladdr((void *)&defuse_teardown, &self) || !self.dli_fname ||
        !dlopen(self.dli_fname, RTLD_NOW | RTLD_NOLOAD | RTLD_NODELETE) ||
        !dlopen(path, RTLD_NOW | RTLD_NOLOAD | RTLD_NODELETE)) {
        reset_guard = NULL;
        return;
    }
    atexit(reset_guard_at_exit);
}

static void release(Shim *s)
{
    if (s->library) dlclose(s->library);
    free(s);
}

/* ``s`` made live (mast_guard.h) once its inner instance exists; else (or out of memory) released: NULL */
static Shim *live_or_released(Shim *s)
{
    if (s->inner && mast_live_add(s)) return s;
    if (s->inner) s->api.FreeInstance(s->inner);
    release(s);
    return NULL;
}

/* a new front with pythonfmu's library loaded and resolved, or NULL with the reason in *why (static text,
 * or dlerror's) and the failing path in *what */
static Shim *load(const char **what, const char **why)
{
    Shim *s = calloc(1, sizeof *s);
    char *path = inner_path();
    *what = "out of memory, or this library cannot find its own path";
    *why = NULL;
    if (!s || !path) {
        free(path);
        free(s);
        return NULL;
    }
    s->library = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!s->library) {
        *what = "cannot load the model's library";
        *why = dlerror();
        free(path);
        release(s);
        return NULL;
    }
    defuse_teardown(s->library, path);
    free(path);
#define RESOLVE0(fn) s->api.fn = (FMI(fn##TYPE) *)dlsym(s->library, TEXT(FMI(fn))); \
    if (!s->api.fn) { *what = "the model's library lacks a function"; *why = #fn; release(s); return NULL; }
#define RESOLVE(fn, params, args) RESOLVE0(fn)
    FORWARDED0(RESOLVE0)
    FORWARDED(RESOLVE)
    HANDWRITTEN(RESOLVE0)
#undef RESOLVE
#undef RESOLVE0
    s->model_status = -1;
#if FMI_VERSION == 2
    for (fmi2ValueReference vr = 0; vr < 1024; vr++) io_refs[vr] = vr;
#endif
    return s;
}

/* the status a forwarded call returns (see the top of this file) */
static Status settled(const Shim *s, Status status)
{
    return status == STATUS_FATAL && s->model_status == STATUS_ERROR ? STATUS_ERROR : status;
}

#if FMI_VERSION == 2
/* The exchange buffer (FMI 2.0). A host that exchanges every 100 us calls fmi2SetReal, fmi2DoStep and
 * fmi2GetReal of each FMU once per step; each call into Python costs a few microseconds before the model does
 * anything. So the front keeps the inputs and outputs (value references 0 .. n_io - 1 of a Python FMU:
 * fmus/common/slave.py) in a buffer of its own, which the Python glue reads and writes inside fmi2DoStep
 * (`_step`): in step mode fmi2SetReal of inputs and fmi2GetReal of inputs and outputs are answered here,
 * and only fmi2DoStep enters Python. The glue takes the buffer at its first step, from inside the step
 * (mast_front_exchange below: the instance whose fmi2DoStep runs in this thread), and fills it with its
 * values; a glue that does not take it (one with direct feedthrough, whose outputs follow a set) leaves
 * every call forwarded. Any other call in step mode sees the same values: the inputs set here are handed
 * over first, the buffer is read again after it (a restored FMU state, a set of another variable); a
 * failed call or a step refused ends the buffer's answers until the next initialisation (inputs set
 * through the glue then are copied into the buffer too, which the glue reads at every step). */
static __thread Shim *stepping_now;

/* the Python C API the fast step calls, from pythonfmu's library and the interpreter it links (resolved once) */
typedef struct {
    int (*ensure)(void);                             /* PyGILState_Ensure */
    void (*release)(int);                            /* PyGILState_Release */
    void *(*call)(void *, const char *, ...);        /* PyObject_CallFunction */
    long (*as_long)(void *);                         /* PyLong_AsLong */
    void (*incref)(void *), (*decref)(void *);       /* Py_IncRef, Py_DecRef */
    void (*clear)(void);                             /* PyErr_Clear */
} PythonApi;
static PythonApi python;

static int resolve_python_in(void *where)
{
    PythonApi p;
    *(void **)&p.ensure = dlsym(where, "PyGILState_Ensure");
    *(void **)&p.release = dlsym(where, "PyGILState_Release");
    *(void **)&p.call = dlsym(where, "PyObject_CallFunction");
    *(void **)&p.as_long = dlsym(where, "PyLong_AsLong");
    *(void **)&p.incref = dlsym(where, "Py_IncRef");
    *(void **)&p.decref = dlsym(where, "Py_DecRef");
    *(void **)&p.clear = dlsym(where, "PyErr_Clear");
    if (!p.ensure || !p.release || !p.call || !p.as_long || !p.incref || !p.decref || !p.clear) return 0;
    python = p;
    return 1;
}

/* pythonfmu's library and what it links (a C host: libpython), else the process (a Python host's interpreter) */
static int resolve_python(void *library)
{
    return python.ensure || resolve_python_in(library) || resolve_python_in(RTLD_DEFAULT);
}

/* called by the glue (holding the GIL) inside the first step of each of its Python objects (pythonfmu makes a
 * new one at fmi2Reset): the buffer (*fresh = 1: just made, the glue fills it; 0: it holds the inputs set
 * since), and the object's step for the fast path below (`step`: a callable (t, h) -> code, kept until the
 * next object's or fmi2FreeInstance; NULL: none) */
__attribute__((visibility("default"))) double *mast_front_exchange(size_t n_in, size_t n_io, void *step, int *fresh)
{
    Shim *s = stepping_now;
    *fresh = 0;
    if (!s || n_in > n_io) return NULL;
    if (!s->io) {
        s->io = calloc(n_io ? n_io : 1, sizeof(double));
        s->n_in = n_in;
        s->n_io = n_io;
        *fresh = 1;
    }
    if (!s->io || s->n_in != n_in || s->n_io != n_io) return NULL;
    if (step != s->py_step && resolve_python(s->library)) {
        if (s->py_step) python.decref(s->py_step);
        if (step) python.incref(step);
        s->py_step = step;
    }
    return s->io;
}

static int buffered(const Shim *s) { return s->io && s->stepping && s->n_io <= 1024; }

/* before a call forwarded in step mode: the inputs set here, handed over */
static void before_call(Shim *s)
{
    if (buffered(s) && s->dirty) {
        s->api.SetReal(s->inner, io_refs, s->n_in, s->io);
        s->dirty = 0;
    }
}

/* after it: step mode begins (exitInitializationMode) or ends (a failure, terminate, reset), the buffer read again */
static Status after_call(Shim *s, const char *fn, Status status)
{
    if (status > fmi2Warning || !strcmp(fn, "Terminate") || !strcmp(fn, "Reset")) {
        s->stepping = 0;
    } else if (!strcmp(fn, "ExitInitializationMode")) {
        s->stepping = 1;
    }
    if (!strcmp(fn, "Reset") || !strcmp(fn, "ExitInitializationMode")) s->refused = 0;
    if (buffered(s)) s->api.GetReal(s->inner, io_refs, s->n_io, s->io);
    return status;
}

static int all_below(const fmi2ValueReference vr[], size_t nvr, size_t n)
{
    for (size_t i = 0; i < nvr; i++)
        if (vr[i] >= n) return 0;
    return 1;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[])
{
    Shim *s = mast_live(c);
    if (!s) return fmi2Error;
    if (buffered(s) && all_below(vr, nvr, s->n_in)) {
        for (size_t i = 0; i < nvr; i++) s->io[vr[i]] = value[i];
        s->dirty = 1;
        return fmi2OK;
    }
    before_call(s);
    s->model_status = -1;
    fmi2Status status = settled(s, s->api.SetReal(s->inner, vr, nvr, value));
    if (s->io && status <= fmi2Warning) {   /* the glue reads its inputs from the buffer at every step */
        for (size_t i = 0; i < nvr; i++)
            if (vr[i] < s->n_in) s->io[vr[i]] = value[i];
    }
    return after_call(s, "SetReal", status);
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[])
{
    Shim *s = mast_live(c);
    if (!s) return fmi2Error;
    if (buffered(s) && all_below(vr, nvr, s->n_io)) {
        for (size_t i = 0; i < nvr; i++) value[i] = s->io[vr[i]];
        return fmi2OK;
    }
    before_call(s);
    s->model_status = -1;
    return after_call(s, "GetReal", settled(s, s->api.GetReal(s->inner, vr, nvr, value)));
}

/* the step: the glue reads the inputs from the buffer and writes the outputs into it (slave.py, `_step`) */
fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean noSetFMUStatePriorToCurrentPoint)
{
    Shim *s = mast_live(c);
    if (!s) return fmi2Error;
    Shim *outer = stepping_now;
    stepping_now = s;
    s->model_status = -1;
    if (buffered(s) && s->py_step) {
        /* the fast path: the glue's step called here (slave.py, `_front_step`), not through pythonfmu's
         * fmi2DoStep: 0 stepped, 3 stepped with messages, 4 refused with messages (pythonfmu passes them on at
         * its next call: a call without values), 2 not stepped (refused before the step: pythonfmu steps) */
        int gil = python.ensure();
        void *result = python.call(s->py_step, "dd", t, h);
        long code = 2;
        if (result) {
            code = python.as_long(result);
            python.decref(result);
        } else {
            python.clear();
        }
        python.release(gil);
        if (code == 0 || code == 3 || code == 4) {
            stepping_now = outer;
            s->dirty = 0;
            if (code != 0) s->api.GetReal(s->inner, io_refs, 0, NULL);
            if (code == 4) s->stepping = 0, s->refused = 1;
            return code == 4 ? fmi2Discard : fmi2OK;
        }
        s->model_status = -1;
    }
    fmi2Status status = settled(s, s->api.DoStep(s->inner, t, h, noSetFMUStatePriorToCurrentPoint));
    stepping_now = outer;
    s->dirty = 0;
    if (status > fmi2Warning) s->stepping = 0;
    return status;
}
/* after a step the fast path saw refused, fmi2Terminated is true, as pythonfmu says after one it refused */
fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind kind, fmi2Boolean *value)
{
    Shim *s = mast_live(c);
    if (!s) return fmi2Error;
    if (s->refused && kind == fmi2Terminated) {
        *value = fmi2True;
        return fmi2OK;
    }
    before_call(s);
    s->model_status = -1;
    return after_call(s, "GetBooleanStatus", settled(s, s->api.GetBooleanStatus(s->inner, kind, value)));
}
#else
#define before_call(s) ((void)(s))
#define after_call(s, fn, status) (status)
#endif

#define FORWARD0(fn) Status FMI(fn)(Instance c) { Shim *s = mast_live(c); if (!s) { return STATUS_ERROR; } \
    before_call(s); s->model_status = -1; return after_call(s, #fn, settled(s, s->api.fn(s->inner))); }
#define FORWARD(fn, params, args) Status FMI(fn)(Instance c, UNPAREN params) { Shim *s = mast_live(c); \
    if (!s) { return STATUS_ERROR; } before_call(s); s->model_status = -1; \
    return after_call(s, #fn, settled(s, s->api.fn(s->inner, UNPAREN args))); }
FORWARDED0(FORWARD0)
FORWARDED(FORWARD)
#undef FORWARD
#undef FORWARD0

#if FMI_VERSION == 3
/* pythonfmu3 0.3.4 drops fmi3EnterInitializationMode's start time (the model would start at t = 0): the
 * front hands it over first, as a set of the value reference the Python glue reserves for it
 * (START_TIME_REFERENCE in fmus/common/fmi3.py; it takes effect only before initialization) */
#define START_TIME_REFERENCE 0x7FFFFFFFu   /* pythonfmu3 passes value references to Python as signed 32-bit integers */

fmi3Status fmi3EnterInitializationMode(fmi3Instance c, fmi3Boolean toleranceDefined, fmi3Float64 tolerance,
                                       fmi3Float64 startTime, fmi3Boolean stopTimeDefined, fmi3Float64 stopTime)
{
    Shim *s = mast_live(c);
    const fmi3ValueReference start = START_TIME_REFERENCE;
    char msg[256];
    if (!s) return fmi3Error;
    if (mast_bad_time("enterInitializationMode", "startTime", startTime, msg, sizeof msg) ||
        (stopTimeDefined && mast_bad_time("enterInitializationMode", "stopTime", stopTime, msg, sizeof msg))) {
        if (s->host_logger) pass_on(s, NULL, fmi3Error, "logStatusError", msg, 0);
        return fmi3Error;
    }
    s->model_status = -1;
    fmi3Status status = settled(s, s->api.SetFloat64(s->inner, &start, 1, &startTime, 1));
    if (status > fmi3Warning) return status;
    s->model_status = -1;
    return settled(s, s->api.EnterInitializationMode(s->inner, toleranceDefined, tolerance, startTime,
                                                     stopTimeDefined, stopTime));
}
#endif

/* a second free, or a free of a pointer never made here, touches nothing (mast_guard.h) */
void FMI(FreeInstance)(Instance c)
{
    Shim *s = c;
    if (!mast_live_remove(s)) return;
#if FMI_VERSION == 2
    if (s->py_step) {  /* the glue's step, released while the interpreter that pythonfmu's instance uses is there */
        int gil = python.ensure();
        python.decref(s->py_step);
        python.release(gil);
    }
#endif
    s->api.FreeInstance(s->inner);
#if FMI_VERSION == 2
    free(s->io);
#endif
    if (s->library) dlclose(s->library);
    mast_retire(s);
}

#if FMI_VERSION == 2
const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String resources,
                              const fmi2CallbackFunctions *functions, fmi2Boolean visible, fmi2Boolean loggingOn)
{
    const char *what, *why;
    Shim *s = load(&what, &why);
    if (!s) {
        if (functions && functions->logger)
            functions->logger(functions->componentEnvironment, name, fmi2Error, "logStatusError",
                              "fmi2Instantiate: %s: %s", what, why ? why : "unknown reason");
        return NULL;
    }
    if (functions) s->host = *functions;
    s->relayed = s->host;
    s->relayed.logger = relay;
    s->relayed.componentEnvironment = s;
    s->logging_on = loggingOn;
    s->inner = s->api.Instantiate(name, type, guid, resources, &s->relayed, visible, fmi2True);
    return live_or_released(s);
}

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t n, const fmi2String categories[])
#else
const char *fmi3GetVersion(void) { return fmi3Version; }

static void refuse_instantiation(fmi3InstanceEnvironment env, fmi3LogMessageCallback logger, const char *what,
                                 const char *why)
{
    if (!logger) return;
    size_t size = strlen(what) + (why ? strlen(why) : 0) + 32;
    char *message = malloc(size);
    if (!message) return;
    snprintf(message, size, "fmi3Instantiate: %s: %s", what, why ? why : "unknown reason");
    logger(env, fmi3Error, "logStatusError", message);
    free(message);
}

fmi3Instance fmi3InstantiateCoSimulation(fmi3String name, fmi3String token, fmi3String resources,
                                         fmi3Boolean visible, fmi3Boolean loggingOn, fmi3Boolean eventModeUsed,
                                         fmi3Boolean earlyReturnAllowed, const fmi3ValueReference required[],
                                         size_t nRequired, fmi3InstanceEnvironment env,
                                         fmi3LogMessageCallback logMessage, fmi3IntermediateUpdateCallback update)
{
    const char *what, *why;
    Shim *s = load(&what, &why);
    if (!s) {
        refuse_instantiation(env, logMessage, what, why);
        return NULL;
    }
    s->host_logger = logMessage;
    s->host_environment = env;
    s->logging_on = loggingOn;
    s->inner = s->api.InstantiateCoSimulation(name, token, resources, visible, fmi3True, eventModeUsed,
                                              earlyReturnAllowed, required, nRequired, s, relay, update);
    return live_or_released(s);
}

/* the MAST FMUs are Co-Simulation FMUs only (modelDescription.xml declares nothing else) */
fmi3Instance fmi3InstantiateModelExchange(fmi3String name, fmi3String token, fmi3String resources,
                                          fmi3Boolean visible, fmi3Boolean loggingOn, fmi3InstanceEnvironment env,
                                          fmi3LogMessageCallback logMessage)
{
    (void)name; (void)token; (void)resources; (void)visible; (void)loggingOn;
    refuse_instantiation(env, logMessage, "Model Exchange", "this FMU is for Co-Simulation only");
    return NULL;
}

fmi3Instance fmi3InstantiateScheduledExecution(fmi3String name, fmi3String token, fmi3String resources,
                                               fmi3Boolean visible, fmi3Boolean loggingOn,
                                               fmi3InstanceEnvironment env, fmi3LogMessageCallback logMessage,
                                               fmi3ClockUpdateCallback clockUpdate,
                                               fmi3LockPreemptionCallback lockPreemption,
                                               fmi3UnlockPreemptionCallback unlockPreemption)
{
    (void)name; (void)token; (void)resources; (void)visible; (void)loggingOn;
    (void)clockUpdate; (void)lockPreemption; (void)unlockPreemption;
    refuse_instantiation(env, logMessage, "Scheduled Execution", "this FMU is for Co-Simulation only");
    return NULL;
}

fmi3Status fmi3SetDebugLogging(fmi3Instance c, fmi3Boolean loggingOn, size_t n, const fmi3String categories[])
#endif
{
    Shim *s = mast_live(c);
    (void)n; (void)categories;
    if (!s) return STATUS_ERROR;
    s->logging_on = loggingOn;  /* the inner instance keeps logging on: the relay filters */
    return STATUS_OK;
}
