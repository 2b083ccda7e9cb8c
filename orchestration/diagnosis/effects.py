"""The library of candidate effects a diagnosis can name, and their residual signatures.

Each effect maps to named parameters of the actuator FMU (applied to every axis, or on one axis), or of
the controller FMU (the drive: a cause outside the plant) and,
where the effect is smooth enough, to a regression column: the change of the observed
motor torque per unit change of its first parameter, computed from a simulation
(reference.md section 6):

| effect | parameters | column (motor shaft; through the measurement chain) |
|---|---|---|
| Coulomb friction | tau_c | tanh(omega_N / omega_c): sign of the guide speed, flat in frequency, square wave |
| viscous friction | b_v | omega_N: in phase with velocity, grows with f |
| Stribeck friction | tau_s, omega_s | exp(-(omega_N/omega_s)^2) tanh(omega_N/omega_c): at low speed, after reversals |
| inertia, motor side | J1_scale | J1 / J1_scale * domega_1/dt: in phase with acceleration, grows with f^2 |
| inertia, guide side | J_guide | domega_N/dt / i_r^2 (the same as the motor side below the transmission resonance) |
| carriage mass | M_load | i_R^2 domega_N/dt + i_R g_guide: acceleration plus a weight bias in a fixed ratio |
| torque offset | tau_offset | 1: a bias |
| measurement lag | T_meas (or delay_meas) | d tau_obs / d T: phase lag growing with f |
| backlash | backlash | none: the loop hunts, scored phase-free (band powers against re-simulated ensembles, phasefree.py) |
| drive gains (controller) | k_p, k_v, k_i | none: the closed loop's re-simulated sensitivity |
| velocity-loop cycle time (controller) | T_vel | none: re-simulated secant to the next cycle; fitted on its grid (multiples of T_cur) |
| current limit (controller) | i_max | none: re-simulated only (no trace below the limit), tried when the data's torque peak stays below the model's |
| transmission stiffness | K_t | none: re-simulated only, from a log scan (1/K_t, not K_t, is what the loop feels), tried when stand-ins were refused |

Plant and measurement effects also exist on one axis only ("<parameter>_axis<j>", an increment on
actuator j; ``PER_AXIS``), for every drive a mechanism can have (``MAX_DRIVES``); a system's library is
that of its own drives (``for_drives``).

In the selection, plant effects use re-simulated sensitivities (a simulation with the
parameter stepped by ``Effect.step``: the exact linearisation of the closed loop, which
reacts to a plant change; the signatures above miss that reaction by 20-50 % at these
test frequencies); measurement effects use their columns, which are exact. The
signatures serve the Jacobian of the fit and the reading of the residual.

The observed torque is tau_obs = drive(sensor(tau_m)), where sensor is the FMU's own
measurement model (T_meas, delay_meas, tau_offset; fmus/actuator/sensor.py) and drive the
measurement chain the data's meta.json documents (the drive's torque filter). Columns go
through the same linear chain and are sampled at the data's time stamps.
"""  # noqa: E501 (a Markdown table, one row a line)

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable, Mapping, Optional, Sequence

import numpy as np

from fmus.actuator.model import transmission_ratio, two_inertia
from fmus.actuator.sensor import measure
from fmus.mechanism.topology import POSE

#: parameters of the measurement model (no re-simulation needed when they change)
MEASUREMENT_PARAMETERS = ("T_meas", "delay_meas", "tau_offset")
#: parameters of the controller component (the drive's cascade gains, velocity-loop cycle time, current
#: limit): a cause outside the plant
CONTROLLER_PARAMETERS = ("k_v", "k_p", "k_i", "T_vel", "i_max")


@dataclass
class SimSignals:
    """One simulated test on the base-step grid (arrays (m, drives): one column per actuator)."""

    time: np.ndarray
    h: float
    tau_m: np.ndarray
    rho: np.ndarray
    rho_dot: np.ndarray
    omega_m: np.ndarray
    _cache: dict = field(default_factory=dict, repr=False)

    def derived(self, name: str, params: Mapping) -> np.ndarray:
        key = (name, float(params["p"]), float(params["i_r"]))
        if key not in self._cache:
            i_R = transmission_ratio(params["p"], params["i_r"])
            if name == "omega_N":
                v = self.rho_dot / i_R
            elif name == "acc_N":
                v = np.gradient(self.rho_dot, self.h, axis=0) / i_R
            elif name == "acc_1":
                v = np.gradient(self.omega_m, self.h, axis=0)
            else:
                raise KeyError(name)
            self._cache[key] = v
        return self._cache[key]


