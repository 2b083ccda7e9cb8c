/* The fixed interface of a native controller (mast build --native): what the runtime mast_controller.c runs
 * (fmus/controller/model.py's DriveController: initialize, evaluate once per communication point, do_step over
 * the ticks inside a step, and the messages of their failures; the feed-forward and computed-torque controllers'
 * inverse model, InverseModel.currents; the workspace controller's direct kinematics, WorkspaceController._wsdk)
 * and what the generator writes for one controller: its sizes and its state's layout in config.h
 * (fmus/controller/tick.py's layout for CTRL_N axes), the traced kernels, the translated tick and the tables in
 * <id>_model.c.
 *
 * Variables (value references): inputs <c>_cmd (c: the mechanism's coordinates), rho_k, omega_m_k (k = 1..CTRL_N),
 * outputs rho_cmd_k, omega_cmd_k, i_cmd_k, then the parameters (the connector convention of docs/interfaces.md).
 */
#ifndef MAST_CONTROLLER_H
#define MAST_CONTROLLER_H

#include "config.h"
#include "mast_mechanism.h"
#include "mast_model.h"

/* config.h defines the sizes of the controller's kinematic model (its description's, mast_mechanism.h: MECH_*;
 * its cold start, lengths and checks of a parameter set are the native mechanism's, mast_mechanism.c) and:
 *   CTRL_N             the axes (the mechanism's coordinates, one linear drive each)
 *   CTRL_SIZE          the state's doubles (tick.layout(CTRL_N, MECH_NP)["size"])
 *   CTRL_<FIELD>       the offset of each field of that layout (CTRL_T0, CTRL_T_CUR, CTRL_FAILED, ...)
 *   CTRL_INVERSE_MODEL 1: the controller has an inverse model (feed-forward, computed torque)
 *   CTRL_WORKSPACE     1: the controller measures the pose by the direct kinematics (workspace control)
 *   CTRL_FORCES_OUT    the doubles the traced forces write (at least CTRL_N)
 *   CTRL_MODEL_FAILED, CTRL_DK_FAILED   the tick's failure codes (tick.MODEL_FAILED, tick.DK_FAILED) */

/* the instance's state: plain data (the wrapper snapshots it), S first (the inverse model's direct kinematics
 * reaches the message buffer from S) */
typedef struct {
    double S[CTRL_SIZE];       /* the tick's state (tick.layout) */
    double before[CTRL_SIZE];  /* S before the laws of the tick evaluated */
    double evaluated;          /* the tick whose laws ran at its communication point, or -1 */
    char text[1024];           /* the message of a failed direct kinematics */
    mast_mechanism_state mech; /* the kinematic model's parameters, cold start and lengths (mast_mechanism.c) */
} mast_controller_state;

/* the functions below are the model's own: hidden from the library's exports, so that the runtime's calls into
 * the generated tick are direct (no PLT) and the compiler may inline between them */
#if defined(__GNUC__) && !defined(_WIN32)
#pragma GCC visibility push(hidden)
#endif

/* ---- generated (<id>_model.c) */
/* the numbers the parameters fix, into S (schedule, transmission, kinematic model, gains; DriveController._constants) */
void ctrl_constants(const mast_parameters *p, double *S);
/* the translated tick (tick.tick_sources): 0, or a failure code (-check of the inverse kinematics, or
 * CTRL_MODEL_FAILED / CTRL_DK_FAILED); R, CUR, QM: CTRL_N doubles, JK: CTRL_N + CTRL_N^2 */
int ctrl_start(double *values, double *S, double *R);
int ctrl_laws(double *values, double *S, double *R, double *CUR, double *QM, double *JK, double n);
int ctrl_steps(double *values, double *S, double *R, double *CUR, double *QM, double *JK, double n, double m);
/* the message of the traced kernels' check ``check`` */
const char *ctrl_why(int check);
/* one attempt of the direct kinematics (mast_dk) of rho from q (into q), dq/drho into J; the message of a failure
 * into msg */
int ctrl_dk(const double *rho, double *S, double *q, double *J, char *msg, size_t size);
/* the inverse model (CTRL_INVERSE_MODEL): mechanism.model.restarted_dk, translated (calls mast_controller_dk); the
 * traced forces at q, J = dq/drho for a = (rho, rho_dot, rho_ddot) into F (0, or -check); motor_torque,
 * translated, for one axis with the actuator constants c (inverse_model.CONSTANTS but k_T) */
int ctrl_restarted_dk(double *rho, double warm, double *S, double *out);
int ctrl_forces(const double *q, const double *J, const double *a, const double *S, double *F);
double ctrl_motor_torque(double rho_dot, double rho_ddot, double F, const double *c);
extern const char *const CTRL_INPUT_NAMES[3 * CTRL_N];
extern const char *const CTRL_COORDINATES[CTRL_N];
extern const char *const CTRL_UNITS[CTRL_N];

/* ---- the runtime (mast_controller.c) */
/* DriveController._ratio: a loop's cycle time an integer multiple of T_cur (1 and msg if not) */
int mast_controller_ratio_check(const char *name, double T, double T_cur, char *msg, size_t size);
/* the inverse model's one attempt of the direct kinematics (mechanism.model.dk): from its last solution
 * (warm = 1.0) or from the description's guess; S: the instance's state, out: q, then J = dq/drho */
int mast_controller_dk(double *rho, double warm, double *S, double *out);
/* InverseModel.currents at a = (rho, rho_dot, rho_ddot) (3 CTRL_N) into out; 0, or a failure */
int mast_controller_currents(const double *a, double *S, double *out);
/* WorkspaceController._wsdk: the direct kinematics of the measured joints rho into out; 0, or a failure */
int mast_controller_wsdk(const double *rho, double *S, double *out);
int mast_controller_initialize(void *state, double *values, const mast_parameters *p, double t0, char *msg,
                               size_t size);
int mast_controller_evaluate(void *state, double *values, const mast_parameters *p, char *msg, size_t size);
int mast_controller_do_step(void *state, double *values, const mast_parameters *p, double t, double h, char *msg,
                            size_t size);

#if defined(__GNUC__) && !defined(_WIN32)
#pragma GCC visibility pop
#endif

#endif
