"""SSP parameter sets (.ssv): read and write, in classes that mirror the schema.

``ParameterSet`` is an ``ssv:ParameterSet`` (its name, its ``ssv:Parameter`` elements as
``ParameterValue``, its ``ssv:Units``); ``read`` gives one from a file, ``ParameterSet.to_bytes`` /
``write`` give the file back, ``parameter_set`` builds one from plain values. Every parameter set
the project writes (``mast build``'s flattened sets, ``mast diagnose``'s, ``mast fit-gains``', the
inline sets of a system) goes through here.

Reading: a Real value with a ``unit`` is converted to the coherent SI unit of its dimension
(``unit="g"``: 2.06 g is 0.00206 kg), the unit the project's models declare for every parameter; the
unit stays with the value (``ParameterValue.unit``) so that ``ssp.applicable_parameters`` can refuse
one whose dimension is not the parameter's. Units come from the set's own definitions
(``ssv:Units``, SSP 1.0) or the notation of ``mast.core.units``; an unknown unit is an error naming
the set, the parameter and the unit.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping, Optional, Sequence, Union

from lxml import etree

from fmus.common.parameters import Value, exact_boolean

from .units import BASE, Unit, UnitError, parse_unit

SSV_NS = "http://ssp-standard.org/SSP1/SystemStructureParameterValues"
SSC_NS = "http://ssp-standard.org/SSP1/SystemStructureCommon"
_TYPES = {"Real": float, "Integer": int, "Boolean": exact_boolean, "String": str}


class SSPFormatError(ValueError):
    """A malformed SSD/SSV file or SSP archive."""


@dataclass(frozen=True)
class ParameterValue:
    """An ``ssv:Parameter``: its name, typed value, unit and description (``source``)."""

    name: str
    value: Value  # a Real with a unit: in the coherent SI unit of that unit's dimension
    unit: str  # as written in the set ("" if none)
    source: str
    si: Optional[Unit] = None  # the parsed ``unit`` (None: no unit given)
    written: Optional[Value] = None  # the value as written in the set, in ``unit`` (None: ``value``)


@dataclass
class ParameterSet:
    """An ``ssv:ParameterSet``: ``parameters`` by name, in document order; ``units``: the ``ssc:Unit``
    definitions of its ``ssv:Units``, by name; ``comment``: the XML comment it opens with ("": none)."""

    name: str
    parameters: dict[str, ParameterValue] = field(default_factory=dict)
    units: dict[str, Unit] = field(default_factory=dict)
    comment: str = ""
    version: str = "1.0"

    def to_element(self) -> etree._Element:
        """The ``ssv:ParameterSet`` element (no layout: ``indent`` gives it one)."""
        root = etree.Element(
            f"{{{SSV_NS}}}ParameterSet", nsmap={"ssv": SSV_NS, "ssc": SSC_NS}, version=self.version, name=self.name
        )
        if self.comment:
            root.append(etree.Comment(f" {self.comment.strip().replace('--', '- -')} "))
        params = etree.SubElement(root, f"{{{SSV_NS}}}Parameters")
        for p in self.parameters.values():
            par = etree.SubElement(params, f"{{{SSV_NS}}}Parameter", name=p.name)
            if p.source:
                par.set("description", p.source)
            kind, text = typed_value(p.value if p.written is None else p.written)  # in p.unit, as written
            typed = etree.SubElement(par, f"{{{SSV_NS}}}{kind}", value=text)
            if p.unit and kind == "Real":
                typed.set("unit", p.unit)
        if self.units:
            section = etree.SubElement(root, f"{{{SSV_NS}}}Units")
            for name, unit in self.units.items():
                section.append(unit_element(name, unit))
        return root

    def to_bytes(self) -> bytes:
        """The .ssv document."""
        root = self.to_element()
        indent(root)
        return xml_document(root)


def write(path: Union[str, Path], parameter_set: ParameterSet) -> Path:
    """Write ``parameter_set`` as the .ssv file ``path``; the path."""
    path = Path(path)
    path.write_bytes(parameter_set.to_bytes())
    return path


def parameter_set(
    name: str,
    values: Mapping[str, Value],
    units: Optional[Mapping[str, str]] = None,
    descriptions: Optional[Mapping[str, str]] = None,
    comment: str = "",
) -> ParameterSet:
    """A set of plain ``values`` [in ``units``, by name; a name without a unit: none], each with its
    description; every unit a value uses is defined in the set's ``ssv:Units`` (``mast.core.units``
    notation). An int stays an Integer, a bool a Boolean, a str a String, anything else is a Real."""
    units, descriptions = units or {}, descriptions or {}
    params, used = {}, {}
    for key, value in values.items():
        if not isinstance(value, (bool, int, str)):
            value = float(value)
        unit = units.get(key, "") if isinstance(value, float) else ""
        if unit:
            used[unit] = parse_unit(unit)
        params[key] = ParameterValue(key, value, unit, descriptions.get(key, ""))
    return ParameterSet(name, params, dict(sorted(used.items())), comment)


def unit_element(name: str, unit: Unit) -> etree._Element:
    """An ``ssc:Unit`` named ``name`` defining ``unit`` (its base-unit exponents, factor and offset)."""
    element = etree.Element(f"{{{SSC_NS}}}Unit", name=name)
    base = etree.SubElement(element, f"{{{SSC_NS}}}BaseUnit")
    for symbol, exponent in zip(BASE, unit.dims):
        if exponent:
            base.set(symbol, str(exponent))
    if unit.factor != 1.0:
        base.set("factor", repr(unit.factor))
    if unit.offset:
        base.set("offset", repr(unit.offset))
    return element


def xml_document(root: etree._Element, comments: Sequence[str] = ()) -> bytes:
    """The UTF-8 document of ``root``, after the XML declaration and ``comments`` (one a line, before the root)."""
    head = "".join(f"<!-- {text.strip().replace('--', '- -')} -->\n" for text in comments)
    return f'<?xml version="1.0" encoding="UTF-8"?>\n{head}'.encode() + etree.tostring(root, encoding="UTF-8") + b"\n"


def indent(element: etree._Element, level: int = 0) -> None:
    """Lay ``element`` out two spaces a level, keeping on one line an element with one child that has
    none (``<ssv:Parameter ...><ssv:Real .../></ssv:Parameter>``, a connector, an annotation) unless
    it is a list (a name ending in s: Parameters, ParameterBindings ...)."""
    children = list(element)
    if not children:
        return
    lone = len(children) == 1 and not len(children[0]) and not etree.QName(element).localname.endswith("s")
    if lone and isinstance(children[0].tag, str):
        element.text, children[0].tail = None, None
        return
    pad = "\n" + "  " * (level + 1)
    element.text = pad
    for child in children:
        child.tail = pad
        if isinstance(child.tag, str):
            indent(child, level + 1)
    children[-1].tail = "\n" + "  " * level


def typed_value(value: Value) -> tuple[str, str]:
    """(SSV element, attribute text) of a parameter value: ("Real", repr) and so on; the text unescaped."""
    if isinstance(value, bool):
        return "Boolean", "true" if value else "false"
    if isinstance(value, int):
        return "Integer", str(value)
    if isinstance(value, float):
        return "Real", repr(value)
    return "String", str(value)


def read(
    data: Union[bytes, str, Path, etree._Element], origin: str = "", units: Optional[Mapping[str, Unit]] = None
) -> ParameterSet:
    """The parameter set of an .ssv document (bytes, text, a path or a parsed ``ssv:ParameterSet``).

    ``units``: unit definitions in scope besides the set's own (an inline set in an .ssd sees the
    .ssd's ``ssd:Units``); the set's own definitions take precedence."""
    if isinstance(data, etree._Element):
        root = data
    else:
        if isinstance(data, Path):
            origin = origin or str(data)
            data = data.read_bytes()
        elif isinstance(data, str):
            data = data.encode()
        try:
            root = etree.fromstring(data)
        except etree.XMLSyntaxError as err:
            raise SSPFormatError(f"{origin}: not well-formed XML: {err}") from None
    if root.tag != f"{{{SSV_NS}}}ParameterSet":
        raise SSPFormatError(f"{origin}: root element is {root.tag}, expected ssv:ParameterSet")
    own = unit_definitions(root, origin)
    defined = {**(units or {}), **own}
    values: dict[str, ParameterValue] = {}
    for par in root.iter(f"{{{SSV_NS}}}Parameter"):
        name = par.get("name")
        if not name:
            raise SSPFormatError(f"{origin}: a Parameter has no name")
        kinds = [child for child in par if isinstance(child.tag, str) and etree.QName(child).localname in _TYPES]
        if len(kinds) != 1:
            raise SSPFormatError(f"{origin}: parameter '{name}' needs exactly one of Real/Integer/Boolean/String")
        kind = etree.QName(kinds[0]).localname
        raw = kinds[0].get("value")
        if raw is None:
            raise SSPFormatError(f"{origin}: parameter '{name}' has no value attribute")
        try:
            value = _TYPES[kind](raw)
        except ValueError:
            raise SSPFormatError(f"{origin}: parameter '{name}': value {raw!r} is not a valid {kind}") from None
        if name in values:
            raise SSPFormatError(f"{origin}: parameter '{name}' is defined twice")
        unit_text = (kinds[0].get("unit") or "").strip()
        unit, written = None, value
        if unit_text:
            if kind != "Real":
                raise SSPFormatError(
                    f"{origin}: parameter '{name}': a unit ('{unit_text}') on a {kind} value; "
                    "SSP gives units to Real values only"
                )
            try:
                unit = parse_unit(unit_text, defined)
            except UnitError as err:
                raise SSPFormatError(f"{origin}: parameter '{name}': {err}") from None
            value = unit.factor * value + unit.offset
        values[name] = ParameterValue(name, value, unit_text, par.get("description", ""), unit, written)
    comments = [c.text for c in root if c.tag is etree.Comment]
    return ParameterSet(root.get("name", ""), values, own, comments[0] if comments else "", root.get("version", "1.0"))


def parse_ssv(
    data: Union[bytes, str, Path, etree._Element], origin: str = "", units: Optional[Mapping[str, Unit]] = None
) -> dict[str, ParameterValue]:
    """The parameters of an .ssv document, by name (``read``)."""
    return read(data, origin, units).parameters


def unit_definitions(root, origin: str) -> dict[str, Unit]:
    """The ``ssc:Unit`` definitions under ``root`` (a set's ``ssv:Units``, an .ssd's ``ssd:Units``), by name."""
    defined = {}
    for element in root.iter(f"{{{SSC_NS}}}Unit"):
        name = element.get("name")
        base = element.find(f"{{{SSC_NS}}}BaseUnit")
        if not name or base is None:
            raise SSPFormatError(f"{origin}: an ssc:Unit needs a name and an ssc:BaseUnit")
        try:
            dims = tuple(int(base.get(b, "0")) for b in BASE)
            defined[name] = Unit(float(base.get("factor", "1")), dims, float(base.get("offset", "0")))
        except ValueError:
            raise SSPFormatError(
                f"{origin}: unit '{name}': its ssc:BaseUnit has a value that is not a number"
            ) from None
    return defined


def read_values(*paths: Union[str, Path]) -> dict[str, Value]:
    """Merge the values of several .ssv files, later files overriding earlier ones."""
    merged: dict[str, Value] = {}
    for path in paths:
        merged.update({name: p.value for name, p in parse_ssv(Path(path)).items()})
    return merged
