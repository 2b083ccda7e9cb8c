"""The FMUs in hosts and on platforms other than this one's master (issue 27).

- every FMU (Python FMI 2.0 and 3.0, native) declares a DefaultExperiment: start 0, a stop time, and the step
  size its block's cycle time from the FMU's own parameter set (the systems' step for a block without one);
- the native Linux binaries need no glibc symbol newer than 2.17 (zig's C compiler targets glibc 2.17), and
  compute what the system's C compiler's binaries compute; an aarch64-linux binary is made by the same toolchain;
- a C host (orchestration/hosts/mast_host.c) that runs the master's own exchange loop runs the native FMUs
  as our master does, on Linux and, cross-compiled for Windows, under Wine: 200 life cycles of each FMU with the
  expected statuses, then the standalone system to 1e-9 of our master's trajectories; the aarch64-linux binaries
  too, under qemu-user where it is installed;
- libcosim stepping the FMUs in several worker threads computes what it computes in one, native and Python FMUs.
"""

from __future__ import annotations

import zipfile
from pathlib import Path

import numpy as np
import pytest
from fmpy import read_model_description

from mast.core.build import FMUS, block_class, build_fmu, build_fmu3, build_ssp, default_experiment
from mast.core.native import models
from mast.core.native.build import build_native_all
from mast.core.native.compiler import GLIBC_FLOOR, compile_shared, has_zig
from mast.core.native.elf import glibc_versions, machine
from mast.hosts.c_host import build_host, launcher, master_run, run_c_host
from mast.hosts.cosim import COMPARED, availability, comparable, run_host

ROOT = Path(__file__).resolve().parents[1]
STANDALONE = ROOT / "ssp" / "MAST_standalone.ssd"
NATIVE = ("MastTrajectory", "MastController", "MastActuator", "MastMechanism")
TOLERANCE = 1e-9  # relative to each signal's largest value: the native FMUs' agreement (tests/test_native.py)
STOP = 1.0  # s of the standalone system in the C host runs
CYCLES = 200


@pytest.fixture(scope="module")
def built(tmp_path_factory) -> Path:
    """Every Python FMU (FMI 2.0 and 3.0) and the standalone system's native FMUs and SSP (chains n_dof <= 2
    in the actuator: a third of its compile; the system runs n_dof = 2), built as `mast build --native` builds
    them where zig is installed (an explicit $CC would take its place)."""
    out = tmp_path_factory.mktemp("portability")
    with pytest.MonkeyPatch.context() as patch:
        patch.delenv("CC", raising=False)
        for spec in FMUS:
            build_fmu(spec, out / "fmus")
            build_fmu3(spec, out / "fmus3")
        build_ssp(STANDALONE, out / "fmus", out / "ssp")
        patch.setattr(models, "N_MAX", 2)
        build_native_all(out, [STANDALONE], log=lambda *_: None, fmus=NATIVE)
    return out


@pytest.fixture(scope="module")
def reference(built, tmp_path_factory):
    """Our master's run of the native standalone system, with what the C host needs to follow it."""
    return master_run(built / "ssp" / "native" / "MAST_standalone.ssp", STOP, tmp_path_factory.mktemp("unpacked"))


def _relative_error(a: dict, b: dict) -> float:
    """The largest difference of the outputs ``a`` and ``b`` over each one's largest value, the drives' force rates
    left out as the hosts' comparisons leave them out (``mast.hosts.cosim.comparable``)."""
    worst = 0.0
    for name in comparable(list(a)):
        x, y = a[name], b[name]
        assert x.shape == y.shape, name
        worst = max(worst, float(np.abs(x - y).max() / max(np.abs(x).max(), 1e-6)))
    return worst


