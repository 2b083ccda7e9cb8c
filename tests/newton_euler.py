"""Newton-Euler inverse dynamics of a parallel mechanism, written for the tests (numpy only).

An independent check of the mechanism engine (``fmus/mechanism/engine.py``) and its descriptions: it
shares no code with ``fmus/`` and takes plain numbers. Every body gets the classic Newton-Euler
equations with the joints' reaction wrenches as unknowns,

    sum_j f_j = m (a_G + g e_z),        sum_j (m_j + (P_j - G) x f_j) = I alpha + omega x I omega,

(f_j, m_j the force and moment joint j applies to the body at its centre P_j; a joint transmits what it
does not let move: a spherical joint a force, a revolute a force and the moments normal to its axis, a
universal joint a force and the moment along the normal of its two axes, a prismatic joint the moments
and the forces normal to its axis plus, when driven, the actuator force along it). The square linear
system of all bodies is solved for every reaction and the n actuator forces. The engine instead projects
the bodies' inertial forces with its Jacobians (energy equivalence, Boltzmann-Hamel); the two routes
agree only if both are right.

Kinematics, also written apart from the engine: the platform pose (x, y, z, psi, theta, phi),
R = Rz(phi) Ry(theta) Rx(psi); the parasitic pose components solved from the legs' constraints by
Newton's method; the platform twist and acceleration from the joint rates by the 6 x 6 system of the
constraint rates and the leg-length rates; every leg body's motion from the motion of its two ends.

Legs (``Leg``), base to platform, s the platform point (platform frame) of its spherical joint S:

- ``"PRS"``: a slider on a fixed guide (foot ``base``, unit direction ``axis``; joint coordinate rho:
  slider travel from the foot, driven), a revolute on the slider (fixed axis ``t``, normal to the guide),
  a rod of length ``length`` from the slider to S (bodies: ``slider``, ``rod``; rod frame x along the rod
  slider -> S, y = t, z = x cross y, origin at the slider).
- ``"RPS"``: a revolute at ``base`` (fixed axis ``t``), a cylinder, a driven prismatic joint, a piston
  carrying S; rho = |S - base| - ``length`` (bodies: ``cylinder``, frame origin at the base joint; ``piston``,
  origin at S; both frames x along the leg base -> S, y = t, z = x cross y).
- ``"UPS"``: a universal joint at ``base`` (first axis ``t`` fixed to the base, second axis fixed in the
  cylinder, normal to t and to the leg: y = unit(t cross x)), cylinder, driven prismatic, piston, S; frames
  x along the leg, y the second axis, z = x cross y; rho = |S - base| - ``length``.

- ``"PUS"``: a PRS whose revolute on the slider is a universal joint (first axis ``t`` fixed to the slider,
  second axis in the rod, normal to t and to the rod: y = unit(t cross x)); rod frame x along the rod slider
  -> S, y that second axis (bodies: ``slider``, ``rod``).

A PRS or RPS leg constrains S to the plane through its base normal to t: (S - base) . t = 0.

Forces: F_k the force actuator k applies along its joint (on the slider or piston along +axis, the
reaction on the guide or cylinder), so that F . rho_dot is its power (the engine's t_rho).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Optional, Sequence

import numpy as np

POSE = ("x", "y", "z", "psi", "theta", "phi")


@dataclass(frozen=True)
class Inertia:
    """A rigid body's mass [kg], centre of mass [m] and inertia tensor about it [kg m^2], in its frame."""

    mass: float = 0.0
    com: tuple = (0.0, 0.0, 0.0)
    tensor: tuple = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))


@dataclass(frozen=True)
class Leg:
    """One leg (module docstring): ``kind`` "PRS" | "RPS" | "UPS" | "PUS"; ``base`` [m] (world); ``axis`` (PRS,
    PUS: guide direction); ``t`` (the revolute axis, or the universal joint's first axis); ``s`` [m] platform frame;
    ``length`` [m] (PRS, PUS: rod length; RPS, UPS: leg length at rho = 0); ``bodies``: the leg's two bodies in
    order (PRS, PUS: slider, rod; RPS, UPS: cylinder, piston)."""

    kind: str
    base: tuple
    t: tuple
    s: tuple
    length: float
    axis: tuple = (0.0, 0.0, 1.0)
    bodies: tuple = (Inertia(), Inertia())


