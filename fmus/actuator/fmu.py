"""FMI 2.0 Co-Simulation wrapper of the actuator model (the equations live in model.py)."""

from __future__ import annotations

from ..common.fmi import BlockSlave
from .drive import DriveActuatorBlock
from .load_axis import LoadAxisBlock


class MastActuator(BlockSlave):
    """One linear axis of the MAST with its drive's PI current loop: DC motor, gearbox and belt guide (paper section 2.2, Fig. 2); current command in."""  # noqa: E501 (one line: the FMU's description)

    block_class = DriveActuatorBlock
    author = "MAST co-simulation project"
    version = "0.1.0"


class MastLoadAxis(BlockSlave):
    """A drive axis seen from the load, force-driven: mass, asymmetric Coulomb and viscous friction, force offset (single-axis benches such as EMPS)."""  # noqa: E501 (one line: the FMU's description)

    block_class = LoadAxisBlock
    author = "MAST co-simulation project"
    version = "0.1.0"
