"""Cross-validation of the selection: every test held out in one fold and trained on in the others.

The search proposes and verifies on one split of the tests (plan.choose_split); what it keeps is then judged
over the folds of ``plan.folds`` (leave-one-test-out): in every fold the selection is refitted by re-simulation
on the fold's training tests (every continuous parameter free, from the values the search found) and predicts
its held-out tests, and so is the selection without each member, and, for a measurement lag, the selection with
the lag in the other form. An effect is named from the held-out evidence summed over the folds whose training
tests identify it (``plan.fold_meets``): removing it must raise the summed held-out residual by the amount a
proposal must remove (selection.Regression.held_out_needed: a share of the noise and of what is left above it).
A member the folds do not confirm is removed (refitted without it, recorded as a step); a plan with no fold
that can check an effect cannot identify it and says so. The delay-or-filter decision (stages.lag_form_check)
takes the summed held-out deviance of the folds in place of the one split's.
"""
from __future__ import annotations

import dataclasses
import math
from typing import Mapping, Optional, Sequence

import numpy as np

from .effects import BY_PARAMETER, MEASUREMENT
from .plan import Excitation, folds
from .resimulation import Point
from .selection import PRACTICAL, RELATIVE, Atom
from .stages import FD_STEP, Context, State, band_rss, fit_state, fitted_parameters, lag_form, polish


def _full_rss(ctx: Context, pt: Point, names: Sequence[str]) -> tuple[float, int]:
    return (sum(float(np.sum((ctx.model.tests[m].y - pt.obs[m]) ** 2)) for m in names),
            sum(ctx.model.tests[m].y.size for m in names))


def _columns(ctx: Context, changes: Mapping[str, float], params: Sequence[str]) -> dict:
    """Re-simulated sensitivities of the plant parameters on every test at ``changes`` (one simulation of the
    tests each, shared by every fold's fit: polish takes a fold's training tests from them)."""
    out = {}
    plant = [p for p in params if p not in MEASUREMENT and p not in FD_STEP and p in BY_PARAMETER]
    steps = {}
    for p in plant:
        v = float(changes[p])
        steps[p] = max(0.01 * abs(v), 0.1 * abs(BY_PARAMETER[p].step)) or 1e-6
    ctx.model.sim.prefetch([{**changes, p: float(changes[p]) + d} for p, d in steps.items()], ctx.names)
    base = ctx.model.trial(dict(changes), ctx.names, "cross-validation")
    for p, d in steps.items():
        pt1 = ctx.model.trial({**changes, p: float(changes[p]) + d}, ctx.names, "cross-validation sensitivity")
        if base is not None and pt1 is not None:
            out[p] = {n: (pt1.obs[n] - base.obs[n]) / d for n in ctx.names}
    return out


def _refit(fctx: Context, selected: Sequence[Atom], start: Mapping[str, float], columns: Mapping) -> Optional[dict]:
    """The selection refitted on the fold's training tests and evaluated on its held-out tests: {"values",
    "band_rss", "full_rss", "n", "n_full"}; None where it does not simulate. Discrete parameters stay on their
    grid values and effects scored phase-free (backlash) at theirs: neither is fitted sample by sample."""
    fitted = [a for a in selected if not a.effect.phase_free]
    free = {p: float(start.get(p, fctx.nominal[p])) for a in fitted for p in fitted_parameters(a, start)}
    fixed = {p: v for p, v in start.items() if p not in free or (p in BY_PARAMETER and BY_PARAMETER[p].quantum)}
    if any(p not in fixed for p in free):
        values, _ = polish(fctx, fitted, {**free, **fixed}, columns, fixed)
        values = {**fixed, **values}
    else:
        values = dict(start)
    pt = fctx.model.trial(values, fctx.held, "cross-validation")
    if pt is None:
        return None
    (rss, n), (full, nf) = band_rss(fctx, pt, fctx.held), _full_rss(fctx, pt, fctx.held)
    return {"values": values, "band_rss": rss, "full_rss": full, "n": n, "n_full": nf}


