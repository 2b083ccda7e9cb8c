"""Workspace position control (paper Fig. 3a): the position error measured on the platform pose.

Per position tick (T_pos), with q = (z, psi, theta) the platform coordinates:

    q_meas    = DK(rho)                          the controller's own direct kinematics
    qdot_cmd  = K (q_cmd - q_meas)               K = k_v diag(s_z, s_psi, s_theta)    [1/s]
    rho_dot_cmd = J_inv(q_meas) qdot_cmd         J_inv = drho/dq, the inverse Jacobian
    omega_cmd_j = rho_dot_cmd_j / i_R

and the velocity PI loop of the joint-space cascade underneath (model.py; the current loop runs in the actuators).
With s = 1 and small errors J_inv (q_cmd - q) = rho_cmd - rho to first order, so the loop
behaves as the joint cascade with the same k_v; what the workspace form adds is a gain per
pose direction (the scales s), so that, say, the rotations can be stiffer than the height,
and error dynamics that are decoupled in the pose, not in the joints. In "joint" mode the
pose command is the direct kinematics of the given rho_cmd.
"""
from __future__ import annotations

from typing import Mapping

from ..common.parameters import Value, nonnegative
from ..mechanism.kinematics import KinematicsError
from .model import ControllerBlock

WORKSPACE_PARAMETERS = (
    nonnegative("k_v_scale_z", "1", "Workspace position gain in z, as a multiple of k_v"),
    nonnegative("k_v_scale_psi", "1", "Workspace position gain in psi, as a multiple of k_v"),
    nonnegative("k_v_scale_theta", "1", "Workspace position gain in theta, as a multiple of k_v"),
)


def pose_gains(k_v: float, s_z: float, s_psi: float, s_theta: float) -> tuple[float, float, float]:
    """K = k_v (s_z, s_psi, s_theta) [1/s]. Written in the generated-code subset: the native FMU computes
    them at initialisation with this source."""
    return (k_v * s_z, k_v * s_psi, k_v * s_theta)


def joint_speed(J_0: float, J_1: float, J_2: float, qdot_0: float, qdot_1: float, qdot_2: float, i_R: float) -> float:
    """One axis' motor speed command [rad/s] for the pose rate qdot through its row (J_0, J_1, J_2) of drho/dq.
    Written in the generated-code subset, as ``pose_gains``."""
    return (J_0 * qdot_0 + J_1 * qdot_1 + J_2 * qdot_2) / i_R


class WorkspaceController(ControllerBlock):
    """Position loop on the platform pose (through the direct kinematics); velocity PI per axis."""

    PARAMETERS = (*ControllerBlock.PARAMETERS, *WORKSPACE_PARAMETERS)
    DESCRIPTIONS = {**ControllerBlock.DESCRIPTIONS,
                    **{f"omega_cmd_{j}": f"Motor speed command of axis {j} (workspace position loop through the "
                                         f"inverse Jacobian)" for j in (1, 2, 3)}}

    def __init__(self, params: Mapping[str, Value], name: str = "") -> None:
        super().__init__(params, name)
        #: pose-space gains [1/s] for z, psi, theta
        self.K = pose_gains(float(self.params["k_v"]),
                            *(float(self.params[f"k_v_scale_{c}"]) for c in ("z", "psi", "theta")))

    def _reset(self) -> None:
        super()._reset()
        self._q_meas = None       # last direct kinematics of the measured joints (its warm start)
        self._q_target = None     # last direct kinematics of rho_cmd (joint mode)

    def _law_state(self) -> tuple:
        return (*super()._law_state(), self._q_meas, self._q_target)

    def _set_law_state(self, state: tuple) -> None:
        super()._set_law_state(state)
        self._q_meas, self._q_target = state[-2:]

    def _dk(self, rho, guess, what: str, t: float):
        try:
            return self.kinematics.dk(rho, guess)[0]
        except KinematicsError as exc:
            raise KinematicsError(f"{self.name}: direct kinematics of the {what} rho = {tuple(rho)!r} m failed at "
                                  f"t = {t!r} s: {exc}") from exc

    def _position_law(self, t: float) -> None:
        vals = self.values
        q = self._q_meas = self._dk((vals[3], vals[4], vals[5]), self._q_meas, "measured joints", t)
        if self._mode == 0:
            target = (vals[0], vals[1], vals[2])
        else:
            target = self._q_target = self._dk(self._rho_cmd, self._q_target or q, "joint command", t)
        qdot = [self.K[k] * (target[k] - q[k]) for k in range(3)]
        J_inv = self.kinematics.jacobian(q)[0]          # drho/dq, row-major
        i_R = self.i_R
        for j in range(3):
            self._omega_cmd[j] = joint_speed(J_inv[3 * j], J_inv[3 * j + 1], J_inv[3 * j + 2], *qdot, i_R)
