"""Batch co-simulation: hundreds of cases from one config, on a local process pool or a Dask cluster.

A config (TOML, YAML or JSON; docs/batch.md) names the SSP(s), the cases
(lists, grids, random samples with seeds, motions, SSP variants) and the
outputs (signals to keep, metrics to compute). :func:`run_batch` (``mast batch``)
expands it into cases, runs every case in a worker process and writes each
case's result atomically the moment it arrives:

    DIR/batch.json          the config, the cases (id, digest) and where the SSPs came from
    DIR/inputs/<ssp>.ssp    the SSPs the batch runs (copied once: a rebuild does not mix results)
    DIR/cases/<id>.json     one per finished case: parameters, motion, status, metrics, error, timings
    DIR/cases/<id>.npz      the kept signals of that case (``outputs.keep``), if any
    DIR/manifest.json       every case, finished or pending, in one file
    DIR/summary.csv         one row per case: status, varied inputs, metrics
    DIR/groups.csv          per frequency sweep (same system, axis, amplitude): bandwidth, resonance
    DIR/plots/*.png         metrics against the swept parameters

Workers. Each worker process keeps one :class:`mast.session.Session` per SSP: the
FMUs are extracted and instantiated once, and reset (fmi2Reset) between cases.
A case that raises, diverges (NaN) or times out is recorded as ``failed``; a
case that kills its worker (segmentation fault, ``os._exit``) is recorded as
``crashed``: the pool is restarted and the cases that were running beside it
are run again, each alone, so only the culprit is blamed. The batch goes on.

Resume. ``cases/<id>.json`` is written last (temp file, fsync, rename), so it
exists only for a finished case; ``resume=True`` skips those (when their
digest still matches the config) and runs the rest: an interrupted batch never
repeats or loses a finished case. Raising ``cases.random.samples`` and resuming
extends a Monte Carlo study: the first samples keep their ids and values.

Cluster. ``scheduler="tcp://host:8786"`` (or a ``distributed.Client``) runs the
same cases on an existing Dask cluster; the SSPs travel to the workers with the
tasks, each worker keeps its sessions between tasks. Start workers with one
thread each (``dask worker ADDRESS --nthreads 1 --nworkers N``): pythonfmu FMUs
share one interpreter per process, so processes, not threads, run cases side
by side.
"""
from __future__ import annotations

import csv
import faulthandler
import fnmatch
import hashlib
import importlib
import io
import itertools
import json
import math
import multiprocessing
import os
import re
import shutil
import signal
import socket
import sys
import tempfile
import threading
import time
import traceback
from collections import deque
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping, Optional, Sequence, Union

import numpy as np

from .frequency import _record_step, measuring_window
from .metrics import FAMILIES, case_metrics, signals_for, sweep_metrics
from .motion import AXES

FORMAT_VERSION = 1
STATUSES = ("ok", "failed", "crashed")
_DIMENSIONS = ("random", "ssp", "list", "grid", "motion", "frequency")  # outermost first


class BatchConfigError(ValueError):
    """The batch config is not valid: the message says where and what is expected."""


# =====================================================================================
# config
# =====================================================================================
_KEYS = {
    "": {"name", "ssp", "run", "parameters", "cases", "outputs"},
    "run": {"stop_time", "record_step", "settle", "direct", "timeout"},
    "cases": set(_DIMENSIONS),
    "outputs": {"keep", "metrics", "plots", "custom"},
    "motion": {"axis", "amplitude", "frequency"},
    "random": {"samples", "seed"},
}
_DISTRIBUTIONS = {"uniform", "normal", "loguniform", "relative", "choice"}


@dataclass
class BatchConfig:
    """A batch: which SSPs, which cases, which outputs (see docs/batch.md for every key)."""

    name: str
    ssp: dict[str, Path]                     # variant name -> .ssp (or .ssd) path
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
                    raise BatchConfigError(f"{path}: YAML configs need PyYAML (pip install 'mast-cosim[batch]')") from None
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
            raise BatchConfigError(f"outputs.metrics: unknown {', '.join(map(repr, bad))}; choose from {', '.join(FAMILIES)}")
        keep = outputs.get("keep", [])
        if isinstance(keep, str):
            keep = [keep]
        plots = outputs.get("plots", [])
        for p in plots:
            if not isinstance(p, Mapping) or set(p) - {"x", "y"} or "x" not in p or "y" not in p:
                raise BatchConfigError(f"outputs.plots entry {p!r}: expected {{x = ..., y = ...}}")
        config = cls(name=str(data.get("name", default_name)), ssp=paths, cases=dict(cases),
                     parameters=dict(_table(data, "parameters")),
                     stop_time=_auto_or_positive(run.get("stop_time", "auto"), "run.stop_time"),
                     record_step=_auto_or_positive(run.get("record_step", "auto"), "run.record_step"),
                     settle=_auto_or_nonnegative(run.get("settle", "auto"), "run.settle"),
                     direct=bool(run.get("direct", False)),
                     timeout=None if run.get("timeout") is None else _auto_or_positive(run["timeout"], "run.timeout"),
                     keep=[str(k) for k in keep], metrics=metrics, plots=[dict(p) for p in plots],
                     custom=outputs.get("custom"), raw=_plain(data))
        config._check_cases()
        return config

    def _check_cases(self) -> None:
        c = self.cases
        if "ssp" in c:
            names = [c["ssp"]] if isinstance(c["ssp"], str) else c["ssp"]
            unknown = [n for n in names if n not in self.ssp]
            if unknown:
                raise BatchConfigError(f"cases.ssp names {', '.join(map(repr, unknown))}; the [ssp] variants are {', '.join(self.ssp)}")
        for m in _as_list(c.get("motion", [])):
            if not isinstance(m, Mapping):
                raise BatchConfigError(f"cases.motion entry {m!r}: expected {{axis = ..., amplitude = ..., frequency = ...}}")
            _check_keys(m, "motion")
            if m.get("axis") not in AXES:
                raise BatchConfigError(f"cases.motion {dict(m)}: axis must be one of {', '.join(AXES)}")
            if "frequency" in m and "frequency" in c:
                raise BatchConfigError("give the frequency either in cases.motion or in cases.frequency, not both")
        for f in _as_list(c.get("frequency", [])):
            if not isinstance(f, (int, float)) or not f >= 0:
                raise BatchConfigError(f"cases.frequency: {f!r} is not a frequency >= 0 Hz")
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
        raise BatchConfigError(f"{place}: unknown key(s) {', '.join(unknown)}; expected {', '.join(sorted(_KEYS[where]))}")


