"""Joint-space cascade controller (fmus/controller/model.py).

The control law is checked by independent routes: the block runs in closed loop
with plants simulated here (exact zero-order-hold discretisation written out in
the test), and its sampled step responses are compared with the closed loops
that python-control builds from transfer functions (c2d of the plant, the PI as
a discrete transfer function, one sample of computation delay, feedback). The
difference equations of the block are documented in docs/controller.md; none of
the block's code is reused here.
"""

from __future__ import annotations

import math

import control as ct
import numpy as np
import pytest
from conftest import RESOURCES
from scipy.linalg import expm

from fmus.common.block import ModelError
from fmus.common.parameters import ParameterError
from fmus.controller.model import ControllerBlock
from fmus.mechanism.kinematics import Geometry, KinematicsError, home_pose, inverse_kinematics
from mast.core.ssv import read_values

# Plant data for the test loops only (Maxon RE 40 24 V catalogue, reference.md section 2);
# the controller under test never sees them.
R_M = 0.299  # ohm
L_M = 0.0823e-3  # H
K_T = 30.2e-3  # N m / A
K_E = 30.2e-3  # V s / rad (SI: equal to k_T)
J_M = 2.44e-5  # kg m^2, motor + reflected load, about what the velocity gains were designed for

AXES = (1, 2, 3)
#: the drive's current loop, which runs in the actuators (restated in the full-cascade test)
DRIVE = read_values(RESOURCES / "drive.ssv")
# Home: all carriages at mid-stroke rho_0 = 0.15 m (actuator_manufacturer.ssv). With psi = theta = 0
# every leg spans the horizontal gap H - r, so z = rho_0 + sqrt(L^2 - (H - r)^2); default geometry
# H = 0.4, r = 0.35, L = 0.26 m (checked against the parameter set in test_home_pose...).
RHO_HOME = 0.15
HOME_Z = RHO_HOME + math.sqrt(0.26**2 - (0.40 - 0.35) ** 2)


def block(params: dict, **changes) -> ControllerBlock:
    return ControllerBlock({**params, **changes})


def set_axes(blk: ControllerBlock, prefix: str, values) -> None:
    blk.set(**{f"{prefix}_{j}": float(v) for j, v in zip(AXES, values)})


def get_axes(blk: ControllerBlock, prefix: str) -> np.ndarray:
    return np.array([blk.get(f"{prefix}_{j}") for j in AXES])


def pi_tf(kp: float, ki: float, T: float) -> ct.TransferFunction:
    """Forward-Euler PI: kp + ki T / (z - 1)."""
    return ct.tf([kp, ki * T - kp], [1.0, -1.0], T)


def delay(T: float) -> ct.TransferFunction:
    return ct.tf([1.0], [1.0, 0.0], T)


def sampled_step(sys: ct.TransferFunction, n: int) -> np.ndarray:
    """y[k], k = 0..n-1, of the unit step response of a discrete system."""
    T = sys.dt
    return np.asarray(ct.step_response(sys, T=np.arange(n) * T).outputs).reshape(-1)


def i_R_of(params: dict) -> float:
    # paper Eq. 1, written out again here
    return params["p"] / (2.0 * math.pi * params["i_r"])


def assert_close(simulated: np.ndarray, expected: np.ndarray, rtol: float = 1e-9) -> None:
    scale = np.max(np.abs(expected))
    assert scale > 0
    err = np.max(np.abs(simulated - expected))
    assert err <= rtol * scale, f"max deviation {err:.3e} vs scale {scale:.3e}"


# --------------------------------------------------------------------------- linear loops