def _without(selected: Sequence[Atom], changes: Mapping[str, float], a: Atom) -> tuple[tuple, dict]:
    rest = tuple(x for x in selected if x is not a)
    gone = set(fitted_parameters(a, changes)) | set(a.effect.parameters)
    return rest, {p: v for p, v in changes.items() if p not in gone}


def cross_validate(ctx: Context, state: State, steps: list, tests: Sequence[Excitation]) -> tuple[State, dict]:
    """The selection of ``state`` judged over the folds (module docstring). Returns the state (members the folds
    do not confirm removed) and the record: per fold its tests, what it can check, the held-out residual (band)
    with the selection and without each member, and per member the sums and the decision."""
    members = [a for a in state.selected if not a.effect.phase_free]
    if not members or len(ctx.names) < 2:
        return state, {}
    keys = [a.effect.key for a in members]
    plan_folds = folds(tests, keys)
    lag = next((a for a in members if a.effect.parameter.startswith("T_meas")), None)
    decided = next((st for st in reversed(steps) if st["how"] == "delay or filter" and lag is not None
                    and st["effect"] == lag.effect.key), None)
    other_form = None
    if decided is not None:
        kept_delay = decided["kept"] == decided["delay_parameter"]
        other_form = decided["parameters_filter"] if kept_delay else decided["parameters_delay"]
    columns = _columns(ctx, state.changes, list(state.changes))
    sims0 = ctx.model.sim.count
    record = []
    for f in plan_folds:
        fctx = dataclasses.replace(ctx, train=list(f["training"]), held=list(f["held_out"]),
                                   names=list(f["training"]) + list(f["held_out"]), log=lambda *_: None)
        row: dict = {"held_out": f["held_out"], "training": f["training"], "checks": f["checks"],
                     "cannot_check": f["cannot_check"]}
        full = _refit(fctx, state.selected, state.changes, columns)
        row["with"] = full
        row["without"] = {}
        if full is not None:
            for a in members:
                if a.effect.key not in f["checks"]:
                    continue
                rest, start = _without(state.selected, state.changes, a)
                row["without"][a.effect.key] = _refit(fctx, rest, start, columns)
            if other_form is not None and lag.effect.key in f["checks"]:
                row["other_form"] = _refit(fctx, state.selected, other_form, columns)
        record.append(row)
        ctx.log("diagnose:   cross-validation, held out " + ", ".join(f["held_out"]) + ": "
                + ("does not simulate" if full is None else
                   f"held-out RSS {full['band_rss']:.3g}" + "".join(
                       f", without {k} {v['band_rss'] / full['band_rss'] - 1:+.0%}" if v else f", without {k}: fails"
                       for k, v in row["without"].items())))
    verdicts = {}
    for a in members:
        key = a.effect.key
        usable = [r for r in record if r["with"] is not None and r["without"].get(key) is not None]
        if not usable:
            verdicts[key] = {"folds": [], "confirmed": None,
                             "note": "no fold whose training tests identify it and whose held-out tests check it"}
            continue
        w = sum(r["with"]["band_rss"] for r in usable)
        wo = sum(r["without"][key]["band_rss"] for r in usable)
        n = sum(r["with"]["n"] for r in usable)
        noise = ctx.sigma_b ** 2 * n
        need = max(PRACTICAL * noise, RELATIVE * max(wo - noise, 0.0))
        verdicts[key] = {"folds": [", ".join(r["held_out"]) for r in usable],
                         "held_out_rss_with": w, "held_out_rss_without": wo, "needed": need,
                         "deviance_change": n * math.log(w / wo) if w > 0 and wo > 0 else None,
                         "rss_change_percent": 100 * (w - wo) / wo if wo > 0 else None,
                         "confirmed": bool(wo - w >= need)}
    out = {"folds": record, "effects": verdicts, "simulations": ctx.model.sim.count - sims0,
           "how": "leave-one-test-out: each fold refitted by re-simulation on its training tests (every continuous "
                  "parameter free, from the search's values), held-out residual in the band"}
    if decided is not None:
        out["lag_form"] = _lag_form(ctx, state, decided, record)
        state = _keep_form(ctx, state, decided, out["lag_form"], steps)
    for key, v in verdicts.items():
        if v["confirmed"] is False:
            a = next(x for x in state.selected if x.effect.key == key)
            rest, start = _without(state.selected, state.changes, a)
            cand = fit_state(ctx, rest, start) if rest else None
            pt = cand.pt if cand is not None else (ctx.model.trial({}, ctx.names, "cross-validation") if not rest
                                                   else None)
            if pt is None:
                v["note"] = "not confirmed by the folds, but the selection without it does not simulate: kept"
                continue
            new = cand if cand is not None else State((), {}, pt)
            steps.append({"how": f"cross-validation (removing {key})", "from": [x.label for x in state.selected],
                          "to": [x.label for x in new.selected], "parameters": dict(new.changes), "accepted": True,
                          "note": f"removing it raised the held-out residual summed over {len(v['folds'])} folds by "
                                  f"{-v['rss_change_percent']:.1f} %, less than needed"})
            ctx.log(f"diagnose:   cross-validation: {key} not confirmed by the folds: removed")
            state = new
    return state, out


