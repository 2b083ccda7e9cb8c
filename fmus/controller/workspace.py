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

from ..common.parameters import nonnegative
from ..mechanism.kinematics import KinematicsError
from .model import ControllerBlock
from .tick import DK_FAILED, LAYOUT, TARGET_FAILED, failed_call

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

    LAWS = (joint_speed,)

    def _constants(self, S: list[float]) -> None:
        super()._constants(S)
        at = LAYOUT["own"]
        #: pose-space gains [1/s] for z, psi, theta
        self.K = S[at:at + 3] = pose_gains(float(self.params["k_v"]),
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

    def _calls(self) -> dict:
        return {**super()._calls(), "wsdk": self._wsdk, "wsdk_target": self._wsdk_target, "ikjac_s": self._ikjac_s}

    def _wsdk(self, r0: float, r1: float, r2: float, S: list[float], out: list[float]) -> int:
        """The direct kinematics of the measured joints (warm-started from the last) into ``out``; 1 if it fails."""
        try:
            q = self._q_meas = self.kinematics.dk((r0, r1, r2), self._q_meas)[0]
        except KinematicsError as exc:
            self._failure = exc
            return 1
        out[0], out[1], out[2] = q
        return 0

    def _wsdk_target(self, r0: float, r1: float, r2: float, S: list[float], out: list[float]) -> int:
        """The direct kinematics of the joint command ("joint" mode; from the last, else from the measured
        joints' pose) into ``out``; 1 if it fails."""
        try:
            q = self._q_target = self.kinematics.dk((r0, r1, r2), self._q_target or self._q_meas)[0]
        except KinematicsError as exc:
            self._failure = exc
            return 1
        out[0], out[1], out[2] = q
        return 0

    def _ikjac_s(self, S: list[float], q0: float, q1: float, q2: float, out: list[float]) -> int:
        """drho/dq at q (row-major) into out[3:12]."""
        out[3:12] = self.kinematics.jacobian((q0, q1, q2))[0]
        return 0

    def _failed(self, code: int, t: float) -> Exception:
        if code not in (DK_FAILED, TARGET_FAILED):
            return super()._failed(code, t)
        at = LAYOUT["model_args"]
        what = "measured joints" if code == DK_FAILED else "joint command"
        error = KinematicsError(f"{self.name}: direct kinematics of the {what} rho = {tuple(self._S[at:at + 3])!r} m "
                                f"failed at t = {t!r} s: {self._failure}")
        error.__cause__ = self._failure
        return error

    @classmethod
    def position_lines(cls, moded: bool) -> list[str]:
        """The direct kinematics of the measured joints, the pose-space P law (towards the pose command, or in
        "joint" mode the direct kinematics of rho_cmd), through drho/dq at the measured pose."""
        own, i_R = LAYOUT["own"], f"S[{LAYOUT['i_R']}]"
        measured = "values[3], values[4], values[5]"
        lines = failed_call(f"wsdk({measured}, S, QM)", measured, DK_FAILED)
        if moded:
            lines += ["if mode == 0.0:", *(f"    tq{k} = values[{k}]" for k in range(3)), "else:",
                      *("    " + line for line in failed_call("wsdk_target(rc0, rc1, rc2, S, JK)", "rc0, rc1, rc2",
                                                               TARGET_FAILED)),
                      *(f"    tq{k} = JK[{k}]" for k in range(3))]
        target = [f"tq{k}" if moded else f"values[{k}]" for k in range(3)]
        lines += [f"qd{k} = S[{own + k}]*({target[k]} - QM[{k}])" for k in range(3)]
        lines.append("c = ikjac_s(S, QM[0], QM[1], QM[2], JK)")
        lines += [f"oc{j} = joint_speed(JK[{3 + 3 * j}], JK[{4 + 3 * j}], JK[{5 + 3 * j}], qd0, qd1, qd2, {i_R})"
                  for j in range(3)]
        return lines
