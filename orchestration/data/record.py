"""Measured records of any machine: named signals of known kind, the format `mast import` writes.

A record folder (docs/measured-data.md, "Records of any machine") is the measured-data
folder of the MAST generalised to any set of signals: a meta.json whose ``signals`` object
says, for each CSV column, what it is

    kind      command | injected | position | velocity | effort
    unit      SI unit of the column (m, rad, m/s, rad/s, N, N.m, V)
    input     (command, injected) the model's system input it drives
    model     (position, velocity, effort) the model's output it is compared with, ELEMENT.CONNECTOR
    sampled   (effort, command outputs of a sampled controller) true: sample k of the log is the
              value the controller computed at t_k (compared with the model's output published
              for that sample, one sample later in the co-simulation)
    tap       (effort) where the drive command is logged: "applied" (the default: what the drive
              applies, the controller's output after its saturation plus the injected inputs,
              compared with ``model``) or "before_injection" (the controller's output before the
              injected inputs are added, compared with the model output ``model`` + "_before_injection")

and one CSV per test (``time`` then the signals, SI units). The simulation of a record is
driven by its command and injected columns (``RecordReplay``); the other kinds are compared.
Every problem is a RecordError naming the file and the column.
"""

from __future__ import annotations

import bisect
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping, Optional, Sequence, Union

import numpy as np

from .measured import FORMAT, VERSION, MeasuredDataError, Sampled, check_finite, check_sampling, read_csv

#: kinds of signals: what drives the model, and what is compared
DRIVING = ("command", "injected")
MEASURED = ("position", "velocity", "effort")
KINDS = DRIVING + MEASURED
#: SI units a column of each kind may carry
SI_UNITS = {
    "command": ("m", "rad", "V", "N", "N.m", "A"),
    "injected": ("V", "N", "N.m", "A"),
    "position": ("m", "rad"),
    "velocity": ("m/s", "rad/s"),
    "effort": ("N", "N.m", "V", "A"),
}
#: where an effort is logged: what the drive applies (the default), or the controller's output before the
#: injected inputs are added (compared with the model output named ``model`` + "_before_injection")
TAPS = ("applied", "before_injection")


class RecordError(MeasuredDataError):
    """A record folder does not follow docs/measured-data.md."""


@dataclass(frozen=True)
class SignalSpec:
    """One column of a record: its kind, SI unit and where it meets the model."""

    name: str
    kind: str
    unit: str
    input: Optional[str] = None  # system input of the model (command, injected)
    model: Optional[str] = None  # model output ELEMENT.CONNECTOR (position, velocity, effort)
    sampled: bool = False  # a sampled controller's output (docstring)
    description: str = ""
    tap: str = "applied"  # effort: where the drive command is logged (TAPS, docstring)

    def to_json(self) -> dict:
        out = {"kind": self.kind, "unit": self.unit}
        for key in ("input", "model", "description"):
            if getattr(self, key):
                out[key] = getattr(self, key)
        if self.sampled:
            out["sampled"] = True
        if self.tap != "applied":
            out["tap"] = self.tap
        return out

    @property
    def model_output(self) -> Optional[str]:
        """The model output this signal is compared with: ``model`` for the applied effort and the other kinds,
        ``model`` + "_" + tap for an effort logged at another tap (before the injection)."""
        return self.model if self.tap == "applied" or not self.model else f"{self.model}_{self.tap}"


