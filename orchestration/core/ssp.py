"""Read an SSP: a system (.ssd) with its parameter sets resolved, and the archive it comes in.

What the project's master needs from an SSP, and nothing else:
- components, their FMU source and their connectors;
- connections (component to component, and system inputs to components);
- parameter bindings (.ssv files or inline values), applied in document order,
  later bindings overriding earlier ones. As SSP 1.0 says (ParameterBinding), a name in a
  parameter source that matches no parameter of the component is ignored, so one set can
  describe a machine to several components (the plant's actuator set also parametrises a
  model-based controller's copy of the actuator). Against typos, ``applicable_parameters``
  refuses a name that matches a parameter of *no* component the set is bound to;
- step sizes and the parameter set of a component's ratings, from the annotations
  ``mast.core.ssd`` reads (OSP's ``osp:FixedStepAlgorithm`` and ``osp:StepSizeHint``;
  ``mast.sizing``'s ``mast:Ratings``).

The document itself (its classes, its structural checks, writing it) is ``mast.core.ssd``; the
parameter sets ``mast.core.ssv``. Here every source must stay inside the SSP (or the folder of the
.ssd), and an archive is checked before a byte of it is extracted.
"""

from __future__ import annotations

import shutil
import tempfile
import zipfile
import zlib
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath
from typing import Iterable, Mapping, Optional, Union

from lxml import etree

from fmus.common.parameters import Value
from fmus.mechanism.designs import parameter_units

from . import ssd
from .ssd import Connection
from .ssv import ParameterValue, SSPFormatError, parse_ssv
from .units import Unit, UnitError, convert, parse_unit


@dataclass
class ComponentSpec:
    name: str
    source: str
    step_size: Optional[float]
    inputs: list[str]
    outputs: list[str]
    parameters: dict[str, Value] = field(default_factory=dict)  # bindings merged in order
    bindings: list[tuple[str, dict[str, Value]]] = field(default_factory=list)  # (source, values) in order
    #: per binding source, the unit each Real value was given in (values are in its coherent SI unit)
    units: dict[str, dict[str, tuple[str, Unit]]] = field(default_factory=dict)
    #: the parameter set of the component's ratings (relative source), if the system names one (docs/sizing.md)
    ratings: Optional[str] = None


@dataclass
class SystemSpec:
    name: str
    root: Path  # folder the relative sources resolve against
    components: dict[str, ComponentSpec]
    connections: list[Connection]
    system_inputs: list[str]
    base_step: Optional[float]
    start_time: float
    stop_time: Optional[float]
    archive: Optional[Path] = None  # the .ssp the system was extracted from (None: a folder)

    def fmu_path(self, component: str) -> Path:
        return self.root / self.components[component].source

    def fmu_label(self, component: str) -> str:
        """How messages name a component's FMU: its path, or the archive and the entry."""
        source = self.components[component].source
        return f"{self.archive} (entry {source})" if self.archive else str(self.fmu_path(component))


#: what an untrusted archive (SSP or FMU) may expand to; beyond, extraction is refused before a byte is written
MAX_ARCHIVE_BYTES = 1 << 30  # all entries together, uncompressed
MAX_ENTRY_BYTES = 512 << 20  # one entry, uncompressed
MAX_ENTRIES = 20_000
MAX_RATIO = 200  # uncompressed / compressed, for an entry of more than RATIO_FLOOR bytes
RATIO_FLOOR = 1 << 20  # small entries (XML, JSON) may compress better without filling a disk


def check_archive(archive: Union[str, Path], label: Optional[str] = None) -> None:
    """Refuse (SSPFormatError naming the archive, ``label`` or its path, and the entry) a zip whose
    entries would land outside the folder it is extracted to (absolute, ``..``, a drive), or that
    would expand beyond MAX_ARCHIVE_BYTES in all, MAX_ENTRY_BYTES per entry, MAX_ENTRIES entries,
    or has an entry of more than RATIO_FLOOR bytes compressed more than MAX_RATIO times (a zip
    bomb). Reads the archive's directory only: also for readers that take one file out of it
    (fmpy's read_model_description)."""
    with _open_zip(archive, label) as handle:
        _check_members(handle.infolist(), label or str(archive))


