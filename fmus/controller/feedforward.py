"""Joint-space cascade with velocity and inverse-dynamics torque feed-forward.

The cascade of model.py, plus two feed-forward paths from the joint reference
(rho_ref = rho_cmd, its velocity and acceleration from reference.py), per axis j:

    omega_cmd_j = k_v (rho_ref_j - rho_j) / i_R + k_ff_v rho_dot_ref_j / i_R
    i_ff_j      = k_ff_tau tau_model_j(rho_ref, rho_dot_ref, rho_ddot_ref) / k_T      added to the velocity PI

tau_model is the controller's inverse dynamic model (inverse_model.py) evaluated on the
reference, so the feedback loops only correct what the model misses. With both weights
0 this is the plain cascade; with 1 and an exact model the tracking error is what the
reference estimate and the loops' sampling leave.
"""

from __future__ import annotations

from typing import Mapping, Optional

from ..common.parameters import Param, Value
from ..mechanism.engine import Engine
from .inverse_model import MODEL_PARAMETERS, InverseModel
from .model import ControllerBlock, position_p_law
from .tick import MODEL_FAILED, failed_call

FEEDFORWARD_PARAMETERS = (
    Param("k_ff_v", "1", "Weight of the velocity feed-forward (0: none, 1: full)", 0.0, 1.5),
    Param("k_ff_tau", "1", "Weight of the inverse-dynamics torque feed-forward (0: none, 1: full)", 0.0, 1.5),
)


def feedforward_gains(k_ff_v: float, k_ff_tau: float, i_R: float) -> tuple[float, float]:
    """(k_ff_v / i_R [rad/m], k_ff_tau [1]): the feed-forward weights as the laws use them. Written in the
    generated-code subset: the native FMU computes them at initialisation with this source."""
    return (k_ff_v / i_R, k_ff_tau)


def velocity_feedforward(omega_cmd: float, rho_dot_ref: float, kff_v_iR: float) -> float:
    """The position law's output plus the velocity feed-forward, one axis [rad/s] (``kff_v_iR`` = k_ff_v / i_R).
    Written in the generated-code subset, as ``feedforward_gains``."""
    return omega_cmd + kff_v_iR * rho_dot_ref


class FeedForwardController(ControllerBlock):
    """Joint-space P/PI/PI cascade with velocity and inverse-dynamics torque feed-forward."""

    PARAMETERS = (*ControllerBlock.PARAMETERS, *MODEL_PARAMETERS, *FEEDFORWARD_PARAMETERS)
    REFERENCE_RATES = True
    FEEDFORWARD_CURRENT = True
    LAWS = (position_p_law, velocity_feedforward)

    def __init__(
        self,
        params: Mapping[str, Value],
        name: str = "",
        kinematics: Optional[Engine] = None,
        dynamics: Optional[Engine] = None,
    ) -> None:
        """``kinematics``, ``dynamics``: as ``ComputedTorqueController``'s."""
        super().__init__(params, name, kinematics)
        self.model = InverseModel(self.params, self.name, dynamics, self.n)

    def _constants(self, S: list[float]) -> None:
        super()._constants(S)
        at = self.LAYOUT["own"]
        S[at : at + 2] = feedforward_gains(float(self.params["k_ff_v"]), float(self.params["k_ff_tau"]), self.i_R)

    def _calls(self) -> dict:
        return {**super()._calls(), "currents": self._currents}

    def _law_state(self) -> tuple:
        return (*super()._law_state(), self.model.warm_start)

    def _set_law_state(self, state: tuple) -> None:
        super()._set_law_state(state)
        self.model.warm_start = state[-1]

    @classmethod
    def position_lines(cls, moded: bool) -> list[str]:
        """The P law, plus the velocity feed-forward and the inverse model's currents on the reference (i_ff)."""
        L, n = cls.LAYOUT, len(cls.COORDINATES)
        Q, kff_v_iR, kff_tau = L["rates"], f"S[{L['own']}]", f"S[{L['own'] + 1}]"
        reference = [f"rc{j}" for j in range(n)] + [f"S[{Q + k}]" for k in range(2 * n)]
        return [
            *super().position_lines(moded),
            *(f"oc{j} = velocity_feedforward(oc{j}, S[{Q + j}], {kff_v_iR})" for j in range(n)),
            f"if {kff_tau} != 0.0:",
            *(
                "    " + line
                for line in failed_call(L, f"currents({', '.join(reference)}, S, CUR)", reference, MODEL_FAILED)
            ),
            *(f"    if{j} = {kff_tau}*CUR[{j}]" for j in range(n)),
        ]
