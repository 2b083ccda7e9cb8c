/* The native actuator (mast_actuator.h): ActuatorBlock with its chains, the discretisation of each step size and
 * the torque measurement's delay line, around the generated kernels and the model's own functions (translated). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "mast_actuator.h"
#include "mast_native.h"

#define MATH_PI 3.141592653589793   /* math.pi */

/* off the step's path (a new step size, a failure): not inlined, so do_step stays small */
#if defined(__GNUC__)
#define COLD __attribute__((noinline, cold))
#else
#define COLD
#endif

static const char *const INPUT_NAMES[] = {"u", "F", "M_carried"};   /* actuator.model.INPUT_ERRORS */

/* the chain lists' names, whether their numbers must be > 0 (else >= 0), their value references */
static const char *const LIST_NAMES[3] = {"J_chain", "K_chain", "C_chain"};
static const int LIST_POSITIVE[3] = {1, 1, 0};
static const int LIST_VR[3] = {ACT_VR_J_CHAIN, ACT_VR_K_CHAIN, ACT_VR_C_CHAIN};

/* _parse_list of the chain lists for n_dof = n (>= 3) into ``lists`` (J: n numbers, K and C: n - 1), refused
 * as ``chain`` refuses them */
static int parse_chain(const mast_parameters *p, int n, double *lists, char *msg, size_t size)
{
    char item[64];
    int items;
    for (int k = 0, at = 0; k < 3; k++) {
        const char *text = p->string[LIST_VR[k]];
        int count = k == 0 ? n : n - 1;
        const char *what = LIST_POSITIVE[k] ? "> 0" : ">= 0";
        int code = mast_parse_list(text, count, LIST_POSITIVE[k], lists + at, &items, item, sizeof item);
        if (code == -1) {
            snprintf(msg, size, "parameter '%s' = '%s': expected %d space separated numbers %s for n_dof = %d, got %d",
                     LIST_NAMES[k], text ? text : "", count, what, n, items);
            return MAST_PARAMETER_ERROR;
        }
        if (code > 0) {
            snprintf(msg, size, "parameter '%s' = '%s': item '%s' is not a finite number %s", LIST_NAMES[k],
                     text ? text : "", item, what);
            return MAST_PARAMETER_ERROR;
        }
        at += count;
    }
    return MAST_OK;
}

/* the row of ACTUATOR_CHAINS of n_dof = n, or -1 */
static int chain_of(int n)
{
    for (int k = 0; k < ACTUATOR_N_CHAINS; k++) if (ACTUATOR_CHAINS[k].N == n) return k;
    return -1;
}

int mast_actuator_check(const mast_parameters *p, char *msg, size_t size)
{
    char a[40], b[40], d[40];
    double rho_min = p->real[ACT_VR_RHO_MIN], rho_max = p->real[ACT_VR_RHO_MAX], rho_0 = p->real[ACT_VR_RHO_0];
    int n = p->integer[ACT_VR_N_DOF];
    if (!(rho_min < rho_max)) {
        snprintf(msg, size, "parameter 'rho_max' = %s: expected a value above rho_min = %s m",
                 mast_repr(rho_max, a, sizeof a), mast_repr(rho_min, b, sizeof b));
        return MAST_PARAMETER_ERROR;
    }
    if (!(rho_min < rho_0 && rho_0 < rho_max)) {
        snprintf(msg, size, "parameter 'rho_0' = %s: expected a position inside the stroke (%s, %s) m",
                 mast_repr(rho_0, a, sizeof a), mast_repr(rho_min, b, sizeof b), mast_repr(rho_max, d, sizeof d));
        return MAST_PARAMETER_ERROR;
    }
    if (chain_of(n) < 0) {
        char runs[200];
        int used = snprintf(runs, sizeof runs, "1..%d", ACT_N_MAX);
        for (int k = 0; k < ACTUATOR_N_CHAINS; k++)
            if (ACTUATOR_CHAINS[k].N > ACT_N_MAX && used > 0 && (size_t)used < sizeof runs)
                used += snprintf(runs + used, sizeof runs - (size_t)used, " and %d", ACTUATOR_CHAINS[k].N);
        snprintf(msg, size, "parameter 'n_dof' = %d: this native FMU has the chains n_dof = %s (N_MAX = %d); the "
                 "project's master (mast run, mast batch, ...) generates one for a larger n_dof itself; for another "
                 "host set n_dof in the actuator's parameter set (.ssv) and rebuild: mast build --native",
                 n, runs, ACT_N_MAX);
        return MAST_PARAMETER_ERROR;
    }
    if (n >= 3) {
        double lists[ACT_N_LISTS];
        int code = parse_chain(p, n, lists, msg, size);
        if (code) return code;
    }
    if (n != 2 && p->real[ACT_VR_BACKLASH] > 0.0) {
        snprintf(msg, size, "parameter 'backlash' = %s: backlash is modelled in the two-inertia transmission only "
                 "(n_dof = 2, here %d)", mast_repr(p->real[ACT_VR_BACKLASH], a, sizeof a), n);
        return MAST_PARAMETER_ERROR;
    }
    return MAST_OK;
}