def _auto_or_positive(value, what: str):
    if value == "auto":
        return value
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not value > 0 or not math.isfinite(value):
        raise BatchConfigError(f"{what} = {value!r}: expected \"auto\" or a positive number of seconds")
    return float(value)


def _auto_or_nonnegative(value, what: str):
    if value == "auto":
        return value
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not value >= 0 or not math.isfinite(value):
        raise BatchConfigError(f"{what} = {value!r}: expected \"auto\" or a number of seconds >= 0")
    return float(value)


def _check_distribution(key: str, dist) -> None:
    if not isinstance(dist, Mapping) or not (set(dist) & _DISTRIBUTIONS) or len(set(dist) & _DISTRIBUTIONS) > 1 \
            or set(dist) - _DISTRIBUTIONS - {"clip"}:
        raise BatchConfigError(f"cases.random.{key} = {dist!r}: expected one of "
                               "{uniform = [lo, hi]}, {loguniform = [lo, hi]}, {normal = [mean, std], clip = [lo, hi]}, "
                               "{relative = tol} (uniform within ±tol of the SSP's value) or {choice = [a, b, ...]}")
    kind = next(iter(set(dist) & _DISTRIBUTIONS))
    arg = dist[kind]
    pair = isinstance(arg, list) and len(arg) == 2 and all(isinstance(x, (int, float)) for x in arg)
    ok = {"uniform": pair and arg[0] <= arg[1], "loguniform": pair and 0 < arg[0] <= arg[1],
          "normal": pair and arg[1] >= 0, "relative": isinstance(arg, (int, float)) and 0 <= arg < 1,
          "choice": isinstance(arg, list) and len(arg) > 0}[kind]
    if "clip" in dist and not (kind == "normal" and isinstance(dist["clip"], list) and len(dist["clip"]) == 2
                               and dist["clip"][0] < dist["clip"][1]):
        raise BatchConfigError(f"cases.random.{key}: clip = [lo, hi] (lo < hi) goes with a normal distribution")
    if not ok:
        raise BatchConfigError(f"cases.random.{key} = {dict(dist)}: invalid {kind} arguments")


def _as_list(value) -> list:
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


# =====================================================================================
# cases
# =====================================================================================
@dataclass
class SystemInfo:
    """What case expansion needs to know about one SSP."""

    path: Path
    sha256: str
    components: list[str]
    system_inputs: list[str]
    nominal: dict[str, dict[str, Any]]        # component -> merged bindings
    parameters: dict[str, list[str]]          # component -> FMU parameter names
    signals: list[str]                        # recordable: system inputs and declared outputs

    @classmethod
    def read(cls, path: Path) -> "SystemInfo":
        from fmpy import read_model_description

        from .run import default_signals
        from .ssp import SSPArchive

        with SSPArchive(path) as archive:
            system = archive.system
            names: dict[str, list[str]] = {}
            by_fmu: dict[Path, list[str]] = {}
            for comp in system.components:
                fmu = system.fmu_path(comp)
                if fmu not in by_fmu:
                    md = read_model_description(str(fmu))
                    by_fmu[fmu] = [v.name for v in md.modelVariables if v.causality == "parameter"]
                names[comp] = by_fmu[fmu]
            return cls(path, _sha256(path) if path.is_file() else "", list(system.components), list(system.system_inputs),
                       {c: dict(s.parameters) for c, s in system.components.items()}, names, default_signals(system))

    def resolve(self, key: str, where: str) -> list[tuple[str, str]]:
        """``ELEMENT.PARAMETER`` (ELEMENT may hold * ? [..] wildcards) -> [(component, parameter)]."""
        pattern, dot, param = str(key).partition(".")
        if not dot or not pattern or not param:
            raise BatchConfigError(f"{where}: '{key}' is not ELEMENT.PARAMETER (e.g. actuator_1.tau_c or actuator_*.tau_c)")
        matches = [c for c in self.components if fnmatch.fnmatchcase(c, pattern)]
        if not matches:
            raise BatchConfigError(f"{where}: '{key}' matches no component of {self.path.name}; "
                                   f"its components are {', '.join(self.components)}")
        for comp in matches:
            if param not in self.parameters[comp]:
                raise BatchConfigError(f"{where}: '{key}': {comp} has no parameter '{param}'; "
                                       f"its parameters are {', '.join(sorted(self.parameters[comp]))}")
        return [(c, param) for c in matches]


@dataclass
class Case:
    """One co-simulation of the batch."""

    id: str
    index: int
    ssp: str                          # variant name
    inputs: dict[str, Any]            # what the case dimensions set, named as in the config
    parameters: dict[str, Any]        # every override, ELEMENT.PARAMETER, wildcards expanded
    motion: Optional[dict]            # axis, amplitude (config units: m, deg), frequency [Hz]
    sample: Optional[int]
    stop_time: float
    record_step: float
    window: tuple[float, float]       # metrics window [s]
    digest: str = ""
    group: str = ""

    def as_dict(self) -> dict:
        return {"id": self.id, "index": self.index, "ssp": self.ssp, "inputs": self.inputs,
                "parameters": self.parameters, "motion": self.motion, "sample": self.sample,
                "stop_time": self.stop_time, "record_step": self.record_step, "window": list(self.window),
                "digest": self.digest, "group": self.group}


