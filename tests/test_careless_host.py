"""What a careless host can do to an instance, on every route (native and Python FMUs): no crash, no hang, no silent OK.

A second fmi2FreeInstance and calls on a freed instance are refused without touching it (a C host in a
subprocess, so a crash fails the test, not the suite); a doStep longer than the model takes in bounded time and
every non-finite or negative time argument are refused with fmi2Error (fmi3Error) and a message naming them, in
the same words on both routes (docs/using-the-fmus.md, "Behaviour a host can rely on").
"""

from __future__ import annotations

import ctypes
import importlib.util
import math
import os
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import pytest
from lxml import etree
from test_fmi_behaviour import ERROR, OK, Instance

from fmus.common.slave import MAX_STEP_SIZE, MAX_STEP_TICKS
from mast.core.build import FMUS, build_fmu, build_fmu3, default_parameters
from mast.core.native.build import build_native_fmu
from mast.core.native.compiler import compiler, fmi_headers
from mast.hosts.cosim import HostUnavailable, host_environment

HOST = Path(__file__).with_name("careless_host.c")
#: the models of the tests: one with a cycle time (the actuator's drive, T_cur) and one without (the trajectory)
MODELS = ("MastActuator", "MastTrajectory")


@pytest.fixture(scope="module")
def fmus(tmp_path_factory) -> dict[str, Path]:
    """Each model's Python FMU (``"<id>"``) and native FMU (``"native/<id>"``)."""
    out = tmp_path_factory.mktemp("careless")
    built = {}
    for spec in FMUS:
        if spec.model_identifier in MODELS:
            ident = spec.model_identifier
            built[ident] = build_fmu(spec, out)
            built[f"native/{ident}"] = build_native_fmu(ident, built[ident], out / "native", default_parameters(ident))
    return built


def _unpacked(fmu: Path, folder: Path) -> tuple[Path, str, str]:
    """(the Linux binary, the GUID, the resources URI) of ``fmu`` unpacked into ``folder``."""
    with zipfile.ZipFile(fmu) as archive:
        archive.extractall(folder)
    root = etree.parse(str(folder / "modelDescription.xml")).getroot()
    ident = root.find("CoSimulation").get("modelIdentifier")
    return folder / "binaries" / "linux64" / f"{ident}.so", root.get("guid"), (folder / "resources").as_uri()


@pytest.mark.parametrize("route", ["native/MastActuator", "MastActuator"])
def test_a_c_host_that_frees_twice_and_calls_a_freed_instance_survives(fmus, tmp_path, route):
    """A second fmi2FreeInstance and doStep/getReal/setReal/terminate on a freed instance: each refused with
    fmi2Error (a free: nothing), nothing logged through the freed instance's callbacks, and the host goes on."""
    host = tmp_path / "careless_host"
    subprocess.run(
        [compiler(), "-O2", f"-I{fmi_headers()}", "-o", str(host), str(HOST), "-ldl"], check=True, capture_output=True
    )
    binary, guid, resources = _unpacked(fmus[route], tmp_path / "fmu")
    env = None
    if not route.startswith("native/"):
        try:  # a C host starts its own interpreter inside the FMU: this environment's, as for ecos
            env = {**os.environ, **host_environment("ecos")}
        except HostUnavailable as err:
            pytest.skip(str(err))
    done = subprocess.run(
        [str(host), str(binary), guid, resources, "1e-4"], capture_output=True, text=True, timeout=120, env=env
    )
    # before the registry: killed by a signal at the second free (SIGABRT "free(): invalid pointer", or SIGSEGV)
    assert done.returncode == 0, (done.returncode, done.stdout, done.stderr[-2000:])
    assert done.stdout.split() == ["bad=0", "logged_after_free=0"], done.stdout


@pytest.mark.skipif(importlib.util.find_spec("pythonfmu3") is None, reason="pythonfmu3 is not installed")
def test_an_fmi3_python_fmu_freed_twice_refuses_every_later_call_and_the_host_survives(tmp_path):
    """The FMI 3.0 front: a second fmi3FreeInstance, then doStep and terminate on the freed instance (a Python
    host in a subprocess): fmi3Error for each, nothing logged, no crash."""
    spec = next(s for s in FMUS if s.model_identifier == "MastActuator")
    fmu = build_fmu3(spec, tmp_path)
    script = (
        f"import sys; sys.path.insert(0, {str(Path(__file__).parent)!r})\n"
        "from pathlib import Path\n"
        "from test_fmi3 import Instance3\n"
        f"inst = Instance3(Path({str(fmu)!r}), 'careless')\n"
        "inst.start()\n"
        "assert inst.step(0.0, 1e-4) == 0, inst.log\n"
        "dll, c = inst.slave.dll, inst.slave.component\n"
        "dll.fmi3FreeInstance(c)\n"
        "before = len(inst.log)\n"
        "dll.fmi3FreeInstance(c)\n"
        "print(inst.step(1e-4, 1e-4), dll.fmi3Terminate(c), len(inst.log) - before)\n"
    )
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, (done.returncode, done.stderr[-2000:])
    assert done.stdout.split() == [str(ERROR), str(ERROR), "0"], done.stdout


