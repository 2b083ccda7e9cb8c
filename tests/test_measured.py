"""Measured-data format (docs/measured-data.md): loading, unit conversion, every validation error
names the file and the column; synthesize writes the format and keeps the truth outside;
replaying the recorded commands with the truth reproduces the noise-free signals."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from message_tables import documented_messages, documented_mismatches

from mast.data.measured import MeasuredDataError, load

N = 400
DT = 1e-3
PAGE = Path(__file__).resolve().parents[1] / "docs" / "measured-data.md"


@pytest.fixture(scope="module")
def built_ssp(built) -> str:
    """MAST.ssp of the session's build (conftest.py, ``built``)."""
    return str(built / "ssp" / "MAST.ssp")


def _write(folder: Path, files: dict, meta_over: dict | None = None, units: dict | None = None) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    meta = {
        "format": "mast-measured-data",
        "version": 1,
        "units": units or {"time": "s", "rho_cmd": "m", "rho": "m", "tau_m": "N.m"},
        "measurement": {"torque_filter_s": 5e-4},
        "tests": [{"file": f, "motion": "z", "amplitude": 0.005, "frequency": 2.0} for f in files],
    }
    meta.update(meta_over or {})
    (folder / "meta.json").write_text(json.dumps(meta))
    for name, table in files.items():
        header = ",".join(table)
        rows = np.column_stack(list(table.values()))
        np.savetxt(folder / name, rows, delimiter=",", header=header, comments="", fmt="%.10g")
    return folder


def _table(scale_time=1.0, scale_len=1.0, scale_tau=1.0, current=False) -> dict:
    t = np.arange(N) * DT
    cmd = 0.15 + 0.005 * np.sin(2 * math.pi * 2 * t)
    tab = {"time": t * scale_time}
    for j in (1, 2, 3):
        tab[f"rho_cmd_{j}"] = cmd * scale_len
    for j in (1, 2, 3):
        tab[f"rho_{j}"] = (cmd - 1e-5) * scale_len
    for j in (1, 2, 3):
        if current:
            tab[f"i_m_{j}"] = 0.05 * np.cos(2 * math.pi * 2 * t) / 0.0302
        else:
            tab[f"tau_m_{j}"] = 0.05 * np.cos(2 * math.pi * 2 * t) * scale_tau
    return tab


def test_load_converts_units(tmp_path):
    si = load(_write(tmp_path / "si", {"a.csv": _table()}))
    mm = load(
        _write(
            tmp_path / "mm",
            {"a.csv": _table(scale_time=1e3, scale_len=1e3, scale_tau=1e3)},
            units={"time": "ms", "rho_cmd": "mm", "rho": "mm", "tau_m": "mN.m"},
        )
    )
    cur = load(
        _write(
            tmp_path / "cur",
            {"a.csv": _table(current=True)},
            meta_over={"k_T": 0.0302},
            units={"time": "s", "rho_cmd": "m", "rho": "m", "i_m": "A"},
        )
    )
    a, b, c = si.tests[0], mm.tests[0], cur.tests[0]
    np.testing.assert_allclose(b.time, a.time, atol=1e-12)
    np.testing.assert_allclose(b.rho_cmd, a.rho_cmd, rtol=1e-9)
    np.testing.assert_allclose(b.tau_m, a.tau_m, rtol=1e-9)
    np.testing.assert_allclose(c.tau_m, a.tau_m, rtol=1e-9)
    assert a.name == "a" and a.frequency == 2.0 and a.amplitude == 0.005 and a.sample_time == pytest.approx(DT)
    assert si.torque_filter_s == 5e-4


def _broken(kind: str) -> tuple[dict, dict, dict | None]:
    tab = _table()
    meta_over: dict = {}
    units = None
    if kind == "missing column":
        del tab["rho_2"]
    elif kind == "nan":
        tab["tau_m_2"][123] = np.nan
    elif kind == "gap":
        tab["time"][200:] += 0.05
    elif kind == "irregular":
        tab["time"][200] += 0.3 * DT
    elif kind == "not increasing":
        tab["time"][17] = tab["time"][16]
    elif kind == "unknown unit":
        units = {"time": "s", "rho_cmd": "m", "rho": "inch", "tau_m": "N.m"}
    elif kind == "rho in mm labelled m":
        for j in (1, 2, 3):
            tab[f"rho_{j}"] = tab[f"rho_{j}"] * 1e3
    elif kind == "torque in mN.m labelled N.m":
        for j in (1, 2, 3):
            tab[f"tau_m_{j}"] = tab[f"tau_m_{j}"] * 1e3
    elif kind == "time in ms labelled s":
        tab["time"] = tab["time"] * 1e3
    elif kind == "current without k_T":
        tab = _table(current=True)
        units = {"time": "s", "rho_cmd": "m", "rho": "m", "i_m": "A"}
    elif kind == "no units entry":
        units = {"time": "s", "rho": "m", "tau_m": "N.m"}
    return tab, meta_over, units


