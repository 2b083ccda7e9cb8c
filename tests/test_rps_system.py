"""The 3-RPS as a system (issue 25): its mechanism block's and controllers' parameters from its description file,
its FMU, its design SSD, its run beside the 3PRS's.

Physics against independent routes: the forces the system's mechanism reports at rest against the Newton-Euler
oracle (tests/newton_euler.py), an energy balance over a run from the recorded joint motion and forces.
"""

from __future__ import annotations

import math

import pytest

from fmus.common.parameters import ParameterError
from fmus.controller.feedforward import FeedForwardController
from fmus.controller.model import ControllerBlock
from fmus.mechanism import designs
from fmus.mechanism.description import load
from fmus.mechanism.model import MechanismBlock

RPS = load("3RPS")


def rps_parameters(**changes) -> dict:
    """The mechanism block's parameters of the 3-RPS: the description's values, ``kinematics``, ``attached``."""
    return {"kinematics": "3RPS", **RPS.values(), "attached": 1, **changes}


def test_the_mechanism_block_takes_the_parameters_of_its_description():
    """Name, unit, description = the file's source, range where the file gives one; kinematics and attached."""
    block = MechanismBlock(rps_parameters(), "rps")
    names = [p.name for p in block.PARAMETERS]
    assert names == ["kinematics", *RPS.parameters, "attached"]
    by_name = {p.name: p for p in block.PARAMETERS}
    for name, p in RPS.parameters.items():
        assert (by_name[name].unit, by_name[name].description) == (p.unit, p.source)
    assert (by_name["m_carriage"].minimum, by_name["g"].maximum) == (0.0, 100.0)
    assert by_name["x_cylinder"].minimum == -math.inf  # the file gives it no range
    assert "3RPS" in by_name["kinematics"].description
    with pytest.raises(ParameterError, match=r"rps: parameter 'm_carriage' = -1.0: expected a float in \[0, inf\]"):
        MechanismBlock(rps_parameters(m_carriage=-1.0), "rps")
    with pytest.raises(ParameterError, match=r"unknown parameter\(s\) H; expected names: .*R_b"):
        MechanismBlock(rps_parameters(H=0.4), "rps")
    with pytest.raises(ParameterError, match=r"missing parameter\(s\) R_b"):
        MechanismBlock({k: v for k, v in rps_parameters().items() if k != "R_b"}, "rps")


def test_the_3prs_schema_is_its_description_file_s():
    """The 3PRS keeps its declared schema (its FMU's parameters: names, order, units); those are its file's."""
    prs = designs.description("3PRS")
    schema = MechanismBlock.PARAMETERS
    assert designs.parameters_for(schema, "3PRS") == schema
    declared = {p.name: p.unit for p in schema if p.name not in ("kinematics", "attached")}
    assert declared == {n: p.unit for n, p in prs.parameters.items()}
    assert tuple(p.name for p in designs.KINEMATIC_PARAMETERS[1:]) == prs.kinematic


def test_an_fmu_class_of_the_3rps_has_its_parameters():
    """Block.for_parameters (what the FMU registers): the 3-RPS's schema; the 3PRS's unchanged."""
    cls = MechanismBlock.for_parameters(rps_parameters())
    assert cls.fixed and cls.MECHANISM == "3RPS" and [p.name for p in cls.PARAMETERS][1] == "R_b"
    assert cls.for_parameters(rps_parameters()) is cls
    block = cls(rps_parameters(), "rps")
    block.set(rho_1=0.41, rho_2=0.41, rho_3=0.41)
    block.initialize(0.0)
    assert block.outputs()["z"] == pytest.approx(RPS.describe().topology.home[0], rel=1e-12)
    prs = MechanismBlock.for_parameters({"kinematics": "3PRS", **designs.description("3PRS").values(), "attached": 1})
    assert prs.PARAMETERS == MechanismBlock.PARAMETERS and prs.MECHANISM == "3PRS"


@pytest.mark.parametrize("kind", [ControllerBlock, FeedForwardController])
def test_the_controllers_kinematic_model_takes_the_geometry_of_its_description(kind):
    """A controller's geometry set is its description's kinematic parameters (R_b, r, alpha_k for the 3-RPS); a
    feed-forward controller's inverse model also takes the bodies' (its mass sets)."""
    base = {p.name for p in kind.PARAMETERS}
    cls = kind.for_parameters({"kinematics": "3RPS", **{n: RPS.parameters[n].value for n in RPS.kinematic}})
    names = [p.name for p in cls.PARAMETERS]
    assert cls.__name__ == kind.__name__ and cls.MECHANISM == "3RPS"
    assert set(RPS.kinematic) <= set(names) and "H" not in names and "L" not in names
    if "m_leg" in base:
        assert "m_carriage" in names and "m_leg" not in names and "attached" in names
    else:
        assert "m_carriage" not in names
    assert kind.for_parameters({"kinematics": "3PRS", **designs.description("3PRS").values()}) is kind
