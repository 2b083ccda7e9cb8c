"""Named only if explained: the guard that keeps a plant name off a cause outside the library.

When a residual is left above the noise floor, or when several effects share the gap (at the floor too: a
combination of small stand-ins can reproduce an unknown cause down to the noise), an accepted selection may
only stand in for what the library lacks (a position loop running at another cycle time projects onto the
inertia's signature in the band; a softer transmission onto the drive's gains, its cycle time and the guide's
inertia). It is named only if (1) each member is one value whatever the test: the data of each test alone,
regressed on the members' re-simulated sensitivities at the fitted model, agree with the values fitted on the
training tests (a stand-in absorbs a different share of the unknown cause at each frequency and kind of motion,
so its per-test estimates scatter), and a member's value does not move when a stand-in is taken out (then it
shared what the stand-in absorbed), and (2) together they remove at least half of the residual power above the
noise floor (full band, every test). Otherwise nothing is named and the members are reported as hints
(``unexplained.hints`` of diagnosis.json, report.md), never as names; the structure they absorbed is a residual
left (``structure_left``), whatever its RMS (workflow._named_only_if_explained).
"""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from .effects import BOUNDS, BY_PARAMETER, MEASUREMENT
from .stages import FD_STEP, Context, State, fitted_parameters, training_bic

#: a per-test estimate agrees with the fitted change if within this many of its standard deviations ...
Z_AGREE = 3.0
#: ... or within this fraction of the fitted change (the linearisation and the fit's tolerance)
REL_AGREE = 0.25
#: a test informs a parameter if it tells the fitted change from zero at this many standard deviations
INFORMATIVE = 2.0


def _columns(ctx: Context, state: State, params: Sequence[str]) -> dict[str, dict[str, np.ndarray]]:
    """d(observed torque)/d(parameter) on every test at the fitted model: exact for the measurement
    parameters, re-simulated (one step, all in one parallel batch) for the others."""
    model, pt, names = ctx.model, state.pt, ctx.names
    steps = {}
    for p in params:
        if p in MEASUREMENT:
            continue
        d = FD_STEP.get(p) or BY_PARAMETER[p].step or 1e-3 * max(abs(state.changes[p]), 1e-6)
        lo, hi = BOUNDS[p]
        steps[p] = d if lo <= state.changes[p] + d <= hi else -d
    model.sim.prefetch([{**state.changes, p: state.changes[p] + d} for p, d in steps.items()], names)
    cols = {}
    for p in params:
        if p in steps:
            pt1 = model.trial({**state.changes, p: state.changes[p] + steps[p]}, names, "consistency")
            cols[p] = (
                {n: (pt1.obs[n] - pt.obs[n]) / steps[p] for n in names}
                if pt1 is not None
                else {n: np.zeros_like(pt.obs[n]) for n in names}
            )
        else:
            cols[p] = model.columns(pt, names, p)
    return cols


def per_test_estimates(ctx: Context, state: State) -> dict:
    """For every parameter of the selection (phase-free effects aside: they are scored on all tests at once),
    the change each test alone asks for on top of the fitted value (in the band, all selected parameters
    together), with its standard deviation from that test's own residual (lag-1 inflated), and whether the
    tests that inform it agree."""
    params = [
        p
        for a in state.selected
        if not a.effect.phase_free
        for p in fitted_parameters(a, state.changes)
        if p in state.changes
    ]
    if not params:
        return {}
    cols = _columns(ctx, state, params)
    est: dict = {p: {} for p in params}
    for n in ctx.names:
        dt = ctx.model.tests[n].test.sample_time
        r = ctx.band.apply(ctx.model.tests[n].y - state.pt.obs[n], dt).ravel()
        A = np.column_stack([ctx.band.apply(cols[p][n], dt).ravel() for p in params])
        live = [k for k in range(len(params)) if float(A[:, k] @ A[:, k]) > 0]
        if not live:
            continue
        Al = A[:, live]
        coef, *_ = np.linalg.lstsq(Al, r, rcond=None)
        e = r - Al @ coef
        s2 = max(float(e @ e) / max(len(r) - len(live), 1), ctx.sigma_b**2)
        x = e - e.mean()
        rho1 = float(x[1:] @ x[:-1]) / float(x @ x) if float(x @ x) > 0 else 0.0
        inflate = (1 + rho1) / (1 - rho1) if 0.0 < rho1 < 0.99 else 1.0
        cov = s2 * inflate * np.linalg.pinv(Al.T @ Al)
        for i, k in enumerate(live):
            est[params[k]][n] = {"change": float(coef[i]), "std": float(math.sqrt(max(cov[i, i], 0.0)))}
    out = {}
    for p in params:
        fitted = float(state.changes[p]) - float(ctx.nominal[p])
        informative = {n: v for n, v in est[p].items() if v["std"] * INFORMATIVE < abs(fitted)}
        disagree = [
            n for n, v in informative.items() if abs(v["change"]) > max(Z_AGREE * v["std"], REL_AGREE * abs(fitted))
        ]
        out[p] = {
            "fitted_change": fitted,
            "per_test": est[p],
            "informative_tests": sorted(informative),
            "disagreeing_tests": disagree,
            "consistent": not disagree and len(informative) >= 2,
            "rule": f"two or more tests inform it (each alone tells the fitted change from zero at "
            f"{INFORMATIVE:g} std), and each one's own estimate is within max({Z_AGREE:g} std, "
            f"{REL_AGREE:.0%} of the fitted change) of the fitted value",
        }
    return out


