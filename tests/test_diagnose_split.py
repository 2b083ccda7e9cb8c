"""`mast diagnose` (issue 29): an effect the whole plan can identify is found whatever the default split, and a
measurement lag is named a delay or a filter by what separates them, both fitted.

Two plans away from those of tests/test_diagnose.py and docs/ (and their values and seeds): PLAN_A, five tests
of the issue's kind (z 0.8, 3.3, 5.8 Hz; psi 1.7 Hz, theta 4.2 Hz), whose default split (every second test in
frequency order) holds out psi and theta only: no held-out fast test moves actuator 2 (psi moves actuator 2
alone, theta actuators 1 and 3). PLAN_B, three short tests (z 2.5 Hz, psi 3 Hz, z 6 Hz), whose default split
holds out psi alone: no held-out test moves actuators 1 and 3. The data are synthesized by the Python models
(the reference), the diagnoses re-simulate on the native form of the fixture's system (``compiled``).
"""

from __future__ import annotations

import numpy as np
import pytest
from docs_figures import figures
from test_diagnose import PLAN, ROOT, SMALL, built_ssp, compiled, named  # noqa: F401  (the module's fixture)

from mast.analyses.synthesize import TestSpec as Spec
from mast.analyses.synthesize import synthesize
from mast.diagnosis import Options, diagnose

#: docs/figures.py DIAGNOSE_PLAN_A (docs/diagnose.md states the cross-validation of a diagnosis on it)
PLAN_A = tuple(Spec(*test) for test in figures.DIAGNOSE_PLAN_A)
PLAN_B = tuple(Spec(*test) for test in figures.DIAGNOSE_PLAN_B)


def run(ssp: str, tmp, truth: dict, plan, seed: int) -> dict:
    data = tmp / "data"
    synthesize(ssp, data, truth, tests=plan, direct=True, seed=seed, log=lambda *_: None)
    return diagnose(Options(data, tmp / "out", compiled(ssp), figures=False, direct=False), log=lambda *_: None)


def excitations(plan, roles=None):
    """The plan's tests as the diagnosis reads them (plan.excitation), from their commanded joint motion."""
    from fmus.mechanism.kinematics import Geometry, inverse_kinematics
    from mast.core.ssp import read_ssd
    from mast.diagnosis.plan import excitation

    geometry = Geometry.checked(
        dict(read_ssd(ROOT / "ssp" / "MAST.ssd").components["controller"].parameters), "controller"
    )
    order = sorted(plan, key=lambda s: s.frequency)
    out = []
    for s in plan:
        t = np.arange(0.0, s.stop_time(), 1e-3)
        q = s.amplitude * np.sin(2 * np.pi * s.frequency * t)
        pose = {m: q if s.motion == m else 0 * q for m in ("z", "psi", "theta")}
        rho = np.array([inverse_kinematics(geometry, *p) for p in zip(pose["z"], pose["psi"], pose["theta"])])
        role = (roles or {}).get(s.name) or ("held-out" if order.index(s) % 2 else "training")
        out.append(excitation(s.name, role, t, rho))
    return out


