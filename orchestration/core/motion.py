"""Pose commands for the system inputs ``z_cmd``, ``psi_cmd``, ``theta_cmd``."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable, Sequence

POSE_INPUTS = ("z_cmd", "psi_cmd", "theta_cmd")
AXES = ("z", "psi", "theta")


@dataclass
class PoseStep:
    """Home pose plus constant ``offsets`` (m for z, rad for psi and theta) from the start on: a step response.

    The command holds its final value from t0 on, so the controllers start with the whole
    error and a constant reference (zero reference velocity and acceleration). The home
    pose is read as for ``SineMotion``.
    """

    offsets: dict
    home_from: str = "mechanism"
    target: list[float] = field(default_factory=list)
    home: list[float] = field(default_factory=list)

    def __post_init__(self) -> None:
        for axis, value in self.offsets.items():
            if axis not in AXES or not math.isfinite(value):
                raise ValueError(f"pose step {axis!r} = {value!r}: expected finite offsets of {', '.join(AXES)}")

    @property
    def reads(self) -> Sequence[str]:
        return [f"{self.home_from}.{a}" for a in AXES]

    def start(self, t0: float, read: Callable[[str], float]) -> None:
        self.home = [read(name) for name in self.reads]
        self.target = [h + self.offsets.get(a, 0.0) for h, a in zip(self.home, AXES)]

    def extremes(self, t0: float, t1: float) -> tuple[list[float], list[list[float]]]:
        """(home pose, the poses commanded between t0 and t1 that bound the motion), after ``start``."""
        return list(self.home), [list(self.target)]

    def __call__(self, t: float) -> list[float]:
        return list(self.target)


@dataclass
class SineMotion:
    """Home pose plus ``amplitude * sin(2 pi frequency (t - t0))`` on one axis.

    ``axis`` is z, psi or theta; ``amplitude`` is in metres for z and radians
    for psi and theta; ``frequency`` in Hz (0 holds the home pose). The home
    pose is the platform pose at the start time, read from the outputs
    ``<home_from>.z``, ``.psi``, ``.theta`` once the plant is initialised.
    """

    axis: str
    amplitude: float
    frequency: float
    home_from: str = "mechanism"
    home: list[float] = field(default_factory=list)

    def __post_init__(self) -> None:
        if self.axis not in AXES:
            raise ValueError(f"motion axis '{self.axis}': expected one of {', '.join(AXES)}")
        if not (math.isfinite(self.amplitude) and math.isfinite(self.frequency) and self.frequency >= 0):
            raise ValueError(f"motion amplitude {self.amplitude!r} / frequency {self.frequency!r}: expected finite values, frequency >= 0 Hz")
        self._k = AXES.index(self.axis)
        self._omega = 2 * math.pi * self.frequency
        self._t0 = 0.0

    @property
    def reads(self) -> Sequence[str]:
        return [f"{self.home_from}.{a}" for a in AXES]

    def start(self, t0: float, read: Callable[[str], float]) -> None:
        self._t0 = t0
        self.home = [read(name) for name in self.reads]

    def extremes(self, t0: float, t1: float) -> tuple[list[float], list[list[float]]]:
        """(home pose, the poses of the largest and smallest command between t0 and t1), after ``start``."""
        amplitude = [0.0, 0.0, 0.0]
        amplitude[self._k] = self.amplitude
        return sine_extremes(self.home, amplitude, self._omega * max(t1 - self._t0, 0.0))

    def __call__(self, t: float) -> list[float]:
        values = list(self.home)
        values[self._k] += self.amplitude * math.sin(self._omega * (t - self._t0))
        return values


def sine_extremes(home: Sequence[float], amplitude: Sequence[float],
                  phase: float) -> tuple[list[float], list[list[float]]]:
    """(home, the extreme poses of home + amplitude sin(p) for p from 0 to ``phase`` [rad])."""
    high = 1.0 if phase >= math.pi / 2 else math.sin(phase)
    low = -1.0 if phase >= 3 * math.pi / 2 else min(0.0, math.sin(phase))
    return list(home), [[h + a * s for h, a in zip(home, amplitude)] for s in sorted({high, low})]


class NoStimulus:
    """For systems without inputs (e.g. ssp/MAST_standalone.ssd, driven by its own trajectory FMU)."""

    reads: Sequence[str] = ()

    def start(self, t0: float, read: Callable[[str], float]) -> None:
        pass

    def __call__(self, t: float) -> list[float]:
        return []
