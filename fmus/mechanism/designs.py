"""Mechanism designs as descriptions for the inverse-dynamics engine (``engine.py``).

One parameterised family, chosen by the geometry parameter ``kinematics`` (bound to the
mechanism *and* to the controller, whose inverse kinematics must be the machine's):

``"3PRS"``: three guides around the vertical centre axis at angles alpha_1..3, at horizontal
distance H from it at the base plane z = 0 and inclined by ``beta`` towards the axis
(beta = 0: vertical guides, the paper's machine). Slider i moves along its guide; a revolute
joint with the horizontal tangential axis t_i carries leg i (length L), whose upper end is the
spherical joint S_i on the platform (radius r). The paper's T layout is alpha = 0, 90, 180 deg,
beta = 0; the textbook layout alpha = 0, 120, 240 deg; with beta != 0 the actuation direction
changes (a structurally different design: the guide is no longer parallel to the platform's
heave motion). See docs/designs/.

Bodies: three legs (mass m_leg, centre of mass at mid-length, inertia I_leg about the revolute
axis direction), the platform (m_platform, centre of mass at P, principal inertias I_px, I_py,
I_pz) and an optional payload fixed to the platform (m_payload, centre of mass at
(payload_x, payload_y, payload_z) in the platform frame, inertia tensor I_payload_* about its
centre of mass, platform axes). Sliders are massless here: their mass is the actuators' M_load.

The 3PRS description repeats the closed form of ``kinematics.py`` operation for operation,
so for beta = 0 its inverse kinematics gives the very same floats.
"""
from __future__ import annotations

import math
from typing import Mapping, Sequence

import numpy as np

from ..common.codegen import largest_parameters
from ..common.parameters import Param, ParameterError, nonnegative
from ..common.tracer import atan2, hypot, require, sign, sqrt
from ..common.tracer import cos as _cos
from ..common.tracer import sin as _sin
from .engine import Body, Description, Engine, Evaluation, Part, TracedBody
from .kinematics import GEOMETRY_PARAMETERS, MAX_TILT, Geometry, KinematicsError
from .kinematics import det3 as _det3
from .topology import Coordinate, Drive, Topology

__all__ = ["KINEMATICS", "KINEMATIC_PARAMETERS", "KINEMATIC_PARAMETERS_NAMES", "MASS_PARAMETERS", "PAYLOAD_PARAMETERS",
           "PRS3", "TRACED_PARAMETERS", "describe", "engine", "kinematic_engine", "level_height", "traced_engine"]


#: the geometry parameter set: bound to the mechanism and to the controller (its kinematic model)
KINEMATIC_PARAMETERS: tuple[Param, ...] = (
    Param("kinematics", "", "Kinematic model of the mechanism: 3PRS (three guides, revolute + spherical joints)",
          kind=str),
    *GEOMETRY_PARAMETERS,
    Param("beta", "rad", "Inclination of every guide from the vertical, towards the centre axis (0: vertical guides)",
          -math.radians(45.0), math.radians(45.0)),
)

KINEMATIC_PARAMETERS_NAMES: tuple[str, ...] = tuple(p.name for p in KINEMATIC_PARAMETERS)

#: bodies of the 3PRS (and switch for the actuators-alone design)
MASS_PARAMETERS: tuple[Param, ...] = (
    nonnegative("m_leg", "kg", "Mass of each leg (COM at mid-length)"),
    nonnegative("I_leg", "kg.m2", "Inertia of each leg about its COM, about the revolute axis direction"),
    Param("m_platform", "kg", "Platform mass (COM at P)", minimum=0.0, exclusive=True, maximum=math.inf),
    nonnegative("I_px", "kg.m2", "Platform inertia about its own x axis, at P"),
    nonnegative("I_py", "kg.m2", "Platform inertia about its own y axis, at P"),
    nonnegative("I_pz", "kg.m2", "Platform inertia about its own z axis, at P"),
    Param("g", "m/s2", "Gravitational acceleration (along -z)", minimum=0.0, maximum=100.0),
    Param("attached", "", "1: the mechanism loads the actuators (its inverse dynamics); 0: actuators alone "
                          "(paper Fig. 10 'without the MAST'): no force, the pose outputs are the kinematics",
          minimum=0, maximum=1, kind=int),
)

