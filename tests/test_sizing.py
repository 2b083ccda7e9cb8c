"""Drive sizing (mast sizing, docs/sizing.md): the two-node thermal model against its closed-form
solution, the figures against an independent computation from results.csv, the verdict against a
lowered rating, and the errors of bad input."""

from __future__ import annotations

import csv
import json
import math
import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from mast.analyses import sizing, thermal

REPO = Path(__file__).resolve().parents[1]
SSD = REPO / "ssp" / "MAST.ssd"
# the RE 40's catalogue network (drive_ratings.ssv) and its terminal resistance
NET = dict(R_th1=1.93, R_th2=4.65, tau_w=42.8, tau_s=809.0, R_25=0.299)


def closed_form_rise(t: np.ndarray, P: float, R_th1: float, R_th2: float, tau_w: float, tau_s: float) -> np.ndarray:
    """T_w - T_a of the two-node network after a step of the loss P at t = 0, solved by hand: the 2x2 system's
    eigenvalues from its trace and determinant, the modes' weights from x(0) = 0."""
    C_w, C_s = tau_w / R_th1, tau_s / R_th2
    a11, a12 = -1 / (R_th1 * C_w), 1 / (R_th1 * C_w)
    a21, a22 = 1 / (R_th1 * C_s), -(1 / R_th1 + 1 / R_th2) / C_s
    tr, det = a11 + a22, a11 * a22 - a12 * a21
    l1, l2 = (tr + math.sqrt(tr * tr - 4 * det)) / 2, (tr - math.sqrt(tr * tr - 4 * det)) / 2
    x_ss = np.array([P * (R_th1 + R_th2), P * R_th2])  # the steady state: the resistances in series
    v1, v2 = np.array([a12, l1 - a11]), np.array([a12, l2 - a11])
    c1, c2 = np.linalg.solve(np.column_stack([v1, v2]), -x_ss)  # x(0) = x_ss + c1 v1 + c2 v2 = 0
    return x_ss[0] + c1 * v1[0] * np.exp(l1 * t) + c2 * v2[0] * np.exp(l2 * t)


def test_thermal_step_response_is_the_closed_form():
    model = thermal.TwoNode(**NET)
    current = 6.0  # the nominal current
    t = np.arange(0.0, 12000.0, 1.0)
    T_w, _ = thermal.run(model, t, np.full(len(t), current))
    expected = closed_form_rise(t, NET["R_25"] * current**2, NET["R_th1"], NET["R_th2"], NET["tau_w"], NET["tau_s"])
    assert np.max(np.abs(T_w - model.T_ambient - expected)) < 1e-9 * expected.max()
    # at the nominal current the RE 40 settles near its rating (6.58 K/W x 10.8 W = 71 K above ambient)
    assert expected[-1] == pytest.approx(10.764 * 6.58, rel=0.02)


def test_thermal_steady_state_with_the_copper_coefficient_is_the_closed_form():
    alpha, current, T_a = 0.0039, 5.0, 313.15
    model = thermal.TwoNode(**NET, alpha_Cu=alpha, T_ambient=T_a)
    t = np.arange(0.0, 1.0, 1e-3)  # a duty cycle of constant current, repeated
    heat = thermal.periodic(model, t, np.full(len(t), current))
    # T_w - T_a = R_25 I^2 (1 + alpha (T_w - 25 degC)) (R_th1 + R_th2), solved for T_w
    R_sum, P_25 = NET["R_th1"] + NET["R_th2"], NET["R_25"] * current**2
    rise = P_25 * (1 + alpha * (T_a - 298.15)) * R_sum / (1 - P_25 * alpha * R_sum)
    assert heat.start[0] == pytest.approx(rise, rel=1e-9)
    assert heat.T_w.max() - T_a == pytest.approx(rise, rel=1e-9)
    assert abs(heat.warmup_T_w[-1] - T_a - rise) <= 0.1  # the warm-up reaches it
    assert 4 * 809 / 3 < heat.warmup_t[-1] < 10 * 809  # on the motor's time constant