/* the kernel of the chain's structure (friction, ripple, backlash), as ActuatorBlock.kernel_source chooses it */
static int variant(const mast_actuator_state *s, const mast_actuator_chain *c)
{
    int fr = s->Q[ACT_Q_TAU_S] > 0.0 ? 2 : s->Q[ACT_Q_TAU_C] > 0.0 ? 1 : 0;
    int rp = s->Q[ACT_Q_RIPPLE] > 0.0, bl = c->hb >= 0 ? s->Q[c->hb] > 0.0 : 0;
    for (int k = c->first; k < c->first + c->count; k++) {
        const mast_actuator_kernel *v = &ACTUATOR_KERNELS[k];
        if (v->friction == fr && v->ripple == rp && v->backlash == bl) return k;
    }
    return c->first;
}

/* 2 pi times chain_frequencies(J, K).max(): the fastest chain mode [rad/s] */
static double omega_max(const mast_actuator_state *s, const mast_actuator_chain *c)
{
    int N = c->N;
    if (N <= 1) return 0.0;
    double S[ACT_NX * ACT_NX];
    for (int i = 0; i < N * N; i++) S[i] = 0.0;
    for (int k = 0; k < N - 1; k++) {
        double K = s->Q[c->K + k];
        S[k * N + k] += K; S[(k + 1) * N + k + 1] += K;
        S[k * N + k + 1] -= K; S[(k + 1) * N + k] -= K;
    }
    for (int i = 0; i < N; i++)
        for (int j = 0; j < N; j++) S[i * N + j] *= (1.0 / sqrt(s->Q[c->J + i])) * (1.0 / sqrt(s->Q[c->J + j]));
    double lam = mast_eig_max(N, S);
    return 2.0 * MATH_PI * (sqrt(lam > 0.0 ? lam : 0.0) / (2.0 * MATH_PI));
}

/* the chain n_dof from the parameters (ActuatorBlock.__init__) */
static int setup(mast_actuator_state *s, int row, const mast_parameters *p, char *msg, size_t size)
{
    const mast_actuator_chain *c = &ACTUATOR_CHAINS[row];
    double reals[ACT_N_REALS], lists[ACT_N_LISTS];
    for (int k = 0; k < ACT_N_REALS; k++) reals[k] = p->real[ACTUATOR_REAL_VR[k]];
    if (c->N >= 3) {
        int code = parse_chain(p, c->N, lists, msg, size);
        if (code) return code;
    }
    c->constants(reals, lists, s->Q);
    s->N = c->N;
    s->chain = row;
    s->bw = c->bw;
    s->variant = variant(s, c);
    s->omega_max = omega_max(s, c);
    return MAST_OK;
}

/* friction numbers of a substep whose d omega_N / d tau_L is b, into F (the kernel's structure fr) */
static void friction(int fr, double b, const double *Q, double *F)
{
    if (fr == 1) act_friction_coulomb(b, Q[ACT_Q_TAU_C], Q[ACT_Q_OMEGA_C], Q[ACT_Q_TAU_S], Q[ACT_Q_OMEGA_S], F);
    if (fr == 2) act_friction_stribeck(b, Q[ACT_Q_TAU_C], Q[ACT_Q_OMEGA_C], Q[ACT_Q_TAU_S], Q[ACT_Q_OMEGA_S], F);
}

