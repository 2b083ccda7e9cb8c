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

from typing import Mapping, Optional

from ..common.parameters import Value, nonnegative, positive
from ..mechanism.engine import Engine
from .inverse_model import MODEL_PARAMETERS, InverseModel
from .model import DRIVE_PARAMETERS, DriveController
from .tick import MODEL_FAILED, failed_call

COMPUTED_TORQUE_PARAMETERS = (
    positive("omega_n", "rad/s", "Natural frequency of the joint error dynamics"),
    nonnegative("zeta", "1", "Damping ratio of the joint error dynamics"),
)


def error_gains(omega_n: float, zeta: float) -> tuple[float, float]:
    """(K_P = omega_n^2 [1/s^2], K_D = 2 zeta omega_n [1/s]). Written in the generated-code subset: the
    native FMU computes them at initialisation with this source."""
    return (omega_n * omega_n, 2.0 * zeta * omega_n)


def commanded_acceleration(
    rho_ddot_ref: float, rho_dot_ref: float, rho_dot: float, rho_ref: float, rho: float, K_P: float, K_D: float
) -> float:
    """a = rho_ddot_ref + K_D (rho_dot_ref - rho_dot) + K_P (rho_ref - rho) [m/s^2], one axis: the joint
    acceleration the inverse model is asked for. Written in the generated-code subset, as ``error_gains``."""
    return rho_ddot_ref + K_D * (rho_dot_ref - rho_dot) + K_P * (rho_ref - rho)


def limited(i: float, i_max: float) -> float:
    """i clipped to [-i_max, i_max] [A]. Written in the generated-code subset, as ``error_gains``."""
    return i_max if i > i_max else (-i_max if i < -i_max else i)


class ComputedTorqueController(DriveController):
    """Computed torque control of the n axes with the controller's own inverse dynamic model."""

    PARAMETERS = (*DRIVE_PARAMETERS, *MODEL_PARAMETERS, *COMPUTED_TORQUE_PARAMETERS)
    REFERENCE_RATES = True
    MODES = ("pose", "joint", "current")

    @classmethod
    def _interface(cls) -> dict:
        declared = super()._interface()
        axes = range(1, len(cls.COORDINATES) + 1)
        return {
            **declared,
            "DESCRIPTIONS": {
                **declared["DESCRIPTIONS"],
                **{
                    f"omega_cmd_{j}": f"Reference speed of motor {j} (rho_dot_ref / i_R; no velocity loop)"
                    for j in axes
                },
                **{f"i_cmd_{j}": f"Current command of axis {j} (computed torque / k_T)" for j in axes},
            },
        }

    LAWS = (commanded_acceleration, limited)

    def __init__(
        self,
        params: Mapping[str, Value],
        name: str = "",
        kinematics: Optional[Engine] = None,
        dynamics: Optional[Engine] = None,
    ) -> None:
        """``kinematics``, ``dynamics``: the controller's kinematic model (``DriveController``) and its inverse
        model's engine (``InverseModel``), by default the ones its parameter sets select."""
        super().__init__(params, name, kinematics)
        self.model = InverseModel(self.params, self.name, dynamics, self.n)

    def _constants(self, S: list[float]) -> None:
        super()._constants(S)
        at = self.LAYOUT["own"]
        self.K_P, self.K_D = S[at : at + 2] = error_gains(float(self.params["omega_n"]), float(self.params["zeta"]))

    def _calls(self) -> dict:
        return {**super()._calls(), "currents": self._currents}

    def _law_state(self) -> tuple:
        return (*super()._law_state(), self.model.warm_start)

    def _set_law_state(self, state: tuple) -> None:
        super()._set_law_state(state)
        self.model.warm_start = state[-1]

    @classmethod
    def position_lines(cls, moded: bool) -> list[str]:
        """omega_cmd reports the reference speed rho_dot_ref / i_R."""
        L = cls.LAYOUT
        return [f"oc{j} = S[{L['rates'] + j}]/S[{L['i_R']}]" for j in range(len(cls.COORDINATES))]

    @classmethod
    def velocity_lines(cls) -> list[str]:
        """The model's currents at the measured state (rho, rho_dot = i_R omega_m) for the acceleration
        a = rho_ddot_ref + K_D e_dot + K_P e, limited to i_max."""
        L, n = cls.LAYOUT, len(cls.COORDINATES)
        Q, i_R, i_max = L["rates"], f"S[{L['i_R']}]", f"S[{L['gains'] + 3}]"
        K_P, K_D = f"S[{L['own']}]", f"S[{L['own'] + 1}]"
        state = [
            *(f"values[{n + j}]" for j in range(n)),
            *(f"rdm{j}" for j in range(n)),
            *(f"acc{j}" for j in range(n)),
        ]
        return [
            *(f"rdm{j} = {i_R}*values[{2 * n + j}]" for j in range(n)),
            *(
                f"acc{j} = commanded_acceleration(S[{Q + n + j}], S[{Q + j}], rdm{j}, rc{j}, values[{n + j}], {K_P}, "
                f"{K_D})"
                for j in range(n)
            ),
            *failed_call(L, f"currents({', '.join(state)}, S, CUR)", state, MODEL_FAILED),
            *(f"ic{j} = limited(CUR[{j}], {i_max})" for j in range(n)),
        ]
