"""Measured data: a folder of tests (one CSV each) and a meta.json; loading, validation, replay.

Format (docs/measured-data.md): columns ``time``, ``rho_cmd_1..n``, ``rho_1..n`` and
``tau_m_1..n`` (or ``i_m_1..n`` with ``k_T`` in meta.json) for the n drives of the machine (the
3PRS's three; n from meta.json's ``drives``, else the highest k of the header's columns), optional pose columns
``x, y, z, psi, theta, phi``; meta.json names the tests, their units and the measurement
chain the lab knows (the drive's torque filter). Every problem (irregular sampling, gaps,
NaNs, missing columns, units that are unknown or give implausible values) is a
MeasuredDataError naming the file and the column.

The simulation of a test is driven by the commands in the data: ``CommandReplay`` turns the
recorded joint commands into the pose commands the SSP's controller takes (direct
kinematics with the controller's own geometry), so that the controller's inverse
kinematics gives back the recorded rho_cmd (to 1e-12 m) at its position-loop ticks.
"""

from __future__ import annotations

import copy
import csv
import json
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Mapping, Optional, Sequence, Union

import numpy as np

from fmus.mechanism.topology import POSE_UNITS

FORMAT = "mast-measured-data"
VERSION = 1
#: the drives of the format's first machine, the 3PRS (a folder without ``drives`` in meta.json and without any
#: column of a drive to count has these)
AXES = (1, 2, 3)
#: the most drives a folder can have: one per pose component (a fully actuated mechanism, topology.py)
MAX_DRIVES = 6
POSE_COLUMNS = ("x", "y", "z", "psi", "theta", "phi")

#: accepted unit strings -> factor to SI, per quantity
UNITS: dict[str, dict[str, float]] = {
    "time": {"s": 1.0, "ms": 1e-3, "us": 1e-6},
    "length": {"m": 1.0, "mm": 1e-3, "um": 1e-6},
    "torque": {"N.m": 1.0, "Nm": 1.0, "N m": 1.0, "mN.m": 1e-3, "mNm": 1e-3},
    "current": {"A": 1.0, "mA": 1e-3},
    "angle": {"rad": 1.0, "deg": math.pi / 180.0, "mrad": 1e-3},
}
#: the unit key in meta.json of each column group, and its quantity
UNIT_KEYS = {
    "time": "time",
    "rho_cmd": "length",
    "rho": "length",
    "tau_m": "torque",
    "i_m": "current",
    "position": "length",
    "angle": "angle",
}
#: plausibility limits after conversion to SI (catch a wrong unit)
MAX_TORQUE = 10.0  # N m at the motor shaft (Maxon RE 40: 2.5 N m stall torque)
MIN_TORQUE = 1e-4  # N m: the largest |tau| of a test must exceed this
MAX_CURRENT = 100.0  # A
MIN_STEP, MAX_STEP = 1e-5, 0.05  # s between samples
JITTER = 0.01  # relative deviation of a sampling step from the median
MIN_SAMPLES = 50
MAX_TRACKING = 0.01  # m: median |rho - rho_cmd| above this is no tracking error but a unit mismatch
#: the commanded joint swing per unit of commanded pose amplitude: z moves every carriage 1:1 (vertical
#: guides; less on inclined ones), psi/theta move the carriages about (platform radius) x angle
#: (x, y: the legs of a hexapod lean, at home 1.10 m/m on the 6-PUS, 0.43 on the 6-UPS; phi: 0.39 and 0.15 m/rad;
#: the bounds catch a unit off by 10^3, as for z, psi and theta)
SWING_PER_AMPLITUDE = {
    "x": (0.05, 5.0),
    "y": (0.05, 5.0),
    "z": (0.2, 5.0),
    "psi": (0.01, 3.0),
    "theta": (0.01, 3.0),
    "phi": (0.01, 3.0),
}  # m/m, m/rad


class MeasuredDataError(ValueError):
    """The measured-data folder does not follow docs/measured-data.md."""


class Sampled:
    """What every test with a time column [s] (from 0) knows of its sampling."""

    time: np.ndarray

    @property
    def sample_time(self) -> float:
        """The median sample interval [s]."""
        return float(np.median(np.diff(self.time)))

    @property
    def duration(self) -> float:
        """The last time stamp [s]."""
        return float(self.time[-1])


