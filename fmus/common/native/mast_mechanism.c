/* The native mechanism (mast_mechanism.h): fmus/mechanism/model.py's MechanismBlock for any description, its
 * sizes from config.h and its kernels and tables from the generated <id>_model.c. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "mast_mechanism.h"
#include "mast_native.h"

/* mast_dk's view of the traced inverse kinematics with its Jacobian */
static int ikjac_of(const void *model, const double *q, double *out)
{
    mast_mechanism_state *s = (mast_mechanism_state *)model;
    return mech_ikjac((double *)q, s->P, s->K_ikjac, out);
}

int mast_mechanism_dk(double *rho, double warm, double *S, double *out)
{
    mast_mechanism_state *s = (mast_mechanism_state *)S;
    if (warm == 1.0) {
        for (int k = 0; k < MECH_N; k++) out[k] = s->q[k];
    } else {
        mech_guess(rho, s->P, out);
    }
    mast_dk_problem dk = {MECH_N, ikjac_of, s, mech_why, MECH_COORDINATES, s->lengths, MECH_MARGIN, MECH_COND_LIMIT,
                          1e-12, 50};
    return mast_dk(&dk, rho, out, out + MECH_N, s->why_text, sizeof s->why_text);
}

/* MechanismBlock's message of a failure at rho (the inputs' first MECH_N) */
static int kinematics_error(const double *values, double t, const char *what, char *msg, size_t size)
{
    char v[40], rho[MECH_N * 42] = "";
    for (int k = 0; k < MECH_N; k++) {
        if (k) strcat(rho, ", ");
        strcat(rho, mast_repr(values[k], v, sizeof v));
    }
    snprintf(msg, size, "at t = %s s, rho = (%s) m: %s", mast_repr(t, v, sizeof v), rho, what);
    return MAST_KINEMATICS_ERROR;
}

/* MechanismBlock._compute: direct kinematics (restarted_dk), then the forces and the pose */
static int compute(mast_mechanism_state *s, double *values, const mast_parameters *p, double t, char *msg,
                   size_t size)
{
    char v[40], w[40];
    double qJ[MECH_N + MECH_N * MECH_N], *q = qJ, *J = qJ + MECH_N;
    for (int k = 0; k < 3 * MECH_N; k++) {
        if (!isfinite(values[k])) {
            snprintf(msg, size, "input '%s' = %s is not finite at t = %s s", MECH_INPUT_NAMES[k],
                     mast_repr(values[k], v, sizeof v), mast_repr(t, w, sizeof w));
            return MAST_MODEL_ERROR;
        }
    }
    int code = mech_restarted_dk(values, s->warm ? 1.0 : 0.0, (double *)s, qJ);
    if (code) {
        kinematics_error(values, t, s->why_text, msg, size);
        return code;          /* MAST_KINEMATICS_ERROR, or MAST_SINGULARITY_ERROR: it stays one */
    }
    if (MECH_ATTACHED_VR < 0 || p->integer[MECH_ATTACHED_VR]) {
        code = mech_dynamics(q, J, values + MECH_N, values + 2 * MECH_N, s->P, s->K_dynamics, values + 3 * MECH_N);
    } else {   /* attached = 0: no force, the kinematics of the mechanism */
        for (int k = 0; k < MECH_N; k++) values[3 * MECH_N + k] = 0.0;
        code = mech_pose(q, s->P, s->K_pose, values + 4 * MECH_N);
    }
    if (code) return kinematics_error(values, t, mech_why(-code), msg, size);
    for (int k = 0; k < MECH_N; k++) s->q[k] = q[k];
    s->warm = 1;
    return MAST_OK;
}

int mast_mechanism_initialize(void *state, double *values, const mast_parameters *p, double t0, char *msg,
                              size_t size)
{
    mast_mechanism_state *s = state;
    s->warm = 0;
    s->t0 = t0;
    for (int k = 0; k < MECH_NP; k++) s->P[k] = MECH_TRACED_VR[k] >= 0 ? p->real[MECH_TRACED_VR[k]] : 0.0;
    mech_ikjac_invariants(s->P, s->K_ikjac);
    mech_dynamics_invariants(s->P, s->K_dynamics);
    mech_pose_invariants(s->P, s->K_pose);
    for (int k = 0; k < MECH_N; k++)
        s->lengths[k] = MECH_LENGTH_PARAMETER[k] >= 0 ? s->P[MECH_LENGTH_PARAMETER[k]] : MECH_LENGTH_VALUE[k];
    return compute(s, values, p, t0, msg, size);
}

/* MechanismBlock.do_step: recomputed when the step [t, t + h) holds an update instant t0 + k T_mech, else held */
int mast_mechanism_do_step(void *state, double *values, const mast_parameters *p, double t, double h, char *msg,
                           size_t size)
{
    mast_mechanism_state *s = state;
    double T = MECH_UPDATE_VR < 0 ? 0.0 : p->real[MECH_UPDATE_VR];
    if (T > 0.0) {
        double eps = 1e-6 * (h < T ? h : T);
        if (s->t0 + ceil((t - s->t0 - eps) / T) * T >= t + h - eps) return MAST_OK;
    }
    return compute(state, values, p, t + h, msg, size);
}
