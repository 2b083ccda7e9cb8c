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

/* x % y of the generated code (tick counters, >= 0): fmod, exact, computed as the integer remainder when
 * both are whole numbers in [0, 2^31) (then the same number: fmod is exact; 0 is +0.0 as fmod's), which
 * costs a few instructions instead of libm's general fmod (a tenth of a controller's step) */
static inline double mast_mod(double x, double y)
{
    if (x >= 0.0 && x < 2147483648.0 && y >= 1.0 && y < 2147483648.0) {
        long a = (long)x, b = (long)y;
        if ((double)a == x && (double)b == y) return (double)(a % b);
    }
    return fmod(x, y);
}

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

/* kinematics.inv3: inverse (row-major) and determinant; returns 0 when det == 0 (Python: ZeroDivisionError) */
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

/* generated: rho (3) and drho/dq (9, row-major) at q for the traced parameters P (Engine.parameters, in
 * order; unused by an engine traced with its parameters as constants); 0, or -N when the description's
 * check N failed */
typedef int (*mast_ikjac3)(const double *P, double q0, double q1, double q2, double *out);
/* generated: the message of a failed check */
typedef const char *(*mast_check_message)(int check);

/* Engine._fmt_q: "z = 0.25 m, psi = 0.3 rad (17.19 deg), ..." (coordinates z, x, y in m, the others angles) */
static inline const char *mast_fmt_q(const char *const *names, const double *q, char *buf, size_t size)
{
    size_t used = 0;
    buf[0] = '\0';
    for (int k = 0; k < 3 && used < size; k++) {
        const char *sep = k ? ", " : "";
        int metres = !strcmp(names[k], "z") || !strcmp(names[k], "x") || !strcmp(names[k], "y");
        int n = metres ? snprintf(buf + used, size - used, "%s%s = %.6g m", sep, names[k], q[k])
                       : snprintf(buf + used, size - used, "%s%s = %.6g rad (%.4g deg)", sep, names[k], q[k],
                                  q[k] * (180.0 / 3.141592653589793));   /* math.degrees */
        if (n < 0) break;
        used += (size_t)n;
    }
    return buf;
}

/* rho as the direct kinematics' messages show it */
static inline const char *mast_fmt_rho(const double *rho, char *buf, size_t size)
{
    snprintf(buf, size, "%.9g, %.9g, %.9g", rho[0], rho[1], rho[2]);
    return buf;
}

/* Singular values of the 3x3 matrix a (row-major) by one-sided Jacobi rotations: smallest and largest */
static inline void mast_sv3(const double *a, double *smin, double *smax)
{
    double u[9];
    for (int k = 0; k < 9; k++) u[k] = a[k];
    for (int sweep = 0; sweep < 60; sweep++) {
        int rotated = 0;
        for (int p = 0; p < 2; p++) {
            for (int r = p + 1; r < 3; r++) {
                double al = 0.0, be = 0.0, ga = 0.0;
                for (int i = 0; i < 3; i++) {
                    al += u[i * 3 + p] * u[i * 3 + p];
                    be += u[i * 3 + r] * u[i * 3 + r];
                    ga += u[i * 3 + p] * u[i * 3 + r];
                }
                if (ga == 0.0 || fabs(ga) <= 1e-17 * sqrt(al * be)) continue;
                rotated = 1;
                double zeta = (be - al) / (2.0 * ga);
                double t = (zeta >= 0.0 ? 1.0 : -1.0) / (fabs(zeta) + sqrt(1.0 + zeta * zeta));
                double c = 1.0 / sqrt(1.0 + t * t), s = c * t;
                for (int i = 0; i < 3; i++) {
                    double x = u[i * 3 + p], y = u[i * 3 + r];
                    u[i * 3 + p] = c * x - s * y;
                    u[i * 3 + r] = s * x + c * y;
                }
            }
        }
        if (!rotated) break;
    }
    double lo = INFINITY, hi = 0.0;
    for (int j = 0; j < 3; j++) {
        double n = sqrt(u[j] * u[j] + u[3 + j] * u[3 + j] + u[6 + j] * u[6 + j]);
        if (n < lo) lo = n;
        if (n > hi) hi = n;
    }
    *smin = lo;
    *smax = hi;
}

/* Engine._check_branch's margin: 0 when the solution is at least ``margin`` [m/m] from a singularity
 * (margins of drho/dq with the coordinates scaled by ``lengths``, engine.margins_of), else 4 with ``msg``
 * (rho and q written only then: formatting them costs more than the Newton iteration) */
