"""The actuator with its drive's current loop (fmus/actuator/drive.py), against python-control.

Independent route: the rigid axis (n_dof = 1, no friction, no weight, no viscous drag) seen from the
voltage is i/u = J s / (L J s^2 + R J s + k_E k_T) (written out here from the motor's equations, not
taken from the model), sampled with an exact zero-order hold at T_cur; the loop is the forward-Euler
PI, one sample of computation delay, unity feedback (python-control's c2d and feedback)."""

from __future__ import annotations

import math

import control as ct
import numpy as np
import pytest
from conftest import load_params

from fmus.actuator.drive import DriveActuatorBlock
from fmus.common.block import ModelError

LOOP = {"k_pc": 0.2586, "k_ic": 939.3, "T_cur": 1e-4, "u_max": 24.0}


def drive(**changes) -> DriveActuatorBlock:
    p = {**load_params("actuator"), **LOOP, "n_dof": 1, "tau_c": 0.0, "g_guide": 0.0, "b_v": 0.0}
    return DriveActuatorBlock({**p, **changes})


def steps(block: DriveActuatorBlock, i_cmd: float, n: int, m: int = 1) -> np.ndarray:
    """(i_m, u) at t = 0, m T_cur, 2 m T_cur, ... for a current command step at t = 0."""
    block.set(i_cmd=i_cmd, F=0.0)
    block.initialize(0.0)
    h = m * block.T_cur
    rows = [(block.get("i_m"), block.get("u"))]
    for k in range(n):
        block.do_step(k * h, h)
        rows.append((block.get("i_m"), block.get("u")))
    return np.array(rows)


