"""Shared fixtures: parameter values as the default system (ssp/MAST.ssd) binds them."""
from __future__ import annotations

from pathlib import Path

import pytest

from mast.core.ssp import read_ssd
from mast.core.ssv import read_values

ROOT = Path(__file__).resolve().parents[1]
SSD = ROOT / "ssp" / "MAST.ssd"
RESOURCES = ROOT / "ssp" / "resources"


def load_params(component: str) -> dict:
    """Merged parameter bindings of a component of the default system.

    ``component`` is "actuator" (actuator_1), "mechanism", "controller", or
    "actuator_identified" (actuator_1 with the paper's identified set bound last).
    """
    system = read_ssd(SSD)
    if component == "actuator_identified":
        return {**system.components["actuator_1"].parameters, **read_values(RESOURCES / "actuator_identified.ssv")}
    name = "actuator_1" if component == "actuator" else component
    return dict(system.components[name].parameters)


@pytest.fixture
def actuator_params() -> dict:
    return load_params("actuator")


@pytest.fixture
def mechanism_params() -> dict:
    return load_params("mechanism")


@pytest.fixture
def controller_params() -> dict:
    return load_params("controller")
