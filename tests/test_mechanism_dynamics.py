"""3PRS inverse dynamics against routes that share no code with it.

- power balance: sum_i F_i rho_dot_i = d/dt (T + V), energies from body poses alone;
- Euler-Lagrange by numbers: L = T - V from body poses alone, derivatives by differences;
- statics: hand calculation at home (T layout) and a 9x9 force/moment balance elsewhere;
- the block: outputs, warm start, errors.

Body poses come from the direct kinematics (checked against the inverse kinematics in
test_mechanism_kinematics.py) and this file's own rotation matrix and joint positions;
velocities and all derivatives are finite differences of positions.
"""

from __future__ import annotations

import math
import time

import numpy as np
import pytest

from fmus.common.block import ModelError
from fmus.common.parameters import ParameterError
from fmus.mechanism.dynamics import Masses, inverse_dynamics, inverse_dynamics_at_pose
from fmus.mechanism.kinematics import Geometry, KinematicsError, direct_kinematics, inverse_kinematics, parasitic
from fmus.mechanism.model import MechanismBlock

DEG = math.pi / 180.0
EZ = np.array([0.0, 0.0, 1.0])


@pytest.fixture
def geom(mechanism_params) -> Geometry:
    return Geometry.from_params(mechanism_params)


@pytest.fixture
def masses(mechanism_params) -> Masses:
    return Masses.from_params(mechanism_params)


# ---- independent body model ------------------------------------------------------------------
def rot(psi, theta, phi):
    cx, sx, cy, sy, cz, sz = (
        math.cos(psi),
        math.sin(psi),
        math.cos(theta),
        math.sin(theta),
        math.cos(phi),
        math.sin(phi),
    )
    return (
        np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
        @ np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
        @ np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    )


def body_poses(geom: Geometry, rho) -> dict:
    """P, R, and per leg: COM (3,), angle gamma, from the slider heights alone."""
    z, psi, theta = direct_kinematics(geom, rho, tol=1e-15)
    x, y, phi = parasitic(geom, z, psi, theta)
    P = np.array([x, y, z])
    R = rot(psi, theta, phi)
    coms, gammas = [], []
    for i, a in enumerate(geom.alpha):
        e = np.array([math.cos(a), math.sin(a), 0.0])
        S = P + R @ (geom.r * e)
        B = geom.H * e + rho[i] * EZ
        coms.append(0.5 * (S + B))
        gammas.append(math.atan2(S[2] - B[2], geom.H - S @ e))
    return {"P": P, "R": R, "com": coms, "gamma": np.array(gammas)}


def vee(W):
    return np.array([W[2, 1] - W[1, 2], W[0, 2] - W[2, 0], W[1, 0] - W[0, 1]]) / 2.0


def kinetic(geom, ms, rho, rho_dot, eps=1e-5) -> float:
    """T from positions at rho -+ eps rho_dot (directional central differences)."""
    rho, rho_dot = np.asarray(rho, float), np.asarray(rho_dot, float)
    bm, b0, bp = (body_poses(geom, rho + k * eps * rho_dot) for k in (-1, 0, 1))
    v = (bp["P"] - bm["P"]) / (2 * eps)
    w = vee(b0["R"].T @ (bp["R"] - bm["R"]) / (2 * eps))
    T = 0.5 * ms.m_platform * v @ v + 0.5 * w @ (np.array([ms.I_px, ms.I_py, ms.I_pz]) * w)
    for i in range(3):
        vc = (bp["com"][i] - bm["com"][i]) / (2 * eps)
        gd = (bp["gamma"][i] - bm["gamma"][i]) / (2 * eps)
        T += 0.5 * ms.m_leg * vc @ vc + 0.5 * ms.I_leg * gd * gd
    return T


def potential(geom, ms, rho) -> float:
    b = body_poses(geom, np.asarray(rho, float))
    return ms.g * (ms.m_platform * b["P"][2] + ms.m_leg * sum(c[2] for c in b["com"]))


def ddt(f, t, h=2e-4):
    """Fourth-order central difference f'(t)."""
    return (-f(t + 2 * h) + 8 * f(t + h) - 8 * f(t - h) + f(t - 2 * h)) / (12 * h)