# -- DefaultExperiment ---------------------------------------------------------------------------------------
def test_every_fmu_declares_a_default_experiment_with_its_cycle_time(built):
    fmus = (
        sorted((built / "fmus").glob("*.fmu"))
        + sorted((built / "fmus3").glob("*.fmu"))
        + sorted((built / "fmus" / "native").glob("*.fmu"))
    )
    assert len(fmus) == 2 * len(FMUS) + len(NATIVE)
    for fmu in fmus:
        md = read_model_description(str(fmu))
        identifier = md.coSimulation.modelIdentifier
        block = block_class(identifier)
        experiment = md.defaultExperiment
        assert experiment is not None, fmu
        start, stop, step = default_experiment(identifier)
        assert float(experiment.startTime) == start == 0.0, fmu
        assert float(experiment.stopTime) == stop > 0, fmu
        if block.CYCLE_TIME is None:  # the step the first system using it gives it
            assert float(experiment.stepSize) == step, fmu
        else:  # the cycle time in the FMU's own parameter set (its start value)
            start_value = {v.name: v.start for v in md.modelVariables}[block.CYCLE_TIME]
            assert float(experiment.stepSize) == float(start_value) > 0, (fmu, experiment.stepSize, start_value)


# -- binaries ------------------------------------------------------------------------------------------------
def _binaries(built: Path, platform: str) -> list[tuple[str, bytes]]:
    out = []
    for fmu in sorted((built / "fmus" / "native").glob("*.fmu")):
        with zipfile.ZipFile(fmu) as z:
            out += [(f"{fmu.name}:{n}", z.read(n)) for n in z.namelist() if n.startswith(f"binaries/{platform}/")]
    return out


@pytest.mark.skipif(
    not has_zig(),
    reason="the Linux binaries target glibc 2.17 through zig's C compiler: "
    "pip install ziglang (in the project's test extra)",
)
def test_native_linux_binaries_need_no_glibc_above_2_17(built):
    binaries = _binaries(built, "linux64")
    assert len(binaries) == len(NATIVE)
    for name, data in binaries:
        assert machine(data) == "x86_64", name
        versions = glibc_versions(data)
        assert versions, name  # it links glibc (libm's functions: a check that reads nothing would pass)
        assert max(versions) <= GLIBC_FLOOR, (name, max(versions))


def test_glibc_versions_reads_a_binary_of_this_machines_compiler(tmp_path, monkeypatch):
    """The reader itself, on a library of the system's compiler calling hypot: this glibc's newest hypot
    (2.35 on glibc >= 2.35) or an older one, never none."""
    monkeypatch.setenv("CC", "cc")
    source = b"#include <math.h>\ndouble f(double x, double y) { return hypot(x, y) + exp(x); }\n"
    compile_shared({"f.c": source}, tmp_path / "f.so")
    data = (tmp_path / "f.so").read_bytes()
    import platform as host

    versions = glibc_versions(data)
    assert versions and max(versions) <= tuple(int(p) for p in host.libc_ver()[1].split(".")[:2])
    assert machine(data) == "x86_64"


@pytest.mark.skipif(not has_zig(), reason="pip install ziglang (in the project's test extra)")
def test_the_same_toolchain_makes_an_aarch64_linux_binary(built, tmp_path):
    with zipfile.ZipFile(built / "fmus" / "native" / "MastTrajectory.fmu") as z:
        sources = {n.removeprefix("sources/"): z.read(n) for n in z.namelist() if n.startswith("sources/")}
    compile_shared(sources, tmp_path / "MastTrajectory.so", "aarch64-linux")
    data = (tmp_path / "MastTrajectory.so").read_bytes()
    assert machine(data) == "aarch64"
    assert glibc_versions(data) and max(glibc_versions(data)) <= GLIBC_FLOOR


def test_zig_and_the_system_compiler_build_the_same_model(reference, tmp_path, monkeypatch):
    """The binaries as built (zig against glibc 2.17) and compiled again from their sources by the system's C
    compiler run the standalone system in the Linux C host to the same trajectories (measured: bit for bit)."""
    if not has_zig():
        pytest.skip("the binaries are the system compiler's already (no ziglang)")
    host = build_host("linux64", tmp_path)
    monkeypatch.setenv("MAST_NATIVE_CACHE", str(tmp_path / "cache"))
    monkeypatch.setenv("CC", "cc")
    recompiled = run_c_host(reference, host, "linux64", cycles=0, recompile=True)
    assert recompiled.status == 0
    assert _relative_error(reference.outputs, recompiled.outputs) <= TOLERANCE


