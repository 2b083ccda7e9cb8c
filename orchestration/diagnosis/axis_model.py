"""The model of a record's drive axis as ``mast diagnose`` fits it (records.py, the workflow on a record).

``Case``: a test of the record with its training and held-out samples; ``Point``: the model at one
parameter set, simulated on every case; ``AxisModel``: simulates the cases with the plant
component's parameters changed (cached, counted); ``Diagnosis``: the state of one diagnosis (cases,
model, band, noise floor) with the band-limited regression of a point's residual and the fit by
re-simulation (Gauss-Newton).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Callable, Mapping, Sequence

import numpy as np

from ..analyses.replay import simulate_record
from ..data.record import Record
from .effects import axis_column, noise_std
from .selection import Atom, Band, Regression

#: Gauss-Newton: converged when the next step promises (linearised) or gives less than this share of the cost,
#: or moves no parameter by more than FIT_TOL (relative); iteration limit; step halvings before giving up
FIT_COST_TOL, FIT_TOL, FIT_ITERATIONS, FIT_HALVINGS = 1e-3, 1e-5, 12, 1


@dataclass
class Case:
    """A test with its training and held-out samples."""

    record: Record
    train: np.ndarray  # bool per sample
    held: np.ndarray  # bool per sample
    efforts: list[str]  # measured effort signals (compared, scored)

    @property
    def name(self) -> str:
        return self.record.name

    @property
    def train_end(self) -> float:
        """The simulation of the training samples needs the record up to here."""
        return float(self.record.time[self.train].max()) if self.train.any() else 0.0


@dataclass
class Point:
    """The model at a parameter set, simulated on every case (whole or up to the training end)."""

    values: dict  # the plant component's diagnosed parameters
    sims: dict[str, dict[str, np.ndarray]]  # case -> signal -> samples
    whole: bool

    def residual(self, case: Case, signal: str) -> np.ndarray:
        y = case.record.values[signal]
        return y[: len(self.sims[case.name][signal])] - self.sims[case.name][signal]


class AxisModel:
    """Simulates the cases with the plant component's parameters changed (cached)."""

    def __init__(
        self, ssp: str, cases: Sequence[Case], component: str, base: Mapping[str, Mapping], direct: bool = True
    ) -> None:
        self.ssp, self.cases, self.component, self.base, self.direct = ssp, list(cases), component, base, direct
        self.count, self.seconds = 0, 0.0
        self._cache: dict = {}

    def point(self, values: Mapping[str, float], whole: bool = True) -> Point:
        key = (tuple(sorted((k, float(v)) for k, v in values.items())), whole)
        if key not in self._cache:
            t0 = time.perf_counter()
            params = {k: dict(v) for k, v in self.base.items()}
            params.setdefault(self.component, {}).update(values)
            sims = {
                c.name: simulate_record(
                    self.ssp,
                    c.record,
                    params,
                    self.direct,
                    extra=(f"{self.component}.q_dot",),
                    stop_time=None if whole else c.train_end,
                )
                for c in self.cases
            }
            self.count += len(self.cases)
            self.seconds += time.perf_counter() - t0
            self._cache[key] = Point(dict(values), sims, whole)
        return self._cache[key]

    def motion(self, pt: Point, case: Case) -> tuple[np.ndarray, np.ndarray]:
        """Simulated velocity and acceleration at the samples."""
        v = pt.sims[case.name][f"{self.component}.q_dot"]
        return v, np.gradient(v, case.record.sample_time)

    def columns(self, pt: Point, case: Case, params: Sequence[str]) -> np.ndarray:
        v, a = self.motion(pt, case)
        return np.column_stack([axis_column(p, v, a) for p in params]) if params else np.zeros((len(v), 0))


