/* The FMI 2.0 Co-Simulation interface of every native MAST FMU (mast build --native).
 *
 * One wrapper for all models: it holds the variables (by value reference), the phase of
 * the FMI state machine, the parameters and the model's state block, and calls the
 * generated model file through MAST_MODEL (mast_model.h). Behaviour, as the Python FMUs
 * (fmus/common/slave.py) where FMI leaves a choice:
 *
 * - parameters are checked when leaving initialization mode; a bad value is logged there
 *   (status Error, the parameter named, the expected range) and exitInitializationMode
 *   returns OK, then every doStep returns Discard with that cause (libcosim aborts the whole
 *   process when a component fails exitInitializationMode; a refused step every host handles);
 * - in initialization mode the outputs follow the inputs: a get after a set recomputes them;
 * - a model failure in doStep is logged and doStep returns Discard: the instance stays usable;
 * - a call the FMI state machine does not allow (doStep before initialization, a parameter set
 *   after it, an unknown value reference, a type that is not the variable's) is logged and
 *   returns Error, changing nothing;
 * - get/set FMU state: a copy of everything the instance holds;
 * - a careless host: a call on an instance this binary did not make or has freed is refused unread (a second
 *   free does nothing; mast_guard.h), a time that is not finite and >= 0 and a step longer than the model takes
 *   in bounded time (mast_model.h, max_ticks) return Error with a message naming them.
 * Errors and warnings are always passed to the host's logger (every '%' of a message escaped,
 * so a host that uses it as a printf format shows it as it is).
 */
#define _GNU_SOURCE   /* dladdr (mast_guard.h) */
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"
#include "mast_guard.h"
#include "mast_model.h"

#define MSG_SIZE 1024

typedef enum { INSTANTIATED, INITIALIZATION, STEPPING, TERMINATED } Phase;

typedef struct {
    double *real;          /* by value reference: inputs and outputs (the model's values), Real parameters */
    int *integer;
    char **string;
    unsigned char *state;  /* the model's state block */
    Phase phase;
    double t0;
    int dirty;             /* inputs or parameters changed in initialization mode: outputs to recompute */
    int failed;            /* the instance did not initialise: every doStep is refused */
    int refused;           /* the last doStep was refused: the FMU asks the host to stop (fmi2Terminated) */
    char cause[MSG_SIZE];
    int eval_failed;       /* the outputs of the inputs set at this communication point failed (evaluate) */
    char eval_cause[MSG_SIZE];
} Snapshot;

typedef struct {
    fmi2CallbackLogger logger;
    fmi2ComponentEnvironment env;
    char *name;
    int logging_on;
    Snapshot s;
} Instance;

static const mast_model *const M = &MAST_MODEL;

static void log_message(Instance *c, fmi2Status status, const char *category, const char *fmt, ...)
{
    char message[2 * MSG_SIZE];
    va_list ap;
    if (!c->logger || (status == fmi2OK && !c->logging_on)) return;
    va_start(ap, fmt);
    vsnprintf(message, sizeof message, fmt, ap);
    va_end(ap);
    /* FMI hands the message to the host as a printf format; some hosts (fmpy) show it unformatted:
     * the message itself, every '%' written '%%' (as the Python FMUs do) suits both */
    char escaped[4 * MSG_SIZE];
    size_t k = 0;
    for (const char *p = message; *p && k + 2 < sizeof escaped; p++) {
        if (*p == '%') escaped[k++] = '%';
        escaped[k++] = *p;
    }
    escaped[k] = '\0';
    c->logger(c->env, c->name, status, category, escaped);
}

#define LOG_ERROR(c, ...) log_message((c), fmi2Error, "logStatusError", __VA_ARGS__)

static const char *error_class(int code)
{
    switch (code) {
    case MAST_PARAMETER_ERROR: return "ParameterError";
    case MAST_KINEMATICS_ERROR: return "KinematicsError";
    case MAST_SINGULARITY_ERROR: return "SingularityError";
    default: return "ModelError";
    }
}

static mast_parameters parameters_of(Instance *c)
{
    mast_parameters p = {c->s.real, c->s.integer, (const char *const *)c->s.string};
    return p;
}

