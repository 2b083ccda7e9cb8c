"""Cases: the config expanded into one case per system, parameter set, motion and frequency; their ids
and digests (a resumed batch recognises its finished cases)."""

from __future__ import annotations

import fnmatch
import hashlib
import itertools
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping, Optional

import numpy as np

from ..analyses.frequency import measuring_window, record_step_of
from ..core.motion import pose_inputs
from .config import DISTRIBUTIONS, BatchConfig, BatchConfigError, as_list


@dataclass
class SystemInfo:
    """What case expansion needs to know about one SSP."""

    path: Path
    sha256: str
    components: list[str]
    system_inputs: list[str]
    nominal: dict[str, dict[str, Any]]  # component -> merged bindings
    parameters: dict[str, list[str]]  # component -> FMU parameter names
    signals: list[str]  # recordable: system inputs and declared outputs
    axes: tuple[str, ...] = ()  # its motion axes: its mechanism's coordinates (core.motion.system_axes)

    @classmethod
    def read(cls, path: Path) -> "SystemInfo":
        from fmpy import read_model_description

        from ..core.motion import system_axes
        from ..core.run import default_signals
        from ..core.ssp import SSPArchive, check_archive

        with SSPArchive(path) as archive:
            system = archive.system
            names: dict[str, list[str]] = {}
            by_fmu: dict[Path, list[str]] = {}
            for comp in system.components:
                fmu = system.fmu_path(comp)
                if fmu not in by_fmu:
                    check_archive(fmu, system.fmu_label(comp))
                    md = read_model_description(str(fmu))
                    by_fmu[fmu] = [v.name for v in md.modelVariables if v.causality == "parameter"]
                names[comp] = by_fmu[fmu]
            return cls(
                path,
                sha256(path) if path.is_file() else "",
                list(system.components),
                list(system.system_inputs),
                {c: dict(s.parameters) for c, s in system.components.items()},
                names,
                default_signals(system),
                system_axes(system),
            )

    def resolve(self, key: str, where: str) -> list[tuple[str, str]]:
        """``ELEMENT.PARAMETER`` (ELEMENT may hold * ? [..] wildcards) -> [(component, parameter)]."""
        pattern, dot, param = str(key).partition(".")
        if not dot or not pattern or not param:
            raise BatchConfigError(
                f"{where}: '{key}' is not ELEMENT.PARAMETER (e.g. actuator_1.tau_c or actuator_*.tau_c)"
            )
        matches = [c for c in self.components if fnmatch.fnmatchcase(c, pattern)]
        if not matches:
            raise BatchConfigError(
                f"{where}: '{key}' matches no component of {self.path.name}; "
                f"its components are {', '.join(self.components)}"
            )
        for comp in matches:
            if param not in self.parameters[comp]:
                raise BatchConfigError(
                    f"{where}: '{key}': {comp} has no parameter '{param}'; "
                    f"its parameters are {', '.join(sorted(self.parameters[comp]))}"
                )
        return [(c, param) for c in matches]


@dataclass
class Case:
    """One co-simulation of the batch."""

    id: str
    index: int
    ssp: str  # variant name
    inputs: dict[str, Any]  # what the case dimensions set, named as in the config
    parameters: dict[str, Any]  # every override, ELEMENT.PARAMETER, wildcards expanded
    motion: Optional[dict]  # axis, amplitude (config units: m, deg), frequency [Hz]
    sample: Optional[int]
    stop_time: float
    record_step: float
    window: tuple[float, float]  # metrics window [s]
    digest: str = ""
    group: str = ""

    def as_dict(self) -> dict:
        return {
            "id": self.id,
            "index": self.index,
            "ssp": self.ssp,
            "inputs": self.inputs,
            "parameters": self.parameters,
            "motion": self.motion,
            "sample": self.sample,
            "stop_time": self.stop_time,
            "record_step": self.record_step,
            "window": list(self.window),
            "digest": self.digest,
            "group": self.group,
        }


#: the most cases a batch runs unless told otherwise (``mast batch --max-cases``, ``max_cases=``)
DEFAULT_MAX_CASES = 10000


def dimension_sizes(config: BatchConfig) -> dict[str, int]:
    """How many entries each dimension of ``config`` present has (``cases.random.samples``, SSP variants,
    ``cases.list``, ``cases.grid`` points, ``cases.motion``, ``cases.frequency``), outermost first, counted from
    the config alone: nothing is drawn, read or built."""
    c = config.cases
    sizes = {}
    if c.get("random"):
        sizes["random samples"] = int(c["random"]["samples"])
    sizes["ssp variants"] = len(as_list(c["ssp"])) if "ssp" in c else len(config.ssp)
    if c.get("list"):
        sizes["list entries"] = len(c["list"])
    if c.get("grid"):
        sizes["grid points"] = math.prod(len(values) for values in c["grid"].values())
    if as_list(c.get("motion", [])):
        sizes["motions"] = len(as_list(c["motion"]))
    if "frequency" in c:
        sizes["frequencies"] = len(as_list(c["frequency"]))
    return sizes


def count_cases(config: BatchConfig) -> int:
    """The number of cases ``config`` expands into, without expanding it (the product of ``dimension_sizes``)."""
    return math.prod(dimension_sizes(config).values())


def check_case_count(config: BatchConfig, max_cases: int = DEFAULT_MAX_CASES) -> int:
    """The number of cases of ``config``; BatchConfigError, giving the count, its factors and the limit, when it is
    over ``max_cases`` (refused before anything is read, built or run: a runaway grid would exhaust the memory)."""
    total = count_cases(config)
    if total > max_cases:
        factors = " x ".join(f"{n} {what}" for what, n in dimension_sizes(config).items() if n != 1)
        raise BatchConfigError(
            f"the config expands to {total} cases ({factors}), over the limit of {max_cases}: "
            f"shrink the grid or raise the limit with --max-cases {total} (max_cases= in Python)"
        )
    return total