@pytest.mark.parametrize(
    "kind, pattern",
    [
        ("missing column", r"a\.csv: missing column\(s\) rho_2"),
        (
            "nan",
            r"a\.csv: column tau_m_2: 1 missing or non-finite value\(s\), the first on data row 124 \(t = 0\.123 s\)",
        ),
        ("gap", r"a\.csv: column time: gap of 0\.051 s after t = 0\.199"),
        ("irregular", r"a\.csv: column time: irregular sampling"),
        ("not increasing", r"a\.csv: column time: not increasing at data row 18"),
        ("unknown unit", r"a\.csv: unit 'inch' for 'rho' is not known"),
        (
            "rho in mm labelled m",
            r"a\.csv: column rho_1: 154\.99 m lies outside the stroke \[0, 0\.3\] m: check units\.rho",
        ),
        (
            "torque in mN.m labelled N.m",
            r"a\.csv: column tau_m_1: motor torque up to 50 N\.m is implausible .* units\.tau_m",
        ),
        ("time in ms labelled s", r"a\.csv: column time: sampling step 1 s is implausible .* check units\.time"),
        ("current without k_T", r"a\.csv: columns i_m_1\.\.3 need the torque constant 'k_T'"),
        ("no units entry", r"a\.csv: meta\.json 'units' has no entry for 'rho_cmd'"),
    ],
)
def test_validation_errors_name_file_and_column(tmp_path, kind, pattern):
    tab, meta_over, units = _broken(kind)
    folder = _write(tmp_path / "d", {"a.csv": tab}, meta_over, units)
    with pytest.raises(MeasuredDataError, match=pattern):
        load(folder)


def test_folder_level_errors(tmp_path):
    folder = _write(tmp_path / "d", {"a.csv": _table()})
    np.savetxt(folder / "extra.csv", np.zeros((3, 2)), delimiter=",", header="time,x", comments="")
    with pytest.raises(MeasuredDataError, match=r"extra\.csv: not listed in meta\.json"):
        load(folder)
    (folder / "extra.csv").unlink()
    meta = json.loads((folder / "meta.json").read_text())
    meta["tests"].append({"file": "b.csv"})
    (folder / "meta.json").write_text(json.dumps(meta))
    with pytest.raises(MeasuredDataError, match=r"b\.csv: listed in meta\.json but not in"):
        load(folder)
    (folder / "meta.json").write_text("{not json")
    with pytest.raises(MeasuredDataError, match=r"meta\.json: not valid JSON"):
        load(folder)
    (folder / "meta.json").unlink()
    with pytest.raises(MeasuredDataError, match=r"no meta\.json"):
        load(folder)
    text = (tmp_path / "d" / "a.csv").read_text().splitlines()
    text[5] = text[5].replace(text[5].split(",")[1], "abc", 1)
    (tmp_path / "d" / "a.csv").write_text("\n".join(text))
    _write(tmp_path / "d", {}, meta_over={"tests": [{"file": "a.csv"}]})
    with pytest.raises(MeasuredDataError, match=r"a\.csv: column rho_cmd_1: 'abc' on line 6 is not a number"):
        load(tmp_path / "d")


