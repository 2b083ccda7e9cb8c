"""Winding temperature of a DC motor: the two-node thermal network of the motor catalogues.

Nodes: the winding (temperature T_w) and the housing (T_s, stator). Catalogue data: thermal
resistances R_th1 (winding-housing) and R_th2 (housing-ambient) [K/W], time constants tau_w
(winding) and tau_s (motor) [s]; capacities C_w = tau_w / R_th1, C_s = tau_s / R_th2 [J/K]
(reference.md section 9)::

    C_w dT_w/dt = P - (T_w - T_s) / R_th1
    C_s dT_s/dt = (T_w - T_s) / R_th1 - (T_s - T_a) / R_th2
    P = R_25 (1 + alpha_Cu (T_w - 25 degC)) i^2                      copper losses

The current is held over each recorded sample (zero-order hold) and the linear network is
discretised exactly over it, x+ = Phi x + Gamma P with Phi = exp(A h); the loss P is taken at
the sample's start (the winding's time constant is four orders above the 1 ms sample). Every
step is affine in the state, so one pass over a duty cycle is an affine map x -> M x + c: the
cycle repeated without end settles at x* = (I - M)^-1 c (the periodic steady state), and the
warm-up from ambient is the map iterated, cycle by cycle.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
from scipy.linalg import expm

#: the temperature at which the catalogue gives the terminal resistance R_25 [K] (25 degC)
T_REF_K = 298.15


@dataclass(frozen=True)
class TwoNode:
    """The network of one motor. Temperatures in K, resistances in K/W, time constants in s."""

    R_th1: float  # winding-housing [K/W]
    R_th2: float  # housing-ambient [K/W]
    tau_w: float  # winding time constant [s]
    tau_s: float  # motor time constant [s]
    R_25: float  # winding resistance at 25 degC [ohm]
    alpha_Cu: float = 0.0  # temperature coefficient of R [1/K]
    T_ambient: float = T_REF_K  # [K]

    def __post_init__(self) -> None:
        for name in ("R_th1", "R_th2", "tau_w", "tau_s", "R_25"):
            if not getattr(self, name) > 0:
                raise ValueError(f"thermal model: {name} = {getattr(self, name)!r}: expected a positive number")
        if not self.alpha_Cu >= 0:
            raise ValueError(f"thermal model: alpha_Cu = {self.alpha_Cu!r}: expected a number >= 0")

    @property
    def capacities(self) -> tuple[float, float]:
        """(C_w, C_s) [J/K]."""
        return self.tau_w / self.R_th1, self.tau_s / self.R_th2

    def system(self) -> tuple[np.ndarray, np.ndarray]:
        """(A, B) of d/dt [T_w - T_a, T_s - T_a] = A x + B P."""
        C_w, C_s = self.capacities
        g1, g2 = 1.0 / self.R_th1, 1.0 / self.R_th2
        A = np.array([[-g1 / C_w, g1 / C_w], [g1 / C_s, -(g1 + g2) / C_s]])
        return A, np.array([1.0 / C_w, 0.0])

    def discrete(self, h: float) -> tuple[np.ndarray, np.ndarray]:
        """(Phi, Gamma) over a step of h [s], the loss held: the exact ZOH discretisation (kept per model and
        step: the drives of a system share one)."""
        return _zoh(self, h)

    def loss_coefficients(self, i: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(p0, p1) per sample: P = p0 + p1 (T_w - T_a) [W, W/K]: the copper losses, affine in the winding's rise."""
        i2 = np.square(np.asarray(i, dtype=float))
        p0 = self.R_25 * i2 * (1.0 + self.alpha_Cu * (self.T_ambient - T_REF_K))
        return p0, self.R_25 * self.alpha_Cu * i2


@functools.lru_cache(maxsize=16)
def _zoh(model: TwoNode, h: float) -> tuple[np.ndarray, np.ndarray]:
    """``TwoNode.discrete``, cached on (model, h) at module level (a cache on the method would hold every
    instance through ``self``, unbounded by the instance's life)."""
    A, B = model.system()
    block = np.zeros((3, 3))
    block[:2, :2], block[:2, 2] = A * h, B * h
    E = expm(block)
    return E[:2, :2], E[:2, 2]


def _sample_steps(t: np.ndarray) -> float:
    """The (uniform) sample step of ``t`` [s]; ValueError if it is not uniform."""
    if len(t) < 2:
        raise ValueError("thermal model: fewer than two samples")
    steps = np.diff(t)
    h = float(np.median(steps))
    if not h > 0 or np.max(np.abs(steps - h)) > 1e-6 * h + 1e-12:
        raise ValueError(
            f"thermal model: the samples are not evenly spaced (steps {steps.min():.6g} to {steps.max():.6g} s)"
        )
    return h