/* a call refused in this phase (0, logged) */
static int refused(Instance *c, const char *call)
{
    static const char *names[] = {"instantiated", "initialization mode", "step mode", "terminated"};
    LOG_ERROR(c, "%s: not allowed in %s", call, names[c->s.phase]);
    return 0;
}

static inline int allowed(Instance *c, const char *call, int mask)
{
    return (mask & (1 << c->s.phase)) ? 1 : refused(c, call);
}
#define IN_INSTANTIATED (1 << INSTANTIATED)
#define IN_INIT (1 << INITIALIZATION)
#define IN_STEP (1 << STEPPING)
#define IN_TERMINATED (1 << TERMINATED)
#define ANY_PHASE (IN_INSTANTIATED | IN_INIT | IN_STEP | IN_TERMINATED)

/* why a value reference is refused (0); ``known``'s failures, out of its inlined common case */
static int unknown(Instance *c, const char *call, fmi2ValueReference vr, mast_type type)
{
    static const char *types[] = {"Real", "Integer", "String"};
    if (vr >= (fmi2ValueReference)M->n_variables) {
        LOG_ERROR(c, "%s: unknown value reference %u (this FMU has %d variables)", call, vr, M->n_variables);
        return 0;
    }
    if (M->variables[vr].type != type) {
        LOG_ERROR(c, "%s: value reference %u ('%s') is a %s variable", call, vr, M->variables[vr].name,
                  types[M->variables[vr].type]);
        return 0;
    }
    return 1;
}

/* a variable of this type? (1; else 0, logged): the check of every get and set, per value reference */
static inline int known(Instance *c, const char *call, fmi2ValueReference vr, mast_type type)
{
    if (vr < (fmi2ValueReference)M->n_variables && M->variables[vr].type == type) return 1;
    return unknown(c, call, vr, type);
}

static void set_starts(Instance *c)
{
    for (int k = 0; k < M->n_variables; k++) {
        const mast_variable *v = &M->variables[k];
        c->s.real[k] = v->real_start;
        c->s.integer[k] = v->integer_start;
        free(c->s.string[k]);
        c->s.string[k] = NULL;
        if (v->type == MAST_STRING) {
            c->s.string[k] = malloc(strlen(v->string_start) + 1);
            if (c->s.string[k]) strcpy(c->s.string[k], v->string_start);
        }
    }
    memset(c->s.state, 0, M->state_size);
    c->s.phase = INSTANTIATED;
    c->s.t0 = 0.0;
    c->s.dirty = 1;
    c->s.failed = 0;
    c->s.refused = 0;
    c->s.cause[0] = '\0';
    c->s.eval_failed = 0;
    c->s.eval_cause[0] = '\0';
}

/* parameters, then the outputs at t0 from the inputs: 0, or the model's error code with ``msg`` */
static int initialize(Instance *c, char *msg)
{
    mast_parameters p = parameters_of(c);
    int code = M->check(&p, msg, MSG_SIZE);
    if (!code) code = M->initialize(c->s.state, c->s.real, &p, c->s.t0, msg, MSG_SIZE);
    return code;
}

/* ------------------------------------------------------------------------------------- common */
const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component comp, fmi2Boolean loggingOn, size_t n, const fmi2String categories[])
{
    Instance *c = mast_live(comp);
    (void)n; (void)categories;
    if (!c) return fmi2Error;
    c->logging_on = loggingOn;
    return fmi2OK;
}