def test_a_steady_rise_just_above_the_tolerance_is_reached_by_the_warm_up():
    """A light duty cycle whose steady rise (0.15 K) is above the 0.1 K tolerance while each of the network's two
    modes alone is below it (a 6-UPS leg in a 5 mm x motion at 1 Hz): the warm-up runs until it is within it
    (it stopped at the first cycle, with no cycle within the tolerance: an IndexError)."""
    model = thermal.TwoNode(**NET)
    current = math.sqrt(0.15 / (NET["R_25"] * (NET["R_th1"] + NET["R_th2"])))
    t = np.arange(0.0, 1.0, 1e-3)
    heat = thermal.periodic(model, t, np.full(len(t), current))
    assert heat.start[0] == pytest.approx(0.15, rel=1e-9)
    assert heat.cycles_to_settle > 0 and abs(heat.warmup_T_w[heat.cycles_to_settle] - model.T_ambient - 0.15) <= 0.1


def test_thermal_runaway_is_refused():
    model = thermal.TwoNode(**NET, alpha_Cu=0.0039)
    t = np.arange(0.0, 1.0, 1e-3)
    with pytest.raises(ValueError, match="thermal runaway"):
        thermal.periodic(model, t, np.full(len(t), 40.0))  # R I^2 alpha (R_th1 + R_th2) > 1


# ----------------------------------------------------------------------------- a run folder, written here
def write_run(folder: Path, ssp: Path = SSD, frequency: float = 1.0, scale: float = 1.0) -> dict:
    """A run folder as `mast run` writes it: 2 s at 1 ms of three drives on a sine (their signals known)."""
    folder.mkdir(parents=True, exist_ok=True)
    t = np.round(np.arange(0.0, 2.0, 1e-3), 9)
    w = 2 * math.pi * frequency
    columns = {"time": t}
    for k in (1, 2, 3):
        columns[f"actuator_{k}.tau_m"] = scale * (0.05 * k * np.sin(w * t) + 0.02)
        columns[f"actuator_{k}.omega_m"] = scale * 80.0 * np.cos(w * t + k)
        columns[f"actuator_{k}.i_m"] = columns[f"actuator_{k}.tau_m"] / 0.0302
    with open(folder / "results.csv", "w", newline="") as handle:
        out = csv.writer(handle)
        out.writerow(columns)
        out.writerows(zip(*(np.char.mod("%.12g", v) for v in columns.values())))
    (folder / "summary.json").write_text(
        json.dumps(
            {
                "motion": {"axis": "z", "amplitude": 0.01, "frequency_Hz": frequency},
                "system": {"ssp": str(ssp), "parameters": {}},
            }
        )
    )
    return columns


def read_back(path: Path, start: float) -> dict[str, list[float]]:
    """results.csv read with the csv module, the samples from ``start`` on."""
    with open(path) as handle:
        rows = list(csv.DictReader(handle))
    return {name: [float(r[name]) for r in rows if float(r["time"]) >= start - 1e-9] for name in rows[0]}


def test_figures_are_those_computed_independently_from_results_csv(tmp_path):
    write_run(tmp_path / "run")
    doc, _ = sizing.size_run(tmp_path / "run")
    data = read_back(tmp_path / "run" / "results.csv", 1.0)  # the duty cycle: the last of two periods
    i_r, p, J_in = 91 / 6, 0.07, 1.42e-05 + 1e-06 + 1.4e-06  # transmission.ssv, actuator_manufacturer.ssv
    for k in (1, 2, 3):
        tau, om, cur = (data[f"actuator_{k}.{s}"] for s in ("tau_m", "omega_m", "i_m"))
        items = {(i["component"], i["item"]): i["figure"] for i in doc["drives"][f"actuator_{k}"]["items"]}
        rms = lambda y: math.sqrt(sum(v * v for v in y) / len(y))  # noqa: E731
        assert items["motor", "RMS torque"] == pytest.approx(rms(tau), rel=1e-9)
        assert items["motor", "peak torque"] == pytest.approx(max(map(abs, tau)), rel=1e-9)
        assert items["motor", "peak speed"] == pytest.approx(max(map(abs, om)) * 60 / (2 * math.pi), rel=1e-9)
        assert items["amplifier", "RMS current"] == pytest.approx(rms(cur), rel=1e-9)
        assert items["amplifier", "peak current"] == pytest.approx(max(map(abs, cur)), rel=1e-9)
        # the gearhead's output torque with the acceleration from the sine's own derivative (not differenced)
        ts = data["time"]
        accel = [-80.0 * 2 * math.pi * math.sin(2 * math.pi * x + k) for x in ts]
        out = [i_r * (a - J_in * b) for a, b in zip(tau, accel)]
        assert items["gearhead", "RMS output torque"] == pytest.approx(rms(out), rel=1e-4)
        assert items["guide", "peak axial force"] == pytest.approx(2 * math.pi * max(map(abs, out)) / p, rel=1e-4)
        assert items["guide", "peak carriage speed"] == pytest.approx(
            max(map(abs, om)) * p / (2 * math.pi * i_r), rel=1e-9
        )
    assert doc["verdict"] == "pass"


