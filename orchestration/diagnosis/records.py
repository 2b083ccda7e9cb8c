"""`mast diagnose` on a record of any machine (mast.data.record): a drive axis on a test bench.

The same five steps as on the MAST (workflow.py), on a record folder written by `mast import`
and a model whose plant is a load-side axis (fmus/actuator/load_axis.py, the library
``effects.AXIS_LIBRARY``), with no assumption on the motion (no sine tests: EMPS drives its
axis with bang-bang acceleration profiles):

1. Localise: the model is driven by the record's commands and injected inputs; the residual
   of every effort signal (measured - simulated force) is located (velocity reversals, peak
   acceleration, bias, correlations with sign(velocity), velocity, acceleration).
2. Name: the residual, low-passed and decimated (selection.Band), is regressed on the
   library's columns along the simulated motion: the inverse-dynamics signatures, where the
   MAST uses re-simulated sensitivities. A position loop that tracks to 0.02 % moves the
   load along the reference whatever the plant, so the force a plant change costs is its
   inverse dynamics along that motion (on EMPS the first re-simulated Gauss-Newton step
   from the regression estimate lowers the cost by 0.6 % only), and the fit below corrects
   what the signatures miss, without one simulation per parameter. Every subset is scored by BIC
   on the training samples plus the held-out deviance, each member must be needed on both
   (selection.select, the MAST's rules). Asymmetries are tried only once the friction they
   refine is named (stage "refine"), so the symmetric model is found first and reported.
3. Add and fit: the named parameters are fitted by re-simulation of the training part
   (Gauss-Newton on the full-band force residual, the Jacobian from the signatures at every
   new simulation, step halving when the cost rises); accepted only if re-simulation lowers
   the training BIC by 10 and the held-out residual measurably.
4. Show: gap before and after per signal (relative error 100 ||y - y_sim|| / ||y|| and fit),
   on the training part, the held-out part and the whole record; the augmented parameter
   set (.ssv) and SSP in OUT.
5. Verdict: what is left, against the noise floor of the effort (third differences), and
   where it concentrates (report.md).

Held-out data: the tests named by ``--holdout``, else those the record's meta.json marks
``held-out``, else the last third of every test (``--holdout-fraction``; the first two
thirds train: the same machine, later in the record).
"""

from __future__ import annotations

import json
import math
import time
from typing import Callable, Sequence

import numpy as np

from ..analyses.replay import fit_pct, relative_error_pct
from ..data.record import RecordSet, load_records
from .axis_model import AxisModel, Case, Diagnosis, Point
from .effects import AXIS_LIBRARY, Effect, localise
from .report import jsonable
from .resimulation import DiagnosisError
from .selection import DELTA_BIC, Atom, Band, select

#: the share of every test held out when the record marks no held-out test
HELD_OUT_FRACTION = 1.0 / 3.0


def _cases(records: RecordSet, fraction: float, holdout: Sequence[str] = ()) -> tuple[list[Case], str]:
    """The tests with their training and held-out samples: the tests named in ``holdout`` (--holdout), else
    those meta.json marks held-out, else the last ``fraction`` of every test."""
    names = [t.name for t in records.tests]
    unknown = [h for h in holdout if h not in names]
    if unknown:
        raise DiagnosisError(f"--holdout {', '.join(unknown)}: no such test (tests: {', '.join(names)})")
    if holdout and len(holdout) == len(names):
        raise DiagnosisError("--holdout names every test: nothing is left to train on")
    cases = []
    roles = (
        {t.name: ("held-out" if t.name in holdout else "training") for t in records.tests}
        if holdout
        else {t.name: t.role for t in records.tests}
    )
    marked = any(roles.values())
    for rec in records.tests:
        efforts = [s.name for s in rec.of_kind("effort")]
        if not efforts:
            raise DiagnosisError(f"{rec.file.name}: no signal of kind 'effort' to diagnose")
        keep = rec.time >= rec.settle_s - 1e-12
        if marked:
            held = keep & (roles[rec.name] == "held-out")
            train = keep & (roles[rec.name] != "held-out")
        else:
            cut = rec.time[keep][0] + (1.0 - fraction) * (rec.duration - rec.time[keep][0])
            train, held = keep & (rec.time < cut), keep & (rec.time >= cut)
        cases.append(Case(rec, train, held, efforts))
    how = (
        f"the tests {', '.join(holdout)} (--holdout)"
        if holdout
        else "the tests meta.json marks held-out"
        if marked
        else f"the last {fraction:.3g} of every test (t >= {(1 - fraction):.3g} x its duration); the rest trains"
    )
    return cases, how


