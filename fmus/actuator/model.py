"""One linear axis of the MAST: DC motor + gearbox + belt guide (paper section 2.2, 3.1).

Physics (all mechanical quantities referred to the motor shaft)
----------------------------------------------------------------
Eq. 1        i_R = p / (2 pi i_r)                       [m/rad] carriage metres per motor radian
electrical   L di/dt = u_sat - R i - k_E omega_1,        u_sat = clip(u, -u_supply, u_supply)
motor        tau_m = k_T i                               on the first inertia
chain        J_k domega_k/dt = sum of spring/damper torques of the neighbours
                               (+ tau_m on k = 1) (+ tau_L - b_v omega_N on k = N)
load         tau_L = -i_R F - i_R M_load g_guide - tau_c tanh(omega_N / omega_c)
                     (mechanism reaction, Eq. 1; carriage weight; guide Coulomb friction, Eq. 23)
output       rho = rho_0 + i_R theta_N

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

The step is compiled once per step size into straight-line Python (constants inlined):
for a 5-state system scalar code is several times faster than numpy calls.
"""
from __future__ import annotations

import math
from typing import Callable, Mapping, Sequence

import numpy as np
from scipy.linalg import expm

from ..common.block import Block, ModelError
from ..common.parameters import Param, ParameterError, Value, nonnegative, positive

__all__ = [
    "ActuatorBlock",
    "transmission_ratio",
    "two_inertia",
    "chain",
    "state_matrices",
    "transfer_functions",
    "natural_frequencies",
    "chain_frequencies",
]

_MAX_PHASE_PER_SUBSTEP = 2.0  # rad: fastest chain mode x substep (keeps the friction equation monotone)


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
    positive("M_load", "kg", "drive carriage mass (Eqs. 21-22); its weight acts on the guide"),
    positive("K_t", "N.m/rad", "transmission stiffness, motor side (Eqs. 2-3, Table 1)"),
    nonnegative("C_t", "N.m.s/rad", "transmission damping, motor side (Eqs. 2-3, Table 1)"),
    nonnegative("tau_c", "N.m", "guide Coulomb friction referred to the motor shaft (Eq. 23)"),
    positive("omega_c", "rad/s", "friction smoothing speed at the motor shaft: tau_c tanh(omega/omega_c)"),
    nonnegative("b_v", "N.m.s/rad", "viscous friction on the guide side, motor shaft"),
    Param("g_guide", "m/s2", "gravity along the guide (positive: pulls the carriage to lower rho)"),
    Param("rho_0", "m", "initial carriage position, rho_min < rho_0 < rho_max"),
    Param("rho_min", "m", "lower end of the stroke"),
    Param("rho_max", "m", "upper end of the stroke"),
    Param("n_dof", "", "transmission model: 1 rigid, 2 two-inertia (Eqs. 2-3), N >= 3 chain",
          1, 64, kind=int),
    Param("J_chain", "kg.m2", "n_dof >= 3: N inertias, motor side first, referred to the motor shaft, "
          "carriage included in the last, space separated", kind=str),
    Param("K_chain", "N.m/rad", "n_dof >= 3: N-1 stiffnesses referred to the motor shaft, space separated",
          kind=str),
    Param("C_chain", "N.m.s/rad", "n_dof >= 3: N-1 dampings referred to the motor shaft, space separated",
          kind=str),
    positive("i_r", "1", "gearbox ratio (Eq. 1)"),
    positive("p", "m", "guide feed per revolution of its input shaft (Eq. 1)"),
)


# --------------------------------------------------------------------------------------
# Paper relations: plain functions of a parameter mapping (validated or straight from .ssv)
# --------------------------------------------------------------------------------------
def transmission_ratio(p: float, i_r: float) -> float:
    """Eq. 1: i_R = p / (2 pi i_r) [m/rad], carriage travel per motor radian.

    ``p`` [m] guide feed per revolution, ``i_r`` [1] gearbox ratio.
    """
    return float(p) / (2.0 * math.pi * float(i_r))


