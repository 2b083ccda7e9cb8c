"""`mast diagnose` on cases nobody tuned it to (issue 18): heavier machines as well as lighter ones, on
the default plan and on a plan of other frequencies, amplitudes and axes; a failed trial simulation is
information, never the end of the run.

SMALL (test_diagnose.py): z 1.2 Hz 4 mm, psi 2.5 Hz 0.6 deg, z 5 Hz 3 mm (0.6 to 1.1 s each; psi held
out). Values and seeds differ from those of tests/test_diagnose.py.
"""

from __future__ import annotations

import numpy as np
import pytest
from docs_figures import figures
from test_diagnose import PLAN, SMALL, built_ssp, compiled, named  # noqa: F401  (the module's fixture)

from mast.analyses.synthesize import TestSpec as Spec
from mast.analyses.synthesize import synthesize
from mast.diagnosis import Options, diagnose


def run(ssp: str, tmp, truth: dict, plan, seed: int, **options) -> dict:
    data = tmp / "data"
    synthesize(ssp, data, truth, tests=plan, direct=True, seed=seed, log=lambda *_: None)
    return diagnose(
        Options(data, tmp / "out", compiled(ssp), figures=False, direct=False, **options), log=lambda *_: None
    )


#: docs/figures.py DIAGNOSE_HEAVIER_LIGHTER: docs/diagnose.md states the fitted values of these runs
HEAVIER_LIGHTER = figures.DIAGNOSE_HEAVIER_LIGHTER


@pytest.mark.parametrize("case", list(HEAVIER_LIGHTER))
def test_heavier_and_lighter_machines_are_named(built_ssp, tmp_path, case):
    truth, seed, plan = HEAVIER_LIGHTER[case]
    ((parameter, value),) = truth.items()
    doc = run(built_ssp, tmp_path, {"actuator": truth}, {"compact": PLAN, "SMALL": SMALL}[plan], seed)
    problems = figures.check({f"diagnose_{case}": figures.diagnose_values(doc)})
    assert not problems, "\n".join(problems)
    effects = named(doc)
    assert len(effects) == 1, effects
    (effect,) = effects.values()
    assert effect["key"] == {"J1_scale": "inertia_motor", "M_load": "carriage_mass"}[parameter]
    assert effect["parameters"][parameter] == pytest.approx(value, rel=0.05)
    assert doc["verdict"]["status"] == "explained"


#: z motions only (SMALL's z tests, z 3 Hz 3 mm held out): on z alone a heavier carriage and more inertia plus an
#: offset look alike (plan.identifiability says so)
Z_ONLY = tuple(s for s in SMALL if s.motion == "z") + (Spec("z", 0.003, 3.0, 0.8, 0.3),)


def test_a_failed_trial_is_information_not_the_end(built_ssp, tmp_path):
    """A motor side 2.5 x heavier (J1_scale 2.5) on z motions only, the library offering only a carriage mass and a
    torque offset: the regression's linear alias, a 75 kg carriage and a -0.53 N m offset, cannot be held by the
    drive at its current limit (k_T i_max through the gearbox and the guide feed p, about 411 N), so its re-simulation
    fails ("carriage left the stroke"), as do the fit's trials above the holding mass. The fit starts halfway back
    and goes on, every failed trial (where, parameters, error) is recorded in diagnosis.json and report.md, and
    the best mass that simulates is refuted by the held-out test: nothing false is named, the residual is reported
    unexplained. (The premise before issue 27, a guide-side inertia that destabilised the loop, is gone: with the
    mechanism's reaction applied every step the guide-side inertia no longer destabilises the loop.)"""
    from mast.core.ssp import SSPArchive

    with SSPArchive(built_ssp) as archive:
        act = archive.system.components["actuator_1"].parameters
        i_max = float(archive.system.components["controller"].parameters["i_max"])
    # the heaviest carriage the drive holds at its current limit, friction aside (lead p per gearbox output turn)
    holding = float(act["k_T"]) * i_max * 2 * np.pi * float(act["i_r"]) / float(act["p"]) / float(act["g_guide"])
    doc = run(built_ssp, tmp_path, {"actuator": {"J1_scale": 2.5}}, Z_ONLY, 34, library=("carriage_mass", "offset"))
    failures = doc["failed_simulations"]
    assert failures and "fit start" in {f["where"] for f in failures}
    for f in failures:  # every failure is the weight: a carriage heavier than the drive holds falls out of the stroke
        assert set(f["parameters"]) == {"M_load", "tau_offset"} and "carriage left the stroke" in f["error"], f
        assert f["parameters"]["M_load"] > holding, (f, holding)
    report = (tmp_path / "out" / "report.md").read_text()
    assert "Trial simulations that failed" in report and "carriage left the stroke" in report
    proposals = [st for st in doc["steps"] if st["how"] == "regression"]
    assert proposals and set(proposals[0]["to"]) == {"carriage_mass", "offset"} and not proposals[0]["accepted"]
    assert named(doc) == {}
    assert doc["verdict"]["status"] == "unexplained residual" and "nothing named" in doc["verdict"]["text"]


