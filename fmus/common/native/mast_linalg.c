/* Matrix helpers of the native models (mast_linalg.h). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "mast_linalg.h"

int mast_inv(int n, const double *m, double *inv, double *det_out)
{
    if (n == 3) return mast_inv3(m, inv, det_out);
    if (n < 1 || n > MAST_LINALG_N_MAX) return 0;
    double a[MAST_LINALG_N_MAX][2 * MAST_LINALG_N_MAX], det = 1.0;
    for (int r = 0; r < n; r++)           /* [m | I] */
        for (int c = 0; c < 2 * n; c++) a[r][c] = c < n ? m[r * n + c] : (c - n == r ? 1.0 : 0.0);
    for (int c = 0; c < n; c++) {
        int p = c;                        /* the first row of the largest |a[r][c]|, as Python's max */
        for (int r = c + 1; r < n; r++) if (fabs(a[r][c]) > fabs(a[p][c])) p = r;
        if (a[p][c] == 0.0) return 0;
        if (p != c) {
            for (int k = 0; k < 2 * n; k++) { double t = a[c][k]; a[c][k] = a[p][k]; a[p][k] = t; }
            det = -det;
        }
        double piv = a[c][c];
        det *= piv;
        for (int k = 0; k < 2 * n; k++) a[c][k] = a[c][k] / piv;
        for (int r = 0; r < n; r++) {
            if (r != c && a[r][c] != 0.0) {
                double f = a[r][c];
                for (int k = 0; k < 2 * n; k++) a[r][k] = a[r][k] - f * a[c][k];
            }
        }
    }
    for (int r = 0; r < n; r++)
        for (int c = 0; c < n; c++) inv[r * n + c] = a[r][n + c];
    *det_out = det;
    return 1;
}

void mast_sv_extremes(int n, const double *a, double *smin, double *smax)
{
    double u[MAST_LINALG_N_MAX * MAST_LINALG_N_MAX];
    if (n < 1 || n > MAST_LINALG_N_MAX) { *smin = NAN; *smax = NAN; return; }
    for (int k = 0; k < n * n; k++) u[k] = a[k];
    for (int sweep = 0; sweep < 60; sweep++) {
        int rotated = 0;
        for (int p = 0; p < n - 1; p++) {
            for (int r = p + 1; r < n; r++) {
                double al = 0.0, be = 0.0, ga = 0.0;
                for (int i = 0; i < n; i++) {
                    al += u[i * n + p] * u[i * n + p];
                    be += u[i * n + r] * u[i * n + r];
                    ga += u[i * n + p] * u[i * n + r];
                }
                if (ga == 0.0 || fabs(ga) <= 1e-17 * sqrt(al * be)) continue;
                rotated = 1;
                double zeta = (be - al) / (2.0 * ga);
                double t = (zeta >= 0.0 ? 1.0 : -1.0) / (fabs(zeta) + sqrt(1.0 + zeta * zeta));
                double c = 1.0 / sqrt(1.0 + t * t), s = c * t;
                for (int i = 0; i < n; i++) {
                    double x = u[i * n + p], y = u[i * n + r];
                    u[i * n + p] = c * x - s * y;
                    u[i * n + r] = s * x + c * y;
                }
            }
        }
        if (!rotated) break;
    }
    double lo = INFINITY, hi = 0.0;
    for (int j = 0; j < n; j++) {         /* the columns' norms: the singular values */
        double s = 0.0;
        for (int i = 0; i < n; i++) s += u[i * n + j] * u[i * n + j];
        double norm = sqrt(s);
        if (norm < lo) lo = norm;
        if (norm > hi) hi = norm;
    }
    *smin = lo;
    *smax = hi;
}

/* The smallest eigenvalue of the symmetric 3x3 matrix a (row-major), by the trigonometric closed form
 * (engine.Body's check of an inertia tensor: numpy's eigvalsh there; they agree to rounding) */
double mast_sym3_min_eig(const double *a)
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

int mast_expm(int n, const double *M, double *E)
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

double mast_eig_max(int n, double *S)
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