def two_inertia(params: Mapping[str, Value]) -> tuple[float, float]:
    """Eqs. 20-22: (J1, J2) [kg m^2] referred to the motor shaft.

    J1 = J1_scale (J_motor + J_gearbox + J_coupling + J_brake) (Eq. 20 plus the brake),
    J2 = J_guide / i_r^2 + M_load i_R^2.
    """
    f = {k: float(params[k]) for k in ("J_motor", "J_gearbox", "J_coupling", "J_brake", "J1_scale",
                                        "J_guide", "M_load", "i_r", "p")}
    i_R = transmission_ratio(f["p"], f["i_r"])
    J1 = f["J1_scale"] * (f["J_motor"] + f["J_gearbox"] + f["J_coupling"] + f["J_brake"])
    J2 = f["J_guide"] / f["i_r"] ** 2 + f["M_load"] * i_R ** 2
    return J1, J2


def _parse_list(params: Mapping[str, Value], name: str, count: int, positive: bool) -> list[float]:
    text = str(params[name]).replace(",", " ").split()
    what = "> 0" if positive else ">= 0"
    if len(text) != count:
        raise ParameterError(f"parameter '{name}' = {params[name]!r}: expected {count} space separated "
                             f"numbers {what} for n_dof = {params['n_dof']}, got {len(text)}")
    values = []
    for item in text:
        try:
            v = float(item)
        except ValueError:
            v = math.nan
        if not math.isfinite(v) or (v <= 0.0 if positive else v < 0.0):
            raise ParameterError(f"parameter '{name}' = {params[name]!r}: item {item!r} is not a finite "
                                 f"number {what}")
        values.append(v)
    return values


def chain(params: Mapping[str, Value]) -> tuple[list[float], list[float], list[float]]:
    """The lumped chain selected by ``n_dof``: (J [kg m^2], K [N m/rad], C [N m s/rad]).

    All referred to the motor shaft, motor side first, guide side last; len(J) = n_dof
    and len(K) = len(C) = n_dof - 1.
    """
    n = int(params["n_dof"])
    if n == 1:
        J1, J2 = two_inertia(params)
        return [J1 + J2], [], []
    if n == 2:
        J1, J2 = two_inertia(params)
        return [J1, J2], [float(params["K_t"])], [float(params["C_t"])]
    J = _parse_list(params, "J_chain", n, True)
    J[0] *= float(params["J1_scale"])
    return J, _parse_list(params, "K_chain", n - 1, True), _parse_list(params, "C_chain", n - 1, False)


def state_matrices(params: Mapping[str, Value]) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """Linear part of the model: dx/dt = A x + B [u_sat, tau_L]^T.

    x = [i, theta_1..theta_N, omega_1..omega_N] (A, rad, rad/s); u_sat [V]; tau_L [N m] the
    torque on the last inertia (mechanism, weight, Coulomb friction; viscous b_v is in A).
    Returns (A, B, state names).
    """
    J, K, C = chain(params)
    n = len(J)
    R, L, k_T, k_E, b_v = (float(params[k]) for k in ("R", "L", "k_T", "k_E", "b_v"))
    size = 2 * n + 1
    A = np.zeros((size, size))
    B = np.zeros((size, 2))
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


# --------------------------------------------------------------------------------------
# The block
# --------------------------------------------------------------------------------------
_ERRORS = {1: "u", 2: "F"}


