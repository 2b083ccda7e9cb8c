"""The 6-UPS hexapod (fmus/mechanism/descriptions/6UPS.toml, docs/designs/6ups.md, issue 26) against routes that
share no code with the engine.

- its numbers: the leg bodies' mass, centre of mass and inertia recomputed here from their parts, the joint
  positions from the layout (pairs at 120 j -/+ gamma_b on the base, 120 j -/+ (60 - gamma_p) on the platform),
  home at mid-stroke;
- inverse dynamics against the Newton-Euler oracle (tests/newton_euler.py) on random states inside the workspace,
  with and without leg masses and gravity, with a payload: 1e-9 relative at the block's own pose;
- statics at rest against virtual work on the potential energy (central differences), and the massless legs'
  forces at home by hand (six equal forces carry the platform's weight);
- the direct kinematics along random walks of the legs (the branch of home kept, a cold start finds it);
- a power balance along smooth leg trajectories: sum F_i rho_dot_i = d/dt (T + V), the energies from the bodies'
  poses alone (the pose from this file's own Newton solution on the oracle's leg lengths), derivatives by
  differences;
- the workspace (constant orientation x, y, z; orientation psi, theta, phi) through home against the leg lengths
  by hand at the range edges, the margins at home against the oracle's drho/dq, --pose with six numbers.
"""

from __future__ import annotations

import math

import newton_euler as ne
import numpy as np
import pytest
from branch_walk import walk_keeps_branch

from fmus.mechanism.description import load
from fmus.mechanism.engine import MARGIN, Engine
from fmus.mechanism.kinematics import KinematicsError

TOL = 1e-9  # relative to the largest force of the state
HEX = load("6UPS")
V = HEX.values()
HOME = np.asarray(HEX.describe().topology.home)
LO, HI = 0.45, 0.75  # the stroke, pin to pin [m] (the paper's 300 mm from 0.45 m retracted)
SPREAD = (0.08, 0.08, 0.08, 0.25, 0.25, 0.25)
LEGS_FREE = dict(
    m_cylinder=0.0,
    I_cylinder_xx=0.0,
    I_cylinder_yy=0.0,
    I_cylinder_zz=0.0,
    I_cylinder_xz=0.0,
    m_rod=0.0,
    I_rod_xx=0.0,
    I_rod=0.0,
)
PAYLOAD = dict(
    m_payload=5.0,
    payload_x=0.03,
    payload_y=-0.02,
    payload_z=0.12,
    I_payload_xx=0.06,
    I_payload_yy=0.05,
    I_payload_zz=0.08,
    I_payload_xy=0.002,
    I_payload_xz=-0.001,
    I_payload_yz=0.003,
)


# ----------------------------------------------------------------------------- the bodies from their parts
def tube(m: float, outer: float, inner: float, length: float) -> np.ndarray:
    """Inertia [kg m^2] of a tube (solid: inner = 0) about its centre, x along its axis."""
    axial = m * (outer**2 + inner**2) / 2
    transverse = m * (3 * (outer**2 + inner**2) + length**2) / 12
    return np.diag((axial, transverse, transverse))


def composite(parts) -> tuple[float, np.ndarray, np.ndarray]:
    """(mass, centre of mass, inertia about it) of (mass, centre, inertia about the centre) parts."""
    m = sum(p[0] for p in parts)
    c = sum(p[0] * np.asarray(p[1], float) for p in parts) / m
    inertia = np.zeros((3, 3))
    for mass, centre, own in parts:
        d = np.asarray(centre, float) - c
        inertia += own + mass * (d @ d * np.eye(3) - np.outer(d, d))
    return m, c, inertia


