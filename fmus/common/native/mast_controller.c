/* The native controller runtime (mast_controller.h): DriveController's life cycle around the generated tick, the
 * inverse model's and the workspace controller's direct kinematics, and the messages of their failures, for
 * CTRL_N axes. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "mast_controller.h"
#include "mast_native.h"

/* DriveController._ratio */
int mast_controller_ratio_check(const char *name, double T, double T_cur, char *msg, size_t size)
{
    char a[40], b[40];
    double ratio = T / T_cur, n = nearbyint(ratio);
    if (n < 1.0 || fabs(ratio - n) > 1e-6 * n) {
        snprintf(msg, size, "parameter '%s' = %s s must be an integer multiple of T_cur = %s s (ratio %.9g)", name,
                 mast_repr(T, a, sizeof a), mast_repr(T_cur, b, sizeof b), ratio);
        return 1;
    }
    return 0;
}

/* "(v_1, ..., v_count)": the numbers as Python's repr writes them, into text */
static const char *numbers(const double *v, int count, char *text, size_t size)
{
    char r[40];
    size_t at = 0;
    text[0] = '\0';
    for (int k = 0; k < count && at < size; k++)
        at += (size_t)snprintf(text + at, size - at, "%s%s%s", k ? ", " : "(", mast_repr(v[k], r, sizeof r),
                               k == count - 1 ? ")" : "");
    return text;
}

static int input_error(const double *values, double t, char *msg, size_t size)
{
    char v[40], w[40];
    for (int k = 0; k < 3 * CTRL_N; k++) {
        if (!isfinite(values[k])) {
            snprintf(msg, size, "input '%s' = %s is not finite at t = %s s", CTRL_INPUT_NAMES[k],
                     mast_repr(values[k], v, sizeof v), mast_repr(t, w, sizeof w));
            return MAST_MODEL_ERROR;
        }
    }
    return MAST_OK;
}

/* DriveController._failed: the inverse kinematics of the pose command (c = v unit, ...) */
static int ik_error(const double *values, double t, int check, char *msg, size_t size)
{
    char pose[80 * CTRL_N], v[40], ts[40];
    size_t at = 0;
    pose[0] = '\0';
    for (int k = 0; k < CTRL_N && at < sizeof pose; k++)
        at += (size_t)snprintf(pose + at, sizeof pose - at, "%s%s = %s %s", k ? ", " : "", CTRL_COORDINATES[k],
                               mast_repr(values[k], v, sizeof v), CTRL_UNITS[k]);
    snprintf(msg, size, "inverse kinematics of the pose command %s failed at t = %s s: %s", pose,
             mast_repr(t, ts, sizeof ts), ctrl_why(check));
    return MAST_KINEMATICS_ERROR;
}

int mast_controller_dk(double *rho, double warm, double *S, double *out)
{
    mast_controller_state *s = (mast_controller_state *)S;
    if (warm == 1.0) {
        for (int k = 0; k < CTRL_N; k++) out[k] = S[CTRL_GUESS + k];
    } else
        mast_mechanism_guess(&s->mech, rho, out);
    return ctrl_dk(rho, S, out, out + CTRL_N, s->text, sizeof s->text);
}

#if CTRL_INVERSE_MODEL
/* InverseModel.currents at a = (rho, rho_dot, rho_ddot); 0, or an error code with msg */
static int model_eval(const double *a, double *S, double *out, char *msg, size_t size)
{
    double qJ[CTRL_N + CTRL_N * CTRL_N], *q = qJ, *J = qJ + CTRL_N, F[CTRL_FORCES_OUT] = {0.0};
    if (S[CTRL_ATTACHED] != 0.0) {
        int code = ctrl_restarted_dk((double *)a, S[CTRL_WARM], S, qJ); /* rho: a[0 .. n-1] */
        if (code) {
            snprintf(msg, size, "%s", ((mast_controller_state *)S)->text);
            return code;
        }
        code = ctrl_forces(q, J, a, S, F);
        if (code) {
            snprintf(msg, size, "%s", ctrl_why(-code));
            return MAST_KINEMATICS_ERROR;
        }
        for (int k = 0; k < CTRL_N; k++) S[CTRL_GUESS + k] = q[k];
        S[CTRL_WARM] = 1.0;
    }
    for (int j = 0; j < CTRL_N; j++)
        out[j] = ctrl_motor_torque(a[CTRL_N + j], a[2 * CTRL_N + j], F[j], S + CTRL_MODEL) / S[CTRL_MODEL + CTRL_K_T];
    return 0;
}

