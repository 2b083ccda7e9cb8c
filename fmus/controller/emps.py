"""The EMPS drive controller: P position loop into a P velocity loop, sampled (Janot et al. 2019).

At every sample k (period T_s, 1 ms on the EMPS dSPACE system):

    qf(k)   = 0.5 q_m(k) + 0.5 q_m(k-1)                      FIR filter of the encoder position
    qd(k)   = (qf(k) - qf(k-1)) / T_s                        velocity estimate
    v(k)    = k_p k_v (q_ref(k) - q_m(k)) - k_v qd(k)        P position loop into a P velocity loop
    u_s(k)  = clip(v(k), -u_max, u_max)                      the controller's output after the saturation
    u       = u_s(k) + u_inj                                 the drive command applied (vir in the EMPS logs)
    F       = g_tau u                                        the drive force on the load

u_inj [V] is a known input a lab adds to the drive command after the saturation
(excitation pulses); 0 in normal operation. A drive logs what it applies, u and F (the
"applied" tap of a record, docs/measured-data.md); the controller's output before the
injection is published too, as u_before_injection = u_s and F_before_injection = g_tau u_s,
for a lab that logs it there. The filter starts at rest at ``q_0``.

Timing: the block ticks with its step h (T_s a whole multiple of h); at the first tick of a
sample it reads q_ref, q_m and computes u(k), which is its output after that tick. A master
stepping the block and the axis at h therefore applies u(k) from t_k + h on: h is the
controller's computation delay (one tick), and the force is a zero-order hold over the
rest of the sample (with h = T_s the delay is a whole sample).
"""

from __future__ import annotations

import math
from typing import Mapping

from ..common.block import Block, ModelError
from ..common.parameters import Param, ParameterError, Value, nonnegative, positive

EMPS_PARAMETERS = (
    nonnegative("k_p", "1/s", "position loop gain"),
    nonnegative("k_v", "V.s/m", "velocity loop gain: drive command per velocity error"),
    positive("g_tau", "N/V", "drive gain: force per volt of drive command"),
    positive("u_max", "V", "drive command saturation (symmetric)"),
    positive("T_s", "s", "sampling period of the controller (a whole multiple of the block's step)"),
    Param("q_0", "m", "position at the start (the velocity filter starts at rest there)"),
)


class EmpsController(Block):
    """Sampled P-P cascade of a single drive axis with FIR velocity estimate and saturation (module docstring)."""

    INPUTS = ("q_ref", "q_m", "u_inj")
    OUTPUTS = ("u", "F", "u_before_injection", "F_before_injection", "q_dot_est")
    PARAMETERS = EMPS_PARAMETERS
    CYCLE_TIME = "T_s"
    UNITS = {
        "q_ref": "m",
        "q_m": "m",
        "u_inj": "V",
        "u": "V",
        "F": "N",
        "u_before_injection": "V",
        "F_before_injection": "N",
        "q_dot_est": "m/s",
    }
    DESCRIPTIONS = {
        "q_ref": "reference position",
        "q_m": "measured position (encoder, load side)",
        "u_inj": "known input added to the drive command after the saturation (excitation pulses; 0: none)",
        "u": "drive command applied: the controller's output after the saturation plus u_inj (the EMPS logs it as vir)",
        "F": "drive force on the load, g_tau u (the logged effort: gtau vir)",
        "u_before_injection": "the controller's output after the saturation, before u_inj is added",
        "F_before_injection": "the controller's force command before u_inj is added, g_tau u_before_injection",
        "q_dot_est": "velocity estimate from the filtered encoder difference",
    }

    def __init__(self, params: Mapping[str, Value], name: str = "") -> None:
        super().__init__(params, name)
        self._per_sample: dict = {}
        self._tick = 0
        self._q_prev = self._qf_prev = 0.0
        self._u = self._qd = 0.0

    def initialize(self, t0: float) -> None:
        q0 = float(self.params["q_0"])
        self._tick = 0
        self._q_prev = self._qf_prev = q0
        self._u = self._qd = 0.0
        self._write()

    def _write(self) -> None:
        g = self.params["g_tau"]
        u_inj = self.values[2]
        if not math.isfinite(u_inj):
            raise ModelError(f"{self.name}: non-finite input u_inj={u_inj!r}")
        u = self._u + u_inj
        self.values[3:] = [u, g * u, self._u, g * self._u, self._qd]

    def _ticks(self, h: float) -> int:
        """Block steps per sample (T_s a whole multiple of the step ``h``)."""
        if h not in self._per_sample:
            ratio = self.params["T_s"] / h
            m = round(ratio)
            if m < 1 or abs(ratio - m) > 1e-9 * ratio:
                raise ParameterError(
                    f"{self.name}: parameter 'T_s' = {self.params['T_s']!r} s: expected a whole "
                    f"multiple of the step {h!r} s"
                )
            self._per_sample[h] = m
        return self._per_sample[h]

    def do_step(self, t: float, h: float) -> None:
        values = self.values
        if self._tick % self._ticks(h) == 0:
            p = self.params
            q_ref, q_m = values[0], values[1]
            if not (math.isfinite(q_ref) and math.isfinite(q_m)):
                raise ModelError(f"{self.name} at t={t:.6g} s: non-finite input (q_ref={q_ref!r}, q_m={q_m!r})")
            qf = 0.5 * q_m + 0.5 * self._q_prev
            self._qd = (qf - self._qf_prev) / p["T_s"]
            self._q_prev, self._qf_prev = q_m, qf
            v = p["k_p"] * p["k_v"] * (q_ref - q_m) - p["k_v"] * self._qd
            self._u = min(p["u_max"], max(-p["u_max"], v))
            self._tick += 1
            self._write()
            return
        self._tick += 1
        u_inj = values[2]
        if not math.isfinite(u_inj):
            raise ModelError(f"{self.name} at t={t:.6g} s: non-finite input u_inj={u_inj!r}")
        u = self._u + u_inj
        values[3], values[4] = u, self.params["g_tau"] * u

    def get_state(self) -> object:
        return (list(self.values), self._tick, self._q_prev, self._qf_prev, self._u, self._qd)

    def set_state(self, state: object) -> None:
        values, self._tick, self._q_prev, self._qf_prev, self._u, self._qd = state
        self.values[:] = values