class Trajectory:
    """rho_i(t) = rho0_i + A_i sin(2 pi f_i t + p_i): smooth, inside the workspace."""

    def __init__(self, geom, seed, amp=0.03, fmax=5.0, tilt=10.0):
        rng = np.random.default_rng(seed)
        self.rho0 = inverse_kinematics(
            geom, 0.40 + rng.uniform(-0.02, 0.02), rng.uniform(-tilt, tilt) * DEG, rng.uniform(-tilt, tilt) * DEG
        )
        self.A = rng.uniform(0.3, 1.0, 3) * amp
        self.w = 2 * math.pi * rng.uniform(0.5, 1.0, 3) * fmax
        self.p = rng.uniform(0, 2 * math.pi, 3)

    def __call__(self, t):
        s = self.w * t + self.p
        return (self.rho0 + self.A * np.sin(s), self.A * self.w * np.cos(s), -self.A * self.w**2 * np.sin(s))


# ---- power balance ---------------------------------------------------------------------------------
def test_power_balance_along_random_trajectories(geom, masses):
    for seed in (1, 2, 3):
        traj = Trajectory(geom, seed)
        energy = lambda t: kinetic(geom, masses, traj(t)[0], traj(t)[1]) + potential(geom, masses, traj(t)[0])  # noqa
        powers, balances = [], []
        for t in np.linspace(0.0, 0.4, 9):
            rho, rd, rdd = traj(t)
            F = inverse_dynamics(geom, masses, rho, rd, rdd).t_rho
            powers.append(F @ rd)
            balances.append(ddt(energy, t))
        powers, balances = np.array(powers), np.array(balances)
        scale = np.abs(powers).max()
        assert scale > 1.0  # a real test: watts flow
        np.testing.assert_allclose(powers, balances, atol=1e-6 * scale)


def test_power_balance_catches_a_missing_term(geom, masses):
    """Sanity of the test itself: without the leg inertia I_leg the balance fails."""
    traj = Trajectory(geom, 4)
    wrong = Masses(masses.m_leg, 0.0, masses.m_platform, masses.I_px, masses.I_py, masses.I_pz, masses.g)
    errors, scale = [], 0.0
    for t in np.linspace(0.0, 0.3, 7):
        rho, rd, rdd = traj(t)
        energy = lambda s: kinetic(geom, masses, traj(s)[0], traj(s)[1]) + potential(geom, masses, traj(s)[0])  # noqa
        dE = ddt(energy, t)
        errors.append(inverse_dynamics(geom, wrong, rho, rd, rdd).t_rho @ rd - dE)
        scale = max(scale, abs(dE))
    assert np.abs(errors).max() > 100 * 1e-6 * scale  # 100 x the tolerance of the balance test


# ---- Euler-Lagrange by numbers -----------------------------------------------------------------------
def lagrange_forces(geom, ms, traj, t):
    """E(L) = d/dt dT/drhodot - dT/drho + dV/drho, by central differences of positions only."""
    rho, rd, rdd = traj(t)
    eta_v, eta_q = 0.05, 1e-5
    E = np.eye(3)

    def momentum(rho_, rd_):  # T is quadratic in rho_dot: a wide central difference is exact
        return np.array(
            [
                (kinetic(geom, ms, rho_, rd_ + eta_v * e) - kinetic(geom, ms, rho_, rd_ - eta_v * e)) / (2 * eta_v)
                for e in E
            ]
        )

    dpdt = ddt(lambda s: momentum(*traj(s)[:2]), t)
    dTdq = np.array(
        [(kinetic(geom, ms, rho + eta_q * e, rd) - kinetic(geom, ms, rho - eta_q * e, rd)) / (2 * eta_q) for e in E]
    )
    dVdq = np.array(
        [(potential(geom, ms, rho + eta_q * e) - potential(geom, ms, rho - eta_q * e)) / (2 * eta_q) for e in E]
    )
    M = np.array([momentum(rho, e) for e in E]).T  # dT/drhodot at rhodot = e_k -> column k of M
    return dpdt - dTdq + dVdq, dVdq, M


