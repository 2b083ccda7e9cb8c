"""Inverse dynamic problem (IDP) of the 3PRS mechanism (paper sections 2.4 and 3.3).

Given the slider motion (rho, rho_dot, rho_ddot), returns the forces t_rho the three
actuators apply to the mechanism along their guides (positive upward), split as in
Eq. 32 into an inertial term M(rho) rho_ddot, a quadratic-velocity (Coriolis and
centrifugal) term and a gravity term:

    t_rho = sum_i J_bi^T (M_bi (J_bi rho_ddot + Jdot_bi rho_dot) + g_bi)          legs, Eqs. 24-27
          + J_G^T m_p (J_G rho_ddot + Jdot_G rho_dot + g e_z)                      platform translation, Eqs. 8-9
          + J_R^T (I_mp (J_R rho_ddot + Jdot_R rho_dot) + w x (I_mp w))           platform rotation, Eqs. 13, 18

Legs: principle of energy equivalence, each leg a planar body in the vertical radial
plane of its guide, generalized coordinates q_bi = (radial position of its COM along
e_i, height of its COM, gamma_i), M_bi = diag(m_leg, m_leg, I_leg), g_bi = (0, m_leg g, 0),
COM at mid-length. Platform: COM at P; rotation by Boltzmann-Hamel with the body
angular velocity w = J_R rho_dot as quasi-velocities, I_mp = diag(I_px, I_py, I_pz) in
the platform frame. Jacobians and their time derivatives come from ``kinematics``
(closed form, exact). See docs/mechanism.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping, Optional, Sequence

import numpy as np

from ..common.parameters import ParameterError
from .kinematics import (
    Geometry,
    KinematicsError,
    dk_frame,
    first_order,
    frame_at,
    leg_jacobians,
    platform_jacobians,
    rates_arrays,
    second_order,
)

__all__ = ["Masses", "IDPResult", "inverse_dynamics", "inverse_dynamics_at_pose"]


@dataclass(frozen=True)
class Masses:
    """Mass properties: m_leg [kg], I_leg [kg m^2] (about the leg COM, normal to its plane),
    m_platform [kg], I_px, I_py, I_pz [kg m^2] (platform principal inertias about P in the
    platform frame), g [m/s^2] (gravity along -z)."""

    m_leg: float
    I_leg: float
    m_platform: float
    I_px: float
    I_py: float
    I_pz: float
    g: float

    def __post_init__(self) -> None:
        for name in ("m_leg", "I_leg", "m_platform", "I_px", "I_py", "I_pz", "g"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0.0):
                raise ParameterError(f"Masses: '{name}' = {value!r}: expected a finite value >= 0")
            object.__setattr__(self, name, float(value))

    @classmethod
    def from_params(cls, params: Mapping[str, object]) -> "Masses":
        """Masses from a parameter mapping (m_leg, I_leg, m_platform, I_px, I_py, I_pz, g; others ignored)."""
        try:
            return cls(**{k: float(params[k]) for k in ("m_leg", "I_leg", "m_platform", "I_px", "I_py", "I_pz", "g")})
        except KeyError as exc:
            raise ParameterError(f"Masses: missing parameter {exc.args[0]!r}") from None


@dataclass(frozen=True)
class IDPResult:
    """Inverse dynamics at one instant.

    t_rho (3,) [N]: force actuator i applies to the mechanism along guide i, positive up;
    t_rho = I_term + c_term + g_term with I_term = M rho_ddot (inertial), c_term (quadratic
    velocity terms), g_term (gravity); M (3, 3) [kg]: mass matrix in rho.
    pose (3,): (z [m], psi [rad], theta [rad]); parasitic (3,): (x [m], y [m], phi [rad]).
    """

    t_rho: np.ndarray
    I_term: np.ndarray
    c_term: np.ndarray
    g_term: np.ndarray
    M: np.ndarray
    pose: np.ndarray
    parasitic: np.ndarray


def _idp(g: Geometry, ms: Masses, fr, rho_dot: Sequence[float], rho_ddot: Sequence[float]):
    """Core (plain floats): returns (t, I_term, c_term, g_term, M as 9-tuple) for a frame with first order."""
    legs = leg_jacobians(g, fr)
    JG, JR = platform_jacobians(fr)
    rt = second_order(g, fr, rho_dot)
    bias = rates_arrays(g, fr, rt)
    ml, Il, mp, gr = ms.m_leg, ms.I_leg, ms.m_platform, ms.g
    Ip = (ms.I_px, ms.I_py, ms.I_pz)
    M = [0.0] * 9
    c = [0.0, 0.0, 0.0]
    gt = [0.0, 0.0, 0.0]
    for i in range(3):
        jr, jz, jg = legs[i]
        ar, az, ag = bias["legs"][i]
        fr_, fz_, fg_ = ml * ar, ml * az, Il * ag
        for a in range(3):
            c[a] += jr[a] * fr_ + jz[a] * fz_ + jg[a] * fg_
            gt[a] += jz[a] * ml * gr
            for b in range(a, 3):
                M[3 * a + b] += ml * (jr[a] * jr[b] + jz[a] * jz[b]) + Il * jg[a] * jg[b]
    P0 = bias["P"]
    wd0 = bias["wdot"]
    w = bias["w"]
    Iw = (Ip[0] * w[0], Ip[1] * w[1], Ip[2] * w[2])
    gyro = (w[1] * Iw[2] - w[2] * Iw[1], w[2] * Iw[0] - w[0] * Iw[2], w[0] * Iw[1] - w[1] * Iw[0])
    mrot = tuple(Ip[k] * wd0[k] + gyro[k] for k in range(3))
    for a in range(3):
        c[a] += (
            mp * (JG[0][a] * P0[0] + JG[1][a] * P0[1] + JG[2][a] * P0[2])
            + JR[0][a] * mrot[0]
            + JR[1][a] * mrot[1]
            + JR[2][a] * mrot[2]
        )
        gt[a] += JG[2][a] * mp * gr
        for b in range(a, 3):
            M[3 * a + b] += (
                mp * (JG[0][a] * JG[0][b] + JG[1][a] * JG[1][b] + JG[2][a] * JG[2][b])
                + Ip[0] * JR[0][a] * JR[0][b]
                + Ip[1] * JR[1][a] * JR[1][b]
                + Ip[2] * JR[2][a] * JR[2][b]
            )
    M[3], M[6], M[7] = M[1], M[2], M[5]
    a0, a1, a2 = rho_ddot
    It = (M[0] * a0 + M[1] * a1 + M[2] * a2, M[3] * a0 + M[4] * a1 + M[5] * a2, M[6] * a0 + M[7] * a1 + M[8] * a2)
    t = (It[0] + c[0] + gt[0], It[1] + c[1] + gt[1], It[2] + c[2] + gt[2])
    return t, It, c, gt, M


def _check3(name: str, v: Sequence[float]) -> list[float]:
    out = [float(x) for x in v]
    if len(out) != 3:
        raise KinematicsError(f"inverse dynamics: {name} must have 3 components, got {len(out)}")
    for k, x in enumerate(out):
        if not math.isfinite(x):
            raise KinematicsError(f"inverse dynamics: {name}_{k + 1} = {x!r} is not finite")
    return out


def _result(fr, out) -> IDPResult:
    t, It, c, gt, M = out
    return IDPResult(
        np.array(t),
        np.array(It),
        np.array(c),
        np.array(gt),
        np.array(M).reshape(3, 3),
        np.array((fr.z, fr.psi, fr.theta)),
        np.array((fr.x, fr.y, fr.phi)),
    )


def inverse_dynamics(
    geom: Geometry,
    masses: Masses,
    rho: Sequence[float],
    rho_dot: Sequence[float],
    rho_ddot: Sequence[float],
    pose_guess: Optional[Sequence[float]] = None,
) -> IDPResult:
    """Actuator forces t_rho [N] for slider heights rho [m], velocities rho_dot [m/s] and
    accelerations rho_ddot [m/s^2] (each (3,)).

    The pose comes from the direct kinematics (warm-started from ``pose_guess`` =
    (z, psi, theta) if given). Raises KinematicsError if the pose cannot be found.
    """
    r = _check3("rho", rho)
    rd = _check3("rho_dot", rho_dot)
    rdd = _check3("rho_ddot", rho_ddot)
    fr = dk_frame(geom, r, pose_guess, 1e-12, 50)
    return _result(fr, _idp(geom, masses, fr, rd, rdd))


def inverse_dynamics_at_pose(
    geom: Geometry, masses: Masses, pose: Sequence[float], rho_dot: Sequence[float], rho_ddot: Sequence[float]
) -> IDPResult:
    """As ``inverse_dynamics`` but at a known pose (z [m], psi [rad], theta [rad]) (no DK);
    for model-based control (computed torque, paper Fig. 3b)."""
    p = _check3("pose", pose)
    fr = first_order(geom, frame_at(geom, *p))
    return _result(fr, _idp(geom, masses, fr, _check3("rho_dot", rho_dot), _check3("rho_ddot", rho_ddot)))