def test_the_split_gives_every_effect_the_plan_can_identify_a_test_on_each_side():
    """No simulation: on PLAN_A the default split has no held-out fast test that moves actuator 2, the plan has
    two (z 3.3 and 5.8 Hz): inertia on axis 2 is identifiable by the plan, not by that split, and the chosen split
    meets it and every effect the default met, moving as few tests as it can. A plan with one fast test that
    moves an axis truly cannot identify inertia on that axis alone, whatever the split, and says so."""
    from mast.diagnosis.effects import LIBRARY
    from mast.diagnosis.plan import Excitation, choose_split, identifiability

    library = [e.key for e in LIBRARY]
    tests = excitations(PLAN_A)
    default = identifiability(tests, library)
    assert default["inertia_motor_axis2"]["plan_meets"] and not default["inertia_motor_axis2"]["split_meets"]
    assert "no such held-out test" in default["inertia_motor_axis2"]["split_why_not"]
    roles = choose_split(tests, library)
    chosen = identifiability(
        [Excitation(x.name, roles[x.name], x.frequency, x.alike, x.moving) for x in tests], library
    )
    assert all(p["split_meets"] for p in chosen.values() if p["plan_meets"]), chosen
    assert sum(roles[x.name] != x.role for x in tests) == 2  # one z test out, theta in
    assert sum(r == "held-out" for r in roles.values()) == 2
    # the compact plan's default split already meets everything: kept
    compact = excitations(PLAN)
    assert choose_split(compact, library) == {x.name: x.role for x in compact}
    # SMALL: Coulomb friction on axis 1 alone would need z 5 Hz held out, the fastest z test: it stays in training
    assert choose_split(excitations(SMALL), library) == {x.name: x.role for x in excitations(SMALL)}
    # one fast test moving actuators 1 and 3 (z 5 Hz; psi moves actuator 2 alone): not identifiable on axis 1
    small = identifiability(excitations(SMALL), library)
    assert not small["inertia_motor_axis1"]["plan_meets"] and not small["inertia_motor_axis1"]["split_meets"]
    assert "only one such test in the plan (z_5Hz)" in small["inertia_motor_axis1"]["why_not"]
    assert small["inertia_motor_axis2"]["plan_meets"]


#: a per-axis inertia change on each axis in turn with an all-axes viscous change (docs/figures.py DIAGNOSE_PER_AXIS,
#: whose values docs/diagnose.md states). On PLAN_A the default split leaves axis 2 without a held-out fast test, on
#: PLAN_B axes 1 and 3
PER_AXIS = figures.DIAGNOSE_PER_AXIS


@pytest.mark.parametrize("case", list(PER_AXIS))
def test_a_per_axis_effect_beside_an_all_axes_one_is_found_whatever_the_default_split(built_ssp, tmp_path, case):
    """The issue's first case: the viscous change was named, the per-axis inertia was not offered ("no such
    held-out test") and the verdict was "unexplained residual". Now both are named, within 5 %, the split holds out a
    fast test that moves that axis, and the report says which held-out tests checked each named effect."""
    hidden, seed, plan = PER_AXIS[case]
    doc = run(built_ssp, tmp_path, hidden, tuple(Spec(*test) for test in figures.DIAGNOSE_PLANS[plan]), seed)
    effects = named(doc)
    (component,) = set(hidden) - {"actuator"}
    axis = int(component.removeprefix("actuator_"))
    key = f"inertia_motor_axis{axis}"
    assert set(effects) == {key, "viscous"}, effects
    for name, truth in figures.per_axis_truth(hidden).items():
        effect = effects[key if name.endswith(f"_axis{axis}") else "viscous"]
        assert effect["parameters"][name] == pytest.approx(truth, rel=0.05)
    assert doc["verdict"]["status"] == "explained"
    assert doc["identifiability"][key]["plan_meets"] and doc["identifiability"][key]["split_meets"]
    moving_fast = {
        t["name"]
        for t in doc["tests"]
        if t["frequency_Hz"] >= 2.0 and (t["motion"] == "z" or (t["motion"] == "psi") == (axis == 2))
    }
    for e in effects.values():
        held = e["evidence"]["held_out_evidence"]["tests"]
        assert held and set(held) == set(doc["split"]["held_out"])
    assert set(doc["split"]["held_out"]) & moving_fast
    report = (tmp_path / "out" / "report.md").read_text()
    assert "(held-out evidence)" in report and "Split: " in report
    cross_validated(doc, report)
    # the per-axis inertia is judged on the folds holding out a fast test that moves that axis, never on the others
    assert set(effects[key]["evidence"]["cross_validation"]["folds"]) <= moving_fast
    problems = figures.check({f"diagnose_{case}": figures.diagnose_values(doc)})
    assert not problems, "\n".join(problems)