class Diagnosis:
    """The state of one diagnosis: cases, model, band, noise floor; scores of points."""

    def __init__(self, model: AxisModel, cases: Sequence[Case], band: Band, log: Callable[[str], None]) -> None:
        self.model, self.cases, self.band, self.log = model, list(cases), band, log
        floors = [noise_std(c.record.values[s]) for c in cases for s in c.efforts]
        self.sigma = float(np.median(floors))
        dt = cases[0].record.sample_time
        self.sigma_b = self.sigma * band.noise_factor(dt)

    # -- band-limited residuals and columns, split training / held-out ---------------------
    def _banded(self, case: Case, x: np.ndarray) -> np.ndarray:
        return self.band.apply(x, case.record.sample_time)

    def _split(self, case: Case, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        dt = case.record.sample_time
        q = self.band.decimation(dt)
        n = x.shape[0]
        tr, ho = case.train[::q][:n].copy(), case.held[::q][:n].copy()
        margin = max(1, int(0.05 / (dt * q)))  # the filter's settling at both ends of a part
        for mask in (tr, ho):
            idx = np.flatnonzero(mask)
            if len(idx) > 2 * margin:
                mask[idx[:margin]] = False
                mask[idx[-margin:]] = False
        return x[tr], x[ho]

    def regression(self, pt: Point, atoms: Sequence[Atom]) -> Regression:
        A_tr, r_tr, A_ho, r_ho = [], [], [], []
        params = [a.effect.parameter for a in atoms]
        for c in self.cases:
            cols = self.model.columns(pt, c, params)
            for s in c.efforts:
                r = pt.residual(c, s)
                Ab, rb = self._banded(c, cols), self._banded(c, r)
                a_tr, a_ho = self._split(c, Ab)
                x_tr, x_ho = self._split(c, rb)
                A_tr.append(a_tr), A_ho.append(a_ho), r_tr.append(x_tr), r_ho.append(x_ho)
        return Regression(
            atoms, np.vstack(A_tr), np.concatenate(r_tr), np.vstack(A_ho), np.concatenate(r_ho), self.sigma_b
        )

    def band_rss(self, pt: Point) -> tuple[float, int, float, int]:
        """(RSS, n) of the band-limited effort residual on the training and on the held-out samples."""
        tr = ho = 0.0
        n_tr = n_ho = 0
        for c in self.cases:
            for s in c.efforts:
                x_tr, x_ho = self._split(c, self._banded(c, pt.residual(c, s)))
                tr += float(x_tr @ x_tr)
                ho += float(x_ho @ x_ho)
                n_tr, n_ho = n_tr + len(x_tr), n_ho + len(x_ho)
        return tr, n_tr, ho, n_ho

    # -- fit by re-simulation ------------------------------------------------------------------
    def fit(
        self, start: Mapping[str, float], free: Sequence[str], bounds: Mapping[str, tuple[float, float]]
    ) -> tuple[dict, dict]:
        """Gauss-Newton on the full-band training residual of the efforts, re-simulating the training part;
        returns (values, info with the covariance's standard deviations)."""
        x = dict(start)

        def residual(pt: Point) -> np.ndarray:
            return np.concatenate(
                [pt.residual(c, s)[c.train[: len(pt.sims[c.name][s])]] for c in self.cases for s in c.efforts]
            )

        def jacobian(pt: Point) -> np.ndarray:
            return np.vstack(
                [
                    self.model.columns(pt, c, free)[c.train[: len(pt.sims[c.name][s])]]
                    for c in self.cases
                    for s in c.efforts
                ]
            )

        pt = self.model.point(x, whole=False)
        r = residual(pt)
        cost = float(r @ r)
        history = [cost]
        for it in range(FIT_ITERATIONS):
            J = jacobian(pt)
            scale = np.linalg.norm(J, axis=0)
            scale[scale == 0] = 1.0
            step = np.linalg.lstsq(J / scale, r, rcond=None)[0] / scale
            predicted = float(np.sum((J @ step) ** 2))  # the cost reduction the linearisation promises
            if predicted < FIT_COST_TOL * cost:
                break
            accepted = False
            for _ in range(FIT_HALVINGS + 1):
                trial = {**x, **{p: float(np.clip(x[p] + d, *bounds[p])) for p, d in zip(free, step)}}
                tp = self.model.point(trial, whole=False)
                tr = residual(tp)
                tc = float(tr @ tr)
                if tc <= cost:
                    accepted = True
                    break
                step = step / 2
            if not accepted:
                break
            rel = max((abs(trial[p] - x[p]) / max(abs(x[p]), abs(trial[p]), 1e-6) for p in free), default=0.0)
            x, pt, r, cost = trial, tp, tr, tc
            history.append(cost)
            self.log(
                f"diagnose: fit iteration {it + 1}: force RSS {cost:.6g} N^2, "
                + ", ".join(f"{p} {x[p]:.6g}" for p in free)
            )
            if rel < FIT_TOL or history[-2] - cost < FIT_COST_TOL * history[-2]:
                break
        J = jacobian(pt)
        n, k = J.shape
        s2 = cost / max(n - k, 1)
        r1 = float(np.corrcoef(r[:-1], r[1:])[0, 1]) if len(r) > 2 else 0.0
        inflate = (1 + r1) / (1 - r1) if r1 < 1 else math.inf
        try:
            cov = s2 * inflate * np.linalg.inv(J.T @ J)
            std = {p: float(math.sqrt(max(cov[i, i], 0.0))) for i, p in enumerate(free)}
        except np.linalg.LinAlgError:
            std = {p: float("nan") for p in free}
        return x, {"rss_history": history, "std": std, "lag1_autocorrelation": r1, "steps": len(history) - 1}