def expand(
    config: BatchConfig, systems: Optional[Mapping[str, SystemInfo]] = None, max_cases: int = DEFAULT_MAX_CASES
) -> list[Case]:
    """Every case of ``config``: the product of its dimensions (random samples outermost, then SSP
    variants, list entries, grid points, motions, frequencies innermost); ids c00000, c00001, ...
    More than ``max_cases`` cases are refused before anything is read (``check_case_count``)."""
    total = check_case_count(config, max_cases)
    systems = dict(systems) if systems else {}
    for name, path in config.ssp.items():
        if name not in systems:
            if not Path(path).exists():
                raise BatchConfigError(f"ssp '{name}': {path} does not exist (run `mast build`?)")
            systems[name] = SystemInfo.read(Path(path))
    for name, info in systems.items():
        unknown = [k for k in config.keep if k not in info.signals]
        if unknown:
            raise BatchConfigError(
                f"outputs.keep: {', '.join(unknown)} not in {info.path.name} (ssp '{name}'); "
                f"it has the system inputs and component outputs {', '.join(info.signals)}"
            )
    c = config.cases
    dims: list[list[dict]] = []
    rnd = c.get("random")
    if rnd:
        dims.append(_draw(rnd))
    names = as_list(c["ssp"]) if "ssp" in c else list(config.ssp)
    dims.append([{"ssp": n} for n in names])
    if c.get("list"):
        dims.append([{"inputs": dict(e), "list": k} for k, e in enumerate(c["list"])])
    grid = c.get("grid") or {}
    if grid:
        keys = list(grid)
        dims.append([{"inputs": dict(zip(keys, values))} for values in itertools.product(*(grid[k] for k in keys))])
    motions = as_list(c.get("motion", []))
    if motions:
        dims.append([{"motion": dict(m)} for m in motions])
    if "frequency" in c:
        dims.append([{"frequency": float(f)} for f in as_list(c["frequency"])])
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
            kind = next(iter(set(dist) & DISTRIBUTIONS))
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
                        raise BatchConfigError(
                            f"cases.random.{key}: 'relative' needs a numeric value of {comp}.{param} "
                            f"bound in {info.path.name}"
                        )
                    v = float(nominal) * (1.0 + value[1])
                if isinstance(v, bool) or not isinstance(v, (int, float, str)):
                    raise BatchConfigError(f"{layer} of {where}: {key} = {v!r}: expected a number or a string")
                overrides[f"{comp}.{param}"] = v
                shown = v if shown is None else shown
            if layer != "parameters":
                inputs[key] = shown
    motion = parts.get("motion")
    if motion is not None:
        motion = {
            "axis": motion["axis"],
            "amplitude": float(motion.get("amplitude", 0.0)),
            "frequency": float(parts.get("frequency", motion.get("frequency", 0.0))),
        }
    elif "frequency" in parts:
        raise BatchConfigError("cases.frequency needs a cases.motion (axis and amplitude)")
    if motion is not None:
        commands = pose_inputs(info.axes)
        if motion["axis"] not in info.axes:
            raise BatchConfigError(
                f"cases.motion axis {motion['axis']!r}: axis must be one of the coordinates of "
                f"{info.path.name}'s mechanism: {', '.join(info.axes)}"
            )
        if not all(s in info.system_inputs for s in commands):
            raise BatchConfigError(
                f"{info.path.name} has no pose command inputs ({', '.join(commands)}): it takes no cases.motion"
            )
    f = motion["frequency"] if motion else 0.0
    if config.stop_time == "auto":
        if not f > 0:
            raise BatchConfigError(
                f'{where}: run.stop_time = "auto" needs a sine motion with a frequency > 0; '
                "give run.stop_time in seconds"
            )
        start, stop = measuring_window(f)
    else:
        stop = float(config.stop_time)
        start = measuring_window(f)[0] if f > 0 and measuring_window(f)[0] < stop else 0.0
    if config.settle != "auto":
        start = min(float(config.settle), stop)
    end = stop
    if f > 0 and (stop - start) * f >= 1 - 1e-9:  # whole periods for the harmonic fit
        end = start + math.floor((stop - start) * f + 1e-9) / f
    record_step = (record_step_of(f) if f > 0 else 1e-3) if config.record_step == "auto" else float(config.record_step)
    case = Case(
        case_id,
        index,
        parts["ssp"],
        inputs,
        dict(sorted(overrides.items())),
        motion,
        parts.get("sample"),
        float(stop),
        float(record_step),
        (float(start), float(end)),
    )
    defining = {
        "ssp": info.sha256,
        "parameters": case.parameters,
        "direct": config.direct,
        "motion": None if motion is None else {k: v for k, v in motion.items() if k != "frequency"},
    }
    case.group = digest_of(defining)
    case.digest = digest_of(
        {
            **defining,
            "motion": motion,
            "stop_time": case.stop_time,
            "record_step": case.record_step,
            "window": case.window,
            "keep": config.keep,
            "metrics": config.metrics,
            "custom": config.custom,
            "timeout": config.timeout,
        }
    )
    return case


def digest_of(obj) -> str:
    return hashlib.sha256(json.dumps(obj, sort_keys=True, default=str).encode()).hexdigest()[:16]


def sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for chunk in iter(lambda: handle.read(1 << 20), b""):
            digest.update(chunk)
    return digest.hexdigest()
