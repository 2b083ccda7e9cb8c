"""SSP system structure descriptions (.ssd): read and write, in classes that mirror the schema.

``SystemStructureDescription`` holds a ``System`` (its ``Connector``s, ``Component``s and
``Connection``s), the ``DefaultExperiment`` and the ``ssd:Units``; a ``Component`` its connectors,
its ``ParameterBinding``s (a parameter set's ``source``, or inline values: an ``ssv.ParameterSet``)
and the two annotations this project reads:

- step sizes from the Open Simulation Platform annotations: the base step of
  ``osp:FixedStepAlgorithm`` (``DefaultExperiment.base_step``) and each component's
  ``osp:StepSizeHint`` (``Component.step_size_hint``);
- the parameter set of a component's ratings (``mast sizing``, docs/sizing.md): an annotation of
  type ``mast.sizing`` holding ``<mast:Ratings source="resources/....ssv"/>`` (``Component.ratings``).
  The ratings are not parameters of the FMU (no host applies them; an annotation of a type a tool
  does not know is ignored, SSP 1.0), so they live in their own set, named by the system per component.

``read`` checks the document's structure (names given, components unique and FMUs, connections
between declared connectors, step sizes positive) and raises SSPFormatError naming the file, the
element and its line; ``SystemStructureDescription.to_bytes`` / ``write`` give the file back. What the
reader meets but does not model (a signal dictionary, a nested system, an annotation of another
type ...) is listed in ``unmodelled``: such a document can be read, but writing it would lose
those parts and is refused. Every .ssd the project writes goes through here (``mast.core.systems``
generates ssp/*.ssd; ``mast build``, ``mast compare`` and ``mast diagnose`` edit systems with it);
``mast.core.ssp`` resolves a document's parameter sets and archives.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Optional, Union

from lxml import etree

from .ssv import ParameterSet, SSPFormatError, indent, unit_definitions, unit_element, xml_document
from .ssv import read as read_parameter_set
from .units import Unit

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
INPUT_KINDS = ("input", "parameter")
OUTPUT_KINDS = ("output", "calculatedParameter")


def _q(prefix: str, name: str) -> str:
    return f"{{{NS[prefix]}}}{name}"


@dataclass
class Connector:
    """An ``ssd:Connector``: ``kind`` input, output, parameter ...; ``type`` its ``ssc:`` type element
    (Real, Integer, Boolean, String; None: untyped) with the ``unit`` of a Real."""

    name: str
    kind: str
    type: Optional[str] = "Real"
    unit: Optional[str] = None

    def to_element(self) -> etree._Element:
        element = etree.Element(_q("ssd", "Connector"), name=self.name, kind=self.kind)
        if self.type:
            typed = etree.SubElement(element, _q("ssc", self.type))
            if self.unit:
                typed.set("unit", self.unit)
        return element


@dataclass
class ParameterBinding:
    """An ``ssd:ParameterBinding``: the parameter set ``source`` (relative to the .ssd), or inline ``values``."""

    source: Optional[str] = None
    values: Optional[ParameterSet] = None

    def to_element(self) -> etree._Element:
        element = etree.Element(_q("ssd", "ParameterBinding"))
        if self.source:
            element.set("source", self.source)
        if self.values is not None:
            etree.SubElement(element, _q("ssd", "ParameterValues")).append(self.values.to_element())
        return element


@dataclass
class Component:
    """An ``ssd:Component`` (an FMU): its connectors, parameter bindings (applied in order) and annotations;
    ``comment``: the XML comment written before it ("": none)."""

    name: str
    source: str
    connectors: list[Connector] = field(default_factory=list)
    bindings: list[ParameterBinding] = field(default_factory=list)
    step_size_hint: Optional[float] = None
    ratings: Optional[str] = None
    comment: str = ""
    type: str = FMU_TYPE

    @property
    def inputs(self) -> list[str]:
        return [c.name for c in self.connectors if c.kind in INPUT_KINDS]

    @property
    def outputs(self) -> list[str]:
        return [c.name for c in self.connectors if c.kind in OUTPUT_KINDS]

    def to_element(self) -> etree._Element:
        element = etree.Element(_q("ssd", "Component"), name=self.name, source=self.source, type=self.type)
        if self.connectors:
            etree.SubElement(element, _q("ssd", "Connectors")).extend(c.to_element() for c in self.connectors)
        if self.bindings:
            etree.SubElement(element, _q("ssd", "ParameterBindings")).extend(b.to_element() for b in self.bindings)
        if self.step_size_hint is not None or self.ratings:
            annotations = etree.SubElement(element, _q("ssd", "Annotations"))
            if self.step_size_hint is not None:
                hint = etree.SubElement(annotations, _q("ssc", "Annotation"), type=OSP_ANNOTATION)
                etree.SubElement(hint, _q("osp", "StepSizeHint"), value=repr(float(self.step_size_hint)))
            if self.ratings:
                ratings = etree.SubElement(annotations, _q("ssc", "Annotation"), type=RATINGS_ANNOTATION)
                etree.SubElement(ratings, _q("mast", "Ratings"), source=self.ratings)
        return element


@dataclass(frozen=True)
class Connection:
    """An ``ssd:Connection``; an element "" is the system itself (a system connector)."""

    start_element: str
    start_connector: str
    end_element: str
    end_connector: str

    def to_element(self) -> etree._Element:
        element = etree.Element(_q("ssd", "Connection"))
        for attribute, value in (
            ("startElement", self.start_element),
            ("startConnector", self.start_connector),
            ("endElement", self.end_element),
            ("endConnector", self.end_connector),
        ):
            if value:
                element.set(attribute, value)
        return element


@dataclass
class System:
    """An ``ssd:System``: its own connectors (system inputs and outputs), components and connections."""

    name: str
    description: str = ""
    connectors: list[Connector] = field(default_factory=list)
    elements: list[Component] = field(default_factory=list)
    connections: list[Connection] = field(default_factory=list)

    def component(self, name: str) -> Component:
        """The component ``name``; KeyError naming the system's components if there is none."""
        for c in self.elements:
            if c.name == name:
                return c
        raise KeyError(
            f"system '{self.name}' has no component '{name}' (it has {', '.join(c.name for c in self.elements)})"
        )

    def bind(self, source: str, accept: Callable[[str], bool]) -> None:
        """Bind the parameter set ``source`` last (it overrides) to every component whose name ``accept`` takes."""
        for component in self.elements:
            if accept(component.name):
                component.bindings.append(ParameterBinding(source))

    def to_element(self) -> etree._Element:
        element = etree.Element(_q("ssd", "System"), name=self.name)
        if self.description:
            element.set("description", self.description)
        if self.connectors:
            etree.SubElement(element, _q("ssd", "Connectors")).extend(c.to_element() for c in self.connectors)
        elements = etree.SubElement(element, _q("ssd", "Elements"))
        for component in self.elements:
            if component.comment:
                elements.append(etree.Comment(f" {component.comment.strip()} "))
            elements.append(component.to_element())
        if self.connections:
            etree.SubElement(element, _q("ssd", "Connections")).extend(c.to_element() for c in self.connections)
        return element


