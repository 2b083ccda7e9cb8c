"""The 3-RPS table as an engine description, for the tests (docs/designs/3rps.md gives every number's source).

Three legs at 0, 120, 240 deg: a revolute joint at the base circle (tangential axis t_i), the paper's
belt axis as the leg (the rail a cylinder turning about t_i, the carriage a piston carrying the spherical
joint S_i), S_i on the platform circle. Coordinates (z, psi, theta); the parasitic (x, y, phi) follow from
S_i . t_i = 0 (the same constraints as the 3PRS's: the closed form of designs.py's null vector);
rho_i = |S_i - B_i| - l0.
"""
from __future__ import annotations

import math
from typing import Sequence

from fmus.mechanism.engine import Body, Description, Evaluation, KinematicsError, atan2, cos, hypot, require, sign, sin, sqrt
from fmus.mechanism.topology import Coordinate, Drive, Topology

#: the 3-RPS's numbers [SI units] (sources: docs/designs/3rps.md)
TABLE = {
    "R_b": 0.40, "r": 0.35, "l0": 0.26, "alpha": (0.0, 2.0 * math.pi / 3.0, 4.0 * math.pi / 3.0),
    "stroke": (0.0, 0.3),
    "m_cylinder": 2.34, "x_cylinder": 0.22628205128205134, "I_cylinder": (0.0004, 0.09353365384615385, 0.09353365384615385),
    "m_piston": 2.27, "I_piston": (0.0015133333333333335, 0.002194333333333334, 0.0031023333333333337),
    "m_platform": 2.06, "I_platform": (0.06308749999999999, 0.06308749999999999, 0.12617499999999998),
    "g": 9.81,
}

MAX_TILT = math.radians(60.0)


def _det3(a, b, c, d, e, f, g, h, i):
    return a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g)


def _finite_tilt(psi, theta) -> None:
    if not (abs(psi) <= MAX_TILT and abs(theta) <= MAX_TILT):
        raise KinematicsError(f"pose out of range: psi = {psi!r} rad, theta = {theta!r} rad beyond {MAX_TILT:.6g} rad")


def _determined(norm, r) -> None:
    if not norm > 1e-9 * r * r:
        raise KinematicsError("singular configuration: S_i . t_i = 0 does not determine (x, y, phi)")


def _diag(v):
    return ((v[0], 0.0, 0.0), (0.0, v[1], 0.0), (0.0, 0.0, v[2]))


class RPS3(Description):
    """The 3-RPS (module docstring); ``masses=False``: massless legs; ``payload``: a body on the platform."""

    name = "3RPS"
    coordinates = ("z", "psi", "theta")
    joints = ("rho_1", "rho_2", "rho_3")

    def __init__(self, table: dict = TABLE, legs: bool = True, payload: "Body | None" = None) -> None:
        self.t = dict(table)
        self.R_b, self.r, self.l0 = self.t["R_b"], self.t["r"], self.t["l0"]
        self.alpha = tuple(self.t["alpha"])
        self.lengths = (1.0, self.r, self.r)
        k = 1.0 if legs else 0.0
        cyl = Body("cylinder", k * self.t["m_cylinder"], (self.t["x_cylinder"], 0.0, 0.0),
                   _diag([k * v for v in self.t["I_cylinder"]]))
        pis = Body("piston", k * self.t["m_piston"], (0.0, 0.0, 0.0), _diag([k * v for v in self.t["I_piston"]]))
        self.bodies = tuple(Body(f"{b.name}_{i + 1}", b.mass, b.com, b.inertia) for i in range(3) for b in (cyl, pis)) \
            + (Body("platform", self.t["m_platform"], (0.0, 0.0, 0.0), _diag(self.t["I_platform"])),) \
            + ((payload,) if payload is not None else ())
        self.payload = payload

    def key(self) -> tuple:
        return (type(self).__name__, tuple(sorted((k, str(v)) for k, v in self.t.items())), self.bodies)

    def evaluate(self, q: Sequence) -> Evaluation:
        z, psi, theta = q
        require(_finite_tilt, psi, theta)
        Rb, r, l0 = self.R_b, self.r, self.l0
        ca = [math.cos(a) for a in self.alpha]
        sa = [math.sin(a) for a in self.alpha]
        cp, sp, ct, st = cos(psi), sin(psi), cos(theta), sin(theta)
        v, rows = [], []
        for i in range(3):
            vx = r * (ca[i] * ct + sa[i] * st * sp)
            vy = r * sa[i] * cp
            vz = r * (sa[i] * ct * sp - ca[i] * st)
            v.append((vx, vy, vz))
            rows.append((-sa[i], ca[i], -sa[i] * vx + ca[i] * vy, ca[i] * vx + sa[i] * vy))
        (m00, m01, m02, m03), (m10, m11, m12, m13), (m20, m21, m22, m23) = rows
        n0 = _det3(m01, m02, m03, m11, m12, m13, m21, m22, m23)
        n1 = -_det3(m00, m02, m03, m10, m12, m13, m20, m22, m23)
        n2 = _det3(m00, m01, m03, m10, m11, m13, m20, m21, m23)
        n3 = -_det3(m00, m01, m02, m10, m11, m12, m20, m21, m22)
        norm = hypot(n2, n3)
        require(_determined, norm, r)
        k = sign(n2) / norm
        x, y, c, s = n0 * k, n1 * k, n2 * k, n3 * k
        R = ((c * ct, c * st * sp - s * cp, c * st * cp + s * sp),
             (s * ct, s * st * sp + c * cp, s * st * cp - c * sp),
             (-st, ct * sp, ct * cp))
        rho, frames = [], []
        for i in range(3):
            vx, vy, vz = v[i]
            Sx, Sy, Sz = x + c * vx - s * vy, y + s * vx + c * vy, z + vz
            dx, dy, dz = Sx - Rb * ca[i], Sy - Rb * sa[i], Sz
            ln = sqrt(dx * dx + dy * dy + dz * dz)
            rho.append(ln - l0)
            ux, uy, uz = dx / ln, dy / ln, dz / ln
            tx, ty = -sa[i], ca[i]
            Rl = ((ux, tx, -uz * ty), (uy, ty, uz * tx), (uz, 0.0, ux * ty - uy * tx))
            frames += [((Rb * ca[i], Rb * sa[i], 0.0), Rl), ((Sx, Sy, Sz), Rl)]
        frames.append(((x, y, z), R))
        if self.payload is not None:
            frames.append(((x, y, z), R))
        return Evaluation(rho, (x, y, z, psi, theta, atan2(s, c)), frames)

    def guess(self, rho: Sequence[float]) -> tuple[float, float, float]:
        mean = sum(rho) / 3.0 + self.l0
        return (math.sqrt(max(mean * mean - (self.R_b - self.r) ** 2, 0.0)), 0.0, 0.0)

    @property
    def topology(self) -> Topology:
        stroke = tuple(self.t["stroke"])
        home = self.guess((0.5 * (stroke[0] + stroke[1]),) * 3)
        return Topology(self.name, tuple(Coordinate(c) for c in self.coordinates),
                        tuple(Drive(j, "linear", stroke) for j in self.joints), home)