static void destroy(Instance *c);

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String resources,
                              const fmi2CallbackFunctions *functions, fmi2Boolean visible, fmi2Boolean loggingOn)
{
    Instance tmp = {0};
    (void)resources; (void)visible;
    tmp.logger = functions ? functions->logger : NULL;
    tmp.env = functions ? functions->componentEnvironment : NULL;
    tmp.name = (char *)(name ? name : "?");
    if (!name || !name[0]) {
        LOG_ERROR(&tmp, "fmi2Instantiate: missing instance name");
        return NULL;
    }
    if (type != fmi2CoSimulation) {
        LOG_ERROR(&tmp, "fmi2Instantiate: %s is a Co-Simulation FMU (no Model Exchange)", M->identifier);
        return NULL;
    }
    if (!guid || strcmp(guid, M->guid) != 0) {
        LOG_ERROR(&tmp, "fmi2Instantiate: GUID %s does not match this binary's %s", guid ? guid : "(none)", M->guid);
        return NULL;
    }
    Instance *c = calloc(1, sizeof *c);
    if (!c) return NULL;
    c->logger = tmp.logger;
    c->env = tmp.env;
    c->logging_on = loggingOn;
    c->name = malloc(strlen(name) + 1);
    c->s.real = calloc((size_t)M->n_variables, sizeof(double));
    c->s.integer = calloc((size_t)M->n_variables, sizeof(int));
    c->s.string = calloc((size_t)M->n_variables, sizeof(char *));
    c->s.state = calloc(1, M->state_size ? M->state_size : 1);
    if (!c->name || !c->s.real || !c->s.integer || !c->s.string || !c->s.state || !mast_live_add(c)) {
        destroy(c);
        return NULL;
    }
    strcpy(c->name, name);
    set_starts(c);
    return c;
}

static void free_snapshot(Snapshot *s)
{
    if (s->string)
        for (int k = 0; k < M->n_variables; k++) free(s->string[k]);
    free(s->string);
    free(s->real);
    free(s->integer);
    free(s->state);
}

/* what an instance holds, released; its own block retired (mast_guard.h) */
static void destroy(Instance *c)
{
    free_snapshot(&c->s);
    free(c->name);
    mast_retire(c);
}

/* a second free, or a free of a pointer never made here, touches nothing (mast_guard.h) */
void fmi2FreeInstance(fmi2Component comp)
{
    if (mast_live_remove(comp)) destroy(comp);
}

fmi2Status fmi2SetupExperiment(fmi2Component comp, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime)
{
    Instance *c = mast_live(comp);
    char msg[MSG_SIZE];
    (void)toleranceDefined; (void)tolerance;
    if (!c || !allowed(c, "fmi2SetupExperiment", IN_INSTANTIATED)) return fmi2Error;
    if (mast_bad_time("setupExperiment", "startTime", startTime, msg, sizeof msg) ||
        (stopTimeDefined && mast_bad_time("setupExperiment", "stopTime", stopTime, msg, sizeof msg))) {
        LOG_ERROR(c, "%s", msg);
        return fmi2Error;
    }
    c->s.t0 = startTime;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component comp)
{
    Instance *c = mast_live(comp);
    if (!c || !allowed(c, "fmi2EnterInitializationMode", IN_INSTANTIATED)) return fmi2Error;
    c->s.phase = INITIALIZATION;
    c->s.dirty = 1;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component comp)
{
    Instance *c = mast_live(comp);
    char msg[MSG_SIZE];
    if (!c || !allowed(c, "fmi2ExitInitializationMode", IN_INIT)) return fmi2Error;
    int code = initialize(c, msg);
    c->s.phase = STEPPING;
    c->s.dirty = 0;
    if (code) {  /* see the file's comment: a refused step, not a failed exitInitializationMode */
        snprintf(c->s.cause, MSG_SIZE, "%s: %s: %s", error_class(code), c->name, msg);
        c->s.failed = 1;
        LOG_ERROR(c, "exitInitializationMode: %s", c->s.cause);
    }
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component comp)
{
    Instance *c = mast_live(comp);
    if (!c || !allowed(c, "fmi2Terminate", IN_STEP)) return fmi2Error;
    c->s.phase = TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component comp)
{
    Instance *c = mast_live(comp);
    if (!c) return fmi2Error;
    set_starts(c);
    return fmi2OK;
}

/* --------------------------------------------------------------------------------- get / set */
/* in initialization mode, outputs read after inputs changed are recomputed; a failure may be an
 * input the host has not set yet: a warning, and the outputs stay as they were */
static void tentative_outputs(Instance *c)
{
    char msg[MSG_SIZE];
    if (c->s.phase != INITIALIZATION || !c->s.dirty) return;
    size_t bytes = (size_t)M->n_io * sizeof(double);
    double *kept = malloc(bytes);
    if (!kept) return;
    memcpy(kept, c->s.real, bytes);
    int code = initialize(c, msg);
    if (code) {
        memcpy(c->s.real, kept, bytes);
        log_message(c, fmi2Warning, "logStatusWarning",
                    "initialization mode, outputs kept at their last values: %s: %s: %s", error_class(code), c->name,
                    msg);
    } else {
        c->s.dirty = 0;
    }
    free(kept);
}