def excess_explained(ctx: Context, before, after) -> float:
    """Share of the residual power above the noise floor (full band, every test) that the model ``after``
    removes from the model ``before``: 1 = down to the floor, 0 = nothing."""

    def excess(pt) -> float:
        return sum(
            float(np.sum((ctx.model.tests[n].y - pt.obs[n]) ** 2)) - ctx.sigma**2 * ctx.model.tests[n].y.size
            for n in ctx.names
        )

    e0 = excess(before)
    return 1.0 - max(excess(after), 0.0) / e0 if e0 > 0 else 1.0


#: with a residual left above the floor, the named effects must remove at least this share of the excess
EXPLAINED_SHARE = 0.5


def _moved(ctx: Context, before: State, after: State, checks: dict, keep: Sequence) -> dict[str, str]:
    """Members of ``keep`` whose fitted change from the nominal value moves, between the selection ``before``
    and its refit without the members taken out (``after``), by more than max(Z_AGREE std, REL_AGREE of the
    change): a value that depends on whether a stand-in is in the model shares what that stand-in absorbed
    (the std: the per-test estimates' combined, inverse-variance). {effect key: how far it moved}."""
    if not after.selected:
        return {}
    out = {}
    for a in keep:
        for p in fitted_parameters(a, before.changes):
            if p not in before.changes or p not in after.changes:
                continue
            c0 = float(before.changes[p]) - float(ctx.nominal[p])
            c1 = float(after.changes[p]) - float(ctx.nominal[p])
            w = [1.0 / v["std"] ** 2 for v in checks.get(p, {}).get("per_test", {}).values() if v["std"] > 0]
            std = 1.0 / math.sqrt(sum(w)) if w else 0.0
            if abs(c1 - c0) > max(Z_AGREE * std, REL_AGREE * abs(c0)):
                out[a.effect.key] = f"{c1 - c0:+.4g} ({p}: change {c0:+.4g} -> {c1:+.4g})"
    return out


def structure_left(ctx: Context, accepted: State, kept: State) -> float:
    """Training BIC (in the band) of the selection kept against the one the search accepted: DELTA_BIC or more
    means the data hold structure that the accepted selection reproduced and the kept one does not, i.e. what
    the members not named absorbed (a residual left, even where its RMS is within the floor factor)."""
    return training_bic(ctx, kept) - training_bic(ctx, accepted)


def needs_check(state: State, status: str, partner_removed: bool = False) -> bool:
    """Whether the accepted selection must pass the check before it is named: always when a residual is left
    above the floor; at the floor when several sample-by-sample effects share the gap (a cause outside the
    library can be reproduced to the floor by a combination of small stand-ins; one effect alone at the floor
    is what the held-out check already confirmed), or when what is left was fitted beside a member the folds
    did not confirm (``partner_removed``: the pair may have been stand-ins together, and the one left alone at
    the floor is not what the held-out check confirmed)."""
    members = [a for a in state.selected if not a.effect.phase_free]
    return bool(members) and (status == "unexplained residual" or len(members) >= 2 or partner_removed)


