"""FMI 2.0 Co-Simulation wrappers of the mechanism model (the equations live in model.py).

One model, several FMUs: each design is the same ``MechanismBlock`` with the default
parameters of its own system (``ssp/MAST_<design>.ssd``, written into the FMU by ``mast
build``); the classes below only give each FMU its model identifier and description. Its
variables and parameters follow the description its built-in parameters name (``Mast3RPS``: the
3-RPS's, ``MechanismBlock.for_parameters``).
Swap a design by the mechanism component's ``source`` and its parameter sets in the SSP.
"""

from __future__ import annotations

from ..common.fmi import BlockSlave
from .model import MechanismBlock


class MastMechanism(BlockSlave):
    """3PRS mechanism of the MAST: kinematics and inverse dynamics, the disturbance forces on the actuators (paper section 3.3)."""  # noqa: E501 (one line: the FMU's description)

    block_class = MechanismBlock
    author = "MAST co-simulation project"
    version = "0.1.0"


class Mast3PRS120(MastMechanism):
    """3PRS mechanism with its guides at 120 degrees (design 3PRS_120): kinematics and inverse dynamics, the disturbance forces on the actuators."""  # noqa: E501 (one line: the FMU's description)


class Mast3PRSInclined(MastMechanism):
    """3PRS mechanism, T layout, guides inclined 15 degrees towards the axis (design 3PRS_inclined): kinematics and inverse dynamics, the disturbance forces on the actuators."""  # noqa: E501 (one line: the FMU's description)


class MastActuatorsOnly(MastMechanism):
    """No mechanism attached (design actuators_only, paper Fig. 10): zero force on the actuators; the pose outputs are the kinematics of the massless 3PRS."""  # noqa: E501 (one line: the FMU's description)


class Mast3RPS(MastMechanism):
    """3-RPS mechanism (design 3RPS, descriptions/3RPS.toml: the paper's belt axes as legs): kinematics and inverse dynamics, the forces on the actuators along the legs."""  # noqa: E501 (one line: the FMU's description)


class Mast6UPS(MastMechanism):
    """6-UPS hexapod (design 6UPS, descriptions/6UPS.toml): kinematics and inverse dynamics of the six legs, the forces on the actuators along them."""  # noqa: E501 (one line: the FMU's description)


class Mast6PUS(MastMechanism):
    """6-PUS hexapod (design 6PUS, descriptions/6PUS.toml: the paper's belt axes as six vertical guides): kinematics and inverse dynamics, the disturbance forces on the actuators."""  # noqa: E501 (one line: the FMU's description)


#: every mechanism FMU built from this model (model identifier -> class)
VARIANTS = {
    cls.__name__: cls
    for cls in (MastMechanism, Mast3PRS120, Mast3PRSInclined, MastActuatorsOnly, Mast3RPS, Mast6UPS, Mast6PUS)
}