PAYLOAD_PARAMETERS: tuple[Param, ...] = (
    nonnegative("m_payload", "kg", "Payload mass, fixed to the platform (0: no payload)"),
    Param("payload_x", "m", "Payload centre of mass, platform frame x"),
    Param("payload_y", "m", "Payload centre of mass, platform frame y"),
    Param("payload_z", "m", "Payload centre of mass, platform frame z (above P: positive)"),
    nonnegative("I_payload_xx", "kg.m2", "Payload inertia about its COM, platform axes, xx"),
    nonnegative("I_payload_yy", "kg.m2", "Payload inertia about its COM, platform axes, yy"),
    nonnegative("I_payload_zz", "kg.m2", "Payload inertia about its COM, platform axes, zz"),
    Param("I_payload_xy", "kg.m2", "Payload inertia about its COM, platform axes, xy (tensor entry)"),
    Param("I_payload_xz", "kg.m2", "Payload inertia about its COM, platform axes, xz (tensor entry)"),
    Param("I_payload_yz", "kg.m2", "Payload inertia about its COM, platform axes, yz (tensor entry)"),
)


def _fmt(v: float) -> str:
    return f"{v:.6g}"


# ----------------------------------------------------------------------------- admissibility checks
# (run at the point of the evaluation where the description calls require(); messages as kinematics.py)
# Each check also has ``admissible``: the same condition as a mask over arrays (Engine.evaluate_many), and
# ``c_condition``, ``c_message``: the condition as a C expression of its arguments a0, a1, ... and what failed,
# for the C backend of the engine's generated code (mast.core.native.translate).
def _finite(z, psi, theta) -> None:
    if not (math.isfinite(z) and math.isfinite(psi) and math.isfinite(theta)):
        raise KinematicsError(f"pose (z = {z!r} m, psi = {psi!r} rad, theta = {theta!r} rad) is not finite")


_finite.c_condition = "isfinite(a0) && isfinite(a1) && isfinite(a2)"
_finite.c_message = "pose (z, psi, theta) is not finite"
_finite.admissible = lambda z, psi, theta: np.isfinite(z) & np.isfinite(psi) & np.isfinite(theta)


def _tilt(psi, theta) -> None:
    if abs(psi) > MAX_TILT or abs(theta) > MAX_TILT:
        raise KinematicsError(
            f"pose out of range: |psi| = {abs(psi):.6g} rad or |theta| = {abs(theta):.6g} rad exceeds "
            f"the admissible tilt {MAX_TILT:.6g} rad ({math.degrees(MAX_TILT):g} deg)")


_tilt.c_condition = f"!(fabs(a0) > {MAX_TILT!r} || fabs(a1) > {MAX_TILT!r})"
_tilt.c_message = (f"pose out of range: |psi| or |theta| exceeds the admissible tilt {MAX_TILT:.6g} rad "
                   f"({math.degrees(MAX_TILT):g} deg)")
_tilt.admissible = lambda psi, theta: (np.abs(psi) <= MAX_TILT) & (np.abs(theta) <= MAX_TILT)


def _pose_text(z, psi, theta) -> str:
    return f"z = {_fmt(z)} m, psi = {_fmt(psi)} rad, theta = {_fmt(theta)} rad"


class _NullCheck:
    """The parasitic motion determined: |null vector| > 1e-9 r^2 (arguments: norm, z, psi, theta, r, alpha_1..3)."""

    c_condition = "a0 > ((1e-09 * a4) * a4)"
    c_message = ("singular configuration: the constraints S_i . t_i = 0 do not determine the parasitic "
                 "motion (x, y, phi)")

    def __call__(self, norm, z, psi, theta, r, *alpha) -> None:
        if not norm > 1e-9 * r * r:
            raise KinematicsError(
                f"singular configuration: the constraints S_i . t_i = 0 do not determine the parasitic motion "
                f"(x, y, phi) at {_pose_text(z, psi, theta)} (guide angles {tuple(alpha)} rad; "
                f"|null vector (cos, sin)| = {norm:.3g})")

    @staticmethod
    def admissible(norm, z, psi, theta, r, *alpha):
        return norm > 1e-9 * r * r


