"""One linear axis of the MAST: DC motor + gearbox + belt guide (paper section 2.2, 3.1).

Physics (all mechanical quantities referred to the motor shaft)
----------------------------------------------------------------
Eq. 1        i_R = p / (2 pi i_r)                       [m/rad] carriage metres per motor radian
electrical   L di/dt = u_sat - R i - k_E omega_1,        u_sat = clip(u, -u_supply, u_supply)
motor        tau_m = k_T i                               on the first inertia
chain        J_k domega_k/dt = sum of spring/damper torques of the neighbours
                               (+ tau_m on k = 1) (+ tau_L - b_v omega_N on k = N)
load         tau_L = -i_R F - i_R M_load g_guide - tau_f(omega_N) - tau_ripple sin(2 pi (rho - rho_0) / ripple_period)
                     (mechanism reaction, Eq. 1; carriage weight; guide friction; position ripple)
friction     tau_f(w) = (tau_c + tau_s exp(-(w/omega_s)^2)) tanh(w / omega_c)
                     (guide Coulomb friction, Eq. 23, with an optional Stribeck excess tau_s)
output       rho = rho_0 + i_R theta_N
measurement  tau_meas = tau_offset + LPF_T_meas(tau_m(t - delay_meas))          (sensor.py)

Effects with neutral defaults (the paper has none of them; they exist so that a
diagnosis can name and fit them): tau_s (Stribeck), backlash (a dead zone of width
``backlash`` in the spring K_t, n_dof = 2), tau_ripple (position-periodic guide torque),
T_meas / delay_meas / tau_offset (the torque measurement, output ``tau_meas``). With the
defaults the generated step is the same code as without them.

Transmission, chosen by ``n_dof``:

* 1: rigid, J = J1 + J2;
* 2: the paper's two-inertia model (Eqs. 2-3): J1 = J1_scale (J_motor + J_gearbox +
  J_coupling + J_brake) (Eq. 20 plus the brake, which sits on the motor shaft),
  J2 = J_guide / i_r^2 + M_load i_R^2 (Eqs. 21-22), spring K_t and damper C_t between them;
* N >= 3: the chain J_chain (complete inertias, the first one scaled by J1_scale, the
  carriage included in the last one), K_chain, C_chain.

State x = [i, theta_1..theta_N, omega_1..omega_N], at rest at the start with every spring
undeflected (theta_k = 0), so rho = rho_0.

Integration
-----------
The linear part (electrical pole, chain, viscous friction) is discretised exactly for
zero-order-hold inputs: [Phi Gamma] = expm([[A B], [0 0]] h_s), computed once per distinct
step size and cached. The inputs over a (sub)step are the saturated voltage and the torque
on the last inertia, tau_L - which contains the Coulomb friction. That friction is held
over the substep at its value at the *end* of the substep (implicit, backward-Euler-like in
the friction only): omega_N(end) = a - b tau_f with a, b > 0 known from Phi and Gamma, so
tau_f = tau_c tanh(omega_N(end) / omega_c) is one monotone scalar equation, solved by a
Newton iteration that provably converges monotonically (see ``_friction_source``). The
scheme is unconditionally stable for the dissipative friction: no chatter at standstill
and at velocity reversals even when the smoothed friction is much stiffer than the step
(tau_c / omega_c / J_2 ~ 45,000 1/s with the identified data, i.e. a 22 us time constant
against h = 100 us). Substeps are used only when the step is long against the fastest
chain mode (omega_max h_s <= 2 rad), which keeps b > 0.

Stribeck friction (tau_s > 0) is not monotone in the speed: the same implicit scheme
solves its scalar equation by Newton safeguarded with bisection on a bracket that
always holds the root (and substeps keep the equation monotone). The position ripple
is evaluated at the start of each step and held (like F). Backlash makes the spring
piecewise linear: two exact discretisations (in contact, with the dead-zone offset as an
extra input, and in the gap, without spring and damper) with substeps of at most 10 us,
the mode chosen from the deflection at the start of each substep.

The step is compiled once per step size into straight-line Python (constants inlined):
for a 5-state system scalar code is several times faster than numpy calls. A host that
varies its step brings a new step size at every step, and a compilation (about 1.5 ms)
per step would make the step hundreds of times slower: after the first few step sizes,
the kernel of a new one is the same source with its step-size-dependent numbers as
arguments, compiled once and given the numbers of each step (``_bind``). Those numbers,
exp(M h_s) for any h_s, come from ``_ZohSeries``: exp(M h_s) = exp(M h_r) exp(M d) around
the nearest of a few reference steps h_r (8 per octave, each exponential computed once),
the second factor a Taylor series in d whose coefficients are precomputed, so a new step
size costs one weighted sum of them. benchmarks/variable_step.py measures both routes. Every
exponential, balancing and product here is ``fmus.common.fixed_order``'s (no BLAS or LAPACK: the
same floats on every machine, and the native actuator's, docs/native.md).
"""

from __future__ import annotations

import functools
import math
from typing import Callable, Mapping, Optional, Sequence

import numpy as np

from ..common.block import Block, ModelError
from ..common.codegen import compile_generated, largest_parameters
from ..common.fixed_order import balance, eig_max, expm, matmul
from ..common.parameters import Param, ParameterError, Value, nonnegative, positive
from .sensor import TorqueSensor, is_neutral

__all__ = [
    "ActuatorBlock",
    "transmission_ratio",
    "two_inertia",
    "guide_friction",
    "chain",
    "state_matrices",
    "transfer_functions",
    "natural_frequencies",
    "chain_frequencies",
    "fastest_mode",
]

MAX_PHASE_PER_SUBSTEP = 2.0  # rad: fastest chain mode x substep (keeps the friction equation monotone)
#: rad: the longest exchange step, as the fastest chain mode's phase over it, whose drive force the mechanism's
#: extrapolation follows (docs/coupling.md: stable to 0.75 with the paper's belt); beyond, the drive reports no
#: load-side mass and the mechanism falls back to the explicit exchange
COUPLING_PHASE = 0.6
BACKLASH_SUBSTEP = 1e-5  # s: longest substep with backlash (contact and separation resolved to 10 us)
_KERNELS_KEPT = 32  # step functions kept, by step size
_COMPILED_STEP_SIZES = 4  # a fixed-step host needs one or two; beyond, the host varies its step (see _bind)


def substep_rule(omega_max: float, h: float, backlash: float, tau_s: float, omega_s: float) -> tuple[int, float]:
    """(m, fall) of a step h [s] (``ActuatorBlock._substeps``): the substeps to try first, so that the fastest
    chain mode omega_max [rad/s] turns at most MAX_PHASE_PER_SUBSTEP per substep and, with backlash (> 0 [m]),
    a substep lasts at most BACKLASH_SUBSTEP; and the Stribeck friction's steepest fall tau_s sqrt(2/e) /
    omega_s [N m s/rad] (0 without). Written in the generated-code subset: the native actuator runs this source."""
    m = math.ceil(omega_max * h / MAX_PHASE_PER_SUBSTEP - 1e-12)
    if m < 1:
        m = 1
    if backlash > 0.0:
        mb = math.ceil(h / BACKLASH_SUBSTEP - 1e-9)
        if mb > m:
            m = mb
    fall = tau_s * math.sqrt(2.0 / math.e) / omega_s if tau_s > 0.0 else 0.0
    return (m, fall)


def substeps_enough(b: float, fall: float, m: float) -> float:
    """1.0 when m substeps do: the friction update over a substep (b = d omega_N / d tau_L) monotone, b > 0 and
    b fall < 1/2, or no more are tried (m > 4096); else 0.0. Written in the generated-code subset, as
    ``substep_rule``."""
    return 1.0 if (b > 0.0 and b * fall < 0.5) or m > 4096 else 0.0


