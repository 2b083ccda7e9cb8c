"""`mast diagnose` on synthesized data with hidden effects (issue 5 acceptance).

Each case: `mast synthesize` hides an effect (the truth), the diagnosis sees only the
measured-data folder. A compact test plan keeps the suite short: z sines at 0.6, 3 and
7 Hz and a theta sine at 1.5 Hz (0.3 s settling, 0.8 to 2 s each); every second test in
frequency order is held out (theta 1.5 Hz, z 7 Hz). Default noise: 2 mN m on the torque,
1 um encoder steps, the drive's 0.5 ms torque filter. Seeds differ between cases.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
from docs_figures import figures

from mast.analyses.synthesize import TestSpec as Spec
from mast.analyses.synthesize import synthesize
from mast.diagnosis import Options, diagnose

ROOT = Path(__file__).resolve().parents[1]

#: the compact plan and the cases hidden alone are docs/figures.py's: docs/diagnose.md states the figures of these runs
PLAN = tuple(Spec(*test) for test in figures.DIAGNOSE_PLAN)
IDENTIFIED = figures.DIAGNOSE_CASES["paper"][0]
#: a smaller plan of other frequencies, amplitudes and axes (docs/figures.py DIAGNOSE_SMALL): z 1.2 Hz 4 mm, psi 2.5 Hz
#: 0.6 deg (held out), z 5 Hz 3 mm
SMALL = tuple(Spec(*test) for test in figures.DIAGNOSE_SMALL)


@pytest.fixture(scope="session")
def built_ssp(built_native) -> str:
    """The Python FMUs' MAST.ssp, which synthesizes the measured data (the reference models), and beside it
    its native form (``compiled``), which the diagnoses re-simulate: the same models to 1e-9 relative
    (tests/test_native.py), cheaper through the compiled exchange loop. The session's build (conftest.py,
    ``built_native``), built once for every module and worker that diagnoses."""
    return str(built_native / "ssp" / "MAST.ssp")


def compiled(ssp: str) -> str:
    """The native form of the fixture's SSP (``built_ssp``)."""
    return str(Path(ssp).parent / "native" / Path(ssp).name)


def run_case(ssp: str, tmp: Path, truth: dict, seed: int, figures: bool = False, plan=PLAN) -> dict:
    data = tmp / "data"
    synthesize(ssp, data, {"actuator": truth}, tests=plan, direct=True, seed=seed, log=lambda *_: None)
    return diagnose(Options(data, tmp / "out", compiled(ssp), figures=figures, direct=False), log=lambda *_: None)


def named(doc: dict) -> dict:
    return {e["key"]: e for e in doc["named_effects"]}


def held_out(doc: dict) -> list[str]:
    return [n for n, g in doc["gap"].items() if g["role"] == "held-out"]


@pytest.mark.parametrize("seed", [1, 2])
def test_paper_case(built_ssp, tmp_path, seed):
    """Nominal = manufacturer data, truth = the paper's identified set: Coulomb friction and inertia
    mismatch are named, both recovered within 5 %, the held-out torque gap falls from tens of percent
    to the noise floor."""
    doc = run_case(built_ssp, tmp_path, IDENTIFIED, seed, figures=seed == 1)
    if seed == figures.DIAGNOSE_CASES["paper"][1]:
        assert_the_docs_state(doc, "paper")
    effects = named(doc)
    assert set(effects) == {"coulomb", "inertia_motor"}
    assert effects["coulomb"]["parameters"]["tau_c"] == pytest.approx(0.0718, rel=0.05)
    assert effects["inertia_motor"]["parameters"]["J1_scale"] == pytest.approx(1 / 1.56, rel=0.05)
    for name in held_out(doc):
        gap = doc["gap"][name]
        assert gap["before"]["torque_nrmse_percent"] > 50
        assert gap["after"]["torque_nrmse_percent"] < 1.2 * gap["before"]["torque_floor_percent"]
    assert doc["verdict"]["status"] == "explained"
    for e in effects.values():
        assert e["uncertainty"][next(iter(e["parameters"]))]["std"] > 0
        assert e["evidence"]["when_added"]["delta_bic_training"] < -10
    if seed == 1:  # the outputs a user gets
        out = tmp_path / "out"
        text = (out / "report.md").read_text()
        for fig in ("fig_time.png", "fig_residual_signals.png", "fig_residual_frequency.png"):
            assert (out / fig).stat().st_size > 10_000 and f"({fig})" in text
        assert json.loads((out / "diagnosis.json").read_text())["named_effects"][0]["effect"]
        from mast.core.ssp import SSPArchive

        with SSPArchive(out / "MAST_diagnosed.ssp") as archive:
            p = archive.system.components["actuator_2"].parameters
        assert p["tau_c"] == pytest.approx(effects["coulomb"]["parameters"]["tau_c"], rel=1e-12)
        assert p["J1_scale"] == pytest.approx(effects["inertia_motor"]["parameters"]["J1_scale"], rel=1e-12)


