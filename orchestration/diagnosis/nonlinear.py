"""Effects fitted by re-simulation only: Stribeck friction (sample by sample, started from a grid) and
backlash, which makes the loop hunt (on the phase-free score of phasefree.py)."""

from __future__ import annotations

import math
from typing import Callable, Mapping, Optional, Sequence

import numpy as np

from .effects import Effect
from .phasefree import ENSEMBLE, GRID_REALISATIONS, POOL_RATIO, Fit, PhaseFreeScore, estimate, pooled, search
from .resimulation import Point
from .selection import DELTA_BIC, Atom, atom_labels
from .stages import (
    FLOOR_FACTOR,
    Context,
    State,
    band_rss,
    failed_step,
    fit_state,
    residual_at_floor,
    training_bic,
    verify,
)

#: the phase-free value: the minimum of a parabola through the smoothed deviances on the fine grid within this
#: ratio of the best one (phasefree.search)
PARABOLA_SPAN = 2.0**0.25
#: a phase-free effect is named present with its value "not determined on this plan" (and left out of the augmented
#: model) when its 95 % interval reaches beyond this ratio either side (the deviance has no curvature there: the
#: parabola fell back to the grid's best value). A test in a quieter regime of the hunting than the re-simulations
#: (not reproduced, quieter in every band) does not decide it: the record is one realisation of a chaotic process as
#: each re-simulation is, and which regime it fell into depends on the commands' last bits (issue 24); the value is
#: fitted on the other tests and its interval is theirs
DETERMINED_RATIO = 1.25


def nonlinear_stage(
    ctx: Context, state: State, effects: Sequence[Effect], rejected: set, steps: list
) -> Optional[State]:
    """Effects whose signature does not linearise (Stribeck friction, the drive's current limit): fitted and
    scored by re-simulation, each tried only where the residual shows its trace (``GATES``)."""
    best: Optional[State] = None
    best_bic = math.inf
    tried = []
    for e in effects:
        shows, why = GATES[e.key](ctx, state.pt)
        if shows:
            tried.append(e)
            continue
        steps.append(
            {
                "how": "re-simulation candidates",
                "from": [a.label for a in state.selected],
                "to": [e.key],
                "accepted": False,
                "note": f"not tried: {why}",
            }
        )
        ctx.log(f"diagnose: {e.title} not tried: {why}")
    effects = tried
    for e in effects:
        if any(a.effect.key == e.key for a in state.selected):
            continue
        labels = atom_labels(tuple(state.selected) + (Atom(e),))
        if labels in rejected or ("refuted", e.key) in rejected:
            continue
        start = dict(state.changes)
        start.update(_nonlinear_start(ctx, state, e))
        atom = Atom(e, start.get("omega_s") if e.key == "stribeck" else None)
        ctx.log(
            f"diagnose: trying {e.title} by re-simulation (start "
            f"{', '.join(f'{p} = {start[p]:.3g}' for p in e.parameters)})"
        )
        cand = fit_state(ctx, tuple(state.selected) + (atom,), start, anchor=state.changes)
        if cand is None:
            failed_step(ctx, state, tuple(state.selected) + (atom,), steps, "re-simulation")
        if cand is not None and verify(ctx, state, cand, steps, "re-simulation"):
            bic = training_bic(ctx, cand)
            if bic < best_bic:
                best, best_bic = cand, bic
            if residual_at_floor(ctx, cand.pt):
                break  # explained: no need to try the others
        else:
            rejected.add(labels)
            rejected.add(("refuted", e.key))
    return best


#: start grids of the nonlinear effects (the Stribeck cost has a narrow curved valley in omega_s)
START_GRIDS = {
    "stribeck": [
        {"tau_s": ts, "omega_s": ws} for ts in (0.012, 0.03) for ws in (1.0, 1.3, 1.7, 2.2, 2.9, 3.7, 4.8, 6.3, 8.2)
    ],
}


#: Stribeck friction is tried when the residual concentrates at velocity reversals this much
REVERSAL_GATE = 2.0
#: the current limit is tried when the model's torque peak exceeds the data's by this many noise deviations
CLIP_GATE = 5.0


def _reversal_gate(ctx: Context, pt: Point) -> tuple[bool, str]:
    where = _reversal_concentration(ctx, pt)
    return where >= REVERSAL_GATE, (
        f"the residual does not concentrate at velocity reversals ({where:.2f} x its "
        f"share of time < {REVERSAL_GATE:g}), where it acts"
    )