def test_euler_lagrange_by_numbers(geom, masses):
    for seed, t in ((11, 0.05), (12, 0.17), (13, 0.31), (14, 0.42)):
        traj = Trajectory(geom, seed)
        rho, rd, rdd = traj(t)
        res = inverse_dynamics(geom, masses, rho, rd, rdd)
        F_el, G_el, M_el = lagrange_forces(geom, masses, traj, t)
        scale = np.abs(res.t_rho).max()
        np.testing.assert_allclose(res.t_rho, F_el, atol=1e-6 * scale)
        np.testing.assert_allclose(res.g_term, G_el, atol=1e-6 * scale)
        np.testing.assert_allclose(res.M, M_el, atol=1e-6)
        np.testing.assert_allclose(res.I_term, res.M @ rdd, atol=1e-12)
        np.testing.assert_allclose(res.I_term + res.c_term + res.g_term, res.t_rho, atol=1e-12)
        # the velocity terms alone: E(L) with gravity and acceleration terms removed
        c_el = F_el - G_el - M_el @ rdd
        np.testing.assert_allclose(res.c_term, c_el, atol=1e-6 * scale)
        assert np.abs(res.c_term).max() > 100 * 1e-6 * scale  # the velocity terms are really exercised


class Line:
    """rho(t) = rho0 + t rho_dot: no acceleration, so E(L) - gravity = the velocity terms alone."""

    def __init__(self, rho0, rho_dot):
        self.rho0, self.rd = np.asarray(rho0, float), np.asarray(rho_dot, float)

    def __call__(self, t):
        return self.rho0 + t * self.rd, self.rd, np.zeros(3)


def test_velocity_terms_by_euler_lagrange_at_speed(geom, masses):
    for q, rd in (
        ((0.40, 10 * DEG, -8 * DEG), (1.0, -0.8, 0.5)),
        ((0.38, -12 * DEG, 5 * DEG), (-0.6, 0.9, 1.0)),
        ((0.42, 0.0, 0.0), (0.0, 1.0, -1.0)),
    ):
        line = Line(inverse_kinematics(geom, *q), rd)
        res = inverse_dynamics_at_pose(geom, masses, q, rd, (0, 0, 0))
        F_el, G_el, _ = lagrange_forces(geom, masses, line, 0.0)
        assert np.abs(res.c_term).max() > 0.05
        np.testing.assert_allclose(res.c_term, F_el - G_el, atol=2e-5 * np.abs(res.c_term).max())


def test_mass_matrix_is_symmetric_positive_definite(geom, masses):
    for q in ((0.40, 0.0, 0.0), (0.43, 12 * DEG, -9 * DEG), (0.37, -14 * DEG, 3 * DEG)):
        M = inverse_dynamics_at_pose(geom, masses, q, (0, 0, 0), (0, 0, 0)).M
        np.testing.assert_allclose(M, M.T, atol=1e-15)
        assert np.linalg.eigvalsh(M).min() > 0


def test_velocity_terms_are_quadratic_and_gravity_free(geom, masses):
    q = (0.41, 7 * DEG, -4 * DEG)
    rd = np.array([0.1, -0.2, 0.15])
    c1 = inverse_dynamics_at_pose(geom, masses, q, rd, (0, 0, 0)).c_term
    c2 = inverse_dynamics_at_pose(geom, masses, q, 2 * rd, (0, 0, 0)).c_term
    np.testing.assert_allclose(c2, 4 * c1, rtol=1e-12, atol=1e-14)
    res = inverse_dynamics_at_pose(geom, masses, q, (0, 0, 0), (0, 0, 0))
    np.testing.assert_allclose(res.c_term, 0, atol=1e-15)
    np.testing.assert_allclose(res.I_term, 0, atol=1e-15)


# ---- statics ------------------------------------------------------------------------------------------
def statics(geom, ms, q):
    """Actuator forces at rest by a 9x9 force/moment balance (massless sliders, frictionless guides).

    Unknowns: F_i, the force leg i exerts on the platform. Platform: sum F_i = m_p g e_z,
    sum (S_i - P) x F_i = 0. Leg i: no moment about its revolute axis t_i at the slider.
    The slider (vertical guide: horizontal reactions only) then needs A_i = F_iz + m_leg g.
    """
    z, psi, theta = q
    x, y, phi = parasitic(geom, z, psi, theta)
    rho = inverse_kinematics(geom, z, psi, theta)
    P, R = np.array([x, y, z]), rot(psi, theta, phi)
    A = np.zeros((9, 9))
    b = np.zeros(9)
    b[2] = ms.m_platform * ms.g
    for i, a in enumerate(geom.alpha):
        e = np.array([math.cos(a), math.sin(a), 0.0])
        t = np.array([-math.sin(a), math.cos(a), 0.0])
        S = P + R @ (geom.r * e)
        B = geom.H * e + rho[i] * EZ
        C = 0.5 * (S + B)
        cols = slice(3 * i, 3 * i + 3)
        A[0:3, cols] = np.eye(3)
        arm = S - P
        A[3:6, cols] = np.array([[0, -arm[2], arm[1]], [arm[2], 0, -arm[0]], [-arm[1], arm[0], 0]])
        # ((S - B) x (-F)) . t + ((C - B) x (-m g e_z)) . t = 0  ->  ((S - B) x F) . t = -((C - B) x m g e_z) . t
        A[6 + i, cols] = np.cross(t, S - B)  # (u x F) . t = F . (t x u)
        b[6 + i] = -np.cross(C - B, ms.m_leg * ms.g * EZ) @ t
    F = np.linalg.solve(A, b).reshape(3, 3)
    return F[:, 2] + ms.m_leg * ms.g


