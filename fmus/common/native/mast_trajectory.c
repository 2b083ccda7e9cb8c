/* The native trajectory (mast_trajectory.h). */
#include <math.h>
#include <stdio.h>

#include "mast_native.h"
#include "mast_trajectory.h"

/* TrajectoryBlock._write */
static int write(const mast_trajectory_state *s, double *values, const mast_parameters *p, double t, char *msg,
                 size_t size)
{
    char v[40];
    if (!isfinite(t)) {
        snprintf(msg, size, "time t = %s s is not finite", mast_repr(t, v, sizeof v));
        return MAST_MODEL_ERROR;
    }
    double omega = 2.0 * 3.141592653589793 * p->real[TRAJECTORY_FREQUENCY_VR];   /* 2.0 * math.pi * frequency */
    double sn = sin(omega * (nearbyint((t - s->t0) / 1e-9) * 1e-9));   /* RESOLUTION: whole nanoseconds */
    for (int k = 0; k < TRAJECTORY_N; k++)
        values[k] = p->real[TRAJECTORY_HOME_VR[k]] + p->real[TRAJECTORY_AMPLITUDE_VR[k]] * sn;
    return MAST_OK;
}

int mast_trajectory_initialize(void *state, double *values, const mast_parameters *p, double t0, char *msg,
                               size_t size)
{
    mast_trajectory_state *s = state;
    s->t0 = t0;
    return write(s, values, p, t0, msg, size);
}

int mast_trajectory_do_step(void *state, double *values, const mast_parameters *p, double t, double h, char *msg,
                            size_t size)
{
    return write(state, values, p, t + h, msg, size);
}
