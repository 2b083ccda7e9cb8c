"""Parameter schema: names, units, admissible ranges and validation.

The *values* of parameters never live in code: they live in the SSP parameter
sets (``ssp/parameters/*.ssv``) with their unit and source. Code only declares
what a model accepts, so that a wrong name or an out-of-range value is rejected
with a message that names it.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass
from typing import Mapping, Sequence, Union

Value = Union[float, int, str]


class ParameterError(ValueError):
    """A parameter is unknown, missing, of the wrong type or out of range."""


#: the range of an FMI Integer (fmi2Integer, fmi3Int32): a larger value would wrap around in the C call
INT32_MIN, INT32_MAX = -(2**31), 2**31 - 1


def exact_integer(value: object) -> int:
    """``value`` as an int if it is a whole number (2, 2.0, "2", "2e0") within the FMI Integer range.

    Every route (FMI, direct, .ssv, --set, batch) goes through this: 2.5 is refused, never truncated.
    Raises ValueError (the caller names the parameter).
    """
    if isinstance(value, bool):
        return int(value)
    if isinstance(value, numbers.Integral):
        number = int(value)
    else:
        try:
            text = value.strip() if isinstance(value, str) else value
            number = int(text) if isinstance(text, str) and text.lstrip("+-").isdigit() else float(text)
        except (TypeError, ValueError):
            raise ValueError(f"{value!r} is not a number") from None
        if isinstance(number, float):
            if not math.isfinite(number) or not number.is_integer():
                raise ValueError(f"{value!r} is not a whole number")
            number = int(number)
    if not INT32_MIN <= number <= INT32_MAX:
        raise ValueError(f"{value!r} is outside the integer range [{INT32_MIN}, {INT32_MAX}]")
    return number


def exact_string(value: object) -> str:
    """``value`` as a String parameter: a string, or a number written as its exact text (``--set`` gives
    ``J_chain=0.001`` as a number); a boolean or anything else is refused."""
    if isinstance(value, str):
        return value
    if isinstance(value, numbers.Real) and not isinstance(value, bool):
        return repr(float(value)) if not isinstance(value, numbers.Integral) else str(int(value))
    raise ValueError(f"{value!r} is not a string")


def exact_boolean(value: object) -> bool:
    """``value`` as a bool if it is one: True/False, 1/0 (also 1.0) or the strings true/false/1/0."""
    if isinstance(value, bool):
        return value
    if isinstance(value, str):
        text = value.strip().lower()
        if text in ("true", "1"):
            return True
        if text in ("false", "0"):
            return False
    elif isinstance(value, (int, float)) and value in (0, 1):
        return bool(value)
    raise ValueError(f"{value!r} is not a boolean (true/false or 1/0)")


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
            try:
                return exact_string(value)
            except ValueError:
                raise ParameterError(
                    f"{where}parameter '{self.name}' = {value!r}: expected {self.expected()}"
                ) from None
        try:
            number = exact_integer(value) if self.kind is int else float(value)
        except (TypeError, ValueError, OverflowError):
            raise ParameterError(f"{where}parameter '{self.name}' = {value!r}: expected {self.expected()}") from None
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
            f"{where}unknown parameter(s) {', '.join(unknown)}; expected names: {', '.join(sorted(by_name))}"
        )
    missing = sorted(set(by_name) - set(values))
    if missing:
        raise ParameterError(f"{where}missing parameter(s) {', '.join(missing)}")
    return {name: by_name[name].check(values[name], owner) for name in by_name}