def per_axis(value, drives: int) -> tuple[float, ...]:
    """A measurement parameter as one value per drive (a scalar applies to every drive)."""
    return tuple(float(x) for x in np.broadcast_to(np.asarray(value, dtype=float), (drives,)))


@dataclass
class Chain:
    """The observation chain: FMU measurement model (per axis), then the documented drive filter, then sampling;
    ``drives`` columns (one per actuator)."""

    h: float
    drive_T: float
    drive_delay: float
    drives: int
    T_meas: tuple = (0.0,)
    delay_meas: tuple = (0.0,)
    tau_offset: tuple = (0.0,)

    def __post_init__(self) -> None:
        for name in MEASUREMENT_PARAMETERS:
            setattr(self, name, per_axis(getattr(self, name), self.drives))
        for name in ("T_meas", "delay_meas"):
            bad = [j + 1 for j, v in enumerate(getattr(self, name)) if not v >= 0.0]
            if bad:
                raise ValueError(f"{name} of actuator(s) {bad}: {getattr(self, name)} s; expected >= 0")

    def linear(self, u: np.ndarray) -> np.ndarray:
        """The linear part (no offset) on the base grid; u (m, drives), one column per actuator."""
        out = np.empty_like(np.asarray(u, dtype=float))
        groups: dict = {}
        for j, key in enumerate(zip(self.T_meas, self.delay_meas)):
            groups.setdefault(key, []).append(j)
        for (T, d), cols in groups.items():
            out[:, cols] = measure(u[:, cols], self.h, T, d, 0.0, axis=0)
        return measure(out, self.h, self.drive_T, self.drive_delay, 0.0, axis=0)

    def observe(self, tau_m: np.ndarray) -> np.ndarray:
        return self.linear(tau_m) + np.asarray(self.tau_offset)

    def with_(self, **changes) -> "Chain":
        d = dict(self.__dict__)
        d.update(changes)
        return Chain(**d)


def chain_for(params: Mapping, h: float, drive_T: float, drive_delay: float, drives: int) -> Chain:
    """The chain of a parameter set on ``drives`` actuators: the all-axes measurement values plus each axis's
    increments."""
    values = {
        p: tuple(float(params[p]) + float(params.get(f"{p}_axis{j}", 0.0)) for j in range(1, drives + 1))
        for p in MEASUREMENT_PARAMETERS
    }
    return Chain(h, drive_T, drive_delay, drives, **values)


# --------------------------------------------------------------------------------------
# columns: d(observed torque) / d(first parameter), on the base grid, before the chain
# --------------------------------------------------------------------------------------
def _col_coulomb(s: SimSignals, p: Mapping, grid: Optional[float]) -> np.ndarray:
    return np.tanh(s.derived("omega_N", p) / float(p["omega_c"]))


def _col_viscous(s: SimSignals, p: Mapping, grid: Optional[float]) -> np.ndarray:
    return s.derived("omega_N", p)


def _col_stribeck(s: SimSignals, p: Mapping, grid: Optional[float]) -> np.ndarray:
    w = s.derived("omega_N", p)
    ws = float(grid if grid is not None else p["omega_s"])
    return np.exp(-((w / ws) ** 2)) * np.tanh(w / float(p["omega_c"]))


def _col_omega_s(s: SimSignals, p: Mapping, grid: Optional[float]) -> np.ndarray:
    w = s.derived("omega_N", p)
    ws = float(p["omega_s"])
    return float(p["tau_s"]) * np.exp(-((w / ws) ** 2)) * 2.0 * w**2 / ws**3 * np.tanh(w / float(p["omega_c"]))


def _col_inertia_motor(s: SimSignals, p: Mapping, grid: Optional[float]) -> np.ndarray:
    J1, _ = two_inertia(p)
    return J1 / float(p["J1_scale"]) * s.derived("acc_1", p)


def _col_inertia_guide(s: SimSignals, p: Mapping, grid: Optional[float]) -> np.ndarray:
    return s.derived("acc_N", p) / float(p["i_r"]) ** 2