int mast_controller_currents(const double *a, double *S, double *out)
{
    char text[1024];
    return model_eval(a, S, out, text, sizeof text);
}

static int model_error(double *S, char *msg, size_t size)
{
    double out[CTRL_N], a[3 * CTRL_N];
    char text[1024], rho[48 * CTRL_N];
    for (int k = 0; k < 3 * CTRL_N; k++) a[k] = S[CTRL_MODEL_ARGS + k];
    model_eval(a, S, out, text, sizeof text);
    snprintf(msg, size, "inverse dynamic model at rho = %s m: %s", numbers(a, CTRL_N, rho, sizeof rho), text);
    return MAST_KINEMATICS_ERROR;
}
#endif

#if CTRL_WORKSPACE
/* WorkspaceController._wsdk: from the last solution, else from the description's guess (the guess only updated
 * on success, so that dk_error fails the same way) */
static int wsdk_eval(const double *rho, double *S, double *q, char *msg, size_t size)
{
    double J[CTRL_N * CTRL_N];
    if (S[CTRL_WARM] == 1.0) {
        for (int k = 0; k < CTRL_N; k++) q[k] = S[CTRL_GUESS + k];
    } else
        mast_mechanism_guess(&((mast_controller_state *)S)->mech, (double *)rho, q);
    int code = ctrl_dk(rho, S, q, J, msg, size);
    if (code) return code;
    for (int k = 0; k < CTRL_N; k++) S[CTRL_GUESS + k] = q[k];
    S[CTRL_WARM] = 1.0;
    return 0;
}

int mast_controller_wsdk(const double *rho, double *S, double *out)
{
    char text[1024];
    return wsdk_eval(rho, S, out, text, sizeof text);
}

static int dk_error(double *S, double t, char *msg, size_t size)
{
    double q[CTRL_N];
    char text[1024], rho[48 * CTRL_N], ts[40];
    wsdk_eval(S + CTRL_MODEL_ARGS, S, q, text, sizeof text);
    snprintf(msg, size, "direct kinematics of the measured joints rho = %s m failed at t = %s s: %s",
             numbers(S + CTRL_MODEL_ARGS, CTRL_N, rho, sizeof rho), mast_repr(t, ts, sizeof ts), text);
    return MAST_KINEMATICS_ERROR;
}
#endif

int mast_controller_initialize(void *state, double *values, const mast_parameters *p, double t0, char *msg,
                               size_t size)
{
    mast_controller_state *s = state;
    double R[CTRL_N];
    for (int k = 0; k < CTRL_SIZE; k++) s->S[k] = 0.0;
    s->evaluated = -1.0;
    s->S[CTRL_T0] = t0;
    /* the kinematic model: its traced parameters and the coordinates' lengths (the arguments of the kernels) */
    mast_mechanism_setup(&s->mech, p);
    for (int k = 0; k < MECH_NP; k++) s->S[CTRL_P + k] = s->mech.P[k];
    for (int k = 0; k < CTRL_N; k++) s->S[CTRL_LENGTHS + k] = s->mech.lengths[k];
    ctrl_constants(p, s->S); /* checked by the model's check at exitInitializationMode */
    if (input_error(values, t0, msg, size)) return MAST_MODEL_ERROR;
    int code = ctrl_start(values, s->S, R);
    return code ? ik_error(values, t0, -code, msg, size) : MAST_OK;
}

