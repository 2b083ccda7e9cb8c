/* The direct kinematics of the native models (mast_dk.h): engine.py's Engine._newton, _check_branch and
 * margins for n coordinates, the same operations in the same order, so the floats agree with the Python
 * engine (the inverse of drho/dq: mast_inv, as engine._inv). */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "mast_dk.h"
#include "mast_linalg.h"
#include "mast_model.h"

/* the functions inlined with a constant n (mast_dk's cases): the compiler unrolls their loops */
#if defined(__GNUC__)
#define ALWAYS_INLINE inline __attribute__((always_inline))
#else
#define ALWAYS_INLINE inline
#endif

const char *mast_fmt_q(int n, const char *const *names, const double *q, char *buf, size_t size)
{
    size_t used = 0;
    buf[0] = '\0';
    for (int k = 0; k < n && used < size; k++) {
        const char *sep = k ? ", " : "";
        int metres = !strcmp(names[k], "z") || !strcmp(names[k], "x") || !strcmp(names[k], "y");
        int w = metres ? snprintf(buf + used, size - used, "%s%s = %.6g m", sep, names[k], q[k])
                       : snprintf(buf + used, size - used, "%s%s = %.6g rad (%.4g deg)", sep, names[k], q[k],
                                  q[k] * (180.0 / 3.141592653589793));   /* math.degrees */
        if (w < 0) break;
        used += (size_t)w;
    }
    return buf;
}

/* engine._shown: rho as the direct kinematics' messages show it */
static const char *fmt_rho(int n, const double *rho, char *buf, size_t size)
{
    size_t used = 0;
    buf[0] = '\0';
    for (int k = 0; k < n && used < size; k++) {
        int w = snprintf(buf + used, size - used, "%s%.9g", k ? ", " : "", rho[k]);
        if (w < 0) break;
        used += (size_t)w;
    }
    return buf;
}

/* Engine._check_branch's margins: 0 when the solution is at least ``margin`` [m/m] from a singularity (the
 * singular values of drho/dq with the coordinates scaled by ``lengths``, engine.margins_of), else
 * MAST_SINGULARITY_ERROR with ``msg`` (rho and q written only then: formatting costs more than the iteration) */
static ALWAYS_INLINE int check_margin(const mast_dk_problem *dk, const int n, const double *Jinv, const double *J,
                                      double det, const double *rho, const double *q, char *msg, size_t size)
{
    const double *l = dk->lengths;
    double fa = 0.0, fb = 0.0, a[MAST_DK_N_MAX * MAST_DK_N_MAX], par, big, m = dk->margin;
    char shown[256], qs[512];
    for (int k = 0; k < n * n; k++) {
        fa += Jinv[k] * Jinv[k] * (1.0 / (l[k % n] * l[k % n]));
        fb += J[k] * J[k] * (l[k / n] * l[k / n]);
    }
    /* cheap lower bounds first: sigma_min(A) >= 1 / |A^-1|_F (exact singular values only near the limit) */
    if (fa * m * m <= 1.0 && fb * m * m <= 1.0) return MAST_OK;
    for (int k = 0; k < n * n; k++) a[k] = Jinv[k] / l[k % n];
    mast_sv_extremes(n, a, &par, &big);
    double inv = 1.0 / big;
    if ((par < inv ? par : inv) >= m) return MAST_OK;
    snprintf(msg, size, "direct kinematics for rho = (%s) m: the solution %s is within the margin of a %s singularity: "
             "margins parallel %.3g, inverse %.3g < %g m/m (det(drho/dq) = %+.3g; docs/mechanism.md, "
             "'Singularities and the assembly branch')", fmt_rho(n, rho, shown, sizeof shown),
             mast_fmt_q(n, dk->names, q, qs, sizeof qs),
             par < m ? "parallel (the platform could move with the joints locked)"
                     : "inverse (a joint could move without moving the platform)", par, inv, m, det);
    return MAST_SINGULARITY_ERROR;
}