@dataclass
class MeasuredTest(Sampled):
    """One test, in SI units, time starting at 0."""

    name: str
    file: Path
    time: np.ndarray  # (n,) s, from 0
    rho_cmd: np.ndarray  # (n, 3) m
    rho: np.ndarray  # (n, 3) m
    tau_m: np.ndarray  # (n, 3) N m (from i_m * k_T when the data hold currents)
    motion: Optional[str] = None
    amplitude: Optional[float] = None  # m for z, rad for psi/theta
    frequency: Optional[float] = None  # Hz (sine tests)
    role: Optional[str] = None  # "training" / "held-out" / None (the diagnosis decides)
    settle_s: float = 1.0  # analysis starts here
    pose: dict[str, np.ndarray] = field(default_factory=dict)
    time_offset: float = 0.0  # the file's first time stamp [s]

    @property
    def drives(self) -> int:
        """The number of drives (columns rho_cmd_1..n)."""
        return int(self.rho_cmd.shape[1])

    def label(self) -> str:
        if self.motion and self.frequency:
            return f"{self.motion} {self.frequency:g} Hz"
        return self.name


@dataclass
class MeasuredData:
    folder: Path
    meta: dict
    tests: list[MeasuredTest]
    torque_filter_s: float = 0.0  # the drive's documented torque filter (first-order) [s]
    torque_delay_s: float = 0.0  # documented logging delay [s]

    @property
    def drives(self) -> int:
        """The number of drives of every test."""
        return self.tests[0].drives

    def test(self, name: str) -> MeasuredTest:
        for t in self.tests:
            if t.name == name:
                return t
        raise KeyError(f"{self.folder}: no test named {name!r}; tests: {', '.join(t.name for t in self.tests)}")


# --------------------------------------------------------------------------------------
# loading
# --------------------------------------------------------------------------------------
def _unit_factor(meta_units: Mapping[str, str], key: str, where: str) -> float:
    quantity = UNIT_KEYS[key]
    if key not in meta_units:
        raise MeasuredDataError(
            f"{where}: meta.json 'units' has no entry for '{key}' (one of {', '.join(UNITS[quantity])})"
        )
    unit = str(meta_units[key]).strip()
    if unit not in UNITS[quantity]:
        raise MeasuredDataError(
            f"{where}: unit '{unit}' for '{key}' is not known; expected one of {', '.join(UNITS[quantity])}"
        )
    return UNITS[quantity][unit]


def _number(value, key: str, unit: str) -> float:
    """A finite number from meta.json, or an error naming the key."""
    try:
        number = float(value) if not isinstance(value, bool) else math.nan
    except (TypeError, ValueError):
        number = math.nan
    if not math.isfinite(number):
        raise MeasuredDataError(f"meta.json: {key} = {value!r}: expected a finite number [{unit}]")
    return number


def read_csv(path: Path) -> tuple[list[str], np.ndarray]:
    try:
        with path.open(newline="", encoding="utf-8-sig") as handle:  # -sig: spreadsheets write a BOM
            rows = [r for r in csv.reader(handle) if r and not r[0].lstrip().startswith("#")]
    except OSError as err:
        raise MeasuredDataError(f"{path.name}: cannot read: {err}") from None
    if not rows:
        raise MeasuredDataError(f"{path.name}: empty file (expected a header line and data)")
    header = [h.strip() for h in rows[0]]
    if len(set(header)) != len(header):
        dup = sorted({h for h in header if header.count(h) > 1})
        raise MeasuredDataError(f"{path.name}: column(s) {', '.join(dup)} appear twice in the header")
    data = np.full((len(rows) - 1, len(header)), np.nan)
    for i, row in enumerate(rows[1:]):
        if len(row) != len(header):
            raise MeasuredDataError(f"{path.name}: line {i + 2} has {len(row)} fields, the header has {len(header)}")
        for j, cell in enumerate(row):
            cell = cell.strip()
            try:
                data[i, j] = float(cell) if cell else np.nan
            except ValueError:
                raise MeasuredDataError(
                    f"{path.name}: column {header[j]}: {cell!r} on line {i + 2} is not a number"
                ) from None
    return header, data


def check_finite(name: str, column: str, values: np.ndarray, time: Optional[np.ndarray]) -> None:
    bad = ~np.isfinite(values)
    if bad.any():
        k = int(np.argmax(bad))
        at = f" (t = {time[k]:.6g} s)" if time is not None and np.isfinite(time[k]) else ""
        raise MeasuredDataError(
            f"{name}: column {column}: {int(bad.sum())} missing or non-finite value(s), "
            f"the first on data row {k + 1}{at}"
        )


