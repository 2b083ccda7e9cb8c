"""Re-simulation of measured tests: the co-simulation driven by their recorded commands, in a pool of
workers, cached per parameter set; the model's observed torque and the effect signatures at a point."""

from __future__ import annotations

import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from typing import Mapping, Optional, Sequence

import numpy as np

from ..data.measured import CommandReplay, MeasuredTest
from .effects import CONTROLLER_PARAMETERS, MEASUREMENT, Chain, SimSignals, axis_values, chain_for, column
from .phasefree import COMMAND_JITTER


class DiagnosisError(RuntimeError):
    pass


class SimulationFailed(DiagnosisError):
    """A re-simulation failed (the loop went unstable, the carriage left the stroke, the model rejected a
    value): in a trial, information that the parameter values are wrong, not the end of the diagnosis."""


# --------------------------------------------------------------------------------------
# simulation of measured tests
# --------------------------------------------------------------------------------------
def sim_job(args: tuple) -> dict:
    from ..core.master import SimulationError
    from ..core.run import simulate

    ssp, name, replay, stop, parameters, direct, steps, actuators = args
    record = [f"{a}.{sig}" for a in actuators for sig in ("tau_m", "rho", "rho_dot", "omega_m")]
    try:
        res = simulate(
            ssp,
            replay,
            stop,
            parameters=parameters,
            record=record,
            record_step=None,
            direct=direct,
            base_step=steps and steps[0],
            step_sizes=steps and steps[1],
        )
    except SimulationError as err:
        return {"name": name, "error": str(err)}
    except Exception as err:  # parameters the model rejects, ...
        return {"name": name, "error": f"{type(err).__name__}: {err}"}
    out = {"name": name, "time": res.time, "h": res.stats["base_step"]}
    for sig in ("tau_m", "rho", "rho_dot", "omega_m"):
        out[sig] = np.column_stack([res[f"{a}.{sig}"] for a in actuators])
    return out


@dataclass
class Prepared:
    """A measured test ready for comparison: analysis window, replay, roles."""

    test: MeasuredTest
    role: str
    replay: CommandReplay
    mask: np.ndarray
    t: np.ndarray  # data times in the window
    y: np.ndarray  # measured torque in the window (samples, drives)
    e: np.ndarray  # measured tracking error rho - rho_cmd in the window (samples, drives)

    @property
    def name(self) -> str:
        return self.test.name