def cylinder_parts():
    """docs/designs/6ups.md: aluminium tube 50/40 mm from 0.04 to 0.42 m, steel screw 16 mm from 0.06 to 0.42 m, the
    drive (0.84 kg, 40 mm x 0.13 m) centred 0.105 m up and 0.055 m beside the axis, the end block 0.35 kg at 0.04 m."""
    m_tube = 2700.0 * math.pi / 4 * (0.05**2 - 0.04**2) * 0.38
    m_screw = 7850.0 * math.pi * 0.008**2 * 0.36
    return [
        (m_tube, (0.23, 0.0, 0.0), tube(m_tube, 0.025, 0.02, 0.38)),
        (m_screw, (0.24, 0.0, 0.0), tube(m_screw, 0.008, 0.0, 0.36)),
        (0.48 + 0.36, (0.105, 0.0, 0.055), tube(0.84, 0.02, 0.0, 0.13)),
        (0.35, (0.04, 0.0, 0.0), np.zeros((3, 3))),
    ]


def rod_parts():
    """Steel piston tube 25/19 mm, 0.35 m back from the spherical joint, ball nut 0.2 kg at its end, rod end 0.1 kg."""
    m_tube = 7850.0 * math.pi / 4 * (0.025**2 - 0.019**2) * 0.35
    return [
        (m_tube, (-0.175, 0.0, 0.0), tube(m_tube, 0.0125, 0.0095, 0.35)),
        (0.2, (-0.35, 0.0, 0.0), np.zeros((3, 3))),
        (0.1, (0.0, 0.0, 0.0), np.zeros((3, 3))),
    ]


CYLINDER = ne.Inertia(*composite(cylinder_parts()))
ROD = ne.Inertia(*composite(rod_parts()))


