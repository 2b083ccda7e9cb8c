"""What a careless host can do to an instance, on every route (native and Python FMUs): no crash.

A second fmi2FreeInstance and calls on a freed instance are refused without touching it (a C host in a
subprocess, so a crash fails the test, not the suite; docs/using-the-fmus.md, "Behaviour a host can rely on").
"""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest
from lxml import etree
from test_fmi_behaviour import ERROR

from mast.core.build import FMUS, build_fmu, build_fmu3, default_parameters
from mast.core.native.build import build_native_fmu
from mast.core.native.compiler import compiler, fmi_headers
from mast.hosts.cosim import HostUnavailable, host_environment

HOST = Path(__file__).with_name("careless_host.c")
#: the models of the tests
MODELS = ("MastActuator",)


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
