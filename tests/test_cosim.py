"""End to end: build the FMUs and the SSP, co-simulate through FMI, compare with the direct composition."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from mast.cli import main as cli_main
from mast.cli import validate_all
from mast.core.master import SimulationError
from mast.core.motion import SineMotion
from mast.core.run import simulate


@pytest.fixture(scope="session")
def ssp(built) -> Path:
    return built / "ssp" / "MAST.ssp"


def test_built_fmus_and_ssp_validate_without_problems(built):
    assert validate_all(built) == []


def test_fmu_cosimulation_reproduces_direct_composition(ssp):
    motion = dict(axis="psi", amplitude=math.radians(2.0), frequency=3.0)
    fmi = simulate(ssp, SineMotion(**motion), 0.25)
    direct = simulate(ssp, SineMotion(**motion), 0.25, direct=True)
    assert set(fmi.signals) == set(direct.signals)
    np.testing.assert_array_equal(fmi.time, direct.time)
    for name in fmi.signals:
        np.testing.assert_allclose(fmi[name], direct[name], rtol=1e-12, atol=1e-14, err_msg=name)
    # the run did something: the platform tilted and the motors worked
    assert np.ptp(fmi["mechanism.psi"]) > math.radians(1.0)
    assert np.ptp(fmi["actuator_2.tau_m"]) > 0.01


def harmonic(t: np.ndarray, y: np.ndarray, f: float) -> complex:
    """Complex amplitude of the f-Hz component by least squares on [1, sin, cos] (whole periods)."""
    w = 2 * np.pi * f
    basis = np.column_stack([np.ones_like(t), np.sin(w * t), np.cos(w * t)])
    c = np.linalg.lstsq(basis, y, rcond=None)[0]
    return complex(c[1], c[2])


def test_default_system_tracks_a_slow_z_motion(ssp):
    result = simulate(ssp, SineMotion("z", 0.005, 0.5), 4.0, direct=True)
    steady = result.time >= 2.0  # one whole period after the settling period
    ratio = harmonic(result.time[steady], result["mechanism.z"][steady], 0.5) / harmonic(
        result.time[steady], result["z_cmd"][steady], 0.5
    )
    assert 0.95 < abs(ratio) < 1.02  # the paper measures 99.4 % at 0.4 Hz
    assert -15.0 < np.degrees(np.angle(ratio)) < 0.0  # a lag of a few degrees (paper: -6.3 deg at 0.4 Hz)
    # a pure z motion leaves the platform level: the T layout loads the guides unequally, so the
    # axes lag by slightly different amounts (~1e-4 rad); a kinematic sign error would tilt it ~1e-2 rad
    assert np.max(np.abs(result["mechanism.psi"])) < 1e-3
    assert np.max(np.abs(result["mechanism.theta"])) < 1e-3
    # at rest the guides carry the platform: forces positive (upward) at the start
    assert np.all(result["mechanism.F_1"][:5] > 0)


def test_unknown_and_out_of_range_parameters_are_named(ssp):
    with pytest.raises(Exception, match=r"mechanism.*unknown parameter 'm_platfrom'"):
        simulate(ssp, SineMotion("z", 0.0, 0.0), 0.01, parameters={"mechanism": {"m_platfrom": 2.0}})
    with pytest.raises(Exception, match=r"mechanism.*m_platform.*-1"):
        simulate(ssp, SineMotion("z", 0.0, 0.0), 0.01, parameters={"mechanism": {"m_platform": -1.0}})


@pytest.mark.parametrize("direct", [False, True])
@pytest.mark.parametrize("component", ["actuator_1", "actuator_3"])
def test_failures_name_component_time_and_cause_and_keep_partial_results(ssp, direct, component):
    # a commanded motion well inside the workspace; a guide gravity of 500 g pulls one carriage off its stroke
    with pytest.raises(SimulationError) as info:
        simulate(ssp, SineMotion("z", 0.01, 1.0), 0.5, direct=direct, parameters={component: {"g_guide": 5000.0}})
    message = str(info.value)
    assert message.startswith(component) and "doStep at t=" in message and "left the stroke" in message.lower()
    partial = info.value.result
    assert 10 < len(partial.time) < 501 and np.all(np.isfinite(partial["mechanism.z"]))


@pytest.mark.parametrize(
    "motion, named",
    [
        (
            SineMotion("z", 1e9, 1.0),
            r"z_cmd = 1e\+09 m is outside the workspace of 'mechanism': carriage 1 would be at "
            r"rho_1 = 1e\+09 m, beyond the stroke \[0, 0\.3\] m of actuator_1\. The largest "
            r"reachable z_cmd .* is 0\.555\d* m",
        ),
        (
            SineMotion("z", -0.5, 1.0),
            r"z_cmd = -0\.09\d* m is outside .* The smallest reachable z_cmd .* is 0\.255\d* m",
        ),
        (
            SineMotion("psi", math.radians(70.0), 1.0),
            r"psi_cmd = 1\.22173 rad \(70 deg\) is outside the workspace.*"
            r"largest reachable psi_cmd .* is 0\.41\d* rad",
        ),
    ],
)
def test_commands_outside_the_workspace_are_refused_before_the_first_step(ssp, motion, named):
    with pytest.raises(ValueError, match=named):
        simulate(ssp, motion, 0.5, direct=True)
    # a motion that reaches its extremes only after the stop time is not refused for them
    assert len(simulate(ssp, SineMotion("z", 0.5, 0.01), 0.2, direct=True).time) == 201


@pytest.mark.parametrize("motion", ["psi", "theta"])
def test_a_refused_pose_command_is_stated_in_the_unit_the_command_line_took(ssp, tmp_path, capsys, motion):
    """The command line takes degrees for the angles: its refusal stated the limit in radians only."""
    out = tmp_path / "run"
    argv = [
        "run",
        str(ssp),
        "--motion",
        motion,
        "--amplitude",
        "40",
        "--frequency",
        "50",
        "--stop-time",
        "0.01",
        "--direct",
    ]
    assert cli_main([*argv, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert re.fullmatch(
        rf"error: {motion}_cmd = 40 deg \(0\.6981 rad\) is outside the workspace of 'mechanism': .*\. The largest "
        rf"reachable {motion}_cmd on the way from the home pose \({motion}_cmd = 0 deg \(0 rad\)\) is \d+\.\d+ deg\n",
        err,
    ), err
    assert " rad\n" not in err and not out.exists()
    # the Python API, which takes radians, keeps them
    with pytest.raises(ValueError, match=rf"largest reachable {motion}_cmd .* is 0\.\d+ rad$"):
        simulate(ssp, SineMotion(motion, math.radians(40.0), 50.0), 0.01, direct=True)


def test_cli_run_writes_results_summary_and_plot(ssp, tmp_path):
    out = tmp_path / "run"
    code = cli_main(
        [
            "run",
            str(ssp),
            "--motion",
            "theta",
            "--amplitude",
            "1",
            "--frequency",
            "2",
            "--stop-time",
            "0.2",
            "--out",
            str(out),
            "--set",
            "actuator_1.tau_c=0.0718",
        ]
    )
    assert code == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["wall_time_s"] > 0 and summary["real_time_factor"] > 0
    header = (out / "results.csv").read_text().splitlines()[0].split(",")
    assert header[0] == "time" and "mechanism.theta" in header and "actuator_3.tau_m" in header
    assert (out / "motion.png").stat().st_size > 10_000


def test_cli_records_only_the_chosen_signals(ssp, tmp_path):
    out = tmp_path / "chosen"
    assert (
        cli_main(
            [
                "run",
                str(ssp),
                "--stop-time",
                "0.05",
                "--out",
                str(out),
                "--record",
                "mechanism.z",
                "--record",
                "actuator_2.i_m",
            ]
        )
        == 0
    )
    assert (out / "results.csv").read_text().splitlines()[0] == "time,mechanism.z,actuator_2.i_m"
    assert cli_main(["run", str(ssp), "--stop-time", "0.05", "--out", str(out), "--record", "mechanism.nope"]) == 2


@pytest.mark.parametrize("direct", [False, True])
@pytest.mark.parametrize(
    "component, parameter, value",
    [
        ("actuator_1", "n_dof", 2.5),  # an Integer parameter: 2.5 ran as 2 through FMI
        ("mechanism", "attached", 0.5),  # 0/1: 0.5 ran as 0 (no mechanism load) through FMI
        ("actuator_1", "n_dof", 2**32 + 2),  # wraps around to 2 in a C int
    ],
)
def test_integer_parameters_refuse_what_they_cannot_hold_on_every_route(ssp, direct, component, parameter, value):
    with pytest.raises(Exception) as info:
        simulate(ssp, SineMotion("z", 0.0, 0.0), 0.002, parameters={component: {parameter: value}}, direct=direct)
    message = str(info.value)
    assert component in message and f"'{parameter}'" in message and str(value) in message


@pytest.mark.parametrize("direct", [False, True])
@pytest.mark.parametrize("component, parameter", [("mechanism", "m_platform"), ("actuator_2", "tau_c")])
def test_overflowing_parameters_are_named_not_a_name_error(ssp, direct, component, parameter):
    """1e308 is a finite, admissible value whose products overflow: the generated code must not print 'inf'."""
    with pytest.raises(Exception) as info:
        simulate(ssp, SineMotion("z", 0.0, 0.0), 0.002, parameters={component: {parameter: 1e308}}, direct=direct)
    message = str(info.value)
    assert "NameError" not in message and f"{parameter} = 1e+308" in message and component in message


def test_a_set_in_grams_is_built_into_the_ssp_in_kilograms(built, tmp_path):
    """libcosim and ecos ignore .ssv units: the built SSP carries the value in the unit the FMU declares."""
    import shutil
    import zipfile

    from mast.core.build import build_ssp
    from mast.core.ssv import parse_ssv

    root = Path(__file__).resolve().parents[1] / "ssp"
    shutil.copytree(root / "resources", tmp_path / "resources")
    shutil.copy(root / "MAST.ssd", tmp_path / "MAST.ssd")
    ssv = tmp_path / "resources" / "mass_3prs.ssv"
    ssv.write_text(ssv.read_text().replace('<ssv:Real value="2.06" unit="kg"/>', '<ssv:Real value="2060" unit="g"/>'))
    with zipfile.ZipFile(build_ssp(tmp_path / "MAST.ssd", built / "fmus", tmp_path / "out")) as archive:
        flat = parse_ssv(archive.read("resources/parameters/mechanism.ssv"))["m_platform"]
    assert (flat.written, flat.unit, flat.value) == (2.06, "kg", 2.06)


@pytest.mark.parametrize(
    "identifier, parameter, fraction", [("MastActuator", "n_dof", 1.5), ("MastMechanism", "attached", 0.5)]
)
def test_a_host_setting_a_fraction_through_set_real_gets_the_parameter_named(
    built, tmp_path, identifier, parameter, fraction
):
    """A host (not this master) may set an Integer parameter with fmi2SetReal: a fraction is refused, never
    truncated (truncated, it would differ from the start value: n_dof 2 -> 1, attached 1 -> 0)."""
    from fmpy import extract, read_model_description
    from fmpy.fmi1 import FMICallException
    from fmpy.fmi2 import (
        FMU2Slave,
        calloc,
        fmi2CallbackAllocateMemoryTYPE,
        fmi2CallbackFreeMemoryTYPE,
        fmi2CallbackFunctions,
        fmi2CallbackLoggerTYPE,
        free,
    )

    fmu = built / "fmus" / f"{identifier}.fmu"
    md = read_model_description(str(fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    log = []
    callbacks = fmi2CallbackFunctions()
    callbacks.logger = fmi2CallbackLoggerTYPE(lambda _e, _n, _s, _c, message: log.append(message.decode()))
    callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
    callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
    slave = FMU2Slave(
        guid=md.guid,
        unzipDirectory=extract(str(fmu), unzipdir=str(tmp_path)),
        modelIdentifier=identifier,
        instanceName="x",
    )
    slave.instantiate(callbacks=callbacks, loggingOn=True)
    slave.setupExperiment(startTime=0.0)
    slave.enterInitializationMode()
    with pytest.raises(FMICallException):  # a Real for an Integer variable: refused by the FMI state machine
        slave.setReal([vr[parameter]], [fraction])
    assert any(f"'{parameter}'" in m and "not Real" in m for m in log), log
    # an illegal call is an fmi2Error that changes nothing (the C front, docs/interfaces.md): the value was
    # never applied, truncated or not, and the instance goes on with its start value
    start = int(next(v for v in md.modelVariables if v.name == parameter).start)
    assert slave.getInteger([vr[parameter]]) == [start]
    slave.exitInitializationMode()
    assert slave.getInteger([vr[parameter]]) == [start]
    slave.freeInstance()


def test_a_trajectory_component_outside_the_workspace_is_refused_before_the_first_step(built):
    """A system without inputs commands itself (ssp/MAST_standalone.ssd): its trajectory is checked the same way."""
    standalone = built / "ssp" / "MAST_standalone.ssp"
    with pytest.raises(
        ValueError,
        match=r"z_cmd = 0\.905\d* m is outside the workspace of 'mechanism': carriage 1 "
        r".* stroke \[0, 0\.3\] m of actuator_1\. The largest reachable z_cmd .* 0\.555",
    ):
        simulate(standalone, None, 0.5, parameters={"trajectory": {"amplitude_z": 0.5}}, direct=True)