def test_a_drive_gain_below_its_documentation_gets_a_controller_name(built_ssp, tmp_path):
    """The drive's velocity-loop gain k_p 40 % below the SSP's value (a cause outside the plant): named as
    the controller-side effect, within 5 %, with no plant effect named; the augmented SSP binds the
    diagnosed gain to the controller, not to the actuators."""
    from mast.core.ssp import SSPArchive

    with SSPArchive(built_ssp) as archive:
        nominal_k_p = float(archive.system.components["controller"].parameters["k_p"])
    doc = run(built_ssp, tmp_path, {"controller": {"k_p": 0.6 * nominal_k_p}}, SMALL, 41)
    effects = named(doc)
    assert set(effects) == {"velocity_gain"}, effects
    assert effects["velocity_gain"]["kind"] == "controller"
    assert effects["velocity_gain"]["parameters"]["k_p"] == pytest.approx(0.6 * nominal_k_p, rel=0.05)
    assert doc["verdict"]["status"] == "explained"
    am = doc["augmented_model"]
    assert am["controller_values"] == {"k_p": effects["velocity_gain"]["parameters"]["k_p"]}
    assert "k_p" not in am["values"]
    with SSPArchive(am["ssp"]) as archive:
        assert archive.system.components["controller"].parameters["k_p"] == pytest.approx(
            effects["velocity_gain"]["parameters"]["k_p"], rel=1e-12
        )
        assert "k_p" not in archive.system.components["actuator_1"].parameters


def test_a_worn_guide_on_one_axis_is_named_on_that_axis(built_ssp, tmp_path):
    """Actuator 2's guide with 0.03 N m more Coulomb friction than the other two: named as the per-axis
    effect of axis 2 (not the all-axes one, not an unexplained residual), its increment within 5 %; the
    augmented SSP binds the value to actuator 2 only. (When the axes agree the all-axes effect wins: the
    single-effect cases of test_diagnose.py assert exactly one effect, the all-axes one.)"""
    from mast.core.ssp import SSPArchive

    with SSPArchive(built_ssp) as archive:
        tau_c = float(archive.system.components["actuator_2"].parameters["tau_c"])
    doc = run(built_ssp, tmp_path, {"actuator_2": {"tau_c": tau_c + 0.03}}, SMALL, 51)
    effects = named(doc)
    assert set(effects) == {"coulomb_axis2"}, effects
    assert effects["coulomb_axis2"]["parameters"]["tau_c_axis2"] == pytest.approx(0.03, rel=0.05)
    assert doc["verdict"]["status"] == "explained"
    am = doc["augmented_model"]
    assert set(am["axis_values"]) == {"actuator_2"} and "tau_c_axis2" not in am["values"]
    with SSPArchive(am["ssp"]) as archive:
        p = {k: archive.system.components[f"actuator_{k}"].parameters["tau_c"] for k in (1, 2, 3)}
    assert p[1] == p[3] == pytest.approx(tau_c, rel=1e-12)
    assert p[2] == pytest.approx(tau_c + effects["coulomb_axis2"]["parameters"]["tau_c_axis2"], rel=1e-12)


