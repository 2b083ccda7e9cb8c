"""Pose command: home pose + sine, the block behind the MastTrajectory FMU.

Outputs at time t (t0 is the start time given to ``initialize``):

    z_cmd     = z_home     + amplitude_z     * sin(2 pi f (t - t0))
    psi_cmd   = psi_home   + amplitude_psi   * sin(2 pi f (t - t0))
    theta_cmd = theta_home + amplitude_theta * sin(2 pi f (t - t0))

the same command as the project's Python stimulus ``mast.core.motion.SineMotion`` (whose home
pose is read from the mechanism at the start). ``do_step(t, h)`` leaves the values at
t + h, so a Jacobi master hands the controller the command of the instant it samples.
"""
from __future__ import annotations

import math
from typing import Mapping

from ..common.block import Block, ModelError
from ..common.parameters import Param, Value, nonnegative


class TrajectoryBlock(Block):
    """Home pose plus a sine on z, psi and theta (one frequency)."""

    INPUTS = ()
    OUTPUTS = ("z_cmd", "psi_cmd", "theta_cmd")
    PARAMETERS = (
        Param("z_home", "m", "Height of the platform centre P at the home pose (all sliders at rho_0)",
              minimum=0.0, exclusive=True),
        Param("psi_home", "rad", "Roll at the home pose", minimum=-math.pi / 2, maximum=math.pi / 2),
        Param("theta_home", "rad", "Pitch at the home pose", minimum=-math.pi / 2, maximum=math.pi / 2),
        Param("amplitude_z", "m", "Amplitude of the sine on z (0: z stays at home)", minimum=-1.0, maximum=1.0),
        Param("amplitude_psi", "rad", "Amplitude of the sine on psi (0: psi stays at home)",
              minimum=-math.pi / 2, maximum=math.pi / 2),
        Param("amplitude_theta", "rad", "Amplitude of the sine on theta (0: theta stays at home)",
              minimum=-math.pi / 2, maximum=math.pi / 2),
        nonnegative("frequency", "Hz", "Frequency of the sine (0 holds the home pose)"),
    )
    UNITS = {"z_cmd": "m", "psi_cmd": "rad", "theta_cmd": "rad"}
    DESCRIPTIONS = {
        "z_cmd": "Commanded height of the platform centre P",
        "psi_cmd": "Commanded roll about x",
        "theta_cmd": "Commanded pitch about y",
    }

    def __init__(self, params: Mapping[str, Value], name: str = "") -> None:
        super().__init__(params, name)
        p = self.params
        self._home = (p["z_home"], p["psi_home"], p["theta_home"])
        self._amplitude = (p["amplitude_z"], p["amplitude_psi"], p["amplitude_theta"])
        self._omega = 2.0 * math.pi * p["frequency"]
        self._t0 = 0.0

    def _write(self, t: float) -> None:
        if not math.isfinite(t):
            raise ModelError(f"{self.name}: time t = {t!r} s is not finite")
        s = math.sin(self._omega * (t - self._t0))
        self.values[:] = [h + a * s for h, a in zip(self._home, self._amplitude)]

    def initialize(self, t0: float) -> None:
        self._t0 = float(t0)
        self._write(self._t0)

    def do_step(self, t: float, h: float) -> None:
        self._write(t + h)
