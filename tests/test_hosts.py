"""The built SSPs in third-party co-simulation hosts: libcosim (libcosimpy), ecos (ecospy) and ecos's C++ CLI.

Each host runs in a child process (mast.hosts.cosim). What is checked:
- the standalone SSD is the default system with its own pose command, and its home pose is the mechanism's;
- the build flattens the parameter bindings to one set per component, values, units and sources kept;
- our master runs the standalone SSP exactly like the default SSP driven by the Python stimulus;
- each host runs an SSP whose bindings differ from the FMUs' built-in defaults (a file that overrides
  another, inline values) and computes what our master computes: every recorded signal to rounding
  (mast.hosts.cosim.RELATIVE), the calling sequence of FMI 2.0 and the same step sizes in every host;
- the hosts step every component at 100 us, and the mechanism makes its full update every 1 ms (T_mech);
- the ecos command line (a C++ program, libpython preloaded) reproduces ecospy and our master to its printed
  precision (6 decimals);
- a model failure and a bad parameter reach the host as the model's message, and the host is not killed.
"""

from __future__ import annotations

import shutil
import zipfile
from pathlib import Path

import numpy as np
import pytest
from conftest import component_shape

from fmus.mechanism.kinematics import Geometry, home_pose
from mast.core.build import FLAT_SET_NAME, build_all, build_ssp
from mast.core.motion import SineMotion
from mast.core.run import default_signals, simulate
from mast.core.ssd import NS
from mast.core.ssp import SSPArchive, read_ssd, validate_ssd_schema
from mast.core.ssv import parse_ssv
from mast.hosts.cosim import PRINTED, HostError, availability, comparable, deviations, out_of_agreement, run_host

ROOT = Path(__file__).resolve().parents[1]
SSP_SRC = ROOT / "ssp"
STOP = 0.5  # s of simulated time in the host comparisons


def needs(host: str):
    reason = availability(host)
    return pytest.mark.skipif(reason is not None, reason=f"{host}: {reason}")


