/* The fixed interface of a native mechanism model (mast build --native): what the runtime mast_mechanism.c
 * runs (MechanismBlock: direct kinematics, then the forces and the pose) and what the generator writes for
 * one mechanism description: the sizes in config.h, the traced kernels and the tables in <id>_model.c.
 *
 * Variables (value references): inputs rho_k, rho_dot_k, rho_ddot_k (k = 1..MECH_N), outputs F_k, then the
 * pose x, y, z, psi, theta, phi, then the parameters (the connector convention of docs/native.md).
 */
#ifndef MAST_MECHANISM_H
#define MAST_MECHANISM_H

#include "config.h"
#include "mast_dk.h"
#include "mast_model.h"

/* config.h defines:
 *   MECH_N            the drives = the coordinates (Engine.n)
 *   MECH_NP           the traced parameters (Engine.parameters; at least 1: a slot no kernel reads)
 *   MECH_NK_IKJAC, MECH_NK_DYNAMICS, MECH_NK_POSE   what the parameters alone fix of each kernel (at least 1)
 *   MECH_ATTACHED_VR  the value reference of the Integer parameter 'attached' (0: kinematics only), or -1
 *   MECH_UPDATE_VR    the value reference of the Real parameter 'T_mech' (the update period), or -1 (every step)
 *   MECH_MARGIN       Engine.margin [m/m];  MECH_COND_LIMIT  Engine.cond_limit */

/* the instance's state: plain data (the wrapper snapshots it), q first (restarted_dk's S) */
typedef struct {
    double q[MECH_N];                    /* the last solution of the direct kinematics */
    double P[MECH_NP];                   /* the traced parameters as the host set them */
    double K_ikjac[MECH_NK_IKJAC];       /* what they alone fix, per kernel (computed at initialisation) */
    double K_dynamics[MECH_NK_DYNAMICS];
    double K_pose[MECH_NK_POSE];
    double lengths[MECH_N];              /* Engine.lengths [m]: the singularity margins compare motions */
    int warm;                            /* q is a solution to start from */
    double t0;                           /* the start time: update instants t0 + k T_mech (MechanismBlock.do_step) */
    char why_text[1024];                 /* the message of a failed direct kinematics */
} mast_mechanism_state;

/* ---- generated (<id>_model.c): the engine's traced kernels, split by what the parameters alone fix
 * (translate.split_invariants); q (MECH_N), J = dq/drho (MECH_N x MECH_N), P (MECH_NP), K: the kernel's
 * invariants. 0, or -N when the description's check N failed (mech_why(N): its message). */
int mech_ikjac_invariants(double *P, double *K);
int mech_ikjac(double *q, double *P, double *K, double *out);            /* rho (n), then drho/dq (n x n) */
int mech_dynamics_invariants(double *P, double *K);
int mech_dynamics(double *q, double *J, double *rho_dot, double *rho_ddot, double *P, double *K,
                  double *out);                                          /* F (n), then the pose (6) */
int mech_pose_invariants(double *P, double *K);
int mech_pose(double *q, double *P, double *K, double *out);             /* the pose (6) */
int mech_guess(double *rho, double *P, double *out);                     /* the description's cold start q */
int mech_restarted_dk(double *rho, double warm, double *S, double *out);  /* mechanism.model.restarted_dk */
const char *mech_why(int check);
/* per traced parameter, its Real value reference, or -1 when this FMU has no such parameter (then 0.0) */
extern const int MECH_TRACED_VR[MECH_NP];
/* per coordinate, the traced parameter that is its length, or -1: its length is MECH_LENGTH_VALUE's */
extern const int MECH_LENGTH_PARAMETER[MECH_N];
extern const double MECH_LENGTH_VALUE[MECH_N];
extern const char *const MECH_COORDINATES[MECH_N];
extern const char *const MECH_INPUT_NAMES[3 * MECH_N];

/* ---- the runtime (mast_mechanism.c) */
/* mechanism.model.dk: one attempt of the direct kinematics of rho from the last solution (warm = 1.0) or from
 * the description's cold start; S: the instance, out: q, then J = dq/drho; a failure's message in why_text */
int mast_mechanism_dk(double *rho, double warm, double *S, double *out);
int mast_mechanism_initialize(void *state, double *values, const mast_parameters *p, double t0, char *msg,
                              size_t size);
int mast_mechanism_do_step(void *state, double *values, const mast_parameters *p, double t, double h, char *msg,
                           size_t size);

#endif