def assert_the_docs_state(doc: dict, case: str) -> None:
    """docs/diagnose.md's figures of this case ("Every effect alone") are this diagnosis' (`python docs/figures.py
    --source diagnose_CASE` writes them)."""
    problems = figures.check({f"diagnose_{case}": figures.diagnose_values(doc)})
    assert not problems, "\n".join(problems)


#: the effects hidden alone (docs/figures.py DIAGNOSE_CASES: the truth and the seed, those the cases had when they were
#: numbered 10, 11, ... in the order of issue 5's library). Viscous friction: beside an inertia change on one axis, on
#: two plans, in tests/test_diagnose_split.py; the measurement lag, as a filter and as a delay: beside another effect
#: there
CASES = ("coulomb", "stribeck", "inertia_motor", "inertia_guide", "carriage_mass", "offset")


@pytest.mark.parametrize("case", CASES)
def test_each_library_effect_hidden_alone_is_named(built_ssp, tmp_path, case):
    truth, seed = figures.DIAGNOSE_CASES[case]
    params = tuple(truth)
    doc = run_case(built_ssp, tmp_path, truth, seed=seed)
    assert_the_docs_state(doc, case)
    effects = named(doc)
    assert len(effects) == 1, effects
    ((key, effect),) = effects.items()
    assert doc["verdict"]["status"] == "explained"
    if case == "inertia_guide":
        # the two sides of the transmission: either named directly or reported as the equivalent alternative
        assert key in ("inertia_motor", "inertia_guide")
        values = dict(effect["parameters"])
        for alt in effect["evidence"]["alternatives"]:
            values.update(alt.get("parameters", {}))
        assert values["J_guide"] == pytest.approx(6.8e-4, rel=0.05)
        return
    assert key == case
    for p in params:
        # within 5 %, or (short tests, a small effect) within 3 standard deviations and 10 %
        error = abs(effect["parameters"][p] - truth[p])
        std = effect["uncertainty"][p]["std"]
        assert error <= max(0.05 * abs(truth[p]), 3 * std) and error <= 0.1 * abs(truth[p]), (p, effect)


@pytest.mark.parametrize(
    "plan, seed", [(PLAN, 3), (PLAN, 4), (SMALL, 95), (SMALL, 96)], ids=["plan-3", "plan-4", "small-95", "small-96"]
)
def test_nothing_hidden_names_nothing(built_ssp, tmp_path, plan, seed):
    doc = run_case(built_ssp, tmp_path, {}, seed, plan=plan)
    if plan is PLAN and seed == figures.DIAGNOSE_CASES["nothing"][1]:
        assert_the_docs_state(doc, "nothing")
    assert doc["named_effects"] == []
    assert doc["verdict"]["status"] == "nothing missing"
    assert doc["unexplained"] is None
    assert all(r < 1.2 for r in doc["verdict"]["residual_over_noise_per_test"].values())


