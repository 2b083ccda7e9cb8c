"""The phase-free score (orchestration/diagnosis/phasefree.py), checked against Monte Carlo (no simulation)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mast.diagnosis.phasefree import BandPowers, PhaseFreeScore, estimate, pooled, search

DT = 1e-3


def test_band_noise_power_and_dof_match_monte_carlo():
    """The exact filter responses give the white-noise power of each band and the degrees of freedom of its
    mean square between the margins: compare with the mean and variance over 400 independent noise records."""
    bands = BandPowers(DT)
    n = 700
    rng = np.random.default_rng(1)
    p = np.array([bands.powers(rng.standard_normal((n, 3))) for _ in range(400)])
    assert p.mean(axis=0) == pytest.approx(bands.noise_fraction, rel=0.03)
    dof = 2 * p.mean(axis=0) ** 2 / p.var(axis=0)
    assert dof == pytest.approx(3 * bands.samples(n) * bands.dof_per_sample, rel=0.2)


def test_deviance_of_noise_is_chi_square_and_profiles_the_noise():
    """Pure noise against a model that predicts nothing but noise: the deviance per test is about chi-square
    with one degree per band (mean = bands), the profiled noise is the true one, and a candidate that adds
    power in a band is penalised."""
    rng = np.random.default_rng(2)
    sigma, names = 2e-3, [f"t{k}" for k in range(40)]
    measured = {n: sigma * rng.standard_normal((700, 3)) for n in names}
    zero = {n: np.zeros((700, 3)) for n in names}
    score = PhaseFreeScore(measured, zero, {n: DT for n in names}, sigma_floor=1.3 * sigma)
    nb = len(score.bands[names[0]].bands)
    silent = {n: np.zeros((3, nb)) for n in names}
    fit = score.fit(silent, names)
    assert fit.sigma == pytest.approx(sigma, rel=0.02)
    assert fit.deviance / len(names) == pytest.approx(nb, rel=0.35)
    assert sum(d > score.floor(n) for n, d in fit.per_test.items()) <= 1
    loud = {n: np.tile([sigma**2 * score.bands[n].noise_fraction[0], 0, 0, 0], (3, 1)) for n in names}
    assert score.fit(loud, names).deviance > fit.deviance + 100


def test_estimate_finds_a_parabola_minimum():
    """On an exact parabola in ln(value) the estimate returns its minimum, with the standard deviation
    1/sqrt(curvature)."""
    x0, c = math.log(0.0123), 400.0
    points = {v: c * (math.log(v) - x0) ** 2 for v in (0.0123 * 2 ** (k / 16) for k in range(-6, 5))}
    value, s_log = estimate(points, 2 ** (1 / 4))
    assert value == pytest.approx(0.0123, rel=1e-9)
    assert s_log == pytest.approx(1 / math.sqrt(c), rel=1e-6)


def test_smoothed_search_finds_a_value_whose_hunting_is_rough_in_the_value():
    """Where the hunting is periodic its band powers jump between neighbouring values: here the hunting power of
    every (test, value, realisation) is the smooth trend (value / truth)^2 times a log-normal factor (sd 0.15)
    drawn per value and realisation, on four hunting tests. From the ratio-2 scan's best value (4e-3) the search
    on the pooled deviance lands within 5 % of the truth (3.5e-3, 5.2e-3), on a fine grid at 2^(1/16) that
    brackets it, with at most the scan, the mid and the fine grid simulated."""
    rng = np.random.default_rng(4)
    sigma, n = 2e-3, 2000
    names = [f"z{k}" for k in range(4)]
    t = np.arange(n) * DT
    hunt = 3 * sigma * np.sin(2 * np.pi * 40 * t)[:, None] * np.ones((1, 3))
    for truth in (3.5e-3, 5.2e-3):
        measured = {m: sigma * rng.standard_normal((n, 3)) + hunt for m in names}
        score = PhaseFreeScore(
            measured, {m: np.zeros((n, 3)) for m in names}, {m: DT for m in names}, sigma_floor=sigma
        )
        unit = score.bands["z0"].powers(hunt)
        ensembles: dict = {}

        def simulate(values):
            for v in values:  # (as the diagnosis does: a value within 1e-9 of one simulated is that one)
                if not any(abs(v - u) <= 1e-9 * u for u in ensembles):
                    g = np.random.default_rng(int(v * 1e9))
                    ensembles[v] = {
                        m: np.array([unit * (v / truth) ** 2 * math.exp(0.15 * g.standard_normal()) for _ in range(3)])
                        for m in names
                    }

        def smoothed(v, ratio):
            return score.fit(pooled(ensembles, v, ratio), names).deviance

        simulate([5e-4 * 2**k for k in range(8)])
        mid, fine = search(simulate, smoothed, 4e-3, (0.0, 0.2))
        value, _ = estimate(fine, 2 ** (1 / 4))
        assert value == pytest.approx(truth, rel=0.05), (truth, value)
        assert np.diff(np.log(sorted(fine))) == pytest.approx(math.log(2) / 16, rel=1e-6)
        assert min(fine) < truth < max(fine)
        assert len(ensembles) <= 8 + 6 + 6


def test_search_grows_the_fine_grid_towards_its_minimum():
    """A smoothed deviance whose minimum on the fine grid lies beyond its end (at 2^(0.6) x the mid grid's best
    value, the fine grid reaching 2^(1/4)): the fine grid grows that way, two steps at a time, until the minimum
    has a full pooling window (2^(1/8): two steps) on either side; values outside the bounds are never asked for."""
    asked = []

    def smoothed(v, ratio):
        x0 = math.log(4e-3) + (0.0 if ratio > 1.1 else 0.6 * math.log(2))
        return (math.log(v) - x0) ** 2

    mid, fine = search(asked.extend, smoothed, 4e-3, (0.0, 0.2))
    best = min(fine, key=fine.get)
    assert best == pytest.approx(4e-3 * 2**0.625, rel=1e-9)  # the grid value nearest 2^0.6
    assert 2 <= sorted(fine).index(best) <= len(fine) - 3
    mid, fine = search(asked.extend, smoothed, 4e-3, (0.0, 5e-3))
    assert max(asked[-len(fine) :]) <= 5e-3 and max(fine) <= 5e-3


def test_leave_one_out_confirms_a_hunting_seen_on_two_tests_whatever_the_split():
    """Backlash's selection (nonlinear.leave_one_out, no simulation here): noise on four tests, a 40 Hz hunting
    on two of them whose power grows with the candidate value (the truth 4e-3). Each test is predicted at the
    scan value best on the other three: the two hunting tests each at the truth (from the other one), strongly
    better than the current model; the quiet tests about unchanged. A split that trains on both hunting tests
    and holds out the quiet ones sees nothing on its held-out set, which is why the decision is not made on it."""
    from mast.diagnosis.nonlinear import leave_one_out

    rng = np.random.default_rng(3)
    sigma, n, truth = 2e-3, 700, 4e-3
    names, hunting = ["z1", "psi2", "z4", "z6"], {"z4", "z6"}
    t = np.arange(n) * DT
    hunt = 3 * sigma * np.sin(2 * np.pi * 40 * t)[:, None] * np.ones((1, 3))
    measured = {m: sigma * rng.standard_normal((n, 3)) + (hunt if m in hunting else 0) for m in names}
    score = PhaseFreeScore(measured, {m: np.zeros((n, 3)) for m in names}, {m: DT for m in names}, sigma_floor=sigma)
    unit = score.bands["z1"].powers(hunt)
    scan = [5e-4 * 2**k for k in range(6)]
    ensembles = {v: {m: np.tile(unit * (v / truth) ** 2 * (m in hunting), (3, 1)) for m in names} for v in scan}
    ensembles[0.0] = {m: np.zeros((3, len(unit))) for m in names}
    folds = leave_one_out(score, ensembles, 0.0, scan, names)
    for m in hunting:
        assert folds[m]["value"] == truth and folds[m]["deviance_change"] < -100
    for m in set(names) - hunting:
        assert abs(folds[m]["deviance_change"]) < 10
    held = ["z1", "psi2"]  # the split that holds out the quiet tests only
    change = score.fit(ensembles[truth], held).deviance - score.fit(ensembles[0.0], held).deviance
    assert abs(change) < 10


def test_quieter_tells_a_quieter_regime_from_power_the_effect_does_not_make():
    """A record whose band powers stay below the loudest realisation plus the noise in every band is quieter than
    the ensemble (a regime of the hunting it did not visit); one band 3 x above the loudest is not, and neither is
    a record just above it by more than 3 standard deviations of its band power (sqrt(2 / nu)), while one within
    them is."""
    rng = np.random.default_rng(4)
    sigma = 2e-3
    measured = {"t": sigma * rng.standard_normal((700, 3))}
    score = PhaseFreeScore(measured, {"t": np.zeros((700, 3))}, {"t": DT}, sigma_floor=sigma)
    noise = sigma**2 * score.bands["t"].noise_fraction
    ensemble = np.array([[4e-5, 5e-6, 3e-7, 5e-6], [6e-5, 6e-6, 4e-7, 4e-6]])
    loudest = ensemble.max(axis=0) + noise
    rel = np.sqrt(2.0 / score.dof["t"])
    for k, factor, expected in [
        (None, 0.5, True),
        (1, 3.0, False),
        (0, 1.0 + 4 * rel[0], False),
        (0, 1.0 + 2 * rel[0], True),
    ]:
        m = 0.5 * loudest if k is None else np.where(np.arange(4) == k, factor * loudest, 0.5 * loudest)
        score.measured["t"] = m
        assert score.quieter("t", ensemble, sigma) is expected, (k, factor)