def safe_extract(archive: Union[str, Path], target: Union[str, Path], label: Optional[str] = None) -> Path:
    """Extract a zip (SSP or FMU) into ``target``, refusing what ``check_archive`` refuses.

    The sizes the archive declares are checked first; the bytes written are counted as well
    (zipfile stops an entry at its declared size and checks its CRC).
    """
    target, name = Path(target), label or str(archive)
    with _open_zip(archive, label) as handle:
        members = handle.infolist()
        _check_members(members, name)
        written = 0
        for info in members:
            path = target.joinpath(*PurePosixPath(info.filename.replace("\\", "/")).parts)
            if info.is_dir():
                path.mkdir(parents=True, exist_ok=True)
                continue
            path.parent.mkdir(parents=True, exist_ok=True)
            try:
                with handle.open(info) as src, open(path, "wb") as dst:
                    while chunk := src.read(1 << 20):
                        written += len(chunk)
                        if written > MAX_ARCHIVE_BYTES:
                            raise SSPFormatError(
                                f"{name}: entry '{info.filename}' expands beyond the "
                                f"{MAX_ARCHIVE_BYTES >> 20} MiB an archive may hold"
                            )
                        dst.write(chunk)
            except (zipfile.BadZipFile, zlib.error, EOFError, NotImplementedError) as err:
                raise SSPFormatError(f"{name}: entry '{info.filename}' cannot be extracted ({err})") from None
    return target


def _open_zip(archive: Union[str, Path], label: Optional[str]) -> zipfile.ZipFile:
    try:
        return zipfile.ZipFile(archive)
    except (zipfile.BadZipFile, OSError) as err:
        raise SSPFormatError(f"{label or archive}: not a readable zip archive ({err})") from None


def _check_members(members: list, name: str) -> None:
    if len(members) > MAX_ENTRIES:
        raise SSPFormatError(f"{name}: {len(members)} entries, more than the {MAX_ENTRIES} an archive may hold")
    total = 0
    for info in members:
        pure = PurePosixPath(info.filename.replace("\\", "/"))
        if pure.is_absolute() or ".." in pure.parts or (pure.parts and ":" in pure.parts[0]):
            raise SSPFormatError(f"{name}: entry '{info.filename}' would be extracted outside the target folder")
        _check_size(name, info.filename, info.file_size, info.compress_size)
        total += info.file_size
        if total > MAX_ARCHIVE_BYTES:
            raise SSPFormatError(
                f"{name}: expands to more than {MAX_ARCHIVE_BYTES >> 20} MiB "
                f"(reached at entry '{info.filename}'): refused as a possible zip bomb"
            )


def _check_size(name: str, entry: str, size: int, compressed: int) -> None:
    if size > MAX_ENTRY_BYTES:
        raise SSPFormatError(
            f"{name}: entry '{entry}' expands to {size >> 20} MiB, more than the "
            f"{MAX_ENTRY_BYTES >> 20} MiB an entry may: refused as a possible zip bomb"
        )
    if size > RATIO_FLOOR and size > MAX_RATIO * max(compressed, 1):
        raise SSPFormatError(
            f"{name}: entry '{entry}' is compressed {size / max(compressed, 1):.0f} times "
            f"({compressed} bytes expand to {size >> 20} MiB), more than {MAX_RATIO}: "
            "refused as a possible zip bomb"
        )


def path_inside(root: Path, reference: str) -> Optional[Path]:
    """``root / reference`` if the reference stays inside ``root``, else None.

    A reference is a relative path (SSP: a relative URI): an absolute path, a drive, a URI
    scheme or a ``..`` that climbs above ``root`` is refused. Checked on the text, so a folder
    of the user's that links elsewhere still works; an extracted archive holds no links
    (zipfile writes none).
    """
    pure = PurePosixPath(reference.replace("\\", "/"))
    depth = 0
    for part in pure.parts:
        depth += -1 if part == ".." else 0 if part == "." else 1
        if depth < 0:
            return None
    if not reference or pure.is_absolute() or (pure.parts and ":" in pure.parts[0]):
        return None
    return root.joinpath(*pure.parts)


def _inside(root: Path, reference: str, origin: str, what: str, within: str) -> Path:
    path = path_inside(root, reference)
    if path is None:
        raise SSPFormatError(f"{origin}: {what} '{reference}' is not a relative path inside {within}: refused")
    return path


def validate_ssd_schema(path: Union[str, Path]) -> list[str]:
    """Problems found by the SSP 1.0 schema (empty list: valid)."""
    from fmpy.ssp.ssd import validate_tree  # the SSP 1.0 XSDs ship with fmpy

    try:
        validate_tree(etree.parse(str(path)).getroot(), "SystemStructureDescription.xsd")
    except Exception as err:  # fmpy raises a plain Exception listing the schema errors
        return [str(err)]
    return []


