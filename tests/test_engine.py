"""The inverse-dynamics engine on its own: traced code against plain evaluation and finite
differences, and whole mechanisms against textbook equations that share no code with it.

- a random expression using every primitive: generated values equal the plain floats bit
  for bit; first and second derivatives equal high-order finite differences;
- the planar two-link arm: M(q), Coriolis/centrifugal and gravity terms of the textbook
  (Spong, Robot Modeling and Control, section 7.4.2);
- a free-spinning gimbal (Z-Y-X angles as joints, full inertia tensor, offset centre of
  mass): the Euler-Lagrange equations by numbers from its Lagrangian written with the
  textbook angular-velocity matrix;
- admissibility checks, refusal to branch on traced values, sharing and copying.
"""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from fmus.common import tracer as E
from fmus.common.tracer import TraceError
from fmus.mechanism.engine import Body, Description, Engine, Evaluation, KinematicsError


# ---------------------------------------------------------------------------- expressions
def expr(q):
    """Every primitive once or more; smooth around the test points."""
    a, b, c = q
    s = E.sin(a * b) + E.cos(c) / (2.0 + a * a)
    r = E.sqrt(1.5 + b * b + 0.3 * c)
    t = E.atan2(s - 0.1, r) * E.hypot(a, c - 0.4)
    u = abs(b - 2.0) * E.sign(a + 5.0) - (-c) * 0.7
    return [s * r - t, u / r + 3.0, E.cos(t) * E.sin(u) - a]


def compiled(outputs_of):
    g = E.Graph()
    q = [g.input(f"q{j}") for j in range(3)]
    outs = [E.lift(g, o) for o in outputs_of(q)]
    d = [E.Forward(g, {f"q{j}": (1.0 if j == k else 0.0) for j in range(3)}) for k in range(3)]
    qd = [g.input(f"qd{j}") for j in range(3)]
    p1 = E.Forward(g, {f"q{j}": qd[j] for j in range(3)})
    p2 = E.Second(g, p1, {})
    flat = outs + [d[k](o) for o in outs for k in range(3)] + [p2(o) for o in outs]
    return E.compile_function("f", [f"q{j}" for j in range(3)] + [f"qd{j}" for j in range(3)], flat, g)


def test_generated_values_are_the_plain_floats_and_derivatives_are_exact():
    f = compiled(expr)
    rng = np.random.default_rng(3)
    for _ in range(20):
        q = rng.uniform(-1.0, 1.0, 3)
        qd = rng.uniform(-1.0, 1.0, 3)
        out = f(*q, *qd)
        plain = expr(list(q))
        assert tuple(out[:3]) == tuple(plain)  # same operations, same floats
        grad = np.array(out[3:12]).reshape(3, 3)
        for k in range(3):  # 6th-order central differences
            h = 1e-3
            e = np.eye(3)[k]
            fd = (
                sum(
                    w * np.array(expr(list(q + s * h * e)))
                    for s, w in ((3, 1 / 60), (2, -3 / 20), (1, 3 / 4), (-1, -3 / 4), (-2, 3 / 20), (-3, -1 / 60))
                )
                / h
            )
            np.testing.assert_allclose(grad[:, k], fd, rtol=1e-9, atol=1e-10)
        h = 1e-3  # second derivative along q + t qd
        line = lambda t: np.array(expr(list(q + t * qd)))  # noqa: E731
        fd2 = (-line(2 * h) + 16 * line(h) - 30 * line(0) + 16 * line(-h) - line(-2 * h)) / (12 * h * h)
        np.testing.assert_allclose(out[12:15], fd2, rtol=1e-7, atol=1e-7)


def test_branching_on_a_traced_value_is_refused():
    class Branchy(Description):
        bodies = (Body("b", 1.0),)

        def evaluate(self, q):
            z = q[0] if q[0] > 0 else -q[0]
            return Evaluation(list(q), [0.0] * 6, [((0.0, 0.0, z), np.eye(3))])

    with pytest.raises(TraceError, match="branch"):
        Engine(Branchy())


def test_checks_run_where_the_description_puts_them():
    class Checked(Description):
        bodies = (Body("b", 1.0),)

        def evaluate(self, q):
            w2 = 1.0 - q[1] * q[1]

            def reach(w2_, q1):
                if not w2_ > 0.0:
                    raise KinematicsError(f"reach lost at q1 = {q1:g}")

            E.require(reach, w2, q[1])
            rho = [q[0], q[1] + E.sqrt(w2), q[2]]
            return Evaluation(rho, [0.0] * 6, [((q[0], 0.0, 0.0), np.eye(3))])

        def guess(self, rho):
            return (rho[0], 0.0, rho[2])

    eng = Engine(Checked())
    assert eng.ik((0.1, 0.6, 0.2)) == (0.1, 0.6 + math.sqrt(1.0 - 0.36), 0.2)
    with pytest.raises(KinematicsError, match="reach lost at q1 = 1.5"):  # not a math domain error
        eng.ik((0.1, 1.5, 0.2))
    with pytest.raises(KinematicsError, match="reach lost"):
        eng.inverse_dynamics_at_pose((0.1, 1.5, 0.2), (0, 0, 0), (0, 0, 0))
    # the plain-float route checks at once too
    with pytest.raises(KinematicsError, match="reach lost"):
        Checked().evaluate([0.1, 1.5, 0.2])


