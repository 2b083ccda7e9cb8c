/* Matrix helpers of the native models (mast_linalg.c): n x n row-major matrices of doubles, each routine
 * the same operations in the same order as the Python it mirrors (named at each), so the floats agree. */
#ifndef MAST_LINALG_H
#define MAST_LINALG_H

#include <math.h>

/* the largest n the routines with work arrays on the stack take (mast_inv, mast_sv_extremes) */
#define MAST_LINALG_N_MAX 12

/* engine._inv: inverse (row-major) and determinant of the n x n matrix m; for n = 3 kinematics.inv3 (cofactors),
 * else Gauss-Jordan elimination with partial pivoting. 0 when the matrix is singular (Python: ZeroDivisionError)
 * or n is above MAST_LINALG_N_MAX, else 1. */
int mast_inv(int n, const double *m, double *inv, double *det);

/* kinematics.inv3: cofactors, then 1 / det (mast_inv for n = 3; inline: the direct kinematics' Newton steps) */
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

/* engine._cond: Frobenius condition number |m|_F |m^-1|_F of the matrices m, minv of n2 entries (inline: with a
 * constant n2 its loops unroll) */
static inline double mast_cond(const double *m, const double *minv, int n2)
{
    double s = 0.0, t = 0.0;
    for (int k = 0; k < n2; k++) s += m[k] * m[k];
    for (int k = 0; k < n2; k++) t += minv[k] * minv[k];
    return sqrt(s) * sqrt(t);
}

/* The smallest and largest singular values of the n x n matrix a (row-major), by one-sided Jacobi rotations
 * (engine.margins_of takes them from LAPACK's svd: they agree to rounding) */
void mast_sv_extremes(int n, const double *a, double *smin, double *smax);

/* The smallest eigenvalue of the symmetric 3x3 matrix a (row-major), by the trigonometric closed form
 * (engine.Body's check of an inertia tensor: numpy's eigvalsh there; they agree to rounding) */
double mast_sym3_min_eig(const double *a);

/* exp(M) of the n x n row-major matrix M into E, the mathematics of the Python actuator's varying-step
 * route (fmus/actuator/model.py; fmus/common/fixed_order.expm, the same operations): M balanced by a diagonal
 * similarity of powers of two (D^-1 M D, exact; Parlett-Reinsch iteration as LAPACK gebal without permutation),
 * then scaling and squaring a degree-16 Taylor polynomial with ||X||_1 <= 1/2, then E = D exp(.) D^-1.
 * A matrix with a non-finite entry (parameters beyond floating point) gives NaN everywhere, as the
 * Python route's (the caller then refuses the step size). 0, or -1 when memory is short.
 * tests/test_native.py checks it against scipy.linalg.expm. */
int mast_expm(int n, const double *M, double *E);

/* The largest eigenvalue of the symmetric n x n matrix S (destroyed), by cyclic Jacobi rotations
 * (fixed_order.eig_max's arithmetic; chain_frequencies takes it from LAPACK's eigvalsh) */
double mast_eig_max(int n, double *S);

#endif
