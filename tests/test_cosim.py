"""End to end: build the FMUs and the SSP, co-simulate through FMI, compare with the direct composition."""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from mast.build import build_all
from mast.cli import main as cli_main
from mast.cli import validate_all
from mast.master import SimulationError
from mast.motion import SineMotion
from mast.run import simulate


@pytest.fixture(scope="session")
def built(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("build")
    build_all(out, log=lambda *_: None)
    return out


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


def test_default_system_tracks_a_slow_z_motion(ssp):
    result = simulate(ssp, SineMotion("z", 0.005, 0.5), 2.0, direct=True)
    steady = result.time > 1.0
    amplitude = np.ptp(result["mechanism.z"][steady]) / np.ptp(result["z_cmd"][steady])
    assert 0.9 < amplitude < 1.1
    # a pure z motion leaves the platform level
    assert np.max(np.abs(result["mechanism.psi"])) < 1e-4
    # at rest the guides carry the platform: forces positive (upward) at the start
    assert np.all(result["mechanism.F_1"][:5] > 0)


def test_unknown_and_out_of_range_parameters_are_named(ssp):
    with pytest.raises(Exception, match=r"mechanism.*unknown parameter 'm_platfrom'"):
        simulate(ssp, SineMotion("z", 0.0, 0.0), 0.01, parameters={"mechanism": {"m_platfrom": 2.0}})
    with pytest.raises(Exception, match=r"mechanism.*m_platform.*-1"):
        simulate(ssp, SineMotion("z", 0.0, 0.0), 0.01, parameters={"mechanism": {"m_platform": -1.0}})


def test_unreachable_pose_is_reported_with_component_and_time_and_partial_results(ssp):
    with pytest.raises(SimulationError) as info:
        simulate(ssp, SineMotion("z", 0.5, 1.0), 0.5)
    assert "controller at t=" in str(info.value)
    assert "unreachable" in str(info.value).lower() or "stroke" in str(info.value).lower()
    assert len(info.value.result.time) > 10


def test_cli_run_writes_results_summary_and_plot(ssp, tmp_path):
    out = tmp_path / "run"
    code = cli_main(["run", str(ssp), "--motion", "theta", "--amplitude", "1", "--frequency", "2",
                     "--stop-time", "0.2", "--out", str(out), "--set", "actuator_1.tau_c=0.0718"])
    assert code == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["wall_time_s"] > 0 and summary["real_time_factor"] > 0
    header = (out / "results.csv").read_text().splitlines()[0].split(",")
    assert header[0] == "time" and "mechanism.theta" in header and "actuator_3.tau_m" in header
    assert (out / "motion.png").stat().st_size > 10_000