/* the message of the tick's failure code (DriveController._failed) */
static int tick_error(mast_controller_state *s, double *values, int code, char *msg, size_t size)
{
    double T = s->S[CTRL_T_CUR], t0 = s->S[CTRL_T0];
#if CTRL_INVERSE_MODEL
    if (code == CTRL_MODEL_FAILED) return model_error(s->S, msg, size);
#endif
#if CTRL_WORKSPACE
    if (code == CTRL_DK_FAILED) return dk_error(s->S, t0 + s->S[CTRL_FAILED] * T, msg, size);
#endif
    return ik_error(values, t0 + s->S[CTRL_FAILED] * T, -code, msg, size);
}

/* DriveController._laws of tick n (the outputs too); 0, or an error code with msg */
static int run_laws(mast_controller_state *s, double *values, double n, char *msg, size_t size)
{
    double R[CTRL_N], CUR[CTRL_N], QM[CTRL_N], JK[CTRL_N + CTRL_N * CTRL_N];
    int code = ctrl_laws(values, s->S, R, CUR, QM, JK, n);
    return code ? tick_error(s, values, code, msg, size) : MAST_OK;
}

/* DriveController.evaluate: the laws of the communication point's tick, once per tick */
int mast_controller_evaluate(void *state, double *values, const mast_parameters *p, char *msg, size_t size)
{
    mast_controller_state *s = state;
    (void)p;
    double n = s->S[CTRL_TICK];
    if (s->evaluated == n)
        memcpy(s->S, s->before, sizeof s->S);
    else {
        memcpy(s->before, s->S, sizeof s->S);
        s->evaluated = n;
    }
    double t = s->S[CTRL_T0] + n * s->S[CTRL_T_CUR];
    double sum = 0.0;
    for (int k = 0; k < 3 * CTRL_N; k++) sum += values[k];
    if (sum - sum != 0.0 && input_error(values, t, msg, size)) return MAST_MODEL_ERROR;
    return run_laws(s, values, n, msg, size);
}

/* DriveController.do_step (its fast path for a tick that runs no loop too) */
int mast_controller_do_step(void *state, double *values, const mast_parameters *p, double t, double h, char *msg,
                            size_t size)
{
    mast_controller_state *s = state;
    char a[40], b[40], c[40];
    double T = s->S[CTRL_T_CUR];
    double m = nearbyint(h / T);
    if (m < 1.0 || fabs(h - m * T) > 1e-6 * T) {
        snprintf(msg, size, "step size h = %s s is not a positive integer multiple of T_cur = %s s",
                 mast_repr(h, a, sizeof a), mast_repr(T, b, sizeof b));
        return MAST_MODEL_ERROR;
    }
    double n = s->S[CTRL_TICK], t0 = s->S[CTRL_T0];
    if (fabs(t - (t0 + n * T)) > 0.5 * T) {
        snprintf(msg, size,
                 "do_step at t = %s s, but tick %.0f belongs to t = %s s (steps must be contiguous from initialize)",
                 mast_repr(t, a, sizeof a), n, mast_repr(t0 + n * T, c, sizeof c));
        return MAST_MODEL_ERROR;
    }
    if (m == 1.0 && s->evaluated != n && fmod(n, s->S[CTRL_N_POS]) != 0.0 && fmod(n, s->S[CTRL_N_VEL]) != 0.0) {
        /* a tick that runs no loop: its laws would change nothing (tick.py), the inputs are checked alone */
        double sum = 0.0;
        for (int k = 0; k < 3 * CTRL_N; k++) sum += values[k];
        if (sum - sum != 0.0 && input_error(values, t0 + n * T, msg, size)) return MAST_MODEL_ERROR;
        s->S[CTRL_TICK] = n + 1.0;
        return MAST_OK;
    }
    int code;
    if (s->evaluated != n && (code = mast_controller_evaluate(s, values, p, msg, size))) return code;
    double R[CTRL_N], CUR[CTRL_N], QM[CTRL_N], JK[CTRL_N + CTRL_N * CTRL_N];
    if ((code = ctrl_steps(values, s->S, R, CUR, QM, JK, n, m))) return tick_error(s, values, code, msg, size);
    s->S[CTRL_TICK] = n + m;
    return MAST_OK;
}
