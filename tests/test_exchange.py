"""The 1 kHz exchange (issue 13), on the Python models in the direct composition: the drive's current
loop inside the actuator, the controller's current command a direct-feedthrough output ordered by the
master, every component at 1 ms. It must give today's trajectories (current loop in the controller,
10 kHz Jacobi exchange) to rounding: the command computed from the samples at t reaches the current
loop at t, and the voltage it computes is applied one T_cur later, as today.

The actuator is the model's own ``DriveActuatorBlock`` (fmus/actuator/drive.py); the controller here is the
prototype of the feedthrough controller, built from the cascade's laws; it is no FMU yet
(docs/interfaces.md, Timing)."""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from fmus.actuator.drive import CURRENT_LOOP_PARAMETERS, DriveActuatorBlock
from fmus.controller.model import ControllerBlock
from mast.core.components import BlockComponent
from mast.core.master import Master
from mast.core.motion import SineMotion
from mast.core.ssp import Connection, read_ssd
from mast.core.ssv import read_values

from conftest import ROOT as REPO

_LOOP = {p.name for p in CURRENT_LOOP_PARAMETERS}


class CurrentCommand(ControllerBlock):
    """The joint cascade without its current loop: i_cmd follows the samples at a communication point."""

    FEEDTHROUGH = {f"i_cmd_{j}": ControllerBlock.INPUTS[:9] for j in (1, 2, 3)}

    def evaluate(self):
        n, t = self._n, self._t0 + self._n * self.T_cur
        assert getattr(self, "_evaluated", None) != n, "evaluated twice at one communication point"
        if n % self._N_pos == 0:
            self._update_ik(t)
            self._position_law(t)
        if n % self._N_vel == 0:
            self._velocity_law(t)
        self._evaluated = n
        self._write_outputs()

    def do_step(self, t, h):
        n = self._n + round(h / self.T_cur)
        assert all(k % self._N_pos and k % self._N_vel for k in range(self._n + 1, n)), "a law tick inside the step"
        self._n = n
        self._write_outputs()


def drive_system(ssd):
    """MAST.ssd rewired: controller.i_cmd_k -> actuator_k.i_cmd, every component at 1 ms."""
    system = read_ssd(ssd)
    cons = [c for c in system.connections if not (c.start_element == "controller" and c.start_connector.startswith("u_"))]
    cons += [Connection("controller", f"i_cmd_{k}", f"actuator_{k}", "i_cmd") for k in (1, 2, 3)]
    comps = {name: replace(spec, step_size=1e-3) for name, spec in system.components.items()}
    for k in (1, 2, 3):
        comps[f"actuator_{k}"] = replace(comps[f"actuator_{k}"], inputs=["i_cmd", "F"])
    return replace(system, components=comps, connections=cons, base_step=1e-3)


def test_the_1khz_drive_pattern_gives_todays_trajectories_to_rounding():
    ssd = REPO / "ssp" / "MAST.ssd"
    drive = {k: v for k, v in read_values(REPO / "ssp" / "resources" / "drive.ssv").items() if k in _LOOP}
    signals = ["mechanism.z", "actuator_1.rho_ddot", "actuator_1.rho", "actuator_2.i_m", "actuator_3.tau_m",
               "actuator_1.omega_m", "controller.i_cmd_2"]
    stop, motion = 0.3, lambda: SineMotion("z", 0.01, 10.0)
    today = read_ssd(ssd)
    blocks = {name: BlockComponent(name, BlockComponent.class_for(spec.source.rsplit("/", 1)[-1][:-4]))
              for name, spec in today.components.items()}
    old = Master(today, blocks).run(stop, motion(), record=signals + ["controller.u_1"], record_step=1e-3)
    system = drive_system(ssd)
    blocks = {name: BlockComponent(name, blocks[name].block_class) for name in system.components}
    blocks["controller"] = BlockComponent("controller", CurrentCommand)
    for k in (1, 2, 3):
        blocks[f"actuator_{k}"] = BlockComponent(f"actuator_{k}", DriveActuatorBlock)
    master = Master(system, blocks)
    assert master.exchange_order.index("controller") < master.exchange_order.index("actuator_1")
    new = master.run(stop, motion(), record=signals + ["actuator_1.u"], record_step=1e-3,
                     parameters={f"actuator_{k}": drive for k in (1, 2, 3)})
    assert len(new.time) == len(old.time) == 301
    worst = 0.0
    for name in signals:
        scale = np.max(np.abs(old[name]))
        worst = max(worst, np.max(np.abs(new[name] - old[name])) / scale)
    np.testing.assert_allclose(new["actuator_1.u"], old["controller.u_1"], rtol=0, atol=1e-12)
    assert worst <= 1e-9, f"largest relative difference {worst:.3g}"
    assert math.isfinite(worst)