/* mast_dk for n coordinates (ALWAYS_INLINE) */
static ALWAYS_INLINE int newton(const mast_dk_problem *dk, const int n, const double *rho, double *q, double *J,
                                char *msg, size_t size)
{
    enum { NM = MAST_DK_N_MAX };
    double out[NM + NM * NM], e[NM], start[NM], res = INFINITY, det = 0.0, det0 = 0.0, cond;
    char shown[256], qs[512], q0s[512];   /* the messages' texts, written only on a failure */
    for (int k = 0; k < n; k++) start[k] = q[k];
    for (int it = 0; it <= dk->max_iter; it++) {
        int check = dk->ikjac(dk->model, q, out);
        if (check) {
            snprintf(msg, size, "direct kinematics did not converge for rho = (%s) m: iteration %d reached %s, where: %s",
                     fmt_rho(n, rho, shown, sizeof shown), it, mast_fmt_q(n, dk->names, q, qs, sizeof qs),
                     dk->why(-check));
            return MAST_KINEMATICS_ERROR;
        }
        for (int i = 0; i < n; i++) e[i] = out[i] - rho[i];
        res = fabs(e[0]);
        for (int i = 1; i < n; i++) if (fabs(e[i]) > res) res = fabs(e[i]);
        if (!(n == 3 ? mast_inv3(out + n, J, &det) : mast_inv(n, out + n, J, &det))) {
            snprintf(msg, size, "direct kinematics did not converge for rho = (%s) m: iteration %d reached %s, where: "
                     "singular configuration: drho/dq is singular at %s", fmt_rho(n, rho, shown, sizeof shown), it,
                     mast_fmt_q(n, dk->names, q, qs, sizeof qs), qs);
            return MAST_KINEMATICS_ERROR;
        }
        if (res < dk->tol) {
            cond = mast_cond(out + n, J, n * n);
            if (!(cond < dk->cond_limit)) {
                mast_fmt_q(n, dk->names, q, qs, sizeof qs);
                snprintf(msg, size, "direct kinematics did not converge for rho = (%s) m: iteration %d reached %s, "
                         "where: singular configuration: drho/dq has condition number %.3g (limit %.0e) at %s",
                         fmt_rho(n, rho, shown, sizeof shown), it, qs, cond, dk->cond_limit, qs);
                return MAST_KINEMATICS_ERROR;
            }
        }
        if (!isfinite(res)) {
            snprintf(msg, size, "direct kinematics did not converge for rho = (%s) m: non-finite residual at iteration "
                     "%d (%s)", fmt_rho(n, rho, shown, sizeof shown), it, mast_fmt_q(n, dk->names, q, qs, sizeof qs));
            return MAST_KINEMATICS_ERROR;
        }
        if (it == 0) det0 = det;
        if (res < dk->tol) {    /* Engine._check_branch: on the start's assembly branch, at least margin from a singularity */
            if ((det > 0.0) != (det0 > 0.0)) {
                mast_fmt_q(n, dk->names, q, qs, sizeof qs);
                snprintf(msg, size, "direct kinematics for rho = (%s) m: the solution %s lies on another assembly "
                         "branch than the start %s (det(drho/dq) = %+.3g there, %+.3g at the start): the joints crossed "
                         "a parallel singularity; refused rather than jump to the other branch",
                         fmt_rho(n, rho, shown, sizeof shown), qs,
                         mast_fmt_q(n, dk->names, start, q0s, sizeof q0s), det, det0);
                return MAST_SINGULARITY_ERROR;
            }
            return check_margin(dk, n, out + n, J, det, rho, q, msg, size);
        }
        if (it == dk->max_iter) break;
        for (int j = 0; j < n; j++) {
            double s = 0.0;
            for (int k = 0; k < n; k++) s += J[j * n + k] * e[k];
            q[j] -= s;
        }
    }
    snprintf(msg, size, "direct kinematics did not converge for rho = (%s) m: %d iterations, residual max|rho(q) - rho| "
             "= %.3g m > tol = %.3g m (last %s)", fmt_rho(n, rho, shown, sizeof shown), dk->max_iter, res, dk->tol,
             mast_fmt_q(n, dk->names, q, qs, sizeof qs));
    return MAST_KINEMATICS_ERROR;
}

int mast_dk(const mast_dk_problem *dk, const double *rho, double *q, double *J, char *msg, size_t size)
{
    switch (dk->n) {     /* the 3-drive and 6-drive mechanisms with n a constant: their loops unrolled */
    case 3: return newton(dk, 3, rho, q, J, msg, size);
    case 6: return newton(dk, 6, rho, q, J, msg, size);
    }
    if (dk->n < 1 || dk->n > MAST_DK_N_MAX) {
        snprintf(msg, size, "direct kinematics: %d coordinates, this native runtime takes 1 to %d (MAST_DK_N_MAX)",
                 dk->n, MAST_DK_N_MAX);
        return MAST_KINEMATICS_ERROR;
    }
    return newton(dk, dk->n, rho, q, J, msg, size);
}
