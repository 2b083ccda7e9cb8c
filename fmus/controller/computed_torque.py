"""Computed torque control (paper Fig. 3b) on the drive's current loop.

Per velocity tick (T_vel), with the joint reference (rho_ref = rho_cmd and its velocity
and acceleration from reference.py, updated every T_pos) and the measurements
(rho from the linear encoders, rho_dot = i_R omega_m from the motor encoders):

    e = rho_ref - rho,  e_dot = rho_dot_ref - rho_dot
    a = rho_ddot_ref + K_D e_dot + K_P e          K_P = omega_n^2, K_D = 2 zeta omega_n
    i_cmd = sat(tau_model(rho, rho_dot, a) / k_T, i_max)

tau_model is the controller's inverse dynamic model of actuators and mechanism
(inverse_model.py), evaluated at the measured state. If it is exact, the current loop
follows and nothing saturates, every joint error obeys e'' + 2 zeta omega_n e' + omega_n^2 e = 0:
decoupled second-order error dynamics with the chosen poles, whatever the load; a model
error (an unknown payload) shows as a forcing term, with a steady offset under gravity
(there is no integral action). There is no velocity loop: the drive runs this law at the
velocity cycle, so the controller has no "velocity" mode; omega_cmd reports the reference
speed rho_dot_ref / i_R.
"""
from __future__ import annotations

from typing import Mapping

from ..common.parameters import Value, nonnegative, positive
from .inverse_model import MODEL_PARAMETERS, InverseModel
from .model import DRIVE_PARAMETERS, DriveController

COMPUTED_TORQUE_PARAMETERS = (
    positive("omega_n", "rad/s", "Natural frequency of the joint error dynamics"),
    nonnegative("zeta", "1", "Damping ratio of the joint error dynamics"),
)


def error_gains(omega_n: float, zeta: float) -> tuple[float, float]:
    """(K_P = omega_n^2 [1/s^2], K_D = 2 zeta omega_n [1/s]). Written in the generated-code subset: the
    native FMU computes them at initialisation with this source."""
    return (omega_n * omega_n, 2.0 * zeta * omega_n)


def commanded_acceleration(rho_ddot_ref: float, rho_dot_ref: float, rho_dot: float, rho_ref: float, rho: float,
                           K_P: float, K_D: float) -> float:
    """a = rho_ddot_ref + K_D (rho_dot_ref - rho_dot) + K_P (rho_ref - rho) [m/s^2], one axis: the joint
    acceleration the inverse model is asked for. Written in the generated-code subset, as ``error_gains``."""
    return rho_ddot_ref + K_D * (rho_dot_ref - rho_dot) + K_P * (rho_ref - rho)


def limited(i: float, i_max: float) -> float:
    """i clipped to [-i_max, i_max] [A]. Written in the generated-code subset, as ``error_gains``."""
    return i_max if i > i_max else (-i_max if i < -i_max else i)


class ComputedTorqueController(DriveController):
    """Computed torque control of the three axes with the controller's own inverse dynamic model."""

    PARAMETERS = (*DRIVE_PARAMETERS, *MODEL_PARAMETERS, *COMPUTED_TORQUE_PARAMETERS)
    REFERENCE_RATES = True
    MODES = ("pose", "joint", "current")
    DESCRIPTIONS = {**DriveController.DESCRIPTIONS,
                    **{f"omega_cmd_{j}": f"Reference speed of motor {j} (rho_dot_ref / i_R; no velocity loop)"
                       for j in (1, 2, 3)},
                    **{f"i_cmd_{j}": f"Current command of axis {j} (computed torque / k_T)" for j in (1, 2, 3)}}

    def __init__(self, params: Mapping[str, Value], name: str = "") -> None:
        super().__init__(params, name)
        self.model = InverseModel(self.params, self.name)
        self.K_P, self.K_D = error_gains(float(self.params["omega_n"]), float(self.params["zeta"]))

    def _law_state(self) -> tuple:
        return (*super()._law_state(), self.model.warm_start)

    def _set_law_state(self, state: tuple) -> None:
        super()._set_law_state(state)
        self.model.warm_start = state[-1]

    def _position_law(self, t: float) -> None:
        for j in range(3):
            self._omega_cmd[j] = self.reference.rho_dot[j] / self.i_R

    def _velocity_law(self, t: float) -> None:
        vals, ref, i_R = self.values, self.reference, self.i_R
        rho = (vals[3], vals[4], vals[5])
        rho_dot = (i_R * vals[6], i_R * vals[7], i_R * vals[8])
        a = [commanded_acceleration(ref.rho_ddot[j], ref.rho_dot[j], rho_dot[j], self._rho_cmd[j], rho[j], self.K_P,
                                    self.K_D) for j in range(3)]
        i_max = self._i_max
        for j, i in enumerate(self.model.currents(rho, rho_dot, a)):
            self._i_cmd[j] = limited(i, i_max)