def _col_mass(s: SimSignals, p: Mapping, grid: Optional[float]) -> np.ndarray:
    i_R = transmission_ratio(p["p"], p["i_r"])
    return i_R**2 * s.derived("acc_N", p) + i_R * float(p["g_guide"])


#: plant columns per parameter (for the Jacobian of the fit)
PLANT_COLUMNS: dict[str, Callable] = {
    "tau_c": _col_coulomb,
    "b_v": _col_viscous,
    "tau_s": _col_stribeck,
    "omega_s": _col_omega_s,
    "J1_scale": _col_inertia_motor,
    "J_guide": _col_inertia_guide,
    "M_load": _col_mass,
}


@dataclass(frozen=True)
class Effect:
    key: str
    title: str
    parameters: tuple[str, ...]  # FMU parameters (the first one is the regression coefficient)
    kind: str  # "plant", "controller" (re-simulated like the plant) or "measurement"
    signature: str
    bounds: dict[str, tuple[float, float]]
    regression: bool = True  # False: scored by re-simulation only (no linear selection)
    phase_free: bool = False  # scored by the phase-free score (phasefree.py), not sample by sample
    scan: tuple[float, ...] = ()  # phase-free effects: the values of the first scan (log-spaced, ratio 2)
    step: float = 0.0  # plant effects: parameter step of the re-simulated sensitivity
    group: Optional[str] = None  # effects in one group are alternatives (not separable)
    preferred: bool = True  # within a group: the one named when the data cannot tell
    grid: tuple[float, ...] = ()  # values of the second (nonlinear) parameter tried in the regression
    cost: int = 1  # parameters counted by the information criterion
    refines: Optional[str] = None  # an asymmetry of this effect: tried only once it is named
    quantum: Optional[str] = None  # a discrete parameter: integer multiples (>= 1) of this one (a cycle time)
    after_stand_ins: bool = False  # re-simulation only, tried when the check "named only if explained" has
    #                                      refused stand-ins: its trace in the band is what the linear effects mimic

    @property
    def parameter(self) -> str:
        return self.parameters[0]