def expand(config: BatchConfig, systems: Optional[Mapping[str, SystemInfo]] = None) -> list[Case]:
    """Every case of ``config``: the product of its dimensions (random samples outermost, then SSP
    variants, list entries, grid points, motions, frequencies innermost); ids c00000, c00001, ..."""
    systems = dict(systems) if systems else {}
    for name, path in config.ssp.items():
        if name not in systems:
            if not Path(path).exists():
                raise BatchConfigError(f"ssp '{name}': {path} does not exist (run `mast build`?)")
            systems[name] = SystemInfo.read(Path(path))
    for name, info in systems.items():
        unknown = [k for k in config.keep if k not in info.signals]
        if unknown:
            raise BatchConfigError(f"outputs.keep: {', '.join(unknown)} not in {info.path.name} (ssp '{name}'); "
                                   f"it has the system inputs and component outputs {', '.join(info.signals)}")
    c = config.cases
    dims: list[list[dict]] = []
    rnd = c.get("random")
    if rnd:
        dims.append(_draw(rnd))
    names = _as_list(c["ssp"]) if "ssp" in c else list(config.ssp)
    dims.append([{"ssp": n} for n in names])
    if c.get("list"):
        dims.append([{"inputs": dict(e), "list": k} for k, e in enumerate(c["list"])])
    grid = c.get("grid") or {}
    if grid:
        keys = list(grid)
        dims.append([{"inputs": dict(zip(keys, values))} for values in itertools.product(*(grid[k] for k in keys))])
    motions = _as_list(c.get("motion", []))
    if motions:
        dims.append([{"motion": dict(m)} for m in motions])
    if "frequency" in c:
        dims.append([{"frequency": float(f)} for f in _as_list(c["frequency"])])
    total = math.prod(len(d) for d in dims)
    width = max(5, len(str(total - 1)))
    cases = []
    for index, combo in enumerate(itertools.product(*dims)):
        parts: dict = {"inputs": {}, "draws": {}}
        for part in combo:
            for key, value in part.items():
                if key in ("inputs", "draws"):
                    parts[key].update(value)
                else:
                    parts[key] = value
        cases.append(_make_case(config, systems[parts["ssp"]], parts, index, f"c{index:0{width}d}"))
    return cases


def _draw(rnd: Mapping) -> list[dict]:
    """Sample-major draws: sample k's values do not depend on how many samples follow."""
    rng = np.random.default_rng(int(rnd["seed"]))
    keys = [k for k in rnd if k not in ("samples", "seed")]
    samples = []
    for k in range(int(rnd["samples"])):
        draws = {}
        for key in keys:
            dist = rnd[key]
            kind = next(iter(set(dist) & _DISTRIBUTIONS))
            arg = dist[kind]
            if kind == "uniform":
                value = float(rng.uniform(arg[0], arg[1]))
            elif kind == "loguniform":
                value = float(math.exp(rng.uniform(math.log(arg[0]), math.log(arg[1]))))
            elif kind == "normal":
                lo, hi = dist.get("clip", (-math.inf, math.inf))
                for _ in range(10000):  # truncated normal by rejection
                    value = float(rng.normal(arg[0], arg[1]))
                    if lo <= value <= hi:
                        break
                else:
                    raise BatchConfigError(f"cases.random.{key}: clip {dist['clip']} is too narrow for normal {arg}")
            elif kind == "relative":
                value = ("relative", float(rng.uniform(-arg, arg)))
            else:
                value = arg[int(rng.integers(len(arg)))]
            draws[key] = value
        samples.append({"draws": draws, "sample": k})
    return samples


def _make_case(config: BatchConfig, info: SystemInfo, parts: dict, index: int, case_id: str) -> Case:
    where = f"case {case_id}"
    overrides: dict[str, Any] = {}
    inputs: dict[str, Any] = {}
    layers = [("parameters", config.parameters), ("inputs", parts["inputs"]), ("draws", parts["draws"])]
    for layer, values in layers:
        for key, value in values.items():
            targets = info.resolve(key, f"{layer} of {where}")
            shown = None
            for comp, param in targets:
                v = value
                if isinstance(value, tuple) and value[0] == "relative":
                    nominal = info.nominal.get(comp, {}).get(param)
                    if not isinstance(nominal, (int, float)) or isinstance(nominal, bool):
                        raise BatchConfigError(f"cases.random.{key}: 'relative' needs a numeric value of {comp}.{param} "
                                               f"bound in {info.path.name}")
                    v = float(nominal) * (1.0 + value[1])
                if isinstance(v, bool) or not isinstance(v, (int, float, str)):
                    raise BatchConfigError(f"{layer} of {where}: {key} = {v!r}: expected a number or a string")
                overrides[f"{comp}.{param}"] = v
                shown = v if shown is None else shown
            if layer != "parameters":
                inputs[key] = shown
    motion = parts.get("motion")
    if motion is not None:
        motion = {"axis": motion["axis"], "amplitude": float(motion.get("amplitude", 0.0)),
                  "frequency": float(parts.get("frequency", motion.get("frequency", 0.0)))}
    elif "frequency" in parts:
        raise BatchConfigError("cases.frequency needs a cases.motion (axis and amplitude)")
    if motion is not None and not all(s in info.system_inputs for s in ("z_cmd", "psi_cmd", "theta_cmd")):
        raise BatchConfigError(f"{info.path.name} has no pose command inputs (z_cmd, psi_cmd, theta_cmd): "
                               "it takes no cases.motion")
    f = motion["frequency"] if motion else 0.0
    if config.stop_time == "auto":
        if not f > 0:
            raise BatchConfigError(f"{where}: run.stop_time = \"auto\" needs a sine motion with a frequency > 0; "
                                   "give run.stop_time in seconds")
        start, stop = measuring_window(f)
    else:
        stop = float(config.stop_time)
        start = measuring_window(f)[0] if f > 0 and measuring_window(f)[0] < stop else 0.0
    if config.settle != "auto":
        start = min(float(config.settle), stop)
    end = stop
    if f > 0 and (stop - start) * f >= 1 - 1e-9:  # whole periods for the harmonic fit
        end = start + math.floor((stop - start) * f + 1e-9) / f
    record_step = (_record_step(f) if f > 0 else 1e-3) if config.record_step == "auto" else float(config.record_step)
    case = Case(case_id, index, parts["ssp"], inputs, dict(sorted(overrides.items())), motion, parts.get("sample"),
                float(stop), float(record_step), (float(start), float(end)))
    defining = {"ssp": info.sha256, "parameters": case.parameters, "direct": config.direct,
                "motion": None if motion is None else {k: v for k, v in motion.items() if k != "frequency"}}
    case.group = _digest(defining)
    case.digest = _digest({**defining, "motion": motion, "stop_time": case.stop_time, "record_step": case.record_step,
                           "window": case.window, "keep": config.keep, "metrics": config.metrics,
                           "custom": config.custom, "timeout": config.timeout})
    return case


def _digest(obj) -> str:
    return hashlib.sha256(json.dumps(obj, sort_keys=True, default=str).encode()).hexdigest()[:16]