def test_effect_outside_the_library_is_reported_unexplained(built_ssp, tmp_path):
    """A position-periodic guide torque (belt tooth mesh): no candidate explains it, backlash included (its
    phase-free score is tried and refused: it would explain only part of the band powers); nothing is named,
    the residual is shown. On the SMALL plan (2.5 s of records against PLAN's 4.8 s: the phase-free scan of
    backlash, which runs in full here, costs in proportion)."""
    doc = run_case(built_ssp, tmp_path, {"tau_ripple": 0.01}, seed=5, figures=True, plan=SMALL)
    assert doc["named_effects"] == []
    assert doc["verdict"]["status"] == "unexplained residual"
    assert doc["verdict"]["residual_over_noise_training"] > 2
    assert doc["unexplained"]["candidates_tried"]
    # the hunting of backlash could stand in for part of the ripple's band powers: tried, not forced onto it
    assert any(c["candidate"] == "backlash (phase-free score)" for c in doc["unexplained"]["candidates_tried"])
    out = tmp_path / "out"
    assert (out / "fig_unexplained.png").stat().st_size > 10_000
    assert "Unexplained residual" in (out / "report.md").read_text()


@pytest.mark.regime
@pytest.mark.parametrize("case", ["backlash", "backlash_small"])
def test_backlash_hidden_alone_is_named_on_the_phase_free_score(built_ssp, tmp_path, case):
    """Backlash hidden: the axes hunt (chaotically: even the exact truth does not reproduce the data sample by
    sample), so it is named and fitted on the band powers of the residual against ensembles of re-simulations
    (orchestration/diagnosis/phasefree.py), and the tests where the loop hunts are judged at the floor by their band
    powers. On docs/figures.py's DIAGNOSE_PLAN_FAST (z 10 Hz 8 mm, z 15 Hz 5 mm beside PLAN's slow tests), 0.06 and
    0.03 rad: with the mechanism's inertial reaction at every step the loop hunts on fast z tests only (the truth and
    the truth + 1e-6 part by 1.1-3.0 mN m there, 0 on the slow tests). PLAN's z 7 Hz barely hunts (0.2 mN m at 0.01
    rad); the hunting main's 0.01 and 0.003 rad cases on PLAN showed came from the mechanism's 1 ms hold."""
    truth, seed = figures.DIAGNOSE_CASES[case]
    backlash = truth["backlash"]
    plan = tuple(Spec(*test) for test in figures.DIAGNOSE_PLANS[figures.DIAGNOSE_CASE_PLANS[case]])
    doc = run_case(built_ssp, tmp_path, truth, seed, figures=seed == 7, plan=plan)
    assert_the_docs_state(doc, case)
    effects = named(doc)
    assert set(effects) == {"backlash"}
    assert doc["verdict"]["status"] == "explained"
    assert doc["verdict"]["judged_by_band_powers"]  # where the loop hunts: not sample by sample
    effect = effects["backlash"]
    value, unc = effect["parameters"]["backlash"], effect["uncertainty"]["backlash"]
    error = abs(value - backlash)
    assert error <= max(0.05 * backlash, 3 * unc["std"]) and error <= 0.1 * backlash, effect
    assert unc["ci95"][0] < value < unc["ci95"][1]
    pf = effect["evidence"]["phase_free"]
    assert pf["delta_bic"] < -10 and pf["cross_validated_deviance_change"] < -10
    assert all(pf["deviance_per_test"]["after"][n] <= pf["floor_per_test"][n] for n in doc["gap"])
    if seed == 7:
        out = tmp_path / "out"
        assert (out / "fig_phase_free.png").stat().st_size > 10_000
        assert "Phase-free score" in (out / "report.md").read_text()


