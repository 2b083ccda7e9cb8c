"""Read SSP parameter sets (.ssv): values with their unit and source."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Union

from lxml import etree

from fmus.common.parameters import Value

SSV_NS = "http://ssp-standard.org/SSP1/SystemStructureParameterValues"
_TYPES = {"Real": float, "Integer": int, "Boolean": lambda s: s.strip() in ("true", "1"), "String": str}


class SSPFormatError(ValueError):
    """A malformed SSD/SSV file or SSP archive."""


@dataclass(frozen=True)
class ParameterValue:
    name: str
    value: Value
    unit: str
    source: str


def parse_ssv(data: Union[bytes, str, Path], origin: str = "") -> dict[str, ParameterValue]:
    """Parse an .ssv document (bytes, text or a path) into {name: ParameterValue}."""
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
        values[name] = ParameterValue(name, value, kinds[0].get("unit", ""), par.get("description", ""))
    return values


def read_values(*paths: Union[str, Path]) -> dict[str, Value]:
    """Merge the values of several .ssv files, later files overriding earlier ones."""
    merged: dict[str, Value] = {}
    for path in paths:
        merged.update({name: p.value for name, p in parse_ssv(Path(path)).items()})
    return merged
