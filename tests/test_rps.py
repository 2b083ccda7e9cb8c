"""The 3-RPS table (fmus/mechanism/descriptions/3RPS.toml, docs/designs/3rps.md) and the Newton-Euler oracle it
is checked against.

The oracle (tests/newton_euler.py, numpy only, no code of fmus/) is first proved on the 3PRS, where the
engine (the 3PRS description file) and the closed-form second formulation (``fmus/mechanism/dynamics.py``) are
known to agree: it must reproduce their forces to 1e-9 relative on random states (T layout, 120 deg,
inclined guides, a payload with an offset centre of mass and a full inertia tensor). Then the 3-RPS
description's inverse dynamics (the engine) against the oracle, with and without leg masses and gravity;
its statics at rest against virtual work on the potential energy (a third route, central differences);
its direct kinematics along random walks (the branch kept); its singularity margins at home. Last, a scratch
6-UPS hexapod (issue 26) from a description file against the oracle, with and without leg masses and gravity.
"""

from __future__ import annotations

import csv
import json
import math

import newton_euler as ne
import numpy as np
import pytest
from branch_walk import walk_keeps_branch

from fmus.mechanism import dynamics
from fmus.mechanism.description import load
from fmus.mechanism.engine import MARGIN, Body, Engine
from fmus.mechanism.kinematics import Geometry, KinematicsError

TOL = 1e-9  # relative to the largest force of the state
T_LAYOUT = (0.0, 0.5 * math.pi, math.pi)
LAYOUT_120 = (0.0, 2.0 * math.pi / 3.0, 4.0 * math.pi / 3.0)
RPS = load("3RPS")
V = RPS.values()  # the file's parameter values: plain numbers for the oracle
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
def engine_3prs(H, alpha, beta, payload=None, g=9.81) -> Engine:
    """The 3PRS description file at these values (the masses below, the payload's)."""
    values = dict(
        load("3PRS_T").values(),
        H=H,
        beta=beta,
        **{f"alpha_{k + 1}": a for k, a in enumerate(alpha)},
        m_leg=0.07,
        I_leg=3.943e-4,
        m_platform=2.06,
        I_px=0.0631,
        I_py=0.0631,
        I_pz=0.1262,
        g=g,
    )
    if payload is not None:
        values.update(
            m_payload=payload.mass,
            **dict(zip(("payload_x", "payload_y", "payload_z"), payload.com)),
            **{
                f"I_payload_{a}{b}": payload.inertia[i][j]
                for a, b, i, j in (
                    ("x", "x", 0, 0),
                    ("y", "y", 1, 1),
                    ("z", "z", 2, 2),
                    ("x", "y", 0, 1),
                    ("x", "z", 0, 2),
                    ("y", "z", 1, 2),
                )
            },
        )
    return Engine(load("3PRS_T").describe(values), g=g)


def oracle_3prs(H, r, L, alpha, beta, m_leg, I_leg, m_platform, I_p, g, payload=None) -> ne.Mechanism:
    rod = ne.Inertia(m_leg, (0.5 * L, 0.0, 0.0), ((0.0, 0.0, 0.0), (0.0, I_leg, 0.0), (0.0, 0.0, I_leg)))
    platform = [ne.Inertia(m_platform, (0.0, 0.0, 0.0), np.diag(I_p))]
    if payload is not None:
        platform.append(ne.Inertia(payload.mass, payload.com, payload.inertia))
    return ne.Mechanism(ne.symmetric_legs("PRS", H, r, alpha, L, (ne.Inertia(), rod), beta), tuple(platform), g)


@pytest.mark.parametrize(
    "H, alpha, beta, payload",
    [
        (0.4, T_LAYOUT, 0.0, None),
        (0.4, LAYOUT_120, 0.0, None),
        (0.55, T_LAYOUT, math.radians(15.0), None),
        (0.4, T_LAYOUT, 0.0, PAYLOAD),
        (0.4, LAYOUT_120, math.radians(-10.0), PAYLOAD),
    ],
)
def test_the_oracle_reproduces_the_3prs_engine(H, alpha, beta, payload):
    masses = dict(m_leg=0.07, I_leg=3.943e-4, m_platform=2.06, I_p=(0.0631, 0.0631, 0.1262))
    eng = engine_3prs(H, alpha, beta, payload)
    desc = eng.description
    mech = oracle_3prs(H, 0.35, 0.26, alpha, beta, g=9.81, payload=payload, **masses)
    worst = 0.0
    for q, rd, rdd in random_states(eng, desc.topology.home, (0.1, 0.3, 0.3), np.random.default_rng(11), 25):
        idp = eng.inverse_dynamics_at_pose(q, rd, rdd)
        pose = ne.full_pose(mech, q)
        np.testing.assert_allclose(pose, idp.pose, rtol=0.0, atol=1e-12)  # the parasitic motion
        np.testing.assert_allclose(ne.joints(mech, pose), eng.ik(q), rtol=0.0, atol=1e-12)
        worst = max(worst, relative(ne.forces(mech, pose, rd, rdd), idp.t_rho))
    assert worst < TOL


