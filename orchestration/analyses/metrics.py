"""Per-case metrics of a co-simulation, and metrics across the cases of a frequency sweep.

Every metric is a plain float in SI units, its unit in its name; a metric whose
signals were not recorded (or do not exist in the system) is left out. The
window is ``[start, stop]`` of the recorded run: for a sine test the batch
takes the measuring window of :func:`mast.analyses.frequency.measuring_window`
(settling discarded, whole periods), otherwise the whole run.

Families (the ``outputs.metrics`` names of a batch config):

``tracking``   ``tracking_<axis>_rms_<unit>``, ``tracking_<axis>_peak_<unit>``: command minus
               achieved pose, per commanded coordinate (``<axis>_cmd`` recorded; the 3PRS: z [m],
               psi and theta [rad])
``sine``       ``magnitude``, ``magnitude_dB``, ``phase_deg``: closed-loop response of a sine test
               (ratio of the steady-state harmonics of achieved and commanded pose, by
               :func:`mast.analyses.frequency.analyse`), and ``tau_m_<k>_h3_h1`` (3rd/1st harmonic of torque)
``torque``     ``tau_m_<k>_peak_Nm``, ``tau_m_<k>_rms_Nm`` per actuator k (every drive k whose signals
               were recorded: the system's n)
``current``    ``i_m_<k>_peak_A``, ``i_m_<k>_rms_A`` per actuator k
``sizing``     ``sizing_margin``: the smallest margin of the drives against their ratings (``mast sizing``,
               docs/sizing.md; the window as the duty cycle, repeated to steady state for the winding
               temperature), ``sizing_<k>_margin`` per drive, ``sizing_fail`` and ``sizing_at_limit`` (1 or 0);
               left out for a system that names no ratings
``saturation`` ``saturation_<k>_s``: time drive k spends at its current limit (``|i_cmd_k| = i_max``)
               or voltage limit (``|u| = u_max`` of ``actuator_<k>``, the drive's current loop), sampled at the record
               step;
               ``saturation_s``: time any drive is saturated; ``saturation_fraction``: that time
               over the window

Across cases (:func:`sweep_metrics`): ``bandwidth_Hz`` (-3 dB, :func:`mast.analyses.frequency.bandwidth`),
``peak_magnitude_dB`` and ``peak_frequency_Hz``, ``n_frequencies``.
"""

from __future__ import annotations

import math
from typing import Mapping, Optional, Sequence

import numpy as np

from fmus.mechanism.topology import POSE, POSE_UNITS

from ..core.master import Result
from . import sizing
from .frequency import analyse, bandwidth, drives_in

FAMILIES = ("tracking", "sine", "torque", "current", "saturation", "sizing")


def signals_for(families: Sequence[str], available: Sequence[str]) -> list[str]:
    """The signals the metric families need, among those ``available`` in the system."""
    want: list[str] = []
    have = set(available)
    numbers = drives_in(available)  # the system's drives, 1..n
    if "tracking" in families or "sine" in families:  # the commanded coordinates
        want += [s for a in POSE if f"{a}_cmd" in have for s in (f"{a}_cmd", f"mechanism.{a}")]
    if "torque" in families or "sine" in families:
        want += [f"actuator_{k}.tau_m" for k in numbers]
    if "current" in families:
        want += [f"actuator_{k}.i_m" for k in numbers]
    if "saturation" in families:
        want += [s for k in numbers for s in (f"controller.i_cmd_{k}", f"controller.u_{k}")]
    if "sizing" in families:
        want += [f"actuator_{k}.{s}" for k in numbers for s in sizing.SIGNALS] + [
            f"controller.i_cmd_{k}" for k in numbers
        ]
    return [s for s in dict.fromkeys(want) if s in have]


def window(result: Result, start: float, stop: Optional[float] = None) -> Result:
    """The part of ``result`` with ``start <= t <= stop`` (times to 1e-9 s)."""
    mask = result.time >= start - 1e-9
    if stop is not None:
        mask &= result.time <= stop + 1e-9
    return Result(
        result.time[mask],
        {name: values[mask] for name, values in result.signals.items()},
        result.wall_time_s,
        result.error,
        dict(result.stats),
    )


