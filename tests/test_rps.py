"""The 3-RPS table (docs/designs/3rps.md) and the Newton-Euler oracle it is checked against.

The oracle (tests/newton_euler.py, numpy only, no code of fmus/) is first proved on the 3PRS, where the
engine (``designs.PRS3``) and the closed-form second formulation (``fmus/mechanism/dynamics.py``) are
known to agree: it must reproduce their forces to 1e-9 relative on random states (T layout, 120 deg,
inclined guides, a payload with an offset centre of mass and a full inertia tensor). Then the 3-RPS
description's inverse dynamics (the engine) against the oracle, with and without leg masses and gravity;
its statics at rest against virtual work on the potential energy (a third route, central differences);
its direct kinematics along random walks (the branch kept); its singularity margins at home.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

import newton_euler as ne
from fmus.mechanism import dynamics
from fmus.mechanism.designs import PRS3
from fmus.mechanism.engine import MARGIN, Body, Engine
from fmus.mechanism.kinematics import Geometry, KinematicsError
from rps3 import RPS3, TABLE

TOL = 1e-9                                   # relative to the largest force of the state
T_LAYOUT = (0.0, 0.5 * math.pi, math.pi)
LAYOUT_120 = (0.0, 2.0 * math.pi / 3.0, 4.0 * math.pi / 3.0)
PAYLOAD = Body("payload", 3.0, (0.02, -0.03, 0.1), ((0.05, 0.001, 0.002), (0.001, 0.04, 0.003), (0.002, 0.003, 0.06)))


def relative(a, b) -> float:
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


def random_states(engine: Engine, home, spread, rng, count: int):
    """(q, rho_dot, rho_ddot) around home inside the workspace (poses the engine refuses are skipped)."""
    states = []
    for _ in range(50 * count):
        if len(states) == count:
            break
        q = np.asarray(home) + rng.uniform(-1.0, 1.0, 3) * spread
        try:
            engine.jacobian(q)
        except KinematicsError:
            continue
        states.append((q, rng.uniform(-0.5, 0.5, 3), rng.uniform(-5.0, 5.0, 3)))
    assert len(states) == count, f"only {len(states)} of {count} random poses around {tuple(home)} are admissible"
    return states


# ----------------------------------------------------------------------------- the oracle on the 3PRS
def oracle_3prs(H, r, L, alpha, beta, m_leg, I_leg, m_platform, I_p, g, payload=None) -> ne.Mechanism:
    rod = ne.Inertia(m_leg, (0.5 * L, 0.0, 0.0), ((0.0, 0.0, 0.0), (0.0, I_leg, 0.0), (0.0, 0.0, I_leg)))
    platform = [ne.Inertia(m_platform, (0.0, 0.0, 0.0), np.diag(I_p))]
    if payload is not None:
        platform.append(ne.Inertia(payload.mass, payload.com, payload.inertia))
    return ne.Mechanism(ne.symmetric_legs("PRS", H, r, alpha, L, (ne.Inertia(), rod), beta), tuple(platform), g)


@pytest.mark.parametrize("H, alpha, beta, payload", [
    (0.4, T_LAYOUT, 0.0, None), (0.4, LAYOUT_120, 0.0, None), (0.55, T_LAYOUT, math.radians(15.0), None),
    (0.4, T_LAYOUT, 0.0, PAYLOAD), (0.4, LAYOUT_120, math.radians(-10.0), PAYLOAD)])
def test_the_oracle_reproduces_the_3prs_engine(H, alpha, beta, payload):
    masses = dict(m_leg=0.07, I_leg=3.943e-4, m_platform=2.06, I_p=(0.0631, 0.0631, 0.1262))
    desc = PRS3(H, 0.35, 0.26, alpha, beta, payload=payload, **masses)
    eng = Engine(desc, g=9.81)
    mech = oracle_3prs(H, 0.35, 0.26, alpha, beta, g=9.81, payload=payload, **masses)
    worst = 0.0
    for q, rd, rdd in random_states(eng, desc.topology.home, (0.1, 0.3, 0.3), np.random.default_rng(11), 25):
        idp = eng.inverse_dynamics_at_pose(q, rd, rdd)
        pose = ne.full_pose(mech, q)
        np.testing.assert_allclose(pose, idp.pose, rtol=0.0, atol=1e-12)          # the parasitic motion
        np.testing.assert_allclose(ne.joints(mech, pose), eng.ik(q), rtol=0.0, atol=1e-12)
        worst = max(worst, relative(ne.forces(mech, pose, rd, rdd), idp.t_rho))
    assert worst < TOL


def test_the_oracle_reproduces_the_closed_form_3prs_dynamics():
    """The second formulation (dynamics.py, Eqs. 5-32 in closed form): vertical guides, no payload."""
    geom = Geometry(0.4, 0.35, 0.26, T_LAYOUT)
    m = dynamics.Masses(m_leg=0.07, I_leg=3.943e-4, m_platform=2.06, I_px=0.0631, I_py=0.0631, I_pz=0.1262, g=9.81)
    mech = oracle_3prs(0.4, 0.35, 0.26, T_LAYOUT, 0.0, 0.07, 3.943e-4, 2.06, (0.0631, 0.0631, 0.1262), 9.81)
    eng = Engine(PRS3(0.4, 0.35, 0.26, T_LAYOUT), g=0.0)            # only to pick admissible poses
    for q, rd, rdd in random_states(eng, eng.description.topology.home, (0.1, 0.3, 0.3), np.random.default_rng(5), 20):
        idp = dynamics.inverse_dynamics_at_pose(geom, m, q, rd, rdd)
        assert relative(ne.forces(mech, ne.full_pose(mech, q), rd, rdd), idp.t_rho) < TOL


def test_the_oracle_sees_what_it_must():
    """A wrong leg inertia or a missing payload shows: the agreement above is not a tautology of zeros."""
    masses = dict(m_leg=0.07, I_leg=3.943e-4, m_platform=2.06, I_p=(0.0631, 0.0631, 0.1262))
    desc = PRS3(0.4, 0.35, 0.26, T_LAYOUT, payload=PAYLOAD, **masses)
    eng = Engine(desc, g=9.81)
    q, rd, rdd = random_states(eng, desc.topology.home, (0.1, 0.3, 0.3), np.random.default_rng(3), 1)[0]
    right = eng.inverse_dynamics_at_pose(q, rd, rdd).t_rho
    for wrong in (oracle_3prs(0.4, 0.35, 0.26, T_LAYOUT, 0.0, 0.07, 2 * 3.943e-4, 2.06, masses["I_p"], 9.81, PAYLOAD),
                  oracle_3prs(0.4, 0.35, 0.26, T_LAYOUT, 0.0, g=9.81, **masses)):
        assert relative(ne.forces(wrong, ne.full_pose(wrong, q), rd, rdd), right) > 1e-5


# ----------------------------------------------------------------------------- the 3-RPS
def oracle_3rps(legs: bool, g: float, payload=None) -> ne.Mechanism:
    k = 1.0 if legs else 0.0
    cylinder = ne.Inertia(k * TABLE["m_cylinder"], (TABLE["x_cylinder"], 0.0, 0.0), k * np.diag(TABLE["I_cylinder"]))
    piston = ne.Inertia(k * TABLE["m_piston"], (0.0, 0.0, 0.0), k * np.diag(TABLE["I_piston"]))
    platform = [ne.Inertia(TABLE["m_platform"], (0.0, 0.0, 0.0), np.diag(TABLE["I_platform"]))]
    if payload is not None:
        platform.append(ne.Inertia(payload.mass, payload.com, payload.inertia))
    return ne.Mechanism(ne.symmetric_legs("RPS", TABLE["R_b"], TABLE["r"], TABLE["alpha"], TABLE["l0"],
                                          (cylinder, piston)), tuple(platform), g)


@pytest.mark.parametrize("legs, g, payload", [(True, 9.81, None), (True, 0.0, None), (False, 9.81, None),
                                              (False, 0.0, None), (True, 9.81, PAYLOAD)])
def test_3rps_inverse_dynamics_agree_with_newton_euler(legs, g, payload):
    desc = RPS3(legs=legs, payload=payload)
    eng = Engine(desc, g=g)
    mech = oracle_3rps(legs, g, payload)
    worst = 0.0
    for q, rd, rdd in random_states(eng, desc.topology.home, (0.12, 0.35, 0.35), np.random.default_rng(7), 30):
        idp = eng.inverse_dynamics_at_pose(q, rd, rdd)
        pose = ne.full_pose(mech, q)
        np.testing.assert_allclose(pose, idp.pose, rtol=0.0, atol=1e-12)
        rho = ne.joints(mech, pose)
        np.testing.assert_allclose(rho, eng.ik(q), rtol=0.0, atol=1e-12)
        worst = max(worst, relative(ne.forces(mech, pose, rd, rdd), idp.t_rho))
    assert worst < TOL


def potential(mech: ne.Mechanism, q) -> float:
    """Potential energy [J] of the 3-RPS at q, from the centres of mass alone (the oracle's pose)."""
    pose = ne.full_pose(mech, q)
    R = ne.rotation(*pose[3:])
    V = sum(b.mass * mech.g * (pose[2] + (R @ np.asarray(b.com))[2]) for b in mech.platform)
    for leg, S in zip(mech.legs, ne.points(mech, pose)):
        u = (S - np.asarray(leg.base)) / np.linalg.norm(S - np.asarray(leg.base))
        cyl, pis = leg.bodies
        V += cyl.mass * mech.g * (leg.base[2] + cyl.com[0] * u[2]) + pis.mass * mech.g * S[2]
    return V


def test_3rps_statics_at_rest_carry_the_weight():
    """At rest F = J^-T dV/dq (virtual work, central differences of V and rho): the weight of platform and legs."""
    desc = RPS3()
    eng = Engine(desc, g=9.81)
    mech = oracle_3rps(True, 9.81)
    home = np.asarray(desc.topology.home)
    for q in [home] + [s[0] for s in random_states(eng, home, (0.1, 0.3, 0.3), np.random.default_rng(2), 4)]:
        h = 1e-5
        dV = np.array([(potential(mech, q + h * e) - potential(mech, q - h * e)) / (2 * h) for e in np.eye(3)])
        J = np.column_stack([(ne.joints(mech, ne.full_pose(mech, q + h * e)) - ne.joints(mech, ne.full_pose(mech, q - h * e)))
                             / (2 * h) for e in np.eye(3)])
        F = eng.inverse_dynamics_at_pose(q, (0, 0, 0), (0, 0, 0)).t_rho
        np.testing.assert_allclose(F, np.linalg.solve(J.T, dV), rtol=1e-7)
    F_home = eng.inverse_dynamics_at_pose(home, (0, 0, 0), (0, 0, 0)).t_rho
    assert F_home == pytest.approx([29.41285318] * 3, rel=1e-8)        # docs/designs/3rps.md
    # massless legs: the legs' forces hold the platform's weight up, sum F_i u_i,z = m_p g
    bare = Engine(RPS3(legs=False), g=9.81).inverse_dynamics_at_pose(home, (0, 0, 0), (0, 0, 0)).t_rho
    pose = ne.full_pose(mech, home)
    uz = [(S - np.asarray(leg.base))[2] / np.linalg.norm(S - np.asarray(leg.base))
          for leg, S in zip(mech.legs, ne.points(mech, pose))]
    assert float(np.dot(bare, uz)) == pytest.approx(TABLE["m_platform"] * 9.81, rel=1e-12)


def test_3rps_direct_kinematics_keep_their_branch_along_random_walks():
    desc = RPS3()
    eng = Engine(desc, g=9.81)
    mech = oracle_3rps(True, 9.81)
    home = np.asarray(desc.topology.home)
    det_home = eng.margins(home).det
    lo, hi = TABLE["stroke"]
    rng = np.random.default_rng(23)
    for _ in range(6):
        rho = ne.joints(mech, ne.full_pose(mech, home))
        q = home
        for _ in range(60):
            step = rng.normal(0.0, 0.006, 3)
            if np.any(rho + step < lo) or np.any(rho + step > hi):
                continue
            rho = rho + step
            try:
                q = np.asarray(eng.dk(rho, guess=q)[0])
            except KinematicsError:          # a refusal (margin) is allowed; a jump is not
                rho = rho - step
                continue
            np.testing.assert_allclose(ne.joints(mech, ne.full_pose(mech, q)), rho, rtol=0.0, atol=1e-11)
            assert np.sign(eng.margins(q).det) == np.sign(det_home)
            cold = np.asarray(eng.dk(rho)[0])                     # from the level guess: the same pose
            np.testing.assert_allclose(cold, q, rtol=0.0, atol=1e-9)


def test_3rps_margins_at_home():
    """By the oracle's own drho/dq (central differences), scaled as the engine scales: tilts by r."""
    desc = RPS3()
    eng = Engine(desc, g=9.81)
    mech = oracle_3rps(True, 9.81)
    home = np.asarray(desc.topology.home)
    h = 1e-6
    J = np.column_stack([(ne.joints(mech, ne.full_pose(mech, home + h * e)) - ne.joints(mech, ne.full_pose(mech, home - h * e)))
                         / (2 * h) for e in np.eye(3)])
    sv = np.linalg.svd(J / np.array([1.0, TABLE["r"], TABLE["r"]]), compute_uv=False)
    m = eng.margins(home)
    assert m.parallel == pytest.approx(sv[-1], rel=1e-7) and m.inverse == pytest.approx(1.0 / sv[0], rel=1e-7)
    assert m.det > 0 and min(m.parallel, m.inverse) > 10 * MARGIN
    assert (m.parallel, m.inverse) == pytest.approx((1.2156, 0.5817), abs=1e-4)    # docs/designs/3rps.md
