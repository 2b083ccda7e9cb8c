/* The native mechanism (mast_mechanism.h): fmus/mechanism/model.py's MechanismBlock for any description, its
 * sizes from config.h and its kernels and tables from the generated <id>_model.c. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "mast_linalg.h"
#include "mast_mechanism.h"
#include "mast_native.h"

/* mast_dk's view of the traced inverse kinematics with its Jacobian */
static int ikjac_of(const void *model, const double *q, double *out)
{
    mast_mechanism_state *s = (mast_mechanism_state *)model;
    return mech_ikjac((double *)q, s->P, s->K_ikjac, out);
}

/* the description's cold start of the direct kinematics (Described.guess) */
void mast_mechanism_guess(const mast_mechanism_state *s, double *rho, double *q)
{
#if MECH_GUESS_RULE
    mech_guess_rule(rho, (double *)s->G, q);
#else
    (void)rho;
    for (int k = 0; k < MECH_N; k++) q[k] = s->G[k];
#endif
}

int mast_mechanism_dk(double *rho, double warm, double *S, double *out)
{
    mast_mechanism_state *s = (mast_mechanism_state *)S;
    if (warm == 1.0) {
        for (int k = 0; k < MECH_N; k++) out[k] = s->q[k];
    } else {
        mast_mechanism_guess(s, rho, out);
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

#define OUT (MECH_KINDS * MECH_N)          /* where the outputs F start among the values */
#define TOLD (OUT + MECH_N + 6)             /* where Fc starts; Mc after it */

/* coupling.condense: W and D of M + diag(m) by Gauss-Jordan without pivoting, in the Python model's order */
static void condense(mast_mechanism_state *s, const double *m)
{
    enum { N = MECH_N, N2 = 2 * MECH_N };
    double A[MECH_N][2 * MECH_N];
    for (int i = 0; i < N; i++)
        for (int j = 0; j < N2; j++)
            A[i][j] = j < N ? s->M[i * N + j] + (i == j ? m[i] : 0.0) : (j - N == i ? 1.0 : 0.0);
    for (int k = 0; k < N; k++) {
        double inv = 1.0 / A[k][k];
        for (int j = 0; j < N2; j++) A[k][j] = A[k][j] * inv;
        for (int i = 0; i < N; i++) {
            if (i == k) continue;
            double f = A[i][k];
            for (int j = 0; j < N2; j++) A[i][j] = A[i][j] - f * A[k][j];
        }
    }
    for (int i = 0; i < N; i++) {
        for (int j = 0; j < N; j++) s->W[i * N + j] = i == j ? 0.0 : -A[i][N + j] / A[i][N + i];
        s->D[i] = 1.0 / A[i][N + i] - m[i];
    }
}

/* MechanismBlock._condense: the condensed interface of the last full update's M, none while a drive reports no
 * load-side mass or detached */
static void condense_update(mast_mechanism_state *s, const double *values, const mast_parameters *p)
{
    const double *m = values + (MECH_KINDS - 1) * MECH_N;
    s->condensed = MECH_ATTACHED_VR < 0 || p->integer[MECH_ATTACHED_VR];
    for (int k = 0; k < MECH_N; k++) s->condensed = s->condensed && m[k] > 0.0;
    if (s->condensed && !s->latched) {     /* model.CONDENSE_ABOVE: the largest eigenvalue of m^-1/2 M m^-1/2 */
        double S[MECH_N * MECH_N], inv[MECH_N];
        for (int k = 0; k < MECH_N; k++) inv[k] = 1.0 / sqrt(m[k]);
        for (int i = 0; i < MECH_N; i++)
            for (int j = 0; j < MECH_N; j++) S[i * MECH_N + j] = s->M[i * MECH_N + j] * (inv[i] * inv[j]);
        if (mast_eig_max(MECH_N, S) < MECH_CONDENSE_ABOVE) s->condensed = 0;
        else s->latched = 1;
    }
    if (s->condensed) condense(s, m);
    else for (int k = 0; k < MECH_N; k++) s->D[k] = 0.0;
}

/* MechanismBlock._tell: Fc and Mc for the step h */
static void tell(const mast_mechanism_state *s, double *values, double h)
{
    const int n = MECH_N;
    if (!s->condensed) {
        for (int k = 0; k < n; k++) { values[TOLD + k] = values[OUT + k]; values[TOLD + n + k] = s->D[k]; }
        return;
    }
    double tau = MECH_EXTRAPOLATION * h, half = 0.5 * tau * tau, T[MECH_N];
    for (int j = 0; j < n; j++) T[j] = values[3 * n + j] + tau * values[4 * n + j] + half * values[5 * n + j];
    for (int k = 0; k < n; k++) {
        double acc = s->b[k];
        for (int j = 0; j < n; j++) if (j != k) acc += s->W[k * n + j] * (T[j] - s->b[j]);
        values[TOLD + k] = acc;
        values[TOLD + n + k] = s->D[k];
    }
}

/* MechanismBlock._compute: direct kinematics (restarted_dk), then the forces and the pose */
static int compute(mast_mechanism_state *s, double *values, const mast_parameters *p, double t, double h, char *msg,
                   size_t size)
{
    char v[40], w[40];
    double qJ[MECH_N + MECH_N * MECH_N], *q = qJ, *J = qJ + MECH_N;
    for (int k = 0; k < MECH_KINDS * MECH_N; k++) {
        if (!isfinite(values[k])) {
            snprintf(msg, size, "input '%s' = %s is not finite at t = %s s", MECH_INPUT_NAMES[k],
                     mast_repr(values[k], v, sizeof v), mast_repr(t, w, sizeof w));
            return MAST_MODEL_ERROR;
        }
    }
    for (int k = (MECH_KINDS - 1) * MECH_N; k < MECH_KINDS * MECH_N; k++) {
        if (values[k] < 0.0) {
            snprintf(msg, size, "input '%s' = %s at t = %s s: expected a load-side mass >= 0 (0: not connected)",
                     MECH_INPUT_NAMES[k], mast_repr(values[k], v, sizeof v), mast_repr(t, w, sizeof w));
            return MAST_MODEL_ERROR;
        }
    }
    int code = mech_restarted_dk(values, s->warm ? 1.0 : 0.0, (double *)s, qJ);
    if (code) {
        kinematics_error(values, t, s->why_text, msg, size);
        return code;          /* MAST_KINEMATICS_ERROR, or MAST_SINGULARITY_ERROR: it stays one */
    }
    if (MECH_ATTACHED_VR < 0 || p->integer[MECH_ATTACHED_VR]) {
        double out[MECH_N + 6 + MECH_N * MECH_N + MECH_N];
        code = mech_dynamics(q, J, values + MECH_N, values + 2 * MECH_N, s->P, s->K_dynamics, out);
        if (!code) {
            memcpy(values + OUT, out, (MECH_N + 6) * sizeof(double));
            memcpy(s->M, out + MECH_N + 6, sizeof s->M);
            memcpy(s->b, out + MECH_N + 6 + MECH_N * MECH_N, sizeof s->b);
        }
    } else {   /* attached = 0: no force, the kinematics of the mechanism */
        for (int k = 0; k < MECH_N; k++) values[OUT + k] = 0.0;
        code = mech_pose(q, s->P, s->K_pose, values + OUT + MECH_N);
    }
    if (code) return kinematics_error(values, t, mech_why(-code), msg, size);
    for (int k = 0; k < MECH_N; k++) s->q[k] = q[k];
    s->warm = 1;
    condense_update(s, values, p);
    tell(s, values, h);
    return MAST_OK;
}

/* what the parameters the host set alone fix: P, the kernels' invariants, the cold start's numbers, the lengths */
void mast_mechanism_setup(mast_mechanism_state *s, const mast_parameters *p)
{
    s->warm = 0;
    for (int k = 0; k < MECH_NP; k++) s->P[k] = MECH_TRACED_VR[k] >= 0 ? p->real[MECH_TRACED_VR[k]] : 0.0;
    mech_ikjac_invariants(s->P, s->K_ikjac);
    mech_dynamics_invariants(s->P, s->K_dynamics);
    mech_pose_invariants(s->P, s->K_pose);
    mech_guess_numbers(s->P, s->G);
    double radius = 0.0;
#if MECH_NL
    double points[3 * MECH_NL];
    mech_platform(s->P, points);
    for (int k = 0; k < MECH_NL; k++) {
        const double *a = points + 3 * k;
        double d = sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
        if (d > radius) radius = d;
    }
#endif
    for (int k = 0; k < MECH_N; k++) s->lengths[k] = MECH_LENGTH_RADIUS[k] ? radius : MECH_LENGTH_VALUE[k];
}

int mast_mechanism_initialize(void *state, double *values, const mast_parameters *p, double t0, char *msg,
                              size_t size)
{
    mast_mechanism_state *s = state;
    mast_mechanism_setup(s, p);
    s->t0 = t0;
    s->latched = 0;
    int code = compute(s, values, p, t0, 0.0, msg, size);
    if (code) return code;
    s->condensed = 0;   /* MechanismBlock.initialize: nothing condensed until the first step */
    for (int k = 0; k < MECH_N; k++) s->D[k] = 0.0;
    tell(s, values, 0.0);
    return MAST_OK;
}

/* designs.describe: the mechanism the parameter 'kinematics' names must be this one */
static int check_kinematics(const mast_parameters *p, char *msg, size_t size)
{
#if MECH_KINEMATICS_VR >= 0
    const char *kind = p->string[MECH_KINEMATICS_VR] ? p->string[MECH_KINEMATICS_VR] : "";
    if (strcmp(kind, MECH_NAME) == 0) return MAST_OK;
    char known[1024] = "";
    for (int k = 0; k < MECH_NKINEMATICS; k++) {
        if (strcmp(kind, MECH_KINEMATICS[k]) == 0) {
            snprintf(msg, size, "parameter 'kinematics' = '%s': this native FMU computes the %s it was generated from",
                     kind, MECH_NAME);
            return MAST_PARAMETER_ERROR;
        }
        if (k) strncat(known, ", ", sizeof known - strlen(known) - 1);
        strncat(known, MECH_KINEMATICS[k], sizeof known - strlen(known) - 1);
    }
    snprintf(msg, size, "parameter 'kinematics' = '%s': expected one of %s", kind, known);
    return MAST_PARAMETER_ERROR;
#else
    (void)p, (void)msg, (void)size;
    return MAST_OK;
#endif
}

/* engine.Body: a finite symmetric inertia tensor, a finite mass >= 0, the tensor positive semi-definite */
static int check_bodies(const mast_mechanism_state *s, char *msg, size_t size)
{
#if MECH_NB
    double B[10 * MECH_NB];
    char v[40];
    mech_bodies((double *)s->P, B);
    for (int b = 0; b < MECH_NB; b++) {
        const double m = B[10 * b], *I = B + 10 * b + 1;
        const mast_mechanism_body *body = MECH_BODY + b;
        int any = m != 0.0, finite = 1;
        double big = 1.0;
        for (int k = 0; k < 9; k++) {
            any = any || I[k] != 0.0;
            finite = finite && isfinite(I[k]);
            if (fabs(I[k]) > big) big = fabs(I[k]);
        }
        if (body->optional && !any) continue;
        if (!finite || I[1] != I[3] || I[2] != I[6] || I[5] != I[7]) {
            snprintf(msg, size, "parameters %s: body %s: inertia must be a finite symmetric 3x3 tensor",
                     body->inertia_by, body->name);
            return MAST_PARAMETER_ERROR;
        }
        if (!(isfinite(m) && m >= 0.0)) {
            snprintf(msg, size, "parameters %s: body %s: mass %s must be finite and >= 0", body->mass_by, body->name,
                     mast_repr(m, v, sizeof v));
            return MAST_PARAMETER_ERROR;
        }
        if (mast_sym3_min_eig(I) < -1e-12 * big) {
            snprintf(msg, size, "parameters %s: body %s: inertia tensor is not positive semi-definite",
                     body->inertia_by, body->name);
            return MAST_PARAMETER_ERROR;
        }
    }
#else
    (void)s, (void)msg, (void)size;
#endif
    return MAST_OK;
}

/* designs.CHECKS: the description's own checks, with the Python model's messages */
static int check_rows(mast_mechanism_state *s, char *msg, size_t size)
{
    double V[MECH_NV];
    mech_check_values(s->P, V);
    for (int c = 0; c < MECH_NCHECK; c++) {
        const mast_parameter_check *row = MECH_CHECK + c;
        if (row->when >= 0 && (V[row->when] == 0.0) != row->when_zero) continue;
        const char *why = NULL;
        if (!row->assembles) {
            if (V[row->a] < V[row->b]) continue;
        } else {
            double rho[MECH_N] = {0.0}, q[MECH_N], out[MECH_N + MECH_N * MECH_N], inv[MECH_N * MECH_N], det;
            mast_mechanism_guess(s, rho, q);
            int code = mech_ikjac(q, s->P, s->K_ikjac, out);
            if (code) {
                why = mech_why(-code);
            } else if (row->regular && !mast_inv(MECH_N, out + MECH_N, inv, &det)) {
                why = "singular configuration";
            } else {
                continue;
            }
        }
        char shown[6][40];
        const char *text[7] = {"", "", "", "", "", "", ""};
        for (int k = 0; k < row->n_shown; k++) text[k] = mast_repr(V[row->shown[k]], shown[k], sizeof shown[k]);
        if (why) text[row->n_shown] = why;
        snprintf(msg, size, row->format, text[0], text[1], text[2], text[3], text[4], text[5], text[6]);
        return MAST_PARAMETER_ERROR;
    }
    return MAST_OK;
}

int mast_mechanism_check(const mast_parameters *p, char *msg, size_t size)
{
    int code = check_kinematics(p, msg, size);
    if (code) return code;
    mast_mechanism_state s;
    mast_mechanism_setup(&s, p);
    if ((code = check_rows(&s, msg, size))) return code;
    return check_bodies(&s, msg, size);
}

/* MechanismBlock.inertial_forces: F = M rho_ddot + b from the accelerations set now (none when detached) */
static int inertial_forces(const mast_mechanism_state *s, double *values, const mast_parameters *p, double t,
                           char *msg, size_t size)
{
    char v[40], w[40];
    if (MECH_ATTACHED_VR >= 0 && !p->integer[MECH_ATTACHED_VR]) return MAST_OK;
    const double *rdd = values + 2 * MECH_N;
    for (int k = 0; k < MECH_N; k++) {
        if (!isfinite(rdd[k])) {
            snprintf(msg, size, "input '%s' = %s is not finite at t = %s s", MECH_INPUT_NAMES[2 * MECH_N + k],
                     mast_repr(rdd[k], v, sizeof v), mast_repr(t, w, sizeof w));
            return MAST_MODEL_ERROR;
        }
    }
    for (int a = 0; a < MECH_N; a++) {
        double f = s->b[a];
        for (int c = 0; c < MECH_N; c++) f += s->M[a * MECH_N + c] * rdd[c];
        values[OUT + a] = f;
    }
    return MAST_OK;
}

/* MechanismBlock.do_step: the full update when the step [t, t + h) holds an update instant t0 + k T_mech, else the
 * inertial forces of the accelerations held (the pose held) */
int mast_mechanism_do_step(void *state, double *values, const mast_parameters *p, double t, double h, char *msg,
                           size_t size)
{
    mast_mechanism_state *s = state;
#if MECH_UPDATE_VR >= 0
    const double T = p->real[MECH_UPDATE_VR];
    if (T > 0.0) {
        const double eps = 1e-6 * (h < T ? h : T);
        if (s->t0 + ceil((t - s->t0 - eps) / T) * T >= t + h - eps) {
            int code = inertial_forces(s, values, p, t + h, msg, size);
            if (!code) tell(s, values, h);
            return code;
        }
    }
#endif
    return compute(s, values, p, t + h, h, msg, size);
}
