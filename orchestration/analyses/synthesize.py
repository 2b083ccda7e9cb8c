"""Synthetic measurements with a hidden effect: ``mast synthesize``.

Runs the co-simulation with a *truth* (the SSP's parameters plus ``--set`` overrides),
then measures it the way a lab would: the drive's torque filter (first-order low-pass,
documented in meta.json), white sensor noise on the logged torque, encoder quantisation
and noise of the carriage positions, sampling at the log rate. The joint commands are
logged as the drive sees them: the controller's inverse kinematics of the pose command at
each sample. Writes a measured-data folder (docs/measured-data.md) and, *outside* it, the
truth (``DIR.truth.json`` by default): the diagnosis never reads that file.
"""

from __future__ import annotations

import json
import math
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Mapping, Optional, Sequence

import numpy as np

from fmus.actuator.sensor import measure
from fmus.mechanism.topology import POSE, Coordinate

from ..core.motion import pose_inputs, system_axes
from ..data.measured import FORMAT, VERSION, controller_kinematics, write_test_csv

#: the drive's torque filter that every synthetic measurement goes through [s] (about 320 Hz)
DEFAULT_TORQUE_FILTER = 5e-4
#: sensor noise (standard deviation) on the logged torque [N m] and carriage position [m]
DEFAULT_NOISE = {"tau_m": 2e-3, "rho": 0.0}
#: encoder resolution of the carriage position [m]
DEFAULT_RESOLUTION = {"rho": 1e-6}
DEFAULT_SAMPLE_TIME = 1e-3
SETTLE_S = 1.0


@dataclass(frozen=True)
class TestSpec:
    """One sine test: motion a coordinate of the system's mechanism (the 3PRS: z, psi, theta), amplitude in m
    for a length, rad for an angle."""

    motion: str
    amplitude: float
    frequency: float
    duration: float = 0.0  # 0: settle + 2 periods, at least 2 s
    settle: float = SETTLE_S  # the analysis starts here (at most half the test)

    def stop_time(self) -> float:
        return self.duration or max(2.0, self.settle + 2.0 / self.frequency)

    @property
    def name(self) -> str:
        return f"{self.motion}_{self.frequency:g}Hz"


#: the default test plan: z sines over the paper's range, and one psi and one theta test
DEFAULT_TESTS: tuple[TestSpec, ...] = (
    TestSpec("z", 0.005, 0.4),
    TestSpec("theta", math.radians(0.8), 0.8),
    TestSpec("z", 0.005, 1.0),
    TestSpec("z", 0.005, 2.0),
    TestSpec("psi", math.radians(0.8), 3.0),
    TestSpec("z", 0.005, 5.0),
    TestSpec("z", 0.005, 10.0),
)


def parse_tests(text: str) -> list[TestSpec]:
    """'z:0.005:0.4,theta:0.8:2' (amplitude in m for a length, degrees for an angle; frequency in Hz)."""
    tests = []
    for item in text.split(","):
        parts = item.strip().split(":")
        if len(parts) not in (3, 4) or parts[0] not in POSE:
            raise ValueError(
                f"--tests item {item!r}: expected MOTION:AMPLITUDE:FREQUENCY[:DURATION], "
                f"motion a pose coordinate ({', '.join(POSE)}; the 3PRS's: z, psi or theta)"
            )
        try:
            a, f = float(parts[1]), float(parts[2])
            d = float(parts[3]) if len(parts) == 4 else 0.0
        except ValueError:
            a = f = d = math.nan
        if not (math.isfinite(a) and f > 0 and math.isfinite(f) and d >= 0 and math.isfinite(d)):
            raise ValueError(
                f"--tests item {item!r}: expected a finite amplitude, a frequency > 0 Hz and a duration >= 0 s"
            )
        tests.append(TestSpec(parts[0], math.radians(a) if Coordinate(parts[0]).angular else a, f, d))
    return tests