#: the issue's kind of plan (issue 18): z, psi and theta at other frequencies and amplitudes than PLAN; the
#: default split holds out the rotations (psi 1.8 Hz, theta 4 Hz), so the fast z tests are all training
ISSUE_PLAN = (
    Spec("z", 0.004, 0.7, 1.2, 0.3),
    Spec("psi", math.radians(0.7), 1.8, 0.9, 0.3),
    Spec("z", 0.003, 3.5, 0.8, 0.2),
    Spec("theta", math.radians(0.5), 4.0, 0.7, 0.2),
    Spec("z", 0.0025, 6.0, 0.7, 0.2),
)


def test_nothing_hidden_on_the_issue_plan_names_nothing(built_ssp, tmp_path):
    data = tmp_path / "data"
    synthesize(built_ssp, data, {}, tests=ISSUE_PLAN, direct=True, seed=63, log=lambda *_: None)
    doc = diagnose(Options(data, tmp_path / "out", built_ssp, figures=False, native=True), log=lambda *_: None)
    assert doc["named_effects"] == [] and doc["verdict"]["status"] == "nothing missing"
    assert doc["identifiability"]["backlash"]["plan_meets"]
    assert doc["timing"]["simulated_ssp"] == compiled(built_ssp)  # Options.native: the variant beside the SSP


def test_cli_and_errors(built_ssp, tmp_path, capsys):
    from mast.cli import main

    data = tmp_path / "data"
    synthesize(built_ssp, data, {"actuator": IDENTIFIED}, tests=PLAN[2:3], direct=True, seed=6, log=lambda *_: None)
    # the identified set as the nominal model (a parameter set inside the SSP): nothing is missing
    assert (
        main(
            [
                "diagnose",
                built_ssp,
                "--measured",
                str(data),
                "--out",
                str(tmp_path / "o"),
                "--model",
                "actuator_identified",
            ]
        )
        == 0
    )
    doc = json.loads((tmp_path / "o" / "diagnosis.json").read_text())
    # one z test at 3 Hz: the console and the report say what such a plan cannot tell
    console = capsys.readouterr().out
    for title, why in (
        ("carriage or payload mass", "only motions of the axes alike"),
        ("backlash", "only one test at 3 Hz"),
        ("Stribeck", "no test at 1 Hz or below"),
    ):
        assert any(
            line.startswith("diagnose: this plan cannot tell") and title in line and why in line
            for line in console.splitlines()
        ), (title, console)
    report = (tmp_path / "o" / "report.md").read_text()
    assert "## What this test plan cannot tell" in report
    assert "| carriage_mass |" in report and "| backlash |" in report and "| lag |" not in report
    ident = doc["identifiability"]
    assert not ident["carriage_mass"]["plan_meets"] and ident["lag"]["plan_meets"]
    assert doc["model"] == "actuator_identified" and doc["verdict"]["status"] == "nothing missing"
    assert doc["augmented_model"]["values"]["tau_c"] == 0.0718
    # the SSP's native variant is built beside it (the fixture): the CLI re-simulates on it by default
    assert doc["timing"]["simulator"].startswith("the native FMUs") and doc["ssp"] == built_ssp
    assert (
        main(["diagnose", built_ssp, "--measured", str(data), "--out", str(tmp_path / "x"), "--fmu", "--direct"]) == 2
    )
    import shutil

    alone = shutil.copy(built_ssp, tmp_path / "alone.ssp")  # no native variant beside it
    assert main(["diagnose", str(alone), "--measured", str(data), "--out", str(tmp_path / "x"), "--native"]) == 2
    assert "no native variant" in capsys.readouterr().err and not (tmp_path / "x").exists()
    assert main(["diagnose", built_ssp, "--measured", str(tmp_path / "nowhere"), "--out", str(tmp_path / "x")]) == 2
    assert (
        main(["diagnose", built_ssp, "--measured", str(data), "--out", str(tmp_path / "x"), "--model", "no_such_set"])
        == 2
    )
