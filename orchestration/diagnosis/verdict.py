"""What the diagnosis concludes: the gap per test before and after, the named effects with their
uncertainty and evidence, and the verdict (nothing missing, explained, or an unexplained residual)."""

from __future__ import annotations

import math
from typing import Mapping, Optional, Sequence

import numpy as np

from .effects import BOUNDS, BY_KEY, BY_PARAMETER, LIBRARY, frequency_slope, localise, nrmse
from .resimulation import Model, Point, Prepared
from .selection import DELTA_BIC, Atom, Regression, SubsetFit
from .stages import FD_STEP, FLOOR_FACTOR, Context, State


def gap_table(
    prepared: Mapping[str, Prepared], pt: Point, names: Sequence[str], sigma: float, resolution: float
) -> dict:
    out = {}
    for n in names:
        p = prepared[n]
        y, yh = p.y, pt.obs[n]
        den = float(np.linalg.norm(y - y.mean(axis=0)))
        g = nrmse(y, yh)
        e_den = float(np.linalg.norm(p.e - p.e.mean(axis=0)))
        ge = nrmse(p.e, pt.err[n])
        out[n] = {
            "torque_nrmse_percent": 100 * g,
            "torque_fit_percent": 100 * (1 - g),
            "torque_rms_Nm": float(np.sqrt(np.mean((y - yh) ** 2))),
            "torque_floor_percent": 100 * sigma * math.sqrt(y.size) / den if den > 0 else None,
            "tracking_error_nrmse_percent": 100 * ge,
            "tracking_error_fit_percent": 100 * (1 - ge),
            "tracking_error_floor_percent": (
                100 * resolution / math.sqrt(12) * math.sqrt(p.e.size) / e_den if resolution and e_den > 0 else None
            ),
        }
    return out


def localise_test(model: Model, pt: Point, prep: Prepared, sigma: float) -> dict:
    omega, acc, _ = model.signals(pt, prep.name)
    return localise(prep.t, prep.y - pt.obs[prep.name], omega, acc, prep.test.frequency, sigma)


def gap_trend(prepared, before, after, names) -> dict:
    """Residual amplitude at the test frequency against frequency, per motion."""
    out = {}
    for motion in sorted({prepared[n].test.motion for n in names if prepared[n].test.frequency}):
        ns = sorted(
            [n for n in names if prepared[n].test.motion == motion and prepared[n].test.frequency],
            key=lambda n: prepared[n].test.frequency,
        )
        f = [prepared[n].test.frequency for n in ns]
        b = [before[n].get("harmonic_1") for n in ns]
        a = [after[n].get("harmonic_1") for n in ns]
        slope = frequency_slope(f, b)
        words = None
        if slope is not None:
            words = (
                (
                    "flat in frequency"
                    if abs(slope) < 0.5
                    else "grows with f"
                    if slope < 1.5
                    else "grows with f^2"
                    if slope < 2.5
                    else "grows faster than f^2"
                )
                if slope > -0.5
                else "falls with frequency"
            )
        out[motion] = {
            "frequencies_Hz": f,
            "residual_h1_before_Nm": b,
            "residual_h1_after_Nm": a,
            "log_slope_before": slope,
            "reading": words,
        }
    return out


