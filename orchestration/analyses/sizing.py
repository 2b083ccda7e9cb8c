"""Drive sizing: what a run asked of each drive against its datasheet ratings (``mast sizing``).

Per drive k (``actuator_k``), from the recorded motor torque tau_m, speed omega_m and current i_m,
over the duty cycle (the run's last whole periods of its sine, repeated; the whole run when it is
not periodic):

motor      RMS torque against the nominal (max. continuous) torque tau_N; the same with the
           gearhead's losses (the model's gearhead is lossless: a real one at efficiency eta needs
           tau_in / eta from the motor while it drives the load, tau_in eta while the load drives it);
           RMS current against the nominal current i_N; peak torque against the stall torque;
           peak speed against the max. permissible speed; the winding's peak temperature with the
           duty cycle repeated to steady state (``thermal``) against its maximum
gearhead   output torque tau_out = i_r (tau_m - J_in domega_m/dt), J_in = J1_scale (J_motor + J_brake +
           J_gearbox) the inertia ahead of its output: RMS against the continuous rating, peak against
           the intermittent one; peak input speed against its maximum
guide      the belt's axial force 2 pi tau_out / p (the gearhead's output torque at the toothed-belt
           axis's pulley) against its maximum; the carriage speed omega_m p / (2 pi i_r) against its maximum
           (a belt axis has no screw whirling speed)
amplifier  RMS current against its continuous current, peak current (and the controller's current
           command, where recorded) against its peak current

Margin = 1 - figure / limit (the temperature's: of the rise above ambient). An item passes below its limit, is "at
limit" on it (a drive that
holds its current at the amplifier's peak: the motion asked for more than the drive gives), and
fails above it. The verdict: fail if any item fails, at limit if any is on its limit, else pass;
the limiting item is the one with the smallest margin.

The ratings are a parameter set the system names per actuator (an annotation, ``mast.core.ssp``);
the motor's R, k_T, k_E, u_supply, inertias and the ratio i_r and feed p are the actuator's own
parameters, as the run bound them (with its ``--set`` overrides, recorded in summary.json).
"""

from __future__ import annotations

import io
import json
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping, Optional, Sequence, Union

import numpy as np

from fmus.common.parameters import Value

from ..core.atomic import atomic_write
from ..core.specimen import Specimen, with_specimen
from ..core.ssp import SSPArchive, SystemSpec, read_ssd
from ..core.ssv import SSPFormatError, parse_ssv
from ..core.units import UnitError, parse_unit
from . import thermal

#: the ratings a drive's set must give: name, unit (values are read in its coherent SI unit), what it is
RATINGS: tuple[tuple[str, str, str], ...] = (
    ("tau_N", "N.m", "motor nominal (max. continuous) torque"),
    ("i_N", "A", "motor nominal (max. continuous) current"),
    ("tau_stall", "N.m", "motor stall torque"),
    ("n_max", "rad/s", "motor max. permissible speed"),
    ("R_th1", "K/W", "thermal resistance winding-housing"),
    ("R_th2", "K/W", "thermal resistance housing-ambient"),
    ("tau_w", "s", "winding thermal time constant"),
    ("tau_s", "s", "motor thermal time constant"),
    ("T_w_max", "K", "max. winding temperature"),
    ("T_ambient", "K", "ambient temperature"),
    ("alpha_Cu", "1/K", "temperature coefficient of the winding resistance"),
    ("tau_gear_cont", "N.m", "gearhead max. continuous output torque"),
    ("tau_gear_int", "N.m", "gearhead max. intermittent output torque"),
    ("n_gear_max", "rad/s", "gearhead max. input speed"),
    ("eta_gear", "1", "gearhead efficiency"),
    ("F_guide_max", "N", "linear guide max. axial (drive) force"),
    ("v_guide_max", "m/s", "linear guide max. carriage speed"),
    ("i_amp_cont", "A", "amplifier continuous current"),
    ("i_amp_peak", "A", "amplifier peak current"),
)
#: the actuator's own parameters the analysis needs
ACTUATOR = ("R", "k_T", "k_E", "u_supply", "i_r", "p", "J_motor", "J_brake", "J_gearbox", "J1_scale")
SIGNALS = ("tau_m", "omega_m", "i_m")
AT_LIMIT = 1e-6  # relative: a figure this close to its limit is on it
RPM = 60.0 / (2.0 * math.pi)
FILES = ("sizing.json", "sizing.md", "sizing_envelope.png", "sizing_temperature.png")


