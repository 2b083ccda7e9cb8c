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
 *   MECH_NG           the numbers the cold start takes from the parameters (Described.guess_rule; at least 1)
 *   MECH_GUESS_RULE   1: the cold start is mech_guess_rule(rho, numbers), 0: the numbers are the cold start
 *   MECH_NL           the platform points the coordinates' lengths come from (Described.lengths; 0: constants)
 *   MECH_NB           the bodies the parameters make (Described.body_specs; 0: none, their numbers constants)
 *   MECH_NV           the numbers the description's checks compare and show (designs.CHECKS; at least 1)
 *   MECH_NCHECK       those checks (designs.CHECKS of this mechanism)
 *   MECH_ATTACHED_VR  the value reference of the Integer parameter 'attached' (0: kinematics only), or -1
 *   MECH_KINEMATICS_VR  the value reference of the String parameter 'kinematics', or -1
 *   MECH_UPDATE_VR    the value reference of the Real parameter 'T_mech' (the full update's period), or -1 (every
 *                     step)
 *   MECH_MARGIN       Engine.margin [m/m];  MECH_COND_LIMIT  Engine.cond_limit */

/* the instance's state: plain data (the wrapper snapshots it), q first (restarted_dk's S) */
typedef struct {
    double q[MECH_N];                    /* the last solution of the direct kinematics */
    double P[MECH_NP];                   /* the traced parameters as the host set them */
    double K_ikjac[MECH_NK_IKJAC];       /* what they alone fix, per kernel (computed at initialisation) */
    double K_dynamics[MECH_NK_DYNAMICS];
    double K_pose[MECH_NK_POSE];
    double G[MECH_NG];                   /* the cold start's numbers (mech_guess_numbers) */
    double lengths[MECH_N];              /* Engine.lengths [m]: the singularity margins compare motions */
    int warm;                            /* q is a solution to start from */
    double t0;                           /* the start time: full updates at t0 + k T_mech (MechanismBlock.do_step) */
    double M[MECH_N * MECH_N];           /* the last full update's joint-space mass matrix (row-major) and bias */
    double b[MECH_N];                    /* (Engine.inertial): between updates F = M rho_ddot + b */
    int condensed;                       /* W and D hold the condensed interface of M (coupling.condense) */
    int latched;                         /* the mass ratio reached MECH_CONDENSE_ABOVE in this run */
    double W[MECH_N * MECH_N];           /* the weights of the other drives' forces (row-major, zero diagonal) */
    double D[MECH_N];                    /* the masses the drives carry */
    char why_text[1024];                 /* the message of a failed direct kinematics */
} mast_mechanism_state;

/* ---- generated (<id>_model.c): the engine's traced kernels, split by what the parameters alone fix
 * (translate.split_invariants); q (MECH_N), J = dq/drho (MECH_N x MECH_N), P (MECH_NP), K: the kernel's
 * invariants. 0, or -N when the description's check N failed (mech_why(N): its message). */
int mech_ikjac_invariants(double *P, double *K);
int mech_ikjac(double *q, double *P, double *K, double *out);            /* rho (n), then drho/dq (n x n) */
int mech_dynamics_invariants(double *P, double *K);
int mech_dynamics(double *q, double *J, double *rho_dot, double *rho_ddot, double *P, double *K,
                  double *out);    /* F (n), the pose (6), M (n x n), b (n): Engine.inertial */