@dataclass(frozen=True)
class Mechanism:
    """Platform (``platform``: its bodies, each in the platform frame, origin at P = (x, y, z)), legs, g
    [m/s^2] along -z, the independent coordinates (names of POSE components)."""

    legs: tuple
    platform: tuple
    g: float
    coordinates: tuple = ("z", "psi", "theta")

    @property
    def parasitic(self) -> tuple:
        return tuple(p for p in POSE if p not in self.coordinates)


# ----------------------------------------------------------------------------- small vector helpers
def _v(x) -> np.ndarray:
    return np.asarray(x, dtype=float)


def _unit(x) -> np.ndarray:
    x = _v(x)
    return x / np.linalg.norm(x)


def rotation(psi: float, theta: float, phi: float) -> np.ndarray:
    """R = Rz(phi) Ry(theta) Rx(psi) (world <- platform)."""
    cx, sx, cy, sy, cz, sz = (
        math.cos(psi),
        math.sin(psi),
        math.cos(theta),
        math.sin(theta),
        math.cos(phi),
        math.sin(phi),
    )
    Rx = np.array(((1, 0, 0), (0, cx, -sx), (0, sx, cx)))
    Ry = np.array(((cy, 0, sy), (0, 1, 0), (-sy, 0, cy)))
    Rz = np.array(((cz, -sz, 0), (sz, cz, 0), (0, 0, 1)))
    return Rz @ Ry @ Rx


def _normals(a: np.ndarray) -> np.ndarray:
    """Two unit vectors normal to a and to each other, as the columns of a 3 x 2 matrix."""
    a = _unit(a)
    helper = np.array((1.0, 0.0, 0.0)) if abs(a[0]) < 0.9 else np.array((0.0, 1.0, 0.0))
    e1 = _unit(np.cross(a, helper))
    return np.column_stack((e1, np.cross(a, e1)))


# ----------------------------------------------------------------------------- kinematics
def points(mech: Mechanism, pose: Sequence[float]) -> list:
    """The spherical joints S_i [m] (world) at a pose."""
    x, y, z, psi, theta, phi = (float(v) for v in pose)
    R = rotation(psi, theta, phi)
    return [np.array((x, y, z)) + R @ _v(leg.s) for leg in mech.legs]


def joints(mech: Mechanism, pose: Sequence[float]) -> np.ndarray:
    """The joint coordinates rho [m] at a pose (PRS: the slider below S, the working assembly)."""
    out = []
    for leg, S in zip(mech.legs, points(mech, pose)):
        d = S - _v(leg.base)
        if leg.kind in ("PRS", "PUS"):
            a = _unit(leg.axis)
            along = d @ a
            out.append(along - math.sqrt(leg.length**2 - (d @ d - along * along)))
        else:
            out.append(math.sqrt(d @ d) - leg.length)
    return np.array(out)


def constraints(mech: Mechanism, pose: Sequence[float]) -> np.ndarray:
    """(S_i - base_i) . t_i of every PRS and RPS leg [m] (0 on an assembled mechanism)."""
    return np.array(
        [
            (S - _v(leg.base)) @ _unit(leg.t)
            for leg, S in zip(mech.legs, points(mech, pose))
            if leg.kind in ("PRS", "RPS")
        ]
    )


def full_pose(mech: Mechanism, q: Sequence[float], tol: float = 1e-15) -> np.ndarray:
    """The six-value pose for the independent coordinates q: the parasitic components by Newton's method on
    the constraints from 0 (finite-difference Jacobian: it only steers, the residual is exact)."""
    pose = np.zeros(6)
    for name, value in zip(mech.coordinates, q):
        pose[POSE.index(name)] = float(value)
    free = [POSE.index(p) for p in mech.parasitic]
    if not free:
        return pose
    for _ in range(60):
        res = constraints(mech, pose)
        if np.max(np.abs(res)) < tol:
            return pose
        J = np.empty((len(res), len(free)))
        for k, i in enumerate(free):
            step = np.zeros(6)
            step[i] = 1e-7
            J[:, k] = (constraints(mech, pose + step) - constraints(mech, pose - step)) / 2e-7
        pose[free] -= np.linalg.solve(J, res)
    if np.max(np.abs(constraints(mech, pose))) < 1e-13:
        return pose
    raise ValueError(f"full_pose: the constraints do not close at q = {tuple(q)} (residual {res})")


