"""A specimen on the table (docs/specimens.md): the forms of ``--specimen``, every refusal and its message, the
payload parameters reaching the mechanism of a run, the static hold against the drives' ratings, and the option in
every command that runs the mechanism."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from fmus.mechanism.designs import PAYLOAD_PARAMETERS
from mast import cli
from mast.analyses.compare import Candidate
from mast.analyses.specimen import check_held
from mast.batch.cli import with_specimen as batch_with_specimen
from mast.batch.config import BatchConfig, BatchConfigError
from mast.core.specimen import Specimen, SpecimenError, parse, with_specimen
from mast.diagnosis.options import Options, with_parameters

COMMANDS = ("run", "compare", "batch", "sizing", "synthesize", "diagnose")
OFFSET = "2,0.05,-0.02,0.1"  # 2 kg, 50 mm along x, -20 mm along y, 100 mm above P


# ----------------------------------------------------------------------------- the forms
def test_the_forms_give_the_mechanisms_payload_parameters(tmp_path):
    names = [p.name for p in PAYLOAD_PARAMETERS]
    assert parse("5").parameters() == dict(zip(names, [5.0] + [0.0] * 9))
    assert parse(OFFSET).parameters() == dict(zip(names, [2.0, 0.05, -0.02, 0.1] + [0.0] * 6))
    assert parse("2,0,0,0.1,0.02,0.03,0.04").inertia == (0.02, 0.03, 0.04, 0.0, 0.0, 0.0)
    full = parse("2,0,0,0.1,0.02,0.03,0.04,0.001,-0.002,0.003")
    assert full.parameters()["I_payload_xz"] == -0.002 and full.parameters()["I_payload_yz"] == 0.003
    file = tmp_path / "block.toml"
    file.write_text("mass = 2.0\ncom = [0.05, -0.02, 0.1]\ninertia = [0.02, 0.03, 0.04, 0.001, -0.002, 0.003]\n")
    assert parse(str(file)).parameters() == {**full.parameters(), "payload_x": 0.05, "payload_y": -0.02}
    (tmp_path / "point.toml").write_text("mass = 3\n")
    assert parse(str(tmp_path / "point.toml")) == Specimen(3.0)


def _rotated(principal, angles) -> tuple:
    """An inertia (Ixx, Iyy, Izz, Ixy, Ixz, Iyz) with the principal moments ``principal`` in axes turned by
    ``angles`` (about x, then y) [rad]."""
    cx, sx, cy, sy = math.cos(angles[0]), math.sin(angles[0]), math.cos(angles[1]), math.sin(angles[1])
    R = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]]) @ np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    T = R @ np.diag(principal) @ R.T
    return (*np.diag(T), T[0, 1], T[0, 2], T[1, 2])


def test_a_principal_moment_beyond_the_others_is_refused_where_the_diagonal_passes():
    inertia = _rotated((0.1, 0.5, 2.4), (math.radians(45), math.atan(1 / math.sqrt(2))))
    xx, yy, zz = inertia[:3]
    assert xx <= yy + zz and yy <= xx + zz and zz <= xx + yy  # only the principal moments tell
    with pytest.raises(SpecimenError, match=r"principal moment 2\.4 kg m\^2 > the sum of the other two, 0\.6"):
        Specimen(1.0, inertia=inertia)
    Specimen(1.0, inertia=_rotated((0.5, 1.0, 1.4), (0.3, 0.7)))  # a physical one, turned: accepted


BAD = [
    ("-1", r"mass -1\.0 kg: expected a finite mass >= 0 kg"),
    ("nan", r"mass nan kg: expected a finite mass >= 0 kg"),
    ("inf,0,0,0", r"mass inf kg: expected a finite mass >= 0 kg"),
    ("2,0,0", r"3 numbers; expected 1, 4, 7 or 10"),
    ("2,0,0,0,1", r"5 numbers; expected 1, 4, 7 or 10"),
    ("2,a", r"not numbers; expected MASS\[,X,Y,Z"),
    ("", r"not numbers"),
    ("2,inf,0,0", r"centre of mass offset \(inf, 0\.0, 0\.0\) m: expected finite numbers"),
    ("2,0,nan,0", r"centre of mass offset"),
    ("1,0,0,0,nan,1,1", r"inertia Ixx = nan: expected finite numbers in kg m\^2"),
    ("1,0,0,0,-1,1,1", r"inertia Ixx = -1 kg m\^2: expected a moment >= 0"),
    ("1,0,0,0,5,1,1", r"inertia Ixx = 5 kg m\^2 > Iyy \+ Izz = 2 kg m\^2: not a rigid body .*triangle inequality"),
    ("1,0,0,0,1,4,1", r"inertia Iyy = 4 kg m\^2 > Ixx \+ Izz = 2 kg m\^2"),
    ("1,0,0,0,1,1,3", r"inertia Izz = 3 kg m\^2 > Ixx \+ Iyy = 2 kg m\^2"),
    ("1,0,0,0,1,1,1,2,0,0", r"not positive semi-definite \(principal moments -1, 1, 3 kg m\^2"),
    ("0,0,0,0,1,1,1", r"with mass 0 kg: a massless body has no inertia"),
]


@pytest.mark.parametrize("text, message", BAD, ids=[b[0] or "empty" for b in BAD])
def test_every_bad_form_is_refused_naming_the_input_and_the_limit(text, message):
    with pytest.raises(SpecimenError, match=message) as err:
        parse(text)
    assert f"--specimen {text or repr(text)}:" in str(err.value)


BAD_FILES = [
    ("mass = -2\n", r"mass -2\.0 kg: expected a finite mass >= 0 kg"),
    ("com = [0, 0, 0.1]\n", r"no key 'mass' \(kg\)"),
    ("mass = 2\nweight = 3\n", r"unknown key\(s\) weight; expected mass, com, inertia"),
    ("mass = 2\ncom = [0, 0]\n", r"com = \[0, 0\]: expected a list of 3 numbers"),
    ("mass = 2\ninertia = [1, 1, 1]\n", r"inertia = \[1, 1, 1\]: expected a list of 6 numbers"),
    ('mass = "2 kg"\n', r"mass = '2 kg': expected a number \(kg\)"),
    ("mass = 2\ninertia = [5, 1, 1, 0, 0, 0]\n", r"Ixx = 5 kg m\^2 > Iyy \+ Izz = 2 kg m\^2"),
    ("mass = \n", r"cannot read it as TOML"),
]


@pytest.mark.parametrize("text, message", BAD_FILES, ids=[f"file{k}" for k in range(len(BAD_FILES))])
def test_every_bad_file_is_refused_naming_the_file_and_the_key(tmp_path, text, message):
    path = tmp_path / "specimen.toml"
    path.write_text(text)
    with pytest.raises(SpecimenError, match=message) as err:
        parse(str(path))
    assert str(path) in str(err.value)


def test_a_missing_file_is_named(tmp_path):
    with pytest.raises(SpecimenError, match=r"no_such\.toml: no such file \(expected a TOML file"):
        parse(str(tmp_path / "no_such.toml"))


def test_the_payload_set_twice_is_refused_and_the_overrides_merge():
    s = parse(OFFSET)
    assert with_specimen({"actuator_1": {"tau_c": 0.07}}, s) == {
        "actuator_1": {"tau_c": 0.07},
        "mechanism": s.parameters(),
    }
    assert with_specimen({"mechanism": {"m_platform": 2.5}}, s)["mechanism"]["m_platform"] == 2.5
    with pytest.raises(SpecimenError, match=r"--specimen 2,0.05.* and --set mechanism\.m_payload both set"):
        with_specimen({"mechanism": {"m_payload": 1.0}}, s)
    assert with_specimen({"mechanism": {"m_payload": 1.0}}, s, replace=True)["mechanism"]["m_payload"] == 2.0
    assert with_specimen(None, None) is None


def test_bodies_bolted_together_follow_the_parallel_axis_theorem():
    two = Specimen(1.0, (1.0, 0.0, 0.0)).combined(Specimen(1.0, (-1.0, 0.0, 0.0)))
    assert two.mass == 2.0 and two.com == (0.0, 0.0, 0.0) and two.inertia == (0.0, 2.0, 2.0, 0.0, 0.0, 0.0)
    block = Specimen(2.0, (0.1, 0.0, 0.2), (0.01, 0.01, 0.01, 0.0, 0.0, 0.0)).combined(Specimen(3.0))
    assert block.com == pytest.approx((0.04, 0.0, 0.08))
    # the products are tensor entries, -sum m dx dz: 2 (0.06)(0.12) + 3 (0.04)(0.08)
    assert block.inertia[4] == pytest.approx(-(2 * 0.06 * 0.12 + 3 * 0.04 * 0.08))


def test_compares_unknown_payload_is_bolted_to_the_specimen():
    s = parse(OFFSET)
    robust = Candidate("joint +3 kg", "x.ssp", "joint", payload_kg=3.0)
    mech = robust.overrides({"mechanism": s.parameters()})["mechanism"]
    assert mech["m_payload"] == 5.0 and mech["payload_x"] == pytest.approx(0.02)
    assert robust.overrides(None) == {"mechanism": {"m_payload": 3.0}}  # --payload alone: as before


# ----------------------------------------------------------------------------- the static hold
def test_the_drives_hold_a_small_specimen_and_name_the_limiting_item(built):
    doc = check_held(built / "ssp" / "MAST.ssp", parse(OFFSET))
    assert set(doc["drives"]) == {"actuator_1", "actuator_2", "actuator_3"}
    items = {r["item"]: r["limit"] for r in doc["drives"]["actuator_1"]["items"]}
    assert items == {"belt (drive) force": 250.0, "output torque": 7.5, "torque": pytest.approx(0.177)}
    # heavier means more force on the drives
    heavier = check_held(built / "ssp" / "MAST.ssp", parse("3,0.05,-0.02,0.1"))
    assert sum(d["static_force_N"] for d in heavier["drives"].values()) > sum(
        d["static_force_N"] for d in doc["drives"].values()
    )
    assert 0 < doc["limiting"]["margin"] < 1


def test_a_specimen_the_drives_cannot_hold_is_refused_before_any_step(built, tmp_path, capsys, monkeypatch):
    import mast.core.run

    def no_run(*args, **kwargs):
        raise AssertionError("the run started")

    monkeypatch.setattr(mast.core.run, "simulate", no_run)
    out = tmp_path / "heavy"
    code = cli.main(["run", str(built / "ssp" / "MAST.ssp"), "--direct", "--specimen", "1000", "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2 and not out.exists()
    assert "--specimen 1000: drive actuator_1 cannot hold it at rest at the home pose" in err
    assert "guide belt (drive) force" in err and "> its rating F_guide_max = 250 N" in err
    assert "resources/drive_ratings.ssv" in err


def test_a_system_without_a_mechanism_cannot_carry_one(built):
    with pytest.raises(SpecimenError, match=r"has no component 'mechanism' to carry a specimen"):
        check_held(built / "ssp" / "EMPS_bench.ssp", parse("2"))


# ----------------------------------------------------------------------------- the commands
def test_a_run_carries_the_specimen_to_the_mechanism(built, tmp_path, capsys):
    out = tmp_path / "run"
    ssp = built / "ssp" / "MAST.ssp"
    code = cli.main(["run", str(ssp), "--direct", "--stop-time", "0.05", "--specimen", OFFSET, "--out", str(out)])
    printed = capsys.readouterr().out
    assert code == 0, printed
    assert "specimen: held at rest at home" in printed and "limiting actuator_" in printed
    mechanism = json.loads((out / "summary.json").read_text())["system"]["parameters"]["mechanism"]
    assert {k: mechanism[k] for k in ("m_payload", "payload_x", "payload_y", "payload_z")} == {
        "m_payload": 2.0,
        "payload_x": 0.05,
        "payload_y": -0.02,
        "payload_z": 0.1,
    }
    # mast sizing of that run: the specimen's static hold beside the verdict; one it cannot hold refused
    assert cli.main(["sizing", str(out), "--specimen", OFFSET, "--no-plots", "--out", str(tmp_path / "s")]) == 0
    held = json.loads((tmp_path / "s" / "sizing.json").read_text())["specimen"]
    assert held["specimen"]["m_payload"] == 2.0 and "actuator_3" in held["drives"]
    assert cli.main(["sizing", str(out), "--specimen", "1000", "--out", str(tmp_path / "s2")]) == 2
    assert "cannot hold it" in capsys.readouterr().err and not (tmp_path / "s2").exists()


def test_simulate_takes_a_specimen(built):
    from mast.core.motion import SineMotion
    from mast.core.run import simulate

    s = parse(OFFSET)
    result = simulate(built / "ssp" / "MAST.ssp", SineMotion("z", 0.001, 1.0), 0.01, specimen=s, direct=True)
    assert {k: result.stats["parameters"]["mechanism"][k] for k in s.parameters()} == s.parameters()


def test_the_triangle_inequality_refusal_on_the_command_line(capsys):
    with pytest.raises(SystemExit) as stop:
        cli.main(["run", "--specimen", "1,0,0,0,5,1,1", "--out", "unused"])
    err = capsys.readouterr().err
    assert stop.value.code == 2
    assert "argument --specimen: 1,0,0,0,5,1,1: inertia Ixx = 5 kg m^2 > Iyy + Izz = 2 kg m^2" in err


@pytest.mark.parametrize("command", COMMANDS)
def test_every_command_that_runs_the_mechanism_takes_the_option(command, capsys):
    with pytest.raises(SystemExit) as stop:
        cli.main([command, "--help"])
    text = capsys.readouterr().out
    assert stop.value.code == 0
    assert "--specimen" in text and "kg m^2" in text and "FILE.toml" in text
    required = {
        "run": [],
        "compare": ["--mechanism", "a.fmu", "--out", "o"],
        "batch": ["config.toml", "--out", "o"],
        "sizing": ["run_dir"],
        "synthesize": ["--out", "o"],
        "diagnose": ["--measured", "m", "--out", "o"],
    }[command]
    with pytest.raises(SystemExit) as stop:
        cli.main([command, *required, "--specimen=-1"])
    assert stop.value.code == 2
    assert "argument --specimen: -1: mass -1.0 kg: expected a finite mass >= 0 kg" in capsys.readouterr().err


def test_batch_carries_the_specimen_in_its_parameters(built, capsys):
    s = parse(OFFSET)
    config = BatchConfig.from_dict({"ssp": str(built / "ssp" / "MAST.ssp"), "parameters": {"controller.k_v": 21.5}})
    params = batch_with_specimen(config, s)
    assert params == {"controller.k_v": 21.5, **{f"mechanism.{k}": v for k, v in s.parameters().items()}}
    assert "specimen: held at rest at home" in capsys.readouterr().out
    clash = BatchConfig.from_dict({"ssp": str(built / "ssp" / "MAST.ssp"), "parameters": {"mechanism.m_payload": 1}})
    with pytest.raises(BatchConfigError, match=r"\[parameters\] mechanism\.m_payload of the config both set"):
        batch_with_specimen(clash, s)
    heavy = BatchConfig.from_dict({"ssp": str(built / "ssp" / "MAST.ssp")})
    with pytest.raises(SpecimenError, match="cannot hold it"):
        batch_with_specimen(heavy, parse("1000"))


def test_diagnose_puts_the_specimen_in_the_nominal_model(tmp_path):
    s = parse(OFFSET)
    opt = Options(tmp_path, tmp_path, "x.ssp", parameters=with_specimen({}, s))
    assert with_parameters({"actuator_1": {"tau_c": 0.07}}, opt) == {
        "actuator_1": {"tau_c": 0.07},
        "mechanism": s.parameters(),
    }
    assert with_parameters({}, Options(tmp_path, tmp_path, "x.ssp")) == {}