def expand_overrides(overrides: Mapping[str, Mapping], components: Sequence[str]) -> dict[str, dict]:
    """``actuator.X`` (or ``actuators.X``) applies X to every actuator_k; other elements as given."""
    out: dict[str, dict] = {}
    actuators = [c for c in components if c.startswith("actuator_")]
    for element, values in overrides.items():
        targets = actuators if element in ("actuator", "actuators") else [element]
        for t in targets:
            if t not in components:
                raise ValueError(f"--set {element}.*: no component '{t}' (components: {', '.join(components)})")
            out.setdefault(t, {}).update(values)
    return out


def _synth_worker(args: tuple) -> dict:
    from ..core.motion import SineMotion
    from ..core.run import simulate

    ssp, spec, parameters, direct, steps, axes = args
    record = [*pose_inputs(axes), *(f"mechanism.{a}" for a in axes)]
    for j in range(1, len(axes) + 1):
        record += [f"actuator_{j}.rho", f"actuator_{j}.tau_meas", f"actuator_{j}.tau_m"]
    res = simulate(
        ssp,
        SineMotion(spec.motion, spec.amplitude, spec.frequency, axes=axes),
        spec.stop_time(),
        parameters=parameters,
        record=record,
        record_step=None,
        direct=direct,
        base_step=steps and steps[0],
        step_sizes=steps and steps[1],
    )
    return {"time": res.time, **res.signals, "base_step": res.stats["base_step"]}