def check_sampling(name: str, t: np.ndarray) -> None:
    if len(t) < MIN_SAMPLES:
        raise MeasuredDataError(f"{name}: column time: {len(t)} samples, expected at least {MIN_SAMPLES}")
    dt = np.diff(t)
    if (dt <= 0).any():
        k = int(np.argmax(dt <= 0))
        raise MeasuredDataError(
            f"{name}: column time: not increasing at data row {k + 2} (t = {t[k]:.9g} s then {t[k + 1]:.9g} s)"
        )
    step = float(np.median(dt))
    if not MIN_STEP <= step <= MAX_STEP:
        raise MeasuredDataError(
            f"{name}: column time: sampling step {step:.3g} s is implausible for a dynamic "
            f"test (expected {MIN_STEP:g} to {MAX_STEP:g} s): check units.time"
        )
    dev = np.abs(dt - step) / step
    if (dev > JITTER).any():
        k = int(np.argmax(dev))
        if dt[k] > 1.5 * step:
            raise MeasuredDataError(
                f"{name}: column time: gap of {dt[k]:.6g} s after t = {t[k]:.9g} s "
                f"(data row {k + 1}); the sampling step is {step:.6g} s. Regular sampling "
                "without gaps is required: split the test or fill the gap in the source"
            )
        raise MeasuredDataError(
            f"{name}: column time: irregular sampling: step {dt[k]:.6g} s at t = {t[k]:.9g} s "
            f"(data row {k + 1}) against the median {step:.6g} s (tolerance {100 * JITTER:g} %); "
            "resample to a regular grid first"
        )


def load(
    folder: Union[str, Path], stroke: tuple[float, float] = (0.0, 0.3), drives: Optional[int] = None
) -> MeasuredData:
    """Read and validate a measured-data folder (SI units, time from 0 in every test).

    ``stroke`` [m]: carriage positions outside it (with 10 mm margin) are reported as a
    unit problem. ``drives``: the number of drives of the machine the data must have (the system's actuators),
    checked before any test's values.
    """
    from ..core.ssp import path_inside

    folder = Path(folder)
    if not folder.is_dir():
        raise MeasuredDataError(f"{folder}: no such folder")
    meta_path = folder / "meta.json"
    if not meta_path.exists():
        raise MeasuredDataError(f"{folder}: no meta.json (see docs/measured-data.md)")
    try:
        meta = json.loads(meta_path.read_text(encoding="utf-8-sig"))
    except json.JSONDecodeError as err:
        raise MeasuredDataError(f"meta.json: not valid JSON: {err}") from None
    if meta.get("format", FORMAT) != FORMAT:
        raise MeasuredDataError(f"meta.json: format {meta.get('format')!r}, expected {FORMAT!r}")
    units = meta.get("units")
    if not isinstance(units, dict):
        raise MeasuredDataError(
            'meta.json: no \'units\' object (e.g. {"time": "s", "rho_cmd": "m", "rho": "m", "tau_m": "N.m"})'
        )
    tests_meta = meta.get("tests")
    if not isinstance(tests_meta, list) or not tests_meta:
        raise MeasuredDataError("meta.json: 'tests' must be a non-empty list of {\"file\": ..., ...}")
    listed = []
    for k, entry in enumerate(tests_meta):
        if not isinstance(entry, dict) or "file" not in entry:
            raise MeasuredDataError(f"meta.json: tests[{k}] has no 'file'")
        if path_inside(folder, str(entry["file"])) is None:
            raise MeasuredDataError(
                f"{meta_path}: tests[{k}] file {str(entry['file'])!r} is not a relative path inside {folder}: refused"
            )
        listed.append(str(entry["file"]))
    for csv_file in sorted(folder.glob("*.csv")):
        if csv_file.name not in listed:
            raise MeasuredDataError(f"{csv_file.name}: not listed in meta.json 'tests' (list it or move it away)")
    measurement = meta.get("measurement", {}) or {}
    if not isinstance(measurement, dict):
        raise MeasuredDataError(f"meta.json: 'measurement' = {measurement!r}: expected an object")
    filt = _number(measurement.get("torque_filter_s", 0.0) or 0.0, "measurement.torque_filter_s", "s")
    delay = _number(measurement.get("torque_delay_s", 0.0) or 0.0, "measurement.torque_delay_s", "s")
    _number(measurement.get("rho_resolution_m", 0.0) or 0.0, "measurement.rho_resolution_m", "m")
    if filt < 0 or delay < 0:
        raise MeasuredDataError("meta.json: measurement.torque_filter_s and torque_delay_s must be finite and >= 0")
    k_T = meta.get("k_T")
    declared = meta.get("drives")
    if declared is not None and (isinstance(declared, bool) or declared not in range(1, MAX_DRIVES + 1)):
        raise MeasuredDataError(f"meta.json: drives = {declared!r}: expected a whole number from 1 to {MAX_DRIVES}")
    tests = [_load_test(folder, entry, units, k_T, stroke, declared, drives) for entry in tests_meta]
    names = [t.name for t in tests]
    if len(set(names)) != len(names):
        raise MeasuredDataError("meta.json: two tests have the same name")
    counts = {t.drives for t in tests}
    if len(counts) > 1:
        raise MeasuredDataError(
            "meta.json: the tests have different numbers of drives ("
            + ", ".join(f"{t.file.name} {t.drives}" for t in tests)
            + "): one folder holds the tests of one machine"
        )
    return MeasuredData(folder, meta, tests, filt, delay)