class _InsideCheck:
    """S_i on the inner side of guide i (the working assembly); arguments: u, d, z, psi, theta, H."""

    def __init__(self, i: int, inclined: bool) -> None:
        self.i, self.inclined = i, inclined
        self.c_condition = "a0 > 0.0"
        self.c_message = (f"pose unreachable (not the working assembly): spherical joint S_{i + 1} is on the outer "
                          f"side of guide {i + 1}")

    def __call__(self, u, d, z, psi, theta, H) -> None:
        if not u > 0.0:
            i = self.i + 1
            if self.inclined:
                raise KinematicsError(
                    f"pose unreachable (not the working assembly): spherical joint S_{i} is {_fmt(-u)} m on the "
                    f"outer side of guide {i} ({_pose_text(z, psi, theta)})")
            raise KinematicsError(
                f"pose unreachable (not the working assembly): spherical joint S_{i} at radial distance "
                f"{_fmt(d)} m is outside the guide radius H = {_fmt(H)} m by {_fmt(-u)} m "
                f"({_pose_text(z, psi, theta)})")

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
                f"(short by {_fmt(u - L)} m) at {_pose_text(z, psi, theta)}")

    @staticmethod
    def admissible(w2, u, z, psi, theta, L):
        return w2 > 0.0


def level_height(rho_1, rho_2, rho_3, H, r, L, cb, sb):
    """z [m] of the level pose (psi = theta = 0) for the mean slider position (guides inclined by beta:
    cb = cos(beta), sb = sin(beta); for beta = 0 the mean plus sqrt(L^2 - (H - r)^2), the same floats):
    the direct kinematics' cold start. In the generated-code subset: the native FMUs translate it."""
    mean = (rho_1 + rho_2 + rho_3) / 3.0
    gap = r - H + mean * sb
    w2 = L * L - gap * gap
    if 0.0 > w2:
        w2 = 0.0
    return mean * cb + sqrt(w2)


#: the names of the parameters a symbolic 3PRS traces as inputs (``PRS3(symbolic=True)``), in argument order
TRACED_PARAMETERS = ("H", "r", "L", "alpha_1", "alpha_2", "alpha_3", "beta", "m_leg", "I_leg", "m_platform",
                     "I_px", "I_py", "I_pz", "g", "m_payload", "payload_x", "payload_y", "payload_z",
                     "I_payload_xx", "I_payload_yy", "I_payload_zz", "I_payload_xy", "I_payload_xz", "I_payload_yz")


# ----------------------------------------------------------------------------- the 3PRS
#: points on the outline of the base and of the platform in the drawing (``PRS3.sketch``)
_RIM_POINTS = 48