fmi2Status fmi2GetReal(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[])
{
    Instance *c = mast_live(comp);
    if (!c || !allowed(c, "fmi2GetReal", ANY_PHASE)) return fmi2Error;
    if (nvr && (!vr || !value)) { LOG_ERROR(c, "fmi2GetReal: null argument"); return fmi2Error; }
    for (size_t k = 0; k < nvr; k++)
        if (!known(c, "fmi2GetReal", vr[k], MAST_REAL)) return fmi2Error;
    if (c->s.phase == INITIALIZATION && c->s.dirty)   /* tentative_outputs' own condition, checked once */
        for (size_t k = 0; k < nvr; k++)
            if ((int)vr[k] >= M->n_inputs && (int)vr[k] < M->n_io) { tentative_outputs(c); break; }
    for (size_t k = 0; k < nvr; k++) value[k] = c->s.real[vr[k]];
    return fmi2OK;
}

fmi2Status fmi2GetInteger(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, fmi2Integer value[])
{
    Instance *c = mast_live(comp);
    if (!c || !allowed(c, "fmi2GetInteger", ANY_PHASE)) return fmi2Error;
    if (nvr && (!vr || !value)) { LOG_ERROR(c, "fmi2GetInteger: null argument"); return fmi2Error; }
    for (size_t k = 0; k < nvr; k++)
        if (!known(c, "fmi2GetInteger", vr[k], MAST_INTEGER)) return fmi2Error;
    for (size_t k = 0; k < nvr; k++) value[k] = c->s.integer[vr[k]];
    return fmi2OK;
}

fmi2Status fmi2GetBoolean(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, fmi2Boolean value[])
{
    Instance *c = mast_live(comp);
    (void)value;
    if (!c) return fmi2Error;
    if (nvr) { LOG_ERROR(c, "fmi2GetBoolean: unknown value reference %u (this FMU has no Boolean variable)", vr ? vr[0] : 0); return fmi2Error; }
    return fmi2OK;
}

fmi2Status fmi2GetString(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, fmi2String value[])
{
    Instance *c = mast_live(comp);
    if (!c || !allowed(c, "fmi2GetString", ANY_PHASE)) return fmi2Error;
    if (nvr && (!vr || !value)) { LOG_ERROR(c, "fmi2GetString: null argument"); return fmi2Error; }
    for (size_t k = 0; k < nvr; k++)
        if (!known(c, "fmi2GetString", vr[k], MAST_STRING)) return fmi2Error;
    for (size_t k = 0; k < nvr; k++) value[k] = c->s.string[vr[k]];
    return fmi2OK;
}

/* may the host set this variable now? inputs: always before terminate; parameters: before
 * exitInitializationMode (variability fixed); outputs: never */
static int settable_checked(Instance *c, const char *call, fmi2ValueReference vr)
{
    const mast_variable *v = &M->variables[vr];
    if (v->causality == MAST_OUTPUT) {
        LOG_ERROR(c, "%s: '%s' is an output: it cannot be set", call, v->name);
        return 0;
    }
    if (v->causality == MAST_PARAMETER && c->s.phase != INSTANTIATED && c->s.phase != INITIALIZATION) {
        LOG_ERROR(c, "%s: parameter '%s' is fixed: it can only be set before exitInitializationMode", call, v->name);
        return 0;
    }
    if (c->s.phase == TERMINATED) {
        LOG_ERROR(c, "%s: not allowed after terminate", call);
        return 0;
    }
    return 1;
}

/* ``settable_checked`` with its common case inlined: an input before terminate */
static inline int settable(Instance *c, const char *call, fmi2ValueReference vr)
{
    if (M->variables[vr].causality == MAST_INPUT && c->s.phase != TERMINATED) return 1;
    return settable_checked(c, call, vr);
}

