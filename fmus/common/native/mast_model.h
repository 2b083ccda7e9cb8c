/* What the one FMI 2.0 wrapper (fmi2_wrapper.c) needs from a generated model file (mast build --native).
 *
 * Value references: 0 .. n_io-1 are the model's inputs then outputs (all Real; ``values`` below),
 * then its parameters, in the order and with the types of the modelDescription.xml (the same
 * variables as the Python FMU). A model keeps its internal state in one block of plain data
 * (``state_size`` bytes, no pointers), so the wrapper snapshots it with memcpy (get/set FMU state).
 */
#ifndef MAST_MODEL_H
#define MAST_MODEL_H

#include <stddef.h>

typedef enum { MAST_REAL, MAST_INTEGER, MAST_STRING } mast_type;
typedef enum { MAST_INPUT, MAST_OUTPUT, MAST_PARAMETER } mast_causality;

/* the kind of failure a model reports, named as the Python model's exception class */
enum { MAST_OK = 0, MAST_PARAMETER_ERROR = 1, MAST_MODEL_ERROR = 2, MAST_KINEMATICS_ERROR = 3, MAST_SINGULARITY_ERROR = 4 };

typedef struct {
    const char *name;
    mast_type type;
    mast_causality causality;
    double real_start;
    int integer_start;
    const char *string_start;
} mast_variable;

/* Parameters as the host set them: every array is indexed by value reference. */
typedef struct {
    const double *real;
    const int *integer;
    const char *const *string;
} mast_parameters;

typedef struct {
    const char *identifier;
    const char *guid;
    int n_variables;
    const mast_variable *variables;
    int n_inputs;
    int n_io;
    size_t state_size;
    /* 0, or an error code with ``msg`` filled (the parameter named, what was expected) */
    int (*check)(const mast_parameters *p, char *msg, size_t size);
    /* outputs at t0 from the current inputs and the initial state */
    int (*initialize)(void *state, double *values, const mast_parameters *p, double t0, char *msg, size_t size);
    /* advance from t to t + h with the inputs held; outputs at t + h */
    int (*do_step)(void *state, double *values, const mast_parameters *p, double t, double h, char *msg, size_t size);
    /* NULL, or direct feedthrough (Block.evaluate): the outputs at the communication point from the inputs
       just set in step mode, once per point (called again there, it starts over from the state before) */
    int (*evaluate)(void *state, double *values, const mast_parameters *p, char *msg, size_t size);
    /* the largest step doStep takes (a doStep in bounded time): max_ticks of the cycle-time parameter (its value
       reference; Block.CYCLE_TIME), or max_step seconds when cycle_time is -1 (fmus/common/slave.py, MAX_STEP_*) */
    int cycle_time;
    double max_ticks, max_step;
} mast_model;

extern const mast_model MAST_MODEL;

#endif