def test_the_oracle_reproduces_the_closed_form_3prs_dynamics():
    """The second formulation (dynamics.py, Eqs. 5-32 in closed form): vertical guides, no payload."""
    geom = Geometry(0.4, 0.35, 0.26, T_LAYOUT)
    m = dynamics.Masses(m_leg=0.07, I_leg=3.943e-4, m_platform=2.06, I_px=0.0631, I_py=0.0631, I_pz=0.1262, g=9.81)
    mech = oracle_3prs(0.4, 0.35, 0.26, T_LAYOUT, 0.0, 0.07, 3.943e-4, 2.06, (0.0631, 0.0631, 0.1262), 9.81)
    eng = engine_3prs(0.4, T_LAYOUT, 0.0)  # only to pick admissible poses
    for q, rd, rdd in random_states(eng, eng.description.topology.home, (0.1, 0.3, 0.3), np.random.default_rng(5), 20):
        idp = dynamics.inverse_dynamics_at_pose(geom, m, q, rd, rdd)
        assert relative(ne.forces(mech, ne.full_pose(mech, q), rd, rdd), idp.t_rho) < TOL


def test_the_oracle_sees_what_it_must():
    """A wrong leg inertia or a missing payload shows: the agreement above is not a tautology of zeros."""
    masses = dict(m_leg=0.07, I_leg=3.943e-4, m_platform=2.06, I_p=(0.0631, 0.0631, 0.1262))
    eng = engine_3prs(0.4, T_LAYOUT, 0.0, PAYLOAD)
    desc = eng.description
    q, rd, rdd = random_states(eng, desc.topology.home, (0.1, 0.3, 0.3), np.random.default_rng(3), 1)[0]
    right = eng.inverse_dynamics_at_pose(q, rd, rdd).t_rho
    for wrong in (
        oracle_3prs(0.4, 0.35, 0.26, T_LAYOUT, 0.0, 0.07, 2 * 3.943e-4, 2.06, masses["I_p"], 9.81, PAYLOAD),
        oracle_3prs(0.4, 0.35, 0.26, T_LAYOUT, 0.0, g=9.81, **masses),
    ):
        assert relative(ne.forces(wrong, ne.full_pose(wrong, q), rd, rdd), right) > 1e-5


# ----------------------------------------------------------------------------- the 3-RPS
LEGS_FREE = dict(m_cylinder=0.0, I_cylinder_axial=0.0, I_cylinder=0.0, m_carriage=0.0)


def rps_engine(g: float = 9.81, **values) -> Engine:
    """The 3RPS description file's engine at its values with ``values`` changed."""
    return Engine(RPS.describe({**V, **values}), g=g)


def oracle_3rps(g: float = 9.81, **values) -> ne.Mechanism:
    """The oracle from the file's numbers (inertias of the carriage block and the disc computed here)."""
    v = {**V, **values}
    mc, a, b, c = v["m_carriage"], v["a_carriage"], v["b_carriage"], v["c_carriage"]
    cylinder = ne.Inertia(
        v["m_cylinder"], (v["x_cylinder"], 0.0, 0.0), np.diag((v["I_cylinder_axial"], v["I_cylinder"], v["I_cylinder"]))
    )
    rod = ne.Inertia(mc, (0.0, 0.0, 0.0), np.diag((b * b + c * c, a * a + c * c, a * a + b * b)) * mc / 12.0)
    mp, r = v["m_platform"], v["r"]
    platform = [ne.Inertia(mp, (0.0, 0.0, 0.0), np.diag((mp * r * r / 4, mp * r * r / 4, mp * r * r / 2)))]
    if v["m_payload"]:
        platform.append(
            ne.Inertia(
                v["m_payload"],
                (v["payload_x"], v["payload_y"], v["payload_z"]),
                [[v[f"I_payload_{min(i, j)}{max(i, j)}"] for j in "xyz"] for i in "xyz"],
            )
        )
    angles = (v["alpha_1"], v["alpha_2"], v["alpha_3"])
    return ne.Mechanism(ne.symmetric_legs("RPS", v["R_b"], r, angles, 0.0, (cylinder, rod)), tuple(platform), g)


