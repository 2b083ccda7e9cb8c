"""Torque measurement model of one axis: what a drive reports as the motor torque.

tau_meas(t) = tau_offset + LPF_T(tau_m(t - delay))

* ``delay`` [s]: a pure delay (transport, communication, logging), linear interpolation
  between the samples of the actuator's step grid;
* ``T`` [s]: a first-order low-pass filter 1 / (T s + 1), discretised exactly for an input
  that is linear between samples (first-order hold):
  y_k = e y_{k-1} + c u_k + (1 - e - c) u_{k-1},  e = exp(-h/T),  c = 1 - (T/h)(1 - e);
* ``tau_offset`` [N m]: a constant offset (sensor or current-measurement offset).

Neutral values (0, 0, 0) give tau_meas = tau_m exactly. The measurement is outside the
control loop (the drive's current loop uses its own current samples): it changes what is
compared with a lab's log, not the motion.

The same arithmetic runs sample by sample inside the FMU (``TorqueSensor``) and on whole
arrays in the analysis (``measure``): equal to rounding on the same step grid.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["TorqueSensor", "measure", "filter_coefficients", "is_neutral", "measurement_step", "relayout"]


def is_neutral(T: float, delay: float, offset: float) -> bool:
    return T == 0.0 and delay == 0.0 and offset == 0.0


def filter_coefficients(T: float, h: float) -> tuple[float, float, float]:
    """(e, c, d) of y_k = e y_{k-1} + c u_k + d u_{k-1} (exact for piecewise-linear u)."""
    if T <= 0.0:
        return 0.0, 1.0, 0.0
    r = h / T
    e = math.exp(-r)
    c = 1.0 - (1.0 - e) / r
    return e, c, 1.0 - e - c


def delay_split(delay: float, h: float) -> tuple[int, float]:
    """delay = (n + phi) h with integer n >= 0 and 0 <= phi < 1."""
    q = delay / h
    n = int(math.floor(q + 1e-9))
    phi = q - n
    if phi < 1e-9:
        phi = 0.0
    return n, phi


def measurement_step(
    u: float, line, head: int, L: int, n: int, phi: float, e: float, c: float, d: float, y: float, u_prev: float
) -> tuple[int, float, float]:
    """One step of the measurement with the new sample u (at the end of the step): the delay line ``line``, a
    ring of L = n + 2 samples (the newest at ``head``), then the filter (y_k = e y_{k-1} + c ud_k + d ud_{k-1}).
    Returns (head, y, ud): the newest sample's place, the filter's output (tau_meas - tau_offset) and the
    delayed sample (the next step's ud_{k-1}). Written in the generated-code subset: the native actuator runs
    this source."""
    head = (head + 1) % L
    line[head] = u
    a = line[(head - n + L) % L]  # u_{k-n}
    ud = a if phi == 0.0 else (1.0 - phi) * a + phi * line[(head - n - 1 + L) % L]
    y = e * y + c * ud + d * u_prev
    return (head, y, ud)


def relayout(old, size: int, head: int, line, L: int, u0: float) -> int:
    """The delay line for another step size: into ``line`` (L samples, the oldest first) the newest
    min(size, L) samples of ``old`` (a ring of ``size``, the newest at ``head``; none before the first step), the
    places before them filled with the newest (u0 when there is none: the steady past). Written in the
    generated-code subset, as ``measurement_step``."""
    kept = size if size < L else L
    fill = old[head] if size > 0 else u0
    gap = L - kept
    i = 0
    for _ in range(gap):
        line[i] = fill
        i += 1
    j = head - kept + 1 + size
    for _ in range(kept):
        line[i] = old[j % size]
        i += 1
        j += 1
    return 0


class TorqueSensor:
    """Sample-by-sample measurement model (used inside the actuator FMU)."""

    def __init__(self, T: float, delay: float, offset: float) -> None:
        self.T, self.delay, self.offset = float(T), float(delay), float(offset)
        self.reset(0.0)

    def reset(self, u0: float) -> float:
        """Steady state at input u0 (an infinite past of u0); returns the measurement."""
        self._u0 = float(u0)
        self._h = math.nan
        self._y = self._u0
        self._u_prev = self._u0
        self._line: list[float] = []  # the delay line (``measurement_step``), none before the first step
        self._head = 0
        return self._y + self.offset

    def _configure(self, h: float) -> None:
        self._h = h
        self._e, self._c, self._d = filter_coefficients(self.T, h)
        self._n, self._phi = delay_split(self.delay, h)
        L = self._n + 2
        line = [0.0] * L
        relayout(self._line, len(self._line), self._head, line, L, self._u0)
        self._line, self._head = line, L - 1

    def step(self, u: float, h: float) -> float:
        """Advance by h with the new torque sample u (at the end of the step); returns tau_meas."""
        if h != self._h:
            self._configure(h)
        self._head, self._y, self._u_prev = measurement_step(
            u, self._line, self._head, self._n + 2, self._n, self._phi, self._e, self._c, self._d, self._y, self._u_prev
        )
        return self._y + self.offset


def measure(
    u: np.ndarray, h: float, T: float = 0.0, delay: float = 0.0, offset: float = 0.0, axis: int = -1
) -> np.ndarray:
    """The measurement model on samples u[0], u[1], ... on a grid of step h (u[0]: steady past)."""
    from scipy.signal import lfilter

    u = np.asarray(u, dtype=float)
    if T == 0.0 and delay == 0.0:
        return u + offset
    u = np.moveaxis(u, axis, -1)
    n, phi = delay_split(delay, h)
    if n or phi:
        pad = np.repeat(u[..., :1], n + 1, axis=-1)
        ext = np.concatenate([pad, u], axis=-1)  # ext[j + n + 1] = u[j]
        m = u.shape[-1]
        a = ext[..., 1 : m + 1]  # u[k - n]
        b = ext[..., 0:m]  # u[k - n - 1]
        ud = a if phi == 0.0 else (1.0 - phi) * a + phi * b
    else:
        ud = u
    e, c, d = filter_coefficients(T, h)
    if T > 0.0:
        zi = e * ud[..., :1] + d * ud[..., :1]  # y_{-1} e + d u_{-1} with y_{-1} = u_{-1} = u0
        y = lfilter([c, d], [1.0, -e], ud, axis=-1, zi=zi)[0]
    else:
        y = ud
    return np.moveaxis(y + offset, -1, axis)