static inline int mast_check_margin(const double *Jinv, const double *J, double det, const double *lengths,
                                    double margin, const double *rho, const char *const *names, const double *q,
                                    char *msg, size_t size)
{
    double fa = 0.0, fb = 0.0, a[9], par, big;
    char shown[96], qs[160];
    for (int k = 0; k < 9; k++) {
        fa += Jinv[k] * Jinv[k] * (1.0 / (lengths[k % 3] * lengths[k % 3]));
        fb += J[k] * J[k] * (lengths[k / 3] * lengths[k / 3]);
    }
    if (fa * margin * margin <= 1.0 && fb * margin * margin <= 1.0) return 0;   /* cheap lower bounds */
    for (int k = 0; k < 9; k++) a[k] = Jinv[k] / lengths[k % 3];
    mast_sv3(a, &par, &big);
    double inv = 1.0 / big;
    if ((par < inv ? par : inv) >= margin) return 0;
    snprintf(msg, size, "direct kinematics for rho = (%s) m: the solution %s is within the margin of a %s singularity: "
             "margins parallel %.3g, inverse %.3g < %g m/m (det(drho/dq) = %+.3g; docs/mechanism.md, "
             "'Singularities and the assembly branch')", mast_fmt_rho(rho, shown, sizeof shown),
             mast_fmt_q(names, q, qs, sizeof qs),
             par < margin ? "parallel (the platform could move with the joints locked)"
                          : "inverse (a joint could move without moving the platform)", par, inv, margin, det);
    return 4;
}

/* The smallest eigenvalue of the symmetric 3x3 matrix a (row-major), by the trigonometric closed form
 * (engine.Body's check of an inertia tensor: numpy's eigvalsh there; they agree to rounding) */
static inline double mast_sym3_min_eig(const double *a)
{
    double p1 = a[1] * a[1] + a[2] * a[2] + a[5] * a[5];
    double tr = (a[0] + a[4] + a[8]) / 3.0;
    if (p1 == 0.0) {
        double lo = a[0] < a[4] ? a[0] : a[4];
        return lo < a[8] ? lo : a[8];
    }
    double d0 = a[0] - tr, d1 = a[4] - tr, d2 = a[8] - tr;
    double p = sqrt((d0 * d0 + d1 * d1 + d2 * d2 + 2.0 * p1) / 6.0);
    double b[9];
    for (int k = 0; k < 9; k++) b[k] = (a[k] - (k % 4 == 0 ? tr : 0.0)) / p;
    double r = (b[0] * (b[4] * b[8] - b[5] * b[7]) - b[1] * (b[3] * b[8] - b[5] * b[6])
                + b[2] * (b[3] * b[7] - b[4] * b[6])) / 2.0;
    double phi = r <= -1.0 ? 3.141592653589793 / 3.0 : (r >= 1.0 ? 0.0 : acos(r) / 3.0);
    return tr + 2.0 * p * cos(phi + 2.0 * 3.141592653589793 / 3.0);
}

/* Engine.dk for three coordinates ``names``: Newton on the inverse kinematics from ``q`` (the guess) until
 * max|rho(q) - rho| < tol; J = dq/drho. 0, MAST_KINEMATICS_ERROR (3) or, for a solution on another
 * assembly branch than the start or within ``margin`` of a singularity, MAST_SINGULARITY_ERROR (4),
 * with ``msg`` filled (Engine.dk's messages). */