class SizingError(ValueError):
    """A run or a system that cannot be sized: what is missing, named."""


@dataclass(frozen=True)
class Drive:
    """What sizing knows of one drive: its ratings [coherent SI] and its actuator's parameters."""

    name: str
    ratings: dict[str, float]
    actuator: dict[str, float]
    source: str = ""

    def thermal_model(self) -> thermal.TwoNode:
        r = self.ratings
        return thermal.TwoNode(
            r["R_th1"], r["R_th2"], r["tau_w"], r["tau_s"], self.actuator["R"], r["alpha_Cu"], r["T_ambient"]
        )


@dataclass
class Item:
    """One line of the margin table: a figure of the run against its rating, both in ``unit``."""

    component: str
    name: str
    figure: float  # in the display unit
    limit: float
    unit: str
    base: float = 0.0  # the margin is taken from here (a temperature: the rise above ambient)

    @property
    def margin(self) -> float:
        return 1.0 - (self.figure - self.base) / (self.limit - self.base)

    @property
    def status(self) -> str:
        if self.figure > self.limit * (1.0 + AT_LIMIT):
            return "fail"
        return "at limit" if self.figure >= self.limit * (1.0 - AT_LIMIT) else "pass"

    def row(self) -> dict:
        return {
            "component": self.component,
            "item": self.name,
            "figure": self.figure,
            "limit": self.limit,
            "unit": self.unit,
            "margin": self.margin,
            "status": self.status,
        }


@dataclass
class DriveSizing:
    """One drive sized: its items, the window they were taken over, what the plots draw."""

    drive: Drive
    items: list[Item]
    periodic: bool
    window: tuple[float, float]
    points: dict = field(default_factory=dict)  # |tau_m| [N m], |omega_m| [rad/s] over the window
    heat: Optional[thermal.Periodic] = None
    heat_run: Optional[tuple[np.ndarray, np.ndarray, np.ndarray]] = None  # (t, T_w, T_s) over the run, from ambient

    @property
    def limiting(self) -> Item:
        return min(self.items, key=lambda item: item.margin)


# ----------------------------------------------------------------------------- inputs
def drives(
    system: SystemSpec,
    parameters: Optional[Mapping[str, Mapping[str, Value]]] = None,
    names: Optional[Sequence[str]] = None,
) -> dict[str, Drive]:
    """The drives of ``system`` (its ``actuator_<k>`` components, or ``names``): ratings and parameters.

    Raises SizingError naming the drive and what is missing: no ratings set named, a rating not in it,
    a rating in a unit of another dimension, an actuator parameter not bound."""
    names = (
        list(names) if names is not None else sorted(n for n in system.components if re.fullmatch(r"actuator_\d+", n))
    )
    if not names:
        raise SizingError(f"system {system.name}: no drives (components named actuator_<k>) to size")
    out = {}
    for name in names:
        spec = system.components.get(name)
        if spec is None:
            raise SizingError(f"system {system.name}: no component '{name}' to size")
        if not spec.ratings:
            raise SizingError(
                f"drive {name}: system {system.name} names no ratings for it (an annotation of type "
                "'mast.sizing' with <mast:Ratings source=\"resources/....ssv\"/>, docs/sizing.md)"
            )
        try:
            values = parse_ssv(system.root / spec.ratings, origin=spec.ratings)
        except (OSError, SSPFormatError) as err:
            raise SizingError(f"drive {name}: its ratings {spec.ratings} cannot be read: {err}") from None
        missing = [r for r, _, _ in RATINGS if r not in values]
        if missing:
            raise SizingError(
                f"drive {name}: its ratings {spec.ratings} lack "
                + ", ".join(f"{r} ({what}, {unit})" for r, unit, what in RATINGS if r in missing)
            )
        ratings = {}
        for r, unit, _ in RATINGS:
            p = values[r]
            expected = parse_unit(unit)
            given = p.si if p.si is not None else parse_unit("1")
            if given.dims != expected.dims or not isinstance(p.value, float):
                raise SizingError(
                    f"drive {name}: rating {r} in {spec.ratings} is {p.value!r} {p.unit or '(no unit)'}; "
                    f"expected a Real in {unit} or a unit of its dimension"
                )
            ratings[r] = float(p.value)
        bound = {**spec.parameters, **(parameters or {}).get(name, {})}
        lacking = [k for k in ACTUATOR if k not in bound]
        if lacking:
            raise SizingError(f"drive {name}: system {system.name} binds no {', '.join(lacking)} for it")
        out[name] = Drive(name, ratings, {k: float(bound[k]) for k in ACTUATOR}, spec.ratings)
    return out