/* ActuatorBlock._substeps (the substep rule) and _bind (the numbers of a step size), for the key h */
static int discretise(mast_actuator_state *s, double h, mast_actuator_disc *d, char *msg, size_t size)
{
    enum { NM = ACT_NX + 2 };
    const mast_actuator_chain *c = &ACTUATOR_CHAINS[s->chain];
    const mast_actuator_kernel *v = &ACTUATOR_KERNELS[s->variant];
    int nx = 2 * c->N + 1, wN = 2 * c->N, nm = 2 * c->N + 3;
    char text[40];
    double rule[2];
    act_substep_rule(s->omega_max, h, (double)v->backlash, s->Q[ACT_Q_TAU_S], s->Q[ACT_Q_OMEGA_S], rule);
    double m = rule[0], fall = rule[1];
    double M[NM * NM], E[NM * NM], b = 0.0;
    for (;;) {
        double hs = h / m;
        for (int i = 0; i < nm * nm; i++) M[i] = 0.0;
        for (int i = 0; i < nx; i++) {
            for (int j = 0; j < nx; j++) M[i * nm + j] = s->Q[c->A + i * nx + j] * hs;
            for (int j = 0; j < 2; j++) M[i * nm + nx + j] = s->Q[c->B + i * 2 + j] * hs;
        }
        if (mast_expm(nm, M, E)) { snprintf(msg, size, "out of memory"); return MAST_MODEL_ERROR; }
        b = E[wN * nm + nx + 1];
        if (act_substeps_enough(b, fall, m)) break;
        m *= 2.0;
    }
    if (!(b > 0.0)) {
        snprintf(msg, size, "no substep gives a monotone friction update for h = %s s", mast_repr(h, text, sizeof text));
        return MAST_MODEL_ERROR;
    }
    d->m = m;
    d->H[v->hs] = h / m;
    if (!v->backlash) {
        for (int i = 0; i < nx; i++) {
            for (int j = 0; j < nx; j++) d->H[i * nx + j] = E[i * nm + j];
            for (int j = 0; j < 2; j++) d->H[nx * nx + i * 2 + j] = E[i * nm + nx + j];
        }
        friction(v->friction, E[wN * nm + nx + 1], s->Q, d->H + v->f0);
        return MAST_OK;
    }
    /* _backlash_matrices (n_dof = 2): in contact (A, B3) and in the gap (Ag, B3), 8 x 8 */
    double hs = h / m, M8[64], E8[64];
    const int system[2] = {c->A, c->Ag};
    for (int which = 0; which < 2; which++) {
        for (int i = 0; i < 64; i++) M8[i] = 0.0;
        for (int i = 0; i < 5; i++) {
            for (int j = 0; j < 5; j++) M8[i * 8 + j] = s->Q[system[which] + i * 5 + j] * hs;
            for (int j = 0; j < 3; j++) M8[i * 8 + 5 + j] = s->Q[c->B3 + i * 3 + j] * hs;
        }
        if (mast_expm(8, M8, E8)) { snprintf(msg, size, "out of memory"); return MAST_MODEL_ERROR; }
        double *P = d->H + which * 40, *G = P + 25;
        for (int i = 0; i < 5; i++) {
            for (int j = 0; j < 5; j++) P[i * 5 + j] = E8[i * 8 + j];
            for (int j = 0; j < 3; j++) G[i * 3 + j] = E8[i * 8 + 5 + j];
        }
        friction(v->friction, G[13], s->Q, d->H + (which ? v->f1 : v->f0));   /* b = G[4][1] */
    }
    return MAST_OK;
}

/* TorqueSensor.step (sensor.py): the delay line of n + 2 samples, newest at head (relayout and measurement_step,
 * translated; the line's allocation, its longest length and its message here) */
