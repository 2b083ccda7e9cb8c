"""FMI 2.0 Co-Simulation wrapper of the controller model (the equations live in model.py)."""
from __future__ import annotations

from ..common.fmi import BlockSlave
from .model import ControllerBlock


class MastController(BlockSlave):
    """Joint-space cascade control of the three MAST axes: P position, PI velocity, PI current (paper Fig. 2 and 6)."""

    block_class = ControllerBlock
    author = "MAST co-simulation project"
    version = "0.1.0"
