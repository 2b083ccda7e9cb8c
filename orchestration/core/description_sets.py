"""The parameter sets of ssp/resources written from the mechanism description files.

Every geometry and mass number of a mechanism lives in its description file
(``fmus/mechanism/descriptions/*.toml``, docs/mechanism.md) with its unit and source; the sets the
SSDs bind are written from it (``python -m mast.core.variants``), never by hand:

- a geometry set (bound to the mechanism and to the controller, whose kinematic model must be the
  machine's): ``kinematics`` = the description's mechanism name, then its kinematic parameters
  (``DescriptionFile.kinematic``);
- a mass set (bound to the mechanism): every other parameter of the description (bodies, gravity,
  payload);
- sets of numbers derived from a description: the home pose (``<c>_home`` for each coordinate, the
  pose command's starting point), the gravity along inclined guides (``g_guide``), the actuators'
  stroke and start from the drives' stroke (``rho_min``, ``rho_max``, ``rho_0``) and the actuator on a
  leg that carries its carriage as a body of the mechanism (``M_load`` = ``g_guide`` = 0, the 3-RPS),
  each with its source "derived from <file>: ...".

Each parameter's description is its source in the file and its unit the file's. ``attached`` (does
the mechanism block load the actuators) is a setting of the block in a system, not of a mechanism:
it lives in the hand-written ``attached.ssv`` (and ``actuators_only.ssv`` overrides it).
``differences`` names what a committed set holds that its description does not give
(tests/test_systems.py).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Optional

from fmus.mechanism.description import DescriptionError, DescriptionFile, Expression, load
from fmus.mechanism.topology import POSE_UNITS

from . import ssv
from .systems import SSP_SRC

#: a row of a set: (name, value, unit ("": none), source)
Row = tuple[str, object, str, str]

#: the gravity component along a guide inclined by beta from the vertical (the 3PRS's guides)
GUIDE_GRAVITY = "g * cos(beta)"


def _unit(unit: str) -> str:
    """The SSV unit of a description's unit ("1", dimensionless: none)."""
    return "" if unit == "1" else unit


def geometry(file: DescriptionFile) -> tuple[list[Row], str]:
    """The geometry set's rows (``kinematics``, then the kinematic parameters) and its comment."""
    origin = f", from {file.extends}" if file.extends else ""
    rows: list[Row] = [
        ("kinematics", file.name, "", f"The mechanism of {file.path.name} (its [mechanism] name{origin}): {file.title}")
    ]
    rows += [
        (n, file.parameters[n].value, _unit(file.parameters[n].unit), file.parameters[n].source) for n in file.kinematic
    ]
    return rows, (
        f"Geometry of design {file.path.stem}: {file.title}. Bound to the mechanism and to the controller "
        "(its kinematic model)."
    )


def masses(file: DescriptionFile) -> tuple[list[Row], str]:
    """The mass set's rows: every parameter that is not the geometry's (bodies, gravity, payload), and its comment."""
    rows: list[Row] = [
        (p.name, p.value, _unit(p.unit), p.source) for p in file.parameters.values() if p.name not in file.kinematic
    ]
    return rows, (
        f"Masses, inertias, gravity and payload of design {file.path.stem}: {file.title}. Bound to the "
        "mechanism (its `attached`: attached.ssv)."
    )


def home(file: DescriptionFile) -> tuple[list[Row], str]:
    """The home pose's rows (``<c>_home`` for each coordinate c, [mechanism.home]) and the set's comment."""
    pose = file.describe().topology.home
    rows: list[Row] = [
        (
            f"{c}_home",
            value,
            POSE_UNITS[c],
            f"Home pose, derived from {file.path.name}: [mechanism.home] {c} = {expr.source}",
        )
        for c, value, expr in zip(file.coordinates, pose, file.home)
    ]
    return rows, (
        f"Home pose of design {file.path.stem}: {file.title}. Where the pose command of its standalone "
        "system starts (every drive at mid-stroke)."
    )


def guide(file: DescriptionFile) -> tuple[list[Row], str]:
    """The actuators' gravity along the guides (``g_guide`` = ``GUIDE_GRAVITY``) and the set's comment."""
    expression = Expression(GUIDE_GRAVITY, f"{file.path.name}: g_guide", file.units)
    expression.check(file.units, "m/s2")
    rows: list[Row] = [
        (
            "g_guide",
            float(expression(file.values())),
            "m/s2",
            f"Gravity along the guides, derived from {file.path.name}: {GUIDE_GRAVITY}",
        )
    ]
    return rows, (
        f"Actuators of design {file.path.stem}: {file.title}. Gravity along its guides; bind after "
        "actuator_manufacturer.ssv."
    )


def _stroke_rows(file: DescriptionFile) -> list[Row]:
    """rho_min, rho_max and rho_0 of every drive of ``file`` (its legs' one stroke; rho_0 its middle, where the home
    pose puts every drive: tests/test_rps_system.py). DescriptionError when the legs' strokes differ (one actuator
    set serves every leg)."""
    strokes = {leg.stroke for leg in file.legs}
    if len(strokes) != 1:
        raise DescriptionError(
            f"{file.path.name}: drive strokes {sorted(strokes)}: one actuator set serves every leg, expected one stroke"
        )
    ((lo, hi),) = strokes
    unit = "m" if file.legs[0].kind == "linear" else "rad"
    where = f"derived from {file.path.name}: [leg] drive stroke [{lo:g}, {hi:g}] {unit}"
    return [
        (
            "rho_0",
            0.5 * (lo + hi),
            unit,
            f"Initial joint position, the middle of the stroke (home: every drive at mid-stroke), {where}",
        ),
        ("rho_min", lo, unit, f"Lower end of the stroke, {where}"),
        ("rho_max", hi, unit, f"Upper end of the stroke, {where}"),
    ]