LIBRARY: tuple[Effect, ...] = (
    Effect(
        "coulomb",
        "Coulomb friction",
        ("tau_c",),
        "plant",
        "in phase with sign(velocity), flat in frequency, a square wave (3rd/1st harmonic about 1/3), "
        "dominant at low frequency",
        {"tau_c": (0.0, 1.0)},
        step=0.01,
    ),
    Effect(
        "viscous",
        "viscous friction",
        ("b_v",),
        "plant",
        "in phase with velocity, amplitude grows with f",
        {"b_v": (0.0, 0.05)},
        step=1e-4,
    ),
    Effect(
        "stribeck",
        "Stribeck friction",
        ("tau_s", "omega_s"),
        "plant",
        "at low speed, right after velocity reversals; decays within omega_s of standstill",
        {"tau_s": (0.0, 0.5), "omega_s": (0.6, 40.0)},
        regression=False,
        cost=2,
    ),
    Effect(
        "inertia_motor",
        "inertia mismatch, motor side",
        ("J1_scale",),
        "plant",
        "in phase with acceleration, amplitude grows with f^2",
        {"J1_scale": (0.05, 20.0)},
        group="inertia",
        preferred=True,
        step=-0.1,
    ),
    Effect(
        "inertia_guide",
        "inertia mismatch, guide side",
        ("J_guide",),
        "plant",
        "in phase with acceleration, amplitude grows with f^2 (same as the motor side below the "
        "transmission resonance)",
        {"J_guide": (1e-7, 0.02)},
        group="inertia",
        preferred=False,
        step=1e-4,
    ),
    Effect(
        "carriage_mass",
        "carriage or payload mass",
        ("M_load",),
        "plant",
        "in phase with acceleration plus a bias (the weight) in the fixed ratio g",
        {"M_load": (0.01, 100.0)},
        step=0.5,
    ),
    Effect(
        "velocity_gain",
        "velocity-loop gain of the drive (controller side)",
        ("k_p",),
        "controller",
        "the loop follows less (or more) tightly: a torque change in phase with the tracking error, "
        "largest at the higher frequencies",
        {"k_p": (0.005, 0.5)},
        step=-0.1 * 0.062,
    ),
    Effect(
        "position_gain",
        "position-loop gain of the drive (controller side)",
        ("k_v",),
        "controller",
        "a slower (or faster) position loop: tracking error and torque phase change at low frequency",
        {"k_v": (1.0, 200.0)},
        step=-0.1 * 21.5,
    ),
    Effect(
        "velocity_integral",
        "velocity-loop integral gain of the drive (controller side)",
        ("k_i",),
        "controller",
        "the loop recovers its speed error more slowly (or faster): a torque change lagging the tracking "
        "error, largest around the cascade's bandwidth",
        {"k_i": (0.01, 200.0)},
        step=-0.1 * 3.79,
    ),
    Effect(
        "velocity_cycle",
        "velocity-loop cycle time of the drive (controller side)",
        ("T_vel",),
        "controller",
        "more (or less) delay inside the velocity loop: its phase margin changes, a torque change growing "
        "with f (a multiple of the current-loop cycle T_cur)",
        {"T_vel": (1e-4, 0.02)},
        step=1e-3,
        quantum="T_cur",
    ),
    Effect(
        "current_limit",
        "current limit of the drive (controller side)",
        ("i_max",),
        "controller",
        "the torque is flat-topped at k_T i_max wherever the model's exceeds it (the peaks of the fastest "
        "tests); no effect below the limit",
        {"i_max": (0.05, 100.0)},
        regression=False,
    ),
    Effect(
        "stiffness",
        "transmission stiffness (two-inertia spring)",
        ("K_t",),
        "plant",
        "a softer (or stiffer) transmission: the guide lags the motor by the spring's deflection (a phase lag "
        "inside the position loop, growing with f, which gains, cycle times and inertia mimic in the band), and "
        "the transmission mode sqrt(K_t (J1 + J2) / (J1 J2)) moves",
        {"K_t": (1.0, 1000.0)},
        regression=False,
        after_stand_ins=True,
    ),
    Effect(
        "offset",
        "constant torque offset",
        ("tau_offset",),
        "measurement",
        "a bias, the same in every test",
        {"tau_offset": (-1.0, 1.0)},
    ),
    Effect(
        "lag",
        "measurement low-pass filter or delay",
        ("T_meas",),
        "measurement",
        "phase lag growing with frequency (a filter and a delay look alike at low f)",
        {"T_meas": (0.0, 0.05), "delay_meas": (0.0, 0.05)},
    ),
    Effect(
        "backlash",
        "backlash",
        ("backlash",),
        "plant",
        "at torque reversals: the motor crosses the dead zone unloaded, then an impact",
        {"backlash": (0.0, 0.2)},
        regression=False,
        phase_free=True,
        scan=tuple(5e-4 * 2.0**k for k in range(8)),
    ),
)
#: effects available on one axis (a worn guide, one heavier carriage, one drive's torque reading): the
#: change of the all-axes parameter on axis j only, parameter "<name>_axis<j>" (an increment added to that
#: actuator's value; 0 = nominal). Their regression column is the all-axes effect's re-simulated
#: sensitivity restricted to axis j where that is computed (the axis's own closed-loop reaction; the
#: mechanism's coupling to the other axes is second order), else the signature on axis j; the fit
#: re-simulates. They cost one parameter each, so when the axes agree the all-axes effect (one
#: parameter) wins on BIC. Inertia on the two sides of one axis's transmission are alternatives, as
#: for all axes (group "inertia_axis<j>"). The platform payload is not in this list: under rotation it
#: loads every actuator through the mechanism, not as a mass on one carriage.
PER_AXIS = ("tau_c", "b_v", "J1_scale", "J_guide", "M_load", "tau_offset", "T_meas")
#: the most drives a mechanism has: one per pose component (a fully actuated mechanism, topology.py)
MAX_DRIVES = len(POSE)


def _per_axis(e: Effect, j: int) -> Effect:
    bounds = {f"{p}_axis{j}": (-hi, hi) for p, (lo, hi) in e.bounds.items()}
    return Effect(
        f"{e.key}_axis{j}",
        f"{e.title}, axis {j} only",
        tuple(f"{p}_axis{j}" for p in e.parameters),
        e.kind,
        f"{e.signature}; on actuator {j} only",
        bounds,
        step=e.step,
        group=f"{e.group}_axis{j}" if e.group else None,
        preferred=e.preferred,
    )


