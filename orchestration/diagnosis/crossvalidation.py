"""Cross-validation of the selection: every test held out in one fold and trained on in the others.

The search proposes and verifies on one split of the tests (plan.choose_split); what it keeps is then judged
over the folds of ``plan.folds`` (leave-one-test-out). In every fold the selection is refitted on the fold's
training tests and predicts its held-out tests; so is the selection without each member, and, for a measurement
lag, the selection with the lag in the other form. A fold's refit is one Gauss-Newton step, in the band, from a
re-simulated model on the re-simulated sensitivities of its parameters: the fold's least-squares optimum to
first order in the parameter change, whatever the tests the start was fitted on (the search's values are fitted
on the split's training tests; a fold's differ from them by a few per cent); a step beyond the sensitivities'
reach (STEP_LIMIT) is shortened to it. The model without a member is
re-simulated with that member at its nominal value and the others at the search's values, then refitted the
same way; the other form of a lag is the one stages.lag_form_check fitted by re-simulation. Cost: one simulation
of every test per plant parameter, per member and for the lag's other form, not a search per fold.

An effect is named from the held-out evidence summed over the folds whose training tests identify it
(``plan.fold_meets``): removing it must raise the summed held-out residual by what a proposal must remove
(selection.Regression.held_out_needed: a share of the noise and of what is left above it). A member the folds do
not confirm is removed (the rest refitted by re-simulation, recorded as a step); a plan with no fold that can
check an effect cannot identify it and says so. The delay-or-filter decision (stages.lag_form_check) takes the
held-out deviance summed over the folds in place of the one split's.
"""

from __future__ import annotations

import math
import time
from typing import Mapping, Optional, Sequence

import numpy as np

from .effects import BY_PARAMETER, MEASUREMENT, physical_bounds
from .nonlinear import phase_free_stage
from .plan import Excitation, folds
from .resimulation import Point
from .selection import PRACTICAL, RELATIVE, Atom
from .stages import (
    FD_STEP,
    Context,
    State,
    fit_state,
    fitted_parameters,
    lag_form,
    lag_form_text,
    residual_at_floor,
)

#: a fold's Gauss-Newton step moves no parameter by more than this share of its value (or of its change from the
#: nominal value, when larger): beyond it the sensitivities, taken at the search's values, do not hold (a stiffness's
#: trace goes with 1/K_t^2), and a step that long means the fold's training tests hardly inform that parameter
#: (a flat valley, which a re-simulated fit would not cross in one step either); the step is shortened, as a
#: whole, to that reach
STEP_LIMIT = 0.2


def _fitted(selected: Sequence[Atom], changes: Mapping[str, float]) -> list[str]:
    """The continuous parameters of ``selected`` as ``changes`` holds them (not the discrete ones, fitted on
    their grid, nor those scored phase-free: neither is fitted sample by sample)."""
    out = []
    for a in selected:
        if a.effect.phase_free:
            continue
        out += [
            p
            for p in fitted_parameters(a, changes)
            if p in changes and p not in out and not (p in BY_PARAMETER and BY_PARAMETER[p].quantum)
        ]
    return out


def _columns(ctx: Context, state: State, params: Sequence[str]) -> dict:
    """Sensitivities of ``params`` on every test at ``state``: re-simulated for the plant and the drive (one
    simulation of the tests each, in one parallel batch), exact for the measurement parameters."""
    changes, names = state.changes, ctx.names
    steps = {}
    for p in params:
        if p in MEASUREMENT:
            continue
        v = float(changes[p])
        step = FD_STEP.get(p) or max(0.01 * abs(v), 0.1 * abs(BY_PARAMETER[p].step)) or 1e-6
        lo, hi = physical_bounds(p, ctx.nominal)
        steps[p] = step if v + step <= hi or v - step < lo else -step
    ctx.model.sim.prefetch([{**changes, p: float(changes[p]) + d} for p, d in steps.items()], names)
    out = {}
    for p in params:
        if p in steps:
            pt1 = ctx.model.trial({**changes, p: float(changes[p]) + steps[p]}, names, "cross-validation sensitivity")
            if pt1 is not None:
                out[p] = {n: (pt1.obs[n] - state.pt.obs[n]) / steps[p] for n in names}
        else:
            out[p] = ctx.model.columns(state.pt, names, p)
    return out


