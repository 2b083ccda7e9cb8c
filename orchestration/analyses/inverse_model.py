"""Inverse-model least squares of a drive axis on a record: the benchmark's own identification route.

tau = M q'' + F_v q' + F_c sign(q') + offset (symmetric), or with separate coefficients per
velocity sign (asymmetric: F_v+, F_c+, F_v-, F_c-, no offset: with both signs the offset is
not separable from the Coulomb pair while the axis moves). As in the EMPS benchmark (Janot,
Gautier, Brunot 2019): the measured position low-pass filtered (4th-order Butterworth,
forward-backward), velocity and acceleration by central differences, the force decimated
the same way; ordinary least squares. An independent route to the values `mast diagnose`
finds by closed-loop re-simulation.
"""

from __future__ import annotations

from typing import Mapping

import numpy as np


def inverse_model_ls(
    time: np.ndarray,
    q: np.ndarray,
    force: np.ndarray,
    asymmetric: bool = False,
    cutoff_Hz: float = 100.0,
    decimate: int = 10,
    edge_s: float = 0.05,
) -> Mapping[str, float]:
    """Least-squares estimates and the relative force error [%] of the fitted inverse model (module docstring)."""
    from scipy.signal import butter, sosfiltfilt

    dt = float(np.median(np.diff(time)))
    sos = butter(4, cutoff_Hz, fs=1.0 / dt, output="sos")
    qf = sosfiltfilt(sos, q)
    qd = np.gradient(qf, dt)
    qdd = np.gradient(qd, dt)
    tau = sosfiltfilt(sos, force)
    edge = int(edge_s / dt)
    sl = slice(edge, len(time) - edge, decimate)
    v, a, y = qd[sl], qdd[sl], tau[sl]
    if asymmetric:
        pos, neg = (v > 0).astype(float), (v < 0).astype(float)
        names = ("M", "F_v+", "F_c+", "F_v-", "F_c-")
        X = np.column_stack([a, v * pos, pos, v * neg, -neg])
    else:
        names = ("M", "F_v", "F_c", "F_offset")
        X = np.column_stack([a, v, np.sign(v), np.ones_like(v)])
    theta = np.linalg.lstsq(X, y, rcond=None)[0]
    out = dict(zip(names, map(float, theta)))
    out["relative_error_pct"] = 100.0 * float(np.linalg.norm(y - X @ theta) / np.linalg.norm(y))
    return out