def test_replay_reproduces_the_noise_free_signals(built_ssp, tmp_path):
    """Synthesize one test with a truth, reload it, simulate it driven by its recorded commands with the
    same truth: the torques before noise agree to 1e-9 N m, the positions to 1e-12 m."""
    from fmus.actuator.sensor import measure
    from mast.analyses.synthesize import TestSpec as Spec
    from mast.analyses.synthesize import synthesize
    from mast.core.run import drive_tick_steps
    from mast.core.ssp import SSPArchive
    from mast.data.measured import CommandReplay, controller_kinematics
    from mast.diagnosis.resimulation import sim_job

    truth = {"actuator": {"tau_c": 0.0718, "J1_scale": 0.641, "T_meas": 2e-3}}
    res = synthesize(
        built_ssp,
        tmp_path / "data",
        truth,
        tests=[Spec("theta", math.radians(0.8), 3.0, 1.0)],
        direct=True,
        workers=1,
        seed=4,
        log=lambda *_: None,
    )
    assert res["truth"] == tmp_path / "data.truth.json" and res["truth"].exists()
    assert "tau_c" not in (tmp_path / "data" / "meta.json").read_text()
    data = load(tmp_path / "data")
    t = data.tests[0]
    replay = CommandReplay(t.time, t.rho_cmd, controller_kinematics(built_ssp))
    params = {f"actuator_{j}": {**truth["actuator"], "rho_0": float(t.rho_cmd[0, j - 1])} for j in (1, 2, 3)}
    # exchanged every T_cur as synthesize and the diagnosis do (mast.core.run.drive_tick_steps)
    with SSPArchive(built_ssp) as archive:
        steps = drive_tick_steps(archive.system)
    assert steps[0] == 1e-4
    run = sim_job((built_ssp, t.name, replay, t.duration + 1e-12, params, True, steps, list(params)))
    obs = measure(measure(run["tau_m"], run["h"], T=2e-3, axis=0), run["h"], T=data.torque_filter_s, axis=0)
    idx = np.round(t.time / run["h"]).astype(int)
    clean = res["clean"][t.name]
    assert np.abs(obs[idx] - clean["tau_m"]).max() < 1e-9
    assert np.abs(run["rho"][idx] - clean["rho"]).max() < 1e-12
    # the measured data: the drive's filter, the noise (2 mN m) and the 1 um encoder steps
    assert np.std(t.tau_m - clean["tau_m"]) == pytest.approx(2e-3, rel=0.1)
    np.testing.assert_allclose(t.rho / 1e-6, np.round(t.rho / 1e-6), atol=1e-6)


def test_synthesize_cli(built_ssp, tmp_path):
    from mast.cli import main

    out = tmp_path / "cli"
    assert (
        main(
            [
                "synthesize",
                built_ssp,
                "--out",
                str(out),
                "--set",
                "actuator.tau_c=0.05",
                "--tests",
                "z:0.005:4:0.5",
                "--noise",
                "tau_m=0.001",
                "--direct",
                "--seed",
                "2",
                "--workers",
                "1",
            ]
        )
        == 0
    )
    data = load(out)
    assert [t.name for t in data.tests] == ["z_4Hz"]
    truth = json.loads((tmp_path / "cli.truth.json").read_text())
    assert truth["parameters"] == {f"actuator_{j}": {"tau_c": 0.05} for j in (1, 2, 3)}
    assert truth["measurement"]["noise_std"]["tau_m"] == 0.001
    assert main(["synthesize", built_ssp, "--out", str(out), "--set", "nowhere.x=1", "--direct"]) == 2


def test_synthesize_truth_out_is_a_folder_and_the_former_truth_file_is_refused(built_ssp, tmp_path, capsys):
    """`--truth-out DIR` (a folder like every --out) puts DIR/NAME.truth.json; the former `--truth FILE` stops before
    anything runs, naming the new option."""
    from mast.cli import main

    with pytest.raises(SystemExit) as stop:
        main(["synthesize", built_ssp, "--out", str(tmp_path / "d"), "--truth", str(tmp_path / "t.json")])
    assert stop.value.code == 2 and "--truth was renamed: --truth-out DIR" in capsys.readouterr().err
    assert not (tmp_path / "d").exists() and not (tmp_path / "t.json").exists()
    out = tmp_path / "d"
    argv = ["--tests", "z:0.005:4:0.2", "--direct", "--workers", "1", "--truth-out", str(tmp_path / "truths")]
    assert main(["synthesize", built_ssp, "--out", str(out), *argv]) == 0
    assert json.loads((tmp_path / "truths" / "d.truth.json").read_text())["parameters"] == {}
    assert not (tmp_path / "d.truth.json").exists()


