/* The direct kinematics of the native models (mast_dk.c): Newton's method on a mechanism's traced inverse
 * kinematics for n coordinates, with the assembly branch kept and the singularity margins checked, as
 * fmus/mechanism/engine.py's Engine.dk (_newton, _check_branch, margins) does it, with its messages. */
#ifndef MAST_DK_H
#define MAST_DK_H

#include <stddef.h>

/* the most coordinates a mechanism has here (the pose's six) */
#define MAST_DK_N_MAX 6

/* generated: rho (n) and drho/dq (n x n, row-major) at q into out; ``model``: what the function reads besides q
 * (the traced parameters and what they alone fix). 0, or -N when the description's check N failed. */
typedef int (*mast_ikjac)(const void *model, const double *q, double *out);
/* generated: the message of the description's failed check N */
typedef const char *(*mast_check_message)(int check);

/* A mechanism's direct kinematics: Engine's n, its traced ikjac, its coordinates' names, ``lengths`` [m]
 * (Engine.lengths: the margins compare motions), ``margin`` [m/m] (Engine.margin), ``cond_limit``
 * (Engine.cond_limit), Newton's tolerance [m] and its iterations (Engine.dk's tol, max_iter). */
typedef struct {
    int n;
    mast_ikjac ikjac;
    const void *model;
    mast_check_message why;
    const char *const *names;
    const double *lengths;
    double margin, cond_limit, tol;
    int max_iter;
} mast_dk_problem;

/* Engine.dk: Newton from the guess ``q`` (n) until max|rho(q) - rho| < tol; q the solution, J = dq/drho (n x n).
 * 0, MAST_KINEMATICS_ERROR (3) or, for a solution on another assembly branch than the start or within
 * ``margin`` of a singularity, MAST_SINGULARITY_ERROR (4), with ``msg`` filled (Engine.dk's messages). */
int mast_dk(const mast_dk_problem *dk, const double *rho, double *q, double *J, char *msg, size_t size);

/* Engine._fmt_q: "z = 0.25 m, psi = 0.3 rad (17.19 deg), ..." (coordinates z, x, y in m, the others angles) */
const char *mast_fmt_q(int n, const char *const *names, const double *q, char *buf, size_t size);

#endif