def read_results(path: Path) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """(time, {signal: values}) of a run's results.csv."""
    if not path.is_file():
        raise SizingError(f"{path.parent}: no results.csv (a run folder of `mast run` holds one)")
    with open(path, encoding="utf-8") as handle:
        header = handle.readline().strip().split(",")
    if not header or header[0] != "time":
        raise SizingError(f"{path}: the first column is {header[0]!r}, expected 'time'")
    try:
        table = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    except ValueError as err:
        raise SizingError(f"{path}: not a table of numbers ({err})") from None
    if table.shape[0] < 2:
        raise SizingError(f"{path}: {table.shape[0]} sample(s); sizing needs a run of at least two")
    return table[:, 0], {name: table[:, k] for k, name in enumerate(header[1:], start=1)}


_JSON_TYPES = (
    (bool, "a boolean"),
    (str, "a string"),
    ((int, float), "a number"),
    (list, "an array"),
    (dict, "an object"),
)


def _json_type(value) -> str:
    return next((name for kinds, name in _JSON_TYPES if isinstance(value, kinds)), "null")


def _field(path: Path, doc: Mapping, key: str, where: str, kind: str):
    """``doc[key]`` (None if absent or null) when its JSON type is ``kind`` ("a string", "a number", "an object"),
    else SizingError naming the file, the field ``where + key`` and both types."""
    value = doc.get(key)
    if value is not None and _json_type(value) != kind:
        raise SizingError(f"{path}: field '{where}{key}' is {_json_type(value)} ({value!r:.60}): expected {kind}")
    return value


def read_summary(path: Path) -> tuple[Optional[str], dict[str, dict[str, Value]], float]:
    """(system.ssp, system.parameters, motion.frequency_Hz) of a run's summary.json, (None, {}, 0.0) for what it
    lacks (or without one); SizingError naming the file and the field when one is not of the JSON type `mast run`
    writes."""
    if not path.is_file():
        return None, {}, 0.0
    try:
        summary = json.loads(path.read_text())
    except json.JSONDecodeError as err:
        raise SizingError(f"{path}: not JSON ({err})") from None
    if not isinstance(summary, dict):
        raise SizingError(f"{path}: the document is {_json_type(summary)}: expected an object (what `mast run` writes)")
    system = _field(path, summary, "system", "", "an object") or {}
    ssp = _field(path, system, "ssp", "system.", "a string")
    parameters = _field(path, system, "parameters", "system.", "an object") or {}
    for component, values in parameters.items():
        _field(path, parameters, component, "system.parameters.", "an object")
        for name, value in (values or {}).items():
            if _json_type(value) not in ("a number", "a string", "a boolean"):
                raise SizingError(
                    f"{path}: field 'system.parameters.{component}.{name}' is {_json_type(value)}: expected a "
                    "number, a string or a boolean"
                )
    motion = _field(path, summary, "motion", "", "an object") or {}
    frequency = _field(path, motion, "frequency_Hz", "motion.", "a number") or 0.0
    if not math.isfinite(frequency) or frequency < 0:
        raise SizingError(f"{path}: field 'motion.frequency_Hz' is {frequency!r}: expected a finite number >= 0 (Hz)")
    return ssp, {c: dict(v or {}) for c, v in parameters.items()}, float(frequency)