def stroke(file: DescriptionFile) -> tuple[list[Row], str]:
    """The actuators' stroke (``rho_min``, ``rho_max``) and start (``rho_0``, mid-stroke) from the description's drive
    stroke, and the set's comment."""
    return _stroke_rows(file), (
        f"Stroke of the actuators of design {file.path.stem}: {file.title}. Bound to every "
        "actuator after actuator_manufacturer.ssv."
    )


def leg_actuator(file: DescriptionFile) -> tuple[list[Row], str]:
    """The actuator on a leg whose carriage is a body of the mechanism (a 3-RPS's rod, docs/designs/3rps.md): no
    carriage mass and no gravity in the actuator (``M_load`` = 0, ``g_guide`` = 0: the mechanism's inverse dynamics
    carries both), its stroke and start (``stroke``), and the set's comment."""
    where = f"{file.path.name}: the carriage is each leg's driven part's body, in the mechanism's inverse dynamics"
    rows: list[Row] = [
        ("M_load", 0.0, "kg", f"No carriage on the belt: {where} (docs/designs/{file.path.stem.lower()}.md)"),
        ("g_guide", 0.0, "m/s2", f"No gravity in the actuator: {where}, its weight along the leaning leg included"),
    ]
    return rows + _stroke_rows(file), (
        f"Actuators on the legs of design {file.path.stem}: {file.title}. Bound to "
        "every actuator after actuator_manufacturer.ssv."
    )


@dataclass(frozen=True)
class DescribedSet:
    """A parameter set of ssp/resources (``name``.ssv) written by ``content`` from the description file
    ``description`` (a shipped file's name)."""

    name: str
    description: str
    content: Callable[[DescriptionFile], tuple[list[Row], str]]

    @property
    def path(self) -> Path:
        return SSP_SRC / "resources" / f"{self.name}.ssv"

    def parameter_set(self) -> ssv.ParameterSet:
        """The set as its description gives it."""
        file = load(self.description)
        rows, comment = self.content(file)
        return ssv.parameter_set(
            self.name,
            {n: v for n, v, _, _ in rows},
            {n: u for n, _, u, _ in rows if u},
            {n: s for n, _, _, s in rows},
            f"{comment} Written by `python -m mast.core.variants` from fmus/mechanism/descriptions/{file.path.name}: "
            "edit that file, not this one.",
        )


#: the sets written from description files (the designs' geometry: mast.core.designs)
SETS = (
    DescribedSet("geometry_3prs", "3PRS_T", geometry),
    DescribedSet("geometry_3prs_120", "3PRS_120", geometry),
    DescribedSet("geometry_3prs_inclined", "3PRS_inclined", geometry),
    DescribedSet("mass_3prs", "3PRS_T", masses),
    DescribedSet("home_3prs", "3PRS_T", home),
    DescribedSet("guide_inclined", "3PRS_inclined", guide),
    DescribedSet("stroke_3prs", "3PRS_T", stroke),
    DescribedSet("geometry_3rps", "3RPS", geometry),
    DescribedSet("mass_3rps", "3RPS", masses),
    DescribedSet("actuator_3rps", "3RPS", leg_actuator),
    DescribedSet("geometry_6ups", "6UPS", geometry),
    DescribedSet("mass_6ups", "6UPS", masses),
    DescribedSet("actuator_6ups", "6UPS", leg_actuator),
    DescribedSet("home_6ups", "6UPS", home),
    DescribedSet("geometry_6pus", "6PUS", geometry),
    DescribedSet("mass_6pus", "6PUS", masses),
    DescribedSet("stroke_6pus", "6PUS", stroke),
)


def write_sets() -> list[Path]:
    """(Re)write every set of ``SETS``; the paths written."""
    return [ssv.write(s.path, s.parameter_set()) for s in SETS]


def differences(described: DescribedSet, path: Optional[Path] = None) -> list[str]:
    """What the set at ``path`` (the committed one: ``described.path``) holds that its description does not give:
    one line per parameter missing, extra or with another value, unit or source, naming the file and the parameter;
    and its layout or comment, if the values agree but the bytes do not."""
    path = path or described.path
    expected = described.parameter_set()
    origin = f"{path.name} (written from {described.description}.toml by python -m mast.core.variants)"
    try:
        committed = ssv.read(path)
    except (OSError, ssv.SSPFormatError) as err:
        return [f"{origin}: cannot be read: {err}"]
    out = []
    for name in sorted(committed.parameters.keys() - expected.parameters.keys()):
        out.append(f"{origin}: parameter '{name}' is not in the description")
    for name, want in expected.parameters.items():
        got = committed.parameters.get(name)
        if got is None:
            out.append(f"{origin}: parameter '{name}' is missing ({want.value!r} {want.unit})")
            continue
        shown = got.value if got.written is None else got.written
        if (type(shown), shown, got.unit) != (type(want.value), want.value, want.unit):
            out.append(
                f"{origin}: parameter '{name}' is {shown!r} {got.unit}, the description gives "
                f"{want.value!r} {want.unit}"
            )
        if got.source != want.source:
            out.append(
                f"{origin}: parameter '{name}': description {got.source!r}, its source in the file is {want.source!r}"
            )
    if not out and path.read_bytes() != expected.to_bytes():
        out.append(f"{origin}: same parameters, but not the file the generator writes (order, units or comment)")
    return out
