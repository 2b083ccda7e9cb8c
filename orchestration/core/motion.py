"""Pose commands for the system inputs ``<c>_cmd``, one per coordinate c of the system's mechanism.

A mechanism's independent coordinates (its ``Topology.names``, fmus/mechanism/topology.py) are the
motion axes: for the 3PRS z, psi, theta (``AXES``), the system inputs ``z_cmd``, ``psi_cmd``,
``theta_cmd`` (``POSE_INPUTS``). A stimulus commands the axes of the system it drives: ``simulate``
and ``Session.run`` bind it to them (``system_axes``, ``bind``); one made for a coordinate the
system lacks is refused, naming the coordinate and the ones the system has.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable, Mapping, Optional, Sequence

#: the 3PRS's motion axes and system inputs (a stimulus not yet bound to a system commands these)
AXES = ("z", "psi", "theta")
POSE_INPUTS = ("z_cmd", "psi_cmd", "theta_cmd")


def pose_inputs(axes: Sequence[str]) -> tuple[str, ...]:
    """The system inputs commanding ``axes``: ``<c>_cmd`` (the connector convention, docs/interfaces.md)."""
    return tuple(f"{a}_cmd" for a in axes)


def unit(axis: str) -> str:
    """The unit of a pose component: "m" for x, y, z, "rad" for psi, theta, phi."""
    from fmus.mechanism.topology import Coordinate

    return Coordinate(axis).unit


def system_axes(
    system, parameters: Optional[Mapping[str, Mapping]] = None, mechanism: str = "mechanism"
) -> tuple[str, ...]:
    """The motion axes of ``system`` (an SSD's ``System``): the coordinates of its mechanism's topology (the
    ``mechanism`` component's bound parameters, with ``parameters``' overrides), else the coordinates of its
    ``<c>_cmd`` system inputs, else ``AXES``."""
    from fmus.mechanism.designs import describe

    from .ssp import mechanism_parameters

    spec = system.components.get(mechanism)
    if spec is not None:
        params = {**mechanism_parameters(spec), **((parameters or {}).get(mechanism, {}))}
        try:
            return describe(params, mechanism, masses=False).topology.names
        except Exception:  # noqa: BLE001 - a mechanism this project does not describe (a third-party FMU)
            pass
    commanded = tuple(s[: -len("_cmd")] for s in system.system_inputs if s.endswith("_cmd"))
    return commanded or AXES


def bind(stimulus, axes: Sequence[str], where: str = "the system") -> None:
    """Make ``stimulus`` command ``axes`` (a stimulus with ``use_axes``; any other stays as it is). ValueError if
    it moves a coordinate ``axes`` lacks: the message names it and the coordinates ``where`` has."""
    use_axes = getattr(stimulus, "use_axes", None)
    if use_axes is not None:
        use_axes(tuple(axes), where)


def _refuse_missing(moved: Sequence[str], axes: Sequence[str], what: str, where: str) -> None:
    missing = [a for a in moved if a not in axes]
    if missing:
        raise ValueError(
            f"{what} {', '.join(repr(a) for a in missing)}: {where} has no such coordinate; its "
            f"mechanism's coordinates are {', '.join(axes)}"
        )


@dataclass
class PoseStep:
    """Home pose plus constant ``offsets`` (m for x, y, z, rad for the angles) from the start on: a step response.

    The command holds its final value from t0 on, so the controllers start with the whole
    error and a constant reference (zero reference velocity and acceleration). The home
    pose is read as for ``SineMotion``; ``axes``: the coordinates commanded (``bind``).
    """

    offsets: dict
    home_from: str = "mechanism"
    target: list[float] = field(default_factory=list)
    home: list[float] = field(default_factory=list)
    axes: tuple[str, ...] = AXES

    def __post_init__(self) -> None:
        self.axes = tuple(self.axes)
        for axis, value in self.offsets.items():
            if axis not in self.axes or not math.isfinite(value):
                raise ValueError(f"pose step {axis!r} = {value!r}: expected finite offsets of {', '.join(self.axes)}")

    def use_axes(self, axes: tuple[str, ...], where: str = "the system") -> None:
        """Command ``axes`` from now on (``bind``)."""
        _refuse_missing(list(self.offsets), axes, "pose step", where)
        self.axes = axes

    @property
    def reads(self) -> Sequence[str]:
        return [f"{self.home_from}.{a}" for a in self.axes]

    def start(self, t0: float, read: Callable[[str], float]) -> None:
        self.home = [read(name) for name in self.reads]
        self.target = [h + self.offsets.get(a, 0.0) for h, a in zip(self.home, self.axes)]

    def extremes(self, t0: float, t1: float) -> tuple[list[float], list[list[float]]]:
        """(home pose, the poses commanded between t0 and t1 that bound the motion), after ``start``."""
        return list(self.home), [list(self.target)]

    def __call__(self, t: float) -> list[float]:
        return list(self.target)


@dataclass
class SineMotion:
    """Home pose plus ``amplitude * sin(2 pi frequency (t - t0))`` on one axis.

    ``axis`` is one of ``axes``, the coordinates commanded (the system's: ``bind``; for the 3PRS
    z, psi, theta); ``amplitude`` is in metres for x, y, z and radians for the angles; ``frequency``
    in Hz (0 holds the home pose). The home pose is the platform pose at the start time, read from
    the outputs ``<home_from>.<c>`` of every axis c once the plant is initialised.
    """

    axis: str
    amplitude: float
    frequency: float
    home_from: str = "mechanism"
    home: list[float] = field(default_factory=list)
    axes: tuple[str, ...] = AXES

    def __post_init__(self) -> None:
        self.axes = tuple(self.axes)
        if self.axis not in self.axes:
            raise ValueError(f"motion axis '{self.axis}': expected one of {', '.join(self.axes)}")
        if not (math.isfinite(self.amplitude) and math.isfinite(self.frequency) and self.frequency >= 0):
            raise ValueError(
                f"motion amplitude {self.amplitude!r} / frequency {self.frequency!r}: expected finite values, "
                "frequency >= 0 Hz"
            )
        self._k = self.axes.index(self.axis)
        self._omega = 2 * math.pi * self.frequency
        self._t0 = 0.0

    def use_axes(self, axes: tuple[str, ...], where: str = "the system") -> None:
        """Command ``axes`` from now on (``bind``)."""
        _refuse_missing([self.axis], axes, "motion axis", where)
        self.axes, self._k = axes, axes.index(self.axis)

    @property
    def reads(self) -> Sequence[str]:
        return [f"{self.home_from}.{a}" for a in self.axes]

    def start(self, t0: float, read: Callable[[str], float]) -> None:
        self._t0 = t0
        self.home = [read(name) for name in self.reads]

    def extremes(self, t0: float, t1: float) -> tuple[list[float], list[list[float]]]:
        """(home pose, the poses of the largest and smallest command between t0 and t1), after ``start``."""
        amplitude = [0.0] * len(self.axes)
        amplitude[self._k] = self.amplitude
        return sine_extremes(self.home, amplitude, self._omega * max(t1 - self._t0, 0.0))

    def __call__(self, t: float) -> list[float]:
        values = list(self.home)
        values[self._k] += self.amplitude * math.sin(self._omega * (t - self._t0))
        return values


def sine_extremes(
    home: Sequence[float], amplitude: Sequence[float], phase: float
) -> tuple[list[float], list[list[float]]]:
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