def test_static_forces_at_home_match_hand_calculation(geom, masses):
    rho = [0.15, 0.15, 0.15]
    res = inverse_dynamics(geom, masses, rho, (0, 0, 0), (0, 0, 0))
    W_p, W_l = masses.m_platform * masses.g, masses.m_leg * masses.g
    # T layout at home: moments about x put no load on leg 2's spherical joint; legs 1 and 3
    # share the platform equally; every slider also carries its own leg.
    np.testing.assert_allclose(res.t_rho, [W_p / 2 + W_l, W_l, W_p / 2 + W_l], atol=1e-12)
    assert res.t_rho.sum() == pytest.approx(W_p + 3 * W_l, abs=1e-12)
    np.testing.assert_allclose(res.pose, [0.15 + math.sqrt(geom.L**2 - (geom.H - geom.r) ** 2), 0, 0], atol=1e-12)
    np.testing.assert_allclose(statics(geom, masses, res.pose), res.t_rho, atol=1e-12)


def test_static_forces_elsewhere_match_force_balance(geom, masses):
    rng = np.random.default_rng(21)
    geoms = (geom, Geometry(geom.H, geom.r, geom.L, (0.0, 2 * math.pi / 3, 4 * math.pi / 3)))
    for g in geoms:
        for _ in range(8):
            q = (0.40 + rng.uniform(-0.05, 0.05), rng.uniform(-15, 15) * DEG, rng.uniform(-15, 15) * DEG)
            res = inverse_dynamics_at_pose(g, masses, q, (0, 0, 0), (0, 0, 0))
            np.testing.assert_allclose(res.t_rho, statics(g, masses, q), atol=1e-10)
            assert res.t_rho.sum() == pytest.approx((masses.m_platform + 3 * masses.m_leg) * masses.g, abs=1e-10)


def test_120_layout_power_balance(geom, masses):
    g = Geometry(geom.H, geom.r, geom.L, (0.0, 2 * math.pi / 3, 4 * math.pi / 3))
    traj = Trajectory(g, 31)
    energy = lambda s: kinetic(g, masses, traj(s)[0], traj(s)[1]) + potential(g, masses, traj(s)[0])  # noqa
    for t in (0.03, 0.21):
        rho, rd, rdd = traj(t)
        F = inverse_dynamics(g, masses, rho, rd, rdd).t_rho
        assert F @ rd == pytest.approx(ddt(energy, t), abs=1e-6 * abs(F).max() * abs(rd).max() * 3)


# ---- the block ---------------------------------------------------------------------------------------------
def test_block_outputs_and_warm_start(mechanism_params, geom, masses):
    blk = MechanismBlock(mechanism_params)
    assert set(blk.UNITS) == set(blk.INPUTS + blk.OUTPUTS) == set(blk.DESCRIPTIONS)
    blk.set(rho_1=0.15, rho_2=0.15, rho_3=0.15)
    blk.initialize(0.0)
    out = blk.outputs()
    assert out["z"] == pytest.approx(0.405147016, abs=1e-9)
    assert out["F_1"] == pytest.approx(10.791, abs=1e-9) and out["F_2"] == pytest.approx(0.6867, abs=1e-9)
    traj = Trajectory(geom, 41)
    for k in range(50):
        t = k * 1e-3
        rho, rd, rdd = traj(t + 1e-3)
        blk.set(
            **{f"rho_{i + 1}": rho[i] for i in range(3)},
            **{f"rho_dot_{i + 1}": rd[i] for i in range(3)},
            **{f"rho_ddot_{i + 1}": rdd[i] for i in range(3)},
        )
        blk.do_step(t, 1e-3)
    res = inverse_dynamics(geom, masses, rho, rd, rdd)
    out = blk.outputs()
    np.testing.assert_allclose([out["F_1"], out["F_2"], out["F_3"]], res.t_rho, atol=1e-9)
    np.testing.assert_allclose([out["z"], out["psi"], out["theta"]], res.pose, atol=1e-12)
    np.testing.assert_allclose([out["x"], out["y"], out["phi"]], res.parasitic, atol=1e-12)


