"""Leg templates and the two leg families a mechanism description is built from (docs/mechanism.md).

A *leg* joins the base to the platform through three joints, named by the template's letters
from the base up (P prismatic, R revolute, U universal, S spherical). Exactly one of its
joints is driven: its joint coordinate rho_k [m for a prismatic joint] is the leg's drive.
A leg closes on its platform attachment point S (world frame, from the pose): given S, the
template computes rho_k and the frame (origin, rotation world <- body) of each of its moving
parts, the bodies that ride on them.

Two families, by how the pose follows from the coordinates q:

- ``PLANE`` (PRS, RPS): three legs whose revolute joint's axis is horizontal and tangential
  (t_i = (-sin a_i, cos a_i, 0)), so that the leg moves in the vertical plane through the centre
  axis at angle a_i and confines the platform's spherical joint S_i to it: S_i . t_i = 0.
  Coordinates q = (z, psi, theta); the parasitic motion (x, y, phi) is the null vector of the
  three plane constraints, in closed form (a generalised cross product). The leg is placed in
  polar form: angle a_i, base radius H_i (the guide foot or base joint at (H_i cos a_i, H_i sin a_i, 0)),
  platform radius r_i (s_i = r_i (cos a_i, sin a_i, 0) in the platform frame).
- ``FREE`` (UPS, PUS): every pose component a coordinate, q = (x, y, z, psi, theta, phi); each
  leg closes on S_i = p + R s_i with its base point b_i and platform point s_i given as vectors.

R = Rz(phi) Ry(theta) Rx(psi). Every formula is written with the engine's functions, so that it
evaluates on floats and traces on expressions (engine.py); the PRS leg repeats the 3PRS's closed
form operation for operation (the paper's machine, kinematics.py), so its floats are those.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Mapping, Sequence

import numpy as np

from ..common.tracer import atan2, cos, hypot, require, sign, sin, sqrt
from .engine import Part
from .kinematics import MAX_TILT, KinematicsError, det3

__all__ = ["FREE", "PLANE", "TEMPLATES", "Family", "Template", "level_height", "prs_guess", "rps_guess"]


def _fmt(v: float) -> str:
    return f"{v:.6g}"


# ----------------------------------------------------------------------------- admissibility checks
# (run at the point of the evaluation where the family or the leg calls require(); ``admissible``: the same
# condition as a mask over arrays (Engine.evaluate_many); ``c_condition``, ``c_message``: the condition as a C
# expression of its arguments a0, a1, ... and what failed, for the engine's C backend (mast.core.native))
def _finite(z, psi, theta) -> None:
    if not (math.isfinite(z) and math.isfinite(psi) and math.isfinite(theta)):
        raise KinematicsError(f"pose (z = {z!r} m, psi = {psi!r} rad, theta = {theta!r} rad) is not finite")


_finite.c_condition = "isfinite(a0) && isfinite(a1) && isfinite(a2)"
_finite.c_message = "pose (z, psi, theta) is not finite"
_finite.admissible = lambda z, psi, theta: np.isfinite(z) & np.isfinite(psi) & np.isfinite(theta)


def _finite6(x, y, z, psi, theta, phi) -> None:
    if not all(math.isfinite(v) for v in (x, y, z, psi, theta, phi)):
        raise KinematicsError(
            f"pose (x = {x!r} m, y = {y!r} m, z = {z!r} m, psi = {psi!r} rad, theta = {theta!r} rad, "
            f"phi = {phi!r} rad) is not finite"
        )


_finite6.c_condition = " && ".join(f"isfinite(a{k})" for k in range(6))
_finite6.c_message = "pose (x, y, z, psi, theta, phi) is not finite"
_finite6.admissible = lambda *q: np.logical_and.reduce([np.isfinite(v) for v in q])


def _tilt(psi, theta) -> None:
    if abs(psi) > MAX_TILT or abs(theta) > MAX_TILT:
        raise KinematicsError(
            f"pose out of range: |psi| = {abs(psi):.6g} rad or |theta| = {abs(theta):.6g} rad exceeds "
            f"the admissible tilt {MAX_TILT:.6g} rad ({math.degrees(MAX_TILT):g} deg)"
        )


_tilt.c_condition = f"!(fabs(a0) > {MAX_TILT!r} || fabs(a1) > {MAX_TILT!r})"
_tilt.c_message = (
    f"pose out of range: |psi| or |theta| exceeds the admissible tilt {MAX_TILT:.6g} rad "
    f"({math.degrees(MAX_TILT):g} deg)"
)
_tilt.admissible = lambda psi, theta: (np.abs(psi) <= MAX_TILT) & (np.abs(theta) <= MAX_TILT)


def _pose_text(z, psi, theta) -> str:
    return f"z = {_fmt(z)} m, psi = {_fmt(psi)} rad, theta = {_fmt(theta)} rad"


class _NullCheck:
    """The parasitic motion determined: |null vector| > 1e-9 r^2 (arguments: norm, z, psi, theta, r, alpha_1..3)."""

    c_condition = "a0 > ((1e-09 * a4) * a4)"
    c_message = (
        "singular configuration: the constraints S_i . t_i = 0 do not determine the parasitic motion (x, y, phi)"
    )

    def __call__(self, norm, z, psi, theta, r, *alpha) -> None:
        if not norm > 1e-9 * r * r:
            raise KinematicsError(
                f"singular configuration: the constraints S_i . t_i = 0 do not determine the parasitic motion "
                f"(x, y, phi) at {_pose_text(z, psi, theta)} (guide angles {tuple(alpha)} rad; "
                f"|null vector (cos, sin)| = {norm:.3g})"
            )

    @staticmethod
    def admissible(norm, z, psi, theta, r, *alpha):
        return norm > 1e-9 * r * r


class _InsideCheck:
    """S_i on the inner side of guide i (the working assembly); arguments: u, d, z, psi, theta, H."""

    def __init__(self, i: int, inclined: bool) -> None:
        self.i, self.inclined = i, inclined
        self.c_condition = "a0 > 0.0"
        self.c_message = (
            f"pose unreachable (not the working assembly): spherical joint S_{i + 1} is on the outer "
            f"side of guide {i + 1}"
        )

    def __call__(self, u, d, z, psi, theta, H) -> None:
        if not u > 0.0:
            i = self.i + 1
            if self.inclined:
                raise KinematicsError(
                    f"pose unreachable (not the working assembly): spherical joint S_{i} is {_fmt(-u)} m on the "
                    f"outer side of guide {i} ({_pose_text(z, psi, theta)})"
                )
            raise KinematicsError(
                f"pose unreachable (not the working assembly): spherical joint S_{i} at radial distance "
                f"{_fmt(d)} m is outside the guide radius H = {_fmt(H)} m by {_fmt(-u)} m "
                f"({_pose_text(z, psi, theta)})"
            )

    @staticmethod
    def admissible(u, d, z, psi, theta, H):
        return u > 0.0


class _ReachCheck:
    """Leg i reaches S_i: w2 = L^2 - u^2 > 0; arguments: w2, u, z, psi, theta, L."""

    def __init__(self, i: int, inclined: bool) -> None:
        self.i, self.inclined = i, inclined
        self.c_condition = "a0 > 0.0"
        self.c_message = f"pose unreachable: leg {i + 1} is too short for the pose"

    def __call__(self, w2, u, z, psi, theta, L) -> None:
        if not w2 > 0.0:
            what = "a reach perpendicular to its guide" if self.inclined else "a horizontal reach"
            raise KinematicsError(
                f"pose unreachable: leg {self.i + 1} would need {what} of {_fmt(u)} m > L = {_fmt(L)} m "
                f"(short by {_fmt(u - L)} m) at {_pose_text(z, psi, theta)}"
            )

    @staticmethod
    def admissible(w2, u, z, psi, theta, L):
        return w2 > 0.0


class _PositiveCheck:
    """A leg quantity that must be > 0 (argument a0), with what its failure means."""

    def __init__(self, message: str) -> None:
        self.c_condition = "a0 > 0.0"
        self.c_message = message

    def __call__(self, value, *_) -> None:
        if not value > 0.0:
            raise KinematicsError(f"{self.c_message} ({_fmt(value)})")

    @staticmethod
    def admissible(value, *_):
        return value > 0.0


def level_height(rho_1, rho_2, rho_3, H, r, L, cb, sb):
    """z [m] of the level pose (psi = theta = 0) of a 3PRS for the mean slider position (guides inclined by beta:
    cb = cos(beta), sb = sin(beta); for beta = 0 the mean plus sqrt(L^2 - (H - r)^2), the same floats):
    the direct kinematics' cold start. In the generated-code subset: the native FMUs translate it."""
    mean = (rho_1 + rho_2 + rho_3) / 3.0
    gap = r - H + mean * sb
    w2 = L * L - gap * gap
    if 0.0 > w2:
        w2 = 0.0
    return mean * cb + sqrt(w2)


