/* The fixed interface of a native actuator (mast build --native): what the runtime mast_actuator.c runs
 * (fmus/actuator/model.py's ActuatorBlock: the exact discretisation of each step size, the step kernels, the
 * torque measurement) and, for a drive (fmus/actuator/drive.py's DriveActuatorBlock), the current loop around
 * it (mast_drive.c); what the generator writes for one parameter set: the sizes and the value references in
 * config.h, the kernels and the tables in <id>_model.c.
 *
 * The axis' values: inputs u [V], F [N], M_carried [kg], then its outputs (rho, rho_dot, rho_ddot, theta_m, omega_m,
 * i_m, tau_m, tau_meas, F_drive, F_drive_dot, F_drive_ddot, m_drive). Every parameter is read at run time, n_dof too:
 * one chain per n_dof of ACTUATOR_CHAINS.
 */
#ifndef MAST_ACTUATOR_H
#define MAST_ACTUATOR_H

#include "config.h"
#include "mast_model.h"

/* config.h defines:
 *   ACT_NX, ACT_NQ, ACT_NH   the largest chain's state, parameter numbers and step numbers
 *   ACT_N_REALS              the Real parameters the chains' numbers are computed from (ACTUATOR_REAL_VR)
 *   ACT_N_LISTS              the most numbers of the chain lists J_chain, K_chain, C_chain together (3 n_dof - 2)
 *   ACT_KEPT, ACT_SENSOR_SAMPLES   step sizes whose discretisation an instance keeps; the delay line's length
 *   ACT_N_MAX                the chains 1..ACT_N_MAX every native actuator carries (more: ACTUATOR_CHAINS)
 *   ACT_Q_<NAME>             the slots in Q of the kernel constants the runtime reads (the same in every chain)
 *   ACT_VR_<NAME>            the value references of the parameters it reads */

/* one step of a kernel: 0, or 1, 2 (input u, F not finite), 3 (diverged), 4 (carriage out of its stroke), 5 (input
 * M_carried not a finite mass >= 0) */
typedef int (*mast_actuator_step)(double *values, double *x, double *H, double *Q, double m);

/* a kernel of a chain: its structure (friction 0 none, 1 Coulomb, 2 Stribeck; ripple; backlash), where its friction
 * numbers start in H (in contact f0, in the gap f1) and where its substep stands in H (hs) */
typedef struct {
    mast_actuator_step step;
    int friction, ripple, backlash, f0, f1, hs;
} mast_actuator_kernel;

/* where the axis' inputs end and its outputs tau_m, tau_meas, F_drive stand among its values (ActuatorBlock) */
#define ACT_INPUTS 3
#define ACT_TAU_M 9
#define ACT_TAU_MEAS 10
#define ACT_F_DRIVE 11

/* a chain n_dof = N: its numbers from the Real parameters and the chain lists (kernel_constants, the state
 * matrices, the backlash's systems: traced), its kernels (first, count in ACTUATOR_KERNELS) and the slots in Q
 * of A (2N+1 x 2N+1), B (2N+1 x 2), J, K, the backlash's Ag and B3 (N = 2; else -1), B[omega_N, tau_L] (bw)
 * and the backlash's half gap (hb; -1 without) */
typedef struct {
    int N;
    int (*constants)(double *reals, double *lists, double *Q);
    int first, count;
    int A, B, J, K, Ag, B3, bw, hb;
} mast_actuator_chain;

/* ---- generated (<id>_model.c) */
extern const mast_actuator_kernel ACTUATOR_KERNELS[];
extern const mast_actuator_chain ACTUATOR_CHAINS[];
extern const int ACTUATOR_N_CHAINS;
extern const int ACTUATOR_REAL_VR[ACT_N_REALS];
/* the model's own functions, translated (fmus/actuator/model.py, sensor.py) */
int act_friction_coulomb(double b, double tau_c, double omega_c, double tau_s, double omega_s, double *out);
int act_friction_stribeck(double b, double tau_c, double omega_c, double tau_s, double omega_s, double *out);
int act_filter_coefficients(double T, double h, double *out);
int act_delay_split(double delay, double h, double *out);
int act_relayout(double *old, double size, double head, double *line, double L, double u0);
int act_measurement_step(double u, double *line, double head, double L, double n, double phi, double e, double c,
                         double d, double y, double u_prev, double *out);
int act_substep_rule(double omega_max, double h, double backlash, double tau_s, double omega_s, double *out);
double act_substeps_enough(double b, double fall, double m);

/* ---- the runtime (mast_actuator.c) */
typedef struct { double m; double H[ACT_NH]; } mast_actuator_disc;

typedef struct {
    int N, bw;                    /* the chain (n_dof) and the slot in Q of its B[omega_N, tau_L] */
    int chain;                    /* its row of ACTUATOR_CHAINS */
    double x[ACT_NX];
    double Q[ACT_NQ];             /* the parameters' numbers: kernel_constants, A, B, the chain */
    double omega_max;
    int variant, n_disc, next_disc, last;   /* last: the slot of the last step's h (ActuatorBlock._h) */
    double h_last;
    double key[ACT_KEPT];
    mast_actuator_disc disc[ACT_KEPT];
    int sensor, s_n, s_len, s_head;
    double s_h, s_e, s_c, s_d, s_phi, s_y, s_uprev, s_u0;
    double hist[ACT_SENSOR_SAMPLES];
} mast_actuator_state;

/* ActuatorBlock.__init__'s checks after the parameters' ranges (the same messages): the stroke, n_dof among
 * the chains, the chain lists, backlash only with n_dof = 2 */
int mast_actuator_check(const mast_parameters *p, char *msg, size_t size);
int mast_actuator_initialize(void *state, double *values, const mast_parameters *p, double t0, char *msg,
                             size_t size);
int mast_actuator_do_step(void *state, double *values, const mast_parameters *p, double t, double h, char *msg,
                          size_t size);

/* do_step in two parts, for the drive's ticks of one step size: the discretisation of h (the last step's, or one
 * kept or made: ActuatorBlock._select; NULL with msg), then the step with it (inline: the kernel, then
 * mast_actuator_finish only for a failure or the torque measurement) */
mast_actuator_disc *mast_actuator_select(mast_actuator_state *s, double h, char *msg, size_t size);
/* ActuatorBlock.condenses: its fastest chain mode turns at most ACT_COUPLING_PHASE over an exchange of h */
static inline int mast_actuator_condenses(const mast_actuator_state *s, double h)
{
    return s->omega_max * h <= ACT_COUPLING_PHASE;
}
int mast_actuator_finish(mast_actuator_state *s, double *values, int code, const mast_parameters *p, double t, double h,
                         char *msg, size_t size);
static inline int mast_actuator_advance(mast_actuator_state *s, mast_actuator_disc *d, double *values,
                                        const mast_parameters *p, double t, double h, char *msg, size_t size)
{
    int code = ACTUATOR_KERNELS[s->variant].step(values, s->x, d->H, s->Q, d->m);
    return code || s->sensor ? mast_actuator_finish(s, values, code, p, t, h, msg, size) : MAST_OK;
}

#endif