def test_the_current_loop_is_the_sampled_pi_with_one_tick_of_delay_around_the_motor():
    blk = drive()
    p, T = blk.params, LOOP["T_cur"]
    J = (
        p["J1_scale"] * (p["J_motor"] + p["J_gearbox"] + p["J_coupling"] + p["J_brake"])
        + p["J_guide"] / p["i_r"] ** 2
        + p["M_load"] * (p["p"] / (2 * math.pi * p["i_r"])) ** 2
    )
    plant = ct.c2d(ct.tf([J, 0.0], [p["L"] * J, p["R"] * J, p["k_E"] * p["k_T"]]), T, method="zoh")
    C = ct.tf([LOOP["k_pc"], LOOP["k_ic"] * T - LOOP["k_pc"]], [1.0, -1.0], T)
    z1 = ct.tf([1.0], [1.0, 0.0], T)
    n, r = 150, 2.0
    t = np.arange(n + 1) * T
    y_i = np.asarray(ct.step_response(ct.feedback(C * z1 * plant, 1), T=t).outputs).reshape(-1)
    y_u = np.asarray(ct.step_response(z1 * ct.feedback(C, z1 * plant), T=t).outputs).reshape(-1)
    got = steps(blk, r, n)
    assert np.max(np.abs(got[:, 1])) < LOOP["u_max"]  # linear regime
    np.testing.assert_allclose(got[:, 0], r * y_i, rtol=0, atol=1e-9 * r)
    np.testing.assert_allclose(got[:, 1], r * y_u, rtol=0, atol=1e-9 * np.abs(r * y_u).max())
    # the current follows the command (lagging the back-EMF ramp of the accelerating, unloaded motor a little)
    assert abs(got[-1, 0] - r) < 0.05 * r
    # a communication step of 10 T_cur runs the same 10 ticks: the same numbers at its end
    np.testing.assert_array_equal(steps(drive(), r, n // 10, m=10), got[::10])


def test_a_bad_command_or_step_is_refused_by_name():
    blk = drive()
    blk.set(i_cmd=float("nan"), F=0.0)
    with pytest.raises(ModelError, match="input 'i_cmd' = nan at t=0 s is not finite"):
        blk.initialize(0.0)
    blk.set(i_cmd=2.0)
    blk.initialize(0.0)
    blk.do_step(0.0, 1e-4)
    before = list(blk.values)
    for h in (1.5e-4, 5e-5, 0.0):
        with pytest.raises(
            ModelError,
            match=rf"step size h = {h!r} s is not a positive integer multiple of "
            r"T_cur = 0\.0001 s",
        ):
            blk.do_step(1e-4, h)
        assert blk.values == before  # refused before anything moved
    blk.do_step(1e-4, 1e-4)  # and the run goes on as if nothing had been asked
    np.testing.assert_array_equal((blk.get("i_m"), blk.get("u")), steps(drive(), 2.0, 2)[-1])


def _run_both(monkeypatch, changes: dict, n: int, i_cmd=lambda k: 3.0 * math.sin(0.05 * k) ** 3) -> tuple[tuple, tuple]:
    """(values after each 1 ms step, error) of the drive with its generated loop over the ticks
    (``ActuatorBlock.ticks``) and with the axis stepped tick by tick, on the same inputs."""
    from fmus.actuator.model import ActuatorBlock

    runs = []
    for batched in (True, False):
        if not batched:
            monkeypatch.setattr(ActuatorBlock, "ticks", lambda self, h, pi_step: None)
        blk = DriveActuatorBlock({**load_params("actuator"), **LOOP, **changes})
        blk.set(i_cmd=0.0, F=-40.0)
        blk.initialize(0.0)
        rows, error = [], None
        try:
            for k in range(n):
                blk.set(i_cmd=i_cmd(k), F=-40.0 + 15.0 * math.cos(0.03 * k))
                blk.do_step(k * 1e-3, 1e-3)
                rows.append(list(blk.values))
        except ModelError as err:
            error = str(err)
        runs.append((rows, error, list(blk.axis.values), list(blk.axis._x)))
    return runs[0], runs[1]


@pytest.mark.parametrize(
    "changes",
    [{}, {"tau_ripple": 0.01, "tau_s": 0.05}, {"u_supply": 0.3}, {"T_meas": 1e-3}],
    ids=["default", "ripple+stribeck", "power stage clips", "torque sensor"],
)
def test_the_generated_loop_over_the_ticks_gives_the_tick_by_tick_numbers(monkeypatch, changes):
    batched, ticked = _run_both(monkeypatch, changes, 120)
    assert batched == ticked  # bit-identical, not close
    assert batched[1] is None and len(batched[0]) == 120


def test_a_failing_tick_fails_as_tick_by_tick(monkeypatch):
    batched, ticked = _run_both(monkeypatch, {"u_supply": 12.0}, 2000, i_cmd=lambda k: 20.0)
    assert batched[1] is not None and "carriage left the stroke" in batched[1]
    assert batched == ticked  # the same message, tick, state and outputs


def test_the_voltage_limit_holds_and_the_integrator_does_not_wind_up():
    """u_max = 1 V and a 6 A command (R 6 A = 1.8 V: out of reach) for 40 ticks, then 0 A for 60.

    Independent route: a hand-written loop around the motor's exact zero-order-hold discretisation
    (expm of its equations, written out here) with the integrator held while the output is saturated
    and the error pushes further in. The same loop with an unclamped integrator is still saturated
    long after the command dropped: the block must not be."""
    from scipy.linalg import expm

    u_max, T, n1, n = 1.0, LOOP["T_cur"], 40, 100
    blk = drive(u_max=u_max)
    p = blk.params
    J = (
        p["J1_scale"] * (p["J_motor"] + p["J_gearbox"] + p["J_coupling"] + p["J_brake"])
        + p["J_guide"] / p["i_r"] ** 2
        + p["M_load"] * (p["p"] / (2 * math.pi * p["i_r"])) ** 2
    )
    # x = (i, omega): L di/dt = u - R i - k_E omega, J domega/dt = k_T i
    M = np.zeros((3, 3))
    M[:2, :2] = [[-p["R"] / p["L"], -p["k_E"] / p["L"]], [p["k_T"] / J, 0.0]]
    M[0, 2] = 1.0 / p["L"]
    E = expm(M * T)
    Ad, Bd = E[:2, :2], E[:2, 2]
    kp, kiT = LOOP["k_pc"], LOOP["k_ic"] * T

    def loop(clamped: bool) -> np.ndarray:
        x, xc, u, rows = np.zeros(2), 0.0, 0.0, []
        for k in range(n):
            e = (6.0 if k < n1 else 0.0) - x[0]
            v = kp * e + xc
            u_next = min(max(v, -u_max), u_max)
            if not clamped or abs(v) <= u_max or v * e < 0.0:
                xc += kiT * e
            x = Ad @ x + Bd * u
            u = u_next
            rows.append((x[0], u))
        return np.array(rows)

    blk.set(i_cmd=6.0, F=0.0)
    blk.initialize(0.0)
    got = []
    for k in range(n):
        if k == n1:
            blk.set(i_cmd=0.0)
        blk.do_step(k * T, T)
        got.append((blk.get("i_m"), blk.get("u")))
    got, clamped, naive = np.array(got), loop(True), loop(False)

    assert np.abs(got[:, 1]).max() == u_max  # the limit is reached and never exceeded
    assert (got[:n1, 1] == u_max).sum() >= n1 - 2  # saturated while the command is out of reach
    np.testing.assert_allclose(got[:, 0], clamped[:, 0], rtol=0, atol=1e-9 * np.abs(clamped[:, 0]).max())
    np.testing.assert_allclose(got[:, 1], clamped[:, 1], rtol=0, atol=1e-9 * u_max)
    # after the drop: the block's current is back at zero within 15 ticks; the wound-up loop still drives it
    settled = slice(n1 + 15, n)
    assert np.abs(got[settled, 0]).max() < 0.05
    assert naive[n1 + 15, 0] > 1.0 and (naive[n1 : n1 + 15, 1] == u_max).all()