PAYLOAD_VALUES = dict(
    m_payload=3.0,
    payload_x=0.02,
    payload_y=-0.03,
    payload_z=0.1,
    I_payload_xx=0.05,
    I_payload_yy=0.04,
    I_payload_zz=0.06,
    I_payload_xy=0.001,
    I_payload_xz=0.002,
    I_payload_yz=0.003,
)


def test_the_3rps_cylinder_numbers_follow_from_their_inputs():
    """docs/designs/3rps.md: rail 1.5 kg, 0.65 m from the joint, 40 mm square; drive 0.84 kg at 0.05 m."""
    m_rail, l_rail, w, m_drive, x_drive = 1.5, 0.65, 0.04, 0.48 + 0.36, 0.05
    m = m_rail + m_drive
    x = (m_rail * l_rail / 2 + m_drive * x_drive) / m
    transverse = m_rail * l_rail**2 / 12 + m_rail * (l_rail / 2 - x) ** 2 + m_drive * (x - x_drive) ** 2
    assert (V["m_cylinder"], V["x_cylinder"], V["I_cylinder"], V["I_cylinder_axial"]) == pytest.approx(
        (m, x, transverse, m_rail * w * w / 6), rel=1e-12
    )
    assert V["m_carriage"] == 2.27 and V["m_platform"] == 2.06 and V["r"] == 0.35  # paper Eq. 22, section 3
    top = RPS.describe().topology
    assert [d.stroke for d in top.drives] == [(0.26, 0.56)] * 3  # the paper's 300 mm


@pytest.mark.parametrize(
    "legs, g, payload",
    [(True, 9.81, False), (True, 0.0, False), (False, 9.81, False), (False, 0.0, False), (True, 9.81, True)],
)
def test_3rps_inverse_dynamics_agree_with_newton_euler(legs, g, payload):
    values = {**({} if legs else LEGS_FREE), **(PAYLOAD_VALUES if payload else {})}
    eng = rps_engine(g, **values)
    mech = oracle_3rps(g, **values)
    worst = 0.0
    for q, rd, rdd in random_states(
        eng, eng.description.topology.home, (0.12, 0.35, 0.35), np.random.default_rng(7), 30
    ):
        idp = eng.inverse_dynamics_at_pose(q, rd, rdd)
        pose = ne.full_pose(mech, q)
        np.testing.assert_allclose(pose, idp.pose, rtol=0.0, atol=1e-12)
        np.testing.assert_allclose(ne.joints(mech, pose), eng.ik(q), rtol=0.0, atol=1e-12)
        worst = max(worst, relative(ne.forces(mech, pose, rd, rdd), idp.t_rho))
    assert worst < TOL


def potential(mech: ne.Mechanism, q) -> float:
    """Potential energy [J] of the 3-RPS at q, from the centres of mass alone (the oracle's pose)."""
    pose = ne.full_pose(mech, q)
    R = ne.rotation(*pose[3:])
    E = sum(b.mass * mech.g * (pose[2] + (R @ np.asarray(b.com))[2]) for b in mech.platform)
    for leg, S in zip(mech.legs, ne.points(mech, pose)):
        u = (S - np.asarray(leg.base)) / np.linalg.norm(S - np.asarray(leg.base))
        cyl, rod = leg.bodies
        E += cyl.mass * mech.g * (leg.base[2] + cyl.com[0] * u[2]) + rod.mass * mech.g * S[2]
    return E


def oracle_jacobian(mech: ne.Mechanism, q, h: float) -> np.ndarray:
    """drho/dq by central differences of the oracle's joints."""
    q = np.asarray(q, dtype=float)
    return np.column_stack(
        [
            (ne.joints(mech, ne.full_pose(mech, q + h * e)) - ne.joints(mech, ne.full_pose(mech, q - h * e))) / (2 * h)
            for e in np.eye(3)
        ]
    )