def copy_system(tmp_path: Path) -> Path:
    """ssp/MAST.ssd and its parameter sets in a folder of the test's own."""
    shutil.copytree(REPO / "ssp" / "resources", tmp_path / "sys" / "resources", ignore=shutil.ignore_patterns("*.fmu"))
    shutil.copy(SSD, tmp_path / "sys" / "MAST.ssd")
    return tmp_path / "sys" / "MAST.ssd"


def test_the_verdict_flips_when_a_rating_is_lowered_below_the_run(tmp_path):
    ssd = copy_system(tmp_path)
    write_run(tmp_path / "run", ssd)
    doc, _ = sizing.size_run(tmp_path / "run")
    rms = max(i["figure"] for d in doc["drives"].values() for i in d["items"] if i["item"] == "RMS torque")
    assert doc["verdict"] == "pass" and rms < 0.177
    ratings = ssd.parent / "resources" / "drive_ratings.ssv"
    text = ratings.read_text()
    ratings.write_text(re.sub(r'(name="tau_N".*?<ssv:Real value=")177(")', rf"\g<1>{1e3 * rms * 0.9:.6g}\g<2>", text))
    doc, _ = sizing.size_run(tmp_path / "run")
    assert doc["verdict"] == "fail"
    assert (doc["limiting"]["component"], doc["limiting"]["item"]) in {
        ("motor", "RMS torque"),
        ("motor", "RMS torque, gearhead losses"),
    }
    assert doc["limiting"]["margin"] < 0


def test_a_drive_on_its_current_limit_is_at_limit(tmp_path):
    write_run(tmp_path / "run")
    t, signals = sizing.read_results(tmp_path / "run" / "results.csv")
    signals["actuator_2.i_m"] = np.clip(signals["actuator_2.i_m"] * 100, -10.0, 10.0)  # held at the 10 A peak
    from mast.core.ssp import read_ssd

    sized = sizing.size_signals(sizing.drives(read_ssd(SSD)), t, signals, 1.0)
    v = sizing.verdict(sized)
    assert v["verdict"] == "fail"  # 10 A RMS-ish is above the 5 A continuous current
    peak = [i for i in sized[1].items if i.name == "peak current"][0]
    assert peak.status == "at limit" and peak.margin == pytest.approx(0.0, abs=1e-12)


def test_a_run_folder_without_results_is_named(tmp_path, capsys):
    from mast.cli import main

    (tmp_path / "run").mkdir()
    with pytest.raises(sizing.SizingError, match=r"no results\.csv"):
        sizing.size_run(tmp_path / "run")
    assert main(["sizing", str(tmp_path / "run")]) == 2
    assert "no results.csv" in capsys.readouterr().err
    assert list((tmp_path / "run").iterdir()) == []  # nothing written