def _sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for chunk in iter(lambda: handle.read(1 << 20), b""):
            digest.update(chunk)
    return digest.hexdigest()


# =====================================================================================
# worker side
# =====================================================================================
_LOCAL = threading.local()  # per thread: {(ssp path, direct): Session}


class CaseTimeout(RuntimeError):
    pass


_MAX_SESSIONS = 4  # per worker thread: a long-lived (Dask) worker serving many batches keeps the latest


def _one_blas_thread() -> None:
    """Cases run side by side in worker processes: one BLAS thread each.

    numpy's and scipy's OpenBLAS start a thread per core, which spin on the other workers' cores
    (measured: 12 % more CPU per case for nothing). threadpoolctl sets the limit in an already
    loaded library (a forked worker); without it, the environment variables serve spawned ones."""
    global _BLAS_LIMITED
    if _BLAS_LIMITED:
        return
    _BLAS_LIMITED = True
    for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(var, "1")
    try:
        from threadpoolctl import threadpool_limits
    except ModuleNotFoundError:
        return
    threadpool_limits(1)


_BLAS_LIMITED = False


def _session(path: str, direct: bool):
    from collections import OrderedDict

    from .session import Session

    _one_blas_thread()

    sessions = _LOCAL.__dict__.setdefault("sessions", OrderedDict())
    key = (path, direct)
    if key in sessions:
        sessions.move_to_end(key)
    else:
        while len(sessions) >= _MAX_SESSIONS:
            sessions.popitem(last=False)[1].close()
        sessions[key] = Session(path, direct=direct)
    return sessions[key]


def run_case(task: Mapping) -> dict:
    """Run one case in this process (a worker): its metrics, kept signals, timings; never raises."""
    from .master import SimulationError
    from .motion import SineMotion
    from .run import default_signals

    t_case, cpu_case = time.perf_counter(), time.process_time()
    record: dict[str, Any] = {"id": task["id"], "status": "ok", "error": None, "metrics": {},
                              "worker": {"pid": os.getpid(), "host": socket.gethostname()},
                              "started": time.time()}
    timing = {"setup_s": 0.0, "init_s": 0.0, "step_s": 0.0, "metrics_s": 0.0}
    result = None
    try:
        if task.get("before_case") is not None:
            task["before_case"](dict(task))
        session = _session(task["ssp_path"], bool(task.get("direct")))
        motion = task.get("motion")
        if motion is not None:
            stimulus = SineMotion(motion["axis"], motion["amplitude_si"], motion["frequency"])
        else:
            stimulus = None
        families = task.get("metrics", FAMILIES)
        wanted = signals_for(families, default_signals(session.system))
        record_names = list(dict.fromkeys(wanted + list(task.get("keep", ()))))
        try:
            result = session.run(stimulus, task["stop_time"], parameters=_nest(task["parameters"]),
                                 record=record_names, record_step=task["record_step"],
                                 progress=_deadline(task.get("timeout")))
        except SimulationError as err:
            result = err.result
            raise
        finally:
            timing["setup_s"] = session.last_setup_s
            if result is not None:
                timing["init_s"] = result.stats.get("init_s", 0.0)
                timing["step_s"] = max(0.0, result.wall_time_s - timing["init_s"])
        t_m = time.perf_counter()
        limits = _limits(session.system, task["parameters"])
        metrics = case_metrics(result, families, _motion_si(motion), task["window"][0], task["window"][1], limits)
        custom = task.get("custom")
        if custom:
            func = _import_function(custom) if isinstance(custom, str) else custom
            metrics.update({str(k): float(v) for k, v in func(result, dict(task)).items()})
        timing["metrics_s"] = time.perf_counter() - t_m
        record["metrics"] = metrics
    except SimulationError as err:
        record["status"], record["error"] = "failed", str(err)
    except Exception as err:  # recorded, the batch goes on
        record["status"], record["error"] = "failed", f"{type(err).__name__}: {err}"
        record["traceback"] = traceback.format_exc(limit=8)
    keep = task.get("keep", ())
    if keep and result is not None and len(result.time):
        record["signals"] = {"time": result.time, **{n: result.signals[n] for n in keep if n in result.signals}}
    timing["case_s"] = time.perf_counter() - t_case
    timing["cpu_s"] = time.process_time() - cpu_case  # this worker's CPU time for the case
    record["timing"] = timing
    record["finished"] = time.time()
    return record


def _motion_si(motion: Optional[Mapping]) -> Optional[dict]:
    if motion is None:
        return None
    return {"axis": motion["axis"], "amplitude": motion["amplitude_si"], "frequency": motion["frequency"]}


def _limits(system, flat: Mapping[str, Any]) -> dict[str, float]:
    if "controller" not in system.components:
        return {}
    merged = {**system.components["controller"].parameters,
              **{k.split(".", 1)[1]: v for k, v in flat.items() if k.startswith("controller.")}}
    return {k: float(merged[k]) for k in ("i_max", "u_max") if isinstance(merged.get(k), (int, float))}


def _nest(flat: Mapping[str, Any]) -> dict[str, dict[str, Any]]:
    nested: dict[str, dict[str, Any]] = {}
    for key, value in flat.items():
        comp, _, param = key.partition(".")
        nested.setdefault(comp, {})[param] = value
    return nested


def _import_function(spec: str) -> Callable:
    module, _, name = spec.partition(":")
    if not module or not name:
        raise ValueError(f"outputs.custom = {spec!r}: expected 'package.module:function'")
    return getattr(importlib.import_module(module), name)


def _deadline(seconds: Optional[float]) -> Optional[Callable[[float], None]]:
    """A master progress callback that stops the run after ``seconds`` of wall time.

    The master calls it from its own loop (about every 1 % of the run), between FMU calls, so the
    run ends as any failing run does: recorded as failed, the instances discarded. A model that
    hangs inside one step is not interrupted."""
    if not seconds:
        return None
    deadline = time.perf_counter() + float(seconds)

    def check(_fraction: float) -> None:
        if time.perf_counter() > deadline:
            raise CaseTimeout(f"timed out after {seconds:g} s (run.timeout)")
    return check