LIBRARY = LIBRARY + tuple(_per_axis(e, j) for e in LIBRARY if e.parameter in PER_AXIS for j in range(1, MAX_DRIVES + 1))
BY_KEY = {e.key: e for e in LIBRARY}
BY_PARAMETER = {p: e for e in LIBRARY for p in e.parameters}
BOUNDS = {name: b for e in LIBRARY for name, b in e.bounds.items()}
#: per-axis parameter -> (the all-axes parameter, 0-based axis)
AXIS_OF: dict[str, tuple[str, int]] = {
    name: (name.rsplit("_axis", 1)[0], int(name[-1]) - 1) for name in BOUNDS if "_axis" in name
}
#: every parameter of the measurement model, all-axes and per axis (no re-simulation when they change)
MEASUREMENT = frozenset(MEASUREMENT_PARAMETERS) | {k for k, (p, _) in AXIS_OF.items() if p in MEASUREMENT_PARAMETERS}


def drive_of(key: str) -> Optional[int]:
    """The drive (1-based) an effect or parameter of one axis acts on ("..._axis<j>"), None for all axes."""
    return int(key.rsplit("_axis", 1)[1]) if "_axis" in key else None


def for_drives(keys: Sequence[str], drives: int) -> list[str]:
    """The effects of ``keys`` a system with ``drives`` actuators has: all-axes effects and those of its own axes.

    The library holds per-axis effects for every drive a mechanism can have (``MAX_DRIVES``): those of drives the
    system lacks are left out when ``keys`` hold all of them (the whole library), and refused (ValueError naming
    them) when some are named on their own."""
    kept = [k for k in keys if (drive_of(k) or 0) <= drives]
    beyond = sorted(k for k in keys if k not in kept)
    if beyond and beyond != sorted(e.key for e in LIBRARY if (drive_of(e.key) or 0) > drives):
        raise ValueError(f"effects {', '.join(beyond)}: the system has {drives} drives (actuator_1..{drives})")
    return kept


def physical_bounds(name: str, nominal: Mapping, own: Optional[tuple[float, float]] = None) -> tuple[float, float]:
    """Bounds of a parameter: ``own`` (its effect's; default: the library's), and for a per-axis increment
    also those that keep the axis's value physical (the all-axes parameter's bounds about its nominal
    value: a lag or a friction never below 0 on one axis, an inertia or a mass never below its floor)."""
    lo, hi = own if own is not None else BOUNDS[name]
    if name in AXIS_OF:
        base = AXIS_OF[name][0]
        v0 = float(nominal[base])
        lo, hi = max(lo, BOUNDS[base][0] - v0), min(hi, BOUNDS[base][1] - v0)
    return lo, hi


def axis_values(plant: Mapping[str, float], nominal: Mapping, j: int) -> dict[str, float]:
    """The parameters of actuator j (0-based): the all-axes values plus that axis's increments."""
    out = {k: v for k, v in plant.items() if k not in AXIS_OF}
    for k, v in plant.items():
        if k in AXIS_OF and AXIS_OF[k][1] == j:
            base = AXIS_OF[k][0]
            out[base] = float(plant.get(base, nominal[base])) + float(v)
    return out