static int sensor_step(mast_actuator_state *s, double u, double h, const mast_parameters *p, double *out, char *msg,
                       size_t size)
{
    double T = p->real[ACT_VR_T_MEAS], delay = p->real[ACT_VR_DELAY_MEAS], offset = p->real[ACT_VR_TAU_OFFSET];
    if (h != s->s_h) {          /* TorqueSensor._configure */
        double co[3], sp[2];
        char a[40], b[40];
        act_filter_coefficients(T, h, co);
        act_delay_split(delay, h, sp);
        if (sp[0] + 2.0 > (double)ACT_SENSOR_SAMPLES) {
            snprintf(msg, size, "parameter 'delay_meas' = %s s is %.0f steps of h = %s s: this native FMU keeps at most "
                     "%d", mast_repr(delay, a, sizeof a), sp[0], mast_repr(h, b, sizeof b), ACT_SENSOR_SAMPLES - 2);
            return MAST_MODEL_ERROR;
        }
        int L = (int)sp[0] + 2;
        double *line = malloc((size_t)L * sizeof(double));
        if (!line) { snprintf(msg, size, "out of memory"); return MAST_MODEL_ERROR; }
        act_relayout(s->hist, s->s_len, s->s_head, line, L, s->s_u0);
        memcpy(s->hist, line, (size_t)L * sizeof(double));
        free(line);
        s->s_len = L; s->s_head = L - 1;
        s->s_e = co[0]; s->s_c = co[1]; s->s_d = co[2]; s->s_n = (int)sp[0]; s->s_phi = sp[1]; s->s_h = h;
    }
    double r[3];
    act_measurement_step(u, s->hist, s->s_head, s->s_len, s->s_n, s->s_phi, s->s_e, s->s_c, s->s_d, s->s_y,
                         s->s_uprev, r);
    s->s_head = (int)r[0]; s->s_y = r[1]; s->s_uprev = r[2];
    *out = s->s_y + offset;
    return MAST_OK;
}

/* the discretisation of another step size h than the last step's: one kept (ActuatorBlock._select's key), or a new
 * one in the oldest slot; NULL with msg for a step size that is not finite and positive or cannot be discretised */
static COLD mast_actuator_disc *select(mast_actuator_state *s, double h, char *msg, size_t size)
{
    char v[40], key_text[40];
    if (!(h > 0.0 && isfinite(h))) {
        snprintf(msg, size, "step size h = %s s: expected a finite positive number", mast_repr(h, v, sizeof v));
        return NULL;
    }
    mast_actuator_disc *d = NULL;
    snprintf(key_text, sizeof key_text, "%.12g", h);      /* ActuatorBlock._select's key */
    double key = strtod(key_text, NULL);
    for (int k = 0; k < s->n_disc; k++) if (s->key[k] == key) { d = &s->disc[k]; s->last = k; }
    if (!d) {
        int slot = s->next_disc;
        if (discretise(s, key, &s->disc[slot], msg, size)) return NULL;
        s->key[slot] = key;
        s->next_disc = (slot + 1) % ACT_KEPT;
        if (s->n_disc < ACT_KEPT) s->n_disc++;
        d = &s->disc[slot];
        s->last = slot;
    }
    s->h_last = h;
    return d;
}

/* the message of an input's failure code (actuator.model.INPUT_ERRORS: 1 u, 2 F, 5 M_carried) */
static int input_error(const double *values, int code, double t, char *msg, size_t size)
{
    char v[40];
    int at = code == 5 ? 2 : code - 1;     /* actuator.model.input_index */
    mast_repr(values[at], v, sizeof v);
    snprintf(msg, size, "input '%s' = %s at t=%.9g s is not %s", INPUT_NAMES[at], v, t,
             code == 5 ? "a finite mass >= 0 kg" : "finite");
    return MAST_MODEL_ERROR;
}