def drive_count(header: Sequence[str]) -> int:
    """The drives a header holds: the highest k of its columns rho_cmd_k, rho_k, tau_m_k and i_m_k (the 3PRS's
    three if it has none; a column missing below that k is then named as missing, never taken as fewer drives)."""
    found = [int(m.group(2)) for h in header if (m := re.fullmatch(r"(rho_cmd|rho|tau_m|i_m)_([1-9][0-9]*)", h))]
    return max(found, default=len(AXES))


def _load_test(
    folder: Path,
    entry: dict,
    units: Mapping[str, str],
    k_T,
    stroke,
    declared: Optional[int],
    expected: Optional[int],
) -> MeasuredTest:
    name = str(entry["file"])
    path = folder / name
    if not path.exists():
        raise MeasuredDataError(f"{name}: listed in meta.json but not in {folder}")
    header, data = read_csv(path)
    col = {h: j for j, h in enumerate(header)}
    n = declared or drive_count(header)
    if n > MAX_DRIVES:
        raise MeasuredDataError(
            f"{name}: columns of drive {n}: a machine has at most {MAX_DRIVES} drives (one per pose coordinate)"
        )
    if expected is not None and n != expected:
        raise MeasuredDataError(
            f"{name}: the test has {n} drives (rho_cmd_1..{n}"
            + ("" if declared else ", counted from its columns")
            + f"), the system has {expected} (actuator_1..{expected}): give the SSP of the machine the data were "
            "measured on"
        )
    axes = range(1, n + 1)
    torque_cols = [f"tau_m_{j}" for j in axes]
    current_cols = [f"i_m_{j}" for j in axes]
    use_current = not all(c in col for c in torque_cols) and all(c in col for c in current_cols)
    needed = (
        ["time"]
        + [f"rho_cmd_{j}" for j in axes]
        + [f"rho_{j}" for j in axes]
        + (current_cols if use_current else torque_cols)
    )
    missing = [c for c in needed if c not in col]
    if missing:
        raise MeasuredDataError(
            f"{name}: missing column(s) {', '.join(missing)}; expected time, rho_cmd_1..{n}, "
            f"rho_1..{n} and tau_m_1..{n} (or i_m_1..{n} with k_T in meta.json)"
        )
    if len(data) == 0:
        raise MeasuredDataError(f"{name}: no data rows")
    t_raw = data[:, col["time"]]
    check_finite(name, "time", t_raw, None)
    t = t_raw * _unit_factor(units, "time", name)
    check_sampling(name, t)
    out = {}
    f_len = _unit_factor(units, "rho_cmd", name)
    f_rho = _unit_factor(units, "rho", name)
    lo, hi = stroke[0] - 0.01, stroke[1] + 0.01
    for group, factor in (("rho_cmd", f_len), ("rho", f_rho)):
        cols = []
        for j in axes:
            c = f"{group}_{j}"
            v = data[:, col[c]]
            check_finite(name, c, v, t)
            v = v * factor
            if v.min() < lo or v.max() > hi:
                bad = v.max() if v.max() > hi else v.min()
                raise MeasuredDataError(
                    f"{name}: column {c}: {bad:.6g} m lies outside the stroke "
                    f"[{stroke[0]:g}, {stroke[1]:g}] m: check units.{group} "
                    f"(now '{units.get(group)}')"
                )
            cols.append(v)
        out[group] = np.column_stack(cols)
    if use_current:
        f_cur = _unit_factor(units, "i_m", name)
        if k_T is None:
            raise MeasuredDataError(f"{name}: columns i_m_1..{n} need the torque constant 'k_T' [N.m/A] in meta.json")
        try:
            kT = float(k_T)
        except (TypeError, ValueError):
            kT = float("nan")
        if not kT > 0 or not math.isfinite(kT):
            raise MeasuredDataError(f"meta.json: k_T = {k_T!r}: expected a positive number [N.m/A]")
        cols = []
        for c in current_cols:
            v = data[:, col[c]]
            check_finite(name, c, v, t)
            v = v * f_cur
            if np.abs(v).max() > MAX_CURRENT:
                raise MeasuredDataError(
                    f"{name}: column {c}: |i| up to {np.abs(v).max():.6g} A is implausible "
                    f"(> {MAX_CURRENT:g} A): check units.i_m (now '{units.get('i_m')}')"
                )
            cols.append(v * kT)
        tau = np.column_stack(cols)
        tcols = current_cols
    else:
        f_tau = _unit_factor(units, "tau_m", name)
        cols = []
        for c in torque_cols:
            v = data[:, col[c]]
            check_finite(name, c, v, t)
            cols.append(v * f_tau)
        tau = np.column_stack(cols)
        tcols = torque_cols
    for j, c in enumerate(tcols):
        peak = float(np.abs(tau[:, j]).max())
        unit_key = "i_m" if use_current else "tau_m"
        if peak > MAX_TORQUE:
            raise MeasuredDataError(
                f"{name}: column {c}: motor torque up to {peak:.6g} N.m is implausible "
                f"(> {MAX_TORQUE:g} N.m): check units.{unit_key} (now '{units.get(unit_key)}')"
            )
        if peak < MIN_TORQUE:
            raise MeasuredDataError(
                f"{name}: column {c}: motor torque never exceeds {peak:.3g} N.m: "
                f"check units.{unit_key} (now '{units.get(unit_key)}')"
            )
    pose = {}
    for c in POSE_COLUMNS:
        if c in col:
            key = "position" if c in ("x", "y", "z") else "angle"
            v = data[:, col[c]]
            check_finite(name, c, v, t)
            pose[c] = v * _unit_factor(units, key, name)
    motion = entry.get("motion")
    amplitude = entry.get("amplitude")
    if amplitude is not None:
        unit = entry.get("amplitude_unit", POSE_UNITS.get(motion, "rad"))
        quantity = "length" if unit in UNITS["length"] else "angle"
        if unit not in UNITS[quantity]:
            raise MeasuredDataError(f"meta.json: test {name}: amplitude_unit '{unit}' is not known")
        amplitude = _number(amplitude, f"tests[{name}].amplitude", unit) * UNITS[quantity][unit]
    frequency = entry.get("frequency")
    if frequency is not None:
        frequency = _number(frequency, f"tests[{name}].frequency", "Hz")
        if not frequency > 0:
            raise MeasuredDataError(f"meta.json: test {name}: frequency {frequency!r} Hz: expected > 0")
    _check_positions(name, out["rho_cmd"], out["rho"], units, motion, amplitude)
    role = entry.get("role")
    if role not in (None, "training", "held-out"):
        raise MeasuredDataError(f"meta.json: test {name}: role {role!r}: expected 'training' or 'held-out'")
    settle = _number(entry.get("settle_s", min(1.0, 0.3 * (t[-1] - t[0]))), f"tests[{name}].settle_s", "s")
    if not 0 <= settle < t[-1] - t[0]:
        raise MeasuredDataError(
            f"meta.json: test {name}: settle_s = {settle!r} s: expected 0 <= settle_s < duration {t[-1] - t[0]:.6g} s"
        )
    return MeasuredTest(
        name=Path(name).stem,
        file=path,
        time=t - t[0],
        rho_cmd=out["rho_cmd"],
        rho=out["rho"],
        tau_m=tau,
        motion=motion,
        amplitude=amplitude,
        frequency=frequency,
        role=role,
        settle_s=settle,
        pose=pose,
        time_offset=float(t[0]),
    )


