"""FMI 2.0 Co-Simulation wrappers of the controllers (the equations live in model.py and its siblings).

All four have the same inputs and outputs (``DriveController``: the 3PRS's axes; another mechanism's
controller is ``block_class.for_topology(topology)``, its variables by the connector convention), so a system
swaps its controller by the controller component's ``source`` and parameter sets in the SSP
(``ssp/MAST_<controller>.ssd``).
"""

from __future__ import annotations

from ..common.fmi import BlockSlave
from .computed_torque import ComputedTorqueController
from .emps import EmpsController
from .feedforward import FeedForwardController
from .model import ControllerBlock
from .workspace import WorkspaceController


class MastController(BlockSlave):
    """Joint-space cascade control of the three MAST axes: P position, PI velocity; current commands to the actuators' current loops (paper Fig. 2 and 6)."""  # noqa: E501 (one line: the FMU's description)

    block_class = ControllerBlock
    author = "MAST co-simulation project"
    version = "0.1.0"


class MastWorkspaceController(MastController):
    """Workspace position control of the MAST (paper Fig. 3a): pose error through the direct kinematics, velocity command through the inverse Jacobian, PI velocity loop per axis."""  # noqa: E501 (one line: the FMU's description)

    block_class = WorkspaceController


class MastFeedForwardController(MastController):
    """Joint-space cascade of the MAST with velocity and inverse-dynamics torque feed-forward (the controller's own model of actuators and mechanism)."""  # noqa: E501 (one line: the FMU's description)

    block_class = FeedForwardController


class MastComputedTorqueController(MastController):
    """Computed torque control of the MAST (paper Fig. 3b): PD error dynamics through the controller's own inverse dynamic model; current commands to the actuators' current loops."""  # noqa: E501 (one line: the FMU's description)

    block_class = ComputedTorqueController


class Mast3RPSController(MastController):
    """Joint-space cascade control of the three legs of the 3-RPS (design 3RPS): its own inverse kinematics from the 3-RPS's geometry; current commands to the actuators' current loops."""  # noqa: E501 (one line: the FMU's description)


class Mast6UPSController(MastController):
    """Joint-space cascade control of the six legs of the 6-UPS hexapod (design 6UPS): its own inverse kinematics from the hexapod's geometry; current commands to the actuators' current loops."""  # noqa: E501 (one line: the FMU's description)


class Mast6PUSController(MastController):
    """Joint-space cascade control of the six carriages of the 6-PUS hexapod (design 6PUS): its own inverse kinematics from the hexapod's geometry; current commands to the actuators' current loops."""  # noqa: E501 (one line: the FMU's description)


class MastEmpsController(BlockSlave):
    """Sampled P position loop into a P velocity loop of one drive axis, FIR velocity estimate, drive command saturation and gain (the EMPS benchmark's controller)."""  # noqa: E501 (one line: the FMU's description)

    block_class = EmpsController
    author = "MAST co-simulation project"
    version = "0.1.0"