class _Variant:
    """One model judged over the folds: its re-simulated point, its free parameters and their columns, in the band
    and in the full band, per test."""

    def __init__(self, ctx: Context, pt: Point, params: Sequence[str], columns: Mapping) -> None:
        self.params = [p for p in params if p in columns]
        # the range in which a parameter's sensitivity holds: STEP_LIMIT of its value or of its change
        self.reach = np.array(
            [
                STEP_LIMIT * max(abs(float(pt.params[p])), abs(float(pt.params[p]) - float(ctx.nominal[p]))) or math.inf
                for p in self.params
            ]
        )
        self.r, self.A, self.r_full, self.A_full = {}, {}, {}, {}
        for n in ctx.names:
            dt, y = ctx.model.tests[n].test.sample_time, ctx.model.tests[n].y
            self.r_full[n] = (y - pt.obs[n]).ravel()
            self.r[n] = ctx.band.apply(y - pt.obs[n], dt).ravel()
            full = [columns[p][n] for p in self.params]
            self.A_full[n] = np.column_stack([c.ravel() for c in full]) if full else np.zeros((y.size, 0))
            band = [ctx.band.apply(c, dt).ravel() for c in full]
            self.A[n] = np.column_stack(band) if band else np.zeros((len(self.r[n]), 0))

    def fold(self, train: Sequence[str], held: Sequence[str]) -> dict:
        """Refitted on ``train`` (one Gauss-Newton step, in the band), predicting ``held``: the held-out residual
        sum of squares in the band and in the full band, the parameter changes of the step."""
        A = np.vstack([self.A[n] for n in train])
        r = np.concatenate([self.r[n] for n in train])
        step = np.linalg.lstsq(A, r, rcond=None)[0] if A.shape[1] else np.zeros(0)
        shortened = min(1.0, float(np.min(self.reach / np.maximum(np.abs(step), 1e-300)))) if len(step) else 1.0
        step = step * shortened
        rss = sum(float(np.sum((self.r[n] - self.A[n] @ step) ** 2)) for n in held)
        full = sum(float(np.sum((self.r_full[n] - self.A_full[n] @ step) ** 2)) for n in held)
        return {
            "band_rss": rss,
            "n": sum(len(self.r[n]) for n in held),
            "full_rss": full,
            "n_full": sum(len(self.r_full[n]) for n in held),
            "step": dict(zip(self.params, map(float, step))),
            "step_shortened_to": shortened,
        }


def _without(selected: Sequence[Atom], changes: Mapping[str, float], a: Atom) -> tuple[tuple, dict]:
    rest = tuple(x for x in selected if x is not a)
    gone = set(fitted_parameters(a, changes)) | set(a.effect.parameters)
    return rest, {p: v for p, v in changes.items() if p not in gone}


