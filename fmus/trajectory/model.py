"""Pose command: home pose + sine, the block behind the MastTrajectory FMU.

Outputs at time t (t0 is the start time given to ``initialize``), one per independent coordinate c
of the mechanism (``fmus.mechanism.topology``; for the 3PRS z, psi, theta):

    <c>_cmd = <c>_home + amplitude_<c> * sin(2 pi f (t - t0))

the same command as the project's Python stimulus ``mast.core.motion.SineMotion`` (whose home
pose is read from the mechanism at the start). ``do_step(t, h)`` leaves the values at
t + h, so a Jacobi master hands the controller the command of the instant it samples.

The time is read on a grid of ``RESOLUTION`` = 1 ns (t - t0 rounded to whole nanoseconds): hosts hand the
same communication point over in different last bits (t0 + n h, a sum of steps, integer nanoseconds
converted), and the command of that point is then the same number in every host. A difference of one
bit in the command would grow to 1e-9 relative in the mechanism's forces (through the stiff transmission's
acceleration) and break the hosts' agreement to rounding (mast.hosts.cosim.RELATIVE).

``TrajectoryBlock`` commands the 3PRS's coordinates (z, psi, theta); ``TrajectoryBlock.for_coordinates``
gives the block of any other set of pose components, and an FMU built with the parameters of another
set (``x_home``, ...) has that block's variables (``Block.for_parameters``).
"""

from __future__ import annotations

import math
from typing import ClassVar, Mapping, Sequence

from ..common.block import Block, ModelError
from ..common.parameters import Param, Value, nonnegative
from ..mechanism.topology import POSE, Coordinate

#: the resolution of the block's clock [s] (module docstring; libcosim's own clock counts nanoseconds)
RESOLUTION = 1e-9

#: per pose component: what its home value is, and what its command is
_TEXT = {
    "x": ("Platform centre P, x, at the home pose", "Commanded x of the platform centre P"),
    "y": ("Platform centre P, y, at the home pose", "Commanded y of the platform centre P"),
    "z": (
        "Height of the platform centre P at the home pose (all sliders at rho_0)",
        "Commanded height of the platform centre P",
    ),
    "psi": ("Roll at the home pose", "Commanded roll about x"),
    "theta": ("Pitch at the home pose", "Commanded pitch about y"),
    "phi": ("Yaw at the home pose", "Commanded yaw about z"),
}


def _parameters(coordinates: Sequence[str]) -> tuple[Param, ...]:
    """The home pose and the amplitude of every coordinate (angles within +-pi/2, z above the base), the frequency."""
    homes, amplitudes = [], []
    for name in coordinates:
        c = Coordinate(name)
        if c.angular:
            homes.append(Param(f"{name}_home", "rad", _TEXT[name][0], minimum=-math.pi / 2, maximum=math.pi / 2))
            amplitudes.append(
                Param(
                    f"amplitude_{name}",
                    "rad",
                    f"Amplitude of the sine on {name} (0: {name} stays at home)",
                    minimum=-math.pi / 2,
                    maximum=math.pi / 2,
                )
            )
        else:
            homes.append(
                Param(
                    f"{name}_home", "m", _TEXT[name][0], **({"minimum": 0.0, "exclusive": True} if name == "z" else {})
                )
            )
            amplitudes.append(
                Param(
                    f"amplitude_{name}",
                    "m",
                    f"Amplitude of the sine on {name} (0: {name} stays at home)",
                    minimum=-1.0,
                    maximum=1.0,
                )
            )
    return (*homes, *amplitudes, nonnegative("frequency", "Hz", "Frequency of the sine (0 holds the home pose)"))


class TrajectoryBlock(Block):
    """Home pose plus a sine on z, psi and theta (one frequency)."""

    #: the commanded coordinates, in the mechanism's order (``Topology.names``)
    COORDINATES: ClassVar[tuple[str, ...]] = ("z", "psi", "theta")
    INPUTS = ()
    OUTPUTS = tuple(f"{c}_cmd" for c in COORDINATES)
    PARAMETERS = _parameters(COORDINATES)
    UNITS = {f"{c}_cmd": Coordinate(c).unit for c in COORDINATES}
    DESCRIPTIONS = {f"{c}_cmd": _TEXT[c][1] for c in COORDINATES}
    _classes: ClassVar[dict] = {}

    @classmethod
    def for_coordinates(cls, coordinates: Sequence[str]) -> type["TrajectoryBlock"]:
        """The block commanding ``coordinates`` (pose components, in the mechanism's order: ``Topology.names``)."""
        names = tuple(Coordinate(c).name for c in coordinates)  # each checked to be a pose component
        if not names or len(set(names)) != len(names):
            raise ValueError(f"trajectory coordinates {names}: expected distinct pose components of {', '.join(POSE)}")
        if names == TrajectoryBlock.COORDINATES:
            return TrajectoryBlock
        found = cls._classes.get(names)
        if found is None:
            found = cls._classes[names] = type(
                f"TrajectoryBlock_{'_'.join(names)}",
                (TrajectoryBlock,),
                {
                    "__doc__": f"Home pose plus a sine on {', '.join(names)} (one frequency).",
                    "__module__": __name__,
                    "COORDINATES": names,
                    "OUTPUTS": tuple(f"{c}_cmd" for c in names),
                    "PARAMETERS": _parameters(names),
                    "UNITS": {f"{c}_cmd": Coordinate(c).unit for c in names},
                    "DESCRIPTIONS": {f"{c}_cmd": _TEXT[c][1] for c in names},
                },
            )
        return found

    @classmethod
    def for_parameters(cls, params: Mapping[str, Value]) -> type["TrajectoryBlock"]:
        """The block of the coordinates whose home values ``params`` give (``<c>_home``, in pose order); this
        class when they give none."""
        names = tuple(c for c in POSE if f"{c}_home" in params)
        return cls.for_coordinates(names) if names else cls

    def __init__(self, params: Mapping[str, Value], name: str = "") -> None:
        super().__init__(params, name)
        p = self.params
        self._home = tuple(p[f"{c}_home"] for c in self.COORDINATES)
        self._amplitude = tuple(p[f"amplitude_{c}"] for c in self.COORDINATES)
        self._omega = 2.0 * math.pi * p["frequency"]
        self._t0 = 0.0

    def _write(self, t: float) -> None:
        if not math.isfinite(t):
            raise ModelError(f"{self.name}: time t = {t!r} s is not finite")
        s = math.sin(self._omega * (round((t - self._t0) / RESOLUTION) * RESOLUTION))
        self.values[:] = [h + a * s for h, a in zip(self._home, self._amplitude)]

    def initialize(self, t0: float) -> None:
        self._t0 = float(t0)
        self._write(self._t0)

    def do_step(self, t: float, h: float) -> None:
        self._write(t + h)