def _plant(ssp: str, library: Sequence[Effect]) -> tuple[str, dict]:
    from ..core.ssp import SSPArchive

    needed = {p for e in library for p in e.parameters}
    with SSPArchive(ssp) as archive:
        for name, comp in archive.system.components.items():
            if needed <= set(comp.parameters):
                return name, dict(comp.parameters)
    raise DiagnosisError(
        f"{ssp}: no component has the load-axis parameters {', '.join(sorted(needed))} "
        "(fmus/actuator/load_axis.py, e.g. build/ssp/EMPS_bench.ssp)"
    )


def gap(cases: Sequence[Case], pt: Point) -> dict:
    """Per test and measured signal: relative error and fit [%] on the training, held-out and whole record."""
    out = {}
    for c in cases:
        rec = c.record
        table = {}
        for s in rec.of_kind("position", "velocity", "effort"):
            y, ys = rec.values[s.name], pt.sims[c.name][s.name]
            row = {"kind": s.kind}
            for part, mask in (("training", c.train), ("held-out", c.held), ("whole", c.train | c.held)):
                if mask.any():
                    row[part] = {
                        "relative_error_pct": relative_error_pct(y[mask], ys[mask]),
                        "fit_pct": fit_pct(y[mask], ys[mask]),
                        "rms": float(np.sqrt(np.mean((y[mask] - ys[mask]) ** 2))),
                    }
            table[s.name] = row
        out[c.name] = table
    return out


#: the held-out residual of every effort within this factor of the noise floor: nothing left to explain
AT_FLOOR = 1.2


def _verdict(diag: Diagnosis, after: dict, localised: dict, effects: Sequence[dict]) -> dict:
    """nothing missing / explained (held-out residual at the noise floor) / unexplained residual (where it is)."""
    ratios = {}
    for c in diag.cases:
        for s in c.efforts:
            part = after[c.name][s].get("held-out") or after[c.name][s]["whole"]
            ratios[f"{c.name}.{s}"] = part["rms"] / diag.sigma
    worst = max(ratios.values())
    if worst <= AT_FLOOR:
        status = "explained" if effects else "nothing missing"
        text = f"held-out effort residual within {AT_FLOOR:g} x the noise floor" + (
            f" with {', '.join(e['effect'] for e in effects)}" if effects else ""
        )
    else:
        status = "unexplained residual"
        where = "; ".join(f"{k}: {v['summary']}" for k, v in localised.items())
        text = (
            f"after {', '.join(e['effect'] for e in effects) or 'nothing named'}, the held-out effort residual is "
            f"{worst:.3g} x the noise floor, outside the library: {where}"
        )
    return {"status": status, "text": text, "residual_over_noise_held_out": ratios}


def _localise(diag: Diagnosis, pt: Point) -> dict:
    out = {}
    for c in diag.cases:
        v, a = diag.model.motion(pt, c)
        for s in c.efforts:
            r = pt.residual(c, s)
            out[f"{c.name}.{s}"] = localise(c.record.time, r[:, None], v[:, None], a[:, None], None, diag.sigma)
    return out


