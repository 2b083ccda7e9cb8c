"""Shared fixtures: parameter values as the default system (ssp/MAST.ssd) binds them."""

from __future__ import annotations

import os
import shutil
from collections.abc import Callable
from pathlib import Path

import pytest
from filelock import FileLock
from xdist.scheduler import LoadFileScheduling

from fmus.actuator.model import ActuatorBlock
from fmus.controller.model import ControllerBlock
from fmus.mechanism.model import MechanismBlock
from mast.core.ssp import read_ssd
from mast.core.ssv import read_values

ROOT = Path(__file__).resolve().parents[1]
SSD = ROOT / "ssp" / "MAST.ssd"
RESOURCES = ROOT / "ssp" / "resources"


def load_params(component: str) -> dict:
    """Merged parameter bindings of a component of the default system, those of its model (the actuator: the
    voltage-driven ActuatorBlock).

    ``component`` is "actuator" (actuator_1), "mechanism", "controller", or
    "actuator_identified" (actuator_1 with the paper's identified set bound last).
    """
    system = read_ssd(SSD)
    if component == "actuator_identified":
        values = {**system.components["actuator_1"].parameters, **read_values(RESOURCES / "actuator_identified.ssv")}
    else:
        values = dict(system.components["actuator_1" if component == "actuator" else component].parameters)
    # a set bound to several components gives each the names it has (SSP; mast.core.ssp.applicable_parameters):
    # drive.ssv, the current loop's parameters for the actuators and the cycle times for the controller
    block = {"mechanism": MechanismBlock, "controller": ControllerBlock}.get(component, ActuatorBlock)
    names = {p.name for p in block.PARAMETERS}
    return {k: v for k, v in values.items() if k in names}


@pytest.fixture
def actuator_params() -> dict:
    return load_params("actuator")


@pytest.fixture
def mechanism_params() -> dict:
    return load_params("mechanism")


@pytest.fixture
def controller_params() -> dict:
    return load_params("controller")


def component_shape(system, component: str) -> tuple:
    """What a component of a read SSD is apart from its name: FMU source, step size, connectors, merged bindings
    (the standalone systems' checks: the same component as in the system they stand in for)."""
    c = system.components[component]
    return c.source, c.step_size, c.inputs, c.outputs, c.parameters


def build_once(tmp_path_factory: pytest.TempPathFactory, name: str, build: Callable[[Path], object]) -> Path:
    """The folder ``name`` that ``build(folder)`` fills, built once per test session however many pytest-xdist
    workers ask for it (xdist's docs, "Making session-scoped fixtures execute only once").

    Under xdist the folder lies in the basetemp's parent, which the workers share; the first worker builds it
    while it holds a file lock, and marks it complete last: a worker that asks meanwhile waits for the lock, and
    no worker reads a half-written build (a build that raised is built again by the next one that asks). Without
    xdist: a fresh folder of this session's basetemp."""
    if os.environ.get("PYTEST_XDIST_WORKER") is None:
        out = tmp_path_factory.mktemp(name)
        build(out)
        return out
    shared = tmp_path_factory.getbasetemp().parent
    out, complete = shared / name, shared / f"{name}.complete"
    with FileLock(shared / f"{name}.lock"):
        if not complete.exists():
            shutil.rmtree(out, ignore_errors=True)
            out.mkdir()
            build(out)
            complete.touch()
    return out


@pytest.fixture(scope="session")
def built(tmp_path_factory) -> Path:
    """A build folder with the Python FMUs and every SSP (``mast build``), built once per session for every file
    and worker that reads it (tests/test_cosim.py, test_fmi_behaviour.py, test_measured.py, test_reproduce.py);
    tests write beside it, never into it."""
    from mast.core.build import build_all

    return build_once(tmp_path_factory, "build", lambda out: build_all(out, log=lambda *_: None))


@pytest.fixture(scope="session")
def built_native(tmp_path_factory, built) -> Path:
    """A build folder with the Python FMUs and SSPs (a copy of ``built``) and their native variants (``mast build
    --native``), shared by the tests that run documented commands and benchmarks (tests/test_docs.py,
    test_benchmarks.py) and by the diagnoses' re-simulations (tests/test_diagnose.py)."""
    from mast.core.build import SSP_SRC
    from mast.core.native.build import build_native_all

    def build(out: Path) -> None:
        shutil.copytree(built, out, dirs_exist_ok=True)
        build_native_all(out, sorted(SSP_SRC.glob("*.ssd")), log=lambda *_: None)

    return build_once(tmp_path_factory, "build_native", build)


#: The test files whose tests pytest-xdist hands out one by one under ``make test`` (``--dist loadfile``): the
#: diagnoses, each test a synthesize-and-diagnose run of tens of seconds to minutes on the session's build
#: (``built_native``), with no module fixture. Every other file's tests stay together on one worker, so its module
#: fixtures are made once.
SPREAD = ("test_diagnose.py", "test_diagnose_backlash.py", "test_diagnose_split.py", "test_diagnose_unseen.py")


class SpreadLoadFile(LoadFileScheduling):
    """xdist's ``--dist loadfile`` but for the files of ``SPREAD``, each of whose tests is a work unit of its own.

    xdist gives out the files with the most tests first and these single tests last, each to the first worker free:
    the diagnoses spread over both workers fill the cores to the end, where whole files left one worker alone with
    the last diagnosis file for minutes. (xdist's ``--dist loadgroup`` would say the same with marks, but its marks
    do not reach the test ids under pytest 9.)"""

    def _split_scope(self, nodeid: str) -> str:
        path = nodeid.split("::", 1)[0]
        return nodeid if Path(path).name in SPREAD else path


@pytest.hookimpl(optionalhook=True)  # xdist's hook: unknown, and not called, under -p no:xdist
def pytest_xdist_make_scheduler(config: pytest.Config, log) -> LoadFileScheduling | None:
    """``SpreadLoadFile`` for ``--dist loadfile`` (the Makefile's ``make test``); xdist's own for the other modes."""
    return SpreadLoadFile(config, log) if config.getvalue("dist") == "loadfile" else None


def build_mechanism_system(name: str, out: Path) -> Path:
    """``build/ssp/MAST_<name>.ssp`` of another mechanism's design (``mast.core.designs.MECHANISMS``) built into
    ``out`` with the Python FMUs it needs alone: the actuator, its mechanism and its controller."""
    from mast.core.build import FMUS, build_fmu, build_ssp
    from mast.core.designs import design

    d = design(name)
    for spec in FMUS:
        if spec.model_identifier in ("MastActuator", d.model_identifier, d.controller):
            build_fmu(spec, out / "fmus")
    return build_ssp(d.ssd, out / "fmus", out / "ssp")
