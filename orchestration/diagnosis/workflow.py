"""``mast diagnose``: the workflow from the measured data to diagnosis.json and report.md."""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Callable, Optional, Sequence

import numpy as np

from ..data.measured import CommandReplay, MeasuredData, controller_kinematics, load
from .consistency import needs_check, only_consistent
from .crossvalidation import cross_validate
from .effects import AXIS_OF, BY_KEY, CONTROLLER_PARAMETERS, LIBRARY, drive_of, for_drives, noise_std
from .nonlinear import nonlinear_stage, phase_free_stage
from .options import Options, model_overrides, with_parameters
from .plan import choose_split, excitation, excitations, identifiability
from .report import jsonable, plot_figures, write_model, write_report
from .resimulation import DiagnosisError, Model, Prepared, Simulator
from .selection import DELTA_BIC, Atom, Band, atom_labels
from .stages import (
    MAX_EFFECTS,
    NONLINEAR_FIRST,
    Context,
    State,
    alias_check,
    lag_form_check,
    prune,
    regression_loop,
    residual_at_floor,
)
from .verdict import gap_table, gap_trend, judge, localise_test, named_effects


def _split(data: MeasuredData, holdout: Optional[Sequence[str]], library: Sequence[str]) -> tuple[dict[str, str], str]:
    """Role of every test, and how it was decided: ``--holdout`` names the held-out tests, else the roles the data
    give; else the default (every second test in frequency order held out, all training with fewer than three),
    changed as little as possible so that every effect the whole plan can identify gets a training and a held-out
    test of what it needs (plan.choose_split): the default split alone does not decide what can be offered."""
    names = [t.name for t in data.tests]
    if holdout:
        unknown = [h for h in holdout if h not in names]
        if unknown:
            raise DiagnosisError(f"--holdout {', '.join(unknown)}: no such test (tests: {', '.join(names)})")
        return {n: ("held-out" if n in holdout else "training") for n in names}, "--holdout"
    if any(t.role for t in data.tests):
        return {t.name: (t.role or "training") for t in data.tests}, "the roles the data give"
    order = sorted(data.tests, key=lambda t: (t.frequency or 0.0, t.name))
    roles = {t.name: ("held-out" if k % 2 else "training") for k, t in enumerate(order)}
    if len(order) < 3:
        return {t.name: "training" for t in order}, "fewer than three tests: all training"
    chosen = choose_split([excitation(t.name, roles[t.name], t.time, t.rho_cmd) for t in data.tests], library)
    moved = sorted(n for n in names if chosen[n] != roles[n])
    return chosen, (
        "every second test in frequency order held out"
        if not moved
        else "every second test in frequency order held out, but "
        + ", ".join(f"{n} {chosen[n]}" for n in moved)
        + ": so that every effect the whole plan can identify has a training and a held-out test of "
        "what it needs (identifiability table)"
    )


#: how the re-simulations run: (on the native variant, direct composition) -> words
_SIMULATORS = {
    (True, False): "the native FMUs (compiled C; the Python models to 1e-9, tests/test_native.py)",
    (False, True): "the direct composition of the Python models (the reference)",
    (False, False): "the FMUs",
}


def _simulated_ssp(opt: Options) -> tuple[str, bool]:
    """(the SSP whose components re-simulate the tests, direct composition?): ``opt.native`` takes the SSP's
    native variant (build/ssp/native/X.ssp beside build/ssp/X.ssp), run through its FMUs; the parameters,
    the nominal model and the augmented SSP stay those of ``opt.ssp``."""
    if not opt.native:
        return str(opt.ssp), opt.direct
    from ..analyses.bench import native_variant

    native = native_variant(str(opt.ssp))
    if native is None:
        raise DiagnosisError(
            f"{opt.ssp}: no native variant beside it ({Path(opt.ssp).parent / 'native'}): "
            "build it with `mast build --native`, or re-simulate without --native"
        )
    return str(native), False


#: measured / simulated torque (rms) beyond which the nominal model is not what is off, the unit is
TORQUE_SCALE_LIMIT = 10.0

#: cross-validations at most: a selection the re-judgement after the folds changes (stand-ins refused, the
#: regression run again without them) faces the folds again, so what is named has been cross-validated; the
#: cap bounds the cost of a search that keeps finding new stand-ins
CV_ROUNDS = 3