def prs_guess(rho_1, rho_2, rho_3, H, r, L, cb, sb):
    """The 3PRS's cold start (z, psi, theta): the level pose for the mean slider position (``level_height``; H, r,
    L, cb, sb: leg 1's base radius, platform radius, length, cos and sin of its inclination). In the
    generated-code subset: the native mechanism translates it."""
    return (level_height(rho_1, rho_2, rho_3, H, r, L, cb, sb), 0.0, 0.0)


def rps_guess(rho_1, rho_2, rho_3, gap):
    """A 3-RPS's cold start (z, psi, theta): the level pose for the mean leg length, the leg's length being the
    distance in its plane (gap: leg 1's base radius minus its platform radius). In the generated-code subset."""
    mean = (rho_1 + rho_2 + rho_3) / 3.0
    w2 = mean * mean - gap * gap
    if 0.0 > w2:
        w2 = 0.0
    return (sqrt(w2), 0.0, 0.0)


# ----------------------------------------------------------------------------- templates
@dataclass(frozen=True)
class Template:
    """A leg template: its joints from the base up, which may be driven (joint letter -> drive kind), its
    family, the geometry fields a leg of it gives (field -> dimension: "m" length, "rad" angle, "1" unit
    vector components) and its moving parts (the bodies that ride on the leg, in order)."""

    name: str
    family: str
    drivable: Mapping[str, str]
    fields: Mapping[str, str]
    parts: tuple[str, ...]
    doc: str