def layout(k: int) -> tuple[float, float]:
    """(base joint angle, platform joint angle) [rad] of leg k (0-based): leg 2j+1 and 2j+2 from base pair j."""
    side = -1 if k % 2 == 0 else 1
    centre = 120.0 * (k // 2)
    return math.radians(centre + side * 10.0), math.radians(centre + side * 50.0)


def oracle(legs: bool = True, g: float = 9.81, payload: bool = False) -> ne.Mechanism:
    """The hexapod from this file's numbers: R_b = 0.4 m, r = 0.35 m, gamma_b = gamma_p = 10 deg, the bodies above."""
    out = []
    for k in range(6):
        b, p = layout(k)
        out.append(
            ne.Leg(
                "UPS",
                (0.4 * math.cos(b), 0.4 * math.sin(b), 0.0),
                (-math.sin(b), math.cos(b), 0.0),
                (0.35 * math.cos(p), 0.35 * math.sin(p), 0.0),
                0.0,
                bodies=(CYLINDER, ROD) if legs else (ne.Inertia(), ne.Inertia()),
            )
        )
    m_p, r = 2.06, 0.35
    platform = [ne.Inertia(m_p, (0.0, 0.0, 0.0), np.diag((m_p * r * r / 4, m_p * r * r / 4, m_p * r * r / 2)))]
    if payload:
        P = PAYLOAD
        tensor = [[P[f"I_payload_{min(i, j)}{max(i, j)}"] for j in "xyz"] for i in "xyz"]
        platform.append(ne.Inertia(P["m_payload"], (P["payload_x"], P["payload_y"], P["payload_z"]), tensor))
    return ne.Mechanism(tuple(out), tuple(platform), g, coordinates=ne.POSE)


def engine(g: float = 9.81, **values) -> Engine:
    return Engine(HEX.describe({**V, **values}), g=g)


def relative(a, b) -> float:
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


def inside(eng: Engine, mech: ne.Mechanism, q) -> bool:
    """Within the strokes (the oracle's leg lengths) and the margins (the engine's refusal or its margin)."""
    rho = ne.joints(mech, q)
    if np.any(rho < LO) or np.any(rho > HI):
        return False
    try:
        m = eng.margins(q)
    except KinematicsError:
        return False
    return min(m.parallel, m.inverse) > MARGIN and np.sign(m.det) == np.sign(eng.margins(HOME).det)


def random_states(eng: Engine, mech: ne.Mechanism, rng, count: int):
    states = []
    for _ in range(50 * count):
        if len(states) == count:
            break
        q = HOME + rng.uniform(-1.0, 1.0, 6) * SPREAD
        if inside(eng, mech, q):
            states.append((q, rng.uniform(-0.5, 0.5, 6), rng.uniform(-5.0, 5.0, 6)))
    assert len(states) == count, f"only {len(states)} of {count} random poses are inside the workspace"
    return states


# ----------------------------------------------------------------------------- the numbers
def test_the_6ups_numbers_follow_from_their_inputs():
    assert (V["m_cylinder"], V["x_cylinder"], V["z_cylinder"]) == pytest.approx(
        (CYLINDER.mass, CYLINDER.com[0], CYLINDER.com[2]), rel=1e-12
    )
    assert CYLINDER.com[1] == 0.0 and ROD.com[1] == ROD.com[2] == 0.0
    t = CYLINDER.tensor
    assert (V["I_cylinder_xx"], V["I_cylinder_yy"], V["I_cylinder_zz"], V["I_cylinder_xz"]) == pytest.approx(
        (t[0][0], t[1][1], t[2][2], t[0][2]), rel=1e-12
    )
    assert t[0][1] == t[1][2] == 0.0
    assert (V["m_rod"], V["x_rod"], V["I_rod_xx"], V["I_rod"]) == pytest.approx(
        (ROD.mass, ROD.com[0], ROD.tensor[0][0], ROD.tensor[1][1]), rel=1e-12
    )
    assert V["m_platform"] == 2.06 and V["r"] == 0.35 and V["R_b"] == 0.4  # paper section 3, the MAST's H
    top = HEX.describe().topology
    assert top.names == ne.POSE and top.n == 6
    assert [d.stroke for d in top.drives] == [(LO, HI)] * 6 and HI - LO == pytest.approx(0.3)  # the paper's 300 mm
    # home: level, centred, every leg at mid-stroke (the oracle's leg lengths on its own layout)
    assert HOME[[0, 1, 3, 4, 5]].tolist() == [0.0] * 5
    np.testing.assert_allclose(ne.joints(oracle(), HOME), 0.6, rtol=0.0, atol=1e-12)
    np.testing.assert_allclose(engine().ik(HOME), 0.6, rtol=0.0, atol=1e-12)
    # the joint pair spacing: two base joints 0.139 m apart, two platform joints 0.122 m (docs/designs/6ups.md)
    desc = HEX.describe()
    b = [np.asarray(leg.base_point()) for leg in desc.legs]
    s = [np.asarray(leg.platform_point()) for leg in desc.legs]
    assert np.linalg.norm(b[0] - b[1]) == pytest.approx(0.8 * math.sin(math.radians(10)), rel=1e-12)
    assert np.linalg.norm(s[1] - s[2]) == pytest.approx(0.7 * math.sin(math.radians(10)), rel=1e-12)


# ----------------------------------------------------------------------------- inverse dynamics
@pytest.mark.parametrize(
    "legs, g, payload",
    [(True, 9.81, False), (True, 0.0, False), (False, 9.81, False), (False, 0.0, False), (True, 9.81, True)],
)
def test_6ups_inverse_dynamics_agree_with_newton_euler(legs, g, payload):
    values = {**({} if legs else LEGS_FREE), **(PAYLOAD if payload else {})}
    eng = engine(g, **values)
    mech = oracle(legs, g, payload)
    worst = 0.0
    for q, rd, rdd in random_states(eng, mech, np.random.default_rng(41), 30):
        idp = eng.inverse_dynamics_at_pose(q, rd, rdd)
        np.testing.assert_allclose(idp.pose, q, rtol=0.0, atol=1e-15)
        np.testing.assert_allclose(ne.joints(mech, q), eng.ik(q), rtol=0.0, atol=1e-12)
        worst = max(worst, relative(ne.forces(mech, q, rd, rdd), idp.t_rho))
    assert worst < TOL


def test_6ups_oracle_sees_the_cylinders_product_of_inertia_and_the_rod():
    """Without the motor's offset (I_xz, z_cylinder) or the rod's mass the oracle disagrees: the check sees them."""
    eng = engine()
    mech = oracle()
    q, rd, rdd = random_states(eng, mech, np.random.default_rng(43), 1)[0]
    right = eng.inverse_dynamics_at_pose(q, rd, rdd).t_rho
    centred = ne.Inertia(CYLINDER.mass, (CYLINDER.com[0], 0.0, 0.0), np.diag(np.diag(CYLINDER.tensor)))
    for bodies in ((centred, ROD), (CYLINDER, ne.Inertia())):
        wrong = ne.Mechanism(
            tuple(ne.Leg(leg.kind, leg.base, leg.t, leg.s, 0.0, bodies=bodies) for leg in mech.legs),
            mech.platform,
            mech.g,
            mech.coordinates,
        )
        assert relative(ne.forces(wrong, q, rd, rdd), right) > 1e-4
    assert relative(ne.forces(mech, q, rd, rdd), right) < TOL


# ----------------------------------------------------------------------------- statics
def leg_frames(mech: ne.Mechanism, q):
    """Per leg: (base point, S, rotation world <- leg frame: x along the leg, y = unit(t x x))."""
    out = []
    for leg, S in zip(mech.legs, ne.points(mech, q)):
        b = np.asarray(leg.base, float)
        x = (S - b) / np.linalg.norm(S - b)
        y = np.cross(leg.t, x)
        y /= np.linalg.norm(y)
        out.append((b, S, np.column_stack((x, y, np.cross(x, y)))))
    return out


def body_poses(mech: ne.Mechanism, q):
    """Every body: (inertia, origin of its frame, rotation world <- body): platform bodies, cylinders, rods."""
    R = ne.rotation(*q[3:])
    P = np.asarray(q[:3], float)
    poses = [(body, P, R) for body in mech.platform]
    for leg, (b, S, Rl) in zip(mech.legs, leg_frames(mech, q)):
        cylinder, rod = leg.bodies
        poses += [(cylinder, b, Rl), (rod, S, Rl)]
    return poses


def potential(mech: ne.Mechanism, q) -> float:
    """V [J]: every body's weight at its centre of mass."""
    return sum(
        body.mass * mech.g * (origin + R @ np.asarray(body.com, float))[2] for body, origin, R in body_poses(mech, q)
    )


def oracle_jacobian(mech: ne.Mechanism, q, h: float) -> np.ndarray:
    """drho/dq by central differences of the oracle's leg lengths."""
    q = np.asarray(q, dtype=float)
    return np.column_stack([(ne.joints(mech, q + h * e) - ne.joints(mech, q - h * e)) / (2 * h) for e in np.eye(6)])


def test_6ups_statics_at_rest_carry_the_weight():
    """At rest F = J^-T dV/dq (virtual work); the massless legs' forces at home by hand; the figures of the docs."""
    eng, mech = engine(), oracle()
    rng = np.random.default_rng(47)
    for q in [HOME] + [s[0] for s in random_states(eng, mech, rng, 5)]:
        h = 1e-5
        dV = np.array([(potential(mech, q + h * e) - potential(mech, q - h * e)) / (2 * h) for e in np.eye(6)])
        F = eng.inverse_dynamics_at_pose(q, np.zeros(6), np.zeros(6)).t_rho
        np.testing.assert_allclose(F, np.linalg.solve(oracle_jacobian(mech, q, h).T, dV), rtol=1e-7)
    # massless legs at home: six equal forces whose vertical components carry the platform, F u_z = m_p g / 6
    bare = engine(**LEGS_FREE).inverse_dynamics_at_pose(HOME, np.zeros(6), np.zeros(6)).t_rho
    uz = HOME[2] / 0.6
    np.testing.assert_allclose(bare, 2.06 * 9.81 / 6 / uz, rtol=1e-12)
    home = eng.inverse_dynamics_at_pose(HOME, np.zeros(6), np.zeros(6)).t_rho
    assert home == pytest.approx([14.9523, 13.0901] * 3, abs=1e-4)  # docs/designs/6ups.md


# ----------------------------------------------------------------------------- direct kinematics
def test_6ups_direct_kinematics_keep_their_branch_along_random_walks():
    eng, mech = engine(), oracle()
    steps = walk_keeps_branch(
        eng, lambda q: ne.joints(mech, q), HOME, (LO, HI), sigma=0.008, seed=53, walks=5, length=50
    )
    assert steps > 150


# ----------------------------------------------------------------------------- power balance
def pose_of(mech: ne.Mechanism, rho, guess) -> np.ndarray:
    """This file's direct kinematics: Newton on the oracle's leg lengths (difference Jacobian steers only)."""
    q = np.array(guess, dtype=float)
    for _ in range(30):
        res = ne.joints(mech, q) - rho
        if np.max(np.abs(res)) < 1e-15:
            break
        q -= np.linalg.solve(oracle_jacobian(mech, q, 1e-7), res)
    assert np.max(np.abs(ne.joints(mech, q) - rho)) < 1e-14
    return q


def vee(W) -> np.ndarray:
    return np.array([W[2, 1] - W[1, 2], W[0, 2] - W[2, 0], W[1, 0] - W[0, 1]]) / 2.0


def kinetic(mech: ne.Mechanism, rho, rho_dot, guess, eps: float = 1e-5) -> float:
    """T [J] from the bodies' poses at rho -+ eps rho_dot (central differences): 1/2 m v^2 + 1/2 w.I w per body."""
    rho, rho_dot = np.asarray(rho, float), np.asarray(rho_dot, float)
    before, now, after = (body_poses(mech, pose_of(mech, rho + k * eps * rho_dot, guess)) for k in (-1, 0, 1))
    T = 0.0
    for (body, o0, R0), (_, _, R1), (_, o2, R2) in zip(before, now, after):
        c = np.asarray(body.com, float)
        v = ((o2 + R2 @ c) - (o0 + R0 @ c)) / (2 * eps)
        w = vee(R1.T @ (R2 - R0) / (2 * eps))  # body frame
        T += 0.5 * body.mass * v @ v + 0.5 * w @ np.asarray(body.tensor, float) @ w
    return T


def test_6ups_power_balance_along_leg_trajectories():
    """sum F_i rho_dot_i = d/dt (T + V) along rho_i(t) = 0.6 + A_i sin(w_i t + p_i) (engine at the test's own pose)."""
    eng, mech = engine(), oracle()
    rng = np.random.default_rng(59)
    A = rng.uniform(0.01, 0.03, 6)
    w = 2 * math.pi * rng.uniform(2.0, 5.0, 6)
    p = rng.uniform(0.0, 2 * math.pi, 6)

    def legs(t):
        s = w * t + p
        return 0.6 + A * np.sin(s), A * w * np.cos(s), -A * w**2 * np.sin(s)

    def energy(t):
        rho, rd, _ = legs(t)
        return kinetic(mech, rho, rd, HOME) + potential(mech, pose_of(mech, rho, HOME))

    h = 2e-4
    powers, balances = [], []
    for t in np.linspace(0.0, 0.3, 7):
        rho, rd, rdd = legs(t)
        q = pose_of(mech, rho, HOME)
        powers.append(eng.inverse_dynamics_at_pose(q, rd, rdd).t_rho @ rd)
        balances.append((-energy(t + 2 * h) + 8 * energy(t + h) - 8 * energy(t - h) + energy(t - 2 * h)) / (12 * h))
    powers, balances = np.array(powers), np.array(balances)
    scale = np.abs(powers).max()
    assert scale > 1.0  # watts flow
    np.testing.assert_allclose(powers, balances, atol=1e-6 * scale)
    # and the balance sees a missing body: without the rods' kinetic and potential energy it fails
    bare = engine(m_rod=0.0, I_rod_xx=0.0, I_rod=0.0)
    missing = [
        bare.inverse_dynamics_at_pose(pose_of(mech, legs(t)[0], HOME), *legs(t)[1:]).t_rho @ legs(t)[1]
        for t in np.linspace(0.0, 0.3, 7)
    ]
    assert np.max(np.abs(np.array(missing) - balances)) > 1e-3 * scale


# ----------------------------------------------------------------------------- singularities and the workspace
def test_6ups_margins_at_home():
    """By the oracle's own drho/dq (central differences), scaled as the engine scales: the angles by r."""
    J = oracle_jacobian(oracle(), HOME, 1e-6)
    sv = np.linalg.svd(J / np.array([1.0, 1.0, 1.0, 0.35, 0.35, 0.35]), compute_uv=False)
    m = engine().margins(HOME)
    assert m.parallel == pytest.approx(sv[-1], rel=1e-7) and m.inverse == pytest.approx(1.0 / sv[0], rel=1e-7)
    assert m.det < 0 and min(m.parallel, m.inverse) > 5 * MARGIN
    assert (m.parallel, m.inverse, m.dexterity) == pytest.approx((0.7391, 0.4533, 2.985), abs=1e-3)  # docs


def through_home_by_hand(ws, d: int) -> tuple[float, float]:
    """The run of grid nodes through home along swept axis d whose six leg lengths (the oracle's) are within the
    stroke, in the summary's units; asserts that the next node on each side is outside it."""
    from mast.analyses.workspace import shown

    mech = oracle()
    axis, k = ws.axes[d], ws.swept[d]
    home = ws.home_index[d]

    def within(i: int) -> bool:
        q = np.array(ws.home, dtype=float)
        q[k] = axis[i]
        rho = ne.joints(mech, q)
        return bool(np.all(rho >= LO - 1e-12) and np.all(rho <= HI + 1e-12))

    lo = hi = home
    while lo > 0 and within(lo - 1):
        lo -= 1
    while hi < len(axis) - 1 and within(hi + 1):
        hi += 1
    assert 0 < lo and hi < len(axis) - 1 and not within(lo - 1) and not within(hi + 1)  # the stroke ends it
    c = ws.coordinates[k]
    return shown(c, axis[lo]), shown(c, axis[hi])


@pytest.mark.parametrize("sweep", [("x", "y", "z"), ("psi", "theta", "phi")])
def test_6ups_workspace_ranges_through_home_are_the_leg_strokes_by_hand(sweep):
    """`mast workspace 6UPS --sweep x,y,z` / `psi,theta,phi` (coarse grid): through home the strokes bound every
    range, at the grid nodes the legs' lengths by hand put there; the static forces at home and inside are the
    oracle's at rest; the other coordinates held at home."""
    from mast.analyses import workspace as W

    m = W.machine("6UPS")
    assert (m.rho_min, m.rho_max) == ((LO,) * 6, (HI,) * 6) and m.rho_home == pytest.approx((0.6,) * 6)
    assert m.missing_masses == ()
    ws = W.compute(m, 0.02, math.radians(3.0), sweep=sweep)
    s = W.summarize(ws)
    assert [c.name for c in ws.swept_coordinates] == list(sweep)
    for d, c in enumerate(ws.swept_coordinates):
        assert s["ranges_through_home"][W.column(c)] == pytest.approx(through_home_by_hand(ws, d), abs=1e-12)
    assert s["limited_by"] == {"outside the stroke": 1.0}
    assert s["static_forces"]["home_N"] == pytest.approx([14.95233353, 13.09014153] * 3, rel=1e-8)
    mech = oracle()
    inside_nodes = np.argwhere(ws.status == W.INSIDE)
    for k in np.random.default_rng(5).choice(len(inside_nodes), 5, replace=False):
        i = tuple(inside_nodes[k])
        at_rest = ne.forces(mech, ws.pose(i), np.zeros(6), np.zeros(6))
        np.testing.assert_allclose(ws.forces[(slice(None),) + i], at_rest, rtol=1e-9)


def test_6ups_pose_takes_six_numbers(capsys):
    """--pose with six numbers: the grid over the coordinates it moves (the translations, or the angles), inside or
    not by the strokes; a pose that moves four coordinates is refused naming them."""
    from mast.analyses.workspace import sweep_for_pose
    from mast.cli import main as cli_main

    top = HEX.describe().topology
    home_z = repr(float(HOME[2]))
    assert sweep_for_pose(top, (0.1, 0.0, HOME[2], 0.0, 0.0, 0.0)) == ("x", "y", "z")
    assert sweep_for_pose(top, (0.0, 0.0, HOME[2], 0.1, 0.0, 0.2)) == ("psi", "theta", "phi")
    assert sweep_for_pose(top, (0.1, 0.0, HOME[2], 0.1, 0.0, 0.0)) == ("x", "psi")
    with pytest.raises(
        ValueError, match=r"leaves home in 4 coordinates \(x, y, z, psi\); a workspace sweeps at most 3"
    ):
        sweep_for_pose(top, (0.1, 0.1, 0.5, 0.1, 0.0, 0.0))
    coarse = ["--step-z", "0.02", "--step-tilt", "3"]
    assert cli_main(["workspace", "6UPS", "--pose", f"0,0,{home_z},10,5,20", *coarse]) == 0
    assert '"inside": true' in capsys.readouterr().out
    # z = 0.72 m level: every leg sqrt(0.72^2 + d^2) = 0.766 m > 0.75 m, by hand
    d2 = 0.4**2 + 0.35**2 - 2 * 0.4 * 0.35 * math.cos(math.radians(40.0))
    assert math.sqrt(0.72**2 + d2) > HI
    assert cli_main(["workspace", "6UPS", "--pose", "0,0,0.72,0,0,0", *coarse]) == 1
    assert '"reason": "outside the stroke"' in capsys.readouterr().out


# ----------------------------------------------------------------------------- a 6-PUS beside it
PUS = load("6PUS")
PUS_HOME = np.asarray(PUS.describe().topology.home)
LINK_FREE = dict(m_link=0.0)


def pus_oracle(links: bool = True, g: float = 9.81, payload: bool = False) -> ne.Mechanism:
    """The 6-PUS from this file's numbers: vertical guides at the 6UPS's base joints, links of 0.35 m (a slender bar
    of 0.07 kg x 0.35 / 0.26, paper section 3's leg scaled), the 6UPS's platform joints and platform."""
    m = 0.07 * 0.35 / 0.26 if links else 0.0
    link = ne.Inertia(m, (0.175, 0.0, 0.0), np.diag((0.0, m * 0.35**2 / 12, m * 0.35**2 / 12)))
    hexapod = oracle(False, g, payload)
    legs = tuple(
        ne.Leg("PUS", leg.base, leg.t, leg.s, 0.35, axis=(0.0, 0.0, 1.0), bodies=(ne.Inertia(), link))
        for leg in hexapod.legs
    )
    return ne.Mechanism(legs, hexapod.platform, g, coordinates=ne.POSE)


def pus_engine(g: float = 9.81, **values) -> Engine:
    return Engine(PUS.describe({**PUS.values(), **values}), g=g)


@pytest.mark.parametrize(
    "links, g, payload",
    [(True, 9.81, False), (True, 0.0, False), (False, 9.81, False), (False, 0.0, False), (True, 9.81, True)],
)
def test_6pus_inverse_dynamics_agree_with_newton_euler(links, g, payload):
    values = {**({} if links else LINK_FREE), **(PAYLOAD if payload else {})}
    eng = pus_engine(g, **values)
    mech = pus_oracle(links, g, payload)
    assert PUS.values()["m_link"] == pytest.approx(0.07 * 0.35 / 0.26, rel=1e-15)
    rng = np.random.default_rng(61)
    worst, count = 0.0, 0
    for _ in range(300):
        q = PUS_HOME + rng.uniform(-1.0, 1.0, 6) * SPREAD
        try:
            margins = eng.margins(q)
        except KinematicsError:  # a link too short for the pose
            continue
        rho = ne.joints(mech, q)
        if np.any(rho < 0.0) or np.any(rho > 0.3) or min(margins.parallel, margins.inverse) < MARGIN:
            continue
        rd, rdd = rng.uniform(-0.5, 0.5, 6), rng.uniform(-5.0, 5.0, 6)
        np.testing.assert_allclose(rho, eng.ik(q), rtol=0.0, atol=1e-12)
        worst = max(worst, relative(ne.forces(mech, q, rd, rdd), eng.inverse_dynamics_at_pose(q, rd, rdd).t_rho))
        count += 1
    assert count >= 30 and worst < TOL


def test_6pus_statics_and_direct_kinematics():
    """Massless links at home by hand: the sliders carry the platform's weight, F_k = m_p g / 6 whatever the links'
    lean; the links' weight adds; the direct kinematics keep their branch along random walks of the carriages."""
    home = pus_engine().inverse_dynamics_at_pose(PUS_HOME, np.zeros(6), np.zeros(6)).t_rho
    bare = pus_engine(**LINK_FREE).inverse_dynamics_at_pose(PUS_HOME, np.zeros(6), np.zeros(6)).t_rho
    np.testing.assert_allclose(bare, 2.06 * 9.81 / 6, rtol=1e-12)
    assert home == pytest.approx([4.2925] * 6, abs=1e-4)  # docs/designs/6ups.md
    eng, mech = pus_engine(), pus_oracle()
    steps = walk_keeps_branch(
        eng,
        lambda q: ne.joints(mech, q),
        PUS_HOME,
        (0.0, 0.3),
        sigma=0.006,
        seed=67,
        walks=4,
        length=40,
        cold_start=False,
    )
    assert steps > 100


def test_6pus_oracle_sees_the_links_inertia():
    """Without the links' inertia about their centre (their mass kept) the oracle disagrees by 1e-2."""
    eng, mech = pus_engine(), pus_oracle()
    link = mech.legs[0].bodies[1]
    point = ne.Inertia(link.mass, link.com)
    wrong = ne.Mechanism(
        tuple(
            ne.Leg("PUS", leg.base, leg.t, leg.s, 0.35, axis=leg.axis, bodies=(ne.Inertia(), point))
            for leg in mech.legs
        ),
        mech.platform,
        mech.g,
        mech.coordinates,
    )
    rng = np.random.default_rng(3)
    q = PUS_HOME + np.array([0.02, -0.01, 0.03, 0.1, -0.05, 0.08])
    rd, rdd = rng.uniform(-0.5, 0.5, 6), rng.uniform(-5.0, 5.0, 6)
    right = eng.inverse_dynamics_at_pose(q, rd, rdd).t_rho
    assert relative(ne.forces(mech, q, rd, rdd), right) < TOL < 1e-3 < relative(ne.forces(wrong, q, rd, rdd), right)


def test_6ups_inertial_split_is_newton_euler_s_mass_matrix_and_bias():
    """Engine.inertial's M and b (what the mechanism block holds between its full updates, F = M rho_ddot + b)
    against the oracle's: b = its forces without acceleration, M's column j = its forces of a unit acceleration of
    drive j less b; and F = M rho_ddot + b is the engine's own t_rho of the same evaluation."""
    eng = engine(9.81, **PAYLOAD)
    mech = oracle(True, 9.81, True)
    n, worst = 6, 0.0
    for q, rd, rdd in random_states(eng, mech, np.random.default_rng(47), 10):
        _, J, _ = eng.jacobian(q)
        out = eng.inertial(q, J, rd, rdd)
        t, M, b = np.array(out[:n]), np.array(out[n + 6 : n + 6 + n * n]).reshape(n, n), np.array(out[n + 6 + n * n :])
        bias = ne.forces(mech, q, rd, np.zeros(n))
        mass = np.column_stack([ne.forces(mech, q, rd, e) - bias for e in np.eye(n)])
        worst = max(worst, relative(bias, b), relative(mass.ravel(), M.ravel()))
        np.testing.assert_allclose(M @ rdd + b, t, rtol=0.0, atol=1e-12 * np.max(np.abs(t)))
        np.testing.assert_allclose(M, M.T, rtol=0.0, atol=1e-12 * np.max(np.abs(M)))
    assert worst < TOL