@dataclass
class DefaultExperiment:
    """An ``ssd:DefaultExperiment`` [s]: start and stop time, and the base step of its
    ``osp:FixedStepAlgorithm`` (None: no such annotation)."""

    start_time: float = 0.0
    stop_time: Optional[float] = None
    base_step: Optional[float] = None

    def to_element(self) -> etree._Element:
        element = etree.Element(_q("ssd", "DefaultExperiment"), startTime=repr(float(self.start_time)))
        if self.stop_time is not None:
            element.set("stopTime", repr(float(self.stop_time)))
        if self.base_step is not None:
            annotation = etree.SubElement(
                etree.SubElement(element, _q("ssd", "Annotations")), _q("ssc", "Annotation"), type=OSP_ANNOTATION
            )
            etree.SubElement(
                etree.SubElement(annotation, _q("osp", "Algorithm")),
                _q("osp", "FixedStepAlgorithm"),
                baseStepSize=repr(float(self.base_step)),
            )
        return element


@dataclass
class SystemStructureDescription:
    """An .ssd document: ``comments`` are the XML comments before its root element; ``units`` its
    ``ssd:Units`` (in scope for inline parameter values); ``unmodelled``: what ``read`` found and this
    model does not hold (module docstring)."""

    name: str
    system: System
    default_experiment: Optional[DefaultExperiment] = None
    units: dict[str, Unit] = field(default_factory=dict)
    comments: list[str] = field(default_factory=list)
    version: str = "1.0"
    unmodelled: list[str] = field(default_factory=list)

    def to_bytes(self) -> bytes:
        """The .ssd document; SSPFormatError if it was read with parts this model does not hold."""
        if self.unmodelled:
            raise SSPFormatError(
                f"system '{self.name}': writing it would drop {', '.join(self.unmodelled)}, "
                "which this tool does not model"
            )
        ratings = any(c.ratings for c in self.system.elements)
        nsmap = {k: v for k, v in NS.items() if k != "mast" or ratings}
        root = etree.Element(_q("ssd", "SystemStructureDescription"), nsmap=nsmap, version=self.version, name=self.name)
        root.append(self.system.to_element())
        if self.units:
            etree.SubElement(root, _q("ssd", "Units")).extend(unit_element(n, u) for n, u in self.units.items())
        if self.default_experiment is not None:
            root.append(self.default_experiment.to_element())
        indent(root)
        etree.cleanup_namespaces(root, top_nsmap=nsmap, keep_ns_prefixes=list(nsmap))  # inline sets declare none
        return xml_document(root, self.comments)


