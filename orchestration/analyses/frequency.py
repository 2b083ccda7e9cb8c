"""Closed-loop frequency response from co-simulated sine tests.

A sine test commands ``home + A sin(2 pi f t)`` on one pose axis, discards the
settling periods and extracts the steady-state harmonic at f of the command and
of the achieved pose by least squares over whole periods; their ratio is the
closed-loop response. Sweeps run independent tests in parallel processes
(pythonfmu FMUs share one interpreter per process, so processes, not threads).
"""

from __future__ import annotations

import math
import os
import sys
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass, field
from typing import Callable, Mapping, Optional, Sequence

import numpy as np

from fmus.common.parameters import Value
from fmus.mechanism.topology import POSE

from ..core.master import Result
from ..core.motion import SineMotion, system_axes

#: settling time before measuring: at least this long and this many periods [s, periods]
SETTLE_S, SETTLE_PERIODS = 1.0, 1
#: measuring window: at least this long and this many whole periods [s, periods]
MEASURE_S, MEASURE_PERIODS = 0.4, 1


def harmonic(t: np.ndarray, y: np.ndarray, f: float) -> complex:
    """Complex amplitude c of ``y ~ y0 + Re(c e^{j 2 pi f t})`` by least squares.

    Exact for a sinusoid plus offset sampled over whole periods; other harmonics
    are orthogonal over whole periods and do not bias it.
    """
    w = 2.0 * math.pi * f
    basis = np.column_stack([np.ones_like(t), np.cos(w * t), np.sin(w * t)])
    coef = np.linalg.lstsq(basis, y, rcond=None)[0]
    return complex(coef[1], -coef[2])


def measuring_window(f: float) -> tuple[float, float]:
    """(start of the measuring window, stop time) [s] for a sine test at f [Hz]."""
    period = 1.0 / f
    settle = math.ceil(max(SETTLE_S / period, SETTLE_PERIODS)) * period
    measure = math.ceil(max(MEASURE_S / period, MEASURE_PERIODS)) * period
    return settle, settle + measure


@dataclass
class SineResult:
    """One sine test: the closed-loop response and what the drives had to deliver."""

    axis: str
    amplitude: float
    frequency: float
    ratio: complex  # achieved / commanded harmonic of the pose axis
    torque_peak: list[float]  # per actuator, steady state [N m]
    torque_rms: list[float]
    torque_h3_h1: list[float]  # 3rd / 1st harmonic of the motor torque (square wave: 1/3)
    tracking_peak: float  # max |command - achieved| on the axis, steady state
    parasitic: dict[str, float]  # peak-to-peak/2 of each parasitic pose component (3PRS: x, y, phi), steady
    current_peak: list[float] = field(default_factory=list)  # per drive, max |i_cmd| in steady state [A] (if recorded)
    error: Optional[str] = None
    signals: dict = field(default_factory=dict)  # steady-state time series, if asked for

    @property
    def magnitude(self) -> float:
        return abs(self.ratio)

    @property
    def phase_deg(self) -> float:
        return math.degrees(math.atan2(self.ratio.imag, self.ratio.real))


def sine_test(
    ssp: str,
    axis: str,
    amplitude: float,
    frequency: float,
    parameters: Optional[Mapping[str, Mapping[str, Value]]] = None,
    direct: bool = False,
    keep: Sequence[str] = (),
) -> SineResult:
    """Run one sine test (amplitude in metres for a length, radians for an angle) and analyse it."""
    from ..core.run import simulate
    from ..core.ssp import SSPArchive

    start, stop = measuring_window(frequency)
    with SSPArchive(ssp) as archive:
        axes = system_axes(archive.system, parameters)
    parasitic = tuple(c for c in POSE if c not in axes)
    record = [
        f"{axis}_cmd",
        f"mechanism.{axis}",
        *(f"mechanism.{c}" for c in parasitic),
        *(f"actuator_{k}.tau_m" for k in range(1, len(axes) + 1)),
        *(f"controller.i_cmd_{k}" for k in range(1, len(axes) + 1)),
    ]
    record = list(dict.fromkeys(record + list(keep)))
    result = simulate(
        ssp,
        SineMotion(axis, amplitude, frequency),
        stop,
        parameters=parameters,
        record=record,
        record_step=record_step_of(frequency),
        direct=direct,
    )
    return analyse(result, axis, amplitude, frequency, start, keep, parasitic)


def drives_in(names: Sequence[str]) -> list[int]:
    """The drives k whose signals ``actuator_<k>.*`` or ``controller.<name>_<k>`` are among ``names``, in order."""
    found = set()
    for name in names:
        element, _, variable = name.partition(".")
        for text in (
            element.rpartition("actuator_")[2] if element.startswith("actuator_") else "",
            variable.rpartition("_")[2] if element == "controller" else "",
        ):
            if text.isdigit():
                found.add(int(text))
    return sorted(found)


