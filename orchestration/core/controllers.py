"""Controllers as SSP variants: the same system with another controller FMU swapped in.

Every controller FMU has the same inputs and outputs (``fmus/controller/model.py``,
``DriveController``), so a variant's system ``ssp/MAST_<controller>.ssd`` is the default
system (``systems.MAST``) with, and only with, the controller component's

- FMU replaced by the variant's;
- parameter sets: for a model-based controller first every set the plant binds (the first
  actuator's and the mechanism's, in their order: the controller's own model is the
  plant's, so it is exact by default); then the default controller's, minus those the
  variant has no use for (the cascade gains, for computed torque), which win on names the
  plant's sets share with them (``L``: the motor's inductance, the legs' length); then the
  variant's own set.

``python -m mast.core.variants`` writes these files (``systems.generate``) with the mechanism
designs' (tests check they are up to date); ``mast build`` builds each controller FMU with the defaults of its
system.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

from .systems import MAST, SSP_SRC, SystemDescription, generate

CONTROLLER_FMU = "MastController"
CASCADE_SETS = ("resources/controller_joint.ssv", "resources/controller_paper_fit.ssv")


@dataclass(frozen=True)
class ControllerVariant:
    """One controller: its FMU, its parameter sets, whether it carries a model of the plant."""

    name: str
    model_identifier: str
    title: str
    sets: tuple[str, ...] = ()  # bound after every other set
    drop_sets: tuple[str, ...] = ()  # default controller sets it does not take
    plant_model: bool = False  # bind the plant's sets too (its own inverse dynamic model)

    @property
    def ssd(self) -> Path:
        return SSP_SRC / ("MAST.ssd" if self.model_identifier == CONTROLLER_FMU else f"MAST_{self.name}.ssd")


CONTROLLERS = (
    ControllerVariant("joint", CONTROLLER_FMU, "joint-space cascade (the paper, Fig. 2)"),
    ControllerVariant(
        "workspace",
        "MastWorkspaceController",
        "workspace position control (paper Fig. 3a)",
        sets=("resources/controller_workspace.ssv",),
    ),
    ControllerVariant(
        "feedforward",
        "MastFeedForwardController",
        "joint-space cascade with inverse-dynamics torque feed-forward",
        sets=("resources/controller_feedforward.ssv",),
        plant_model=True,
    ),
    ControllerVariant(
        "computed_torque",
        "MastComputedTorqueController",
        "computed torque control (paper Fig. 3b)",
        sets=("resources/controller_computed_torque.ssv",),
        drop_sets=CASCADE_SETS,
        plant_model=True,
    ),
)


def controller(name_or_identifier: str) -> ControllerVariant:
    for c in CONTROLLERS:
        if name_or_identifier in (c.name, c.model_identifier):
            return c
    raise KeyError(f"no controller {name_or_identifier!r}; controllers: {', '.join(c.name for c in CONTROLLERS)}")


def variant(c: ControllerVariant, base: SystemDescription = MAST) -> SystemDescription:
    """The system of controller ``c``: ``base`` with the controller swapped (module docstring)."""
    plant = []
    if c.plant_model:
        plant = list(dict.fromkeys(base.actuator.bindings + base.mechanism.bindings))
    own = [s for s in base.controller.bindings if s not in c.drop_sets]
    plant = [s for s in plant if s not in own]
    comment = (
        f"Controller {c.name}: {c.title} (docs/controller.md).\n"
        f"     Written by `python -m mast.core.variants` from {base.name}.ssd: it differs from it only in the "
        f"controller's\n     source ({c.model_identifier}.fmu) and parameter sets"
        + (f" (without {', '.join(c.drop_sets)})" if c.drop_sets else "")
        + ".\n"
        + (
            f"     The plant's sets come first ({', '.join(plant)}): the controller's model is the plant's, and the\n"
            f"     controller's own sets, bound after them, win on shared names (L: winding inductance / leg length).\n"
            if plant
            else ""
        )
        + (f"     Its own: {', '.join(c.sets)}, bound last.\n" if c.sets else "")
        + "     Components may be swapped by editing their `source`; parameter sets are bound in order, later ones "
        "override."
    )
    return dataclasses.replace(
        base,
        name=f"{base.name}_{c.name}",
        description=f"{base.description} - controller {c.name}: {c.title}",
        comment=comment,
        controller=dataclasses.replace(
            base.controller, fmu=f"{c.model_identifier}.fmu", bindings=tuple(plant + own) + c.sets
        ),
    )


def variant_ssd(c: ControllerVariant) -> bytes:
    """The .ssd file of controller ``c`` (``variant``)."""
    return generate(variant(c))


def write_variants() -> list[Path]:
    """(Re)write ssp/MAST_<controller>.ssd for every controller but the default one."""
    written = []
    for c in CONTROLLERS:
        if c.model_identifier != CONTROLLER_FMU:
            c.ssd.write_bytes(variant_ssd(c))
            written.append(c.ssd)
    return written