def _worker_init() -> None:
    """Pool workers leave Ctrl-C to the driver, which stops them; a crash is diagnosed in its rerun alone."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    faulthandler.disable()
    _one_blas_thread()


def _isolated_main(task: Mapping, conn, fault_file: str) -> None:
    _worker_init()
    with open(fault_file, "w") as handle:  # the Python stack at a fatal signal, for the crash record
        faulthandler.enable(file=handle)
        conn.send(run_case(task))
    conn.close()


def _dask_run(task: Mapping, ssp_bytes: bytes) -> dict:
    """On a Dask worker: the SSP arrives as bytes (scattered once), cached on the worker's disk by digest."""
    cache = Path(tempfile.gettempdir()) / "mast_batch_ssp"
    cache.mkdir(parents=True, exist_ok=True)
    path = cache / f"{task['ssp_sha']}{Path(task['ssp_path']).suffix or '.ssp'}"
    if not path.exists():
        _atomic_write(path, ssp_bytes, sync=False)
    return run_case({**task, "ssp_path": str(path)})


def _crashed(task: Mapping, why: str) -> dict:
    return {"id": task["id"], "status": "crashed", "error": why, "metrics": {}, "worker": {},
            "timing": {}, "started": None, "finished": time.time()}


# =====================================================================================
# executors
# =====================================================================================
class LocalPool:
    """Cases in a pool of worker processes on this machine; a dead worker costs only its case."""

    def __init__(self, workers: Optional[int] = None, mp_context=None) -> None:
        self.workers = max(1, workers or os.cpu_count() or 1)
        self.context = multiprocessing.get_context(mp_context) if isinstance(mp_context, str) or mp_context is None \
            else mp_context
        self.restarts = 0

    def _pool(self) -> ProcessPoolExecutor:
        return ProcessPoolExecutor(max_workers=self.workers, mp_context=self.context, initializer=_worker_init)

    def run(self, tasks: Sequence[dict], on_result: Callable[[dict], None]) -> None:
        queue = deque(tasks)
        pool = self._pool()
        running: dict = {}
        try:
            while queue or running:
                suspects = []
                while queue and len(running) < self.workers:  # no backlog: a crash has few suspects
                    try:
                        running[pool.submit(run_case, queue[0])] = queue[0]
                    except BrokenProcessPool:  # a worker died since the last look: recover below
                        break
                    queue.popleft()
                done, _ = wait(running, return_when=FIRST_COMPLETED) if running else (set(), set())
                for future in done:
                    task = running.pop(future)
                    try:
                        record = future.result()
                    except BrokenProcessPool:
                        suspects.append(task)
                        continue
                    except Exception as err:  # e.g. a task that could not be pickled
                        record = {**_crashed(task, f"{type(err).__name__}: {err}"), "status": "failed"}
                    on_result(record)
                if suspects or getattr(pool, "_broken", False):
                    # a worker died and took the pool with it: every case that was running is a suspect;
                    # each runs again alone, so only the one that crashes is recorded as crashed
                    for future, task in running.items():
                        if future.done() and not future.cancelled() and future.exception() is None:
                            on_result(future.result())  # finished just before the crash: keep it
                        else:
                            suspects.append(task)
                    running.clear()
                    self._stop(pool)
                    for task in suspects:
                        on_result(self._isolated(task))
                    pool = self._pool()
                    self.restarts += 1
        finally:
            self._stop(pool)

    def _isolated(self, task: dict) -> dict:
        reader, writer = self.context.Pipe(duplex=False)
        fd, fault_file = tempfile.mkstemp(prefix="mast_batch_fault_", suffix=".txt")
        os.close(fd)
        proc = self.context.Process(target=_isolated_main, args=(task, writer, fault_file), daemon=True)
        proc.start()
        writer.close()
        record = None
        try:
            while record is None:
                if reader.poll(0.05):
                    try:
                        record = reader.recv()
                    except EOFError:
                        break
                elif not proc.is_alive():
                    if reader.poll(0):
                        continue
                    break
        finally:
            proc.join(5)
            if proc.is_alive():
                proc.kill()
                proc.join()
            reader.close()
            try:
                stack = Path(fault_file).read_text(errors="replace").strip().splitlines()
            finally:
                os.unlink(fault_file)
        if record is None:
            where = ""
            if stack:
                where = "; Python stack at the crash (most recent call first):\n" + "\n".join(stack[:12])
            return _crashed(task, f"the worker process died ({_exit_text(proc.exitcode)}) while running this case{where}")
        return record

    @staticmethod
    def _stop(pool: ProcessPoolExecutor) -> None:
        processes = list(getattr(pool, "_processes", {}).values())  # no public way to stop running workers
        pool.shutdown(wait=False, cancel_futures=True)
        for proc in processes:
            if proc.is_alive():
                proc.terminate()
        for proc in processes:
            proc.join(5)


def _exit_text(code: Optional[int]) -> str:
    if code is None:
        return "exit code unknown"
    if code < 0:
        try:
            return f"killed by signal {-code}, {signal.Signals(-code).name}"
        except ValueError:
            return f"killed by signal {-code}"
    return f"exit code {code}"


class DaskCluster:
    """Cases on an existing Dask distributed cluster (a scheduler address or a Client)."""

    def __init__(self, scheduler) -> None:
        try:
            from distributed import Client
        except ModuleNotFoundError:
            raise RuntimeError("--scheduler needs Dask distributed: pip install 'mast-cosim[batch]'") from None
        self._own = not isinstance(scheduler, Client)
        self.client = Client(scheduler) if self._own else scheduler

    def run(self, tasks: Sequence[dict], on_result: Callable[[dict], None]) -> None:
        from distributed import as_completed

        try:
            from distributed.scheduler import KilledWorker
        except ImportError:  # moved between releases
            from distributed import KilledWorker
        blobs: dict[str, Any] = {}
        for task in tasks:
            if Path(task["ssp_path"]).suffix == ".ssd":
                raise BatchConfigError(f"{task['ssp_path']}: on a cluster, give a built .ssp (the workers get the "
                                       "archive; an .ssd's FMUs and parameter files stay behind)")
            if task["ssp_sha"] not in blobs:
                blobs[task["ssp_sha"]] = self.client.scatter(Path(task["ssp_path"]).read_bytes(), broadcast=True, hash=False)
        token = os.urandom(4).hex()
        futures = {self.client.submit(_dask_run, task, blobs[task["ssp_sha"]], key=f"mast-{task['id']}-{token}",
                                      pure=False, retries=0): task for task in tasks}
        try:
            for future in as_completed(futures):
                task = futures[future]
                try:
                    record = future.result()
                except KilledWorker as err:
                    record = _crashed(task, f"the Dask worker running this case died ({err})")
                except Exception as err:
                    record = {**_crashed(task, f"{type(err).__name__}: {err}"), "status": "failed"}
                future.release()
                on_result(record)
        finally:
            for future in futures:
                if not future.done():
                    future.cancel()
            if self._own:
                self.client.close()


