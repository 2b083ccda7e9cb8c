"""Selection of effects: regression of the residual on the effect signatures in a frequency band, best
subset by BIC, each member needed on the training (BIC) and held-out data."""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field
from typing import Mapping, Optional, Sequence

import numpy as np

from .effects import LIBRARY, Effect, physical_bounds

#: a member of a selection must lower BIC by at least this much ("very strong" evidence)
DELTA_BIC = 10.0
#: ... and explain at least this fraction of the noise variance on the held-out tests
PRACTICAL = 0.05
#: ... and at least this fraction of the held-out residual left above the noise
RELATIVE = 0.1
#: ... and at least this share of the whole gap of the current model (above the noise): far from the data (the first
#: round, the nominal model) small terms that only soak up the linearisation error of the big ones wait; near it
#: (the gap left by the effects fitted) a small true effect (a millisecond delay) is not measured against the
#: nominal model's gap, which the effects already fitted have removed
SHARE_OF_GAP = 0.01
#: at most this many effects on one axis only in a subset (two worn axes at once, not a per-axis refit of all)
MAX_PER_AXIS = 2
#: the explanations ranked next behind the best that may challenge it (``rivals``)
RIVALS = 2


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
    coef: np.ndarray  # per atom, in parameter units (change of the first parameter)
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

    def decimation(self, dt: float) -> int:
        """Every how many samples ``apply`` keeps one."""
        return self._design(dt)[1]

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

    def __init__(
        self,
        atoms: Sequence[Atom],
        A_tr: np.ndarray,
        r_tr: np.ndarray,
        A_ho: np.ndarray,
        r_ho: np.ndarray,
        sigma: float,
        current: Optional[tuple[float, float]] = None,
    ) -> None:
        """``current``: the residual sum of squares (training, held-out) of the current model (the residual
        ``r_tr``, ``r_ho`` are taken back to the nominal model); the nominal model's if None."""
        self.atoms = list(atoms)
        scale = np.linalg.norm(A_tr, axis=0)
        scale[scale == 0] = 1.0
        self.scale = scale
        Atr, Aho = A_tr / scale, A_ho / scale
        self.G, self.g, self.rr = Atr.T @ Atr, Atr.T @ r_tr, float(r_tr @ r_tr)
        self.Gh, self.gh, self.rrh = Aho.T @ Aho, Aho.T @ r_ho, float(r_ho @ r_ho)
        self.n_tr, self.n_ho = len(r_tr), len(r_ho)
        self.sigma = sigma  # noise standard deviation in the band
        self.current = current if current is not None else (self.rr, self.rrh)
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
        noise = self.sigma**2 * self.n_ho
        return max(PRACTICAL * noise, RELATIVE * max(rss_ho_without - noise, 0.0))


def _in_bounds(effect: Effect, nominal: Mapping, change: float) -> bool:
    name = effect.parameter
    lo, hi = physical_bounds(name, nominal, effect.bounds[name])  # a records library's effects have their own
    value = float(nominal[name]) + change
    return lo - 1e-12 <= value <= hi + 1e-12


def _per_axis_excess(combo: Sequence[str]) -> bool:
    """More than MAX_PER_AXIS per-axis effects, or an all-axes effect with its per-axis versions on two axes
    (three values for three axes: the third axis's effect alone, which the plan may not be able to tell)."""
    per_axis = [k.rsplit("_axis", 1)[0] for k in combo if "_axis" in k]
    return len(per_axis) > MAX_PER_AXIS or any(k in combo and per_axis.count(k) >= 2 for k in set(per_axis))


def atom_labels(atoms: Sequence[Atom]) -> tuple[str, ...]:
    return tuple(sorted(a.effect.key for a in atoms))