def _rows(mech: Mechanism, pose, twist=None):
    """Rows A (6 x 6) of the constraint and leg-length rates in the platform twist (v_P, omega), and per row
    the velocity-product term of its second derivative (given the twist): A [a_P; alpha] + bias = second
    derivative of (constraint, leg coordinate) (for a PRS leg: of k rho with k = (S - C) . axis)."""
    x, y, z, psi, theta, phi = pose
    R = rotation(psi, theta, phi)
    P = np.array((x, y, z))
    con_rows, con_bias, leg_rows, leg_bias, scale = [], [], [], [], []
    v, w = (None, None) if twist is None else (_v(twist[:3]), _v(twist[3:]))
    rho = joints(mech, pose)
    for leg, rk in zip(mech.legs, rho):
        r = R @ _v(leg.s)
        S = P + r
        vS = None if v is None else v + np.cross(w, r)
        cen = None if v is None else np.cross(w, np.cross(w, r))  # S's acceleration when a_P = alpha = 0
        if leg.kind in ("PRS", "RPS"):
            t = _unit(leg.t)
            con_rows.append(np.concatenate((t, np.cross(r, t))))
            con_bias.append(None if v is None else t @ cen)
        if leg.kind in ("PRS", "PUS"):
            a = _unit(leg.axis)
            n = S - (_v(leg.base) + rk * a)
            k = n @ a
            leg_rows.append(np.concatenate((n, np.cross(r, n))) / k)
            scale.append(("PRS", n, k, a))
        else:
            d = S - _v(leg.base)
            u = d / np.linalg.norm(d)
            leg_rows.append(np.concatenate((u, np.cross(r, u))))
            scale.append(("LEG", u, np.linalg.norm(d), None))
        if v is not None:
            kind, n, k, a = scale[-1]
            if kind == "PRS":
                rd = (n @ vS) / k
                rel = vS - rd * a
                # n . a_S = k rho_ddot - |v_S - rho_dot a|^2
                leg_bias.append(((n @ cen) + rel @ rel) / k)
            else:
                rd = n @ vS
                # rho_ddot = u . a_S + (|v_S|^2 - rho_dot^2) / l
                leg_bias.append(n @ cen + (vS @ vS - rd * rd) / k)
    A = np.array(con_rows + leg_rows)
    bias = None if v is None else np.array(con_bias + leg_bias)
    return A, bias, len(con_rows)


def platform_motion(mech: Mechanism, pose, rho_dot, rho_ddot) -> tuple[np.ndarray, np.ndarray]:
    """The platform twist (v_P, omega) and acceleration (a_P, alpha) [world frame] for the joint rates."""
    A, _, nc = _rows(mech, pose)
    rhs = np.concatenate((np.zeros(nc), _v(rho_dot)))
    twist = np.linalg.solve(A, rhs)
    _, bias, _ = _rows(mech, pose, twist)
    acc = np.linalg.solve(A, np.concatenate((np.zeros(nc), _v(rho_ddot))) - bias)
    return twist, acc


# ----------------------------------------------------------------------------- Newton-Euler
@dataclass
class _Body:
    inertia: Inertia
    R: np.ndarray  # world <- body
    origin: np.ndarray
    a_origin: np.ndarray  # acceleration of the frame origin
    w: np.ndarray
    alpha: np.ndarray

    def com(self) -> np.ndarray:
        return self.origin + self.R @ _v(self.inertia.com)

    def wrench(self, g: float) -> tuple[np.ndarray, np.ndarray]:
        """What the joints must apply: m (a_G + g e_z) and I alpha + w x I w about the centre of mass."""
        c = self.R @ _v(self.inertia.com)
        aG = self.a_origin + np.cross(self.alpha, c) + np.cross(self.w, np.cross(self.w, c))
        I = self.R @ _v(self.inertia.tensor) @ self.R.T
        F = self.inertia.mass * (aG + np.array((0.0, 0.0, g)))
        return F, I @ self.alpha + np.cross(self.w, I @ self.w)


@dataclass
class _Joint:
    parent: Optional[int]  # body index, None: the ground
    child: int
    point: np.ndarray
    forces: np.ndarray  # 3 x k basis of the reaction force
    moments: np.ndarray  # 3 x j basis of the reaction moment
    drive: Optional[int] = None
    drive_axis: np.ndarray = field(default_factory=lambda: np.zeros(3))


