"""The drive's current loop around one axis (paper Fig. 2 draws it inside the actuator).

``DriveActuatorBlock`` is ``ActuatorBlock`` (model.py, voltage in) with the servo drive's sampled PI
current loop in front of it: current command ``i_cmd`` [A] and force ``F`` [N] in, the axis' outputs
and the voltage ``u`` [V] the loop applies out. Every ``T_cur`` (tick k at t_k = t0 + k T_cur):

    e   = i_cmd - i_m(t_k)
    v   = k_pc e + x_c
    u_k = sat(v, u_max)
    x_c <- x_c + k_ic T_cur e     unless saturated and e pushes further into the limit

and u_k is applied over [t_(k+1), t_(k+2)]: one ``T_cur`` of computation delay, as in a real drive
(and as when the loop ran in the controller FMU with a 100 us exchange). A communication step
h = m T_cur runs m ticks with ``i_cmd`` and ``F`` held; the axis steps T_cur at a time, so the
voltage is a 100 us zero-order hold whatever h is. ``u`` after a step is the voltage applied from
that communication point on (computed at the last tick), before the power stage's clip to
+-u_supply (ActuatorBlock).
"""

from __future__ import annotations

import math
from typing import Mapping

from ..common.block import Block, ModelError
from ..common.parameters import Value, nonnegative, positive
from .model import ActuatorBlock


def pi_step(e: float, x: float, k_p: float, k_iT: float, limit: float, offset: float = 0.0) -> tuple[float, float]:
    """One forward-Euler PI update with output limit and conditional integration.

    ``e`` error, ``x`` integrator state (in output units), ``k_p`` proportional
    gain, ``k_iT`` integral gain times the loop's cycle time, ``limit`` the
    symmetric output limit, ``offset`` a feed-forward added to the output before
    the limit. Returns (output, new state): while the output is saturated, the
    integrator only moves when the error drives it back out of the limit
    (anti-windup).
    """
    v = k_p * e + x + offset
    if v > limit:
        return limit, (x + k_iT * e if e < 0.0 else x)
    if v < -limit:
        return -limit, (x + k_iT * e if e > 0.0 else x)
    return v, x + k_iT * e


def current_gains(k_pc: float, k_ic: float, T_cur: float, u_max: float) -> tuple[float, float, float]:
    """The current loop's constants: (k_pc [V/A], k_ic T_cur [V/A], u_max [V]).

    Written in the generated-code subset: the native FMU computes them at initialisation from its
    parameters with this source (mast.core.native.models translates it)."""
    return (k_pc, k_ic * T_cur, u_max)


#: the drive's current loop (ssp/resources/drive.ssv)
CURRENT_LOOP_PARAMETERS = (
    nonnegative("k_pc", "V/A", "Current PI proportional gain: voltage per current error"),
    nonnegative("k_ic", "V/(A.s)", "Current PI integral gain"),
    positive("T_cur", "s", "Current loop cycle time (the block's tick)"),
    positive("u_max", "V", "Voltage command limit (symmetric)"),
)
_LOOP = tuple(p.name for p in CURRENT_LOOP_PARAMETERS)
#: where the axis' output i_m stands among its values
I_M = len(ActuatorBlock.INPUTS) + ActuatorBlock.OUTPUTS.index("i_m")