def write(path: Union[str, Path], document: SystemStructureDescription) -> Path:
    """Write ``document`` as the .ssd file ``path``; the path."""
    path = Path(path)
    path.write_bytes(document.to_bytes())
    return path


def read(source: Union[str, Path, bytes], origin: Optional[str] = None) -> SystemStructureDescription:
    """The document of an .ssd file (a path, or its bytes); ``origin``: how messages name it (default: the path)."""
    where = origin or (str(source) if not isinstance(source, bytes) else "SystemStructure.ssd")
    try:
        if isinstance(source, bytes):
            doc = etree.fromstring(source)
        else:
            doc = etree.parse(str(source)).getroot()
    except (etree.XMLSyntaxError, OSError) as err:
        text = (
            str(err)
            if isinstance(source, bytes)
            else str(err).replace(f"{source}:", "").replace(str(source), Path(source).name)
        )
        raise SSPFormatError(f"{where}: cannot read the system structure: {text.strip()}") from None
    return _Reader(where).document(doc)


class _Reader:
    """``read``'s checks, each message naming the file (``where``), the element and its line."""

    def __init__(self, where: str) -> None:
        self.where = where
        self.unmodelled: list[str] = []

    def need(self, element, attribute: str, what: str) -> str:
        value = element.get(attribute)
        if not value:
            raise SSPFormatError(f"{self.where}: {what} has no '{attribute}' attribute (line {element.sourceline})")
        return value

    def number(self, text: str, what: str) -> float:
        try:
            value = float(text)
        except ValueError:
            value = float("nan")
        if value != value or value in (float("inf"), float("-inf")):
            raise SSPFormatError(f"{self.where}: {what}={text!r}: expected a finite number of seconds")
        return value

    def positive(self, text: str, what: str) -> float:
        try:
            value = float(text)
        except ValueError:
            value = float("nan")
        if not value > 0:
            raise SSPFormatError(f"{self.where}: {what}={text!r}: expected a positive number of seconds")
        return value

    def note(self, element, known: tuple[str, ...]) -> None:
        """Record the children of ``element`` that are not among the ``known`` (prefix:name) elements."""
        names = {_q(*k.split(":")) for k in known}
        for child in element:
            if isinstance(child.tag, str) and child.tag not in names:
                self.unmodelled.append(f"{etree.QName(child).localname} (line {child.sourceline})")

    def document(self, doc) -> SystemStructureDescription:
        if doc.tag != _q("ssd", "SystemStructureDescription"):
            raise SSPFormatError(f"{self.where}: root element is {doc.tag}, expected ssd:SystemStructureDescription")
        system = doc.find("ssd:System", NS)
        if system is None:
            raise SSPFormatError(f"{self.where}: no ssd:System element")
        self.note(doc, ("ssd:System", "ssd:Units", "ssd:DefaultExperiment"))
        units_element = doc.find("ssd:Units", NS)
        units = {} if units_element is None else unit_definitions(units_element, self.where)
        connectors = [self.connector(c, system=True) for c in system.findall("ssd:Connectors/ssd:Connector", NS)]
        self.note(system, ("ssd:Connectors", "ssd:Elements", "ssd:Connections"))
        components: list[Component] = []
        for element in system.findall("ssd:Elements/*", NS):
            if element.tag != _q("ssd", "Component"):
                self.unmodelled.append(f"{etree.QName(element).localname} (line {element.sourceline})")
                continue
            component = self.component(element, units)
            if any(c.name == component.name for c in components):
                raise SSPFormatError(f"{self.where}: component name '{component.name}' is used twice")
            components.append(component)
        if not components:
            raise SSPFormatError(f"{self.where}: the system has no components")
        inputs = [c.name for c in connectors if c.kind in INPUT_KINDS]
        by_name = {c.name: c for c in components}
        connections = []
        for con in system.findall("ssd:Connections/ssd:Connection", NS):
            c = Connection(
                con.get("startElement", ""),
                self.need(con, "startConnector", "a connection"),
                con.get("endElement", ""),
                self.need(con, "endConnector", "a connection"),
            )
            self.check_end(c.start_element, c.start_connector, "output", by_name, inputs)
            self.check_end(c.end_element, c.end_connector, "input", by_name, inputs)
            self.note(con, ())
            connections.append(c)
        comments = [c.text for c in doc.itersiblings(preceding=True) if c.tag is etree.Comment][::-1]
        return SystemStructureDescription(
            doc.get("name", ""),
            System(system.get("name", ""), system.get("description", ""), connectors, components, connections),
            self.experiment(doc),
            units,
            comments,
            doc.get("version", "1.0"),
            self.unmodelled,
        )

    def connector(self, element, system: bool = False) -> Connector:
        kind = element.get("kind", "")
        name = (
            self.need(element, "name", "a system connector") if system and kind in INPUT_KINDS else element.get("name")
        )
        typed = [c for c in element if isinstance(c.tag, str) and c.tag.startswith(f"{{{NS['ssc']}}}")]
        return Connector(
            name, kind, etree.QName(typed[0]).localname if typed else None, typed[0].get("unit") if typed else None
        )

    def component(self, comp, units: dict[str, Unit]) -> Component:
        name = self.need(comp, "name", "a component")
        connectors = [self.connector(c) for c in comp.findall("ssd:Connectors/ssd:Connector", NS)]
        source = self.need(comp, "source", f"component '{name}'")
        if comp.get("type", FMU_TYPE) != FMU_TYPE:
            raise SSPFormatError(
                f"{self.where}: component '{name}' has type '{comp.get('type')}': only FMUs ({FMU_TYPE}) are supported"
            )
        self.note(comp, ("ssd:Connectors", "ssd:ParameterBindings", "ssd:Annotations"))
        previous = comp.getprevious()
        return Component(
            name,
            source,
            connectors,
            [self.binding(b, name, units) for b in comp.findall("ssd:ParameterBindings/ssd:ParameterBinding", NS)],
            self.step_size_hint(comp, name),
            self.ratings(comp, name),
            previous.text if previous is not None and previous.tag is etree.Comment else "",
        )

    def step_size_hint(self, comp, name: str) -> Optional[float]:
        for annotation in comp.findall("ssd:Annotations/ssc:Annotation", NS):
            if annotation.get("type") not in (OSP_ANNOTATION, RATINGS_ANNOTATION):
                self.unmodelled.append(f"the annotation '{annotation.get('type')}' of '{name}'")
        hint = comp.find(f"ssd:Annotations/ssc:Annotation[@type='{OSP_ANNOTATION}']/osp:StepSizeHint", NS)
        return None if hint is None else self.positive(hint.get("value", ""), f"StepSizeHint of '{name}'")

    def ratings(self, comp, name: str) -> Optional[str]:
        found = comp.findall(f"ssd:Annotations/ssc:Annotation[@type='{RATINGS_ANNOTATION}']/mast:Ratings", NS)
        if not found:
            return None
        source = found[0].get("source")
        if len(found) > 1 or not source:
            raise SSPFormatError(
                f"{self.where}: component '{name}' needs one mast:Ratings with a 'source' in its "
                f"'{RATINGS_ANNOTATION}' annotation (line {found[0].sourceline})"
            )
        return source

    def binding(self, binding, component: str, units: dict[str, Unit]) -> ParameterBinding:
        unsupported = [
            what
            for what, present in (
                (f"prefix={binding.get('prefix')!r}", binding.get("prefix")),
                ("an ssd:ParameterMapping", binding.find("ssd:ParameterMapping", NS) is not None),
                (f"type={binding.get('type')!r}", binding.get("type", SSV_TYPE) != SSV_TYPE),
            )
            if present
        ]
        if unsupported:  # applying the values without them would be silently wrong
            raise SSPFormatError(
                f"{self.where}: a parameter binding of '{component}' has {' and '.join(unsupported)}, "
                f"which this reader does not support (line {binding.sourceline})"
            )
        source = binding.get("source")
        if source:
            return ParameterBinding(source)
        inline = binding.find("ssd:ParameterValues/ssv:ParameterSet", NS)
        if inline is None:
            raise SSPFormatError(f"{self.where}: a parameter binding of '{component}' has neither a source nor values")
        return ParameterBinding(
            None, read_parameter_set(inline, f"{self.where} (inline values of '{component}')", units)
        )

    def experiment(self, doc) -> Optional[DefaultExperiment]:
        experiment = doc.find("ssd:DefaultExperiment", NS)
        if experiment is None:
            return None
        start = self.number(experiment.get("startTime", "0"), "DefaultExperiment startTime")
        stop = (
            self.number(experiment.get("stopTime"), "DefaultExperiment stopTime")
            if experiment.get("stopTime")
            else None
        )
        algo = experiment.find(
            f"ssd:Annotations/ssc:Annotation[@type='{OSP_ANNOTATION}']/osp:Algorithm/osp:FixedStepAlgorithm", NS
        )
        base = (
            None
            if algo is None
            else self.positive(self.need(algo, "baseStepSize", "osp:FixedStepAlgorithm"), "baseStepSize")
        )
        return DefaultExperiment(start, stop, base)

    def check_end(
        self, element: str, connector: str, kind: str, components: dict[str, Component], system_inputs: list[str]
    ) -> None:
        if element == "":
            if connector not in system_inputs:
                raise SSPFormatError(
                    f"{self.where}: connection names system connector '{connector}', which is not declared"
                )
            return
        if element not in components:
            raise SSPFormatError(f"{self.where}: connection names component '{element}', which does not exist")
        declared = components[element].outputs if kind == "output" else components[element].inputs
        if connector not in declared:
            raise SSPFormatError(
                f"{self.where}: connection names {kind} '{element}.{connector}', which is not a "
                f"declared {kind} connector"
            )