def _peaks(ctx: Context, pt: Point) -> tuple[float, float]:
    """The largest |torque| over every test and axis, measured (99.9th percentile: robust to the noise's
    extremes) and simulated."""
    y = np.concatenate([np.abs(ctx.model.tests[n].y).ravel() for n in ctx.names])
    yh = np.concatenate([np.abs(pt.obs[n]).ravel() for n in ctx.names])
    return float(np.percentile(y, 99.9)), float(yh.max())


def _clip_gate(ctx: Context, pt: Point) -> tuple[bool, str]:
    measured, model = _peaks(ctx, pt)
    return model - measured >= CLIP_GATE * ctx.sigma, (
        f"the model's torque peak ({model:.4g} N.m) does not exceed the data's ({measured:.4g} N.m) by "
        f"{CLIP_GATE:g} noise deviations: nothing is clipped"
    )


def _stand_in_gate(ctx: Context, pt: Point) -> tuple[bool, str]:
    """The transmission stiffness is offered only once stand-ins were refused (workflow): its trace in the band is
    the one gains, cycle times and inertia mimic, so nothing cheaper tells it."""
    return True, ""


GATES = {"stribeck": _reversal_gate, "current_limit": _clip_gate, "stiffness": _stand_in_gate}


def _reversal_concentration(ctx: Context, pt: Point) -> float:
    """Largest concentration of the residual near velocity reversals (energy share / time share) over
    the tests whose residual is above the noise floor (0 if none is)."""
    best = 0.0
    for n in ctx.names:
        r = ctx.model.tests[n].y - pt.obs[n]
        if float(np.sqrt(np.mean(r**2))) <= FLOOR_FACTOR * ctx.sigma:
            continue
        omega = ctx.model.signals(pt, n)[0]
        mask = np.abs(omega) < 0.15 * np.abs(omega).max(axis=0)
        if mask.any():
            best = max(best, float((r[mask] ** 2).sum() / (r**2).sum()) / float(mask.mean()))
    return best


def log_scan(
    cost: Callable[[Sequence[float]], Sequence[float]],
    start: float,
    octaves: Sequence[float],
    per_octave: int,
    halvings: int,
    bounds: tuple[float, float],
) -> float:
    """The best value of a positive parameter, searched in ln: the coarse grid ``start * 2**k`` (k in
    ``octaves``); around its best value, a fine grid of ``per_octave`` values per octave, one octave either side
    (to its neighbours on a grid of octaves); then, around the best value so far, ``halvings`` times the two values
    half the last step either side, moving to whichever is lower. Values beyond ``bounds`` are left out. The fine
    grid finds a minimum narrower than the coarse grid's step among shallower ones (the transmission stiffness's
    dip, +-2 % wide, issue 27), where a descent from the coarse grid's best stalls. ``cost`` takes a batch of
    values (simulated together) and returns one cost per value (inf where the simulation failed)."""
    lo, hi = bounds

    def best_of(values: list[float], best: float, best_cost: float) -> tuple[float, float]:
        values = [v for v in values if lo <= v <= hi]
        for v, c in zip(values, cost(values)):
            if c < best_cost:
                best, best_cost = v, c
        return best, best_cost

    best, best_cost = best_of([start * 2.0**k for k in octaves], math.nan, math.inf)
    if math.isnan(best):
        return min(max(start, lo), hi)
    fine = [best * 2.0 ** (j / per_octave) for j in range(-per_octave, per_octave + 1) if j]
    best, best_cost = best_of(fine, best, best_cost)
    step = 1.0 / per_octave
    for _ in range(halvings):
        step /= 2.0
        best, best_cost = best_of([best * 2.0**-step, best * 2.0**step], best, best_cost)
    return best


#: the transmission stiffness's start: octaves of its current value (1/K_t, not K_t, is what the loop feels), the
#: octave either side of the best on a fine grid (2.2 %), then two halvings of its step (0.5 %), scored on the full
#: band of every training test (``_full_rss``). Its signature is the transmission mode (about 200 Hz at K_t 5 N m/rad),
#: which rings for the whole record: the full-band RSS has a dip +-2 % wide at the true K_t, where the mode's phase
#: matches the data's, among shallower ones; in the band (< 40 Hz) the cost is a rugged plateau whose lowest point is
#: elsewhere (K_t 4.62 for a truth of 5, SMALL seed 203; issue 27, docs/diagnose.md)
STIFFNESS_OCTAVES = (1, -1, -2, -3, -4, -5)
STIFFNESS_PER_OCTAVE = 32
STIFFNESS_HALVINGS = 2


