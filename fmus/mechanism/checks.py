"""Checks of a parameter set as data: a description's own checks beyond its parameters' ranges and its bodies.

The Python model makes them in its own code (``kinematics.Geometry.checked``, ``designs.describe``) with the
messages these rows hold; the native mechanism runs the same rows (mast.core.native.models writes them as tables,
fmus/common/native/mast_mechanism.c checks them), so both give the same words (tests/test_native.py).
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["Check"]


@dataclass(frozen=True)
class Check:
    """One check of a parameter set. Expressions are in the description files' subset of their parameters.

    ``kind``: "less" (``operands[0] < operands[1]``) or "assembles" (the mechanism assembles at its cold start for
    every joint at 0: its inverse kinematics admits that pose; ``regular``: with an invertible Jacobian too);
    ``when``: (expression, "zero" | "nonzero"): the check applies when the expression is (not) 0, ("", "") always;
    ``message``: its text, one ``{}`` per ``shown`` expression (their values as Python writes floats, ``repr``),
    and for "assembles" a last ``{}``: why the pose is refused."""

    kind: str
    message: str
    shown: tuple[str, ...]
    operands: tuple[str, ...] = ()
    when: tuple[str, str] = ("", "")
    regular: bool = False