class PRS3(Description):
    """3-PRS with guides at angles alpha around the centre axis, inclined by beta (module docstring).

    Coordinates q = (z, psi, theta); joints rho_i = slider position along guide i, measured
    from the base plane (for vertical guides: the slider height). Parasitic motion (x, y, phi)
    from S_i . t_i = 0 (closed form, kinematics.py). R = Rz(phi) Ry(theta) Rx(psi).
    """

    name = "3PRS"

    def __init__(self, H: float, r: float, L: float, alpha: Sequence[float], beta: float = 0.0,
                 m_leg: float = 0.0, I_leg: float = 0.0, m_platform: float = 0.0,
                 I_p: Sequence[float] = (0.0, 0.0, 0.0), payload: "Body | None" = None) -> None:
        self.geometry = Geometry(H, r, L, tuple(alpha))     # validates H, r, L > 0 and the angles
        self.H, self.r, self.L = self.geometry.H, self.geometry.r, self.geometry.L
        self.alpha = self.geometry.alpha
        self.beta = float(beta)
        self._ca, self._sa = self.geometry._ca, self.geometry._sa
        self._cb, self._sb = math.cos(self.beta), math.sin(self.beta)
        self.inclined = self.beta != 0.0
        self.lengths = (1.0, self.r, self.r)   # a tilt moves the spherical joints by r times the angle
        L = self.L
        leg_inertia = ((0.0, 0.0, 0.0), (0.0, float(I_leg), 0.0), (0.0, 0.0, float(I_leg)))
        legs = tuple(Body(f"leg_{i + 1}", float(m_leg), (0.5 * L, 0.0, 0.0), leg_inertia) for i in range(3))
        Ix, Iy, Iz = (float(v) for v in I_p)
        platform = Body("platform", float(m_platform), (0.0, 0.0, 0.0), ((Ix, 0.0, 0.0), (0.0, Iy, 0.0), (0.0, 0.0, Iz)))
        self.payload = payload
        self.bodies = legs + (platform,) + ((payload,) if payload is not None else ())
        #: the parameter values, when traced as inputs (``traced``); None: traced as constants
        self.values = None

    @classmethod
    def traced(cls, params: Mapping[str, object], masses: bool = True) -> "PRS3":
        """The description of ``params`` traced with every parameter of ``TRACED_PARAMETERS`` (geometry,
        bodies, payload, g) as a named input of the generated functions instead of a constant: one
        generated code for every parameter set (the native FMUs compute with what a host sets). Always
        traced with the inclined guides' formulas and the payload body, which for beta = 0 and no payload
        give the same floats as the specialised ones (up to the sign of a zero). ``masses=False``: a
        kinematic model (``kinematic_engine``): its bodies' data and g are 0 (``params`` need not have them)."""
        desc = describe(params, masses=masses)
        desc.values = {name: float(params[name]) if masses or name in KINEMATIC_PARAMETERS_NAMES else 0.0
                       for name in TRACED_PARAMETERS}
        return desc

    def key(self) -> tuple:
        return (type(self).__name__, self.H, self.r, self.L, self.alpha, self.beta, self.bodies,
                None if self.values is None else tuple(self.values.items()))

    def _traced_inputs(self, q: Sequence):
        """(H, r, L, alpha, cos alpha, sin alpha, cos beta, sin beta, bodies, inclined): this description's
        numbers, or (``traced``) the named inputs of q's graph and expressions of them."""
        if self.values is None:
            return (self.H, self.r, self.L, self.alpha, self._ca, self._sa, self._cb, self._sb, None,
                    self.inclined)
        graph = q[0].g
        P = {name: graph.input(name) for name in TRACED_PARAMETERS}
        alpha = tuple(P[f"alpha_{i + 1}"] for i in range(3))
        L, I_leg = P["L"], P["I_leg"]
        leg_inertia = ((0.0, 0.0, 0.0), (0.0, I_leg, 0.0), (0.0, 0.0, I_leg))
        bodies = [TracedBody(f"leg_{i + 1}", P["m_leg"], (0.5 * L, 0.0, 0.0), leg_inertia) for i in range(3)]
        bodies.append(TracedBody("platform", P["m_platform"], (0.0, 0.0, 0.0),
                                 ((P["I_px"], 0.0, 0.0), (0.0, P["I_py"], 0.0), (0.0, 0.0, P["I_pz"]))))
        xy, xz, yz = P["I_payload_xy"], P["I_payload_xz"], P["I_payload_yz"]
        bodies.append(TracedBody("payload", P["m_payload"], (P["payload_x"], P["payload_y"], P["payload_z"]),
                                 ((P["I_payload_xx"], xy, xz), (xy, P["I_payload_yy"], yz),
                                  (xz, yz, P["I_payload_zz"]))))
        return (P["H"], P["r"], L, alpha, tuple(_cos(a) for a in alpha), tuple(_sin(a) for a in alpha),
                _cos(P["beta"]), _sin(P["beta"]), bodies, True)

    # ---------------------------------------------------------------- positions (the closed form)
    def evaluate(self, q: Sequence) -> Evaluation:
        z, psi, theta = q
        require(_finite, z, psi, theta)
        require(_tilt, psi, theta)
        H, r, L, alpha, ca, sa, cb, sb, bodies, inclined = self._traced_inputs(q)
        cp, sp = _cos(psi), _sin(psi)
        ct, st = _cos(theta), _sin(theta)
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
        n0 = _det3(m01, m02, m03, m11, m12, m13, m21, m22, m23)
        n1 = -_det3(m00, m02, m03, m10, m12, m13, m20, m22, m23)
        n2 = _det3(m00, m01, m03, m10, m11, m13, m20, m21, m23)
        n3 = -_det3(m00, m01, m02, m10, m11, m12, m20, m21, m22)
        norm = hypot(n2, n3)
        require(_NullCheck(), norm, z, psi, theta, r, *alpha)
        k = sign(n2) / norm       # choose cos(phi) > 0
        x, y, c, s = n0 * k, n1 * k, n2 * k, n3 * k
        R = ((c * ct, c * st * sp - s * cp, c * st * cp + s * sp),
             (s * ct, s * st * sp + c * cp, s * st * cp - c * sp),
             (-st, ct * sp, ct * cp))
        rho, frames = [], []
        for i in range(3):
            vx, vy, vz = v[i]
            ax, ay = c * vx - s * vy, s * vx + c * vy
            Sx, Sy, Sz = x + ax, y + ay, z + vz
            d = ca[i] * Sx + sa[i] * Sy
            h = Sz
            if inclined:
                dr = d - H                           # S_i relative to the foot of guide i, in its plane
                u = -(cb * dr + sb * h)              # distance of S_i inside the guide line
                a = cb * h - sb * dr                 # position of S_i's projection along the guide
            else:
                u = H - d
                a = h
            require(_InsideCheck(i, inclined), u, d, z, psi, theta, H)
            w2 = L * L - u * u
            require(_ReachCheck(i, inclined), w2, u, z, psi, theta, L)
            w = sqrt(w2)
            rho_i = a - w
            rho.append(rho_i)
            # leg frame: x along the leg (slider -> S_i), y = t_i (revolute axis), z = x cross y
            radial = H - sb * rho_i
            Bx, By, Bz = ca[i] * radial, sa[i] * radial, cb * rho_i
            lx, ly, lz = (Sx - Bx) / L, (Sy - By) / L, (Sz - Bz) / L
            tx, ty = -sa[i], ca[i]
            frames.append(((Bx, By, Bz), ((lx, tx, -lz * ty), (ly, ty, lz * tx), (lz, 0.0, lx * ty - ly * tx))))
        frames.append(((x, y, z), R))
        if bodies is not None or self.payload is not None:
            frames.append(((x, y, z), R))
        pose = (x, y, z, psi, theta, atan2(s, c))
        if self.values is None:
            return Evaluation(rho, pose, frames)
        return Evaluation(rho, pose, frames, bodies, self.values, q[0].g.input("g"))

    def sketch(self) -> tuple[Part, ...]:
        """The base (a disc of radius H through the guides' feet), per guide its axis (``evaluate``'s slider
        origin at rho = 0 and 1 m), the carriage and the leg (origins of the leg frames; x along the leg, length
        L), the platform (a disc of radius r) and its spherical joints s_i = r (cos alpha_i, sin alpha_i, 0)."""
        H, r, L, ca, sa, cb, sb = self.H, self.r, self.L, self._ca, self._sa, self._cb, self._sb
        rim = [2.0 * math.pi * k / _RIM_POINTS for k in range(_RIM_POINTS)]
        parts = [Part("plate", None, [(H * math.cos(a), H * math.sin(a), 0.0) for a in rim])]
        for i in range(3):
            leg = f"leg_{i + 1}"
            parts += [Part("guide", None, [(ca[i] * H, sa[i] * H, 0.0), (ca[i] * (H - sb), sa[i] * (H - sb), cb)],
                           joint=i),
                      Part("carriage", leg, [(0.0, 0.0, 0.0)]),
                      Part("link", leg, [(0.0, 0.0, 0.0), (L, 0.0, 0.0)])]
        parts += [Part("plate", "platform", [(r * math.cos(a), r * math.sin(a), 0.0) for a in rim]),
                  Part("joint", "platform", [(r * ca[i], r * sa[i], 0.0) for i in range(3)])]
        return tuple(parts)

    @property
    def topology(self) -> Topology:
        """Three linear drives along the guides with the paper's 300 mm stroke (section 3.1), coordinates
        (z, psi, theta), home: the level pose with every slider at mid-stroke (``actuator_manufacturer.ssv``'s
        rho_0 = 0.15 m)."""
        stroke = (0.0, 0.3)
        home = self.guess((0.5 * (stroke[0] + stroke[1]),) * 3)
        return Topology(self.name, tuple(Coordinate(c) for c in self.coordinates),
                        tuple(Drive(j, "linear", stroke) for j in self.joints), home)

    def guess(self, rho: Sequence[float]) -> tuple[float, float, float]:
        """Level pose for the mean slider position (the direct kinematics' cold start)."""
        return (level_height(rho[0], rho[1], rho[2], self.H, self.r, self.L, self._cb, self._sb), 0.0, 0.0)