def named_effects(ctx: Context, state: State, last_fit, steps: list) -> list:
    if not state.selected:
        return []
    model, names, nominal, pt = ctx.model, ctx.train, ctx.nominal, state.pt
    # the phase-free effects' uncertainty comes from their score (phasefree.estimate)
    # discrete parameters (cycle times) have a grid, not a covariance: their neighbours were simulated and refuted
    free = [
        p for p in state.changes if not (p in BY_PARAMETER and (BY_PARAMETER[p].phase_free or BY_PARAMETER[p].quantum))
    ]
    y = np.concatenate([model.tests[n].y.ravel() for n in names])
    r = y - np.concatenate([pt.obs[n].ravel() for n in names])
    cols = []
    for p in free:
        if p in FD_STEP:
            d = FD_STEP[p] if state.changes[p] + FD_STEP[p] <= BOUNDS[p][1] else -FD_STEP[p]
            pt1 = model.trial({**state.changes, p: state.changes[p] + d}, names, "uncertainty")
            if pt1 is None and BOUNDS[p][0] <= state.changes[p] - d:
                d = -d
                pt1 = model.trial({**state.changes, p: state.changes[p] + d}, names, "uncertainty")
            if pt1 is None:
                c = model.columns(pt, names, p)
                cols.append(np.concatenate([c[n].ravel() for n in names]))
                continue
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
        delay = e.parameter.replace("T_meas", "delay_meas")
        if e.parameter.startswith("T_meas") and delay in state.changes:  # the lag is a delay
            params = {delay: state.changes[delay]}
        added = next(
            (
                st
                for st in steps
                if st.get("accepted")
                and ("delta_bic_training" in st or "delta_bic" in st)
                and a.label in st["to"]
                and a.label not in st["from"]
            ),
            None,
        )
        ev: dict = {"signature": e.signature}
        if added and e.phase_free:
            ev["when_added"] = {
                "how": added["how"],
                "delta_bic": added["delta_bic"],
                "held_out_rss_change_percent": None,
                "cross_validated_deviance_change": added["cross_validated_deviance_change"],
                "note": "phase-free score: band powers of the residual against ensembles of "
                "re-simulations, the model before and after adding it, on all tests; "
                "leave-one-test-out for the cross-validated change",
            }
            ev["phase_free"] = state.info["phase_free"]
        elif added:
            ev["when_added"] = {
                "how": added["how"],
                "delta_bic_training": added["delta_bic_training"],
                "held_out_rss_change_percent": added["held_out_rss_change_percent"],
                "note": f"re-simulated: the model before and after adding it (band below {ctx.band.fc:g} Hz)",
            }
        ev.update(_evidence(reg, best, a))
        decided = [st for st in steps if st["how"] == "delay or filter" and st["effect"] == e.key]
        if decided:  # stages.lag_form_check: both forms fitted by re-simulation
            ev["filter_or_delay"] = decided[-1]
        elif e.parameter.startswith("T_meas") and e.key in state.info:
            ev["filter_or_delay"] = state.info[e.key]
        if e.group:
            ev["alternatives"] = _alternatives(reg, best, a, nominal) + [
                {
                    "effect": BY_KEY[x["effect"]].title,
                    "parameters": x["parameters"],
                    "delta_bic_full_band": x["delta_bic_full_band"],
                    "delta_bic_band": x["delta_bic_band"],
                    "how": "re-simulated alternative (fitted)",
                    "separable": bool(abs(x["delta_bic_full_band"]) >= DELTA_BIC),
                    "note": (
                        "the data prefer the named side"
                        if x["delta_bic_full_band"] >= DELTA_BIC
                        else "the data cannot tell the two apart: the preferred side is named"
                    ),
                }
                for x in state.info.get("alias", [])
            ]
        if added and e.phase_free:
            ev["held_out_evidence"] = {
                "tests": list(added.get("leave_one_out") or {}),
                "how": "leave-one-test-out: each test predicted at the value best on the others",
            }
        elif added:  # the held-out tests that checked it when it was added, and how their residual changed
            ev["held_out_evidence"] = {
                "tests": list(added.get("held_out_rss_change_percent_per_test") or {}),
                "rss_change_percent_per_test": added.get("held_out_rss_change_percent_per_test"),
                "how": "fitted on the training tests, predicted on the held-out tests of the "
                "split (diagnosis.json: split), in the band",
            }
        form = {}
        if "filter_or_delay" in ev and "text" in ev["filter_or_delay"]:
            form = {"form": ev["filter_or_delay"]["text"]}
        out.append(
            {
                "effect": e.title,
                "key": e.key,
                "kind": e.kind,
                **form,
                "parameters": params,
                "nominal": {p: float(nominal[p]) for p in params},
                "uncertainty": {p: {"std": stds.get(p), "ci95": ci95.get(p)} for p in params},
                "evidence": ev,
            }
        )
    return out