def parse_signals(raw: object, where: str) -> dict[str, SignalSpec]:
    """The ``signals`` object of meta.json (or of an import map), checked."""
    if not isinstance(raw, Mapping) or not raw:
        raise RecordError(f"{where}: 'signals' must be a non-empty object {{NAME: {{kind, unit, ...}}}}")
    specs = {}
    for name, entry in raw.items():
        if name == "time":
            raise RecordError(f"{where}: signal name 'time' is reserved for the time column")
        if not isinstance(entry, Mapping):
            raise RecordError(f"{where}: signal {name}: expected an object with kind and unit")
        kind = entry.get("kind")
        if kind not in KINDS:
            raise RecordError(f"{where}: signal {name}: kind {kind!r}, expected one of {', '.join(KINDS)}")
        unit = str(entry.get("unit", ""))
        if unit not in SI_UNITS[kind]:
            raise RecordError(
                f"{where}: signal {name}: unit {unit!r} for a {kind} signal, expected one of "
                f"{', '.join(SI_UNITS[kind])} (SI: `mast import` converts)"
            )
        tap = entry.get("tap", "applied")
        if tap not in TAPS:
            raise RecordError(
                f"{where}: signal {name}: tap {tap!r}, expected one of {', '.join(TAPS)} (where the "
                "drive command is logged: after the injected inputs are added, or before)"
            )
        if tap != "applied" and kind != "effort":
            raise RecordError(f"{where}: signal {name}: tap {tap!r} on a {kind} signal: only an effort has a tap")
        spec = SignalSpec(
            name,
            kind,
            unit,
            entry.get("input"),
            entry.get("model"),
            bool(entry.get("sampled", False)),
            str(entry.get("description", "")),
            tap,
        )
        if kind in DRIVING and not spec.input:
            raise RecordError(
                f"{where}: signal {name}: a {kind} signal needs 'input', the model's system input it drives"
            )
        if kind in MEASURED and (not spec.model or "." not in spec.model):
            raise RecordError(
                f"{where}: signal {name}: a {kind} signal needs 'model', the model output it is "
                "compared with (ELEMENT.CONNECTOR)"
            )
        specs[name] = spec
    if not any(s.kind == "command" for s in specs.values()):
        raise RecordError(f"{where}: no signal of kind 'command': the model cannot be driven")
    return specs


@dataclass
class Record(Sampled):
    """One test of a record folder, SI units, time from 0."""

    name: str
    file: Path
    time: np.ndarray
    values: dict[str, np.ndarray]
    specs: dict[str, SignalSpec]
    role: Optional[str] = None
    settle_s: float = 0.0
    description: str = ""
    time_offset: float = 0.0

    def of_kind(self, *kinds: str) -> list[SignalSpec]:
        return [s for s in self.specs.values() if s.kind in kinds]

    def label(self) -> str:
        return self.name


@dataclass
class RecordSet:
    folder: Path
    meta: dict
    specs: dict[str, SignalSpec]
    tests: list[Record] = field(default_factory=list)

    @property
    def machine(self) -> str:
        return str(self.meta.get("machine", self.folder.name))


def is_record_folder(folder: Union[str, Path]) -> bool:
    """True when ``folder``'s meta.json describes named signals (a record of any machine), not MAST columns."""
    meta = Path(folder) / "meta.json"
    try:
        return "signals" in json.loads(meta.read_text())
    except (OSError, json.JSONDecodeError):
        return False


def load_records(folder: Union[str, Path]) -> RecordSet:
    """Read and validate a record folder (SI units, time from 0 in every test)."""
    folder = Path(folder)
    meta_path = folder / "meta.json"
    if not meta_path.exists():
        raise RecordError(f"{folder}: no meta.json (see docs/measured-data.md)")
    try:
        meta = json.loads(meta_path.read_text())
    except json.JSONDecodeError as err:
        raise RecordError(f"{meta_path}: not valid JSON: {err}") from None
    if meta.get("format") != FORMAT:
        raise RecordError(f"{meta_path}: format {meta.get('format')!r}, expected {FORMAT!r}")
    specs = parse_signals(meta.get("signals"), str(meta_path))
    tests_meta = meta.get("tests")
    if not isinstance(tests_meta, list) or not tests_meta:
        raise RecordError(f"{meta_path}: 'tests' must be a non-empty list of {{\"file\": ...}}")
    listed = [str(e.get("file")) for e in tests_meta if isinstance(e, Mapping)]
    for csv_file in sorted(folder.glob("*.csv")):
        if csv_file.name not in listed:
            raise RecordError(f"{csv_file.name}: not listed in meta.json 'tests' (list it or move it away)")
    out = RecordSet(folder, meta, specs)
    for k, entry in enumerate(tests_meta):
        if not isinstance(entry, Mapping) or "file" not in entry:
            raise RecordError(f"{meta_path}: tests[{k}] has no 'file'")
        out.tests.append(_load_test(folder, entry, specs))
    return out