# ----------------------------------------------------------------------------- from parameters
KINEMATICS = {"3PRS": PRS3}


def _payload(params: Mapping[str, object], owner: str) -> "Body | None":
    m = float(params.get("m_payload", 0.0))
    I = ((float(params.get("I_payload_xx", 0.0)), float(params.get("I_payload_xy", 0.0)), float(params.get("I_payload_xz", 0.0))),
         (float(params.get("I_payload_xy", 0.0)), float(params.get("I_payload_yy", 0.0)), float(params.get("I_payload_yz", 0.0))),
         (float(params.get("I_payload_xz", 0.0)), float(params.get("I_payload_yz", 0.0)), float(params.get("I_payload_zz", 0.0))))
    if m == 0.0 and not any(any(row) for row in I):
        return None
    com = (float(params.get("payload_x", 0.0)), float(params.get("payload_y", 0.0)), float(params.get("payload_z", 0.0)))
    try:
        return Body("payload", m, com, I)
    except ValueError as exc:
        raise ParameterError(f"{owner}: parameters 'I_payload_*': {exc}") from None


def describe(params: Mapping[str, object], owner: str = "", masses: bool = True) -> Description:
    """The description a parameter set defines (``masses=False``: kinematics only, massless bodies).

    Raises ParameterError naming the parameter: an unknown ``kinematics``, or a geometry that
    cannot be assembled at the level pose.
    """
    where = owner or "mechanism"
    kind = params.get("kinematics", "3PRS")
    if kind not in KINEMATICS:
        raise ParameterError(f"{where}: parameter 'kinematics' = {kind!r}: expected one of {', '.join(KINEMATICS)}")
    beta = float(params.get("beta", 0.0))
    geom = Geometry.checked(params, where) if beta == 0.0 else Geometry.from_params(params)
    args = dict(H=geom.H, r=geom.r, L=geom.L, alpha=geom.alpha, beta=beta)
    if masses:
        args.update(m_leg=float(params["m_leg"]), I_leg=float(params["I_leg"]),
                    m_platform=float(params["m_platform"]),
                    I_p=(float(params["I_px"]), float(params["I_py"]), float(params["I_pz"])),
                    payload=_payload(params, where))
    desc = KINEMATICS[kind](**args)
    if beta != 0.0:
        _check_inclined(desc, where)
    return desc