/* ActuatorBlock.initialize: the chain n_dof selects, at rest (x = 0), the inputs checked, the outputs of rest */
int mast_actuator_initialize(void *state, double *values, const mast_parameters *p, double t0, char *msg, size_t size)
{
    mast_actuator_state *s = state;
    const double *Q = s->Q;
    memset(s, 0, sizeof *s);
    s->h_last = NAN;
    int row = chain_of(p->integer[ACT_VR_N_DOF]);
    if (row < 0) {     /* refused by check (exitInitializationMode runs it first), with its message */
        int code = mast_actuator_check(p, msg, size);
        return code ? code : MAST_PARAMETER_ERROR;
    }
    int code = setup(s, row, p, msg, size);
    if (code) return code;
    double u = values[0], F = values[1], Dc = values[2];
    if (!isfinite(u)) return input_error(values, 1, t0, msg, size);
    if (!isfinite(F)) return input_error(values, 2, t0, msg, size);
    if (!(isfinite(Dc) && Dc >= 0.0)) return input_error(values, 5, t0, msg, size);   /* actuator.model.carried_ok */
    double w = 0.0;
    double tm = Q[ACT_Q_KT] * 0.0;
    double T = p->real[ACT_VR_T_MEAS], delay = p->real[ACT_VR_DELAY_MEAS], offset = p->real[ACT_VR_TAU_OFFSET];
    values[3] = Q[ACT_Q_RHO0] + Q[ACT_Q_IR] * 0.0;
    values[4] = Q[ACT_Q_IR] * w;
    values[5] = 0.0;   /* at rest until the first step: no loop with the mechanism's forces (ActuatorBlock) */
    values[6] = 0.0; values[7] = 0.0; values[8] = 0.0; values[ACT_TAU_M] = tm;
    s->sensor = !(T == 0.0 && delay == 0.0 && offset == 0.0);
    s->s_u0 = tm; s->s_y = tm; s->s_uprev = tm; s->s_h = NAN; s->s_len = 0; s->s_head = 0;
    values[ACT_TAU_MEAS] = s->sensor ? s->s_y + offset : tm;
    values[ACT_F_DRIVE] = -Q[ACT_Q_MG];   /* the drive force at rest: the carriage's weight alone */
    values[ACT_F_DRIVE + 1] = 0.0;
    values[ACT_F_DRIVE + 2] = 0.0;
    values[ACT_F_DRIVE + 3] = Q[ACT_Q_MD];
    return MAST_OK;
}

/* the message of a kernel's failure ``code`` in the step from t to t + h */
static COLD int step_error(const mast_actuator_state *s, const double *values, int code, double t, double h,
                           char *msg, size_t size)
{
    if (code == 1 || code == 2 || code == 5) return input_error(values, code, t, msg, size);
    if (code == 3) {
        snprintf(msg, size, "diverged at t=%.9g s (non-finite state)", t + h);
        return MAST_MODEL_ERROR;
    }
    snprintf(msg, size, "carriage left the stroke [%g, %g] m: rho = %.6g m at t=%.9g s", s->Q[ACT_Q_RMIN],
             s->Q[ACT_Q_RMAX], s->Q[ACT_Q_RHO0] + s->Q[ACT_Q_IR] * s->x[s->N], t + h);
    return MAST_MODEL_ERROR;
}

mast_actuator_disc *mast_actuator_select(mast_actuator_state *s, double h, char *msg, size_t size)
{
    /* do_step selects only for another h than the last step's (h_last: NaN until a step, equal to no h) */
    return h == s->h_last ? &s->disc[s->last] : select(s, h, msg, size);
}

int mast_actuator_finish(mast_actuator_state *s, double *values, int code, const mast_parameters *p, double t, double h,
                         char *msg, size_t size)
{
    if (code) return step_error(s, values, code, t, h, msg, size);
    return s->sensor ? sensor_step(s, values[ACT_TAU_M], h, p, values + ACT_TAU_MEAS, msg, size) : MAST_OK;
}

int mast_actuator_do_step(void *state, double *values, const mast_parameters *p, double t, double h, char *msg,
                          size_t size)
{
    mast_actuator_state *s = state;
    mast_actuator_disc *d = mast_actuator_select(s, h, msg, size);
    if (!d) return MAST_MODEL_ERROR;
    int code = mast_actuator_advance(s, d, values, p, t, h, msg, size);
    if (!code && !mast_actuator_condenses(s, h)) values[ACT_F_DRIVE + 3] = 0.0;
    return code;
}
