"""Backlash on a plan of the issue's kind and on ours (issue 18): named right, its value within 5 %, a record in a
regime no re-simulation visits reported, and a backlash too small to make the loop hunt not invented.

With the mechanism's inertial reaction applied at every 100 us step (issue 27) a few mrad of backlash no longer make
the loop hunt on PLAN (z 0.6, 3, 7 Hz, theta 1.5 Hz) or ISSUE_PLAN (tests/test_diagnose.py): the torque stays at the
noise floor (before, the reaction held for 1 ms made the loop hunt). The cases are therefore on plans whose fast z tests
make the loop hunt: docs/figures.py DIAGNOSE_PLAN_FAST (PLAN with z 10 Hz 8 mm and z 15 Hz 5 mm) and
DIAGNOSE_ISSUE_PLAN_FAST (ISSUE_PLAN, z, psi and theta, with z 12 Hz 6 mm and z 16 Hz 4.5 mm), with tens of mrad; the
detection limit is a few mrad on PLAN, named nothing. Values and seeds away from those of tests/test_diagnose.py
(0.06 and 0.03 rad on DIAGNOSE_PLAN_FAST, seeds 7 and 8) and of docs/diagnose.md. Clean data on both plans names
nothing: tests/test_diagnose.py (PLAN seeds 3 and 4, ISSUE_PLAN seed 63). The diagnoses re-simulate on the native form
of the fixture's system (``compiled``).

The hunting is chaotic: which regime a record (the truth's one run) and each re-simulation fall into depends on the
floats' last bits, which differed between BLAS kernels before the models' small algebra was written out in a fixed
order (issue 24), and still may between libms or compilers. The tests assert what holds in every regime: backlash
named alone, the verdict that follows from the tests it is fitted on, an interval that holds the truth, every test the
value is fitted on at its floor and any other one quieter than the re-simulations; never which test falls into which
regime (marker ``regime``: .ci/run runs them again under another BLAS kernel).
"""

from __future__ import annotations

import numpy as np
import pytest
from docs_figures import figures
from test_diagnose import PLAN, built_ssp, compiled, named  # noqa: F401  (the module's fixture)

from mast.analyses.synthesize import TestSpec as Spec
from mast.analyses.synthesize import synthesize
from mast.diagnosis import Options, diagnose

pytestmark = pytest.mark.regime


def run(ssp: str, tmp, truth: dict, plan, seed: int, **options) -> dict:
    data = tmp / "data"
    synthesize(ssp, data, truth, tests=plan, direct=True, seed=seed, log=lambda *_: None)
    return diagnose(
        Options(data, tmp / "out", compiled(ssp), figures=False, direct=False, **options), log=lambda *_: None
    )


#: our compact plan with fast z tests where the loop hunts (docs/figures.py)
PLAN_FAST = tuple(Spec(*test) for test in figures.DIAGNOSE_PLAN_FAST)


@pytest.mark.parametrize("case", list(figures.DIAGNOSE_BACKLASH))
def test_backlash_is_named_within_5_percent(built_ssp, tmp_path, case):
    """docs/figures.py DIAGNOSE_BACKLASH: 0.07 rad on the issue's kind of plan with fast z tests (seed 77), 0.05 rad on
    ours (seed 75). Backlash alone: named (nothing else), its value within 5 % with a 95 % interval that holds it
    (determined on the plan), confirmed by leave-one-test-out, the band powers of every test it is fitted on at the
    floor with it (and any other test reported as hunting in a quieter regime: whichever regime a record falls into);
    the value is the minimum of the smoothed deviance on the fine grid (ratio 2^(1/16)) that brackets it. The value,
    error and interval docs/diagnose.md states are these runs' (to the 5 % asserted here)."""
    truth, seed, plan_name = figures.DIAGNOSE_BACKLASH[case]
    backlash, plan = truth["backlash"], tuple(Spec(*test) for test in figures.DIAGNOSE_PLANS[plan_name])
    doc = run(built_ssp, tmp_path, {"actuator": truth}, plan, seed)
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
    problems = figures.check({f"diagnose_{case}": figures.diagnose_values(doc)})
    assert not problems, "\n".join(problems)
    if plan_name == "issue_fast":  # where the deviance had no curvature, the report would say the plan does not pin it
        from mast.diagnosis.report import write_report

        assert "not determined on this plan" not in (tmp_path / "out" / "report.md").read_text()
        pf["value_determined"], pf["value_not_determined_because"] = False, ["z_12Hz predicted at 0.1 ..."]
        write_report(tmp_path / "out", doc, {})
        assert (
            "Its value is not determined on this plan (z_12Hz predicted at 0.1"
            in (tmp_path / "out" / "report.md").read_text()
        )