def test_3rps_statics_at_rest_carry_the_weight():
    """At rest F = J^-T dV/dq (virtual work, central differences of V and rho): the weight of platform and legs."""
    eng = rps_engine()
    mech = oracle_3rps()
    home = np.asarray(eng.description.topology.home)
    for q in [home] + [s[0] for s in random_states(eng, home, (0.1, 0.3, 0.3), np.random.default_rng(2), 4)]:
        h = 1e-5
        dV = np.array([(potential(mech, q + h * e) - potential(mech, q - h * e)) / (2 * h) for e in np.eye(3)])
        F = eng.inverse_dynamics_at_pose(q, (0, 0, 0), (0, 0, 0)).t_rho
        np.testing.assert_allclose(F, np.linalg.solve(oracle_jacobian(mech, q, h).T, dV), rtol=1e-7)
    F_home = eng.inverse_dynamics_at_pose(home, (0, 0, 0), (0, 0, 0)).t_rho
    assert F_home == pytest.approx([29.41285318] * 3, rel=1e-8)  # docs/designs/3rps.md
    # massless legs: the legs' forces hold the platform's weight up, sum F_i u_i,z = m_p g
    bare = rps_engine(**LEGS_FREE).inverse_dynamics_at_pose(home, (0, 0, 0), (0, 0, 0)).t_rho
    pose = ne.full_pose(mech, home)
    uz = [
        (S - np.asarray(leg.base))[2] / np.linalg.norm(S - np.asarray(leg.base))
        for leg, S in zip(mech.legs, ne.points(mech, pose))
    ]
    assert float(np.dot(bare, uz)) == pytest.approx(V["m_platform"] * 9.81, rel=1e-12)


def test_3rps_direct_kinematics_keep_their_branch_along_random_walks():
    eng = rps_engine()
    mech = oracle_3rps()
    home = np.asarray(eng.description.topology.home)
    stroke = eng.description.topology.drives[0].stroke
    steps = walk_keeps_branch(
        eng, lambda q: ne.joints(mech, ne.full_pose(mech, q)), home, stroke, sigma=0.006, seed=23, walks=6, length=60
    )
    assert steps > 200


def test_3rps_margins_at_home():
    """By the oracle's own drho/dq (central differences), scaled as the engine scales: tilts by r."""
    eng = rps_engine()
    home = np.asarray(eng.description.topology.home)
    J = oracle_jacobian(oracle_3rps(), home, 1e-6)
    sv = np.linalg.svd(J / np.array([1.0, V["r"], V["r"]]), compute_uv=False)
    m = eng.margins(home)
    assert m.parallel == pytest.approx(sv[-1], rel=1e-7) and m.inverse == pytest.approx(1.0 / sv[0], rel=1e-7)
    assert m.det > 0 and min(m.parallel, m.inverse) > 10 * MARGIN
    assert (m.parallel, m.inverse) == pytest.approx((1.2156, 0.5817), abs=1e-4)  # docs/designs/3rps.md


# ----------------------------------------------------------------------------- a 6-UPS hexapod (issue 26)
# a scratch hexapod: pairs of universal joints 24 deg apart on the base circle, spherical joints on the platform
# circle, legs and platform with offset centres of mass and full inertia tensors (the legs' spin about their own
# axis, which the universal joint fixes, matters then)
HEXAPOD = """
[mechanism]
name = "6UPS"
coordinates = ["x", "y", "z", "psi", "theta", "phi"]
gravity = "g"
home = { x = 0.0, y = 0.0, z = 0.45, psi = 0.0, theta = 0.0, phi = 0.0 }

[parameters]
R_b = { value = 0.4, unit = "m", source = "assumed: a test hexapod" }
r = { value = 0.3, unit = "m", source = "assumed: a test hexapod" }
gap = { value = 12.0, unit = "deg", source = "assumed: half the angle between a pair of joints" }
g = { value = 9.81, unit = "m/s2", source = "standard gravity" }
m_c = { value = 2.34, unit = "kg", source = "assumed" }
m_r = { value = 2.27, unit = "kg", source = "assumed" }
m_p = { value = 2.06, unit = "kg", source = "assumed" }

[leg]
template = "UPS"
drive = { joint = "P", kind = "linear", stroke = [0.3, 0.7] }

[[bodies]]
name = "platform"
mass = "m_p"
com = [0.01, -0.02, 0.03]
inertia = [[0.063, 0.002, -0.001], [0.002, 0.06, 0.003], [-0.001, 0.003, 0.126]]
"""
LEG_BODIES = """
[leg.bodies.cylinder]
mass = "m_c"
com = [0.2, 0.01, -0.02]
inertia = [[0.002, 0.0003, -0.0002], [0.0003, 0.09, 0.001], [-0.0002, 0.001, 0.08]]

[leg.bodies.rod]
mass = "m_r"
com = [-0.04, 0.015, 0.01]
inertia = [[0.0015, -0.0001, 0.0002], [-0.0001, 0.0022, 0.0003], [0.0002, 0.0003, 0.0031]]
"""
CYLINDER = ne.Inertia(
    2.34, (0.2, 0.01, -0.02), ((0.002, 0.0003, -0.0002), (0.0003, 0.09, 0.001), (-0.0002, 0.001, 0.08))
)
ROD = ne.Inertia(
    2.27, (-0.04, 0.015, 0.01), ((0.0015, -0.0001, 0.0002), (-0.0001, 0.0022, 0.0003), (0.0002, 0.0003, 0.0031))
)
PLATFORM = ne.Inertia(2.06, (0.01, -0.02, 0.03), ((0.063, 0.002, -0.001), (0.002, 0.06, 0.003), (-0.001, 0.003, 0.126)))