class ActuatorBlock(Block):
    """One MAST linear axis: DC motor, gearbox, flexible transmission and belt guide."""

    INPUTS = ("u", "F")
    OUTPUTS = ("rho", "rho_dot", "rho_ddot", "theta_m", "omega_m", "i_m", "tau_m")
    PARAMETERS = PARAMETERS
    UNITS = {"u": "V", "F": "N", "rho": "m", "rho_dot": "m/s", "rho_ddot": "m/s2", "theta_m": "rad",
             "omega_m": "rad/s", "i_m": "A", "tau_m": "N.m"}
    DESCRIPTIONS = {
        "u": "voltage command from the controller (clipped to +-u_supply)",
        "F": "force this actuator applies to the mechanism along its guide, positive upward",
        "rho": "carriage position along the guide",
        "rho_dot": "carriage velocity",
        "rho_ddot": "carriage acceleration at the end of the step",
        "theta_m": "motor angle (0 at the start)",
        "omega_m": "motor speed",
        "i_m": "motor current",
        "tau_m": "motor torque k_T i_m",
    }

    def __init__(self, params: Mapping[str, Value], name: str = "") -> None:
        super().__init__(params, name)
        p = self.params
        if not p["rho_min"] < p["rho_max"]:
            raise ParameterError(f"{self.name}: parameter 'rho_max' = {p['rho_max']!r}: expected a value above "
                                 f"rho_min = {p['rho_min']!r} m")
        if not p["rho_min"] < p["rho_0"] < p["rho_max"]:
            raise ParameterError(f"{self.name}: parameter 'rho_0' = {p['rho_0']!r}: expected a position inside "
                                 f"the stroke ({p['rho_min']!r}, {p['rho_max']!r}) m")
        try:
            self.J, self.K, self.C = chain(p)
        except ParameterError as err:
            raise ParameterError(f"{self.name}: {err}") from None
        self.N = len(self.J)
        self.i_R = transmission_ratio(p["p"], p["i_r"])
        self.A, self.B, self.state_names = state_matrices(p)
        self._omega_max = 2.0 * math.pi * float(chain_frequencies(self.J, self.K).max(initial=0.0))
        self._kernels: dict[float, tuple[Callable, int]] = {}
        self._h = math.nan
        self._kernel: Callable = _no_kernel
        self.substeps = 0
        self._x: list[float] = [0.0] * (2 * self.N + 1)

    # -- life cycle ------------------------------------------------------------------
    def initialize(self, t0: float) -> None:
        """(Re)start from the initial state (rest, i = 0, springs undeflected, rho = rho_0)
        and compute the outputs from it and the current inputs."""
        self._x = [0.0] * (2 * self.N + 1)
        u, F = self.values[0], self.values[1]
        for k, v in enumerate((u, F)):
            if not math.isfinite(v):
                raise ModelError(f"{self.name}: input '{_ERRORS[k + 1]}' = {v} at t={t0:.9g} s is not finite")
        self._write_outputs(F)

    def do_step(self, t: float, h: float) -> None:
        """Advance from t to t + h [s] with u [V] and F [N] held (zero-order hold)."""
        if h != self._h:
            self._select(h)
        code = self._kernel(self.values, self._x)
        if code:
            self._fail(code, t, h)

    # -- helpers ---------------------------------------------------------------------
    def state(self) -> dict[str, float]:
        """Current state by name: i [A], theta_k [rad], omega_k [rad/s] (k = 1 motor .. N guide)."""
        return dict(zip(self.state_names, self._x))

    def _write_outputs(self, F: float) -> None:
        """Outputs from the state (used by initialize; do_step's kernel does the same inline)."""
        p, x, N = self.params, self._x, self.N
        w = x[2 * N]
        tau_f = p["tau_c"] * math.tanh(w / p["omega_c"])
        tau_L = -self.i_R * (F + p["M_load"] * p["g_guide"]) - tau_f
        alpha = float(self.A[2 * N] @ np.asarray(x) + self.B[2 * N, 1] * tau_L)
        n_in = len(self.INPUTS)
        self.values[n_in:] = [p["rho_0"] + self.i_R * x[N], self.i_R * w, self.i_R * alpha,
                              x[1], x[N + 1], x[0], p["k_T"] * x[0]]

    def _fail(self, code: int, t: float, h: float) -> None:
        if code in _ERRORS:
            name = _ERRORS[code]
            raise ModelError(f"{self.name}: input '{name}' = {self.values[code - 1]} at t={t:.9g} s "
                             f"is not finite")
        if code == 3:
            raise ModelError(f"{self.name}: diverged at t={t + h:.9g} s (non-finite state)")
        p = self.params
        rho = p["rho_0"] + self.i_R * self._x[self.N]
        raise ModelError(f"{self.name}: carriage left the stroke [{p['rho_min']:g}, {p['rho_max']:g}] m: "
                         f"rho = {rho:.6g} m at t={t + h:.9g} s")

    def _select(self, h: float) -> None:
        if not (h > 0.0 and math.isfinite(h)):
            raise ModelError(f"{self.name}: step size h = {h!r} s: expected a finite positive number")
        key = float(f"{h:.12g}")
        entry = self._kernels.get(key)
        if entry is None:
            if len(self._kernels) >= 32:
                self._kernels.pop(next(iter(self._kernels)))
            entry = self._kernels[key] = self._compile(key)
        self._kernel, self.substeps = entry
        self._h = h

    def discretise(self, h_sub: float) -> tuple[np.ndarray, np.ndarray]:
        """Exact ZOH discretisation over h_sub [s]: (Phi, Gamma) with x+ = Phi x + Gamma [u_sat, tau_L]."""
        n = self.A.shape[0]
        M = np.zeros((n + 2, n + 2))
        M[:n, :n] = self.A
        M[:n, n:] = self.B
        E = expm(M * h_sub)
        return E[:n, :n], E[:n, n:]

    def _compile(self, h: float) -> tuple[Callable, int]:
        """Generate the step function for step h: straight-line scalar code, constants inlined."""
        m = max(1, math.ceil(self._omega_max * h / _MAX_PHASE_PER_SUBSTEP - 1e-12))
        while True:
            Phi, Gam = self.discretise(h / m)
            b = Gam[2 * self.N, 1]  # d omega_N(end) / d tau_L over a substep
            if b > 0.0 or m > 4096:
                break
            m *= 2
        if not b > 0.0:
            raise ModelError(f"{self.name}: no substep gives a monotone friction update for h = {h} s")
        source = _kernel_source(self, Phi, Gam, m)
        namespace: dict = {"tanh": math.tanh}
        exec(compile(source, f"<actuator kernel h={h!r} m={m}>", "exec"), namespace)
        kernel = namespace["kernel"]
        kernel.source = source
        return kernel, m