def _largest(inst: Instance, ident: str) -> tuple[float, str]:
    """The largest step ``inst`` takes and how the message words it (MAX_STEP_TICKS of T_cur, else MAX_STEP_SIZE)."""
    if ident != "MastActuator":
        return MAX_STEP_SIZE, f"{MAX_STEP_SIZE:.6g} s"
    tick = inst.slave.getReal([inst.vr["T_cur"]])[0]
    return MAX_STEP_TICKS * tick, f"{MAX_STEP_TICKS * tick:.6g} s ({MAX_STEP_TICKS:.6g} ticks of T_cur = {tick:.6g} s)"


@pytest.mark.parametrize("route", ["", "native/"])
@pytest.mark.parametrize("ident", MODELS)
def test_a_step_longer_than_the_model_takes_in_bounded_time_is_refused_at_once(fmus, ident, route):
    """doStep over 1e9 s (minutes in the Python actuator before): fmi2Error within a second, the message naming
    the largest step the FMU takes, the same words on both routes; the instance goes on."""
    inst = Instance(fmus[route + ident], "careless")
    assert inst.start() == OK
    largest, words = _largest(inst, ident)
    started = time.perf_counter()
    assert inst.step(0.0, 1e9) == ERROR
    assert time.perf_counter() - started < 1.0
    assert inst.log[-1] == (
        ERROR,
        f"doStep: communicationStepSize = 1e+09 s exceeds the largest step this FMU takes, {words}",
    )
    assert inst.step(0.0, largest * (1 + 1e-9)) == ERROR  # just above the bound
    h = 1e-4
    assert inst.step(0.0, h) == OK, inst.log[-3:]
    inst.close()


@pytest.mark.parametrize("route", ["", "native/"])
@pytest.mark.parametrize("ident", MODELS)
def test_a_non_finite_or_negative_time_is_refused_and_named(fmus, ident, route):
    """NaN, inf or a negative time as setupExperiment's start or stop time or doStep's communication point or
    step size: fmi2Error and a message naming the argument and its value (the same on both routes); an undefined
    stop time is not read; the instance goes on."""
    inst = Instance(fmus[route + ident], "careless")
    setup = inst.dll.fmi2SetupExperiment
    expected = "{}: {} = {} s: a time must be finite and >= 0"
    for start, defined, stop, name, value in (
        (math.nan, 0, 0.0, "startTime", "nan"),
        (-1.0, 0, 0.0, "startTime", "-1"),
        (0.0, 1, math.inf, "stopTime", "inf"),
        (0.0, 1, -0.5, "stopTime", "-0.5"),
    ):
        assert setup(inst.c, 0, 0.0, start, defined, stop) == ERROR
        assert inst.log[-1] == (ERROR, expected.format("setupExperiment", name, value))
    assert setup(inst.c, 0, 0.0, 0.0, 0, math.nan) == OK  # no stop time defined: its value means nothing
    inst.slave.enterInitializationMode()
    assert inst.dll.fmi2ExitInitializationMode(inst.c) == OK
    h = 1e-4
    for t, step, name, value in (
        (0.0, math.nan, "communicationStepSize", "nan"),
        (0.0, -h, "communicationStepSize", "-0.0001"),
        (0.0, math.inf, "communicationStepSize", "inf"),
        (math.nan, h, "currentCommunicationPoint", "nan"),
        (-math.inf, h, "currentCommunicationPoint", "-inf"),
    ):
        assert inst.step(t, step) == ERROR
        assert inst.log[-1] == (ERROR, expected.format("doStep", name, value))
    assert inst.step(0.0, h) == OK, inst.log[-3:]
    inst.close()


@pytest.mark.skipif(importlib.util.find_spec("pythonfmu3") is None, reason="pythonfmu3 is not installed")
def test_fmi3_refuses_a_non_finite_or_negative_time_and_a_step_too_long(tmp_path):
    """The FMI 3.0 variant: fmi3EnterInitializationMode's start and stop time, fmi3DoStep's times and a step
    longer than the bound, each fmi3Error with the FMI 2.0 FMUs' words; the instance goes on."""
    from test_fmi3 import Instance3

    spec = next(s for s in FMUS if s.model_identifier == "MastActuator")
    inst = Instance3(build_fmu3(spec, tmp_path), "careless")
    enter = inst.slave.dll.fmi3EnterInitializationMode
    c, d, b = inst.slave.component, ctypes.c_double, ctypes.c_bool
    assert enter(c, b(False), d(0.0), d(math.nan), b(False), d(0.0)) == ERROR
    assert inst.log[-1] == (ERROR, "enterInitializationMode: startTime = nan s: a time must be finite and >= 0")
    assert enter(c, b(False), d(0.0), d(0.0), b(True), d(-2.0)) == ERROR
    assert inst.log[-1] == (ERROR, "enterInitializationMode: stopTime = -2 s: a time must be finite and >= 0")
    assert enter(c, b(False), d(0.0), d(0.0), b(True), d(1.0)) == OK
    assert inst.slave.dll.fmi3ExitInitializationMode(c) == OK
    assert inst.step(0.0, math.nan) == ERROR
    assert inst.log[-1] == (ERROR, "doStep: communicationStepSize = nan s: a time must be finite and >= 0")
    assert inst.step(0.0, 1e9) == ERROR
    assert inst.log[-1][1].startswith("doStep: communicationStepSize = 1e+09 s exceeds the largest step")
    assert inst.step(0.0, 1e-4) == OK, inst.log[-3:]
    inst.close()
