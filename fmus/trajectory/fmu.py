"""FMI 2.0 Co-Simulation wrapper of the pose command (the equations live in model.py).

Its variables follow the built-in parameters (``TrajectoryBlock.for_parameters``): built with the home values of
another description's coordinates (``x_home``, ..., ``phi_home`` for a hexapod) it commands those, Python and
native (``mast.core.native.build.native_sources`` takes the same class).
"""

from __future__ import annotations

from ..common.fmi import BlockSlave
from .model import TrajectoryBlock


class MastTrajectory(BlockSlave):
    """Pose command for the MAST: home pose plus a sine on each coordinate of the mechanism (z, psi and theta by default), for hosts without a Python stimulus."""  # noqa: E501 (one line: the FMU's description)

    block_class = TrajectoryBlock
    author = "MAST co-simulation project"
    version = "0.1.0"


class Mast6UPSTrajectory(MastTrajectory):
    """Pose command for the 6-UPS hexapod (design 6UPS): home pose plus a sine on x, y, z, psi, theta and phi, for hosts without a Python stimulus."""  # noqa: E501 (one line: the FMU's description)
