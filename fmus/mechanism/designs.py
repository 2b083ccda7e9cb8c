"""Mechanism designs as descriptions for the inverse-dynamics engine (``engine.py``).

A design is a description file (``descriptions/*.toml``, docs/mechanism.md): its legs, bodies, home
pose and parameters with units and sources; ``description.py`` reads it. The geometry parameter
``kinematics`` (bound to the mechanism *and* to the controller, whose inverse kinematics must be the
machine's) names the mechanism, the file that extends no other (``KINEMATICS``); a parameter set
gives its values (the file's where it has none).

``"3PRS"`` (descriptions/3PRS_T.toml): three guides around the vertical centre axis at angles
alpha_1..3, at horizontal distance H from it at the base plane z = 0 and inclined by ``beta``
towards the axis (beta = 0: vertical guides, the paper's machine). Slider i moves along its guide; a
revolute joint with the horizontal tangential axis t_i carries leg i (length L), whose upper end is
the spherical joint S_i on the platform (radius r). The paper's T layout is alpha = 0, 90, 180 deg,
beta = 0 (3PRS_T.toml); the textbook layout alpha = 0, 120, 240 deg (3PRS_120.toml); with beta != 0
the actuation direction changes (3PRS_inclined.toml). See docs/designs/. Bodies: three legs (m_leg,
centre of mass at mid-length, I_leg about the revolute axis direction), the platform (m_platform,
I_px, I_py, I_pz) and an optional payload fixed to the platform; sliders are massless here (their
mass is the actuators' M_load). The PRS leg template (``legs.py``) repeats the closed form of
``kinematics.py`` operation for operation, so for beta = 0 its inverse kinematics gives the very
same floats.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path
from typing import Mapping, Sequence

from ..common.codegen import largest_parameters
from ..common.parameters import Param, ParameterError, nonnegative
from .checks import Check
from .description import Described, DescriptionFile, kinematics, load
from .engine import Engine
from .kinematics import GEOMETRY_CHECKS, GEOMETRY_PARAMETERS, Geometry, KinematicsError
from .legs import level_height

__all__ = [
    "CHECKS",
    "INCLINED_CHECK",
    "KINEMATICS",
    "KINEMATIC_PARAMETERS",
    "KINEMATIC_PARAMETERS_NAMES",
    "MASS_PARAMETERS",
    "PAYLOAD_PARAMETERS",
    "TRACED_PARAMETERS",
    "describe",
    "description",
    "description_parameters",
    "engine",
    "kinematic_engine",
    "kinematic_names",
    "level_height",
    "parameters_for",
    "traced_engine",
]


#: the geometry parameter set: bound to the mechanism and to the controller (its kinematic model)
KINEMATIC_PARAMETERS: tuple[Param, ...] = (
    Param(
        "kinematics", "", "Kinematic model of the mechanism: 3PRS (three guides, revolute + spherical joints)", kind=str
    ),
    *GEOMETRY_PARAMETERS,
    Param(
        "beta",
        "rad",
        "Inclination of every guide from the vertical, towards the centre axis (0: vertical guides)",
        -math.radians(45.0),
        math.radians(45.0),
    ),
)

KINEMATIC_PARAMETERS_NAMES: tuple[str, ...] = tuple(p.name for p in KINEMATIC_PARAMETERS)

#: bodies of the 3PRS (and switch for the actuators-alone design)
MASS_PARAMETERS: tuple[Param, ...] = (
    nonnegative("m_leg", "kg", "Mass of each leg (COM at mid-length)"),
    nonnegative("I_leg", "kg.m2", "Inertia of each leg about its COM, about the revolute axis direction"),
    Param("m_platform", "kg", "Platform mass (COM at P)", minimum=0.0, exclusive=True, maximum=math.inf),
    nonnegative("I_px", "kg.m2", "Platform inertia about its own x axis, at P"),
    nonnegative("I_py", "kg.m2", "Platform inertia about its own y axis, at P"),
    nonnegative("I_pz", "kg.m2", "Platform inertia about its own z axis, at P"),
    Param("g", "m/s2", "Gravitational acceleration (along -z)", minimum=0.0, maximum=100.0),
    Param(
        "attached",
        "",
        "1: the mechanism loads the actuators (its inverse dynamics); 0: actuators alone "
        "(paper Fig. 10 'without the MAST'): no force, the pose outputs are the kinematics",
        minimum=0,
        maximum=1,
        kind=int,
    ),
)

PAYLOAD_PARAMETERS: tuple[Param, ...] = (
    nonnegative("m_payload", "kg", "Payload mass, fixed to the platform (0: no payload)"),
    Param("payload_x", "m", "Payload centre of mass, platform frame x"),
    Param("payload_y", "m", "Payload centre of mass, platform frame y"),
    Param("payload_z", "m", "Payload centre of mass, platform frame z (above P: positive)"),
    nonnegative("I_payload_xx", "kg.m2", "Payload inertia about its COM, platform axes, xx"),
    nonnegative("I_payload_yy", "kg.m2", "Payload inertia about its COM, platform axes, yy"),
    nonnegative("I_payload_zz", "kg.m2", "Payload inertia about its COM, platform axes, zz"),
    Param("I_payload_xy", "kg.m2", "Payload inertia about its COM, platform axes, xy (tensor entry)"),
    Param("I_payload_xz", "kg.m2", "Payload inertia about its COM, platform axes, xz (tensor entry)"),
    Param("I_payload_yz", "kg.m2", "Payload inertia about its COM, platform axes, yz (tensor entry)"),
)


#: the mechanisms by name (the values of the parameter ``kinematics``): their description files, or a callable
#: ``(params, masses=True) -> Description`` for a description written in Python (tests' scratch mechanisms)
KINEMATICS = kinematics()


def description(kind: str = "3PRS", owner: str = "") -> DescriptionFile:
    """The description file of the mechanism ``kind`` (ParameterError naming the parameter if there is none)."""
    if kind not in KINEMATICS:
        raise ParameterError(
            f"{owner or 'mechanism'}: parameter 'kinematics' = {kind!r}: expected one of {', '.join(KINEMATICS)}"
        )
    return load(KINEMATICS[kind])


def description_parameters(kind: str) -> tuple[tuple[Param, ...], tuple[Param, ...]]:
    """The parameter schema of the mechanism ``kind``'s description file: (its geometry's, ``kinematic``; the
    others: bodies, gravity, payload), each ``Param(name, unit, description = its source, range = the file's
    range)`` in the file's order."""
    file = description(kind)

    def param(p) -> Param:
        return Param(p.name, p.unit, p.source, p.range[0], p.range[1])

    return (
        tuple(param(p) for n, p in file.parameters.items() if n in file.kinematic),
        tuple(param(p) for n, p in file.parameters.items() if n not in file.kinematic),
    )