def test_velocity_loop_step_matches_discrete_closed_loop(controller_params):
    """Velocity PI at T_vel = 10 T_cur, ideal current loop, inertia plant; block stepped with h = T_vel."""
    P = controller_params
    T_cur = P["T_cur"]
    T_vel = 10 * T_cur
    blk = block(P, T_vel=T_vel, T_pos=T_vel)
    r = np.array([10.0, -20.0, 5.0])  # rad/s, k_p r well below i_max
    blk.set_mode("velocity", r)
    blk.initialize(0.0)
    n = 300
    w = np.zeros(3)
    w_log, i_log = np.zeros((n, 3)), np.zeros((n, 3))
    for k in range(n):
        i_now = get_axes(blk, "i_cmd")  # ideal current loop: i_m = i_cmd
        w_log[k], i_log[k] = w, i_now
        set_axes(blk, "omega_m", w)
        blk.do_step(k * T_vel, T_vel)  # 10 ticks, inputs held
        w = w + K_T / J_M * T_vel * i_now
    assert blk.ticks == 10 * n
    plant = ct.c2d(ct.tf([K_T], [J_M, 0.0]), T_vel, method="zoh")
    C = pi_tf(P["k_p"], P["k_i"], T_vel)
    y_w = sampled_step(ct.feedback(C * delay(T_vel) * plant, 1), n)
    y_i = sampled_step(delay(T_vel) * ct.feedback(C, delay(T_vel) * plant), n)
    assert np.max(np.abs(i_log)) < P["i_max"]
    for j in range(3):
        assert_close(w_log[:, j], r[j] * y_w)
        assert_close(i_log[:, j], r[j] * y_i)
    np.testing.assert_allclose(w_log[-1], r, rtol=1e-2)


def test_position_loop_step_matches_discrete_closed_loop(controller_params):
    """Position P at T_pos, ideal velocity loop, guide = integrator of i_R omega; joint mode."""
    P = controller_params
    T_pos = P["T_pos"]
    blk = block(P)
    i_R = i_R_of(P)
    r = np.array([0.01, -0.02, 0.005])  # m
    blk.set_mode("joint", r)
    blk.initialize(0.0)
    m = round(T_pos / P["T_cur"])
    n = 200
    rho = np.zeros(3)
    rho_log, w_log = np.zeros((n, 3)), np.zeros((n, 3))
    for k in range(n):
        w_now = get_axes(blk, "omega_cmd")
        rho_log[k], w_log[k] = rho, w_now
        set_axes(blk, "rho", rho)
        blk.do_step(k * T_pos, T_pos)
        assert blk.ticks == (k + 1) * m
        rho = rho + i_R * T_pos * w_now
    plant = ct.c2d(ct.tf([i_R], [1.0, 0.0]), T_pos, method="zoh")
    C = ct.tf([P["k_v"] / i_R], [1.0], T_pos)
    y_rho = sampled_step(ct.feedback(C * delay(T_pos) * plant, 1), n)
    y_w = sampled_step(delay(T_pos) * ct.feedback(C, delay(T_pos) * plant), n)
    for j in range(3):
        assert_close(rho_log[:, j], r[j] * y_rho)
        assert_close(w_log[:, j], r[j] * y_w)
    np.testing.assert_allclose(get_axes(blk, "rho_cmd"), r)


def motor_plant(T: float, i_R: float):
    """Exact ZOH of the stiff axis: x = [i, omega, rho], input u.

    L di/dt = u - R i - k_E omega;  J domega/dt = k_T i;  drho/dt = i_R omega.
    """
    A = np.array([[-R_M / L_M, -K_E / L_M, 0.0], [K_T / J_M, 0.0, 0.0], [0.0, i_R, 0.0]])
    B = np.array([[1.0 / L_M], [0.0], [0.0]])
    M = expm(np.block([[A, B], [np.zeros((1, 4))]]) * T)
    return A, B, M[:3, :3], M[:3, 3]


