"""Linear stability of the drive-mechanism exchange: which coupling a fixed-step host can run, at which masses.

The drives and the mechanism linearised about a pose (the mechanism's joint-space mass M there, no bias), each
drive its transmission chain from ``fmus.actuator.model.state_matrices`` with a motor-side PD loop for the
position and velocity controllers (an ideal current loop, tuned to ``BANDWIDTH`` on the inertia the drive
moves, so that the monolithic system is asymptotically stable), stepped as a fixed-step host steps the FMUs:
every drive over [t_n, t_n + h] with the mechanism's output of t_n held, the mechanism from the drives'
outputs of t_n. The exchange is one linear map of (the drives' states, the mechanism's outputs of the last two
exchanges); it grows without bound where its spectral radius exceeds 1.

Schemes (``SCHEMES``; fmus/mechanism/coupling.py):

- ``acceleration``: the mechanism returns F = M rho_ddot from the drives' accelerations, each drive carries
  nothing (the exchange of today's FMUs);
- ``condensed``: each drive carries D_k on its load side, held as the force D_k times its mean acceleration
  over the step (implicit, as its friction), and is told c = W T from the other drives' forces T;
- ``extrapolated``: ``condensed`` with T extrapolated by its first two derivatives (``coupling.EXTRAPOLATION``
  steps ahead).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping

import numpy as np
from scipy.linalg import expm

from fmus.actuator.model import chain, state_matrices, transmission_ratio
from fmus.mechanism.coupling import EXTRAPOLATION, condensation, extrapolated
from fmus.mechanism.designs import engine

__all__ = ["BANDWIDTH", "SCHEMES", "Drive", "Exchange", "exchange", "joint_space_mass"]

#: Hz: the motor-side loop's bandwidth (the order of the MAST's position loop; any stabilising loop will do)
BANDWIDTH = 30.0
SCHEMES = ("acceleration", "condensed", "extrapolated")


@dataclass(frozen=True)
class Drive:
    """One drive's linear model at the motor shaft: dx/dt = A x + B tau_L, x = [theta_1..N, omega_1..N] [rad,
    rad/s], tau_L [N m] the torque on the last inertia from outside (-i_R F for a force F [N] on the load side);
    ``T`` [N m/rad...] the row giving the drive force on the load side from x; ``m`` [kg] the load-side mass."""

    A: np.ndarray
    B: np.ndarray
    T: np.ndarray
    m: float
    i_R: float

    @classmethod
    def of(cls, params: Mapping[str, object], carried: float = 0.0, bandwidth: float = BANDWIDTH) -> "Drive":
        """The drive of an actuator parameter set, its loop tuned for ``bandwidth`` [Hz] on the inertia it moves
        with ``carried`` [kg] of the mechanism on its load side."""
        J, K, C = chain(params)
        A, B, _ = state_matrices(params, (J, K, C))
        N = len(J)
        i_R = transmission_ratio(float(params["p"]), float(params["i_r"]))
        A_m = A[1:, 1:].copy()  # the current is the ideal loop's: the motor torque is -k_p theta_1 - k_d omega_1
        J_total = sum(J) + carried * i_R * i_R
        w = 2.0 * math.pi * bandwidth
        A_m[N, 0] -= J_total * w * w / J[0]
        A_m[N, N] -= 2.0 * 0.7 * w * J_total / J[0]
        T = J[-1] * A_m[2 * N - 1] / i_R  # the last inertia's torques but the outside one, as a force on the load side
        return cls(A_m, B[1:, 1].copy(), T, J[-1] / (i_R * i_R), i_R)


@dataclass(frozen=True)
class Exchange:
    """The exchange's linear map and its growth: ``radius`` its spectral radius per step, ``frequency`` [Hz] the
    frequency of the mode that has it (0: a real mode)."""

    radius: float
    frequency: float
    matrix: np.ndarray


def exchange(M: np.ndarray, drives: list[Mapping[str, object]], scheme: str, h: float = 1e-4) -> Exchange:
    """The exchange of the drives of parameter sets ``drives`` on a mechanism of joint-space mass ``M`` [kg] by
    ``scheme`` (``SCHEMES``) at the step ``h`` [s] (module docstring)."""
    if scheme not in SCHEMES:
        raise ValueError(f"scheme {scheme!r}: expected one of {', '.join(SCHEMES)}")
    M = np.asarray(M, dtype=float)
    n = len(drives)
    bare = [Drive.of(p) for p in drives]
    m = np.array([d.m for d in bare])
    if scheme == "acceleration":
        W, D = None, np.zeros(n)
    else:
        W, D = condensation(M, m)
    models = [Drive.of(p, carried) for p, carried in zip(drives, D)]
    sizes = [len(d.B) for d in models]
    offsets = np.concatenate([[0], np.cumsum(sizes)])
    S = int(offsets[-1])
    size = S + 2 * n
    Z = np.zeros((size, size))
    out_x = np.zeros((n, size))  # what the mechanism reads at t_n: per drive its acceleration or its force
    for k, (d, carried) in enumerate(zip(models, D)):
        rows = slice(offsets[k], offsets[k + 1])
        P, Q = _step(d, carried, h)
        Z[rows, rows] = P
        Z[rows, S + k] = Q
        if scheme == "acceleration":
            # rho_ddot at t_n: the state's and the force held over the step before (c_(n-1), the last slot)
            out_x[k, rows] = d.i_R * d.A[-1]
            out_x[k, S + n + k] = -d.i_R * d.i_R * d.B[-1]
        else:
            row_x, row_c = _force_row(d, carried, h if scheme == "extrapolated" else 0.0)
            out_x[k, rows] = row_x
            out_x[k, S + n + k] = row_c
    Z[S : S + n] = (M @ out_x) if scheme == "acceleration" else (W @ out_x)
    Z[S + n :, S : S + n] = np.eye(n)
    eig = np.linalg.eigvals(Z)
    top = eig[np.argmax(np.abs(eig))]
    return Exchange(float(abs(top)), float(abs(np.angle(top)) / (2.0 * math.pi * h)), Z)


def _step(d: Drive, carried: float, h: float) -> tuple[np.ndarray, np.ndarray]:
    """(P, Q): x(t + h) = P x + Q c for a drive told the force c [N] and carrying ``carried`` [kg], the carried
    mass's force held at its mean acceleration over the step (implicit in the end speed, module docstring)."""
    n = len(d.B)
    G = np.zeros((n + 1, n + 1))
    G[:n, :n] = d.A
    G[:n, n] = d.B
    E = expm(G * h)
    Phi, Gam = E[:n, :n], E[:n, n]
    w = n - 1
    kappa = Gam[w] * d.i_R * d.i_R * carried / h
    # end speed: w1 (1 + kappa) = Phi[w] x + kappa x_w - Gam[w] i_R c
    w1_x = (Phi[w] + kappa * np.eye(n)[w]) / (1.0 + kappa)
    w1_c = -Gam[w] * d.i_R / (1.0 + kappa)
    # the torque held: tau = -i_R c - i_R^2 D (w1 - x_w) / h
    scale = d.i_R * d.i_R * carried / h
    tau_x = -scale * (w1_x - np.eye(n)[w])
    tau_c = -d.i_R - scale * w1_c
    return Phi + np.outer(Gam, tau_x), Gam * tau_c


