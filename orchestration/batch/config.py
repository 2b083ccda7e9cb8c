"""The batch config (TOML, YAML or JSON; docs/batch.md): its keys, checked with errors that say where
and what is expected."""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping, Optional, Union

from fmus.mechanism.topology import POSE

from ..analyses.metrics import FAMILIES

_DIMENSIONS = ("random", "ssp", "list", "grid", "motion", "frequency")  # outermost first


class BatchConfigError(ValueError):
    """The batch config is not valid: the message says where and what is expected."""


_KEYS = {
    "": {"name", "ssp", "run", "parameters", "cases", "outputs"},
    "run": {"stop_time", "record_step", "settle", "direct", "timeout"},
    "cases": set(_DIMENSIONS),
    "outputs": {"keep", "metrics", "plots", "custom"},
    "motion": {"axis", "amplitude", "frequency"},
    "random": {"samples", "seed"},
}
DISTRIBUTIONS = {"uniform", "normal", "loguniform", "relative", "choice"}


@dataclass
class BatchConfig:
    """A batch: which SSPs, which cases, which outputs (see docs/batch.md for every key)."""

    name: str
    ssp: dict[str, Path]  # variant name -> .ssp (or .ssd) path
    cases: dict = field(default_factory=dict)
    parameters: dict[str, Any] = field(default_factory=dict)
    stop_time: Union[str, float] = "auto"
    record_step: Union[str, float] = "auto"
    settle: Union[str, float] = "auto"
    direct: bool = False
    timeout: Optional[float] = None
    keep: list[str] = field(default_factory=list)
    metrics: list[str] = field(default_factory=lambda: list(FAMILIES))
    plots: list[dict] = field(default_factory=list)
    custom: Optional[str] = None
    raw: dict = field(default_factory=dict)

    @classmethod
    def load(cls, path: Union[str, Path]) -> "BatchConfig":
        """Read a .toml, .yaml/.yml or .json config; relative paths in it resolve against its folder."""
        path = Path(path)
        if not path.exists():
            raise BatchConfigError(f"{path}: no such config file")
        text = path.read_text(encoding="utf-8")
        suffix = path.suffix.lower()
        try:
            if suffix == ".toml":
                try:
                    import tomllib
                except ModuleNotFoundError:  # Python 3.10
                    import tomli as tomllib
                data = tomllib.loads(text)
            elif suffix in (".yaml", ".yml"):
                try:
                    import yaml
                except ModuleNotFoundError:
                    raise BatchConfigError(
                        f"{path}: YAML configs need PyYAML (pip install 'mast-cosim[batch]')"
                    ) from None
                data = yaml.safe_load(text)
            elif suffix == ".json":
                data = json.loads(text)
            else:
                raise BatchConfigError(f"{path}: expected a .toml, .yaml, .yml or .json config")
        except BatchConfigError:
            raise
        except Exception as err:
            raise BatchConfigError(f"{path}: cannot parse: {err}") from None
        return cls.from_dict(data, path.parent, default_name=path.stem)

    @classmethod
    def from_dict(cls, data: Mapping, base: Union[str, Path] = ".", default_name: str = "batch") -> "BatchConfig":
        """A config from a dict (the same keys as a file); relative SSP paths resolve against ``base``."""
        if not isinstance(data, Mapping):
            raise BatchConfigError("the config must be a table/mapping at the top level")
        _check_keys(data, "")
        base = Path(base)
        ssp = data.get("ssp")
        if ssp is None:
            raise BatchConfigError("'ssp': give the SSP to run (a path, or a table of named variants)")
        variants = {"default": ssp} if isinstance(ssp, (str, Path)) else dict(ssp) if isinstance(ssp, Mapping) else None
        if not variants or not all(isinstance(v, (str, Path)) for v in variants.values()):
            raise BatchConfigError(f"'ssp' = {ssp!r}: expected a path or a table of name = path")
        for name in variants:
            if not re.fullmatch(r"[A-Za-z0-9_.-]+", str(name)):
                raise BatchConfigError(f"ssp variant name {name!r}: use letters, digits, '_', '-' and '.'")
        paths = {str(k): (base / v if not Path(v).is_absolute() else Path(v)) for k, v in variants.items()}
        run = _table(data, "run")
        _check_keys(run, "run")
        cases = _table(data, "cases")
        _check_keys(cases, "cases")
        outputs = _table(data, "outputs")
        _check_keys(outputs, "outputs")
        metrics = list(outputs.get("metrics", FAMILIES))
        bad = [m for m in metrics if m not in FAMILIES]
        if bad:
            raise BatchConfigError(
                f"outputs.metrics: unknown {', '.join(map(repr, bad))}; choose from {', '.join(FAMILIES)}"
            )
        keep = outputs.get("keep", [])
        if isinstance(keep, str):
            keep = [keep]
        plots = outputs.get("plots", [])
        for p in plots:
            if not isinstance(p, Mapping) or set(p) - {"x", "y"} or "x" not in p or "y" not in p:
                raise BatchConfigError(f"outputs.plots entry {p!r}: expected {{x = ..., y = ...}}")
        config = cls(
            name=str(data.get("name", default_name)),
            ssp=paths,
            cases=dict(cases),
            parameters=dict(_table(data, "parameters")),
            stop_time=_auto_or_positive(run.get("stop_time", "auto"), "run.stop_time"),
            record_step=_auto_or_positive(run.get("record_step", "auto"), "run.record_step"),
            settle=_auto_or_nonnegative(run.get("settle", "auto"), "run.settle"),
            direct=bool(run.get("direct", False)),
            timeout=None if run.get("timeout") is None else _auto_or_positive(run["timeout"], "run.timeout"),
            keep=[str(k) for k in keep],
            metrics=metrics,
            plots=[dict(p) for p in plots],
            custom=outputs.get("custom"),
            raw=_plain(data),
        )
        config._check_cases()
        return config

    def _check_cases(self) -> None:
        c = self.cases
        if "ssp" in c:
            names = [c["ssp"]] if isinstance(c["ssp"], str) else c["ssp"]
            unknown = [n for n in names if n not in self.ssp]
            if unknown:
                raise BatchConfigError(
                    f"cases.ssp names {', '.join(map(repr, unknown))}; the [ssp] variants are {', '.join(self.ssp)}"
                )
        for m in as_list(c.get("motion", [])):
            if not isinstance(m, Mapping):
                raise BatchConfigError(
                    f"cases.motion entry {m!r}: expected {{axis = ..., amplitude = ..., frequency = ...}}"
                )
            _check_keys(m, "motion")
            if m.get("axis") not in POSE:  # the system's own coordinates are checked when the cases are made
                raise BatchConfigError(
                    f"cases.motion {dict(m)}: axis must be one of the pose components "
                    f"{', '.join(POSE)} (a coordinate of the system's mechanism)"
                )
            if "frequency" in m and "frequency" in c:
                raise BatchConfigError("give the frequency either in cases.motion or in cases.frequency, not both")
            if "frequency" in m:
                _check_frequency(m["frequency"], f"cases.motion {dict(m)}: frequency")
            elif "frequency" not in c:
                raise BatchConfigError(
                    f"cases.motion {dict(m)}: no frequency; give it (Hz) in the motion or in cases.frequency "
                    "(leave the motion out to hold the home pose)"
                )
        for f in as_list(c.get("frequency", [])):
            _check_frequency(f, "cases.frequency")
        grid = c.get("grid", {})
        if not isinstance(grid, Mapping) or not all(isinstance(v, list) and v for v in grid.values()):
            raise BatchConfigError("cases.grid: expected a table of ELEMENT.PARAMETER = [value, ...] (non-empty lists)")
        entries = c.get("list", [])
        if not isinstance(entries, list) or not all(isinstance(e, Mapping) for e in entries):
            raise BatchConfigError("cases.list: expected a list of tables of ELEMENT.PARAMETER = value")
        rnd = c.get("random")
        if rnd is not None:
            if not isinstance(rnd, Mapping):
                raise BatchConfigError("cases.random: expected a table")
            n = rnd.get("samples")
            if not isinstance(n, int) or n < 1:
                raise BatchConfigError(f"cases.random.samples = {n!r}: expected a whole number >= 1")
            if not isinstance(rnd.get("seed"), int):
                raise BatchConfigError("cases.random.seed: give an integer seed (the draws must be reproducible)")
            for key, dist in rnd.items():
                if key in ("samples", "seed"):
                    continue
                _check_distribution(key, dist)

    def to_json(self) -> dict:
        return {"name": self.name, "ssp": {k: str(v) for k, v in self.ssp.items()}, "source": self.raw}


