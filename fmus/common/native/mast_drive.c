/* The native drive (mast_drive.h). */
#include <math.h>
#include <stdio.h>

#include "mast_drive.h"
#include "mast_native.h"

#define I_M (ACT_INPUTS + 5)   /* the axis' output i_m among its values (drive.I_M) */

static int command_error(const double *values, double t, char *msg, size_t size)
{
    char v[40];
    snprintf(msg, size, "input 'i_cmd' = %s at t=%.9g s is not finite", mast_repr(values[0], v, sizeof v), t);
    return MAST_MODEL_ERROR;
}

static void outputs(const mast_drive_state *s, double *values)
{
    for (int k = ACT_INPUTS; k < ACT_INPUTS + MAST_AXIS_OUTPUTS; k++) values[k] = s->av[k];
    values[ACT_INPUTS + MAST_AXIS_OUTPUTS] = s->u;
}

int mast_drive_initialize(void *state, double *values, const mast_parameters *p, double t0, char *msg, size_t size)
{
    mast_drive_state *s = state;
    if (!isfinite(values[0])) return command_error(values, t0, msg, size);
    act_current_gains(p->real[ACT_VR_K_PC], p->real[ACT_VR_K_IC], p->real[ACT_VR_T_CUR], p->real[ACT_VR_U_MAX],
                      s->gains);
    s->x_c = 0.0; s->u = 0.0;
    s->av[0] = 0.0; s->av[1] = values[1]; s->av[2] = values[2];
    int code = mast_actuator_initialize(&s->a, s->av, p, t0, msg, size);
    if (code) return code;
    outputs(s, values);
    return MAST_OK;
}

/* DriveActuatorBlock.do_step: m ticks of the PI, each followed by the axis' step */
int mast_drive_do_step(void *state, double *values, const mast_parameters *p, double t, double h, char *msg,
                       size_t size)
{
    mast_drive_state *s = state;
    char v[40], w[40];
    double T = p->real[ACT_VR_T_CUR], m = nearbyint(h / T), PI[2];
    if (m < 1.0 || fabs(h - m * T) > 1e-6 * T) {
        snprintf(msg, size, "step size h = %s s is not a positive integer multiple of T_cur = %s s",
                 mast_repr(h, v, sizeof v), mast_repr(T, w, sizeof w));
        return MAST_MODEL_ERROR;
    }
    if (!isfinite(values[0])) return command_error(values, t, msg, size);
    mast_actuator_disc *d = mast_actuator_select(&s->a, T, msg, size);     /* the same for every tick */
    if (!d) return MAST_MODEL_ERROR;
    for (int k = 0; k < (int)m; k++) {      /* the PI on i_m at this tick; its voltage from the next one */
        act_pi_step(values[0] - s->av[I_M], s->x_c, s->gains[0], s->gains[1], s->gains[2], 0.0, PI);
        s->x_c = PI[1];
        s->av[0] = s->u; s->av[1] = values[1]; s->av[2] = values[2];
        int code = mast_actuator_advance(&s->a, d, s->av, p, t + k * T, T, msg, size);
        if (code) return code;
        s->u = PI[0];
    }
    outputs(s, values);
    if (!mast_actuator_condenses(&s->a, h)) values[ACT_F_DRIVE + 3] = 0.0;
    return MAST_OK;
}