def duty_cycle(t: np.ndarray, frequency: float) -> Optional[slice]:
    """The samples of the run's last whole periods of a sine at ``frequency`` [Hz] (the first period dropped as
    the start's transient when the run holds two or more; as many periods as make a whole number of samples,
    3 at 3 Hz and 1 ms, else the nearest sample), or None when the run is not periodic (f = 0) or shorter than
    a period."""
    if not frequency or frequency <= 0:
        return None
    h = float(np.median(np.diff(t)))
    per_period = 1.0 / (frequency * h)
    periods = math.floor((len(t) + 1e-6) / per_period)
    if periods < 1:
        return None
    keep = max(1, periods - 1)
    whole = [m for m in range(keep, 0, -1) if abs(m * per_period - round(m * per_period)) <= 1e-6 * per_period]
    n = round((whole[0] if whole else keep) * per_period)
    return slice(len(t) - n, len(t)) if n >= 1 else None


# ----------------------------------------------------------------------------- the analysis
def size_drive(
    drive: Drive,
    t: np.ndarray,
    tau_m: np.ndarray,
    omega_m: np.ndarray,
    i_m: np.ndarray,
    cycle: Optional[slice] = None,
    i_cmd: Optional[np.ndarray] = None,
) -> DriveSizing:
    """The items of one drive from its signals over the run (``cycle``: the duty cycle's samples, repeated to
    steady state for the temperature; None: the run as it is, from ambient). ``i_cmd``: the controller's
    current command, if recorded: its peak against the amplifier's peak current (at limit where the
    controller asks for all the drive gives)."""
    r, a = drive.ratings, drive.actuator
    J_in = a["J1_scale"] * (a["J_motor"] + a["J_brake"] + a["J_gearbox"])
    alpha = np.gradient(omega_m, t)
    window = cycle or slice(0, len(t))
    tw, tau, om, cur, acc = t[window], tau_m[window], omega_m[window], i_m[window], alpha[window]
    tau_in = tau - J_in * acc  # at the gearhead's input
    tau_out = a["i_r"] * tau_in  # at its output (the model's gearhead is lossless)
    driving = tau_in * om >= 0.0
    eta = r["eta_gear"]
    tau_lossy = J_in * acc + np.where(driving, tau_in / eta, tau_in * eta)
    F_belt = 2.0 * math.pi * tau_out / a["p"]
    v = om * a["p"] / (2.0 * math.pi * a["i_r"])
    model = drive.thermal_model()
    heat = heat_run = None
    if cycle is not None:
        heat = thermal.periodic(model, tw, cur)
        T_w_peak = float(heat.T_w.max())
    else:
        T_w, T_s = thermal.run(model, t, i_m)
        heat_run = (t, T_w, T_s)
        T_w_peak = float(T_w.max())
    C = 273.15
    items = [
        Item("motor", "RMS torque", _rms(tau), r["tau_N"], "N m"),
        Item("motor", "RMS torque, gearhead losses", _rms(tau_lossy), r["tau_N"], "N m"),
        Item("motor", "RMS current", _rms(cur), r["i_N"], "A"),
        Item("motor", "peak torque", _peak(tau), r["tau_stall"], "N m"),
        Item("motor", "peak speed", _peak(om) * RPM, r["n_max"] * RPM, "rpm"),
        Item(
            "motor",
            "winding temperature" + (", steady cycle" if cycle is not None else ", over the run"),
            T_w_peak - C,
            r["T_w_max"] - C,
            "degC",
            r["T_ambient"] - C,
        ),
        Item("gearhead", "RMS output torque", _rms(tau_out), r["tau_gear_cont"], "N m"),
        Item("gearhead", "peak output torque", _peak(tau_out), r["tau_gear_int"], "N m"),
        Item("gearhead", "peak input speed", _peak(om) * RPM, r["n_gear_max"] * RPM, "rpm"),
        Item("guide", "peak axial force", _peak(F_belt), r["F_guide_max"], "N"),
        Item("guide", "peak carriage speed", _peak(v), r["v_guide_max"], "m/s"),
        Item("amplifier", "RMS current", _rms(cur), r["i_amp_cont"], "A"),
        Item("amplifier", "peak current", _peak(cur), r["i_amp_peak"], "A"),
    ]
    if i_cmd is not None:
        items.append(Item("amplifier", "peak current command", _peak(i_cmd[window]), r["i_amp_peak"], "A"))
    return DriveSizing(
        drive,
        items,
        cycle is not None,
        (float(tw[0]), float(tw[-1])),
        {"tau": np.abs(tau), "omega": np.abs(om), "tau_rms": _rms(tau), "omega_rms": _rms(om)},
        heat,
        heat_run,
    )