def _check_torque_scale(
    prepared: dict[str, Prepared], simulated: dict[str, np.ndarray], names: Sequence[str], units: dict
) -> None:
    """Before the search: a measured torque 1000 times off what the nominal model needs to follow the
    recorded commands (gravity, inertia, friction) is a unit declared wrong (mN.m for N.m), not an effect."""
    for n in names:
        y, yh = prepared[n].y, simulated[n]
        for j in range(y.shape[1]):
            measured, needed = float(np.sqrt(np.mean(y[:, j] ** 2))), float(np.sqrt(np.mean(yh[:, j] ** 2)))
            if needed > 0 and not 1 / TORQUE_SCALE_LIMIT <= measured / needed <= TORQUE_SCALE_LIMIT:
                key = "i_m" if "i_m" in units and "tau_m" not in units else "tau_m"
                raise DiagnosisError(
                    f"{prepared[n].test.file.name}: column {key}_{j + 1}: the measured torque (rms {measured:.3g} N.m) "
                    f"is {measured / needed:.3g} times what the nominal model needs to follow the recorded commands "
                    f"(rms {needed:.3g} N.m): check units.{key} (now '{units.get(key)}')"
                    + (" and k_T" if key == "i_m" else "")
                )


def _named_only_if_explained(
    ctx: Context,
    state: State,
    last_fit,
    steps: list,
    nominal_pt,
    library,
    atoms,
    rejected: set,
    partner_removed: bool = False,
    excluded: frozenset = frozenset(),
) -> tuple:
    """The verdict on the search's selection, and what of it is named (consistency.py): when a residual is left,
    or several effects share the gap, only effects that are one value whatever the test keep their name. When
    members were refused as stand-ins and the structure they absorbed is left (training BIC +DELTA_BIC without
    them), the effects whose trace the linear ones mimic (``after_stand_ins``: the transmission stiffness) are
    tried by re-simulation from the model kept (the members kept refitted with them); if the structure is still
    left, the regression loop runs again from the model kept without the refused stand-ins among its candidates
    (the cause they stood in for may be another effect of the library, which they had crowded out: a measurement
    delay beside a heavier motor side, SMALL seed 332). What is accepted is checked again; ``partner_removed``:
    the cross-validation took out a member the folds do not confirm, so what is left is checked even alone at the
    floor (``needs_check``); ``excluded``: effects an earlier round refused or the folds did not confirm, left out
    of the regression run again too. Returns (state, named effects, verdict, unexplained, last_fit)."""
    named = named_effects(ctx, state, last_fit, steps)
    verdict, unexplained = judge(ctx, state, last_fit, steps)
    if not needs_check(state, verdict["status"], partner_removed):
        return state, named, verdict, unexplained, last_fit
    state, hints = only_consistent(ctx, state, named, steps, nominal_pt)

    def recheck(tried: State, hints: list) -> tuple:
        named = named_effects(ctx, tried, last_fit, steps)
        verdict, unexplained = judge(ctx, tried, last_fit, steps)
        if not needs_check(tried, verdict["status"]):
            return tried, [], (named, verdict, unexplained)
        tried, again = only_consistent(ctx, tried, named, steps, nominal_pt)
        known = {x["key"] for x in again} | {a.effect.key for a in tried.selected}
        return tried, again + [h for h in hints if h["key"] not in known], None

    later = [e for e in library if e.after_stand_ins and not any(a.effect.key == e.key for a in state.selected)]
    if hints and later and state.info["structure_left"] >= DELTA_BIC and len(state.selected) < MAX_EFFECTS:
        ctx.log("diagnose: stand-ins refused, their structure left: trying " + ", ".join(e.title for e in later))
        tried = nonlinear_stage(ctx, state, later, rejected, steps)
        if tried is not None:  # accepted beside the members kept (refitted with it): checked again, once
            state, hints, done = recheck(tried, hints)
            if done:
                return (state, *done, last_fit)
    refused = {h["key"] for h in hints} | excluded
    if hints and state.info["structure_left"] >= DELTA_BIC and len(state.selected) < MAX_EFFECTS:
        ctx.log(
            "diagnose: stand-ins refused (" + ", ".join(sorted(refused)) + "), their structure left: the "
            "regression again without them"
        )
        before = atom_labels(state.selected)
        tried, fit = regression_loop(ctx, state, [a for a in atoms if a.effect.key not in refused], rejected, steps)
        if atom_labels(tried.selected) != before:
            tried = lag_form_check(ctx, prune(ctx, tried, steps), steps)
            last_fit = fit
            state, hints, done = recheck(tried, hints)
            if done:
                return (state, *done, last_fit)
    named = named_effects(ctx, state, last_fit, steps)
    verdict, unexplained = judge(ctx, state, last_fit, steps, state.info["structure_left"] if hints else None)
    if hints:
        where = "unexplained" if unexplained is not None else "verdict"
        (unexplained if unexplained is not None else verdict)["hints"] = hints
        verdict["text"] += (
            "; hints, not named (they may only stand in for a cause outside the library: "
            f"{where}.hints): " + ", ".join(h["effect"] for h in hints)
        )
    for e in named:  # named after the check: the evidence that allowed it
        e["evidence"]["per_test"] = {
            p: state.info["consistency"][p] for p in e["parameters"] if p in state.info["consistency"]
        }
        e["evidence"]["excess_explained"] = state.info["excess_explained"]
    return state, named, verdict, unexplained, last_fit


