"""Shared fixtures: parameter sets loaded from the project's own .ssv files."""
from __future__ import annotations

from pathlib import Path

import pytest

from mast.ssv import read_values

ROOT = Path(__file__).resolve().parents[1]
PARAMS = ROOT / "ssp" / "parameters"

#: which parameter sets each component binds in the default system (ssp/MAST.ssd), in binding order
DEFAULT_SETS = {
    "actuator": ("transmission", "actuator_manufacturer"),
    "actuator_identified": ("transmission", "actuator_manufacturer", "actuator_identified"),
    "mechanism": ("geometry_3prs", "mass_3prs"),
    "controller": ("transmission", "geometry_3prs", "controller_joint"),
}


def load_params(component: str) -> dict:
    return read_values(*(PARAMS / f"{name}.ssv" for name in DEFAULT_SETS[component]))


@pytest.fixture
def actuator_params() -> dict:
    return load_params("actuator")


@pytest.fixture
def mechanism_params() -> dict:
    return load_params("mechanism")


@pytest.fixture
def controller_params() -> dict:
    return load_params("controller")