def parameter_units(params: Mapping[str, object]) -> dict[str, str]:
    """The unit of each description parameter of the mechanism ``params`` name (its ``kinematics``, the 3PRS's by
    default): the unit its block declares and its expressions read the value in (an angle in deg: in degrees);
    empty for a mechanism without a description file (one written in Python, an unknown name)."""
    kind = params.get("kinematics", "3PRS")
    if not isinstance(kind, str) or not isinstance(KINEMATICS.get(kind), Path):
        return {}
    return {name: p.unit for name, p in description(kind).parameters.items()}


def parameters_for(schema: Sequence[Param], kind: object) -> tuple[Param, ...]:
    """``schema`` (a block's parameters, written for the 3PRS: ``KINEMATIC_PARAMETERS``, ``MASS_PARAMETERS``,
    ``PAYLOAD_PARAMETERS`` among its own) for the mechanism ``kind`` (the ``kinematics`` parameter's value): the
    3PRS's description parameters replaced by ``kind``'s (``description_parameters``), its geometry's where the
    3PRS's geometry starts, its others where the 3PRS's bodies start (a schema with geometry only, a controller's,
    takes the geometry's alone). The 3PRS's (and a mechanism described in Python, a test's) is ``schema``."""
    if kind == "3PRS" or not isinstance(kind, str) or not isinstance(KINEMATICS.get(kind), Path):
        return tuple(schema)
    base = description("3PRS")
    geometry, others = description_parameters(kind)
    out: list[Param] = []
    placed = set()
    for p in schema:
        if p.name == "kinematics":
            out.append(
                Param(
                    "kinematics", "", f"Kinematic model of the mechanism: {kind} ({description(kind).title})", kind=str
                )
            )
        elif p.name in base.parameters:
            group = "geometry" if p.name in base.kinematic else "others"
            if group not in placed:
                placed.add(group)
                out += geometry if group == "geometry" else others
        else:
            out.append(p)
    return tuple(out)


def kinematic_names(params: Mapping[str, object]) -> tuple[str, ...]:
    """The geometry parameters of the mechanism ``params`` describe (``kinematics`` and its description's kinematic
    ones: the 3PRS's ``KINEMATIC_PARAMETERS_NAMES``, the 3-RPS's R_b, r, alpha_k), which the controller's model
    takes."""
    kind = params.get("kinematics", "3PRS")
    if isinstance(kind, str) and isinstance(KINEMATICS.get(kind), Path):
        return ("kinematics", *description(kind).kinematic)
    return KINEMATIC_PARAMETERS_NAMES


