"""Mechanism designs as SSP variants: the same system with another mechanism swapped in.

A design is a mechanism FMU (built from ``fmus/mechanism`` with its own default parameters)
plus the parameter sets that define it. Its system ``ssp/MAST_<design>.ssd`` is the default
system (``systems.MAST``) with, and only with:

- the mechanism component's FMU replaced by the design's;
- the geometry set (bound to the mechanism *and* the controller, whose inverse kinematics
  must be the machine's) replaced by the design's;
- the design's extra sets bound after the others (mechanism, actuators).

``python -m mast.core.variants`` writes those files (``systems.generate``), with the controller
variants of ``controllers.py`` (tests check they are up to date); ``mast build`` builds each
design's FMU with the defaults of its system.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

from .systems import MAST, REPO, SSP_SRC, SystemDescription, generate

DEFAULT_GEOMETRY = "resources/geometry_3prs.ssv"
MECHANISM_FMU = "MastMechanism"
ACTUATOR_FMU = "MastActuator"


@dataclass(frozen=True)
class Design:
    """One mechanism design: its FMU, its parameter sets, its documentation page."""

    name: str
    model_identifier: str
    title: str
    geometry: str = DEFAULT_GEOMETRY
    mechanism_sets: tuple[str, ...] = ()      # bound to the mechanism after its other sets
    actuator_sets: tuple[str, ...] = ()       # bound to every actuator after its other sets

    @property
    def ssd(self) -> Path:
        return SSP_SRC / ("MAST.ssd" if self.model_identifier == MECHANISM_FMU else f"MAST_{self.name}.ssd")

    @property
    def doc(self) -> Path:
        return REPO / "docs" / "designs" / f"{self.name}.md"


DESIGNS = (
    Design("3PRS_T", MECHANISM_FMU, "3PRS, T layout, vertical guides (the paper)"),
    Design("3PRS_120", "Mast3PRS120", "3PRS, guides at 120 deg", geometry="resources/geometry_3prs_120.ssv"),
    Design("3PRS_inclined", "Mast3PRSInclined", "3PRS, T layout, guides inclined 15 deg",
           geometry="resources/geometry_3prs_inclined.ssv", actuator_sets=("resources/guide_inclined.ssv",)),
    Design("actuators_only", "MastActuatorsOnly", "actuators alone (paper Fig. 10, without the MAST)",
           mechanism_sets=("resources/actuators_only.ssv",)),
)


def design(name_or_identifier: str) -> Design:
    for d in DESIGNS:
        if name_or_identifier in (d.name, d.model_identifier):
            return d
    raise KeyError(f"no design {name_or_identifier!r}; designs: {', '.join(d.name for d in DESIGNS)}")


def variant(d: Design, base: SystemDescription = MAST) -> SystemDescription:
    """The system of design ``d``: ``base`` with the mechanism swapped (module docstring)."""
    sets = ", ".join((d.geometry,) + d.mechanism_sets + d.actuator_sets)

    def geometry(part):
        return dataclasses.replace(part, bindings=tuple(d.geometry if s == DEFAULT_GEOMETRY else s for s in part.bindings))

    mechanism = geometry(base.mechanism)
    return dataclasses.replace(
        base, name=f"{base.name}_{d.name}", description=f"{base.description} - design {d.name}: {d.title}",
        comment=f"Design {d.name}: {d.title} (docs/designs/{d.name}.md).\n"
                f"     Written by `python -m mast.core.variants` from {base.name}.ssd: it differs from it only in the "
                f"mechanism's\n     source ({d.model_identifier}.fmu) and the design's parameter sets\n     ({sets}).\n"
                "     Components may be swapped by editing their `source`; parameter sets are bound in order, later "
                "ones override.",
        controller=geometry(base.controller),
        mechanism=dataclasses.replace(mechanism, fmu=f"{d.model_identifier}.fmu",
                                      bindings=mechanism.bindings + d.mechanism_sets),
        actuator=dataclasses.replace(base.actuator, bindings=base.actuator.bindings + d.actuator_sets))


def variant_ssd(d: Design) -> bytes:
    """The .ssd file of design ``d`` (``variant``)."""
    return generate(variant(d))


def write_variants() -> list[Path]:
    """(Re)write ssp/MAST_<design>.ssd for every design but the default one."""
    written = []
    for d in DESIGNS:
        if d.model_identifier == MECHANISM_FMU:
            continue
        d.ssd.write_bytes(variant_ssd(d))
        written.append(d.ssd)
    return written
