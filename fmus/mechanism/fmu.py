"""FMI 2.0 Co-Simulation wrapper of the mechanism model (the equations live in model.py)."""
from __future__ import annotations

from ..common.fmi import BlockSlave
from .model import MechanismBlock


class MastMechanism(BlockSlave):
    """3PRS mechanism of the MAST: kinematics and inverse dynamics, the disturbance forces on the actuators (paper section 3.3)."""

    block_class = MechanismBlock
    author = "MAST co-simulation project"
    version = "0.1.0"