def test_block_speed(mechanism_params):
    blk = MechanismBlock(mechanism_params)
    blk.set(rho_1=0.15, rho_2=0.15, rho_3=0.15)
    blk.initialize(0.0)
    n = 300
    start = time.perf_counter()
    for k in range(n):
        blk.set(rho_1=0.15 + 1e-5 * k, rho_dot_1=0.01, rho_ddot_2=0.1)
        blk.do_step(k * 1e-3, 1e-3)
    per_step = (time.perf_counter() - start) / n
    assert per_step < 1e-3  # generous: about 0.07 ms here; 1 ms would be real time


def test_block_errors(mechanism_params):
    blk = MechanismBlock(mechanism_params)
    blk.set(rho_1=0.15, rho_2=0.15, rho_3=0.15, rho_dot_2=math.nan)
    with pytest.raises(ModelError, match="rho_dot_2"):
        blk.initialize(0.0)
    blk.set(rho_dot_2=0.0, rho_2=0.6)  # no assembly exists
    with pytest.raises(KinematicsError, match=r"MechanismBlock: at t = 0.001 s.*did not converge"):
        blk.do_step(0.0, 1e-3)


def test_inverse_dynamics_input_errors(geom, masses):
    with pytest.raises(KinematicsError, match="rho_ddot_3"):
        inverse_dynamics(geom, masses, (0.15,) * 3, (0, 0, 0), (0, 0, math.nan))
    with pytest.raises(KinematicsError, match="did not converge"):
        inverse_dynamics(geom, masses, (0.0, 0.6, 0.0), (0, 0, 0), (0, 0, 0))


@pytest.mark.parametrize(
    "change, name",
    [
        ({"r": 0.45}, "'r'"),  # spherical joints outside the guides
        ({"L": 0.04}, "'L'"),  # legs cannot reach
        ({"alpha_2": 0.0}, "'alpha_1'"),  # two guides on top of each other
        ({"m_leg": -1.0}, "'m_leg'"),
        ({"m_platform": 0.0}, "'m_platform'"),
        ({"H": 0.0}, "'H'"),
        ({"alpha_3": 7.0}, "'alpha_3'"),
        ({"I_pz": math.nan}, "'I_pz'"),
    ],
)
def test_bad_parameters_are_named(mechanism_params, change, name):
    with pytest.raises(ParameterError, match=name):
        MechanismBlock({**mechanism_params, **change})


def _joint_motion(t: float) -> dict:
    """Three sliders 10 mm at 3 Hz, a third of a period apart, with a 1 kHz ripple of 2 m/s^2 on the accelerations
    (what the current loop puts on them): the inputs of the update-period tests."""
    A, w, out = 0.01, 2 * math.pi * 3.0, {}
    for k in range(1, 4):
        phase = w * t + 2 * math.pi * (k - 1) / 3
        out[f"rho_{k}"] = 0.15 + A * math.sin(phase)
        out[f"rho_dot_{k}"] = A * w * math.cos(phase)
        out[f"rho_ddot_{k}"] = -A * w * w * math.sin(phase) + 2.0 * math.sin(2 * math.pi * 1000.0 * t)
    return out