def cross_validated(doc: dict, report: str) -> None:
    """Every test held out in one fold and trained on in the others; every named effect confirmed by the held-out
    residual summed over the folds that can check it (crossvalidation.py), with the figures per fold in the report."""
    cv = doc["cross_validation"]
    names = [t["name"] for t in doc["tests"]]
    assert sorted(n for f in cv["folds"] for n in f["held_out"]) == sorted(names)
    for f in cv["folds"]:
        assert set(f["training"]) == set(names) - set(f["held_out"])
    for e in doc["named_effects"]:
        ev = e["evidence"]["cross_validation"]
        assert ev["confirmed"] and ev["folds"], (e["key"], ev)
        assert ev["held_out_rss_without"] - ev["held_out_rss_with"] >= ev["needed"]
    assert "## Cross-validation" in report and all(f"without {e['key']}" in report for e in doc["named_effects"])


#: a lag inside two- and three-effect combinations, as a delay and as a filter (docs/figures.py DIAGNOSE_LAGS, whose
#: values docs/diagnose.md states): case -> (truth, plan, seed, the form hidden). The issue's two cases left wrong
#: (docs/diagnose.md): a 1.2-1.5 ms delay carried less than 1 % of the nominal model's gap and was never proposed (a
#: stiffness K_t 4.95 named instead on PLAN_A; "unexplained residual" on SMALL, seed 332)
LAGS = {
    case: (truth, tuple(Spec(*test) for test in figures.DIAGNOSE_PLANS[plan]), seed, lag)
    for case, (truth, seed, plan) in figures.DIAGNOSE_LAGS.items()
    for lag in truth
    if lag in ("delay_meas", "T_meas")
}
KEYS = {"tau_c": "coulomb", "J1_scale": "inertia_motor", "b_v": "viscous", "delay_meas": "lag", "T_meas": "lag"}


@pytest.mark.parametrize("case", list(LAGS))
def test_a_lag_among_other_effects_is_named_a_delay_or_a_filter_as_it_is(built_ssp, tmp_path, case):
    """The issue's second case: Coulomb friction, a motor-side inertia change and a measurement delay; the lag was
    named a first-order filter (T_meas) with the delay's value. Now the selection is fitted again with the lag in
    the other form (every parameter free) and the training BIC and the held-out test decide: the form hidden is
    named, or, where the plan cannot tell them apart (a lag of 1.7 ms beside a viscous change on SMALL's short
    records: the training and the held-out test disagree, or tell by a few units), "delay or filter: not
    distinguishable on this plan", never the other form. Every parameter
    within 5 % (or, for the lag on these short records, 3 standard deviations and 10 %)."""
    truth, plan, seed, form = LAGS[case]
    doc = run(built_ssp, tmp_path, {"actuator": truth}, plan, seed)
    effects = named(doc)
    assert set(effects) == {KEYS[p] for p in truth}, effects
    decided = effects["lag"]["evidence"]["filter_or_delay"]
    assert decided["choice"] in (form, "not distinguishable"), decided
    lag = decided["kept"]
    assert set(effects["lag"]["parameters"]) == {lag} and (lag == form or decided["choice"] != form)
    for p, v in truth.items():
        key = lag if KEYS[p] == "lag" else p
        value = effects[KEYS[p]]["parameters"][key]
        error, std = abs(value - v), effects[KEYS[p]]["uncertainty"][key]["std"]
        assert error <= 0.05 * v or (KEYS[p] == "lag" and error <= min(3 * std, 0.1 * v)), (p, effects)
    assert doc["verdict"]["status"] == "explained"
    assert effects["lag"]["form"] in doc["verdict"]["text"]
    if decided["choice"] == "not distinguishable":
        assert "delay or filter: not distinguishable on this plan" in doc["verdict"]["text"]
    cross_validated(doc, (tmp_path / "out" / "report.md").read_text())
    assert doc["cross_validation"]["lag_form"]["choice"] == decided["choice"]
    problems = figures.check({f"diagnose_{case}": figures.diagnose_values(doc)})
    assert not problems, "\n".join(problems)


