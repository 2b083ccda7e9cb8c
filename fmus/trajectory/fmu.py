"""FMI 2.0 Co-Simulation wrapper of the pose command (the equations live in model.py)."""

from __future__ import annotations

from ..common.fmi import BlockSlave
from .model import TrajectoryBlock


class MastTrajectory(BlockSlave):
    """Pose command for the MAST: home pose plus a sine on z, psi and theta, for hosts without a Python stimulus."""

    block_class = TrajectoryBlock
    author = "MAST co-simulation project"
    version = "0.1.0"