#: The library of a drive axis seen from the load, force-driven (fmus/actuator/load_axis.py: single-axis
#: benches such as EMPS). The effort compared is the drive force; columns d F / d parameter (axis_column)
#: are the inverse-dynamics signatures along the simulated motion. The asymmetries refine a named
#: friction: dF_c differs from the offset only at standstill (both shift the force by a constant while
#: the axis moves), so the two are alternatives and the offset is preferred when the data cannot tell.
AXIS_LIBRARY: tuple[Effect, ...] = (
    Effect(
        "mass", "moving mass", ("M",), "plant", "in phase with acceleration (the bang-bang phases)", {"M": (0.1, 1e4)}
    ),
    Effect(
        "viscous",
        "viscous friction",
        ("F_v",),
        "plant",
        "in phase with velocity (the constant-velocity plateaus, growing with speed)",
        {"F_v": (0.0, 1e5)},
    ),
    Effect(
        "coulomb",
        "Coulomb friction",
        ("F_c",),
        "plant",
        "in phase with sign(velocity): a step at every reversal, the same on every plateau",
        {"F_c": (0.0, 1e4)},
    ),
    Effect(
        "offset",
        "constant force offset",
        ("F_offset",),
        "plant",
        "a bias, moving or not",
        {"F_offset": (-1e4, 1e4)},
        group="bias",
        preferred=True,
    ),
    Effect(
        "viscous_asymmetry",
        "asymmetric viscous friction",
        ("dF_v",),
        "plant",
        "in phase with |velocity|: the plateaus of one direction need more force per speed than the other",
        {"dF_v": (-1e5, 1e5)},
        refines="viscous",
    ),
    Effect(
        "coulomb_asymmetry",
        "asymmetric Coulomb friction",
        ("dF_c",),
        "plant",
        "a bias while moving, none at standstill (the same as an offset while the axis moves)",
        {"dF_c": (-1e4, 1e4)},
        refines="coulomb",
        group="bias",
        preferred=False,
    ),
)


def axis_column(param: str, q_dot: np.ndarray, q_ddot: np.ndarray) -> np.ndarray:
    """d F / d parameter of the load-side axis along a motion (q_dot [m/s], q_ddot [m/s^2]): the inverse
    dynamics F = M q'' + F_f(q') + F_offset differentiated (load_axis.py)."""
    s = np.sign(q_dot)
    columns = {
        "M": q_ddot,
        "F_v": q_dot,
        "F_c": s,
        "F_offset": np.ones_like(q_dot),
        "dF_v": np.abs(q_dot),
        "dF_c": np.abs(s),
    }
    if param not in columns:
        raise KeyError(f"no load-axis column for parameter {param!r}; known: {', '.join(columns)}")
    return columns[param]


def column(
    effect_or_param: str,
    signals: SimSignals,
    params: Mapping,
    chain: Chain,
    grid: Optional[float] = None,
    eps: float = 2e-4,
) -> np.ndarray:
    """d tau_obs / d parameter on the base grid (through the chain), for a plant or measurement parameter
    (all axes, or "<name>_axis<j>": that axis's column, zero on the others)."""
    base, axes = (
        (AXIS_OF[effect_or_param][0], [AXIS_OF[effect_or_param][1]])
        if effect_or_param in AXIS_OF
        else (effect_or_param, list(range(chain.drives)))
    )
    if base in PLANT_COLUMNS:
        c = PLANT_COLUMNS[base](signals, params, grid)
    elif base == "tau_offset":
        c = np.ones_like(signals.tau_m)
    elif base in ("T_meas", "delay_meas"):
        v = np.array(getattr(chain, base))
        lo = v.copy()
        lo[axes] = np.maximum(0.0, v[axes] - eps)
        hi = v.copy()
        hi[axes] = lo[axes] + 2 * eps
        c = (
            chain.with_(**{base: tuple(hi)}).linear(signals.tau_m)
            - chain.with_(**{base: tuple(lo)}).linear(signals.tau_m)
        ) / (2 * eps)
    else:
        raise KeyError(f"no regression column for parameter {effect_or_param!r}")
    if len(axes) < chain.drives:
        only = np.zeros_like(c)
        only[:, axes] = c[:, axes]
        c = only
    return chain.linear(c) if base in PLANT_COLUMNS else c


# --------------------------------------------------------------------------------------
# signal analysis
# --------------------------------------------------------------------------------------
def noise_std(y: np.ndarray) -> float:
    """Standard deviation of white measurement noise from third differences (robust: MAD).

    The third difference of white noise has variance 20 sigma^2; a smooth signal sampled
    well above its bandwidth contributes (omega dt)^3 of its amplitude; steps (friction
    reversals) are outliers the median ignores.
    """
    d = np.diff(np.asarray(y, dtype=float), n=3, axis=0).ravel()
    mad = np.median(np.abs(d - np.median(d)))
    return float(1.4826 * mad / math.sqrt(20.0))


def nrmse(y: np.ndarray, yhat: np.ndarray) -> float:
    """||y - yhat|| / ||y - mean(y)|| (columns: one mean per actuator)."""
    y = np.asarray(y)
    den = float(np.linalg.norm(y - y.mean(axis=0)))
    return float(np.linalg.norm(y - yhat)) / den if den > 0 else float("nan")