def run(
    model: TwoNode, t: np.ndarray, i: np.ndarray, start: tuple[float, float] = (0.0, 0.0)
) -> tuple[np.ndarray, np.ndarray]:
    """(T_w, T_s) [K] at the samples ``t`` [s] with the current ``i`` [A] held over each, starting at the
    rises ``start`` [K] above ambient at ``t[0]``."""
    t = np.asarray(t, dtype=float)
    Phi, Gamma = model.discrete(_sample_steps(t))
    (f11, f12), (f21, f22) = Phi.tolist()
    g1, g2 = Gamma.tolist()
    p0, p1 = (p.tolist() for p in model.loss_coefficients(i))
    xw, xs = float(start[0]), float(start[1])
    out_w, out_s = [], []
    for a, b in zip(p0, p1):  # scalar arithmetic: a 2-state step is faster than numpy's small arrays
        out_w.append(xw)
        out_s.append(xs)
        loss = a + b * xw
        xw, xs = f11 * xw + f12 * xs + g1 * loss, f21 * xw + f22 * xs + g2 * loss
    return np.array(out_w) + model.T_ambient, np.array(out_s) + model.T_ambient


def cycle_map(model: TwoNode, t: np.ndarray, i: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(M, c): one pass over the duty cycle (the samples ``t``, each held one step) maps the rises
    x [K] at its start to M x + c at its end."""
    Phi, Gamma = model.discrete(_sample_steps(np.asarray(t, dtype=float)))
    (f11, f12), (f21, f22) = Phi.tolist()
    g1, g2 = Gamma.tolist()
    p0, p1 = (p.tolist() for p in model.loss_coefficients(i))
    m11, m12, m21, m22, c1, c2 = 1.0, 0.0, 0.0, 1.0, 0.0, 0.0
    for a, b in zip(p0, p1):  # the step x -> S x + Gamma a, S = Phi + Gamma b e_w^T, composed
        s11, s21 = f11 + g1 * b, f21 + g2 * b
        m11, m12, m21, m22 = s11 * m11 + f12 * m21, s11 * m12 + f12 * m22, s21 * m11 + f22 * m21, s21 * m12 + f22 * m22
        c1, c2 = s11 * c1 + f12 * c2 + g1 * a, s21 * c1 + f22 * c2 + g2 * a
    return np.array([[m11, m12], [m21, m22]]), np.array([c1, c2])


@dataclass
class Periodic:
    """The duty cycle repeated from ambient until steady state."""

    cycle_s: float  # duration of one cycle [s]
    start: np.ndarray  # rises [K] at the start of a cycle in steady state
    T_w: np.ndarray  # winding temperature over one steady cycle [K]
    T_s: np.ndarray
    warmup_t: np.ndarray  # [s] the starts of the cycles from ambient
    warmup_T_w: np.ndarray  # [K] the winding's temperature at those starts
    cycles_to_settle: int  # cycles until within the tolerance (0.1 K) of the steady state


def periodic(model: TwoNode, t: np.ndarray, i: np.ndarray, tolerance_K: float = 0.1) -> Periodic:
    """The duty cycle ``t``, ``i`` repeated: the steady cycle, and the warm-up from ambient.

    Raises ValueError if the losses grow faster with temperature than the network sheds them
    (thermal runaway: no steady state)."""
    t = np.asarray(t, dtype=float)
    h = _sample_steps(t)
    M, c = cycle_map(model, t, i)
    if max(abs(np.linalg.eigvals(M))) >= 1.0:
        raise ValueError(
            "thermal model: thermal runaway: the copper losses grow with the winding's temperature "
            "faster than the motor sheds them; there is no steady state"
        )
    x_star = np.linalg.solve(np.eye(2) - M, c)
    # from ambient, x_k = x* - M^k x* = x* - V diag(mu^k) V^-1 x*: every cycle's start at once
    mu, V = np.linalg.eig(M)
    weights = np.linalg.solve(V, x_star)
    size = float(np.sum(np.abs(V[0] * weights)))  # bounds |rise_w - x*_w| = |sum mu^k V0 w| by size max|mu|^k
    k_max = 0 if size <= tolerance_K else math.ceil(math.log(tolerance_K / size) / math.log(max(abs(mu)))) + 1
    k = np.arange(k_max + 1)
    rise_w = np.real(x_star[0] - (np.power.outer(mu, k).T * (V[0] * weights)).sum(axis=1))
    settled = np.nonzero(np.abs(rise_w - x_star[0]) <= tolerance_K)[0]
    T_w, T_s = run(model, t, i, tuple(x_star))
    cycle = h * len(t)
    return Periodic(cycle, x_star, T_w, T_s, k * cycle, rise_w + model.T_ambient, int(settled[0]))
