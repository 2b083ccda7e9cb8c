"""Backlash on the issue's plan and on ours (issue 18): named right, its value within 5 %, nothing named on clean
data.

The issue's case: a five-test plan mixing z, psi and theta at other frequencies and amplitudes than the default
(ISSUE_PLAN, tests/test_diagnose.py), a few mrad of backlash that makes only the faster tests hunt; on these
short records (0.5 s analysed per fast test) the hunting is periodic rather than chaotic and its band powers jump
between neighbouring values, so the value comes from the smoothed (pooled) phase-free deviance on a fine grid
(orchestration/diagnosis/phasefree.search). Our plan: PLAN (z 0.6, 3, 7 Hz, theta 1.5 Hz). Values and seeds away
from those of tests/test_diagnose.py (0.003 and 0.01 rad on PLAN, seeds 7 and 8) and of docs/diagnose.md.
Clean data on both plans names nothing: tests/test_diagnose.py (PLAN seeds 3 and 4, ISSUE_PLAN seed 63).
The diagnoses re-simulate on the native form of the fixture's system (``compiled``).
"""
from __future__ import annotations

import pytest

from mast.diagnosis import Options, diagnose
from mast.analyses.synthesize import synthesize

from test_diagnose import ISSUE_PLAN, PLAN, built_ssp, compiled, named  # noqa: F401  (the module's fixture)


def run(ssp: str, tmp, truth: dict, plan, seed: int, **options) -> dict:
    data = tmp / "data"
    synthesize(ssp, data, truth, tests=plan, direct=True, seed=seed, log=lambda *_: None)
    return diagnose(Options(data, tmp / "out", compiled(ssp), figures=False, direct=False, **options),
                    log=lambda *_: None)


@pytest.mark.parametrize("backlash, plan, seed", [(0.0045, ISSUE_PLAN, 72), (0.0065, PLAN, 73)],
                         ids=["issue-plan-4.5mrad", "default-plan-6.5mrad"])
def test_backlash_is_named_within_5_percent(built_ssp, tmp_path, backlash, plan, seed):
    """Backlash alone: named (nothing else), its value within 5 % with a 95 % interval that holds it (determined on
    the plan), confirmed by leave-one-test-out, every test's band powers at the floor with it; the value is the
    minimum of the smoothed deviance on the fine grid (ratio 2^(1/16)) that brackets it."""
    doc = run(built_ssp, tmp_path, {"actuator": {"backlash": backlash}}, plan, seed)
    effects = named(doc)
    assert set(effects) == {"backlash"}, effects
    assert doc["verdict"]["status"] == "explained"
    effect = effects["backlash"]
    value, unc = effect["parameters"]["backlash"], effect["uncertainty"]["backlash"]
    assert value == pytest.approx(backlash, rel=0.05), effect
    assert unc["ci95"][0] < value < unc["ci95"][1]
    pf = effect["evidence"]["phase_free"]
    assert pf["delta_bic"] < -10 and pf["cross_validated_deviance_change"] < -10
    assert all(pf["deviance_per_test"]["after"][n] <= pf["floor_per_test"][n] for n in doc["gap"])
    grid = sorted(pf["profile"])
    assert grid[0] < value < grid[-1]
    assert pf["value_determined"]
    if plan is ISSUE_PLAN:   # where the deviance had no curvature, the report would say the plan does not pin the value
        from mast.diagnosis.report import write_report

        assert "not determined on this plan" not in (tmp_path / "out" / "report.md").read_text()
        pf["value_determined"], pf["value_not_determined_because"] = False, ["z_3.5Hz predicted at 0.008 ..."]
        write_report(tmp_path / "out", doc, {})
        assert "Its value is not determined on this plan (z_3.5Hz predicted at 0.008" in (
            tmp_path / "out" / "report.md").read_text()


def test_backlash_whose_value_the_plan_does_not_pin(built_ssp, tmp_path):
    """4 mrad on the issue's plan (seed 61; the seed draws only the noise, the record's hunting is the truth's one
    run on the exact commands): z 3.5 Hz's record is in a quieter regime of the hunting than the re-simulations
    near 4 mrad (about 1 in 60 of them visit it, docs/diagnose.md), which no ensemble of a few realisations covers;
    the pooled deviance on all tests then followed a lucky member to 4.967 mrad (+24 %). The value is fitted on the
    tests that agree (leave-one-test-out) and z 3.5 Hz is checked at it: not reproduced, with less power in every
    band than the loudest re-simulation, so backlash is named present, its value not determined, and left out of
    the augmented model; the interval from the other tests holds the truth. The library is backlash alone (the
    case's other candidates are refused, docs/diagnose.md): the phase-free stage is what is tested."""
    doc = run(built_ssp, tmp_path, {"actuator": {"backlash": 0.004}}, ISSUE_PLAN, 61, library=("backlash",))
    effects = named(doc)
    assert set(effects) == {"backlash"}, effects
    pf = effects["backlash"]["evidence"]["phase_free"]
    assert not pf["value_determined"] and pf["not_reproduced"] == ["z_3.5Hz"]
    assert "z_3.5Hz" not in pf["fitted_on"] and len(pf["fitted_on"]) == 4
    assert pf["ci95"][0] < 0.004 < pf["ci95"][1] and pf["ci95"][1] / pf["ci95"][0] < 1.25
    dev, floors = pf["deviance_per_test"]["after"], pf["floor_per_test"]
    assert all(dev[n] <= floors[n] for n in pf["fitted_on"]) and dev["z_3.5Hz"] > floors["z_3.5Hz"]
    assert doc["verdict"]["status"] == "present, value not determined"
    am = doc["augmented_model"]
    assert "backlash" not in am["values"] and set(am["not_determined"]) == {"backlash"}
    assert "backlash" not in (tmp_path / "out" / "actuator_diagnosed.ssv").read_text()
    report = (tmp_path / "out" / "report.md").read_text()
    assert "not determined on this plan" in report and "not in the augmented model" in report