def test_diagnose_refuses_torques_whose_unit_is_a_thousand_times_off_before_searching(built_ssp, tmp_path, capsys):
    """Torques in N.m declared as mN.m pass every plausibility bound of the loader; the nominal model's
    torque (gravity, inertia, friction of the recorded motion) shows the factor 1000 at once: the message
    docs/measured-data.md's validation table quotes, whole, said by the command it names."""
    from mast.cli import main

    data = tmp_path / "data"
    assert (
        main(["synthesize", built_ssp, "--out", str(data), "--tests", "z:0.005:5:0.3", "--direct", "--workers", "1"])
        == 0
    )
    meta = json.loads((data / "meta.json").read_text())
    meta["units"]["tau_m"] = "mN.m"
    (data / "meta.json").write_text(json.dumps(meta))
    capsys.readouterr()
    assert main(["diagnose", built_ssp, "--measured", str(data), "--out", str(tmp_path / "d"), "--workers", "1"]) == 2
    err = capsys.readouterr().err
    assert "z_5Hz.csv: column tau_m_1" in err and "units.tau_m (now 'mN.m')" in err and "0.001 times" in err
    row = "torques in the wrong unit, inside the bounds"
    said = documented_messages(PAGE, "### Validation: every problem names the file and the column")[row]
    message = next(line for line in err.splitlines() if "z_5Hz.csv: column tau_m_1" in line)
    message = message[message.index("z_5Hz.csv") :]
    problems = documented_mismatches({row: said}, {row: ["mast diagnose", message]})
    assert not problems, "docs/measured-data.md's validation table (update the page):\n" + "\n".join(problems)


@pytest.mark.parametrize(
    "units, pattern",
    [
        (
            {"time": "s", "rho_cmd": "mm", "rho": "mm", "tau_m": "N.m"},  # metres declared as mm: inside the stroke
            r"a\.csv: columns rho_cmd_1\.\.3 swing by \+-5e-06 m while meta\.json gives a z amplitude of 0\.005 m.*"
            r"check units\.rho_cmd \(now 'mm'\)",
        ),
        (
            {"time": "s", "rho_cmd": "m", "rho": "um", "tau_m": "N.m"},
            r"a\.csv: column rho_1 differs from rho_cmd_1 by 15\d mm .* 1e-06 times the commands.*units\.rho = 'um'",
        ),
    ],
)
def test_positions_in_the_wrong_length_unit_are_named(tmp_path, units, pattern):
    with pytest.raises(MeasuredDataError, match=pattern):
        load(_write(tmp_path / "d", {"a.csv": _table()}, units=units))


@pytest.mark.parametrize(
    "where, value, pattern",
    [
        (
            "measurement",
            {"torque_filter_s": "fast"},
            r"meta\.json: measurement\.torque_filter_s = 'fast': expected a finite",
        ),
        ("measurement", {"rho_resolution_m": [1]}, r"meta\.json: measurement\.rho_resolution_m = \[1\]"),
        ("test", {"frequency": "2 Hz"}, r"meta\.json: tests\[a\.csv\]\.frequency = '2 Hz'"),
        ("test", {"amplitude": None, "settle_s": "x"}, r"meta\.json: tests\[a\.csv\]\.settle_s = 'x'"),
    ],
)
def test_non_numeric_meta_values_name_the_key(tmp_path, where, value, pattern):
    folder = _write(tmp_path / "d", {"a.csv": _table()})
    meta = json.loads((folder / "meta.json").read_text())
    (meta["measurement"] if where == "measurement" else meta["tests"][0]).update(value)
    (folder / "meta.json").write_text(json.dumps(meta))
    with pytest.raises(MeasuredDataError, match=pattern):
        load(folder)


def test_csv_and_meta_with_a_utf8_byte_order_mark_load(tmp_path):
    """Spreadsheet programs save 'CSV UTF-8' with a BOM: the first column is still 'time'."""
    plain = load(_write(tmp_path / "plain", {"a.csv": _table()}))
    folder = _write(tmp_path / "bom", {"a.csv": _table()})
    for name in ("a.csv", "meta.json"):
        (folder / name).write_bytes(b"\xef\xbb\xbf" + (folder / name).read_bytes())
    np.testing.assert_array_equal(load(folder).tests[0].tau_m, plain.tests[0].tau_m)


def _message(make) -> str:
    with pytest.raises(MeasuredDataError) as error:
        make()
    return str(error.value)


def _loaded_with(tmp: Path, test: dict | None = None, **load_options) -> str:
    """The message of loading the clean table with ``test``'s keys changed in meta.json's test."""
    folder = _write(tmp, {"a.csv": _table()})
    meta = json.loads((folder / "meta.json").read_text())
    meta["tests"][0].update(test or {})
    (folder / "meta.json").write_text(json.dumps(meta))
    return _message(lambda: load(folder, **load_options))