def title(a: Atom, state: State, steps: list) -> str:
    """An effect's name in the verdict: a measurement lag with its value and form (stages.lag_form_check)."""
    decided = [st for st in steps if st["how"] == "delay or filter" and st["effect"] == a.effect.key]
    if not decided:
        return a.effect.title
    p = decided[-1]["kept"]
    return f"{a.effect.title} ({p} {1e3 * state.changes.get(p, float('nan')):.3g} ms: {decided[-1]['text']})"


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
    return {
        "at_the_fitted_model": {
            "delta_bic_training": rest.bic - full.bic,
            "held_out_residual_reduction_percent": (
                100 * (rest.rss_ho - full.rss_ho) / rest.rss_ho if rest.rss_ho > 0 else None
            ),
            "training_residual_reduction_percent": 100 * (rest.rss_tr - full.rss_tr) / rest.rss_tr,
            "note": "linearised at the fitted model: the same selection without this effect",
        }
    }


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
        out.append(
            {
                "effect": other.title,
                "parameter": other.parameter,
                "equivalent_value": value,
                "delta_bic_band": dbic,
                "how": "regression in the band (linearised)",
                "separable": bool(math.isfinite(dbic) and dbic >= DELTA_BIC),
            }
        )
    return out


def judge(
    ctx: Context, state: State, last_fit, steps: list, structure_left: Optional[float] = None
) -> tuple[dict, Optional[dict]]:
    """The verdict on the model ``state``. ``structure_left``: the training BIC of ``state`` against a selection
    the search accepted and the check "named only if explained" took members out of (consistency.py); from
    DELTA_BIC up the residual holds structure those members absorbed, so it is not at the floor whatever its
    RMS (they stood in for a cause outside the library)."""
    model, pt, names, sigma = ctx.model, state.pt, ctx.names, ctx.sigma
    prepared = model.tests

    def ratio(ns):
        if not ns:
            return None
        r = np.concatenate([(prepared[n].y - pt.obs[n]).ravel() for n in ns])
        return float(np.sqrt(np.mean(r**2)) / sigma)

    rt, rh = ratio(ctx.train), ratio(ctx.held)
    per_test = {n: float(np.sqrt(np.mean((prepared[n].y - pt.obs[n]) ** 2)) / sigma) for n in names}
    white = _whiteness(prepared, pt, names)
    worst = max(per_test.values())
    # where a named effect makes the loop hunt, the band powers decide (phasefree.py): not sample by sample
    pf = state.info.get("phase_free")
    by_bands = [
        n
        for n in names
        if per_test[n] > FLOOR_FACTOR and pf and pf["deviance_per_test"]["after"][n] <= pf["floor_per_test"][n]
    ]
    # a named phase-free effect: tests in a regime of the hunting its re-simulations do not visit (quieter than all of
    # them, phasefree.PhaseFreeScore.quieter) are its trace, not an unknown cause, whichever regime a record fell into
    unreproduced = [n for n in (pf or {}).get("not_reproduced", ()) if per_test[n] > FLOOR_FACTOR]
    quiet = (
        f"; {', '.join(unreproduced)} hunts in a quieter regime than the re-simulations visit (one realisation of "
        "the hunting, not fitted)"
        if unreproduced
        else ""
    )
    rms_at_floor = all(per_test[n] <= FLOOR_FACTOR or n in by_bands or n in unreproduced for n in names)
    structured = structure_left is not None and structure_left >= DELTA_BIC
    at_floor = rms_at_floor and not structured
    titles = ", ".join(title(a, state, steps) for a in state.selected)
    rh_text = f"{rh:.2f}" if rh is not None else "-"
    if at_floor and not state.selected:
        status, text = (
            "nothing missing",
            (
                f"the nominal model's residual is at the noise floor (RMS {rt:.2f} x the "
                f"noise on training, {rh_text} x on held-out tests) and no candidate "
                "effect improves it: nothing is missing"
            ),
        )
    elif at_floor and pf and not pf["value_determined"]:
        hunting = next(a.effect.title for a in state.selected if a.effect.phase_free)
        others = ", ".join(a.effect.title for a in state.selected if not a.effect.phase_free)
        status, text = (
            "present, value not determined",
            (
                (f"with {others} named, " if others else "")
                + f"{hunting} is present, its value not determined on this plan "
                f"({'; '.join(pf['value_not_determined_because'])}); the residual is at the noise floor sample by "
                "sample on "
                f"{', '.join(n for n in names if n not in by_bands and n not in unreproduced) or 'no test'}"
                + (f", in the band powers of the hunting on {', '.join(by_bands)}" if by_bands else "")
                + f"; `{pf['parameter']}` is left out of the augmented model"
            ),
        )
    elif at_floor and by_bands:
        status, text = (
            "explained",
            (
                f"with {titles} the residual is at the noise floor: sample by sample on "
                f"{', '.join(n for n in names if n not in by_bands) or 'no test'}; on "
                f"{', '.join(by_bands)}, where the loop hunts (RMS "
                + ", ".join(f"{per_test[n]:.1f}" for n in by_bands)
                + " x noise, not predictable sample by sample), in its band powers (phase-free "
                "deviance "
                + ", ".join(f"{pf['deviance_per_test']['after'][n]:.1f}" for n in by_bands)
                + f" <= {max(pf['floor_per_test'][n] for n in by_bands):.1f})"
                + quiet
            ),
        )
    elif at_floor:
        status, text = (
            "explained",
            (
                f"with {titles} the residual is at the noise floor (RMS {rt:.2f} x noise on "
                f"training, {rh_text} x on held-out)" + quiet
            ),
        )
    else:
        status = "unexplained residual"
        text = (
            f"a residual remains that no candidate effect explains: RMS {rt:.2f} x the noise floor on training, "
            f"{rh_text} x on held-out tests (worst test {worst:.2f} x)"
            + (
                f", within {FLOOR_FACTOR:g} x in RMS but structured: the effects the search accepted reproduce "
                f"it (training BIC {structure_left:+.0f} without them) only as stand-ins"
                if rms_at_floor
                else ""
            )
            + "; "
            + (f"named: {titles}" if state.selected else "nothing named")
        )
    verdict = {
        "status": status,
        "text": text,
        "residual_over_noise_training": rt,
        "residual_over_noise_held_out": rh,
        "residual_over_noise_per_test": per_test,
        "floor_factor": FLOOR_FACTOR,
        "whiteness": white,
        "judged_by_band_powers": by_bands,
    }
    if structure_left is not None:
        verdict["structure_left_delta_bic"] = structure_left
    unexplained = None
    if not at_floor:
        loc = {n: localise_test(model, pt, prepared[n], sigma) for n in names}
        reg, best, fits = last_fit
        tried = []
        labels = [x.label for x in reg.atoms]
        for a in reg.atoms:
            if a in best.atoms:
                continue
            idx = tuple(sorted([labels.index(x.label) for x in best.atoms] + [labels.index(a.label)]))
            f = reg.fit(idx)
            tried.append(
                {
                    "candidate": a.label,
                    "delta_bic": f.bic - best.bic,
                    "held_out_rss_change_percent": (
                        100 * (f.rss_ho - best.rss_ho) / best.rss_ho if best.rss_ho > 0 else None
                    ),
                    "rejected_because": "; ".join(f.reasons) or "not better than the selection",
                }
            )
        for st in steps:  # the phase-free candidates: not tried, not confirmed, or not explaining all
            if st["how"].startswith("phase-free score") and not st["accepted"]:
                tried.append(
                    {
                        "candidate": f"{st['to'][-1]} (phase-free score)",
                        "delta_bic": st.get("delta_bic"),
                        "held_out_rss_change_percent": None,
                        "rejected_because": st["note"],
                    }
                )
        unexplained = {
            "text": (
                "The residual is within the noise floor's RMS, but structured: the search reproduced it only "
                "with effects whose values the tests do not agree on (hints); it is shown, not named."
                if rms_at_floor
                else "The residual is above the noise floor and no candidate of the library reduces it on the "
                "held-out tests (by regression, for the nonlinear candidates by re-simulation, for backlash by "
                "the phase-free score) or explains all of it; it is shown, not named."
            ),
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
            Q = N * (N + 2) * float(np.sum(ac**2 / (N - np.arange(1, lags + 1))))
            passed += chi2.sf(Q, lags) > 0.01
            total += 1
    return {"white_fraction": passed / total if total else None, "test": "Ljung-Box, lags 1-20, p > 0.01"}
