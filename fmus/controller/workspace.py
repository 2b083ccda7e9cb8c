"""Workspace position control (paper Fig. 3a): the position error measured on the platform pose.

Per position tick (T_pos), with q the platform coordinates (the mechanism's, topology.Topology.names: for
the 3PRS (z, psi, theta)):

    q_meas    = DK(rho)                          the controller's own direct kinematics
    qdot_cmd  = K (q_cmd - q_meas)               K = k_v diag(s_c) per coordinate c (k_v_scale_<c>)  [1/s]
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

from typing import Sequence

from ..common.parameters import Param, nonnegative
from ..mechanism.kinematics import KinematicsError
from .model import ControllerBlock
from .tick import DK_FAILED, TARGET_FAILED, failed_call


def workspace_parameters(coordinates: Sequence[str]) -> tuple[Param, ...]:
    """The pose-space gain scales, one per coordinate c: ``k_v_scale_<c>`` [1] (for the 3PRS: z, psi, theta)."""
    return tuple(
        nonnegative(f"k_v_scale_{c}", "1", f"Workspace position gain in {c}, as a multiple of k_v") for c in coordinates
    )


def pose_gain(k_v: float, s: float) -> float:
    """One coordinate's gain of K = k_v diag(s) [1/s]. Written in the generated-code subset: the native FMU
    computes them at initialisation with this source."""
    return k_v * s


def joint_speed_source(row: Sequence[str], qdot: Sequence[str], i_R: str) -> str:
    """One axis' motor speed command [rad/s] for the pose rate qdot through its row of drho/dq:
    (J_0 qdot_0 + ... + J_(n-1) qdot_(n-1)) / i_R, as an expression of the tick (tick.py) in the names given."""
    return f"({' + '.join(f'{J}*{qd}' for J, qd in zip(row, qdot))})/{i_R}"


class WorkspaceController(ControllerBlock):
    """Position loop on the platform pose (through the direct kinematics); velocity PI per axis."""

    @classmethod
    def _interface(cls) -> dict:
        """The cascade's, with a gain scale per coordinate (``workspace_parameters``)."""
        declared = super()._interface()
        axes = range(1, len(cls.COORDINATES) + 1)
        return {
            **declared,
            "PARAMETERS": (*ControllerBlock.PARAMETERS, *workspace_parameters(cls.COORDINATES)),
            "DESCRIPTIONS": {
                **declared["DESCRIPTIONS"],
                **{
                    f"omega_cmd_{j}": f"Motor speed command of axis {j} (workspace position loop "
                    f"through the inverse Jacobian)"
                    for j in axes
                },
            },
        }

    LAWS = ()

    def _constants(self, S: list[float]) -> None:
        super()._constants(S)
        at, k_v = self.LAYOUT["own"], float(self.params["k_v"])
        #: pose-space gains [1/s], one per coordinate
        self.K = S[at : at + self.n] = tuple(
            pose_gain(k_v, float(self.params[f"k_v_scale_{c}"])) for c in self.COORDINATES
        )

    def _reset(self) -> None:
        super()._reset()
        self._q_meas = None  # last direct kinematics of the measured joints (its warm start)
        self._q_target = None  # last direct kinematics of rho_cmd (joint mode)

    def _law_state(self) -> tuple:
        return (*super()._law_state(), self._q_meas, self._q_target)

    def _set_law_state(self, state: tuple) -> None:
        super()._set_law_state(state)
        self._q_meas, self._q_target = state[-2:]

    def _calls(self) -> dict:
        return {**super()._calls(), "wsdk": self._wsdk, "wsdk_target": self._wsdk_target, "ikjac_s": self._ikjac_s}

    def _wsdk(self, *rho_S_out) -> int:
        """``wsdk(rho_1, ..., rho_n, S, out)``: the direct kinematics of the measured joints (warm-started from the
        last) into ``out``; 1 if it fails."""
        try:
            q = self._q_meas = self.kinematics.dk(rho_S_out[:-2], self._q_meas)[0]
        except KinematicsError as exc:
            self._failure = exc
            return 1
        rho_S_out[-1][: len(q)] = q
        return 0

    def _wsdk_target(self, *rho_S_out) -> int:
        """``wsdk_target(rho_1, ..., rho_n, S, out)``: the direct kinematics of the joint command ("joint" mode;
        from the last, else from the measured joints' pose) into ``out``; 1 if it fails."""
        try:
            q = self._q_target = self.kinematics.dk(rho_S_out[:-2], self._q_target or self._q_meas)[0]
        except KinematicsError as exc:
            self._failure = exc
            return 1
        rho_S_out[-1][: len(q)] = q
        return 0

    def _ikjac_s(self, S: list[float], *q_out) -> int:
        """``ikjac_s(S, q_1, ..., q_n, out)``: drho/dq at q (row-major) into out[n:n + n^2]."""
        n = self.n
        q_out[-1][n : n + n * n] = self.kinematics.jacobian(q_out[:-1])[0]
        return 0

    def _failed(self, code: int, t: float) -> Exception:
        if code not in (DK_FAILED, TARGET_FAILED):
            return super()._failed(code, t)
        at = self.LAYOUT["model_args"]
        what = "measured joints" if code == DK_FAILED else "joint command"
        rho = tuple(self._S[at : at + self.n])
        error = KinematicsError(
            f"{self.name}: direct kinematics of the {what} rho = {rho!r} m failed at t = {t!r} s: {self._failure}"
        )
        error.__cause__ = self._failure
        return error

    @classmethod
    def position_lines(cls, moded: bool) -> list[str]:
        """The direct kinematics of the measured joints, the pose-space P law (towards the pose command, or in
        "joint" mode the direct kinematics of rho_cmd), through drho/dq at the measured pose."""
        L, n = cls.LAYOUT, len(cls.COORDINATES)
        own, i_R = L["own"], f"S[{L['i_R']}]"
        measured = [f"values[{n + j}]" for j in range(n)]
        lines = failed_call(L, f"wsdk({', '.join(measured)}, S, QM)", measured, DK_FAILED)
        if moded:
            commanded = [f"rc{j}" for j in range(n)]
            lines += [
                "if mode == 0.0:",
                *(f"    tq{k} = values[{k}]" for k in range(n)),
                "else:",
                *(
                    "    " + line
                    for line in failed_call(L, f"wsdk_target({', '.join(commanded)}, S, JK)", commanded, TARGET_FAILED)
                ),
                *(f"    tq{k} = JK[{k}]" for k in range(n)),
            ]
        target = [f"tq{k}" if moded else f"values[{k}]" for k in range(n)]
        lines += [f"qd{k} = S[{own + k}]*({target[k]} - QM[{k}])" for k in range(n)]
        lines.append(f"c = ikjac_s(S, {', '.join(f'QM[{k}]' for k in range(n))}, JK)")
        qdot = [f"qd{k}" for k in range(n)]
        lines += [
            f"oc{j} = " + joint_speed_source([f"JK[{n + n * j + k}]" for k in range(n)], qdot, i_R) for j in range(n)
        ]
        return lines
