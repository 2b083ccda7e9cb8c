"""The analyses follow the mechanism's topology (issue 25): the scratch two-drive mechanism of
test_mechanism_topology (coordinates z, theta) gets its workspace grid over (z, theta), or over theta alone
with z held at home, CSV columns for its two drives, ``--pose`` with two numbers; a batch's motion axes and a
case's metrics are its coordinates and drives; ``compare``'s test set and columns follow its coordinates. A
six-coordinate topology needs the swept coordinates named. Bad input is refused naming what was expected."""

from __future__ import annotations

import csv
import math

import numpy as np
import pytest
from test_mechanism_topology import planar  # noqa: F401 - the fixture registering the scratch mechanism

from fmus.mechanism.topology import POSE, Coordinate, Drive, Topology
from mast.analyses import workspace as W
from mast.analyses.compare import RUN_COLUMNS, SUMMARY_COLUMNS, TestSet, columns, for_axes, parasitic_of
from mast.analyses.metrics import case_metrics, signals_for
from mast.batch import BatchConfig, BatchConfigError, expand
from mast.batch.cases import SystemInfo
from mast.cli import main as cli
from mast.core.master import Result

STROKE = (0.0, 0.3)
DEG = math.pi / 180.0


@pytest.fixture
def machine(planar):  # noqa: F811
    return W.Machine("2PRR", planar, (STROKE[0],) * 2, (STROKE[1],) * 2, (0.15, 0.15))


def closed_form_rho(planar, z, theta):
    """The two sliders of the scratch mechanism (its legs closed by hand: the point (+-r, 0, 0) of the platform
    rotated by theta about y, each leg of length L from its guide at x = +-H)."""
    H, r, L = planar["H"], planar["r"], planar["L"]
    with np.errstate(invalid="ignore"):  # NaN where a leg cannot reach
        w = np.sqrt(L * L - (H - r * np.cos(theta)) ** 2)
    return z - r * np.sin(theta) - w, z + r * np.sin(theta) - w


def test_the_workspace_grid_of_a_two_drive_mechanism(machine, planar, tmp_path):  # noqa: F811
    ws = W.compute(machine, 0.01, 2 * DEG)
    assert [c.name for c in ws.swept_coordinates] == ["z", "theta"] and ws.status.ndim == 2 and ws.held == {}
    s = W.summarize(ws)
    home = ws.home
    # the sliders move together in z: the whole stroke through home
    assert s["ranges_through_home"]["z_m"] == pytest.approx([home[0] - 0.15, home[0] + 0.15], abs=1e-9)
    # in theta the stroke stops it: the last grid angle whose sliders (closed form) are within the stroke
    grid = np.arange(1, 60) * 2 * DEG
    within = [t for t in grid if all(STROKE[0] <= v <= STROKE[1] for v in closed_form_rho(planar, home[0], t))]
    assert s["ranges_through_home"]["theta_deg"] == pytest.approx(
        [-math.degrees(within[-1]), math.degrees(within[-1])], abs=1e-9
    )
    assert s["limited_by"] == {W.STATUS[W.STROKE]: 1.0}
    # statics at home: a massless leg pinned at both ends pushes along itself, each slider carries m g / 2
    assert s["static_forces"]["home_N"] == pytest.approx([0.5 * planar["m_platform"] * planar["g"]] * 2, rel=1e-12)
    assert s["volume_m_deg"] == pytest.approx(s["poses_inside"] * 0.01 * 2.0, rel=1e-9) and "volume_m_rad" in s
    W.write(ws, tmp_path, plots=True)
    with open(tmp_path / "workspace.csv") as handle:
        rows = list(csv.DictReader(handle))
    assert list(rows[0]) == [
        "z_m",
        "theta_deg",
        "status",
        "inside",
        "rho_1_m",
        "rho_2_m",
        "det",
        "margin_parallel",
        "margin_inverse",
        "dexterity",
        "distance_to_singularity_m",
        "F_1_N",
        "F_2_N",
    ]
    for row in rows[::37]:  # every drive's joint is the closed form's at the row's pose
        if row["status"] != W.STATUS[W.UNASSEMBLABLE]:
            rho = closed_form_rho(planar, float(row["z_m"]), math.radians(float(row["theta_deg"])))
            assert [float(row["rho_1_m"]), float(row["rho_2_m"])] == pytest.approx(rho, rel=1e-5, abs=1e-6)
    assert (tmp_path / "workspace.png").stat().st_size > 0
    # one pose: as many values as coordinates
    assert W.classify(ws, (home[0] + 0.05, 10 * DEG))["inside"]
    assert not W.classify(ws, (home[0], 40 * DEG))["inside"]
    with pytest.raises(ValueError, match=r"expected 2 values, one per coordinate \(z, theta\)"):
        W.classify(ws, (home[0], 0.0, 0.0))


