"""A drive axis in its load-side, force-driven form: the model of a single-axis test bench.

For a bench whose drive reports the force it applies (a current-controlled motor behind
a ball screw, such as the EMPS benchmark: force = g_tau * drive command), the motor, the
screw and the load are one rigid body seen from the load:

    M q'' = F - F_f(q') - F_offset

q [m] load position, F [N] the drive force (input), M [kg] the moving mass (load and the
motor's inertia reflected through the screw), F_offset [N] a constant force (a bias of the
drive or a cable), and the friction

    F_f(v) = (F_c + dF_c sign v) sign v + (F_v + dF_v sign v) v

Coulomb F_c and viscous F_v, with the asymmetries dF_c, dF_v: for positive velocity the
coefficients are F_c + dF_c, F_v + dF_v, for negative F_c - dF_c, F_v - dF_v (real screws
and guides differ by direction). Neutral defaults: every friction term and the offset 0.

This is the benchmark's own inverse model (tau = M q'' + F_v q' + F_c sign(q') + offset).
The MAST actuator (``model.py``) is the electrical and torsional model of a motor behind a
gearbox and a belt with a smoothed friction at the motor shaft: a different description of
a drive, whose kernel does not take a force command.

Integration (``step``): n_sub equal substeps per step (substeps of at most ``h_max``),
implicit (backward) Euler in the velocity with the set-valued sign: the velocity at the end
of a substep v1 = a - b F_f(v1), a = v0 + b (F - F_offset), b = h/M, is

    a >  b F_c+  :  v1 = (a - b F_c+) / (1 + b F_v+)
    a < -b F_c-  :  v1 = (a + b F_c-) / (1 + b F_v-)
    otherwise    :  v1 = 0 (the axis sticks: the drive force is below the friction)

(the time-stepping of set-valued friction: no chatter at rest, no smoothing speed to
choose), the position by the trapezoidal rule q1 = q0 + h (v0 + v1) / 2.
"""

from __future__ import annotations

import math
from typing import Mapping

import numpy as np

from ..common.block import Block, ModelError
from ..common.parameters import Param, ParameterError, Value, nonnegative, positive

__all__ = ["LoadAxisBlock", "load_friction", "LOAD_AXIS_PARAMETERS"]

LOAD_AXIS_PARAMETERS: tuple[Param, ...] = (
    positive("M", "kg", "moving mass seen from the load (load plus motor and screw inertia reflected)"),
    nonnegative("F_c", "N", "Coulomb friction (mean of the two directions)"),
    nonnegative("F_v", "N.s/m", "viscous friction (mean of the two directions)"),
    Param(
        "dF_c",
        "N",
        "Coulomb friction asymmetry: F_c + dF_c for positive velocity, F_c - dF_c for negative (0: symmetric)",
    ),
    Param(
        "dF_v",
        "N.s/m",
        "viscous friction asymmetry: F_v + dF_v for positive velocity, F_v - dF_v for negative (0: symmetric)",
    ),
    Param("F_offset", "N", "constant force against the drive: M q'' = F - F_f(q') - F_offset (0: none)"),
    Param("q_0", "m", "initial position (at rest)"),
    positive("h_max", "s", "longest integration substep"),
)


def load_friction(v: np.ndarray, F_c: float, F_v: float, dF_c: float = 0.0, dF_v: float = 0.0) -> np.ndarray:
    """F_f(v) [N] of the module docstring at velocities ``v`` [m/s] (sign(0) = 0)."""
    s = np.sign(v)
    return (F_c + dF_c * s) * s + (F_v + dF_v * s) * v


class LoadAxisBlock(Block):
    """Rigid drive axis seen from the load: mass, asymmetric Coulomb and viscous friction, offset."""

    INPUTS = ("F",)
    OUTPUTS = ("q", "q_dot", "F_friction")
    PARAMETERS = LOAD_AXIS_PARAMETERS
    UNITS = {"F": "N", "q": "m", "q_dot": "m/s", "F_friction": "N"}
    DESCRIPTIONS = {
        "F": "drive force on the load",
        "q": "load position",
        "q_dot": "load velocity",
        "F_friction": "friction force over the last substep (F_f(q_dot))",
    }

    def __init__(self, params: Mapping[str, Value], name: str = "") -> None:
        super().__init__(params, name)
        p = self.params
        for side, sign in (("positive", 1.0), ("negative", -1.0)):
            for mean, delta in (("F_c", "dF_c"), ("F_v", "dF_v")):
                if p[mean] + sign * p[delta] < 0.0:
                    raise ParameterError(
                        f"{self.name}: parameter '{delta}' = {p[delta]!r}: the {side}-velocity "
                        f"coefficient {mean} {'+' if sign > 0 else '-'} {delta} would be negative "
                        f"({mean} = {p[mean]!r})"
                    )
        self._q = self._v = self._ff = 0.0
        self._steps: dict = {}

    def initialize(self, t0: float) -> None:
        self._q, self._v, self._ff = float(self.params["q_0"]), 0.0, 0.0
        self._write()

    def _write(self) -> None:
        self.values[1:] = [self._q, self._v, self._ff]

    def _constants(self, h: float) -> tuple:
        """Per step size: (substeps, substep, b, F_c+, F_c-, 1 + b F_v+, 1 + b F_v-) of the module docstring."""
        if h not in self._steps:
            p = self.params
            n = max(1, math.ceil(h / p["h_max"] - 1e-9))
            hs = h / n
            b = hs / p["M"]
            self._steps[h] = (
                n,
                hs,
                b,
                p["F_c"] + p["dF_c"],
                p["F_c"] - p["dF_c"],
                1.0 + b * (p["F_v"] + p["dF_v"]),
                1.0 + b * (p["F_v"] - p["dF_v"]),
            )
        return self._steps[h]

    def do_step(self, t: float, h: float) -> None:
        F = self.values[0]
        if not math.isfinite(F):
            raise ModelError(f"{self.name} at t={t:.6g} s: input F = {F!r} is not finite")
        n, hs, b, c_pos, c_neg, v_pos, v_neg = self._constants(h)
        push = b * (F - self.params["F_offset"])
        q, v = self._q, self._v
        a = v + push
        for _ in range(n):
            a = v + push
            if a > b * c_pos:
                v1 = (a - b * c_pos) / v_pos
            elif a < -b * c_neg:
                v1 = (a + b * c_neg) / v_neg
            else:
                v1 = 0.0
            q += 0.5 * hs * (v + v1)
            v = v1
        self._ff = (a - v) / b
        self._q, self._v = q, v
        self.values[1] = q
        self.values[2] = v
        self.values[3] = self._ff

    def get_state(self) -> object:
        return (list(self.values), self._q, self._v, self._ff)

    def set_state(self, state: object) -> None:
        values, self._q, self._v, self._ff = state
        self.values[:] = values