def test_full_cascade_single_rate_matches_interconnection(controller_params):
    """All three loops at one rate (T_pos = T_vel = T_cur), motor with back-EMF, joint step; the current
    PI (the actuator's, fmus/actuator/drive.py) written out here.

    Checks that within one tick the cascade runs position -> velocity -> current with no
    extra delay between the loops (the controller's commands are direct feedthrough of the samples)
    and one cycle of delay to the plant.
    """
    P = controller_params
    k_pc, k_ic, u_max = (DRIVE[k] for k in ("k_pc", "k_ic", "u_max"))
    T = P["T_cur"]
    i_R = i_R_of(P)
    blk = block(P, T_pos=T, T_vel=T)
    r = np.array([1e-4, -2e-4, 5e-5])  # m, small: no saturation
    blk.set_mode("joint", r)
    blk.initialize(0.0)
    A, B, Ad, Bd = motor_plant(T, i_R)
    n = 2500
    x = np.zeros((3, 3))  # axis x state
    rho_log, u_log = np.zeros((n, 3)), np.zeros((n, 3))
    u_now, x_c = np.zeros(3), np.zeros(3)  # the voltage applied, the current PI's integrator
    for k in range(n):
        rho_log[k], u_log[k] = x[:, 2], u_now
        set_axes(blk, "omega_m", x[:, 1])
        set_axes(blk, "rho", x[:, 2])
        blk.evaluate()  # i_cmd from the samples at t_k
        e = get_axes(blk, "i_cmd") - x[:, 0]
        u_next, x_c = k_pc * e + x_c, x_c + k_ic * T * e
        blk.do_step(k * T, T)
        x = x @ Ad.T + np.outer(u_now, Bd)
        u_now = u_next  # applied from the next tick: one cycle of computation delay
    assert np.max(np.abs(u_log)) < u_max
    # python-control: plant c2d, controller blocks, interconnect by signal names
    plant = ct.c2d(ct.ss(A, B, np.eye(3), np.zeros((3, 1))), T, method="zoh")
    plant = ct.ss(plant.A, plant.B, plant.C, plant.D, T, inputs=["u_applied"], outputs=["i", "w", "rho"])
    dly = ct.ss(delay(T), inputs="u", outputs="u_applied", name="delay")
    cp = ct.ss(ct.tf([P["k_v"] / i_R], [1.0], T), inputs="e_p", outputs="w_cmd", name="cp")
    cv = ct.ss(pi_tf(P["k_p"], P["k_i"], T), inputs="e_w", outputs="i_cmd", name="cv")
    cc = ct.ss(pi_tf(k_pc, k_ic, T), inputs="e_i", outputs="u", name="cc")
    sp = ct.summing_junction(inputs=["r", "-rho"], output="e_p", dt=T)
    sv = ct.summing_junction(inputs=["w_cmd", "-w"], output="e_w", dt=T)
    sc = ct.summing_junction(inputs=["i_cmd", "-i"], output="e_i", dt=T)
    loop = ct.interconnect([plant, dly, cp, cv, cc, sp, sv, sc], inputs="r", outputs=["rho", "u_applied"], dt=T)
    resp = ct.step_response(loop, T=np.arange(n) * T)
    y = np.asarray(resp.outputs).reshape(2, -1)
    for j in range(3):
        assert_close(rho_log[:, j], r[j] * y[0])
        assert_close(u_log[:, j], r[j] * y[1])
    # settles on the command (the loop is stable and tracks)
    np.testing.assert_allclose(rho_log[-1], r, rtol=2e-2)


# --------------------------------------------------------------------------- timing


def test_multirate_outer_loops_hold_between_their_ticks(controller_params):
    """h = T_cur: omega_cmd changes only every N_pos ticks, i_cmd every N_vel ticks."""
    P = controller_params
    T = P["T_cur"]
    N_pos, N_vel = 20, 5
    blk = block(P, T_pos=N_pos * T, T_vel=N_vel * T)
    assert (blk.ticks_per_position, blk.ticks_per_velocity) == (N_pos, N_vel)
    rng = np.random.default_rng(1)
    r = np.array([2e-4, -1e-4, 5e-5])
    blk.set_mode("joint", r)
    blk.initialize(0.0)
    i_R = i_R_of(P)
    prev = {k: get_axes(blk, k) for k in ("omega_cmd", "i_cmd")}
    for n in range(100):
        rho = rng.normal(0, 1e-5, 3)
        w = rng.normal(0, 0.1, 3)
        set_axes(blk, "rho", rho)
        set_axes(blk, "omega_m", w)
        blk.do_step(n * T, T)
        now = {k: get_axes(blk, k) for k in prev}
        if n % N_pos == 0:
            # sampled at this tick: k_v (rho_cmd - rho) / i_R
            np.testing.assert_allclose(now["omega_cmd"], P["k_v"] * (r - rho) / i_R, rtol=1e-12)
        else:
            np.testing.assert_array_equal(now["omega_cmd"], prev["omega_cmd"])
        if n % N_vel == 0:
            assert np.all(now["i_cmd"] != prev["i_cmd"])
        else:
            np.testing.assert_array_equal(now["i_cmd"], prev["i_cmd"])
        prev = now