int mech_pose_invariants(double *P, double *K);
int mech_pose(double *q, double *P, double *K, double *out);             /* the pose (6) */
int mech_restarted_dk(double *rho, double warm, double *S, double *out);  /* mechanism.model.restarted_dk */
const char *mech_why(int check);
/* what the parameters alone give (traced from the description with the parameters P as inputs) */
int mech_guess_numbers(double *P, double *out);   /* the cold start's numbers (MECH_NG) */
int mech_platform(double *P, double *out);        /* the platform points s_k (3 MECH_NL, platform frame [m]) */
int mech_bodies(double *P, double *out);          /* per body: mass [kg], inertia (9, row-major) [kg m^2] */
int mech_check_values(double *P, double *out);    /* the numbers the checks compare and show (MECH_NV) */
#if MECH_GUESS_RULE
int mech_guess_rule(double *rho, double *G, double *out);  /* the cold start q of rho (legs.py, translated) */
#endif
/* per traced parameter, its Real value reference, or -1 when this FMU has no such parameter (then 0.0) */
extern const int MECH_TRACED_VR[MECH_NP];
/* per coordinate: 1 when its length is the platform's radius (the largest |s_k|), else MECH_LENGTH_VALUE's */
extern const int MECH_LENGTH_RADIUS[MECH_N];
extern const double MECH_LENGTH_VALUE[MECH_N];
extern const char *const MECH_COORDINATES[MECH_N];
/* the inputs per drive (mechanism.model.INPUT_NAMES: rho, rho_dot, rho_ddot, F_drive, F_drive_dot, F_drive_ddot,
 * m_drive): the outputs F start at MECH_KINDS * MECH_N, then the pose, Fc and Mc (mechanism.model.Variables) */
#define MECH_KINDS 7
extern const char *const MECH_INPUT_NAMES[MECH_KINDS * MECH_N];
/* the mechanism's name (the parameter 'kinematics' it computes), and every name that parameter may take */
extern const char *const MECH_NAME;
extern const char *const MECH_KINEMATICS[];
extern const int MECH_NKINEMATICS;

/* a body the parameters make (engine.Body's checks, with the Python model's messages) */
typedef struct {
    const char *name;
    int optional;          /* left out when its mass and inertia are 0 */
    const char *mass_by;   /* the parameters its mass comes from, as the message names them */
    const char *inertia_by;
} mast_mechanism_body;
extern const mast_mechanism_body MECH_BODY[];

/* a check of a parameter set (designs.Check): its numbers are mech_check_values' */
typedef struct {
    int assembles;       /* 0: value a < value b; 1: the mechanism assembles at its cold start for every joint 0 */
    int regular;         /* assembles: with an invertible Jacobian too */
    int when;            /* -1: always; else the value that decides whether it applies */
    int when_zero;       /* 1: it applies when that value is 0, 0: when it is not */
    int a, b;
    int n_shown;
    int shown[6];        /* the values the message shows, in order */
    const char *format;  /* a %s per value shown, then (assembles) a %s for why the pose is refused */
} mast_parameter_check;
extern const mast_parameter_check MECH_CHECK[];

/* ---- the runtime (mast_mechanism.c; a native controller's kinematic model runs on it too, mast_controller.c) */
/* what the parameters the host set alone fix, into s: the traced parameters P, the kernels' invariants, the cold
 * start's numbers, the coordinates' lengths (Engine.lengths) */
void mast_mechanism_setup(mast_mechanism_state *s, const mast_parameters *p);
/* the description's cold start q of the direct kinematics for rho (Described.guess) */
void mast_mechanism_guess(const mast_mechanism_state *s, double *rho, double *q);
/* mechanism.model.dk: one attempt of the direct kinematics of rho from the last solution (warm = 1.0) or from
 * the description's cold start; S: the instance, out: q, then J = dq/drho; a failure's message in why_text */
int mast_mechanism_dk(double *rho, double warm, double *S, double *out);
/* MAST_OK, or MAST_PARAMETER_ERROR with ``msg``: the parameter 'kinematics', the bodies, the checks (designs.py) */
int mast_mechanism_check(const mast_parameters *p, char *msg, size_t size);
int mast_mechanism_initialize(void *state, double *values, const mast_parameters *p, double t0, char *msg,
                              size_t size);
int mast_mechanism_do_step(void *state, double *values, const mast_parameters *p, double t, double h, char *msg,
                           size_t size);

#endif