def _load_test(folder: Path, entry: Mapping, specs: Mapping[str, SignalSpec]) -> Record:
    name = str(entry["file"])
    path = folder / name
    if not path.exists():
        raise RecordError(f"{name}: listed in meta.json but not in {folder}")
    header, data = read_csv(path)
    col = {h: j for j, h in enumerate(header)}
    missing = [c for c in ["time", *specs] if c not in col]
    if missing:
        raise RecordError(
            f"{name}: missing column(s) {', '.join(missing)}; meta.json 'signals' names "
            f"{', '.join(specs)} (and the time column 'time')"
        )
    t = data[:, col["time"]]
    check_finite(name, "time", t, None)
    check_sampling(name, t)
    values = {}
    for s in specs:
        v = data[:, col[s]]
        check_finite(name, s, v, t)
        values[s] = v
    role = entry.get("role")
    if role not in (None, "training", "held-out"):
        raise RecordError(f"meta.json: test {name}: role {role!r}: expected 'training' or 'held-out'")
    settle = float(entry.get("settle_s", 0.0))
    if not 0 <= settle < t[-1] - t[0]:
        raise RecordError(
            f"meta.json: test {name}: settle_s = {settle!r} s: expected 0 <= settle_s < duration {t[-1] - t[0]:.6g} s"
        )
    return Record(
        Path(name).stem,
        path,
        t - t[0],
        values,
        dict(specs),
        role,
        settle,
        str(entry.get("description", "")),
        float(t[0]),
    )


def write_records(
    folder: Union[str, Path],
    specs: Mapping[str, SignalSpec],
    tests: Sequence[Mapping],
    meta_extra: Optional[Mapping] = None,
) -> Path:
    """Write a record folder: ``tests`` = [{"name", "time", "values": {signal: array}, ...test keys}]."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    entries = []
    for test in tests:
        file = f"{test['name']}.csv"
        names = ["time", *specs]
        table = np.column_stack([test["time"]] + [np.asarray(test["values"][s], dtype=float) for s in specs])
        np.savetxt(folder / file, table, delimiter=",", header=",".join(names), comments="", fmt="%.12g")
        entry = {"file": file}
        entry.update({k: v for k, v in test.items() if k not in ("name", "time", "values")})
        entries.append(entry)
    meta = {
        "format": FORMAT,
        "version": VERSION,
        **(meta_extra or {}),
        "signals": {n: s.to_json() for n, s in specs.items()},
        "tests": entries,
    }
    (folder / "meta.json").write_text(json.dumps(meta, indent=2))
    return folder


class RecordReplay:
    """Stimulus (mast.core.master.Stimulus) replaying a record's driving columns on the model's system inputs.

    Sample k of the record holds on [t_k, t_k+1) (zero-order hold, as a sampled controller
    reads its reference and a lab's logger adds its injected input); system inputs of the
    model the record does not drive stay 0.
    """

    reads: Sequence[str] = ()

    def __init__(self, record: Record, system_inputs: Sequence[str]) -> None:
        driving = record.of_kind(*DRIVING)
        unknown = [s.input for s in driving if s.input not in system_inputs]
        if unknown:
            raise RecordError(
                f"{record.file.name}: signal(s) drive input(s) {', '.join(unknown)} the model does not "
                f"have; its system inputs: {', '.join(system_inputs) or 'none'}"
            )
        self.time = record.time
        self._times = [float(x) for x in record.time]
        self._tol = 0.01 * record.sample_time  # sampling jitter (< 1 %, checked on loading)
        table = np.zeros((len(record.time), len(system_inputs)))
        for s in driving:
            table[:, list(system_inputs).index(s.input)] = record.values[s.name]
        self._rows = [list(map(float, r)) for r in table]
        self._n = len(self._rows)
        self._k = 0

    def start(self, t0: float, read) -> None:
        pass

    def __call__(self, t: float) -> list[float]:
        k, times, at = self._k, self._times, t + self._tol
        if not (times[k] <= at and (k + 1 == self._n or times[k + 1] > at)):  # not the last sample's hold
            k = self._k = min(max(bisect.bisect_right(times, at) - 1, 0), self._n - 1)
        return self._rows[k]
