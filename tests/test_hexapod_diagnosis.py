"""The hexapod (6-UPS: six drives, six coordinates) in batch and diagnosis (issue 26).

One synthesized data set, shared by the tests (module fixture ``hexapod_data``): the 6-UPS system with Coulomb
friction 0.05 N m on drive 5 alone (its actuator set's nominal value on the others), three short sine tests, z and
x (x_2.5Hz held out). The measured-data folder has six drives and all six pose coordinates; replaying its
commands with the truth gives back the noise-free torques; the diagnosis names the friction of drive 5, an axis
the 3PRS does not have, within 5 %. A batch of hexapod cases gives the drive torques the hexapod's symmetries
require. The system is a parameter (``SYSTEM``, "6PUS" runs them on the 6-PUS): the tests use nothing of the
hexapod but its design's name.
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest
from conftest import build_mechanism_system
from docs_figures import figures

from mast.analyses.synthesize import TestSpec as Spec
from mast.analyses.synthesize import synthesize
from mast.core.ssp import SSPArchive
from mast.data.measured import MeasuredDataError, load
from mast.diagnosis import Options, diagnose
from mast.diagnosis.effects import LIBRARY, drive_of, for_drives

ROOT = Path(__file__).resolve().parents[1]
#: docs/figures.py DIAGNOSE_HEXAPOD (docs/diagnose.md states the diagnosis' figures): the design (mast.core.designs,
#: ssp/MAST_6UPS.ssd); short tests where Coulomb friction stays identifiable (reversals in a training and a held-out
#: test, every drive moving in both): z 1.2 Hz 4 mm, x 2.5 Hz 4 mm (held out), z 5 Hz 3 mm, 2.5 s simulated in all;
#: the hidden effect, Coulomb friction of drive 5 [N m]; the actuator-side effects (friction, inertia, lag, offset) on
#: all axes and on each of the six alone
SYSTEM = figures.DIAGNOSE_HEXAPOD["system"]
PLAN = tuple(Spec(*test) for test in figures.DIAGNOSE_HEXAPOD["plan"])
DRIVE, TAU_C = figures.DIAGNOSE_HEXAPOD["drive"], figures.DIAGNOSE_HEXAPOD["tau_c"]
SEED = figures.DIAGNOSE_HEXAPOD["seed"]


@pytest.fixture(scope="module")
def hexapod_ssp(tmp_path_factory) -> str:
    """The system's SSP with the Python FMUs it needs, built from this tree."""
    return str(build_mechanism_system(SYSTEM, tmp_path_factory.mktemp("hexapod_build")))


@pytest.fixture(scope="module")
def nominal_tau_c(hexapod_ssp) -> float:
    with SSPArchive(hexapod_ssp) as archive:
        return float(archive.system.components[f"actuator_{DRIVE}"].parameters["tau_c"])


@pytest.fixture(scope="module")
def stroke(hexapod_ssp) -> tuple[float, float]:
    """The drives' stroke [m] (the plausibility bounds of the positions in the data)."""
    with SSPArchive(hexapod_ssp) as archive:
        p = archive.system.components["actuator_1"].parameters
        return float(p["rho_min"]), float(p["rho_max"])


@pytest.fixture(scope="module")
def hexapod_data(hexapod_ssp, tmp_path_factory) -> dict:
    """The measured-data folder of the plan with the hidden friction, and the noise-free signals."""
    folder = tmp_path_factory.mktemp("hexapod_data") / "data"
    return synthesize(
        hexapod_ssp,
        folder,
        {f"actuator_{DRIVE}": {"tau_c": TAU_C}},
        tests=PLAN,
        direct=True,
        seed=SEED,
        log=lambda *_: None,
    )


def test_the_folder_holds_six_drives_and_the_six_coordinates(hexapod_data, stroke):
    data = load(hexapod_data["folder"], stroke, drives=6)
    meta = json.loads((hexapod_data["folder"] / "meta.json").read_text())
    assert meta["drives"] == data.drives == 6
    assert [t.name for t in data.tests] == ["z_1.2Hz", "x_2.5Hz", "z_5Hz"]
    for t in data.tests:
        assert t.rho_cmd.shape == t.rho.shape == t.tau_m.shape == (len(t.time), 6)
        assert sorted(t.pose) == sorted(("x", "y", "z", "psi", "theta", "phi"))
    x = data.test("x_2.5Hz")
    assert x.amplitude == 0.004 and 0.004 < np.ptp(x.pose["x"]) < 0.012  # metres (an x amplitude is no angle)
    # a z motion moves the six carriages alike; x moves them in the mirror pairs about the x axis (1-2, 3-6, 4-5)
    z = data.test("z_5Hz").rho_cmd
    assert np.abs(z - z[:, :1]).max() < 1e-9
    for a, b in ((0, 1), (2, 5), (3, 4)):
        assert np.abs(x.rho_cmd[:, a] - x.rho_cmd[:, b]).max() < 1e-9
    assert np.abs(x.rho_cmd[:, 0] - x.rho_cmd[:, 2]).max() > 1e-4


