/* The native drive (mast_drive.c): fmus/actuator/drive.py's DriveActuatorBlock, the native actuator
 * (mast_actuator.h) run T_cur at a time behind the current loop's PI. Inputs i_cmd [A], F [N], M_carried [kg];
 * outputs the axis' (rho ... m_drive), then u [V]. config.h adds ACT_VR_K_PC, ACT_VR_K_IC, ACT_VR_T_CUR, ACT_VR_U_MAX. */
#ifndef MAST_DRIVE_H
#define MAST_DRIVE_H

#include "mast_actuator.h"

/* the axis' outputs (values ACT_INPUTS.. of its own) */
#define MAST_AXIS_OUTPUTS 12

typedef struct {
    mast_actuator_state a;
    double av[ACT_INPUTS + MAST_AXIS_OUTPUTS];   /* the axis' values: u, F, M_carried, then its outputs */
    double x_c, u, gains[3];
} mast_drive_state;

/* ---- generated: the model's own functions, translated (fmus/actuator/drive.py) */
int act_pi_step(double e, double x, double k_p, double k_iT, double limit, double offset, double *out);
int act_current_gains(double k_pc, double k_ic, double T_cur, double u_max, double *out);

/* ---- the runtime */
int mast_drive_initialize(void *state, double *values, const mast_parameters *p, double t0, char *msg, size_t size);
int mast_drive_do_step(void *state, double *values, const mast_parameters *p, double t, double h, char *msg,
                       size_t size);

#endif