class DriveActuatorBlock(Block):
    """One MAST linear axis with its drive's PI current loop: current command in (module docstring)."""

    INPUTS = ("i_cmd", "F", "M_carried")
    OUTPUTS = (*ActuatorBlock.OUTPUTS, "u")
    PARAMETERS = (*ActuatorBlock.PARAMETERS, *CURRENT_LOOP_PARAMETERS)
    CYCLE_TIME = "T_cur"
    UNITS = {**{k: v for k, v in ActuatorBlock.UNITS.items() if k != "u"}, "i_cmd": "A", "u": "V"}
    DESCRIPTIONS = {
        **{k: v for k, v in ActuatorBlock.DESCRIPTIONS.items() if k != "u"},
        "i_cmd": "current command from the controller (the drive's current loop follows it every T_cur)",
        "u": "voltage the current loop applies from this communication point on (computed at the last "
        "T_cur tick; before the power stage's clip to +-u_supply)",
    }

    def __init__(self, params: Mapping[str, Value], name: str = "") -> None:
        super().__init__(params, name)
        P = self.params
        #: the voltage-driven axis the loop drives (its values: u, F, then the outputs)
        self.axis = ActuatorBlock({k: v for k, v in P.items() if k not in _LOOP}, self.name)
        self.T_cur = float(P["T_cur"])
        self._gains = current_gains(float(P["k_pc"]), float(P["k_ic"]), self.T_cur, float(P["u_max"]))
        self._x_c = 0.0  # integrator state [V]
        self._u = 0.0  # voltage applied over the next T_cur [V]
        #: (the step size do_step checked last, its ticks of T_cur, the axis' state and ticks function: ``_prepare``)
        self._step_ticks: tuple = (math.nan, 0, None, None)

    def initialize(self, t0: float) -> None:
        """At rest, no voltage applied yet; the outputs from the axis' state and the inputs."""
        self._check(t0)
        self._x_c, self._u = 0.0, 0.0
        self._step_ticks = (math.nan, 0, None, None)  # the axis' state is a new list
        axis = self.axis.values
        axis[0], axis[1], axis[2] = 0.0, self.values[1], self.values[2]
        self.axis.initialize(t0)
        self._publish()

    def do_step(self, t: float, h: float) -> None:
        """m = h / T_cur ticks of the current loop, each followed by the axis' step over T_cur."""
        T = self.T_cur
        if h != self._step_ticks[0]:  # checked once per step size
            self._prepare(h)
        _, m, x, ticks = self._step_ticks
        values, block = self.values, self.axis
        axis = block.values
        i_cmd = values[0]
        if i_cmd - i_cmd != 0.0:  # NaN or inf
            self._check(t)
        axis[1], axis[2] = values[1], values[2]  # F and M_carried, held over the ticks (the kernel only reads them)
        kp, kiT, u_max = self._gains
        x_c, u = self._x_c, self._u
        if ticks is not None:  # the loop below in one generated function (the same arithmetic)
            code, _, x_c_end, u_end = ticks(axis, x, m, i_cmd, x_c, u, kp, kiT, u_max)
            if not code:
                self._x_c = x_c_end
                self._u = u_end
                values[3:] = [*axis[3:], u_end]  # _publish
                if not block.condenses(h):
                    values[ActuatorBlock.M_DRIVE] = 0.0
                return
            # it failed and wrote nothing: the loop below fails at the same tick, with the model's message
        kernel, x, sensor = block.stepper(T)  # the axis' do_step(t_k, T), without a call per tick
        for k in range(m):
            u_next, x_c = pi_step(i_cmd - axis[I_M], x_c, kp, kiT, u_max)  # i_m at this tick
            axis[0] = u
            code = kernel(axis, x)
            if code:
                self.axis.fail(code, t + k * T, T)
            if sensor is not None:
                axis[ActuatorBlock.TAU_MEAS] = sensor.step(axis[ActuatorBlock.TAU_M], T)
            u = u_next
        self._x_c, self._u = x_c, u
        self._publish()
        if not block.condenses(h):
            values[ActuatorBlock.M_DRIVE] = 0.0

    def _prepare(self, h: float) -> None:
        """Check the step size h [s] (a multiple m of T_cur) and keep, until the next ``initialize`` or step of
        another size, (h, m, the axis' state, its ticks function or None: ``ActuatorBlock.stepper``, ``ticks``)."""
        T = self.T_cur
        m = round(h / T)
        if m < 1 or abs(h - m * T) > 1e-6 * T:
            raise ModelError(
                f"{self.name}: step size h = {h!r} s is not a positive integer multiple of T_cur = {T!r} s"
            )
        _, x, _ = self.axis.stepper(T)
        self._step_ticks = (h, m, x, self.axis.ticks(T, pi_step))

    def _check(self, t: float) -> None:
        i_cmd = self.values[0]
        if not math.isfinite(i_cmd):
            raise ModelError(f"{self.name}: input 'i_cmd' = {i_cmd} at t={t:.9g} s is not finite")

    def _publish(self) -> None:
        self.values[3:] = [*self.axis.values[3:], self._u]
