"""Parameter schema: names, units, admissible ranges and validation.

The *values* of parameters never live in code: they live in the SSP parameter
sets (``ssp/parameters/*.ssv``) with their unit and source. Code only declares
what a model accepts, so that a wrong name or an out-of-range value is rejected
with a message that names it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping, Sequence, Union

Value = Union[float, int, str]


class ParameterError(ValueError):
    """A parameter is unknown, missing, of the wrong type or out of range."""


@dataclass(frozen=True)
class Param:
    """Declaration of one model parameter.

    ``minimum``/``maximum`` bound the value; ``exclusive`` makes both bounds
    strict (use it for quantities that must be strictly positive).
    ``kind`` is ``float``, ``int`` or ``str``.
    """

    name: str
    unit: str
    description: str
    minimum: float = -math.inf
    maximum: float = math.inf
    exclusive: bool = False
    kind: type = float

    def expected(self) -> str:
        if self.kind is str:
            return "a string"
        lo, hi = ("(", ")") if self.exclusive else ("[", "]")
        return f"a {self.kind.__name__} in {lo}{self.minimum:g}, {self.maximum:g}{hi} {self.unit}".rstrip()

    def check(self, value: Value, owner: str = "") -> Value:
        """Return ``value`` converted to ``kind``; raise ParameterError if inadmissible."""
        where = f"{owner}: " if owner else ""
        if self.kind is str:
            if not isinstance(value, str):
                raise ParameterError(f"{where}parameter '{self.name}' = {value!r}: expected {self.expected()}")
            return value
        try:
            number = float(value)
        except (TypeError, ValueError):
            raise ParameterError(f"{where}parameter '{self.name}' = {value!r}: expected {self.expected()}") from None
        if self.kind is int:
            if number != int(number):
                raise ParameterError(f"{where}parameter '{self.name}' = {value!r}: expected {self.expected()}")
            number = int(number)
        if not math.isfinite(number):
            raise ParameterError(f"{where}parameter '{self.name}' = {value!r}: expected a finite number")
        low_bad = number <= self.minimum if self.exclusive else number < self.minimum
        high_bad = number >= self.maximum if self.exclusive else number > self.maximum
        if low_bad or high_bad:
            raise ParameterError(f"{where}parameter '{self.name}' = {value!r}: expected {self.expected()}")
        return number


def positive(name: str, unit: str, description: str) -> Param:
    """A parameter that must be strictly positive (lengths, resistances, cycle times ...)."""
    return Param(name, unit, description, minimum=0.0, exclusive=True)


def nonnegative(name: str, unit: str, description: str) -> Param:
    """A parameter that may be zero but not negative (gains, optional inertias ...)."""
    return Param(name, unit, description, minimum=0.0)


def validate(specs: Sequence[Param], values: Mapping[str, Value], owner: str = "") -> dict[str, Value]:
    """Check a complete parameter set against its schema.

    Every declared parameter must be present, no undeclared name may appear,
    and each value must be admissible. Returns the converted values.
    """
    where = f"{owner}: " if owner else ""
    by_name = {p.name: p for p in specs}
    unknown = sorted(set(values) - set(by_name))
    if unknown:
        raise ParameterError(
            f"{where}unknown parameter(s) {', '.join(unknown)}; expected names: {', '.join(sorted(by_name))}")
    missing = sorted(set(by_name) - set(values))
    if missing:
        raise ParameterError(f"{where}missing parameter(s) {', '.join(missing)}")
    return {name: by_name[name].check(values[name], owner) for name in by_name}