def _lag_form(ctx: Context, state: State, decided: dict, record: list) -> dict:
    """The lag's form from the training BIC (stages.lag_form_check) and the held-out deviance summed over the folds
    that can check a lag (full band: a filter damps the torque's fast content, a delay only shifts it)."""
    kept_delay = decided["kept"] == decided["delay_parameter"]
    dho, used = 0.0, []
    for r in record:
        other, mine = r.get("other_form"), r["with"]
        if other is None or mine is None:
            continue
        d, fl = (mine, other) if kept_delay else (other, mine)
        dho += d["n_full"] * math.log(d["full_rss"] / fl["full_rss"])
        used.append(", ".join(r["held_out"]))
    choice = lag_form(decided["delta_bic_delay_vs_filter"], dho) if used else decided["choice"]
    return {"held_out_deviance_delay_vs_filter": dho, "folds": used, "choice": choice}


def _keep_form(ctx: Context, state: State, decided: dict, form: dict, steps: list) -> State:
    """The lag_form_check step updated with the folds' held-out deviance; the other fitted form kept where the
    decision now prefers it."""
    choice = form["choice"]
    decided["held_out_deviance_delay_vs_filter_one_split"] = decided["held_out_deviance_delay_vs_filter"]
    decided["held_out_deviance_delay_vs_filter"] = form["held_out_deviance_delay_vs_filter"]
    decided["held_out"] = "summed over the folds of the cross-validation: " + "; ".join(form["folds"])
    decided["choice"], decided["separable"] = choice, choice != "not distinguishable"
    decided["text"] = ({"delay_meas": "a delay (the training tests and the held-out tests prefer it)",
                        "T_meas": "a first-order filter (the training tests and the held-out tests prefer it)"}.get(choice)
                       or "delay or filter: not distinguishable on this plan")
    want_delay = choice == "delay_meas" or (choice == "not distinguishable" and decided["delta_bic_delay_vs_filter"] < 0)
    if want_delay == (decided["kept"] == decided["delay_parameter"]):
        return state
    values = decided["parameters_delay"] if want_delay else decided["parameters_filter"]
    pt = ctx.model.trial(values, ctx.names, "delay or filter")
    if pt is None:
        return state
    decided["kept"] = decided["delay_parameter"] if want_delay else decided["filter_parameter"]
    ctx.log(f"diagnose:   cross-validation: the lag kept as {decided['kept']} ({decided['text']})")
    return State(state.selected, dict(values), pt, state.info)