def _full_rss(ctx: Context, pt: Point, names: Sequence[str]) -> float:
    """The RSS of the torque on the tests ``names``, over the full band (every sample, unfiltered)."""
    return sum(float(np.sum((ctx.model.tests[n].y - pt.obs[n]) ** 2)) for n in names)


def _nonlinear_start(ctx: Context, state: State, e: Effect) -> dict:
    """A start for the fit. The current limit: the data's torque peak over the motor constant (where the
    drive limits the current, the torque stays at k_T i_max). The transmission stiffness: a refined log scan
    (log_scan) of the full-band RSS of every training test (its mode rings above the band). Stribeck friction:
    the best point of a grid, each simulated on the lowest-frequency training test (the one friction dominates),
    all in one parallel batch."""
    if e.key == "current_limit":
        return {"i_max": _peaks(ctx, state.pt)[0] / float(ctx.nominal["k_T"])}
    if e.key == "stiffness":
        k0 = float(state.changes.get("K_t", ctx.nominal["K_t"]))
        scan = log_scan(
            lambda values: _grid_costs(
                ctx,
                state,
                [{"K_t": v} for v in values],
                list(ctx.train),
                e.key,
                lambda pt, names: _full_rss(ctx, pt, names),
            ),
            k0,
            STIFFNESS_OCTAVES,
            STIFFNESS_PER_OCTAVE,
            STIFFNESS_HALVINGS,
            e.bounds["K_t"],
        )
        return {"K_t": scan}
    grid = START_GRIDS[e.key]
    probe = [min(ctx.train, key=lambda n: (ctx.model.tests[n].test.frequency or 0.0, n))]
    costs = _grid_costs(ctx, state, grid, probe, e.key, lambda pt, names: band_rss(ctx, pt, names)[0])
    return grid[min(range(len(grid)), key=lambda j: costs[j])]


def _grid_costs(
    ctx: Context,
    state: State,
    grid: Sequence[Mapping],
    probe: Sequence[str],
    key: str,
    rss: Callable[[Point, Sequence[str]], float],
) -> list[float]:
    """``rss`` on the tests ``probe`` of the current model changed by each point of ``grid``, all simulated in one
    parallel batch (inf where a simulation failed)."""
    ctx.model.sim.prefetch([{**state.changes, **g} for g in grid], probe)
    costs = []
    for g in grid:
        pt = ctx.model.trial({**state.changes, **g}, probe, f"{key} start grid")
        costs.append(math.inf if pt is None else rss(pt, probe))
    return costs


