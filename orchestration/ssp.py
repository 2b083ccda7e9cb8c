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
  ``osp:FixedStepAlgorithm`` and each component's ``osp:StepSizeHint``.
"""
from __future__ import annotations

import shutil
import tempfile
import zipfile
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath
from typing import Iterable, Mapping, Optional, Union

from lxml import etree

from fmus.common.parameters import Value

from .data.units import Unit, UnitError, convert, parse_unit
from .ssv import ParameterValue, SSPFormatError, parse_ssv

NS = {
    "ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription",
    "ssc": "http://ssp-standard.org/SSP1/SystemStructureCommon",
    "ssv": "http://ssp-standard.org/SSP1/SystemStructureParameterValues",
    "osp": "http://opensimulationplatform.com/SSP/OSPAnnotations",
}
OSP_ANNOTATION = "com.opensimulationplatform"


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

    def fmu_path(self, component: str) -> Path:
        return self.root / self.components[component].source


def safe_extract(archive: Union[str, Path], target: Union[str, Path]) -> Path:
    """Extract a zip (SSP or FMU) refusing entries that would land outside ``target``."""
    archive, target = Path(archive), Path(target)
    try:
        handle = zipfile.ZipFile(archive)
    except (zipfile.BadZipFile, OSError) as err:
        raise SSPFormatError(f"{archive}: not a readable zip archive ({err})") from None
    with handle:
        for member in handle.namelist():
            pure = PurePosixPath(member.replace("\\", "/"))
            if pure.is_absolute() or ".." in pure.parts or (pure.parts and ":" in pure.parts[0]):
                raise SSPFormatError(f"{archive}: entry '{member}' would be extracted outside the target folder")
        handle.extractall(target)
    return target


def validate_ssd_schema(path: Union[str, Path]) -> list[str]:
    """Problems found by the SSP 1.0 schema (empty list: valid)."""
    from fmpy.ssp.ssd import validate_tree  # the SSP 1.0 XSDs ship with fmpy

    try:
        validate_tree(etree.parse(str(path)).getroot(), "SystemStructureDescription.xsd")
    except Exception as err:  # fmpy raises a plain Exception listing the schema errors
        return [str(err)]
    return []


def read_ssd(path: Union[str, Path], root: Optional[Path] = None) -> SystemSpec:
    """Parse a SystemStructure.ssd; relative sources resolve against ``root`` (default: its folder)."""
    path = Path(path)
    root = root or path.parent
    try:
        doc = etree.parse(str(path)).getroot()
    except (etree.XMLSyntaxError, OSError) as err:
        raise SSPFormatError(f"{path}: cannot read the system structure: {err}") from None
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
    components: dict[str, ComponentSpec] = {}
    for comp in system.findall("ssd:Elements/ssd:Component", NS):
        name = need(comp, "name", "a component")
        if name in components:
            raise SSPFormatError(f"{path}: component name '{name}' is used twice")
        connectors = comp.findall("ssd:Connectors/ssd:Connector", NS)
        spec = ComponentSpec(
            name=name,
            source=need(comp, "source", f"component '{name}'"),
            step_size=_step_size_hint(comp, path, name),
            inputs=[c.get("name") for c in connectors if c.get("kind") in ("input", "parameter")],
            outputs=[c.get("name") for c in connectors if c.get("kind") in ("output", "calculatedParameter")],
        )
        for binding in comp.findall("ssd:ParameterBindings/ssd:ParameterBinding", NS):
            parsed = _binding_values(binding, root, path, name)
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
        start = float(experiment.get("startTime", 0.0))
        stop = float(experiment.get("stopTime")) if experiment.get("stopTime") else None
        algo = experiment.find(f"ssd:Annotations/ssc:Annotation[@type='{OSP_ANNOTATION}']/osp:Algorithm/osp:FixedStepAlgorithm", NS)
        if algo is not None:
            base_step = _positive(need(algo, "baseStepSize", "osp:FixedStepAlgorithm"), path, "baseStepSize")
    return SystemSpec(system.get("name", path.stem), root, components, connections, system_inputs, base_step, start, stop)


def _positive(text: str, path: Path, what: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not value > 0:
        raise SSPFormatError(f"{path}: {what}={text!r}: expected a positive number of seconds")
    return value


def _step_size_hint(comp, path: Path, name: str) -> Optional[float]:
    hint = comp.find(f"ssd:Annotations/ssc:Annotation[@type='{OSP_ANNOTATION}']/osp:StepSizeHint", NS)
    return None if hint is None else _positive(hint.get("value", ""), path, f"StepSizeHint of '{name}'")


def _binding_values(binding, root: Path, path: Path, component: str) -> dict[str, ParameterValue]:
    source = binding.get("source")
    if source:
        file = root / source
        if not file.exists():
            raise SSPFormatError(f"{path}: component '{component}' binds '{source}', which does not exist")
        values = parse_ssv(file)
    else:
        inline = binding.find("ssd:ParameterValues/ssv:ParameterSet", NS)
        if inline is None:
            raise SSPFormatError(f"{path}: a parameter binding of '{component}' has neither a source nor values")
        values = parse_ssv(etree.tostring(inline), origin=f"{path} (inline values of '{component}')")
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


def _check_end(element: str, connector: str, kind: str, components, system_inputs, path: Path) -> None:
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
        if self.path.suffix == ".ssd":
            self.ssd = self.path
        else:
            self._tmp = tempfile.mkdtemp(prefix="mast_ssp_")
            safe_extract(self.path, self._tmp)
            self.ssd = Path(self._tmp) / "SystemStructure.ssd"
            if not self.ssd.exists():
                self.close()
                raise SSPFormatError(f"{self.path}: no SystemStructure.ssd at the root of the archive")
        self.system = read_ssd(self.ssd)
        for name in self.system.components:
            fmu = self.system.fmu_path(name)
            if not fmu.exists():
                self.close()
                raise SSPFormatError(f"{self.path}: component '{name}' source {self.system.components[name].source} is missing")

    def close(self) -> None:
        if self._tmp:
            shutil.rmtree(self._tmp, ignore_errors=True)
            self._tmp = None

    def __enter__(self) -> "SSPArchive":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