def read_ssd(path: Union[str, Path], root: Optional[Path] = None, archive: Optional[Path] = None) -> SystemSpec:
    """Parse a SystemStructure.ssd (``ssd.read``) and its parameter sets; relative sources resolve against
    ``root`` (default: its folder).

    ``archive``: the .ssp the file was extracted from; messages then name it and the entry
    (``MAST.ssp (entry SystemStructure.ssd)``), not the temporary folder. Every source (FMU,
    parameter set, ratings) must stay inside ``root``.
    """
    ssd_path = Path(path)
    root = root or ssd_path.parent
    path = _Origin(ssd_path, archive, root)
    within = f"the archive {archive}" if archive else f"the folder {root}"
    document = ssd.read(ssd_path, str(path))
    components: dict[str, ComponentSpec] = {}
    for comp in document.system.elements:
        name = comp.name
        _inside(root, comp.source, str(path), f"component '{name}' source", within)
        if comp.ratings:  # read by mast sizing, which names it if absent
            _inside(root, comp.ratings, str(path), f"component '{name}' ratings", within)
        spec = ComponentSpec(
            name=name,
            source=comp.source,
            step_size=comp.step_size_hint,
            ratings=comp.ratings,
            inputs=comp.inputs,
            outputs=comp.outputs,
        )
        for binding in comp.bindings:
            parsed = _binding_values(binding, root, path, name, within)
            source = binding.source or f"inline values of '{name}'"
            values = {k: p.value for k, p in parsed.items()}
            spec.bindings.append((source, values))
            spec.units.setdefault(source, {}).update((k, (p.unit, p.si)) for k, p in parsed.items() if p.si is not None)
            spec.parameters.update(values)
        components[name] = spec
    experiment = document.default_experiment or ssd.DefaultExperiment()
    system = document.system
    return SystemSpec(
        system.name or ssd_path.stem,
        root,
        components,
        list(system.connections),
        [c.name for c in system.connectors if c.kind in ssd.INPUT_KINDS],
        experiment.base_step,
        experiment.start_time,
        experiment.stop_time,
        archive,
    )


class _Origin:
    """How messages name an SSD: its path, or the archive and the entry it came from."""

    def __init__(self, path: Path, archive: Optional[Path], root: Path) -> None:
        self.path, self.archive, self.root = path, archive, root

    def entry(self, file: Path) -> str:
        if self.archive is None:
            return str(file)
        return f"{self.archive} (entry {file.relative_to(self.root).as_posix()})"

    def __str__(self) -> str:
        return self.entry(self.path)


def _binding_values(
    binding: ssd.ParameterBinding, root: Path, path: _Origin, component: str, within: str
) -> dict[str, ParameterValue]:
    if binding.values is not None:
        return binding.values.parameters
    file = _inside(root, binding.source, str(path), f"component '{component}' binds parameter set", within)
    if not file.is_file():
        raise SSPFormatError(f"{path}: component '{component}' binds '{binding.source}', which does not exist")
    return parse_ssv(file.read_bytes(), origin=path.entry(file))


def applicable_parameters(
    system: SystemSpec,
    parameter_names: Mapping[str, Iterable[str]],
    parameter_units: Optional[Mapping[str, Mapping[str, str]]] = None,
) -> dict[str, dict[str, Value]]:
    """Each component's bound values restricted to its own parameters (``parameter_names``).

    SSP 1.0 ignores a bound name the component does not have; here that is allowed only
    when another component bound to the same source has it: a name no component of its
    set uses is a typo, and raises SSPFormatError naming the set and the name.

    A value the set gives with a unit is in that unit's coherent SI unit (``ssv.parse_ssv``);
    against ``parameter_units`` (per component, the unit each parameter declares) it is
    expressed in the declared unit, and a unit of another dimension is refused, naming the
    set, the parameter, both units and the component. A declared unit that is unknown
    (or not given) takes values in coherent SI units only.
    """
    names = {comp: set(parameter_names[comp]) for comp in system.components}
    users: dict[str, set] = {}
    for comp, spec in system.components.items():
        for source, values in spec.bindings:
            users.setdefault(source, set()).update(k for k in values if k in names[comp])
    for _comp, spec in system.components.items():
        for source, values in spec.bindings:
            unused = sorted(k for k in values if k not in users[source])
            if unused:
                bound = sorted(c for c, s in system.components.items() if any(src == source for src, _ in s.bindings))
                raise SSPFormatError(
                    f"parameter set {source}: {', '.join(map(repr, unused))} is a parameter of no "
                    f"component it is bound to ({', '.join(bound)})"
                )
    out = {}
    for comp, spec in system.components.items():
        values = {k: v for k, v in spec.parameters.items() if k in names[comp]}
        declared = (parameter_units or {}).get(comp, {})
        setter = {k: source for source, bound in spec.bindings for k in bound}  # the binding whose value counts
        for k in values:
            given = spec.units.get(setter.get(k, ""), {}).get(k)
            if given is not None:
                values[k] = _in_declared_unit(values[k], given, declared.get(k), setter[k], k, comp)
        out[comp] = values
    return out