# =====================================================================================
# results on disk
# =====================================================================================
def _atomic_write(path: Path, data: bytes, sync: bool = True) -> None:
    """Write ``data`` to ``path`` all or nothing: temp file in the same folder, fsync, rename."""
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{threading.get_ident()}.tmp")
    try:
        with open(tmp, "wb") as handle:
            handle.write(data)
            handle.flush()
            if sync:
                os.fsync(handle.fileno())
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()
    if sync and hasattr(os, "O_DIRECTORY"):
        fd = os.open(path.parent, os.O_RDONLY | os.O_DIRECTORY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def _json_safe(value):
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, (np.floating, np.integer)):
        return _json_safe(value.item())
    if isinstance(value, Mapping):
        return {str(k): _json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_safe(v) for v in value]
    return value


def _dumps(obj) -> bytes:
    return (json.dumps(_json_safe(obj), indent=1, allow_nan=False) + "\n").encode()


class Store:
    """The batch folder (layout in the module docstring)."""

    def __init__(self, out: Union[str, Path]) -> None:
        self.out = Path(out)
        self.cases_dir = self.out / "cases"
        self._next_manifest = 0.0

    def case_file(self, case_id: str) -> Path:
        return self.cases_dir / f"{case_id}.json"

    def exists(self) -> bool:
        return (self.out / "batch.json").exists()

    def start(self, config: BatchConfig, cases: Sequence[Case], systems: Mapping[str, SystemInfo], sources: Mapping) -> None:
        self.cases_dir.mkdir(parents=True, exist_ok=True)
        meta = {"format": FORMAT_VERSION, "name": config.name, "created": time.strftime("%Y-%m-%dT%H:%M:%S"),
                "config": config.to_json(), "ssp": {n: {"source": str(sources[n]), "copy": str(systems[n].path.name),
                                                        "sha256": systems[n].sha256} for n in systems},
                "direct": config.direct, "cases": [{"id": c.id, "digest": c.digest} for c in cases]}
        _atomic_write(self.out / "batch.json", _dumps(meta))

    def finished(self) -> dict[str, dict]:
        records = {}
        if self.cases_dir.exists():
            for path in self.cases_dir.glob("*.json"):
                try:
                    records[path.stem] = json.loads(path.read_text())
                except (OSError, ValueError):  # never written whole (cannot happen with atomic writes): run again
                    continue
        return records

    def write_case(self, case: Case, record: dict) -> dict:
        signals = record.pop("signals", None)
        entry = {**case.as_dict(), **{k: v for k, v in record.items() if k != "id"}}
        if signals:
            buffer = io.BytesIO()
            np.savez(buffer, **{name: np.asarray(values) for name, values in signals.items()})
            _atomic_write(self.cases_dir / f"{case.id}.npz", buffer.getvalue())
            entry["signals_file"] = f"cases/{case.id}.npz"
        _atomic_write(self.case_file(case.id), _dumps(entry))  # last: its presence means "finished"
        return entry

    def write_manifest(self, name: str, cases: Sequence[Case], records: Mapping[str, dict], force: bool = False) -> None:
        now = time.monotonic()
        if not force and now < self._next_manifest:
            return
        counts = {s: 0 for s in STATUSES}
        rows = []
        for case in cases:
            rec = records.get(case.id)
            if rec is not None:
                counts[rec["status"]] = counts.get(rec["status"], 0) + 1
                rows.append(rec)
            else:
                rows.append({**case.as_dict(), "status": "pending"})
        manifest = {"name": name, "total": len(cases), **counts, "pending": len(cases) - sum(counts.values()),
                    "updated": time.strftime("%Y-%m-%dT%H:%M:%S"), "cases": rows}
        _atomic_write(self.out / "manifest.json", _dumps(manifest), sync=force)
        # at most every 2 s, and never more than 5 % of the time (a manifest of 10 000 cases is large)
        self._next_manifest = time.monotonic() + max(2.0, 20.0 * (time.monotonic() - now))


# =====================================================================================
# progress
# =====================================================================================
class BatchProgress:
    """'batch NAME [#####     ] 37/120 done, 35 ok, 1 failed, 1 crashed, ~3m10s left' on stderr.

    Redrawn in place on a terminal; in logs a line every 10 % of the cases (at most one a minute apart
    otherwise)."""

    def __init__(self, name: str, stream=None) -> None:
        self.name = name
        self.stream = stream or sys.stderr
        self.tty = hasattr(self.stream, "isatty") and self.stream.isatty()
        self.t0 = time.perf_counter()
        self._last_step = -1
        self._last_line = 0.0

    def __call__(self, state: Mapping) -> None:
        total, done, skipped = state["total"], state["done"], state["skipped"]
        ran = done - skipped
        elapsed = time.perf_counter() - self.t0
        left = elapsed / ran * (total - done) if ran else float("nan")
        bar = "#" * int(25 * done / total) if total else ""
        text = (f"batch {self.name} [{bar:<25}] {done}/{total} done, {state['ok']} ok, {state['failed']} failed, "
                f"{state['crashed']} crashed, {_duration(elapsed)} elapsed, ~{_duration(left)} left")
        if self.tty:
            self.stream.write("\r" + text + ("\n" if done == total else ""))
        else:
            step = int(10 * done / total) if total else 10
            if step == self._last_step and done != total and time.monotonic() - self._last_line < 60:
                return
            self._last_step, self._last_line = step, time.monotonic()
            self.stream.write(text + "\n")
        self.stream.flush()


def _duration(seconds: float) -> str:
    if not math.isfinite(seconds):
        return "?"
    seconds = int(round(seconds))
    if seconds < 60:
        return f"{seconds}s"
    if seconds < 3600:
        return f"{seconds // 60}m{seconds % 60:02d}s"
    return f"{seconds // 3600}h{seconds % 3600 // 60:02d}m"


