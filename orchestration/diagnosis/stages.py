"""The stages of the search: the regression loop (select, fit by re-simulation, verify), the alias check
between the two sides of the transmission, pruning, and the bounded least-squares fit (polish)."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Callable, Mapping, Optional, Sequence

import numpy as np

from .effects import AXIS_OF, BOUNDS, BY_PARAMETER, LIBRARY, MEASUREMENT, Chain, physical_bounds
from .resimulation import Model, Point, resample
from .selection import (
    DELTA_BIC,
    PRACTICAL,
    RELATIVE,
    Atom,
    Band,
    Regression,
    SubsetFit,
    atom_labels,
    held_out_prefers,
    rivals,
    select,
)

#: re-simulation steps (finite differences) for the parameters whose signature does not linearise well
FD_STEP = {"tau_s": 2e-3, "omega_s": 0.3, "k_p": 6e-4, "k_v": 0.2, "k_i": 0.04, "i_max": 0.05, "K_t": 0.05}
#: effects fitted and verified by re-simulation (sample by sample): kept at their fitted values by the regression loop
NONLINEAR = tuple(e.key for e in LIBRARY if not e.regression and not e.phase_free)
#: ... of which these are tried when a residual remains after the regression loop (the others: after stand-ins)
NONLINEAR_FIRST = tuple(e.key for e in LIBRARY if not e.regression and not e.phase_free and not e.after_stand_ins)
#: at most this many effects at once
MAX_EFFECTS = 4
#: residual RMS within this factor of the noise floor: nothing left to explain
FLOOR_FACTOR = 1.2
MAX_ROUNDS = 5


@dataclass
class State:
    """The current model: selected effects, their fitted parameters, its evaluation on every test."""

    selected: tuple
    changes: dict
    pt: Point
    info: dict = field(default_factory=dict)


@dataclass
class Context:
    model: Model
    nominal: dict
    names: list
    train: list
    held: list
    band: Band
    sigma: float
    sigma_b: float
    log: Callable


def regression_loop(ctx: Context, state: State, atoms, rejected: set, steps: list) -> tuple[State, tuple]:
    """Select by regression at the current model, fit by re-simulation, verify; until the selection is stable."""
    last_fit = None
    for _ in range(MAX_ROUNDS):
        # effects found by re-simulation stay in, at their fitted values (their signature does not linearise)
        locked = tuple(a for a in state.selected if a.effect.key in NONLINEAR)
        keys = {a.effect.key for a in locked}
        free_atoms = [a for a in atoms if a.effect.key not in keys]
        exclude = frozenset(tuple(sorted(set(r) - keys)) for r in rejected if keys <= set(r))
        if residual_at_floor(ctx, state.pt):
            # at the noise floor: a cheap screen with the signatures first; sensitivities only if it proposes a change
            reg = regression_at(ctx, state, free_atoms, sensitivities=False)
            best, fits = select(reg, ctx.nominal, MAX_EFFECTS - len(locked), exclude)
            if atom_labels(tuple(best.atoms) + locked) == atom_labels(state.selected):
                last_fit = (reg, best, fits)
                break
        reg = regression_at(ctx, state, free_atoms)
        best, fits = select(reg, ctx.nominal, MAX_EFFECTS - len(locked), exclude)
        last_fit = (reg, best, fits)
        proposal = tuple(best.atoms) + locked
        if atom_labels(proposal) == atom_labels(state.selected):
            break
        labels = [a.label for a in reg.atoms]
        current = [a for a in state.selected if a.effect.key not in keys]
        if all(a.label in labels for a in current):
            now = reg.fit(tuple(labels.index(a.label) for a in current))
            if math.isfinite(now.bic) and reg.score(best) >= reg.score(now):
                break  # the regression sees nothing better than the current model
        ctx.log(f"diagnose: proposed by regression: {[a.label for a in proposal] or 'none'}")
        chosen, cand = best, _fitted(ctx, state, reg, best, locked)
        for rival in rivals(reg, best, fits):
            if held_out_prefers(reg, rival, chosen) and atom_labels(rival.atoms + locked) != atom_labels(
                state.selected
            ):
                chosen, cand = _challenge(ctx, state, reg, (chosen, cand), rival, locked, steps)
        proposal, last_fit = tuple(chosen.atoms) + locked, (reg, chosen, fits)
        ok = cand is not None and verify(ctx, state, cand, steps, "regression")
        if cand is None:
            failed_step(ctx, state, proposal, steps, "regression")
        if ok:
            state = cand
        else:
            rejected.add(atom_labels(proposal))
    return state, last_fit


def _fitted(ctx: Context, state: State, reg: Regression, fit: SubsetFit, locked: tuple) -> Optional[State]:
    """The regression's subset ``fit`` (with the effects ``locked`` at their values) fitted by re-simulation from
    its linear coefficients; None if it does not simulate."""
    start = dict(state.changes)
    for a, c in zip(fit.atoms, fit.coef):
        # a lag held as a delay stays one: the filter column's coefficient is its delay (the same phase slope)
        p0 = fitted_parameters(a, state.changes)[0]
        lo, hi = physical_bounds(p0, ctx.nominal)
        start[p0] = float(np.clip(float(ctx.nominal[p0]) + c, lo, hi))
        if a.grid is not None:
            start[a.effect.parameters[1]] = a.grid
    proposal = tuple(fit.atoms) + locked
    return fit_state(ctx, proposal, start, getattr(reg, "columns", {}), anchor=state.changes, lag_form=True)


def resimulated_score(ctx: Context, state: State) -> float:
    """The regression's score (selection.Regression.score) on the re-simulated model: training BIC in the band
    plus the held-out deviance n_ho ln(RSS_ho / n_ho)."""
    score = training_bic(ctx, state)
    if ctx.held:
        rss, n = band_rss(ctx, state.pt, ctx.held)
        score += n * math.log(rss / n)
    return score


def _challenge(
    ctx: Context, state: State, reg: Regression, current: tuple, rival: SubsetFit, locked: tuple, steps: list
) -> tuple[SubsetFit, Optional[State]]:
    """The proposal ``current`` (its subset fit, its state fitted by re-simulation or None) against a ``rival``
    the held-out tests rank above it (selection.held_out_prefers): both fitted by re-simulation, the lower
    re-simulated score goes on."""
    fit, cand = current
    labels = [[a.label for a in f.atoms + locked] for f in (fit, rival)]
    ctx.log(
        f"diagnose:   the held-out tests rank {labels[1]} above it (predicted held-out RSS {rival.rss_ho:.3g} "
        f"against {fit.rss_ho:.3g}): fitted by re-simulation too"
    )
    fitted = _fitted(ctx, state, reg, rival, locked)
    scores = [None if x is None else resimulated_score(ctx, x) for x in (cand, fitted)]
    wins = scores[1] is not None and (scores[0] is None or scores[1] < scores[0])
    steps.append(
        {
            "how": "held-out rival (re-simulated)",
            "from": labels[0],
            "to": labels[1],
            "scores_re_simulated": scores,
            "accepted": bool(wins),
            "note": "the regression's score (training BIC + held-out deviance, in the band) of both, fitted by "
            "re-simulation; the lower goes on",
        }
    )
    ctx.log(
        "diagnose:   re-simulated scores "
        + ", ".join(f"{x} {'fails' if v is None else f'{v:.1f}'}" for x, v in zip(labels, scores))
        + f": {'the rival' if wins else 'the proposal'} goes on"
    )
    return (rival, fitted) if wins else (fit, cand)


#: a start whose simulation fails is moved back towards the current model this many times (halving the step)
BACK_OFF = 4


def fit_state(
    ctx: Context,
    selected: Sequence[Atom],
    start: Mapping[str, float],
    columns: Optional[Mapping] = None,
    anchor: Optional[Mapping[str, float]] = None,
    lag_form: bool = False,
) -> Optional[State]:
    """The selection fitted by re-simulation from ``start``; None if no value near it simulates on every test.
    A lag is fitted in the form ``start`` holds it (``fitted_parameters``); ``lag_form``: a fitted filter is then
    compared with a delay fitted alone, the others fixed (polish; a first guess, no re-simulation; the form is
    decided by ``lag_form_check``).

    A start that does not simulate (a proposed value that destabilises the loop) is moved back
    towards ``anchor`` (the current model; the nominal one by default), halving the step each time."""
    free = _free_parameters(selected, start)
    start = {p: start.get(p, float(ctx.nominal[p])) for p in free}
    base = {p: float((anchor or {}).get(p, ctx.nominal[p])) for p in free}
    for k in range(BACK_OFF + 1):
        trial = _snap(ctx, {p: base[p] + (start[p] - base[p]) * 0.5**k for p in free})
        if ctx.model.trial(trial, ctx.train, "fit start") is not None:
            break
    else:
        return None
    if k:
        ctx.log(
            f"diagnose:   the proposed values do not simulate: fit started {k} halving(s) back towards the "
            "current model"
        )
    fixed = _discrete_fit(ctx, trial)
    changes, info = polish(ctx, selected, {**trial, **fixed}, columns or {}, fixed, lag_form)
    pt = ctx.model.trial(changes, ctx.names, "fitted values on every test")
    if pt is None:
        return None
    return State(tuple(selected), changes, pt, info)


def _snap(ctx: Context, values: Mapping[str, float]) -> dict[str, float]:
    """Discrete parameters (cycle times) on their grid: the nearest multiple (>= 1) of their quantum."""
    out = dict(values)
    for p, v in values.items():
        e = BY_PARAMETER.get(p)
        if e is not None and e.quantum:
            q = float(ctx.nominal[e.quantum])
            out[p] = max(1, round(v / q)) * q
    return out


def _discrete_fit(ctx: Context, trial: Mapping[str, float]) -> dict[str, float]:
    """The discrete parameters of ``trial`` fitted on their grid: the start and its neighbours (one quantum
    either side, the others at their start values) simulated on the training tests, the lowest RSS in the
    band kept. The continuous parameters are then fitted with these fixed (polish)."""
    fixed: dict[str, float] = {}
    for p, v in trial.items():
        e = BY_PARAMETER.get(p)
        if e is None or not e.quantum:
            continue
        q = float(ctx.nominal[e.quantum])
        n0 = round(v / q)
        values = [n * q for n in (n0 - 1, n0, n0 + 1) if n >= 1 and BOUNDS[p][0] <= n * q <= BOUNDS[p][1]]
        ctx.model.sim.prefetch([{**trial, **fixed, p: x} for x in values], ctx.train)
        best, best_rss = v, math.inf
        for x in values:
            pt = ctx.model.trial({**trial, **fixed, p: x}, ctx.train, f"{p} grid")
            if pt is not None and band_rss(ctx, pt, ctx.train)[0] < best_rss:
                best, best_rss = x, band_rss(ctx, pt, ctx.train)[0]
        fixed[p] = best
    return fixed


def failed_step(ctx: Context, old: State, selected: Sequence[Atom], steps: list, how: str) -> None:
    """A proposal whose fitted model does not simulate: refuted, recorded as a step."""
    steps.append(
        {
            "how": how,
            "from": [a.label for a in old.selected],
            "to": [a.label for a in selected],
            "accepted": False,
            "note": "refuted: its re-simulation failed (see failed_simulations)",
        }
    )
    ctx.log(f"diagnose:   refuted by re-simulation: {[a.label for a in selected]} (its simulation failed)")


def band_rss(ctx: Context, pt: Point, names: Sequence[str]) -> tuple[float, int]:
    rss, n = 0.0, 0
    for name in names:
        prep = ctx.model.tests[name]
        r = ctx.band.apply(prep.y - pt.obs[name], prep.test.sample_time)
        rss += float(np.sum(r**2))
        n += r.size
    return rss, n


def selection_cost(selected: Sequence[Atom]) -> int:
    return sum(a.effect.cost for a in selected)


def training_bic(ctx: Context, state: State) -> float:
    """BIC of ``state`` on the training tests, in the band: n ln(RSS/n) + (its selection's cost) ln n."""
    rss, n = band_rss(ctx, state.pt, ctx.train)
    return n * math.log(rss / n) + selection_cost(state.selected) * math.log(n)


def verify(ctx: Context, old: State, new: State, steps: list, how: str) -> bool:
    """Accept a new selection only if re-simulation confirms it: training BIC and held-out residual."""
    bic0, bic1 = training_bic(ctx, old), training_bic(ctx, new)
    k0, k1 = selection_cost(old.selected), selection_cost(new.selected)
    ho0, nh = band_rss(ctx, old.pt, ctx.held) if ctx.held else (0.0, 0)
    ho1, _ = band_rss(ctx, new.pt, ctx.held) if ctx.held else (0.0, 0)
    noise = ctx.sigma_b**2 * nh
    need = max(PRACTICAL * noise, RELATIVE * max(ho0 - noise, 0.0))
    # no held-out test may get markedly worse: a true effect improves every test or leaves it alone
    worse, per_test = [], {}
    for name in ctx.held:
        a, m = band_rss(ctx, old.pt, [name])
        b, _ = band_rss(ctx, new.pt, [name])
        per_test[name] = 100 * (b - a) / a if a > 0 else None
        if b > a + max(PRACTICAL * ctx.sigma_b**2 * m, RELATIVE * a, 3.0 * math.sqrt(2.0 * m) * ctx.sigma_b**2):
            worse.append(name)
    if k1 > k0:
        ok = bic1 <= bic0 - DELTA_BIC and (not ctx.held or ho0 - ho1 >= need) and not worse
    else:  # fewer or as many parameters: kept effects must have been strongly needed
        ok = bic1 < bic0 + (DELTA_BIC if k1 < k0 else 0.0) and (not ctx.held or ho1 <= ho0 + need)
    step = {
        "how": how,
        "from": [a.label for a in old.selected],
        "to": [a.label for a in new.selected],
        "parameters": dict(new.changes),
        "delta_bic_training": bic1 - bic0,
        "held_out_rss_change_percent": 100 * (ho1 - ho0) / ho0 if ho0 > 0 else None,
        "held_out_rss_needed_percent": -100 * need / ho0 if ho0 > 0 else None,
        "held_out_tests_worse": worse,
        "held_out_rss_change_percent_per_test": per_test,
        "accepted": bool(ok),
        "fit": new.info,
    }
    steps.append(step)
    ctx.log(
        f"diagnose:   {'accepted' if ok else 'refuted by re-simulation'}: {step['to'] or 'none'} "
        f"(dBIC {bic1 - bic0:+.0f}, held-out RSS {step['held_out_rss_change_percent'] or 0:+.1f} %"
        + (f"; worse on {', '.join(worse)}" if worse else "")
        + ")"
    )
    return ok


def residual_at_floor(ctx: Context, pt: Point) -> bool:
    return all(
        float(np.sqrt(np.mean((ctx.model.tests[n].y - pt.obs[n]) ** 2))) <= FLOOR_FACTOR * ctx.sigma for n in ctx.names
    )


def alias_check(ctx: Context, state: State, last_fit, steps: list) -> State:
    """Effects the regression cannot separate (inertia on either side): compare them by re-simulation."""
    for a in state.selected:
        if not a.effect.group:
            continue
        for other in LIBRARY:
            if other.group != a.effect.group or other.key == a.effect.key:
                continue
            start = {k: v for k, v in state.changes.items() if k not in a.effect.parameters}
            # the equivalent value of the other side: the same change of reflected inertia
            start[other.parameter] = _equivalent(
                ctx.nominal, a.effect.parameter, state.changes[a.effect.parameter], other.parameter
            )
            lo, hi = BOUNDS[other.parameter]
            if not lo <= start[other.parameter] <= hi:
                steps.append(
                    {
                        "how": "alias check",
                        "from": [x.label for x in state.selected],
                        "to": f"{other.key} instead of {a.effect.key}",
                        "accepted": False,
                        "note": f"the equivalent {other.parameter} = {start[other.parameter]:.3g} is outside its "
                        "bounds",
                    }
                )
                continue
            swapped = tuple(x for x in state.selected if x is not a) + (Atom(other),)
            # the equivalent value must itself reproduce the data's stable run: if it does not simulate
            # (more inertia behind the elastic transmission destabilises the loop), the data refute it
            cand = None
            if ctx.model.trial(start, ctx.train, "alias check") is not None:
                cand = fit_state(ctx, swapped, start)
            if cand is None:
                steps.append(
                    {
                        "how": "alias check",
                        "from": [x.label for x in state.selected],
                        "to": [x.label for x in swapped],
                        "accepted": False,
                        "note": f"the equivalent {other.parameter} = {start[other.parameter]:.3g} does not "
                        "simulate (see failed_simulations): the data, which ran, refute it",
                    }
                )
                ctx.log(
                    f"diagnose:   alias check {a.effect.key} -> {other.key}: the equivalent value does not "
                    "simulate: kept"
                )
                continue
            rss0, n = band_rss(ctx, state.pt, ctx.train)
            rss1, _ = band_rss(ctx, cand.pt, ctx.train)
            full0 = sum(float(np.sum((ctx.model.tests[m].y - state.pt.obs[m]) ** 2)) for m in ctx.train)
            full1 = sum(float(np.sum((ctx.model.tests[m].y - cand.pt.obs[m]) ** 2)) for m in ctx.train)
            nf = sum(ctx.model.tests[m].y.size for m in ctx.train)
            dbic_full = nf * math.log(full1 / full0)
            better = dbic_full <= -DELTA_BIC
            steps.append(
                {
                    "how": "alias check",
                    "from": [x.label for x in state.selected],
                    "to": [x.label for x in swapped],
                    "parameters": dict(cand.changes),
                    "delta_bic_band": n * math.log(rss1 / rss0),
                    "delta_bic_full_band": dbic_full,
                    "accepted": bool(better),
                    "note": "full band (the transmission's ringing) decides; in the band the two are alike",
                }
            )
            ctx.log(
                f"diagnose:   alias check {a.effect.key} -> {other.key}: dBIC (full band) {dbic_full:+.0f}"
                + (": swapped" if better else ": kept")
            )
            state.info.setdefault("alias", []).append(
                {
                    "effect": other.key,
                    "parameters": dict(cand.changes),
                    "delta_bic_full_band": dbic_full,
                    "delta_bic_band": n * math.log(rss1 / rss0),
                }
            )
            if better:
                cand.info.setdefault("alias", []).append(
                    {
                        "effect": a.effect.key,
                        "parameters": dict(state.changes),
                        "delta_bic_full_band": -dbic_full,
                        "delta_bic_band": -n * math.log(rss1 / rss0),
                    }
                )
                return cand
    return state


#: effects whose removal costs less than this (linearised BIC) are re-checked by re-simulation
PRUNE_DBIC = 200.0


#: frequencies [Hz] of the lag's comparison table: what tells a delay from a first-order filter of the same phase
#: slope is their difference at the higher frequencies the tests' torque holds (the fundamentals, their harmonics)
LAG_TABLE_HZ = (1.0, 3.0, 10.0, 30.0, 100.0)


def lag_form(dbic: float, dho: float) -> str:
    """The form of a lag from dbic = training BIC (delay - filter) and dho = held-out deviance (delay - filter), the
    two parts of the selection's score (selection.Regression.score): "delay_meas" or "T_meas" where both prefer it
    and together by DELTA_BIC or more; else "not distinguishable"."""
    if dbic <= 0 and dho <= 0 and dbic + dho <= -DELTA_BIC:
        return "delay_meas"
    if dbic >= 0 and dho >= 0 and dbic + dho >= DELTA_BIC:
        return "T_meas"
    return "not distinguishable"


def lag_form_text(choice: str) -> str:
    """The words of a lag's form (``lag_form``) in the verdict and the report."""
    return {
        "delay_meas": "a delay (the training tests and the held-out tests prefer it)",
        "T_meas": "a first-order filter (the training tests and the held-out tests prefer it)",
    }.get(choice) or "delay or filter: not distinguishable on this plan"


def lag_form_check(ctx: Context, state: State, steps: list) -> State:
    """A measurement lag: a pure delay (unit magnitude, phase -omega d growing linearly with frequency) or a
    first-order filter (magnitude 1/sqrt(1 + (omega T)^2) dropping, phase -atan(omega T) bending)? Both alike at
    low frequency; the selection is fitted again by re-simulation with the lag in the other form (every
    parameter of the selection free: the others had adapted to the first), and the two are compared by the same
    information criterion (training BIC, full band: the same number of parameters) and held-out test (held-out
    deviance n ln(RSS_delay / RSS_filter), full band). The delay is named if both prefer it and their sum (the
    selection's score) by DELTA_BIC or more, the filter likewise (``lag_form``); otherwise the lag is named with its
    value and "delay or filter: not
    distinguishable on this plan", the form fitting the training tests better kept in the model. The decision is
    a step ``how: delay or filter`` (named_effects reads it)."""
    for a in state.selected:
        if not _is_lag(a.effect.parameter):
            continue
        T, D = a.effect.parameter, a.effect.parameter.replace("T_meas", "delay_meas")
        as_delay = fitted_parameters(a, state.changes)[0] == D
        cur, other = (D, T) if as_delay else (T, D)
        start = {k: v for k, v in state.changes.items() if k != cur}
        start[other] = float(state.changes[cur])  # the same phase slope at low frequency
        cand = fit_state(ctx, state.selected, start, anchor=state.changes)
        if cand is None:
            failed_step(ctx, state, state.selected, steps, "delay or filter")
            continue
        delay, filt = (state, cand) if as_delay else (cand, state)

        def full(pt: Point, names: Sequence[str]) -> tuple[float, int]:
            return (
                sum(float(np.sum((ctx.model.tests[m].y - pt.obs[m]) ** 2)) for m in names),
                sum(ctx.model.tests[m].y.size for m in names),
            )

        (rd, n), (rf, _) = full(delay.pt, ctx.train), full(filt.pt, ctx.train)
        dbic = n * math.log(rd / rf)
        if ctx.held:
            (hd, nh), (hf, _) = full(delay.pt, ctx.held), full(filt.pt, ctx.held)
            dho = nh * math.log(hd / hf)
        else:
            dho = 0.0
        bd, nb = band_rss(ctx, delay.pt, ctx.train)
        bf, _ = band_rss(ctx, filt.pt, ctx.train)
        diff = math.sqrt(
            sum(float(np.sum((delay.pt.obs[m] - filt.pt.obs[m]) ** 2)) for m in ctx.names)
            / sum(ctx.model.tests[m].y.size for m in ctx.names)
        )
        choice = lag_form(dbic, dho)
        keep = delay if (choice == "delay_meas" or choice == "not distinguishable" and dbic < 0) else filt
        d_val, T_val = float(delay.changes[D]), float(filt.changes[T])
        table = {
            f: {
                "filter_magnitude": 1.0 / math.sqrt(1.0 + (2 * math.pi * f * T_val) ** 2),
                "phase_difference_rad": 2 * math.pi * f * d_val - math.atan(2 * math.pi * f * T_val),
            }
            for f in LAG_TABLE_HZ
        }
        freqs = sorted({ctx.model.tests[m].test.frequency for m in ctx.names if ctx.model.tests[m].test.frequency})
        text = lag_form_text(choice)
        steps.append(
            {
                "how": "delay or filter",
                "effect": a.effect.key,
                "from": [x.label for x in state.selected],
                "to": [x.label for x in keep.selected],
                "accepted": True,
                "filter_parameter": T,
                "delay_parameter": D,
                "T_meas": T_val,
                "delay_meas": d_val,
                "delta_bic_delay_vs_filter": dbic,
                "held_out_deviance_delay_vs_filter": dho,
                "delta_bic_band_delay_vs_filter": nb * math.log(bd / bf),
                "choice": choice,
                "separable": choice != "not distinguishable",
                "text": text,
                "prediction_difference_over_noise": diff / ctx.sigma,
                "test_frequencies_Hz": freqs,
                "filter_vs_delay_at_Hz": table,
                "kept": D if keep is delay else T,
                "parameters_filter": dict(filt.changes),
                "parameters_delay": dict(delay.changes),
                "note": "both forms fitted by re-simulation with every parameter of the selection free; full "
                "band (a filter damps the torque's fast content, a delay only shifts it)",
            }
        )
        ctx.log(
            f"diagnose:   delay or filter ({a.effect.key}): {D} = {1e3 * d_val:.3g} ms against {T} = "
            f"{1e3 * T_val:.3g} ms: dBIC (delay - filter) training {dbic:+.0f}, held-out {dho:+.0f}: {text}"
        )
        state = keep
    return state


def prune(ctx: Context, state: State, steps: list) -> State:
    """Backward check: an effect that the others (refitted) can stand in for is removed if re-simulation
    does not show it strongly needed (e.g. a mass change and an offset cancelling each other's weight).
    Effects found by re-simulation (Stribeck friction, a current limit) are re-checked too: one that entered
    while another effect was still misfitted (far from the data) and no longer explains anything once the
    others are right is not named."""
    state = _prune_linear(ctx, state, steps)
    for a in [a for a in state.selected if a.effect.key in NONLINEAR]:
        rest = tuple(x for x in state.selected if x is not a)
        how = f"backward check (removing {a.effect.key})"
        if rest:
            cand = fit_state(ctx, rest, dict(state.changes))
        else:
            pt = ctx.model.trial({}, ctx.names, how)
            cand = State((), {}, pt) if pt is not None else None
        if cand is None:
            failed_step(ctx, state, rest, steps, how)
        elif verify(ctx, state, cand, steps, how):
            state = cand
    return state


def _prune_linear(ctx: Context, state: State, steps: list) -> State:
    while len(state.selected) > 1:
        linear = [a for a in state.selected if a.effect.key not in NONLINEAR]
        if len(linear) < 2:
            return state
        reg = regression_at(ctx, state, linear, sensitivities=False)
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
            cand = fit_state(ctx, rest, dict(state.changes))
            if cand is None:
                failed_step(ctx, state, rest, steps, f"backward check (removing {a.effect.key})")
                continue
            if verify(ctx, state, cand, steps, f"backward check (removing {a.effect.key})"):
                state, removed = cand, True
                break
        if not removed:
            return state
    return state


def _equivalent(nominal: Mapping, param: str, value: float, other: str) -> float:
    """The value of ``other`` giving the same total reflected inertia as ``param`` = value (both all-axes
    parameters, or both increments on one axis: J1_scale_axis<j>, J_guide_axis<j>)."""
    from fmus.actuator.model import two_inertia

    base, _ = AXIS_OF.get(param, (param, None))
    other_base, _ = AXIS_OF.get(other, (other, None))
    increment = param in AXIS_OF
    J1, J2 = two_inertia(nominal)
    J = two_inertia({**nominal, base: float(nominal[base]) + value if increment else value})
    delta = (J[0] + J[1]) - (J1 + J2)
    start = 0.0 if increment else float(nominal[other_base])
    if other_base == "J_guide":
        return start + delta * float(nominal["i_r"]) ** 2
    if other_base == "J1_scale":
        return start + delta / (J1 / float(nominal["J1_scale"]))
    raise KeyError(other)


def _steps(ctx: Context, state: State, atoms: Sequence[Atom]) -> dict[str, tuple[float, float]]:
    """(value, step) of the re-simulated sensitivity of each plant atom's parameter."""
    out = {}
    for a in atoms:
        if a.effect.kind in ("plant", "controller") and a.effect.parameter not in AXIS_OF:
            p0 = a.effect.parameter
            v0 = float(state.changes.get(p0, ctx.nominal[p0]))
            step = a.effect.step if BOUNDS[p0][0] <= v0 + a.effect.step <= BOUNDS[p0][1] else -a.effect.step
            out[a.label] = (v0, step)
    return out


def regression_at(ctx: Context, state: State, atoms: Sequence[Atom], sensitivities: bool = True) -> Regression:
    """Columns at the current model; the residual taken back to the nominal model (linearised); in the band.

    ``sensitivities``: plant columns re-simulated (exact linearisation of the closed loop, one
    simulation of every test per plant parameter, all in one parallel batch); otherwise the
    effect signatures (no simulation: a screen).
    """
    model, pt, names = ctx.model, state.pt, ctx.names
    if any(a.effect.kind == "controller" for a in tuple(atoms) + tuple(state.selected)):
        sensitivities = True  # a controller gain has no signature: its column is the closed loop's response
    cols = {}
    steps = _steps(ctx, state, atoms) if sensitivities else {}
    if steps:
        model.sim.prefetch(
            [
                {**state.changes, a.effect.parameter: v0 + st}
                for a in atoms
                if a.label in steps
                for v0, st in [steps[a.label]]
            ],
            names,
        )
    for a in atoms:
        if a.label in steps:  # re-simulated sensitivity: the closed loop's own response
            p0 = a.effect.parameter
            v0, step = steps[a.label]
            pt1 = model.trial({**state.changes, p0: v0 + step}, names, "sensitivity")
            if pt1 is not None:
                cols[a.label] = {n: (pt1.obs[n] - pt.obs[n]) / step for n in names}
            elif a.effect.kind == "controller":  # no signature: a zero column, which the selection skips
                cols[a.label] = {n: np.zeros_like(pt.obs[n]) for n in names}
            else:
                cols[a.label] = model.columns(pt, names, p0, a.grid)
        elif a.effect.parameter not in AXIS_OF:
            cols[a.label] = model.columns(pt, names, a.effect.parameter, a.grid if a not in state.selected else None)
    sensitivity = {atom.effect.parameter: atom.label for atom in atoms if atom.label in steps}
    for a in atoms:  # per-axis effects: the all-axes sensitivity on that axis where it was re-simulated
        if a.effect.parameter in AXIS_OF:
            base, j = AXIS_OF[a.effect.parameter]
            if base in sensitivity and sensitivity[base] in cols:
                cols[a.label] = {n: _on_axis(c, j) for n, c in cols[sensitivity[base]].items()}
                steps[a.label] = steps[sensitivity[base]]
            else:
                cols[a.label] = model.columns(pt, names, a.effect.parameter)
    resid = {n: model.tests[n].y - pt.obs[n] for n in names}
    now = dict(resid)  # the current model's residual (the gap each proposal's members must carry a share of)
    for a in state.selected:
        if a.effect.key in NONLINEAR:
            continue
        for pname in fitted_parameters(a, state.changes):
            if pname in state.changes:
                delta = state.changes[pname] - float(ctx.nominal[pname])
                if delta:
                    c = (
                        cols[a.label]
                        if (pname == a.effect.parameter and a.label in cols)
                        else model.columns(pt, names, pname)
                    )
                    for n in names:
                        resid[n] = resid[n] + c[n] * delta

    def banded(d: Mapping[str, np.ndarray], ns: Sequence[str]) -> np.ndarray:
        return (
            np.concatenate([ctx.band.apply(d[n], model.tests[n].test.sample_time).ravel() for n in ns])
            if ns
            else np.zeros(0)
        )

    A_tr = np.column_stack([banded(cols[a.label], ctx.train) for a in atoms]) if atoms else np.zeros((0, 0))
    A_ho = (
        np.column_stack([banded(cols[a.label], ctx.held) for a in atoms])
        if ctx.held and atoms
        else np.zeros((0, len(atoms)))
    )
    if not atoms:  # a library without regression effects (--library backlash): nothing to propose
        A_tr = np.zeros((len(banded(resid, ctx.train)), 0))
        A_ho = np.zeros((len(banded(resid, ctx.held)), 0))
    current = tuple(float(np.sum(banded(now, ns) ** 2)) for ns in (ctx.train, ctx.held))
    reg = Regression(atoms, A_tr, banded(resid, ctx.train), A_ho, banded(resid, ctx.held), ctx.sigma_b, current)
    reg.columns = {a.effect.parameter: cols[a.label] for a in atoms if a.label in steps}
    return reg


def _on_axis(c: np.ndarray, j: int) -> np.ndarray:
    out = np.zeros_like(c)
    out[:, j] = c[:, j]
    return out


def _is_lag(p: str) -> bool:
    return AXIS_OF.get(p, (p,))[0] == "T_meas"


def fitted_parameters(a: Atom, changes: Mapping[str, float]) -> tuple[str, ...]:
    """The parameters of ``a`` as the model ``changes`` holds them: a measurement lag (T_meas, T_meas_axis<j>: a
    first-order filter) held as a delay (delay_meas, delay_meas_axis<j>) when ``changes`` has the delay and not the
    filter."""
    return tuple(
        p.replace("T_meas", "delay_meas")
        if _is_lag(p) and p not in changes and p.replace("T_meas", "delay_meas") in changes
        else p
        for p in a.effect.parameters
    )


def _free_parameters(selected: Sequence[Atom], start: Mapping[str, float]) -> list[str]:
    out = []
    for a in selected:
        out += [p for p in fitted_parameters(a, start) if p not in out]
    return out


def polish(
    ctx: Context,
    selected: Sequence[Atom],
    start: Mapping[str, float],
    columns: Mapping[str, Mapping[str, np.ndarray]],
    fixed: Optional[Mapping[str, float]] = None,
    lag_form: bool = False,
) -> tuple[dict, dict]:
    """Bounded least squares of the selected parameters on the training tests, re-simulating.

    Jacobian: the measurement parameters' columns are exact (no simulation); plant
    parameters start from re-simulated sensitivities (those of the regression, or one
    simulation each at the start) and are updated by Broyden's rank-one formula along the
    iterates, so each iteration costs one simulation of the training tests.
    """
    from scipy.optimize import least_squares

    model, train, sigma = ctx.model, ctx.train, ctx.sigma
    fixed = dict(fixed or {})  # discrete parameters, fitted on their grid (_discrete_fit)
    free = [p for p in _free_parameters(selected, start) if p not in fixed]
    if not free:
        return fixed, {"simulations_of_the_training_tests": 0, "note": "only discrete parameters: fitted on their grid"}
    x0 = np.array([start[p] for p in free], dtype=float)
    lo = np.array([physical_bounds(p, ctx.nominal)[0] for p in free])
    hi = np.array([physical_bounds(p, ctx.nominal)[1] for p in free])
    x0 = np.clip(x0, lo + 1e-9 * (hi - lo), hi - 1e-9 * (hi - lo))
    scale = np.array([max(abs(v), 0.01 * (h - l), 1e-9) for v, l, h in zip(x0, lo, hi)])
    y = np.concatenate([model.tests[n].y.ravel() for n in train])
    count = [0]
    points: dict = {}
    plant = [k for k, p in enumerate(free) if p not in MEASUREMENT]
    sensor = [k for k, p in enumerate(free) if p in MEASUREMENT]

    def at(x: np.ndarray) -> Optional[Point]:
        """The training tests at x; None where they do not simulate (least squares then shrinks its step)."""
        key = tuple(np.round(x, 15))
        if key not in points:
            if len(points) > 8:
                points.clear()
            points[key] = model.trial({**fixed, **dict(zip(free, map(float, x)))}, train, "fit")
            count[0] += 1
        return points[key]

    def obs(pt: Point) -> np.ndarray:
        return np.concatenate([pt.obs[n].ravel() for n in train])

    def fun(x: np.ndarray) -> np.ndarray:
        pt = at(x)
        return np.full(y.shape, 1e3) if pt is None else (y - obs(pt)) / sigma

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
        model.sim.prefetch([{**fixed, **dict(zip(free, map(float, x1)))} for x1, _ in fd.values()], train)
        for k, (x1, d) in fd.items():
            pt1 = at(x1)
            J[:, k] = 0.0 if pt1 is None else -(obs(pt1) - obs(pt)) / d / sigma
        return J

    def jac(x: np.ndarray) -> np.ndarray:
        pt = at(x)
        if pt is None:
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
    sol = least_squares(
        fun, x0, jac=jac, bounds=(lo, hi), x_scale=scale, method="trf", xtol=1e-4, ftol=1e-5, max_nfev=12
    )
    if at(sol.x) is None:  # never worse than the start, which simulates
        sol.x = x0
    values = {**fixed, **dict(zip(free, map(float, sol.x)))}
    info = {
        "simulations_of_the_training_tests": count[0],
        "cost": float(sol.cost),
        "wall_s": round(time.perf_counter() - t0, 1),
        "status": sol.message,
        "jacobian": "exact columns (measurement), re-simulated sensitivities with Broyden updates (plant)",
    }
    for p in [p for p in values if lag_form and _is_lag(p)]:  # a filter or a delay? (a first guess, no re-simulation)
        key = BY_PARAMETER[p].key
        info[key] = _filter_or_delay(model, at(sol.x), p, values[p], train)
        if info[key]["choice"] == "delay_meas":
            values.pop(p)
            values[info[key]["delay_parameter"]] = info[key]["delay_meas"]
    ctx.log(
        "diagnose:   fit "
        + ", ".join(f"{k} = {v:.5g}" for k, v in values.items())
        + f" ({count[0]} simulations of the training tests, {info['wall_s']:.0f} s)"
    )
    return values, info


def _filter_or_delay(model: Model, pt: Point, param: str, value: float, train: Sequence[str]) -> dict:
    """The fitted low-pass ``param`` (T_meas, or T_meas_axis<j> on one axis) against a pure delay on the same
    axes (delay_meas, delay_meas_axis<j>): a 1-D fit of the delay, BIC decides."""
    from scipy.optimize import minimize_scalar

    y = np.concatenate([model.tests[n].y.ravel() for n in train])
    axes = [AXIS_OF[param][1]] if param in AXIS_OF else list(range(pt.chain.drives))
    delay_param = param.replace("T_meas", "delay_meas")

    def rss(chain: Chain) -> float:
        yh = np.concatenate(
            [resample(pt.sims[n], chain.observe(pt.sims[n].tau_m), model.tests[n].t).ravel() for n in train]
        )
        return float(np.sum((y - yh) ** 2))

    T = np.array(pt.chain.T_meas)
    T[axes] -= value  # the filter removed ...
    D = np.array(pt.chain.delay_meas)
    D[axes] -= float(pt.params.get(delay_param, 0.0))

    def delayed(d: float) -> Chain:  # ... and a delay d on the same axes
        Dd = D.copy()
        Dd[axes] += d
        return pt.chain.with_(T_meas=tuple(np.maximum(T, 0.0)), delay_meas=tuple(Dd))

    rss_filter = rss(pt.chain)
    res = minimize_scalar(
        lambda d: rss(delayed(d)), bounds=(0.0, 4 * value + 1e-4), method="bounded", options={"xatol": 1e-6}
    )
    n = len(y)
    dbic = n * math.log(res.fun / rss_filter)
    choice = "delay_meas" if dbic < -DELTA_BIC else "T_meas"
    return {
        "T_meas": value,
        "rss_filter": rss_filter,
        "delay_meas": float(res.x),
        "rss_delay": float(res.fun),
        "delta_bic_delay_vs_filter": dbic,
        "choice": choice,
        "separable": abs(dbic) >= DELTA_BIC,
        "filter_parameter": param,
        "delay_parameter": delay_param,
    }