def declared_values(
    values: Mapping[str, Value], given: Mapping[str, tuple[str, Unit, str]], declared: Mapping[str, str], comp: str
) -> dict[str, Value]:
    """``values`` as the reader gives them (a Real given with a unit: in that unit's coherent SI unit) in the units
    ``declared`` (by name; a name not declared keeps its value); ``given``: per name the unit text, the parsed unit and
    the set that gave it. A unit of another dimension is refused (SSPFormatError naming the set and ``comp``)."""
    return {
        k: _in_declared_unit(v, given[k][:2], declared[k], given[k][2], k, comp) if k in given and k in declared else v
        for k, v in values.items()
    }


def mechanism_parameters(spec: ComponentSpec) -> dict[str, Value]:
    """A mechanism component's bound values in the units its description declares (``parameter_units``: an angle
    the description gives in deg in degrees, as the mechanism's block and its expressions read it), the form
    ``fmus.mechanism.designs.describe`` takes; the reader's ``spec.parameters`` are in coherent SI units."""
    setter = {k: source for source, bound in spec.bindings for k in bound}
    given = {
        k: (*spec.units[setter[k]][k], setter[k]) for k in spec.parameters if k in spec.units.get(setter.get(k, ""), {})
    }
    return declared_values(spec.parameters, given, parameter_units(spec.parameters), spec.name)


def _in_declared_unit(
    value: float, given: tuple[str, Unit], declared: Optional[str], source: str, name: str, comp: str
) -> float:
    """``value`` (coherent SI of the ``given`` unit's dimension) in the unit the component declares."""
    text, unit = given
    target = None
    if declared:
        try:
            target = parse_unit(declared)
        except UnitError:
            target = None
    if target is None:
        if unit.factor != 1.0 or unit.offset:
            raise SSPFormatError(
                f"parameter set {source}: '{name}' is given in '{text}', but component '{comp}' "
                f"declares no unit this tool knows for it ({declared or 'none'}): give it in "
                "coherent SI units"
            )
        return value
    try:
        return convert(value, Unit(dims=unit.dims), target)
    except UnitError:
        raise SSPFormatError(
            f"parameter set {source}: '{name}' is given in '{text}' (dimension {unit.dimension()}), "
            f"but component '{comp}' declares it in '{declared}' (dimension "
            f"{target.dimension()})"
        ) from None


class SSPArchive:
    """An extracted .ssp (or a source folder with a .ssd); use as a context manager."""

    def __init__(self, path: Union[str, Path]) -> None:
        self.path = Path(path)
        self._tmp: Optional[str] = None
        if not self.path.exists():
            raise SSPFormatError(f"{self.path}: no such SSP file")
        try:
            if self.path.suffix == ".ssd":
                self.ssd = self.path
                self.system = read_ssd(self.ssd)
            else:
                self._tmp = tempfile.mkdtemp(prefix="mast_ssp_")
                safe_extract(self.path, self._tmp)
                self.ssd = Path(self._tmp) / "SystemStructure.ssd"
                if not self.ssd.is_file():
                    raise SSPFormatError(f"{self.path}: no SystemStructure.ssd at the root of the archive")
                self.system = read_ssd(self.ssd, archive=self.path)
            for name in self.system.components:
                if not self.system.fmu_path(name).is_file():
                    raise SSPFormatError(
                        f"{self.path}: component '{name}' source {self.system.components[name].source} is missing"
                    )
        except BaseException:  # nothing extracted stays behind a refused archive
            self.close()
            raise

    def close(self) -> None:
        if self._tmp:
            shutil.rmtree(self._tmp, ignore_errors=True)
            self._tmp = None

    def __enter__(self) -> "SSPArchive":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