def _table(data: Mapping, key: str) -> Mapping:
    value = data.get(key, {})
    if not isinstance(value, Mapping):
        raise BatchConfigError(f"'{key}': expected a table")
    return value


def _check_keys(data: Mapping, where: str) -> None:
    unknown = sorted(set(map(str, data)) - _KEYS[where])
    if unknown:
        place = f"[{where}]" if where else "the top level"
        raise BatchConfigError(
            f"{place}: unknown key(s) {', '.join(unknown)}; expected {', '.join(sorted(_KEYS[where]))}"
        )


def _auto_or_positive(value, what: str):
    if value == "auto":
        return value
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not value > 0 or not math.isfinite(value):
        raise BatchConfigError(f'{what} = {value!r}: expected "auto" or a positive number of seconds')
    return float(value)


def _auto_or_nonnegative(value, what: str):
    if value == "auto":
        return value
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not value >= 0 or not math.isfinite(value):
        raise BatchConfigError(f'{what} = {value!r}: expected "auto" or a number of seconds >= 0')
    return float(value)


def _check_frequency(value, what: str) -> None:
    """BatchConfigError naming ``what`` unless ``value`` is a positive, finite number of Hz (a sine of 0 Hz is no
    motion: leave the motion out to hold the home pose)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not value > 0 or not math.isfinite(value):
        raise BatchConfigError(f"{what} = {value!r}: expected a positive, finite number of Hz")


def _check_distribution(key: str, dist) -> None:
    if (
        not isinstance(dist, Mapping)
        or not (set(dist) & DISTRIBUTIONS)
        or len(set(dist) & DISTRIBUTIONS) > 1
        or set(dist) - DISTRIBUTIONS - {"clip"}
    ):
        raise BatchConfigError(
            f"cases.random.{key} = {dist!r}: expected one of "
            "{uniform = [lo, hi]}, {loguniform = [lo, hi]}, {normal = [mean, std], clip = [lo, hi]}, "
            "{relative = tol} (uniform within ±tol of the SSP's value) or {choice = [a, b, ...]}"
        )
    kind = next(iter(set(dist) & DISTRIBUTIONS))
    arg = dist[kind]
    pair = isinstance(arg, list) and len(arg) == 2 and all(isinstance(x, (int, float)) for x in arg)
    ok = {
        "uniform": pair and arg[0] <= arg[1],
        "loguniform": pair and 0 < arg[0] <= arg[1],
        "normal": pair and arg[1] >= 0,
        "relative": isinstance(arg, (int, float)) and 0 <= arg < 1,
        "choice": isinstance(arg, list) and len(arg) > 0,
    }[kind]
    if "clip" in dist and not (
        kind == "normal"
        and isinstance(dist["clip"], list)
        and len(dist["clip"]) == 2
        and dist["clip"][0] < dist["clip"][1]
    ):
        raise BatchConfigError(f"cases.random.{key}: clip = [lo, hi] (lo < hi) goes with a normal distribution")
    if not ok:
        raise BatchConfigError(f"cases.random.{key} = {dict(dist)}: invalid {kind} arguments")


def as_list(value) -> list:
    return value if isinstance(value, list) else [value]


def _plain(value):
    """A JSON-able copy (TOML dates and the like become strings)."""
    if isinstance(value, Mapping):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, (str, int, float, bool)) or value is None:
        return value
    return str(value)