def _no_kernel(values: list, x: list) -> int:  # pragma: no cover - replaced before use
    raise ModelError("do_step before a step size was selected")


def _lin(coefs: Sequence[float], names: Sequence[str]) -> str:
    terms = [f"{float(c)!r}*{v}" for c, v in zip(coefs, names) if c != 0.0]
    return " + ".join(terms) if terms else "0.0"


def _friction_source(b: float, tau_c: float, omega_c: float, indent: str) -> list[str]:
    """Implicit Coulomb friction over one substep.

    With the friction torque tau_f held over the substep, the end velocity of the last
    inertia is v = a - b tau_f (a: everything else, b > 0). Requiring tau_f = tau_c
    tanh(v / omega_c) gives f(v) = v - a + b tau_c tanh(v / omega_c) = 0, increasing in v
    and, for v of the sign of a, concave (a > 0) or convex (a < 0). Newton started at
    v0 = max(a - b tau_c, a / (1 + k)), k = b tau_c / omega_c (a > 0; mirrored for a < 0),
    where f(v0) <= 0 (tanh(s) <= s for s >= 0), then climbs monotonically to the root:
    no overshoot, whatever the friction stiffness.
    tau_f = (a - v) / b is then exactly consistent with v and bounded by tau_c.
    """
    btc, k, inv_wc, inv_b = b * tau_c, b * tau_c / omega_c, 1.0 / omega_c, 1.0 / b
    lin = 1.0 / (1.0 + k)
    tol = 1e-10 * omega_c
    i = indent
    return [
        f"{i}if a > 0.0:",
        f"{i}    v = a - {btc!r}",
        f"{i}    v0 = a*{lin!r}",
        f"{i}    if v0 > v: v = v0",
        f"{i}    for _ in range(60):",
        f"{i}        th = tanh(v*{inv_wc!r})",
        f"{i}        dv = (a - v - {btc!r}*th) / (1.0 + {k!r}*(1.0 - th*th))",
        f"{i}        v += dv",
        f"{i}        if dv < {tol!r}: break",
        f"{i}elif a < 0.0:",
        f"{i}    v = a + {btc!r}",
        f"{i}    v0 = a*{lin!r}",
        f"{i}    if v0 < v: v = v0",
        f"{i}    for _ in range(60):",
        f"{i}        th = tanh(v*{inv_wc!r})",
        f"{i}        dv = (a - v - {btc!r}*th) / (1.0 + {k!r}*(1.0 - th*th))",
        f"{i}        v += dv",
        f"{i}        if dv > -{tol!r}: break",
        f"{i}else:",
        f"{i}    v = 0.0",
        f"{i}tf = (a - v)*{inv_b!r}",
    ]