#: PRS: a driven slider on a guide (foot at base radius H, inclined by beta towards the axis), a revolute joint
#: with the tangential axis, a link of length L to the spherical joint; part "link": frame at the slider, x along
#: the link (slider -> S), y the revolute axis. RPS: a revolute joint at the base (radius H, tangential axis), a
#: driven prismatic leg of length rho, the spherical joint; parts "cylinder" (frame at the base joint) and "rod"
#: (frame at S), both x along the leg (base -> S), y the revolute axis. UPS: a universal joint at the base point b
#: (first axis ``axis`` fixed in the base), a driven prismatic leg, the spherical joint at the platform point s;
#: parts "cylinder" (frame at b) and "rod" (frame at S), x along the leg, y = axis x leg (the universal joint's
#: second axis). PUS: a driven slider on a guide from b along the unit vector ``guide``, a universal joint (first
#: axis ``axis``), a link of length L to the spherical joint at s; part "link": frame at the slider.
TEMPLATES: dict[str, Template] = {
    t.name: t
    for t in (
        Template(
            "PRS",
            "plane",
            {"P": "linear"},
            {"angle": "rad", "base_radius": "m", "platform_radius": "m", "length": "m", "inclination": "rad"},
            ("link",),
            "driven slider on an inclined guide, revolute joint, link, spherical joint",
        ),
        Template(
            "RPS",
            "plane",
            {"P": "linear"},
            {"angle": "rad", "base_radius": "m", "platform_radius": "m"},
            ("cylinder", "rod"),
            "revolute joint at the base, driven prismatic leg, spherical joint",
        ),
        Template(
            "UPS",
            "free",
            {"P": "linear"},
            {"base": "m", "platform": "m", "axis": "1"},
            ("cylinder", "rod"),
            "universal joint at the base, driven prismatic leg, spherical joint",
        ),
        Template(
            "PUS",
            "free",
            {"P": "linear"},
            {"base": "m", "guide": "1", "platform": "m", "length": "m", "axis": "1"},
            ("link",),
            "driven slider on a guide, universal joint, link, spherical joint",
        ),
    )
}