# ---------------------------------------------------------------------------- planar two-link arm
def ry(a):
    """Rotation about -y by a: the x axis turns towards +z (the arm's plane is x-z)."""
    c, s = E.cos(a), E.sin(a)
    return ((c, 0.0, -s), (0.0, 1.0, 0.0), (s, 0.0, c))


class TwoLink(Description):
    name = "2R arm"
    coordinates = ("q1", "q2")
    joints = ("q1", "q2")

    def __init__(self, m1, m2, l1, lc1, lc2, I1, I2):
        self.p = (m1, m2, l1, lc1, lc2, I1, I2)
        self.bodies = (
            Body("link1", m1, (lc1, 0.0, 0.0), ((0.3 * I1, 0, 0), (0, I1, 0), (0, 0, I1))),
            Body("link2", m2, (lc2, 0.0, 0.0), ((0.1 * I2, 0, 0), (0, I2, 0), (0, 0, I2))),
        )

    def evaluate(self, q):
        q1, q2 = q
        l1 = self.p[2]
        elbow = (l1 * E.cos(q1), 0.0, l1 * E.sin(q1))
        return Evaluation([q1, q2], [0.0] * 6, [((0.0, 0.0, 0.0), ry(q1)), (elbow, ry(q1 + q2))])

    def guess(self, rho):
        return tuple(rho)


def test_two_link_arm_matches_the_textbook():
    m1, m2, l1, lc1, lc2, I1, I2, g = 1.3, 0.8, 0.5, 0.22, 0.17, 0.031, 0.012, 9.81
    eng = Engine(TwoLink(m1, m2, l1, lc1, lc2, I1, I2), g=g)
    rng = np.random.default_rng(5)
    for _ in range(10):
        q = rng.uniform(-2, 2, 2)
        qd = rng.uniform(-3, 3, 2)
        qdd = rng.uniform(-5, 5, 2)
        res = eng.inverse_dynamics(q, qd, qdd)
        c2 = math.cos(q[1])
        M = np.array(
            [
                [m1 * lc1**2 + m2 * (l1**2 + lc2**2 + 2 * l1 * lc2 * c2) + I1 + I2, m2 * (lc2**2 + l1 * lc2 * c2) + I2],
                [m2 * (lc2**2 + l1 * lc2 * c2) + I2, m2 * lc2**2 + I2],
            ]
        )
        h = -m2 * l1 * lc2 * math.sin(q[1])
        C = np.array([h * qd[1] ** 2 + 2 * h * qd[0] * qd[1], -h * qd[0] ** 2])
        G = np.array(
            [
                (m1 * lc1 + m2 * l1) * g * math.cos(q[0]) + m2 * lc2 * g * math.cos(q[0] + q[1]),
                m2 * lc2 * g * math.cos(q[0] + q[1]),
            ]
        )
        np.testing.assert_allclose(res.M, M, atol=1e-14)
        np.testing.assert_allclose(res.c_term, C, atol=1e-13)
        np.testing.assert_allclose(res.g_term, G, atol=1e-13)
        np.testing.assert_allclose(res.t_rho, M @ qdd + C + G, atol=1e-12)
        np.testing.assert_allclose(res.q, q, atol=1e-15)  # identity kinematics: DK trivial
        # the body split adds up, and rotation never carries gravity
        total = sum(i + c + gg for i, c, gg in res.terms.values())
        np.testing.assert_allclose(total, res.t_rho, atol=1e-12)
        assert all(not np.any(gg) for (body, kind), (_, _, gg) in res.terms.items() if kind == "rotation")


# ---------------------------------------------------------------------------- gimbal
def rzyx(psi, theta, phi):
    cx, sx, cy, sy, cz, sz = (E.cos(psi), E.sin(psi), E.cos(theta), E.sin(theta), E.cos(phi), E.sin(phi))
    return (
        (cz * cy, cz * sy * sx - sz * cx, cz * sy * cx + sz * sx),
        (sz * cy, sz * sy * sx + cz * cx, sz * sy * cx - cz * sx),
        (-sy, cy * sx, cy * cx),
    )


INERTIA = ((0.08, 0.004, -0.006), (0.004, 0.05, 0.003), (-0.006, 0.003, 0.11))
COM = (0.02, -0.015, 0.04)


class Gimbal(Description):
    name = "gimbal"
    coordinates = ("psi", "theta", "phi")
    joints = ("psi", "theta", "phi")
    bodies = (Body("rotor", 2.5, COM, INERTIA),)

    def evaluate(self, q):
        psi, theta, phi = q
        return Evaluation(list(q), [0.0] * 6, [((0.0, 0.0, 0.3), rzyx(psi, theta, phi))])

    def guess(self, rho):
        return tuple(rho)


