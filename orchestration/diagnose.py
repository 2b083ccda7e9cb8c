"""``mast diagnose``: find where simulation and measurement disagree, name the missing effect,
add it, show the gap shrink (docs/diagnose.md).

1. Localise: simulate the nominal model on every measured test, driven by the recorded
   joint commands; per test and signal: fit %, NRMSE and where the residual concentrates.
2. Name: regress the torque residual on the signatures of the effect library
   (orchestration/effects.py), linearised at the current model. Every subset of effects
   is scored by BIC on the training tests; a subset is admissible only if each of its
   members is needed (removing it costs >= 10 in BIC *and* a measurable part of the
   held-out residual) and its parameters are physical.
3. Add and fit: the selected parameters by bounded least squares on the training tests,
   re-simulating the co-simulation at every step (start: the regression estimate;
   Jacobian: the effect signatures of the current simulation). Steps 2-3 repeat,
   re-linearised at the fitted model, until the selection stops changing.
   Backlash, which makes the loop hunt (unpredictably sample by sample), comes last, on a
   phase-free score: band powers of the residual against ensembles of re-simulations
   (orchestration/phasefree.py).
4. Show: re-simulate every test; diagnosis.json, report.md with figures, the augmented
   parameter set (actuator_diagnosed.ssv) and an SSP that binds it.
5. The verdict: nothing missing (residual at the noise floor), explained (at the floor
   sample by sample, or by the band powers where a named backlash makes the loop hunt), or
   an unexplained residual (shown, never forced onto a name).
"""
from __future__ import annotations

import itertools
import json
import math
import time
import zipfile
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Mapping, Optional, Sequence

import numpy as np

from .effects import (BOUNDS, BY_KEY, BY_PARAMETER, LIBRARY, MEASUREMENT_PARAMETERS, Chain, Effect, SimSignals, chain_for, column,
                      frequency_slope, localise, noise_std, nrmse)
from .measured import AXES, CommandReplay, MeasuredData, MeasuredTest, controller_geometry, load
from .phasefree import COMMAND_JITTER, ENSEMBLE, PhaseFreeScore, estimate, refine

#: a member of a selection must lower BIC by at least this much ("very strong" evidence)
DELTA_BIC = 10.0
#: ... and explain at least this fraction of the noise variance on the held-out tests
PRACTICAL = 0.05
#: ... and at least this fraction of the held-out residual left above the noise
RELATIVE = 0.1
#: re-simulation steps (finite differences) for the parameters whose signature does not linearise well
FD_STEP = {"tau_s": 2e-3, "omega_s": 0.3}
#: effects fitted and verified by re-simulation (sample by sample) when a residual remains after the regression loop
NONLINEAR = tuple(e.key for e in LIBRARY if not e.regression and not e.phase_free)
#: bisection levels of a phase-free value after its scan (ratio 2 -> 2^(1/32): 2.2 %) ...
REFINE_LEVELS = 5
#: ... and the parabola through the deviances within the ratio of this level (2^(1/8)) of the best value
PARABOLA_LEVEL = 3
#: ... and at least this share of the whole gap of the current model (above the noise)
SHARE_OF_GAP = 0.01
#: at most this many effects at once
MAX_EFFECTS = 4
#: residual RMS within this factor of the noise floor: nothing left to explain
FLOOR_FACTOR = 1.2
MAX_ROUNDS = 5


class DiagnosisError(RuntimeError):
    pass


# --------------------------------------------------------------------------------------
# simulation of measured tests
# --------------------------------------------------------------------------------------
def _sim_job(args: tuple) -> dict:
    from .master import SimulationError
    from .run import simulate

    ssp, name, replay, stop, parameters, direct = args
    record = []
    for j in AXES:
        record += [f"actuator_{j}.tau_m", f"actuator_{j}.rho", f"actuator_{j}.rho_dot", f"actuator_{j}.omega_m"]
    try:
        res = simulate(ssp, replay, stop, parameters=parameters, record=record, record_step=1e-9, direct=direct)
    except SimulationError as err:
        return {"name": name, "error": str(err)}
    except Exception as err:  # parameters the model rejects, ...
        return {"name": name, "error": f"{type(err).__name__}: {err}"}
    out = {"name": name, "time": res.time, "h": res.stats["base_step"]}
    for sig in ("tau_m", "rho", "rho_dot", "omega_m"):
        out[sig] = np.column_stack([res[f"actuator_{j}.{sig}"] for j in AXES])
    return out


@dataclass
class Prepared:
    """A measured test ready for comparison: analysis window, replay, roles."""

    test: MeasuredTest
    role: str
    replay: CommandReplay
    mask: np.ndarray
    t: np.ndarray            # data times in the window
    y: np.ndarray            # measured torque in the window (n, 3)
    e: np.ndarray            # measured tracking error rho - rho_cmd in the window (n, 3)

    @property
    def name(self) -> str:
        return self.test.name