static fmi2Status after_set(Instance *c)
{
    if (c->s.phase == INITIALIZATION || c->s.phase == INSTANTIATED) c->s.dirty = 1;
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[])
{
    Instance *c = mast_live(comp);
    if (!c) return fmi2Error;
    if (nvr && (!vr || !value)) { LOG_ERROR(c, "fmi2SetReal: null argument"); return fmi2Error; }
    for (size_t k = 0; k < nvr; k++)
        if (!known(c, "fmi2SetReal", vr[k], MAST_REAL) || !settable(c, "fmi2SetReal", vr[k])) return fmi2Error;
    for (size_t k = 0; k < nvr; k++) c->s.real[vr[k]] = value[k];
    if (c->s.phase == STEPPING && M->evaluate && !c->s.failed) {   /* direct feedthrough: the outputs follow */
        int input = 0;
        for (size_t k = 0; k < nvr; k++) input |= (int)vr[k] < M->n_inputs;
        if (input) {
            char msg[MSG_SIZE];
            mast_parameters p = parameters_of(c);
            int code = M->evaluate(c->s.state, c->s.real, &p, msg, MSG_SIZE);
            c->s.eval_failed = code != 0;
            if (code) {
                snprintf(c->s.eval_cause, MSG_SIZE, "%s: %s: %s", error_class(code), c->name, msg);
                LOG_ERROR(c, "setReal: evaluating the outputs: %s", c->s.eval_cause);
            }
        }
    }
    return after_set(c);
}

fmi2Status fmi2SetInteger(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, const fmi2Integer value[])
{
    Instance *c = mast_live(comp);
    if (!c) return fmi2Error;
    if (nvr && (!vr || !value)) { LOG_ERROR(c, "fmi2SetInteger: null argument"); return fmi2Error; }
    for (size_t k = 0; k < nvr; k++)
        if (!known(c, "fmi2SetInteger", vr[k], MAST_INTEGER) || !settable(c, "fmi2SetInteger", vr[k]))
            return fmi2Error;
    for (size_t k = 0; k < nvr; k++) c->s.integer[vr[k]] = value[k];
    return after_set(c);
}

fmi2Status fmi2SetBoolean(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, const fmi2Boolean value[])
{
    Instance *c = mast_live(comp);
    (void)value;
    if (!c) return fmi2Error;
    if (nvr) { LOG_ERROR(c, "fmi2SetBoolean: unknown value reference %u (this FMU has no Boolean variable)", vr ? vr[0] : 0); return fmi2Error; }
    return fmi2OK;
}

fmi2Status fmi2SetString(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, const fmi2String value[])
{
    Instance *c = mast_live(comp);
    if (!c) return fmi2Error;
    if (nvr && (!vr || !value)) { LOG_ERROR(c, "fmi2SetString: null argument"); return fmi2Error; }
    for (size_t k = 0; k < nvr; k++) {
        if (!known(c, "fmi2SetString", vr[k], MAST_STRING) || !settable(c, "fmi2SetString", vr[k])) return fmi2Error;
        if (!value[k]) { LOG_ERROR(c, "fmi2SetString: null string for '%s'", M->variables[vr[k]].name); return fmi2Error; }
    }
    for (size_t k = 0; k < nvr; k++) {
        char *copy = malloc(strlen(value[k]) + 1);
        if (!copy) return fmi2Error;
        strcpy(copy, value[k]);
        free(c->s.string[vr[k]]);
        c->s.string[vr[k]] = copy;
    }
    return after_set(c);
}

/* ---------------------------------------------------------------------------------- stepping */
/* a step longer than the model takes in bounded time (mast_model.h, max_ticks): 1 with the message (the Python
 * FMUs' words: fmus/common/slave.py, ``_too_long``) */
static int too_long(Instance *c, double h, char *msg)
{
    double tick = M->cycle_time >= 0 ? c->s.real[M->cycle_time] : 0.0;
    double largest = M->cycle_time >= 0 ? M->max_ticks * tick : M->max_step;
    if (h <= largest) return 0;
    int n = snprintf(msg, MSG_SIZE, "doStep: communicationStepSize = %.6g s exceeds the largest step this FMU takes, "
                     "%.6g s", h, largest);
    if (M->cycle_time >= 0)
        snprintf(msg + n, MSG_SIZE - (size_t)n, " (%.6g ticks of %s = %.6g s)", M->max_ticks,
                 M->variables[M->cycle_time].name, tick);
    return 1;
}