def test_long_steps_equal_ticks_with_held_inputs(controller_params):
    """do_step with h = 5 T_cur gives the same outputs as 5 steps of T_cur with the inputs held."""
    P = controller_params
    T = P["T_cur"]
    a, b = block(P), block(P)
    for blk in (a, b):
        blk.set_mode("joint", (1e-3, 2e-3, -1e-3))
        blk.initialize(0.0)
    rng = np.random.default_rng(2)
    for s in range(40):
        inputs = {f"rho_{j}": rng.normal(0, 1e-3) for j in AXES}
        inputs |= {f"omega_m_{j}": rng.normal(0, 2.0) for j in AXES}
        a.set(**inputs)
        b.set(**inputs)
        a.do_step(5 * s * T, 5 * T)
        for q in range(5):
            b.do_step((5 * s + q) * T, T)
        assert a.outputs() == b.outputs()


def test_initialize_resets_state_and_outputs(controller_params):
    P = controller_params
    blk = block(P)
    blk.set_mode("velocity", (3.0, 3.0, 3.0))
    blk.initialize(0.0)
    for k in range(50):
        blk.do_step(k * P["T_cur"], P["T_cur"])
    assert np.all(get_axes(blk, "i_cmd") != 0.0)
    blk.set_mode("joint", (0.0, 0.0, 0.0))
    blk.initialize(1.0)
    assert blk.ticks == 0
    for name in ("omega_cmd", "i_cmd", "rho_cmd"):
        np.testing.assert_array_equal(get_axes(blk, name), 0.0)
    # integrators were reset: with zero errors the first tick gives i_cmd = 0
    blk.do_step(1.0, P["T_cur"])
    np.testing.assert_array_equal(get_axes(blk, "i_cmd"), 0.0)


# --------------------------------------------------------------------------- limits and anti-windup


def naive_pi(kp, ki, T, limit):
    """PI with the same saturation but no anti-windup (the integrator always integrates)."""
    state = {"x": 0.0}

    def step(e):
        v = kp * e + state["x"]
        state["x"] += ki * T * e
        return min(max(v, -limit), limit)

    return step


def test_velocity_limit_and_anti_windup(controller_params):
    """Large speed step: i_cmd saturates at i_max; recovery without the naive PI's overshoot."""
    P = controller_params
    T_vel = P["T_vel"]
    blk = block(P)
    target = 1000.0  # rad/s, k_p * target >> i_max
    blk.set_mode("velocity", (target, -target, 0.0))
    blk.initialize(0.0)
    naive = naive_pi(P["k_p"], P["k_i"], T_vel, P["i_max"])
    n = 400
    w, w_naive = np.zeros(3), 0.0
    i_log, w_log, wn_log = np.zeros((n, 3)), np.zeros((n, 3)), np.zeros(n)
    i_naive = 0.0
    for k in range(n):
        i_now = get_axes(blk, "i_cmd")
        i_log[k], w_log[k], wn_log[k] = i_now, w, w_naive
        set_axes(blk, "omega_m", w)
        blk.do_step(k * T_vel, T_vel)
        w = w + K_T / J_M * T_vel * i_now
        w_naive, i_naive = w_naive + K_T / J_M * T_vel * i_naive, naive(target - w_naive)
    assert np.max(np.abs(i_log)) == P["i_max"]  # saturates, never beyond
    assert i_log[5, 0] == P["i_max"] and i_log[5, 1] == -P["i_max"]
    overshoot = np.max(w_log[:, 0]) / target - 1.0
    overshoot_naive = np.max(wn_log) / target - 1.0
    assert overshoot_naive > 0.3  # wind-up with a naive PI ...
    assert overshoot < 0.05  # ... and not with the block's
    np.testing.assert_allclose(w_log[-1, :2], (target, -target), rtol=1e-3)
    np.testing.assert_array_equal(w_log[:, 2], 0.0)