def test_a_folder_missing_a_drive_or_with_an_impossible_count_is_refused(hexapod_data, stroke, tmp_path):
    src = hexapod_data["folder"]
    meta = json.loads((src / "meta.json").read_text())
    folder = tmp_path / "broken"
    folder.mkdir()
    header, *rows = (src / "z_5Hz.csv").read_text().splitlines()
    keep = [k for k, c in enumerate(header.split(",")) if c != "tau_m_6"]
    lines = [",".join(line.split(",")[k] for k in keep) for line in [header, *rows]]
    (folder / "z_5Hz.csv").write_text("\n".join(lines) + "\n")
    meta["tests"] = [e for e in meta["tests"] if e["file"] == "z_5Hz.csv"]
    (folder / "meta.json").write_text(json.dumps(meta))
    with pytest.raises(MeasuredDataError, match=r"z_5Hz.csv: missing column\(s\) tau_m_6; expected .*tau_m_1..6"):
        load(folder, stroke)
    (folder / "meta.json").write_text(json.dumps({**meta, "drives": 7}))
    with pytest.raises(MeasuredDataError, match="drives = 7: expected a whole number from 1 to 6"):
        load(folder, stroke)
    # without 'drives' the header's highest drive counts: a missing command column is named, never fewer drives
    del meta["drives"]
    (folder / "meta.json").write_text(json.dumps(meta))
    keep = [k for k, c in enumerate(header.split(",")) if c != "rho_cmd_2"]
    lines = [",".join(line.split(",")[k] for k in keep) for line in [header, *rows]]
    (folder / "z_5Hz.csv").write_text("\n".join(lines) + "\n")
    with pytest.raises(MeasuredDataError, match=r"missing column\(s\) rho_cmd_2; expected time, rho_cmd_1..6"):
        load(folder, stroke)


def test_the_replay_of_the_six_drive_commands_gives_back_the_noise_free_torques(hexapod_ssp, hexapod_data, stroke):
    """The recorded joint commands, turned into pose commands with the controller's kinematic model (its engine's
    direct kinematics) and replayed with the truth: the torques before noise to 1e-9 N m, positions to 1e-12 m."""
    from fmus.actuator.sensor import measure
    from mast.core.run import drive_tick_steps
    from mast.data.measured import CommandReplay, controller_kinematics
    from mast.diagnosis.resimulation import sim_job

    data = load(hexapod_data["folder"], stroke)
    t = data.test("x_2.5Hz")
    kinematics = controller_kinematics(hexapod_ssp)
    assert kinematics.names == ("x", "y", "z", "psi", "theta", "phi")
    replay = CommandReplay(t.time, t.rho_cmd, kinematics)
    actuators = [f"actuator_{j}" for j in range(1, 7)]
    params = {a: {"rho_0": float(t.rho_cmd[0, j])} for j, a in enumerate(actuators)}
    params[f"actuator_{DRIVE}"]["tau_c"] = TAU_C
    with SSPArchive(hexapod_ssp) as archive:
        steps = drive_tick_steps(archive.system)
    run = sim_job((hexapod_ssp, t.name, replay, t.duration + 1e-12, params, True, steps, actuators))
    obs = measure(run["tau_m"], run["h"], T=data.torque_filter_s, axis=0)
    idx = np.round(t.time / run["h"]).astype(int)
    clean = hexapod_data["clean"][t.name]
    assert np.abs(obs[idx] - clean["tau_m"]).max() < 1e-9
    assert np.abs(run["rho"][idx] - clean["rho"]).max() < 1e-12


def test_the_diagnosis_names_the_friction_of_drive_5_within_5_percent(
    hexapod_ssp, hexapod_data, nominal_tau_c, tmp_path
):
    """Offered the actuator-side effects on all axes and on each drive alone (35 effects), the diagnosis names
    Coulomb friction on drive 5 alone, its increment within 5 % of the truth's, and writes the augmented model
    with drive 5's own parameter set, the report and its figures."""
    doc = diagnose(
        Options(hexapod_data["folder"], tmp_path / "out", hexapod_ssp, direct=True, library=figures.hexapod_library()),
        log=lambda *_: None,
    )
    named = {e["key"]: e for e in doc["named_effects"]}
    assert set(named) == {f"coulomb_axis{DRIVE}"}, named
    fitted = named[f"coulomb_axis{DRIVE}"]["parameters"][f"tau_c_axis{DRIVE}"]
    assert fitted == pytest.approx(TAU_C - nominal_tau_c, rel=0.05)
    assert doc["verdict"]["status"] == "explained"
    assert [g["role"] for g in doc["gap"].values()] == ["training", "held-out", "training"]
    written = (tmp_path / "out" / f"actuator_{DRIVE}_diagnosed.ssv").read_text()
    assert 'name="tau_c"' in written
    assert sorted(p.name for p in (tmp_path / "out").glob("actuator_*_diagnosed.ssv")) == [
        f"actuator_{DRIVE}_diagnosed.ssv"
    ]
    for fig in ("fig_time.png", "fig_residual_signals.png", "fig_residual_frequency.png"):
        assert (tmp_path / "out" / fig).stat().st_size > 10_000 and fig in (tmp_path / "out" / "report.md").read_text()
    problems = figures.check({"diagnose_hexapod": figures.diagnose_values(doc)})
    assert not problems, "\n".join(problems)


