"""A specimen bolted to the table: its mass, centre of mass and inertia, as the mechanism's payload parameters.

``Specimen(mass, com, inertia)``: mass [kg]; com = (x, y, z) [m], the centre of mass's offset from the platform
centre P in platform axes (z above P: positive); inertia = (Ixx, Iyy, Izz, Ixy, Ixz, Iyz) [kg m^2], the tensor
about the centre of mass in platform axes (the entries of the matrix, as the mechanism's ``I_payload_*``). A
specimen is checked when made (``SpecimenError`` naming the input and the limit): a finite mass >= 0, a finite
offset, a physical inertia (positive semi-definite, each principal moment at most the sum of the other two).

``parameters()`` are the overrides of the mechanism component (``fmus.mechanism.designs.PAYLOAD_PARAMETERS``, which
every mechanism description has); ``with_specimen`` merges them into a run's overrides, ``parse`` reads the command
line's ``--specimen MASS[,X,Y,Z[,IXX,IYY,IZZ[,IXY,IXZ,IYZ]]]`` or ``--specimen FILE.toml`` (keys ``mass``, ``com``,
``inertia``). Whether the drives can hold it is the analyses' question (``mast.analyses.specimen``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping, Optional

import numpy as np

from fmus.common.parameters import Value
from fmus.mechanism.designs import PAYLOAD_PARAMETERS

#: the mechanism's payload parameters, in the order of (mass, x, y, z, Ixx, Iyy, Izz, Ixy, Ixz, Iyz)
PAYLOAD_NAMES: tuple[str, ...] = tuple(p.name for p in PAYLOAD_PARAMETERS)
#: the component the specimen's parameters override
MECHANISM = "mechanism"
#: the command line's forms, for messages and --help
FORMS = "MASS[,X,Y,Z[,IXX,IYY,IZZ[,IXY,IXZ,IYZ]]] (kg, m, kg m^2) or FILE.toml (keys mass, com, inertia)"
INERTIA_NAMES = ("Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz")
#: relative tolerance of the inertia's checks (rounding of a tensor given to a few digits)
TOLERANCE = 1e-9


class SpecimenError(ValueError):
    """A specimen that is not physical, cannot be read or cannot be held: the message names the input and the limit."""


@dataclass(frozen=True)
class Specimen:
    """A rigid specimen on the platform: mass [kg], centre of mass (x, y, z) [m] from P in platform axes, inertia
    (Ixx, Iyy, Izz, Ixy, Ixz, Iyz) [kg m^2] about its centre of mass in platform axes."""

    mass: float
    com: tuple[float, float, float] = (0.0, 0.0, 0.0)
    inertia: tuple[float, float, float, float, float, float] = (0.0,) * 6
    source: str = field(default="", compare=False)  # what the user gave (text or file), for messages

    def __post_init__(self) -> None:
        object.__setattr__(self, "mass", float(self.mass))
        object.__setattr__(self, "com", tuple(float(v) for v in self.com))
        object.__setattr__(self, "inertia", tuple(float(v) for v in self.inertia))
        check(self)

    @property
    def label(self) -> str:
        """How messages name it: what the user gave, or its values."""
        return self.source or f"{self.mass:g} kg at ({', '.join(f'{v:g}' for v in self.com)}) m"

    def parameters(self) -> dict[str, float]:
        """The mechanism's payload parameter overrides (m_payload, payload_x/y/z, I_payload_xx..yz)."""
        return dict(zip(PAYLOAD_NAMES, (float(self.mass), *self.com, *self.inertia)))

    @classmethod
    def from_parameters(cls, params: Mapping[str, Value]) -> "Specimen":
        """The specimen the mechanism's payload parameters ``params`` describe (one not given: 0)."""
        v = [float(params.get(name, 0.0)) for name in PAYLOAD_NAMES]
        return cls(v[0], tuple(v[1:4]), tuple(v[4:]))

    def combined(self, other: "Specimen") -> "Specimen":
        """This specimen and ``other`` bolted together: the masses added, the common centre of mass, the inertia
        about it (each body's moved there by the parallel-axis theorem)."""
        mass = self.mass + other.mass
        if mass == 0.0:
            return Specimen(0.0)
        c = (self.mass * np.array(self.com) + other.mass * np.array(other.com)) / mass
        total = np.zeros((3, 3))
        for body in (self, other):
            d = np.array(body.com) - c
            total += body.tensor() + body.mass * (d @ d * np.eye(3) - np.outer(d, d))
        return Specimen(mass, tuple(c), (*np.diag(total), total[0, 1], total[0, 2], total[1, 2]))

    def tensor(self) -> np.ndarray:
        """The 3x3 inertia matrix about the centre of mass [kg m^2]."""
        xx, yy, zz, xy, xz, yz = self.inertia
        return np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])