@pytest.fixture(scope="module")
def built(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("build")
    build_all(out, log=lambda *_: None)
    return out


def inline_binding(component: str, values: dict[str, tuple[float, str]]):
    """An edit of the SSD text: one more binding, inline values, after the component's last binding."""

    def edit(text: str) -> str:
        start = text.index(f'<ssd:Component name="{component}"')
        end = text.index("</ssd:ParameterBindings>", start)
        params = "".join(
            f'<ssv:Parameter name="{n}"><ssv:Real value="{v!r}" unit="{u}"/></ssv:Parameter>'
            for n, (v, u) in values.items()
        )
        binding = (
            '<ssd:ParameterBinding><ssd:ParameterValues><ssv:ParameterSet version="1.0" name="test">'
            f"<ssv:Parameters>{params}</ssv:Parameters></ssv:ParameterSet></ssd:ParameterValues>"
            "</ssd:ParameterBinding>\n        "
        )
        return text[:end] + binding + text[end:]

    return edit


def file_binding(component: str, source: str):
    def edit(text: str) -> str:
        start = text.index(f'<ssd:Component name="{component}"')
        end = text.index("</ssd:ParameterBindings>", start)
        return text[:end] + f'<ssd:ParameterBinding source="{source}"/>\n        ' + text[end:]

    return edit


def variant(built: Path, folder: Path, name: str, *edits) -> Path:
    """MAST_standalone.ssd with ``edits``, built into an SSP with the FMUs of ``built``."""
    folder.mkdir(parents=True, exist_ok=True)
    if not (folder / "resources").exists():
        (folder / "resources").symlink_to(SSP_SRC / "resources")
    text = (SSP_SRC / "MAST_standalone.ssd").read_text()
    for edit in edits:
        text = edit(text)
    ssd = folder / f"{name}.ssd"
    ssd.write_text(text)
    assert validate_ssd_schema(ssd) == []
    return build_ssp(ssd, built / "fmus", folder / "ssp")


# Parameter values the FMUs were not built with: the hosts must apply the SSP's bindings
MOTION = {"amplitude_z": (0.004, "m"), "amplitude_theta": (0.02, "rad"), "frequency": (2.0, "Hz")}


@pytest.fixture(scope="module")
def bound(built, tmp_path_factory) -> Path:
    """actuator_1 with the paper's identified set bound over the manufacturer's; a 2 Hz z + theta motion inline."""
    return variant(
        built,
        tmp_path_factory.mktemp("variant"),
        "bound",
        file_binding("actuator_1", "resources/actuator_identified.ssv"),
        inline_binding("trajectory", MOTION),
    )


#: every signal the standalone system records by default (every output of every component), and three parameters
RECORDED = comparable(default_signals(read_ssd(SSP_SRC / "MAST_standalone.ssd")))
SIGNALS = RECORDED + ["actuator_1.tau_c", "actuator_2.tau_c", "trajectory.frequency"]


@pytest.fixture(scope="module")
def reference(bound):
    return simulate(bound, None, STOP, record=SIGNALS)


# -- the standalone system and the built archives ------------------------------------------------


def test_standalone_ssd_is_the_default_system_with_its_own_pose_command():
    mast, alone = read_ssd(SSP_SRC / "MAST.ssd"), read_ssd(SSP_SRC / "MAST_standalone.ssd")
    assert validate_ssd_schema(SSP_SRC / "MAST_standalone.ssd") == []
    assert alone.system_inputs == [] and set(alone.components) == set(mast.components) | {"trajectory"}
    for name in mast.components:  # same FMUs, connectors, step sizes and merged bindings
        assert component_shape(alone, name) == component_shape(mast, name), (
            f"{name} differs between MAST.ssd and MAST_standalone.ssd"
        )
    pose = {(c.end_element, c.end_connector) for c in mast.connections if not c.start_element}
    assert {(c.start_element, c.start_connector, c.end_element, c.end_connector) for c in alone.connections} == (
        {
            (c.start_element, c.start_connector, c.end_element, c.end_connector)
            for c in mast.connections
            if c.start_element
        }
        | {("trajectory", connector, element, connector) for element, connector in pose}
    )
    assert (alone.base_step, alone.start_time) == (mast.base_step, mast.start_time)
    assert alone.components["trajectory"].step_size == alone.components["controller"].step_size


def test_trajectory_starts_at_the_mechanisms_home_pose():
    system = read_ssd(SSP_SRC / "MAST_standalone.ssd")
    traj = system.components["trajectory"].parameters
    rho0 = {system.components[f"actuator_{k}"].parameters["rho_0"] for k in (1, 2, 3)}
    assert len(rho0) == 1
    z, psi, theta = home_pose(Geometry.from_params(system.components["mechanism"].parameters), rho0.pop())
    assert traj["z_home"] == pytest.approx(z, abs=1e-12)
    assert (traj["psi_home"], traj["theta_home"]) == (pytest.approx(psi, abs=1e-12), pytest.approx(theta, abs=1e-12))
    assert 0.40514701644 < traj["z_home"] < 0.40514701645  # rho_0 = 0.15 m in the default geometry


def test_built_ssps_bind_one_parameter_set_per_component_with_values_units_and_sources(built, tmp_path):
    from fmpy import read_model_description
    from fmpy.ssp.ssd import validate_tree
    from lxml import etree

    for source in sorted(SSP_SRC.glob("*.ssd")):
        original = read_ssd(source)
        with SSPArchive(built / "ssp" / f"{source.stem}.ssp") as archive:
            assert validate_ssd_schema(archive.ssd) == []
            doc = etree.parse(str(archive.ssd)).getroot()
            for comp in doc.iterfind("ssd:System/ssd:Elements/ssd:Component", NS):
                name = comp.get("name")
                bindings = comp.findall("ssd:ParameterBindings/ssd:ParameterBinding", NS)
                assert [b.get("source") for b in bindings] == [f"resources/parameters/{name}.ssv"]
                ssv = archive.ssd.parent / bindings[0].get("source")
                validate_tree(etree.parse(str(ssv)).getroot(), "SystemStructureParameterValues.xsd")
                assert etree.parse(str(ssv)).getroot().get("name") == FLAT_SET_NAME
                flat = parse_ssv(ssv)
                fmu = archive.ssd.parent / comp.get("source")
                own = {v.name for v in read_model_description(str(fmu)).modelVariables if v.causality == "parameter"}
                # the merged bindings, restricted to the FMU's own parameters (SSP: other names are ignored)
                assert {n: p.value for n, p in flat.items()} == {
                    n: v for n, v in original.components[name].parameters.items() if n in own
                }
                # unit and source travel with each value: the last binding that set it
                for binding in reversed(original_bindings(source, name)):
                    for n, p in parse_ssv(source.parent / binding).items():
                        if n in flat and flat[n].value == p.value:
                            assert (flat[n].unit, flat[n].source) == (p.unit, p.source), f"{name}.{n}"
    # an inline binding after a file: the inline values win, the rest of the file stays
    ssp = variant(built, tmp_path, "inline", inline_binding("mechanism", {"m_platform": (3.5, "kg")}))
    with SSPArchive(ssp) as archive:
        flat = parse_ssv(archive.ssd.parent / "resources/parameters/mechanism.ssv")
    assert flat["m_platform"].value == 3.5 and flat["m_platform"].unit == "kg"
    assert flat["I_px"].value == read_ssd(SSP_SRC / "MAST.ssd").components["mechanism"].parameters["I_px"]


def original_bindings(ssd: Path, component: str) -> list[str]:
    from lxml import etree

    comp = etree.parse(str(ssd)).getroot().find(f"ssd:System/ssd:Elements/ssd:Component[@name='{component}']", NS)
    return [b.get("source") for b in comp.iterfind("ssd:ParameterBindings/ssd:ParameterBinding", NS) if b.get("source")]


class HomeMotion(SineMotion):
    """SineMotion around a given home pose (the trajectory FMU's parameters) instead of the one read."""

    def __init__(self, home, *args) -> None:
        super().__init__(*args)
        self._given = list(home)

    def start(self, t0, read) -> None:
        super().start(t0, read)
        self.home = list(self._given)


def test_our_master_runs_the_standalone_ssp_like_the_default_one_with_the_python_stimulus(built):
    alone = simulate(built / "ssp" / "MAST_standalone.ssp", None, 0.3)
    traj = read_ssd(SSP_SRC / "MAST_standalone.ssd").components["trajectory"].parameters
    assert traj["amplitude_z"] > 0 and traj["amplitude_psi"] == traj["amplitude_theta"] == 0
    stimulus = HomeMotion(
        [traj["z_home"], traj["psi_home"], traj["theta_home"]], "z", traj["amplitude_z"], traj["frequency"]
    )
    driven = simulate(built / "ssp" / "MAST.ssp", stimulus, 0.3)
    np.testing.assert_allclose(alone["trajectory.z_cmd"], driven["z_cmd"], rtol=0, atol=1e-15)
    for name in driven.signals:  # equal but for the rounding of t + h (FMU) against t0 + (n + 1) h (master)
        if "." in name:
            np.testing.assert_allclose(
                alone[name], driven[name], rtol=0, atol=1e-8 * np.ptp(driven[name]) + 1e-15, err_msg=name
            )
    assert np.ptp(alone["mechanism.z"]) > 0.009  # it moved: up to the +10 mm crest of the 1 Hz sine


def test_standalone_ssp_needs_no_stimulus_and_the_default_one_does(built):
    with pytest.raises(ValueError, match="z_cmd.*give a stimulus"):
        simulate(built / "ssp" / "MAST.ssp", None, 0.01)


# -- third-party hosts -----------------------------------------------------------------------------
@pytest.fixture(scope="module")
def host_runs() -> dict:
    """Host results shared by the tests of this module (a run takes seconds)."""
    return {}


def run_cached(host_runs, host, ssp, signals, **kwargs):
    key = (host, str(ssp), tuple(signals), tuple(sorted(kwargs.items())))
    if key not in host_runs:
        host_runs[key] = run_host(host, ssp, STOP, signals, **kwargs)
    return host_runs[key]


@pytest.mark.parametrize(
    "host", [pytest.param("libcosim", marks=needs("libcosim")), pytest.param("ecospy", marks=needs("ecospy"))]
)
def test_host_applies_the_bindings_and_matches_our_master(host, bound, reference, host_runs):
    result = run_cached(host_runs, host, bound, SIGNALS)
    assert "exit_signal" not in result.stats  # a Python host exits cleanly (fmus/common/slave.py)
    # the SSP's bindings, not the FMUs' built-in defaults (0.0193 N.m, 1 Hz)
    assert result["actuator_1.tau_c"][-1] == pytest.approx(0.0718)
    assert result["actuator_2.tau_c"][-1] == pytest.approx(0.019278, rel=1e-4)
    assert result["trajectory.frequency"][-1] == 2.0
    assert result.time[-1] == pytest.approx(STOP) and np.all(np.diff(result.time) == pytest.approx(1e-3))
    dev = deviations(result, reference, RECORDED)
    over = {s: f"{dev[s]:.3g}" for s in out_of_agreement(dev, reference)}
    assert not over, f"{host} differs from our master: {over}"
    # and the run is the bound one: 2 Hz, 4 mm on z and 0.02 rad on theta around the home pose
    assert np.ptp(result["mechanism.theta"]) == pytest.approx(np.ptp(reference["mechanism.theta"]), rel=1e-3)
    assert 0.03 < np.ptp(result["mechanism.theta"]) < 0.045


@pytest.mark.parametrize(
    "host", [pytest.param("libcosim", marks=needs("libcosim")), pytest.param("ecospy", marks=needs("ecospy"))]
)
def test_host_steps_each_component_at_its_step_size_hint(host, bound):
    """Every component at T_cur = 100 us (docs/interfaces.md, Timing): the actuators, the pose command and the
    mechanism's forces (its inertial reaction to the accelerations) move at every base step, the mechanism's pose
    every 1 ms (its full update's period T_mech, attached.ssv)."""
    signals = ["mechanism.F_1", "mechanism.z", "actuator_1.rho", "trajectory.z_cmd"]
    result = run_host(host, bound, 0.02, signals, sample_step=1e-4)
    assert len(result.time) >= 200 and np.all(np.diff(result.time) == pytest.approx(1e-4))
    moving = result.time[1:] > 0.0025
    for name in ("actuator_1.rho", "trajectory.z_cmd", "mechanism.F_1"):
        assert np.count_nonzero(np.diff(result[name])[moving]) == np.count_nonzero(moving), name
    changes = np.count_nonzero(np.diff(result["mechanism.z"])[moving])
    assert changes == pytest.approx(np.count_nonzero(moving) / 10, abs=1)


@needs("ecos")
@needs("ecospy")
def test_ecos_command_line_runs_the_ssp_like_ecospy(bound, reference, host_runs):
    cli = run_host("ecos", bound, STOP, SIGNALS)
    python = run_cached(host_runs, "ecospy", bound, SIGNALS)
    np.testing.assert_allclose(cli.time, python.time, atol=1e-9)
    for s in SIGNALS:  # the CLI prints 6 decimals
        np.testing.assert_allclose(cli[s], python[s], rtol=0, atol=PRINTED, err_msg=s)
    dev = deviations(cli, reference, RECORDED)
    assert out_of_agreement(dev, reference, PRINTED) == [], dev


# -- failures inside a host ------------------------------------------------------------------------
@pytest.fixture(scope="module")
def out_of_stroke(built, tmp_path_factory) -> Path:
    return variant(
        built, tmp_path_factory.mktemp("stroke"), "stroke", inline_binding("trajectory", {"amplitude_z": (0.5, "m")})
    )


@pytest.fixture(scope="module")
def bad_parameter(built, tmp_path_factory) -> Path:
    return variant(
        built, tmp_path_factory.mktemp("param"), "param", inline_binding("mechanism", {"m_platform": (-1.0, "kg")})
    )


@needs("libcosim")
def test_libcosim_reports_a_model_failure_with_its_cause(out_of_stroke):
    with pytest.raises(HostError) as info:
        run_host("libcosim", out_of_stroke, STOP, ["mechanism.z"])
    message = str(info.value)
    assert "exit status 2" in message  # our child reported the failed step: the host did not crash
    assert "left the stroke" in message and "actuator_" in message and "doStep at t=" in message


@needs("libcosim")
def test_libcosim_reports_a_bad_parameter_by_name(bad_parameter):
    with pytest.raises(HostError) as info:
        run_host("libcosim", bad_parameter, STOP, ["mechanism.z"])
    message = str(info.value)
    assert "exit status 2" in message
    assert "m_platform" in message and "-1" in message


@needs("ecos")
@pytest.mark.parametrize("case, cause", [("out_of_stroke", "left the stroke"), ("bad_parameter", "m_platform")])
def test_ecos_command_line_logs_the_cause_and_keeps_running(case, cause, request):
    """ecos ignores the status of doStep and exitInitializationMode: the run goes on, the log names the cause."""
    result = run_host("ecos", request.getfixturevalue(case), 0.4, ["mechanism.z"], fmu_log=True)
    assert cause in result.stats["log"]
    assert result.time[-1] == pytest.approx(0.4) and np.all(np.isfinite(result["mechanism.z"]))


def test_unknown_host_is_refused_with_the_list_of_hosts():
    assert availability("nohost") == "unknown host 'nohost'; hosts: libcosim, ecospy, ecos"


# -- running the hosts by hand ------------------------------------------------------------------------
def test_the_ecos_command_writes_only_the_signals_asked_for(tmp_path):
    """Without a CSV configuration ecos writes every variable at every base step (docs/using-the-fmus.md)."""
    from mast.hosts.cosim import ecos_command

    command = ecos_command(Path("x.ssp"), 0.2, ["mechanism.z", "actuator_1.rho"], 1e-3, tmp_path, base_step=1e-4)
    assert command[command.index("--csvConfig") + 1] == str(tmp_path / "csv.xml")
    assert command[command.index("--parameterSet") + 1] == FLAT_SET_NAME
    assert float(command[command.index("--stopTime") + 1]) == pytest.approx(0.20005)
    config = (tmp_path / "csv.xml").read_text()
    assert 'decimationFactor="10"' in config and config.count("<ecos:variable ") == 2
    assert '<ecos:component name="mechanism"><ecos:variable name="z"/></ecos:component>' in config


@needs("ecospy")
def test_ecospy_imports_without_ld_library_path_and_the_shown_environment_works(tmp_path):
    import os
    import subprocess
    import sys

    env = {k: v for k, v in os.environ.items() if k != "LD_LIBRARY_PATH"}
    plain = subprocess.run([sys.executable, "-c", "import ecospy"], env=env, capture_output=True, text=True)
    assert plain.returncode != 0 and "libtbb.so.12" in plain.stderr  # what a user meets
    helped = subprocess.run(
        [sys.executable, "-c", "from mast.hosts.cosim import import_ecospy; import_ecospy()"],
        env=env,
        capture_output=True,
        text=True,
    )
    assert helped.returncode == 0, helped.stderr[-2000:]
    from mast.hosts.cosim import show

    shown = show("ecospy", "unused.ssp", 1.0, [], tmp_path)  # what `mast hosts --show ecospy` prints
    assert "export LD_LIBRARY_PATH=" in shown
    exports = "\n".join(line for line in shown.splitlines() if line.startswith("export"))
    shell = subprocess.run(
        ["bash", "-c", f'{exports}\n"{sys.executable}" -c "import ecospy"'], env=env, capture_output=True, text=True
    )
    assert shell.returncode == 0, shell.stderr[-2000:]


@needs("ecospy")
def test_a_host_run_leaves_no_temporary_files(built, tmp_path, monkeypatch):
    """ecos extracts the SSP into the temporary directory and leaves it there: run_host gives it a folder it removes."""
    import tempfile

    fresh = tmp_path / "tmp"
    fresh.mkdir()
    monkeypatch.setenv("TMPDIR", str(fresh))
    monkeypatch.setattr(tempfile, "tempdir", str(fresh))
    result = run_host("ecospy", built / "ssp" / "MAST_standalone.ssp", 0.01, ["mechanism.z"])
    assert len(result.time) == 11
    assert not any(fresh.iterdir()), list(fresh.iterdir())


@needs("ecos")
@pytest.mark.skipif(shutil.which("valgrind") is None, reason="needs valgrind")
def test_a_cpp_host_exits_without_touching_freed_memory(built):
    """pythonfmu's library resets its interpreter guard from its destructor function after the C++ exit
    handlers destroyed it: a write into freed memory that aborted 6 of 50 runs of the ecos command line with
    the Python FMUs (SIGABRT after the run; the native FMUs 0 of 50). The FMUs' C front resets the guard in
    an exit handler that runs first (fmus/common/pythonfmu_shim.c): under valgrind the ecos command line
    running a Python FMU exits without an error (before: 3 errors, invalid reads in finalizePythonInterpreter)."""
    fmu = built / "fmus" / "MastTrajectory.fmu"
    with zipfile.ZipFile(fmu) as z:
        if not any(n.endswith(".pythonfmu.so") for n in z.namelist()):
            pytest.skip("built without a C compiler: no C front")
    result = run_host(
        "ecos", fmu, 0.01, ["instance.z_cmd"], base_step=1e-3, wrapper=("valgrind", "--error-exitcode=99")
    )
    assert "exit_signal" not in result.stats
    assert "ERROR SUMMARY: 0 errors" in result.stats["log"], result.stats["log"][-3000:]
