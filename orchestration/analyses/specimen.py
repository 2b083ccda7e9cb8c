"""Can the drives hold a specimen at rest at the home pose? Checked before a run's first step.

The static drive forces with the specimen on the platform are the mechanism engine's inverse dynamics at rest at
the home pose (``workspace.home_static_forces``, what ``mast workspace`` reports as static forces), plus each
carriage's weight along its guide (``workspace.held_force``). Each drive's force is set against its datasheet
ratings (``sizing.drives``: the set the system names per actuator, ssp/resources/drive_ratings.ssv), as items
held continuously: the belt axis's drive force (F_guide_max), the gearhead's output torque F p / (2 pi) against its
continuous rating (tau_gear_cont) and the motor's torque F p / (2 pi i_r) against its nominal torque (tau_N),
gearhead lossless as in ``mast sizing``. An item above its rating refuses the specimen (``SpecimenError`` naming the
drive, the force and the rating).
"""

from __future__ import annotations

import contextlib
import math
from pathlib import Path
from typing import Mapping, Optional, Union

from fmus.common.parameters import Value

from ..core.specimen import MECHANISM, Specimen, SpecimenError
from ..core.ssp import SSPArchive, mechanism_parameters, read_ssd
from .sizing import SizingError, drives
from .workspace import held_force, home_static_forces, machine

#: the items a drive holds the specimen with: (component, item, rating, unit, the figure from the held force F [N]
#: and the actuator's parameters)
ITEMS = (
    ("guide", "belt (drive) force", "F_guide_max", "N", lambda F, a: F),
    ("gearhead", "output torque", "tau_gear_cont", "N m", lambda F, a: F * a["p"] / (2 * math.pi)),
    ("motor", "torque", "tau_N", "N m", lambda F, a: F * a["p"] / (2 * math.pi * a["i_r"])),
)


def _system(path: Path):
    """The system of a .ssd (its structure) or of a built .ssp (unpacked while the block runs)."""
    if path.suffix == ".ssd":
        return contextlib.nullcontext(read_ssd(path))
    return _unpacked(path)


@contextlib.contextmanager
def _unpacked(path: Path):
    with SSPArchive(path) as archive:
        yield archive.system


def check_held(
    ssp: Union[str, Path],
    specimen: Specimen,
    parameters: Optional[Mapping[str, Mapping[str, Value]]] = None,
    mechanism: Optional[Mapping[str, Value]] = None,
) -> dict:
    """The static drive forces holding ``specimen`` at rest at the home pose of the system ``ssp`` (.ssp or .ssd,
    with the run's overrides ``parameters``; ``mechanism``: the parameters of a mechanism FMU swapped into it, as
    ``mast compare`` does) against each drive's ratings. Returns the figures; raises SpecimenError naming the drive,
    the force and the rating when one is above it, and when the system has no mechanism to carry it."""
    path = Path(ssp)
    where = f"--specimen {specimen.label}"
    if not path.exists():
        raise SpecimenError(f"{where}: no such system {path}")
    with _system(path) as system:
        if MECHANISM not in system.components:
            raise SpecimenError(f"{where}: system {path} has no component '{MECHANISM}' to carry a specimen")
        base = dict(mechanism) if mechanism is not None else mechanism_parameters(system.components[MECHANISM])
        params = {**base, **(parameters or {}).get(MECHANISM, {}), **specimen.parameters()}
        m = machine(path, mechanism=params)
        out: dict = {"specimen": specimen.parameters(), "system": str(path)}
        kinds = {d.kind for d in m.topology.drives}
        try:
            home, forces = home_static_forces(m)
        except ValueError as err:
            out["not_checked"] = f"no static forces: {err}"
            return out
        out["home"] = list(home)
        if kinds != {"linear"}:
            out["not_checked"] = "the drives are not all linear (the ratings are a belt axis's)"
            return out
        try:
            rated = drives(system, parameters)
        except SizingError as err:
            out["not_checked"] = f"no ratings: {err}"
            return out
    out["drives"], refused = {}, []
    for k, F in enumerate(abs(held_force(forces, m.drive))):
        name = f"actuator_{k + 1}"
        drive = rated.get(name)
        if drive is None:
            continue
        rows, above = [], []
        for component, item, rating, unit, figure in ITEMS:
            value, limit = float(figure(float(F), drive.actuator)), drive.ratings[rating]
            rows.append({"component": component, "item": item, "figure": value, "limit": limit, "unit": unit})
            if value > limit:
                above.append(f"{component} {item} {value:.4g} {unit} > its rating {rating} = {limit:.4g} {unit}")
        if above:
            refused.append(
                f"drive {name} cannot hold it at rest at the home pose (static force {F:.4g} N): "
                f"{', '.join(above)} ({drive.source})"
            )
        out["drives"][name] = {"static_force_N": float(F), "items": rows}
    if refused:
        raise SpecimenError(f"{where}: " + "; ".join(refused))
    rows = [(name, r) for name, d in out["drives"].items() for r in d["items"]]
    if rows:  # the item nearest its rating
        worst = max(rows, key=lambda row: row[1]["figure"] / row[1]["limit"])
        name, r = worst
        out["limiting"] = {"drive": name, **r, "margin": 1.0 - r["figure"] / r["limit"]}
    return out


def held_text(doc: Mapping) -> str:
    """One line for the commands: the limiting item of the static hold, or why it was not checked."""
    where = doc.get("system", "")
    if "not_checked" in doc:
        return f"specimen: not checked against the drives' ratings ({where}): {doc['not_checked']}"
    lim = doc.get("limiting")
    if not lim:
        return f"specimen: no drive with ratings in {where}"
    return (
        f"specimen: held at rest at home ({where}); limiting {lim['drive']} {lim['component']} {lim['item']} "
        f"{lim['figure']:.4g} of {lim['limit']:.4g} {lim['unit']} (margin {100 * lim['margin']:.0f} %)"
    )


__all__ = ["ITEMS", "check_held", "held_text"]
