"""Every mechanism design against routes that share no code with the engine.

This file's own model of a 3-PRS (any guide layout and inclination, with a payload): its
own rotation matrix, the parasitic motion by Newton's method on S_i . t_i = 0, the slider
position from |S_i - B_i(rho_i)| = L as a quadratic along the guide, energies from body
poses alone, every derivative by finite differences. The dynamics are checked in the
independent coordinates q = (z, psi, theta), so no direct kinematics enters them:

- power balance t_rho . rho_dot = d/dt (T + V) along random trajectories;
- Euler-Lagrange by numbers: t_rho = J^T (d/dt dT/dq_dot - dT/dq + dV/dq), J = dq/drho, and
  the mass matrix, gravity and velocity terms separately;
- static equilibrium: a 9x9 force/moment balance of platform, payload and legs;
- IK against this file's IK, IK/DK round trips (cold and warm);
- the workspace boundary and the approach to a singularity: a KinematicsError that says
  why, or a finite result with a growing condition number; never a NaN;
- the 3PRS of the paper: the Appendix A Jacobians (typos fixed, docs/mechanism.md) and the
  closed-form model of kinematics.py/dynamics.py agree with the engine;
- the designs as systems: FMU co-simulation equals the direct composition, each variant
  system differs from the default one only by the swap.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from fmus.controller.model import ControllerBlock
from fmus.mechanism import designs
from fmus.mechanism.dynamics import Masses, inverse_dynamics_at_pose
from fmus.mechanism.kinematics import Geometry, KinematicsError, jacobians
from fmus.mechanism.model import MechanismBlock
from mast.core.designs import DESIGNS, variant_ssd
from mast.core.ssp import read_ssd

DEG = math.pi / 180.0
EZ = np.array([0.0, 0.0, 1.0])
PAYLOAD = {
    "m_payload": 1.7,
    "payload_x": 0.04,
    "payload_y": -0.03,
    "payload_z": 0.09,
    "I_payload_xx": 0.012,
    "I_payload_yy": 0.009,
    "I_payload_zz": 0.015,
    "I_payload_xy": 0.001,
    "I_payload_xz": -0.002,
    "I_payload_yz": 0.0015,
}


def system_params(design_name: str, component: str = "mechanism") -> dict:
    """The component's parameters as the design's system binds them (each its own names of a shared set)."""
    from mast.core.build import default_parameters

    d = next(d for d in DESIGNS if d.name == design_name)
    source = read_ssd(d.ssd).components[component].source
    return default_parameters(Path(source).stem, d.ssd)


CASES = {
    "3PRS_T": lambda: system_params("3PRS_T"),
    "3PRS_120": lambda: system_params("3PRS_120"),
    "3PRS_inclined": lambda: system_params("3PRS_inclined"),
    "3PRS_T+payload": lambda: {**system_params("3PRS_T"), **PAYLOAD},
    "3PRS_inclined+payload": lambda: {**system_params("3PRS_inclined"), **PAYLOAD},
}


@pytest.fixture(params=list(CASES))
def case(request):
    params = CASES[request.param]()
    return request.param, params, designs.engine(params), Own(params)


# ---- this file's own model ---------------------------------------------------------------------
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


def vee(W):
    return np.array([W[2, 1] - W[1, 2], W[0, 2] - W[2, 0], W[1, 0] - W[0, 1]]) / 2.0


class Own:
    """A 3-PRS from its parameters: guides through H e_i at z = 0 with direction
    cos(beta) e_z - sin(beta) e_i, revolute axes t_i, spherical joints at r e_i on the platform."""

    def __init__(self, P: dict) -> None:
        self.H, self.r, self.L, self.beta = P["H"], P["r"], P["L"], P["beta"]
        self.g = P["g"]
        self.e, self.t, self.d = [], [], []
        for a in (P["alpha_1"], P["alpha_2"], P["alpha_3"]):
            e = np.array([math.cos(a), math.sin(a), 0.0])
            self.e.append(e)
            self.t.append(np.array([-math.sin(a), math.cos(a), 0.0]))
            self.d.append(math.cos(self.beta) * EZ - math.sin(self.beta) * e)
        self.m_leg, self.I_leg, self.m_p = P["m_leg"], P["I_leg"], P["m_platform"]
        self.I_p = np.diag([P["I_px"], P["I_py"], P["I_pz"]])
        self.m_pl = P.get("m_payload", 0.0)
        self.c_pl = np.array([P.get("payload_x", 0.0), P.get("payload_y", 0.0), P.get("payload_z", 0.0)])
        xy, xz, yz = P.get("I_payload_xy", 0.0), P.get("I_payload_xz", 0.0), P.get("I_payload_yz", 0.0)
        self.I_pl = np.array(
            [
                [P.get("I_payload_xx", 0.0), xy, xz],
                [xy, P.get("I_payload_yy", 0.0), yz],
                [xz, yz, P.get("I_payload_zz", 0.0)],
            ]
        )

    def parasitic(self, q):
        """(x, y, phi) by Newton on S_i . t_i = 0 (analytic Jacobian), from (0, 0, 0)."""
        z, psi, theta = q
        p = np.zeros(3)
        for _ in range(30):
            R = rot(psi, theta, p[2])
            P = np.array([p[0], p[1], z])
            res = np.array([t @ (P + R @ (self.r * e)) for e, t in zip(self.e, self.t)])
            Jm = np.array([[t[0], t[1], t @ np.cross(EZ, R @ (self.r * e))] for e, t in zip(self.e, self.t)])
            step = np.linalg.solve(Jm, res)
            p = p - step
            if np.abs(step).max() < 1e-17:
                break
        return p

    def poses(self, q):
        z, psi, theta = q
        x, y, phi = self.parasitic(q)
        P, R = np.array([x, y, z]), rot(psi, theta, phi)
        out = {"P": P, "R": R, "S": [], "B": [], "rho": []}
        for e, d in zip(self.e, self.d):
            S = P + R @ (self.r * e)
            delta = S - self.H * e
            a = d @ delta
            rho = a - math.sqrt(a * a - delta @ delta + self.L**2)  # the root below S_i
            out["S"].append(S)
            out["B"].append(self.H * e + rho * d)
            out["rho"].append(rho)
        out["rho"] = np.array(out["rho"])
        return out

    def rho(self, q):
        return self.poses(q)["rho"]

    def kinetic(self, q, qd, eps=1e-5):
        q, qd = np.asarray(q, float), np.asarray(qd, float)
        m, b0, p = (self.poses(q + k * eps * qd) for k in (-1, 0, 1))
        v = (p["P"] - m["P"]) / (2 * eps)
        w = vee(b0["R"].T @ (p["R"] - m["R"]) / (2 * eps))
        T = 0.5 * self.m_p * v @ v + 0.5 * w @ self.I_p @ w
        vc = v + b0["R"] @ np.cross(w, self.c_pl)  # payload centre of mass
        T += 0.5 * self.m_pl * vc @ vc + 0.5 * w @ self.I_pl @ w
        for i in range(3):
            cm, cp = 0.5 * (m["S"][i] + m["B"][i]), 0.5 * (p["S"][i] + p["B"][i])
            u0 = (b0["S"][i] - b0["B"][i]) / self.L
            ud = ((p["S"][i] - p["B"][i]) - (m["S"][i] - m["B"][i])) / (2 * eps * self.L)
            om = np.cross(u0, ud)  # planar leg: omega = u x u_dot
            vc_leg = (cp - cm) / (2 * eps)
            T += 0.5 * self.m_leg * vc_leg @ vc_leg + 0.5 * self.I_leg * om @ om
        return T

    def potential(self, q):
        b = self.poses(np.asarray(q, float))
        h = self.m_p * b["P"][2] + self.m_pl * (b["P"] + b["R"] @ self.c_pl)[2]
        h += self.m_leg * sum(0.5 * (S[2] + B[2]) for S, B in zip(b["S"], b["B"]))
        return self.g * h

    def drho_dq(self, q, h=1e-6):
        q = np.asarray(q, float)
        return np.array([(self.rho(q + h * e) - self.rho(q - h * e)) / (2 * h) for e in np.eye(3)]).T


def home(own: Own, rho0: float = 0.15) -> float:
    """z of the level pose with every slider at rho0 (this file's geometry)."""
    base = own.H * own.e[0] + rho0 * own.d[0]
    gap = own.r - base @ own.e[0]
    return base[2] + math.sqrt(own.L**2 - gap**2)


def ddt(f, t, h):
    return (-f(t + 2 * h) + 8 * f(t + h) - 8 * f(t - h) + f(t - 2 * h)) / (12 * h)


def d2dt2(f, t, h):
    return (-f(t + 2 * h) + 16 * f(t + h) - 30 * f(t) + 16 * f(t - h) - f(t - 2 * h)) / (12 * h * h)


class Path3:
    """q(t) = q0 + A sin(w t + p): a smooth random motion inside the workspace."""

    def __init__(self, own: Own, seed: int, tilt: float = 8.0) -> None:
        rng = np.random.default_rng(seed)
        self.q0 = np.array(
            [home(own) + rng.uniform(-0.015, 0.015), rng.uniform(-tilt, tilt) * DEG, rng.uniform(-tilt, tilt) * DEG]
        )
        self.A = np.array([0.02, 6 * DEG, 6 * DEG]) * rng.uniform(0.4, 1.0, 3)
        self.w = 2 * math.pi * rng.uniform(2.0, 5.0, 3)
        self.p = rng.uniform(0, 2 * math.pi, 3)

    def q(self, t):
        return self.q0 + self.A * np.sin(self.w * t + self.p)

    def qd(self, t):
        return self.A * self.w * np.cos(self.w * t + self.p)

    def qdd(self, t):
        return -self.A * self.w**2 * np.sin(self.w * t + self.p)


def joint_motion(own: Own, path: Path3, t: float):
    """rho, rho_dot, rho_ddot along the path, by this file's IK and differences in time."""
    r = lambda s: own.rho(path.q(s))  # noqa: E731
    return r(t), ddt(r, t, 1e-4), d2dt2(r, t, 1e-3)


# ---- dynamics ----------------------------------------------------------------------------------
def test_power_balance_along_random_trajectories(case):
    name, params, eng, own = case
    for seed in (1, 2):
        path = Path3(own, seed)

        def energy(s, path=path):
            return own.kinetic(path.q(s), path.qd(s)) + own.potential(path.q(s))

        powers, balances = [], []
        for t in np.linspace(0.0, 0.3, 5):
            rho, rd, rdd = joint_motion(own, path, t)
            F = eng.inverse_dynamics_at_pose(path.q(t), rd, rdd).t_rho
            powers.append(F @ rd)
            balances.append(ddt(energy, t, 2e-4))
        powers, balances = np.array(powers), np.array(balances)
        scale = np.abs(powers).max()
        assert scale > 1.0, name
        np.testing.assert_allclose(powers, balances, atol=2e-6 * scale, err_msg=name)


def lagrange_in_q(own: Own, path: Path3, t: float):
    """Q_q = d/dt dT/dq_dot - dT/dq + dV/dq by differences of body poses; also M_q and dV/dq."""
    q, qd = path.q(t), path.qd(t)
    E = np.eye(3)

    def momentum(qq, vv):  # T is quadratic in q_dot: a wide central difference is exact
        return np.array([(own.kinetic(qq, vv + 0.05 * e) - own.kinetic(qq, vv - 0.05 * e)) / 0.1 for e in E])

    dpdt = ddt(lambda s: momentum(path.q(s), path.qd(s)), t, 2e-4)
    h = 1e-5
    dTdq = np.array([(own.kinetic(q + h * e, qd) - own.kinetic(q - h * e, qd)) / (2 * h) for e in E])
    dVdq = np.array([(own.potential(q + h * e) - own.potential(q - h * e)) / (2 * h) for e in E])
    Mq = np.array([momentum(q, e) for e in E]).T
    return dpdt - dTdq + dVdq, dVdq, Mq


def test_euler_lagrange_by_numbers(case):
    name, params, eng, own = case
    for seed, t in ((11, 0.05), (12, 0.21)):
        path = Path3(own, seed)
        rho, rd, rdd = joint_motion(own, path, t)
        res = eng.inverse_dynamics_at_pose(path.q(t), rd, rdd)
        Qq, Gq, Mq = lagrange_in_q(own, path, t)
        J = np.linalg.inv(own.drho_dq(path.q(t)))  # dq/drho
        F, G, M = J.T @ Qq, J.T @ Gq, J.T @ Mq @ J
        scale = np.abs(res.t_rho).max()
        np.testing.assert_allclose(res.t_rho, F, atol=2e-6 * scale, err_msg=name)
        np.testing.assert_allclose(res.g_term, G, atol=2e-6 * scale, err_msg=name)
        np.testing.assert_allclose(res.M, M, atol=2e-6 * np.abs(M).max(), err_msg=name)
        np.testing.assert_allclose(res.c_term, F - G - M @ rdd, atol=2e-6 * scale, err_msg=name)
        assert np.abs(res.c_term).max() > 100 * 2e-6 * scale  # the velocity terms are exercised
        np.testing.assert_allclose(res.I_term + res.c_term + res.g_term, res.t_rho, atol=1e-12)
        np.testing.assert_allclose(sum(i + c + g for i, c, g in res.terms.values()), res.t_rho, atol=1e-11)


def statics(own: Own, q):
    """Actuator forces at rest: 9x9 balance of the platform (+ payload) and the legs.

    Unknowns f_i: force of leg i on the platform. Platform: sum f_i = (m_p + m_pl) g e_z and
    sum (S_i - P) x f_i = (C_pl - P) x m_pl g e_z. Leg i: no moment about its revolute axis at
    the slider. Massless slider on a frictionless guide: actuator force = d_i . (f_i + m_leg g e_z).
    """
    b = own.poses(q)
    A, rhs = np.zeros((9, 9)), np.zeros(9)
    rhs[2] = (own.m_p + own.m_pl) * own.g
    rhs[3:6] = np.cross(b["R"] @ own.c_pl, own.m_pl * own.g * EZ)
    for i in range(3):
        S, B, t = b["S"][i], b["B"][i], own.t[i]
        cols = slice(3 * i, 3 * i + 3)
        A[0:3, cols] = np.eye(3)
        arm = S - b["P"]
        A[3:6, cols] = np.array([[0, -arm[2], arm[1]], [arm[2], 0, -arm[0]], [-arm[1], arm[0], 0]])
        A[6 + i, cols] = np.cross(t, S - B)
        rhs[6 + i] = -np.cross(0.5 * (S + B) - B, own.m_leg * own.g * EZ) @ t
    f = np.linalg.solve(A, rhs).reshape(3, 3)
    return np.array([own.d[i] @ (f[i] + own.m_leg * own.g * EZ) for i in range(3)])


def test_static_equilibrium(case):
    name, params, eng, own = case
    rng = np.random.default_rng(21)
    for _ in range(6):
        q = (home(own) + rng.uniform(-0.03, 0.03), rng.uniform(-12, 12) * DEG, rng.uniform(-12, 12) * DEG)
        res = eng.inverse_dynamics_at_pose(q, (0, 0, 0), (0, 0, 0))
        np.testing.assert_allclose(res.t_rho, statics(own, q), atol=1e-10, err_msg=name)
        np.testing.assert_allclose(res.t_rho, res.g_term, atol=0)
        if own.beta == 0.0:  # vertical frictionless guides carry no vertical load
            total = (own.m_p + own.m_pl + 3 * own.m_leg) * own.g
            assert res.t_rho.sum() == pytest.approx(total, abs=1e-10)


def test_mass_matrix_symmetric_positive_definite(case):
    name, params, eng, own = case
    for q in ((home(own), 0.0, 0.0), (home(own) + 0.02, 10 * DEG, -7 * DEG)):
        M = eng.inverse_dynamics_at_pose(q, (0, 0, 0), (0, 0, 0)).M
        np.testing.assert_allclose(M, M.T, atol=0)
        assert np.linalg.eigvalsh(M).min() > 0, name


# ---- kinematics ---------------------------------------------------------------------------------
def test_ik_and_dk_round_trips(case):
    name, params, eng, own = case
    rng = np.random.default_rng(2)
    for _ in range(25):
        q = np.array([home(own) + rng.uniform(-0.04, 0.04), rng.uniform(-15, 15) * DEG, rng.uniform(-15, 15) * DEG])
        rho = own.rho(q)
        np.testing.assert_allclose(eng.ik(q), rho, atol=1e-12, err_msg=name)
        np.testing.assert_allclose(eng.dk(rho)[0], q, atol=1e-11, err_msg=name)  # cold
        np.testing.assert_allclose(eng.dk(rho, guess=q + 0.01)[0], q, atol=1e-11, err_msg=name)  # warm
        x, y, phi = own.parasitic(q)
        np.testing.assert_allclose(eng.pose(q), [x, y, q[0], q[1], q[2], phi], atol=1e-14, err_msg=name)


def test_jacobians_and_rates_against_differences(case):
    """J = dq/drho from this file's IK; body velocity Jacobians and "Jdot rho_dot" from positions."""
    name, params, eng, own = case
    q = np.array([home(own) + 0.01, 7 * DEG, -5 * DEG])
    rd = np.array([0.3, -0.5, 0.2])
    jac = eng.jacobians(q, rd)
    J = np.linalg.inv(own.drho_dq(q))
    np.testing.assert_allclose(jac.J, J, atol=1e-8)
    # along rho(s) = rho0 + s rd (rho_ddot = 0): the platform centre's velocity and acceleration
    rho0 = own.rho(q)
    P = lambda s: own.poses(eng.dk(rho0 + s * rd, tol=1e-15)[0])["P"]  # noqa: E731
    np.testing.assert_allclose(jac.v["platform"], ddt(P, 0.0, 1e-4), atol=1e-8)
    np.testing.assert_allclose(jac.J_v["platform"] @ rd, jac.v["platform"], atol=1e-14)
    np.testing.assert_allclose(
        jac.a0["platform"], d2dt2(P, 0.0, 2e-3), atol=1e-5 * (1 + np.abs(jac.a0["platform"]).max())
    )


def test_controller_uses_the_design_kinematics(controller_params):
    """A swap changes the controller's joint commands through its geometry binding alone."""
    base = ControllerBlock(controller_params)
    for design in ("3PRS_120", "3PRS_inclined"):
        P = system_params(design, "controller")
        blk = ControllerBlock(P)
        own = Own({**P, **{k: 0.0 for k in ("m_leg", "I_leg", "m_platform", "I_px", "I_py", "I_pz")}, "g": 9.81})
        pose = (home(own) + 0.01, 0.05, -0.03)
        for b in (blk, base):
            b.set(z_cmd=pose[0], psi_cmd=pose[1], theta_cmd=pose[2])
            b.initialize(0.0)
        rho_cmd = np.array([blk.get(f"rho_cmd_{j}") for j in (1, 2, 3)])
        np.testing.assert_allclose(rho_cmd, own.rho(pose), atol=1e-12)
        assert np.abs(rho_cmd - [base.get(f"rho_cmd_{j}") for j in (1, 2, 3)]).max() > 1e-4


# ---- boundary and singularities -------------------------------------------------------------------
REASONS = ("unreachable", "singular", "out of range", "did not converge")


def probe(eng, q):
    """Everything the engine offers at q: finite numbers, or a KinematicsError saying why."""
    try:
        rho = eng.ik(q)
        _, J, cond = eng.jacobian(q)
        res = eng.inverse_dynamics_at_pose(q, (0.2, -0.1, 0.3), (1.0, 2.0, -1.0))
    except KinematicsError as exc:
        assert any(r in str(exc) for r in REASONS), str(exc)
        return None
    values = np.concatenate([rho, J, res.t_rho, res.M.ravel(), res.pose, [cond]])
    assert np.all(np.isfinite(values)), (q, values)
    return cond


@pytest.mark.parametrize(
    "direction", [(0.0, 1.0, 0.0), (0.0, 0.0, -1.0), (0.0, 0.7, 0.7), (1.0, 0.0, 0.0), (-1.0, 0.0, 0.0)]
)
def test_rays_to_the_workspace_boundary(case, direction):
    """Walking out of the workspace: finite results up to a clear error, never a NaN."""
    name, params, eng, own = case
    q0 = np.array([home(own), 0.0, 0.0])
    scale = np.array([0.4, 70 * DEG, 70 * DEG])
    outcomes = [probe(eng, q0 + s * scale * np.array(direction)) for s in np.linspace(0.0, 1.0, 141)]
    assert outcomes[0] is not None
    first_failure = next((k for k, c in enumerate(outcomes) if c is None), None)
    if direction[0] == 0.0:
        assert first_failure is not None, name  # a tilt of 70 deg is out of range
    # the reachable part is one piece: no pose works again after the first failure along the ray
    if first_failure is not None:
        assert all(c is None for c in outcomes[first_failure:]) or direction[0] != 0.0


def test_singularity_is_flagged_then_refused(case):
    """Tilting until a leg stands perpendicular to its guide (Jq singular, the reach lost): the
    condition number of drho/dq grows without bound, then a clear error. The legs are shortened
    so that this happens inside the admissible tilt (the designs themselves reach 60 deg)."""
    name, params, _, _ = case
    short = {**params, "L": params["H"] - params["r"] * math.cos(params["beta"]) + 0.06}
    eng, own = designs.engine(short), Own(short)
    z = home(own)
    lo, hi = 0.0, 59.0 * DEG  # psi: find where the pose stops being reachable
    assert probe(eng, (z, 0.0, lo)) is not None and probe(eng, (z, 0.0, hi)) is None, name
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if probe(eng, (z, 0.0, mid)) is not None else (lo, mid)
    conds = [probe(eng, (z, 0.0, lo - d)) for d in (1e-2, 1e-4, 1e-6)]
    assert all(c is not None for c in conds), name
    assert conds[0] < conds[1] < conds[2] and conds[2] > 30 * conds[0], (name, conds)  # the flag
    with pytest.raises(KinematicsError, match="unreachable"):
        eng.ik((z, 0.0, hi + 1e-9))
    res = eng.inverse_dynamics_at_pose((z, 0.0, lo - 1e-6), (0, 0, 0), (0, 0, 0))
    assert res.cond == pytest.approx(conds[2]) and np.all(np.isfinite(res.t_rho))


def test_degenerate_layout_is_singular():
    file = designs.description("3PRS")
    desc = file.describe({**file.values(), "alpha_2": 0.0, "alpha_3": math.pi})  # two guides on top of each other
    with pytest.raises(KinematicsError, match="singular"):
        designs.Engine(desc).ik((0.4, 0.05, 0.05))


def test_direct_kinematics_outside_the_workspace(case):
    name, params, eng, own = case
    with pytest.raises(KinematicsError, match="did not converge"):
        eng.dk((0.0, 0.6, 0.0))
    with pytest.raises(KinematicsError, match="not finite"):
        eng.dk((0.15, math.nan, 0.15))


# ---- the paper's 3PRS: Appendix A and the closed form -------------------------------------------------
def test_engine_agrees_with_appendix_a(mechanism_params):
    from test_mechanism_kinematics import appendix, poses

    eng = designs.engine(mechanism_params)
    geom = Geometry.from_params(mechanism_params)
    for q in poses(geom, 15, seed=6):
        jac = eng.jacobians(q)
        gamma = jacobians(geom, *q).pose.gamma
        Jx, Jq, JxJq, Jb, JR = appendix(geom, q, gamma)
        np.testing.assert_allclose(jac.J, JxJq, atol=1e-12)
        for i, flip in ((0, 1.0), (1, 1.0), (2, -1.0)):  # bar 3: the paper's x is -radial
            e = np.array([math.cos(geom.alpha[i]), math.sin(geom.alpha[i]), 0.0])
            leg = f"leg_{i + 1}"
            rows = np.array([flip * (e @ jac.J_v[leg]), jac.J_v[leg][2], jac.J_w[leg][1]])  # radial, height, gamma
            np.testing.assert_allclose(rows, Jb[i], atol=1e-12)
        np.testing.assert_allclose(jac.J_v["platform"], jacobians(geom, *q).J_G, atol=1e-12)
        np.testing.assert_allclose(jac.J_w["platform"], JR, atol=1e-12)


@pytest.mark.parametrize("alpha", [(0.0, math.pi / 2, math.pi), (0.0, 2 * math.pi / 3, 4 * math.pi / 3)])
def test_engine_agrees_with_the_closed_form(mechanism_params, alpha):
    P = {**mechanism_params, "alpha_1": alpha[0], "alpha_2": alpha[1], "alpha_3": alpha[2]}
    eng, geom, ms = designs.engine(P), Geometry.from_params(P), Masses.from_params(P)
    rng = np.random.default_rng(8)
    from fmus.mechanism.kinematics import inverse_kinematics

    for _ in range(20):
        q = (0.405 + rng.uniform(-0.04, 0.04), rng.uniform(-15, 15) * DEG, rng.uniform(-15, 15) * DEG)
        rd, rdd = rng.uniform(-1, 1, 3), rng.uniform(-10, 10, 3)
        assert tuple(eng.ik(q)) == tuple(inverse_kinematics(geom, *q))  # same floats
        new, old = eng.inverse_dynamics_at_pose(q, rd, rdd), inverse_dynamics_at_pose(geom, ms, q, rd, rdd)
        scale = np.abs(old.t_rho).max()
        for a, b in (
            (new.t_rho, old.t_rho),
            (new.I_term, old.I_term),
            (new.c_term, old.c_term),
            (new.g_term, old.g_term),
        ):
            np.testing.assert_allclose(a, b, atol=1e-12 * scale)
        np.testing.assert_allclose(new.M, old.M, atol=1e-14)


# ---- the designs as blocks and systems ------------------------------------------------------------------
def test_actuators_only_exerts_no_force_and_reports_the_kinematics():
    P = system_params("actuators_only")
    assert P["attached"] == 0
    blk, loaded = MechanismBlock(P), MechanismBlock({**P, "attached": 1})
    rng = np.random.default_rng(4)
    for b in (blk, loaded):
        b.set(rho_1=0.15, rho_2=0.15, rho_3=0.15)
        b.initialize(0.0)
    for k in range(20):
        rho = 0.15 + rng.uniform(-0.02, 0.02, 3)
        inputs = {**{f"rho_{i + 1}": rho[i] for i in range(3)}, "rho_dot_1": 0.3, "rho_ddot_2": 4.0}
        for b in (blk, loaded):
            b.set(**inputs)
            b.do_step(k * 1e-3, 1e-3)
        out, ref = blk.outputs(), loaded.outputs()
        assert (out["F_1"], out["F_2"], out["F_3"]) == (0.0, 0.0, 0.0)
        assert abs(ref["F_1"]) > 1.0
        for name in ("x", "y", "z", "psi", "theta", "phi"):
            assert out[name] == ref[name]


def test_payload_adds_its_weight_and_moves_the_load(mechanism_params):
    bare, loaded = MechanismBlock(mechanism_params), MechanismBlock({**mechanism_params, **PAYLOAD})
    for b in (bare, loaded):
        b.set(rho_1=0.15, rho_2=0.15, rho_3=0.15)
        b.initialize(0.0)
    F0 = np.array([bare.get(f"F_{i}") for i in (1, 2, 3)])
    F1 = np.array([loaded.get(f"F_{i}") for i in (1, 2, 3)])
    assert (F1 - F0).sum() == pytest.approx(PAYLOAD["m_payload"] * 9.81, abs=1e-10)
    assert F1[0] - F0[0] > F1[2] - F0[2]  # centre of mass towards guide 1 (+x)
    with pytest.raises(Exception, match="I_payload"):
        MechanismBlock({**mechanism_params, **PAYLOAD, "I_payload_xy": 0.5})  # not positive semi-definite


def test_bad_design_parameters_are_named(mechanism_params):
    from fmus.common.parameters import ParameterError

    with pytest.raises(ParameterError, match="'kinematics'"):
        MechanismBlock({**mechanism_params, "kinematics": "6UPS"})
    with pytest.raises(ParameterError, match="'beta'"):
        MechanismBlock({**mechanism_params, "beta": 1.2})  # beyond 45 deg
    with pytest.raises(ParameterError, match="'H', 'r', 'L', 'beta'"):
        MechanismBlock({**mechanism_params, "beta": 0.6})  # no assembly


def test_variant_systems_differ_from_the_default_only_by_the_swap():
    default = read_ssd(DESIGNS[0].ssd)
    for d in DESIGNS[1:]:
        assert d.ssd.read_bytes() == variant_ssd(d), f"{d.ssd.name} is stale: run python -m mast.core.variants"
        system = read_ssd(d.ssd)
        assert [c.__dict__ for c in system.connections] == [c.__dict__ for c in default.connections]
        for name, comp in system.components.items():
            ref = default.components[name]
            assert (comp.inputs, comp.outputs, comp.step_size) == (ref.inputs, ref.outputs, ref.step_size)
            changed = {
                k for k in set(comp.parameters) | set(ref.parameters) if comp.parameters.get(k) != ref.parameters.get(k)
            }
            if name == "mechanism":
                assert Path(comp.source).stem == d.model_identifier
            else:
                assert comp.source == ref.source
            allowed = set(designs.KINEMATIC_PARAMETERS_NAMES) | {"attached", "g_guide"}
            assert changed <= allowed, (d.name, name, changed)
        assert (
            system.components["mechanism"].parameters.items()
            >= {
                k: v
                for k, v in system.components["controller"].parameters.items()
                if k in designs.KINEMATIC_PARAMETERS_NAMES
            }.items()
        )  # one geometry for both


@pytest.fixture(scope="module")
def design_systems(tmp_path_factory):
    from mast.core.build import FMUS, build_fmu, build_ssp

    out = tmp_path_factory.mktemp("designs")
    needed = {"MastActuator", "MastController"} | {d.model_identifier for d in DESIGNS[1:]}
    for spec in FMUS:
        if spec.model_identifier in needed:
            build_fmu(spec, out / "fmus")
    return {d.name: build_ssp(d.ssd, out / "fmus", out / "ssp") for d in DESIGNS[1:]}


def test_design_fmus_reproduce_the_direct_composition(design_systems):
    from mast.core.motion import SineMotion
    from mast.core.run import simulate

    for name, ssp in design_systems.items():
        motion = dict(axis="theta", amplitude=math.radians(2.0), frequency=3.0)
        fmi = simulate(ssp, SineMotion(**motion), 0.2)
        direct = simulate(ssp, SineMotion(**motion), 0.2, direct=True)
        for signal in fmi.signals:
            np.testing.assert_allclose(fmi[signal], direct[signal], rtol=1e-12, atol=1e-14, err_msg=f"{name} {signal}")
        assert np.ptp(fmi["mechanism.theta"]) > math.radians(1.0)
        F = fmi["mechanism.F_1"]
        assert np.all(F == 0.0) if name == "actuators_only" else np.all(F > 0.0)