# =====================================================================================
# the batch
# =====================================================================================
@dataclass
class BatchResult:
    """What a batch produced: one record per case (as in DIR/cases/<id>.json) and one per sweep group."""

    out: Path
    name: str
    records: list[dict]
    groups: list[dict]
    ran: list[str] = field(default_factory=list)       # case ids run by this call
    skipped: list[str] = field(default_factory=list)   # finished before this call (resume)
    wall_s: float = 0.0
    interrupted: bool = False

    def count(self, status: str) -> int:
        return sum(1 for r in self.records if r.get("status") == status)

    @property
    def ok(self) -> int:
        return self.count("ok")

    @property
    def failed(self) -> int:
        return self.count("failed")

    @property
    def crashed(self) -> int:
        return self.count("crashed")

    @property
    def pending(self) -> int:
        return self.count("pending")

    def metric(self, name: str) -> np.ndarray:
        """One metric across the cases (NaN where missing)."""
        return np.array([_num(r.get("metrics", {}).get(name)) for r in self.records])

    def table(self) -> list[dict]:
        """summary.csv as a list of rows."""
        return summary_rows(self.records)


def _num(value) -> float:
    return float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) else float("nan")


def run_batch(config: Union[str, Path, Mapping, BatchConfig], out: Union[str, Path], workers: Optional[int] = None,
              scheduler=None, resume: bool = False, retry_failed: bool = False,
              progress: Union[bool, Callable[[Mapping], None]] = True, plots: bool = True,
              before_case: Optional[Callable[[Mapping], None]] = None, custom_metrics: Optional[Callable] = None,
              mp_context=None) -> BatchResult:
    """Run every case of ``config`` and write the results to ``out`` (see the module docstring).

    ``workers``: local worker processes (default: the number of cores); ``scheduler``: a Dask scheduler
    address or ``distributed.Client`` instead of the local pool. ``resume``: go on with the batch in
    ``out``, skipping its finished cases (``retry_failed``: run its failed and crashed cases again).
    ``progress``: True for the progress bar on stderr, or a callable given the counts after each case.
    ``before_case(task)`` and ``custom_metrics(result, task) -> {name: value}`` run in the worker for
    each case (module-level functions: they are pickled). Returns a :class:`BatchResult`; an
    interrupted batch (Ctrl-C) raises KeyboardInterrupt after saving what finished.
    """
    if not isinstance(config, BatchConfig):
        config = BatchConfig.load(config) if isinstance(config, (str, Path)) else BatchConfig.from_dict(config)
    Path(out).mkdir(parents=True, exist_ok=True)
    with _Lock(Path(out) / ".lock"):
        return _run_batch(config, Path(out), workers, scheduler, resume, retry_failed, progress, plots,
                          before_case, custom_metrics, mp_context)