# --------------------------------------------------------------------------- inverse kinematics


def test_home_pose_maps_to_mid_stroke(controller_params):
    """Home pose command -> the IK values, all three carriages at rho_0 (geometry by hand and the DK)."""
    P = controller_params
    assert (P["H"], P["r"], P["L"]) == (0.4, 0.35, 0.26)
    geom = Geometry.from_params(P)
    z, psi, theta = home_pose(geom, RHO_HOME)  # direct kinematics of the mechanism module
    assert z == pytest.approx(HOME_Z, abs=1e-9) and abs(psi) < 1e-9 and abs(theta) < 1e-9
    blk = block(P)
    blk.set(z_cmd=HOME_Z, psi_cmd=0.0, theta_cmd=0.0)
    blk.initialize(0.0)
    np.testing.assert_allclose(get_axes(blk, "rho_cmd"), RHO_HOME, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(get_axes(blk, "rho_cmd"), inverse_kinematics(geom, HOME_Z, 0.0, 0.0))


def test_pose_command_maps_through_the_inverse_kinematics(controller_params):
    P = controller_params
    geom = Geometry.from_params(P)
    blk = block(P)
    for pose in [(HOME_Z + 0.01, 0.02, -0.03), (HOME_Z - 0.02, -0.05, 0.04), (HOME_Z, 0.0, 0.1)]:
        blk.set(z_cmd=pose[0], psi_cmd=pose[1], theta_cmd=pose[2])
        blk.initialize(0.0)
        rho_cmd = get_axes(blk, "rho_cmd")
        np.testing.assert_array_equal(rho_cmd, inverse_kinematics(geom, *pose))
        assert np.ptp(rho_cmd) > 1e-3  # a tilt really moves the joints differently
        for name in ("omega_cmd", "i_cmd"):
            np.testing.assert_array_equal(get_axes(blk, name), 0.0)


def test_pure_z_command_moves_all_joints_equally(controller_params):
    """Vertical guides: a platform translation dz moves every slider by dz (geometry, not code)."""
    P = controller_params
    blk = block(P)
    blk.set(z_cmd=HOME_Z)
    blk.initialize(0.0)
    rho0 = get_axes(blk, "rho_cmd")
    dz = 0.015
    blk.set(z_cmd=HOME_Z + dz)
    blk.do_step(0.0, P["T_cur"])  # tick 0 runs the position loop
    np.testing.assert_allclose(get_axes(blk, "rho_cmd") - rho0, dz, rtol=1e-9)


def test_pose_step_position_loop_response(controller_params):
    """Pose mode, z step from a settled state: each joint follows the closed loop from IK(z0) to IK(z1)."""
    P = controller_params
    geom = Geometry.from_params(P)
    T_pos = P["T_pos"]
    i_R = i_R_of(P)
    rho0 = np.asarray(inverse_kinematics(geom, HOME_Z, 0.01, 0.0))
    rho1 = np.asarray(inverse_kinematics(geom, HOME_Z + 0.01, 0.01, 0.0))
    blk = block(P)
    blk.set(z_cmd=HOME_Z, psi_cmd=0.01)
    set_axes(blk, "rho", rho0)
    blk.initialize(0.0)
    blk.set(z_cmd=HOME_Z + 0.01)
    n = 150
    rho = rho0.copy()
    log = np.zeros((n, 3))
    for k in range(n):
        w_now = get_axes(blk, "omega_cmd")
        log[k] = rho
        set_axes(blk, "rho", rho)
        blk.do_step(k * T_pos, T_pos)
        rho = rho + i_R * T_pos * w_now
    plant = ct.c2d(ct.tf([1.0], [1.0, 0.0]), T_pos, method="zoh")
    y = sampled_step(ct.feedback(P["k_v"] * delay(T_pos) * plant, 1), n)
    for j in range(3):
        assert_close(log[:, j] - rho0[j], (rho1[j] - rho0[j]) * y)


def test_controller_geometry_is_its_own_binding(controller_params):
    """A calibration error in the controller's geometry changes its joint commands."""
    P = controller_params
    nominal, miscalibrated = block(P), block(P, r=P["r"] + 0.002)
    for blk in (nominal, miscalibrated):
        blk.set(z_cmd=HOME_Z, psi_cmd=0.03)
        blk.initialize(0.0)
    d = get_axes(miscalibrated, "rho_cmd") - get_axes(nominal, "rho_cmd")
    assert np.max(np.abs(d)) > 1e-5
    geom = Geometry.from_params({**P, "r": P["r"] + 0.002})
    np.testing.assert_array_equal(get_axes(miscalibrated, "rho_cmd"), inverse_kinematics(geom, HOME_Z, 0.03, 0.0))


# --------------------------------------------------------------------------- errors


@pytest.mark.parametrize(
    "name, value, match",
    [
        ("T_vel", 0.00105, "T_vel"),
        ("T_pos", 0.00015, "T_pos"),
        ("k_p", -0.1, "k_p"),
        ("T_cur", 0.0, "T_cur"),
        ("i_max", 0.0, "i_max"),
        ("p", 0.0, "'p'"),
    ],
)
def test_bad_parameters(controller_params, name, value, match):
    with pytest.raises(ParameterError, match=match):
        block(controller_params, **{name: value})


def test_missing_and_unknown_parameters(controller_params):
    params = dict(controller_params)
    del params["k_v"]
    with pytest.raises(ParameterError, match="k_v"):
        ControllerBlock(params)
    with pytest.raises(ParameterError, match="k_x"):
        ControllerBlock({**controller_params, "k_x": 1.0})


@pytest.mark.parametrize("name", ["omega_m_2", "z_cmd", "omega_m_3", "rho_1"])
@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf])
def test_non_finite_input(controller_params, name, value):
    blk = block(controller_params)
    blk.set(z_cmd=HOME_Z)
    blk.initialize(0.0)
    blk.set(**{name: value})
    with pytest.raises(ModelError, match=name):
        blk.do_step(0.0, controller_params["T_cur"])