def _check_positions(
    name: str,
    rho_cmd: np.ndarray,
    rho: np.ndarray,
    units: Mapping[str, str],
    motion: Optional[str],
    amplitude: Optional[float],
) -> None:
    """Catch a length unit that is off (m declared as mm or um, or the reverse) though inside the stroke:
    measured positions must follow their commands, and the commands must swing as the test says."""
    now = f"units.rho = '{units.get('rho')}', units.rho_cmd = '{units.get('rho_cmd')}'"
    for j in range(rho.shape[1]):
        dev = float(np.median(np.abs(rho[:, j] - rho_cmd[:, j])))
        if dev > MAX_TRACKING:
            scale = float(np.median(np.abs(rho[:, j]))) / max(float(np.median(np.abs(rho_cmd[:, j]))), 1e-300)
            raise MeasuredDataError(
                f"{name}: column rho_{j + 1} differs from rho_cmd_{j + 1} by {1e3 * dev:.3g} mm (median), far more "
                f"than a tracking error (< {1e3 * MAX_TRACKING:g} mm): the positions are {scale:.3g} times the "
                f"commands; check the unit of one of them ({now})"
            )
    if motion in SWING_PER_AMPLITUDE and amplitude:
        swing = float(np.max(np.ptp(rho_cmd, axis=0))) / 2.0
        ratio = swing / abs(amplitude)
        low, high = SWING_PER_AMPLITUDE[motion]
        if not low <= ratio <= high:
            per = POSE_UNITS[motion]
            raise MeasuredDataError(
                f"{name}: columns rho_cmd_1..{rho_cmd.shape[1]} swing by +-{swing:.3g} m while meta.json gives a "
                f"{motion} amplitude of {abs(amplitude):.3g} {per}: {ratio:.3g} m per {per}, expected {low:g} to "
                f"{high:g}; check units.rho_cmd (now '{units.get('rho_cmd')}') or the test's amplitude and "
                "amplitude_unit"
            )


