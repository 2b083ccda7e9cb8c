"""Read an SSP: the system structure (.ssd), its parameter bindings and step sizes.

What the project's master needs from an SSP, and nothing else:
- components, their FMU source and their connectors;
- connections (component to component, and system inputs to components);
- parameter bindings (.ssv files or inline values), applied in document order,
  later bindings overriding earlier ones. As SSP 1.0 says (ParameterBinding), a name in a
  parameter source that matches no parameter of the component is ignored, so one set can
  describe a machine to several components (the plant's actuator set also parametrises a
  model-based controller's copy of the actuator). Against typos, ``applicable_parameters``
  refuses a name that matches a parameter of *no* component the set is bound to;
- step sizes from the Open Simulation Platform annotations: the base step of
  ``osp:FixedStepAlgorithm`` and each component's ``osp:StepSizeHint``;
- the parameter set of a component's ratings (``mast sizing``, docs/sizing.md): an annotation of
  type ``mast.sizing`` holding ``<mast:Ratings source="resources/....ssv"/>``. The ratings are not
  parameters of the FMU (no host applies them; an annotation of a type a tool does not know is
  ignored, SSP 1.0), so they live in their own set, named by the system per component.
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

from .units import Unit, UnitError, convert, parse_unit
from .ssv import ParameterValue, SSPFormatError, parse_ssv, unit_definitions

NS = {
    "ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription",
    "ssc": "http://ssp-standard.org/SSP1/SystemStructureCommon",
    "ssv": "http://ssp-standard.org/SSP1/SystemStructureParameterValues",
    "osp": "http://opensimulationplatform.com/SSP/OSPAnnotations",
    "mast": "urn:mast:sizing",
}
OSP_ANNOTATION = "com.opensimulationplatform"
RATINGS_ANNOTATION = "mast.sizing"
SSV_TYPE = "application/x-ssp-parameter-set"
FMU_TYPE = "application/x-fmu-sharedlibrary"


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


@dataclass(frozen=True)
class Connection:
    start_element: str  # "" for a system connector
    start_connector: str
    end_element: str
    end_connector: str


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
MAX_ARCHIVE_BYTES = 1 << 30        # all entries together, uncompressed
MAX_ENTRY_BYTES = 512 << 20        # one entry, uncompressed
MAX_ENTRIES = 20_000
MAX_RATIO = 200                    # uncompressed / compressed, for an entry of more than RATIO_FLOOR bytes
RATIO_FLOOR = 1 << 20              # small entries (XML, JSON) may compress better without filling a disk


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
                            raise SSPFormatError(f"{name}: entry '{info.filename}' expands beyond the "
                                                 f"{MAX_ARCHIVE_BYTES >> 20} MiB an archive may hold")
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
            raise SSPFormatError(f"{name}: expands to more than {MAX_ARCHIVE_BYTES >> 20} MiB "
                                 f"(reached at entry '{info.filename}'): refused as a possible zip bomb")


def _check_size(name: str, entry: str, size: int, compressed: int) -> None:
    if size > MAX_ENTRY_BYTES:
        raise SSPFormatError(f"{name}: entry '{entry}' expands to {size >> 20} MiB, more than the "
                             f"{MAX_ENTRY_BYTES >> 20} MiB an entry may: refused as a possible zip bomb")
    if size > RATIO_FLOOR and size > MAX_RATIO * max(compressed, 1):
        raise SSPFormatError(f"{name}: entry '{entry}' is compressed {size / max(compressed, 1):.0f} times "
                             f"({compressed} bytes expand to {size >> 20} MiB), more than {MAX_RATIO}: "
                             "refused as a possible zip bomb")


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
    """Parse a SystemStructure.ssd; relative sources resolve against ``root`` (default: its folder).

    ``archive``: the .ssp the file was extracted from; messages then name it and the entry
    (``MAST.ssp (entry SystemStructure.ssd)``), not the temporary folder. Every source (FMU,
    parameter set) must stay inside ``root``.
    """
    ssd_path = Path(path)
    root = root or ssd_path.parent
    path = _Origin(ssd_path, archive, root)
    within = f"the archive {archive}" if archive else f"the folder {root}"
    try:
        doc = etree.parse(str(ssd_path)).getroot()
    except (etree.XMLSyntaxError, OSError) as err:
        raise SSPFormatError(f"{path}: cannot read the system structure: {_strip(err, ssd_path)}") from None
    if doc.tag != f"{{{NS['ssd']}}}SystemStructureDescription":
        raise SSPFormatError(f"{path}: root element is {doc.tag}, expected ssd:SystemStructureDescription")
    system = doc.find("ssd:System", NS)
    if system is None:
        raise SSPFormatError(f"{path}: no ssd:System element")

    def need(element, attribute: str, what: str) -> str:
        value = element.get(attribute)
        if not value:
            raise SSPFormatError(f"{path}: {what} has no '{attribute}' attribute (line {element.sourceline})")
        return value

    system_inputs = [need(c, "name", "a system connector") for c in system.findall("ssd:Connectors/ssd:Connector", NS)
                     if c.get("kind") in ("input", "parameter")]
    ssd_units = ssd_unit_definitions(doc, str(path))
    components: dict[str, ComponentSpec] = {}
    for comp in system.findall("ssd:Elements/ssd:Component", NS):
        name = need(comp, "name", "a component")
        if name in components:
            raise SSPFormatError(f"{path}: component name '{name}' is used twice")
        connectors = comp.findall("ssd:Connectors/ssd:Connector", NS)
        source = need(comp, "source", f"component '{name}'")
        if comp.get("type", FMU_TYPE) != FMU_TYPE:
            raise SSPFormatError(f"{path}: component '{name}' has type '{comp.get('type')}': only FMUs "
                                 f"({FMU_TYPE}) are supported")
        _inside(root, source, str(path), f"component '{name}' source", within)
        spec = ComponentSpec(
            name=name,
            source=source,
            step_size=_step_size_hint(comp, path, name),
            ratings=_ratings_source(comp, root, path, name, within),
            inputs=[c.get("name") for c in connectors if c.get("kind") in ("input", "parameter")],
            outputs=[c.get("name") for c in connectors if c.get("kind") in ("output", "calculatedParameter")],
        )
        for binding in comp.findall("ssd:ParameterBindings/ssd:ParameterBinding", NS):
            parsed = _binding_values(binding, root, path, name, within, ssd_units)
            source = binding.get("source") or f"inline values of '{name}'"
            values = {k: p.value for k, p in parsed.items()}
            spec.bindings.append((source, values))
            spec.units.setdefault(source, {}).update((k, (p.unit, p.si)) for k, p in parsed.items() if p.si is not None)
            spec.parameters.update(values)
        components[name] = spec
    if not components:
        raise SSPFormatError(f"{path}: the system has no components")

    connections = []
    for con in system.findall("ssd:Connections/ssd:Connection", NS):
        c = Connection(con.get("startElement", ""), need(con, "startConnector", "a connection"),
                       con.get("endElement", ""), need(con, "endConnector", "a connection"))
        _check_end(c.start_element, c.start_connector, "output", components, system_inputs, path)
        _check_end(c.end_element, c.end_connector, "input", components, system_inputs, path)
        connections.append(c)

    base_step, start, stop = None, 0.0, None
    experiment = doc.find("ssd:DefaultExperiment", NS)
    if experiment is not None:
        start = _number(experiment.get("startTime", "0"), path, "DefaultExperiment startTime")
        stop = _number(experiment.get("stopTime"), path, "DefaultExperiment stopTime") if experiment.get("stopTime") else None
        algo = experiment.find(f"ssd:Annotations/ssc:Annotation[@type='{OSP_ANNOTATION}']/osp:Algorithm/osp:FixedStepAlgorithm", NS)
        if algo is not None:
            base_step = _positive(need(algo, "baseStepSize", "osp:FixedStepAlgorithm"), path, "baseStepSize")
    return SystemSpec(system.get("name", ssd_path.stem), root, components, connections, system_inputs, base_step, start,
                      stop, archive)


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


def _strip(err: Exception, path: Path) -> str:
    """An XML parser's message without the (temporary) file name it repeats."""
    return str(err).replace(f"{path}:", "").replace(str(path), path.name).strip()


