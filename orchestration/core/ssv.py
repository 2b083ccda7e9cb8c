"""Read SSP parameter sets (.ssv): values with their unit and source.

A Real value with a ``unit`` is converted to the coherent SI unit of its dimension (``unit="g"``:
2.06 g is 0.00206 kg), the unit the project's models declare for every parameter; the unit
stays with the value (``ParameterValue.unit``) so that ``ssp.applicable_parameters`` can
refuse one whose dimension is not the parameter's. Units come from the set's own
definitions (``ssv:Units``, SSP 1.0) or the notation of ``mast.core.units``; an unknown unit
is an error naming the set, the parameter and the unit.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Mapping, Optional, Union

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
    name: str
    value: Value       # a Real with a unit: in the coherent SI unit of that unit's dimension
    unit: str          # as written in the set ("" if none)
    source: str
    si: Optional[Unit] = None   # the parsed ``unit`` (None: no unit given)
    written: Optional[Value] = None  # the value as written in the set, in ``unit`` (None: ``value``)


def typed_value(value: Value) -> tuple[str, str]:
    """(SSV element, attribute text) of a parameter value: ("Real", repr) and so on; the text unescaped."""
    if isinstance(value, bool):
        return "Boolean", "true" if value else "false"
    if isinstance(value, int):
        return "Integer", str(value)
    if isinstance(value, float):
        return "Real", repr(value)
    return "String", str(value)


def parse_ssv(data: Union[bytes, str, Path], origin: str = "",
              units: Optional[Mapping[str, Unit]] = None) -> dict[str, ParameterValue]:
    """Parse an .ssv document (bytes, text or a path) into {name: ParameterValue}.

    ``units``: unit definitions in scope besides the set's own (an inline set in an .ssd sees the
    .ssd's ``ssd:Units``); the set's own definitions take precedence."""
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
    defined = {**(units or {}), **unit_definitions(root, origin)}
    values: dict[str, ParameterValue] = {}
    for par in root.iter(f"{{{SSV_NS}}}Parameter"):
        name = par.get("name")
        if not name:
            raise SSPFormatError(f"{origin}: a Parameter has no name")
        kinds = [child for child in par if etree.QName(child).localname in _TYPES]
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
                raise SSPFormatError(f"{origin}: parameter '{name}': a unit ('{unit_text}') on a {kind} value; "
                                     "SSP gives units to Real values only")
            try:
                unit = parse_unit(unit_text, defined)
            except UnitError as err:
                raise SSPFormatError(f"{origin}: parameter '{name}': {err}") from None
            value = unit.factor * value + unit.offset
        values[name] = ParameterValue(name, value, unit_text, par.get("description", ""), unit, written)
    return values


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
            raise SSPFormatError(f"{origin}: unit '{name}': its ssc:BaseUnit has a value that is not a number") from None
    return defined


def read_values(*paths: Union[str, Path]) -> dict[str, Value]:
    """Merge the values of several .ssv files, later files overriding earlier ones."""
    merged: dict[str, Value] = {}
    for path in paths:
        merged.update({name: p.value for name, p in parse_ssv(Path(path)).items()})
    return merged