def test_one_coordinate_swept_the_other_held_at_home(machine):
    """theta swept with z at home: the same nodes as the (z, theta) grid's line through home, the same range."""
    full = W.summarize(W.compute(machine, 0.01, 2 * DEG))
    ws = W.compute(machine, 0.01, 2 * DEG, sweep=["theta"])
    assert ws.status.shape == (len(ws.axes[0]),) and ws.held == {"z": ws.home[0]}
    s = W.summarize(ws)
    assert s["grid"]["held_at_home"] == {"z_m": ws.home[0]} and "step_z_m" not in s["grid"]
    assert s["ranges_through_home"] == {"theta_deg": full["ranges_through_home"]["theta_deg"]}
    assert s["volume_deg"] == pytest.approx(s["poses_inside"] * 2.0)
    # a pose off the held height is not in this section
    with pytest.raises(ValueError, match=r"holds z at home \(z = .* m\)"):
        W.classify(ws, (ws.home[0] + 0.01, 0.0))
    assert W.classify(ws, (ws.home[0], 5 * DEG))["inside"]


def test_swept_coordinates_and_pose_text_are_checked(machine):
    topo = machine.topology
    with pytest.raises(
        ValueError,
        match=r"swept coordinate 'psi': 2PRR has no such coordinate; its coordinates "
        r"are z, theta",
    ):
        W.compute(machine, 0.01, 2 * DEG, sweep=["psi"])
    with pytest.raises(ValueError, match="expected 1 to 3 different ones of z, theta"):
        W.sweep_of(topo, ["z", "z"])
    assert W.parse_pose("0.4,5", topo) == pytest.approx((0.4, 5 * DEG))
    for bad in ("0.4", "0.4,5,-3", "0.4,five"):
        with pytest.raises(
            ValueError,
            match=r"expected Z,THETA_DEG, 2 finite numbers \(m, deg\), one per coordinate "
            r"of 2PRR \(z, theta\), e.g. 0.405,0 \(home\)",
        ):
            W.parse_pose(bad, topo)


def test_a_six_coordinate_mechanism_names_its_swept_coordinates():
    six = Topology(
        "6UPS",
        tuple(Coordinate(c) for c in POSE),
        tuple(Drive(f"rho_{k}", "linear", (0.0, 0.2)) for k in range(1, 7)),
        (0.0, 0.0, 0.5, 0.0, 0.0, 0.0),
    )
    with pytest.raises(
        ValueError,
        match=r"6UPS has 6 coordinates .*give the \(at most 3\) swept ones.*x,y,z: the "
        r"constant-orientation workspace; psi,theta,phi: the orientation workspace",
    ):
        W.sweep_of(six)
    assert W.sweep_of(six, ["z", "x", "y"]) == (0, 1, 2)  # in the topology's order
    assert W.sweep_of(six, ["psi", "theta", "phi"]) == (3, 4, 5)
    with pytest.raises(ValueError, match="expected 1 to 3 different ones"):
        W.sweep_of(six, ["x", "y", "z", "phi"])
    assert W.parse_pose("0,0,0.5,1,2,3", six)[3:] == pytest.approx((DEG, 2 * DEG, 3 * DEG))


def test_cli_pose_of_the_3prs_names_its_three_coordinates(capsys):
    assert cli(["workspace", "3PRS_T", "--step-z", "0.025", "--step-tilt", "4", "--pose", "0.405,5"]) == 2
    err = capsys.readouterr().err
    assert (
        "expected Z,PSI_DEG,THETA_DEG, 3 finite numbers (m, deg, deg), one per coordinate of 3PRS (z, psi, theta)"
        in err
    )


def _info(tmp_path, axes=("z", "theta")) -> SystemInfo:
    """The case expansion's view of a system of the scratch mechanism (its two actuators, its pose commands)."""
    comps = ["mechanism", "controller", "actuator_1", "actuator_2"]
    return SystemInfo(
        tmp_path / "planar.ssp",
        "0" * 64,
        comps,
        [f"{a}_cmd" for a in axes],
        {c: {} for c in comps},
        {c: ["tau_c"] for c in comps},
        [],
        tuple(axes),
    )