def _kernel_source(block: ActuatorBlock, Phi: np.ndarray, Gam: np.ndarray, m: int) -> str:
    """Python source of ``kernel(values, x) -> int`` (0 ok, 1/2 bad input u/F, 3 diverged, 4 stroke)."""
    p, N = block.params, block.N
    n = 2 * N + 1
    xs = [f"x{j}" for j in range(n)]
    wN = 2 * N  # index of omega_N
    tau_c, omega_c = float(p["tau_c"]), float(p["omega_c"])
    i_R = block.i_R
    weight = i_R * float(p["M_load"]) * float(p["g_guide"])
    us = float(p["u_supply"])
    lines = [
        "def kernel(values, x):",
        "    u = values[0]",
        "    F = values[1]",
        "    if u - u != 0.0: return 1",
        "    if F - F != 0.0: return 2",
        f"    if u > {us!r}: u = {us!r}",
        f"    elif u < {-us!r}: u = {-us!r}",
        f"    tl = {-i_R!r}*F - {weight!r}",
        f"    {', '.join(xs)}, = x",
    ]
    body = []
    if tau_c > 0.0:
        a_terms = _lin(list(Phi[wN]) + [Gam[wN, 0], Gam[wN, 1]], xs + ["u", "tl"])
        body.append(f"a = {a_terms}")
        body += _friction_source(float(Gam[wN, 1]), tau_c, omega_c, "")
        body.append("w = tl - tf")
    else:
        body += ["tf = 0.0", "w = tl"]
    news = [f"n{j}" for j in range(n)]
    for j in range(n):
        body.append(f"{news[j]} = {_lin(list(Phi[j]) + [Gam[j, 0], Gam[j, 1]], xs + ['u', 'w'])}")
    body.append(f"{', '.join(xs)} = {', '.join(news)}")
    if m == 1:
        lines += ["    " + s for s in body]
    else:
        lines.append(f"    for _ in range({m}):")
        lines += ["        " + s for s in body]
    # end of step: checks, state, outputs
    A, B = block.A, block.B
    alpha = _lin(list(A[wN]) + [B[wN, 1]], xs + ["(tl - tf)"])
    rho0, rmin, rmax = float(p["rho_0"]), float(p["rho_min"]), float(p["rho_max"])
    n_in = len(block.INPUTS)
    lines += [
        f"    s = {' + '.join(xs)}",
        "    if s - s != 0.0: return 3",
        f"    rho = {rho0!r} + {i_R!r}*x{N}",
        f"    x[:] = ({', '.join(xs)},)",
        f"    values[{n_in}:] = (rho, {i_R!r}*x{wN}, {i_R!r}*({alpha}), x1, x{N + 1}, x0, {float(p['k_T'])!r}*x0)",
        f"    if rho < {rmin!r} or rho > {rmax!r}: return 4",
        "    return 0",
    ]
    return "\n".join(lines) + "\n"
