/* Support for the generated model files (mast build --native): the scalar functions the
 * generated code calls and the engine's algorithms that are not traced (Newton's direct
 * kinematics, the 3x3 inverse), each the same operations in the same order as the Python
 * it mirrors (fmus/mechanism/engine.py, kinematics.py), so the floats agree.
 */
#ifndef MAST_NATIVE_H
#define MAST_NATIVE_H

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static inline double mast_sign(double x) { return x > 0.0 ? 1.0 : -1.0; }   /* engine._sign */
static inline double mast_sgn0(double x) { return x >= 0.0 ? 1.0 : -1.0; }  /* engine._sgn0 */
static inline double mast_hypot(double a, double b) { return hypot(a, b); }

/* Python's repr of a float (shortest round-trip digits, the same layout), for messages */
static inline const char *mast_repr(double x, char *buf, size_t size)
{
    if (isnan(x)) { snprintf(buf, size, "nan"); return buf; }
    if (isinf(x)) { snprintf(buf, size, x > 0 ? "inf" : "-inf"); return buf; }
    char e[40];
    int p;
    for (p = 1; p < 17; p++) {
        snprintf(e, sizeof e, "%.*e", p - 1, x);
        if (strtod(e, NULL) == x) break;
    }
    snprintf(e, sizeof e, "%.*e", p - 1, x);
    int exp10 = atoi(strchr(e, 'e') + 1);
    if (exp10 < -4 || exp10 >= 16) {
        snprintf(buf, size, "%s", e);                      /* Python writes 1e-05, 1.5e+20: as C does */
    } else {
        int decimals = p - 1 - exp10;
        if (decimals < 0) decimals = 0;
        snprintf(buf, size, "%.*f", decimals, x);
        if (!strchr(buf, '.')) strncat(buf, ".0", size - strlen(buf) - 1);
    }
    return buf;
}

/* kinematics._inv3: inverse (row-major) and determinant; returns 0 when det == 0 (Python: ZeroDivisionError) */
static inline int mast_inv3(const double *m, double *inv, double *det_out)
{
    double a = m[0], b = m[1], c = m[2], d = m[3], e = m[4], f = m[5], g = m[6], h = m[7], i = m[8];
    double A = e * i - f * h, B = f * g - d * i, C = d * h - e * g;
    double det = a * A + b * B + c * C;
    if (det == 0.0) return 0;
    double k = 1.0 / det;
    inv[0] = A * k; inv[1] = (c * h - b * i) * k; inv[2] = (b * f - c * e) * k;
    inv[3] = B * k; inv[4] = (a * i - c * g) * k; inv[5] = (c * d - a * f) * k;
    inv[6] = C * k; inv[7] = (b * g - a * h) * k; inv[8] = (a * e - b * d) * k;
    *det_out = det;
    return 1;
}

/* engine._cond: Frobenius condition number */
static inline double mast_cond(const double *m, const double *minv, int n2)
{
    double s = 0.0, t = 0.0;
    for (int k = 0; k < n2; k++) s += m[k] * m[k];
    for (int k = 0; k < n2; k++) t += minv[k] * minv[k];
    return sqrt(s) * sqrt(t);
}

/* generated: rho (3) and drho/dq (9, row-major) at q; 0, or -N when the description's check N failed */
typedef int (*mast_ikjac3)(double q0, double q1, double q2, double *out);
/* generated: the message of a failed check */
typedef const char *(*mast_check_message)(int check);

/* Engine.dk for three coordinates: Newton on the inverse kinematics from ``q`` (the guess) until
 * max|rho(q) - rho| < tol; J = dq/drho. 0, MAST_KINEMATICS_ERROR (3) or, for a solution on another
 * assembly branch than the start, MAST_SINGULARITY_ERROR (4), with ``msg`` filled. */
static inline int mast_dk3(mast_ikjac3 ikjac, mast_check_message why, const double *rho, double *q, double *J,
                           double tol, int max_iter, double cond_limit, char *msg, size_t size)
{
    double out[12], e[3], res = INFINITY, det = 0.0, det0 = 0.0, cond;
    char r0[32], r1[32], r2[32];
    for (int it = 0; it <= max_iter; it++) {
        int check = ikjac(q[0], q[1], q[2], out);
        if (check) {
            snprintf(msg, size, "direct kinematics did not converge for rho = (%.9g, %.9g, %.9g) m: iteration %d "
                     "reached z = %.6g m, psi = %.6g rad, theta = %.6g rad, where: %s", rho[0], rho[1], rho[2], it,
                     q[0], q[1], q[2], why(-check));
            return 3;
        }
        for (int i = 0; i < 3; i++) e[i] = out[i] - rho[i];
        res = fabs(e[0]);
        if (fabs(e[1]) > res) res = fabs(e[1]);
        if (fabs(e[2]) > res) res = fabs(e[2]);
        if (!mast_inv3(out + 3, J, &det)) {
            snprintf(msg, size, "direct kinematics did not converge for rho = (%.9g, %.9g, %.9g) m: iteration %d: "
                     "singular configuration: drho/dq is singular", rho[0], rho[1], rho[2], it);
            return 3;
        }
        cond = mast_cond(out + 3, J, 9);
        if (res < tol && !(cond < cond_limit)) {
            snprintf(msg, size, "direct kinematics did not converge for rho = (%.9g, %.9g, %.9g) m: singular "
                     "configuration: drho/dq has condition number %.3g (limit %.0e)", rho[0], rho[1], rho[2], cond,
                     cond_limit);
            return 3;
        }
        if (!isfinite(res)) {
            snprintf(msg, size, "direct kinematics did not converge for rho = (%.9g, %.9g, %.9g) m: non-finite "
                     "residual at iteration %d", rho[0], rho[1], rho[2], it);
            return 3;
        }
        if (it == 0) det0 = det;
        if (res < tol) {        /* Engine._check_branch: on the start's assembly branch (the margin is not checked here) */
            if ((det > 0.0) != (det0 > 0.0)) {
                snprintf(msg, size, "direct kinematics for rho = (%.9g, %.9g, %.9g) m: the solution z = %.6g m, "
                         "psi = %.6g rad, theta = %.6g rad lies on another assembly branch than the start "
                         "(det(drho/dq) = %+.3g there, %+.3g at the start): the joints crossed a parallel singularity; "
                         "refused rather than jump to the other branch", rho[0], rho[1], rho[2], q[0], q[1], q[2],
                         det, det0);
                return 4;
            }
            return 0;
        }
        if (it == max_iter) break;
        for (int j = 0; j < 3; j++) {
            double s = 0.0;
            for (int k = 0; k < 3; k++) s += J[j * 3 + k] * e[k];
            q[j] -= s;
        }
    }
    snprintf(msg, size, "direct kinematics did not converge for rho = (%s, %s, %s) m: %d iterations, residual "
             "max|rho(q) - rho| = %.3g m > tol = %.3g m", mast_repr(rho[0], r0, sizeof r0),
             mast_repr(rho[1], r1, sizeof r1), mast_repr(rho[2], r2, sizeof r2), max_iter, res, tol);
    return 3;
}

#endif