class Simulator:
    """Runs the measured tests on the SSP (direct composition by default), in parallel, cached."""

    def __init__(
        self,
        ssp: str,
        tests: Mapping[str, Prepared],
        base: Mapping[str, Mapping],
        actuators: Sequence[str],
        direct: bool = True,
        workers: int = 2,
        nominal: Optional[Mapping[str, float]] = None,
    ) -> None:
        self.ssp, self.tests, self.base, self.actuators, self.direct = ssp, tests, base, list(actuators), direct
        self.nominal = dict(nominal or {})  # the all-axes values per-axis increments add to
        self.workers = max(1, workers)
        self._pool: Optional[ProcessPoolExecutor] = None
        self._cache: dict = {}
        self.count = 0
        self.seconds = 0.0
        from ..core.run import drive_tick_steps
        from ..core.ssp import SSPArchive

        with SSPArchive(ssp) as archive:  # exchanged every T_cur: the torque chain restated at that record step
            self.steps = drive_tick_steps(archive.system)

    def __enter__(self) -> "Simulator":
        if self.workers > 1:
            self._pool = ProcessPoolExecutor(max_workers=self.workers)
        return self

    def __exit__(self, *exc) -> None:
        if self._pool:
            self._pool.shutdown()

    def parameters(self, plant: Mapping[str, float], test: Prepared) -> dict:
        params = {k: dict(v) for k, v in self.base.items()}
        drive = {k: v for k, v in plant.items() if k in CONTROLLER_PARAMETERS}
        actuator = {k: v for k, v in plant.items() if k not in CONTROLLER_PARAMETERS}
        for j, name in enumerate(self.actuators):
            params.setdefault(name, {}).update(axis_values(actuator, self.nominal, j))
            params[name]["rho_0"] = float(test.test.rho_cmd[0, j])
        if drive:
            params.setdefault("controller", {}).update(drive)
        return params

    @staticmethod
    def _key(plant: Mapping[str, float]) -> tuple:
        return tuple(sorted((k, float(v)) for k, v in plant.items() if k not in MEASUREMENT))

    def prefetch(
        self, plants: Sequence[Mapping[str, float]], names: Sequence[str], realisations: Sequence[int] = (0,)
    ) -> None:
        """Simulate every (parameter set, test, realisation) not cached yet, all in one parallel batch.

        Realisation 0 replays the recorded commands; realisation r > 0 replays them perturbed far
        below their precision (phasefree.COMMAND_JITTER, seed r): another run of a loop that hunts."""
        todo = []
        for plant in plants:
            key = self._key(plant)
            todo += [
                (key, n, r)
                for n in names
                for r in realisations
                if (key, n, r) not in self._cache and (key, n, r) not in todo
            ]
        if not todo:
            return
        t0 = time.perf_counter()
        jobs = []
        for key, n, r in todo:
            params = self.parameters(dict(key), self.tests[n])
            jobs.append(
                (
                    self.ssp,
                    n,
                    self._replay(n, r),
                    self.tests[n].test.duration + 1e-12,
                    params,
                    self.direct,
                    self.steps,
                    self.actuators,
                )
            )
        order = sorted(range(len(jobs)), key=lambda k: -jobs[k][3])  # longest first keeps the workers busy
        if self._pool and len(jobs) > 1:
            results = dict(zip(order, self._pool.map(sim_job, [jobs[k] for k in order])))
        else:
            results = {k: sim_job(jobs[k]) for k in order}
        self.count += len(jobs)
        self.seconds += time.perf_counter() - t0
        if len(self._cache) + len(jobs) > 400:
            for k in list(self._cache)[: len(self._cache) // 2]:
                del self._cache[k]
        for k, entry in enumerate(todo):
            r = results[k]
            self._cache[entry] = (
                r["error"]
                if "error" in r
                else SimSignals(r["time"], r["h"], r["tau_m"], r["rho"], r["rho_dot"], r["omega_m"])
            )

    def _replay(self, name: str, realisation: int) -> CommandReplay:
        replay = self.tests[name].replay
        return replay.perturbed(realisation, COMMAND_JITTER) if realisation else replay

    def run(self, plant: Mapping[str, float], names: Sequence[str], realisation: int = 0) -> dict[str, SimSignals]:
        key = self._key(plant)
        self.prefetch([plant], names, (realisation,))
        out = {}
        for n in names:
            v = self._cache[(key, n, realisation)]
            if isinstance(v, str):
                raise SimulationFailed(f"simulation of test {n} with {dict(plant)} failed: {v}")
            out[n] = v
        return out


def resample(sim: SimSignals, values: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Base-grid values (m, drives) at the data times t (linear interpolation)."""
    return np.column_stack([np.interp(t, sim.time, values[:, j]) for j in range(values.shape[1])])


# --------------------------------------------------------------------------------------
# the model state: parameters and their evaluation
# --------------------------------------------------------------------------------------
@dataclass
class Point:
    """A model (actuator parameters, shared by the axes) evaluated on a set of tests."""

    params: dict  # full actuator parameters
    sims: dict[str, SimSignals]
    chain: Chain
    obs: dict[str, np.ndarray] = field(default_factory=dict)  # observed torque in the window
    err: dict[str, np.ndarray] = field(default_factory=dict)  # simulated tracking error in the window


class Model:
    """Evaluates parameter sets on the prepared tests (simulation + observation chain)."""

    def __init__(
        self, sim: Simulator, nominal: Mapping, tests: Mapping[str, Prepared], drive_T: float, drive_delay: float
    ) -> None:
        self.sim, self.nominal, self.tests = sim, dict(nominal), tests
        self.drive_T, self.drive_delay = drive_T, drive_delay
        #: trial simulations that failed: where in the workflow, the parameters, the error (for the report)
        self.failures: list[dict] = []

    def trial(
        self, changes: Mapping[str, float], names: Sequence[str], where: str, realisation: int = 0
    ) -> Optional[Point]:
        """``point`` for a trial value: None if a simulation fails (recorded in ``failures``, once per
        stage and parameter set). Every stage evaluates its trial values through here; a failure tells
        the stage the value is wrong (reject the proposal, shrink the step), never stops the diagnosis."""
        try:
            return self.point(changes, names, realisation)
        except SimulationFailed as err:
            entry = {"where": where, "parameters": {k: float(v) for k, v in changes.items()}, "error": str(err)}
            if not any(f["where"] == where and f["parameters"] == entry["parameters"] for f in self.failures):
                self.failures.append(entry)
            return None

    def point(self, changes: Mapping[str, float], names: Sequence[str], realisation: int = 0) -> Point:
        params = {**self.nominal, **changes}
        changed_plant = {k: v for k, v in changes.items() if k not in MEASUREMENT}
        sims = self.sim.run(changed_plant, names, realisation)
        h = next(iter(sims.values())).h
        try:
            chain = chain_for(params, h, self.drive_T, self.drive_delay, len(self.sim.actuators))
        except ValueError as err:  # a measurement value the model rejects (a negative lag)
            raise SimulationFailed(f"measurement model with {dict(changes)}: {err}") from None
        pt = Point(params, sims, chain)
        for n in names:
            prep, s = self.tests[n], sims[n]
            pt.obs[n] = resample(s, chain.observe(s.tau_m), prep.t)
            pt.err[n] = resample(s, s.rho, prep.t) - prep.test.rho_cmd[prep.mask]
        return pt

    def columns(
        self, pt: Point, names: Sequence[str], param: str, grid: Optional[float] = None
    ) -> dict[str, np.ndarray]:
        out = {}
        for n in names:
            s = pt.sims[n]
            out[n] = resample(s, column(param, s, pt.params, pt.chain, grid), self.tests[n].t)
        return out

    def signals(self, pt: Point, n: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(guide speed at the motor shaft, its acceleration, carriage position) in the window."""
        s, prep = pt.sims[n], self.tests[n]
        return (
            resample(s, s.derived("omega_N", pt.params), prep.t),
            resample(s, s.derived("acc_N", pt.params), prep.t),
            resample(s, s.rho, prep.t),
        )