fmi2Status fmi2DoStep(fmi2Component comp, fmi2Real t, fmi2Real h, fmi2Boolean noSetFMUStatePriorToCurrentPoint)
{
    Instance *c = mast_live(comp);
    char msg[MSG_SIZE];
    (void)noSetFMUStatePriorToCurrentPoint;
    if (!c) return fmi2Error;
    if (c->s.phase != STEPPING) {
        LOG_ERROR(c, "doStep at t=%.6g s: doStep before exitInitializationMode", t);
        return fmi2Error;
    }
    if (mast_bad_time("doStep", "currentCommunicationPoint", t, msg, sizeof msg) ||
        mast_bad_time("doStep", "communicationStepSize", h, msg, sizeof msg)) {
        LOG_ERROR(c, "%s", msg);
        return fmi2Error;
    }
    if (c->s.failed) {
        LOG_ERROR(c, "doStep at t=%.6g s: RuntimeError: the instance did not initialise: %s", t, c->s.cause);
        c->s.refused = 1;
        return fmi2Discard;
    }
    if (c->s.eval_failed) {
        LOG_ERROR(c, "doStep at t=%.6g s: RuntimeError: the outputs of the inputs set at this communication point "
                  "failed: %s", t, c->s.eval_cause);
        c->s.refused = 1;
        return fmi2Discard;
    }
    if (too_long(c, h, msg)) {   /* after the refusals above: a failed instance may have no valid cycle time */
        LOG_ERROR(c, "%s", msg);
        return fmi2Error;
    }
    mast_parameters p = parameters_of(c);
    int code = M->do_step(c->s.state, c->s.real, &p, t, h, msg, MSG_SIZE);
    c->s.refused = code != 0;
    if (code) {
        LOG_ERROR(c, "doStep at t=%.6g s: %s: %s: %s", t, error_class(code), c->name, msg);
        return fmi2Discard;
    }
    return fmi2OK;
}

fmi2Status fmi2CancelStep(fmi2Component comp)
{
    Instance *c = mast_live(comp);
    if (c) LOG_ERROR(c, "fmi2CancelStep: doStep is synchronous here, there is nothing to cancel");
    return fmi2Error;
}

fmi2Status fmi2SetRealInputDerivatives(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[])
{
    Instance *c = mast_live(comp);
    (void)vr; (void)nvr; (void)order; (void)value;
    if (c) LOG_ERROR(c, "fmi2SetRealInputDerivatives: not supported (canInterpolateInputs=false)");
    return fmi2Error;
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[])
{
    Instance *c = mast_live(comp);
    (void)vr; (void)nvr; (void)order; (void)value;
    if (c) LOG_ERROR(c, "fmi2GetRealOutputDerivatives: not supported (maxOutputDerivativeOrder=0)");
    return fmi2Error;
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component comp, const fmi2ValueReference u[], size_t nu,
                                        const fmi2ValueReference z[], size_t nz, const fmi2Real dv[], fmi2Real dz[])
{
    Instance *c = mast_live(comp);
    (void)u; (void)nu; (void)z; (void)nz; (void)dv; (void)dz;
    if (c) LOG_ERROR(c, "fmi2GetDirectionalDerivative: not supported (providesDirectionalDerivative=false)");
    return fmi2Error;
}

static fmi2Status no_status(fmi2Component comp, const char *call)
{
    Instance *c = mast_live(comp);
    if (c) LOG_ERROR(c, "%s: doStep never runs asynchronously here: no status to ask for", call);
    return fmi2Error;
}

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *v)
{ (void)s; (void)v; return no_status(c, "fmi2GetStatus"); }
fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *v)
{ (void)s; (void)v; return no_status(c, "fmi2GetRealStatus"); }
fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *v)
{ (void)s; (void)v; return no_status(c, "fmi2GetIntegerStatus"); }
/* fmi2Terminated: after a refused step the FMU cannot go on (as the Python FMUs answer) */
fmi2Status fmi2GetBooleanStatus(fmi2Component comp, const fmi2StatusKind s, fmi2Boolean *v)
{
    Instance *c = mast_live(comp);
    if (!c || !v || s != fmi2Terminated) return no_status(comp, "fmi2GetBooleanStatus");
    *v = c->s.refused ? fmi2True : fmi2False;
    return fmi2OK;
}
fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *v)
{ (void)s; (void)v; return no_status(c, "fmi2GetStringStatus"); }