def test_the_named_effects_do_not_depend_on_the_split(built_ssp, tmp_path):
    """The same data diagnosed with the default split (psi 2.5 Hz held out) and with another one (z 5 Hz held out):
    the same effects named, the same values within 2 %, every test held out in one fold of the cross-validation
    whatever the split (SMALL: Coulomb friction, a heavier motor side and a 1.5 ms delay, seed 333)."""
    truth = {"tau_c": 0.042, "J1_scale": 1.15, "delay_meas": 0.0015}
    data = tmp_path / "data"
    synthesize(built_ssp, data, {"actuator": truth}, tests=SMALL, direct=True, seed=333, log=lambda *_: None)
    docs = [
        diagnose(
            Options(data, tmp_path / f"out{k}", compiled(built_ssp), figures=False, direct=False, holdout=holdout),
            log=lambda *_: None,
        )
        for k, holdout in enumerate((None, ["z_5Hz"]))
    ]
    assert docs[0]["split"]["held_out"] == ["psi_2.5Hz"] and docs[1]["split"]["held_out"] == ["z_5Hz"]
    first, second = named(docs[0]), named(docs[1])
    assert set(first) == set(second) == {"coulomb", "inertia_motor", "lag"}, (first, second)
    for key, e in first.items():
        for p, v in e["parameters"].items():
            assert second[key]["parameters"][p] == pytest.approx(v, rel=0.02), (p, e, second[key])
            truth_value = truth.get(p, truth.get("delay_meas"))
            assert v == pytest.approx(truth_value, rel=0.05), (p, v)
    for doc in docs:
        assert doc["verdict"]["status"] == "explained"
        assert sorted(n for f in doc["cross_validation"]["folds"] for n in f["held_out"]) == sorted(
            n for n in doc["gap"]
        )


def test_the_folds_hold_every_test_out_once_and_check_what_their_training_tests_identify():
    """No simulation: leave-one-test-out whatever the order of the tests; a fold judges an effect only when its
    training tests identify it and its held-out test can check it (plan.fold_meets): on PLAN_A inertia on axis 2
    alone is judged by the folds holding out z 3.3 or 5.8 Hz (the fast tests that move actuator 2, the other one
    in training), never by psi 1.7 Hz; on SMALL inertia on axis 1 by no fold (one fast test moves it: the plan
    cannot identify it, as the identifiability table says)."""
    from mast.diagnosis.plan import folds

    keys = ["coulomb", "viscous", "inertia_motor", "inertia_motor_axis1", "inertia_motor_axis2", "lag"]
    tests = excitations(PLAN_A)
    out = folds(tests, keys)
    names = sorted(x.name for x in tests)
    assert sorted(n for f in out for n in f["held_out"]) == names
    for f in out:
        assert sorted(f["training"] + f["held_out"]) == names
    judged = {f["held_out"][0]: f["checks"] for f in out}
    assert {n for n, c in judged.items() if "inertia_motor_axis2" in c} == {"z_3.3Hz", "z_5.8Hz"}
    assert all("coulomb" in c for c in judged.values())
    assert all("lag" in c for c in judged.values())  # theta 4.2 Hz trains it when z 5.8 Hz is held out

    def as_sets(fs):
        return sorted((tuple(f["held_out"]), frozenset(f["training"]), frozenset(f["checks"])) for f in fs)

    assert as_sets(folds(list(reversed(tests)), keys)) == as_sets(out)
    small = folds(excitations(SMALL), keys)
    assert not any("inertia_motor_axis1" in f["checks"] for f in small)
    assert {f["held_out"][0] for f in small if "lag" in f["checks"]} == {"z_1.2Hz", "psi_2.5Hz"}  # z 5 Hz trains it


def test_delay_or_filter_not_distinguishable_is_said_not_picked():
    """The rule of stages.lag_form_check: a form is named only if the training BIC and the held-out deviance both
    prefer it and together by DELTA_BIC (the selection's score); otherwise "not distinguishable on this plan"."""
    from mast.diagnosis.stages import lag_form

    assert lag_form(-25.0, -3.0) == "delay_meas" and lag_form(25.0, 0.5) == "T_meas"
    assert lag_form(-3.0, -22.0) == "delay_meas"  # the held-out tests tell, the training leans to it
    assert lag_form(-4.0, -5.0) == "not distinguishable"  # neither tells
    assert lag_form(-16.0, 4.0) == "not distinguishable"  # the held-out test disagrees (SMALL, seed 323)
    assert lag_form(30.0, -1.0) == "not distinguishable"