def diagnose(opt: Options, log: Callable[[str], None] = print) -> dict:
    """The five steps of the package docstring on the measured-data folder ``opt.measured``; writes
    diagnosis.json, report.md, the figures and the augmented model to ``opt.out`` and returns the
    diagnosis (the content of diagnosis.json)."""
    from ..data.record import is_record_folder

    if is_record_folder(opt.measured):  # a record of any machine (mast import): a drive axis on a bench
        from .records import diagnose_records

        return diagnose_records(opt, log)
    t_start = time.perf_counter()
    sim_ssp, direct = _simulated_ssp(opt)
    from ..core.build import block_class
    from ..core.ssp import SSPArchive

    with SSPArchive(opt.ssp) as archive:
        system = archive.system
        actuators = [n for n in system.components if n.startswith("actuator_")]
        if sorted(actuators) != [f"actuator_{k}" for k in range(1, len(actuators) + 1)]:
            raise DiagnosisError(
                f"{opt.ssp}: expected actuator components actuator_1..n, one per drive, found {', '.join(actuators)}"
            )
        actuators = [f"actuator_{k}" for k in range(1, len(actuators) + 1)]
        # its own parameters: a set bound to the actuators and the controller (drive.ssv) holds both's
        own = {p.name for p in block_class(Path(system.components[actuators[0]].source).stem).PARAMETERS}
        ssp_actuator = {k: v for k, v in system.components[actuators[0]].parameters.items() if k in own}
        drive = system.components.get("controller")
        # the drive's parameters the library can change, and the quanta of the discrete ones (T_cur)
        wanted = set(CONTROLLER_PARAMETERS) | {e.quantum for e in LIBRARY if e.kind == "controller" and e.quantum}
        ssp_drive = {k: float(drive.parameters[k]) for k in wanted if drive is not None and k in drive.parameters}
    stroke = (float(ssp_actuator["rho_min"]), float(ssp_actuator["rho_max"]))
    drives = len(actuators)
    data = load(opt.measured, stroke=stroke, drives=drives)
    try:
        keys = for_drives(opt.library, drives)
    except ValueError as err:
        raise DiagnosisError(f"library: {err} ({opt.ssp})") from None
    model_over = model_overrides(opt.ssp, opt.model)
    nominal = {**ssp_drive, **ssp_actuator, **model_over, **{p: 0.0 for p in AXIS_OF if drive_of(p) <= drives}}
    base = with_parameters({a: dict(model_over) for a in actuators} if model_over else {}, opt)
    kinematics = controller_kinematics(opt.ssp)
    roles, split_how = _split(data, opt.holdout, keys)
    prepared: dict[str, Prepared] = {}
    for t in data.tests:
        mask = t.time >= t.settle_s - 1e-12
        prepared[t.name] = Prepared(
            t,
            roles[t.name],
            CommandReplay(t.time, t.rho_cmd, kinematics),
            mask,
            t.time[mask],
            t.tau_m[mask],
            (t.rho - t.rho_cmd)[mask],
        )
    names = [t.name for t in data.tests]
    plan = identifiability(excitations(prepared, roles), keys)
    for key, p in plan.items():
        if not p["plan_meets"] and "_axis" not in key:
            log(f"diagnose: this plan cannot tell {BY_KEY[key].title}: it needs {p['requires']} ({p['why_not']})")
        elif p["plan_meets"] and not p["split_meets"]:
            log(
                f"diagnose: this split ({split_how}) cannot check {BY_KEY[key].title}, the plan could: it needs "
                f"{p['requires']} ({p['split_why_not']})"
            )
    for j in range(1, drives + 1):  # effects on one axis: one line per axis
        blind = [k.rsplit("_axis", 1)[0] for k, p in plan.items() if k.endswith(f"_axis{j}") and not p["plan_meets"]]
        if blind:
            log(
                f"diagnose: this plan cannot tell effects on axis {j} alone ({', '.join(blind)}): they need "
                "what the all-axes effect needs, in tests where that axis moves"
            )
    train = [n for n in names if roles[n] == "training"]
    held = [n for n in names if roles[n] == "held-out"]
    sigma = float(np.median([noise_std(prepared[name].y[:, j]) for name in names for j in range(drives)]))
    if not sigma > 0:
        raise DiagnosisError("the torque noise floor came out as 0: are the torques quantised coarsely or constant?")
    resolution = float(data.meta.get("measurement", {}).get("rho_resolution_m", 0.0) or 0.0)
    band = Band()
    sigma_b = sigma * float(np.median([band.noise_factor(prepared[n].test.sample_time) for n in names]))
    log(
        f"diagnose: {len(names)} tests ({len(train)} training, {len(held)} held-out: {', '.join(held) or 'none'}; "
        f"{split_how}), torque noise floor {1e3 * sigma:.3g} mN.m"
    )

    log(f"diagnose: re-simulating on {_SIMULATORS[(sim_ssp != opt.ssp, direct)]} ({sim_ssp})")
    with Simulator(sim_ssp, prepared, base, actuators, direct=direct, workers=opt.workers, nominal=nominal) as sim:
        model = Model(sim, nominal, prepared, data.torque_filter_s, data.torque_delay_s)
        ctx = Context(model, nominal, names, train, held, band, sigma, sigma_b, log)
        nominal_pt = model.point({}, names)
        _check_torque_scale(prepared, nominal_pt.obs, names, data.meta.get("units", {}))
        before = gap_table(prepared, nominal_pt, names, sigma, resolution)
        localised = {n: localise_test(model, nominal_pt, prepared[n], sigma) for n in names}
        log("diagnose: nominal model: " + ", ".join(f"{n} {before[n]['torque_nrmse_percent']:.1f} %" for n in names))

        # controller-side effects need the SSP's controller (its gains k_p, k_v)
        # per-axis effects the plan cannot tell (an axis that does not move in both roles) are not offered:
        # the held-out check would refuse them, and each costs the subset search a column
        library = [
            BY_KEY[k]
            for k in keys
            if (
                BY_KEY[k].kind != "controller"
                or all(
                    p in ssp_drive for p in BY_KEY[k].parameters + ((BY_KEY[k].quantum,) if BY_KEY[k].quantum else ())
                )
            )
            and ("_axis" not in k or plan.get(k, {}).get("split_meets", True))
        ]
        atoms = [Atom(e, g) for e in library if e.regression for g in (e.grid or (None,))]
        state = State((), {}, nominal_pt)
        steps: list = []
        rejected: set = set()
        state, last_fit = regression_loop(ctx, state, atoms, rejected, steps)
        for _ in range(2):  # nonlinear candidates, then the regression loop again around the new model
            if residual_at_floor(ctx, state.pt) or len(state.selected) >= MAX_EFFECTS:
                break
            tried = nonlinear_stage(ctx, state, [e for e in library if e.key in NONLINEAR_FIRST], rejected, steps)
            if tried is None:
                break
            state, last_fit = regression_loop(ctx, tried, atoms, rejected, steps)
        state = alias_check(ctx, state, last_fit, steps)
        state = prune(ctx, state, steps)
        state = lag_form_check(ctx, state, steps)
        for e in library:  # effects that make the loop hunt: last, on the phase-free score
            if e.phase_free and not residual_at_floor(ctx, state.pt) and len(state.selected) < MAX_EFFECTS:
                state = phase_free_stage(ctx, state, e, steps)
        state, named, verdict, unexplained, last_fit = _named_only_if_explained(
            ctx, state, last_fit, steps, nominal_pt, library, atoms, rejected
        )
        tests = excitations(prepared, roles)
        excluded: frozenset = frozenset()  # refused as stand-ins or not confirmed by the folds: not tried again
        for _ in range(CV_ROUNDS):  # what is named has faced the folds
            judged = state
            state, cv = cross_validate(ctx, state, steps, tests)
            if state is judged and not cv.get("lag_form", {}).get("changed"):
                break
            # a member the folds do not confirm removed, or the lag's form decided otherwise: judged again
            validated = set(atom_labels(state.selected))
            gone = {a.effect.key for a in judged.selected} - {a.effect.key for a in state.selected}
            excluded |= gone | {h["key"] for h in (unexplained or verdict).get("hints", [])}
            state, named, verdict, unexplained, last_fit = _named_only_if_explained(
                ctx, state, last_fit, steps, nominal_pt, library, atoms, rejected, bool(gone), excluded
            )
            if set(atom_labels(state.selected)) <= validated:  # nothing new the folds have not judged
                break
        for e in named:  # the folds' evidence for each named effect (crossvalidation.py)
            if e["key"] in cv.get("effects", {}):
                e["evidence"]["cross_validation"] = cv["effects"][e["key"]]
        final_pt = state.pt
        after = gap_table(prepared, final_pt, names, sigma, resolution)
        final_local = {n: localise_test(model, final_pt, prepared[n], sigma) for n in names}
        n_sims, sim_seconds = sim.count, sim.seconds

    opt.out.mkdir(parents=True, exist_ok=True)
    outputs = write_model(opt, state.changes, named, nominal, model_over)
    wall = time.perf_counter() - t_start
    doc = {
        "measured": str(opt.measured),
        "ssp": str(opt.ssp),
        "model": opt.model or "the SSP's bindings",
        "tests": [
            {
                "name": n,
                "label": prepared[n].test.label(),
                "role": roles[n],
                "frequency_Hz": prepared[n].test.frequency,
                "motion": prepared[n].test.motion,
                "localise_before": localised[n],
                "localise_after": final_local[n],
            }
            for n in names
        ],
        "noise_floor": {
            "torque_std_Nm": sigma,
            "method": "robust (MAD) third differences of the measured torques, median over tests and axes",
            "torque_std_in_band_Nm": sigma_b,
            "band_Hz": band.fc,
            "position_resolution_m": resolution or None,
            "per_test_torque_nrmse_percent": {n: before[n]["torque_floor_percent"] for n in names},
        },
        "named_effects": named,
        "gap": {n: {"role": roles[n], "before": before[n], "after": after[n]} for n in names},
        "frequency_trend": gap_trend(prepared, localised, final_local, names),
        "verdict": verdict,
        "unexplained": unexplained,
        "steps": steps,
        "failed_simulations": model.failures,
        "identifiability": plan,
        "split": {"how": split_how, "held_out": held, "training": train},
        "cross_validation": cv,
        "augmented_model": outputs,
        "timing": {
            "wall_s": round(wall, 1),
            "simulations": n_sims,
            "simulation_wall_s": round(sim_seconds, 1),
            "workers": opt.workers,
            "direct": direct,
            "simulator": _SIMULATORS[(sim_ssp != opt.ssp, direct)],
            "simulated_ssp": str(sim_ssp),
        },
    }
    (opt.out / "diagnosis.json").write_text(json.dumps(jsonable(doc), indent=2))
    if opt.figures:
        figs = plot_figures(
            opt.out,
            model,
            prepared,
            names,
            nominal_pt,
            final_pt,
            sigma,
            roles,
            unexplained is not None,
            state.info.get("phase_free"),
        )
    else:
        figs = {}
    write_report(opt.out, doc, figs)
    log(f"diagnose: {verdict['status']}: {verdict['text']}")
    log(f"diagnose: wrote {opt.out / 'diagnosis.json'}, {opt.out / 'report.md'} in {wall:.0f} s")
    return doc