def phase_free_stage(ctx: Context, state: State, effect: Effect, steps: list) -> State:
    """An effect that makes the loop hunt (backlash), on the phase-free score (phasefree.py).

    Every value is an ensemble of re-simulations of every test. Selection, independent of which tests
    the split holds out (the hunting shows only on some tests, often the fastest ones of one kind of
    motion): the best value of the effect's scan on all tests must lower their BIC (deviance plus
    ln(statistics) per parameter) by DELTA_BIC, and leave-one-test-out must confirm it: every test in
    turn is predicted at the scan value best on the others, and these predictions' deviances must sum to
    DELTA_BIC below the current model's. The scan already simulates every test, so the cross-validation
    costs no simulation. The value: on the tests that agree (all, unless a test predicted at the scan value
    best on the others fits worse than without the effect: a record in a regime of the hunting the ensembles
    near the others' value do not visit), the minimum of the smoothed deviance (the ensembles of the values
    within a few percent pooled, phasefree.pooled) by a grid search around their best scan value
    (phasefree.search), then a parabola. It is named only if with it every test's score is at the floor: the
    hunting's band powers can stand in for part of almost any excess (a position ripple, say), so the
    effect must explain all of what is left (this also refuses a value that leaves any test, made worse
    or not, above its floor). The one exception: a test that stays above its floor with less power in every
    band than the loudest re-simulation (a quieter regime, never a cause the effect does not make) is taken
    out of the value's fit (the value searched again on the others, which must keep a test the effect is
    needed for) and reported as not reproduced; it does not change the verdict, since which regime a record
    falls into depends on its commands' last bits, not on the value. Where the smoothed deviance has no
    curvature (95 % interval wider than DETERMINED_RATIO either side) the effect is named present, its value
    "not determined on this plan", and it is left out of the augmented model (report.write_model).
    """
    model, p = ctx.model, effect.parameter
    try:
        score = PhaseFreeScore(
            {n: model.tests[n].y for n in ctx.names},
            state.pt.obs,
            {n: model.tests[n].test.sample_time for n in ctx.names},
            ctx.sigma,
        )
    except ValueError as err:  # sampled too slowly for the bands
        steps.append(
            {
                "how": "phase-free score",
                "from": [a.label for a in state.selected],
                "to": [a.label for a in state.selected] + [effect.key],
                "accepted": False,
                "note": f"not tried: {err}",
            }
        )
        ctx.log(f"diagnose: {effect.title} not tried: {err}")
        return state
    ensembles: dict[float, Optional[dict]] = {}
    current = float(state.changes.get(p, ctx.nominal[p]))

    def changes(v: float) -> dict:  # the current model as it is (its simulations are cached)
        return dict(state.changes) if v == current else {**state.changes, p: v}

    def simulate(values: Sequence[float], realisations: int = ENSEMBLE) -> None:
        new = [v for v in values if not any(abs(v - u) <= 1e-9 * abs(u) for u in ensembles)]
        model.sim.prefetch([changes(v) for v in new], ctx.names, range(realisations))
        for v in new:
            pts = [
                model.trial(changes(v), [n], f"{effect.key} phase-free ensemble", r)
                for n in ctx.names
                for r in range(realisations)
            ]
            ensembles[v] = (
                None
                if any(q is None for q in pts)
                else {
                    n: np.array([score.powers(n, pts[k * realisations + r].obs[n]) for r in range(realisations)])
                    for k, n in enumerate(ctx.names)
                }
            )

    def deviance(v: float, names: Sequence[str]) -> float:
        return score.fit(ensembles[v], names).deviance if ensembles[v] is not None else math.inf

    ctx.log(
        f"diagnose: trying {effect.title} on the phase-free score ({len(effect.scan)} values x {ENSEMBLE} "
        f"realisations of every test)"
    )
    simulate([current, *effect.scan])
    scan_all = {v: deviance(v, ctx.names) for v in effect.scan}
    v_all = min(scan_all, key=scan_all.get)
    if ensembles[current] is None or not math.isfinite(scan_all[v_all]):
        steps.append(
            {
                "how": "phase-free score",
                "from": [a.label for a in state.selected],
                "to": [a.label for a in state.selected] + [effect.key],
                "accepted": False,
                "note": "not tried: every simulation of its scan failed (see failed_simulations)",
            }
        )
        ctx.log(f"diagnose: {effect.title} not tried: every simulation of its scan failed")
        return state
    before_all = score.fit(ensembles[current], ctx.names)
    dbic = scan_all[v_all] - before_all.deviance + effect.cost * math.log(score.statistics(ctx.names))
    folds = leave_one_out(score, ensembles, current, effect.scan, ctx.names)
    dcv = sum(f["deviance_change"] for f in folds.values())
    ok = dbic <= -DELTA_BIC and dcv <= -DELTA_BIC
    labels = [a.label for a in state.selected]
    steps.append(
        {
            "how": "phase-free score",
            "from": labels,
            "to": labels + [effect.key],
            "parameters": {p: v_all},
            "delta_bic": dbic,
            "cross_validated_deviance_change": dcv,
            "leave_one_out": folds,
            "accepted": bool(ok),
            "note": "the best value of the scan on all tests, band powers of the residual against ensembles of "
            "re-simulations; leave-one-test-out: each test predicted at the scan value best on the "
            "others"
            + ("" if ok else f": refused (dBIC and cross-validated deviance change must be <= -{DELTA_BIC:g})"),
        }
    )
    ctx.log(
        f"diagnose:   {effect.key} = {v_all:.3g} (scan, all tests): phase-free dBIC {dbic:+.0f}, leave-one-test-out "
        f"deviance {dcv:+.0f} ("
        + ", ".join(f"{n} {f['deviance_change']:+.0f} at {f['value']:.3g}" for n, f in folds.items())
        + ")"
        + (": confirmed" if ok else ": refused")
    )
    if not ok:
        return state
    # the tests that disagree: each predicted at the scan value best on the others fits worse than without the effect.
    # Such a test's record is in a regime of the hunting the ensembles near the others' value do not visit (on short
    # records the hunting has regimes a few percent of the realisations fall into: the axes hunting in step, a
    # quieter torque); its mixture likelihood is then decided by whichever value's pooled window happens to hold such
    # a member, not by the value. The value is fitted on the tests that agree (two or more), the others are checked
    # at it; a fitted test left above its floor and quieter than every re-simulation is such a test too: it leaves
    # the fit (the worst first) and the value is searched again (the grids' simulations are reused).
    disagree = [n for n, f in folds.items() if f["deviance_change"] > DELTA_BIC]
    fitted = [n for n in ctx.names if n not in disagree]
    if len(fitted) < 2:
        fitted = list(ctx.names)
    before = score.fit(ensembles[current], ctx.names)
    floors = {n: score.floor(n) for n in ctx.names}
    while True:
        on_tests = list(fitted)
        start = min(effect.scan, key=lambda v: deviance(v, on_tests)) if on_tests != list(ctx.names) else v_all

        def smoothed(v: float, ratio: float, on_tests: list[str] = on_tests) -> float:
            ensemble = pooled(ensembles, v, ratio)
            return score.fit(ensemble, on_tests).deviance if ensemble is not None else math.inf

        mid, points = search(lambda values: simulate(values, GRID_REALISATIONS), smoothed, start, effect.bounds[p])
        value, s_log = estimate(points, PARABOLA_SPAN)
        if smoothed(value, POOL_RATIO) > min(points.values()):
            # the parabola's minimum fits worse than a value of the grid (its window pools other values): that value
            value = min(points, key=points.get)
        ensemble = pooled(ensembles, value, POOL_RATIO)
        if ensemble is None:
            steps.append(
                {
                    "how": "phase-free score: value on all tests",
                    "from": labels,
                    "to": labels + [effect.key],
                    "accepted": False,
                    "profile": {v: points[v] for v in sorted(points)},
                    "note": "not named: the simulations around its best value failed (see failed_simulations)",
                }
            )
            ctx.log(f"diagnose:   {effect.key}: the simulations around its best value failed, not named")
            return state
        final = score.fit(ensemble, fitted)
        per_test = {**score.deviances(ensemble, ctx.names, final.sigma), **final.per_test}

        def quieter_regime(n: str, ensemble: Mapping[str, np.ndarray] = ensemble, final: Fit = final) -> bool:
            """Test n's record shows the effect (above its floor without it) but hunts less than every realisation
            with it, in every band: a regime of the hunting the ensemble did not visit. A record with no trace of
            it, or with more power in a band than the effect makes, is evidence against the effect."""
            return before.per_test[n] > floors[n] and score.quieter(n, ensemble[n], final.sigma)

        quiet = [n for n in sorted(fitted, key=lambda m: -per_test[m]) if per_test[n] > floors[n] and quieter_regime(n)]
        # the tests left must hold one the effect is needed for (above its floor without it), and one more
        rest = [n for n in fitted if not quiet or n != quiet[0]]
        if not quiet or len(rest) < 2 or not any(before.per_test[n] > floors[n] for n in rest):
            break
        ctx.log(
            f"diagnose:   {effect.key} = {value:.4g}: {quiet[0]} stays above its floor ({per_test[quiet[0]]:.0f}) "
            "with less power than the re-simulations: fitted again without it"
        )
        fitted = rest
    # a test outside the fit at the floor with the value agrees after all (its disagreement was the scan's coarse
    # grid); one above it is not reproduced, which only a quieter regime of the hunting may explain
    unreproduced = [n for n in ctx.names if n not in fitted and per_test[n] > floors[n]]
    unlike = [n for n in unreproduced if not quieter_regime(n)]
    above = [n for n in fitted if per_test[n] > floors[n]] + unlike
    realisations = len(next(iter(ensemble.values())))
    on = "all tests" if fitted == list(ctx.names) else ", ".join(fitted)
    steps.append(
        {
            "how": "phase-free score: value on all tests",
            "from": labels,
            "to": labels + [effect.key],
            "parameters": {p: value},
            "delta_bic": dbic,
            "deviance_per_test": per_test,
            "fitted_on": fitted,
            "floor_per_test": floors,
            "profile": {v: points[v] for v in sorted(points)},
            "profile_mid_grid": {v: mid[v] for v in sorted(mid)},
            "accepted": not above,
            "note": (
                "every test's band powers at the floor with it"
                if not above and not unreproduced
                else f"the band powers of the tests it is fitted on at the floor with it; {', '.join(unreproduced)} "
                f"in a quieter regime of the hunting than its {realisations} re-simulations"
                if not above
                else f"not named: with it the band powers of {', '.join(above)} stay above the floor "
                + (
                    "(it would explain only part of the residual)"
                    if not unlike
                    else f"({', '.join(unlike)}: more power in a band than every re-simulation with it, or no "
                    "trace of the effect at all: at its floor without it)"
                )
            ),
        }
    )
    ctx.log(
        f"diagnose:   {effect.key} = {value:.4g} on {on} (deviance per test "
        + ", ".join(f"{n} {d:.1f}" for n, d in per_test.items())
        + ")"
        + (f": above the floor on {', '.join(above)}, not named" if above else ": named")
    )
    if above:
        return state
    why_not = (
        [f"95 % interval {value * math.exp(-1.96 * s_log):.3g} to {value * math.exp(1.96 * s_log):.3g}"]
        if 1.96 * s_log > math.log(DETERMINED_RATIO)
        else []
    )
    quieter = [
        f"{n} is in a regime of the hunting that none of the {realisations} re-simulations within "
        f"{100 * (POOL_RATIO - 1):.0f} % of the value visits (deviance {per_test[n]:.0f} > {floors[n]:.1f}, with "
        f"less power in every band than the loudest of them): one realisation of the hunting, not fitted; the "
        f"value is fitted on {on}"
        for n in unreproduced
    ]
    if quieter:
        ctx.log(f"diagnose:   {effect.key}: {'; '.join(quieter)}")
    if why_not:
        ctx.log(
            f"diagnose:   {effect.key}: present, its value is not determined on this plan (not written into the "
            f"augmented model): {'; '.join(why_not)}"
        )
    nf = {n: score.bands[n].noise_fraction for n in ctx.names}
    info = {
        **state.info,
        "phase_free": {
            "parameter": p,
            "value": value,
            "std": value * s_log,
            "value_determined": not why_not,
            "value_not_determined_because": why_not,
            "fitted_on": fitted,
            "not_reproduced": unreproduced,
            "not_reproduced_because": quieter,
            "ci95": [value * math.exp(-1.96 * s_log), value * math.exp(1.96 * s_log)],
            "scan_value": v_all,
            "delta_bic": dbic,
            "cross_validated_deviance_change": dcv,
            "leave_one_out": folds,
            "deviance_per_test": {"before": before.per_test, "after": per_test},
            "floor_per_test": floors,
            "noise_std_Nm": final.sigma,
            "bands_Hz": {n: score.bands[n].bands for n in ctx.names},
            "ensemble": ENSEMBLE,
            "pooled_realisations": realisations,
            "pool_ratio": POOL_RATIO,
            "band_powers_Nm_squared": {
                n: {
                    "measured": score.measured[n].tolist(),
                    "with": (ensemble[n].mean(axis=0) + final.sigma**2 * nf[n]).tolist(),
                    "without": (ensembles[current][n].mean(axis=0) + before.sigma**2 * nf[n]).tolist(),
                }
                for n in ctx.names
            },
            "profile": {v: points[v] for v in sorted(points)},
            "profile_mid_grid": {v: mid[v] for v in sorted(mid)},
        },
    }
    pt = model.trial(changes(value), ctx.names, f"{effect.key} value on every test")
    if pt is None:
        return state
    return State(tuple(state.selected) + (Atom(effect),), changes(value), pt, info)


def leave_one_out(
    score: PhaseFreeScore,
    ensembles: Mapping[float, Optional[dict]],
    current: float,
    scan: Sequence[float],
    names: Sequence[str],
) -> dict[str, dict]:
    """Every test predicted at the scan value best on the other tests: that value, and the test's deviance
    change against the current model (negative: the prediction fits it better). A test alone (no others)
    is predicted at the best value on itself."""
    valid = [v for v in scan if ensembles[v] is not None]
    out = {}
    for n in names:
        others = [m for m in names if m != n] or [n]
        v = min(valid, key=lambda u: score.fit(ensembles[u], others).deviance)
        change = score.fit(ensembles[v], [n]).deviance - score.fit(ensembles[current], [n]).deviance
        out[n] = {"value": v, "deviance_change": change}
    return out
