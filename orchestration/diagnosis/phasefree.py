"""A phase-insensitive score for effects that make the closed loop hunt (backlash).

With backlash the axes hunt: a limit cycle whose phase depends chaotically on the commands
(two runs whose commands differ by 1e-13 m part after 0.17 s) or, where it is periodic, so
sensitively on the parameter that 2 % more backlash turns a residual at the noise floor
into 2.4 x the noise. No sample-by-sample residual can confirm such an effect; what the
model does predict is how much the torque hunts and in which frequency bands.

The statistic: per test, the mean square of the torque residual against a fixed
reference (the current model's simulation) in a few frequency bands, averaged over the
axes. The measurement's statistic is compared with an *ensemble*: the candidate model
re-simulated with commands perturbed far below their precision (``ENSEMBLE`` realisations),
plus white noise of variance s^2. A band power of white noise over N samples is a
chi-square (Gamma) variable with nu = N / sum(rho_k^2) degrees of freedom (rho the
autocorrelation of the band filter), so given one realisation the measured band powers
have a Gamma likelihood; the model's likelihood of a test is the average over its
realisations (a mixture: where the loop sometimes hunts and sometimes not, both count).
The deviance -2 ln L (0 for a perfect match) is summed over tests; the noise variance
s^2 is profiled, between a quarter of the noise floor's variance and the floor (the
floor from third differences also sees fast content of the signal: an upper estimate).

The value: where the hunting is periodic (short records) a value's band powers jump between neighbours a few
percent apart, and so does its deviance; the value is the minimum of the deviance pooled over the values within
POOL_RATIO (``pooled``), found on a grid (``search``) and by a parabola (``estimate``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Mapping, Optional, Sequence

import numpy as np

#: band edges of the statistic [Hz]: the hunting (tens of hertz), its harmonics, the transmission's ringing
BAND_EDGES_HZ = (20.0, 60.0, 200.0)
#: realisations of every candidate (commands perturbed far below their precision)
ENSEMBLE = 3
#: standard deviation of the command perturbation between realisations (m for z, rad for the angles)
COMMAND_JITTER = 1e-12
#: a test's deviance is at the floor below this quantile of chi-square with one degree per band
FLOOR_QUANTILE = 0.999


class BandPowers:
    """Zero-phase Butterworth bands of one sample time; the white-noise power and dof of each band."""

    def __init__(self, dt: float) -> None:
        from scipy.signal import butter, sosfiltfilt

        self._filt = sosfiltfilt
        fs = 1.0 / dt
        edges = [e for e in BAND_EDGES_HZ if e < 0.8 * fs / 2]
        if not edges:
            raise ValueError(
                f"sample time {dt:g} s: too slow for the phase-free score (bands from {BAND_EDGES_HZ[0]:g} Hz)"
            )
        self.bands = list(zip([0.0] + edges, edges + [fs / 2]))
        self.sos = []
        for lo, hi in self.bands:
            if lo == 0.0:
                self.sos.append(butter(4, hi, fs=fs, output="sos"))
            elif hi >= fs / 2:
                self.sos.append(butter(4, lo, btype="high", fs=fs, output="sos"))
            else:
                self.sos.append(butter(4, [lo, hi], btype="band", fs=fs, output="sos"))
        # the exact impulse response of each zero-phase filter: the power fraction of white noise it
        # passes, the degrees of freedom per sample of the mean square of filtered white noise, and
        # the samples at each end of a record where the filter has not settled (the power there is
        # not that of the band: they are left out, 1e-4 of the response's energy beyond them)
        half = 4096
        impulse = np.zeros(2 * half + 1)
        impulse[half] = 1.0
        self.noise_fraction = np.empty(len(self.bands))
        self.dof_per_sample = np.empty(len(self.bands))
        self.margin = np.empty(len(self.bands), dtype=int)
        for k, sos in enumerate(self.sos):
            h = sosfiltfilt(sos, impulse)
            energy = float(h @ h)
            rho = np.correlate(h, h, mode="full") / energy
            self.noise_fraction[k] = energy
            self.dof_per_sample[k] = 1.0 / float(rho @ rho)
            outside = energy - np.cumsum(h[half:] ** 2 + np.concatenate([[0.0], h[half - 1 :: -1] ** 2]))
            self.margin[k] = int(np.argmax(outside < 1e-4 * energy))

    def samples(self, n: int) -> np.ndarray:
        """Samples of a record of n per band after the margins (at least a third of the record)."""
        return np.maximum(n - 2 * self.margin, n // 3)

    def powers(self, x: np.ndarray) -> np.ndarray:
        """Mean square of x (n, axes) in every band, averaged over axes and the samples between the margins."""
        out = []
        for sos, keep in zip(self.sos, self.samples(len(x))):
            m = (len(x) - keep) // 2
            out.append(float(np.mean(self._filt(sos, x, axis=0)[m : m + keep] ** 2)))
        return np.array(out)


@dataclass
class Fit:
    deviance: float  # summed over the tests
    per_test: dict[str, float]
    sigma: float  # the profiled noise standard deviation


class PhaseFreeScore:
    """Band powers of the measured residual (against a fixed reference) and the deviance of ensembles."""

    def __init__(
        self,
        measured: Mapping[str, np.ndarray],
        reference: Mapping[str, np.ndarray],
        dt: Mapping[str, float],
        sigma_floor: float,
    ) -> None:
        self.reference = dict(reference)
        self.sigma_floor = sigma_floor
        by_step: dict[float, BandPowers] = {}
        for n in measured:
            if round(dt[n], 12) not in by_step:
                by_step[round(dt[n], 12)] = BandPowers(dt[n])
        self.bands = {n: by_step[round(dt[n], 12)] for n in measured}
        self.measured = {n: self.powers(n, y) for n, y in measured.items()}
        self.dof = {
            n: self.bands[n].samples(len(y)) * y.shape[1] * self.bands[n].dof_per_sample for n, y in measured.items()
        }

    def powers(self, name: str, observed: np.ndarray) -> np.ndarray:
        """Band powers of a torque (samples, drives) of test ``name`` against the reference."""
        return self.bands[name].powers(observed - self.reference[name])

    def floor(self, name: str) -> float:
        from scipy.stats import chi2

        return float(chi2.ppf(FLOOR_QUANTILE, len(self.bands[name].bands)))

    def statistics(self, names: Sequence[str]) -> int:
        return sum(len(self.bands[n].bands) for n in names)

    def _test_deviance(self, name: str, ensemble: np.ndarray, s2: float) -> float:
        from scipy.special import logsumexp

        m, nu = self.measured[name], self.dof[name]
        mu = ensemble + s2 * self.bands[name].noise_fraction  # (realisations, bands)
        q = m / mu
        loglik = -0.5 * (nu * (q - 1.0 - np.log(q))).sum(axis=1)
        return float(-2.0 * (logsumexp(loglik) - math.log(len(loglik))))

    def deviances(self, ensembles: Mapping[str, np.ndarray], names: Sequence[str], sigma: float) -> dict[str, float]:
        """Deviance of every test ``names`` at a given noise standard deviation (one profiled on other tests)."""
        return {n: self._test_deviance(n, ensembles[n], sigma**2) for n in names}

    def quieter(self, name: str, ensemble: np.ndarray, sigma: float, z: float = 3.0) -> bool:
        """Whether the measured band powers of test ``name`` are nowhere above what the ensemble's loudest
        realisation in that band plus the noise gives (within ``z`` standard deviations of a band power,
        sqrt(2 / nu)): the
        record hunts less than, or as much as, the re-simulations, never more in any band. A cause the effect
        does not make adds power somewhere; a regime of the hunting the ensemble did not visit (fewer or weaker
        episodes in the record's window) only takes it away."""
        loudest = ensemble.max(axis=0) + sigma**2 * self.bands[name].noise_fraction
        return bool(np.all(self.measured[name] <= loudest * (1.0 + z * np.sqrt(2.0 / self.dof[name]))))

    def fit(self, ensembles: Mapping[str, np.ndarray], names: Sequence[str]) -> Fit:
        """Deviance of the ensembles (per test: realisations x bands, from ``powers``) on the tests
        ``names``, with the noise variance profiled."""
        from scipy.optimize import minimize_scalar

        def total(log_s2: float) -> float:
            return sum(self._test_deviance(n, ensembles[n], math.exp(log_s2)) for n in names)

        hi = 2.0 * math.log(self.sigma_floor)
        res = minimize_scalar(total, bounds=(hi - math.log(4.0), hi), method="bounded", options={"xatol": 1e-4})
        s2 = math.exp(float(res.x))
        per = {n: self._test_deviance(n, ensembles[n], s2) for n in names}
        return Fit(sum(per.values()), per, math.sqrt(s2))


#: the value's search after the scan (ratio 2): a grid at ratio 2^(1/4) between the scan's best value's neighbours,
#: then one at 2^(1/16) (4.4 %) around the best of those, 2^(1/4) either side
MID_RATIO = 2.0**0.25
FINE_RATIO = 2.0 ** (1.0 / 16.0)
FINE_STEPS = 4
#: realisations of every value of the mid and fine grids (the scan's have ENSEMBLE): the pooling window holds five
#: or more values, neighbours at 4.4 % differ as much as the commands' last digits do, so two per value suffice
GRID_REALISATIONS = 2
#: the smoothed deviance of a value pools the realisations of every value simulated within this ratio of it on the
#: fine grid (on the mid grid: within one mid step); see ``pooled``
POOL_RATIO = 2.0 ** (1.0 / 8.0)
#: the fine grid is extended by two steps at an end its smoothed minimum lies within a pooling window of (so that the
#: window about the minimum is full on both sides), at most this many times
MAX_EXTENSIONS = 4


def pooled(
    ensembles: Mapping[float, Optional[Mapping[str, np.ndarray]]], value: float, ratio: float
) -> Optional[dict[str, np.ndarray]]:
    """The realisations of every value simulated within ``ratio`` of ``value`` (positive values only), as one
    ensemble per test: a mixture over the value's last few percent, as the ensemble is one over the commands'
    last digits. Where the hunting is periodic its band powers jump between neighbouring values (2 % more
    backlash: from no hunting to 2.4 x the noise), so one value's few realisations make a rough deviance whose
    minimum wanders; the pooled one is smooth at the scale of the window and its minimum stays centred.
    None if no simulated value (or a failed one) lies in the window."""
    near = [u for u in ensembles if u > 0 and abs(math.log(u / value)) <= math.log(ratio) + 1e-9]
    if not near or any(ensembles[u] is None for u in near):
        return None
    names = list(ensembles[near[0]])
    return {n: np.concatenate([ensembles[u][n] for u in near]) for n in names}


def search(
    simulate: Callable[[Sequence[float]], None],
    smoothed: Callable[[float, float], float],
    best: float,
    bounds: tuple[float, float],
) -> tuple[dict[float, float], dict[float, float]]:
    """A bounded 1-D search for the minimum of the smoothed deviance ``smoothed(value, pooling ratio)`` around
    ``best`` (the scan's best value, ratio 2 from its neighbours): the grid at MID_RATIO between the
    neighbours, smoothed over one mid step, picks the centre of a grid at FINE_RATIO (FINE_STEPS either side),
    smoothed over POOL_RATIO; that grid grows towards an end its minimum lies within POOL_RATIO of. ``simulate``
    makes the ensembles of values not simulated yet. Returns the smoothed deviances on the mid and on the fine
    grid."""
    lo, hi = bounds
    margin = round(math.log(POOL_RATIO) / math.log(FINE_RATIO))

    def grid(centre: float, ratio: float, steps: Sequence[int]) -> list[float]:
        return [v for v in (centre * ratio**k for k in steps) if lo <= v <= hi]

    mid_values = grid(best, MID_RATIO, range(-4, 5))
    simulate(mid_values)
    mid = {v: smoothed(v, MID_RATIO) for v in mid_values}
    centre = min(mid, key=mid.get)
    steps = list(range(-FINE_STEPS, FINE_STEPS + 1))
    for _ in range(MAX_EXTENSIONS + 1):
        values = grid(centre, FINE_RATIO, steps)
        simulate(values)
        fine = {v: smoothed(v, POOL_RATIO) for v in values}
        k = values.index(min(fine, key=fine.get))
        low = k < margin and values[0] / FINE_RATIO >= lo  # the window about the minimum is cut short
        high = k > len(values) - 1 - margin and values[-1] * FINE_RATIO <= hi
        if not (low or high):
            break
        steps += [steps[0] - 1, steps[0] - 2] if low else [steps[-1] + 1, steps[-1] + 2]
        steps.sort()
    return mid, fine


def estimate(points: Mapping[float, float], span: float) -> tuple[float, float]:
    """Minimum of a parabola in ln(value) fitted to the deviances within ``span`` (a ratio) of the best
    point, and the standard deviation of ln(value): the statistical part 1/sqrt(curvature) (the
    deviance is -2 ln L) and the part from the scatter of the deviances about the parabola (the
    ensembles are finite), by the delta method. Falls back to the best point when the parabola has
    no minimum inside the span (std then the span)."""
    best = min(points, key=points.get)
    near = sorted(v for v in points if best / span <= v <= best * span and math.isfinite(points[v]))
    x = np.log(np.array(near))
    d = np.array([points[v] for v in near])
    if len(near) < 3:
        return best, math.log(span)
    X = np.column_stack([np.ones_like(x), x, x**2])
    c, *_ = np.linalg.lstsq(X, d, rcond=None)
    if c[2] <= 0:
        return best, math.log(span)
    x0 = -c[1] / (2.0 * c[2])
    if not x.min() <= x0 <= x.max():
        return best, math.log(span)
    var = 1.0 / c[2]
    if len(near) > 3:
        s2 = float(np.sum((d - X @ c) ** 2)) / (len(near) - 3)
        g = np.array([0.0, -1.0 / (2.0 * c[2]), c[1] / (2.0 * c[2] ** 2)])
        var += s2 * float(g @ np.linalg.inv(X.T @ X) @ g)
    return float(math.exp(x0)), math.sqrt(var)