def only_consistent(ctx: Context, state: State, named: Sequence[dict], steps: list, nominal_pt) -> tuple[State, list]:
    """With a residual left above the noise floor, or several effects sharing the gap (``needs_check``), a member
    of the selection is named only if it cannot be a stand-in for a cause outside the library: two or more tests
    inform it and their per-test estimates agree (members that fail are taken out, the rest refitted; a member
    whose value then moves is taken out too; what is left is checked again), and what is kept removes at least
    EXPLAINED_SHARE of the residual power above the floor (else the gap is mostly the unknown cause, whose
    projection onto a signature is no evidence of an effect: nothing is named). Returns the state of what is
    named and the hints (the members not named, with their checks)."""

    from .stages import fit_state

    why: dict = {}
    checks: dict = {}  # every member's check, as it stood when it was kept or taken out
    kept = state
    while kept.selected:
        latest = per_test_estimates(ctx, kept)
        checks.update(latest)
        for p, c in latest.items():
            ctx.log(
                f"diagnose:   per-test {p}: fitted change {c['fitted_change']:+.4g}; "
                + ", ".join(f"{n} {v['change']:+.3g} (std {v['std']:.2g})" for n, v in c["per_test"].items())
                + (
                    ""
                    if c["consistent"]
                    else f": disagree on {', '.join(c['disagreeing_tests'])}"
                    if c["disagreeing_tests"]
                    else f": {len(c['informative_tests'])} test(s) inform it"
                )
            )
        bad = {
            a.effect.key: latest[p]
            for a in kept.selected
            for p in fitted_parameters(a, kept.changes)
            if p in latest and not latest[p]["consistent"]
        }
        if not bad:
            break
        why.update(
            {
                k: (
                    f"its per-test estimates disagree ({', '.join(c['disagreeing_tests'])}): a plant or drive "
                    "parameter is one value whatever the test"
                    if c["disagreeing_tests"]
                    else f"{'only one test tells' if c['informative_tests'] else 'no test alone tells'} it from "
                    "zero: its value cannot be checked across tests"
                )
                for k, c in bad.items()
            }
        )
        before, keep = kept, tuple(a for a in kept.selected if a.effect.key not in bad)
        while keep:
            kept = fit_state(ctx, keep, dict(before.changes)) or State((), {}, nominal_pt)
            moved = _moved(ctx, before, kept, latest, keep)
            if not moved:
                break
            why.update(
                {
                    k: f"its value moves by {m} when {', '.join(bad)} (not named) is taken out: it was fitted "
                    "together with a stand-in, and shares what that one absorbed"
                    for k, m in moved.items()
                }
            )
            keep = tuple(a for a in keep if a.effect.key not in moved)
        if not keep:
            kept = State((), {}, nominal_pt)
    share = excess_explained(ctx, nominal_pt, kept.pt)
    if kept.selected:
        ctx.log(
            f"diagnose:   the selection kept ({', '.join(a.label for a in kept.selected)}) removes "
            f"{100 * share:.0f} % of the residual power above the noise floor"
        )
    if kept.selected and share < EXPLAINED_SHARE:
        why.update(
            {
                a.effect.key: f"the selection kept ({', '.join(b.label for b in kept.selected)}) removes only "
                f"{100 * share:.0f} % of the residual power above the noise floor (< "
                f"{100 * EXPLAINED_SHARE:.0f} %): the gap is mostly a cause outside the library, "
                "which it may only stand in for"
                for a in kept.selected
            }
        )
        kept = State((), {}, nominal_pt)
    kept.info["consistency"] = {p: c for p, c in checks.items() if p in kept.changes}
    kept.info["excess_explained"] = share
    kept.info["structure_left"] = structure_left(ctx, state, kept)
    if not why:
        return kept, []
    hints = [
        {
            **e,
            "consistency": {p: checks[p] for p in e["parameters"] if p in checks},
            "excess_explained": share,
            "why_not_named": why[e["key"]],
        }
        for e in named
        if e["key"] in why
    ]
    steps.append(
        {
            "how": "named only if explained",
            "from": [a.label for a in state.selected],
            "to": [a.label for a in kept.selected],
            "accepted": True,
            "structure_left_delta_bic": kept.info["structure_left"],
            "note": "a residual is left above the noise floor, or several effects share the gap; not named: "
            + "; ".join(f"{k} ({w})" for k, w in why.items()),
        }
    )
    ctx.log(f"diagnose:   not named (hints only): {', '.join(why)}")
    return kept, hints