#: the bodies ``describe`` builds, their masses and inertias as the parameters that set them (None: 0 by
#: construction), and g: the engine's forces with these as inputs (``Engine.forces_of``) read them at run time
#: in the native FMU (the payload's, which also moves its centre of mass, are not among them)
_LEG = ("m_leg", ((None, None, None), (None, "I_leg", None), (None, None, "I_leg")))
INERTIAL_PARAMETERS = {**{f"leg_{i + 1}": _LEG for i in range(3)},
                       "platform": ("m_platform", (("I_px", None, None), (None, "I_py", None), (None, None, "I_pz")))}
GRAVITY_PARAMETER = "g"


def _check_inclined(desc: PRS3, owner: str) -> None:
    """Inclined guides: the level pose with the sliders at rho = 0 must exist (working assembly, reach)."""
    try:
        desc.evaluate(list(desc.guess((0.0, 0.0, 0.0))))      # plain floats: the checks run at once
    except KinematicsError as exc:
        raise ParameterError(f"{owner}: parameters 'H', 'r', 'L', 'beta' = {desc.H!r} m, {desc.r!r} m, {desc.L!r} m, "
                             f"{desc.beta!r} rad: the mechanism cannot be assembled at the level pose with the "
                             f"sliders at the foot of their guides: {exc}") from None


_ENGINES: dict = {}


def engine(params: Mapping[str, object], owner: str = "", masses: bool = True) -> Engine:
    """The engine of a parameter set, shared between blocks with the same description and g."""
    try:
        desc = describe(params, owner, masses)
        key = (desc.key(), float(params.get("g", 9.81)) if masses else 0.0)
        found = _ENGINES.get(key)
        if found is None:
            if len(_ENGINES) > 64:
                _ENGINES.clear()
            found = Engine(desc, g=key[1])
            found.overflow_hint = largest_parameters(params)
            _ENGINES[key] = found
        return found
    except OverflowError as err:
        raise ParameterError(f"{owner}: {err}{largest_parameters(params)}") from None


def kinematic_engine(params: Mapping[str, object], owner: str = "") -> Engine:
    """Kinematics only (the controller's model): the same description with massless bodies."""
    return engine(params, owner, masses=False)


def traced_engine(params: Mapping[str, object], owner: str = "", masses: bool = True) -> Engine:
    """The engine of ``PRS3.traced(params)``: its generated functions take every parameter of
    ``TRACED_PARAMETERS`` as an input after their own arguments (``Engine.parameters``), the same floats as
    ``engine(params, owner, masses)`` computes with them as constants (tests/test_native.py); it calls them
    with ``params``."""
    try:
        return Engine(PRS3.traced(params, masses), g=float(params["g"]) if masses else 0.0)
    except OverflowError as err:
        raise ParameterError(f"{owner}: {err}{largest_parameters(params)}") from None
