"""Small fixed-size linear algebra in a written-out order of operations: the same floats on every machine.

numpy's ``@``/``dot``/``matmul`` on float arrays, ``numpy.linalg`` and ``scipy.linalg`` call BLAS and LAPACK,
whose kernels are chosen at run time for the CPU (or by ``OPENBLAS_CORETYPE``) and sum in different orders:
the same product differs in its last bits between two machines, and a closed loop that hunts (backlash)
turns that into another trajectory. Here every sum runs in increasing index order from 0.0, each product
and sum a single exactly rounded IEEE operation (numpy's elementwise ``*``, ``+``, ``/``, or Python floats),
so the result depends on nothing but the inputs. The functions compute the same floats, operation for
operation, as the native FMUs' C (``mast_expm``, ``mast_eig_max`` in fmus/common/native/mast_native.h,
built with ``-ffp-contract=off``): the Python and the native actuator discretise with the same digits.
"""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np

__all__ = ["matmul", "balance", "expm", "eig_max"]


def matmul(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """A B of 2-D float arrays: out[i, j] = ((0.0 + A[i, 0] B[0, j]) + A[i, 1] B[1, j]) + ..., in that order."""
    out = np.zeros((A.shape[0], B.shape[1]))
    for k in range(A.shape[1]):
        out += A[:, k, None] * B[None, k, :]
    return out


def balance(M: np.ndarray) -> np.ndarray:
    """Scales d (powers of two) with D^-1 M D balanced (D = diag(d)): the Parlett-Reinsch iteration in the 1-norm
    of the off-diagonal rows and columns, without permutation (LAPACK gebal's mathematics before LAPACK 3.5,
    which uses 2-norms computed by BLAS). M's entries must be finite."""
    n = len(M)
    X = [[float(v) for v in row] for row in M]
    d = [1.0] * n
    for _ in range(100):
        done = True
        for i in range(n):
            c = r = 0.0
            for j in range(n):
                if j != i:
                    c += abs(X[j][i])
                    r += abs(X[i][j])
            if c == 0.0 or r == 0.0:
                continue
            g, f, s = r / 2.0, 1.0, c + r
            while c < g:
                f *= 2.0
                c *= 4.0
            g = r * 2.0
            while c > g:
                f /= 2.0
                c /= 4.0
            if (c + r) / f < 0.95 * s:
                done = False
                d[i] *= f
                for j in range(n):
                    X[i][j] /= f
                for j in range(n):
                    X[j][i] *= f
        if done:
            break
    return np.array(d)


def expm(M: np.ndarray) -> np.ndarray:
    """exp(M) of a small square matrix: balanced (``balance``: D^-1 M D, exact), scaled by 2^-s so that its
    1-norm is at most 1/2, a degree-16 Taylor polynomial by Horner (E = I + X E / k, k = 15 .. 1, truncation
    below 0.5^17 / 17! ~ 2e-20), s squarings, then D exp(.) D^-1. About 1e-13 relative to scipy's Pade route
    on the actuator's matrices (tests/test_fixed_order.py). A non-finite entry gives NaN everywhere."""
    M = np.asarray(M, dtype=float)
    n = len(M)
    if not np.isfinite(M).all():
        return np.full((n, n), np.nan)
    d = balance(M)
    ratio = d[None, :] / d[:, None]
    X = M * ratio
    col = np.zeros(n)
    for i in range(n):
        col += np.abs(X[i])
    norm = float(col.max(initial=0.0))
    if not math.isfinite(norm):
        return np.full((n, n), np.nan)
    squarings = max(0, math.ceil(math.log2(norm / 0.5))) if norm > 0.5 else 0
    X = np.ldexp(X, -squarings)
    diagonal = np.diag_indices(n)
    E = X * (1.0 / 16.0)
    E[diagonal] += 1.0
    for k in range(15, 0, -1):
        E = matmul(X, E)
        E *= 1.0 / k
        E[diagonal] += 1.0
    for _ in range(squarings):
        E = matmul(E, E)
    return E / ratio


def eig_max(S: Sequence[Sequence[float]]) -> float:
    """The largest eigenvalue of a small symmetric matrix, by cyclic Jacobi rotations (to an off-diagonal
    square sum below 1e-36 of the diagonal's)."""
    n = len(S)
    S = [[float(v) for v in row] for row in S]
    sqrt = math.sqrt
    for _ in range(100):
        off = diag = 0.0
        for i in range(n):
            diag += S[i][i] * S[i][i]
            for j in range(i + 1, n):
                off += S[i][j] * S[i][j]
        if off <= 1e-36 * diag:
            break
        for p in range(n - 1):
            for q in range(p + 1, n):
                apq = S[p][q]
                if apq == 0.0:
                    continue
                theta = (S[q][q] - S[p][p]) / (2.0 * apq)
                t = (1.0 if theta >= 0.0 else -1.0) / (abs(theta) + sqrt(theta * theta + 1.0))
                c = 1.0 / sqrt(t * t + 1.0)
                s = t * c
                for row in S:  # S <- S R (columns p, q)
                    kp, kq = row[p], row[q]
                    row[p] = c * kp - s * kq
                    row[q] = s * kp + c * kq
                rp, rq = S[p], S[q]  # S <- R^T S (rows p, q)
                for k in range(n):
                    pk, qk = rp[k], rq[k]
                    rp[k] = c * pk - s * qk
                    rq[k] = s * pk + c * qk
    top = S[0][0] if n else 0.0
    for i in range(1, n):
        if S[i][i] > top:
            top = S[i][i]
    return top