def diagnose_records(opt, log: Callable[[str], None] = print) -> dict:
    """``mast diagnose`` on a record folder (module docstring); ``opt`` is options.Options."""
    from .options import model_overrides, with_parameters

    t_start = time.perf_counter()
    records = load_records(opt.measured)
    library = AXIS_LIBRARY
    component, bound = _plant(opt.ssp, library)
    model_over = model_overrides(opt.ssp, opt.model) if opt.model else {}
    by_key = {e.key: e for e in library}
    nominal = {p: float({**bound, **model_over}[p]) for e in library for p in e.parameters}
    bounds = {p: e.bounds[p] for e in library for p in e.parameters}
    fraction = opt.holdout_fraction or HELD_OUT_FRACTION
    if not 0.0 < fraction < 1.0:
        raise DiagnosisError(f"--holdout-fraction {fraction!r}: expected a share between 0 and 1")
    cases, holdout_how = _cases(records, fraction, tuple(opt.holdout or ()))
    base = with_parameters({component: dict(model_over)} if model_over else {}, opt)
    model = AxisModel(opt.ssp, cases, component, base, direct=opt.direct)
    diag = Diagnosis(model, cases, Band(), log)
    log(
        f"diagnose: {records.machine}: {len(cases)} test(s), held out: {holdout_how}; force noise floor "
        f"{diag.sigma:.3g} N"
    )

    steps: list = []
    values = dict(nominal)
    pt0 = model.point(values)
    before = gap(cases, pt0)
    localised_before = _localise(diag, pt0)
    named: list[str] = []  # effect keys, in the order named
    stds: dict = {}
    symmetric = None
    stage_sets = (("name", [e for e in library if not e.refines]), ("refine", list(library)))
    for stage, candidates in stage_sets:
        rejected: set = set()
        for _round in range(4):
            pt = model.point(values)
            pool = [e for e in candidates if (not e.refines or e.refines in named)]
            atoms = [Atom(e) for e in pool]
            reg = diag.regression(pt, atoms)
            best, fits = select(reg, values, max_size=len(atoms), exclude=frozenset(rejected), library=library)
            keys = [a.effect.key for a in best.atoms]
            new = [k for k in keys if k not in named]
            proposal = {
                a.effect.key: {"parameter": a.effect.parameter, "change": float(c)}
                for a, c in zip(best.atoms, best.coef)
            }
            step = {
                "stage": stage,
                "proposed": keys,
                "new": new,
                "regression": proposal,
                "delta_bic_regression": float(reg.fit(()).bic - best.bic),
                "admissible_subsets": sum(f.admissible for f in fits),
            }
            if not new:
                step["result"] = "nothing new"
                steps.append(step)
                break
            # drop members of a group an effect of the proposal replaces (offset <-> Coulomb asymmetry)
            groups = {by_key[k].group for k in keys if by_key[k].group}
            trial_named = [k for k in named if k in keys or by_key[k].group not in groups] + new
            free = [by_key[k].parameter for k in trial_named]
            start = dict(values)
            for _k, change in proposal.items():
                p = change["parameter"]
                start[p] = float(np.clip(values[p] + change["change"], *bounds[p]))
            for k in named:
                if k not in trial_named:
                    start[by_key[k].parameter] = nominal[by_key[k].parameter]
            fitted, info = diag.fit(start, free, bounds)
            old_tr, n_tr, old_ho, n_ho = diag.band_rss(pt)
            new_pt = model.point(fitted)
            new_tr, _, new_ho, _ = diag.band_rss(new_pt)
            k_old = len(named)
            k_new = len(trial_named)
            dbic = (n_tr * math.log(new_tr / n_tr) + k_new * math.log(n_tr)) - (
                n_tr * math.log(old_tr / n_tr) + k_old * math.log(n_tr)
            )
            needed = reg.held_out_needed(old_ho) if n_ho else 0.0
            confirmed = dbic <= -DELTA_BIC and (not n_ho or old_ho - new_ho >= needed)
            step.update(
                {
                    "fitted": {p: fitted[p] for p in free},
                    "fit": info,
                    "delta_bic_training": dbic,
                    "held_out_rss_change_percent": 100.0 * (new_ho - old_ho) / old_ho if n_ho else None,
                    "confirmed": confirmed,
                }
            )
            steps.append(step)
            held = f", held-out {step['held_out_rss_change_percent']:+.1f} %" if n_ho else ""
            log(
                f"diagnose: {stage}: proposed {', '.join(keys)}; re-simulation dBIC {dbic:.1f}{held}: "
                f"{'confirmed' if confirmed else 'refused'}"
            )
            if not confirmed:
                rejected.add(tuple(sorted(keys)))
                break
            named, values, stds = trial_named, fitted, info["std"]
        if stage == "name":
            pt_sym = model.point(values)
            symmetric = {
                "named": list(named),
                "values": {by_key[k].parameter: values[by_key[k].parameter] for k in named},
                "std": dict(stds),
                "gap": gap(cases, pt_sym),
            }

    final = model.point(values)
    after = gap(cases, final)
    effects_doc = []
    for k in named:
        e = by_key[k]
        p = e.parameter
        effects_doc.append(
            {
                "effect": e.title,
                "key": k,
                "parameters": {p: values[p]},
                "nominal": {p: nominal[p]},
                "uncertainty": {
                    p: {
                        "std": stds.get(p),
                        "ci95": [values[p] - 1.96 * stds[p], values[p] + 1.96 * stds[p]]
                        if stds.get(p) is not None
                        else None,
                    }
                },
                "signature": e.signature,
            }
        )
    asym = {}
    for k, mean, delta in (("viscous", "F_v", "dF_v"), ("coulomb", "F_c", "dF_c")):
        asym[k] = {
            "asymmetric": any(e["key"] == f"{k}_asymmetry" for e in effects_doc),
            "positive_velocity": values[mean] + values[delta],
            "negative_velocity": values[mean] - values[delta],
        }
    floor_pct = {}
    for c in cases:
        for s in c.efforts:
            y = c.record.values[s][c.held] if c.held.any() else c.record.values[s]
            floor_pct[f"{c.name}.{s}"] = 100.0 * diag.sigma / float(np.sqrt(np.mean(y**2)))
    localised_after = _localise(diag, final)
    verdict = _verdict(diag, after, localised_after, effects_doc)
    wall = time.perf_counter() - t_start
    doc = {
        "measured": str(opt.measured),
        "ssp": str(opt.ssp),
        "machine": records.machine,
        "component": component,
        "model": opt.model or "the SSP's bindings",
        "held_out": holdout_how,
        "noise_floor": {
            "effort_std": diag.sigma,
            "method": "robust (MAD) third differences of the measured effort",
            "band_Hz": diag.band.fc,
            "relative_error_pct": floor_pct,
        },
        "named_effects": effects_doc,
        "asymmetry": asym,
        "symmetric_model": symmetric,
        "gap": {"before": before, "after": after},
        "localise": {"before": localised_before, "after": localised_after},
        "verdict": verdict,
        "steps": steps,
        "values": values,
        "nominal": nominal,
        "timing": {"wall_s": round(wall, 1), "simulations": model.count, "simulation_wall_s": round(model.seconds, 1)},
    }
    opt.out.mkdir(parents=True, exist_ok=True)
    from .records_report import write_outputs

    doc["augmented_model"] = write_outputs(opt, doc, component, model, cases, pt0, final, diag)
    (opt.out / "diagnosis.json").write_text(json.dumps(jsonable(doc), indent=2))
    log(f"diagnose: {verdict['status']}: {verdict['text']}")
    log(f"diagnose: wrote {opt.out / 'diagnosis.json'}, {opt.out / 'report.md'} in {wall:.0f} s")
    return doc