def test_the_plan_says_which_effects_it_cannot_tell():
    """Identifiability from the commanded joint motion alone (no simulation): a plan of slow z tests
    cannot tell inertia, lag, the drive's gains, a carriage mass or backlash; backlash needs two fast tests
    of one kind of motion, whatever their roles (the issue's five-test case: its fast z tests all training
    or one held out, the plan meets it either way; one fast z test, or one z and one rotation, do not)."""
    from mast.diagnosis.plan import excitation, identifiability

    t = np.arange(0.0, 2.0, 1e-3)

    def test(name, role, f, rotation=False):
        s = 0.004 * np.sin(2 * np.pi * f * t)
        rho = 0.15 + np.column_stack([s, -s if rotation else s, s])
        return excitation(name, role, t, rho)

    slow = [test("z0.5", "training", 0.5), test("z0.8", "held-out", 0.8)]
    plan = identifiability(
        slow, ["coulomb", "inertia_motor", "lag", "velocity_gain", "carriage_mass", "stribeck", "backlash"]
    )
    assert plan["coulomb"]["plan_meets"] and plan["stribeck"]["plan_meets"]
    assert not any(
        plan[k]["plan_meets"] for k in ("inertia_motor", "lag", "velocity_gain", "carriage_mass", "backlash")
    )
    assert slow[0].frequency == pytest.approx(0.5, rel=0.05) and slow[0].alike
    issue = [
        test("z1", "training", 1.0),
        test("z4", "training", 4.5),
        test("z6", "training", 6.0),
        test("psi2", "held-out", 2.0, True),
        test("theta3", "held-out", 3.0, True),
    ]
    assert not issue[3].alike
    for roles in (("training", "training"), ("training", "held-out"), ("held-out", "training")):
        issue[1].role, issue[2].role = roles
        plan = identifiability(issue, ["backlash", "carriage_mass", "coulomb_axis2"])
        assert all(p["plan_meets"] for p in plan.values()), (roles, plan)
    one_fast = identifiability(issue[:2] + issue[3:4], ["backlash"])["backlash"]
    assert not one_fast["plan_meets"] and "only one test" in one_fast["why_not"]
    mixed = [issue[0], issue[1], test("theta5", "held-out", 5.0, True)]
    assert not identifiability(mixed, ["backlash"])["backlash"]["plan_meets"]


#: effects on one axis and on the drive (issue 18), values, plans and seeds away from those above and in docs/
#: (docs/figures.py DIAGNOSE_ONE_AXIS_AND_DRIVE, whose fitted values docs/diagnose.md states); inertia on one axis
#: beside an all-axes viscous change: each axis on two plans, tests/test_diagnose_split.py
ONE_AXIS_AND_DRIVE = figures.DIAGNOSE_ONE_AXIS_AND_DRIVE


@pytest.mark.parametrize("case", list(ONE_AXIS_AND_DRIVE))
def test_effects_on_one_axis_and_in_the_drive_are_named(built_ssp, tmp_path, case):
    """One actuator heavier on its motor side or lighter on its carriage, one drive reading its torque with an
    offset, a drive whose velocity-loop integral gain is 40 % low (before k_i was in the library: named as
    motor-side inertia plus k_p and k_v), that runs its velocity loop at half the documented rate or limits the
    current below its documentation: each named as itself (the per-axis effect on that axis, the controller-side
    effect: never a
    plant name), its value within 5 %, the augmented model binding it to that actuator or to the controller.
    (When the axes agree the all-axes effect is named: the all-axes cases above and in test_diagnose.py.)"""
    from mast.core.ssp import SSPArchive

    truth, seed, plan, key, parameter, value = ONE_AXIS_AND_DRIVE[case]
    doc = run(built_ssp, tmp_path, truth, {"compact": PLAN, "SMALL": SMALL}[plan], seed)
    effects = named(doc)
    assert set(effects) == {key}, effects
    assert effects[key]["parameters"][parameter] == pytest.approx(value, rel=0.05)
    assert doc["verdict"]["status"] == "explained"
    am = doc["augmented_model"]
    (component,) = truth
    if component == "controller":
        assert effects[key]["kind"] == "controller" and set(am["controller_values"]) == {parameter}
        with SSPArchive(am["ssp"]) as archive:
            assert archive.system.components["controller"].parameters[parameter] == pytest.approx(
                effects[key]["parameters"][parameter], rel=1e-12
            )
    else:
        base = parameter.rsplit("_axis", 1)[0]
        assert set(am["axis_values"]) == {component} and parameter not in am["values"]
        assert am["axis_values"][component][base] == pytest.approx(
            truth[component][base], rel=0.05, abs=0.05 * abs(value)
        )
    problems = figures.check({f"diagnose_{case}": figures.diagnose_values(doc)})
    assert not problems, "\n".join(problems)