def cross_validate(ctx: Context, state: State, steps: list, tests: Sequence[Excitation]) -> tuple[State, dict]:
    """The selection of ``state`` judged over the folds (module docstring). Returns the state (members the folds
    do not confirm removed, the lag in the form the folds decide) and the record: per fold its tests, what it can
    check, the held-out residual (band) with the selection refitted on its training tests and without each member,
    the refitted values; per member the sums and the decision."""
    members = [a for a in state.selected if not a.effect.phase_free]
    if not members or len(ctx.names) < 2:
        return state, {}
    sims0, t0 = ctx.model.sim.count, time.perf_counter()
    keys = [a.effect.key for a in members]
    params = _fitted(state.selected, state.changes)
    columns = _columns(ctx, state, params)
    variants: dict[str, Optional[_Variant]] = {"with": _Variant(ctx, state.pt, params, columns)}
    starts = {a.effect.key: _without(state.selected, state.changes, a)[1] for a in members}
    ctx.model.sim.prefetch(list(starts.values()), ctx.names)
    for key, start in starts.items():
        pt = ctx.model.trial(start, ctx.names, "cross-validation")
        variants[key] = None if pt is None else _Variant(ctx, pt, [p for p in params if p in start], columns)
    lag = next((a for a in members if a.effect.parameter.startswith("T_meas")), None)
    decided = next(
        (
            st
            for st in reversed(steps)
            if lag is not None and st["how"] == "delay or filter" and st["effect"] == lag.effect.key
        ),
        None,
    )
    if decided is not None:
        kept_delay = decided["kept"] == decided["delay_parameter"]
        other = decided["parameters_filter"] if kept_delay else decided["parameters_delay"]
        pt = ctx.model.trial(other, ctx.names, "cross-validation")
        if pt is not None:
            lag_other = decided["filter_parameter"] if kept_delay else decided["delay_parameter"]
            cols = {**columns, lag_other: ctx.model.columns(pt, ctx.names, lag_other)}
            variants["other form"] = _Variant(ctx, pt, [p for p in other if p in cols], cols)
    record = []
    for f in folds(tests, keys):
        row: dict = {
            "held_out": f["held_out"],
            "training": f["training"],
            "checks": f["checks"],
            "cannot_check": f["cannot_check"],
            "with": variants["with"].fold(f["training"], f["held_out"]),
            "without": {},
        }
        row["values"] = {p: float(state.changes[p]) + d for p, d in row["with"]["step"].items()}
        for key in f["checks"]:
            v = variants.get(key)
            row["without"][key] = None if v is None else v.fold(f["training"], f["held_out"])
        if "other form" in variants and lag.effect.key in f["checks"]:
            row["other_form"] = variants["other form"].fold(f["training"], f["held_out"])
        record.append(row)
        w = row["with"]["band_rss"]
        ctx.log(
            "diagnose:   cross-validation, held out "
            + ", ".join(f["held_out"])
            + f": RSS {w:.3g}"
            + "".join(
                f", without {k} {100 * (v['band_rss'] / w - 1):+.0f} %" if v else f", without {k}: does not simulate"
                for k, v in row["without"].items()
            )
        )
    verdicts = {a.effect.key: _judge(ctx, a.effect.key, record) for a in members}
    out = {
        "folds": record,
        "effects": verdicts,
        "how": "leave-one-test-out; each fold refitted on its training tests (one Gauss-Newton step on "
        "re-simulated sensitivities, in the band) and predicting its held-out tests",
    }
    if decided is not None and "other form" in variants:
        out["lag_form"] = _lag_form(decided, record)
        state = _keep_form(ctx, state, decided, out["lag_form"])
    for key, v in verdicts.items():
        if v["confirmed"] is False:
            state = _remove(ctx, state, key, v, steps)
    out["simulations"], out["wall_s"] = ctx.model.sim.count - sims0, round(time.perf_counter() - t0, 1)
    return state, out


def _judge(ctx: Context, key: str, record: list) -> dict:
    usable = [r for r in record if r["without"].get(key) is not None]
    if not usable:
        why = "; ".join(sorted({r["cannot_check"].get(key, "") for r in record} - {""}))
        return {
            "folds": [],
            "confirmed": None,
            "note": "no fold whose training tests identify it and whose "
            f"held-out tests check it ({why or 'its model without it does not simulate'}): the split's "
            "held-out evidence stands",
        }
    w = sum(r["with"]["band_rss"] for r in usable)
    wo = sum(r["without"][key]["band_rss"] for r in usable)
    n = sum(r["with"]["n"] for r in usable)
    noise = ctx.sigma_b**2 * n
    need = max(PRACTICAL * noise, RELATIVE * max(wo - noise, 0.0))
    return {
        "folds": [", ".join(r["held_out"]) for r in usable],
        "held_out_rss_with": w,
        "held_out_rss_without": wo,
        "needed": need,
        "deviance_change": n * math.log(w / wo) if w > 0 and wo > 0 else None,
        "rss_change_percent": 100 * (w - wo) / wo if wo > 0 else None,
        "confirmed": bool(wo - w >= need),
    }


