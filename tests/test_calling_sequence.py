"""The master keeps FMI 2.0 Co-Simulation's calling sequence (FMI 2.0.5 section 4.2.4): in step mode no
fmi2GetReal of an FMU after an fmi2SetReal of it without an fmi2DoStep in between.

Every FMU of the default system is driven through a call logger (each component's setReal, getReal and
doStep wrapped; the master's exchange loop in Python, which makes the calls the compiled loop makes:
tests/test_native.py holds them bit-identical), and the log is checked call by call. The same logger sees
the route outside the standard (``feedthrough=True``) break it when a component declares feedthrough.
"""

from __future__ import annotations

import pytest

from mast.core.components import FMUComponent
from mast.core.master import Master
from mast.core.motion import SineMotion
from mast.core.ssp import SSPArchive, safe_extract


@pytest.fixture(scope="module")
def built_ssp(tmp_path_factory) -> str:
    """build/ssp/MAST.ssp with the Python FMUs it needs alone."""
    from mast.core.build import FMUS, SSP_SRC, build_fmu, build_ssp

    out = tmp_path_factory.mktemp("build")
    for spec in FMUS:
        if spec.model_identifier in ("MastActuator", "MastMechanism", "MastController"):
            build_fmu(spec, out / "fmus")
    return str(build_ssp(SSP_SRC / "MAST.ssd", out / "fmus", out / "ssp"))


class LoggedFMU(FMUComponent):
    """An FMUComponent whose step-mode setReal, getReal and doStep calls go into ``log`` as (name, call)."""

    def __init__(self, name, fmu, unzip_dir, log: list) -> None:
        super().__init__(name, fmu, unzip_dir)
        self.log = log
        self.stepping = False

    def exit_initialization(self) -> None:
        super().exit_initialization()
        self.stepping = True

    def _logged(self, call: str, func):
        def wrapped(*args):
            if self.stepping:
                self.log.append((self.name, call))
            return func(*args)

        return wrapped

    def setter(self, names):
        return self._logged("setReal", super().setter(names))

    def getter(self, names):
        return self._logged("getReal", super().getter(names))

    def stepper(self):
        return self._logged("doStep", super().stepper())


def violations(log: list) -> list[tuple[int, str]]:
    """(position in the log, component) of every getReal after a setReal of that component with no doStep
    between them."""
    dirty: dict[str, bool] = {}
    bad = []
    for k, (name, call) in enumerate(log):
        if call == "setReal":
            dirty[name] = True
        elif call == "doStep":
            dirty[name] = False
        elif dirty.get(name):
            bad.append((k, name))
    return bad


def run_logged(ssp: str, tmp_path, feedthrough: bool, monkeypatch) -> list:
    monkeypatch.setenv("MAST_PYTHON_EXCHANGE", "1")  # the calls through the wrapped functions
    log: list = []
    with SSPArchive(ssp) as archive:
        system = archive.system
        components = {}
        for name in system.components:
            fmu = system.fmu_path(name)
            components[name] = LoggedFMU(name, fmu, safe_extract(fmu, tmp_path / name, name), log)
        if feedthrough:  # a component that declares direct feedthrough (the MAST FMUs declare none)
            components["controller"].feedthrough = {o: frozenset({"rho_1"}) for o in ("i_cmd_1", "i_cmd_2", "i_cmd_3")}
        Master(system, components, feedthrough=feedthrough).run(
            0.01, SineMotion("z", 0.004, 2.0), record=["mechanism.z", "controller.i_cmd_1"]
        )
    return log


def test_the_master_never_reads_an_fmu_after_setting_it_without_a_step(built_ssp, tmp_path, monkeypatch):
    log = run_logged(built_ssp, tmp_path, False, monkeypatch)
    steps = {name: sum(1 for n, c in log if n == name and c == "doStep") for name, _ in log}
    assert steps["controller"] == steps["actuator_1"] == steps["mechanism"] == 100  # 10 ms, every one at 100 us
    assert {c for _, c in log} == {"setReal", "getReal", "doStep"}
    assert violations(log) == []


def test_the_logger_catches_the_feedthrough_route_outside_the_standard(built_ssp, tmp_path, monkeypatch):
    log = run_logged(built_ssp, tmp_path, True, monkeypatch)
    assert {name for _, name in violations(log)} == {"controller"}