def size_signals(
    drive_set: Mapping[str, Drive], t: np.ndarray, signals: Mapping[str, np.ndarray], frequency: float = 0.0
) -> list[DriveSizing]:
    """Every drive of ``drive_set`` from the recorded ``actuator_<k>.tau_m/omega_m/i_m`` (SizingError naming
    the signals not recorded), and ``controller.i_cmd_<k>`` where recorded."""
    missing = [f"{name}.{s}" for name in drive_set for s in SIGNALS if f"{name}.{s}" not in signals]
    if missing:
        raise SizingError(f"the run did not record {', '.join(missing)}, which sizing needs")
    cycle = duty_cycle(t, frequency)
    return [
        size_drive(
            d,
            t,
            *(signals[f"{name}.{s}"] for s in SIGNALS),
            cycle,
            signals.get(f"controller.i_cmd_{name.rsplit('_', 1)[-1]}"),
        )
        for name, d in drive_set.items()
    ]


def _rms(y: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(y))))


def _peak(y: np.ndarray) -> float:
    return float(np.max(np.abs(y)))


def verdict(sized: Sequence[DriveSizing]) -> dict:
    """{"verdict": pass / at limit / fail, "limiting": {drive, component, item, margin, ...}}."""
    statuses = {item.status for s in sized for item in s.items}
    worst = min(sized, key=lambda s: s.limiting.margin)
    return {
        "verdict": "fail" if "fail" in statuses else "at limit" if "at limit" in statuses else "pass",
        "limiting": {"drive": worst.drive.name, **worst.limiting.row()},
    }


def document(sized: Sequence[DriveSizing], run: str = "", ssp: str = "") -> dict:
    """What sizing.json holds."""
    return {
        **verdict(sized),
        "run": run,
        "ssp": ssp,
        "drives": {
            s.drive.name: {
                "ratings": s.drive.source,
                "duty_cycle": "steady cycle, repeated" if s.periodic else "the run, from ambient",
                "window_s": list(s.window),
                "verdict": verdict([s])["verdict"],
                "limiting": s.limiting.row(),
                "items": [item.row() for item in s.items],
                **(
                    {
                        "cycles_to_thermal_steady_state": s.heat.cycles_to_settle,
                        "time_to_thermal_steady_state_s": s.heat.cycles_to_settle * s.heat.cycle_s,
                        "time_to_max_winding_temperature_s": _time_to(s.heat, s.drive.ratings["T_w_max"]),
                    }
                    if s.heat
                    else {}
                ),
            }
            for s in sized
        },
    }


def _time_to(heat: thermal.Periodic, T_max: float) -> Optional[float]:
    """When the winding, the duty cycle repeated from ambient, first reaches ``T_max`` [K] at a cycle's start [s]
    (None: never). A cycle's peak comes earlier by less than a cycle."""
    above = np.nonzero(heat.warmup_T_w >= T_max)[0]
    return float(heat.warmup_t[above[0]]) if len(above) else None