@pytest.mark.parametrize(
    "edit, message",
    [
        (
            lambda d: d["motion"].update(frequency_Hz="1"),
            "field 'motion.frequency_Hz' is a string ('1'): expected a number",
        ),
        (
            lambda d: d["motion"].update(frequency_Hz=-1),
            "field 'motion.frequency_Hz' is -1: expected a finite number >= 0",
        ),
        (lambda d: d.update(motion=[1.0]), "field 'motion' is an array ([1.0]): expected an object"),
        (lambda d: d.update(system=["a.ssp"]), "field 'system' is an array (['a.ssp']): expected an object"),
        (lambda d: d["system"].update(ssp=3), "field 'system.ssp' is a number (3): expected a string"),
        (lambda d: d["system"].update(parameters=[]), "field 'system.parameters' is an array ([]): expected an object"),
        (
            lambda d: d["system"].update(parameters={"actuator_1": 2.0}),
            "field 'system.parameters.actuator_1' is a number (2.0): expected an object",
        ),
        (
            lambda d: d["system"].update(parameters={"actuator_1": {"R": [1]}}),
            "field 'system.parameters.actuator_1.R' is an array: expected a number, a string or a boolean",
        ),
    ],
)
def test_summary_fields_of_the_wrong_type_are_named(tmp_path, capsys, edit, message):
    """They ended in a TypeError (or AttributeError) traceback; now the file, the field and what was expected."""
    from mast.cli import main

    write_run(tmp_path / "run")
    path = tmp_path / "run" / "summary.json"
    doc = json.loads(path.read_text())
    edit(doc)
    path.write_text(json.dumps(doc))
    with pytest.raises(sizing.SizingError, match=re.escape(f"{path}: {message}")):
        sizing.size_run(tmp_path / "run")
    assert main(["sizing", str(tmp_path / "run"), "--no-plots"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"error: {path}: {message}") and "Traceback" not in err
    assert sorted(f.name for f in (tmp_path / "run").iterdir()) == ["results.csv", "summary.json"]  # nothing written
    path.write_text("[1, 2]")
    with pytest.raises(sizing.SizingError, match=r"summary\.json: the document is an array: expected an object"):
        sizing.size_run(tmp_path / "run")


def test_ratings_missing_for_a_drive_are_named_and_nothing_is_written(tmp_path):
    ssd = copy_system(tmp_path)
    write_run(tmp_path / "run", ssd)
    text = ssd.read_text()
    blocks = text.split('<ssd:Component name="actuator_2"', 1)
    ssd.write_text(
        blocks[0]
        + '<ssd:Component name="actuator_2"'
        + re.sub(r"\n[ \t]*<ssc:Annotation type=\"mast.sizing\">.*?</ssc:Annotation>", "", blocks[1], count=1)
    )
    before = sorted(p.name for p in (tmp_path / "run").iterdir())
    with pytest.raises(sizing.SizingError, match=r"drive actuator_2: .* names no ratings"):
        sizing.size_run(tmp_path / "run")
    ssd.write_text(text)
    ratings = ssd.parent / "resources" / "drive_ratings.ssv"
    ratings.write_text(re.sub(r'\n[ \t]*<ssv:Parameter name="R_th2".*?</ssv:Parameter>', "", ratings.read_text()))
    with pytest.raises(
        sizing.SizingError,
        match=r"drive actuator_1: its ratings resources/drive_ratings.ssv lack R_th2 "
        r"\(thermal resistance housing-ambient, K/W\)",
    ):
        sizing.size_run(tmp_path / "run")
    ratings.unlink()
    with pytest.raises(
        sizing.SizingError, match=r"drive actuator_1: its ratings resources/drive_ratings.ssv cannot be read"
    ):
        sizing.size_run(tmp_path / "run")
    assert sorted(p.name for p in (tmp_path / "run").iterdir()) == before


def test_a_rating_of_the_wrong_dimension_is_named(tmp_path):
    ssd = copy_system(tmp_path)
    write_run(tmp_path / "run", ssd)
    ratings = ssd.parent / "resources" / "drive_ratings.ssv"
    ratings.write_text(
        ratings.read_text().replace('<ssv:Real value="12000" unit="rpm"/>', '<ssv:Real value="12000" unit="N.m"/>')
    )
    with pytest.raises(sizing.SizingError, match=r"rating n_max .* expected a Real in rad/s"):
        sizing.size_run(tmp_path / "run")


def test_mast_sizing_writes_the_table_and_plots_atomically(tmp_path, capsys):
    from mast.cli import main

    write_run(tmp_path / "run")
    assert main(["sizing", str(tmp_path / "run")]) == 0
    printed = capsys.readouterr().out
    assert "Sizing verdict: **pass**" in printed and "| actuator_3 | amplifier | peak current |" in printed
    names = sorted(p.name for p in (tmp_path / "run").iterdir())
    assert names == sorted(["results.csv", "summary.json", *sizing.FILES])  # no temporary file left
    doc = json.loads((tmp_path / "run" / "sizing.json").read_text())
    assert doc["verdict"] == "pass" and set(doc["drives"]) == {"actuator_1", "actuator_2", "actuator_3"}
    assert (tmp_path / "run" / "sizing_envelope.png").read_bytes()[:4] == b"\x89PNG"


def test_the_built_system_carries_its_ratings(tmp_path, built_native):
    """mast build packs the ratings set each actuator names; mast run puts the verdict in summary.json."""
    built = built_native / "ssp" / "MAST.ssp"
    from mast.cli import main
    from mast.core.ssp import SSPArchive

    with SSPArchive(built) as archive:
        assert archive.system.components["actuator_1"].ratings is not None
        assert set(sizing.drives(archive.system)) == {"actuator_1", "actuator_2", "actuator_3"}
    assert main(["run", str(built), "--direct", "--stop-time", "0.5", "--frequency", "4", "--out", str(tmp_path)]) == 0
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["sizing"]["verdict"] == "pass" and summary["system"]["ssp"] == str(built.resolve())
    assert (tmp_path / "sizing.md").is_file()


def test_batch_metrics_and_compare_columns_carry_the_verdict(tmp_path):
    """mast batch's metric family `sizing` and mast compare's columns: the verdict of the same signals."""
    from mast.analyses.compare import Candidate, sizing_columns
    from mast.analyses.frequency import SineResult
    from mast.analyses.metrics import case_metrics
    from mast.core.master import Result
    from mast.core.ssp import read_ssd

    drive_set = sizing.drives(read_ssd(SSD))
    results = []
    for frequency, scale in ((1.0, 1.0), (2.0, 3.0)):  # a gentle test and a hard one
        columns = write_run(tmp_path / f"run{frequency:g}", frequency=frequency, scale=scale)
        t = columns.pop("time")
        expected = sizing.verdict(sizing.size_signals(drive_set, t, columns, frequency))
        motion = {"axis": "z", "amplitude": 0.01, "frequency": frequency}
        metrics = case_metrics(Result(t, columns), ["sizing"], motion, drives=drive_set)
        assert metrics["sizing_margin"] == pytest.approx(expected["limiting"]["margin"], rel=1e-12)
        assert metrics["sizing_fail"] == float(expected["verdict"] == "fail")
        assert "sizing_margin" not in case_metrics(Result(t, columns), ["sizing"], motion, drives=None)
        results.append(
            (
                expected,
                SineResult(
                    "z", 0.01, frequency, 1.0 + 0j, [0.0], [0.0], [0.0], 0.0, {}, signals={"time": t, **columns}
                ),
            )
        )
    assert results[0][0]["verdict"] == "pass" and results[1][0]["verdict"] == "fail"
    row = sizing_columns(Candidate("MAST", str(SSD), str(SSD)), [r for _, r in results], None)
    worst = results[1][0]["limiting"]
    assert row["sizing_verdict"] == "fail" and row["sizing_margin"] == pytest.approx(worst["margin"], rel=1e-12)
    assert row["sizing_limiting"] == f"{worst['drive']} {worst['component']} {worst['item']} at 2 Hz"
    assert row["sizing_holds_up_to_Hz"] == 1.0
    no_ratings = sizing_columns(Candidate("X", str(tmp_path / "none.ssd"), ""), [results[0][1]], None)
    assert no_ratings["sizing_verdict"] is None and "none.ssd" in no_ratings["sizing_note"]


def test_the_duty_cycle_is_whole_periods_at_the_end_of_the_run():
    t = np.round(np.arange(0.0, 3.0005, 1e-3), 9)  # 3 s at 1 ms, as `make run` records
    for frequency, samples in ((10.0, 2900), (1.0, 2000), (3.0, 2000), (7.0, 2000), (0.5, 2000)):
        cycle = sizing.duty_cycle(t, frequency)
        assert (cycle.start, cycle.stop) == (len(t) - samples, len(t)), frequency
        assert (samples * 1e-3 * frequency) == pytest.approx(round(samples * 1e-3 * frequency))  # whole periods
    assert sizing.duty_cycle(t, 0.0) is None and sizing.duty_cycle(t, 0.2) is None  # not periodic, too short


def test_a_ratings_source_outside_the_system_is_refused(tmp_path):
    from mast.core.ssp import read_ssd
    from mast.core.ssv import SSPFormatError

    ssd = copy_system(tmp_path)
    ssd.write_text(
        ssd.read_text().replace('source="resources/drive_ratings.ssv"', 'source="../../drive_ratings.ssv"', 1)
    )
    with pytest.raises(
        SSPFormatError, match="component 'actuator_1' ratings '../../drive_ratings.ssv' is not a relative path inside"
    ):
        read_ssd(ssd)
