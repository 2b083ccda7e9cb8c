"""Mechanism designs as SSP variants: the same system with another mechanism swapped in.

A design is a mechanism FMU (built from ``fmus/mechanism`` with its own default parameters)
plus the parameter sets that define it. Its system ``ssp/MAST_<design>.ssd`` is the default
system (``systems.MAST``) with, and only with:

- the mechanism component's FMU replaced by the design's;
- the geometry set (bound to the mechanism *and* the controller, whose inverse kinematics
  must be the machine's) replaced by the design's;
- the design's extra sets bound after the others (mechanism, actuators);
- the transmission set (gear ratio and feed, bound to the actuators and the controller) replaced by the
  design's (the 6-UPS's ball screws: ``transmission_screw.ssv``).

``DESIGNS`` are the 3PRS's (parameter variants of the default system). ``MECHANISMS`` are designs of
another mechanism (a description file that extends no other: the 3-RPS), each a system of its own
made the same way, with also its mass set and its actuators' set (stroke, carriage: written from its
description, ``description_sets``) in place of the 3PRS's, and its own controller FMU (the
controller's parameters and kinematic model are its description's, ``designs.parameters_for``).

``python -m mast.core.variants`` writes those files (``systems.generate``), with the controller
variants of ``controllers.py`` (tests check they are up to date); ``mast build`` builds each
design's FMU with the defaults of its system.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

from .systems import MAST, REPO, SSP_SRC, STANDALONE, Part, SystemDescription, generate

DEFAULT_GEOMETRY = "resources/geometry_3prs.ssv"
DEFAULT_MASSES = "resources/mass_3prs.ssv"
DEFAULT_STROKE = "resources/stroke_3prs.ssv"
DEFAULT_TRANSMISSION = "resources/transmission.ssv"
MECHANISM_FMU = "MastMechanism"
ACTUATOR_FMU = "MastActuator"


@dataclass(frozen=True)
class Design:
    """One mechanism design: its FMU, its parameter sets, its documentation page."""

    name: str
    model_identifier: str
    title: str
    geometry: str = DEFAULT_GEOMETRY
    mechanism_sets: tuple[str, ...] = ()  # bound to the mechanism after its other sets
    actuator_sets: tuple[str, ...] = ()  # bound to every actuator after its other sets
    masses: str = DEFAULT_MASSES  # in place of the 3PRS's mass set
    stroke: str = DEFAULT_STROKE  # in place of the 3PRS's actuator stroke set
    transmission: str = DEFAULT_TRANSMISSION  # gear ratio and feed (actuators and controller): the belt axis's
    controller: str = ""  # the controller FMU's model identifier ("": the base system's)

    @property
    def ssd(self) -> Path:
        return SSP_SRC / ("MAST.ssd" if self.model_identifier == MECHANISM_FMU else f"MAST_{self.name}.ssd")

    @property
    def doc(self) -> Path:
        return REPO / "docs" / "designs" / f"{self.name}.md"


DESIGNS = (
    Design("3PRS_T", MECHANISM_FMU, "3PRS, T layout, vertical guides (the paper)"),
    Design("3PRS_120", "Mast3PRS120", "3PRS, guides at 120 deg", geometry="resources/geometry_3prs_120.ssv"),
    Design(
        "3PRS_inclined",
        "Mast3PRSInclined",
        "3PRS, T layout, guides inclined 15 deg",
        geometry="resources/geometry_3prs_inclined.ssv",
        actuator_sets=("resources/guide_inclined.ssv",),
    ),
    Design(
        "actuators_only",
        "MastActuatorsOnly",
        "actuators alone (paper Fig. 10, without the MAST)",
        mechanism_sets=("resources/actuators_only.ssv",),
    ),
)


#: designs of another mechanism than the 3PRS: systems of their own (module docstring)
MECHANISMS = (
    Design(
        "3RPS",
        "Mast3RPS",
        "3-RPS, 120 deg, the paper's belt axes as legs",
        geometry="resources/geometry_3rps.ssv",
        masses="resources/mass_3rps.ssv",
        stroke="resources/actuator_3rps.ssv",
        controller="Mast3RPSController",
    ),
    Design(
        "6UPS",
        "Mast6UPS",
        "6-UPS hexapod, the paper's motor and gearhead on ball-screw legs",
        geometry="resources/geometry_6ups.ssv",
        masses="resources/mass_6ups.ssv",
        stroke="resources/actuator_6ups.ssv",
        actuator_sets=("resources/actuator_screw.ssv",),
        transmission="resources/transmission_screw.ssv",
        controller="Mast6UPSController",
    ),
    Design(
        "6PUS",
        "Mast6PUS",
        "6-PUS hexapod, the paper's belt axes as vertical guides",
        geometry="resources/geometry_6pus.ssv",
        masses="resources/mass_6pus.ssv",
        stroke="resources/stroke_6pus.ssv",
        controller="Mast6PUSController",
    ),
)


def design(name_or_identifier: str) -> Design:
    for d in DESIGNS + MECHANISMS:
        if name_or_identifier in (d.name, d.model_identifier):
            return d
    raise KeyError(f"no design {name_or_identifier!r}; designs: {', '.join(d.name for d in DESIGNS + MECHANISMS)}")


def variant(d: Design, base: SystemDescription = MAST) -> SystemDescription:
    """The system of design ``d``: ``base`` with the mechanism swapped (module docstring)."""
    swaps = {
        DEFAULT_GEOMETRY: d.geometry,
        DEFAULT_MASSES: d.masses,
        DEFAULT_STROKE: d.stroke,
        DEFAULT_TRANSMISSION: d.transmission,
    }
    swaps = {k: v for k, v in swaps.items() if k != v}
    sets = ", ".join(
        (d.geometry, *(v for k, v in swaps.items() if k != DEFAULT_GEOMETRY)) + d.mechanism_sets + d.actuator_sets
    )

    def geometry(part):
        return dataclasses.replace(part, bindings=tuple(swaps.get(s, s) for s in part.bindings))

    mechanism = geometry(base.mechanism)
    controller = geometry(base.controller)
    if d.controller:
        controller = dataclasses.replace(controller, fmu=f"{d.controller}.fmu")
    return dataclasses.replace(
        base,
        name=f"{base.name}_{d.name}",
        description=f"{base.description} - design {d.name}: {d.title}",
        comment=f"Design {d.name}: {d.title} (docs/designs/{d.name}.md).\n"
        f"     Written by `python -m mast.core.variants` from {base.name}.ssd: it differs from it only in the "
        "mechanism's\n     source "
        f"({d.model_identifier}.fmu{f', the controller {d.controller}.fmu' if d.controller else ''})"
        f" and the design's parameter sets\n     ({sets}).\n"
        "     Components may be swapped by editing their `source`; parameter sets are bound in order, later "
        "ones override.",
        controller=controller,
        mechanism=dataclasses.replace(
            mechanism, fmu=f"{d.model_identifier}.fmu", bindings=mechanism.bindings + d.mechanism_sets
        ),
        actuator=dataclasses.replace(
            geometry(base.actuator), bindings=geometry(base.actuator).bindings + d.actuator_sets
        ),
    )


def variant_ssd(d: Design) -> bytes:
    """The .ssd file of design ``d`` (``variant``)."""
    return generate(variant(d))


def write_variants() -> list[Path]:
    """(Re)write ssp/MAST_<design>.ssd for every design but the default one, and for every other mechanism's."""
    written = []
    for d in DESIGNS + MECHANISMS:
        if d.model_identifier == MECHANISM_FMU:
            continue
        d.ssd.write_bytes(variant_ssd(d))
        written.append(d.ssd)
    return written