def test_data_of_another_drive_count_and_effects_of_drives_the_system_lacks_are_refused(hexapod_ssp, tmp_path):
    """Three-drive data against the six-drive system: refused before any simulation, naming both counts. The
    library's per-axis effects of drives 4-6 belong to the six-drive systems: a three-drive system leaves them
    out of the whole library and refuses them named alone."""
    folder = tmp_path / "three"
    folder.mkdir()
    t = np.arange(400) * 1e-3
    cmd = 0.15 + 0.005 * np.sin(2 * math.pi * 2 * t)
    table = {"time": t, **{f"rho_cmd_{j}": cmd for j in (1, 2, 3)}, **{f"rho_{j}": cmd for j in (1, 2, 3)}}
    table |= {f"tau_m_{j}": 0.05 * np.cos(2 * math.pi * 2 * t) for j in (1, 2, 3)}
    np.savetxt(
        folder / "z.csv", np.column_stack(list(table.values())), delimiter=",", header=",".join(table), comments=""
    )
    units = {"time": "s", "rho_cmd": "m", "rho": "m", "tau_m": "N.m"}
    (folder / "meta.json").write_text(json.dumps({"units": units, "tests": [{"file": "z.csv"}]}))
    assert load(folder).drives == 3  # the 3PRS's stroke, the default
    with pytest.raises(
        MeasuredDataError,
        match=r"z.csv: the test has 3 drives \(rho_cmd_1..3, counted from its columns\), the system has 6",
    ):
        diagnose(Options(folder, tmp_path / "out", hexapod_ssp, direct=True), log=lambda *_: None)
    every = [e.key for e in LIBRARY]
    assert for_drives(every, 3) == [k for k in every if (drive_of(k) or 0) <= 3]
    assert "coulomb_axis3" in for_drives(every, 3) and "coulomb_axis4" not in for_drives(every, 3)
    with pytest.raises(ValueError, match="effects coulomb_axis5: the system has 3 drives"):
        for_drives(["coulomb", "coulomb_axis5"], 3)


#: drives (0-based) whose torques a case's motion loads alike, by the designs' symmetries. Both hexapods have the
#: three-fold symmetry about z: under z and phi legs 1, 3, 5 alike and 2, 4, 6 alike. The 6-PUS's legs are also
#: mirror images of each other in pairs (z: all six alike; x, mirror symmetric about the x axis: 1-2, 3-6, 4-5);
#: the 6-UPS's are not (every motor on the same side of its leg, docs/designs/6ups.md)
THREE_FOLD = [(0, 2), (0, 4), (1, 3), (1, 5)]
SYMMETRIES = {
    "6PUS": {"z": [(0, k) for k in range(1, 6)], "phi": THREE_FOLD, "x": [(0, 1), (2, 5), (3, 4)]},
    "6UPS": {"z": THREE_FOLD, "phi": THREE_FOLD, "x": []},
}


def test_a_batch_of_hexapod_cases_gives_the_torques_its_symmetries_require(hexapod_ssp, tmp_path):
    """examples/hexapod_sweep.toml: x, phi and z sines on the hexapod's six drives, two friction values: every case
    runs; the drives' torques follow the design's symmetries (``SYMMETRIES``: an independent check of the six
    channels the batch records), and the friction raises every drive's RMS torque."""
    from mast.batch import BatchConfig, run_batch

    config = {**BatchConfig.load(ROOT / "examples" / "hexapod_sweep.toml").raw, "ssp": hexapod_ssp}
    result = run_batch(config, tmp_path / "batch", workers=2, progress=False)
    assert (result.ok, result.failed, result.crashed) == (6, 0, 0)
    # the headline figures: the tracking of the coordinates the cases move, against the varied friction
    plots = sorted(p.name for p in (tmp_path / "batch" / "plots").glob("tracking_*.png"))
    assert len(plots) == 3 and all(any(f"tracking_{a}_" in p for p in plots) for a in ("x", "phi", "z")), plots
    with (tmp_path / "batch" / "summary.csv").open() as f:
        rows = list(csv.DictReader(f))
    pairs = SYMMETRIES[SYSTEM]
    rms = {}
    for row in rows:
        tau = np.array([float(row[f"tau_m_{k}_rms_Nm"]) for k in range(1, 7)])
        unit = "m" if row["axis"] in ("x", "z") else "rad"
        assert float(row[f"tracking_{row['axis']}_rms_{unit}"]) > 0
        for a, b in pairs[row["axis"]]:
            assert tau[a] == pytest.approx(tau[b], rel=1e-6), (row["axis"], a + 1, b + 1)
        rms[row["axis"], float(row["actuator_*.tau_c"])] = tau
    for axis in pairs:
        assert (rms[axis, 0.0718] > rms[axis, 0.0193]).all()
    assert abs(rms["phi", 0.0193][0] - rms["phi", 0.0193][1]) > 1e-4  # phi: the two leg families differ