def case_metrics(
    result: Result,
    families: Sequence[str] = FAMILIES,
    motion: Optional[Mapping] = None,
    start: float = 0.0,
    stop: Optional[float] = None,
    limits: Optional[Mapping[str, float]] = None,
    drives: Optional[Mapping[str, "sizing.Drive"]] = None,
) -> dict[str, float]:
    """Metrics of one run over ``[start, stop]``.

    ``motion``: ``{"axis", "amplitude" (m or rad), "frequency" (Hz)}`` of a sine test (needed by
    ``sine``); ``limits``: ``{"i_max": A, "u_max": V}``, the drive's limits: the controller's current
    command and the actuators' current loop (needed by ``saturation``); ``drives``: the system's drives with
    their ratings (``sizing.drives``, needed by ``sizing``).
    """
    w = window(result, start, stop)
    sig = w.signals
    numbers = drives_in(list(sig))  # the drives recorded, 1..n
    out: dict[str, float] = {}
    if not len(w.time):
        return out
    out["window_start_s"], out["window_stop_s"] = float(w.time[0]), float(w.time[-1])
    if "tracking" in families:
        for a in POSE:
            cmd, got = sig.get(f"{a}_cmd"), sig.get(f"mechanism.{a}")
            if cmd is not None and got is not None:
                err = cmd - got
                out[f"tracking_{a}_rms_{POSE_UNITS[a]}"] = _rms(err)
                out[f"tracking_{a}_peak_{POSE_UNITS[a]}"] = float(np.max(np.abs(err)))
    if "sine" in families and motion and motion.get("frequency", 0) > 0 and motion.get("amplitude", 0) != 0:
        a, f = motion["axis"], float(motion["frequency"])
        if f"{a}_cmd" in sig and f"mechanism.{a}" in sig:
            sine = analyse(w, a, float(motion["amplitude"]), f, float(w.time[0]))
            mag = abs(sine.ratio)
            out["magnitude"] = mag
            out["magnitude_dB"] = 20.0 * math.log10(mag) if mag > 0 else -math.inf
            out["phase_deg"] = sine.phase_deg
            for k, value in zip([k for k in numbers if f"actuator_{k}.tau_m" in sig], sine.torque_h3_h1):
                out[f"tau_m_{k}_h3_h1"] = float(value)
    for family, signal, unit in (("torque", "tau_m", "Nm"), ("current", "i_m", "A")):
        if family in families:
            for k in numbers:
                y = sig.get(f"actuator_{k}.{signal}")
                if y is not None:
                    out[f"{signal}_{k}_peak_{unit}"] = float(np.max(np.abs(y)))
                    out[f"{signal}_{k}_rms_{unit}"] = _rms(y)
    if "sizing" in families and drives and len(w.time) > 1:
        frequency = float(motion.get("frequency", 0.0)) if motion else 0.0
        sized = sizing.size_signals(drives, w.time, sig, frequency)
        v = sizing.verdict(sized)
        out["sizing_margin"] = float(v["limiting"]["margin"])
        out["sizing_fail"] = float(v["verdict"] == "fail")
        out["sizing_at_limit"] = float(v["verdict"] == "at limit")
        for s in sized:
            out[f"sizing_{s.drive.name.rsplit('_', 1)[-1]}_margin"] = float(s.limiting.margin)
    if "saturation" in families and limits and len(w.time) > 1:
        dt = float(np.median(np.diff(w.time)))
        any_sat = np.zeros(len(w.time), dtype=bool)
        found = False
        for k in numbers:
            sat = np.zeros(len(w.time), dtype=bool)
            for name, limit in (
                (f"controller.i_cmd_{k}", limits.get("i_max")),
                (f"actuator_{k}.u", limits.get("u_max")),
            ):
                if name in sig and limit:
                    sat |= np.abs(sig[name]) >= float(limit) * (1.0 - 1e-9)
                    found = True
            out[f"saturation_{k}_s"] = float(np.count_nonzero(sat) * dt)
            any_sat |= sat
        if found:
            out["saturation_s"] = float(np.count_nonzero(any_sat) * dt)
            out["saturation_fraction"] = float(np.count_nonzero(any_sat) / len(w.time))
        else:
            for k in numbers:
                out.pop(f"saturation_{k}_s", None)
    return out


def sweep_metrics(
    frequencies: Sequence[float], magnitudes: Sequence[float], phases_deg: Sequence[float]
) -> dict[str, float]:
    """Bandwidth and resonance of the sine tests of one group (same system, axis and amplitude)."""
    pairs = sorted(
        (f, m, p)
        for f, m, p in zip(frequencies, magnitudes, phases_deg)
        if f and f > 0 and m is not None and math.isfinite(m) and p is not None
    )
    out: dict[str, float] = {"n_frequencies": float(len(pairs))}
    if not pairs:
        return out
    ratios = [m * complex(math.cos(math.radians(p)), math.sin(math.radians(p))) for _, m, p in pairs]
    bw = bandwidth([f for f, _, _ in pairs], ratios)
    out["bandwidth_Hz"] = float("nan") if bw is None else bw
    f_peak, m_peak, _ = max(pairs, key=lambda x: x[1])
    out["peak_magnitude_dB"] = 20.0 * math.log10(m_peak) if m_peak > 0 else -math.inf
    out["peak_frequency_Hz"] = f_peak
    return out


def _rms(y: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(y))))