def _frame(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    return np.column_stack((x, y, np.cross(x, y)))


def _universal(t, y, u, ud, udd) -> tuple[np.ndarray, np.ndarray]:
    """Angular velocity and acceleration of a body on a universal joint (first axis t fixed, second axis y) whose
    unit vector u moves with u_dot = ud, u_ddot = udd: w = th1 t + th2 y, u_dot = w x u; alpha = th1dd t + th2dd y
    + th2 (th1 t x y)."""
    G = np.column_stack((np.cross(t, u), np.cross(y, u)))
    th1, th2 = np.linalg.lstsq(G, ud, rcond=None)[0]
    w = th1 * t + th2 * y
    extra = th2 * th1 * np.cross(t, y)
    th1dd, th2dd = np.linalg.lstsq(G, udd - np.cross(w, ud) - np.cross(extra, u), rcond=None)[0]
    return w, th1dd * t + th2dd * y + extra


def _leg_bodies(leg: Leg, k: int, S, vS, aS, rho, rd, rdd, first: int):
    """The two bodies of leg k and its three joints (body indices from ``first``; the platform is body 0)."""
    B = _v(leg.base)
    t = _unit(leg.t)
    if leg.kind == "PRS":
        a = _unit(leg.axis)
        C = B + rho * a
        L = leg.length
        e = (S - C) / L
        ed = (vS - rd * a) / L
        edd = (aS - rdd * a) / L
        w, alpha = np.cross(e, ed), np.cross(e, edd)  # the rod turns about t only: w normal to e
        slider = _Body(leg.bodies[0], np.eye(3), C, rdd * a, np.zeros(3), np.zeros(3))
        rod = _Body(leg.bodies[1], _frame(e, t), C, rdd * a, w, alpha)
        joints = [
            _Joint(None, first, C, _normals(a), np.eye(3), drive=k, drive_axis=a),
            _Joint(first, first + 1, C, np.eye(3), _normals(t)),
            _Joint(first + 1, 0, S, np.eye(3), np.zeros((3, 0))),
        ]
        return [slider, rod], joints
    if leg.kind == "PUS":
        a = _unit(leg.axis)
        C = B + rho * a
        L = leg.length
        e = (S - C) / L
        ed = (vS - rd * a) / L
        edd = (aS - rdd * a) / L
        y = _unit(np.cross(t, e))  # the universal joint's second axis: normal to t and to the link
        w, alpha = _universal(t, y, e, ed, edd)
        slider = _Body(leg.bodies[0], np.eye(3), C, rdd * a, np.zeros(3), np.zeros(3))
        rod = _Body(leg.bodies[1], _frame(e, y), C, rdd * a, w, alpha)
        joints = [
            _Joint(None, first, C, _normals(a), np.eye(3), drive=k, drive_axis=a),
            _Joint(first, first + 1, C, np.eye(3), _unit(np.cross(t, y)).reshape(3, 1)),
            _Joint(first + 1, 0, S, np.eye(3), np.zeros((3, 0))),
        ]
        return [slider, rod], joints
    d = S - B
    ln = np.linalg.norm(d)
    u = d / ln
    ud = (vS - rd * u) / ln
    udd = (aS - rdd * u - 2.0 * rd * ud) / ln
    if leg.kind == "RPS":
        y = t
        w, alpha = np.cross(u, ud), np.cross(u, udd)  # turns about t only (t normal to u)
        base_joint = _Joint(None, first, B, np.eye(3), _normals(t))
    elif leg.kind == "UPS":
        y = _unit(np.cross(t, u))  # second axis: normal to t and to the leg
        w, alpha = _universal(t, y, u, ud, udd)
        base_joint = _Joint(None, first, B, np.eye(3), _unit(np.cross(t, y)).reshape(3, 1))
    else:
        raise ValueError(f"leg {k + 1}: kind {leg.kind!r}: expected PRS, RPS, UPS or PUS")
    Rl = _frame(u, y)
    cylinder = _Body(leg.bodies[0], Rl, B, np.zeros(3), w, alpha)
    piston = _Body(leg.bodies[1], Rl, S, aS, w, alpha)
    joints = [
        base_joint,
        _Joint(first, first + 1, S, _normals(u), np.eye(3), drive=k, drive_axis=u),
        _Joint(first + 1, 0, S, np.eye(3), np.zeros((3, 0))),
    ]
    return [cylinder, piston], joints


def forces_of_motion(mech: Mechanism, pose, twist, acc) -> np.ndarray:
    """Actuator forces F [N] for the platform pose, twist (v_P, omega) and acceleration (a_P, alpha)."""
    pose = _v(pose)
    x, y, z, psi, theta, phi = pose
    R = rotation(psi, theta, phi)
    P = np.array((x, y, z))
    v, w = _v(twist[:3]), _v(twist[3:])
    a, alpha = _v(acc[:3]), _v(acc[3:])
    rho = joints(mech, pose)
    # the platform's bodies (platform, payload) are rigidly one: body 0 of the equations, their wrenches summed
    bodies = [_Body(b, R, P, a, w, alpha) for b in mech.platform]
    body_list, joint_list = [], []
    A6, bias, nc = _rows(mech, pose, twist)
    rd_all = (A6 @ _v(twist))[nc:]
    rdd_all = (A6 @ _v(acc))[nc:] + bias[nc:]
    for k, (leg, r_s) in enumerate(zip(mech.legs, [R @ _v(leg.s) for leg in mech.legs])):
        S = P + r_s
        vS = v + np.cross(w, r_s)
        aS = a + np.cross(alpha, r_s) + np.cross(w, np.cross(w, r_s))
        rd, rdd = rd_all[k], rdd_all[k]
        lb, lj = _leg_bodies(leg, k, S, vS, aS, rho[k], rd, rdd, 1 + len(body_list))
        body_list += lb
        joint_list += lj
    nb = 1 + len(body_list)
    cols = []
    for j in joint_list:
        cols += [("f", j, c) for c in range(j.forces.shape[1])] + [("m", j, c) for c in range(j.moments.shape[1])]
    n = len(mech.legs)
    size = len(cols) + n
    if 6 * nb != size:
        raise ValueError(f"Newton-Euler: {6 * nb} equations for {size} unknowns")
    M = np.zeros((6 * nb, size))
    rhs = np.zeros(6 * nb)
    centres = [None] * nb
    # platform (body 0): the sum of its bodies' wrenches about the first one's centre of mass
    G0 = bodies[0].com()
    centres[0] = G0
    for b in bodies:
        F, Mo = b.wrench(mech.g)
        rhs[0:3] += F
        rhs[3:6] += Mo + np.cross(b.com() - G0, F)
    for i, b in enumerate(body_list, start=1):
        F, Mo = b.wrench(mech.g)
        rhs[6 * i : 6 * i + 3] = F
        rhs[6 * i + 3 : 6 * i + 6] = Mo
        centres[i] = b.com()

    def put(col: int, body: Optional[int], sign: float, f: np.ndarray, m: np.ndarray, at: np.ndarray) -> None:
        if body is None:
            return
        M[6 * body : 6 * body + 3, col] += sign * f
        M[6 * body + 3 : 6 * body + 6, col] += sign * (m + np.cross(at - centres[body], f))

    zero = np.zeros(3)
    for col, (what, j, c) in enumerate(cols):
        if what == "f":
            f = j.forces[:, c]
            put(col, j.child, 1.0, f, zero, j.point)
            put(col, j.parent, -1.0, f, zero, j.point)
        else:
            m = j.moments[:, c]
            put(col, j.child, 1.0, zero, m, j.point)
            put(col, j.parent, -1.0, zero, m, j.point)
    for j in joint_list:
        if j.drive is not None:
            col = len(cols) + j.drive
            put(col, j.child, 1.0, j.drive_axis, zero, j.point)
            put(col, j.parent, -1.0, j.drive_axis, zero, j.point)
    x_all = np.linalg.solve(M, rhs)
    return x_all[len(cols) :]


def forces(mech: Mechanism, pose, rho_dot, rho_ddot) -> np.ndarray:
    """Actuator forces F [N] at a pose for the joint rates rho_dot [m/s] and accelerations rho_ddot [m/s^2]."""
    twist, acc = platform_motion(mech, pose, rho_dot, rho_ddot)
    return forces_of_motion(mech, pose, twist, acc)


# ----------------------------------------------------------------------------- mechanisms from plain numbers
def symmetric_legs(
    kind: str,
    base_radius: float,
    platform_radius: float,
    angles: Sequence[float],
    length: float,
    bodies: tuple,
    beta: float = 0.0,
) -> tuple:
    """Legs whose base joints lie at ``base_radius`` [m] and platform joints at ``platform_radius`` [m] at
    the ``angles`` [rad] around z, revolute (first universal) axes tangential, t_i = (-sin a_i, cos a_i, 0);
    PRS: guides at the base joints inclined by ``beta`` [rad] towards the centre axis."""
    legs = []
    for a in angles:
        ca, sa = math.cos(a), math.sin(a)
        axis = (-math.sin(beta) * ca, -math.sin(beta) * sa, math.cos(beta))
        legs.append(
            Leg(
                kind,
                (base_radius * ca, base_radius * sa, 0.0),
                (-sa, ca, 0.0),
                (platform_radius * ca, platform_radius * sa, 0.0),
                length,
                axis=axis,
                bodies=bodies,
            )
        )
    return tuple(legs)
