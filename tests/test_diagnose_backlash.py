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

The hunting is chaotic: which regime a record (the truth's one run) and each re-simulation fall into depends on the
floats' last bits, which differed between BLAS kernels before the models' small algebra was written out in a fixed
order (issue 24), and still may between libms or compilers. The tests assert what holds in every regime: backlash
named alone, the verdict, an interval that holds the truth, every test the value is fitted on at its floor and any
other one quieter than the re-simulations; never which test falls into which regime (marker ``regime``: .ci/run runs
them again under another BLAS kernel).
"""

from __future__ import annotations

import pytest
from test_diagnose import ISSUE_PLAN, PLAN, built_ssp, compiled, named  # noqa: F401  (the module's fixture)

from mast.analyses.synthesize import synthesize
from mast.diagnosis import Options, diagnose

pytestmark = pytest.mark.regime


def run(ssp: str, tmp, truth: dict, plan, seed: int, **options) -> dict:
    data = tmp / "data"
    synthesize(ssp, data, truth, tests=plan, direct=True, seed=seed, log=lambda *_: None)
    return diagnose(
        Options(data, tmp / "out", compiled(ssp), figures=False, direct=False, **options), log=lambda *_: None
    )


@pytest.mark.parametrize(
    "backlash, plan, seed",
    [(0.0045, ISSUE_PLAN, 72), (0.0065, PLAN, 73)],
    ids=["issue-plan-4.5mrad", "default-plan-6.5mrad"],
)
def test_backlash_is_named_within_5_percent(built_ssp, tmp_path, backlash, plan, seed):
    """Backlash alone: named (nothing else), its value within 5 % with a 95 % interval that holds it (determined on
    the plan), confirmed by leave-one-test-out, the band powers of every test it is fitted on at the floor with it
    (and any other test reported as hunting in a quieter regime: whichever regime a record falls into); the value
    is the minimum of the smoothed deviance on the fine grid (ratio 2^(1/16)) that brackets it."""
    doc = run(built_ssp, tmp_path, {"actuator": {"backlash": backlash}}, plan, seed)
    effects = named(doc)
    assert set(effects) == {"backlash"}, effects
    assert doc["verdict"]["status"] == "explained"
    effect = effects["backlash"]
    value, unc = effect["parameters"]["backlash"], effect["uncertainty"]["backlash"]
    assert value == pytest.approx(backlash, rel=0.05), effect
    assert unc["ci95"][0] < value < unc["ci95"][1] and unc["ci95"][0] < backlash < unc["ci95"][1]
    pf = effect["evidence"]["phase_free"]
    assert pf["delta_bic"] < -10 and pf["cross_validated_deviance_change"] < -10
    dev, floors = pf["deviance_per_test"]["after"], pf["floor_per_test"]
    assert len(pf["fitted_on"]) >= len(doc["gap"]) - 1 and all(dev[n] <= floors[n] for n in pf["fitted_on"])
    assert pf["not_reproduced"] == [n for n in doc["gap"] if n not in pf["fitted_on"] and dev[n] > floors[n]]
    grid = sorted(pf["profile"])
    assert grid[0] < value < grid[-1]
    assert pf["value_determined"]
    if plan is ISSUE_PLAN:  # where the deviance had no curvature, the report would say the plan does not pin the value
        from mast.diagnosis.report import write_report

        assert "not determined on this plan" not in (tmp_path / "out" / "report.md").read_text()
        pf["value_determined"], pf["value_not_determined_because"] = False, ["z_3.5Hz predicted at 0.008 ..."]
        write_report(tmp_path / "out", doc, {})
        assert (
            "Its value is not determined on this plan (z_3.5Hz predicted at 0.008"
            in (tmp_path / "out" / "report.md").read_text()
        )


def test_backlash_is_named_whichever_regime_each_record_hunts_in(built_ssp, tmp_path):
    """4 mrad on the issue's plan (seed 61; the seed draws only the noise, the record's hunting is the truth's one
    run on the exact commands). z 3.5 Hz's hunting at 4 mrad on this 0.8 s test has a quiet regime (the axes in
    step) that about 1 in 60 runs visit (docs/diagnose.md) and no ensemble of a few realisations covers; whether
    the record falls into it depends on the floats' last bits (it did with one BLAS kernel's and not with
    another's: issue 24). Either way: backlash named, explained, its value from the tests it is fitted on with an
    interval that holds the truth and is written into the augmented model; a test left out of the fit is not
    reproduced only if quieter than every re-simulation, and is reported, not fitted. The library is backlash
    alone (the case's other candidates are refused, docs/diagnose.md): the phase-free stage is what is tested."""
    from mast.diagnosis.report import write_report

    doc = run(built_ssp, tmp_path, {"actuator": {"backlash": 0.004}}, ISSUE_PLAN, 61, library=("backlash",))
    effects = named(doc)
    assert set(effects) == {"backlash"}, effects
    pf = effects["backlash"]["evidence"]["phase_free"]
    assert doc["verdict"]["status"] == "explained" and pf["value_determined"], pf["value_not_determined_because"]
    assert pf["ci95"][0] < 0.004 < pf["ci95"][1] and pf["ci95"][1] / pf["ci95"][0] < 1.25
    dev, floors = pf["deviance_per_test"]["after"], pf["floor_per_test"]
    assert len(pf["fitted_on"]) >= 4 and all(dev[n] <= floors[n] for n in pf["fitted_on"])
    assert pf["not_reproduced"] == [n for n in doc["gap"] if n not in pf["fitted_on"] and dev[n] > floors[n]]
    am = doc["augmented_model"]
    assert am["values"]["backlash"] == pytest.approx(pf["value"]) and not am.get("not_determined")
    assert "backlash" in (tmp_path / "out" / "actuator_diagnosed.ssv").read_text()
    # the report of a record in the quiet regime, whichever regime this one fell into
    pf["not_reproduced"], pf["fitted_on"] = ["z_3.5Hz"], [n for n in doc["gap"] if n != "z_3.5Hz"]
    write_report(tmp_path / "out", doc, {})
    report = (tmp_path / "out" / "report.md").read_text()
    assert "z_3.5Hz hunts in a quieter regime than its re-simulations visit" in report
    assert "not determined on this plan" not in report