#: defaults of optional fields (a vertical guide)
OPTIONAL_FIELDS = {"inclination": 0.0}


def _cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _unit_cross(a, b):
    """a x b / |a x b| (the universal joint's second axis); guarded by the leg's check."""
    c = _cross(a, b)
    n = sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2])
    return (c[0] / n, c[1] / n, c[2] / n), n


def _frame(x_axis, y_axis):
    """Rotation world <- body with columns x, y, z = x cross y."""
    z_axis = _cross(x_axis, y_axis)
    return tuple((x_axis[i], y_axis[i], z_axis[i]) for i in range(3))


class Leg:
    """One leg of a description: its template, its geometry (field -> value: float or traced; vectors as
    3-tuples) and its index (0-based, the drive's)."""

    def __init__(self, template: Template, index: int, geometry: Mapping[str, object], traced_values: bool) -> None:
        self.template, self.i, self.g = template, index, dict(geometry)
        if template.family == "plane":
            a = self.g["angle"]
            self.ca, self.sa = cos(a), sin(a)
            if template.name == "PRS":
                beta = self.g.get("inclination", 0.0)
                self.cb, self.sb = cos(beta), sin(beta)
                self.inclined = traced_values or beta != 0.0

    # -------------------------------------------------------------------------- closing on S
    def close(self, S, q) -> tuple[object, list]:
        """(rho, [(origin, rotation) per part]) of the leg whose spherical joint is at S (world), pose q."""
        return getattr(self, f"_close_{self.template.name}")(S, q)

    def _close_PRS(self, S, q):
        z, psi, theta = q
        i, g, ca, sa, cb, sb = self.i, self.g, self.ca, self.sa, self.cb, self.sb
        H, L = g["base_radius"], g["length"]
        Sx, Sy, Sz = S
        d = ca * Sx + sa * Sy
        h = Sz
        if self.inclined:
            dr = d - H  # S_i relative to the foot of guide i, in its plane
            u = -(cb * dr + sb * h)  # distance of S_i inside the guide line
            a = cb * h - sb * dr  # position of S_i's projection along the guide
        else:
            u = H - d
            a = h
        require(_InsideCheck(i, self.inclined), u, d, z, psi, theta, H)
        w2 = L * L - u * u
        require(_ReachCheck(i, self.inclined), w2, u, z, psi, theta, L)
        w = sqrt(w2)
        rho = a - w
        # leg frame: x along the leg (slider -> S_i), y = t_i (revolute axis), z = x cross y
        radial = H - sb * rho
        Bx, By, Bz = ca * radial, sa * radial, cb * rho
        lx, ly, lz = (Sx - Bx) / L, (Sy - By) / L, (Sz - Bz) / L
        tx, ty = -sa, ca
        return rho, [((Bx, By, Bz), ((lx, tx, -lz * ty), (ly, ty, lz * tx), (lz, 0.0, lx * ty - ly * tx)))]

    def _close_RPS(self, S, q):
        i, g, ca, sa = self.i, self.g, self.ca, self.sa
        H = g["base_radius"]
        Sx, Sy, Sz = S
        dr = ca * Sx + sa * Sy - H  # S_i relative to the base joint, in the leg's plane
        require(
            _PositiveCheck(
                f"pose unreachable (not the working assembly): spherical joint S_{i + 1} is not "
                f"above the base joint of leg {i + 1}"
            ),
            Sz,
        )
        rho = sqrt(dr * dr + Sz * Sz)
        Bx, By = ca * H, sa * H
        lx, ly, lz = (Sx - Bx) / rho, (Sy - By) / rho, Sz / rho
        tx, ty = -sa, ca
        R = ((lx, tx, -lz * ty), (ly, ty, lz * tx), (lz, 0.0, lx * ty - ly * tx))
        return rho, [((Bx, By, 0.0), R), ((Sx, Sy, Sz), R)]

    def _close_UPS(self, S, q):
        i, b, axis = self.i, self.g["base"], self.g["axis"]
        e = (S[0] - b[0], S[1] - b[1], S[2] - b[2])
        n2 = e[0] * e[0] + e[1] * e[1] + e[2] * e[2]
        require(_PositiveCheck(f"pose unreachable: leg {i + 1} has zero length"), n2)
        rho = sqrt(n2)
        x_axis = (e[0] / rho, e[1] / rho, e[2] / rho)
        y_axis, n = _unit_cross(axis, x_axis)
        require(_PositiveCheck(f"singular configuration: leg {i + 1} lies along its universal joint's first axis"), n)
        R = _frame(x_axis, y_axis)
        return rho, [(tuple(b), R), (tuple(S), R)]

    def _close_PUS(self, S, q):
        i, b, gd, L, axis = self.i, self.g["base"], self.g["guide"], self.g["length"], self.g["axis"]
        e = (S[0] - b[0], S[1] - b[1], S[2] - b[2])
        a = gd[0] * e[0] + gd[1] * e[1] + gd[2] * e[2]
        w2 = L * L - (e[0] * e[0] + e[1] * e[1] + e[2] * e[2] - a * a)
        require(_PositiveCheck(f"pose unreachable: leg {i + 1} is too short for the pose"), w2)
        rho = a - sqrt(w2)
        B = (b[0] + rho * gd[0], b[1] + rho * gd[1], b[2] + rho * gd[2])
        x_axis = ((S[0] - B[0]) / L, (S[1] - B[1]) / L, (S[2] - B[2]) / L)
        y_axis, n = _unit_cross(axis, x_axis)
        require(_PositiveCheck(f"singular configuration: leg {i + 1} lies along its universal joint's first axis"), n)
        return rho, [(B, _frame(x_axis, y_axis))]

    # -------------------------------------------------------------------------- placement (floats)
    def base_point(self) -> tuple[float, float, float]:
        """Where the leg meets the base (the guide's foot at rho = 0, or the base joint) [m]."""
        if self.template.family == "plane":
            H = self.g["base_radius"]
            return (self.ca * H, self.sa * H, 0.0)
        return tuple(self.g["base"])

    def platform_point(self) -> tuple[float, float, float]:
        """s: the spherical joint in the platform frame [m]."""
        if self.template.family == "plane":
            r = self.g["platform_radius"]
            return (r * self.ca, r * self.sa, 0.0)
        return tuple(self.g["platform"])

    def sketch(self, bodies: Sequence[str], short: float) -> list[Part]:
        """This leg's parts of the drawing (``Description.sketch``); ``short`` [m]: the shortest leg length
        (lower stroke) for the parts of a prismatic leg."""
        name = self.template.name
        if name == "PRS":
            ca, sa, cb, sb, H, L = self.ca, self.sa, self.cb, self.sb, self.g["base_radius"], self.g["length"]
            return [
                Part("guide", None, [(ca * H, sa * H, 0.0), (ca * (H - sb), sa * (H - sb), cb)], joint=self.i),
                Part("carriage", bodies[0], [(0.0, 0.0, 0.0)]),
                Part("link", bodies[0], [(0.0, 0.0, 0.0), (L, 0.0, 0.0)]),
            ]
        if name == "PUS":
            b, gd, L = self.g["base"], self.g["guide"], self.g["length"]
            return [
                Part("guide", None, [tuple(b), tuple(b[k] + gd[k] for k in range(3))], joint=self.i),
                Part("carriage", bodies[0], [(0.0, 0.0, 0.0)]),
                Part("link", bodies[0], [(0.0, 0.0, 0.0), (L, 0.0, 0.0)]),
            ]
        half = 0.5 * short  # RPS, UPS: a cylinder from the base joint, a rod from the spherical joint
        return [
            Part("joint", None, [self.base_point()]),
            Part("link", bodies[0], [(0.0, 0.0, 0.0), (half, 0.0, 0.0)]),
            Part("carriage", bodies[1], [(-half, 0.0, 0.0)]),
            Part("link", bodies[1], [(-half, 0.0, 0.0), (0.0, 0.0, 0.0)]),
        ]