def hexapod_angles(k: int) -> tuple[float, float]:
    """(base joint angle, platform joint angle) [deg] of leg k (0-based): pairs at 0, 120, 240 deg on the base."""
    pair, side = 120 * (k // 2), (1 if k % 2 else -1)
    return pair + side * 12.0, pair + side * 48.0


def hexapod_file(tmp_path, legs: bool):
    """The scratch hexapod's description file, its legs with their bodies or massless."""
    text = HEXAPOD + (LEG_BODIES if legs else "")
    for k in range(6):
        b, p = hexapod_angles(k)
        text += (
            f'\n[[legs]]\nname = "leg_{k + 1}"\nbase = ["R_b * cos(radians({b}))", "R_b * sin(radians({b}))", 0.0]\n'
            f'platform = ["r * cos(radians({p}))", "r * sin(radians({p}))", 0.0]\n'
            f'axis = ["-sin(radians({b}))", "cos(radians({b}))", 0.0]\n'
        )
    path = tmp_path / "hexapod.toml"
    path.write_text(text)
    return load(path)


def oracle_hexapod(legs: bool, g: float) -> ne.Mechanism:
    bodies = (CYLINDER, ROD) if legs else (ne.Inertia(), ne.Inertia())
    out = []
    for k in range(6):
        b, p = (math.radians(a) for a in hexapod_angles(k))
        out.append(
            ne.Leg(
                "UPS",
                (0.4 * math.cos(b), 0.4 * math.sin(b), 0.0),
                (-math.sin(b), math.cos(b), 0.0),
                (0.3 * math.cos(p), 0.3 * math.sin(p), 0.0),
                0.0,
                bodies=bodies,
            )
        )
    return ne.Mechanism(tuple(out), (PLATFORM,), g, coordinates=ne.POSE)


@pytest.mark.parametrize("legs, g", [(True, 9.81), (True, 0.0), (False, 9.81), (False, 0.0)])
def test_6ups_inverse_dynamics_agree_with_newton_euler(tmp_path, legs, g):
    file = hexapod_file(tmp_path, legs)
    eng = Engine(file.describe(), g=g)
    mech = oracle_hexapod(legs, g)
    home = np.asarray(eng.description.topology.home)
    rng = np.random.default_rng(29)
    worst = 0.0
    for _ in range(30):
        q = home + rng.uniform(-1.0, 1.0, 6) * (0.05, 0.05, 0.08, 0.2, 0.2, 0.2)
        rd, rdd = rng.uniform(-0.5, 0.5, 6), rng.uniform(-5.0, 5.0, 6)
        idp = eng.inverse_dynamics_at_pose(q, rd, rdd)
        np.testing.assert_allclose(ne.joints(mech, q), eng.ik(q), rtol=0.0, atol=1e-12)
        worst = max(worst, relative(ne.forces(mech, q, rd, rdd), idp.t_rho))
    assert worst < TOL


def test_6ups_check_sees_the_legs_inertia_off_their_axis(tmp_path):
    """With the cylinder's products of inertia left out the oracle disagrees: the comparison above tests them."""
    eng = Engine(hexapod_file(tmp_path, True).describe(), g=9.81)
    plain = ne.Inertia(CYLINDER.mass, CYLINDER.com, np.diag(np.diag(CYLINDER.tensor)))
    mech = oracle_hexapod(True, 9.81)
    wrong = ne.Mechanism(
        tuple(ne.Leg(leg.kind, leg.base, leg.t, leg.s, 0.0, bodies=(plain, ROD)) for leg in mech.legs),
        mech.platform,
        mech.g,
        mech.coordinates,
    )
    rng = np.random.default_rng(31)
    q = np.asarray(eng.description.topology.home) + rng.uniform(-1.0, 1.0, 6) * (0.05, 0.05, 0.08, 0.2, 0.2, 0.2)
    rd, rdd = rng.uniform(-0.5, 0.5, 6), rng.uniform(-5.0, 5.0, 6)
    right = eng.inverse_dynamics_at_pose(q, rd, rdd).t_rho
    assert relative(ne.forces(mech, q, rd, rdd), right) < TOL < 1e-6 < relative(ne.forces(wrong, q, rd, rdd), right)


# ----------------------------------------------------------------------------- beside the designs
def test_the_3rps_workspace_from_its_description_alone():
    """`mast workspace 3RPS`: its own strokes and home, every body's mass (static forces against the oracle)."""
    from mast.analyses import workspace as W

    m = W.machine("3RPS")
    assert (m.rho_min, m.rho_max) == ((0.26,) * 3, (0.56,) * 3) and m.rho_home == pytest.approx((0.41,) * 3)
    assert m.missing_masses == () and m.drive == {}
    ws = W.compute(m, 0.025, math.radians(4.0))
    s = W.summarize(ws)
    home = rps_engine().margins(rps_engine().description.topology.home)
    assert (s["home"]["margin_parallel"], s["home"]["margin_inverse"]) == pytest.approx((home.parallel, home.inverse))
    assert s["static_forces"]["home_N"] == pytest.approx([29.41285318] * 3, rel=1e-8)
    mech = oracle_3rps()
    inside = np.argwhere(ws.status == W.INSIDE)
    for k in np.random.default_rng(3).choice(len(inside), 5, replace=False):
        i = tuple(inside[k])
        q = [ws.axes[d][i[d]] for d in range(3)]
        at_rest = ne.forces(mech, ne.full_pose(mech, q), np.zeros(3), np.zeros(3))
        np.testing.assert_allclose(ws.forces[(slice(None),) + i], at_rest, rtol=1e-9)


def test_compare_puts_the_3rps_beside_the_designs_without_running_it(tmp_path):
    from mast.analyses.compare import NOT_RUN, QUICK, WORKSPACE_GRID_QUICK, compare
    from mast.cli import main as cli_main

    comp = compare(["3RPS"], tmp_path / "cmp", QUICK, workspace_grid=WORKSPACE_GRID_QUICK, workers=1)
    assert comp.candidates == [] and comp.summary == []
    rows = list(csv.DictReader(open(tmp_path / "cmp" / "comparison.csv")))
    assert [(r["design"], r["motion"], r["sizing_note"]) for r in rows] == [("3RPS", "", NOT_RUN)]
    assert float(rows[0]["margin_home"]) == pytest.approx(0.5817, abs=1e-4) and float(rows[0]["workspace_m_deg2"]) > 100
    md = (tmp_path / "cmp" / "comparison.md").read_text()
    assert "| 3RPS (description, not run) | 29.41, 29.41, 29.41 |" in md
    data = json.loads((tmp_path / "cmp" / "comparison.json").read_text())
    assert data["descriptions"][0]["workspace"]["static_forces"]["home_N"] == pytest.approx([29.41285318] * 3)
    assert cli_main(["compare", "--mechanism", "3RPS", "--out", str(tmp_path / "cli"), "--quick"]) == 0
    assert "3RPS (description, not run)" in (tmp_path / "cli" / "comparison.md").read_text()
    with pytest.raises(
        FileNotFoundError,
        match=r"mechanism 3XYZ: no such file or a mechanism description's name "
        r"\(3PRS, 3RPS",
    ):
        compare(["3XYZ"], tmp_path / "none", QUICK)
    assert not (tmp_path / "none").exists()
