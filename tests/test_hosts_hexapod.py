"""The hexapod's standalone system (ssp/MAST_6UPS_standalone.ssd) in third-party co-simulation hosts.

What is checked:
- the standalone SSD is the 6-UPS system (ssp/MAST_6UPS.ssd) with its own pose command in place of the system
  inputs, the command's home pose the mechanism's;
- the signals compared with our master are the system's (six pose components, six drives), the 3PRS's those of
  mast.hosts.cosim.COMPARED;
- libcosim, ecospy and the ecos command line run the native SSP (``mast build --native``) and compute what our
  master computes (every component at T_cur under FMI 2.0's calling sequence): every compared signal to rounding
  (mast.hosts.cosim.RELATIVE; the ecos command line to its printed digits), on the commanded motion;
- `mast hosts` (cross_check) compares every signal the system records.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import component_shape

from fmus.mechanism.designs import description
from mast.core.run import default_signals, simulate
from mast.core.ssp import SSPArchive, read_ssd, validate_ssd_schema
from mast.hosts.cosim import (
    ABSOLUTE,
    COMPARED,
    PRINTED,
    availability,
    comparable,
    compared_signals,
    cross_check,
    deviations,
    out_of_agreement,
    run_host,
)

ROOT = Path(__file__).resolve().parents[1]
SSP_SRC = ROOT / "ssp"
STOP = 0.3  # s of simulated time in the host comparisons
AMPLITUDE_Z = 0.01  # m: ssp/resources/trajectory_6ups.ssv, 1 Hz


def needs(host: str):
    reason = availability(host)
    return pytest.mark.skipif(reason is not None, reason=f"{host}: {reason}")


def test_hexapod_standalone_ssd_is_the_6ups_system_with_its_own_pose_command():
    hexapod, alone = read_ssd(SSP_SRC / "MAST_6UPS.ssd"), read_ssd(SSP_SRC / "MAST_6UPS_standalone.ssd")
    assert validate_ssd_schema(SSP_SRC / "MAST_6UPS_standalone.ssd") == []
    assert alone.system_inputs == [] and set(alone.components) == set(hexapod.components) | {"trajectory"}
    for name in hexapod.components:
        assert component_shape(alone, name) == component_shape(hexapod, name), f"{name} differs from MAST_6UPS.ssd"
    edges = {(c.start_element, c.start_connector, c.end_element, c.end_connector) for c in alone.connections}
    inputs = {(c.end_element, c.end_connector) for c in hexapod.connections if not c.start_element}
    assert len(inputs) == 6 and edges == (
        {
            (c.start_element, c.start_connector, c.end_element, c.end_connector)
            for c in hexapod.connections
            if c.start_element
        }
        | {("trajectory", connector, element, connector) for element, connector in inputs}
    )
    top = description("6UPS").describe(masses=False).topology
    traj = alone.components["trajectory"].parameters
    assert [traj[f"{c}_home"] for c in top.names] == pytest.approx(top.home, abs=1e-12)
    assert traj["amplitude_z"] == AMPLITUDE_Z and traj["frequency"] == 1.0


def test_the_compared_signals_are_the_system_s():
    assert compared_signals(SSP_SRC / "MAST_standalone.ssd") == COMPARED
    hexapod = compared_signals(SSP_SRC / "MAST_6UPS_standalone.ssd")
    drives = range(1, 7)
    assert list(hexapod) == [
        *(f"mechanism.{c}" for c in ("x", "y", "z", "psi", "theta", "phi")),
        *(f"actuator_{k}.rho" for k in drives),
        *(f"actuator_{k}.i_m" for k in drives),
        *(f"mechanism.F_{k}" for k in drives),
    ]
    assert set(hexapod.values()) == {"m", "rad", "A", "N"}  # ball-screw legs: linear drives


@pytest.fixture(scope="module")
def native_ssp(built_native) -> Path:
    return built_native / "ssp" / "native" / "MAST_6UPS_standalone.ssp"


@pytest.fixture(scope="module")
def reference(native_ssp):
    return simulate(native_ssp, None, STOP, record=list(compared_signals(native_ssp)))


@pytest.mark.parametrize("host", [pytest.param(h, marks=needs(h)) for h in ("libcosim", "ecospy", "ecos")])
def test_host_runs_the_native_hexapod_like_our_master(host, native_ssp, reference):
    units = compared_signals(native_ssp)
    result = run_host(host, native_ssp, STOP, list(units), python_free=host == "ecos")
    assert result.time[-1] == pytest.approx(STOP) and np.all(np.diff(result.time) == pytest.approx(1e-3))
    dev = deviations(result, reference, list(units))
    over = {s: f"{dev[s]:.3g}" for s in out_of_agreement(dev, reference, PRINTED if host == "ecos" else ABSOLUTE)}
    assert not over, f"{host} differs from our master on the hexapod: {over}"
    # the commanded motion: z from home up 10 mm sin(2 pi t), every leg moving
    z = result["mechanism.z"]
    assert np.ptp(z) == pytest.approx(np.ptp(reference["mechanism.z"]), rel=1e-2)
    assert 0.9 * AMPLITUDE_Z < np.ptp(z) < 1.01 * AMPLITUDE_Z
    assert all(np.ptp(result[f"actuator_{k}.rho"]) > 1e-3 for k in range(1, 7))


@needs("libcosim")
def test_mast_hosts_compares_the_hexapod_on_its_own_signals(native_ssp):
    """What `mast hosts` runs (cross_check): every signal the system records, each to rounding."""
    rows = cross_check(native_ssp, 0.1, hosts=["libcosim"], log=lambda *_: None)
    assert [r["host"] for r in rows] == ["mast (reference)", "libcosim"]
    with SSPArchive(native_ssp) as archive:
        recorded = comparable(default_signals(archive.system))
    assert set(compared_signals(native_ssp)) <= set(recorded)
    assert list(rows[1]["deviation"]) == recorded and rows[1]["failed"] == []
