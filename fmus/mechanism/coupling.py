"""The mechanism's condensed interface to its drives: what each drive carries and what it is told, per exchange.

The monolithic joint-space equations of n drives on a mechanism are

    (M + m) rho_ddot = T - b

M [kg] the mechanism's joint-space mass matrix (n x n), b [N] its bias (Coriolis, centrifugal, gravity),
m = diag(m_1..m_n) [kg] the drives' load-side masses (the inertia their transmission force accelerates, as a
mass along the guide) and T [N] the drives' forces on their load sides, everything but the load side's own
inertia and the mechanism (spring and damper of the transmission, or the motor's torque through a rigid one;
guide friction, weight). A rotary drive reads kg m^2 and N m.

A co-simulation splits the drives from the mechanism: each drive integrates its own load side, so the force
the mechanism returns reaches it one exchange late. Returned as F = M rho_ddot + b (the inertial reaction of
the accelerations of the last exchange), it is a delayed feedback of the drives' own accelerations with gain
-M/m, which diverges once the mechanism outweighs the drives (the added-mass instability of partitioned
coupling). Condensed instead, each drive k carries on its load side the mass the rest of the system presents
to it, and is told the rest of the force:

    F_k = c_k + D_k rho_ddot_k,   Y = (M + m)^-1,   D_k = 1 / Y_kk - m_k,
    c_k = b_k + sum_(j != k) W_kj (T_j - b_j),      W_kj = -Y_kj / Y_kk,

which is the monolithic solution exactly while the drive forces T hold still (the Schur complement of the
other drives' rows). What stays delayed is T of the other drives: a belt's spring force oscillates at the
belt's mode, near 1 kHz on the MAST's axes, and a spring force one exchange late feeds that mode energy.
Extrapolated by its first two derivatives to the middle of the exchange in which the drive applies it (1.5
exchanges after it was sampled, ``EXTRAPOLATION``), the delay leaves no energy in the mode
(docs/coupling.md gives the analysis and its figures).
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

__all__ = ["EXTRAPOLATION", "condense", "condensation", "condensed_forces", "extrapolated"]

#: how far ahead the drive forces are extrapolated, in exchange steps: sampled at t_n, they reach the mechanism
#: in its step from t_n, whose output a drive applies over [t_(n+1), t_(n+2)], centred 1.5 steps after t_n
EXTRAPOLATION = 1.5


def condense(M: Sequence[float], m: Sequence[float]) -> tuple[list[float], list[float]]:
    """The condensed interface of the joint-space mass ``M`` [kg] (n x n, row-major) to drives of load-side masses
    ``m`` [kg] (each > 0): (W, D), the weights W (n x n row-major, zero diagonal) of the other drives' forces in each
    drive's force and the masses D [kg] each drive carries (module docstring). Y = (M + m)^-1 by Gauss-Jordan
    without pivoting (M + m is symmetric positive definite), in a fixed order of operations: the native mechanism
    computes the same floats (mast_mechanism.c)."""
    n = len(m)
    A = [[M[i * n + j] + (m[i] if i == j else 0.0) for j in range(n)] + [1.0 if i == j else 0.0 for j in range(n)]
         for i in range(n)]  # fmt: skip
    for k in range(n):
        inv = 1.0 / A[k][k]
        A[k] = [v * inv for v in A[k]]
        for i in range(n):
            if i != k:
                f = A[i][k]
                A[i] = [v - f * w for v, w in zip(A[i], A[k])]
    W = [0.0 if i == j else -A[i][n + j] / A[i][n + i] for i in range(n) for j in range(n)]
    return W, [1.0 / A[i][n + i] - m[i] for i in range(n)]


def condensation(M: np.ndarray, m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``condense`` of arrays, checked: (W (n x n), D (n)) for the joint-space mass ``M`` [kg] and the load-side
    masses ``m`` [kg]."""
    M = np.asarray(M, dtype=float)
    m = np.asarray(m, dtype=float)
    if M.shape != (len(m), len(m)):
        raise ValueError(f"joint-space mass of shape {M.shape}: expected ({len(m)}, {len(m)}) for {len(m)} drives")
    if not np.all(m > 0.0):
        raise ValueError(f"load-side masses {m.tolist()}: expected every one > 0 kg")
    W, D = condense(M.ravel().tolist(), m.tolist())
    return np.array(W).reshape(len(m), len(m)), np.array(D)


def condensed_forces(b: np.ndarray, T: np.ndarray, W: np.ndarray) -> np.ndarray:
    """c [N] (n): the force each drive is told, the bias ``b`` [N] plus the weights ``W`` of the other drives'
    forces ``T`` [N] net of their bias (module docstring)."""
    b = np.asarray(b, dtype=float)
    return b + W @ (np.asarray(T, dtype=float) - b)


def extrapolated(T: np.ndarray, T_dot: np.ndarray, T_ddot: np.ndarray, tau: float) -> np.ndarray:
    """The drive forces ``T`` [N] ``tau`` [s] ahead by their second-order Taylor series (``T_dot`` [N/s],
    ``T_ddot`` [N/s^2])."""
    return np.asarray(T) + tau * np.asarray(T_dot) + 0.5 * tau * tau * np.asarray(T_ddot)