def _text_in_a_number_field(tmp: Path) -> str:
    folder = _write(tmp, {"a.csv": _table()})
    lines = (folder / "a.csv").read_text().splitlines()
    cells = lines[6].split(",")
    cells[4] = "abc"  # rho_1 on line 7
    lines[6] = ",".join(cells)
    (folder / "a.csv").write_text("\n".join(lines) + "\n")
    return _message(lambda: load(folder))


def _not_listed(tmp: Path) -> str:
    folder = _write(tmp, {"a.csv": _table()})
    (folder / "extra.csv").write_text("time,x\n0,0\n")
    return _message(lambda: load(folder))


def _listed_but_missing(tmp: Path) -> str:
    folder = _write(tmp, {"a.csv": _table(), "z_9Hz.csv": _table()})
    (folder / "z_9Hz.csv").unlink()
    return _message(lambda: load(folder))


def _commands_in_the_wrong_unit(tmp: Path) -> str:
    """Commands in m declared as mm (the positions too): inside the stroke, but their swing is not the amplitude's."""
    units = {"time": "s", "rho_cmd": "mm", "rho": "mm", "tau_m": "N.m"}
    return _message(lambda: load(_write(tmp, {"z_5Hz.csv": _table()}, units=units)))


def _broken_message(kind: str):
    def make(tmp: Path) -> str:
        tab, meta_over, units = _broken(kind)
        return _message(lambda: load(_write(tmp, {"a.csv": tab}, meta_over, units)))

    return make


#: docs/measured-data.md's validation table: problem -> the messages the code gives for it on the tests' data, one for
#: each message the row quotes, in its order
DOCUMENTED = {
    "missing column": (_broken_message("missing column"),),
    "NaN, empty cell, inf": (_broken_message("nan"),),
    "text in a number field": (_text_in_a_number_field,),
    "gap": (_broken_message("gap"),),
    "irregular sampling": (_broken_message("irregular"),),
    "not increasing": (_broken_message("not increasing"),),
    "unknown unit": (_broken_message("unknown unit"),),
    "wrong unit (implausible values)": (
        _broken_message("rho in mm labelled m"),
        _broken_message("time in ms labelled s"),
    ),
    "positions in the wrong length unit, inside the stroke": (
        lambda tmp: _message(
            lambda: load(
                _write(tmp, {"a.csv": _table()}, units={"time": "s", "rho_cmd": "m", "rho": "um", "tau_m": "N.m"})
            )
        ),
        _commands_in_the_wrong_unit,
    ),
    "a meta.json value that is not a number": (lambda tmp: _loaded_with(tmp, {"frequency": "2 Hz"}),),
    "CSV not listed, listed but missing": (_not_listed, _listed_but_missing),
    "another number of drives than the system's actuators (`mast diagnose`)": (
        lambda tmp: _loaded_with(tmp, drives=6),
    ),
    "currents without k_T": (_broken_message("current without k_T"),),
    "a test file outside the folder": (lambda tmp: _loaded_with(tmp, {"file": "../other/x.csv"}),),
}
#: rows whose message needs more than loading the data: problem -> the test that checks its quoted messages
CHECKED_ELSEWHERE = {
    "torques in the wrong unit, inside the bounds": (
        "test_diagnose_refuses_torques_whose_unit_is_a_thousand_times_off_before_searching"
    ),
}


def test_the_documented_messages_are_the_codes(tmp_path):
    """Every example message of docs/measured-data.md's validation table is what the code says for that problem
    (``...`` standing for the rest of the text, DIR for the folder), and every row is checked (here or by the test
    named in CHECKED_ELSEWHERE)."""
    rows = documented_messages(PAGE, "### Validation: every problem names the file and the column")
    assert set(rows) == set(DOCUMENTED) | set(CHECKED_ELSEWHERE), set(rows) ^ (set(DOCUMENTED) | set(CHECKED_ELSEWHERE))
    actual = {
        problem: [make(tmp_path / f"d{k}_{j}") for j, make in enumerate(makers)]
        for k, (problem, makers) in enumerate(DOCUMENTED.items())
    }
    problems = documented_mismatches(rows, actual)
    assert not problems, "docs/measured-data.md's validation table (update the page):\n" + "\n".join(problems)