def analyse(
    result: Result,
    axis: str,
    amplitude: float,
    frequency: float,
    start: float,
    keep: Sequence[str] = (),
    parasitic: Sequence[str] = ("x", "y", "phi"),
) -> SineResult:
    """Steady-state analysis of a sine test: signals named ``<axis>_cmd``, ``mechanism.<axis>``,
    and, when recorded, ``actuator_<k>.tau_m``, ``controller.i_cmd_<k>`` of every drive k and
    ``mechanism.<c>`` of the ``parasitic`` pose components (the mechanism's ``Topology.parasitic``; by default the
    3PRS's)."""
    steady = result.time >= start - 1e-9
    t = result.time[steady]
    cmd, got = result[f"{axis}_cmd"][steady], result[f"mechanism.{axis}"][steady]
    drives = drives_in(list(result.signals))
    torques = [result[f"actuator_{j}.tau_m"][steady] for j in drives if f"actuator_{j}.tau_m" in result.signals]
    h3h1 = []
    for tau in torques:
        h1 = abs(harmonic(t, tau, frequency))
        h3h1.append(abs(harmonic(t, tau, 3 * frequency)) / h1 if h1 > 0 else float("nan"))
    return SineResult(
        axis=axis,
        amplitude=amplitude,
        frequency=frequency,
        ratio=harmonic(t, got, frequency) / harmonic(t, cmd, frequency),
        torque_peak=[float(np.abs(tau).max()) for tau in torques],
        torque_rms=[float(np.sqrt(np.mean(tau**2))) for tau in torques],
        torque_h3_h1=h3h1,
        tracking_peak=float(np.abs(cmd - got).max()),
        current_peak=[
            float(np.abs(result[f"controller.i_cmd_{j}"][steady]).max())
            for j in drives
            if f"controller.i_cmd_{j}" in result.signals
        ],
        parasitic={
            k: float(np.ptp(result[f"mechanism.{k}"][steady]) / 2)
            for k in parasitic
            if f"mechanism.{k}" in result.signals
        },
        signals={"time": t, **{name: result[name][steady] for name in keep}} if keep else {},
    )


def record_step_of(frequency: float) -> float:
    """One sample per millisecond, the MAST systems' exchange step (docs/interfaces.md): the outputs change only
    there, so a finer record adds no information (at 50 Hz, 20 samples a period for the harmonics)."""
    return 1e-3


@dataclass(frozen=True)
class SineCase:
    """One independent run of a sweep: which SSP, which motion, which parameters."""

    ssp: str
    axis: str
    amplitude: float
    frequency: float
    parameters: Optional[Mapping[str, Mapping[str, Value]]] = None
    direct: bool = False
    keep: tuple[str, ...] = ()
    label: str = ""


def _run_case(case: SineCase) -> SineResult:
    try:
        return sine_test(case.ssp, case.axis, case.amplitude, case.frequency, case.parameters, case.direct, case.keep)
    except Exception as err:  # a failing case is recorded, the sweep goes on
        nan = float("nan")
        return SineResult(
            case.axis,
            case.amplitude,
            case.frequency,
            complex(nan, nan),
            [nan] * 3,
            [nan] * 3,
            [nan] * 3,
            nan,
            {},
            error=f"{type(err).__name__}: {err}",
        )


def run_cases(
    cases: Sequence[SineCase], workers: Optional[int] = None, progress: Optional[Callable[[int, int], None]] = None
) -> list[SineResult]:
    """Run independent sine tests, in parallel processes when workers > 1; results in input order."""
    workers = workers or min(len(cases), os.cpu_count() or 1)
    results: list[Optional[SineResult]] = [None] * len(cases)
    if workers <= 1:
        for k, case in enumerate(cases):
            results[k] = _run_case(case)
            if progress:
                progress(k + 1, len(cases))
        return results  # type: ignore[return-value]
    # longest tests first keeps both processes busy to the end
    order = sorted(range(len(cases)), key=lambda k: -measuring_window(cases[k].frequency)[1])
    with ProcessPoolExecutor(max_workers=workers) as pool:
        futures = {pool.submit(_run_case, cases[k]): k for k in order}
        for done, future in enumerate(as_completed(futures), 1):
            results[futures[future]] = future.result()
            if progress:
                progress(done, len(cases))
    return results  # type: ignore[return-value]


def bandwidth(frequencies: Sequence[float], ratios: Sequence[complex], level_db: float = -3.0) -> Optional[float]:
    """First frequency where |ratio| falls through ``level_db``, interpolated in log f; None if it never does."""
    mags_db = [20.0 * math.log10(abs(r)) if abs(r) > 0 else -math.inf for r in ratios]
    pairs = sorted(zip(frequencies, mags_db))
    for (f0, m0), (f1, m1) in zip(pairs, pairs[1:]):
        if m0 >= level_db > m1:
            s = (level_db - m0) / (m1 - m0)
            return float(math.exp(math.log(f0) + s * (math.log(f1) - math.log(f0))))
    return None


class CountProgress:
    """'label: 7/20 done, 1 failed, ~12 s left' on stderr."""

    def __init__(self, label: str) -> None:
        import time

        self.label, self.t0, self._time = label, time.perf_counter(), time.perf_counter

    def __call__(self, done: int, total: int) -> None:
        elapsed = self._time() - self.t0
        left = elapsed / done * (total - done) if done else float("nan")
        end = "\n" if done == total or not sys.stderr.isatty() else ""
        sys.stderr.write(f"\r{self.label}: {done}/{total} done, ~{left:.0f} s left{end}")
        sys.stderr.flush()