class Simulator:
    """Runs the measured tests on the SSP (direct composition by default), in parallel, cached."""

    def __init__(self, ssp: str, tests: Mapping[str, Prepared], base: Mapping[str, Mapping], actuators: Sequence[str],
                 direct: bool = True, workers: int = 2) -> None:
        self.ssp, self.tests, self.base, self.actuators, self.direct = ssp, tests, base, list(actuators), direct
        self.workers = max(1, workers)
        self._pool: Optional[ProcessPoolExecutor] = None
        self._cache: dict = {}
        self.count = 0
        self.seconds = 0.0

    def __enter__(self) -> "Simulator":
        if self.workers > 1:
            self._pool = ProcessPoolExecutor(max_workers=self.workers)
        return self

    def __exit__(self, *exc) -> None:
        if self._pool:
            self._pool.shutdown()

    def parameters(self, plant: Mapping[str, float], test: Prepared) -> dict:
        params = {k: dict(v) for k, v in self.base.items()}
        for j, name in enumerate(self.actuators):
            params.setdefault(name, {}).update(plant)
            params[name]["rho_0"] = float(test.test.rho_cmd[0, j])
        return params

    @staticmethod
    def _key(plant: Mapping[str, float]) -> tuple:
        return tuple(sorted((k, float(v)) for k, v in plant.items() if k not in MEASUREMENT_PARAMETERS))

    def prefetch(self, plants: Sequence[Mapping[str, float]], names: Sequence[str],
                 realisations: Sequence[int] = (0,)) -> None:
        """Simulate every (parameter set, test, realisation) not cached yet, all in one parallel batch.

        Realisation 0 replays the recorded commands; realisation r > 0 replays them perturbed far
        below their precision (phasefree.COMMAND_JITTER, seed r): another run of a loop that hunts."""
        todo = []
        for plant in plants:
            key = self._key(plant)
            todo += [(key, n, r) for n in names for r in realisations
                     if (key, n, r) not in self._cache and (key, n, r) not in todo]
        if not todo:
            return
        t0 = time.perf_counter()
        jobs = [(self.ssp, n, self._replay(n, r), self.tests[n].test.duration + 1e-12,
                 self.parameters(dict(key), self.tests[n]), self.direct) for key, n, r in todo]
        order = sorted(range(len(jobs)), key=lambda k: -jobs[k][3])   # longest first keeps the workers busy
        if self._pool and len(jobs) > 1:
            results = dict(zip(order, self._pool.map(_sim_job, [jobs[k] for k in order])))
        else:
            results = {k: _sim_job(jobs[k]) for k in order}
        self.count += len(jobs)
        self.seconds += time.perf_counter() - t0
        if len(self._cache) + len(jobs) > 400:
            for k in list(self._cache)[:len(self._cache) // 2]:
                del self._cache[k]
        for k, entry in enumerate(todo):
            r = results[k]
            self._cache[entry] = r["error"] if "error" in r else SimSignals(
                r["time"], r["h"], r["tau_m"], r["rho"], r["rho_dot"], r["omega_m"])

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
                raise DiagnosisError(f"simulation of test {n} with {dict(plant)} failed: {v}")
            out[n] = v
        return out


def _sample(sim: SimSignals, values: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Base-grid values (m, 3) at the data times t (linear interpolation)."""
    return np.column_stack([np.interp(t, sim.time, values[:, j]) for j in range(values.shape[1])])


# --------------------------------------------------------------------------------------
# the model state: parameters and their evaluation
# --------------------------------------------------------------------------------------
@dataclass
class Point:
    """A model (actuator parameters, shared by the axes) evaluated on a set of tests."""

    params: dict                      # full actuator parameters
    sims: dict[str, SimSignals]
    chain: Chain
    obs: dict[str, np.ndarray] = field(default_factory=dict)       # observed torque in the window
    err: dict[str, np.ndarray] = field(default_factory=dict)       # simulated tracking error in the window


class Model:
    """Evaluates parameter sets on the prepared tests (simulation + observation chain)."""

    def __init__(self, sim: Simulator, nominal: Mapping, tests: Mapping[str, Prepared], drive_T: float,
                 drive_delay: float) -> None:
        self.sim, self.nominal, self.tests = sim, dict(nominal), tests
        self.drive_T, self.drive_delay = drive_T, drive_delay

    def point(self, changes: Mapping[str, float], names: Sequence[str], realisation: int = 0) -> Point:
        params = {**self.nominal, **changes}
        changed_plant = {k: v for k, v in changes.items() if k not in MEASUREMENT_PARAMETERS}
        sims = self.sim.run(changed_plant, names, realisation)
        h = next(iter(sims.values())).h
        chain = chain_for(params, h, self.drive_T, self.drive_delay)
        pt = Point(params, sims, chain)
        for n in names:
            prep, s = self.tests[n], sims[n]
            pt.obs[n] = _sample(s, chain.observe(s.tau_m), prep.t)
            pt.err[n] = _sample(s, s.rho, prep.t) - prep.test.rho_cmd[prep.mask]
        return pt

    def columns(self, pt: Point, names: Sequence[str], param: str, grid: Optional[float] = None) -> dict[str, np.ndarray]:
        out = {}
        for n in names:
            s = pt.sims[n]
            out[n] = _sample(s, column(param, s, pt.params, pt.chain, grid), self.tests[n].t)
        return out

    def signals(self, pt: Point, n: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(guide speed at the motor shaft, its acceleration, carriage position) in the window."""
        s, prep = pt.sims[n], self.tests[n]
        return (_sample(s, s.derived("omega_N", pt.params), prep.t), _sample(s, s.derived("acc_N", pt.params), prep.t),
                _sample(s, s.rho, prep.t))


# --------------------------------------------------------------------------------------
# selection: best subset by BIC, each member needed on training (BIC) and held-out data
# --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Atom:
    effect: Effect
    grid: Optional[float] = None

    @property
    def label(self) -> str:
        return self.effect.key + (f"@{self.grid:g}" if self.grid is not None else "")


@dataclass
class SubsetFit:
    atoms: tuple[Atom, ...]
    coef: np.ndarray          # per atom, in parameter units (change of the first parameter)
    rss_tr: float
    rss_ho: float
    bic: float
    admissible: bool = False
    reasons: list = field(default_factory=list)


class Band:
    """Low-pass (zero phase) and decimation of a test's samples before regression and scoring.

    The library's signatures live below a few tens of hertz; the transmission mode (786 Hz,
    almost undamped) rings after every friction reversal and aliases into a 1 kHz log. A
    change of inertia or mass detunes that ringing, which no linear signature follows. The
    selection therefore looks at the band below ``fc``; the fit (re-simulation) and the
    final comparison use the full band.
    """

    def __init__(self, fc: float = 40.0) -> None:
        self.fc = fc
        self._sos: dict = {}
        self._factor: dict = {}

    def _design(self, dt: float):
        key = round(dt, 12)
        if key not in self._sos:
            from scipy.signal import butter

            fs = 1.0 / dt
            if fs < 5.0 * self.fc:
                self._sos[key] = (None, 1)
            else:
                self._sos[key] = (butter(4, self.fc, fs=fs, output="sos"), max(1, int(fs / (2.5 * self.fc))))
        return self._sos[key]

    def apply(self, x: np.ndarray, dt: float) -> np.ndarray:
        from scipy.signal import sosfiltfilt

        sos, q = self._design(dt)
        if sos is None:
            return np.asarray(x)
        return sosfiltfilt(sos, x, axis=0)[::q]

    def noise_factor(self, dt: float) -> float:
        """Standard deviation of white noise after the band, per unit of its standard deviation."""
        key = round(dt, 12)
        if key not in self._factor:
            rng = np.random.default_rng(12345)
            w = rng.standard_normal((20000, 2))
            self._factor[key] = float(np.std(self.apply(w, dt)[50:-50]))
        return self._factor[key]


class Regression:
    """Least squares of a residual on the atoms' columns, for every subset, from Gram matrices."""

    def __init__(self, atoms: Sequence[Atom], A_tr: np.ndarray, r_tr: np.ndarray, A_ho: np.ndarray, r_ho: np.ndarray,
                 sigma: float) -> None:
        self.atoms = list(atoms)
        scale = np.linalg.norm(A_tr, axis=0)
        scale[scale == 0] = 1.0
        self.scale = scale
        Atr, Aho = A_tr / scale, A_ho / scale
        self.G, self.g, self.rr = Atr.T @ Atr, Atr.T @ r_tr, float(r_tr @ r_tr)
        self.Gh, self.gh, self.rrh = Aho.T @ Aho, Aho.T @ r_ho, float(r_ho @ r_ho)
        self.n_tr, self.n_ho = len(r_tr), len(r_ho)
        self.sigma = sigma          # noise standard deviation in the band
        self._fits: dict = {}

    def fit(self, idx: tuple[int, ...]) -> SubsetFit:
        idx = tuple(sorted(idx))
        if idx in self._fits:
            return self._fits[idx]
        atoms = tuple(self.atoms[i] for i in idx)
        k = sum(a.effect.cost for a in atoms)
        if idx:
            G = self.G[np.ix_(idx, idx)]
            if np.linalg.cond(G) > 1e10:
                fit = SubsetFit(atoms, np.full(len(idx), np.nan), math.inf, math.inf, math.inf, reasons=["degenerate"])
                self._fits[idx] = fit
                return fit
            th = np.linalg.solve(G, self.g[list(idx)])
            rss = max(self.rr - float(th @ self.g[list(idx)]), 1e-300)
            rss_ho = self.rrh - 2 * float(th @ self.gh[list(idx)]) + float(th @ self.Gh[np.ix_(idx, idx)] @ th)
            coef = th / self.scale[list(idx)]
        else:
            rss, rss_ho, coef = self.rr, self.rrh, np.zeros(0)
        bic = self.n_tr * math.log(rss / self.n_tr) + k * math.log(self.n_tr)
        fit = SubsetFit(atoms, coef, rss, rss_ho, bic)
        self._fits[idx] = fit
        return fit

    def score(self, fit: SubsetFit) -> float:
        held = self.n_ho * math.log(max(fit.rss_ho, 1e-300) / self.n_ho) if self.n_ho else 0.0
        return fit.bic + held

    def held_out_needed(self, rss_ho_without: float) -> float:
        """The held-out RSS an effect must remove: a share of the noise and of what is left to explain."""
        noise = self.sigma ** 2 * self.n_ho
        return max(PRACTICAL * noise, RELATIVE * max(rss_ho_without - noise, 0.0))


def _in_bounds(effect: Effect, nominal: Mapping, change: float) -> bool:
    name = effect.parameter
    lo, hi = BOUNDS[name]
    value = float(nominal[name]) + change
    return lo - 1e-12 <= value <= hi + 1e-12


def _labels(atoms: Sequence[Atom]) -> tuple[str, ...]:
    return tuple(sorted(a.effect.key for a in atoms))


def select(reg: Regression, nominal: Mapping, max_size: int, exclude: frozenset = frozenset()
           ) -> tuple[SubsetFit, list[SubsetFit]]:
    """The admissible subset with the lowest BIC (at most ``max_size`` effects, one per group).

    Admissible: every member is needed (removing it raises BIC by >= DELTA_BIC on the
    training tests and the held-out RSS by ``held_out_needed``) and every parameter stays
    within its bounds. Subsets in ``exclude`` (by effect keys) were refuted by re-simulation.
    """
    fits = []
    # far from the data (the first rounds), each member must also carry a share of the whole gap:
    # small terms that only soak up the linearisation error of the big ones wait for the next round
    empty = reg.fit(())
    if reg.n_ho:
        floor_total = SHARE_OF_GAP * max(empty.rss_ho - reg.sigma ** 2 * reg.n_ho, 0.0)
    else:
        floor_total = SHARE_OF_GAP * max(empty.rss_tr - reg.sigma ** 2 * reg.n_tr, 0.0)
    by_effect: dict[str, list[int]] = {}
    for i, a in enumerate(reg.atoms):
        by_effect.setdefault(a.effect.key, []).append(i)
    keys = list(by_effect)
    for size in range(0, max_size + 1):
        for combo in itertools.combinations(keys, size):
            groups = [BY_KEY[k].group for k in combo if BY_KEY[k].group]
            if len(groups) != len(set(groups)) or tuple(sorted(combo)) in exclude:
                continue
            for idx in itertools.product(*[by_effect[k] for k in combo]):
                fit = reg.fit(idx)
                if not math.isfinite(fit.bic):
                    continue
                reasons = []
                for a, c in zip(fit.atoms, fit.coef):
                    if not _in_bounds(a.effect, nominal, c):
                        reasons.append(f"{a.effect.parameter} outside its bounds")
                for m in range(len(idx)):
                    rest = reg.fit(idx[:m] + idx[m + 1:])
                    dbic = rest.bic - fit.bic
                    dho = rest.rss_ho - fit.rss_ho
                    if dbic < DELTA_BIC:
                        reasons.append(f"{fit.atoms[m].label}: BIC gain {dbic:.1f} < {DELTA_BIC:g}")
                    if reg.n_ho and dho < reg.held_out_needed(rest.rss_ho):
                        reasons.append(f"{fit.atoms[m].label}: held-out gain too small")
                    gain = dho if reg.n_ho else rest.rss_tr - fit.rss_tr
                    if gain < floor_total:
                        reasons.append(f"{fit.atoms[m].label}: less than {100 * SHARE_OF_GAP:g} % of the gap")
                fit.admissible = not reasons
                fit.reasons = reasons
                fits.append(fit)
    admissible = [f for f in fits if f.admissible]
    # score: BIC on the training tests plus the held-out deviance n_ho ln(RSS_ho / n_ho): explanations the
    # training tests cannot tell apart (a heavier carriage, or more inertia and an offset, on z motions
    # only) are told apart by how they predict the held-out tests
    best = min(admissible, key=reg.score) if admissible else reg.fit(())
    # alternatives the data cannot separate: name the preferred member of a group
    for a in list(best.atoms):
        if a.effect.group and not a.effect.preferred:
            pref = [e for e in LIBRARY if e.group == a.effect.group and e.preferred][0]
            want = {x.effect.key for x in best.atoms if x is not a} | {pref.key}
            cand = [f for f in admissible if {x.effect.key for x in f.atoms} == want]
            if cand:
                c = min(cand, key=reg.score)
                if reg.score(c) - reg.score(best) < DELTA_BIC:
                    best = c
    return best, fits


# --------------------------------------------------------------------------------------
# the workflow
# --------------------------------------------------------------------------------------
@dataclass
class Options:
    measured: Path
    out: Path
    ssp: str
    model: Optional[str] = None           # a parameter set (.ssv path or name in the SSP's resources)
    holdout: Optional[Sequence[str]] = None
    workers: int = 2
    direct: bool = True
    library: Sequence[str] = tuple(e.key for e in LIBRARY)
    figures: bool = True


def _model_overrides(ssp: str, model: Optional[str]) -> dict:
    """Actuator parameter overrides of the nominal model (``--model``): an .ssv file, or the name of a
    parameter set inside the SSP (resources/NAME.ssv) or of the project's sources (ssp/resources/NAME.ssv)."""
    if not model:
        return {}
    from .ssp import SSPArchive
    from .ssv import parse_ssv

    path = Path(model)
    if path.exists():
        return {k: v.value for k, v in parse_ssv(path).items()}
    name = model if model.endswith(".ssv") else f"{model}.ssv"
    with SSPArchive(ssp) as archive:
        res = archive.ssd.parent / "resources"
        for candidate in (res / name, res / "parameters" / name, Path(__file__).resolve().parents[1] / "ssp" /
                          "resources" / name):
            if candidate.exists():
                return {k: v.value for k, v in parse_ssv(candidate).items()}
        have = sorted({p.stem for p in res.rglob("*.ssv")} |
                      {p.stem for p in (Path(__file__).resolve().parents[1] / "ssp" / "resources").glob("*.ssv")})
    raise DiagnosisError(f"--model {model}: neither a file nor a parameter set of the SSP or of ssp/resources "
                         f"(known: {', '.join(have)})")


def _split(data: MeasuredData, holdout: Optional[Sequence[str]]) -> dict[str, str]:
    names = [t.name for t in data.tests]
    if holdout:
        unknown = [h for h in holdout if h not in names]
        if unknown:
            raise DiagnosisError(f"--holdout {', '.join(unknown)}: no such test (tests: {', '.join(names)})")
        return {n: ("held-out" if n in holdout else "training") for n in names}
    if any(t.role for t in data.tests):
        return {t.name: (t.role or "training") for t in data.tests}
    order = sorted(data.tests, key=lambda t: (t.frequency or 0.0, t.name))
    roles = {t.name: ("held-out" if k % 2 else "training") for k, t in enumerate(order)}
    if len(order) < 3:
        roles = {t.name: "training" for t in order}
    return roles


def _stack(d: Mapping[str, np.ndarray], names: Sequence[str]) -> np.ndarray:
    return np.concatenate([d[n].ravel() for n in names]) if names else np.zeros(0)


@dataclass
class State:
    """The current model: selected effects, their fitted parameters, its evaluation on every test."""

    selected: tuple
    changes: dict
    pt: Point
    info: dict = field(default_factory=dict)


def diagnose(opt: Options, log: Callable[[str], None] = print) -> dict:
    t_start = time.perf_counter()
    from .ssp import SSPArchive

    with SSPArchive(opt.ssp) as archive:
        system = archive.system
        actuators = [n for n in system.components if n.startswith("actuator_")]
        if len(actuators) != 3:
            raise DiagnosisError(f"{opt.ssp}: expected three actuator_k components, found {', '.join(actuators)}")
        ssp_actuator = dict(system.components[actuators[0]].parameters)
    stroke = (float(ssp_actuator["rho_min"]), float(ssp_actuator["rho_max"]))
    data = load(opt.measured, stroke=stroke)
    model_over = _model_overrides(opt.ssp, opt.model)
    nominal = {**ssp_actuator, **model_over}
    base = {a: dict(model_over) for a in actuators} if model_over else {}
    geometry = controller_geometry(opt.ssp)
    roles = _split(data, opt.holdout)
    prepared: dict[str, Prepared] = {}
    for t in data.tests:
        mask = t.time >= t.settle_s - 1e-12
        prepared[t.name] = Prepared(t, roles[t.name], CommandReplay(t.time, t.rho_cmd, geometry), mask, t.time[mask],
                                    t.tau_m[mask], (t.rho - t.rho_cmd)[mask])
    names = [t.name for t in data.tests]
    train = [n for n in names if roles[n] == "training"]
    held = [n for n in names if roles[n] == "held-out"]
    sigma = float(np.median([noise_std(prepared[n].y[:, j]) for n in names for j in range(3)]))
    if not sigma > 0:
        raise DiagnosisError("the torque noise floor came out as 0: are the torques quantised coarsely or constant?")
    resolution = float(data.meta.get("measurement", {}).get("rho_resolution_m", 0.0) or 0.0)
    band = Band()
    sigma_b = sigma * float(np.median([band.noise_factor(prepared[n].test.sample_time) for n in names]))
    log(f"diagnose: {len(names)} tests ({len(train)} training, {len(held)} held-out), torque noise floor "
        f"{1e3 * sigma:.3g} mN.m")

    with Simulator(opt.ssp, prepared, base, actuators, direct=opt.direct, workers=opt.workers) as sim:
        model = Model(sim, nominal, prepared, data.torque_filter_s, data.torque_delay_s)
        ctx = _Context(model, nominal, names, train, held, band, sigma, sigma_b, log)
        nominal_pt = model.point({}, names)
        before = _gaps(prepared, nominal_pt, names, sigma, resolution)
        localised = {n: _localise(model, nominal_pt, prepared[n], sigma) for n in names}
        log("diagnose: nominal model: " + ", ".join(f"{n} {before[n]['torque_nrmse_percent']:.1f} %" for n in names))

        library = [BY_KEY[k] for k in opt.library]
        atoms = [Atom(e, g) for e in library if e.regression for g in (e.grid or (None,))]
        state = State((), {}, nominal_pt)
        steps: list = []
        rejected: set = set()
        state, last_fit = _regression_loop(ctx, state, atoms, rejected, steps)
        for _ in range(2):   # nonlinear candidates, then the regression loop again around the new model
            if _at_floor(ctx, state.pt) or len(state.selected) >= MAX_EFFECTS:
                break
            tried = _nonlinear_stage(ctx, state, [e for e in library if e.key in NONLINEAR], rejected, steps)
            if tried is None:
                break
            state, last_fit = _regression_loop(ctx, tried, atoms, rejected, steps)
        state = _alias_check(ctx, state, last_fit, steps)
        state = _prune(ctx, state, steps)
        for e in library:   # effects that make the loop hunt: last, on the phase-free score
            if e.phase_free and not _at_floor(ctx, state.pt) and len(state.selected) < MAX_EFFECTS:
                state = _phase_free_stage(ctx, state, e, steps)
        final_pt = state.pt
        after = _gaps(prepared, final_pt, names, sigma, resolution)
        named = _named_effects(ctx, state, last_fit, steps)
        verdict, unexplained = _verdict(ctx, state, after, last_fit, steps)
        final_local = {n: _localise(model, final_pt, prepared[n], sigma) for n in names}
        n_sims, sim_seconds = sim.count, sim.seconds

    opt.out.mkdir(parents=True, exist_ok=True)
    outputs = _write_model(opt, state.changes, named, nominal, model_over)
    wall = time.perf_counter() - t_start
    doc = {
        "measured": str(opt.measured), "ssp": str(opt.ssp), "model": opt.model or "the SSP's bindings",
        "tests": [{"name": n, "label": prepared[n].test.label(), "role": roles[n],
                   "frequency_Hz": prepared[n].test.frequency, "motion": prepared[n].test.motion,
                   "localise_before": localised[n], "localise_after": final_local[n]} for n in names],
        "noise_floor": {"torque_std_Nm": sigma,
                        "method": "robust (MAD) third differences of the measured torques, median over tests and axes",
                        "torque_std_in_band_Nm": sigma_b, "band_Hz": band.fc,
                        "position_resolution_m": resolution or None,
                        "per_test_torque_nrmse_percent": {n: before[n]["torque_floor_percent"] for n in names}},
        "named_effects": named,
        "gap": {n: {"role": roles[n], "before": before[n], "after": after[n]} for n in names},
        "frequency_trend": _trend(prepared, localised, final_local, names),
        "verdict": verdict,
        "unexplained": unexplained,
        "steps": steps,
        "augmented_model": outputs,
        "timing": {"wall_s": round(wall, 1), "simulations": n_sims, "simulation_wall_s": round(sim_seconds, 1),
                   "workers": opt.workers, "direct": opt.direct},
    }
    (opt.out / "diagnosis.json").write_text(json.dumps(_jsonable(doc), indent=2))
    if opt.figures:
        figs = _figures(opt.out, model, prepared, names, nominal_pt, final_pt, sigma, roles, unexplained is not None,
                        state.info.get("phase_free"))
    else:
        figs = {}
    _report(opt.out, doc, figs)
    log(f"diagnose: {verdict['status']}: {verdict['text']}")
    log(f"diagnose: wrote {opt.out / 'diagnosis.json'}, {opt.out / 'report.md'} in {wall:.0f} s")
    return doc


@dataclass
class _Context:
    model: Model
    nominal: dict
    names: list
    train: list
    held: list
    band: Band
    sigma: float
    sigma_b: float
    log: Callable


def _regression_loop(ctx: _Context, state: State, atoms, rejected: set, steps: list) -> tuple[State, tuple]:
    """Select by regression at the current model, fit by re-simulation, verify; until the selection is stable."""
    last_fit = None
    for _ in range(MAX_ROUNDS):
        # effects found by re-simulation stay in, at their fitted values (their signature does not linearise)
        locked = tuple(a for a in state.selected if a.effect.key in NONLINEAR)
        keys = {a.effect.key for a in locked}
        free_atoms = [a for a in atoms if a.effect.key not in keys]
        exclude = frozenset(tuple(sorted(set(r) - keys)) for r in rejected if keys <= set(r))
        if _at_floor(ctx, state.pt):
            # at the noise floor: a cheap screen with the signatures first; sensitivities only if it proposes a change
            reg = _regression(ctx, state, free_atoms, sensitivities=False)
            best, fits = select(reg, ctx.nominal, MAX_EFFECTS - len(locked), exclude)
            if _labels(tuple(best.atoms) + locked) == _labels(state.selected):
                last_fit = (reg, best, fits)
                break
        reg = _regression(ctx, state, free_atoms)
        best, fits = select(reg, ctx.nominal, MAX_EFFECTS - len(locked), exclude)
        last_fit = (reg, best, fits)
        proposal = tuple(best.atoms) + locked
        if _labels(proposal) == _labels(state.selected):
            break
        labels = [a.label for a in reg.atoms]
        current = [a for a in state.selected if a.effect.key not in keys]
        if all(a.label in labels for a in current):
            now = reg.fit(tuple(labels.index(a.label) for a in current))
            if math.isfinite(now.bic) and reg.score(best) >= reg.score(now):
                break       # the regression sees nothing better than the current model
        ctx.log(f"diagnose: proposed by regression: {[a.label for a in proposal] or 'none'}")
        start = dict(state.changes)
        for a, c in zip(best.atoms, best.coef):
            p0 = a.effect.parameter
            lo, hi = BOUNDS[p0]
            start[p0] = float(np.clip(float(ctx.nominal[p0]) + c, lo, hi))
            if a.grid is not None:
                start[a.effect.parameters[1]] = a.grid
        cand = _fit_state(ctx, proposal, start, getattr(reg, "columns", {}))
        ok = _verify(ctx, state, cand, steps, "regression")
        if ok:
            state = cand
        else:
            rejected.add(_labels(proposal))
    return state, last_fit


def _fit_state(ctx: _Context, selected: Sequence[Atom], start: Mapping[str, float],
               columns: Optional[Mapping] = None) -> State:
    free = _free_parameters(selected)
    start = {p: start.get(p, float(ctx.nominal[p])) for p in free}
    changes, info = _polish(ctx, selected, start, columns or {})
    return State(tuple(selected), changes, ctx.model.point(changes, ctx.names), info)


def _band_rss(ctx: _Context, pt: Point, names: Sequence[str]) -> tuple[float, int]:
    rss, n = 0.0, 0
    for name in names:
        prep = ctx.model.tests[name]
        r = ctx.band.apply(prep.y - pt.obs[name], prep.test.sample_time)
        rss += float(np.sum(r ** 2))
        n += r.size
    return rss, n


def _cost(selected: Sequence[Atom]) -> int:
    return sum(a.effect.cost for a in selected)


def _verify(ctx: _Context, old: State, new: State, steps: list, how: str) -> bool:
    """Accept a new selection only if re-simulation confirms it: training BIC and held-out residual."""
    rss0, n = _band_rss(ctx, old.pt, ctx.train)
    rss1, _ = _band_rss(ctx, new.pt, ctx.train)
    k0, k1 = _cost(old.selected), _cost(new.selected)
    bic0 = n * math.log(rss0 / n) + k0 * math.log(n)
    bic1 = n * math.log(rss1 / n) + k1 * math.log(n)
    ho0, nh = _band_rss(ctx, old.pt, ctx.held) if ctx.held else (0.0, 0)
    ho1, _ = _band_rss(ctx, new.pt, ctx.held) if ctx.held else (0.0, 0)
    noise = ctx.sigma_b ** 2 * nh
    need = max(PRACTICAL * noise, RELATIVE * max(ho0 - noise, 0.0))
    # no held-out test may get markedly worse: a true effect improves every test or leaves it alone
    worse = []
    for name in ctx.held:
        a, m = _band_rss(ctx, old.pt, [name])
        b, _ = _band_rss(ctx, new.pt, [name])
        if b > a + max(PRACTICAL * ctx.sigma_b ** 2 * m, RELATIVE * a, 3.0 * math.sqrt(2.0 * m) * ctx.sigma_b ** 2):
            worse.append(name)
    if k1 > k0:
        ok = bic1 <= bic0 - DELTA_BIC and (not ctx.held or ho0 - ho1 >= need) and not worse
    else:   # fewer or as many parameters: kept effects must have been strongly needed
        ok = bic1 < bic0 + (DELTA_BIC if k1 < k0 else 0.0) and (not ctx.held or ho1 <= ho0 + need)
    step = {"how": how, "from": [a.label for a in old.selected], "to": [a.label for a in new.selected],
            "parameters": dict(new.changes), "delta_bic_training": bic1 - bic0,
            "held_out_rss_change_percent": 100 * (ho1 - ho0) / ho0 if ho0 > 0 else None,
            "held_out_rss_needed_percent": -100 * need / ho0 if ho0 > 0 else None,
            "held_out_tests_worse": worse,
            "accepted": bool(ok), "fit": new.info}
    steps.append(step)
    ctx.log(f"diagnose:   {'accepted' if ok else 'refuted by re-simulation'}: {step['to'] or 'none'} "
            f"(dBIC {bic1 - bic0:+.0f}, held-out RSS {step['held_out_rss_change_percent'] or 0:+.1f} %"
            + (f"; worse on {', '.join(worse)}" if worse else "") + ")")
    return ok


def _at_floor(ctx: _Context, pt: Point) -> bool:
    return all(float(np.sqrt(np.mean((ctx.model.tests[n].y - pt.obs[n]) ** 2))) <= FLOOR_FACTOR * ctx.sigma
               for n in ctx.names)


def _nonlinear_stage(ctx: _Context, state: State, effects: Sequence[Effect], rejected: set, steps: list
                     ) -> Optional[State]:
    """Effects whose signature does not linearise (Stribeck friction): fitted and scored by re-simulation."""
    best: Optional[State] = None
    best_bic = math.inf
    where = _reversal_concentration(ctx, state.pt)
    if where < REVERSAL_GATE:
        steps.append({"how": "re-simulation candidates", "from": [a.label for a in state.selected],
                      "to": [e.key for e in effects], "accepted": False,
                      "note": f"not tried: the residual does not concentrate at velocity reversals "
                              f"({where:.2f} x its share of time < {REVERSAL_GATE:g}), where "
                              + ", ".join(e.title for e in effects) + " act"})
        ctx.log(f"diagnose: {', '.join(e.title for e in effects)} not tried: the residual does not concentrate at "
                f"velocity reversals ({where:.2f} x its share of time)")
        return None
    for e in effects:
        if any(a.effect.key == e.key for a in state.selected):
            continue
        labels = _labels(tuple(state.selected) + (Atom(e),))
        if labels in rejected or ("refuted", e.key) in rejected:
            continue
        start = dict(state.changes)
        start.update(_nonlinear_start(ctx, state, e))
        atom = Atom(e, start.get("omega_s") if e.key == "stribeck" else None)
        ctx.log(f"diagnose: trying {e.title} by re-simulation (start {', '.join(f'{p} = {start[p]:.3g}' for p in e.parameters)})")
        cand = _fit_state(ctx, tuple(state.selected) + (atom,), start)
        if _verify(ctx, state, cand, steps, "re-simulation"):
            rss, n = _band_rss(ctx, cand.pt, ctx.train)
            bic = n * math.log(rss / n) + _cost(cand.selected) * math.log(n)
            if bic < best_bic:
                best, best_bic = cand, bic
            if _at_floor(ctx, cand.pt):
                break       # explained: no need to try the others
        else:
            rejected.add(labels)
            rejected.add(("refuted", e.key))
    return best


#: start grids of the nonlinear effects (the Stribeck cost has a narrow curved valley in omega_s)
START_GRIDS = {
    "stribeck": [{"tau_s": ts, "omega_s": ws} for ts in (0.012, 0.03)
                 for ws in (1.0, 1.3, 1.7, 2.2, 2.9, 3.7, 4.8, 6.3, 8.2)],
}


#: the re-simulation candidates are tried when the residual concentrates at velocity reversals this much
REVERSAL_GATE = 2.0


def _reversal_concentration(ctx: _Context, pt: Point) -> float:
    """Largest concentration of the residual near velocity reversals (energy share / time share) over
    the tests whose residual is above the noise floor (0 if none is)."""
    best = 0.0
    for n in ctx.names:
        r = ctx.model.tests[n].y - pt.obs[n]
        if float(np.sqrt(np.mean(r ** 2))) <= FLOOR_FACTOR * ctx.sigma:
            continue
        omega = ctx.model.signals(pt, n)[0]
        mask = np.abs(omega) < 0.15 * np.abs(omega).max(axis=0)
        if mask.any():
            best = max(best, float((r[mask] ** 2).sum() / (r ** 2).sum()) / float(mask.mean()))
    return best


def _nonlinear_start(ctx: _Context, state: State, e: Effect) -> dict:
    """A start for the fit: the best point of a grid, each simulated on the lowest-frequency training test
    (the one friction dominates), all in one parallel batch."""
    grid = START_GRIDS[e.key]
    probe = [min(ctx.train, key=lambda n: (ctx.model.tests[n].test.frequency or 0.0, n))]
    ctx.model.sim.prefetch([{**state.changes, **g} for g in grid], probe)
    best, best_rss = grid[0], math.inf
    for g in grid:
        try:
            pt = ctx.model.point({**state.changes, **g}, probe)
        except DiagnosisError:
            continue
        rss, _ = _band_rss(ctx, pt, probe)
        if rss < best_rss:
            best, best_rss = g, rss
    return best


def _phase_free_stage(ctx: _Context, state: State, effect: Effect, steps: list) -> State:
    """An effect that makes the loop hunt (backlash), on the phase-free score (phasefree.py).

    Every value is an ensemble of re-simulations of every test. Selection: the best value of the
    effect's scan on the training tests must lower the training BIC (deviance plus ln(statistics)
    per parameter) by DELTA_BIC and the held-out deviance by DELTA_BIC, no held-out test worse by
    DELTA_BIC. The value: refined on all tests (log-scale bisection around the best scan value,
    then a parabola), once the held-out tests have confirmed the effect. It is named only if with
    it every test's score is at the floor: the hunting's band powers can stand in for part of
    almost any excess (a position ripple, say), so the effect must explain all of what is left.
    """
    model, p = ctx.model, effect.parameter
    try:
        score = PhaseFreeScore({n: model.tests[n].y for n in ctx.names}, state.pt.obs,
                               {n: model.tests[n].test.sample_time for n in ctx.names}, ctx.sigma)
    except ValueError as err:   # sampled too slowly for the bands
        steps.append({"how": "phase-free score", "from": [a.label for a in state.selected],
                      "to": [a.label for a in state.selected] + [effect.key], "accepted": False,
                      "note": f"not tried: {err}"})
        ctx.log(f"diagnose: {effect.title} not tried: {err}")
        return state
    ensembles: dict[float, Optional[dict]] = {}
    current = float(state.changes.get(p, ctx.nominal[p]))

    def changes(v: float) -> dict:   # the current model as it is (its simulations are cached)
        return dict(state.changes) if v == current else {**state.changes, p: v}

    def simulate(values: Sequence[float]) -> None:
        new = [v for v in values if v not in ensembles]
        model.sim.prefetch([changes(v) for v in new], ctx.names, range(ENSEMBLE))
        for v in new:
            try:
                ensembles[v] = {n: np.array([score.powers(n, model.point(changes(v), [n], r).obs[n])
                                             for r in range(ENSEMBLE)]) for n in ctx.names}
            except DiagnosisError:
                ensembles[v] = None

    def deviance(v: float, names: Sequence[str]) -> float:
        return score.fit(ensembles[v], names).deviance if ensembles[v] is not None else math.inf

    ctx.log(f"diagnose: trying {effect.title} on the phase-free score ({len(effect.scan)} values x {ENSEMBLE} "
            f"realisations of every test)")
    simulate([current, *effect.scan])
    scan_tr = {v: deviance(v, ctx.train) for v in effect.scan}
    v_tr = min(scan_tr, key=scan_tr.get)
    if ensembles[current] is None or not math.isfinite(scan_tr[v_tr]):
        raise DiagnosisError(f"the phase-free score of {effect.title}: every simulation of its scan failed")
    before_tr, with_tr = score.fit(ensembles[current], ctx.train), score.fit(ensembles[v_tr], ctx.train)
    dbic = with_tr.deviance - before_tr.deviance + effect.cost * math.log(score.statistics(ctx.train))
    ok = dbic <= -DELTA_BIC
    dho, worse = None, []
    if ctx.held:
        before_ho, with_ho = score.fit(ensembles[current], ctx.held), score.fit(ensembles[v_tr], ctx.held)
        dho = with_ho.deviance - before_ho.deviance
        worse = [n for n in ctx.held if with_ho.per_test[n] - before_ho.per_test[n] > DELTA_BIC]
        ok = ok and dho <= -DELTA_BIC and not worse
    labels = [a.label for a in state.selected]
    steps.append({"how": "phase-free score", "from": labels, "to": labels + [effect.key], "parameters": {p: v_tr},
                  "delta_bic_training": dbic, "held_out_deviance_change": dho, "held_out_tests_worse": worse,
                  "accepted": bool(ok),
                  "note": "the best value of the scan on the training tests, band powers of the residual against "
                          "ensembles of re-simulations" + ("" if ok else
                          f": refused (training dBIC and held-out deviance change must be <= -{DELTA_BIC:g}, "
                          f"no held-out test worse by {DELTA_BIC:g})")})
    ctx.log(f"diagnose:   {effect.key} = {v_tr:.3g} (training scan): phase-free dBIC {dbic:+.0f}, held-out deviance "
            f"{dho if dho is not None else 0:+.0f}" + (f"; worse on {', '.join(worse)}" if worse else "")
            + (": confirmed" if ok else ": refused"))
    if not ok:
        return state

    ratio = effect.scan[1] / effect.scan[0]

    def on_all(values: Sequence[float]) -> dict[float, float]:
        simulate(values)
        return {v: deviance(v, ctx.names) for v in values}

    points = refine(on_all, on_all(effect.scan), ratio, REFINE_LEVELS, effect.bounds[p])
    value, s_log = estimate(points, ratio ** (0.5 ** PARABOLA_LEVEL))
    simulate([value])
    if ensembles[value] is None:    # the estimate's simulation failed: the best value simulated instead
        value = min(points, key=points.get)
    final, before = score.fit(ensembles[value], ctx.names), score.fit(ensembles[current], ctx.names)
    floors = {n: score.floor(n) for n in ctx.names}
    above = [n for n, d in final.per_test.items() if d > floors[n]]
    steps.append({"how": "phase-free score: value on all tests", "from": labels, "to": labels + [effect.key],
                  "parameters": {p: value}, "delta_bic_training": dbic, "deviance_per_test": final.per_test,
                  "floor_per_test": floors, "accepted": not above,
                  "note": ("every test's band powers at the floor with it" if not above else
                           f"not named: with it the band powers of {', '.join(above)} stay above the floor "
                           "(it would explain only part of the residual)")})
    ctx.log(f"diagnose:   {effect.key} = {value:.4g} on all tests (deviance per test "
            + ", ".join(f"{n} {d:.1f}" for n, d in final.per_test.items()) + ")"
            + (f": above the floor on {', '.join(above)}, not named" if above else ": named"))
    if above:
        return state
    nf = {n: score.bands[n].noise_fraction for n in ctx.names}
    info = {**state.info, "phase_free": {
        "parameter": p, "value": value, "std": value * s_log,
        "ci95": [value * math.exp(-1.96 * s_log), value * math.exp(1.96 * s_log)],
        "training_scan_value": v_tr, "delta_bic_training": dbic, "held_out_deviance_change": dho,
        "deviance_per_test": {"before": before.per_test, "after": final.per_test}, "floor_per_test": floors,
        "noise_std_Nm": final.sigma, "bands_Hz": {n: score.bands[n].bands for n in ctx.names},
        "ensemble": ENSEMBLE,
        "band_powers_Nm_squared": {n: {"measured": score.measured[n].tolist(),
                                 "with": (ensembles[value][n].mean(axis=0) + final.sigma ** 2 * nf[n]).tolist(),
                                 "without": (ensembles[current][n].mean(axis=0) + before.sigma ** 2 * nf[n]).tolist()}
                             for n in ctx.names},
        "profile": {v: points[v] for v in sorted(points)}}}
    return State(tuple(state.selected) + (Atom(effect),), changes(value), model.point(changes(value), ctx.names), info)


def _alias_check(ctx: _Context, state: State, last_fit, steps: list) -> State:
    """Effects the regression cannot separate (inertia on either side): compare them by re-simulation."""
    for a in state.selected:
        if not a.effect.group:
            continue
        for other in LIBRARY:
            if other.group != a.effect.group or other.key == a.effect.key:
                continue
            start = {k: v for k, v in state.changes.items() if k not in a.effect.parameters}
            # the equivalent value of the other side: the same change of reflected inertia
            start[other.parameter] = _equivalent(ctx.nominal, a.effect.parameter, state.changes[a.effect.parameter],
                                                 other.parameter)
            lo, hi = BOUNDS[other.parameter]
            if not lo <= start[other.parameter] <= hi:
                steps.append({"how": "alias check", "from": [x.label for x in state.selected],
                              "to": f"{other.key} instead of {a.effect.key}", "accepted": False,
                              "note": f"the equivalent {other.parameter} = {start[other.parameter]:.3g} is outside its bounds"})
                continue
            swapped = tuple(x for x in state.selected if x is not a) + (Atom(other),)
            cand = _fit_state(ctx, swapped, start)
            rss0, n = _band_rss(ctx, state.pt, ctx.train)
            rss1, _ = _band_rss(ctx, cand.pt, ctx.train)
            full0 = sum(float(np.sum((ctx.model.tests[m].y - state.pt.obs[m]) ** 2)) for m in ctx.train)
            full1 = sum(float(np.sum((ctx.model.tests[m].y - cand.pt.obs[m]) ** 2)) for m in ctx.train)
            nf = sum(ctx.model.tests[m].y.size for m in ctx.train)
            dbic_full = nf * math.log(full1 / full0)
            better = dbic_full <= -DELTA_BIC
            steps.append({"how": "alias check", "from": [x.label for x in state.selected],
                          "to": [x.label for x in swapped], "parameters": dict(cand.changes),
                          "delta_bic_band": n * math.log(rss1 / rss0), "delta_bic_full_band": dbic_full,
                          "accepted": bool(better),
                          "note": "full band (the transmission's ringing) decides; in the band the two are alike"})
            ctx.log(f"diagnose:   alias check {a.effect.key} -> {other.key}: dBIC (full band) {dbic_full:+.0f}"
                    + (": swapped" if better else ": kept"))
            state.info.setdefault("alias", []).append({"effect": other.key, "parameters": dict(cand.changes),
                                                        "delta_bic_full_band": dbic_full,
                                                        "delta_bic_band": n * math.log(rss1 / rss0)})
            if better:
                cand.info.setdefault("alias", []).append({"effect": a.effect.key, "parameters": dict(state.changes),
                                                           "delta_bic_full_band": -dbic_full,
                                                           "delta_bic_band": -n * math.log(rss1 / rss0)})
                return cand
    return state


#: effects whose removal costs less than this (linearised BIC) are re-checked by re-simulation
PRUNE_DBIC = 200.0


def _prune(ctx: _Context, state: State, steps: list) -> State:
    """Backward check: an effect that the others (refitted) can stand in for is removed if re-simulation
    does not show it strongly needed (e.g. a mass change and an offset cancelling each other's weight)."""
    while len(state.selected) > 1:
        linear = [a for a in state.selected if a.effect.key not in NONLINEAR]
        if len(linear) < 2:
            return state
        reg = _regression(ctx, state, linear, sensitivities=False)
        full = tuple(range(len(linear)))
        costs = []
        for k, a in enumerate(linear):
            rest = reg.fit(tuple(i for i in full if i != k))
            costs.append((rest.bic - reg.fit(full).bic, a))
        costs.sort(key=lambda c: c[0])
        removed = False
        for dbic, a in costs:
            if dbic > PRUNE_DBIC:
                break
            rest = tuple(x for x in state.selected if x is not a)
            cand = _fit_state(ctx, rest, dict(state.changes))
            if _verify(ctx, state, cand, steps, f"backward check (removing {a.effect.key})"):
                state, removed = cand, True
                break
        if not removed:
            return state
    return state


def _equivalent(nominal: Mapping, param: str, value: float, other: str) -> float:
    """The value of ``other`` giving the same total reflected inertia as ``param`` = value."""
    from fmus.actuator.model import two_inertia

    J1, J2 = two_inertia(nominal)
    J = two_inertia({**nominal, param: value})
    delta = (J[0] + J[1]) - (J1 + J2)
    if other == "J_guide":
        return float(nominal["J_guide"]) + delta * float(nominal["i_r"]) ** 2
    if other == "J1_scale":
        return float(nominal["J1_scale"]) + delta / (J1 / float(nominal["J1_scale"]))
    raise KeyError(other)


def _jsonable(x):
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, (np.floating, np.integer)):
        return x.item()
    if isinstance(x, float) and not math.isfinite(x):
        return None
    if isinstance(x, Path):
        return str(x)
    return x


def _gaps(prepared: Mapping[str, Prepared], pt: Point, names: Sequence[str], sigma: float, resolution: float) -> dict:
    out = {}
    for n in names:
        p = prepared[n]
        y, yh = p.y, pt.obs[n]
        den = float(np.linalg.norm(y - y.mean(axis=0)))
        g = nrmse(y, yh)
        e_den = float(np.linalg.norm(p.e - p.e.mean(axis=0)))
        ge = nrmse(p.e, pt.err[n])
        out[n] = {
            "torque_nrmse_percent": 100 * g, "torque_fit_percent": 100 * (1 - g),
            "torque_rms_Nm": float(np.sqrt(np.mean((y - yh) ** 2))),
            "torque_floor_percent": 100 * sigma * math.sqrt(y.size) / den if den > 0 else None,
            "tracking_error_nrmse_percent": 100 * ge, "tracking_error_fit_percent": 100 * (1 - ge),
            "tracking_error_floor_percent": (100 * resolution / math.sqrt(12) * math.sqrt(p.e.size) / e_den
                                             if resolution and e_den > 0 else None),
        }
    return out


def _localise(model: Model, pt: Point, prep: Prepared, sigma: float) -> dict:
    omega, acc, _ = model.signals(pt, prep.name)
    return localise(prep.t, prep.y - pt.obs[prep.name], omega, acc, prep.test.frequency, sigma)


def _trend(prepared, before, after, names) -> dict:
    """Residual amplitude at the test frequency against frequency, per motion."""
    out = {}
    for motion in sorted({prepared[n].test.motion for n in names if prepared[n].test.frequency}):
        ns = sorted([n for n in names if prepared[n].test.motion == motion and prepared[n].test.frequency],
                    key=lambda n: prepared[n].test.frequency)
        f = [prepared[n].test.frequency for n in ns]
        b = [before[n].get("harmonic_1") for n in ns]
        a = [after[n].get("harmonic_1") for n in ns]
        slope = frequency_slope(f, b)
        words = None
        if slope is not None:
            words = ("flat in frequency" if abs(slope) < 0.5 else "grows with f" if slope < 1.5 else "grows with f^2"
                     if slope < 2.5 else "grows faster than f^2") if slope > -0.5 else "falls with frequency"
        out[motion] = {"frequencies_Hz": f, "residual_h1_before_Nm": b, "residual_h1_after_Nm": a,
                       "log_slope_before": slope, "reading": words}
    return out


def _steps(ctx: _Context, state: State, atoms: Sequence[Atom]) -> dict[str, tuple[float, float]]:
    """(value, step) of the re-simulated sensitivity of each plant atom's parameter."""
    out = {}
    for a in atoms:
        if a.effect.kind == "plant":
            p0 = a.effect.parameter
            v0 = float(state.changes.get(p0, ctx.nominal[p0]))
            step = a.effect.step if BOUNDS[p0][0] <= v0 + a.effect.step <= BOUNDS[p0][1] else -a.effect.step
            out[a.label] = (v0, step)
    return out


def _regression(ctx: _Context, state: State, atoms: Sequence[Atom], sensitivities: bool = True) -> Regression:
    """Columns at the current model; the residual taken back to the nominal model (linearised); in the band.

    ``sensitivities``: plant columns re-simulated (exact linearisation of the closed loop, one
    simulation of every test per plant parameter, all in one parallel batch); otherwise the
    effect signatures (no simulation: a screen).
    """
    model, pt, names = ctx.model, state.pt, ctx.names
    cols = {}
    steps = _steps(ctx, state, atoms) if sensitivities else {}
    if steps:
        model.sim.prefetch([{**state.changes, a.effect.parameter: v0 + st} for a in atoms if a.label in steps
                            for v0, st in [steps[a.label]]], names)
    for a in atoms:
        if a.label in steps:   # re-simulated sensitivity: the closed loop's own response
            p0 = a.effect.parameter
            v0, step = steps[a.label]
            try:
                pt1 = model.point({**state.changes, p0: v0 + step}, names)
                cols[a.label] = {n: (pt1.obs[n] - pt.obs[n]) / step for n in names}
            except DiagnosisError:
                cols[a.label] = model.columns(pt, names, p0, a.grid)
        else:
            cols[a.label] = model.columns(pt, names, a.effect.parameter, a.grid if a not in state.selected else None)
    resid = {n: model.tests[n].y - pt.obs[n] for n in names}
    for a in state.selected:
        if a.effect.key in NONLINEAR:
            continue
        for pname in a.effect.parameters:
            if pname in state.changes:
                delta = state.changes[pname] - float(ctx.nominal[pname])
                if delta:
                    c = cols[a.label] if (pname == a.effect.parameter and a.label in cols) else \
                        model.columns(pt, names, pname)
                    for n in names:
                        resid[n] = resid[n] + c[n] * delta

    def banded(d: Mapping[str, np.ndarray], ns: Sequence[str]) -> np.ndarray:
        return np.concatenate([ctx.band.apply(d[n], model.tests[n].test.sample_time).ravel() for n in ns]) \
            if ns else np.zeros(0)

    A_tr = np.column_stack([banded(cols[a.label], ctx.train) for a in atoms]) if atoms else np.zeros((0, 0))
    A_ho = np.column_stack([banded(cols[a.label], ctx.held) for a in atoms]) if ctx.held and atoms else \
        np.zeros((0, len(atoms)))
    if not atoms:
        A_tr = np.zeros((len(banded(resid, ctx.train)), 0))
    reg = Regression(atoms, A_tr, banded(resid, ctx.train), A_ho, banded(resid, ctx.held), ctx.sigma_b)
    reg.columns = {a.effect.parameter: cols[a.label] for a in atoms if a.label in steps}
    return reg


def _free_parameters(selected: Sequence[Atom]) -> list[str]:
    out = []
    for a in selected:
        out += [p for p in a.effect.parameters if p not in out]
    return out


def _polish(ctx: _Context, selected: Sequence[Atom], start: Mapping[str, float],
            columns: Mapping[str, Mapping[str, np.ndarray]]) -> tuple[dict, dict]:
    """Bounded least squares of the selected parameters on the training tests, re-simulating.

    Jacobian: the measurement parameters' columns are exact (no simulation); plant
    parameters start from re-simulated sensitivities (those of the regression, or one
    simulation each at the start) and are updated by Broyden's rank-one formula along the
    iterates, so each iteration costs one simulation of the training tests.
    """
    from scipy.optimize import least_squares

    model, train, sigma = ctx.model, ctx.train, ctx.sigma
    free = _free_parameters(selected)
    x0 = np.array([start[p] for p in free], dtype=float)
    lo = np.array([BOUNDS[p][0] for p in free])
    hi = np.array([BOUNDS[p][1] for p in free])
    x0 = np.clip(x0, lo + 1e-9 * (hi - lo), hi - 1e-9 * (hi - lo))
    scale = np.array([max(abs(v), 0.01 * (h - l), 1e-9) for v, l, h in zip(x0, lo, hi)])
    y = np.concatenate([model.tests[n].y.ravel() for n in train])
    count = [0]
    points: dict = {}
    plant = [k for k, p in enumerate(free) if p not in MEASUREMENT_PARAMETERS]
    sensor = [k for k, p in enumerate(free) if p in MEASUREMENT_PARAMETERS]

    def at(x: np.ndarray) -> Point:
        key = tuple(np.round(x, 15))
        if key not in points:
            if len(points) > 8:
                points.clear()
            points[key] = model.point(dict(zip(free, map(float, x))), train)
            count[0] += 1
        return points[key]

    def obs(pt: Point) -> np.ndarray:
        return np.concatenate([pt.obs[n].ravel() for n in train])

    def fun(x: np.ndarray) -> np.ndarray:
        try:
            pt = at(x)
        except DiagnosisError:
            return np.full(y.shape, 1e3)
        return (y - obs(pt)) / sigma

    memory: dict = {}

    def initial(x: np.ndarray, pt: Point) -> np.ndarray:
        J = np.zeros((len(y), len(free)))
        need = []
        for k in plant:
            p = free[k]
            if p in columns and p not in FD_STEP:
                J[:, k] = -np.concatenate([columns[p][n].ravel() for n in train]) / sigma
            else:
                need.append(k)
        fd = {}
        for k in need:
            p = free[k]
            # a small step: the fit needs the local slope (the regression's secant columns are for naming)
            d = FD_STEP.get(p) or max(0.01 * abs(x[k]), 0.1 * abs(BY_PARAMETER[p].step)) or 1e-3 * scale[k]
            d = d if x[k] + d <= hi[k] else -d
            x1 = x.copy()
            x1[k] += d
            fd[k] = (x1, d)
        model.sim.prefetch([dict(zip(free, map(float, x1))) for x1, _ in fd.values()], train)
        for k, (x1, d) in fd.items():
            try:
                J[:, k] = -(obs(at(x1)) - obs(pt)) / d / sigma
            except DiagnosisError:
                J[:, k] = 0.0
        return J

    def jac(x: np.ndarray) -> np.ndarray:
        try:
            pt = at(x)
        except DiagnosisError:
            return np.zeros((len(y), len(free)))
        r = (y - obs(pt)) / sigma
        if "J" not in memory:
            J = initial(x, pt)
        else:
            J = memory["J"].copy()
            dx = x - memory["x"]
            if plant and float(dx[plant] @ dx[plant]) > 0:
                dr = r - memory["r"]
                J[:, plant] += np.outer(dr - J @ dx, dx[plant]) / float(dx[plant] @ dx[plant])
        for k in sensor:
            c = model.columns(pt, train, free[k])
            J[:, k] = -np.concatenate([c[n].ravel() for n in train]) / sigma
        memory.update(J=J, x=x.copy(), r=r)
        return J

    t0 = time.perf_counter()
    sol = least_squares(fun, x0, jac=jac, bounds=(lo, hi), x_scale=scale, method="trf", xtol=1e-4, ftol=1e-5,
                        max_nfev=12)
    values = dict(zip(free, map(float, sol.x)))
    info = {"simulations_of_the_training_tests": count[0], "cost": float(sol.cost),
            "wall_s": round(time.perf_counter() - t0, 1), "status": sol.message,
            "jacobian": "exact columns (measurement), re-simulated sensitivities with Broyden updates (plant)"}
    if "T_meas" in values:   # a filter or a delay? (measurement only: no re-simulation)
        info["lag"] = _filter_or_delay(model, at(sol.x), values, train)
        if info["lag"]["choice"] == "delay_meas":
            values.pop("T_meas")
            values["delay_meas"] = info["lag"]["delay_meas"]
    ctx.log("diagnose:   fit " + ", ".join(f"{k} = {v:.5g}" for k, v in values.items())
            + f" ({count[0]} simulations of the training tests, {info['wall_s']:.0f} s)")
    return values, info


def _filter_or_delay(model: Model, pt: Point, values: Mapping, train: Sequence[str]) -> dict:
    from scipy.optimize import minimize_scalar

    y = np.concatenate([model.tests[n].y.ravel() for n in train])

    def rss(chain: Chain) -> float:
        yh = np.concatenate([_sample(pt.sims[n], chain.observe(pt.sims[n].tau_m), model.tests[n].t).ravel()
                             for n in train])
        return float(np.sum((y - yh) ** 2))

    rss_filter = rss(pt.chain)
    base = pt.chain.with_(T_meas=0.0)
    res = minimize_scalar(lambda d: rss(base.with_(delay_meas=d)), bounds=(0.0, 4 * values["T_meas"] + 1e-4),
                          method="bounded", options={"xatol": 1e-6})
    n = len(y)
    dbic = n * math.log(res.fun / rss_filter)
    choice = "delay_meas" if dbic < -DELTA_BIC else "T_meas"
    return {"T_meas": values["T_meas"], "rss_filter": rss_filter, "delay_meas": float(res.x), "rss_delay": float(res.fun),
            "delta_bic_delay_vs_filter": dbic, "choice": choice, "separable": abs(dbic) >= DELTA_BIC}


def _named_effects(ctx: _Context, state: State, last_fit, steps: list) -> list:
    if not state.selected:
        return []
    model, names, nominal, pt = ctx.model, ctx.train, ctx.nominal, state.pt
    # the phase-free effects' uncertainty comes from their score (phasefree.estimate)
    free = [p for p in state.changes if not (p in BY_PARAMETER and BY_PARAMETER[p].phase_free)]
    y = np.concatenate([model.tests[n].y.ravel() for n in names])
    r = y - np.concatenate([pt.obs[n].ravel() for n in names])
    cols = []
    for p in free:
        if p in FD_STEP:
            d = FD_STEP[p] if state.changes[p] + FD_STEP[p] <= BOUNDS[p][1] else -FD_STEP[p]
            pt1 = model.point({**state.changes, p: state.changes[p] + d}, names)
            cols.append((np.concatenate([pt1.obs[n].ravel() for n in names]) - (y - r)) / d)
        else:
            c = model.columns(pt, names, p)
            cols.append(np.concatenate([c[n].ravel() for n in names]))
    s2 = float(r @ r) / max(len(r) - len(free), 1)
    rho1 = _lag1(model, pt, names)
    inflate = max((1 + rho1) / (1 - rho1), 1.0) if -0.99 < rho1 < 0.99 else 1.0
    try:
        J = np.column_stack(cols) if cols else np.zeros((len(r), 0))
        std = np.sqrt(np.clip(np.diag(s2 * np.linalg.inv(J.T @ J) * inflate), 0, None))
    except np.linalg.LinAlgError:
        std = np.full(len(free), np.nan)
    stds = dict(zip(free, map(float, std)))
    ci95 = {p: [v - 1.96 * stds[p], v + 1.96 * stds[p]] for p, v in state.changes.items() if p in stds}
    if "phase_free" in state.info:
        pf = state.info["phase_free"]
        stds[pf["parameter"]], ci95[pf["parameter"]] = pf["std"], pf["ci95"]
    reg, best, fits = last_fit
    out = []
    for a in state.selected:
        e = a.effect
        params = {p: state.changes[p] for p in e.parameters if p in state.changes}
        if e.key == "lag" and "delay_meas" in state.changes:
            params = {"delay_meas": state.changes["delay_meas"]}
        added = next((st for st in steps if st.get("accepted") and "delta_bic_training" in st
                      and a.label in st["to"] and a.label not in st["from"]), None)
        ev: dict = {"signature": e.signature}
        if added and e.phase_free:
            ev["when_added"] = {"how": added["how"], "delta_bic_training": added["delta_bic_training"],
                                "held_out_rss_change_percent": None,
                                "held_out_deviance_change": added["held_out_deviance_change"],
                                "note": "phase-free score: band powers of the residual against ensembles of "
                                        "re-simulations, the model before and after adding it"}
            ev["phase_free"] = state.info["phase_free"]
        elif added:
            ev["when_added"] = {"how": added["how"], "delta_bic_training": added["delta_bic_training"],
                                "held_out_rss_change_percent": added["held_out_rss_change_percent"],
                                "note": "re-simulated: the model before and after adding it (band below "
                                        f"{ctx.band.fc:g} Hz)"}
        ev.update(_evidence(reg, best, a))
        if e.key == "lag" and "lag" in state.info:
            ev["filter_or_delay"] = state.info["lag"]
        if e.group:
            ev["alternatives"] = _alternatives(reg, best, a, nominal) + [
                {"effect": BY_KEY[x["effect"]].title, "parameters": x["parameters"],
                 "delta_bic_full_band": x["delta_bic_full_band"], "delta_bic_band": x["delta_bic_band"],
                 "how": "re-simulated alternative (fitted)",
                 "separable": bool(abs(x["delta_bic_full_band"]) >= DELTA_BIC),
                 "note": ("the data prefer the named side" if x["delta_bic_full_band"] >= DELTA_BIC else
                          "the data cannot tell the two apart: the preferred side is named")}
                for x in state.info.get("alias", [])]
        out.append({
            "effect": e.title, "key": e.key, "kind": e.kind,
            "parameters": params,
            "nominal": {p: float(nominal[p]) for p in params},
            "uncertainty": {p: {"std": stds.get(p), "ci95": ci95.get(p)} for p in params},
            "evidence": ev,
        })
    return out


def _lag1(model, pt, names) -> float:
    vals = []
    for n in names:
        r = model.tests[n].y - pt.obs[n]
        for j in range(r.shape[1]):
            x = r[:, j] - r[:, j].mean()
            d = float(x @ x)
            if d > 0:
                vals.append(float(x[1:] @ x[:-1]) / d)
    return float(np.mean(vals)) if vals else 0.0


def _evidence(reg: Regression, best: SubsetFit, a: Atom) -> dict:
    labels = [x.label for x in reg.atoms]
    if a.label not in labels or a not in best.atoms:
        return {}
    idx = [labels.index(x.label) for x in best.atoms]
    k = labels.index(a.label)
    rest = reg.fit(tuple(i for i in idx if i != k))
    full = reg.fit(tuple(idx))
    return {"at_the_fitted_model": {
        "delta_bic_training": rest.bic - full.bic,
        "held_out_residual_reduction_percent": (100 * (rest.rss_ho - full.rss_ho) / rest.rss_ho
                                                if rest.rss_ho > 0 else None),
        "training_residual_reduction_percent": 100 * (rest.rss_tr - full.rss_tr) / rest.rss_tr,
        "note": "linearised at the fitted model: the same selection without this effect"}}


def _alternatives(reg: Regression, best: SubsetFit, a: Atom, nominal) -> list:
    out = []
    labels = [x.label for x in reg.atoms]
    if a not in best.atoms:
        return out
    for other in LIBRARY:
        if other.group != a.effect.group or other.key == a.effect.key or other.key not in labels:
            continue
        i = labels.index(other.key)
        idx = tuple(sorted([labels.index(x.label) for x in best.atoms if x is not a] + [i]))
        f = reg.fit(idx)
        dbic = f.bic - best.bic
        k = [x.label for x in f.atoms].index(other.key) if math.isfinite(dbic) else None
        value = float(nominal[other.parameter]) + float(f.coef[k]) if k is not None else None
        out.append({"effect": other.title, "parameter": other.parameter, "equivalent_value": value,
                    "delta_bic_band": dbic, "how": "regression in the band (linearised)",
                    "separable": bool(math.isfinite(dbic) and dbic >= DELTA_BIC)})
    return out


def _verdict(ctx: _Context, state: State, after: dict, last_fit, steps: list) -> tuple[dict, Optional[dict]]:
    model, pt, names, sigma = ctx.model, state.pt, ctx.names, ctx.sigma
    prepared = model.tests

    def ratio(ns):
        if not ns:
            return None
        r = np.concatenate([(prepared[n].y - pt.obs[n]).ravel() for n in ns])
        return float(np.sqrt(np.mean(r ** 2)) / sigma)

    rt, rh = ratio(ctx.train), ratio(ctx.held)
    per_test = {n: float(np.sqrt(np.mean((prepared[n].y - pt.obs[n]) ** 2)) / sigma) for n in names}
    white = _whiteness(prepared, pt, names)
    worst = max(per_test.values())
    # where a named effect makes the loop hunt, the band powers decide (phasefree.py): not sample by sample
    pf = state.info.get("phase_free")
    by_bands = [n for n in names if per_test[n] > FLOOR_FACTOR and pf
                and pf["deviance_per_test"]["after"][n] <= pf["floor_per_test"][n]]
    at_floor = all(per_test[n] <= FLOOR_FACTOR or n in by_bands for n in names)
    titles = ", ".join(a.effect.title for a in state.selected)
    rh_text = f"{rh:.2f}" if rh is not None else "-"
    if at_floor and not state.selected:
        status, text = "nothing missing", (f"the nominal model's residual is at the noise floor (RMS {rt:.2f} x the "
                                           f"noise on training, {rh_text} x on held-out tests) and no candidate "
                                           "effect improves it: nothing is missing")
    elif at_floor and by_bands:
        status, text = "explained", (f"with {titles} the residual is at the noise floor: sample by sample on "
                                     f"{', '.join(n for n in names if n not in by_bands) or 'no test'}; on "
                                     f"{', '.join(by_bands)}, where the loop hunts (RMS "
                                     + ", ".join(f"{per_test[n]:.1f}" for n in by_bands)
                                     + " x noise, not predictable sample by sample), in its band powers (phase-free "
                                     "deviance " + ", ".join(f"{pf['deviance_per_test']['after'][n]:.1f}" for n in by_bands)
                                     + f" <= {max(pf['floor_per_test'][n] for n in by_bands):.1f})")
    elif at_floor:
        status, text = "explained", (f"with {titles} the residual is at the noise floor (RMS {rt:.2f} x noise on "
                                     f"training, {rh_text} x on held-out)")
    else:
        status = "unexplained residual"
        text = (f"a residual remains that no candidate effect explains: RMS {rt:.2f} x the noise floor on training, "
                f"{rh_text} x on held-out tests (worst test {worst:.2f} x); "
                + (f"named: {titles}" if state.selected else "nothing named"))
    verdict = {"status": status, "text": text, "residual_over_noise_training": rt, "residual_over_noise_held_out": rh,
               "residual_over_noise_per_test": per_test, "floor_factor": FLOOR_FACTOR, "whiteness": white,
               "judged_by_band_powers": by_bands}
    unexplained = None
    if not at_floor:
        loc = {n: _localise(model, pt, prepared[n], sigma) for n in names}
        reg, best, fits = last_fit
        tried = []
        labels = [x.label for x in reg.atoms]
        for a in reg.atoms:
            if a in best.atoms:
                continue
            idx = tuple(sorted([labels.index(x.label) for x in best.atoms] + [labels.index(a.label)]))
            f = reg.fit(idx)
            tried.append({"candidate": a.label, "delta_bic": f.bic - best.bic,
                          "held_out_rss_change_percent": (100 * (f.rss_ho - best.rss_ho) / best.rss_ho
                                                          if best.rss_ho > 0 else None),
                          "rejected_because": "; ".join(f.reasons) or "not better than the selection"})
        for st in steps:    # the phase-free candidates: not tried, not confirmed, or not explaining all
            if st["how"].startswith("phase-free score") and not st["accepted"]:
                tried.append({"candidate": f"{st['to'][-1]} (phase-free score)",
                              "delta_bic": st.get("delta_bic_training"), "held_out_rss_change_percent": None,
                              "rejected_because": st["note"]})
        unexplained = {
            "text": "The residual is above the noise floor and no candidate of the library reduces it on the "
                    "held-out tests (by regression, for the nonlinear candidates by re-simulation, for backlash by "
                    "the phase-free score) or explains all of it; it is shown, not named.",
            "where": {n: loc[n]["summary"] for n in names},
            "candidates_tried": tried,
            "figure": "fig_unexplained.png",
        }
    return verdict, unexplained


def _whiteness(prepared, pt, names, lags: int = 20) -> dict:
    """Ljung-Box statistic of the residual (per test and axis, lags 1..20): fraction that looks white (p > 1 %)."""
    from scipy.stats import chi2

    passed, total = 0, 0
    for n in names:
        r = prepared[n].y - pt.obs[n]
        for j in range(r.shape[1]):
            x = r[:, j] - r[:, j].mean()
            N = len(x)
            d = float(x @ x)
            if d <= 0 or N <= lags + 1:
                continue
            ac = np.array([float(x[k:] @ x[:-k]) / d for k in range(1, lags + 1)])
            Q = N * (N + 2) * float(np.sum(ac ** 2 / (N - np.arange(1, lags + 1))))
            passed += chi2.sf(Q, lags) > 0.01
            total += 1
    return {"white_fraction": passed / total if total else None, "test": "Ljung-Box, lags 1-20, p > 0.01"}


# --------------------------------------------------------------------------------------
# outputs: augmented parameter set, SSP, figures, report
# --------------------------------------------------------------------------------------
def _write_model(opt: Options, changes: Mapping[str, float], named: Sequence[dict], nominal: Mapping,
                 model_over: Mapping) -> dict:
    from lxml import etree

    from .ssp import NS

    values = {**{k: v for k, v in model_over.items()}, **changes}
    why = {}
    for eff in named:
        for p, v in eff["parameters"].items():
            u = eff["uncertainty"].get(p, {}).get("std")
            why[p] = (f"mast diagnose: {eff['effect']}; fitted {v:.6g} (std {u:.2g})" if u is not None
                      else f"mast diagnose: {eff['effect']}; fitted {v:.6g}")
    from fmus.actuator.model import PARAMETERS

    units = {p.name: p.unit for p in PARAMETERS}
    ssv, ssc = NS["ssv"], NS["ssc"]
    root = etree.Element(f"{{{ssv}}}ParameterSet", nsmap={"ssv": ssv, "ssc": ssc}, version="1.0",
                         name="actuator_diagnosed")
    root.append(etree.Comment(f" Written by mast diagnose from {Path(opt.measured).name}: the nominal model "
                              f"({opt.model or 'SSP bindings'}) plus the named effects; bind it after the "
                              "actuators' other parameter sets (MAST_diagnosed.ssp does). "))
    params = etree.SubElement(root, f"{{{ssv}}}Parameters")
    used_units = set()
    for name, v in values.items():
        desc = why.get(name, f"nominal model ({opt.model})")
        par = etree.SubElement(params, f"{{{ssv}}}Parameter", name=name, description=desc)
        if isinstance(v, str):
            etree.SubElement(par, f"{{{ssv}}}String", value=v)
        elif isinstance(v, int) and not isinstance(v, bool):
            etree.SubElement(par, f"{{{ssv}}}Integer", value=str(v))
        else:
            unit = units.get(name, "")
            etree.SubElement(par, f"{{{ssv}}}Real", value=repr(float(v)), **({"unit": unit} if unit else {}))
            if unit:
                used_units.add(unit)
    base_units = {"N.m": {"kg": "1", "m": "2", "s": "-2"}, "1": {}, "kg": {"kg": "1"}, "kg.m2": {"kg": "1", "m": "2"},
                  "N.m.s/rad": {"kg": "1", "m": "2", "s": "-1", "rad": "-1"}, "rad/s": {"rad": "1", "s": "-1"},
                  "rad": {"rad": "1"}, "s": {"s": "1"}, "m": {"m": "1"}}
    if used_units:
        ue = etree.SubElement(root, f"{{{ssv}}}Units")
        for u in sorted(used_units):
            etree.SubElement(etree.SubElement(ue, f"{{{ssc}}}Unit", name=u), f"{{{ssc}}}BaseUnit",
                             **base_units.get(u, {}))
    ssv_path = opt.out / "actuator_diagnosed.ssv"
    ssv_path.write_bytes(etree.tostring(root, xml_declaration=True, encoding="UTF-8", pretty_print=True))
    out = {"parameter_set": str(ssv_path), "values": dict(values),
           "use": "bind resources/actuator_diagnosed.ssv after the other parameter sets of every actuator_k "
                  "(MAST_diagnosed.ssp does that); compare the lab's torque with actuator_k.tau_meas"}
    src = Path(opt.ssp)
    if src.suffix == ".ssp" and src.exists():
        dst = opt.out / "MAST_diagnosed.ssp"
        with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w", zipfile.ZIP_DEFLATED) as zout:
            for item in zin.infolist():
                data = zin.read(item.filename)
                if item.filename == "SystemStructure.ssd":
                    data = _bind_diagnosed(data)
                zout.writestr(item, data)
            zout.write(ssv_path, "resources/actuator_diagnosed.ssv")
        out["ssp"] = str(dst)
    return out


def _bind_diagnosed(ssd: bytes) -> bytes:
    from lxml import etree

    from .ssp import NS

    root = etree.fromstring(ssd)
    for comp in root.iterfind(".//ssd:Component", NS):
        if not comp.get("name", "").startswith("actuator_"):
            continue
        bindings = comp.find("ssd:ParameterBindings", NS)
        if bindings is None:
            bindings = etree.SubElement(comp, f"{{{NS['ssd']}}}ParameterBindings")
        etree.SubElement(bindings, f"{{{NS['ssd']}}}ParameterBinding", source="resources/actuator_diagnosed.ssv")
    return etree.tostring(root, xml_declaration=True, encoding="UTF-8")


def _figures(out: Path, model: Model, prepared, names, before: Point, after: Point, sigma: float, roles,
             unexplained: bool, phase_free: Optional[dict]) -> dict:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figs = {}
    # 1. measured vs simulated, before and after: lowest, a held-out, highest frequency
    order = sorted(names, key=lambda n: (prepared[n].test.frequency or 0.0, n))
    show = list(dict.fromkeys([order[0]] + [n for n in order if roles[n] == "held-out"][:1] + [order[-1]]))
    fig, axes = plt.subplots(len(show), 1, figsize=(9, 2.6 * len(show)), squeeze=False)
    for ax, n in zip(axes[:, 0], show):
        p = prepared[n]
        f = p.test.frequency
        keep = p.t >= (p.t[-1] - min(2.0 / f, p.t[-1] - p.t[0]) if f else p.t[0])
        ax.plot(p.t[keep], p.y[keep, 0], color="0.55", lw=0.8, label="measured")
        ax.plot(p.t[keep], before.obs[n][keep, 0], color="tab:red", lw=1.2, label="nominal model")
        ax.plot(p.t[keep], after.obs[n][keep, 0], color="tab:blue", lw=1.2, ls="--", label="diagnosed model")
        ax.set_title(f"{p.test.label()} ({roles[n]}), motor 1", fontsize=9)
        ax.set_ylabel("tau_m [N m]")
        ax.grid(alpha=0.3)
    axes[0, 0].legend(fontsize=8, loc="upper right")
    axes[-1, 0].set_xlabel("t [s]")
    fig.tight_layout()
    fig.savefig(out / "fig_time.png", dpi=110)
    plt.close(fig)
    figs["time"] = "fig_time.png"

    # 2. residual against velocity and acceleration, before and after
    fig, axes = plt.subplots(2, 2, figsize=(10, 7), sharey="row")
    for row, (pt, title) in enumerate(((before, "nominal model"), (after, "diagnosed model"))):
        for n in names:
            w, a, _ = model.signals(pt, n)
            r = prepared[n].y - pt.obs[n]
            step = max(1, r.shape[0] // 400)
            axes[row, 0].plot(w[::step].ravel(), r[::step].ravel(), ".", ms=1.5, alpha=0.5, label=prepared[n].test.label())
            axes[row, 1].plot(a[::step].ravel(), r[::step].ravel(), ".", ms=1.5, alpha=0.5)
        for c in (0, 1):
            axes[row, c].axhline(2 * sigma, color="k", lw=0.6, ls=":")
            axes[row, c].axhline(-2 * sigma, color="k", lw=0.6, ls=":")
            axes[row, c].grid(alpha=0.3)
        axes[row, 0].set_ylabel(f"torque residual [N m]\n{title}")
    axes[1, 0].set_xlabel("guide speed at the motor shaft omega_N [rad/s]")
    axes[1, 1].set_xlabel("guide acceleration [rad/s^2]")
    axes[0, 0].legend(fontsize=7, markerscale=6, loc="best")
    fig.suptitle("Residual (measured - simulated) against velocity and acceleration; dotted: +-2 sigma noise", fontsize=10)
    fig.tight_layout()
    fig.savefig(out / "fig_residual_signals.png", dpi=110)
    plt.close(fig)
    figs["residual_signals"] = "fig_residual_signals.png"

    # 3. residual amplitude against frequency
    fig, ax = plt.subplots(figsize=(7, 4.2))
    for pt, color, label in ((before, "tab:red", "nominal"), (after, "tab:blue", "diagnosed")):
        for role, marker in (("training", "o"), ("held-out", "s")):
            ns = [n for n in names if roles[n] == role and prepared[n].test.frequency]
            if not ns:
                continue
            f = [prepared[n].test.frequency for n in ns]
            rms = [float(np.sqrt(np.mean((prepared[n].y - pt.obs[n]) ** 2))) for n in ns]
            ax.loglog(f, rms, marker, color=color, mfc=color if role == "training" else "none",
                      label=f"{label}, {role}")
    ax.axhline(sigma, color="k", ls="--", lw=0.8, label="noise floor")
    ax.set_xlabel("test frequency [Hz]")
    ax.set_ylabel("torque residual RMS [N m]")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "fig_residual_frequency.png", dpi=110)
    plt.close(fig)
    figs["residual_frequency"] = "fig_residual_frequency.png"

    if phase_free:
        fig, axes = plt.subplots(1, len(names), figsize=(3.2 * len(names), 3.4), squeeze=False)
        for ax, n in zip(axes[0], names):
            bp, bands = phase_free["band_powers_Nm_squared"][n], phase_free["bands_Hz"][n]
            x = np.arange(len(bands))
            for key, style, label in (("measured", "ko", "measured"), ("without", "s--", "without it"),
                                      ("with", "o-", "with it (ensemble)")):
                ax.semilogy(x, np.sqrt(bp[key]) * 1e3, style, ms=4, lw=1, label=label)
            ax.set_xticks(x, [f"{lo:g}-{hi:g}" for lo, hi in bands], fontsize=7)
            ax.set_title(f"{prepared[n].test.label()} ({roles[n]})", fontsize=8)
            ax.set_xlabel("band [Hz]", fontsize=8)
            ax.grid(alpha=0.3, which="both")
        axes[0, 0].set_ylabel("residual RMS in the band [mN m]")
        axes[0, 0].legend(fontsize=7)
        fig.suptitle(f"Phase-free score of {phase_free['parameter']} = {phase_free['value']:.4g}: band powers of the "
                     "residual against the nominal model", fontsize=9)
        fig.tight_layout()
        fig.savefig(out / "fig_phase_free.png", dpi=110)
        plt.close(fig)
        figs["phase_free"] = "fig_phase_free.png"

    if unexplained:
        fig, axes = plt.subplots(1, 2, figsize=(11, 4))
        for n in names:
            _, _, rho = model.signals(after, n)
            r = prepared[n].y - after.obs[n]
            step = max(1, r.shape[0] // 600)
            start = prepared[n].test.rho_cmd[0]
            axes[0].plot((rho - start)[::step].ravel() * 1e3, r[::step].ravel(), ".", ms=1.5, alpha=0.5,
                         label=prepared[n].test.label())
            dt = prepared[n].test.sample_time
            spec = np.abs(np.fft.rfft(r - r.mean(axis=0), axis=0)).mean(axis=1) / r.shape[0]
            fr = np.fft.rfftfreq(r.shape[0], dt)
            axes[1].loglog(fr[1:], spec[1:], lw=0.6, label=prepared[n].test.label())
        axes[0].set_xlabel("carriage position from the test's start [mm]")
        axes[0].set_ylabel("torque residual [N m]")
        axes[1].set_xlabel("frequency [Hz]")
        axes[1].set_ylabel("residual spectrum [N m]")
        axes[0].legend(fontsize=7, markerscale=6)
        for ax in axes:
            ax.grid(alpha=0.3)
        fig.suptitle("Unexplained residual of the diagnosed model: against position and its spectrum", fontsize=10)
        fig.tight_layout()
        fig.savefig(out / "fig_unexplained.png", dpi=110)
        plt.close(fig)
        figs["unexplained"] = "fig_unexplained.png"
    return figs


def _report(out: Path, doc: dict, figs: Mapping[str, str]) -> None:
    v = doc["verdict"]
    lines = [f"# Diagnosis of {Path(doc['measured']).name}", "",
             f"Nominal model: {doc['model']} ({Path(doc['ssp']).name}). Torque noise floor: "
             f"{1e3 * doc['noise_floor']['torque_std_Nm']:.3g} mN m ({doc['noise_floor']['method']}).", "",
             f"**Verdict: {v['status']}.** {v['text']}.", ""]
    lines += ["## Named effects", ""]
    if doc["named_effects"]:
        lines += ["| effect | parameter | nominal | fitted | std | evidence (re-simulated when added) |",
                  "|---|---|---|---|---|---|"]
        for e in doc["named_effects"]:
            ev = e["evidence"]
            wa = ev.get("when_added")
            text = (f"dBIC {wa['delta_bic_training']:+.0f}, held-out RSS {wa['held_out_rss_change_percent']:+.0f} %"
                    if wa and wa.get("held_out_rss_change_percent") is not None else
                    f"phase-free dBIC {wa['delta_bic_training']:+.0f}, held-out deviance "
                    f"{wa['held_out_deviance_change']:+.0f}" if wa and wa.get("held_out_deviance_change") is not None
                    else f"dBIC {wa['delta_bic_training']:+.0f}" if wa else "")
            for p, val in e["parameters"].items():
                std = e["uncertainty"][p]["std"]
                std_text = f"{std:.2g}" if std is not None and math.isfinite(std) else "-"
                lines.append(f"| {e['effect']} | `{p}` | {e['nominal'][p]:.5g} | {val:.5g} | {std_text} | {text} |")
            for alt in ev.get("alternatives", []):
                if "equivalent_value" in alt and alt["equivalent_value"] is not None:
                    lines.append(f"| (or) {alt['effect']} | `{alt['parameter']}` | | {alt['equivalent_value']:.5g} | | "
                                 f"{alt['how']}: dBIC {alt['delta_bic_band']:+.1f} |")
                elif "parameters" in alt:
                    vals = ", ".join(f"`{k}` = {v:.5g}" for k, v in alt["parameters"].items())
                    lines.append(f"| (or) {alt['effect']} | {vals} | | | | {alt['how']}: dBIC full band "
                                 f"{alt['delta_bic_full_band']:+.0f}, in the band {alt['delta_bic_band']:+.1f}: "
                                 f"{alt['note']} |")
            if "filter_or_delay" in ev:
                fd = ev["filter_or_delay"]
                lines.append(f"| (filter or delay) | `delay_meas` | | {fd['delay_meas']:.4g} | | "
                             f"dBIC delay vs filter {fd['delta_bic_delay_vs_filter']:+.0f}: chose {fd['choice']} |")
        lines.append("")
    else:
        lines += ["None.", ""]
    for e in doc["named_effects"]:
        pf = e["evidence"].get("phase_free")
        if not pf:
            continue
        lo, hi = pf["ci95"]
        lines += ["## Phase-free score", "",
                  f"{e['effect']} makes the loop hunt, which no simulation reproduces sample by sample; it was scored by "
                  f"the band powers of the torque residual against ensembles of {pf['ensemble']} re-simulations "
                  f"(commands perturbed far below their precision), noise {1e3 * pf['noise_std_Nm']:.3g} mN m "
                  f"(profiled). `{pf['parameter']}` = {pf['value']:.4g} (95 %: {lo:.4g} to {hi:.4g}); the training "
                  f"scan chose {pf['training_scan_value']:.4g} (dBIC {pf['delta_bic_training']:+.0f}, held-out "
                  f"deviance {pf['held_out_deviance_change'] or 0:+.0f}).", "",
                  "| test | deviance without it | with it | floor |", "|---|---|---|---|"]
        dev = pf["deviance_per_test"]
        lines += [f"| {n} | {dev['before'][n]:.1f} | {dev['after'][n]:.1f} | {pf['floor_per_test'][n]:.1f} |"
                  for n in dev["after"]]
        lines.append("")
    lines += ["## Gap per test (torque NRMSE %, lower is better)", "",
              "| test | role | before | after | noise floor | tracking error NRMSE % before / after |",
              "|---|---|---|---|---|---|"]
    for t in doc["tests"]:
        g = doc["gap"][t["name"]]
        b, a = g["before"], g["after"]
        lines.append(f"| {t['label']} | {g['role']} | {b['torque_nrmse_percent']:.1f} | {a['torque_nrmse_percent']:.1f} | "
                     f"{b['torque_floor_percent']:.1f} | {b['tracking_error_nrmse_percent']:.1f} / "
                     f"{a['tracking_error_nrmse_percent']:.1f} |")
    lines += ["", "## Where the nominal model's residual concentrates", ""]
    for t in doc["tests"]:
        lb = t["localise_before"]
        lines.append(f"- {t['label']}: RMS {lb['rms_over_noise']:.1f} x noise; {lb['summary']}")
    for motion, tr in doc["frequency_trend"].items():
        if tr["log_slope_before"] is not None:
            lines.append(f"- {motion} tests: residual at the test frequency {tr['reading']} "
                         f"(log-log slope {tr['log_slope_before']:.2f})")
    lines.append("")
    if doc["unexplained"]:
        u = doc["unexplained"]
        lines += ["## Unexplained residual", "", u["text"], ""]
        lines += [f"- {n}: {w}" for n, w in u["where"].items()]
        lines += ["", "| candidate | dBIC | held-out RSS change % | rejected because |", "|---|---|---|---|"]
        for c in u["candidates_tried"]:
            ho, dbic = c["held_out_rss_change_percent"], c["delta_bic"]
            lines.append(f"| {c['candidate']} | {'-' if dbic is None else f'{dbic:+.1f}'} | "
                         f"{'-' if ho is None else f'{ho:+.1f}'} | {c['rejected_because']} |")
        lines.append("")
    lines += ["## Figures", ""]
    captions = {"time": "Measured and simulated motor torque, before and after",
                "residual_signals": "Residual against velocity and acceleration",
                "residual_frequency": "Residual amplitude against test frequency",
                "unexplained": "The residual no candidate explains",
                "phase_free": "Band powers of the residual: measured, and predicted with and without the effect"}
    for k, f in figs.items():
        lines += [f"![{captions[k]}]({f})", ""]
    am = doc["augmented_model"]
    lines += ["## The augmented model", "", f"Parameter set: `{Path(am['parameter_set']).name}` ({am['use']}).", ""]
    if am.get("ssp"):
        lines += [f"Ready to run: `mast run {Path(am['ssp']).name} ...` (records `actuator_k.tau_meas`).", ""]
    lines += ["## Steps", "", "| how | from | to | dBIC training | held-out RSS % | accepted |", "|---|---|---|---|---|---|"]
    for st in doc["steps"]:
        dbic = st.get("delta_bic_training", st.get("delta_bic_full_band"))
        ho = st.get("held_out_rss_change_percent")
        lines.append(f"| {st['how']} | {', '.join(st['from']) or 'nominal'} | "
                     f"{', '.join(st['to']) if isinstance(st['to'], list) else st['to']} | "
                     f"{dbic:+.0f} | {ho:+.1f} | {st['accepted']} |" if dbic is not None and ho is not None else
                     f"| {st['how']} | {', '.join(st['from']) or 'nominal'} | "
                     f"{', '.join(st['to']) if isinstance(st['to'], list) else st['to']} | "
                     f"{'' if dbic is None else f'{dbic:+.0f}'} | | {st['accepted']} |")
    lines.append("")
    tm = doc["timing"]
    lines += ["## Timing", "", f"{tm['wall_s']} s wall ({tm['simulations']} test simulations, {tm['simulation_wall_s']} s "
              f"in simulation, {tm['workers']} workers, direct composition: {tm['direct']}).", ""]
    (out / "report.md").write_text("\n".join(lines))