class _Lock:
    """One driver per batch folder: a second `mast batch` on the same --out stops at once."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.handle = None

    def __enter__(self) -> "_Lock":
        self.handle = open(self.path, "a+")
        try:
            import fcntl

            fcntl.flock(self.handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except ImportError:  # not POSIX: no lock
            pass
        except OSError:
            self.handle.close()
            raise BatchConfigError(f"{self.path.parent}: another mast batch is running on this folder") from None
        return self

    def __exit__(self, *exc) -> None:
        self.handle.close()  # closing releases the lock


def _run_batch(config: BatchConfig, out: Path, workers, scheduler, resume, retry_failed, progress, plots,
               before_case, custom_metrics, mp_context) -> BatchResult:
    t0 = time.perf_counter()
    store = Store(out)
    if store.exists() and not resume:
        raise BatchConfigError(f"{store.out} already holds a batch: resume it (--resume) or choose another --out")
    if resume and not store.exists():
        resume = False  # nothing to resume: a fresh start
    sources = dict(config.ssp)
    inputs_dir = store.out / "inputs"
    inputs_dir.mkdir(parents=True, exist_ok=True)
    systems: dict[str, SystemInfo] = {}
    for name, source in sources.items():
        copy = inputs_dir / f"{name}{Path(source).suffix}"
        if not copy.exists():
            if not Path(source).exists():
                raise BatchConfigError(f"ssp '{name}': {source} does not exist (run `mast build`?)")
            if Path(source).suffix == ".ssd":  # a source folder: run it where it is
                copy = Path(source).resolve()
            else:
                tmp = copy.with_suffix(".tmp")
                shutil.copyfile(source, tmp)
                os.replace(tmp, copy)
        elif Path(source).exists() and _sha256(Path(source)) != _sha256(copy):
            print(f"warning: {source} changed since this batch started; the batch goes on with its copy {copy}",
                  file=sys.stderr)
        systems[name] = SystemInfo.read(copy)
    cases = expand(config, systems)
    by_id = {c.id: c for c in cases}
    finished = store.finished() if resume else {}
    for case_id, rec in finished.items():
        if case_id in by_id and rec.get("digest") != by_id[case_id].digest:
            raise BatchConfigError(f"{store.out}: case {case_id} was run with other settings than the config gives now "
                                   "(parameters, motion, SSP or outputs changed); start a new batch in another folder")
    if retry_failed:
        finished = {k: v for k, v in finished.items() if v.get("status") == "ok"}
    records: dict[str, dict] = {k: v for k, v in finished.items() if k in by_id}
    store.start(config, cases, systems, sources)
    todo = [c for c in cases if c.id not in records]
    skipped = [c.id for c in cases if c.id in records]
    show = BatchProgress(config.name) if progress is True else (progress or None)
    counts = {s: sum(1 for r in records.values() if r["status"] == s) for s in STATUSES}
    ran: list[str] = []

    def state() -> dict:
        return {"total": len(cases), "done": len(records), "skipped": len(skipped), **counts}

    def on_result(record: dict) -> None:
        case = by_id[record["id"]]
        entry = store.write_case(case, record)
        records[case.id] = entry
        counts[entry["status"]] += 1
        ran.append(case.id)
        store.write_manifest(config.name, cases, records)
        if show:
            show(state())

    tasks = [_task(config, c, systems[c.ssp], before_case, custom_metrics) for c in todo]
    interrupted = False
    try:
        if tasks:
            if show:
                show(state())
            executor = DaskCluster(scheduler) if scheduler is not None else LocalPool(workers, mp_context)
            executor.run(tasks, on_result)
    except KeyboardInterrupt:
        interrupted = True
        raise
    finally:
        store.write_manifest(config.name, cases, records, force=True)
        ordered = [records.get(c.id, {**c.as_dict(), "status": "pending"}) for c in cases]
        groups = group_rows(ordered)
        _write_tables(store.out, ordered, groups)
        if plots and not interrupted and any(r["status"] == "ok" for r in ordered):
            try:
                from .batch_plots import plot_batch

                plot_batch(store.out / "plots", ordered, groups, config.plots)
            except Exception as err:  # a figure is not worth losing the batch summary
                print(f"warning: plots not written: {type(err).__name__}: {err}", file=sys.stderr)
    return BatchResult(store.out, config.name, ordered, groups, ran, skipped, time.perf_counter() - t0, interrupted)


def _task(config: BatchConfig, case: Case, info: SystemInfo, before_case, custom_metrics) -> dict:
    motion = None
    if case.motion is not None:
        m = case.motion
        motion = {**m, "amplitude_si": m["amplitude"] if m["axis"] == "z" else math.radians(m["amplitude"])}
    return {"id": case.id, "ssp_path": str(info.path), "ssp_sha": info.sha256 or _digest(str(info.path)),
            "direct": config.direct, "parameters": case.parameters, "motion": motion, "stop_time": case.stop_time,
            "record_step": case.record_step, "window": case.window, "keep": list(config.keep),
            "metrics": list(config.metrics), "timeout": config.timeout, "before_case": before_case,
            "custom": custom_metrics or config.custom}


def read_batch(out: Union[str, Path]) -> BatchResult:
    """The results of a batch folder (finished or not) as a :class:`BatchResult`."""
    out = Path(out)
    try:
        manifest = json.loads((out / "manifest.json").read_text())
    except (OSError, ValueError) as err:
        raise FileNotFoundError(f"{out}: no readable manifest.json ({err})") from None
    finished = Store(out).finished()  # the per-case files are the truth; the manifest may lag
    records = [finished.get(r["id"], r) for r in manifest["cases"]]
    return BatchResult(out, manifest["name"], records, group_rows(records))


# =====================================================================================
# tables
# =====================================================================================
def summary_rows(records: Sequence[Mapping]) -> list[dict]:
    """One row per case: id, status, ssp, motion, sample, the varied inputs, the metrics, time, error."""
    input_keys = list(dict.fromkeys(k for r in records for k in r.get("inputs", {})))
    metric_keys = list(dict.fromkeys(k for r in records for k in r.get("metrics", {}) or {}))
    rows = []
    for r in records:
        motion = r.get("motion") or {}
        row = {"id": r["id"], "status": r["status"], "ssp": r.get("ssp"), "axis": motion.get("axis"),
               "amplitude": motion.get("amplitude"), "frequency_Hz": motion.get("frequency"), "sample": r.get("sample")}
        row.update({k: r.get("inputs", {}).get(k) for k in input_keys})
        row.update({k: (r.get("metrics") or {}).get(k) for k in metric_keys})
        row["case_s"] = (r.get("timing") or {}).get("case_s")
        row["error"] = (r.get("error") or "").splitlines()[0][:300] if r.get("error") else None
        rows.append(row)
    return rows


def group_rows(records: Sequence[Mapping]) -> list[dict]:
    """Per sweep group (same SSP, parameters and motion but the frequency): bandwidth and resonance."""
    groups: dict[str, list[Mapping]] = {}
    for r in records:
        if r.get("motion") and r["motion"].get("frequency"):
            groups.setdefault(r.get("group", ""), []).append(r)
    rows = []
    for key, members in groups.items():
        if len({m["motion"]["frequency"] for m in members}) < 2:
            continue
        first = members[0]
        ok = [m for m in members if m["status"] == "ok" and "magnitude" in (m.get("metrics") or {})]
        row = {"group": key, "ssp": first.get("ssp"), "axis": first["motion"]["axis"],
               "amplitude": first["motion"]["amplitude"], "sample": first.get("sample"),
               **{k: v for k, v in first.get("inputs", {}).items()},
               "cases": len(members), "ok": len(ok)}
        row.update(sweep_metrics([m["motion"]["frequency"] for m in ok], [m["metrics"]["magnitude"] for m in ok],
                                 [m["metrics"]["phase_deg"] for m in ok]))
        row["frequencies_Hz"] = [m["motion"]["frequency"] for m in ok]
        row["magnitudes"] = [m["metrics"]["magnitude"] for m in ok]
        row["phases_deg"] = [m["metrics"]["phase_deg"] for m in ok]
        rows.append(row)
    return rows


def _write_tables(out: Path, records: Sequence[Mapping], groups: Sequence[Mapping]) -> None:
    _write_csv(out / "summary.csv", summary_rows(records))
    if groups:
        _write_csv(out / "groups.csv", [{k: v for k, v in g.items() if not isinstance(v, list)} for g in groups])


def _write_csv(path: Path, rows: Sequence[Mapping]) -> None:
    keys = list(dict.fromkeys(k for r in rows for k in r))
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=keys, lineterminator="\n")
    writer.writeheader()
    for row in rows:
        writer.writerow({k: ("" if row.get(k) is None else _fmt(row.get(k))) for k in keys})
    _atomic_write(path, buffer.getvalue().encode())


def _fmt(value) -> str:
    if isinstance(value, float):
        return "nan" if value != value else f"{value:.10g}"
    return str(value)


def describe(cases: Sequence[Case], limit: int = 20) -> str:
    """A short listing of the cases (``mast batch --dry-run``)."""
    lines = [f"{len(cases)} case(s)"]
    for case in cases[:limit]:
        m = case.motion
        motion = f"{m['axis']} {m['amplitude']:g} @ {m['frequency']:g} Hz" if m else "no motion"
        inputs = ", ".join(f"{k}={_fmt(v) if isinstance(v, float) else v}" for k, v in case.inputs.items())
        lines.append(f"  {case.id}  ssp={case.ssp}  {motion}  stop {case.stop_time:g} s  {inputs}")
    if len(cases) > limit:
        lines.append(f"  ... {len(cases) - limit} more")
    return "\n".join(lines)