# ----------------------------------------------------------------------------- families
@dataclass(frozen=True)
class Family:
    """How the pose follows from the coordinates: ``coordinates`` (in order), ``legs`` (how many), and ``pose``
    (q, legs) -> (pose (x, y, z, psi, theta, phi), R, the legs' spherical joints S_i [world])."""

    name: str
    coordinates: tuple[str, ...]
    legs: int
    pose: Callable


def _plane_pose(q, legs: Sequence[Leg]):
    """The 3PRS closed form (kinematics.py): v_i = Ry(theta) Rx(psi) s_i; constraint i:
    -sa x + ca y + cos(phi) A_i + sin(phi) B_i = 0; (x, y, cos phi, sin phi) the null vector of the 3x4 system."""
    z, psi, theta = q
    require(_finite, z, psi, theta)
    require(_tilt, psi, theta)
    cp, sp = cos(psi), sin(psi)
    ct, st = cos(theta), sin(theta)
    v = []
    rows = []
    for leg in legs:
        r, ca, sa = leg.g["platform_radius"], leg.ca, leg.sa
        vx = r * (ca * ct + sa * st * sp)
        vy = r * sa * cp
        vz = r * (sa * ct * sp - ca * st)
        v.append((vx, vy, vz))
        rows.append((-sa, ca, -sa * vx + ca * vy, ca * vx + sa * vy))
    (m00, m01, m02, m03), (m10, m11, m12, m13), (m20, m21, m22, m23) = rows
    # null vector of the 3x4 homogeneous system (generalised cross product)
    n0 = det3(m01, m02, m03, m11, m12, m13, m21, m22, m23)
    n1 = -det3(m00, m02, m03, m10, m12, m13, m20, m22, m23)
    n2 = det3(m00, m01, m03, m10, m11, m13, m20, m21, m23)
    n3 = -det3(m00, m01, m02, m10, m11, m12, m20, m21, m22)
    norm = hypot(n2, n3)
    require(_NullCheck(), norm, z, psi, theta, legs[0].g["platform_radius"], *(leg.g["angle"] for leg in legs))
    k = sign(n2) / norm  # choose cos(phi) > 0
    x, y, c, s = n0 * k, n1 * k, n2 * k, n3 * k
    R = (
        (c * ct, c * st * sp - s * cp, c * st * cp + s * sp),
        (s * ct, s * st * sp + c * cp, s * st * cp - c * sp),
        (-st, ct * sp, ct * cp),
    )
    S = []
    for vx, vy, vz in v:
        ax, ay = c * vx - s * vy, s * vx + c * vy
        S.append((x + ax, y + ay, z + vz))
    return (x, y, z, psi, theta, atan2(s, c)), R, S


def _free_pose(q, legs: Sequence[Leg]):
    """Every pose component a coordinate: S_i = p + R s_i."""
    x, y, z, psi, theta, phi = q
    require(_finite6, x, y, z, psi, theta, phi)
    require(_tilt, psi, theta)
    cp, sp = cos(psi), sin(psi)
    ct, st = cos(theta), sin(theta)
    c, s = cos(phi), sin(phi)
    R = (
        (c * ct, c * st * sp - s * cp, c * st * cp + s * sp),
        (s * ct, s * st * sp + c * cp, s * st * cp - c * sp),
        (-st, ct * sp, ct * cp),
    )
    S = []
    for leg in legs:
        p = leg.g["platform"]
        S.append(tuple(q[k] + R[k][0] * p[0] + R[k][1] * p[1] + R[k][2] * p[2] for k in range(3)))
    return (x, y, z, psi, theta, phi), R, S


PLANE = Family("plane", ("z", "psi", "theta"), 3, _plane_pose)
FREE = Family("free", ("x", "y", "z", "psi", "theta", "phi"), 6, _free_pose)
FAMILIES = {f.name: f for f in (PLANE, FREE)}
