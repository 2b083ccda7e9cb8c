"""Mechanism block: direct kinematics + inverse dynamics of the 3PRS (paper sections 2.1, 3.3).

An algebraic block: from the slider motion (rho, rho_dot, rho_ddot) held over the step
it computes the platform pose (direct kinematics, Newton warm-started from the previous
pose) and the forces F_i = t_rho_i each actuator applies to the mechanism along its
guide, positive upward (inverse dynamics). The actuators feel -F_i: the mechanism is
their disturbance (paper section 2).
"""
from __future__ import annotations

import math
from typing import Mapping

from ..common.block import Block, ModelError
from ..common.parameters import Param, Value, nonnegative
from .dynamics import Masses, _idp
from .kinematics import GEOMETRY_PARAMETERS, Geometry, KinematicsError, _dk_frame

class MechanismBlock(Block):
    """3PRS mechanism: DK and IDP; outputs the actuator forces and the platform pose."""

    INPUTS = ("rho_1", "rho_2", "rho_3",
              "rho_dot_1", "rho_dot_2", "rho_dot_3",
              "rho_ddot_1", "rho_ddot_2", "rho_ddot_3")
    OUTPUTS = ("F_1", "F_2", "F_3", "x", "y", "z", "psi", "theta", "phi")
    PARAMETERS = (
        *GEOMETRY_PARAMETERS,
        nonnegative("m_leg", "kg", "Mass of each leg (COM at mid-length)"),
        nonnegative("I_leg", "kg.m2", "Inertia of each leg about its COM, about the revolute axis direction"),
        Param("m_platform", "kg", "Platform mass (COM at P)", minimum=0.0, exclusive=True, maximum=math.inf),
        nonnegative("I_px", "kg.m2", "Platform inertia about its own x axis, at P"),
        nonnegative("I_py", "kg.m2", "Platform inertia about its own y axis, at P"),
        nonnegative("I_pz", "kg.m2", "Platform inertia about its own z axis, at P"),
        Param("g", "m/s2", "Gravitational acceleration (along -z)", minimum=0.0, maximum=100.0),
    )
    UNITS = {
        **{f"rho_{i}": "m" for i in (1, 2, 3)},
        **{f"rho_dot_{i}": "m/s" for i in (1, 2, 3)},
        **{f"rho_ddot_{i}": "m/s2" for i in (1, 2, 3)},
        **{f"F_{i}": "N" for i in (1, 2, 3)},
        "x": "m", "y": "m", "z": "m", "psi": "rad", "theta": "rad", "phi": "rad",
    }
    DESCRIPTIONS = {
        **{f"rho_{i}": f"Height of slider {i} above the base plane" for i in (1, 2, 3)},
        **{f"rho_dot_{i}": f"Velocity of slider {i} along its guide (up positive)" for i in (1, 2, 3)},
        **{f"rho_ddot_{i}": f"Acceleration of slider {i} along its guide (up positive)" for i in (1, 2, 3)},
        **{f"F_{i}": f"Force actuator {i} applies to the mechanism along its guide, positive upward "
                     f"(inverse dynamics t_rho_{i})" for i in (1, 2, 3)},
        "x": "Platform centre P, x (parasitic)",
        "y": "Platform centre P, y (parasitic)",
        "z": "Platform centre P, height above the base plane",
        "psi": "Platform roll about x (R = Rz(phi) Ry(theta) Rx(psi))",
        "theta": "Platform pitch about y",
        "phi": "Platform yaw about z (parasitic)",
    }

    def __init__(self, params: Mapping[str, Value], name: str = "") -> None:
        super().__init__(params, name)
        self.geometry = Geometry.checked(self.params, self.name)
        self.masses = Masses.from_params(self.params)
        self._guess = None
        self._zero = (0.0, 0.0, 0.0)

    # -------------------------------------------------------------------------------------
    def _compute(self, t: float) -> None:
        vals = self.values
        for k in range(9):
            v = vals[k]
            if not math.isfinite(v):
                raise ModelError(f"{self.name}: input '{self.INPUTS[k]}' = {v!r} is not finite at t = {t!r} s")
        rho = (vals[0], vals[1], vals[2])
        g = self.geometry
        try:
            try:
                fr = _dk_frame(g, rho, self._guess, 1e-12, 50)
            except KinematicsError:
                if self._guess is None:
                    raise
                fr = _dk_frame(g, rho, None, 1e-12, 50)   # cold start from the level pose
            t_rho = _idp(g, self.masses, fr, (vals[3], vals[4], vals[5]), (vals[6], vals[7], vals[8]))[0]
        except KinematicsError as exc:
            raise KinematicsError(f"{self.name}: at t = {t!r} s, rho = {rho!r} m: {exc}") from exc
        self._guess = (fr.z, fr.psi, fr.theta)
        vals[9], vals[10], vals[11] = t_rho
        vals[12], vals[13], vals[14] = fr.x, fr.y, fr.z
        vals[15], vals[16], vals[17] = fr.psi, fr.theta, fr.phi

    def initialize(self, t0: float) -> None:
        """Outputs at t0 from the current inputs (direct kinematics from the level pose)."""
        self._guess = None
        self._compute(t0)

    def do_step(self, t: float, h: float) -> None:
        """Outputs at t + h for the inputs held (algebraic: DK warm-started, then IDP)."""
        self._compute(t + h)