# -- the C host ------------------------------------------------------------------------------------------------
def test_the_c_host_on_linux_runs_the_fmus_as_our_master(reference, tmp_path):
    host = build_host("linux64", tmp_path)
    run = run_c_host(reference, host, "linux64", cycles=CYCLES)
    assert run.cycles == {name: (CYCLES, 0) for name in reference.names}
    assert run.status == 0
    # the same binaries, the same calls in the same order from the same exchange loop: the same floats
    assert all(np.array_equal(run.outputs[n], x) for n, x in reference.outputs.items())


@pytest.mark.skipif(
    launcher("win64") is None,
    reason="Wine is not installed (Debian: apt-get install wine64; .ci/run "
    "installs it where it can): the Windows binaries are compiled, not run",
)
@pytest.mark.skipif(not has_zig(), reason="the Windows binaries and host are compiled by zig: pip install ziglang")
def test_the_windows_binaries_run_under_wine_as_on_linux(reference, tmp_path):
    """One Wine process: 200 life cycles of each FMU (a doStep before initialization refused with fmi2Error,
    the others fmi2OK), then the standalone system, against our master's run on Linux (measured: 6e-10, the
    different C libraries' last bits, amplified by the closed loop)."""
    host = build_host("win64", tmp_path)
    run = run_c_host(reference, host, "win64", cycles=CYCLES)
    assert run.cycles == {name: (CYCLES, 0) for name in reference.names}, run.log[-2000:]
    assert run.status == 0, run.log[-2000:]
    assert _relative_error(reference.outputs, run.outputs) <= TOLERANCE


@pytest.mark.skipif(
    launcher("aarch64-linux") is None,
    reason="qemu-user and Debian's aarch64 C library are not installed (apt-get install qemu-user "
    "libc6-arm64-cross; .ci/run installs them where it can): the aarch64-linux binaries are "
    "compiled, not run",
)
@pytest.mark.skipif(not has_zig(), reason="the aarch64 binaries and host are compiled by zig: pip install ziglang")
def test_the_aarch64_binaries_run_under_qemu_as_on_x86_64(reference, tmp_path):
    """The same on aarch64-linux (binaries compiled from the FMUs' sources, glibc 2.17), under qemu-user with
    Debian's aarch64 glibc (measured: the same floats as x86_64; the test allows 1e-9: another CPU's libm)."""
    host = build_host("aarch64-linux", tmp_path)
    run = run_c_host(reference, host, "aarch64-linux", cycles=CYCLES)
    assert run.cycles == {name: (CYCLES, 0) for name in reference.names}, run.log[-2000:]
    assert run.status == 0, run.log[-2000:]
    assert _relative_error(reference.outputs, run.outputs) <= TOLERANCE


# -- hosts that step in parallel -------------------------------------------------------------------------------
@pytest.mark.skipif(availability("libcosim") is not None, reason=f"libcosim: {availability('libcosim')}")
@pytest.mark.parametrize(
    "ssp, stop", [("native/MAST_standalone.ssp", 1.0), ("MAST_standalone.ssp", 0.1)], ids=["native", "python"]
)
def test_libcosim_stepping_in_several_worker_threads_gives_the_trajectories_of_one(built, ssp, stop):
    """libcosim steps the FMUs of a step in a pool of worker threads: 3 workers against 1 give the same floats
    (each instance keeps its own state); the Python FMUs, called from several threads at once, take the GIL in
    turn: no deadlock (a run that hangs fails at the timeout), no crash."""
    runs = {
        n: run_host("libcosim", built / "ssp" / ssp, stop, list(COMPARED), worker_threads=n, timeout=300)
        for n in (1, 3)
    }
    assert runs[1].stats["threads"] < runs[3].stats["threads"]  # the pool did grow (measured: 3 and 6 threads)
    assert len(runs[3].time) == round(stop / 1e-3)
    for signal in COMPARED:
        assert np.array_equal(runs[1][signal], runs[3][signal]), signal