def test_non_finite_input_at_initialize(controller_params):
    blk = block(controller_params)
    blk.set(z_cmd=HOME_Z, theta_cmd=math.nan)
    with pytest.raises(ModelError, match="theta_cmd"):
        blk.initialize(0.0)


def test_unreachable_pose_passes_kinematics_error_on(controller_params):
    geom = Geometry.from_params(controller_params)
    bad = (HOME_Z, 1.2, 0.0)  # far beyond the joint range
    with pytest.raises(KinematicsError) as expected:
        inverse_kinematics(geom, *bad)
    blk = block(controller_params)
    blk.set(z_cmd=HOME_Z)
    blk.initialize(0.0)
    blk.set(psi_cmd=bad[1])
    with pytest.raises(KinematicsError) as raised:
        blk.do_step(0.0, controller_params["T_cur"])
    assert str(expected.value) in str(raised.value)
    assert isinstance(raised.value, ModelError)


def test_bad_steps_and_modes(controller_params):
    P = controller_params
    blk = block(P)
    blk.set(z_cmd=HOME_Z)
    blk.initialize(0.0)
    with pytest.raises(ModelError, match="step size"):
        blk.do_step(0.0, 1.5 * P["T_cur"])
    with pytest.raises(ModelError, match="contiguous"):
        blk.do_step(5 * P["T_cur"], P["T_cur"])
    with pytest.raises(ValueError, match="mode"):
        blk.set_mode("torque", (0.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="three"):
        blk.set_mode("current", (1.0, 2.0))
    with pytest.raises(ModelError, match="i_cmd_2"):
        blk.set_mode("current", (1.0, math.nan, 0.0))