/* --------------------------------------------------------------------------------- FMU state */
static int copy_snapshot(Snapshot *to, const Snapshot *from)
{
    size_t n = (size_t)M->n_variables;
    to->real = malloc(n * sizeof(double));
    to->integer = malloc(n * sizeof(int));
    to->string = calloc(n, sizeof(char *));
    to->state = malloc(M->state_size ? M->state_size : 1);
    if (!to->real || !to->integer || !to->string || !to->state) return 0;
    memcpy(to->real, from->real, n * sizeof(double));
    memcpy(to->integer, from->integer, n * sizeof(int));
    memcpy(to->state, from->state, M->state_size);
    for (size_t k = 0; k < n; k++) {
        if (!from->string[k]) continue;
        to->string[k] = malloc(strlen(from->string[k]) + 1);
        if (!to->string[k]) return 0;
        strcpy(to->string[k], from->string[k]);
    }
    to->phase = from->phase;
    to->t0 = from->t0;
    to->dirty = from->dirty;
    to->failed = from->failed;
    to->refused = from->refused;
    memcpy(to->cause, from->cause, sizeof to->cause);
    to->eval_failed = from->eval_failed;
    memcpy(to->eval_cause, from->eval_cause, sizeof to->eval_cause);
    return 1;
}

/* the FMU state: a tagged snapshot, so a state of another FMU is recognised and refused */
typedef struct {
    const mast_model *owner;
    Snapshot s;
} State;

fmi2Status fmi2GetFMUstate(fmi2Component comp, fmi2FMUstate *state)
{
    Instance *c = mast_live(comp);
    if (!c || !state) return fmi2Error;
    State *st = *state;
    if (st && st->owner == M) {    /* FMI: update the state the host passes back */
        free_snapshot(&st->s);
    } else {
        st = calloc(1, sizeof *st);
        if (!st) return fmi2Error;
        st->owner = M;
    }
    if (!copy_snapshot(&st->s, &c->s)) {
        free_snapshot(&st->s);
        free(st);
        *state = NULL;
        LOG_ERROR(c, "fmi2GetFMUstate: out of memory");
        return fmi2Error;
    }
    *state = st;
    return fmi2OK;
}

fmi2Status fmi2SetFMUstate(fmi2Component comp, fmi2FMUstate state)
{
    Instance *c = mast_live(comp);
    State *st = state;
    Snapshot copy = {0};
    if (!c) return fmi2Error;
    if (!st || st->owner != M) {
        LOG_ERROR(c, "fmi2SetFMUstate: not an FMU state of %s", M->identifier);
        return fmi2Error;
    }
    if (!copy_snapshot(&copy, &st->s)) {
        free_snapshot(&copy);
        LOG_ERROR(c, "fmi2SetFMUstate: out of memory");
        return fmi2Error;
    }
    free_snapshot(&c->s);
    c->s = copy;
    return fmi2OK;
}

fmi2Status fmi2FreeFMUstate(fmi2Component comp, fmi2FMUstate *state)
{
    (void)comp;
    if (!state || !*state) return fmi2OK;
    State *st = *state;
    if (st->owner == M) {
        free_snapshot(&st->s);
        free(st);
    }
    *state = NULL;
    return fmi2OK;
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component comp, fmi2FMUstate state, size_t *size)
{
    Instance *c = mast_live(comp);
    (void)state; (void)size;
    if (c) LOG_ERROR(c, "fmi2SerializedFMUstateSize: not supported (canSerializeFMUstate=false)");
    return fmi2Error;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component comp, fmi2FMUstate state, fmi2Byte data[], size_t size)
{
    Instance *c = mast_live(comp);
    (void)state; (void)data; (void)size;
    if (c) LOG_ERROR(c, "fmi2SerializeFMUstate: not supported (canSerializeFMUstate=false)");
    return fmi2Error;
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component comp, const fmi2Byte data[], size_t size, fmi2FMUstate *state)
{
    Instance *c = mast_live(comp);
    (void)data; (void)size; (void)state;
    if (c) LOG_ERROR(c, "fmi2DeSerializeFMUstate: not supported (canSerializeFMUstate=false)");
    return fmi2Error;
}
