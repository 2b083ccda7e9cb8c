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
acceleration at 10 Hz. While fewer samples exist (after ``initialize``) the order drops:
one sample gives zero derivatives, two a first difference and zero acceleration, three
the quadratic's. Commands with steps (a reference jump) give a burst of large values for
three samples, as any differentiator does: shape references before differentiating them.
"""

from __future__ import annotations


def rates(k: int, r0: float, r1: float, r2: float, r3: float, T: float) -> tuple[float, float]:
    """(velocity, acceleration) at the newest of the ``k`` samples r0 (newest), r1, r2, r3 of period ``T``
    (module docstring; the samples beyond k are not read). Written in the generated-code subset: every
    position tick of the controllers calls it on the last four samples of rho_cmd (tick.py)."""
    if k == 1:
        return (0.0, 0.0)
    if k == 2:
        return ((r0 - r1) / T, 0.0)
    if k == 3:
        return ((3.0 * r0 - 4.0 * r1 + r2) / (2.0 * T), (r0 - 2.0 * r1 + r2) / (T * T))
    return ((11.0 * r0 - 18.0 * r1 + 9.0 * r2 - 2.0 * r3) / (6.0 * T), (2.0 * r0 - 5.0 * r1 + 4.0 * r2 - r3) / (T * T))
