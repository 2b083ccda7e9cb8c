"""The exchange of every MAST system (issue 27): the drive's current loop inside the actuator
(fmus/actuator/drive.py), every component exchanging every T_cur = 100 us (the mechanism updating its
outputs every T_mech = 1 ms inside), Jacobi (no output read after an input set without a step: FMI 2.0's
calling sequence). The
current command computed from the samples at t reaches the current loop at its next tick, t + T_cur,
and the voltage the loop computes there acts one T_cur later again.

That is rebuilt here independently, in the direct composition: a controller with the current loop inside
(``TenKilohertzController``: the laws of each tick, a one-tick latch on their current command, then the PI
on the measured current, voltages out after the step) exchanging with voltage-driven axes every 100 us."""

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
    """The controller with the current loop inside: measured currents in, voltages out, stepped every T_cur
    (Jacobi); ``LATCH``: the PI at a tick uses the current command of the tick before (the drive's
    computation delay), else the one just computed (the former pattern, issue 13)."""

    LATCH = True

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
        self.i_cmd = list(self.laws.values[15:18])
        self.values[12:] = [*self.u, *self.laws.values[9:]]

    def do_step(self, t, h):
        assert round(h / self.T) == 1
        laws = self.laws
        laws.values[:9] = self.values[:9]
        laws.do_step(t, h)  # the laws of the tick at t from the samples at t (no input set: held)
        i_cmd = self.i_cmd if self.LATCH else laws.values[15:18]
        self.i_cmd = list(laws.values[15:18])
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


class FormerController(TenKilohertzController):
    """The former pattern: the current command reaches the current loop at the tick that computed it."""

    LATCH = False


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


def run_rebuilt(controller):
    system = ten_kilohertz(REPO / "ssp" / "MAST.ssd")
    blocks = blocks_of(system, controller=controller, **{f"actuator_{k}": ActuatorBlock for k in AXES})
    params = {f"actuator_{k}": {} for k in AXES}
    return Master(system, blocks).run(
        0.3, SineMotion("z", 0.01, 10.0), record=SIGNALS + ["controller.u_1"], record_step=1e-3, parameters=params
    )


@pytest.fixture(scope="module")
def rebuilt():
    return run_rebuilt(TenKilohertzController)


def test_the_drive_pattern_gives_the_trajectories_of_the_current_loop_in_the_controller(rebuilt):
    system = read_ssd(REPO / "ssp" / "MAST.ssd")
    assert system.base_step == 1e-4
    assert {s.step_size for s in system.components.values()} == {1e-4}
    new = Master(system, blocks_of(system)).run(
        0.3, SineMotion("z", 0.01, 10.0), record=SIGNALS + ["actuator_1.u"], record_step=1e-3
    )
    assert len(new.time) == len(rebuilt.time) == 301
    worst = largest_difference(new, rebuilt)
    np.testing.assert_allclose(new["actuator_1.u"], rebuilt["controller.u_1"], rtol=0, atol=1e-12)
    print(f"largest relative difference {worst:.3g}")
    assert math.isfinite(worst) and worst <= 1e-9, f"largest relative difference {worst:.3g}"


def test_a_current_command_a_tick_early_or_an_exchange_late_is_detected(rebuilt):
    """The former pattern (the command at the tick that computed it) and the whole system at 1 ms (the command
    1 ms late, what a 1 kHz Jacobi exchange gives) both differ measurably from the drive's timing."""
    early_by = largest_difference(run_rebuilt(FormerController), rebuilt)
    system = read_ssd(REPO / "ssp" / "MAST.ssd")
    slow = Master(system, blocks_of(system), base_step=1e-3, step_sizes={n: 1e-3 for n in system.components})
    late_by = largest_difference(slow.run(0.3, SineMotion("z", 0.01, 10.0), record=SIGNALS, record_step=1e-3), rebuilt)
    print(f"a tick early: {early_by:.3g}; 1 ms late: {late_by:.3g}")
    assert early_by > 1e-4 and late_by > 1e-2


def test_exchanging_at_every_current_loop_tick_gives_the_same_trajectories(rebuilt):
    """mast.core.run.drive_tick_steps (synthesize and the diagnosis record the torque at T_cur): the controller and
    the actuators every 100 us, as the systems step them now: the same run to rounding."""
    from mast.core.run import drive_tick_steps

    system = read_ssd(REPO / "ssp" / "MAST.ssd")
    base, sizes = drive_tick_steps(system)
    assert base == 1e-4 and set(sizes) == {"controller", "actuator_1", "actuator_2", "actuator_3"}
    fine = Master(system, blocks_of(system), base_step=base, step_sizes=sizes)
    new = fine.run(0.3, SineMotion("z", 0.01, 10.0), record=SIGNALS, record_step=1e-3)
    assert largest_difference(new, rebuilt) <= 1e-9