def select(
    reg: Regression,
    nominal: Mapping,
    max_size: int,
    exclude: frozenset = frozenset(),
    library: Sequence[Effect] = LIBRARY,
) -> tuple[SubsetFit, list[SubsetFit]]:
    """The admissible subset with the lowest BIC (at most ``max_size`` effects, one per group).

    Admissible: every member is needed (removing it raises BIC by >= DELTA_BIC on the
    training tests and the held-out RSS by ``held_out_needed``) and every parameter stays
    within its bounds. Subsets in ``exclude`` (by effect keys) were refuted by re-simulation.
    ``library``: the effects the atoms come from (groups and preferred members).
    """
    by_key = {e.key: e for e in library}
    fits = []
    # each member must also carry a share of the current model's gap: far from the data (the first rounds)
    # small terms that only soak up the linearisation error of the big ones wait for the next round
    if reg.n_ho:
        floor_total = SHARE_OF_GAP * max(reg.current[1] - reg.sigma**2 * reg.n_ho, 0.0)
    else:
        floor_total = SHARE_OF_GAP * max(reg.current[0] - reg.sigma**2 * reg.n_tr, 0.0)
    by_effect: dict[str, list[int]] = {}
    for i, a in enumerate(reg.atoms):
        by_effect.setdefault(a.effect.key, []).append(i)
    keys = list(by_effect)
    for size in range(0, max_size + 1):
        for combo in itertools.combinations(keys, size):
            groups = [by_key[k].group for k in combo if by_key[k].group]
            if len(groups) != len(set(groups)) or tuple(sorted(combo)) in exclude or _per_axis_excess(combo):
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
                    rest = reg.fit(idx[:m] + idx[m + 1 :])
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
    best = _preferred(reg, min(admissible, key=reg.score), admissible, library) if admissible else reg.fit(())
    return best, fits


def _preferred(
    reg: Regression, fit: SubsetFit, admissible: Sequence[SubsetFit], library: Sequence[Effect]
) -> SubsetFit:
    """Alternatives of a group (inertia on either side of the transmission): the preferred member is proposed
    whenever it is admissible; the alias check decides between them by re-simulation (in the band their
    linearised columns differ by how far the secant of each extrapolates, not by physics)."""
    for a in list(fit.atoms):
        if a.effect.group and not a.effect.preferred:
            pref = [e for e in library if e.group == a.effect.group and e.preferred][0]
            want = {x.effect.key for x in fit.atoms if x is not a} | {pref.key}
            cand = [f for f in admissible if {x.effect.key for x in f.atoms} == want]
            if cand:
                fit = min(cand, key=reg.score)
    return fit


def rivals(reg: Regression, best: SubsetFit, fits: Sequence[SubsetFit], library: Sequence[Effect] = LIBRARY) -> list:
    """The RIVALS admissible explanations ranked next behind ``best`` by score (one per set of effects up to the
    alternatives of a group, which the alias check separates), for ``held_out_prefers``."""
    if not reg.n_ho:
        return []
    by_key = {e.key: e for e in library}

    def explanation(fit: SubsetFit) -> frozenset:
        return frozenset(by_key[a.effect.key].group or a.effect.key for a in fit.atoms)

    admissible = sorted((f for f in fits if f.admissible), key=reg.score)
    seen, out = {explanation(best)}, []
    for fit in admissible:
        if len(out) == RIVALS:
            break
        if explanation(fit) not in seen:
            seen.add(explanation(fit))
            out.append(_preferred(reg, fit, admissible, library))
    return out


def held_out_prefers(reg: Regression, rival: SubsetFit, fit: SubsetFit) -> bool:
    """Whether the held-out tests rank ``rival`` above ``fit``, which the score ranks first: its predicted
    held-out RSS is lower by what an effect must remove there (``held_out_needed``). Far from the data (a
    nominal model 40-60 % off) the linearisation can let stand-ins fit the training tests better than the true
    effects while predicting the held-out tests worse; the linear ranking cannot settle that, re-simulation can
    (stages.regression_loop fits both)."""
    return bool(reg.n_ho) and rival.rss_ho < fit.rss_ho - reg.held_out_needed(fit.rss_ho)
