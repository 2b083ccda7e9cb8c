"""3PRS kinematics: constraints, IK/DK, every Jacobian and Jdot*rhodot against finite
differences, the paper's Appendix A (typos fixed, docs/mechanism.md), errors.

Independent routes: positions are rebuilt here from (P, R) with this file's own rotation
matrix; Jacobians are checked by central differences of positions only."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fmus.common.block import ModelError
from fmus.common.parameters import ParameterError
from fmus.mechanism.kinematics import (
    MAX_TILT,
    Geometry,
    KinematicsError,
    direct_kinematics,
    full_pose,
    home_pose,
    inverse_kinematics,
    jacobian_rates,
    jacobians,
    parasitic,
)

DEG = math.pi / 180.0
T_ALPHA = (0.0, math.pi / 2, math.pi)
Y_ALPHA = (0.0, 2 * math.pi / 3, 4 * math.pi / 3)


@pytest.fixture
def geom(mechanism_params) -> Geometry:
    return Geometry.from_params(mechanism_params)


@pytest.fixture
def geom120(mechanism_params) -> Geometry:
    g = Geometry.from_params(mechanism_params)
    return Geometry(g.H, g.r, g.L, Y_ALPHA)


def poses(geom: Geometry, n: int, seed: int = 1) -> np.ndarray:
    """Random (z, psi, theta): z around home +-0.05 m, psi, theta within +-15 deg."""
    rng = np.random.default_rng(seed)
    z0 = 0.15 + math.sqrt(geom.L**2 - (geom.H - geom.r) ** 2)
    return np.column_stack(
        [z0 + rng.uniform(-0.05, 0.05, n), rng.uniform(-15, 15, n) * DEG, rng.uniform(-15, 15, n) * DEG]
    )


# ---- this file's own geometry (not the module's) ------------------------------------------
def rot(psi: float, theta: float, phi: float) -> np.ndarray:
    cx, sx, cy, sy, cz, sz = (
        math.cos(psi),
        math.sin(psi),
        math.cos(theta),
        math.sin(theta),
        math.cos(phi),
        math.sin(phi),
    )
    Rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    Ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    Rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return Rz @ Ry @ Rx


def units(geom: Geometry, i: int):
    a = geom.alpha[i]
    e = np.array([math.cos(a), math.sin(a), 0.0])
    t = np.array([-math.sin(a), math.cos(a), 0.0])
    return e, t


def bodies(geom: Geometry, q) -> dict:
    """Body positions from the actuated pose: P, R, S_i, sliders, leg coordinates."""
    z, psi, theta = q
    x, y, phi = parasitic(geom, z, psi, theta)
    rho = inverse_kinematics(geom, z, psi, theta)
    P = np.array([x, y, z])
    R = rot(psi, theta, phi)
    out = {"P": P, "R": R, "rho": rho, "S": [], "B": [], "leg": []}
    for i in range(3):
        e, t = units(geom, i)
        S = P + R @ (geom.r * e)
        B = geom.H * e + np.array([0, 0, rho[i]])
        com = 0.5 * (S + B)
        gamma = math.atan2(S[2] - B[2], geom.H - S @ e)
        out["S"].append(S)
        out["B"].append(B)
        out["leg"].append(np.array([com @ e, com[2], gamma]))
    return out


def vee(W: np.ndarray) -> np.ndarray:
    return np.array([W[2, 1] - W[1, 2], W[0, 2] - W[2, 0], W[1, 0] - W[0, 1]]) / 2.0


# ---- constraints, closed forms -------------------------------------------------------------
def test_constraints_and_leg_lengths_both_layouts(geom, geom120):
    for g in (geom, geom120):
        for q in poses(g, 40):
            b = bodies(g, q)
            sol = full_pose(g, *q)
            for i in range(3):
                e, t = units(g, i)
                assert abs(b["S"][i] @ t) < 1e-14  # S_i . t_i = 0 (leg in its plane)
                assert np.linalg.norm(b["S"][i] - b["B"][i]) == pytest.approx(g.L, abs=1e-14)
                assert b["S"][i][2] > b["B"][i][2]  # legs point up
                assert g.H - b["S"][i] @ e > 0  # S_i inside the guide radius
                np.testing.assert_allclose(sol.S[i], b["S"][i], atol=1e-14)
                # leg direction = L (-cos gamma e_i + sin gamma e_z)
                gam = sol.gamma[i]
                np.testing.assert_allclose(
                    b["S"][i] - b["B"][i], g.L * (-math.cos(gam) * e + math.sin(gam) * np.array([0, 0, 1])), atol=1e-14
                )
            np.testing.assert_allclose(sol.R, b["R"], atol=1e-15)


def test_t_layout_parasitic_closed_form(geom):
    for z, psi, theta in poses(geom, 50):
        x, y, phi = parasitic(geom, z, psi, theta)
        assert x == pytest.approx(-geom.r * math.sin(theta) * math.sin(psi), abs=1e-15)
        assert abs(y) < 1e-15 and abs(phi) < 1e-15


def test_120_layout_has_yaw_and_side_motion(geom120):
    x, y, phi = parasitic(geom120, 0.4, 10 * DEG, 10 * DEG)
    assert abs(phi) > 1e-3 and abs(x) > 1e-5 and abs(y) > 1e-3
    # known result for the symmetric 120 deg 3PRS with R = Rz Ry Rx:
    # phi = atan(sin psi sin theta / (cos psi + cos theta)); guide 1 (on x) gives y = -r sin(phi) cos(theta)
    for psi, theta in ((10 * DEG, 10 * DEG), (-7 * DEG, 12 * DEG), (14 * DEG, -3 * DEG)):
        x, y, phi = parasitic(geom120, 0.4, psi, theta)
        assert phi == pytest.approx(
            math.atan2(math.sin(psi) * math.sin(theta), math.cos(psi) + math.cos(theta)), abs=1e-14
        )
        assert y == pytest.approx(-geom120.r * math.sin(phi) * math.cos(theta), abs=1e-15)


def test_home_pose(geom):
    q = home_pose(geom, 0.15)
    z0 = 0.15 + math.sqrt(geom.L**2 - (geom.H - geom.r) ** 2)
    np.testing.assert_allclose(q, [z0, 0, 0], atol=1e-13)
    assert z0 == pytest.approx(0.405147, abs=1e-6)
    np.testing.assert_allclose(inverse_kinematics(geom, z0, 0, 0), [0.15] * 3, atol=1e-15)


def test_ik_dk_round_trip(geom, geom120):
    for g in (geom, geom120):
        for q in poses(g, 60, seed=2):
            rho = inverse_kinematics(g, *q)
            np.testing.assert_allclose(direct_kinematics(g, rho), q, atol=1e-11)  # cold start
            np.testing.assert_allclose(direct_kinematics(g, rho, guess=q + 0.01), q, atol=1e-11)


# ---- Jacobians against central differences --------------------------------------------------
def fd_jac(f, x0, eps):
    x0 = np.asarray(x0, float)
    cols = [(np.asarray(f(x0 + eps * e)) - np.asarray(f(x0 - eps * e))) / (2 * eps) for e in np.eye(len(x0))]
    return np.array(cols).T


@pytest.mark.parametrize("layout", ["T", "120"])
def test_jacobians_against_finite_differences(geom, geom120, layout):
    g = geom if layout == "T" else geom120
    for q in poses(g, 12, seed=3):
        jac = jacobians(g, *q)
        rho = inverse_kinematics(g, *q)
        dk = lambda r: direct_kinematics(g, r, guess=q)  # noqa: E731
        eps = 1e-6
        np.testing.assert_allclose(jac.J, fd_jac(dk, rho, eps), atol=2e-8)
        np.testing.assert_allclose(jac.J_inv, fd_jac(lambda qq: inverse_kinematics(g, *qq), q, eps), atol=2e-8)
        np.testing.assert_allclose(np.linalg.solve(jac.Jx, jac.Jq), jac.J, atol=1e-12)
        np.testing.assert_allclose(jac.K, fd_jac(lambda qq: parasitic(g, *qq), q, eps), atol=2e-8)
        body = lambda r: bodies(g, dk(r))  # noqa: E731
        for i in range(3):
            np.testing.assert_allclose(jac.J_b[i], fd_jac(lambda r: body(r)["leg"][i], rho, eps), atol=1e-7)
        np.testing.assert_allclose(jac.J_G, fd_jac(lambda r: body(r)["P"], rho, eps), atol=2e-8)
        R0 = body(rho)["R"]
        JR = np.array(
            [vee(R0.T @ (body(rho + eps * e)["R"] - body(rho - eps * e)["R"]) / (2 * eps)) for e in np.eye(3)]
        ).T
        np.testing.assert_allclose(jac.J_R, JR, atol=1e-7)


@pytest.mark.parametrize("layout", ["T", "120"])
def test_jacobian_rates_against_finite_differences(geom, geom120, layout):
    """Jdot rhodot = acceleration along rho(t) = rho0 + t rhodot (rho_ddot = 0)."""
    g = geom if layout == "T" else geom120
    rng = np.random.default_rng(4)
    for q in poses(g, 10, seed=5):
        rho = inverse_kinematics(g, *q)
        rd = rng.uniform(-1.0, 1.0, 3)
        rates = jacobian_rates(g, *q, rd)
        # cold start and a tight tolerance: a warm-started Newton step would be linear in rho
        dk = lambda r: direct_kinematics(g, r, tol=1e-15)  # noqa: E731
        h = 3e-4
        # second differences of positions (fully independent of the Jacobians)
        qdd = (dk(rho + h * rd) - 2 * dk(rho) + dk(rho - h * rd)) / h**2
        np.testing.assert_allclose(rates.Jdot, qdd, atol=1e-5 * (1 + np.abs(qdd).max()))
        b = [bodies(g, dk(rho + k * h * rd)) for k in (-1, 0, 1)]
        Pdd = (b[2]["P"] - 2 * b[1]["P"] + b[0]["P"]) / h**2
        np.testing.assert_allclose(rates.J_G_dot, Pdd, atol=1e-5 * (1 + np.abs(Pdd).max()))
        for i in range(3):
            legdd = (b[2]["leg"][i] - 2 * b[1]["leg"][i] + b[0]["leg"][i]) / h**2
            np.testing.assert_allclose(rates.J_b_dot[i], legdd, atol=1e-5 * (1 + np.abs(legdd).max()))
        # velocities
        np.testing.assert_allclose(rates.qdot, (dk(rho + 1e-6 * rd) - dk(rho - 1e-6 * rd)) / 2e-6, atol=1e-8)

        # angular: w(t) = vee(R^T Rdot) by central differences, then its derivative
        def w_at(s):
            Rm, R0, Rp = (bodies(g, dk(rho + (s + k * 1e-5) * rd))["R"] for k in (-1, 0, 1))
            return vee(R0.T @ (Rp - Rm) / 2e-5)

        np.testing.assert_allclose(rates.w, w_at(0.0), rtol=1e-8, atol=1e-8)
        h2 = 2e-4
        wdot = (w_at(h2) - w_at(-h2)) / (2 * h2)
        np.testing.assert_allclose(rates.J_R_dot, wdot, atol=1e-5 * (1 + np.abs(wdot).max()))
        # and via the Jacobians themselves: d/dt (J(rho(t))) rhodot
        Jp, Jm = jacobians(g, *dk(rho + h * rd)), jacobians(g, *dk(rho - h * rd))
        np.testing.assert_allclose(rates.J_R_dot, (Jp.J_R - Jm.J_R) @ rd / (2 * h), rtol=1e-5, atol=1e-5)
        np.testing.assert_allclose(
            rates.J_b_dot, np.einsum("ijk,k->ij", Jp.J_b - Jm.J_b, rd) / (2 * h), rtol=1e-5, atol=1e-5
        )


# ---- the paper's Appendix A, typos fixed (docs/mechanism.md) ---------------------------------
def appendix(geom: Geometry, q, gamma):
    """Appendix A matrices for the T layout, written from the paper with the fixes noted."""
    L, r = geom.L, geom.r
    z, psi, th = q
    g1, g2, g3 = gamma
    s, c = math.sin, math.cos
    Jx = np.array(
        [
            [L * s(g1), L * r * s(th) * c(psi) * c(g1), L * r * c(th) * s(psi) * c(g1) + L * r * s(th - g1)],  # A.2-4
            [
                L * s(g2),
                L * r * (s(psi) * c(g2) + c(th) * c(psi) * s(g2)),
                -L * r * s(th) * s(psi) * s(g2),
            ],  # A.7 FIXED: gamma_1 -> gamma_2 and sign + -> -
            [
                L * s(g3),
                -L * r * s(th) * c(psi) * c(g3),
                -L * r * c(th) * s(psi) * c(g3) + L * r * s(th + g3),
            ],  # A.8-10
        ]
    )
    Jq = np.diag([L * s(g1), L * s(g2), L * s(g3)])  # A.11
    JxJq = np.linalg.solve(Jx, Jq)
    A1 = np.array(
        [
            [0, -0.5 * r * s(th) * c(psi), -0.5 * (r * s(th) + r * c(th) * s(psi))],
            [0.5, 0, -0.5 * r * c(th)],
            [0, -r * s(th) * c(psi) / (L * s(g1)), -(r * s(th) + r * c(th) * s(psi)) / (L * s(g1))],
        ]
    )
    Jb1 = A1 @ JxJq + np.array([[0, 0, 0], [0.5, 0, 0], [0, 0, 0]])  # A.24
    A2 = np.array(
        [[0, -0.5 * r * s(psi), 0], [0, -c(g2) / (2 * s(g2)) * r * s(psi), 0], [0, -r * s(psi) / (L * s(g2)), 0]]
    )
    Jb2 = A2 @ JxJq + np.array([[0, 0, 0], [0, 1, 0], [0, 0, 0]])  # A.28
    A3 = np.array(
        [
            [0, -0.5 * r * s(th) * c(psi), +0.5 * (r * s(th) - r * c(th) * s(psi))],  # FIXED sign
            [0.5, 0, 0.5 * r * c(th)],
            [0, r * s(th) * c(psi) / (L * s(g3)), -(r * s(th) - r * c(th) * s(psi)) / (L * s(g3))],
        ]
    )  # FIXED + -> -
    Jb3 = A3 @ JxJq + np.array([[0, 0, 0], [0, 0, 0.5], [0, 0, 0]])  # A.29
    JR = np.array([[1, 0], [0, c(psi)], [0, -s(psi)]]) @ JxJq[1:3, :]  # A.32
    return Jx, Jq, JxJq, (Jb1, Jb2, Jb3), JR


def test_appendix_jacobians_after_fixing_typos(geom):
    for q in poses(geom, 30, seed=6):
        jac = jacobians(geom, *q)
        Jx, Jq, JxJq, Jb, JR = appendix(geom, q, jac.pose.gamma)
        np.testing.assert_allclose(jac.Jx, Jx, atol=1e-14)
        np.testing.assert_allclose(jac.Jq, Jq, atol=1e-14)
        np.testing.assert_allclose(jac.J, JxJq, atol=1e-12)
        np.testing.assert_allclose(jac.J_b[0], Jb[0], atol=1e-12)  # bar 1: radial = +x
        np.testing.assert_allclose(jac.J_b[1], Jb[1], atol=1e-12)  # bar 2: radial = +y
        flip = np.diag([-1.0, 1.0, 1.0])  # bar 3: radial = -x, the paper uses x
        np.testing.assert_allclose(flip @ jac.J_b[2], Jb[2], atol=1e-12)
        np.testing.assert_allclose(jac.J_R, JR, atol=1e-12)


def test_appendix_typos_are_real(geom):
    """The printed A.7 and A.29 do not match finite differences: the fixes are needed."""
    q = (0.41, 8 * DEG, -11 * DEG)
    jac = jacobians(geom, *q)
    L, r = geom.L, geom.r
    g1, g2, g3 = jac.pose.gamma
    z, psi, th = q
    printed_a7 = L * r * math.sin(th) * math.sin(psi) * math.sin(g1)
    assert abs(printed_a7 - jac.Jx[1, 2]) > 1e-4
    printed_a29_13 = -0.5 * (r * math.sin(th) - r * math.cos(th) * math.sin(psi))
    fixed_a29_13 = -printed_a29_13
    # entry (1, 3) of the pose part of J_b3 is the x_3 velocity per theta_dot at zdot = psidot = 0
    dx3_dtheta = -(jac.J_b[2] @ np.linalg.solve(jac.J, [0, 0, 1.0]))[0]
    assert dx3_dtheta == pytest.approx(fixed_a29_13, abs=1e-12)
    assert abs(dx3_dtheta - printed_a29_13) > 1e-3


def test_appendix_loop_closure_velocities(geom):
    """A.12-A.17 (A.15 with psi_dot in its last term) hold for the velocities of the model."""
    rng = np.random.default_rng(7)
    r, L = geom.r, geom.L
    for q in poses(geom, 20, seed=8):
        rd = rng.uniform(-0.1, 0.1, 3)
        jac = jacobians(geom, *q)
        rates = jacobian_rates(geom, *q, rd)
        zd, psd, thd = rates.qdot
        xd = rates.parasitic_dot[0]
        gd = jac.J_b[:, 2, :] @ rd
        g1, g2, g3 = jac.pose.gamma
        z, psi, th = q
        s, c = math.sin, math.cos
        assert xd == pytest.approx(L * gd[0] * s(g1) + r * thd * s(th), abs=1e-12)  # A.12
        assert zd == pytest.approx(rd[0] + L * gd[0] * c(g1) + r * thd * c(th), abs=1e-12)  # A.13
        assert -r * psd * s(psi) == pytest.approx(L * gd[1] * s(g2), abs=1e-12)  # A.14
        assert zd == pytest.approx(
            rd[1] + L * gd[1] * c(g2) + r * thd * s(th) * s(psi) - r * psd * c(th) * c(psi), abs=1e-12
        )  # A.15 fixed
        assert xd == pytest.approx(-L * gd[2] * s(g3) - r * thd * s(th), abs=1e-12)  # A.16
        assert zd == pytest.approx(rd[2] + L * gd[2] * c(g3) - r * thd * c(th), abs=1e-12)  # A.17


# ---- errors ------------------------------------------------------------------------------------
def test_unreachable_pose_names_the_leg(geom):
    with pytest.raises(KinematicsError, match=r"leg 1 .*short by") as err:
        inverse_kinematics(geom, 0.4, 50 * DEG, 50 * DEG)
    assert isinstance(err.value, ModelError)
    short = Geometry(geom.H, geom.r, 0.06, geom.alpha)
    with pytest.raises(KinematicsError, match=r"leg 2 would need a horizontal reach of .* > L = 0.06"):
        inverse_kinematics(short, 0.2, 20 * DEG, 0.0)


def test_out_of_range_and_not_finite(geom):
    with pytest.raises(KinematicsError, match="out of range"):
        inverse_kinematics(geom, 0.4, 0.0, MAX_TILT + 0.01)
    with pytest.raises(KinematicsError, match="not finite"):
        inverse_kinematics(geom, math.nan, 0.0, 0.0)
    with pytest.raises(KinematicsError, match="not finite"):
        direct_kinematics(geom, (0.15, math.inf, 0.15))


def test_dk_failure_is_reported(geom):
    with pytest.raises(KinematicsError, match="did not converge"):
        direct_kinematics(geom, (0.0, 0.6, 0.0))  # no assembly exists
    rho = inverse_kinematics(geom, 0.42, 10 * DEG, -10 * DEG)
    with pytest.raises(KinematicsError, match=r"did not converge.*2 iterations, residual"):
        direct_kinematics(geom, rho, max_iter=2, tol=1e-15)


def test_singular_layout_is_reported(geom):
    same = Geometry(geom.H, geom.r, geom.L, (0.0, 0.0, math.pi))  # two guides on top of each other
    with pytest.raises(KinematicsError, match="singular"):
        jacobians(same, 0.4, 0.05, 0.05)


def test_geometry_validation(mechanism_params):
    with pytest.raises(ParameterError, match="'L'"):
        Geometry(0.4, 0.35, -0.26, T_ALPHA)
    with pytest.raises(ParameterError, match="missing parameter 'alpha_2'"):
        Geometry.from_params({k: v for k, v in mechanism_params.items() if k != "alpha_2"})
    g = Geometry.from_params({**mechanism_params, "extra": 1.0})
    assert g.alpha == pytest.approx(T_ALPHA)