def lagrangian(q, qd, m=2.5, g=9.81):
    """Textbook: w_body = E(q) qd for R = Rz Ry Rx; centre of mass R c above (0, 0, 0.3)."""
    psi, theta, phi = q
    Em = np.array(
        [
            [1, 0, -math.sin(theta)],
            [0, math.cos(psi), math.sin(psi) * math.cos(theta)],
            [0, -math.sin(psi), math.cos(psi) * math.cos(theta)],
        ]
    )
    w = Em @ qd
    R = np.array(rzyx(*q), dtype=float)
    # centre-of-mass velocity: omega_world x (R c), omega_world = R w
    v = np.cross(R @ w, R @ np.array(COM))
    T = 0.5 * w @ np.array(INERTIA) @ w + 0.5 * m * v @ v
    V = m * g * (0.3 + (R @ np.array(COM))[2])
    return T - V


def test_gimbal_matches_euler_lagrange_by_numbers():
    eng = Engine(Gimbal())
    rng = np.random.default_rng(9)
    h = 1e-5
    for _ in range(5):
        q, qd, qdd = rng.uniform(-0.8, 0.8, 3), rng.uniform(-2, 2, 3), rng.uniform(-4, 4, 3)
        res = eng.inverse_dynamics_at_pose(q, qd, qdd)
        path = lambda t: (q + t * qd + 0.5 * t * t * qdd, qd + t * qdd)  # noqa: E731

        def p(t):  # dL/dqd along the path (L is quadratic in qd: a wide difference is exact)
            qq, vv = path(t)
            return np.array([(lagrangian(qq, vv + 0.1 * e) - lagrangian(qq, vv - 0.1 * e)) / 0.2 for e in np.eye(3)])

        hp = 1e-3
        dpdt = (-p(2 * hp) + 8 * p(hp) - 8 * p(-hp) + p(-2 * hp)) / (12 * hp)
        dLdq = np.array([(lagrangian(q + h * e, qd) - lagrangian(q - h * e, qd)) / (2 * h) for e in np.eye(3)])
        np.testing.assert_allclose(res.t_rho, dpdt - dLdq, atol=2e-6 * max(1.0, np.abs(res.t_rho).max()))
        np.testing.assert_allclose(res.M, res.M.T, atol=0)
        assert np.linalg.eigvalsh(res.M).min() > 0


# ---------------------------------------------------------------------------- sharing, copying, errors
def test_engines_are_shared_and_survive_deep_copies(mechanism_params):
    from fmus.mechanism.designs import engine
    from fmus.mechanism.model import MechanismBlock

    assert engine(mechanism_params) is engine(dict(mechanism_params))
    blk = MechanismBlock(mechanism_params)
    clone = copy.deepcopy(blk)
    assert clone.engine is blk.engine
    blk.set(rho_1=0.15, rho_2=0.15, rho_3=0.15)
    blk.initialize(0.0)
    state = blk.get_state()
    blk.set(rho_1=0.16)
    blk.do_step(0.0, 1e-3)
    blk.set_state(state)
    assert blk.get("F_1") == pytest.approx(10.791, abs=1e-9)


@pytest.mark.parametrize("sets", [(), ("geometry_3prs_inclined.ssv",), ("geometry_3prs_120.ssv",)])
def test_forces_after_the_direct_kinematics_reuse_its_pose_bit_for_bit(mechanism_params, sets):
    """dk_kept + forces_kept (the mechanism block's hot path: the forces read the pose's geometry the direct
    kinematics computed at q) give the very floats of dk + inertial (the forces, the pose, M and b), which compute
    everything themselves; inertial's forces and pose are forces'."""
    from conftest import RESOURCES, read_values

    from fmus.mechanism.designs import engine

    params = dict(mechanism_params)
    for name in sets:
        params.update(read_values(RESOURCES / name))
    eng = engine({**params, "m_payload": 3.0, "payload_x": 0.02})
    assert eng._kept()[0] and len(eng._fn("forces_kept").source) < len(eng._fn("forces").source)
    q = None
    for k in range(6):
        rho = eng.ik((0.4 + 0.005 * k, 0.01 * k, -0.008 * k))
        rd, rdd = (0.1 * k, -0.05, 0.02 * k), (1.0, -2.0 * k, 0.5)
        (*plain,) = eng.dk(rho, q)
        q, J, cond, kept = eng.dk_kept(rho, q)
        assert [q, J, cond] == plain
        full = eng.inertial(q, J, rd, rdd)
        assert eng.forces_kept(kept, q, J, rd, rdd) == full
        assert full[: eng.n + 6] == eng.forces(q, J, rd, rdd) and len(full) == eng.n + 6 + eng.n**2 + eng.n


def test_engine_rejects_inconsistent_descriptions():
    class Wrong(Description):
        bodies = (Body("b", 1.0),)

        def evaluate(self, q):
            return Evaluation(list(q)[:2], [0.0] * 6, [((0, 0, 0), np.eye(3))])

    with pytest.raises(ValueError, match="3 joint coordinates"):
        Engine(Wrong())
    with pytest.raises(ValueError, match="symmetric"):
        Body("b", 1.0, inertia=((1, 2, 0), (0, 1, 0), (0, 0, 1)))
    with pytest.raises(ValueError, match="mass"):
        Body("b", -1.0)
