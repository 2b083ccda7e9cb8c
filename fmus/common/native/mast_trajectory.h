/* The fixed interface of the native trajectory (mast_trajectory.c): fmus/trajectory/model.py's TrajectoryBlock,
 * the sine about the home pose, output k = home_k + amplitude_k sin(2 pi frequency (t - t0)), its parameters
 * read at run time (tunable as in the Python FMU); the generated <id>_model.c gives the tables. */
#ifndef MAST_TRAJECTORY_H
#define MAST_TRAJECTORY_H

#include "mast_model.h"

typedef struct { double t0; } mast_trajectory_state;

/* ---- generated: the outputs (value references 0..TRAJECTORY_N-1) and their parameters' value references */
extern const int TRAJECTORY_N;
extern const int TRAJECTORY_HOME_VR[];
extern const int TRAJECTORY_AMPLITUDE_VR[];
extern const int TRAJECTORY_FREQUENCY_VR;

/* ---- the runtime */
int mast_trajectory_initialize(void *state, double *values, const mast_parameters *p, double t0, char *msg,
                               size_t size);
int mast_trajectory_do_step(void *state, double *values, const mast_parameters *p, double t, double h, char *msg,
                            size_t size);

#endif