static inline int mast_dk3(mast_ikjac3 ikjac, const double *P, mast_check_message why, const char *const *names,
                           const double *lengths, double margin, const double *rho, double *q, double *J,
                           double tol, int max_iter, double cond_limit, char *msg, size_t size)
{
    double out[12], e[3], res = INFINITY, det = 0.0, det0 = 0.0, cond, start[3] = {q[0], q[1], q[2]};
    char shown[96], qs[160], q0s[160];   /* the messages' texts, written only on a failure */
    for (int it = 0; it <= max_iter; it++) {
        int check = ikjac(P, q[0], q[1], q[2], out);
        if (check) {
            snprintf(msg, size, "direct kinematics did not converge for rho = (%s) m: iteration %d reached %s, where: %s",
                     mast_fmt_rho(rho, shown, sizeof shown), it, mast_fmt_q(names, q, qs, sizeof qs), why(-check));
            return 3;
        }
        for (int i = 0; i < 3; i++) e[i] = out[i] - rho[i];
        res = fabs(e[0]);
        if (fabs(e[1]) > res) res = fabs(e[1]);
        if (fabs(e[2]) > res) res = fabs(e[2]);
        if (!mast_inv3(out + 3, J, &det)) {
            snprintf(msg, size, "direct kinematics did not converge for rho = (%s) m: iteration %d reached %s, where: "
                     "singular configuration: drho/dq is singular at %s", mast_fmt_rho(rho, shown, sizeof shown), it,
                     mast_fmt_q(names, q, qs, sizeof qs), qs);
            return 3;
        }
        if (res < tol) {
            cond = mast_cond(out + 3, J, 9);
            if (!(cond < cond_limit)) {
                mast_fmt_q(names, q, qs, sizeof qs);
                snprintf(msg, size, "direct kinematics did not converge for rho = (%s) m: iteration %d reached %s, "
                         "where: singular configuration: drho/dq has condition number %.3g (limit %.0e) at %s",
                         mast_fmt_rho(rho, shown, sizeof shown), it, qs, cond, cond_limit, qs);
                return 3;
            }
        }
        if (!isfinite(res)) {
            snprintf(msg, size, "direct kinematics did not converge for rho = (%s) m: non-finite residual at iteration "
                     "%d (%s)", mast_fmt_rho(rho, shown, sizeof shown), it, mast_fmt_q(names, q, qs, sizeof qs));
            return 3;
        }
        if (it == 0) det0 = det;
        if (res < tol) {        /* Engine._check_branch: on the start's assembly branch, at least margin from a singularity */
            if ((det > 0.0) != (det0 > 0.0)) {
                mast_fmt_q(names, q, qs, sizeof qs);
                snprintf(msg, size, "direct kinematics for rho = (%s) m: the solution %s lies on another assembly "
                         "branch than the start %s (det(drho/dq) = %+.3g there, %+.3g at the start): the joints crossed "
                         "a parallel singularity; refused rather than jump to the other branch",
                         mast_fmt_rho(rho, shown, sizeof shown), qs,
                         mast_fmt_q(names, start, q0s, sizeof q0s), det, det0);
                return 4;
            }
            return mast_check_margin(out + 3, J, det, lengths, margin, rho, names, q, msg, size);
        }
        if (it == max_iter) break;
        for (int j = 0; j < 3; j++) {
            double s = 0.0;
            for (int k = 0; k < 3; k++) s += J[j * 3 + k] * e[k];
            q[j] -= s;
        }
    }
    snprintf(msg, size, "direct kinematics did not converge for rho = (%s) m: %d iterations, residual max|rho(q) - rho| "
             "= %.3g m > tol = %.3g m (last %s)", mast_fmt_rho(rho, shown, sizeof shown), max_iter, res, tol,
             mast_fmt_q(names, q, qs, sizeof qs));
    return 3;
}

/* exp(M) of the n x n row-major matrix M into E, the mathematics of the Python actuator's varying-step
 * route (fmus/actuator/model.py, _BalancedExp and _expm_taylor): M balanced by a diagonal similarity of
 * powers of two (D^-1 M D, exact; Parlett-Reinsch iteration as LAPACK gebal without permutation), then
 * scaling and squaring a degree-16 Taylor polynomial with ||X||_1 <= 1/2, then E = D exp(.) D^-1.
 * A matrix with a non-finite entry (parameters beyond floating point) gives NaN everywhere, as the
 * Python route's (the caller then refuses the step size). 0, or -1 when memory is short.
 * tests/test_native.py checks it against scipy.linalg.expm. */
static inline int mast_expm(int n, const double *M, double *E)
{
    size_t nn = (size_t)n * (size_t)n;
    double *X = malloc(3 * nn * sizeof(double) + (size_t)n * sizeof(double));
    if (!X) return -1;
    double *T = X + nn, *P = T + nn, *d = P + nn;
    memcpy(X, M, nn * sizeof(double));
    for (size_t k = 0; k < nn; k++) {
        if (!isfinite(X[k])) {
            for (size_t j = 0; j < nn; j++) E[j] = NAN;
            free(X);
            return 0;
        }
    }
    for (int i = 0; i < n; i++) d[i] = 1.0;
    for (int sweep = 0, done = 0; !done && sweep < 100; sweep++) {
        done = 1;
        for (int i = 0; i < n; i++) {
            double c = 0.0, r = 0.0;
            for (int j = 0; j < n; j++) {
                if (j == i) continue;
                c += fabs(X[(size_t)j * n + i]);
                r += fabs(X[(size_t)i * n + j]);
            }
            if (c == 0.0 || r == 0.0) continue;
            double g = r / 2.0, f = 1.0, s = c + r;
            while (c < g) { f *= 2.0; c *= 4.0; }
            g = r * 2.0;
            while (c > g) { f /= 2.0; c /= 4.0; }
            if ((c + r) / f < 0.95 * s) {
                done = 0;
                d[i] *= f;
                for (int j = 0; j < n; j++) X[(size_t)i * n + j] /= f;
                for (int j = 0; j < n; j++) X[(size_t)j * n + i] *= f;
            }
        }
    }
    double norm = 0.0;
    for (int j = 0; j < n; j++) {
        double col = 0.0;
        for (int i = 0; i < n; i++) col += fabs(X[(size_t)i * n + j]);
        if (col > norm) norm = col;
    }
    if (!isfinite(norm)) {           /* balanced beyond floating point */
        for (size_t j = 0; j < nn; j++) E[j] = NAN;
        free(X);
        return 0;
    }
    int squarings = norm > 0.5 ? (int)ceil(log2(norm / 0.5)) : 0;
    if (squarings < 0) squarings = 0;
    for (size_t k = 0; k < nn; k++) X[k] = ldexp(X[k], -squarings);
    for (size_t k = 0; k < nn; k++) E[k] = X[k] * (1.0 / 16.0);
    for (int i = 0; i < n; i++) E[(size_t)i * n + i] += 1.0;
    for (int k = 15; k >= 0; k--) {       /* Horner: E = I + X E / k */
        if (k == 0) break;
        for (int i = 0; i < n; i++)
            for (int j = 0; j < n; j++) {
                double acc = 0.0;
                for (int l = 0; l < n; l++) acc += X[(size_t)i * n + l] * E[(size_t)l * n + j];
                T[(size_t)i * n + j] = acc * (1.0 / k);
            }
        for (int i = 0; i < n; i++) T[(size_t)i * n + i] += 1.0;
        memcpy(E, T, nn * sizeof(double));
    }
    for (int q = 0; q < squarings; q++) {
        for (int i = 0; i < n; i++)
            for (int j = 0; j < n; j++) {
                double acc = 0.0;
                for (int l = 0; l < n; l++) acc += E[(size_t)i * n + l] * E[(size_t)l * n + j];
                P[(size_t)i * n + j] = acc;
            }
        memcpy(E, P, nn * sizeof(double));
    }
    for (int i = 0; i < n; i++)
        for (int j = 0; j < n; j++) E[(size_t)i * n + j] /= d[j] / d[i];
    free(X);
    return 0;
}