#: causes outside the library (issue 18): (truth, plan, seed, what may be named)
OUTSIDE = {
    # the drive's position loop at 4 ms instead of 1 ms (T_pos is not in the library): before the guard, named
    # motor-side inertia (J1_scale 1.025) and a measurement lag beside an unexplained residual
    "position-cycle": ({"controller": {"T_pos": 0.004}}, SMALL, 201, {}),
    # a true Coulomb friction with a guide torque ripple the library lacks: before the guard, Coulomb friction and
    # a viscous friction (a stand-in for part of the ripple) named; the ripple's residual stays
    "coulomb-and-ripple": (
        {"actuator": {"tau_c": 0.045, "tau_ripple": 0.002}},
        SMALL,
        204,
        {"coulomb": ("tau_c", 0.045)},
    ),
    # the position loop at 2 ms: motor-side inertia (J1_scale 1.008) and a measurement lag (0.32 ms) reproduce its
    # trace down to the noise floor; before the check ran at the floor, both were named ("explained")
    "position-cycle-at-the-floor": ({"controller": {"T_pos": 0.002}}, SMALL, 209, {}),
}


@pytest.mark.parametrize("case", list(OUTSIDE))
def test_a_cause_outside_the_library_gets_no_plant_name(built_ssp, tmp_path, case):
    """A residual is left that no candidate explains, or several stand-ins reproduce it down to the noise floor: an
    effect accepted by the search is named only if each test alone agrees on its value, its value does not move when
    a stand-in is taken out, and the selection removes most of the gap (diagnosis/consistency.py); the others are
    hints in unexplained.hints and report.md, never names, and stand-ins refused at the floor leave an unexplained
    (structured) residual, not "explained". The true effect beside an unknown one is still named, within 5 %."""
    from mast.diagnosis.effects import LIBRARY

    truth, plan, seed, expected = OUTSIDE[case]
    # backlash left out (its phase-free scan, half the cost here, is refused on such residuals: the ripple test of
    # test_diagnose.py covers that)
    doc = run(built_ssp, tmp_path, truth, plan, seed, library=tuple(e.key for e in LIBRARY if e.key != "backlash"))
    effects = named(doc)
    assert set(effects) == set(expected), effects
    for key, (parameter, value) in expected.items():
        assert effects[key]["parameters"][parameter] == pytest.approx(value, rel=0.05)
        assert effects[key]["evidence"]["per_test"][parameter]["consistent"]
    assert doc["verdict"]["status"] == "unexplained residual"
    hints = doc["unexplained"]["hints"]
    assert hints and not {h["key"] for h in hints} & set(expected)
    assert all(h["why_not_named"] for h in hints)
    assert "Hints, not names" in (tmp_path / "out" / "report.md").read_text()
    if not expected:  # nothing named: the augmented model is the nominal one
        assert doc["augmented_model"]["values"] == {} and "controller_values" not in doc["augmented_model"]
    if case.endswith("at-the-floor"):  # stand-ins that reach the noise floor together: refused there too
        assert all(r <= 1.2 for r in doc["verdict"]["residual_over_noise_per_test"].values())
        assert len(hints) >= 2 and "structured" in doc["verdict"]["text"]


def test_a_softer_transmission_is_named_as_itself(built_ssp, tmp_path):
    """A transmission 13.5 x softer than documented (K_t 5 N m/rad, paper Eqs. 2-3; the SMALL plan): its trace in the
    band is what drive gains, cycle times and inertia mimic, and the search first reaches the noise floor with three
    of them (k_i, T_vel, J_guide; before issue 18's last round they were named). Their per-test values disagree
    (T_vel) or move once it is taken out (J_guide, k_i): refused at the floor, their structure left (training BIC),
    so the stiffness is tried by re-simulation from a log scan and named alone, within 5 %."""
    doc = run(built_ssp, tmp_path, {"actuator": {"K_t": 5.0}}, SMALL, 203)
    effects = named(doc)
    assert set(effects) == {"stiffness"}, effects
    assert effects["stiffness"]["parameters"]["K_t"] == pytest.approx(5.0, rel=0.05)
    assert doc["verdict"]["status"] == "explained"
    refused = [st for st in doc["steps"] if st["how"] == "named only if explained"]
    assert refused and len(refused[0]["from"]) >= 2 and not refused[0]["to"]
    assert doc["augmented_model"]["values"] == {"K_t": effects["stiffness"]["parameters"]["K_t"]}