PARAMETERS: tuple[Param, ...] = (
    positive("R", "ohm", "winding terminal resistance"),
    positive("L", "H", "winding terminal inductance"),
    positive("k_T", "N.m/A", "torque constant"),
    positive("k_E", "V.s/rad", "back-EMF constant"),
    positive("u_supply", "V", "power stage supply: the voltage command is clipped to +-u_supply"),
    positive("J_motor", "kg.m2", "rotor inertia (Eq. 20)"),
    nonnegative("J_gearbox", "kg.m2", "gearbox inertia referred to the motor shaft (Eq. 20)"),
    nonnegative("J_coupling", "kg.m2", "coupling inertia, added to J1 as in Eq. 20"),
    nonnegative("J_brake", "kg.m2", "brake inertia, on the motor shaft: added to J1"),
    positive("J1_scale", "1", "multiplier on J1 (paper identified set: 1/1.56); scales J_chain[0] when n_dof >= 3"),
    positive("J_guide", "kg.m2", "linear guide inertia at its input shaft (Eq. 21)"),
    nonnegative(
        "M_load",
        "kg",
        "drive carriage mass (Eqs. 21-22); its weight acts on the guide (0: the carriage is a "
        "body of the mechanism, a 3-RPS's leg: docs/designs/3rps.md)",
    ),
    positive("K_t", "N.m/rad", "transmission stiffness, motor side (Eqs. 2-3, Table 1)"),
    nonnegative("C_t", "N.m.s/rad", "transmission damping, motor side (Eqs. 2-3, Table 1)"),
    nonnegative("tau_c", "N.m", "guide Coulomb friction referred to the motor shaft (Eq. 23)"),
    positive("omega_c", "rad/s", "friction smoothing speed at the motor shaft: tau_c tanh(omega/omega_c)"),
    nonnegative("b_v", "N.m.s/rad", "viscous friction on the guide side, motor shaft"),
    nonnegative(
        "tau_s", "N.m", "Stribeck: static friction excess over tau_c at standstill, motor shaft (0: no Stribeck effect)"
    ),
    positive("omega_s", "rad/s", "Stribeck speed at the motor shaft: the excess decays as exp(-(omega/omega_s)^2)"),
    nonnegative(
        "backlash",
        "rad",
        "total dead zone of the transmission spring K_t at the motor shaft (n_dof = 2 only; 0: no backlash)",
    ),
    nonnegative(
        "tau_ripple",
        "N.m",
        "amplitude of a position-periodic guide torque (belt tooth mesh, cogging) "
        "at the motor shaft: tau_ripple sin(2 pi (rho - rho_0) / ripple_period); 0: none",
    ),
    positive("ripple_period", "m", "carriage travel per period of the guide torque ripple"),
    nonnegative("T_meas", "s", "torque measurement: first-order low-pass time constant (output tau_meas)"),
    nonnegative("delay_meas", "s", "torque measurement: pure delay (output tau_meas)"),
    Param("tau_offset", "N.m", "torque measurement: constant offset (output tau_meas)"),
    Param("g_guide", "m/s2", "gravity along the guide (positive: pulls the carriage to lower rho)"),
    Param("rho_0", "m", "initial carriage position, rho_min < rho_0 < rho_max"),
    Param("rho_min", "m", "lower end of the stroke"),
    Param("rho_max", "m", "upper end of the stroke"),
    Param("n_dof", "", "transmission model: 1 rigid, 2 two-inertia (Eqs. 2-3), N >= 3 chain", 1, 64, kind=int),
    Param(
        "J_chain",
        "kg.m2",
        "n_dof >= 3: N inertias, motor side first, referred to the motor shaft, "
        "carriage included in the last, space separated",
        kind=str,
    ),
    Param("K_chain", "N.m/rad", "n_dof >= 3: N-1 stiffnesses referred to the motor shaft, space separated", kind=str),
    Param("C_chain", "N.m.s/rad", "n_dof >= 3: N-1 dampings referred to the motor shaft, space separated", kind=str),
    positive("i_r", "1", "gearbox ratio (Eq. 1)"),
    positive("p", "m", "guide feed per revolution of its input shaft (Eq. 1)"),
)


# --------------------------------------------------------------------------------------
# Paper relations: plain functions of a parameter mapping (validated or straight from .ssv)
# --------------------------------------------------------------------------------------
def transmission_ratio(p: float, i_r: float) -> float:
    """Eq. 1: i_R = p / (2 pi i_r) [m/rad], carriage travel per motor radian.

    ``p`` [m] guide feed per revolution, ``i_r`` [1] gearbox ratio: numbers (or traced numbers: the
    native generators translate this function and trace it).
    """
    return p / (2.0 * math.pi * i_r)


def real_or_traced(x):
    """A parameter value as a float; a traced number (the native generator's, ``mast build --native``)
    passes through, so the relations below also write the C that computes them from the parameters."""
    return float(x) if isinstance(x, (int, float, str, np.number)) else x


def two_inertia(params: Mapping[str, Value]) -> tuple[float, float]:
    """Eqs. 20-22: (J1, J2) [kg m^2] referred to the motor shaft.

    J1 = J1_scale (J_motor + J_gearbox + J_coupling + J_brake) (Eq. 20 plus the brake),
    J2 = J_guide / i_r^2 + M_load i_R^2.
    """
    f = {
        k: real_or_traced(params[k])
        for k in ("J_motor", "J_gearbox", "J_coupling", "J_brake", "J1_scale", "J_guide", "M_load", "i_r", "p")
    }
    i_R = transmission_ratio(f["p"], f["i_r"])
    J1 = f["J1_scale"] * (f["J_motor"] + f["J_gearbox"] + f["J_coupling"] + f["J_brake"])
    J2 = f["J_guide"] / (f["i_r"] * f["i_r"]) + f["M_load"] * (i_R * i_R)  # x * x: the same float as x ** 2
    return J1, J2


def guide_friction(omega: float, tau_c: float, omega_c: float, tau_s: float = 0.0, omega_s: float = 1.0) -> float:
    """Guide friction torque at the motor shaft [N m] at motor speed ``omega`` [rad/s] (module docstring):
    (tau_c + tau_s exp(-(omega/omega_s)^2)) tanh(omega/omega_c); tau_c, tau_s [N m], omega_c, omega_s [rad/s]."""
    excess = tau_s * math.exp(-((omega / omega_s) ** 2)) if tau_s else 0.0
    return (tau_c + excess) * math.tanh(omega / omega_c)


def _parse_list(params: Mapping[str, Value], name: str, count: int, positive: bool) -> list[float]:
    text = str(params[name]).replace(",", " ").split()
    what = "> 0" if positive else ">= 0"
    if len(text) != count:
        raise ParameterError(
            f"parameter '{name}' = {params[name]!r}: expected {count} space separated "
            f"numbers {what} for n_dof = {params['n_dof']}, got {len(text)}"
        )
    values = []
    for item in text:
        try:
            v = float(item)
        except ValueError:
            v = math.nan
        if not math.isfinite(v) or (v <= 0.0 if positive else v < 0.0):
            raise ParameterError(f"parameter '{name}' = {params[name]!r}: item {item!r} is not a finite number {what}")
        values.append(v)
    return values


def chain(
    params: Mapping[str, Value], lists: Optional[Mapping[str, Sequence]] = None
) -> tuple[list[float], list[float], list[float]]:
    """The lumped chain selected by ``n_dof``: (J [kg m^2], K [N m/rad], C [N m s/rad]).

    All referred to the motor shaft, motor side first, guide side last; len(J) = n_dof
    and len(K) = len(C) = n_dof - 1. ``lists``: J_chain, K_chain, C_chain as numbers (n_dof >= 3;
    traced numbers for the native generator), by default parsed from the parameters' text.
    """
    n = int(params["n_dof"])
    if n == 1:
        J1, J2 = two_inertia(params)
        return [J1 + J2], [], []
    if n == 2:
        J1, J2 = two_inertia(params)
        return [J1, J2], [real_or_traced(params["K_t"])], [real_or_traced(params["C_t"])]
    if lists is None:
        lists = {
            "J_chain": _parse_list(params, "J_chain", n, True),
            "K_chain": _parse_list(params, "K_chain", n - 1, True),
            "C_chain": _parse_list(params, "C_chain", n - 1, False),
        }
    J = list(lists["J_chain"])
    J[0] *= real_or_traced(params["J1_scale"])
    return J, list(lists["K_chain"]), list(lists["C_chain"])


def state_matrices(
    params: Mapping[str, Value], lumped: Optional[tuple[Sequence, Sequence, Sequence]] = None
) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """Linear part of the model: dx/dt = A x + B [u_sat, tau_L]^T.

    x = [i, theta_1..theta_N, omega_1..omega_N] (A, rad, rad/s); u_sat [V]; tau_L [N m] the
    torque on the last inertia (mechanism, weight, Coulomb friction; viscous b_v is in A).
    ``lumped``: the chain (J, K, C), by default ``chain(params)``. Returns (A, B, state names).
    """
    J, K, C = chain(params) if lumped is None else lumped
    n = len(J)
    R, L, k_T, k_E, b_v = (real_or_traced(params[k]) for k in ("R", "L", "k_T", "k_E", "b_v"))
    size = 2 * n + 1
    numbers = all(isinstance(v, float) for v in (*J, *K, *C, R, L, k_T, k_E, b_v))
    A = np.zeros((size, size), dtype=float if numbers else object)  # object: traced numbers (native generator)
    B = np.zeros((size, 2), dtype=A.dtype)
    th = lambda k: 1 + k  # noqa: E731  (index helpers)
    om = lambda k: 1 + n + k  # noqa: E731
    A[0, 0] = -R / L
    A[0, om(0)] = -k_E / L
    B[0, 0] = 1.0 / L
    for k in range(n):
        A[th(k), om(k)] = 1.0
    A[om(0), 0] = k_T / J[0]
    for k in range(n - 1):  # spring/damper k between inertias k and k+1
        for a, b in ((k, k + 1), (k + 1, k)):
            A[om(a), th(a)] -= K[k] / J[a]
            A[om(a), th(b)] += K[k] / J[a]
            A[om(a), om(a)] -= C[k] / J[a]
            A[om(a), om(b)] += C[k] / J[a]
    A[om(n - 1), om(n - 1)] -= b_v / J[n - 1]
    B[om(n - 1), 1] = 1.0 / J[n - 1]
    names = ["i"] + [f"theta_{k + 1}" for k in range(n)] + [f"omega_{k + 1}" for k in range(n)]
    return A, B, names