def _force_row(d: Drive, carried: float, h: float) -> tuple[np.ndarray, float]:
    """The drive force the mechanism reads at t_n, (row on x, weight of the force held over the step before):
    T itself (``h`` = 0) or extrapolated ``coupling.EXTRAPOLATION`` steps of ``h`` ahead by its derivatives along
    the drive's model with that force held and its carried mass on its load side."""
    n = len(d.B)
    scale = np.ones(n)
    scale[-1] = 1.0 / (1.0 + carried * d.i_R * d.i_R * d.B[-1])  # J_N / (J_N + D i_R^2)
    A = d.A * scale[:, None]
    B = d.B * scale * -d.i_R  # per newton told
    # x' = A x + B c, x'' = A x' (the force held): T, T', T'' as rows on x and weights of c
    tau = EXTRAPOLATION * h
    row = extrapolated(d.T, d.T @ A, d.T @ A @ A, tau)
    held = float(extrapolated(0.0, d.T @ B, d.T @ A @ B, tau))
    return row, held


def joint_space_mass(mechanism: Mapping[str, object], q: "np.ndarray | None" = None) -> np.ndarray:
    """The joint-space mass matrix M [kg] of a mechanism parameter set at the pose ``q`` (its coordinates; by
    default its home pose)."""
    eng = engine(mechanism)
    top = eng.description.topology
    pose = list(top.home) if q is None else list(q)
    rho = eng.description.evaluate(pose).rho
    qs, J, _ = eng.dk(list(rho))
    n = eng.n
    out = eng.inertial(qs, J, [0.0] * n, [0.0] * n)
    return np.array(out[n + 6 : n + 6 + n * n]).reshape(n, n)