# --------------------------------------------------------------------------------------
# writing (synthesize, and labs converting their logs)
# --------------------------------------------------------------------------------------
def write_test_csv(
    path: Path,
    time: np.ndarray,
    rho_cmd: np.ndarray,
    rho: np.ndarray,
    tau_m: np.ndarray,
    pose: Optional[Mapping[str, np.ndarray]] = None,
) -> None:
    """One test's CSV: time, then rho_cmd_1..n, rho_1..n, tau_m_1..n for the n columns of the (samples, n)
    arrays, then the ``pose`` columns."""
    n = rho_cmd.shape[1]
    if rho.shape[1] != n or tau_m.shape[1] != n:
        raise ValueError(f"{path.name}: rho_cmd, rho and tau_m have {n}, {rho.shape[1]}, {tau_m.shape[1]} columns")
    axes = range(1, n + 1)
    names = ["time"] + [f"rho_cmd_{j}" for j in axes] + [f"rho_{j}" for j in axes] + [f"tau_m_{j}" for j in axes]
    cols = [time, *rho_cmd.T, *rho.T, *tau_m.T]
    for k, v in (pose or {}).items():
        names.append(k)
        cols.append(v)
    table = np.column_stack(cols)
    fmt = ["%.9f"] + ["%.12g"] * n + ["%.12g"] * n + ["%.9g"] * n + ["%.9g"] * len(pose or {})
    np.savetxt(path, table, delimiter=",", header=",".join(names), comments="", fmt=fmt)


# --------------------------------------------------------------------------------------
# replay: drive the co-simulation by the recorded joint commands
# --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class ReplayKinematics:
    """The controller's kinematic model as the replay needs it: ``ik(q)`` rho of a pose command q (one value per
    coordinate of ``names``) and ``dk(rho, guess)`` its inverse (Newton to ``DK_TOL``)."""

    names: tuple[str, ...]
    ik: Callable[[Sequence[float]], Sequence[float]]
    dk: Callable[[Sequence[float], Optional[Sequence[float]]], Sequence[float]]

    @property
    def n(self) -> int:
        return len(self.names)


#: the replay's direct kinematics stops when max |rho(q) - rho_cmd| is below this [m]
DK_TOL = 1e-13