def transfer_functions(params: Mapping[str, Value]) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Eqs. 2-3 of the paper as (numerator, denominator) coefficients, highest power first.

    TF1 = theta_m / tau_m, TF2 = theta_rho_m / theta_m, TF1d = theta_rho_d / tau_d,
    TF2d = theta_d / theta_rho_d [rad/(N m) or rad/rad], with J1, J2 from Eqs. 20-22
    and k_t = K_t, c_t = C_t (always the two-inertia model, whatever n_dof).
    """
    J1, J2 = two_inertia(params)
    k, c = float(params["K_t"]), float(params["C_t"])
    den = np.array([J1 * J2, (J1 + J2) * c, (J1 + J2) * k, 0.0, 0.0])
    return {
        "TF1": (np.array([J2, c, k]), den),
        "TF2": (np.array([c, k]), np.array([J2, c, k])),
        "TF1d": (np.array([J1, c, k]), den.copy()),
        "TF2d": (np.array([c, k]), np.array([J1, c, k])),
    }


def natural_frequencies(params: Mapping[str, Value]) -> dict[str, float]:
    """Undamped natural frequencies [Hz] of the two-inertia model (Eqs. 2-3).

    ``TF1`` (= ``TF1d``): poles, the free-free mode sqrt(K_t (J1 + J2) / (J1 J2));
    ``TF2``: sqrt(K_t / J2), guide side on a spring with the motor held (TF1's antiresonance);
    ``TF2d``: sqrt(K_t / J1), motor side with the guide held (TF1d's antiresonance).
    """
    J1, J2 = two_inertia(params)
    k = float(params["K_t"])
    two_pi = 2.0 * math.pi
    f1 = math.sqrt(k * (J1 + J2) / (J1 * J2)) / two_pi
    return {"TF1": f1, "TF1d": f1, "TF2": math.sqrt(k / J2) / two_pi, "TF2d": math.sqrt(k / J1) / two_pi}


def chain_frequencies(J: Sequence[float], K: Sequence[float]) -> np.ndarray:
    """Undamped free-free natural frequencies [Hz] of a chain (rigid-body mode left out)."""
    n = len(J)
    if n < 2:
        return np.zeros(0)
    Kmat = np.zeros((n, n))
    for k, stiff in enumerate(K):
        Kmat[k, k] += stiff
        Kmat[k + 1, k + 1] += stiff
        Kmat[k, k + 1] -= stiff
        Kmat[k + 1, k] -= stiff
    s = 1.0 / np.sqrt(np.asarray(J, dtype=float))
    lam = np.linalg.eigvalsh(s[:, None] * Kmat * s[None, :])
    return np.sqrt(np.clip(np.sort(lam)[1:], 0.0, None)) / (2.0 * math.pi)


def fastest_mode(J: Sequence[float], K: Sequence[float]) -> float:
    """2 pi times ``chain_frequencies(J, K).max()`` [rad/s] (0 for a rigid chain), in a fixed order of operations
    (``fixed_order.eig_max``, no LAPACK): the substep rule's omega_max, the same float as the native actuator's."""
    n = len(J)
    if n < 2:
        return 0.0
    S = [[0.0] * n for _ in range(n)]
    for k, stiff in enumerate(K):
        S[k][k] += stiff
        S[k + 1][k + 1] += stiff
        S[k][k + 1] -= stiff
        S[k + 1][k] -= stiff
    for i in range(n):
        for j in range(n):
            S[i][j] *= (1.0 / math.sqrt(J[i])) * (1.0 / math.sqrt(J[j]))
    lam = eig_max(S)
    return 2.0 * math.pi * (math.sqrt(lam if lam > 0.0 else 0.0) / (2.0 * math.pi))


# --------------------------------------------------------------------------------------
# The block
# --------------------------------------------------------------------------------------
def input_index(code: int) -> int:
    """The position among the values of the input a kernel's failure ``code`` names (``INPUT_ERRORS``)."""
    return 2 if code == 5 else code - 1


def carried_ok(mass: float) -> bool:
    """Whether ``mass`` [kg] may be carried on a load side: finite and >= 0 (a negative mass would make the
    implicit step's divisor 1 + kappa reach 0)."""
    return math.isfinite(mass) and mass >= 0.0


#: the kernel's failure codes of its inputs, by the input's name (3: diverged, 4: out of the stroke)
INPUT_ERRORS = {1: "u", 2: "F", 5: "M_carried"}


class ActuatorBlock(Block):
    """One MAST linear axis: DC motor, gearbox, flexible transmission and belt guide."""

    INPUTS = ("u", "F", "M_carried")
    OUTPUTS = (
        "rho",
        "rho_dot",
        "rho_ddot",
        "theta_m",
        "omega_m",
        "i_m",
        "tau_m",
        "tau_meas",
        "F_drive",
        "F_drive_dot",
        "F_drive_ddot",
        "m_drive",
    )
    #: where tau_m, tau_meas and m_drive stand among the values (inputs, then outputs)
    TAU_M, TAU_MEAS, M_DRIVE = 9, 10, 14
    PARAMETERS = PARAMETERS
    UNITS = {
        "u": "V",
        "F": "N",
        "M_carried": "kg",
        "F_drive": "N",
        "F_drive_dot": "N/s",
        "F_drive_ddot": "N/s2",
        "m_drive": "kg",
        "rho": "m",
        "rho_dot": "m/s",
        "rho_ddot": "m/s2",
        "theta_m": "rad",
        "omega_m": "rad/s",
        "i_m": "A",
        "tau_m": "N.m",
        "tau_meas": "N.m",
    }
    DESCRIPTIONS = {
        "u": "voltage command from the controller (clipped to +-u_supply)",
        "F": "force this actuator applies to the mechanism along its guide, positive upward, beyond M_carried "
        "rho_ddot (with M_carried = 0: the whole force)",
        "M_carried": "mass of the mechanism this actuator carries on its load side: the force on the mechanism is "
        "F + M_carried rho_ddot (the mechanism's condensed interface, docs/coupling.md; 0: none)",
        "F_drive": "force of the drive on its load side (transmission, weight, guide friction: all but the load "
        "side's inertia and the mechanism), at the end of the step",
        "F_drive_dot": "time derivative of F_drive along the model, its inputs held",
        "F_drive_ddot": "second time derivative of F_drive along the model, its inputs held",
        "m_drive": "load-side mass F_drive accelerates (n_dof = 1: the whole drive reflected to the guide; else "
        "its last inertia)",
        "rho": "carriage position along the guide",
        "rho_dot": "carriage velocity",
        "rho_ddot": "carriage acceleration at the end of the step",
        "theta_m": "motor angle (0 at the start)",
        "omega_m": "motor speed",
        "i_m": "motor current",
        "tau_m": "motor torque k_T i_m",
        "tau_meas": "measured motor torque: tau_m through the measurement model (T_meas, delay_meas, tau_offset)",
    }

    def __init__(self, params: Mapping[str, Value], name: str = "") -> None:
        super().__init__(params, name)
        p = self.params
        if not p["rho_min"] < p["rho_max"]:
            raise ParameterError(
                f"{self.name}: parameter 'rho_max' = {p['rho_max']!r}: expected a value above "
                f"rho_min = {p['rho_min']!r} m"
            )
        if not p["rho_min"] < p["rho_0"] < p["rho_max"]:
            raise ParameterError(
                f"{self.name}: parameter 'rho_0' = {p['rho_0']!r}: expected a position inside "
                f"the stroke ({p['rho_min']!r}, {p['rho_max']!r}) m"
            )
        try:
            self.J, self.K, self.C = chain(p)
        except ParameterError as err:
            raise ParameterError(f"{self.name}: {err}") from None
        self.N = len(self.J)
        self.i_R = transmission_ratio(p["p"], p["i_r"])
        self.A, self.B, self.state_names = state_matrices(p)
        self.constants = kernel_constants(p, self.i_R, self.A, self.B, self.J, self.K, self.C)
        self._omega_max = fastest_mode(self.J, self.K)
        if p["backlash"] > 0.0 and self.N != 2:
            raise ParameterError(
                f"{self.name}: parameter 'backlash' = {p['backlash']!r}: backlash is modelled "
                f"in the two-inertia transmission only (n_dof = 2, here {self.N})"
            )
        self._sensor = (
            None
            if is_neutral(p["T_meas"], p["delay_meas"], p["tau_offset"])
            else TorqueSensor(p["T_meas"], p["delay_meas"], p["tau_offset"])
        )
        self._kernels: dict[float, tuple[Callable, int]] = {}
        self._ticks: dict[float, Callable] = {}  # the drive's loop over steps of h (``ticks``), by h
        self._ticks_h, self._ticks_fn = math.nan, None  # the last h asked and its loop
        self._compiled = 0  # step sizes compiled with their numbers inlined
        self._bound: Optional[Callable] = None  # the kernel that takes its step size's numbers first
        self._series: Optional[list["_ZohSeries"]] = None  # exp(M h)[:n] for any h, per generator
        self._h = math.nan
        self._kernel: Callable = _no_kernel
        self.substeps = 0
        self._x: list[float] = [0.0] * (2 * self.N + 1)

    # -- life cycle ------------------------------------------------------------------
    def initialize(self, t0: float) -> None:
        """(Re)start from the initial state (rest, i = 0, springs undeflected, rho = rho_0), check the inputs
        and write the outputs of rest (``_write_outputs``)."""
        self._x = [0.0] * (2 * self.N + 1)
        for code in INPUT_ERRORS:
            value = self.values[input_index(code)]
            if not (carried_ok(value) if code == 5 else math.isfinite(value)):
                self.fail(code, t0, 0.0)
        self._write_outputs()

    def do_step(self, t: float, h: float) -> None:
        """Advance from t to t + h [s] with u [V] and F [N] held (zero-order hold)."""
        if h != self._h:
            self._select(h)
        code = self._kernel(self.values, self._x)
        if code:
            self.fail(code, t, h)
        if self._sensor is not None:
            values = self.values
            values[self.TAU_MEAS] = self._sensor.step(values[self.TAU_M], h)
        if not self.condenses(h):
            self.values[self.M_DRIVE] = 0.0

    def condenses(self, h: float) -> bool:
        """Whether the mechanism may condense this drive at an exchange step of ``h`` [s]: its fastest chain mode
        turns at most ``COUPLING_PHASE`` over the step (a rigid drive always)."""
        return self._omega_max * h <= COUPLING_PHASE

    def stepper(self, h: float) -> tuple[Callable, list, Optional[TorqueSensor]]:
        """What ``do_step(t, h)`` runs, for a caller that steps by h many times in a row (the drive's
        current loop): (kernel, x, sensor). ``kernel(values, x)`` advances the state ``x`` in place over h
        and writes the outputs into ``values``, returning 0 or a failure code for ``fail(code, t, h)``;
        then, unless ``sensor`` is None, ``values[TAU_MEAS] = sensor.step(values[TAU_M], h)``. Valid until the next
        ``initialize``, ``set_state`` or step of another size."""
        if h != self._h:
            self._select(h)
        return self._kernel, self._x, self._sensor

    def ticks(self, h: float, pi_step: Callable) -> Optional[Callable]:
        """The drive's current loop and this axis over several steps of h in one generated function
        (``_ticks_source``; ``pi_step``: the drive's PI), or None where the drive steps the axis tick by tick
        (backlash, a torque sensor). The same discretisation as ``do_step(t, h)``'s, compiled once per h."""
        if h == self._ticks_h:
            return self._ticks_fn
        if self.params["backlash"] > 0.0 or self._sensor is not None:
            return None
        key = float(f"{h:.12g}")
        found = self._ticks.get(key)
        if found is None:
            n = 2 * self.N + 1
            first = self._generators()[0]
            m, (E,) = self._substeps(key, lambda h_sub: [expm(first * h_sub)[:n].ravel()])
            E = E.reshape(n, -1)
            namespace: dict = {"tanh": math.tanh, "exp": math.exp, "sin": math.sin, "pi_step": pi_step}
            found = self._ticks[key] = compile_generated(
                _ticks_source(self, E[:, :n], E[:, n : n + 2], m, key / m),
                "ticks",
                f"{self.name}: drive ticks h={key!r} m={m}",
                namespace,
                largest_parameters(self.params),
            )
        self._ticks_h, self._ticks_fn = h, found
        return found

    # -- helpers ---------------------------------------------------------------------
    def state(self) -> dict[str, float]:
        """Current state by name: i [A], theta_k [rad], omega_k [rad/s] (k = 1 motor .. N guide)."""
        return dict(zip(self.state_names, self._x))

    def _write_outputs(self) -> None:
        """The outputs of the state at rest (``initialize``): the acceleration 0 until the first step, from which on
        the inputs act. So the initial point follows from the parameters alone: no algebraic loop with the
        mechanism's forces (which follow the accelerations), and every host reaches the same initial point
        whatever its initialisation passes (docs/interfaces.md, Timing)."""
        p, x, N = self.params, self._x, self.N
        w, alpha = x[2 * N], 0.0
        n_in = len(self.INPUTS)
        tau_m = p["k_T"] * x[0]
        tau_meas = tau_m if self._sensor is None else self._sensor.reset(tau_m)
        self.values[n_in:] = [
            p["rho_0"] + self.i_R * x[N],
            self.i_R * w,
            self.i_R * alpha,
            x[1],
            x[N + 1],
            x[0],
            tau_m,
            tau_meas,
            -p["M_load"] * p["g_guide"],  # the drive force at rest: the carriage's weight alone
            0.0,
            0.0,
            float(self.constants["md"]),
        ]

    def fail(self, code: int, t: float, h: float) -> None:
        """Raise the ModelError of the kernel's failure ``code`` in the step from t over h [s]."""
        if code in INPUT_ERRORS:
            name, value = INPUT_ERRORS[code], self.values[input_index(code)]
            what = "a finite mass >= 0 kg" if code == 5 else "finite"
            raise ModelError(f"{self.name}: input '{name}' = {value} at t={t:.9g} s is not {what}")
        if code == 3:
            raise ModelError(f"{self.name}: diverged at t={t + h:.9g} s (non-finite state)")
        p = self.params
        rho = p["rho_0"] + self.i_R * self._x[self.N]
        raise ModelError(
            f"{self.name}: carriage left the stroke [{p['rho_min']:g}, {p['rho_max']:g}] m: "
            f"rho = {rho:.6g} m at t={t + h:.9g} s"
        )

    def _select(self, h: float) -> None:
        if not (h > 0.0 and math.isfinite(h)):
            raise ModelError(f"{self.name}: step size h = {h!r} s: expected a finite positive number")
        key = float(f"{h:.12g}")
        entry = self._kernels.get(key)
        if entry is None:
            if len(self._kernels) >= _KERNELS_KEPT:
                self._kernels.pop(next(iter(self._kernels)))
            if self._compiled < _COMPILED_STEP_SIZES:
                self._compiled += 1
                entry = self._compile(key)
            else:  # the host varies its step: no compilation per step size
                entry = self._bind(key)
            self._kernels[key] = entry
        self._kernel, self.substeps = entry
        self._h = h

    def generator(self) -> np.ndarray:
        """M = [[A B], [0 0]]: exp(M h)[:n] = [Phi Gamma], the exact ZOH discretisation over h."""
        n = self.A.shape[0]
        M = np.zeros((n + 2, n + 2))
        M[:n, :n] = self.A
        M[:n, n:] = self.B
        return M

    def _generators(self) -> tuple[np.ndarray, ...]:
        """The generators of the step's discretisations: ``generator()``, or with backlash the contact and
        gap ones (``_backlash_generators``)."""
        return _backlash_generators(self) if self.params["backlash"] > 0.0 else (self.generator(),)

    def discretise(self, h_sub: float, exponential: Callable = expm) -> tuple[np.ndarray, np.ndarray]:
        """Exact ZOH discretisation over h_sub [s]: (Phi, Gamma) with x+ = Phi x + Gamma [u_sat, tau_L]."""
        n = self.A.shape[0]
        E = exponential(self.generator() * h_sub)
        return E[:n, :n], E[:n, n:]

    def _substeps(self, h: float, zoh: Callable[[float], list]) -> tuple[int, list]:
        """The number of substeps m for step h, and ``zoh(h / m)``: the discretisations over a substep
        ([Phi Gamma] of each, flattened by rows; the first one's inputs start with u_sat, tau_L)."""
        p = self.params
        m, fall = substep_rule(self._omega_max, h, p["backlash"], p["tau_s"], p["omega_s"])
        n = 2 * self.N + 1
        b_at = 2 * self.N * (n + 2 + (p["backlash"] > 0.0)) + n + 1  # Gamma[omega_N, tau_L]: [Phi Gamma] has n + 2
        while True:  # columns, n + 3 with backlash's input pl
            discretisations = zoh(h / m)
            b = discretisations[0][b_at]  # d omega_N(end) / d tau_L over a substep
            if substeps_enough(b, fall, m):
                break
            m *= 2
        if not b > 0.0:
            raise ModelError(f"{self.name}: no substep gives a monotone friction update for h = {h} s")
        return m, discretisations

    def _compile(self, h: float) -> tuple[Callable, int]:
        """Generate the step function for step h: straight-line scalar code, constants inlined."""
        n = 2 * self.N + 1
        first = self._generators()[0]
        m, (E,) = self._substeps(h, lambda h_sub: [expm(first * h_sub)[:n].ravel()])
        E = E.reshape(n, -1)
        Phi, Gam = E[:, :n], E[:, n : n + 2]
        if self.params["backlash"] > 0.0:
            source = backlash_kernel_source(self, h / m, m)
        else:
            source = kernel_source(self, Phi, Gam, m, h_sub=h / m)
        namespace: dict = {"tanh": math.tanh, "exp": math.exp, "sin": math.sin}
        kernel = compile_generated(
            source, "kernel", f"{self.name}: actuator kernel h={h!r} m={m}", namespace, largest_parameters(self.params)
        )
        return kernel, m

    def _bind(self, h: float) -> tuple[Callable, int]:
        """The step function for step h without compiling: one kernel, whose source has the
        step-size-dependent numbers (and the number of substeps) as names, compiled once and called
        with this step's numbers (the same arithmetic as ``_compile``'s kernel, each number read by
        name, not inlined); the discretisations from ``_ZohSeries``, no exponential per step."""
        p, n = self.params, 2 * self.N + 1
        backlash = p["backlash"] > 0.0
        if self._series is None:
            self._series = [_ZohSeries(M, n) for M in self._generators()]
        m, discretisations = self._substeps(h, lambda h_sub: [s(h_sub) for s in self._series])
        numbers = []
        cols = [len(E) // n for E in discretisations]  # [Phi Gamma]: n + 2 columns, n + 3 with backlash
        for E in discretisations:
            numbers += E.tolist()
        for E, c in zip(discretisations, cols):  # the friction solve of each: d omega_N(end) / d tau_L
            numbers += friction_constants(p, float(E[2 * self.N * c + n + 1])).values()
        numbers += [h / m, m]
        if self._bound is None:
            names = []
            for prefix, c in zip(("PC", "PG") if backlash else ("P",), cols):
                rows = name_grid(prefix, (n, c))  # P_i_j for Phi; Gamma's columns renamed G_i_k below
                rows[:, n:] = name_grid("G" + prefix[1:], (n, c - n))
                names += rows.ravel().tolist()
            for prefix in ("FC_", "FG_") if backlash else ("F_",):
                names += [prefix + k for k in friction_constants(p, 1.0)]
            names += ["H_SUB", "M_SUB"]
            if backlash:
                source = backlash_kernel_source(self, h / m, m, named=True)
            else:
                source = kernel_source(self, name_grid("P", (n, n)), name_grid("G", (n, 2)), m, named=True)
            source = source.replace(
                "def kernel(values, x):\n", f"def kernel(c, values, x):\n    {', '.join(names)}, = c\n", 1
            )
            namespace: dict = {"tanh": math.tanh, "exp": math.exp, "sin": math.sin}
            exec(compile(source, "<actuator kernel bound per step size>", "exec"), namespace)
            self._bound = namespace["kernel"]
        return functools.partial(self._bound, numbers), m


class _ZohSeries:
    """exp(M h)[:rows], flattened, for any step h [s], exact to rounding, without an exponential per step.

    exp(M h) = exp(M h_r) exp(M d), h_r the nearest of the reference steps (h rounded to 4 bits of
    mantissa: 8 per octave, |d| <= h / 16), exp(M d) its Taylor series. Per reference, computed once:
    exp(M h_r)[:rows] by ``fixed_order.expm`` and the series' coefficients C_k = exp(M h_r)[:rows] (M s)^k / k!
    (s = the largest |d| there), to the degree where the remainder is below 2^-60 in M's balanced norm
    (M's entries mix radians, rad/s and amperes: the norm of D^-1 M D, D from ``fixed_order.balance``, bounds
    the series). A step size is then the sum of the coefficients weighted by [1, d/s, (d/s)^2, ...], in that
    order (no BLAS: the same floats on every machine, ``fmus.common.fixed_order``).
    """

    REMAINDER = 2.0**-60
    KEPT = 256  # reference steps kept

    def __init__(self, M: np.ndarray, rows: int) -> None:
        self._M, self._rows = M, rows
        d = balance(M)
        self._norm = float(np.abs(M * (d[None, :] / d[:, None])).sum(axis=0).max())
        self._references: dict[float, tuple[float, np.ndarray, np.ndarray]] = {}

    def __call__(self, h: float) -> np.ndarray:
        mantissa, exponent = math.frexp(h)
        h_r = math.ldexp(round(mantissa * 16.0) / 16.0, exponent)
        reference = self._references.get(h_r)
        if reference is None:
            if len(self._references) >= self.KEPT:
                self._references.pop(next(iter(self._references)))
            reference = self._references[h_r] = self._expand(h_r, math.ldexp(1.0, exponent - 5))
        s, degree, C = reference
        if C is None:  # M s too large for a short series: the exponential itself
            return expm(self._M * h)[: self._rows].ravel()
        x, weights = (h - h_r) / s, [1.0]
        for _ in range(degree):
            weights.append(weights[-1] * x)
        return (np.array(weights)[:, None] * C).sum(axis=0)

    def _expand(self, h_r: float, s: float) -> tuple[float, int, Optional[np.ndarray]]:
        nu = self._norm * s  # the series' terms fall at least as nu^k / k!
        if nu > 1.0:
            return s, 0, None
        degree, bound = 1, nu * nu / 2.0
        while bound > self.REMAINDER:
            degree += 1
            bound *= nu / (degree + 1)
        X = self._M * s
        term = expm(self._M * h_r)[: self._rows] if h_r > 0.0 else np.eye(len(X))[: self._rows]
        terms = [term]
        for k in range(1, degree + 1):
            term = matmul(term, X) / k
            terms.append(term)
        return s, degree, np.array([t.ravel() for t in terms])


def name_grid(prefix: str, shape: tuple[int, int]) -> np.ndarray:
    """A matrix of constant names, ``prefix_i_j``, for a kernel source bound per step size."""
    out = np.empty(shape, dtype=object)
    for i, j in np.ndindex(shape):
        out[i, j] = f"{prefix}_{i}_{j}"
    return out


def _no_kernel(values: list, x: list) -> int:  # pragma: no cover - replaced before use
    raise ModelError("do_step before a step size was selected")


def _lin(coefs: Sequence, names: Sequence[str]) -> str:
    """sum(c v): a number is inlined (a zero left out), a string is the name of a constant bound later."""
    terms = [
        f"{c}*{v}" if isinstance(c, str) else f"{float(c)!r}*{v}"
        for c, v in zip(coefs, names)
        if isinstance(c, str) or c != 0.0
    ]
    return " + ".join(terms) if terms else "0.0"


def _friction_source(c: Mapping[str, str], indent: str) -> list[str]:
    """Implicit Coulomb friction over one substep.

    With the friction torque tau_f held over the substep, the end velocity of the last
    inertia is v = a - b tau_f (a: everything else, b > 0). Requiring tau_f = tau_c
    tanh(v / omega_c) gives f(v) = v - a + b tau_c tanh(v / omega_c) = 0, increasing in v
    and, for v of the sign of a, concave (a > 0) or convex (a < 0). Newton started at
    v0 = max(a - b tau_c, a / (1 + k)), k = b tau_c / omega_c (a > 0; mirrored for a < 0),
    where f(v0) <= 0 (tanh(s) <= s for s >= 0), then climbs monotonically to the root:
    no overshoot, whatever the friction stiffness.
    tau_f = (a - v) / b is then exactly consistent with v and bounded by tau_c.
    ``c``: the constants of ``friction_constants`` as text (numbers, or names bound later).
    """
    btc, k, inv_wc, inv_b, lin, tol = c["btc"], c["k"], c["inv_wc"], c["inv_b"], c["lin"], c["tol"]
    i = indent
    return [
        f"{i}if a > 0.0:",
        f"{i}    v = a - {btc}",
        f"{i}    v0 = a*{lin}",
        f"{i}    if v0 > v: v = v0",
        f"{i}    for _ in range(60):",
        f"{i}        th = tanh(v*{inv_wc})",
        f"{i}        dv = (a - v - {btc}*th) / (1.0 + {k}*(1.0 - th*th))",
        f"{i}        v += dv",
        f"{i}        if dv < {tol}: break",
        f"{i}elif a < 0.0:",
        f"{i}    v = a + {btc}",
        f"{i}    v0 = a*{lin}",
        f"{i}    if v0 < v: v = v0",
        f"{i}    for _ in range(60):",
        f"{i}        th = tanh(v*{inv_wc})",
        f"{i}        dv = (a - v - {btc}*th) / (1.0 + {k}*(1.0 - th*th))",
        f"{i}        v += dv",
        f"{i}        if dv > -{tol}: break",
        f"{i}else:",
        f"{i}    v = 0.0",
        f"{i}tf = (a - v)*{inv_b}",
    ]


def _stribeck_source(c: Mapping[str, str], indent: str) -> list[str]:
    """Implicit friction with a Stribeck excess over one substep (same idea as ``_friction_source``).

    tau_f(v) = (tau_c + tau_s exp(-(v/omega_s)^2)) tanh(v/omega_c) is not monotone, so the
    root of f(v) = v - a + b tau_f(v) is bracketed: for a > 0 it lies in
    [max(0, a - b (tau_c + tau_s)), a] (f <= 0 at the left end, f >= 0 at the right end);
    Newton steps that leave the bracket are replaced by bisection. The substep keeps
    b tau_s sqrt(2/e) / omega_s < 1/2, so f is increasing and the root unique.
    """
    i = indent
    b, bt, iwc, iws2, tol, tau_c, tau_s = c["b"], c["bt"], c["iwc"], c["iws2"], c["tol"], c["tau_c"], c["tau_s"]
    return [
        f"{i}if a != 0.0:",
        f"{i}    sg = 1.0 if a > 0.0 else -1.0",
        f"{i}    aa = a*sg",
        f"{i}    lo = aa - {bt}",
        f"{i}    if lo < 0.0: lo = 0.0",
        f"{i}    hi = aa",
        f"{i}    v = lo",
        f"{i}    for _ in range(200):",
        f"{i}        th = tanh(v*{iwc})",
        f"{i}        ex = {tau_s}*exp(-v*v*{iws2})",
        f"{i}        gl = {tau_c} + ex",
        f"{i}        fv = v - aa + {b}*gl*th",
        f"{i}        if fv > 0.0: hi = v",
        f"{i}        else: lo = v",
        f"{i}        df = 1.0 + {b}*(gl*(1.0 - th*th)*{iwc} - 2.0*ex*v*{iws2}*th)",
        f"{i}        vn = v - fv/df if df > 0.0 else 0.5*(lo + hi)",
        f"{i}        if not lo <= vn <= hi: vn = 0.5*(lo + hi)",
        f"{i}        dv = vn - v",
        f"{i}        v = vn",
        f"{i}        if -{tol} < dv < {tol} or hi - lo < {tol}: break",
        f"{i}    v = v*sg",
        f"{i}else:",
        f"{i}    v = 0.0",
        f"{i}tf = (a - v)*{c['inv_b']}",
    ]


def friction_constants(p: Mapping[str, Value], b: float, stribeck: Optional[bool] = None) -> dict[str, float]:
    """The numbers of the implicit friction solve over a substep whose d omega_N / d tau_L is ``b``
    (``stribeck``: which solve, by default tau_s > 0; given when the values are traced)."""
    tau_c, omega_c, tau_s = real_or_traced(p["tau_c"]), real_or_traced(p["omega_c"]), real_or_traced(p["tau_s"])
    if tau_s > 0.0 if stribeck is None else stribeck:
        omega_s = real_or_traced(p["omega_s"])
        return {
            "b": b,
            "bt": b * (tau_c + tau_s),
            "iwc": 1.0 / omega_c,
            "iws2": 1.0 / (omega_s * omega_s),
            "tol": 1e-10 * omega_c,
            "tau_c": tau_c,
            "tau_s": tau_s,
            "inv_b": 1.0 / b,
        }
    k = b * tau_c / omega_c
    return {
        "btc": b * tau_c,
        "k": k,
        "inv_wc": 1.0 / omega_c,
        "inv_b": 1.0 / b,
        "lin": 1.0 / (1.0 + k),
        "tol": 1e-10 * omega_c,
    }


def structure(N: int) -> list[tuple[int, int]]:
    """The entries of ``state_matrices``' A that a chain of N inertias can have non-zero, by (row, column): the
    current's row (i, omega_1), each angle's (its speed), each speed's (its neighbours' angles and speeds, the
    current on omega_1)."""
    out = [(0, 0), (0, N + 1)]
    out += [(k, N + k) for k in range(1, N + 1)]
    for k in range(1, N + 1):
        near = [j for j in (k - 1, k, k + 1) if 1 <= j <= N]
        out += ([(N + 1, 0)] if k == 1 else []) + [(N + k, j) for j in near] + [(N + k, N + j) for j in near]
    return out


#: the friction numbers that the carried mass scales (``_carried_lines``): by 1 / e, or by e
_SCALED = {"btc": "/", "k": "/", "inv_b": "*", "b": "/", "bt": "/"}


def _carried_lines(p: Mapping[str, Value], g: str, f: Mapping[str, str], tag: str) -> tuple[list[str], dict]:
    """The mass M_carried on the load side over a substep, implicit as the friction (docs/coupling.md): its force
    held at M_carried i_R^2 (omega_N(end) - omega_N) / h_sub, with ``q`` = M_carried i_R^2 / h_sub given, turns
    the end speed's equation omega_N(end) = a - g tau_f into the same with a' = (a + kappa omega_N) / e,
    g' = g / e, kappa = g q, e = 1 + kappa. ``g``: d omega_N(end) / d tau_L as text; ``f``: the friction solve's
    numbers as text (``friction_constants``; empty without friction). Returns the lines that compute ``kap<tag>``,
    ``e<tag>`` and the scaled numbers, and the numbers' text for the solve (with M_carried = 0 the same floats:
    divided and multiplied by 1.0)."""
    lines = [f"kap{tag} = {g}*q", f"e{tag} = 1.0 + kap{tag}"]
    text = dict(f)
    for key, op in _SCALED.items():
        if key in f:
            text[key] = f"{key}{tag}_"
            lines.append(f"{text[key]} = {f[key]}{op}e{tag}")
    if "lin" in f:
        text["lin"] = f"lin{tag}_"
        lines.append(f"lin{tag}_ = 1.0/(1.0 + {text['k']})")
    return lines, text


def _friction_text(p: Mapping[str, Value], b: float, prefix: Optional[str] = None) -> dict[str, str]:
    """The implicit friction solve's numbers for this parameter set as text: inlined, or (``prefix``) the names
    ``prefix + key`` bound per step size; empty without friction."""
    if not (float(p["tau_c"]) > 0.0 or float(p["tau_s"]) > 0.0):
        return {}
    constants = friction_constants(p, b)
    return {k: repr(v) if prefix is None else prefix + k for k, v in constants.items()}


def _solve_lines(p: Mapping[str, Value], text: Mapping[str, str], tag: str, wN: int) -> list[str]:
    """One substep's end speed v and friction torque tf from ``a`` (the friction solve with the carried mass's
    numbers ``text`` of ``_carried_lines``), then the torque w on the last inertia."""
    body = [f"a = (a + kap{tag}*x{wN})/e{tag}"]
    if text:
        body += (_stribeck_source if float(p["tau_s"]) > 0.0 else _friction_source)(text, "")
    else:
        body += ["v = a", "tf = 0.0"]
    body.append(f"w = tl - q*(v - x{wN}) - tf")
    return body


def kernel_constants(
    p: Mapping[str, Value], i_R, A: np.ndarray, B: np.ndarray, J: Sequence, K: Sequence, C: Sequence
) -> dict[str, object]:
    """The numbers the step kernel computes with that depend on the parameters only (not on the step
    size), by name: inlined into a compiled kernel, or (``symbolic``) read by name, as the native FMU
    does after computing them from the parameters at initialisation (these same lines, traced)."""
    us, n = real_or_traced(p["u_supply"]), A.shape[0]
    c = {
        "us": us,
        "nus": -us,
        "iR": i_R,
        "niR": -i_R,
        "weight": i_R * real_or_traced(p["M_load"]) * real_or_traced(p["g_guide"]),
        "mg": real_or_traced(p["M_load"]) * real_or_traced(p["g_guide"]),
        "ripple": real_or_traced(p["tau_ripple"]),
        "rk": 2.0 * math.pi * i_R / real_or_traced(p["ripple_period"]),
        "rho0": real_or_traced(p["rho_0"]),
        "rmin": real_or_traced(p["rho_min"]),
        "rmax": real_or_traced(p["rho_max"]),
        "kT": real_or_traced(p["k_T"]),
        "tau_c": real_or_traced(p["tau_c"]),
        "omega_c": real_or_traced(p["omega_c"]),
        "tau_s": real_or_traced(p["tau_s"]),
        "omega_s": real_or_traced(p["omega_s"]),
    }
    c["iR2"] = i_R * i_R
    c["md"] = 1.0 / (B[n - 1, 1] * (i_R * i_R))  # J_N / i_R^2: the load-side mass
    c.update({f"aw{j}": A[n - 1, j] for j in range(n)})
    c["bw"] = B[n - 1, 1]
    c.update({f"a{i}_{j}": A[i, j] for i, j in structure(len(J))})
    c["b00"] = B[0, 0]
    if len(J) == 2:  # backlash (two-inertia model only)
        hb = 0.5 * real_or_traced(p["backlash"])
        c.update(
            {
                "hb": hb,
                "nhb": -hb,
                "khb": K[0] * hb,
                "nkhb": -K[0] * hb,
                "ks": K[0],
                "cs": C[0],
                "bv": real_or_traced(p["b_v"]),
                "ij2": 1.0 / J[1],
            }
        )
    return c


def _numbers(block: ActuatorBlock, symbolic: bool) -> dict[str, str]:
    """The kernel's parameter numbers as source text: ``repr`` of the value, or (``symbolic``) ``Q_<key>``."""
    if symbolic:
        return {k: f"Q_{k}" for k in block.constants}
    return {k: repr(float(v)) for k, v in block.constants.items()}


def _load_lines(block: ActuatorBlock, xs: Sequence[str], c: Mapping[str, str], ripple: bool) -> list[str]:
    """Unpack the state and compute tl, the torque on the last inertia except friction (held over the step)."""
    if ripple:
        return [
            f"    {', '.join(xs)}, = x",
            f"    tl = {c['niR']}*F - {c['weight']} - {c['ripple']}*sin({c['rk']}*x{block.N})",
        ]
    return [f"    tl = {c['niR']}*F - {c['weight']}", f"    {', '.join(xs)}, = x"]


def _kernel_head(c: Mapping[str, str], h_sub: str) -> list[str]:
    return [
        "def kernel(values, x):",
        "    u = values[0]",
        "    F = values[1]",
        "    Dc = values[2]",
        "    if u - u != 0.0: return 1",
        "    if F - F != 0.0: return 2",
        "    if Dc - Dc != 0.0 or Dc < 0.0: return 5",
        f"    if u > {c['us']}: u = {c['us']}",
        f"    elif u < {c['nus']}: u = {c['nus']}",
        f"    q = Dc*{c['iR2']}/{h_sub}",
    ]


def _outputs_lines(
    block: ActuatorBlock, xs: Sequence[str], alpha: str, torque: str, c: Mapping[str, str], symbolic: bool
) -> list[str]:
    """The outputs after a step (values after the inputs), from the state, ``alpha`` (the last inertia's
    acceleration without the carried mass, as source) and ``torque`` (the torque on the last inertia from the
    transmission or the motor, as source): the acceleration with the carried mass, the drive force and its two
    derivatives along the model with the inputs held (docs/coupling.md)."""
    N, n_in = block.N, len(block.INPUTS)
    n, wN = 2 * N + 1, 2 * N
    if symbolic:
        A = {(i, j): c[f"a{i}_{j}"] for i, j in structure(N)}
        b00 = c["b00"]
    else:
        A = {(i, j): block.A[i, j] for i, j in structure(N)}
        b00 = block.B[0, 0]

    def row(i: int, names: Sequence[str]) -> str:
        return _lin([A.get((i, j), 0.0) for j in range(n)], names)

    last = [j for j in range(n) if (wN, j) in A]
    need = sorted({j for i in last if i != wN for j in range(n) if (i, j) in A} | set(last))
    d = [f"d{j}" for j in range(n)]
    e = [f"e{j}" for j in range(n)]
    lines = [
        f"    al = ({alpha})/(1.0 + Dc*{c['iR2']}*{c['bw']})",
        f"    tn = tl - {c['niR']}*F",
        f"    T = ({torque} + tn - tf)/{c['iR']}",
    ]
    for j in need:
        if j == wN:
            lines.append(f"    d{j} = al")
        else:
            extra = f" + {_lin([b00], ['u'])}" if j == 0 else ""
            lines.append(f"    d{j} = {row(j, xs)}{extra}")
    unused = [f"d{j}" for j in range(n) if j not in need]
    if unused:
        lines.append(f"    {', '.join(unused)} = {', '.join(['0.0'] * len(unused))}")
    lines.append(f"    s1 = {row(wN, d)}")
    for j in last:
        lines.append(f"    e{j} = s1/(1.0 + Dc*{c['iR2']}*{c['bw']})" if j == wN else f"    e{j} = {row(j, d)}")
    rest = [f"e{j}" for j in range(n) if j not in last]
    if rest:
        lines.append(f"    {', '.join(rest)} = {', '.join(['0.0'] * len(rest))}")
    lines += [
        f"    s2 = {row(wN, e)}",
        f"    values[{n_in}:] = (rho, {c['iR']}*x{wN}, {c['iR']}*al, x1, x{N + 1}, x0, tm, tm, T, "
        f"s1/({c['bw']}*{c['iR']}), s2/({c['bw']}*{c['iR']}), {c['md']})",
    ]
    return lines


def _kernel_tail(
    block: ActuatorBlock, xs: Sequence[str], alpha: str, torque: str, c: Mapping[str, str], symbolic: bool
) -> list[str]:
    N = block.N
    return [
        f"    s = {' + '.join(xs)}",
        "    if s - s != 0.0: return 3",
        f"    rho = {c['rho0']} + {c['iR']}*x{N}",
        f"    x[:] = ({', '.join(xs)},)",
        f"    tm = {c['kT']}*x0",
        *_outputs_lines(block, xs, alpha, torque, c, symbolic),
        f"    if rho < {c['rmin']} or rho > {c['rmax']}: return 4",
        "    return 0",
    ]


def _torque(block: ActuatorBlock, c: Mapping[str, str], symbolic: bool) -> str:
    """The torque on the last inertia from its spring, damper, viscous friction (the motor's through a rigid
    transmission), as source: J_N times the last row of A on the state."""
    n = 2 * block.N + 1
    coefs = [c[f"aw{j}"] for j in range(n)] if symbolic else list(block.A[n - 1])
    return f"({_lin(coefs, [f'x{j}' for j in range(n)])})/{c['bw']}"


def kernel_source(
    block: ActuatorBlock,
    Phi: np.ndarray,
    Gam: np.ndarray,
    m: int,
    named: bool = False,
    symbolic: bool = False,
    h_sub: float = 0.0,
) -> str:
    """Python source of ``kernel(values, x) -> int`` (0 ok, 1/2/5 bad input u/F/M_carried, 3 diverged, 4 stroke)
    over m substeps of ``h_sub`` [s].

    ``named``: Phi and Gam are arrays of names (``name_grid``), the friction constants, the substep
    (``H_SUB``) and the number of substeps (``M_SUB``) are names too: one source for every step size, bound to
    the numbers by ``ActuatorBlock._bind``. ``symbolic`` (with ``named``): the parameters' numbers
    too (``kernel_constants`` as ``Q_<key>``): one source for every parameter set of this
    structure (the native FMU's, mast.core.native.models).
    """
    xs = [f"x{j}" for j in range(2 * block.N + 1)]
    c = _numbers(block, symbolic)
    lines = _kernel_head(c, "H_SUB" if named else repr(h_sub))
    lines += _load_lines(block, xs, c, float(block.params["tau_ripple"]) > 0.0)
    carried, body = _substep_lines(block, Phi, Gam, named)
    lines += ["    " + s for s in carried]
    if m == 1 and not named:
        lines += ["    " + s for s in body]
    else:
        lines.append(f"    for _ in range({'M_SUB' if named else m}):")
        lines += ["        " + s for s in body]
    lines += _kernel_tail(block, xs, _alpha(block, c, symbolic), _torque(block, c, symbolic), c, symbolic)
    return "\n".join(lines) + "\n"


def _substep_lines(
    block: ActuatorBlock, Phi: np.ndarray, Gam: np.ndarray, named: bool, shared: bool = False
) -> tuple[list[str], list[str]]:
    """(lines once per step, lines of one substep): the carried mass's numbers (``_carried_lines``), then per
    substep (u, tl, q and the state x0.. given) the implicit end speed and friction torque tf, then the state.

    ``shared`` (numbers inlined): the friction's ``a`` and the new omega_N have the same terms but the
    last (tl, w), summed left to right: their common partial sum ``s_a`` is computed once, the same floats."""
    p, N = block.params, block.N
    n = 2 * N + 1
    xs = [f"x{j}" for j in range(n)]
    wN = 2 * N  # index of omega_N
    body = []
    rows = [_lin(list(Phi[j]) + [Gam[j, 0], Gam[j, 1]], xs + ["u", "w"]) for j in range(n)]
    a_terms = _lin(list(Phi[wN]) + [Gam[wN, 0], Gam[wN, 1]], xs + ["u", "tl"])
    head = _lin(list(Phi[wN]) + [Gam[wN, 0]], xs + ["u"])
    last = _lin([Gam[wN, 1]], ["w"])
    to_tl = _lin([Gam[wN, 1]], ["tl"])
    if (
        shared
        and not named
        and head != "0.0"
        and last != "0.0"
        and rows[wN] == f"{head} + {last}"
        and a_terms == f"{head} + {to_tl}"
    ):
        body.append(f"s_a = {head}")
        a_terms, rows[wN] = f"s_a + {to_tl}", f"s_a + {last}"
    body.append(f"a = {a_terms}")
    g = Gam[wN, 1] if named else repr(float(Gam[wN, 1]))
    text = _friction_text(p, 1.0 if named else float(Gam[wN, 1]), "F_" if named else None)
    carried, text = _carried_lines(p, g, text, "")
    body += _solve_lines(p, text, "", wN)
    news = [f"n{j}" for j in range(n)]
    for j in range(n):
        body.append(f"{news[j]} = {rows[j]}")
    body.append(f"{', '.join(xs)} = {', '.join(news)}")
    return carried, body


def _alpha(block: ActuatorBlock, c: Mapping[str, str], symbolic: bool) -> str:
    """The last inertia's acceleration at the end of the step (the output rho_ddot / i_R), as source."""
    n, wN = 2 * block.N + 1, 2 * block.N
    coefs = [c[f"aw{j}"] for j in range(n)] + [c["bw"]] if symbolic else list(block.A[wN]) + [block.B[wN, 1]]
    return _lin(coefs, [f"x{j}" for j in range(n)] + ["(tl - tf)"])


def _ticks_source(block: ActuatorBlock, Phi: np.ndarray, Gam: np.ndarray, m: int, h_sub: float) -> str:
    """Python source of the drive's current loop over ``ticks`` steps of T_cur in one function (drive.py):

        ticks(values, x, ticks, i_cmd, x_c, u_c, k_p, k_iT, u_max) -> (code, tick, x_c, u_c)

    each tick ``pi_step`` (drive.py) on i_m = x0, then the step over T_cur of ``kernel_source`` (the same
    lines: the same arithmetic) with the voltage u_c of the tick before; ``values`` and ``x`` are written
    once, after the last tick (the last u_c applied in values[0]). ``code``: 0, or the kernel's failure code at
    ``tick`` (then nothing is written). No backlash, no torque sensor (``ActuatorBlock.ticks``)."""
    N = block.N
    xs = [f"x{j}" for j in range(2 * N + 1)]
    c = _numbers(block, False)
    ripple = float(block.params["tau_ripple"]) > 0.0
    carried, body = _substep_lines(block, Phi, Gam, False, shared=True)
    lines = [
        "def ticks(values, x, ticks, i_cmd, x_c, u_c, k_p, k_iT, u_max):",
        "    F = values[1]",
        "    Dc = values[2]",
        "    if F - F != 0.0: return 2, 0, x_c, u_c",
        "    if Dc - Dc != 0.0 or Dc < 0.0: return 5, 0, x_c, u_c",
        f"    q = Dc*{c['iR2']}/{h_sub!r}",
        *("    " + line for line in carried),
        f"    tl = {c['niR']}*F - {c['weight']}",
        f"    {', '.join(xs)}, = x",
        "    for k in range(ticks):",
        "        u_n, x_c = pi_step(i_cmd - x0, x_c, k_p, k_iT, u_max)",
        "        u = u_a = u_c",
        "        if u - u != 0.0: return 1, k, x_c, u_c",
        f"        if u > {c['us']}: u = {c['us']}",
        f"        elif u < {c['nus']}: u = {c['nus']}",
    ]
    if ripple:
        lines.append(f"        tl = {c['niR']}*F - {c['weight']} - {c['ripple']}*sin({c['rk']}*x{N})")
    if m == 1:
        lines += ["        " + s for s in body]
    else:
        lines.append(f"        for _ in range({m}):")
        lines += ["            " + s for s in body]
    lines += [
        f"        s = {' + '.join(xs)}",
        "        if s - s != 0.0: return 3, k, x_c, u_c",
        f"        rho = {c['rho0']} + {c['iR']}*x{N}",
        f"        if rho < {c['rmin']} or rho > {c['rmax']}: return 4, k, x_c, u_c",
        "        u_c = u_n",
        f"    x[:] = ({', '.join(xs)},)",
        f"    tm = {c['kT']}*x0",
        "    values[0] = u_a",
        *_outputs_lines(block, xs, _alpha(block, c, False), _torque(block, c, False), c, False),
        "    return 0, ticks, x_c, u_c",
    ]
    return "\n".join(lines) + "\n"


def _backlash_matrices(
    block: ActuatorBlock, h_sub: float, exponential: Callable = expm
) -> tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]:
    """Exact ZOH discretisations of the two-inertia model in contact and in the gap: ((Phi, Gamma) each)."""
    out = []
    for M in _backlash_generators(block):
        E = exponential(M * h_sub)
        out.append((E[:5, :5], E[:5, 5:]))
    return out[0], out[1]


def _backlash_generators(block: ActuatorBlock) -> tuple[np.ndarray, np.ndarray]:
    """[[A B], [0 0]] of the two-inertia model in contact and in the gap (``ActuatorBlock.generator``).

    Inputs [u_sat, tau_L, pl]: pl is the dead-zone offset K_t hb sgn (on inertia 1, and minus
    it on inertia 2) that makes the spring torque K_t (theta_1 - theta_2 -+ hb) in contact.
    In the gap the spring and the damper carry no torque.
    """
    A, Ag, B3 = backlash_systems(block.A, block.B, block.J, block.K, block.C)
    out = []
    for mat in (A, Ag):
        M = np.zeros((8, 8))
        M[:5, :5] = mat
        M[:5, 5:] = B3
        out.append(M)
    return out[0], out[1]


def backlash_systems(
    A: np.ndarray, B: np.ndarray, J: Sequence, K: Sequence, C: Sequence
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The two-inertia model with backlash: (A in contact, A in the gap, B3 for [u_sat, tau_L, pl])."""
    A = A.copy()
    J1, J2 = J
    B3 = np.zeros((5, 3), dtype=A.dtype)
    B3[:, :2] = B
    B3[3, 2] = 1.0 / J1
    B3[4, 2] = -1.0 / J2
    Ag = A.copy()
    K, C = K[0], C[0]
    Ag[3, 1] += K / J1
    Ag[3, 2] -= K / J1
    Ag[3, 3] += C / J1
    Ag[3, 4] -= C / J1
    Ag[4, 2] += K / J2
    Ag[4, 1] -= K / J2
    Ag[4, 4] += C / J2
    Ag[4, 3] -= C / J2
    return A, Ag, B3


def backlash_kernel_source(
    block: ActuatorBlock, h_sub: float, m: int, named: bool = False, symbolic: bool = False
) -> str:
    """Step with backlash (n_dof = 2): substeps of h_sub, the mode from the deflection at each substep start.

    ``named``, ``symbolic``: the step-size-dependent numbers, and the parameters' numbers, are names
    (see ``kernel_source``), h_sub is unused."""
    p = block.params
    xs = [f"x{j}" for j in range(5)]
    c = _numbers(block, symbolic)
    if named:
        (Pc, Gc), (Pg, Gg) = (
            (name_grid("PC", (5, 5)), name_grid("GC", (5, 3))),
            (name_grid("PG", (5, 5)), name_grid("GG", (5, 3))),
        )
    else:
        (Pc, Gc), (Pg, Gg) = _backlash_matrices(block, h_sub)
    lines = _kernel_head(c, "H_SUB" if named else repr(h_sub))
    lines += _load_lines(block, xs, c, float(p["tau_ripple"]) > 0.0)
    modes = []
    for Gam, prefix, tag in ((Gc, "FC_", "C"), (Gg, "FG_", "G")):
        g = Gam[4, 1] if named else repr(float(Gam[4, 1]))
        text = _friction_text(p, 1.0 if named else float(Gam[4, 1]), prefix if named else None)
        carried, text = _carried_lines(p, g, text, tag)
        lines += ["    " + line for line in carried]
        modes.append(text)
    lines.append(f"    for _ in range({'M_SUB' if named else m}):")
    lines.append("        d = x1 - x2")
    lines += [
        f"        if d > {c['hb']}:",
        f"            pl = {c['khb']}",
        "            contact = 1.0",
        f"        elif d < {c['nhb']}:",
        f"            pl = {c['nkhb']}",
        "            contact = 1.0",
        "        else:",
        "            pl = 0.0",
        "            contact = 0.0",
    ]
    for cond, (Phi, Gam), text, tag in (
        ("if contact > 0.0:", (Pc, Gc), modes[0], "C"),
        ("else:", (Pg, Gg), modes[1], "G"),
    ):
        lines.append(f"        {cond}")
        body = [
            f"a = {_lin(list(Phi[4]) + list(Gam[4]), xs + ['u', 'tl', 'pl'])}"
            if cond.startswith("if")
            else f"a = {_lin(list(Phi[4]) + list(Gam[4, :2]), xs + ['u', 'tl'])}"
        ]
        body += _solve_lines(p, text, tag, 4)
        ins = xs + ["u", "w", "pl"] if cond.startswith("if") else xs + ["u", "w"]
        for j in range(5):
            coefs = list(Phi[j]) + (list(Gam[j]) if cond.startswith("if") else list(Gam[j, :2]))
            body.append(f"n{j} = {_lin(coefs, ins)}")
        body.append(f"{', '.join(xs)} = {', '.join(f'n{j}' for j in range(5))}")
        lines += ["            " + s for s in body]
    lines += [
        "    d = x1 - x2",
        f"    if d > {c['hb']}: ts = {c['ks']}*(d - {c['hb']}) + {c['cs']}*(x3 - x4)",
        f"    elif d < {c['nhb']}: ts = {c['ks']}*(d + {c['hb']}) + {c['cs']}*(x3 - x4)",
        "    else: ts = 0.0",
    ]
    alpha = f"(ts + tl - tf - {c['bv']}*x4)*{c['ij2']}"
    lines += _kernel_tail(block, xs, alpha, f"(ts - {c['bv']}*x4)", c, symbolic)
    return "\n".join(lines) + "\n"