#: the names of the parameters the 3PRS traces as inputs (``traced_engine``), in argument order: the parameters
#: of its description file that its geometry, bodies and gravity use
TRACED_PARAMETERS = description("3PRS").traced


def describe(params: Mapping[str, object], owner: str = "", masses: bool = True, traced: bool = False) -> Described:
    """The description a parameter set defines (``masses=False``: kinematics only, massless bodies; ``traced``:
    its parameters traced as named inputs of the generated functions, ``DescriptionFile.describe``).

    Raises ParameterError naming the parameter: an unknown ``kinematics``, or a geometry that
    cannot be assembled at the level pose.
    """
    where = owner or "mechanism"
    written = KINEMATICS.get(params.get("kinematics", "3PRS"))
    if callable(written):  # a description written in Python: called with the parameter set
        return written(params, masses=masses)
    file = description(params.get("kinematics", "3PRS"), where)
    if file.name == "3PRS":
        _check_3prs(file, file.values(params, masses=False, owner=where), where)
    return file.describe(params, masses=masses, traced=traced, owner=where)


def _check_3prs(file: DescriptionFile, values: Mapping[str, float], owner: str) -> None:
    """The 3PRS's parameters (the native FMUs repeat these messages): with vertical guides, r < H < r + L and an
    assembly at the level pose (``Geometry.checked``); inclined guides: the level pose with the sliders at rho = 0
    must exist (working assembly, reach)."""
    beta = values["beta"]
    if beta == 0.0:
        Geometry.checked(values, owner)
        return
    Geometry.from_params(values)  # H, r, L > 0, finite angles
    desc = file.describe(values, masses=False)
    try:
        desc.evaluate(list(desc.guess((0.0, 0.0, 0.0))))  # plain floats: the checks run at once
    except KinematicsError as exc:
        shown = (repr(float(values[n])) for n in INCLINED_CHECK.shown)
        raise ParameterError(f"{owner}: {INCLINED_CHECK.message.format(*shown, exc)}") from None


#: the inclined guides' check (``_check_3prs``)
INCLINED_CHECK = Check(
    "assembles",
    "parameters 'H', 'r', 'L', 'beta' = {} m, {} m, {} m, {} rad: the mechanism cannot be assembled at the level "
    "pose with the sliders at the foot of their guides: {}",
    ("H", "r", "L", "beta"),
    when=("beta", "nonzero"),
)

#: per mechanism (the ``kinematics`` value), its checks of a parameter set in the order the Python model makes them
#: (the 3PRS's: ``Geometry.checked``'s for vertical guides, ``_check_3prs``'s for inclined ones)
CHECKS: dict[str, tuple[Check, ...]] = {
    "3PRS": (*(replace(c, when=("beta", "zero")) for c in GEOMETRY_CHECKS), INCLINED_CHECK),
}


_ENGINES: dict = {}


def engine(params: Mapping[str, object], owner: str = "", masses: bool = True) -> Engine:
    """The engine of a parameter set, shared between blocks with the same description and g."""
    try:
        desc = describe(params, owner, masses)
        key = (desc.key(), float(params.get("g", 9.81)) if masses else 0.0)
        found = _ENGINES.get(key)
        if found is None:
            if len(_ENGINES) > 64:
                _ENGINES.clear()
            found = Engine(desc, g=key[1])
            found.overflow_hint = largest_parameters(params)
            _ENGINES[key] = found
        return found
    except OverflowError as err:
        raise ParameterError(f"{owner}: {err}{largest_parameters(params)}") from None


def kinematic_engine(params: Mapping[str, object], owner: str = "") -> Engine:
    """Kinematics only (the controller's model): the same description with massless bodies."""
    return engine(params, owner, masses=False)


def traced_engine(params: Mapping[str, object], owner: str = "", masses: bool = True) -> Engine:
    """The engine of ``describe(params, traced=True)``: its generated functions take every parameter of
    ``TRACED_PARAMETERS`` as an input after their own arguments (``Engine.parameters``), the same floats as
    ``engine(params, owner, masses)`` computes with them as constants (tests/test_native.py); it calls them
    with ``params``. Always traced with the inclined guides' formulas and the payload body, which for beta = 0
    and no payload give the same floats as the specialised ones (up to the sign of a zero). ``masses=False``: a
    kinematic model (``kinematic_engine``): its bodies' data and g are 0 (``params`` need not have them)."""
    try:
        return Engine(describe(params, owner, masses, traced=True), g=float(params["g"]) if masses else 0.0)
    except OverflowError as err:
        raise ParameterError(f"{owner}: {err}{largest_parameters(params)}") from None