/* The largest eigenvalue of the symmetric n x n row-major matrix S (destroyed), by cyclic Jacobi rotations:
 * chain_frequencies (fmus/actuator/model.py) takes it from LAPACK's eigvalsh. */
static inline double mast_eig_max(int n, double *S)
{
    for (int sweep = 0; sweep < 100; sweep++) {
        double off = 0.0, diag = 0.0;
        for (int i = 0; i < n; i++) {
            diag += S[i * n + i] * S[i * n + i];
            for (int j = i + 1; j < n; j++) off += S[i * n + j] * S[i * n + j];
        }
        if (off <= 1e-36 * diag) break;
        for (int p = 0; p < n - 1; p++)
            for (int q = p + 1; q < n; q++) {
                double apq = S[p * n + q];
                if (apq == 0.0) continue;
                double theta = (S[q * n + q] - S[p * n + p]) / (2.0 * apq);
                double t = (theta >= 0.0 ? 1.0 : -1.0) / (fabs(theta) + sqrt(theta * theta + 1.0));
                double c = 1.0 / sqrt(t * t + 1.0), s = t * c;
                for (int k = 0; k < n; k++) {      /* S <- S R (columns p, q) */
                    double kp = S[k * n + p], kq = S[k * n + q];
                    S[k * n + p] = c * kp - s * kq;
                    S[k * n + q] = s * kp + c * kq;
                }
                for (int k = 0; k < n; k++) {      /* S <- R^T S (rows p, q) */
                    double pk = S[p * n + k], qk = S[q * n + k];
                    S[p * n + k] = c * pk - s * qk;
                    S[q * n + k] = s * pk + c * qk;
                }
            }
    }
    double top = n ? S[0] : 0.0;
    for (int i = 1; i < n; i++) if (S[i * n + i] > top) top = S[i * n + i];
    return top;
}

/* _parse_list (fmus/actuator/model.py): ``count`` numbers separated by blanks or commas, each finite and
 * > 0 (``positive``) or >= 0, into ``out``. 0; -1 when there are not ``count`` items (*items: how many);
 * k + 1 when item k is not a finite number of that kind (its text in ``item``, ``size`` bytes). */
static inline int mast_parse_list(const char *text, int count, int positive, double *out, int *items, char *item,
                                  size_t size)
{
    const char *blank = " ,\t\n\r\f\v";
    const char *s = text ? text : "";
    int n = 0;
    for (const char *c = s; *c;) {
        c += strspn(c, blank);
        if (!*c) break;
        n++;
        c += strcspn(c, blank);
    }
    *items = n;
    if (n != count) return -1;
    int k = 0;
    for (const char *c = s; *c && k < count; k++) {
        c += strspn(c, blank);
        size_t len = strcspn(c, blank);
        char token[64];
        char *end = NULL;
        double v = NAN;
        if (len < sizeof token) {
            memcpy(token, c, len);
            token[len] = '\0';
            v = strtod(token, &end);
            if (end != token + len) v = NAN;
        }
        if (!isfinite(v) || (positive ? v <= 0.0 : v < 0.0)) {
            snprintf(item, size, "%.*s", (int)len, c);
            return k + 1;
        }
        out[k] = v;
        c += len;
    }
    return 0;
}

#endif
