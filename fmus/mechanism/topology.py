"""What every layer around the engine needs to know of a mechanism: its topology.

A mechanism's *topology* is the shape of its interface, not its numbers: how many drives it has
(linear or rotary, each with its stroke), which coordinates of the platform pose are independent
(commanded, controlled) and in which units, which pose components follow from them (the parasitic
motion of a lower-mobility mechanism), and its home pose. The mechanism FMU's variables, the
controllers' state layout, the SSD's actuators and connections, the CLI's motion axes, the
workspace grid and the admissibility check are all derived from it (issue "Describe a parallel
mechanism in one file"; docs/mechanism.md).

The platform pose is always the six values (x, y, z, psi, theta, phi) [m, m, m, rad, rad, rad]
(``POSE``; R = Rz(phi) Ry(theta) Rx(psi)); a mechanism's coordinates are a subset of them, in
its own order, and its parasitic components are the rest.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["POSE", "POSE_UNITS", "Coordinate", "Drive", "Topology", "TopologyError"]

#: the platform pose every description gives (Evaluation.pose), with the unit of each component
POSE: tuple[str, ...] = ("x", "y", "z", "psi", "theta", "phi")
POSE_UNITS: dict[str, str] = {"x": "m", "y": "m", "z": "m", "psi": "rad", "theta": "rad", "phi": "rad"}

#: the unit of a drive's joint coordinate by its kind
DRIVE_UNITS: dict[str, str] = {"linear": "m", "rotary": "rad"}


class TopologyError(ValueError):
    """A topology that cannot be: the message names the coordinate or drive and what was expected."""


@dataclass(frozen=True)
class Coordinate:
    """An independent coordinate: one component of the platform pose (``POSE``), with its unit
    ("m" for x, y, z; "rad" for psi, theta, phi)."""

    name: str

    def __post_init__(self) -> None:
        if self.name not in POSE:
            raise TopologyError(f"coordinate {self.name!r}: expected one of the pose components {', '.join(POSE)}")

    @property
    def unit(self) -> str:
        return POSE_UNITS[self.name]

    @property
    def angular(self) -> bool:
        return self.unit == "rad"

    @property
    def index(self) -> int:
        """Its position in the six-value pose (``POSE``)."""
        return POSE.index(self.name)


@dataclass(frozen=True)
class Drive:
    """A driven joint: its joint coordinate ``name`` (rho_1, ...), ``kind`` ("linear" [m] or "rotary"
    [rad]) and ``stroke`` (lower, upper) in that unit."""

    name: str
    kind: str
    stroke: tuple[float, float]

    def __post_init__(self) -> None:
        if self.kind not in DRIVE_UNITS:
            raise TopologyError(f"drive {self.name}: kind {self.kind!r}: expected one of {', '.join(DRIVE_UNITS)}")
        lo, hi = (float(v) for v in self.stroke)
        if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
            raise TopologyError(
                f"drive {self.name}: stroke {self.stroke!r}: expected finite (lower, upper) "
                f"[{self.unit}] with lower < upper"
            )
        object.__setattr__(self, "stroke", (lo, hi))

    @property
    def unit(self) -> str:
        return DRIVE_UNITS[self.kind]


@dataclass(frozen=True)
class Topology:
    """The interface shape of a mechanism (module docstring).

    name: the mechanism's name (for example "3PRS"); coordinates: the independent coordinates in the
    description's order (q); drives: the driven joints in order (rho), as many as coordinates; home:
    the home pose, one value per coordinate in its unit.
    """

    name: str
    coordinates: tuple[Coordinate, ...]
    drives: tuple[Drive, ...]
    home: tuple[float, ...]

    def __post_init__(self) -> None:
        names = [c.name for c in self.coordinates]
        if len(set(names)) != len(names):
            raise TopologyError(f"{self.name}: coordinates {names}: each pose component at most once")
        if len(self.drives) != len(self.coordinates):
            raise TopologyError(
                f"{self.name}: {len(self.drives)} drives for {len(self.coordinates)} coordinates "
                f"({', '.join(names)}): a fully actuated mechanism needs one drive per coordinate"
            )
        drives = [d.name for d in self.drives]
        if len(set(drives)) != len(drives):
            raise TopologyError(f"{self.name}: drives {drives}: each joint name at most once")
        if len(self.home) != len(self.coordinates) or not all(math.isfinite(float(v)) for v in self.home):
            raise TopologyError(
                f"{self.name}: home {self.home!r}: expected {len(self.coordinates)} finite values ({', '.join(names)})"
            )
        object.__setattr__(self, "home", tuple(float(v) for v in self.home))

    @property
    def n(self) -> int:
        """The number of drives (= of independent coordinates)."""
        return len(self.drives)

    @property
    def names(self) -> tuple[str, ...]:
        """The coordinates' names, in order (for the 3PRS: z, psi, theta)."""
        return tuple(c.name for c in self.coordinates)

    @property
    def joints(self) -> tuple[str, ...]:
        """The drives' joint coordinate names, in order (rho_1, ...)."""
        return tuple(d.name for d in self.drives)

    @property
    def parasitic(self) -> tuple[Coordinate, ...]:
        """The pose components that follow from the coordinates (for the 3PRS: x, y, phi)."""
        return tuple(Coordinate(p) for p in POSE if p not in self.names)