def harmonic(t: np.ndarray, y: np.ndarray, f: float) -> complex:
    """Complex amplitude of y at f (least squares with an offset), over whole periods of t."""
    w = 2.0 * math.pi * f
    T = 1.0 / f
    n_per = math.floor((t[-1] - t[0]) / T + 1e-9)
    if n_per < 1:
        keep = np.ones_like(t, dtype=bool)
    else:
        keep = t <= t[-1] - ((t[-1] - t[0]) - n_per * T) + 1e-12
    tt, yy = t[keep], y[keep]
    basis = np.column_stack([np.ones_like(tt), np.cos(w * tt), np.sin(w * tt)])
    c = np.linalg.lstsq(basis, yy, rcond=None)[0]
    return complex(c[1], -c[2])


def localise(
    t: np.ndarray, r: np.ndarray, omega: np.ndarray, acc: np.ndarray, frequency: Optional[float], sigma: float
) -> dict:
    """Where in the cycle the residual r (samples, drives) concentrates.

    Energy shares of the residual near velocity reversals (|omega| < 15 % of its peak) and
    near peak acceleration (|acc| > 70 % of its peak), against the share of time spent
    there (concentration = share of energy / share of time), the bias share, the
    correlation with sign(velocity), velocity and acceleration, and for sine tests the
    residual's harmonics.
    """
    e = r**2
    total = float(e.sum()) or 1e-300
    out: dict = {
        "rms": float(np.sqrt(e.mean())),
        "rms_over_noise": float(np.sqrt(e.mean()) / sigma) if sigma > 0 else None,
    }
    zones = {
        "velocity reversals": np.abs(omega) < 0.15 * np.abs(omega).max(axis=0),
        "peak acceleration": np.abs(acc) > 0.7 * np.abs(acc).max(axis=0),
    }
    for name, mask in zones.items():
        share_e = float(e[mask].sum()) / total
        share_t = float(mask.mean())
        out[name] = {
            "energy_share": round(share_e, 4),
            "time_share": round(share_t, 4),
            "concentration": round(share_e / share_t, 3) if share_t > 0 else None,
        }
    out["bias_share"] = round(float((r.mean(axis=0) ** 2).sum() / (e.mean(axis=0).sum() or 1e-300)), 4)

    def corr(a: np.ndarray) -> float:
        a = a - a.mean(axis=0)
        rr = r - r.mean(axis=0)
        den = float(np.linalg.norm(a) * np.linalg.norm(rr))
        return round(float((a * rr).sum()) / den, 3) if den > 0 else 0.0

    out["correlation"] = {"sign(velocity)": corr(np.sign(omega)), "velocity": corr(omega), "acceleration": corr(acc)}
    if frequency:
        h1 = [harmonic(t, r[:, j], frequency) for j in range(r.shape[1])]
        h3 = [harmonic(t, r[:, j], 3 * frequency) for j in range(r.shape[1])]
        a1 = float(np.mean([abs(c) for c in h1]))
        out["harmonic_1"] = a1
        out["harmonic_3_over_1"] = round(float(np.mean([abs(c) for c in h3])) / a1, 3) if a1 > 0 else None
    words = []
    for name in zones:
        c = out[name]["concentration"]
        if c is not None and c > 1.5:
            words.append(f"concentrates at {name} ({c:.1f} x its share of time)")
    if out["bias_share"] > 0.5:
        words.append("mostly a bias")
    best = max(out["correlation"].items(), key=lambda kv: abs(kv[1]))
    if abs(best[1]) > 0.5:
        words.append(f"follows {best[0]} (correlation {best[1]:+.2f})")
    out["summary"] = "; ".join(words) if words else "no concentration (spread over the cycle)"
    return out


def frequency_slope(freqs: Sequence[float], amps: Sequence[float]) -> Optional[float]:
    """Slope of log(residual harmonic amplitude) against log(f): 0 flat, 1 grows with f, 2 with f^2."""
    pts = [(math.log(f), math.log(a)) for f, a in zip(freqs, amps) if f and a and a > 0]
    if len(pts) < 2:
        return None
    x, y = np.array(pts).T
    return float(np.polyfit(x, y, 1)[0])