def synthesize(
    ssp: str,
    out: Path,
    truth: Mapping[str, Mapping] = None,
    tests: Sequence[TestSpec] = DEFAULT_TESTS,
    noise: Optional[Mapping[str, float]] = None,
    resolution: Optional[Mapping[str, float]] = None,
    torque_filter_s: float = DEFAULT_TORQUE_FILTER,
    sample_time: float = DEFAULT_SAMPLE_TIME,
    seed: int = 0,
    direct: bool = False,
    workers: int = 2,
    truth_path: Optional[Path] = None,
    log=print,
) -> dict:
    """Write the measured-data folder ``out`` and the truth file; return the noise-free signals too.

    The system's mechanism may have any drives and coordinates (its topology): the tests' motions are its
    coordinates, the folder holds one rho_cmd_k, rho_k, tau_m_k column per drive (meta.json's ``drives``)."""
    from ..core.ssp import SSPArchive

    out = Path(out)
    noise = {**DEFAULT_NOISE, **(noise or {})}
    resolution = {**DEFAULT_RESOLUTION, **(resolution or {})}
    for key in noise:
        if key not in ("tau_m", "rho"):
            raise ValueError(f"--noise {key}: expected tau_m or rho")
    from ..core.run import drive_tick_steps

    with SSPArchive(ssp) as archive:
        components = list(archive.system.components)
        # every T_cur: the torque measured at the resolution of the drive's sensor (the diagnosis restates its chain)
        steps = drive_tick_steps(archive.system)
        base = steps[0] if steps else archive.system.base_step
        truth = expand_overrides(truth or {}, components)
        axes = system_axes(archive.system, truth)
        system_name = archive.system.name
    kinematics = controller_kinematics(ssp, truth)
    if kinematics.names != tuple(axes):
        raise ValueError(
            f"{ssp}: its mechanism's coordinates are {', '.join(axes)}, its controller's kinematic model's "
            f"{', '.join(kinematics.names)}: the joint commands are logged with the controller's model"
        )
    drives = range(1, len(axes) + 1)
    for spec in tests:
        if spec.motion not in axes:
            raise ValueError(
                f"--tests motion {spec.motion!r}: {ssp} has no such coordinate; its mechanism's "
                f"coordinates are {', '.join(axes)}"
            )
    every = round(sample_time / base)
    if every < 1 or abs(every * base - sample_time) > 1e-9 * sample_time:
        raise ValueError(f"--sample-time {sample_time:g} s: expected a whole multiple of the base step {base:g} s")
    out.mkdir(parents=True, exist_ok=True)
    for old in out.glob("*.csv"):
        old.unlink()
    jobs = [(str(ssp), spec, truth, direct, steps, axes) for spec in tests]
    names = [spec.name for spec in tests]
    if len(set(names)) != len(names):
        raise ValueError("two tests with the same motion and frequency")
    workers = max(1, min(workers, len(jobs)))
    if workers > 1:
        with ProcessPoolExecutor(max_workers=workers) as pool:
            runs = list(pool.map(_synth_worker, jobs))
    else:
        runs = [_synth_worker(j) for j in jobs]
    clean = {}
    entries = []
    for k, (spec, run) in enumerate(zip(tests, runs)):
        rng = np.random.default_rng([seed, k])
        h = run["base_step"]
        idx = np.arange(0, len(run["time"]), every)
        t = run["time"][idx]
        poses = np.column_stack([run[f"{a}_cmd"][idx] for a in axes])
        rho_cmd = np.array([kinematics.ik(q) for q in poses])
        rho = np.column_stack([run[f"actuator_{j}.rho"][idx] for j in drives])
        tau_fine = np.column_stack([run[f"actuator_{j}.tau_meas"] for j in drives])
        tau = measure(tau_fine, h, T=torque_filter_s, axis=0)[idx]
        clean[spec.name] = {
            "time": t,
            "rho_cmd": rho_cmd,
            "rho": rho.copy(),
            "tau_m": tau.copy(),
            "tau_m_plant": np.column_stack([run[f"actuator_{j}.tau_m"][idx] for j in drives]),
        }
        rho_meas = rho + noise["rho"] * rng.standard_normal(rho.shape)
        if resolution.get("rho"):
            q = resolution["rho"]
            rho_meas = np.round(rho_meas / q) * q
        tau_meas = tau + noise["tau_m"] * rng.standard_normal(tau.shape)
        pose = {a: run[f"mechanism.{a}"][idx] for a in axes}
        file = f"{spec.name}.csv"
        write_test_csv(out / file, t, rho_cmd, rho_meas, tau_meas, pose)
        entries.append(
            {
                "file": file,
                "motion": spec.motion,
                "amplitude": math.degrees(spec.amplitude) if Coordinate(spec.motion).angular else spec.amplitude,
                "amplitude_unit": "deg" if Coordinate(spec.motion).angular else "m",
                "frequency": spec.frequency,
                "settle_s": min(spec.settle, 0.5 * spec.stop_time()),
            }
        )
    meta = {
        "format": FORMAT,
        "version": VERSION,
        "machine": f"{system_name} (synthetic: mast synthesize)",
        "drives": len(drives),
        "description": "Sine tests around the home pose; joint commands as logged by the drive",
        "units": {"time": "s", "rho_cmd": "m", "rho": "m", "tau_m": "N.m", "position": "m", "angle": "rad"},
        "measurement": {
            "torque_filter_s": torque_filter_s,
            "torque_filter": "first-order low-pass of the drive's torque (current) measurement",
            "rho_resolution_m": resolution.get("rho", 0.0),
            "sample_time_s": sample_time,
        },
        "tests": entries,
    }
    (out / "meta.json").write_text(json.dumps(meta, indent=2))
    truth_path = Path(truth_path) if truth_path else out.parent / f"{out.name}.truth.json"
    truth_doc = {
        "note": f"The truth behind the synthetic measurements in the folder {out}. The diagnosis never reads it.",
        "ssp": str(ssp),
        "parameters": truth,
        "seed": seed,
        "measurement": {
            "noise_std": noise,
            "resolution": resolution,
            "torque_filter_s": torque_filter_s,
            "sample_time_s": sample_time,
        },
        "tests": [asdict(s) for s in tests],
    }
    truth_path.parent.mkdir(parents=True, exist_ok=True)
    truth_path.write_text(json.dumps(truth_doc, indent=2))
    log(f"wrote {len(tests)} tests to {out} (meta.json), the truth to {truth_path}")
    return {"folder": out, "truth": truth_path, "clean": clean}