def _number(text: str, path, what: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if value != value or value in (float("inf"), float("-inf")):
        raise SSPFormatError(f"{path}: {what}={text!r}: expected a finite number of seconds")
    return value


def _positive(text: str, path, what: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not value > 0:
        raise SSPFormatError(f"{path}: {what}={text!r}: expected a positive number of seconds")
    return value


def _step_size_hint(comp, path, name: str) -> Optional[float]:
    hint = comp.find(f"ssd:Annotations/ssc:Annotation[@type='{OSP_ANNOTATION}']/osp:StepSizeHint", NS)
    return None if hint is None else _positive(hint.get("value", ""), path, f"StepSizeHint of '{name}'")


def _ratings_source(comp, root: Path, path, name: str, within: str) -> Optional[str]:
    found = comp.findall(f"ssd:Annotations/ssc:Annotation[@type='{RATINGS_ANNOTATION}']/mast:Ratings", NS)
    if not found:
        return None
    source = found[0].get("source")
    if len(found) > 1 or not source:
        raise SSPFormatError(f"{path}: component '{name}' needs one mast:Ratings with a 'source' in its "
                             f"'{RATINGS_ANNOTATION}' annotation (line {found[0].sourceline})")
    _inside(root, source, str(path), f"component '{name}' ratings", within)   # read by mast sizing, which names it if absent
    return source


def ssd_unit_definitions(doc, origin: str) -> dict[str, Unit]:
    """The units an .ssd defines (``ssd:Units``, SSP 1.0), by name: in scope for its inline parameter values."""
    units = doc.find("ssd:Units", NS)
    return {} if units is None else unit_definitions(units, origin)


def _binding_values(binding, root: Path, path: "_Origin", component: str, within: str,
                    ssd_units: Mapping[str, Unit]) -> dict[str, ParameterValue]:
    unsupported = [what for what, present in (
        (f"prefix={binding.get('prefix')!r}", binding.get("prefix")),
        ("an ssd:ParameterMapping", binding.find("ssd:ParameterMapping", NS) is not None),
        (f"type={binding.get('type')!r}", binding.get("type", SSV_TYPE) != SSV_TYPE)) if present]
    if unsupported:  # applying the values without them would be silently wrong
        raise SSPFormatError(f"{path}: a parameter binding of '{component}' has {' and '.join(unsupported)}, "
                             f"which this reader does not support (line {binding.sourceline})")
    source = binding.get("source")
    if source:
        file = _inside(root, source, str(path), f"component '{component}' binds parameter set", within)
        if not file.is_file():
            raise SSPFormatError(f"{path}: component '{component}' binds '{source}', which does not exist")
        values = parse_ssv(file.read_bytes(), origin=path.entry(file))
    else:
        inline = binding.find("ssd:ParameterValues/ssv:ParameterSet", NS)
        if inline is None:
            raise SSPFormatError(f"{path}: a parameter binding of '{component}' has neither a source nor values")
        values = parse_ssv(etree.tostring(inline), origin=f"{path} (inline values of '{component}')", units=ssd_units)
    return values


def applicable_parameters(system: SystemSpec, parameter_names: Mapping[str, Iterable[str]],
                          parameter_units: Optional[Mapping[str, Mapping[str, str]]] = None) -> dict[str, dict[str, Value]]:
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
    for comp, spec in system.components.items():
        for source, values in spec.bindings:
            unused = sorted(k for k in values if k not in users[source])
            if unused:
                bound = sorted(c for c, s in system.components.items() if any(src == source for src, _ in s.bindings))
                raise SSPFormatError(f"parameter set {source}: {', '.join(map(repr, unused))} is a parameter of no "
                                     f"component it is bound to ({', '.join(bound)})")
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


def _in_declared_unit(value: float, given: tuple[str, Unit], declared: Optional[str], source: str, name: str,
                      comp: str) -> float:
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
            raise SSPFormatError(f"parameter set {source}: '{name}' is given in '{text}', but component '{comp}' "
                                 f"declares no unit this tool knows for it ({declared or 'none'}): give it in "
                                 "coherent SI units")
        return value
    try:
        return convert(value, Unit(dims=unit.dims), target)
    except UnitError:
        raise SSPFormatError(f"parameter set {source}: '{name}' is given in '{text}' (dimension {unit.dimension()}), "
                             f"but component '{comp}' declares it in '{declared}' (dimension "
                             f"{target.dimension()})") from None


def _check_end(element: str, connector: str, kind: str, components, system_inputs, path) -> None:
    if element == "":
        if connector not in system_inputs:
            raise SSPFormatError(f"{path}: connection names system connector '{connector}', which is not declared")
        return
    if element not in components:
        raise SSPFormatError(f"{path}: connection names component '{element}', which does not exist")
    declared = components[element].outputs if kind == "output" else components[element].inputs
    if connector not in declared:
        raise SSPFormatError(f"{path}: connection names {kind} '{element}.{connector}', which is not a declared {kind} connector")


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
                    raise SSPFormatError(f"{self.path}: component '{name}' source "
                                         f"{self.system.components[name].source} is missing")
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