def table(doc: Mapping) -> str:
    """The margin table (markdown): one row per item and drive, the limiting item of each drive marked."""
    lines = [
        f"Sizing verdict: **{doc['verdict']}**; limiting: {doc['limiting']['drive']} "
        f"{doc['limiting']['component']} {doc['limiting']['item']}, margin {100 * doc['limiting']['margin']:.1f} %",
        "",
        "| drive | component | item | figure | limit | unit | margin | status |",
        "|---|---|---|---:|---:|---|---:|---|",
    ]
    for name, d in doc["drives"].items():
        for item in d["items"]:
            mark = " (limiting)" if item == d["limiting"] else ""
            lines.append(
                f"| {name} | {item['component']} | {item['item']}{mark} | {item['figure']:.4g} | "
                f"{item['limit']:.4g} | {item['unit']} | {100 * item['margin']:.1f} % | {item['status']} |"
            )
    return "\n".join(lines) + "\n"


def run_system(
    run_dir: Union[str, Path],
    ssp: Optional[Union[str, Path]] = None,
    parameters: Optional[Mapping[str, Mapping[str, Value]]] = None,
    specimen: Optional[Specimen] = None,
) -> tuple[float, str, dict]:
    """(the motion's frequency [Hz], the system, its parameter overrides) of the run in ``run_dir``
    (``read_summary``): ``ssp`` or the system summary.json names; ``parameters`` or the values the run set, recorded
    in summary.json; ``specimen``: the one the run carried, on the mechanism in place of a recorded payload."""
    run_dir = Path(run_dir)
    recorded_ssp, recorded_parameters, frequency = read_summary(run_dir / "summary.json")
    ssp = ssp or recorded_ssp
    if not ssp:
        raise SizingError(f"{run_dir}: summary.json names no system (runs before `mast sizing` existed): give --ssp")
    if not Path(ssp).exists():
        raise SizingError(f"{ssp}: no such system (.ssp or .ssd)")
    recorded = parameters is None
    parameters = parameters if parameters is not None else recorded_parameters
    return frequency, str(ssp), with_specimen(parameters, specimen, replace=recorded)


def size_run(
    run_dir: Union[str, Path],
    ssp: Optional[Union[str, Path]] = None,
    parameters: Optional[Mapping[str, Mapping[str, Value]]] = None,
    specimen: Optional[Specimen] = None,
) -> tuple[dict, list[DriveSizing]]:
    """Size the run in ``run_dir`` (results.csv, summary.json) against the ratings of ``ssp`` (``run_system``: the
    system summary.json names, the values the run set, a specimen in place of its payload, unless given)."""
    run_dir = Path(run_dir)
    t, signals = read_results(run_dir / "results.csv")
    frequency, ssp, parameters = run_system(run_dir, ssp, parameters, specimen)
    try:
        if Path(ssp).suffix == ".ssd":  # the structure is enough: its FMUs need not be built
            drive_set = drives(read_ssd(ssp), parameters)
        else:
            with SSPArchive(ssp) as archive:
                drive_set = drives(archive.system, parameters)
    except UnitError as err:
        raise SizingError(f"{ssp}: {err}") from None
    sized = size_signals(drive_set, t, signals, frequency)
    return document(sized, str(run_dir), str(ssp)), sized


