"""Mechanism designs as SSP variants: the same system with another mechanism swapped in.

A design is a mechanism FMU (built from ``fmus/mechanism`` with its own default parameters)
plus the parameter sets that define it. Its system ``ssp/MAST_<design>.ssd`` is the default
system ``ssp/MAST.ssd`` with, and only with:

- the mechanism component's ``source`` replaced by the design's FMU;
- the geometry set (bound to the mechanism *and* the controller, whose inverse kinematics
  must be the machine's) replaced by the design's;
- the design's extra sets bound after the others (mechanism, actuators).

``python -m mast.core.variants`` rewrites those files from ``ssp/MAST.ssd``, and the controller
variants of ``controllers.py`` (tests check they are up to date); ``mast build`` builds each
design's FMU with the defaults of its system.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

REPO = Path(__file__).resolve().parents[2]
SSP_SRC = REPO / "ssp"
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


def _append_bindings(block: str, sources: Sequence[str]) -> str:
    """A component's XML text with bindings added after its last one (same indentation)."""
    if not sources:
        return block
    matches = list(re.finditer(r"\n([ \t]*)<ssd:ParameterBinding\b[^>]*/>", block))
    if not matches:
        raise ValueError("a component to add parameter sets to has no ParameterBinding")
    last = matches[-1]
    lines = "".join(f"\n{last.group(1)}<ssd:ParameterBinding source=\"{src}\"/>" for src in sources)
    return block[:last.end()] + lines + block[last.end():]


def retitle(base: Path, name: str, what: str, note: str) -> str:
    """``base``'s text named MAST_<name>, its system description extended by ``what``, its leading comment ``note``."""
    text = base.read_text(encoding="utf-8")
    text, n = re.subn(r"<!--.*?-->", lambda m: note, text, count=1, flags=re.S)
    if not n:
        raise ValueError(f"{base}: no leading comment to replace")
    text = re.sub(r'(<ssd:SystemStructureDescription\b[^>]*?\bname=")[^"]*(")', rf"\g<1>MAST_{name}\g<2>",
                  text, count=1)
    return re.sub(r'(<ssd:System\b[^>]*?\bdescription=")([^"]*)(")',
                  lambda m: f"{m.group(1)}{m.group(2)} - {what}{m.group(3)}", text, count=1)


def variant_ssd(d: Design, base: Path = SSP_SRC / "MAST.ssd") -> bytes:
    """The system of design ``d``: ``base`` with the mechanism swapped (module docstring).

    Edits the text, so that everything else stays byte for byte as in ``base``.
    """
    text = retitle(base, d.name, f"design {d.name}: {d.title}", (
        f"<!-- Design {d.name}: {d.title} (docs/designs/{d.name}.md).\n"
        f"     Written by `python -m mast.core.variants` from {base.name}: it differs from it only in the mechanism's\n"
        f"     source ({d.model_identifier}.fmu) and the design's parameter sets\n"
        f"     ({', '.join((d.geometry,) + d.mechanism_sets + d.actuator_sets)}).\n"
        f"     Components may be swapped by editing their `source`; parameter sets are bound in order, later ones override. -->"))
    text = text.replace(f'source="{DEFAULT_GEOMETRY}"', f'source="{d.geometry}"')
    swapped = 0

    def component(m: re.Match) -> str:
        nonlocal swapped
        block = m.group(0)
        source = re.search(r'\bsource="([^"]*)"', block).group(1)
        if Path(source).stem == MECHANISM_FMU:
            swapped += 1
            new = Path(source).with_name(f"{d.model_identifier}.fmu").as_posix()
            block = block.replace(f'source="{source}"', f'source="{new}"', 1)
            return _append_bindings(block, d.mechanism_sets)
        if Path(source).stem == ACTUATOR_FMU:
            return _append_bindings(block, d.actuator_sets)
        return block

    text = re.sub(r"<ssd:Component\b.*?</ssd:Component>", component, text, flags=re.S)
    if swapped != 1:
        raise ValueError(f"{base}: expected one component using {MECHANISM_FMU}.fmu, found {swapped}")
    return text.encode("utf-8")


def write_variants(base: Path = SSP_SRC / "MAST.ssd") -> list[Path]:
    """(Re)write ssp/MAST_<design>.ssd for every design but the default one."""
    written = []
    for d in DESIGNS:
        if d.model_identifier == MECHANISM_FMU:
            continue
        d.ssd.write_bytes(variant_ssd(d, base))
        written.append(d.ssd)
    return written