def test_the_block_makes_its_full_update_every_update_period(mechanism_params):
    """T_mech (mechanism.model.UPDATE_PERIOD; 1 ms in the systems, attached.ssv): stepped every 100 us, the block
    makes its full update on the 1 ms grid, there equal to a block without one (T_mech = 0) stepped every 1 ms with
    the inputs of the same instants; between, the pose held, and the forces those a full update computes at the
    last update's joint positions and velocities with the step's accelerations (a second block: its direct
    kinematics and forces anew), whatever the positions and velocities set meanwhile."""
    T = mechanism_params["T_mech"]
    assert T == 1e-3
    every_n = round(T / 1e-4)
    fast = MechanismBlock(mechanism_params)
    every = MechanismBlock({**mechanism_params, "T_mech": 0.0})
    probe = MechanismBlock({**mechanism_params, "T_mech": 0.0})
    for blk in (fast, every, probe):
        blk.set(**_joint_motion(0.0))
        blk.initialize(0.0)
    pose = ("z", "psi", "theta")
    updated, worst = {}, 0.0
    for n in range(40):
        t = n * 1e-4
        inputs = _joint_motion(t)
        held = fast.outputs()
        fast.set(**inputs)
        fast.do_step(t, 1e-4)
        got = fast.outputs()
        if n % every_n == 0:
            every.set(**inputs)
            every.do_step(t, T)
            assert got == every.outputs(), t
            updated = {k: v for k, v in inputs.items() if not k.startswith("rho_ddot")}
            continue
        assert [got[c] for c in pose] == [held[c] for c in pose], t
        probe.set(**updated, **{k: v for k, v in inputs.items() if k.startswith("rho_ddot")})
        probe.do_step(t, 1e-4)
        expected = probe.outputs()
        worst = max(worst, max(abs(got[f"F_{k}"] - expected[f"F_{k}"]) / abs(expected[f"F_{k}"]) for k in (1, 2, 3)))
        assert got["F_1"] != held["F_1"], t  # the accelerations act at every step
    assert worst < 1e-12


def test_the_update_period_s_forces_against_an_update_at_every_step(mechanism_params):
    """The price of T_mech = 1 ms: 0.3 s of the 3 Hz motion (``_joint_motion``) stepped every 100 us, the forces
    within 5e-4 of their peak of those of a full update at every step (measured 1.3e-4: 2.2 mN of 16.4 N), the pose
    within what the joints move in 1 ms."""
    fast = MechanismBlock(mechanism_params)
    every = MechanismBlock({**mechanism_params, "T_mech": 0.0})
    for blk in (fast, every):
        blk.set(**_joint_motion(0.0))
        blk.initialize(0.0)
    worst = peak = 0.0
    for n in range(3000):
        t = n * 1e-4
        for blk in (fast, every):
            blk.set(**_joint_motion(t))
            blk.do_step(t, 1e-4)
        a, e = fast.outputs(), every.outputs()
        worst = max(worst, *(abs(a[f"F_{k}"] - e[f"F_{k}"]) for k in (1, 2, 3)))
        peak = max(peak, *(abs(e[f"F_{k}"]) for k in (1, 2, 3)))
        assert abs(a["z"] - e["z"]) < 0.01 * 2 * math.pi * 3.0 * 1e-3, t
    assert peak > 10.0 and worst < 5e-4 * peak


def test_the_inertial_reaction_between_updates_refuses_a_non_finite_acceleration_by_name(mechanism_params):
    """Between full updates (T_mech) only the accelerations are read: a NaN or inf among them is refused with the
    input's name; finite accelerations whose sum overflows (the generated reaction's quick check) still give the
    forces F = M rho_ddot + b, the sum of the products, linear in rho_ddot."""
    blk = MechanismBlock(mechanism_params)
    blk.set(**_joint_motion(0.0))
    blk.initialize(0.0)
    blk.do_step(0.0, 1e-4)  # a full update at t = 0
    for name, bad in (("rho_ddot_2", math.nan), ("rho_ddot_3", -math.inf)):
        blk.set(**{**_joint_motion(1e-4), name: bad})
        with pytest.raises(ModelError, match=rf"input '{name}' = {bad!r} is not finite at t = 0.0002 s"):
            blk.do_step(1e-4, 1e-4)
    forces = {}
    for a in (1e307, 1e308):  # 1e308 + 1e308 overflows, each input is finite
        blk.set(rho_ddot_1=a, rho_ddot_2=a, rho_ddot_3=0.0)
        blk.do_step(1e-4, 1e-4)
        forces[a] = [blk.outputs()[f"F_{k}"] for k in (1, 2, 3)]
    for small, large in zip(forces[1e307], forces[1e308]):
        assert math.isfinite(small) and small != 0.0
        if math.isinf(large):  # M rho_ddot beyond the largest float: its sign
            assert math.copysign(1.0, large) == math.copysign(1.0, small)
        else:
            assert large == pytest.approx(10.0 * small, rel=1e-12)