# ----------------------------------------------------------------------------- output
def envelope_png(sized: Sequence[DriveSizing]) -> bytes:
    """The operating points on each motor's torque-speed envelope."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(sized), figsize=(5 * len(sized), 4.5), squeeze=False)
    for ax, s in zip(axes[0], sized):
        r, a = s.drive.ratings, s.drive.actuator
        tau_top = max(r["tau_stall"] * 0.25, 1.3 * float(s.points["tau"].max()), 1.3 * r["tau_N"])
        torque = np.linspace(0.0, tau_top, 50)
        voltage = (a["u_supply"] - a["R"] * torque / a["k_T"]) / a["k_E"] * RPM
        ax.plot(s.points["tau"], s.points["omega"] * RPM, ".", ms=2, alpha=0.4, label="operating points")
        ax.plot([s.points["tau_rms"]], [s.points["omega_rms"] * RPM], "r*", ms=12, label="RMS point")
        ax.axvline(r["tau_N"], color="g", label=f"nominal torque {r['tau_N']:.3g} N m (continuous)")
        ax.axhline(r["n_max"] * RPM, color="k", label=f"max. speed {r['n_max'] * RPM:.0f} rpm")
        ax.axhline(
            r["n_gear_max"] * RPM, color="k", ls="--", label=f"gearhead max. input {r['n_gear_max'] * RPM:.0f} rpm"
        )
        ax.plot(torque, voltage, color="m", label=f"speed-torque line at {a['u_supply']:g} V")
        ax.axvline(
            a["k_T"] * r["i_amp_peak"],
            color="c",
            ls="-.",
            label=f"amplifier peak current x k_T {a['k_T'] * r['i_amp_peak']:.3g} N m",
        )
        if r["tau_stall"] <= tau_top:
            ax.axvline(r["tau_stall"], color="r", ls=":", label="stall torque")
        ax.set_xlim(0, tau_top)
        ax.set_ylim(0, 1.1 * r["n_max"] * RPM)
        ax.set_xlabel("|motor torque| [N m]")
        ax.set_ylabel("|motor speed| [rpm]")
        ax.set_title(
            f"{s.drive.name}: {verdict([s])['verdict']}\nlimiting: {s.limiting.component} {s.limiting.name}, "
            f"{100 * s.limiting.margin:.0f} %",
            fontsize=9,
        )
        ax.legend(fontsize=7, loc="upper right")
    fig.tight_layout()
    return _png(fig)


def temperature_png(sized: Sequence[DriveSizing]) -> bytes:
    """The winding temperature: warm-up with the duty cycle repeated, and the steady cycle (or the run)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (warm, cycle) = plt.subplots(1, 2, figsize=(12, 4.5))
    C = 273.15
    for s in sized:
        if s.heat is not None:
            (line,) = warm.plot(s.heat.warmup_t / 60.0, s.heat.warmup_T_w - C, label=s.drive.name)
            t = s.heat.cycle_s * np.arange(len(s.heat.T_w)) / len(s.heat.T_w)
            cycle.plot(t, s.heat.T_w - C, color=line.get_color(), label=f"{s.drive.name} winding")
            cycle.plot(t, s.heat.T_s - C, color=line.get_color(), ls="--", label=f"{s.drive.name} housing")
        else:
            t, T_w, T_s = s.heat_run
            cycle.plot(t, T_w - C, label=f"{s.drive.name} winding")
            cycle.plot(t, T_s - C, ls="--", label=f"{s.drive.name} housing")
    limit = sized[0].drive.ratings["T_w_max"] - C
    for ax in (warm, cycle):
        ax.axhline(limit, color="r", ls=":", label=f"max. winding {limit:.0f} degC")
        ax.set_ylabel("temperature [degC]")
        ax.legend(fontsize=7)
    warm.set_xlabel("time [min]")
    warm.set_title("warm-up: the duty cycle repeated from ambient (at each cycle's start)")
    cycle.set_xlabel("time in the cycle [s]" if sized[0].heat is not None else "time [s]")
    cycle.set_title("steady cycle" if sized[0].heat is not None else "the run, from ambient (not periodic)")
    fig.tight_layout()
    return _png(fig)


def _png(fig) -> bytes:
    import matplotlib.pyplot as plt

    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=110)
    plt.close(fig)
    return buffer.getvalue()


def write(doc: Mapping, sized: Sequence[DriveSizing], out: Union[str, Path], plots: bool = True) -> list[Path]:
    """sizing.json, sizing.md and (``plots``) the two figures into ``out``: everything made first, then each
    file written all or nothing."""
    out = Path(out)
    files = {"sizing.json": json.dumps(doc, indent=2).encode(), "sizing.md": table(doc).encode()}
    if plots:
        files["sizing_envelope.png"] = envelope_png(sized)
        files["sizing_temperature.png"] = temperature_png(sized)
    out.mkdir(parents=True, exist_ok=True)
    for name, data in files.items():
        atomic_write(out / name, data)
    return [out / name for name in files]