def _remove(ctx: Context, state: State, key: str, verdict: dict, steps: list) -> State:
    """A member the folds do not confirm: the rest refitted by re-simulation on the training tests. An effect of the
    rest on the phase-free score (backlash: its value and evidence were found beside the removed member) is scored
    again, phase-free, against the refitted rest (nonlinear.phase_free_stage), never refitted sample by sample."""
    a = next(x for x in state.selected if x.effect.key == key)
    rest, start = _without(state.selected, state.changes, a)
    hunting = [x.effect for x in rest if x.effect.phase_free]
    rest = tuple(x for x in rest if not x.effect.phase_free)
    start = {p: v for p, v in start.items() if not any(p in e.parameters for e in hunting)}
    new = fit_state(ctx, rest, start) if rest else None
    if new is None:
        pt = ctx.model.trial({}, ctx.names, "cross-validation") if not rest else None
        if pt is None:
            verdict["note"] = "not confirmed by the folds, but the selection without it does not simulate: kept"
            return state
        new = State((), {}, pt)
    steps.append(
        {
            "how": f"cross-validation (removing {key})",
            "from": [x.label for x in state.selected],
            "to": [x.label for x in new.selected],
            "parameters": dict(new.changes),
            "accepted": True,
            "note": f"removing it changed the held-out residual summed over {len(verdict['folds'])} folds by "
            f"{-verdict['rss_change_percent']:+.1f} %, less than needed",
        }
    )
    verdict["note"] = "not confirmed by the folds: removed"
    ctx.log(f"diagnose:   cross-validation: {key} not confirmed by the folds: removed")
    for e in hunting:
        if not residual_at_floor(ctx, new.pt):
            new = phase_free_stage(ctx, new, e, steps)
    return new


def _lag_form(decided: dict, record: list) -> dict:
    """The lag's form from the training BIC (stages.lag_form_check) and the held-out deviance summed over the folds
    that can check a lag (full band: a filter damps the torque's fast content, a delay only shifts it)."""
    kept_delay = decided["kept"] == decided["delay_parameter"]
    dho, used = 0.0, []
    for r in record:
        if "other_form" not in r:
            continue
        d, f = (r["with"], r["other_form"]) if kept_delay else (r["other_form"], r["with"])
        dho += d["n_full"] * math.log(d["full_rss"] / f["full_rss"])
        used.append(", ".join(r["held_out"]))
    choice = lag_form(decided["delta_bic_delay_vs_filter"], dho) if used else decided["choice"]
    return {
        "held_out_deviance_delay_vs_filter": dho,
        "folds": used,
        "choice": choice,
        "choice_one_split": decided["choice"],
        "changed": choice != decided["choice"],
    }


def _keep_form(ctx: Context, state: State, decided: dict, form: dict) -> State:
    """The lag_form_check step updated with the folds' held-out deviance; the other fitted form kept where the
    decision now prefers it."""
    choice = form["choice"]
    decided["held_out_deviance_delay_vs_filter_one_split"] = decided["held_out_deviance_delay_vs_filter"]
    decided["held_out_deviance_delay_vs_filter"] = form["held_out_deviance_delay_vs_filter"]
    decided["held_out_tests"] = "the folds of the cross-validation, held out: " + "; ".join(form["folds"])
    decided["choice"], decided["separable"] = choice, choice != "not distinguishable"
    decided["text"] = lag_form_text(choice)
    want_delay = choice == "delay_meas" or (
        choice == "not distinguishable" and decided["delta_bic_delay_vs_filter"] < 0
    )
    if want_delay == (decided["kept"] == decided["delay_parameter"]):
        return state
    values = decided["parameters_delay"] if want_delay else decided["parameters_filter"]
    pt = ctx.model.trial(values, ctx.names, "delay or filter")
    if pt is None:
        return state
    decided["kept"] = decided["delay_parameter"] if want_delay else decided["filter_parameter"]
    ctx.log(f"diagnose:   cross-validation: the lag kept as {decided['kept']} ({decided['text']})")
    return State(state.selected, dict(values), pt, state.info)