def standalone(d: Design, home: str, motion: str) -> SystemDescription:
    """The system of design ``d`` driven by its own pose command (as ssp/MAST_standalone.ssd is the default
    system's): ``variant(d, STANDALONE)`` with its FMU ``Mast<design>Trajectory`` (the coordinates of ``d``'s
    description) bound to the home pose ``home`` and the motion ``motion`` (parameter sets of ssp/resources)."""
    system = variant(d, STANDALONE)
    name = f"MAST_{d.name}_standalone"
    return dataclasses.replace(
        system,
        name=name,
        system=name,
        comment=f"Design {d.name}: {d.title} (docs/designs/{d.name}.md), driven by its own pose command.\n"
        f"     Written by `python -m mast.core.variants`: MAST_{d.name}.ssd with a {d.model_identifier}Trajectory "
        "component in place\n     of the system inputs, so that any co-simulation host runs it as it is "
        "(libcosim and ecos accept no\n     system-level connectors).\n"
        "     Components may be swapped by editing their `source`; parameter sets are bound in order, later "
        "ones override.",
        trajectory=Part(
            f"{d.model_identifier}Trajectory.fmu",
            (home, motion),
            STANDALONE.trajectory.step,
            f"Pose command: home pose ({Path(home).name}) + sine ({Path(motion).name}); stepped with the controller",
        ),
    )


#: the standalone systems of other mechanisms (hosts without system inputs run them: mast hosts)
STANDALONES = (standalone(design("6UPS"), "resources/home_6ups.ssv", "resources/trajectory_6ups.ssv"),)


def write_standalones() -> list[Path]:
    """(Re)write ssp/MAST_<design>_standalone.ssd of ``STANDALONES``."""
    for system in STANDALONES:
        system.path.write_bytes(generate(system))
    return [system.path for system in STANDALONES]