class CommandReplay:
    """Stimulus (mast.core.master.Stimulus) replaying recorded joint commands as pose commands.

    The controller of the SSP takes pose commands and converts them with its own inverse
    kinematics; the recorded rho_cmd are turned into poses once, with the direct
    kinematics of the same model (``controller_kinematics``: warm-started Newton, 1e-13 m), and
    the pose is interpolated linearly in time between samples. At the samples (and so at the
    controller's position ticks when the data are logged at the position-loop rate or a
    divisor of it) the controller's IK returns the recorded rho_cmd to 1e-12 m.
    """

    reads: Sequence[str] = ()

    def __init__(self, time: np.ndarray, rho_cmd: np.ndarray, kinematics: ReplayKinematics) -> None:
        self.time = np.asarray(time, dtype=float)
        n = len(self.time)
        if rho_cmd.shape[1] != kinematics.n:
            raise MeasuredDataError(
                f"command replay: {rho_cmd.shape[1]} joint commands per sample, the controller's kinematic model "
                f"has {kinematics.n} drives (coordinates {', '.join(kinematics.names)})"
            )
        poses = np.empty((n, kinematics.n))
        guess = None
        worst = 0.0
        for k in range(n):
            q = kinematics.dk(rho_cmd[k], guess)
            poses[k] = q
            guess = q
        for k in range(0, n, max(1, n // 50)):  # spot check the round trip
            worst = max(worst, float(np.abs(np.asarray(kinematics.ik(poses[k])) - rho_cmd[k]).max()))
        if worst > 1e-9:
            raise MeasuredDataError(f"command replay: IK(DK(rho_cmd)) differs from rho_cmd by {worst:.3g} m")
        self.poses = poses
        self._t0 = float(self.time[0])
        self._dt = float((self.time[-1] - self.time[0]) / (n - 1))
        self._n = n
        self._rows = [tuple(map(float, p)) for p in poses]

    def perturbed(self, seed: int, scale: float) -> "CommandReplay":
        """A copy whose pose commands carry independent normal perturbations of standard deviation
        ``scale`` (m for z, rad for the angles): another realisation of commands known only to finite
        precision (for a closed loop that hunts chaotically, docs/diagnose.md)."""
        out = copy.copy(self)
        rng = np.random.default_rng(seed)
        out.poses = self.poses + scale * rng.standard_normal(self.poses.shape)
        out._rows = [tuple(map(float, p)) for p in out.poses]
        return out

    def start(self, t0: float, read) -> None:
        pass

    def __call__(self, t: float) -> list[float]:
        s = (t - self._t0) / self._dt
        if s <= 0.0:
            return list(self._rows[0])
        k = int(s)
        if k >= self._n - 1:
            return list(self._rows[-1])
        f = s - k
        a = self._rows[k]
        if f < 1e-9:
            return list(a)
        b = self._rows[k + 1]
        if f > 1.0 - 1e-9:
            return list(b)
        return [x + f * (y - x) for x, y in zip(a, b)]


def controller_kinematics(
    ssp: Union[str, Path], overrides: Optional[Mapping[str, Mapping]] = None, controller: str = "controller"
) -> ReplayKinematics:
    """The kinematic model the SSP binds to its controller (with ``overrides``): the description its geometry set
    selects (``kinematics``), massless, as the controller builds it; the 3PRS with vertical guides by its closed
    form (fmus/mechanism/kinematics.py, the controller's to 1e-12 m), with which the replays of the 3PRS's data
    were made and its diagnoses' figures computed."""
    from fmus.mechanism.designs import kinematic_engine
    from fmus.mechanism.kinematics import Geometry, direct_kinematics, inverse_kinematics

    from ..core.ssp import SSPArchive

    with SSPArchive(ssp) as archive:
        params = dict(archive.system.components[controller].parameters)
    params.update((overrides or {}).get(controller, {}))
    if params.get("kinematics", "3PRS") == "3PRS" and float(params.get("beta", 0.0)) == 0.0:
        geometry = Geometry.checked(params, controller)
        return ReplayKinematics(
            ("z", "psi", "theta"),
            lambda q: inverse_kinematics(geometry, *q),
            lambda rho, guess: direct_kinematics(geometry, rho, guess=guess, tol=DK_TOL),
        )
    engine = kinematic_engine(params, controller)
    return ReplayKinematics(
        engine.description.topology.names,
        engine.ik,
        lambda rho, guess: engine.dk(rho, guess, tol=DK_TOL)[0],
    )


def actuator_names(ssp: Union[str, Path]) -> list[str]:
    from ..core.ssp import SSPArchive

    with SSPArchive(ssp) as archive:
        return [n for n in archive.system.components if n.startswith("actuator_")]
