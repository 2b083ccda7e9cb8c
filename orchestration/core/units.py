"""Units of parameter values: parse a unit string, convert between compatible units.

A unit is a factor and offset onto the coherent SI unit of its dimension, and the exponents
of the SSP/FMI base units (``kg m s A K mol cd rad``, SSP 1.0 ``ssc:BaseUnit``):
value_SI = factor * value + offset. Unit strings follow the notation of the project's .ssv
files and of FMI unit names: products with ``.`` (or a space, ``*``), one or more ``/``,
parentheses, integer exponents written after the symbol (``kg.m2``, ``m/s2``, ``V/(A.s)``,
``s-1``, ``m^2``), SI prefixes (``mm``, ``um``, ``mN.m``, ``g.cm2``) and a few non-SI units
(``deg``, ``min``, ``h``, ``rpm``). An .ssv file may define its own units (``ssv:Units``);
those take precedence over the notation.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Mapping, Optional

BASE = ("kg", "m", "s", "A", "K", "mol", "cd", "rad")


class UnitError(ValueError):
    """A unit string that cannot be read, or two units of different dimensions."""


@dataclass(frozen=True)
class Unit:
    """value_SI = factor * value + offset; ``dims``: exponents of ``BASE``."""

    factor: float = 1.0
    dims: tuple[int, ...] = (0,) * len(BASE)
    offset: float = 0.0

    def __mul__(self, other: "Unit") -> "Unit":
        return Unit(self.factor * other.factor, tuple(a + b for a, b in zip(self.dims, other.dims)))

    def __pow__(self, n: int) -> "Unit":
        return Unit(self.factor**n, tuple(a * n for a in self.dims))

    def dimension(self) -> str:
        text = ".".join(f"{b}{e if e != 1 else ''}" for b, e in zip(BASE, self.dims) if e)
        return text or "1"


def _u(factor: float = 1.0, **exponents: int) -> Unit:
    return Unit(factor, tuple(exponents.get(b, 0) for b in BASE))


#: symbols without prefix (g is the gram: kg is k + g)
SYMBOLS: dict[str, Unit] = {
    "1": _u(),
    "m": _u(m=1),
    "g": _u(1e-3, kg=1),
    "s": _u(s=1),
    "A": _u(A=1),
    "K": _u(K=1),
    "mol": _u(mol=1),
    "cd": _u(cd=1),
    "rad": _u(rad=1),
    "N": _u(kg=1, m=1, s=-2),
    "J": _u(kg=1, m=2, s=-2),
    "W": _u(kg=1, m=2, s=-3),
    "V": _u(kg=1, m=2, s=-3, A=-1),
    "ohm": _u(kg=1, m=2, s=-3, A=-2),
    "Ohm": _u(kg=1, m=2, s=-3, A=-2),
    "\u03a9": _u(kg=1, m=2, s=-3, A=-2),
    "H": _u(kg=1, m=2, s=-2, A=-2),
    "F": _u(kg=-1, m=-2, s=4, A=2),
    "C": _u(A=1, s=1),
    "Wb": _u(kg=1, m=2, s=-2, A=-1),
    "T": _u(kg=1, s=-2, A=-1),
    "Pa": _u(kg=1, m=-1, s=-2),
    "Hz": _u(s=-1),
    "deg": _u(math.pi / 180.0, rad=1),
    "min": _u(60.0, s=1),
    "h": _u(3600.0, s=1),
    "rpm": _u(2.0 * math.pi / 60.0, rad=1, s=-1),
    "l": _u(1e-3, m=3),
    "L": _u(1e-3, m=3),
}
PREFIXES = {
    "T": 1e12,
    "G": 1e9,
    "M": 1e6,
    "k": 1e3,
    "h": 1e2,
    "da": 1e1,
    "d": 1e-1,
    "c": 1e-2,
    "m": 1e-3,
    "u": 1e-6,
    "\u00b5": 1e-6,
    "\u03bc": 1e-6,
    "n": 1e-9,
    "p": 1e-12,
}
_PREFIXABLE = {
    "m",
    "g",
    "s",
    "A",
    "K",
    "mol",
    "cd",
    "rad",
    "N",
    "J",
    "W",
    "V",
    "ohm",
    "Ohm",
    "\u03a9",
    "H",
    "F",
    "C",
    "Wb",
    "T",
    "Pa",
    "Hz",
    "l",
    "L",
}
_TOKEN = re.compile(
    r"(?P<open>\()|(?P<close>\))|(?P<op>[./*\u00b7])"
    r"|(?P<atom>[A-Za-z\u00b5\u03bc\u03a9]+|1)(?:\^?(?P<exp>[+-]?\d+))?"
)


def _symbol(text: str, unit: str) -> Unit:
    if text in SYMBOLS:
        return SYMBOLS[text]
    for prefix, factor in PREFIXES.items():
        rest = text[len(prefix) :]
        if text.startswith(prefix) and rest in _PREFIXABLE:
            return Unit(factor * SYMBOLS[rest].factor, SYMBOLS[rest].dims)
    raise UnitError(f"unit '{unit}': '{text}' is not a known unit symbol")


def parse_unit(text: str, defined: Optional[Mapping[str, Unit]] = None) -> Unit:
    """The Unit of ``text`` (``defined``: an .ssv file's own unit definitions, by name)."""
    if defined and text in defined:
        return defined[text]
    tokens, pos = [], 0
    text_s = re.sub(r"\s+", ".", text.strip())  # "N m" is N.m
    while pos < len(text_s):
        match = _TOKEN.match(text_s, pos)
        if not match or match.end() == pos:
            raise UnitError(f"unit '{text}': cannot read it at '{text_s[pos:]}'")
        tokens.append(match)
        pos = match.end()
    if not tokens:
        raise UnitError("an empty unit")
    k = 0

    def product() -> Unit:  # factor (('.' | '/') factor)*
        nonlocal k
        result = factor()
        while k < len(tokens) and tokens[k].group("op"):
            op = tokens[k].group("op")
            k += 1
            right = factor()
            result = result * (right**-1 if op == "/" else right)
        return result

    def factor() -> Unit:
        nonlocal k
        if k >= len(tokens):
            raise UnitError(f"unit '{text}': ends where a unit symbol is expected")
        tok = tokens[k]
        k += 1
        if tok.group("open"):
            inner = product()
            if k >= len(tokens) or not tokens[k].group("close"):
                raise UnitError(f"unit '{text}': a '(' is not closed")
            k += 1
            return inner
        if not tok.group("atom"):
            raise UnitError(f"unit '{text}': '{tok.group(0).strip()}' where a unit symbol is expected")
        unit = _symbol(tok.group("atom"), text)
        return unit ** int(tok.group("exp")) if tok.group("exp") else unit

    unit = product()
    if k != len(tokens):
        raise UnitError(f"unit '{text}': unexpected '{tokens[k].group(0).strip()}'")
    return unit


def convert(value: float, source: Unit, target: Unit) -> float:
    """``value`` in ``source`` expressed in ``target``; UnitError if their dimensions differ."""
    if source.dims != target.dims:
        raise UnitError(f"dimension {source.dimension()} is not {target.dimension()}")
    return ((source.factor * value + source.offset) - target.offset) / target.factor
