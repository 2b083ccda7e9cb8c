"""Kinematics of the 3PRS mechanism of the MAST (paper section 3, Fig. 4 and Appendix A).

Geometry (docs/geometry.md): world frame on the base, origin on the centre axis, z up.
Guide i is the vertical line (H cos a_i, H sin a_i, rho_i); ``rho_i`` [m] is the height
of slider i above the base plane z = 0. Slider i carries a revolute joint whose axis is
the horizontal tangent t_i = (-sin a_i, cos a_i, 0), so leg i (length L) moves in the
vertical radial plane of guide i. Its upper end is the spherical joint S_i, at
platform-frame position s_i = r (cos a_i, sin a_i, 0):

    S_i = P + R s_i = slider_i + L (-cos(gamma_i) e_i + sin(gamma_i) e_z),
    e_i = (cos a_i, sin a_i, 0),   R = Rz(phi) Ry(theta) Rx(psi).

The actuated (controlled) coordinates are q = (z, psi, theta); the parasitic ones
(x, y, phi) follow from the three constraints S_i . t_i = 0. For the T layout
(a = 0, 90, 180 deg) they are y = 0, phi = 0, x = -r sin(theta) sin(psi).

Per leg, with d_i = S_i . e_i (radial distance of S_i) and h_i = S_i . e_z (its height),
u_i = H - d_i = L cos(gamma_i) and w_i = h_i - rho_i = L sin(gamma_i), so

    rho_i = h_i - sqrt(L^2 - (H - d_i)^2)     (working assembly: 0 < u_i < L, w_i > 0).

Velocities (Appendix A, Eq. A.1): Jx qdot = Jq rhodot with
Jx[i, :] = w_i dh_i/dq - u_i dd_i/dq (total derivatives, parasitic motion included) and
Jq = diag(w_i) = diag(L sin gamma_i); so qdot = J rhodot with J = Jx^-1 Jq.

All Jacobians are derived from this geometry in closed form, and so are their time
derivatives (the bias accelerations "Jdot rhodot", obtained by differentiating the
constraints twice), with scalar ``math`` for speed: the co-simulation calls the direct
kinematics and the inverse dynamics every millisecond.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Mapping, Optional, Sequence

import numpy as np

from ..common.block import ModelError
from ..common.parameters import Param, ParameterError, positive
from .checks import Check

__all__ = [
    "GEOMETRY_CHECKS",
    "Geometry",
    "KinematicsError",
    "PoseSolution",
    "Jacobians",
    "JacobianRates",
    "MAX_TILT",
    "parasitic",
    "inverse_kinematics",
    "full_pose",
    "direct_kinematics",
    "home_pose",
    "jacobians",
    "jacobian_rates",
]

#: largest |psi| or |theta| accepted [rad] (60 deg: three times the machine's 20 deg,
#: well inside the Z-Y-X representation singularity at theta = 90 deg)
MAX_TILT = math.radians(60.0)
#: condition number of Jx (or of Jq) above which a configuration is called singular
COND_LIMIT = 1.0e8

_sin = math.sin
_cos = math.cos
_sqrt = math.sqrt
_isfinite = math.isfinite


#: the geometry parameters, declared once for every block that holds a kinematic model
GEOMETRY_PARAMETERS: tuple[Param, ...] = (
    positive("H", "m", "Horizontal distance from the centre axis to each guide"),
    positive("r", "m", "Platform radius: distance from the platform centre P to each spherical joint"),
    positive("L", "m", "Leg length (slider revolute joint to platform spherical joint)"),
    Param("alpha_1", "rad", "Angle of guide 1 around the vertical centre axis", -2 * math.pi, 2 * math.pi),
    Param("alpha_2", "rad", "Angle of guide 2 around the vertical centre axis", -2 * math.pi, 2 * math.pi),
    Param("alpha_3", "rad", "Angle of guide 3 around the vertical centre axis", -2 * math.pi, 2 * math.pi),
)


class KinematicsError(ModelError):
    """Unreachable pose, singular configuration, direct kinematics without convergence,
    or a pose out of the admissible range."""


# --------------------------------------------------------------------------- geometry

#: ``Geometry.checked``'s checks as data, with its messages (the native mechanism runs the same rows: designs.CHECKS)
GEOMETRY_CHECKS = (
    Check(
        "less",
        "parameter 'r' = {}: must be < H = {} m (working assembly: the spherical joints lie inside the guide radius)",
        ("r", "H"),
        ("r", "H"),
    ),
    Check(
        "less",
        "parameter 'L' = {}: must exceed H - r = {} m, or the legs cannot reach the platform",
        ("L", "H - r"),
        ("H - r", "L"),
    ),
    Check(
        "assembles",
        "parameters 'alpha_1', 'alpha_2', 'alpha_3' = ({}, {}, {}) rad: the mechanism cannot be assembled at the "
        "level pose: {}",
        ("alpha_1", "alpha_2", "alpha_3"),
        regular=True,
    ),
)


@dataclass(frozen=True)
class Geometry:
    """3PRS geometry.

    H [m]: horizontal distance from the centre axis to each guide (assumed reading of
    the paper's H, docs/geometry.md); r [m]: platform radius to the spherical joints;
    L [m]: leg length; alpha [rad]: angles of the three guides around z.
    """

    H: float
    r: float
    L: float
    alpha: tuple[float, float, float]
    _ca: tuple[float, float, float] = field(init=False, repr=False, compare=False)
    _sa: tuple[float, float, float] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        for name in ("H", "r", "L"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and _isfinite(value) and value > 0.0):
                raise ParameterError(f"Geometry: '{name}' = {value!r}: expected a finite length > 0 m")
            object.__setattr__(self, name, float(value))
        alpha = tuple(float(a) for a in self.alpha)
        if len(alpha) != 3 or not all(_isfinite(a) for a in alpha):
            raise ParameterError(f"Geometry: alpha = {self.alpha!r}: expected three finite angles in rad")
        object.__setattr__(self, "alpha", alpha)
        object.__setattr__(self, "_ca", tuple(_cos(a) for a in alpha))
        object.__setattr__(self, "_sa", tuple(_sin(a) for a in alpha))

    @classmethod
    def from_params(cls, params: Mapping[str, object]) -> "Geometry":
        """Geometry from a parameter mapping (H, r, L, alpha_1..3; other keys ignored)."""
        try:
            return cls(
                H=float(params["H"]),
                r=float(params["r"]),
                L=float(params["L"]),
                alpha=(float(params["alpha_1"]), float(params["alpha_2"]), float(params["alpha_3"])),
            )
        except KeyError as exc:
            raise ParameterError(f"Geometry: missing parameter {exc.args[0]!r}") from None

    @classmethod
    def checked(cls, params: Mapping[str, object], owner: str) -> "Geometry":
        """Geometry from validated parameters, refusing layouts that cannot be assembled.

        Raises ParameterError naming the parameter: r >= H (the spherical joints must lie
        inside the guide radius), L <= H - r (the legs cannot reach the platform), or guide
        angles that give no assembly at the level pose.
        """
        geom = cls.from_params(params)
        H, r, L = geom.H, geom.r, geom.L
        inside, reach, assembled = GEOMETRY_CHECKS
        if not r < H:
            raise ParameterError(f"{owner}: {inside.message.format(repr(r), repr(H))}")
        if not H - r < L:
            raise ParameterError(f"{owner}: {reach.message.format(repr(L), repr(H - r))}")
        try:
            first_order(geom, frame_at(geom, geom.home_reach, 0.0, 0.0))
        except KinematicsError as exc:
            raise ParameterError(f"{owner}: {assembled.message.format(*map(repr, geom.alpha), exc)}") from None
        return geom

    @property
    def home_reach(self) -> float:
        """sqrt(L^2 - (H - r)^2) [m]: height of S_i above slider i at psi = theta = 0."""
        u = self.H - self.r
        return _sqrt(max(self.L * self.L - u * u, 0.0))


# --------------------------------------------------------------------------- internals
class _Frame:
    """Everything the kinematics knows at one pose (plain floats, filled in stages)."""

    __slots__ = (
        "z",
        "psi",
        "theta",
        "x",
        "y",
        "phi",
        "c",
        "s",
        "R",
        "a",
        "u",
        "w",
        "rho",
        "gamma",
        # first order
        "kpsi",
        "kth",
        "Cinv",
        "K",
        "JP",
        "Jw",
        "D",
        "Hh",
        "Jx",
        "Jxinv",
        "J",
    )


def _fmt(v: float) -> str:
    return f"{v:.6g}"


def det3(a: float, b: float, c: float, d: float, e: float, f: float, g: float, h: float, i: float) -> float:
    return a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g)


def inv3(m: Sequence[float]) -> tuple[tuple[float, ...], float]:
    """Inverse of a row-major 3x3 (9 floats) and its determinant (det 0 -> ZeroDivisionError)."""
    a, b, c, d, e, f, g, h, i = m
    A = e * i - f * h
    B = f * g - d * i
    C = d * h - e * g
    det = a * A + b * B + c * C
    k = 1.0 / det
    return (
        (
            A * k,
            (c * h - b * i) * k,
            (b * f - c * e) * k,
            B * k,
            (a * i - c * g) * k,
            (c * d - a * f) * k,
            C * k,
            (b * g - a * h) * k,
            (a * e - b * d) * k,
        ),
        det,
    )


def _cond(m: Sequence[float], minv: Sequence[float]) -> float:
    return _sqrt(sum(v * v for v in m)) * _sqrt(sum(v * v for v in minv))


def frame_at(g: Geometry, z: float, psi: float, theta: float) -> _Frame:
    """Positions: parasitic motion (closed form, any layout), rotation, legs, rho, gamma."""
    if not (_isfinite(z) and _isfinite(psi) and _isfinite(theta)):
        raise KinematicsError(f"pose (z = {z!r} m, psi = {psi!r} rad, theta = {theta!r} rad) is not finite")
    if abs(psi) > MAX_TILT or abs(theta) > MAX_TILT:
        raise KinematicsError(
            f"pose out of range: |psi| = {abs(psi):.6g} rad or |theta| = {abs(theta):.6g} rad exceeds "
            f"the admissible tilt {MAX_TILT:.6g} rad ({math.degrees(MAX_TILT):g} deg)"
        )
    r = g.r
    cp, sp = _cos(psi), _sin(psi)
    ct, st = _cos(theta), _sin(theta)
    ca, sa = g._ca, g._sa
    # v_i = Ry(theta) Rx(psi) s_i ; constraint i: -sa x + ca y + cos(phi) A_i + sin(phi) B_i = 0
    v = []
    rows = []
    for i in range(3):
        vx = r * (ca[i] * ct + sa[i] * st * sp)
        vy = r * sa[i] * cp
        vz = r * (sa[i] * ct * sp - ca[i] * st)
        v.append((vx, vy, vz))
        rows.append((-sa[i], ca[i], -sa[i] * vx + ca[i] * vy, ca[i] * vx + sa[i] * vy))
    (m00, m01, m02, m03), (m10, m11, m12, m13), (m20, m21, m22, m23) = rows
    # null vector of the 3x4 homogeneous system (generalised cross product)
    n0 = det3(m01, m02, m03, m11, m12, m13, m21, m22, m23)
    n1 = -det3(m00, m02, m03, m10, m12, m13, m20, m22, m23)
    n2 = det3(m00, m01, m03, m10, m11, m13, m20, m21, m23)
    n3 = -det3(m00, m01, m02, m10, m11, m12, m20, m21, m22)
    norm = math.hypot(n2, n3)
    if not norm > 1e-9 * r * r:
        raise KinematicsError(
            f"singular configuration: the constraints S_i . t_i = 0 do not determine the parasitic motion "
            f"(x, y, phi) at z = {_fmt(z)} m, psi = {_fmt(psi)} rad, theta = {_fmt(theta)} rad "
            f"(guide angles {g.alpha} rad; |null vector (cos, sin)| = {norm:.3g})"
        )
    k = (1.0 if n2 > 0.0 else -1.0) / norm  # choose cos(phi) > 0
    x, y, c, s = n0 * k, n1 * k, n2 * k, n3 * k
    fr = _Frame()
    fr.z, fr.psi, fr.theta = z, psi, theta
    fr.x, fr.y, fr.phi, fr.c, fr.s = x, y, math.atan2(s, c), c, s
    # R = Rz(phi) Ry(theta) Rx(psi), row-major
    fr.R = (
        c * ct,
        c * st * sp - s * cp,
        c * st * cp + s * sp,
        s * ct,
        s * st * sp + c * cp,
        s * st * cp - c * sp,
        -st,
        ct * sp,
        ct * cp,
    )
    H, L = g.H, g.L
    a, uu, ww, rho, gam = [], [], [], [], []
    for i in range(3):
        vx, vy, vz = v[i]
        ax, ay = c * vx - s * vy, s * vx + c * vy
        a.append((ax, ay, vz))
        d = ca[i] * (x + ax) + sa[i] * (y + ay)
        h = z + vz
        u = H - d
        if not u > 0.0:
            raise KinematicsError(
                f"pose unreachable (not the working assembly): spherical joint S_{i + 1} at radial distance "
                f"{_fmt(d)} m is outside the guide radius H = {_fmt(H)} m by {_fmt(-u)} m "
                f"(z = {_fmt(z)} m, psi = {_fmt(psi)} rad, theta = {_fmt(theta)} rad)"
            )
        w2 = L * L - u * u
        if not w2 > 0.0:
            raise KinematicsError(
                f"pose unreachable: leg {i + 1} would need a horizontal reach of {_fmt(u)} m > L = {_fmt(L)} m "
                f"(short by {_fmt(u - L)} m) at z = {_fmt(z)} m, psi = {_fmt(psi)} rad, theta = {_fmt(theta)} rad"
            )
        w = _sqrt(w2)
        uu.append(u)
        ww.append(w)
        rho.append(h - w)
        gam.append(math.atan2(w, u))
    fr.a, fr.u, fr.w, fr.rho, fr.gamma = a, uu, ww, rho, gam
    return fr


def first_order(g: Geometry, fr: _Frame, check: bool = True) -> _Frame:
    """First order: parasitic Jacobian K, point velocities, Jx, Jq, J = Jx^-1 Jq."""
    c, s = fr.c, fr.s
    ct, st = _cos(fr.theta), _sin(fr.theta)
    kpsi = (c * ct, s * ct, -st)  # world axis of psi_dot: Rz(phi) Ry(theta) e_x
    kth = (-s, c, 0.0)  # world axis of theta_dot: Rz(phi) e_y
    ca, sa = g._ca, g._sa
    cpar = []
    cact = []
    for i in range(3):
        ax, ay, az = fr.a[i]
        # m_i = a_i x t_i, t_i = (-sa, ca, 0)
        mx, my, mz = -az * ca[i], -az * sa[i], ax * ca[i] + ay * sa[i]
        cpar.extend((-sa[i], ca[i], mz))
        cact.append((kpsi[0] * mx + kpsi[1] * my + kpsi[2] * mz, kth[0] * mx + kth[1] * my))
    try:
        Cinv, detc = inv3(cpar)
    except ZeroDivisionError:
        raise KinematicsError(
            f"singular configuration: constraint matrix of the parasitic motion is singular at "
            f"z = {_fmt(fr.z)} m, psi = {_fmt(fr.psi)} rad, theta = {_fmt(fr.theta)} rad"
        ) from None
    # K: d(x, y, phi)/d(psi, theta) (no dependence on z); K[k] = (dk/dpsi, dk/dtheta)
    K = tuple(
        (
            -(Cinv[3 * k] * cact[0][0] + Cinv[3 * k + 1] * cact[1][0] + Cinv[3 * k + 2] * cact[2][0]),
            -(Cinv[3 * k] * cact[0][1] + Cinv[3 * k + 1] * cact[1][1] + Cinv[3 * k + 2] * cact[2][1]),
        )
        for k in range(3)
    )
    # columns (psi, theta) of dP/dq and domega/dq (the z column is (0,0,1) and 0)
    JPp, JPt = (K[0][0], K[1][0], 0.0), (K[0][1], K[1][1], 0.0)
    Jwp = (kpsi[0], kpsi[1], kpsi[2] + K[2][0])
    Jwt = (kth[0], kth[1], K[2][1])
    D, Hh, Jx = [], [], []
    for i in range(3):
        ax, ay, az = fr.a[i]
        # V = JP_col + Jw_col x a_i ; need e_i . V and e_z . V
        vpx = JPp[0] + Jwp[1] * az - Jwp[2] * ay
        vpy = JPp[1] + Jwp[2] * ax - Jwp[0] * az
        vpz = Jwp[0] * ay - Jwp[1] * ax
        vtx = JPt[0] + Jwt[1] * az - Jwt[2] * ay
        vty = JPt[1] + Jwt[2] * ax - Jwt[0] * az
        vtz = Jwt[0] * ay - Jwt[1] * ax
        dp = ca[i] * vpx + sa[i] * vpy
        dt = ca[i] * vtx + sa[i] * vty
        D.append((0.0, dp, dt))
        Hh.append((1.0, vpz, vtz))
        u, w = fr.u[i], fr.w[i]
        Jx.extend((w, w * vpz - u * dp, w * vtz - u * dt))
    try:
        Jxinv, det = inv3(Jx)
    except ZeroDivisionError:
        raise KinematicsError(
            f"singular configuration: Jx is singular (det = 0) at z = {_fmt(fr.z)} m, psi = {_fmt(fr.psi)} rad, "
            f"theta = {_fmt(fr.theta)} rad"
        ) from None
    if check:
        cond = _cond(Jx, Jxinv)
        if not cond < COND_LIMIT:
            raise KinematicsError(
                f"singular configuration: Jx has condition number {cond:.3g} (limit {COND_LIMIT:.0e}) at "
                f"z = {_fmt(fr.z)} m, psi = {_fmt(fr.psi)} rad, theta = {_fmt(fr.theta)} rad"
            )
        w = fr.w
        condq = max(w) / min(w)
        if not condq < COND_LIMIT:
            raise KinematicsError(
                f"singular configuration: Jq = diag(L sin gamma_i) has condition number {condq:.3g} "
                f"(a leg is horizontal: gamma = {[round(x, 6) for x in fr.gamma]} rad)"
            )
    w = fr.w
    fr.kpsi, fr.kth, fr.Cinv, fr.K = kpsi, kth, Cinv, K
    fr.JP, fr.Jw = (JPp, JPt), (Jwp, Jwt)
    fr.D, fr.Hh, fr.Jx, fr.Jxinv = D, Hh, Jx, Jxinv
    fr.J = tuple(Jxinv[3 * rr + cc] * w[cc] for rr in range(3) for cc in range(3))
    return fr


class _Rates:
    """Second-order quantities at one (pose, rhodot) with rho_ddot = 0."""

    __slots__ = ("qd", "pard", "omega", "dd", "hd", "wd", "gd", "qdd0", "Pdd0", "alpha0", "dddot0", "hddot0")


def second_order(g: Geometry, fr: _Frame, rho_dot: Sequence[float]) -> _Rates:
    """Velocities for rhodot and the bias accelerations (rho_ddot = 0): qdd0 = Jdot rhodot, ..."""
    J = fr.J
    r0, r1, r2 = rho_dot
    zd = J[0] * r0 + J[1] * r1 + J[2] * r2
    pd = J[3] * r0 + J[4] * r1 + J[5] * r2
    td = J[6] * r0 + J[7] * r1 + J[8] * r2
    K = fr.K
    xd = K[0][0] * pd + K[0][1] * td
    yd = K[1][0] * pd + K[1][1] * td
    fd = K[2][0] * pd + K[2][1] * td
    kp, kt = fr.kpsi, fr.kth
    om = (pd * kp[0] + td * kt[0], pd * kp[1] + td * kt[1], pd * kp[2] + fd)
    # alpha0 = theta_dot phi_dot (e_z x k_theta) + psi_dot ((phi_dot e_z + theta_dot k_theta) x k_psi)
    bx, by, bz = td * kt[0], td * kt[1], fd  # phi_dot e_z + theta_dot k_theta
    al0 = (
        td * fd * (-kt[1]) + pd * (by * kp[2] - bz * kp[1]),
        td * fd * kt[0] + pd * (bz * kp[0] - bx * kp[2]),
        pd * (bx * kp[1] - by * kp[0]),
    )
    ca, sa = g._ca, g._sa
    wsq = om[0] * om[0] + om[1] * om[1] + om[2] * om[2]
    cen = []  # omega x (omega x a_i) = omega (omega . a) - a |omega|^2
    b = []
    for i in range(3):
        ax, ay, az = fr.a[i]
        oa = om[0] * ax + om[1] * ay + om[2] * az
        cx, cy, cz = om[0] * oa - ax * wsq, om[1] * oa - ay * wsq, om[2] * oa - az * wsq
        cen.append((cx, cy, cz))
        mx, my, mz = -az * ca[i], -az * sa[i], ax * ca[i] + ay * sa[i]
        b.append(al0[0] * mx + al0[1] * my + al0[2] * mz + (-sa[i] * cx + ca[i] * cy))
    Ci = fr.Cinv
    xb = -(Ci[0] * b[0] + Ci[1] * b[1] + Ci[2] * b[2])
    yb = -(Ci[3] * b[0] + Ci[4] * b[1] + Ci[5] * b[2])
    fb = -(Ci[6] * b[0] + Ci[7] * b[1] + Ci[8] * b[2])
    alb = (al0[0], al0[1], al0[2] + fb)
    D, Hh = fr.D, fr.Hh
    dd, hd, wd, beta, db_, hb_ = [], [], [], [], [], []
    rd = (r0, r1, r2)
    for i in range(3):
        ax, ay, az = fr.a[i]
        cx, cy, cz = cen[i]
        # S_i acceleration bias (qdd = 0): P_b + alpha_b x a + omega x (omega x a)
        sx = xb + alb[1] * az - alb[2] * ay + cx
        sy = yb + alb[2] * ax - alb[0] * az + cy
        sz = alb[0] * ay - alb[1] * ax + cz
        dbias = ca[i] * sx + sa[i] * sy
        hbias = sz
        ddi = D[i][1] * pd + D[i][2] * td
        hdi = zd + Hh[i][1] * pd + Hh[i][2] * td
        wdi = hdi - rd[i]
        dd.append(ddi)
        hd.append(hdi)
        wd.append(wdi)
        db_.append(dbias)
        hb_.append(hbias)
        beta.append(fr.w[i] * hbias - fr.u[i] * dbias + ddi * ddi + wdi * wdi)
    Xi = fr.Jxinv
    qdd0 = (
        -(Xi[0] * beta[0] + Xi[1] * beta[1] + Xi[2] * beta[2]),
        -(Xi[3] * beta[0] + Xi[4] * beta[1] + Xi[5] * beta[2]),
        -(Xi[6] * beta[0] + Xi[7] * beta[1] + Xi[8] * beta[2]),
    )
    zdd, pdd, tdd = qdd0
    # full bias accelerations with qdd = qdd0
    xdd = K[0][0] * pdd + K[0][1] * tdd + xb
    ydd = K[1][0] * pdd + K[1][1] * tdd + yb
    fdd = K[2][0] * pdd + K[2][1] * tdd + fb
    rt = _Rates()
    rt.qd = (zd, pd, td)
    rt.pard = (xd, yd, fd)
    rt.omega = om
    rt.dd, rt.hd, rt.wd = dd, hd, wd
    rt.gd = [dd[i] / fr.w[i] for i in range(3)]
    rt.qdd0 = qdd0
    rt.Pdd0 = (xdd, ydd, zdd)
    # alpha = Jw qdd0 + alpha0 + e_z phi_ddot_bias  (fdd already holds phi_ddot_bias)
    rt.alpha0 = (pdd * kp[0] + tdd * kt[0] + al0[0], pdd * kp[1] + tdd * kt[1] + al0[1], pdd * kp[2] + fdd + al0[2])
    rt.dddot0 = [D[i][1] * pdd + D[i][2] * tdd + db_[i] for i in range(3)]
    rt.hddot0 = [zdd + Hh[i][1] * pdd + Hh[i][2] * tdd + hb_[i] for i in range(3)]
    return rt


def _home_guess(g: Geometry, rho: Sequence[float]) -> tuple[float, float, float]:
    return ((rho[0] + rho[1] + rho[2]) / 3.0 + g.home_reach, 0.0, 0.0)


# --------------------------------------------------------------------------- public API
@dataclass(frozen=True)
class PoseSolution:
    """Full pose of the platform and the legs for one (z, psi, theta).

    x, y, z [m]: platform centre P (= TCP = platform COM); psi, theta, phi [rad]:
    R = Rz(phi) Ry(theta) Rx(psi); rho (3,) [m]: slider heights; gamma (3,) [rad]: leg
    elevations from the horizontal; S (3, 3) [m]: spherical joints (row i = S_i);
    sliders (3, 3) [m]: revolute joints on the sliders; R (3, 3): rotation matrix.
    """

    x: float
    y: float
    z: float
    psi: float
    theta: float
    phi: float
    rho: np.ndarray
    gamma: np.ndarray
    S: np.ndarray
    sliders: np.ndarray
    R: np.ndarray


def parasitic(geom: Geometry, z: float, psi: float, theta: float) -> tuple[float, float, float]:
    """Parasitic motion (x [m], y [m], phi [rad]) for the actuated pose (z [m], psi, theta [rad]).

    Solves S_i . t_i = 0 (i = 1..3), which are linear in (x, y, cos phi, sin phi): the
    solution is the normalised null vector of a 3x4 matrix (closed form, any guide layout).
    T layout: y = 0, phi = 0, x = -r sin(theta) sin(psi).
    """
    fr = frame_at(geom, float(z), float(psi), float(theta))
    return fr.x, fr.y, fr.phi


def inverse_kinematics(geom: Geometry, z: float, psi: float, theta: float) -> np.ndarray:
    """Slider heights rho (3,) [m] for the pose z [m], psi [rad], theta [rad].

    Raises KinematicsError naming the leg if the pose is unreachable.
    """
    fr = frame_at(geom, float(z), float(psi), float(theta))
    return np.array(fr.rho)


def full_pose(geom: Geometry, z: float, psi: float, theta: float) -> PoseSolution:
    """Full platform pose, slider heights, leg angles gamma and joint positions (see PoseSolution)."""
    fr = frame_at(geom, float(z), float(psi), float(theta))
    S = np.array([[fr.x + a[0], fr.y + a[1], fr.z + a[2]] for a in fr.a])
    sl = np.array([[geom.H * geom._ca[i], geom.H * geom._sa[i], fr.rho[i]] for i in range(3)])
    return PoseSolution(
        fr.x,
        fr.y,
        fr.z,
        fr.psi,
        fr.theta,
        fr.phi,
        np.array(fr.rho),
        np.array(fr.gamma),
        S,
        sl,
        np.array(fr.R).reshape(3, 3),
    )


def home_pose(geom: Geometry, rho0: float) -> np.ndarray:
    """(z, psi, theta) with all sliders at height rho0 [m] (direct kinematics)."""
    return direct_kinematics(geom, (rho0, rho0, rho0))


def dk_frame(g: Geometry, rho: Sequence[float], guess: Optional[Sequence[float]], tol: float, max_iter: int) -> _Frame:
    """Newton on the inverse kinematics; returns the frame (with first order) at the solution."""
    r0, r1, r2 = rho
    if not (_isfinite(r0) and _isfinite(r1) and _isfinite(r2)):
        raise KinematicsError(f"direct kinematics: rho = ({r0!r}, {r1!r}, {r2!r}) m is not finite")
    if guess is None:
        q0, q1, q2 = _home_guess(g, rho)
    else:
        q0, q1, q2 = (float(v) for v in guess)
        if not (_isfinite(q0) and _isfinite(q1) and _isfinite(q2)):
            q0, q1, q2 = _home_guess(g, rho)
    res = math.inf
    for it in range(max_iter + 1):
        try:
            fr = frame_at(g, q0, q1, q2)
            e0, e1, e2 = fr.rho[0] - r0, fr.rho[1] - r1, fr.rho[2] - r2
            res = max(abs(e0), abs(e1), abs(e2))
            first_order(g, fr, check=res < tol)
        except KinematicsError as exc:
            raise KinematicsError(
                f"direct kinematics did not converge for rho = ({r0:.9g}, {r1:.9g}, {r2:.9g}) m: "
                f"iteration {it} reached z = {q0:.6g} m, psi = {q1:.6g} rad, theta = {q2:.6g} rad, where: {exc}"
            ) from exc
        if res < tol:
            return fr
        if it == max_iter:
            break
        J = fr.J
        q0 -= J[0] * e0 + J[1] * e1 + J[2] * e2
        q1 -= J[3] * e0 + J[4] * e1 + J[5] * e2
        q2 -= J[6] * e0 + J[7] * e1 + J[8] * e2
    raise KinematicsError(
        f"direct kinematics did not converge for rho = ({r0:.9g}, {r1:.9g}, {r2:.9g}) m: "
        f"{max_iter} iterations, residual max|rho(q) - rho| = {res:.3g} m > tol = {tol:.3g} m "
        f"(last z = {q0:.6g} m, psi = {q1:.6g} rad, theta = {q2:.6g} rad)"
    )


def direct_kinematics(
    geom: Geometry,
    rho: Sequence[float],
    guess: Optional[Sequence[float]] = None,
    tol: float = 1e-12,
    max_iter: int = 50,
) -> np.ndarray:
    """Pose (z [m], psi [rad], theta [rad]) for slider heights rho (3,) [m].

    Newton's method on the inverse kinematics (step J = Jx^-1 Jq), warm-started from
    ``guess`` (z, psi, theta) or, without one, from the level pose of mean height.
    Stops when max_i |rho_i(q) - rho_i| < tol [m]. Raises KinematicsError if it does
    not converge within ``max_iter`` iterations, leaves the admissible range (working
    assembly, |psi|, |theta| <= MAX_TILT) or ends in a singular configuration.
    """
    r = [float(v) for v in rho]
    if len(r) != 3:
        raise KinematicsError(f"direct kinematics: expected 3 slider heights, got {len(r)}")
    fr = dk_frame(geom, r, guess, tol, max_iter)
    return np.array((fr.z, fr.psi, fr.theta))


@dataclass(frozen=True)
class Jacobians:
    """Jacobians at one pose; rho_dot is (3,) [m/s], q = (z, psi, theta).

    Jx, Jq: Appendix A (A.1-A.11), Jx qdot = Jq rhodot.
    J = Jx^-1 Jq: qdot = J rhodot ("inverse Jacobian"); J_inv = Jq^-1 Jx = d rho / d q.
    K (3, 3): d(x, y, phi)/dq (parasitic motion; first column zero).
    J_b (3, 3, 3): J_b[i] maps rhodot to (radial COM velocity of leg i along e_i [m/s],
        vertical COM velocity [m/s], gamma_i dot [rad/s]) (A.22-A.29).
    J_G (3, 3): rhodot -> platform COM (= P) velocity in the world frame [m/s].
    J_R (3, 3): rhodot -> platform angular velocity in the platform frame [rad/s] (A.32).
    """

    pose: PoseSolution
    Jx: np.ndarray
    Jq: np.ndarray
    J: np.ndarray
    J_inv: np.ndarray
    K: np.ndarray
    J_b: np.ndarray
    J_G: np.ndarray
    J_R: np.ndarray


@dataclass(frozen=True)
class JacobianRates:
    """Time-derivative terms for one (pose, rhodot): each is Jdot rhodot for the matching
    Jacobian of ``Jacobians`` (the accelerations when rho_ddot = 0).

    qdot (3,): J rhodot; w (3,): platform body angular velocity [rad/s];
    Jdot (3,): Jdot rhodot [m/s^2, rad/s^2]; J_b_dot (3, 3): row i = Jdot_b_i rhodot;
    J_G_dot (3,) [m/s^2]; J_R_dot (3,) [rad/s^2]; parasitic_dot (3,): (xdot, ydot, phidot).
    """

    qdot: np.ndarray
    w: np.ndarray
    Jdot: np.ndarray
    J_b_dot: np.ndarray
    J_G_dot: np.ndarray
    J_R_dot: np.ndarray
    parasitic_dot: np.ndarray


def leg_jacobians(g: Geometry, fr: _Frame) -> list[tuple[tuple[float, float, float], ...]]:
    """Rows (radial, vertical, gamma) of J_b_i in rhodot, for each leg."""
    J = fr.J
    out = []
    for i in range(3):
        Di, Hi = fr.D[i], fr.Hh[i]
        dj = tuple(Di[0] * J[c] + Di[1] * J[3 + c] + Di[2] * J[6 + c] for c in range(3))
        hj = tuple(Hi[0] * J[c] + Hi[1] * J[3 + c] + Hi[2] * J[6 + c] for c in range(3))
        w = fr.w[i]
        out.append(
            (
                tuple(0.5 * v for v in dj),
                tuple(0.5 * (hj[c] + (1.0 if c == i else 0.0)) for c in range(3)),
                tuple(v / w for v in dj),
            )
        )
    return out


def platform_jacobians(fr: _Frame) -> tuple[list[list[float]], list[list[float]]]:
    """J_G (rows x, y, z) and J_R (rows body w_x, w_y, w_z) in rhodot."""
    J = fr.J
    (JPp, JPt), (Jwp, Jwt) = fr.JP, fr.Jw
    JG = [[(1.0 if k == 2 else 0.0) * J[c] + JPp[k] * J[3 + c] + JPt[k] * J[6 + c] for c in range(3)] for k in range(3)]
    Jw = [[Jwp[k] * J[3 + c] + Jwt[k] * J[6 + c] for c in range(3)] for k in range(3)]
    R = fr.R
    JR = [[R[k] * Jw[0][c] + R[3 + k] * Jw[1][c] + R[6 + k] * Jw[2][c] for c in range(3)] for k in range(3)]
    return JG, JR


def jacobians(geom: Geometry, z: float, psi: float, theta: float) -> Jacobians:
    """All velocity Jacobians at the pose (z [m], psi [rad], theta [rad]); see Jacobians.

    Raises KinematicsError (naming Jx or Jq and its condition number) near a singularity.
    """
    fr = first_order(geom, frame_at(geom, float(z), float(psi), float(theta)))
    pose = full_pose(geom, z, psi, theta)
    Jx = np.array(fr.Jx).reshape(3, 3)
    Jq = np.diag(fr.w)
    J = np.array(fr.J).reshape(3, 3)
    K = np.array([[0.0, fr.K[k][0], fr.K[k][1]] for k in range(3)])
    JG, JR = platform_jacobians(fr)
    return Jacobians(
        pose, Jx, Jq, J, np.linalg.solve(Jq, Jx), K, np.array(leg_jacobians(geom, fr)), np.array(JG), np.array(JR)
    )


def rates_arrays(g: Geometry, fr: _Frame, rt: _Rates) -> dict:
    """Bias accelerations of every body coordinate (rho_ddot = 0)."""
    legs = []
    for i in range(3):
        w = fr.w[i]
        legs.append((0.5 * rt.dddot0[i], 0.5 * rt.hddot0[i], (rt.dddot0[i] - rt.wd[i] * rt.gd[i]) / w))
    R = fr.R
    al = rt.alpha0
    wdot = tuple(R[k] * al[0] + R[3 + k] * al[1] + R[6 + k] * al[2] for k in range(3))
    om = rt.omega
    wb = tuple(R[k] * om[0] + R[3 + k] * om[1] + R[6 + k] * om[2] for k in range(3))
    return {"legs": legs, "P": rt.Pdd0, "wdot": wdot, "w": wb}


def jacobian_rates(geom: Geometry, z: float, psi: float, theta: float, rho_dot: Sequence[float]) -> JacobianRates:
    """Jdot rhodot of every Jacobian at the pose (z, psi, theta) for slider velocities
    rho_dot (3,) [m/s], exact (closed form: the constraints differentiated twice)."""
    fr = first_order(geom, frame_at(geom, float(z), float(psi), float(theta)))
    rd = [float(v) for v in rho_dot]
    rt = second_order(geom, fr, rd)
    b = rates_arrays(geom, fr, rt)
    return JacobianRates(
        np.array(rt.qd),
        np.array(b["w"]),
        np.array(rt.qdd0),
        np.array(b["legs"]),
        np.array(b["P"]),
        np.array(b["wdot"]),
        np.array(rt.pard),
    )
