"""Velocity and acceleration of a sampled joint reference (for the model-based laws).

The controller receives the pose command as a sampled signal, as a drive receives
set-points from an interpolator, and has to estimate the reference velocity and
acceleration the feed-forward and computed-torque laws need. Without a look-ahead the
estimate must be causal, and a delayed (central) difference would delay the whole
reference. So the derivatives at the newest sample r_0 (r_k: k samples of T before) are
the backward differences of the cubic through the last four samples:

    rho_dot  = (11 r_0 - 18 r_1 + 9 r_2 - 2 r_3) / (6 T)        error O(T^3)
    rho_ddot = (2 r_0 - 5 r_1 + 4 r_2 - r_3) / T^2              error O(T^2)

exact for every cubic in time. For a sine of frequency f sampled at T = 1 ms the
relative errors are about (2 pi f T)^3 / 4 and 11/12 (2 pi f T)^2: 0.2 % of the
acceleration at 10 Hz. While fewer samples exist (after ``reset``) the order drops:
one sample gives zero derivatives, two a first difference and zero acceleration, three
the quadratic's. Commands with steps (a reference jump) give a burst of large values for
three samples, as any differentiator does: shape references before differentiating them.
"""
from __future__ import annotations

from typing import Sequence


class JointReference:
    """Last four samples of the joint reference and its derivative estimates (module docstring).

    ``T`` [s] sampling period; ``rho_dot`` [m/s] and ``rho_ddot`` [m/s^2] hold the estimates
    at the newest sample after each ``update``.
    """

    def __init__(self, T: float, n: int = 3) -> None:
        self.T = float(T)
        self.n = n
        self.reset()

    def reset(self) -> None:
        """Forget every sample (the next ``update`` gives zero velocity and acceleration)."""
        self._history: list[list[float]] = []
        self.rho_dot = [0.0] * self.n
        self.rho_ddot = [0.0] * self.n

    def update(self, rho: Sequence[float]) -> None:
        """Add the newest sample and update ``rho_dot`` and ``rho_ddot``."""
        h = self._history
        h.insert(0, [float(v) for v in rho])
        del h[4:]
        T, k = self.T, len(h)
        for j in range(self.n):
            r = [s[j] for s in h]
            if k == 1:
                v, a = 0.0, 0.0
            elif k == 2:
                v, a = (r[0] - r[1]) / T, 0.0
            elif k == 3:
                v, a = (3.0 * r[0] - 4.0 * r[1] + r[2]) / (2.0 * T), (r[0] - 2.0 * r[1] + r[2]) / (T * T)
            else:
                v = (11.0 * r[0] - 18.0 * r[1] + 9.0 * r[2] - 2.0 * r[3]) / (6.0 * T)
                a = (2.0 * r[0] - 5.0 * r[1] + 4.0 * r[2] - r[3]) / (T * T)
            self.rho_dot[j] = v
            self.rho_ddot[j] = a