def check(s: Specimen) -> None:
    """Refuse (SpecimenError) a specimen that is not physical: its mass, offset or inertia, named with the limit."""
    where = f"--specimen {s.label}"
    if len(s.com) != 3 or len(s.inertia) != 6:
        raise SpecimenError(f"{where}: expected com (x, y, z) and inertia (Ixx, Iyy, Izz, Ixy, Ixz, Iyz)")
    if not (math.isfinite(s.mass) and s.mass >= 0.0):
        raise SpecimenError(f"{where}: mass {s.mass!r} kg: expected a finite mass >= 0 kg")
    if not all(math.isfinite(v) for v in s.com):
        raise SpecimenError(f"{where}: centre of mass offset {s.com!r} m: expected finite numbers (x, y, z) in m")
    bad = [f"{n} = {v!r}" for n, v in zip(INERTIA_NAMES, s.inertia) if not math.isfinite(v)]
    if bad:
        raise SpecimenError(f"{where}: inertia {', '.join(bad)}: expected finite numbers in kg m^2")
    if s.mass == 0.0 and any(s.inertia):
        raise SpecimenError(f"{where}: inertia {s.inertia!r} kg m^2 with mass 0 kg: a massless body has no inertia")
    diagonal = s.inertia[:3]
    scale = TOLERANCE * max(1.0, *map(abs, s.inertia))
    for k, name in enumerate(INERTIA_NAMES[:3]):
        others = [INERTIA_NAMES[j] for j in range(3) if j != k]
        if diagonal[k] < -scale:
            raise SpecimenError(f"{where}: inertia {name} = {diagonal[k]:g} kg m^2: expected a moment >= 0")
        rest = sum(diagonal) - diagonal[k]
        if diagonal[k] > rest + scale:
            raise SpecimenError(
                f"{where}: inertia {name} = {diagonal[k]:g} kg m^2 > {others[0]} + {others[1]} = {rest:g} kg m^2: "
                "not a rigid body (each moment is at most the sum of the other two: the triangle inequality)"
            )
    principal = np.linalg.eigvalsh(s.tensor())
    if principal[0] < -scale:
        raise SpecimenError(
            f"{where}: inertia {s.inertia!r} kg m^2 is not positive semi-definite (principal moments "
            f"{', '.join(f'{v:.4g}' for v in principal)} kg m^2; the products of inertia too large for the moments)"
        )
    if principal[2] > principal[0] + principal[1] + scale:
        raise SpecimenError(
            f"{where}: inertia {s.inertia!r} kg m^2: principal moment {principal[2]:.4g} kg m^2 > the sum of the "
            f"other two, {principal[0] + principal[1]:.4g} kg m^2: not a rigid body (the triangle inequality)"
        )


def _numbers(text: str, where: str) -> list[float]:
    try:
        return [float(v) for v in text.split(",")]
    except ValueError:
        raise SpecimenError(f"{where}: not numbers; expected {FORMS}") from None


def parse(text: str) -> Specimen:
    """The command line's ``--specimen``: ``MASS[,X,Y,Z[,IXX,IYY,IZZ[,IXY,IXZ,IYZ]]]`` (kg, m, kg m^2; what is left
    out is 0) or a TOML file ``FILE.toml`` with ``mass`` [kg], ``com = [x, y, z]`` [m], ``inertia = [Ixx, Iyy,
    Izz, Ixy, Ixz, Iyz]`` [kg m^2] (com and inertia optional). SpecimenError naming the input otherwise."""
    where = f"--specimen {text or repr(text)}"
    if text.strip().lower().endswith(".toml"):
        return read(Path(text.strip()))
    values = _numbers(text, where)
    if len(values) not in (1, 4, 7, 10):
        raise SpecimenError(f"{where}: {len(values)} numbers; expected 1, 4, 7 or 10: {FORMS}")
    values += [0.0] * (10 - len(values))
    return Specimen(values[0], tuple(values[1:4]), tuple(values[4:]), source=text)


def read(path: Path) -> Specimen:
    """A specimen from a TOML file (``parse``'s file form); SpecimenError naming the file and the key."""
    try:
        import tomllib
    except ModuleNotFoundError:  # Python 3.10
        import tomli as tomllib

    where = f"--specimen {path}"
    if not path.is_file():
        raise SpecimenError(f"{where}: no such file (expected a TOML file with keys mass, com, inertia)")
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as err:
        raise SpecimenError(f"{where}: cannot read it as TOML: {err}") from None
    unknown = sorted(set(data) - {"mass", "com", "inertia"})
    if unknown:
        raise SpecimenError(f"{where}: unknown key(s) {', '.join(unknown)}; expected mass, com, inertia")
    if "mass" not in data:
        raise SpecimenError(f"{where}: no key 'mass' (kg)")
    shapes = {"mass": None, "com": 3, "inertia": 6}
    got = {}
    for key, size in shapes.items():
        value = data.get(key, 0.0 if size is None else [0.0] * size)
        items = [value] if size is None else value
        if (size is not None and (not isinstance(value, list) or len(value) != size)) or not all(
            isinstance(v, (int, float)) and not isinstance(v, bool) for v in items
        ):
            what = "a number (kg)" if size is None else f"a list of {size} numbers"
            raise SpecimenError(f"{where}: {key} = {value!r}: expected {what}")
        got[key] = value
    return Specimen(float(got["mass"]), tuple(got["com"]), tuple(got["inertia"]), source=str(path))


def with_specimen(
    parameters: Optional[Mapping[str, Mapping[str, Value]]], specimen: Optional[Specimen], replace: bool = False
) -> Optional[dict[str, dict[str, Value]]]:
    """``parameters`` (a run's overrides, {component: {parameter: value}}) with the specimen's on the mechanism.
    A payload parameter the overrides set too is refused (SpecimenError naming both), unless ``replace`` (overrides
    recorded by a run, not typed: the specimen's win)."""
    if specimen is None:
        return None if parameters is None else {k: dict(v) for k, v in parameters.items()}
    out = {k: dict(v) for k, v in (parameters or {}).items()}
    mechanism = out.setdefault(MECHANISM, {})
    clash = sorted(k for k in PAYLOAD_NAMES if k in mechanism)
    if clash and not replace:
        raise SpecimenError(
            f"--specimen {specimen.label} and --set {', '.join(f'{MECHANISM}.{k}' for k in clash)} both set the "
            "payload: give one"
        )
    mechanism.update(specimen.parameters())
    return out


__all__ = ["FORMS", "PAYLOAD_NAMES", "Specimen", "SpecimenError", "check", "parse", "read", "with_specimen"]
