"""`mast import FILE --map MAP --out DIR`: a lab's log (.mat or CSV) into a record folder (record.py).

The column map (TOML, docs/measured-data.md "Importing a lab's file") names, for the time
and for each signal, the variable of the file, its unit in the file (after ``scale``), an
optional ``scale`` (a number, or the name of a scalar variable of the file, e.g. the drive
gain) and the signal's kind and place in the model:

    [source]
    machine = "EMPS"
    time = { variable = "t", unit = "s" }
    [test]
    name = "estimation"
    [signals.q_m]
    variable = "qm"
    unit = "m"
    kind = "position"
    model = "axis.q"
    [signals.u_inj]            # an input the lab injects; absent from this file: a constant column
    value = 0.0
    unit = "V"
    kind = "injected"
    input = "u_inj"

Every problem names the file and the variable: a missing variable, a variable that is not a
vector of the time's length, time that does not increase (or is irregular), NaN or inf, an
injected input without a declared unit (the unit it acts in is never guessed from its name).

An effort is logged where the drive applies it (the default tap, "applied": the controller's
output plus the injected inputs) or, as the map may say, before the injection (tap =
"before_injection"). When an injected input has edges (a pulse train), the effort's steps at
them (mast.data.injection) are checked against the declared tap: a warning names the column
when it steps by the input's jump while the map says before the injection, or shows no step
while the map says applied. Warnings are returned in the summary (``warnings``), not raised.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Mapping, Union

import numpy as np

from .injection import edge_steps
from .measured import JITTER, MeasuredDataError
from .record import KINDS, SignalSpec, parse_signals, write_records

#: unit in the file -> (SI unit, factor)
UNIT_FACTORS: dict[str, tuple[str, float]] = {
    "s": ("s", 1.0),
    "ms": ("s", 1e-3),
    "us": ("s", 1e-6),
    "m": ("m", 1.0),
    "mm": ("m", 1e-3),
    "um": ("m", 1e-6),
    "rad": ("rad", 1.0),
    "deg": ("rad", math.pi / 180.0),
    "mrad": ("rad", 1e-3),
    "m/s": ("m/s", 1.0),
    "mm/s": ("m/s", 1e-3),
    "rad/s": ("rad/s", 1.0),
    "rpm": ("rad/s", math.pi / 30.0),
    "N": ("N", 1.0),
    "kN": ("N", 1e3),
    "N.m": ("N.m", 1.0),
    "Nm": ("N.m", 1.0),
    "mN.m": ("N.m", 1e-3),
    "V": ("V", 1.0),
    "mV": ("V", 1e-3),
    "A": ("A", 1.0),
    "mA": ("A", 1e-3),
}


class LabFileError(MeasuredDataError):
    """A lab file or its column map cannot be imported (the message names the file and the variable)."""


def read_map(path: Union[str, Path]) -> dict:
    import tomllib

    path = Path(path)
    try:
        with path.open("rb") as handle:
            spec = tomllib.load(handle)
    except OSError as err:
        raise LabFileError(f"{path}: cannot read the column map: {err}") from None
    except tomllib.TOMLDecodeError as err:
        raise LabFileError(f"{path}: not valid TOML: {err}") from None
    if "time" not in spec.get("source", {}):
        raise LabFileError(f"{path}: [source] needs time = {{ variable = ..., unit = ... }}")
    if not isinstance(spec.get("signals"), Mapping) or not spec["signals"]:
        raise LabFileError(f"{path}: no [signals.NAME] tables")
    return spec


def _read_file(path: Path, fmt: str) -> dict[str, np.ndarray]:
    if not path.exists():
        raise LabFileError(f"{path}: no such file")
    if fmt == "mat":
        import scipy.io

        try:
            raw = scipy.io.loadmat(str(path))
        except Exception as err:  # scipy raises ValueError, MatReadError, NotImplementedError (v7.3 files)
            raise LabFileError(f"{path}: cannot read as a MATLAB file: {err}") from None
        return {k: v for k, v in raw.items() if not k.startswith("__")}
    if fmt == "csv":
        from .measured import read_csv

        try:
            header, data = read_csv(path)
        except MeasuredDataError as err:
            raise LabFileError(f"{path}: {err}") from None
        return {h: data[:, j] for j, h in enumerate(header)}
    raise LabFileError(f"{path}: format {fmt!r}: expected 'mat' or 'csv'")


def _vector(path: Path, variables: Mapping[str, np.ndarray], name: str, what: str, n: int | None) -> np.ndarray:
    if name not in variables:
        raise LabFileError(
            f"{path}: variable '{name}' ({what}) not found; the file has "
            f"{', '.join(sorted(variables)) or 'no variables'}"
        )
    v = np.asarray(variables[name])
    if v.dtype.kind not in "fiu" or v.ndim > 2 or (v.ndim == 2 and min(v.shape) != 1) or v.size < 2:
        raise LabFileError(
            f"{path}: variable '{name}' ({what}): shape {v.shape} and type {v.dtype}, expected a "
            "numeric vector (n x 1 or 1 x n)"
        )
    v = v.astype(float).ravel()
    if n is not None and len(v) != n:
        raise LabFileError(f"{path}: variable '{name}' ({what}): {len(v)} samples, expected {n} like the time")
    return v


def _finite(path: Path, name: str, what: str, v: np.ndarray, t: np.ndarray | None) -> None:
    bad = ~np.isfinite(v)
    if bad.any():
        k = int(np.argmax(bad))
        at = f" (t = {t[k]:.6g})" if t is not None else ""
        raise LabFileError(
            f"{path}: variable '{name}' ({what}): {int(bad.sum())} NaN or infinite value(s), the first "
            f"at sample {k + 1}{at}"
        )


def _scalar(path: Path, variables: Mapping[str, np.ndarray], scale: object, signal: str) -> float:
    if isinstance(scale, (int, float)):
        return float(scale)
    name = str(scale)
    if name not in variables:
        raise LabFileError(
            f"{path}: variable '{name}' (scale of signal {signal}) not found; the file has "
            f"{', '.join(sorted(variables))}"
        )
    v = np.asarray(variables[name])
    if v.size != 1 or v.dtype.kind not in "fiu":
        raise LabFileError(
            f"{path}: variable '{name}' (scale of signal {signal}): shape {v.shape}, expected a numeric scalar"
        )
    value = float(v.ravel()[0])
    if not math.isfinite(value):
        raise LabFileError(f"{path}: variable '{name}' (scale of signal {signal}): {value!r} is not finite")
    return value


def _unit(map_path: Path, unit: object, where: str) -> tuple[str, float]:
    if str(unit) not in UNIT_FACTORS:
        raise LabFileError(
            f"{map_path}: {where}: unit {unit!r} is not known; expected one of {', '.join(UNIT_FACTORS)}"
        )
    return UNIT_FACTORS[str(unit)]


def import_file(file: Union[str, Path], map_path: Union[str, Path], out: Union[str, Path]) -> dict:
    """Convert ``file`` through the column map ``map_path`` into the record folder ``out``; returns its summary."""
    file, map_path, out = Path(file), Path(map_path), Path(out)
    spec = read_map(map_path)
    source = spec["source"]
    fmt = str(source.get("format") or file.suffix.lstrip(".").lower())
    variables = _read_file(file, fmt)
    tspec = source["time"]
    if "variable" not in tspec:
        raise LabFileError(f"{map_path}: [source] time needs 'variable'")
    t = _vector(file, variables, tspec["variable"], "time", None)
    _finite(file, tspec["variable"], "time", t, None)
    si, factor = _unit(map_path, tspec.get("unit", "s"), "time")
    if si != "s":
        raise LabFileError(f"{map_path}: time: unit {tspec.get('unit')!r} is not a time unit")
    t = t * factor
    dt = np.diff(t)
    if (dt <= 0).any():
        k = int(np.argmax(dt <= 0))
        raise LabFileError(
            f"{file}: variable '{tspec['variable']}' (time): not increasing at sample {k + 2} "
            f"(t = {t[k]:.9g} s then {t[k + 1]:.9g} s)"
        )
    step = float(np.median(dt))
    dev = np.abs(dt - step) / step
    if (dev > JITTER).any():
        k = int(np.argmax(dev))
        raise LabFileError(
            f"{file}: variable '{tspec['variable']}' (time): irregular sampling, step {dt[k]:.6g} s "
            f"at sample {k + 1} (t = {t[k]:.9g} s) against the median {step:.6g} s (tolerance "
            f"{100 * JITTER:g} %): resample the log to a regular grid first"
        )
    n = len(t)
    meta_signals, columns = {}, {}
    for name, entry in spec["signals"].items():
        if not isinstance(entry, Mapping):
            raise LabFileError(f"{map_path}: [signals.{name}] must be a table")
        kind = entry.get("kind")
        if kind not in KINDS:
            raise LabFileError(f"{map_path}: [signals.{name}]: kind {kind!r}, expected one of {', '.join(KINDS)}")
        if kind == "injected" and not str(entry.get("unit", "")).strip():
            what = f"variable '{entry['variable']}'" if "variable" in entry else "its value"
            raise LabFileError(
                f"{map_path}: [signals.{name}]: the injected input ({what}) has no unit: declare the "
                'unit it acts in, e.g. unit = "V" for a voltage added to the drive command (it is '
                "never read from the variable's name)"
            )
        si, factor = _unit(map_path, entry.get("unit"), f"[signals.{name}]")
        if "variable" in entry:
            v = _vector(file, variables, str(entry["variable"]), f"signal {name}", n)
            _finite(file, str(entry["variable"]), f"signal {name}", v, t)
            v = v * _scalar(file, variables, entry.get("scale", 1.0), name) * factor
        elif "value" in entry:
            v = np.full(n, float(entry["value"]) * factor)
        else:
            raise LabFileError(
                f"{map_path}: [signals.{name}] needs 'variable' (a variable of the file) or 'value' "
                "(a constant, for an input absent from this file)"
            )
        columns[name] = v
        meta_signals[name] = {
            "kind": kind,
            "unit": si,
            **{k: entry[k] for k in ("input", "model", "sampled", "description", "tap") if k in entry},
        }
    specs: dict[str, SignalSpec] = parse_signals(meta_signals, str(map_path))
    warnings = tap_warnings(file, spec["signals"], specs, columns)
    test = dict(spec.get("test", {}))
    name = str(test.pop("name", file.stem))
    meta_extra = {
        "machine": str(source.get("machine", "")),
        "source": {"file": file.name, "map": map_path.name},
        "description": str(source.get("description", "")),
    }
    write_records(out, specs, [{"name": name, "time": t - t[0], "values": columns, **test}], meta_extra)
    return {
        "folder": str(out),
        "test": name,
        "samples": n,
        "sample_time_s": step,
        "duration_s": float(t[-1] - t[0]),
        "signals": {s: specs[s].kind for s in specs},
        "warnings": warnings,
    }


def tap_warnings(
    file: Path, entries: Mapping[str, Mapping], specs: Mapping[str, SignalSpec], columns: Mapping[str, np.ndarray]
) -> list[str]:
    """Warnings for every effort column whose steps at an injected input's edges contradict its declared tap
    (module docstring; the columns in SI units)."""
    out = []
    for e in (s for s in specs.values() if s.kind == "effort"):
        for inj in (s for s in specs.values() if s.kind == "injected"):
            found = edge_steps(columns[e.name], columns[inj.name])
            if found is None:
                continue
            column = f"{file.name}: signal {e.name} (variable '{entries[e.name].get('variable', e.name)}')"
            edges = (
                f"the {found.edges} edges of the injected input {inj.name} (jumps of {found.amplitude:.4g} {inj.unit})"
            )
            if e.tap == "before_injection" and found.steps:
                out.append(
                    f"{column} steps by {found.step:.4g} {e.unit} ({found.gain:.4g} {e.unit}/{inj.unit}) at "
                    f"{edges}, at exactly the edge samples, as a log taken after the injection does; the map "
                    f'says tap = "before_injection": if the log is the command applied, remove the tap (the '
                    f'default, "applied")'
                )
            elif e.tap == "applied" and found.no_steps:
                out.append(
                    f"{column} shows no step at {edges}: {found.step:.4g} {e.unit} there against "
                    f"{found.spread:.4g} {e.unit} of change from one sample to the next elsewhere, as a log "
                    f"taken before the injection does; the map says it is the command applied (tap "
                    f'"applied", the default): if the lab logs the controller\'s output before the '
                    f'injected input is added, say tap = "before_injection"'
                )
    return out
