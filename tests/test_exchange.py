"""The 1 kHz exchange of every MAST system (issue 13): the drive's current loop inside the actuator
(fmus/actuator/drive.py), the controller's commands direct-feedthrough outputs ordered by the master,
every component at 1 ms. It must give the trajectories of the former pattern (current loop in the
controller, 10 kHz Jacobi exchange) to rounding: the command computed from the samples at t reaches
the current loop at t, and the voltage it computes is applied one T_cur later, as before.

The former pattern is rebuilt here independently, in the direct composition: a controller with the
current loop inside (``TenKilohertzController``: the laws of each tick, then the PI on the measured
current, outputs after the step, no feedthrough) exchanging with voltage-driven axes every 100 us."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from conftest import ROOT as REPO

from fmus.actuator.drive import CURRENT_LOOP_PARAMETERS, pi_step
from fmus.actuator.model import ActuatorBlock
from fmus.common.block import Block
from fmus.controller.model import ControllerBlock
from mast.core.components import BlockComponent
from mast.core.master import Master
from mast.core.motion import SineMotion
from mast.core.ssp import Connection, read_ssd

AXES = (1, 2, 3)


class TenKilohertzController(Block):
    """The controller as it was: measured currents in, voltages out, stepped every T_cur (Jacobi)."""

    INPUTS = (*ControllerBlock.INPUTS, "i_m_1", "i_m_2", "i_m_3")
    OUTPUTS = ("u_1", "u_2", "u_3", *ControllerBlock.OUTPUTS)
    PARAMETERS = (*ControllerBlock.PARAMETERS, *(p for p in CURRENT_LOOP_PARAMETERS if p.name != "T_cur"))

    def __init__(self, params, name=""):
        super().__init__(params, name)
        P = self.params
        self.laws = ControllerBlock({k: v for k, v in P.items() if k not in ("k_pc", "k_ic", "u_max")}, self.name)
        self.T = float(P["T_cur"])
        self.gains = (float(P["k_pc"]), float(P["k_ic"]) * self.T, float(P["u_max"]))

    def initialize(self, t0):
        self.laws.values[:9] = self.values[:9]
        self.laws.initialize(t0)
        self.x_c, self.u = [0.0] * 3, [0.0] * 3
        self.values[12:] = [*self.u, *self.laws.values[9:]]

    def do_step(self, t, h):
        assert round(h / self.T) == 1
        laws = self.laws
        laws.values[:9] = self.values[:9]
        laws.do_step(t, h)  # the laws of the tick at t from the samples at t (no input set: held)
        i_cmd = laws.values[15:18]
        for j in range(3):
            self.u[j], self.x_c[j] = pi_step(i_cmd[j] - self.values[9 + j], self.x_c[j], *self.gains)
        self.values[12:] = [*self.u, *laws.values[9:]]


def ten_kilohertz(ssd):
    """The system of ``ssd`` rewired as before: controller.u_k -> actuator_k.u, actuator_k.i_m -> controller,
    controller and actuators at 100 us."""
    system = read_ssd(ssd)
    cons = [c for c in system.connections if c.end_connector != "i_cmd"]
    cons += [Connection("controller", f"u_{k}", f"actuator_{k}", "u") for k in AXES]
    cons += [Connection(f"actuator_{k}", "i_m", "controller", f"i_m_{k}") for k in AXES]
    comps = dict(system.components)
    comps["controller"] = replace(
        comps["controller"],
        step_size=1e-4,
        inputs=list(TenKilohertzController.INPUTS),
        outputs=list(TenKilohertzController.OUTPUTS),
    )
    for k in AXES:
        comps[f"actuator_{k}"] = replace(comps[f"actuator_{k}"], step_size=1e-4, inputs=["u", "F"])
    return replace(system, components=comps, connections=cons, base_step=1e-4)


def blocks_of(system, **override):
    return {
        name: BlockComponent(name, override.get(name) or BlockComponent.class_for(spec.source.rsplit("/", 1)[-1][:-4]))
        for name, spec in system.components.items()
    }


class LateController(ControllerBlock):
    """The same controller declaring no feedthrough: the master hands i_cmd on one exchange (1 ms) late."""

    FEEDTHROUGH = {}


SIGNALS = [
    "mechanism.z",
    "actuator_1.rho_ddot",
    "actuator_1.rho",
    "actuator_2.i_m",
    "actuator_3.tau_m",
    "actuator_1.omega_m",
    "controller.i_cmd_2",
]


def largest_difference(a, b) -> float:
    return max(float(np.max(np.abs(a[n] - b[n])) / np.max(np.abs(b[n]))) for n in SIGNALS)


@pytest.fixture(scope="module")
def former():
    ssd = REPO / "ssp" / "MAST.ssd"
    system = ten_kilohertz(ssd)
    blocks = blocks_of(system, controller=TenKilohertzController, **{f"actuator_{k}": ActuatorBlock for k in AXES})
    params = {f"actuator_{k}": {} for k in AXES}
    master = Master(system, blocks)
    return master.run(
        0.3, SineMotion("z", 0.01, 10.0), record=SIGNALS + ["controller.u_1"], record_step=1e-3, parameters=params
    )


def test_the_1khz_drive_pattern_gives_the_former_10khz_trajectories_to_rounding(former):
    system = read_ssd(REPO / "ssp" / "MAST.ssd")
    assert system.base_step == 1e-3 and {s.step_size for s in system.components.values()} == {1e-3}
    master = Master(system, blocks_of(system))
    assert master.exchange_order.index("controller") < master.exchange_order.index("actuator_1")
    new = master.run(0.3, SineMotion("z", 0.01, 10.0), record=SIGNALS + ["actuator_1.u"], record_step=1e-3)
    assert len(new.time) == len(former.time) == 301
    worst = largest_difference(new, former)
    np.testing.assert_allclose(new["actuator_1.u"], former["controller.u_1"], rtol=0, atol=1e-12)
    print(f"largest relative difference {worst:.3g}")
    assert math.isfinite(worst) and worst <= 1e-9, f"largest relative difference {worst:.3g}"


def test_a_current_command_one_exchange_late_is_detected(former):
    system = read_ssd(REPO / "ssp" / "MAST.ssd")
    late = Master(system, blocks_of(system, controller=LateController))
    new = late.run(0.3, SineMotion("z", 0.01, 10.0), record=SIGNALS, record_step=1e-3)
    late_by = largest_difference(new, former)
    print(f"one exchange late: {late_by:.3g}")
    assert late_by > 1e-3


def test_exchanging_at_every_current_loop_tick_gives_the_same_trajectories(former):
    """mast.core.run.drive_tick_steps (synthesize and the diagnosis record the torque at T_cur): controller and
    actuators exchanged every 100 us, the laws still sampled at their 1 ms ticks, the same run to rounding."""
    from mast.core.run import drive_tick_steps

    system = read_ssd(REPO / "ssp" / "MAST.ssd")
    base, sizes = drive_tick_steps(system)
    assert base == 1e-4 and set(sizes) == {"controller", "actuator_1", "actuator_2", "actuator_3"}
    fine = Master(system, blocks_of(system), base_step=base, step_sizes=sizes)
    new = fine.run(0.3, SineMotion("z", 0.01, 10.0), record=SIGNALS, record_step=1e-3)
    assert largest_difference(new, former) <= 1e-9