def test_backlash_is_named_whichever_regime_each_record_hunts_in(built_ssp, tmp_path):
    """45 mrad on our plan with fast z tests (seed 73; the seed draws only the noise, the record's hunting is the
    truth's one run on the exact commands). Measured: z 15 Hz's record fell into a regime none of the 10
    re-simulations within 9 % of the value visits (deviance 19.2 > 18.5, quieter in every band); whether a record
    falls into such a regime depends on the floats' last bits (issue 24). Either way: backlash named alone, with an
    interval that holds the truth from the tests it is fitted on, each at its floor; a test left out of the fit is
    not reproduced only if quieter than every re-simulation, and is reported, not fitted. The value is determined
    only as far as the tests it is fitted on pin it: with one of the plan's two hunting tests left out, one hunting
    test is left and the value is not determined (measured 0.0433 rad, 95 % 0.0336-0.0558): the verdict is then
    "present, value not determined" and backlash is left out of the augmented model, its interval reported;
    determined, it is written into the augmented model. The library is backlash alone: the phase-free stage is
    what is tested."""
    from mast.diagnosis.report import write_report

    backlash = 0.045
    doc = run(built_ssp, tmp_path, {"actuator": {"backlash": backlash}}, PLAN_FAST, 73, library=("backlash",))
    effects = named(doc)
    assert set(effects) == {"backlash"}, effects
    pf = effects["backlash"]["evidence"]["phase_free"]
    assert pf["ci95"][0] < backlash < pf["ci95"][1]
    assert pf["delta_bic"] < -10 and pf["cross_validated_deviance_change"] < -10
    dev, floors = pf["deviance_per_test"]["after"], pf["floor_per_test"]
    assert len(pf["fitted_on"]) >= len(doc["gap"]) - 1 and all(dev[n] <= floors[n] for n in pf["fitted_on"])
    assert pf["not_reproduced"] == [n for n in doc["gap"] if n not in pf["fitted_on"] and dev[n] > floors[n]]
    am = doc["augmented_model"]
    if pf["value_determined"]:
        assert doc["verdict"]["status"] == "explained"
        assert am["values"]["backlash"] == pytest.approx(pf["value"]) and not am.get("not_determined")
        assert "backlash" in (tmp_path / "out" / "actuator_diagnosed.ssv").read_text()
    else:  # a hunting test left out of the fit: the value rests on the one left
        assert pf["not_reproduced"], pf["value_not_determined_because"]
        assert doc["verdict"]["status"] == "present, value not determined"
        assert "backlash" not in am.get("values", {})
        assert am["not_determined"]["backlash"]["ci95"] == pytest.approx(pf["ci95"])
    report = (tmp_path / "out" / "report.md").read_text()
    for name in pf["not_reproduced"]:
        assert f"{name} hunts in a quieter regime than its re-simulations visit" in report
    if not pf["not_reproduced"]:  # the report of a record in the quiet regime, whichever regime this one fell into
        pf["not_reproduced"], pf["fitted_on"] = ["z_15Hz"], [n for n in doc["gap"] if n != "z_15Hz"]
        write_report(tmp_path / "out", doc, {})
        report = (tmp_path / "out" / "report.md").read_text()
        assert "z_15Hz hunts in a quieter regime than its re-simulations visit" in report


def test_a_few_mrad_on_the_compact_plan_are_below_the_detection_limit(built_ssp, tmp_path):
    """5 mrad on PLAN (seed 79): with the inertial reaction at every step the loop does not hunt, the truth's torque
    differs from the nominal model's by less than the noise (checked on the two noise-free syntheses, not by the
    diagnosis), and the diagnosis invents nothing: "nothing missing", nothing named."""
    from mast.analyses.synthesize import DEFAULT_NOISE

    backlash, seed = 0.005, 79
    data = tmp_path / "data"
    truth = synthesize(
        built_ssp, data, {"actuator": {"backlash": backlash}}, tests=PLAN, direct=True, seed=seed, log=lambda *_: None
    )["clean"]
    nominal = synthesize(built_ssp, tmp_path / "nominal", {}, tests=PLAN, direct=True, seed=seed, log=lambda *_: None)[
        "clean"
    ]
    for spec in PLAN:
        t = truth[spec.name]["time"]
        after = t >= spec.settle
        diff = truth[spec.name]["tau_m"][after] - nominal[spec.name]["tau_m"][after]
        assert 0 < float(np.sqrt(np.mean(diff**2))) < DEFAULT_NOISE["tau_m"], spec.name
    doc = diagnose(
        Options(data, tmp_path / "out", compiled(built_ssp), figures=False, direct=False), log=lambda *_: None
    )
    assert doc["verdict"]["status"] == "nothing missing", doc["verdict"]
    assert doc["named_effects"] == []