def test_batch_motion_axes_are_the_system_coordinates(tmp_path):
    info = _info(tmp_path)
    config = BatchConfig.from_dict(
        {
            "name": "t",
            "ssp": str(info.path),
            "run": {"stop_time": 0.1},
            "cases": {
                "motion": {"axis": "theta", "amplitude": 0.5, "frequency": 2.0},
                "grid": {"actuator_*.tau_c": [0.01, 0.02]},
            },
        }
    )
    cases = expand(config, {"default": info})
    assert [c.motion["axis"] for c in cases] == ["theta", "theta"]
    assert cases[1].parameters == {"actuator_1.tau_c": 0.02, "actuator_2.tau_c": 0.02}
    psi = BatchConfig.from_dict(
        {**config.raw, "cases": {"motion": {"axis": "psi", "amplitude": 0.5, "frequency": 2.0}}}
    )
    with pytest.raises(
        BatchConfigError,
        match=r"axis 'psi': axis must be one of the coordinates of planar.ssp's "
        r"mechanism: z, theta",
    ):
        expand(psi, {"default": info})
    with pytest.raises(BatchConfigError, match="axis must be one of the pose components x, y, z, psi, theta, phi"):
        BatchConfig.from_dict({**config.raw, "cases": {"motion": {"axis": "q1", "amplitude": 0.5}}})
    no_inputs = _info(tmp_path)
    no_inputs.system_inputs = ["z_cmd"]
    with pytest.raises(BatchConfigError, match=r"no pose command inputs \(z_cmd, theta_cmd\)"):
        expand(config, {"default": no_inputs})


def test_case_metrics_of_two_drives_and_two_coordinates():
    t = np.linspace(0.0, 1.0, 1001)
    signals = {
        "z_cmd": 0.4 + 0.0 * t,
        "mechanism.z": 0.4 - 0.001 * t,
        "theta_cmd": 0.01 * np.sin(2 * np.pi * t),
        "mechanism.theta": 0.01 * np.sin(2 * np.pi * t),
        "actuator_1.tau_m": 0.2 + 0.0 * t,
        "actuator_2.tau_m": -0.3 + 0.0 * t,
        "mechanism.psi": 0.0 * t,
    }
    assert signals_for(["tracking", "torque"], list(signals)) == [
        "z_cmd",
        "mechanism.z",
        "theta_cmd",
        "mechanism.theta",
        "actuator_1.tau_m",
        "actuator_2.tau_m",
    ]
    m = case_metrics(Result(t, signals), ["tracking", "torque"])
    assert m["tracking_z_peak_m"] == pytest.approx(0.001) and m["tracking_theta_peak_rad"] == 0.0
    assert m["tau_m_1_peak_Nm"] == pytest.approx(0.2) and m["tau_m_2_rms_Nm"] == pytest.approx(0.3)
    assert not any(k.startswith(("tau_m_3", "tracking_psi")) for k in m)


def test_compare_test_set_and_columns_follow_the_coordinates():
    ts = for_axes(TestSet(), ("z", "theta"))
    assert ts.axes == ("z", "theta") and ts.amplitudes["theta"] == pytest.approx(0.8 * DEG)
    assert for_axes(TestSet(), ("x", "phi")).amplitudes["x"] == 0.005  # assumed: the paper's of the same unit
    assert for_axes(TestSet(axes=("theta",)), ("z", "theta")).axes == ("theta",)
    assert parasitic_of(("z", "theta")) == ("x", "y", "psi", "phi")
    row = {
        "design": "a",
        "parasitic_x_m": 0.0,
        "parasitic_y_m": 0.0,
        "parasitic_psi_rad": 0.0,
        "parasitic_phi_rad": 0.0,
        "workspace_m_deg": 7.5,
    }
    cols = columns(SUMMARY_COLUMNS, [row])
    assert [c for c in cols if c.startswith(("parasitic_", "workspace_"))] == [
        "parasitic_x_m",
        "parasitic_y_m",
        "parasitic_psi_rad",
        "parasitic_phi_rad",
        "workspace_m_deg",
    ]
    # the 3PRS's rows: the columns as they were
    threeprs = {"parasitic_x_m": 0, "parasitic_y_m": 0, "parasitic_phi_rad": 0, "workspace_m_deg2": 1}
    assert columns(SUMMARY_COLUMNS, [threeprs]) == SUMMARY_COLUMNS and columns(RUN_COLUMNS, [threeprs]) == RUN_COLUMNS
